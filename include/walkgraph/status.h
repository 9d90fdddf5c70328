// Status and StatusOr<T>: how every walkgraph library function reports failure.
//
// The library never aborts, prints or exits on bad input; it returns a Status whose message
// names what was wrong (for files: "path:line: what was expected"). Modelled on absl::Status
// and Ceres' habit of returning a message instead of crashing.
#ifndef WALKGRAPH_STATUS_H_
#define WALKGRAPH_STATUS_H_

#include <cassert>
#include <string>
#include <utility>
#include <variant>

namespace walkgraph {

enum class StatusCode {
  kOk = 0,
  kInvalidArgument,     // malformed input, bad configuration
  kNotFound,            // missing file, unknown id
  kIoError,             // the operating system refused a read or write
  kFailedPrecondition,  // input is valid but unusable for this operation (e.g. no anchors)
  kNumerical,           // a solver or decomposition failed
  kInternal,
  kCancelled,  // stopped on request (RequestCancel, e.g. SIGINT); outputs left as they were
};

class Status {
 public:
  Status() = default;
  Status(StatusCode code, std::string message) : code_(code), message_(std::move(message)) {}

  static Status Ok() { return Status(); }
  bool ok() const { return code_ == StatusCode::kOk; }
  StatusCode code() const { return code_; }
  const std::string& message() const { return message_; }
  std::string ToString() const;

 private:
  StatusCode code_ = StatusCode::kOk;
  std::string message_;
};

inline Status InvalidArgument(std::string m) {
  return {StatusCode::kInvalidArgument, std::move(m)};
}
inline Status NotFound(std::string m) { return {StatusCode::kNotFound, std::move(m)}; }
inline Status IoError(std::string m) { return {StatusCode::kIoError, std::move(m)}; }
inline Status FailedPrecondition(std::string m) {
  return {StatusCode::kFailedPrecondition, std::move(m)};
}
inline Status NumericalError(std::string m) { return {StatusCode::kNumerical, std::move(m)}; }
inline Status InternalError(std::string m) { return {StatusCode::kInternal, std::move(m)}; }
inline Status Cancelled(std::string m) { return {StatusCode::kCancelled, std::move(m)}; }

// Either a value or a non-OK Status.
template <typename T>
class StatusOr {
 public:
  StatusOr(T value) : v_(std::move(value)) {}        // NOLINT(runtime/explicit)
  StatusOr(Status status) : v_(std::move(status)) {  // NOLINT(runtime/explicit)
    if (std::get<Status>(v_).ok()) v_ = Status(StatusCode::kInternal, "StatusOr built from OK");
  }
  bool ok() const { return std::holds_alternative<T>(v_); }
  Status status() const { return ok() ? Status::Ok() : std::get<Status>(v_); }
  const T& value() const& {
    assert(ok());
    return std::get<T>(v_);
  }
  T& value() & {
    assert(ok());
    return std::get<T>(v_);
  }
  T&& value() && {
    assert(ok());
    return std::get<T>(std::move(v_));
  }
  const T& operator*() const& { return value(); }
  T& operator*() & { return value(); }
  const T* operator->() const { return &value(); }
  T* operator->() { return &value(); }

 private:
  std::variant<T, Status> v_;
};

}  // namespace walkgraph

#define WG_STATUS_CONCAT_INNER_(a, b) a##b
#define WG_STATUS_CONCAT_(a, b) WG_STATUS_CONCAT_INNER_(a, b)

// Returns from the calling function if `expr` (a Status) is not OK.
#define WG_RETURN_IF_ERROR(expr)             \
  do {                                       \
    ::walkgraph::Status wg_status_ = (expr); \
    if (!wg_status_.ok()) return wg_status_; \
  } while (false)

// `lhs = value of expr` (a StatusOr), or returns its Status from the calling function.
#define WG_ASSIGN_OR_RETURN(lhs, expr) \
  WG_ASSIGN_OR_RETURN_IMPL_(WG_STATUS_CONCAT_(wg_statusor_, __LINE__), lhs, expr)
#define WG_ASSIGN_OR_RETURN_IMPL_(tmp, lhs, expr) \
  auto tmp = (expr);                              \
  if (!tmp.ok()) return tmp.status();             \
  lhs = std::move(tmp).value()

#endif  // WALKGRAPH_STATUS_H_
