// Strict streaming reader for the walk format's numeric CSV files (internal).
//
// One header line naming the columns, then rows of numbers. Accepts a UTF-8 BOM and CRLF line
// ends; rejects everything else that is not exactly the expected shape, with "path:line: ...".
// Reads line by line, so a large file is never held in memory as text.
#ifndef WALKGRAPH_SRC_IO_CSV_READER_H_
#define WALKGRAPH_SRC_IO_CSV_READER_H_

#include <fstream>
#include <string>
#include <vector>

#include "walkgraph/status.h"

namespace walkgraph::internal {

class CsvReader {
 public:
  // `required` columns must come first and in this order; `optional` may follow (all or none
  // of them, in order). The header is checked by Open().
  CsvReader(std::string path, std::vector<std::string> required,
            std::vector<std::string> optional = {});

  Status Open();
  // Reads the next data row into `fields` (size = number of header columns). Returns false at
  // the end of the file. Blank lines are errors (they are where truncated files show up).
  StatusOr<bool> Next(std::vector<double>* fields);

  int line() const { return line_; }
  size_t num_columns() const { return num_columns_; }
  const std::string& path() const { return path_; }
  // "path:line: " for messages about the current row.
  std::string Where() const;

 private:
  std::string path_;
  std::vector<std::string> required_;
  std::vector<std::string> optional_;
  std::ifstream in_;
  std::string buffer_;
  int line_ = 0;
  size_t num_columns_ = 0;
};

// Splits on commas (no quoting in the walk format).
std::vector<std::string> SplitCsvLine(const std::string& line);
// Parses a whole field as a finite double; false on junk, empty, NaN or Inf.
bool ParseFiniteDouble(const std::string& field, double* value);
// Removes a trailing '\r' (CRLF files).
void StripCarriageReturn(std::string* line);

}  // namespace walkgraph::internal

#endif  // WALKGRAPH_SRC_IO_CSV_READER_H_
