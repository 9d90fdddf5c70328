// GapReachFactor: a walker covers at most so much ground in a given time, so the horizontal
// distance between two states that nothing else links (either side of an IMU gap) is bounded:
//
//   r = max(0, ‖[p_b − p_a]_xy‖ − L) / σ,
//
// L the reach (m) the walker showed over spans as long before (ins_graph.cc learns it), σ how
// sharp the bound is. One-sided: a shorter distance (a turn, a stop inside the gap) costs
// nothing. Parameter blocks: p_a (3), p_b (3).
#ifndef WALKGRAPH_FACTORS_GAP_REACH_FACTOR_H_
#define WALKGRAPH_FACTORS_GAP_REACH_FACTOR_H_

#include <cmath>

#include <ceres/autodiff_cost_function.h>
#include <ceres/jet.h>

namespace walkgraph {

class GapReachFactor {
 public:
  GapReachFactor(double reach_m, double sigma_m) : reach_m_(reach_m), inv_sigma_(1.0 / sigma_m) {}

  template <typename T>
  bool operator()(const T* p_a, const T* p_b, T* residual) const {
    using std::sqrt;
    const T dx = p_b[0] - p_a[0], dy = p_b[1] - p_a[1];
    const T d2 = dx * dx + dy * dy;
    // Inside the reach (and at d = 0, where the norm has no derivative) the factor is inactive.
    if (!(d2 > T(reach_m_ * reach_m_))) {
      residual[0] = T(0.0);
      return true;
    }
    residual[0] = (sqrt(d2) - T(reach_m_)) * T(inv_sigma_);
    return true;
  }

  static ceres::CostFunction* Create(double reach_m, double sigma_m) {
    return new ceres::AutoDiffCostFunction<GapReachFactor, 1, 3, 3>(
        new GapReachFactor(reach_m, sigma_m));
  }

 private:
  double reach_m_, inv_sigma_;
};

}  // namespace walkgraph

#endif  // WALKGRAPH_FACTORS_GAP_REACH_FACTOR_H_
