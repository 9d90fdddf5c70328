// Output folders that appear complete or not at all (internal; compare and study use it).
#ifndef WALKGRAPH_SRC_REPORT_FOLDER_H_
#define WALKGRAPH_SRC_REPORT_FOLDER_H_

#include <filesystem>
#include <functional>
#include <string>

#include "walkgraph/status.h"

namespace walkgraph::report {

// `fill` writes into a fresh temporary folder "<out_dir>.tmp-<pid>"; when it succeeds the
// folder replaces `out_dir` (renamed), else it is removed and out_dir is left untouched.
Status WriteFolderAtomically(const std::string& out_dir,
                             const std::function<Status(const std::filesystem::path& tmp)>& fill);

}  // namespace walkgraph::report

#endif  // WALKGRAPH_SRC_REPORT_FOLDER_H_
