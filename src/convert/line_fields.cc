#include "convert/line_fields.h"

#include <cerrno>
#include <cmath>
#include <cstdlib>

#include "util/csv_reader.h"
#include "util/text.h"

namespace walkgraph::internal {

namespace {

std::string_view WithoutCarriageReturn(std::string_view line) {
  if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
  return line;
}

}  // namespace

LineFields::LineFields(std::string path, int line_number, std::string_view line, char separator)
    : path_(std::move(path)),
      line_number_(line_number),
      fields_(Split(WithoutCarriageReturn(line), separator)) {}

std::string LineFields::Where() const { return path_ + ":" + std::to_string(line_number_) + ": "; }

Status LineFields::Error(const std::string& what) const { return InvalidArgument(Where() + what); }

Status LineFields::ExpectCount(size_t n, size_t n_alt) const {
  if (fields_.size() == n || (n_alt != 0 && fields_.size() == n_alt)) return Status::Ok();
  std::string expected = std::to_string(n);
  if (n_alt != 0) expected += " or " + std::to_string(n_alt);
  return Error("expected " + expected + " fields, found " + std::to_string(fields_.size()));
}

StatusOr<double> LineFields::Number(size_t i) const {
  if (i >= fields_.size()) return Error("field " + std::to_string(i + 1) + " missing");
  double v = 0.0;
  if (!ParseFiniteDouble(Trim(fields_[i]), &v)) {
    return Error("field " + std::to_string(i + 1) + " " + QuotedNumber(fields_[i]) +
                 " is not a finite decimal number");
  }
  return v;
}

StatusOr<long long> LineFields::Integer(size_t i) const {
  WG_ASSIGN_OR_RETURN(const double v, Number(i));
  if (std::floor(v) != v || std::fabs(v) > 9.0e15) {
    return Error("field " + std::to_string(i + 1) + " " + QuotedNumber(fields_[i]) +
                 " is not an integer");
  }
  return static_cast<long long>(v);
}

}  // namespace walkgraph::internal
