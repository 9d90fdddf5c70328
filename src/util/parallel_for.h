// The one worker pool of the library (internal): Monte Carlo runs, study cells and PCRB runs.
#ifndef WALKGRAPH_SRC_UTIL_PARALLEL_FOR_H_
#define WALKGRAPH_SRC_UTIL_PARALLEL_FOR_H_

#include <functional>

#include "walkgraph/status.h"

namespace walkgraph::internal {

// Runs body(i) for i in [begin, end) on `threads` workers (threads <= 1: on the caller's thread,
// in order). Indices are handed out in increasing order; after the first failure no new index
// starts, and the failure of the smallest failed index is returned. An exception escaping `body`
// becomes a Status (std::bad_alloc: "out of memory"); a worker that cannot be started leaves
// its share to the others. A cancel request (walkgraph/cancel.h) stops the loop with kCancelled.
Status ParallelFor(int begin, int end, int threads, const std::function<Status(int)>& body);

}  // namespace walkgraph::internal

#endif  // WALKGRAPH_SRC_UTIL_PARALLEL_FOR_H_
