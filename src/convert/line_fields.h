// Splitting and parsing the fields of one line of someone else's text log (internal): strict,
// every failure names "file:line: field N ...".
#ifndef WALKGRAPH_SRC_CONVERT_LINE_FIELDS_H_
#define WALKGRAPH_SRC_CONVERT_LINE_FIELDS_H_

#include <string>
#include <string_view>
#include <vector>

#include "walkgraph/status.h"

namespace walkgraph::internal {

// A line being parsed: where it is (for messages) and its fields.
class LineFields {
 public:
  // Splits `line` at every `separator` (empty fields are kept); trailing '\r' is dropped.
  LineFields(std::string path, int line_number, std::string_view line, char separator);

  size_t size() const { return fields_.size(); }
  const std::string& field(size_t i) const { return fields_[i]; }
  // "path:line: "
  std::string Where() const;
  // An InvalidArgument status "path:line: <what>".
  Status Error(const std::string& what) const;
  // Requires exactly `n` fields (or n_alt when given).
  Status ExpectCount(size_t n, size_t n_alt = 0) const;
  // Field i (0-based) as a finite number / an integer; surrounding spaces are allowed.
  StatusOr<double> Number(size_t i) const;
  StatusOr<long long> Integer(size_t i) const;

 private:
  std::string path_;
  int line_number_;
  std::vector<std::string> fields_;
};

}  // namespace walkgraph::internal

#endif  // WALKGRAPH_SRC_CONVERT_LINE_FIELDS_H_
