// What an estimator returns: its trajectory and figures (the Kalman driver fills one below the
// estimator interface, walkgraph/estimator.h, which includes this header).
#ifndef WALKGRAPH_ESTIMATE_RESULT_H_
#define WALKGRAPH_ESTIMATE_RESULT_H_

#include <map>
#include <string>
#include <vector>

#include "walkgraph/trajectory.h"

namespace walkgraph {

struct EstimateResult {
  Trajectory trajectory;
  // Normalized innovation squared of each accepted measurement update (filters), for
  // consistency checks; empty where the estimator has no innovations.
  std::vector<double> nis;
  // Named figures an estimator wants to report (e.g. "ceres_iterations", "gated_updates"):
  // deterministic for a given walk and configuration.
  std::map<std::string, double> diagnostics;
  // Wall-clock figures in seconds (e.g. "update_latency_p99_s"): machine-dependent, so compare
  // keeps them out of a Monte Carlo results.json (they go to timing.json).
  std::map<std::string, double> timings;
};

}  // namespace walkgraph

#endif  // WALKGRAPH_ESTIMATE_RESULT_H_
