// Opening the files walkgraph reads (internal): one place that refuses what is not a regular
// file and lines or files too long to be data.
//
// FIFOs, sockets, devices, folders, symbolic-link loops and dangling links are errors at once
// (a FIFO would block the reader forever; a loop would look like a missing file). Lines are read
// with a length cap, so a file without line ends (or of NUL bytes) is an error, not a read of
// the whole file into memory.
#ifndef WALKGRAPH_SRC_UTIL_INPUT_FILE_H_
#define WALKGRAPH_SRC_UTIL_INPUT_FILE_H_

#include <fstream>
#include <string>

#include "walkgraph/status.h"

namespace walkgraph::internal {

// Longest line the readers accept (the walk format's lines are < 200 bytes; the converters'
// sources < 10 kB).
inline constexpr size_t kMaxLineBytes = 1 << 20;
// Largest YAML file (walk.yaml, configs, manifests) read whole.
inline constexpr size_t kMaxYamlBytes = 16 << 20;

// OK when `path` is (a link to) a regular file; NotFound when there is nothing at `path`;
// InvalidArgument naming what is there instead ("a FIFO", "a folder", ...) otherwise.
Status CheckInputFile(const std::string& path);

// Whether an optional file is there: false when nothing is at `path`, true for a regular file,
// the error of CheckInputFile for anything else.
StatusOr<bool> OptionalInputFile(const std::string& path);

// The whole file as text, at most `max_bytes`.
StatusOr<std::string> ReadInputFile(const std::string& path, size_t max_bytes);

class LineReader {
 public:
  explicit LineReader(std::string path) : path_(std::move(path)) {}
  // Checks the file (CheckInputFile) and opens it.
  Status Open();
  // The next line without its line end ("\n" or "\r\n"; a UTF-8 byte-order mark is dropped
  // from line 1); false at the end of the file.
  StatusOr<bool> Next(std::string* line);
  int line() const { return line_; }
  const std::string& path() const { return path_; }
  // "path:line: " for messages about the current line.
  std::string Where() const { return path_ + ":" + std::to_string(line_) + ": "; }

 private:
  std::string path_;
  std::ifstream in_;
  int line_ = 0;
};

}  // namespace walkgraph::internal

#endif  // WALKGRAPH_SRC_UTIL_INPUT_FILE_H_
