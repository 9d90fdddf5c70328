// Thread counts of walkgraph's parallel loops (Monte Carlo runs, study cells, PCRB runs).
#ifndef WALKGRAPH_PARALLEL_H_
#define WALKGRAPH_PARALLEL_H_

#include "walkgraph/status.h"

namespace walkgraph {

// The most worker threads a loop accepts; larger requests are refused (a typo such as 100000
// would otherwise exhaust the process's threads).
inline constexpr int kMaxThreads = 256;

// The thread count for `requested` (<= 0: the machine's hardware threads) and `work_items`
// (never more threads than items); InvalidArgument above kMaxThreads.
StatusOr<int> ResolveThreads(int requested, int work_items);

}  // namespace walkgraph

#endif  // WALKGRAPH_PARALLEL_H_
