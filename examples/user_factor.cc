// Extending a factor-graph estimator through the public API only: (1) a waypoint, a known
// position at a known time, added to the walk (the same as a row of waypoints.csv), and (2) the
// user's own Ceres cost function through StepGraphOptions::user_factors — here "the walker
// crossed the gate line x = c" at one pose. Runs fg-batch with and without them and prints
// what moved. Usage: user_factor WALK_DIR (a walk with truth, e.g. datasets/plaza1; the
// waypoint and the gate are taken from its truth). Exit 0 when both pulled the estimate.
#include <cmath>
#include <cstdio>
#include <memory>
#include <vector>

#include <ceres/autodiff_cost_function.h>

#include "walkgraph/graph.h"
#include "walkgraph/io.h"
#include "walkgraph/smoothers/step_graph.h"

// The user's factor: r = (x − c)/σ on one pose's position block (x, y).
struct GateCrossing {
  double c, sigma;
  template <typename T>
  bool operator()(const T* p, T* r) const {
    r[0] = (p[0] - T(c)) / T(sigma);
    return true;
  }
};

int main(int argc, char** argv) {
  namespace wg = walkgraph;
  if (argc != 2) return std::fprintf(stderr, "usage: user_factor WALK_DIR\n"), 2;
  auto walk = wg::ReadWalk(argv[1]);
  if (!walk.ok()) return std::fprintf(stderr, "%s\n", walk.status().message().c_str()), 1;
  if (walk->truth.size() < 4) return std::fprintf(stderr, "the walk needs truth\n"), 1;
  const wg::TruthSample& mark = walk->truth[walk->truth.size() / 2];
  const double gate_x = walk->truth[walk->truth.size() / 4].position_m.x();
  const double gate_t = walk->truth[walk->truth.size() / 4].t_s;

  auto before = wg::StepGraphBatch(wg::StepGraphOptions()).Run(*walk);
  if (!before.ok()) return std::fprintf(stderr, "%s\n", before.status().message().c_str()), 1;

  wg::Walk with = *walk;
  with.waypoints.push_back({mark.t_s, mark.position_m.head<2>(), /*sigma_m=*/0.2});
  wg::StepGraphOptions options;
  double gate_pose_t = 0.0;
  options.user_factors = [&](const wg::Walk&, const std::vector<double>& pose_times,
                             std::vector<wg::GraphFactor>* factors) {
    size_t k = 0;  // the pose nearest the gate time
    for (size_t i = 1; i < pose_times.size(); ++i) {
      if (std::abs(pose_times[i] - gate_t) < std::abs(pose_times[k] - gate_t)) k = i;
    }
    gate_pose_t = pose_times[k];
    factors->push_back({std::make_shared<ceres::AutoDiffCostFunction<GateCrossing, 1, 2>>(
                            new GateCrossing{gate_x, 0.05}),
                        nullptr,
                        {wg::StepGraph::PositionKey(static_cast<int>(k))}});
    return wg::Status::Ok();
  };
  auto after = wg::StepGraphBatch(options).Run(with);
  if (!after.ok()) return std::fprintf(stderr, "%s\n", after.status().message().c_str()), 1;

  const Eigen::Vector2d z = mark.position_m.head<2>();
  const auto error_at = [&](const wg::EstimateResult& r) {
    return (r.trajectory.PositionAt(mark.t_s).head<2>() - z).norm();
  };
  const auto sigma_at = [&](const wg::EstimateResult& r) {
    const auto c = r.trajectory.PositionCovarianceAt(mark.t_s);
    return c ? std::sqrt(c->trace()) : NAN;
  };
  const auto gate_offset = [&](const wg::EstimateResult& r) {
    return std::abs(r.trajectory.PositionAt(gate_pose_t).x() - gate_x);
  };
  std::printf("waypoint t=%.1f s: error %.3f -> %.3f m, sigma %.3f -> %.3f m\n", mark.t_s,
              error_at(*before), error_at(*after), sigma_at(*before), sigma_at(*after));
  std::printf("gate x=%.2f m at t=%.1f s: offset %.3f -> %.3f m\n", gate_x, gate_pose_t,
              gate_offset(*before), gate_offset(*after));
  const bool moved = error_at(*after) < error_at(*before) && sigma_at(*after) < sigma_at(*before) &&
                     gate_offset(*after) < gate_offset(*before);
  std::printf(moved ? "both moved the estimate\n" : "NOT MOVED\n");
  return moved ? 0 : 1;
}
