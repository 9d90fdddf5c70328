// The log-distance path-loss model and the ranges it implies.
//
//   RSS(d) = A − s·10·η·log10(d/d0) + N(0, σ²)       (000 eq. 1, 001 eq. 13, 002 eq. 5, 004 eq. 4)
// with s = +1 for dBm and s = −1 for RFCode units (004: larger is weaker).
//   ML range   d̂ = d0·10^(s·(A − RSS)/(10η))          (001 eq. 14, 004 eq. 5)
// d̂ is log-normal: ln d̂ = ln d + N(0, σ_d²), σ_d = σ·ln10/(10η), so E[d̂] = d·e^{σ_d²/2}
// (001 eq. 15–17). The bias-corrected range divides by e^{σ_d²/2}.
//   Range sigma  σ_r = σ·ln10·d/(10η)                  (004 eq. 7, first-order)
#ifndef WALKGRAPH_PATH_LOSS_H_
#define WALKGRAPH_PATH_LOSS_H_

#include <cmath>

#include "walkgraph/walk.h"

namespace walkgraph {

class PathLossModel {
 public:
  PathLossModel() = default;
  PathLossModel(PathLossParams params, RssUnits units) : p_(params), units_(units) {}

  const PathLossParams& params() const { return p_; }
  RssUnits units() const { return units_; }
  // +1 for dBm (RSS falls with distance), −1 for RFCode units (RSS grows with distance).
  double sign() const { return units_ == RssUnits::kDbm ? 1.0 : -1.0; }

  // Mean RSS at distance d (d clamped to ≥ 1 mm).
  double ExpectedRss(double distance_m) const {
    const double d = std::max(distance_m, 1e-3);
    return p_.A_dbm - sign() * 10.0 * p_.eta * std::log10(d / p_.d0_m);
  }
  // Maximum-likelihood range from one RSS reading (001 eq. 14, 004 eq. 5).
  double MlRange(double rss) const {
    return p_.d0_m * std::pow(10.0, sign() * (p_.A_dbm - rss) / (10.0 * p_.eta));
  }
  // σ of ln d̂: σ_d = σ·ln10/(10η) (001 eq. 16).
  double LogRangeSigma() const { return p_.sigma_db * std::log(10.0) / (10.0 * p_.eta); }
  // Median-unbiased → mean-unbiased: d̂ / e^{σ_d²/2} (001 eq. 17).
  double BiasCorrectedRange(double rss) const {
    const double s = LogRangeSigma();
    return MlRange(rss) / std::exp(0.5 * s * s);
  }
  // First-order range standard deviation at distance d (004 eq. 7).
  double RangeSigma(double distance_m) const { return LogRangeSigma() * distance_m; }

 private:
  PathLossParams p_;
  RssUnits units_ = RssUnits::kDbm;
};

}  // namespace walkgraph

#endif  // WALKGRAPH_PATH_LOSS_H_
