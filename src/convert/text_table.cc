#include "convert/text_table.h"

#include <cctype>

#include "util/csv_reader.h"
#include "util/input_file.h"
#include "util/text.h"

namespace walkgraph::internal {

StatusOr<TextTable> ReadTextTable(const std::string& path, size_t columns, bool has_header) {
  internal::LineReader in(path);
  WG_RETURN_IF_ERROR(in.Open());
  TextTable table;
  std::string line;
  int n = 0;
  while (true) {
    WG_ASSIGN_OR_RETURN(const bool more, in.Next(&line));
    if (!more) break;
    ++n;
    // Commas and runs of white space (as istream's >> reads it) separate the fields.
    for (char& ch : line) {
      if (ch == ',' || std::isspace(static_cast<unsigned char>(ch))) ch = ' ';
    }
    std::vector<std::string> tokens;
    for (std::string& field : Split(line, ' ')) {
      if (!field.empty()) tokens.push_back(std::move(field));
    }
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
        return InvalidArgument(
            path + ":" + std::to_string(n) + ": column " + std::to_string(i + 1) +
            ": expected a finite decimal number, found " + QuotedNumber(tokens[i]));
      }
    }
    table.rows.push_back(std::move(row));
    table.line_numbers.push_back(n);
  }
  if (table.rows.empty()) return InvalidArgument(path + ": no data rows");
  return table;
}

}  // namespace walkgraph::internal
