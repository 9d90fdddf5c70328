#include "util/input_file.h"

#include <sys/stat.h>

#include <cerrno>
#include <system_error>

namespace walkgraph::internal {

namespace {

std::string ErrnoText(int e) { return std::error_code(e, std::generic_category()).message(); }

const char* KindOf(mode_t mode) {
  if (S_ISDIR(mode)) return "a folder";
  if (S_ISFIFO(mode)) return "a FIFO";
  if (S_ISSOCK(mode)) return "a socket";
  if (S_ISCHR(mode) || S_ISBLK(mode)) return "a device";
  return "a special file";
}

}  // namespace

Status CheckInputFile(const std::string& path) {
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0) {
    const int e = errno;
    struct stat link {};
    if (e == ENOENT && ::lstat(path.c_str(), &link) == 0) {
      return InvalidArgument(path + ": is a symbolic link to nothing; expected a regular file");
    }
    if (e == ENOENT) return NotFound(path + ": no such file");
    if (e == ELOOP) {
      return InvalidArgument(path + ": symbolic link loop; expected a regular file");
    }
    return IoError(path + ": cannot read: " + ErrnoText(e));
  }
  if (!S_ISREG(st.st_mode)) {
    return InvalidArgument(path + ": is " + KindOf(st.st_mode) + "; expected a regular file");
  }
  return Status::Ok();
}

StatusOr<bool> OptionalInputFile(const std::string& path) {
  const Status s = CheckInputFile(path);
  if (s.ok()) return true;
  if (s.code() == StatusCode::kNotFound) return false;
  return s;
}

StatusOr<std::string> ReadInputFile(const std::string& path, size_t max_bytes) {
  WG_RETURN_IF_ERROR(CheckInputFile(path));
  std::ifstream in(path, std::ios::binary);
  if (!in) return IoError(path + ": cannot open: " + ErrnoText(errno));
  std::string text;
  char buffer[1 << 16];
  while (in.read(buffer, sizeof(buffer)) || in.gcount() > 0) {
    text.append(buffer, static_cast<size_t>(in.gcount()));
    if (text.size() > max_bytes) {
      return InvalidArgument(path + ": larger than " + std::to_string(max_bytes >> 20) +
                             " MiB; expected a small text file");
    }
  }
  if (in.bad()) return IoError(path + ": read error");
  return text;
}

Status LineReader::Open() {
  WG_RETURN_IF_ERROR(CheckInputFile(path_));
  in_.open(path_, std::ios::binary);
  if (!in_) return IoError(path_ + ": cannot open: " + ErrnoText(errno));
  return Status::Ok();
}

StatusOr<bool> LineReader::Next(std::string* line) {
  line->clear();
  std::streambuf* buf = in_.rdbuf();
  bool any = false;
  while (true) {
    const int c = buf->sbumpc();
    if (c == std::char_traits<char>::eof()) break;
    any = true;
    if (c == '\n') break;
    if (line->size() >= kMaxLineBytes) {
      ++line_;
      return InvalidArgument(Where() + "line longer than " + std::to_string(kMaxLineBytes >> 20) +
                             " MiB; expected a text file with one record per line");
    }
    line->push_back(static_cast<char>(c));
  }
  if (!any) return false;
  ++line_;
  if (line_ == 1 && line->compare(0, 3, "\xEF\xBB\xBF") == 0) line->erase(0, 3);
  if (!line->empty() && line->back() == '\r') line->pop_back();
  return true;
}

}  // namespace walkgraph::internal
