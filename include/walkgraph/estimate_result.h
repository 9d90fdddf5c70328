// What an estimator returns: its trajectory and figures (the Kalman driver fills one below the
// estimator interface, walkgraph/estimator.h, which includes this header).
#ifndef WALKGRAPH_ESTIMATE_RESULT_H_
#define WALKGRAPH_ESTIMATE_RESULT_H_

#include <cmath>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "walkgraph/trajectory.h"

namespace walkgraph {

// An anchor position an estimator estimated (fg-batch: the unknown and uncertain anchors,
// walk.h Anchor). An unobservable one (heard too little, or from too narrow a geometry for one
// position to stand out) was left out of the solution: no position, no covariance.
struct AnchorEstimate {
  int id = 0;
  bool observable = true;
  int readings = 0;  // its RSS or range readings in the walk
  Eigen::Vector2d position_m = Eigen::Vector2d::Constant(std::nan(""));
  // Marginal covariance of (x, y), m²; absent when not computed (rank deficiency, or
  // covariance: false).
  std::optional<Eigen::Matrix2d> covariance;
};

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
  // The anchors the estimator placed (empty for estimators that take anchors as given); compare
  // writes them to anchors_estimated/<estimator>.csv.
  std::vector<AnchorEstimate> anchors;
};

}  // namespace walkgraph

#endif  // WALKGRAPH_ESTIMATE_RESULT_H_
