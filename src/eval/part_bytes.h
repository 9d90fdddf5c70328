// The bytes of results that travel between processes (internal): a study's parts (study.h) and
// a Monte Carlo comparison's runs (compare.h). Fields are whitespace-separated tokens; strings
// are <length>:<bytes>; doubles go by their bits, so what is read back is exactly what was
// written.
#ifndef WALKGRAPH_SRC_EVAL_PART_BYTES_H_
#define WALKGRAPH_SRC_EVAL_PART_BYTES_H_

#include <charconv>
#include <cinttypes>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <optional>
#include <sstream>
#include <string>
#include <utility>

#include "walkgraph/metrics.h"
#include "walkgraph/status.h"

namespace walkgraph::internal {

class PartWriter {
 public:
  void Int(long long v) { out_ << v << ' '; }
  void Unsigned(uint64_t v) { out_ << v << ' '; }
  void Double(double v) {
    uint64_t bits;
    std::memcpy(&bits, &v, sizeof(bits));
    char buf[24];
    std::snprintf(buf, sizeof(buf), "%016" PRIx64 " ", bits);
    out_ << buf;
  }
  void OptDouble(const std::optional<double>& v) {
    Int(v ? 1 : 0);
    if (v) Double(*v);
  }
  void String(const std::string& s) { out_ << s.size() << ':' << s << ' '; }
  void Line() { out_ << '\n'; }
  std::string str() const { return out_.str(); }

 private:
  std::ostringstream out_;
};

class PartReader {
 public:
  // `what` names the kind of bytes in errors ("walkgraph study part").
  PartReader(const std::string& bytes, std::string origin, std::string what)
      : b_(bytes), origin_(std::move(origin)), what_(std::move(what)) {}
  bool ok() const { return ok_; }
  Status Error() const {
    return InvalidArgument(origin_ + ": not a " + what_ + ", or damaged (at byte " +
                           std::to_string(pos_) + ")");
  }
  std::string Token() {
    while (pos_ < b_.size() && (b_[pos_] == ' ' || b_[pos_] == '\n')) ++pos_;
    const size_t start = pos_;
    while (pos_ < b_.size() && b_[pos_] != ' ' && b_[pos_] != '\n' && b_[pos_] != ':') ++pos_;
    if (start == pos_) ok_ = false;
    return b_.substr(start, pos_ - start);
  }
  long long Int(long long lo, long long hi) {
    long long v = 0;
    if (!Parse(Token(), 10, &v) || v < lo || v > hi) ok_ = false;
    return ok_ ? v : lo;
  }
  uint64_t Unsigned() {
    uint64_t v = 0;
    if (!Parse(Token(), 10, &v)) ok_ = false;
    return v;
  }
  double Double() {
    const std::string t = Token();
    uint64_t bits = 0;
    if (t.size() != 16 || !Parse(t, 16, &bits)) ok_ = false;
    double v;
    std::memcpy(&v, &bits, sizeof(v));
    return v;
  }
  std::optional<double> OptDouble() {
    if (Int(0, 1) == 0) return std::nullopt;
    return Double();
  }
  std::string String() {
    const long long n = Int(0, static_cast<long long>(b_.size()));
    if (!ok_ || pos_ >= b_.size() || b_[pos_] != ':' || b_.size() - pos_ - 1 < size_t(n)) {
      ok_ = false;
      return "";
    }
    std::string s = b_.substr(pos_ + 1, n);
    pos_ += 1 + n;
    return s;
  }
  // A count of items that follow, each taking at least one byte: at most the bytes left.
  long long Count() { return Int(0, static_cast<long long>(b_.size() - pos_)); }
  // The whole token as an integer in `base` (no sign for unsigned types, no overflow).
  template <typename T>
  static bool Parse(const std::string& t, int base, T* v) {
    const char* end = t.data() + t.size();
    const auto r = std::from_chars(t.data(), end, *v, base);
    return !t.empty() && r.ec == std::errc() && r.ptr == end;
  }
  bool AtEnd() {
    while (pos_ < b_.size() && (b_[pos_] == ' ' || b_[pos_] == '\n')) ++pos_;
    return pos_ == b_.size();
  }

 private:
  const std::string& b_;
  std::string origin_, what_;
  size_t pos_ = 0;
  bool ok_ = true;
};

// ErrorStats: every ErrorStatFields() figure, then n_points.
inline void PutStats(PartWriter& w, const ErrorStats& s) {
  for (const ErrorStatField& f : ErrorStatFields()) w.Double(s.*f.field);
  w.Int(s.n_points);
}

inline ErrorStats GetStats(PartReader& r) {
  ErrorStats s;
  for (const ErrorStatField& f : ErrorStatFields()) s.*f.field = r.Double();
  s.n_points = static_cast<int>(r.Int(0, INT32_MAX));
  return s;
}

// A Status: its code, then its message.
inline void PutStatus(PartWriter& w, const Status& s) {
  w.Int(static_cast<int>(s.code()));
  w.String(s.message());
}

inline Status GetStatus(PartReader& r) {
  const auto code = static_cast<StatusCode>(r.Int(0, static_cast<int>(StatusCode::kCancelled)));
  std::string message = r.String();
  return code == StatusCode::kOk ? Status::Ok() : Status(code, std::move(message));
}

}  // namespace walkgraph::internal

#endif  // WALKGRAPH_SRC_EVAL_PART_BYTES_H_
