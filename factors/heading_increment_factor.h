// HeadingIncrementFactor: the gyro-integrated heading change between two step poses.
//
//   r = NormalizeAngle(θ_k − θ_{k−1} − Δθ) / σ_Δθ
// Δθ is Step::dheading_rad (000 eq. 4: θ_i = θ_{i−1} + δT·ω_z summed over the step).
#ifndef WALKGRAPH_FACTORS_HEADING_INCREMENT_FACTOR_H_
#define WALKGRAPH_FACTORS_HEADING_INCREMENT_FACTOR_H_

#include <ceres/autodiff_cost_function.h>

#include "walkgraph/angle.h"

namespace walkgraph {

class HeadingIncrementFactor {
 public:
  HeadingIncrementFactor(double dheading_rad, double sigma_rad)
      : dheading_rad_(dheading_rad), inv_sigma_(1.0 / sigma_rad) {}

  template <typename T>
  bool operator()(const T* theta_prev, const T* theta, T* residual) const {
    residual[0] = NormalizeAngle(theta[0] - theta_prev[0] - T(dheading_rad_)) * T(inv_sigma_);
    return true;
  }

  // Blocks: θ_{k−1} (1), θ_k (1).
  static ceres::CostFunction* Create(double dheading_rad, double sigma_rad) {
    return new ceres::AutoDiffCostFunction<HeadingIncrementFactor, 1, 1, 1>(
        new HeadingIncrementFactor(dheading_rad, sigma_rad));
  }

 private:
  double dheading_rad_, inv_sigma_;
};

}  // namespace walkgraph

#endif  // WALKGRAPH_FACTORS_HEADING_INCREMENT_FACTOR_H_
