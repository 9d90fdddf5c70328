// RssFactor: one RSS reading in the dB domain, with the path loss as a parameter block.
//
//   r = (RSS − (A − s·10·η·log10(d/d0))) / σ,   d = ‖p − a‖   (000 eq. 1, 001 eq. 13,
//                                                               002 eq. 5, 004 eq. 4)
// s = +1 in dBm, −1 in RFCode units (004: larger is weaker). Under the papers' own model the
// shadowing is Gaussian in dB, so this residual is exactly Gaussian — unlike the range-domain
// residual (RssRangeFactor), whose noise is log-normal and biased (001 eq. 15–17).
// The path-loss block is (A, η). Keep it constant for a known model; free (one block for the
// walk, or one per anchor, with a weak prior) for path-loss self-calibration.
// Position blocks: one state, or two with interpolation (receiver_position.h).
#ifndef WALKGRAPH_FACTORS_RSS_FACTOR_H_
#define WALKGRAPH_FACTORS_RSS_FACTOR_H_

#include <cmath>

#include <ceres/autodiff_cost_function.h>
#include <Eigen/Core>

#include "factors/receiver_position.h"

namespace walkgraph {

template <int kDim>
class RssFactor {
 public:
  struct Reading {
    double rss = 0.0;
    Eigen::Vector3d anchor_m = Eigen::Vector3d::Zero();
    double sigma_db = 5.0;
    double sign = 1.0;  // +1 dBm, −1 RFCode
    double d0_m = 1.0;
    double receiver_height_m = 0.0;  // kDim == 2 only
  };

  RssFactor(const Reading& reading, double alpha) : reading_(reading) {
    receiver_.anchor_m = reading.anchor_m;
    receiver_.receiver_height_m = reading.receiver_height_m;
    receiver_.alpha = alpha;
  }

  template <typename T>
  bool operator()(const T* p, const T* path_loss, T* residual) const {
    return Evaluate(p, static_cast<const T*>(nullptr), path_loss, residual);
  }
  template <typename T>
  bool operator()(const T* p_a, const T* p_b, const T* path_loss, T* residual) const {
    return Evaluate(p_a, p_b, path_loss, residual);
  }

  // Blocks: p (kDim), (A, η) (2).
  static ceres::CostFunction* Create(const Reading& reading) {
    return new ceres::AutoDiffCostFunction<RssFactor, 1, kDim, 2>(new RssFactor(reading, 0.0));
  }
  // Blocks: p_a (kDim), p_b (kDim), (A, η) (2); received at (1 − α)·p_a + α·p_b.
  static ceres::CostFunction* CreateInterpolated(const Reading& reading, double alpha) {
    return new ceres::AutoDiffCostFunction<RssFactor, 1, kDim, kDim, 2>(
        new RssFactor(reading, alpha));
  }

  // r of the top of this file for `reading` at distance d, path loss (A, η) = path_loss (the
  // one place the model is written; AnchorRssFactor uses it too).
  template <typename T>
  static T Whitened(const Reading& reading, const T& d, const T* path_loss) {
    using std::log10;
    const T expected =
        path_loss[0] - T(reading.sign * 10.0) * path_loss[1] * log10(d / T(reading.d0_m));
    return (T(reading.rss) - expected) / T(reading.sigma_db);
  }

 private:
  template <typename T>
  bool Evaluate(const T* p_a, const T* p_b, const T* path_loss, T* residual) const {
    residual[0] = Whitened(reading_, receiver_.Distance(p_a, p_b), path_loss);
    return true;
  }

  Reading reading_;
  factors_internal::Receiver<kDim> receiver_;
};

}  // namespace walkgraph

#endif  // WALKGRAPH_FACTORS_RSS_FACTOR_H_
