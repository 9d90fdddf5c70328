// The project's one logging header (internal). Everything logs through these macros, so moving
// from glog to abseil logging (as Ceres master did) is a change to this file only.
#ifndef WALKGRAPH_SRC_LOG_H_
#define WALKGRAPH_SRC_LOG_H_

#include <glog/logging.h>

#define WG_LOG(severity) LOG(severity)
#define WG_VLOG(level) VLOG(level)

#endif  // WALKGRAPH_SRC_LOG_H_
