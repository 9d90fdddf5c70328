// Gauge prior of the foot-INS graph: a known start position and heading.
//
// IMU-only, a ZUPT-aided INS observes roll, pitch, velocity and the biases (through gravity and
// the stance constraints), but not the position (3) nor the yaw (1) — a 4-dimensional gauge.
// This factor fixes it on the first state:
//   r = [ (p − p̄) ⊘ σ_p ;  NormalizeAngle(ψ(q) − ψ̄) / σ_ψ ],
// ψ(q) = atan2(R₁₀, R₀₀) the ENU angle of the body x axis on the horizontal (QuaternionYaw).
// With a known start (walk.yaml initial_pose) p̄, ψ̄ and σ are its values; without one they are
// an arbitrary origin (0, yaw of the initial attitude) with small σ, which only picks the frame.
// Roll and pitch get no prior: gravity observes them. Parameter blocks: p (3), q (4).
#ifndef WALKGRAPH_FACTORS_INS_PRIOR_FACTOR_H_
#define WALKGRAPH_FACTORS_INS_PRIOR_FACTOR_H_

#include <ceres/autodiff_cost_function.h>
#include <Eigen/Core>
#include <Eigen/Geometry>

#include "factors/nav_quaternion_manifold.h"
#include "walkgraph/angle.h"

namespace walkgraph {

class InsPriorFactor {
 public:
  InsPriorFactor(const Eigen::Vector3d& position_m, const Eigen::Vector3d& sigma_position_m,
                 double yaw_rad, double sigma_yaw_rad)
      : p_(position_m),
        inv_sigma_p_(sigma_position_m.cwiseInverse()),
        yaw_(yaw_rad),
        inv_sigma_yaw_(1.0 / sigma_yaw_rad) {}

  template <typename T>
  bool operator()(const T* p, const T* q, T* residual) const {
    for (int k = 0; k < 3; ++k) residual[k] = (p[k] - T(p_[k])) * inv_sigma_p_[k];
    Eigen::Map<const Eigen::Quaternion<T>> qm(q);
    residual[3] =
        NormalizeAngle(QuaternionYaw(Eigen::Quaternion<T>(qm)) - T(yaw_)) * inv_sigma_yaw_;
    return true;
  }

  static ceres::CostFunction* Create(const Eigen::Vector3d& position_m,
                                     const Eigen::Vector3d& sigma_position_m, double yaw_rad,
                                     double sigma_yaw_rad) {
    return new ceres::AutoDiffCostFunction<InsPriorFactor, 4, 3, 4>(
        new InsPriorFactor(position_m, sigma_position_m, yaw_rad, sigma_yaw_rad));
  }

 private:
  Eigen::Vector3d p_, inv_sigma_p_;
  double yaw_, inv_sigma_yaw_;
};

}  // namespace walkgraph

#endif  // WALKGRAPH_FACTORS_INS_PRIOR_FACTOR_H_
