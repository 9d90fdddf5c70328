#include "util/csv_reader.h"

#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <sstream>

#include "util/text.h"

namespace walkgraph::internal {

namespace {

std::string Join(const std::vector<std::string>& names) { return internal::Join(names, ","); }

}  // namespace

std::vector<std::string> SplitCsvLine(const std::string& line) {
  std::vector<std::string> fields = Split(line, ',');
  for (std::string& f : fields) f = Trim(f);
  return fields;
}

bool ParseFiniteDouble(std::string_view field, double* value) {
  // The grammar first: strtod alone would also take hexadecimal, "inf", "nan" and spaces.
  size_t i = 0;
  const size_t n = field.size();
  auto digits = [&] {
    const size_t start = i;
    while (i < n && field[i] >= '0' && field[i] <= '9') ++i;
    return i - start;
  };
  if (i < n && (field[i] == '+' || field[i] == '-')) ++i;
  size_t mantissa = digits();
  if (i < n && field[i] == '.') {
    ++i;
    mantissa += digits();
  }
  if (mantissa == 0) return false;
  if (i < n && (field[i] == 'e' || field[i] == 'E')) {
    ++i;
    if (i < n && (field[i] == '+' || field[i] == '-')) ++i;
    if (digits() == 0) return false;
  }
  if (i != n) return false;
  const std::string text(field);
  errno = 0;
  const double v = std::strtod(text.c_str(), nullptr);
  // ERANGE is also set for subnormal results, which are finite: only overflow is refused.
  if (!std::isfinite(v)) return false;
  *value = v;
  return true;
}

void StripCarriageReturn(std::string* line) {
  if (!line->empty() && line->back() == '\r') line->pop_back();
}

CsvReader::CsvReader(std::string path, std::vector<std::string> required,
                     std::vector<std::string> optional)
    : lines_(std::move(path)), required_(std::move(required)), optional_(std::move(optional)) {}

CsvReader::CsvReader(std::string path, CsvHeaders headers)
    : lines_(std::move(path)), accepted_(std::move(headers.accepted)) {
  if (!accepted_.empty()) required_ = accepted_.front();
}

int CsvReader::Column(const std::string& name) const {
  for (size_t i = 0; i < header_.size(); ++i) {
    if (header_[i] == name) return static_cast<int>(i);
  }
  return -1;
}

Status CsvReader::Open() {
  WG_RETURN_IF_ERROR(lines_.Open());
  WG_ASSIGN_OR_RETURN(const bool any, lines_.Next(&buffer_));
  if (!any) {
    return InvalidArgument(path() + ":1: empty file; expected the header line '" + Join(required_) +
                           "'");
  }
  const std::vector<std::string> header = SplitCsvLine(buffer_);
  if (!accepted_.empty()) {
    std::string expected;
    for (const std::vector<std::string>& h : accepted_) {
      if (header == h) {
        header_ = h;
        num_columns_ = h.size();
        return Status::Ok();
      }
      expected += (expected.empty() ? "'" : " or '") + Join(h) + "'";
    }
    return InvalidArgument(Where() + "header is " + Quoted(buffer_) + "; expected " + expected);
  }
  std::vector<std::string> with_optional = required_;
  with_optional.insert(with_optional.end(), optional_.begin(), optional_.end());
  if (header == required_) {
    num_columns_ = required_.size();
    header_ = required_;
  } else if (!optional_.empty() && header == with_optional) {
    num_columns_ = with_optional.size();
    header_ = with_optional;
  } else {
    std::string expected = "'" + Join(required_) + "'";
    if (!optional_.empty()) expected += " or '" + Join(with_optional) + "'";
    return InvalidArgument(Where() + "header is " + Quoted(buffer_) + "; expected " + expected);
  }
  return Status::Ok();
}

StatusOr<bool> CsvReader::Next(std::vector<double>* fields) {
  std::vector<std::string> parts;
  WG_ASSIGN_OR_RETURN(const bool any, NextText(&parts));
  if (!any) return false;
  fields->resize(num_columns_);
  for (size_t i = 0; i < parts.size(); ++i) {
    if (!ParseFiniteDouble(parts[i], &(*fields)[i])) {
      const std::string& name = header_[i];
      return InvalidArgument(Where() + "column '" + name +
                             "': expected a finite decimal number, found " +
                             QuotedNumber(parts[i]));
    }
  }
  return true;
}

StatusOr<bool> CsvReader::NextText(std::vector<std::string>* fields) {
  WG_ASSIGN_OR_RETURN(const bool any, lines_.Next(&buffer_));
  if (!any) return false;
  if (buffer_.empty()) {
    // A single trailing empty line is how most tools end a file; anything after it is not.
    const std::string blank = Where();
    std::string rest;
    while (true) {
      WG_ASSIGN_OR_RETURN(const bool more, lines_.Next(&rest));
      if (!more) return false;
      if (!rest.empty()) return InvalidArgument(blank + "empty line inside the data");
    }
  }
  *fields = SplitCsvLine(buffer_);
  if (fields->size() != num_columns_) {
    return InvalidArgument(Where() + "expected " + std::to_string(num_columns_) +
                           " comma-separated columns, found " + std::to_string(fields->size()));
  }
  return true;
}

}  // namespace walkgraph::internal
