// ZUPT/ZARU-aided strapdown INS dead reckoning for a foot-mounted IMU (estimator id
// "zupt-ins"): the nominal trajectory of the stride front end's error-state EKF (strides.h),
// the baseline the foot-INS graph is measured against.
//
// Output: a pose every 1/output_rate_hz (and at every stride end) with the foot's position and
// yaw. Covariance of (x, y, ψ): the front end resets the filter's position/yaw covariance at
// every stride, so the absolute one is composed stride by stride,
//   P_k = F P_b Fᵀ + C(t_k),   F = [1 0 −d_y; 0 1 d_x; 0 0 1],
// with b the last stride end, d the horizontal displacement since b and C the filter's
// covariance of (δp_x, δp_y, δψ) since the reset; P_0 from initial_pose (σ_xy, σ_ψ) or, without
// one, gauge_sigma_m / gauge_sigma_yaw_rad around the arbitrary origin.
#ifndef WALKGRAPH_ZUPT_INS_H_
#define WALKGRAPH_ZUPT_INS_H_

#include "walkgraph/estimator.h"
#include "walkgraph/strides.h"

namespace walkgraph {

struct ZuptInsOptions {
  StrideOptions front_end = StrideOptions().Causal();  // a filter: the causal detector
  double output_rate_hz = 20.0;
  double gauge_sigma_m = 1e-3;
  double gauge_sigma_yaw_rad = 1e-3;

  // Every rule its YAML reader applies (and front_end's); Run refuses options that break one.
  Status Validate() const;
};

class ZuptInsDeadReckoning : public Estimator {
 public:
  explicit ZuptInsDeadReckoning(ZuptInsOptions options) : options_(std::move(options)) {}
  Status CheckApplicable(const Walk& walk) const override;
  StatusOr<EstimateResult> Run(const Walk& walk) const override;

 private:
  ZuptInsOptions options_;
};

}  // namespace walkgraph

#endif  // WALKGRAPH_ZUPT_INS_H_
