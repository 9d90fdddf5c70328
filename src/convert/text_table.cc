#include "convert/text_table.h"

#include <fstream>
#include <sstream>

#include "io/csv_reader.h"

namespace walkgraph::internal {

StatusOr<TextTable> ReadTextTable(const std::string& path, size_t columns, bool has_header) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return NotFound(path + ": cannot open file");
  TextTable table;
  std::string line;
  int n = 0;
  while (std::getline(in, line)) {
    ++n;
    if (n == 1 && line.size() >= 3 && line.compare(0, 3, "\xEF\xBB\xBF") == 0) line.erase(0, 3);
    StripCarriageReturn(&line);
    for (char& ch : line) {
      if (ch == ',' || ch == '\t') ch = ' ';
    }
    std::istringstream ss(line);
    std::vector<std::string> tokens;
    std::string tok;
    while (ss >> tok) tokens.push_back(tok);
    if (tokens.empty()) continue;
    if (has_header && table.header.empty() && table.rows.empty()) {
      table.header = tokens;
      if (tokens.size() != columns) {
        return InvalidArgument(path + ":" + std::to_string(n) + ": header has " +
                               std::to_string(tokens.size()) + " columns; expected " +
                               std::to_string(columns));
      }
      continue;
    }
    if (tokens.size() != columns) {
      return InvalidArgument(path + ":" + std::to_string(n) + ": expected " +
                             std::to_string(columns) + " numeric columns, found " +
                             std::to_string(tokens.size()));
    }
    std::vector<double> row(columns);
    for (size_t i = 0; i < columns; ++i) {
      if (!ParseFiniteDouble(tokens[i], &row[i])) {
        return InvalidArgument(path + ":" + std::to_string(n) + ": column " +
                               std::to_string(i + 1) + ": expected a finite number, found '" +
                               tokens[i] + "'");
      }
    }
    table.rows.push_back(std::move(row));
    table.line_numbers.push_back(n);
  }
  if (table.rows.empty()) return InvalidArgument(path + ": no data rows");
  return table;
}

}  // namespace walkgraph::internal
