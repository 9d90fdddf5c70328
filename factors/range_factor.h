// RangeFactor: a measured range (TOA, UWB, ranging radios) to an anchor, with an additive
// per-anchor bias as a parameter block.
//
//   r = (ρ − (‖p − a‖ + b)) / σ
// Ranging radios read long: multipath and NLOS delay the first path, so ρ − d has a positive
// median (Plaza1: +2.8 m, σ ≈ 1.2 m; 002 eq. 6 models TOA as α + β·d + noise). Estimate b per
// anchor (free block with a weak prior) or hold it constant (0 for unbiased ranges). Give the
// factor a robust loss against multipath outliers.
//
// ScaledRangeFactor adds a scale block s: ρ = (1 + s)·‖p − a‖ + b, the TOA model of 002 eq. 6
// (α + β·d with α = b, β = 1 + s). Plaza1's ranging radios read (1.07·d + 0.9 m): a bias alone
// leaves a distance-dependent error.
#ifndef WALKGRAPH_FACTORS_RANGE_FACTOR_H_
#define WALKGRAPH_FACTORS_RANGE_FACTOR_H_

#include <type_traits>

#include <ceres/autodiff_cost_function.h>
#include <Eigen/Core>

#include "factors/receiver_position.h"

namespace walkgraph {

// kScaled = false: blocks p [, p_b], b; true: p [, p_b], b, s (see the top of this file).
template <int kDim, bool kScaled>
class RangeFactorT {
 public:
  RangeFactorT(double range_m, const Eigen::Vector3d& anchor_m, double sigma_m,
               double receiver_height_m, double alpha)
      : range_m_(range_m), inv_sigma_(1.0 / sigma_m) {
    receiver_.anchor_m = anchor_m;
    receiver_.receiver_height_m = receiver_height_m;
    receiver_.alpha = alpha;
  }

  template <typename T, bool S = kScaled, std::enable_if_t<!S, int> = 0>
  bool operator()(const T* p, const T* bias, T* residual) const {
    return Residual(p, static_cast<const T*>(nullptr), bias, static_cast<const T*>(nullptr),
                    residual);
  }
  template <typename T, bool S = kScaled, std::enable_if_t<!S, int> = 0>
  bool operator()(const T* p_a, const T* p_b, const T* bias, T* residual) const {
    return Residual(p_a, p_b, bias, static_cast<const T*>(nullptr), residual);
  }
  template <typename T, bool S = kScaled, std::enable_if_t<S, int> = 0>
  bool operator()(const T* p, const T* bias, const T* scale, T* residual) const {
    return Residual(p, static_cast<const T*>(nullptr), bias, scale, residual);
  }
  template <typename T, bool S = kScaled, std::enable_if_t<S, int> = 0>
  bool operator()(const T* p_a, const T* p_b, const T* bias, const T* scale, T* residual) const {
    return Residual(p_a, p_b, bias, scale, residual);
  }

  // Blocks: p (kDim), b (1) [, s (1)].
  static ceres::CostFunction* Create(double range_m, const Eigen::Vector3d& anchor_m,
                                     double sigma_m, double receiver_height_m = 0.0) {
    auto* f = new RangeFactorT(range_m, anchor_m, sigma_m, receiver_height_m, 0.0);
    if constexpr (kScaled) {
      return new ceres::AutoDiffCostFunction<RangeFactorT, 1, kDim, 1, 1>(f);
    } else {
      return new ceres::AutoDiffCostFunction<RangeFactorT, 1, kDim, 1>(f);
    }
  }
  // Blocks: p_a (kDim), p_b (kDim), b (1) [, s (1)]; received at (1 − α)·p_a + α·p_b.
  static ceres::CostFunction* CreateInterpolated(double range_m, const Eigen::Vector3d& anchor_m,
                                                 double sigma_m, double alpha,
                                                 double receiver_height_m = 0.0) {
    auto* f = new RangeFactorT(range_m, anchor_m, sigma_m, receiver_height_m, alpha);
    if constexpr (kScaled) {
      return new ceres::AutoDiffCostFunction<RangeFactorT, 1, kDim, kDim, 1, 1>(f);
    } else {
      return new ceres::AutoDiffCostFunction<RangeFactorT, 1, kDim, kDim, 1>(f);
    }
  }

 private:
  template <typename T>
  bool Residual(const T* p_a, const T* p_b, const T* bias, const T* scale, T* residual) const {
    T d = receiver_.Distance(p_a, p_b);
    if (scale != nullptr) d *= T(1.0) + scale[0];
    residual[0] = (T(range_m_) - d - bias[0]) * T(inv_sigma_);
    return true;
  }

  double range_m_, inv_sigma_;
  factors_internal::Receiver<kDim> receiver_;
};

template <int kDim>
using RangeFactor = RangeFactorT<kDim, false>;
template <int kDim>
using ScaledRangeFactor = RangeFactorT<kDim, true>;

}  // namespace walkgraph

#endif  // WALKGRAPH_FACTORS_RANGE_FACTOR_H_
