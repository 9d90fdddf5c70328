#include "util/text_spill.h"

#include <cerrno>
#include <ostream>
#include <streambuf>
#include <system_error>
#include <vector>

namespace walkgraph::internal {

namespace {

std::string ErrnoText(int e) { return std::error_code(e, std::generic_category()).message(); }

// An output stream buffer over a FILE*.
class FileBuf : public std::streambuf {
 public:
  explicit FileBuf(std::FILE* f) : file_(f) {}

 protected:
  int_type overflow(int_type c) override {
    if (c == traits_type::eof()) return traits_type::not_eof(c);
    return std::fputc(c, file_) == EOF ? traits_type::eof() : c;
  }
  std::streamsize xsputn(const char* s, std::streamsize n) override {
    return static_cast<std::streamsize>(std::fwrite(s, 1, static_cast<size_t>(n), file_));
  }

 private:
  std::FILE* file_;
};

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

void TextSpill::Append(const std::function<void(std::ostream&)>& write) {
  if (!status_.ok()) return;
  FileBuf buf(file_);
  std::ostream out(&buf);
  write(out);
  if (!out.good() || std::ferror(file_) != 0) {
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
