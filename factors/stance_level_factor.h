// Levelling at a stance as a factor: while the foot stands, the accelerometer reads gravity
// alone, so the mean specific force over the stance's ZUPT samples fixes the state's roll and
// pitch (with the accelerometer bias) — the information a ZUPT-aided EKF draws from its
// sample-by-sample ZUPTs through a stance (the velocity that a tilt error makes grow, g·δθ·t),
// and which one ZUPT per stance state does not carry.
//
//   r = (R(q)ᵀ·(0, 0, g) − (f̄ − b_a)) / σ,
//
// R(q) the body-to-navigation (ENU) rotation of the state, f̄ the mean accelerometer reading
// (m/s², body frame) over the stance samples the factor stands for, σ per axis the σ of that
// mean. The foot does not rotate while it stands, so every sample of the run shares the
// state's attitude. Parameter blocks: q (4; x, y, z, w on NavQuaternionManifold), b_a (3).
#ifndef WALKGRAPH_FACTORS_STANCE_LEVEL_FACTOR_H_
#define WALKGRAPH_FACTORS_STANCE_LEVEL_FACTOR_H_

#include <ceres/autodiff_cost_function.h>
#include <Eigen/Core>
#include <Eigen/Geometry>

namespace walkgraph {

class StanceLevelFactor {
 public:
  StanceLevelFactor(const Eigen::Vector3d& mean_acc_mps2, double gravity_mps2, double sigma_mps2)
      : f_(mean_acc_mps2), g_(gravity_mps2), inv_sigma_(1.0 / sigma_mps2) {}

  template <typename T>
  bool operator()(const T* q, const T* ba, T* residual) const {
    const Eigen::Map<const Eigen::Quaternion<T>> q_nb(q);
    const Eigen::Matrix<T, 3, 1> up(T(0), T(0), T(g_));
    const Eigen::Matrix<T, 3, 1> predicted = q_nb.conjugate() * up;
    for (int i = 0; i < 3; ++i) {
      residual[i] = (predicted[i] - (T(f_[i]) - ba[i])) * inv_sigma_;
    }
    return true;
  }

  static ceres::CostFunction* Create(const Eigen::Vector3d& mean_acc_mps2, double gravity_mps2,
                                     double sigma_mps2) {
    return new ceres::AutoDiffCostFunction<StanceLevelFactor, 3, 4, 3>(
        new StanceLevelFactor(mean_acc_mps2, gravity_mps2, sigma_mps2));
  }

 private:
  Eigen::Vector3d f_;
  double g_;
  double inv_sigma_;
};

}  // namespace walkgraph

#endif  // WALKGRAPH_FACTORS_STANCE_LEVEL_FACTOR_H_
