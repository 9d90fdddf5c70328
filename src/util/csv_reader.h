// Strict streaming reader for the walk format's numeric CSV files (internal).
//
// One header line naming the columns, then rows of numbers. Accepts a UTF-8 BOM and CRLF line
// ends; rejects everything else that is not exactly the expected shape, with "path:line: ...".
// Reads line by line, so a large file is never held in memory as text.
#ifndef WALKGRAPH_SRC_UTIL_CSV_READER_H_
#define WALKGRAPH_SRC_UTIL_CSV_READER_H_

#include <string>
#include <string_view>
#include <vector>

#include "util/input_file.h"
#include "walkgraph/status.h"

namespace walkgraph::internal {

// Headers a file may have, any one of them (a stream with independent optional columns).
struct CsvHeaders {
  std::vector<std::vector<std::string>> accepted;
};

class CsvReader {
 public:
  // `required` columns must come first and in this order; `optional` may follow (all or none
  // of them, in order). The header is checked by Open().
  CsvReader(std::string path, std::vector<std::string> required,
            std::vector<std::string> optional = {});
  // Any one of `headers` (the first is named in the message of an empty file).
  CsvReader(std::string path, CsvHeaders headers);

  Status Open();
  // Reads the next data row into `fields` (size = number of header columns). Returns false at
  // the end of the file. Blank lines are errors (they are where truncated files show up).
  StatusOr<bool> Next(std::vector<double>* fields);
  // The same row checks (blank lines, number of columns), the fields as text (trimmed), for a
  // file with empty or non-numeric fields (anchors.csv).
  StatusOr<bool> NextText(std::vector<std::string>* fields);
  // The name of column i of the header that was read.
  const std::string& ColumnName(size_t i) const { return header_[i]; }

  int line() const { return lines_.line(); }
  size_t num_columns() const { return num_columns_; }
  // Index of a column in the header that was read, -1 when it is not there.
  int Column(const std::string& name) const;
  const std::string& path() const { return lines_.path(); }
  // "path:line: " for messages about the current row.
  std::string Where() const { return lines_.Where(); }

 private:
  LineReader lines_;
  std::vector<std::string> required_;
  std::vector<std::string> optional_;
  std::vector<std::vector<std::string>> accepted_;  // the CsvHeaders form
  std::vector<std::string> header_;                 // as read
  std::string buffer_;
  size_t num_columns_ = 0;
};

// Splits on commas (no quoting in the walk format).
std::vector<std::string> SplitCsvLine(const std::string& line);
// Parses a whole field as a finite decimal number: [+-]digits[.digits][(e|E)[+-]digits] (or
// .digits); false on anything else: empty, junk, hexadecimal (0x5, 0x1p3), NaN, Inf, or a
// magnitude beyond the double range. Subnormal values (1e-320) are finite and accepted.
bool ParseFiniteDouble(std::string_view field, double* value);
// Removes a trailing '\r' (CRLF files).
void StripCarriageReturn(std::string* line);

}  // namespace walkgraph::internal

#endif  // WALKGRAPH_SRC_UTIL_CSV_READER_H_
