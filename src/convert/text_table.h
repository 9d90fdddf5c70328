// Reading whitespace- or comma-separated numeric tables from other people's files (internal):
// strict, with file:line messages.
#ifndef WALKGRAPH_SRC_CONVERT_TEXT_TABLE_H_
#define WALKGRAPH_SRC_CONVERT_TEXT_TABLE_H_

#include <string>
#include <vector>

#include "walkgraph/status.h"

namespace walkgraph::internal {

struct TextTable {
  std::vector<std::string> header;          // empty when the file has none
  std::vector<std::vector<double>> rows;
  std::vector<int> line_numbers;            // source line of each row
};

// Reads `path`; every data row must have exactly `columns` numeric fields separated by commas
// or whitespace. With `has_header`, the first line is kept as column names.
StatusOr<TextTable> ReadTextTable(const std::string& path, size_t columns, bool has_header);

}  // namespace walkgraph::internal

#endif  // WALKGRAPH_SRC_CONVERT_TEXT_TABLE_H_
