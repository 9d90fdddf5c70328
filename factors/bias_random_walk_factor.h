// IMU bias factors of the foot-INS graph (gyro or accelerometer bias, one 3-vector each).
//
// BiasRandomWalkFactor — the bias is a random walk with density σ_w (per √s):
//   b_j = b_i + w,  w ~ N(0, σ_w² Δt I),   r = (b_j − b_i) / (σ_w √Δt).
// BiasPriorFactor — a turn-on bias prior (e.g. the data sheet's bias stability):
//   r = (b − b̄) / σ_b.
// Parameter blocks: b_i (3), b_j (3); or b (3).
#ifndef WALKGRAPH_FACTORS_BIAS_RANDOM_WALK_FACTOR_H_
#define WALKGRAPH_FACTORS_BIAS_RANDOM_WALK_FACTOR_H_

#include <cmath>

#include <ceres/autodiff_cost_function.h>
#include <Eigen/Core>

namespace walkgraph {

class BiasRandomWalkFactor {
 public:
  // sigma_per_sqrt_s · √dt must be > 0.
  BiasRandomWalkFactor(double sigma_per_sqrt_s, double dt_s)
      : inv_sigma_(1.0 / (sigma_per_sqrt_s * std::sqrt(dt_s))) {}

  template <typename T>
  bool operator()(const T* b_i, const T* b_j, T* residual) const {
    for (int k = 0; k < 3; ++k) residual[k] = (b_j[k] - b_i[k]) * inv_sigma_;
    return true;
  }

  static ceres::CostFunction* Create(double sigma_per_sqrt_s, double dt_s) {
    return new ceres::AutoDiffCostFunction<BiasRandomWalkFactor, 3, 3, 3>(
        new BiasRandomWalkFactor(sigma_per_sqrt_s, dt_s));
  }

 private:
  double inv_sigma_;
};

class BiasPriorFactor {
 public:
  BiasPriorFactor(const Eigen::Vector3d& mean, double sigma)
      : mean_(mean), inv_sigma_(1.0 / sigma) {}

  template <typename T>
  bool operator()(const T* b, T* residual) const {
    for (int k = 0; k < 3; ++k) residual[k] = (b[k] - T(mean_[k])) * inv_sigma_;
    return true;
  }

  static ceres::CostFunction* Create(const Eigen::Vector3d& mean, double sigma) {
    return new ceres::AutoDiffCostFunction<BiasPriorFactor, 3, 3>(new BiasPriorFactor(mean, sigma));
  }

 private:
  Eigen::Vector3d mean_;
  double inv_sigma_;
};

}  // namespace walkgraph

#endif  // WALKGRAPH_FACTORS_BIAS_RANDOM_WALK_FACTOR_H_
