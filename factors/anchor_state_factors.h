// Radio readings of an anchor whose horizontal position is a state (an unknown or uncertain
// anchor: walk.h Anchor), the same residuals as RssFactor and ScaledRangeFactor with the
// anchor's (a_x, a_y) a parameter block; its height a_z stays the walk's (anchors.csv z_m).
//
//   AnchorRssFactor:    r = (RSS − (A − s·10·η·log10(d/d0))) / σ    (000 eq. 1, 002 eq. 5)
//   AnchorRangeFactor:  r = (ρ − ((1 + k)·d + b)) / σ_ρ, k the scale (002 eq. 6: ρ = α + β·d)
//   d = ‖p − (a_x, a_y, a_z)‖, p the receiver (receiver_position.h: one state or interpolated)
// An anchor block needs a gauge: the walk's known start or surveyed anchors (fg-batch says which
// in its diagnostics), and a prior N(mean, sigma_m²) per axis for an uncertain anchor.
#ifndef WALKGRAPH_FACTORS_ANCHOR_STATE_FACTORS_H_
#define WALKGRAPH_FACTORS_ANCHOR_STATE_FACTORS_H_

#include <cmath>

#include <ceres/autodiff_cost_function.h>
#include <Eigen/Core>

#include "factors/receiver_position.h"
#include "factors/rss_factor.h"

namespace walkgraph {

// Blocks: p (kDim) [, p_b (kDim)], anchor (2), path loss (A, η) (2).
template <int kDim>
class AnchorRssFactor {
 public:
  using Reading = typename RssFactor<kDim>::Reading;  // anchor_m: its z (and x, y unused)

  AnchorRssFactor(const Reading& reading, double alpha) : reading_(reading) {
    receiver_.anchor_m = reading.anchor_m;
    receiver_.receiver_height_m = reading.receiver_height_m;
    receiver_.alpha = alpha;
  }

  template <typename T>
  bool operator()(const T* p, const T* anchor, const T* path_loss, T* residual) const {
    return Evaluate(p, static_cast<const T*>(nullptr), anchor, path_loss, residual);
  }
  template <typename T>
  bool operator()(const T* p_a, const T* p_b, const T* anchor, const T* path_loss,
                  T* residual) const {
    return Evaluate(p_a, p_b, anchor, path_loss, residual);
  }

  static ceres::CostFunction* Create(const Reading& reading) {
    return new ceres::AutoDiffCostFunction<AnchorRssFactor, 1, kDim, 2, 2>(
        new AnchorRssFactor(reading, 0.0));
  }
  // Received at (1 − α)·p_a + α·p_b.
  static ceres::CostFunction* CreateInterpolated(const Reading& reading, double alpha) {
    return new ceres::AutoDiffCostFunction<AnchorRssFactor, 1, kDim, kDim, 2, 2>(
        new AnchorRssFactor(reading, alpha));
  }

 private:
  template <typename T>
  bool Evaluate(const T* p_a, const T* p_b, const T* anchor, const T* path_loss,
                T* residual) const {
    residual[0] =
        RssFactor<kDim>::Whitened(reading_, receiver_.DistanceTo(p_a, p_b, anchor), path_loss);
    return true;
  }

  Reading reading_;
  factors_internal::Receiver<kDim> receiver_;
};

// Blocks: p (kDim) [, p_b (kDim)], anchor (2), bias b (1), scale s (1).
template <int kDim>
class AnchorRangeFactor {
 public:
  AnchorRangeFactor(double range_m, double anchor_z_m, double sigma_m, double receiver_height_m,
                    double alpha)
      : range_m_(range_m), inv_sigma_(1.0 / sigma_m) {
    receiver_.anchor_m = Eigen::Vector3d(0.0, 0.0, anchor_z_m);
    receiver_.receiver_height_m = receiver_height_m;
    receiver_.alpha = alpha;
  }

  template <typename T>
  bool operator()(const T* p, const T* anchor, const T* bias, const T* scale, T* residual) const {
    return Evaluate(p, static_cast<const T*>(nullptr), anchor, bias, scale, residual);
  }
  template <typename T>
  bool operator()(const T* p_a, const T* p_b, const T* anchor, const T* bias, const T* scale,
                  T* residual) const {
    return Evaluate(p_a, p_b, anchor, bias, scale, residual);
  }

  static ceres::CostFunction* Create(double range_m, double anchor_z_m, double sigma_m,
                                     double receiver_height_m = 0.0) {
    return new ceres::AutoDiffCostFunction<AnchorRangeFactor, 1, kDim, 2, 1, 1>(
        new AnchorRangeFactor(range_m, anchor_z_m, sigma_m, receiver_height_m, 0.0));
  }
  // Received at (1 − α)·p_a + α·p_b.
  static ceres::CostFunction* CreateInterpolated(double range_m, double anchor_z_m, double sigma_m,
                                                 double alpha, double receiver_height_m = 0.0) {
    return new ceres::AutoDiffCostFunction<AnchorRangeFactor, 1, kDim, kDim, 2, 1, 1>(
        new AnchorRangeFactor(range_m, anchor_z_m, sigma_m, receiver_height_m, alpha));
  }

 private:
  template <typename T>
  bool Evaluate(const T* p_a, const T* p_b, const T* anchor, const T* bias, const T* scale,
                T* residual) const {
    const T d = receiver_.DistanceTo(p_a, p_b, anchor) * (T(1.0) + scale[0]);
    residual[0] = (T(range_m_) - d - bias[0]) * T(inv_sigma_);
    return true;
  }

  double range_m_, inv_sigma_;
  factors_internal::Receiver<kDim> receiver_;
};

}  // namespace walkgraph

#endif  // WALKGRAPH_FACTORS_ANCHOR_STATE_FACTORS_H_
