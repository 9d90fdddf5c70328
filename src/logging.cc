#include "walkgraph/logging.h"

#include <mutex>

#include "log.h"

namespace walkgraph {

void InitLogging(const char* program_name, int verbosity) {
  static std::once_flag once;
  std::call_once(once, [&] {
    FLAGS_logtostderr = true;
    FLAGS_minloglevel = 1;  // warnings and errors only, unless verbose
    google::InitGoogleLogging(program_name);
  });
  FLAGS_v = verbosity;
  if (verbosity > 0) FLAGS_minloglevel = 0;
}

}  // namespace walkgraph
