// HeadingFactor: an absolute heading measurement (magnetometer / compass, or a known start).
//
//   r = NormalizeAngle(θ − θ_meas) / σ
// Indoor magnetic disturbances make compass headings heavy-tailed: give this factor a robust
// loss (the smoothers default to Cauchy for it).
#ifndef WALKGRAPH_FACTORS_HEADING_FACTOR_H_
#define WALKGRAPH_FACTORS_HEADING_FACTOR_H_

#include <ceres/autodiff_cost_function.h>

#include "walkgraph/angle.h"

namespace walkgraph {

class HeadingFactor {
 public:
  HeadingFactor(double heading_rad, double sigma_rad)
      : heading_rad_(heading_rad), inv_sigma_(1.0 / sigma_rad) {}

  template <typename T>
  bool operator()(const T* theta, T* residual) const {
    residual[0] = NormalizeAngle(theta[0] - T(heading_rad_)) * T(inv_sigma_);
    return true;
  }

  // Block: θ (1).
  static ceres::CostFunction* Create(double heading_rad, double sigma_rad) {
    return new ceres::AutoDiffCostFunction<HeadingFactor, 1, 1>(
        new HeadingFactor(heading_rad, sigma_rad));
  }

 private:
  double heading_rad_, inv_sigma_;
};

}  // namespace walkgraph

#endif  // WALKGRAPH_FACTORS_HEADING_FACTOR_H_
