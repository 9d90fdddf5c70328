// RssRangeFactor: one RSS reading turned into a range first, the range-domain residual the
// range-based filters use (004), so that it can be compared with RssFactor's dB domain.
//
//   d̂ = d0·10^(s·(A − RSS)/(10η))          (001 eq. 14, 004 eq. 5; optionally / e^{σ_d²/2},
//                                            001 eq. 17)
//   σ_d = σ·ln10·d̂/(10η)                    (004 eq. 7, first order, at the measured range)
//   r = (d̂ − ‖p − a‖) / σ_d
// The path loss is fixed (a range-domain residual cannot calibrate it consistently).
#ifndef WALKGRAPH_FACTORS_RSS_RANGE_FACTOR_H_
#define WALKGRAPH_FACTORS_RSS_RANGE_FACTOR_H_

#include <algorithm>
#include <cmath>

#include <ceres/autodiff_cost_function.h>
#include <Eigen/Core>

#include "factors/receiver_position.h"

namespace walkgraph {

template <int kDim>
class RssRangeFactor {
 public:
  struct Reading {
    double rss = 0.0;
    Eigen::Vector3d anchor_m = Eigen::Vector3d::Zero();
    double A = -60.0, eta = 2.5, d0_m = 1.0, sigma_db = 5.0;
    double sign = 1.0;  // +1 dBm, −1 RFCode
    bool bias_corrected = false;
    double min_sigma_m = 0.1;  // floor on σ_d (eq. 7 vanishes at d → 0)
    double receiver_height_m = 0.0;
  };

  RssRangeFactor(const Reading& r, double alpha) {
    const double sigma_log = r.sigma_db * std::log(10.0) / (10.0 * r.eta);
    range_m_ = r.d0_m * std::pow(10.0, r.sign * (r.A - r.rss) / (10.0 * r.eta));
    if (r.bias_corrected) range_m_ /= std::exp(0.5 * sigma_log * sigma_log);
    inv_sigma_ = 1.0 / std::max(sigma_log * range_m_, r.min_sigma_m);
    receiver_.anchor_m = r.anchor_m;
    receiver_.receiver_height_m = r.receiver_height_m;
    receiver_.alpha = alpha;
  }

  template <typename T>
  bool operator()(const T* p, T* residual) const {
    residual[0] =
        (T(range_m_) - receiver_.Distance(p, static_cast<const T*>(nullptr))) * T(inv_sigma_);
    return true;
  }
  template <typename T>
  bool operator()(const T* p_a, const T* p_b, T* residual) const {
    residual[0] = (T(range_m_) - receiver_.Distance(p_a, p_b)) * T(inv_sigma_);
    return true;
  }

  double range_m() const { return range_m_; }

  // Blocks: p (kDim).
  static ceres::CostFunction* Create(const Reading& reading) {
    return new ceres::AutoDiffCostFunction<RssRangeFactor, 1, kDim>(
        new RssRangeFactor(reading, 0.0));
  }
  // Blocks: p_a (kDim), p_b (kDim).
  static ceres::CostFunction* CreateInterpolated(const Reading& reading, double alpha) {
    return new ceres::AutoDiffCostFunction<RssRangeFactor, 1, kDim, kDim>(
        new RssRangeFactor(reading, alpha));
  }

 private:
  double range_m_ = 0.0, inv_sigma_ = 1.0;
  factors_internal::Receiver<kDim> receiver_;
};

}  // namespace walkgraph

#endif  // WALKGRAPH_FACTORS_RSS_RANGE_FACTOR_H_
