#include "walkgraph/status.h"

namespace walkgraph {

std::string Status::ToString() const {
  switch (code_) {
    case StatusCode::kOk:
      return "OK";
    case StatusCode::kInvalidArgument:
      return "invalid argument: " + message_;
    case StatusCode::kNotFound:
      return "not found: " + message_;
    case StatusCode::kIoError:
      return "I/O error: " + message_;
    case StatusCode::kFailedPrecondition:
      return "failed precondition: " + message_;
    case StatusCode::kNumerical:
      return "numerical failure: " + message_;
    case StatusCode::kInternal:
      return "internal error: " + message_;
    case StatusCode::kCancelled:
      return "cancelled: " + message_;
  }
  return message_;
}

}  // namespace walkgraph
