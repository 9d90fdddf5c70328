// PositionPriorFactor: a known 2-D position z at time t with an isotropic σ (a waypoint, a
// surveyed landmark), on the estimate at t — one node, or linearly interpolated between the
// two nodes a, b around t (α = (t − t_a)/(t_b − t_a), as the interpolated radio factors do):
//   r = ((1 − α) p_a + α p_b − z) / σ            (one node: α = 0, r = (p_a − z)/σ)
// ∂r/∂p_a = (1 − α)/σ · I₂,  ∂r/∂p_b = α/σ · I₂. The residual is linear in the positions, so
// its Gauss–Newton step is exact; autodiff keeps the Jacobians and the residual in one place.
// kDim = 2 (the step graph's p = (x, y)) or 3 (the foot INS's p = (x, y, z); z is left free).
#ifndef WALKGRAPH_FACTORS_POSITION_PRIOR_FACTOR_H_
#define WALKGRAPH_FACTORS_POSITION_PRIOR_FACTOR_H_

#include <ceres/autodiff_cost_function.h>
#include <Eigen/Core>

namespace walkgraph {

template <int kDim>
class PositionPriorFactor {
 public:
  PositionPriorFactor(const Eigen::Vector2d& position_m, double sigma_m, double alpha)
      : z_(position_m), inv_sigma_(1.0 / sigma_m), alpha_(alpha) {}

  // One node: block p (kDim).
  template <typename T>
  bool operator()(const T* p, T* residual) const {
    residual[0] = (p[0] - T(z_.x())) * T(inv_sigma_);
    residual[1] = (p[1] - T(z_.y())) * T(inv_sigma_);
    return true;
  }

  // Two nodes: blocks p_a, p_b (kDim each).
  template <typename T>
  bool operator()(const T* pa, const T* pb, T* residual) const {
    const T a(alpha_), one_minus_a(1.0 - alpha_);
    residual[0] = (one_minus_a * pa[0] + a * pb[0] - T(z_.x())) * T(inv_sigma_);
    residual[1] = (one_minus_a * pa[1] + a * pb[1] - T(z_.y())) * T(inv_sigma_);
    return true;
  }

  static ceres::CostFunction* Create(const Eigen::Vector2d& position_m, double sigma_m) {
    return new ceres::AutoDiffCostFunction<PositionPriorFactor, 2, kDim>(
        new PositionPriorFactor(position_m, sigma_m, 0.0));
  }

  // alpha ∈ [0, 1]: the weight of p_b.
  static ceres::CostFunction* CreateInterpolated(const Eigen::Vector2d& position_m, double sigma_m,
                                                 double alpha) {
    return new ceres::AutoDiffCostFunction<PositionPriorFactor, 2, kDim, kDim>(
        new PositionPriorFactor(position_m, sigma_m, alpha));
  }

 private:
  Eigen::Vector2d z_;
  double inv_sigma_, alpha_;
};

}  // namespace walkgraph

#endif  // WALKGRAPH_FACTORS_POSITION_PRIOR_FACTOR_H_
