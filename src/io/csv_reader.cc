#include "io/csv_reader.h"

#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <sstream>

namespace walkgraph::internal {

namespace {

std::string Join(const std::vector<std::string>& v) {
  std::string s;
  for (size_t i = 0; i < v.size(); ++i) s += (i ? "," : "") + v[i];
  return s;
}

std::string Trim(const std::string& s) {
  const size_t b = s.find_first_not_of(" \t");
  if (b == std::string::npos) return "";
  const size_t e = s.find_last_not_of(" \t");
  return s.substr(b, e - b + 1);
}

}  // namespace

std::vector<std::string> SplitCsvLine(const std::string& line) {
  std::vector<std::string> out;
  size_t start = 0;
  while (true) {
    const size_t comma = line.find(',', start);
    if (comma == std::string::npos) {
      out.push_back(Trim(line.substr(start)));
      break;
    }
    out.push_back(Trim(line.substr(start, comma - start)));
    start = comma + 1;
  }
  return out;
}

bool ParseFiniteDouble(const std::string& field, double* value) {
  if (field.empty()) return false;
  const char* begin = field.c_str();
  char* end = nullptr;
  errno = 0;
  const double v = std::strtod(begin, &end);
  if (end != begin + field.size() || errno == ERANGE || !std::isfinite(v)) return false;
  *value = v;
  return true;
}

void StripCarriageReturn(std::string* line) {
  if (!line->empty() && line->back() == '\r') line->pop_back();
}

CsvReader::CsvReader(std::string path, std::vector<std::string> required,
                     std::vector<std::string> optional)
    : path_(std::move(path)), required_(std::move(required)), optional_(std::move(optional)) {}

std::string CsvReader::Where() const { return path_ + ":" + std::to_string(line_) + ": "; }

Status CsvReader::Open() {
  in_.open(path_, std::ios::binary);
  if (!in_) return NotFound(path_ + ": cannot open file");
  if (!std::getline(in_, buffer_)) {
    return InvalidArgument(path_ + ":1: empty file; expected the header line '" +
                           Join(required_) + "'");
  }
  line_ = 1;
  if (buffer_.size() >= 3 && static_cast<unsigned char>(buffer_[0]) == 0xEF &&
      static_cast<unsigned char>(buffer_[1]) == 0xBB &&
      static_cast<unsigned char>(buffer_[2]) == 0xBF) {
    buffer_.erase(0, 3);  // UTF-8 byte-order mark
  }
  StripCarriageReturn(&buffer_);
  const std::vector<std::string> header = SplitCsvLine(buffer_);
  std::vector<std::string> with_optional = required_;
  with_optional.insert(with_optional.end(), optional_.begin(), optional_.end());
  if (header == required_) {
    num_columns_ = required_.size();
  } else if (!optional_.empty() && header == with_optional) {
    num_columns_ = with_optional.size();
  } else {
    std::string expected = "'" + Join(required_) + "'";
    if (!optional_.empty()) expected += " or '" + Join(with_optional) + "'";
    return InvalidArgument(Where() + "header is '" + buffer_ + "'; expected " + expected);
  }
  return Status::Ok();
}

StatusOr<bool> CsvReader::Next(std::vector<double>* fields) {
  if (!std::getline(in_, buffer_)) {
    if (in_.bad()) return IoError(path_ + ": read error after line " + std::to_string(line_));
    return false;
  }
  ++line_;
  StripCarriageReturn(&buffer_);
  if (buffer_.empty()) {
    // A single trailing empty line is how most tools end a file; anything after it is not.
    std::string rest;
    while (std::getline(in_, rest)) {
      StripCarriageReturn(&rest);
      if (!rest.empty()) return InvalidArgument(Where() + "empty line inside the data");
    }
    return false;
  }
  const std::vector<std::string> parts = SplitCsvLine(buffer_);
  if (parts.size() != num_columns_) {
    return InvalidArgument(Where() + "expected " + std::to_string(num_columns_) +
                           " comma-separated columns, found " + std::to_string(parts.size()));
  }
  fields->resize(num_columns_);
  for (size_t i = 0; i < parts.size(); ++i) {
    if (!ParseFiniteDouble(parts[i], &(*fields)[i])) {
      const std::string name = i < required_.size() ? required_[i] : optional_[i - required_.size()];
      return InvalidArgument(Where() + "column '" + name + "': expected a finite number, found '" +
                             parts[i] + "'");
    }
  }
  return true;
}

}  // namespace walkgraph::internal
