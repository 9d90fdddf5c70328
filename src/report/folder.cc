#include "report/folder.h"

#include <unistd.h>

namespace walkgraph::report {

namespace fs = std::filesystem;

Status WriteFolderAtomically(const std::string& out_dir,
                             const std::function<Status(const fs::path& tmp)>& fill) {
  const fs::path final_dir(out_dir);
  const fs::path tmp = final_dir.string() + ".tmp-" + std::to_string(::getpid());
  std::error_code ec;
  fs::remove_all(tmp, ec);
  if (!fs::create_directories(tmp, ec)) {
    return IoError(out_dir + ": cannot create " + tmp.string() + ": " + ec.message());
  }
  const Status s = fill(tmp);
  if (!s.ok()) {
    fs::remove_all(tmp, ec);
    return s;
  }
  if (fs::exists(final_dir, ec)) fs::remove_all(final_dir, ec);
  fs::rename(tmp, final_dir, ec);
  if (ec) {
    const std::string why = ec.message();
    fs::remove_all(tmp, ec);
    return IoError(out_dir + ": cannot rename " + tmp.string() + ": " + why);
  }
  return Status::Ok();
}

}  // namespace walkgraph::report
