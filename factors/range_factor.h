// RangeFactor: a measured range (TOA, UWB, ranging radios) to an anchor, with an additive
// per-anchor bias as a parameter block.
//
//   r = (ρ − (‖p − a‖ + b)) / σ
// Ranging radios read long: multipath and NLOS delay the first path, so ρ − d has a positive
// median (Plaza1: +2.8 m, σ ≈ 1.2 m; 002 eq. 6 models TOA as α + β·d + noise). Estimate b per
// anchor (free block with a weak prior) or hold it constant (0 for unbiased ranges). Give the
// factor a robust loss against multipath outliers.
#ifndef WALKGRAPH_FACTORS_RANGE_FACTOR_H_
#define WALKGRAPH_FACTORS_RANGE_FACTOR_H_

#include <ceres/autodiff_cost_function.h>
#include <Eigen/Core>

#include "factors/receiver_position.h"

namespace walkgraph {

template <int kDim>
class RangeFactor {
 public:
  RangeFactor(double range_m, const Eigen::Vector3d& anchor_m, double sigma_m,
              double receiver_height_m, double alpha)
      : range_m_(range_m), inv_sigma_(1.0 / sigma_m) {
    receiver_.anchor_m = anchor_m;
    receiver_.receiver_height_m = receiver_height_m;
    receiver_.alpha = alpha;
  }

  template <typename T>
  bool operator()(const T* p, const T* bias, T* residual) const {
    residual[0] = (T(range_m_) - receiver_.Distance(p, static_cast<const T*>(nullptr)) - bias[0]) *
                  T(inv_sigma_);
    return true;
  }
  template <typename T>
  bool operator()(const T* p_a, const T* p_b, const T* bias, T* residual) const {
    residual[0] = (T(range_m_) - receiver_.Distance(p_a, p_b) - bias[0]) * T(inv_sigma_);
    return true;
  }

  // Blocks: p (kDim), b (1).
  static ceres::CostFunction* Create(double range_m, const Eigen::Vector3d& anchor_m,
                                     double sigma_m, double receiver_height_m = 0.0) {
    return new ceres::AutoDiffCostFunction<RangeFactor, 1, kDim, 1>(
        new RangeFactor(range_m, anchor_m, sigma_m, receiver_height_m, 0.0));
  }
  // Blocks: p_a (kDim), p_b (kDim), b (1); received at (1 − α)·p_a + α·p_b.
  static ceres::CostFunction* CreateInterpolated(double range_m, const Eigen::Vector3d& anchor_m,
                                                 double sigma_m, double alpha,
                                                 double receiver_height_m = 0.0) {
    return new ceres::AutoDiffCostFunction<RangeFactor, 1, kDim, kDim, 1>(
        new RangeFactor(range_m, anchor_m, sigma_m, receiver_height_m, alpha));
  }

 private:
  double range_m_, inv_sigma_;
  factors_internal::Receiver<kDim> receiver_;
};

}  // namespace walkgraph

#endif  // WALKGRAPH_FACTORS_RANGE_FACTOR_H_
