// README's library example, built against the installed package by the install_consumer test:
// a radio-only walk tracked with walkgraph's fixed-lag smoother and its Ceres cost functions.
// A point walks east at 1 m/s past three anchors; one range per anchor and second; the smoother
// keeps 5 s of states, marginalizing older ones into a prior.
#include <cmath>
#include <iostream>
#include <memory>
#include <vector>

#include "walkgraph/factors/position_random_walk_factor.h"
#include "walkgraph/factors/range_factor.h"
#include "walkgraph/smoothers/fixed_lag_smoother.h"

int main() {
  using walkgraph::FixedLagSmoother;
  using walkgraph::GraphFactor;
  using walkgraph::GraphState;
  const std::vector<Eigen::Vector3d> anchors = {{0, 5, 0}, {10, -5, 0}, {20, 5, 0}};

  FixedLagSmoother::Options options;
  options.lag_s = 5.0;
  FixedLagSmoother smoother(options);
  double last_error_m = 0.0;
  smoother.set_on_marginalize([&](walkgraph::Key key, double t_s, const std::vector<double>& p) {
    if (key < 100) last_error_m = std::hypot(p[0] - t_s, p[1]);  // truth: (t, 0)
  });

  // Static states (no timestamp, never marginalized): one range bias per anchor, held at 0.
  std::vector<GraphState> states;
  for (int a = 0; a < 3; ++a) states.push_back({100 + a, std::nullopt, {0.0}, nullptr, true});
  for (int k = 0; k <= 20; ++k) {
    const double t = k;
    GraphState s{k, t, {t + 0.3, -0.2}, nullptr, false};  // a rough initial guess
    std::vector<GraphFactor> factors;
    if (k > 0) {
      factors.push_back({std::unique_ptr<ceres::CostFunction>(
                             walkgraph::PositionRandomWalkFactor::Create(1.0, 1.0)),
                         nullptr,
                         {k - 1, k}});
    }
    for (int a = 0; a < 3; ++a) {
      const double range = (Eigen::Vector3d(t, 0, 0) - anchors[a]).norm();
      factors.push_back({std::unique_ptr<ceres::CostFunction>(
                             walkgraph::RangeFactor<2>::Create(range, anchors[a], /*sigma_m=*/0.3)),
                         std::make_shared<ceres::CauchyLoss>(0.5),
                         {k, 100 + a}});
    }
    states.push_back(std::move(s));
    auto result = smoother.Update(std::move(states), std::move(factors));
    states.clear();
    if (!result.ok()) {  // failures come back as a Status; nothing aborts
      std::cerr << result.status().message() << "\n";
      return 1;
    }
  }
  auto cov = smoother.MarginalCovariance(20);
  if (!cov.ok()) return 1;
  std::cout << "lagged error " << last_error_m << " m, final sigma_x " << std::sqrt((*cov)(0, 0))
            << " m\n";
  return last_error_m < 0.05 ? 0 : 1;
}
