// PositionRandomWalkFactor: the motion model of a walk without steps (radio only): the
// position diffuses as a Brownian motion between two states Δt apart,
//   p_k − p_{k−1} ~ N(0, q·Δt·I),   r = (p_k − p_{k−1}) / √(q·Δt),
// with q = σ_v² (m²/s) the diffusion rate; σ_v ≈ walking speed keeps a pedestrian's typical
// displacement within one σ over a second.
#ifndef WALKGRAPH_FACTORS_POSITION_RANDOM_WALK_FACTOR_H_
#define WALKGRAPH_FACTORS_POSITION_RANDOM_WALK_FACTOR_H_

#include <cmath>

#include <ceres/autodiff_cost_function.h>

namespace walkgraph {

class PositionRandomWalkFactor {
 public:
  PositionRandomWalkFactor(double dt_s, double sigma_mps)
      : inv_sigma_(1.0 / (sigma_mps * std::sqrt(dt_s))) {}

  template <typename T>
  bool operator()(const T* p_prev, const T* p, T* residual) const {
    residual[0] = (p[0] - p_prev[0]) * T(inv_sigma_);
    residual[1] = (p[1] - p_prev[1]) * T(inv_sigma_);
    return true;
  }

  // Blocks: p_{k−1} (2), p_k (2). dt_s > 0, sigma_mps > 0.
  static ceres::CostFunction* Create(double dt_s, double sigma_mps) {
    return new ceres::AutoDiffCostFunction<PositionRandomWalkFactor, 2, 2, 2>(
        new PositionRandomWalkFactor(dt_s, sigma_mps));
  }

 private:
  double inv_sigma_;
};

}  // namespace walkgraph

#endif  // WALKGRAPH_FACTORS_POSITION_RANDOM_WALK_FACTOR_H_
