// OdometryFactor: an odometry increment (Δdistance, Δheading) between two planar poses,
// the relative-pose (Pose2 "between") factor of wheel or step odometry (e.g. Plaza).
//
// Pose k = (p_k ∈ R², θ_k). The increment moves d along θ_{k−1}, then turns by Δθ:
//   r_xy = S_xy^{-1/2} (R(θ_{k−1})ᵀ (p_k − p_{k−1}) − (d, 0)ᵀ),   S_xy = diag(σ_d², σ_c²)
//   r_θ  = NormalizeAngle(θ_k − θ_{k−1} − Δθ) / σ_Δθ
#ifndef WALKGRAPH_FACTORS_ODOMETRY_FACTOR_H_
#define WALKGRAPH_FACTORS_ODOMETRY_FACTOR_H_

#include <cmath>

#include <ceres/autodiff_cost_function.h>

#include "walkgraph/angle.h"

namespace walkgraph {

class OdometryFactor {
 public:
  OdometryFactor(double dist_m, double dheading_rad, double sigma_dist_m, double sigma_cross_m,
                 double sigma_dheading_rad)
      : dist_m_(dist_m),
        dheading_rad_(dheading_rad),
        inv_sigma_d_(1.0 / sigma_dist_m),
        inv_sigma_c_(1.0 / sigma_cross_m),
        inv_sigma_h_(1.0 / sigma_dheading_rad) {}

  template <typename T>
  bool operator()(const T* p_prev, const T* theta_prev, const T* p, const T* theta,
                  T* residual) const {
    using std::cos;
    using std::sin;
    const T dx = p[0] - p_prev[0], dy = p[1] - p_prev[1];
    const T c = cos(theta_prev[0]), s = sin(theta_prev[0]);
    residual[0] = (c * dx + s * dy - T(dist_m_)) * T(inv_sigma_d_);
    residual[1] = (-s * dx + c * dy) * T(inv_sigma_c_);
    residual[2] = NormalizeAngle(theta[0] - theta_prev[0] - T(dheading_rad_)) * T(inv_sigma_h_);
    return true;
  }

  // Blocks: p_{k−1} (2), θ_{k−1} (1), p_k (2), θ_k (1).
  static ceres::CostFunction* Create(double dist_m, double dheading_rad, double sigma_dist_m,
                                     double sigma_cross_m, double sigma_dheading_rad) {
    return new ceres::AutoDiffCostFunction<OdometryFactor, 3, 2, 1, 2, 1>(
        new OdometryFactor(dist_m, dheading_rad, sigma_dist_m, sigma_cross_m, sigma_dheading_rad));
  }

 private:
  double dist_m_, dheading_rad_, inv_sigma_d_, inv_sigma_c_, inv_sigma_h_;
};

}  // namespace walkgraph

#endif  // WALKGRAPH_FACTORS_ODOMETRY_FACTOR_H_
