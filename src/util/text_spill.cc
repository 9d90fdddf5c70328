#include "util/text_spill.h"

#include <cerrno>
#include <system_error>
#include <vector>

namespace walkgraph::internal {

namespace {
std::string ErrnoText(int e) { return std::error_code(e, std::generic_category()).message(); }
}  // namespace

TextSpill::TextSpill() : file_(std::tmpfile()) {
  if (file_ == nullptr) status_ = IoError("cannot create a temporary file: " + ErrnoText(errno));
}

TextSpill::~TextSpill() {
  if (file_ != nullptr) std::fclose(file_);
}

void TextSpill::Append(const std::string& text) {
  if (!status_.ok() || text.empty()) return;
  if (std::fwrite(text.data(), 1, text.size(), file_) != text.size()) {
    status_ = IoError("cannot write a temporary file: " + ErrnoText(errno));
  }
}

Status TextSpill::CopyTo(std::ostream& out) const {
  if (!status_.ok()) return status_;
  if (std::fflush(file_) != 0 || std::fseek(file_, 0, SEEK_SET) != 0) {
    return IoError("cannot read back a temporary file: " + ErrnoText(errno));
  }
  std::vector<char> buffer(1 << 16);
  size_t n = 0;
  while ((n = std::fread(buffer.data(), 1, buffer.size(), file_)) > 0) {
    out.write(buffer.data(), static_cast<std::streamsize>(n));
  }
  const bool failed = std::ferror(file_) != 0;
  std::fseek(file_, 0, SEEK_END);  // later appends go to the end again
  if (failed) return IoError("cannot read back a temporary file");
  return Status::Ok();
}

}  // namespace walkgraph::internal
