// Zero angular-rate update as a factor: when the whole foot is still it does not rotate, so the
// gyro reads its bias (004: ZARU "when the user is motionless").
//
//   r = (ω̄ − b_g) / σ_ω,
//
// ω̄ the mean gyro reading (rad/s, body frame) over the still samples the factor stands for,
// σ_ω the σ of that mean (per-reading σ/√m for m readings). Parameter block: b_g (3).
#ifndef WALKGRAPH_FACTORS_ZARU_FACTOR_H_
#define WALKGRAPH_FACTORS_ZARU_FACTOR_H_

#include <ceres/autodiff_cost_function.h>
#include <Eigen/Core>

namespace walkgraph {

class ZaruFactor {
 public:
  ZaruFactor(const Eigen::Vector3d& mean_gyro_radps, double sigma_radps)
      : omega_(mean_gyro_radps), inv_sigma_(1.0 / sigma_radps) {}

  template <typename T>
  bool operator()(const T* bg, T* residual) const {
    for (int i = 0; i < 3; ++i) residual[i] = (T(omega_[i]) - bg[i]) * inv_sigma_;
    return true;
  }

  static ceres::CostFunction* Create(const Eigen::Vector3d& mean_gyro_radps, double sigma_radps) {
    return new ceres::AutoDiffCostFunction<ZaruFactor, 3, 3>(
        new ZaruFactor(mean_gyro_radps, sigma_radps));
  }

 private:
  Eigen::Vector3d omega_;
  double inv_sigma_;
};

}  // namespace walkgraph

#endif  // WALKGRAPH_FACTORS_ZARU_FACTOR_H_
