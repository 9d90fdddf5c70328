// Text kept on disk instead of in memory (internal): an anonymous temporary file (tmpfile(3)),
// unlinked from the start, so nothing is left behind whatever ends the process.
#ifndef WALKGRAPH_SRC_UTIL_TEXT_SPILL_H_
#define WALKGRAPH_SRC_UTIL_TEXT_SPILL_H_

#include <cstdio>
#include <functional>
#include <ostream>
#include <string>

#include "walkgraph/status.h"

namespace walkgraph::internal {

class TextSpill {
 public:
  TextSpill();
  ~TextSpill();
  TextSpill(const TextSpill&) = delete;
  TextSpill& operator=(const TextSpill&) = delete;

  // The first failure (no temporary file, disk full) is kept and returned by status().
  void Append(const std::string& text);
  // Appends what `write` puts on the stream (streamed to the file, not built in memory).
  void Append(const std::function<void(std::ostream&)>& write);
  Status status() const { return status_; }
  // Writes everything appended so far to `out`.
  Status CopyTo(std::ostream& out) const;

 private:
  std::FILE* file_ = nullptr;
  Status status_;
};

}  // namespace walkgraph::internal

#endif  // WALKGRAPH_SRC_UTIL_TEXT_SPILL_H_
