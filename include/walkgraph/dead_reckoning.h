// Dead reckoning from odometry increments (estimator id "odometry-dr").
//
// Each increment (d, Δθ) moves d along the current heading, then turns by Δθ:
//   x_k = x_{k-1} + d·cos θ_{k-1},  y_k = y_{k-1} + d·sin θ_{k-1},  θ_k = θ_{k-1} + Δθ,
// the convention of GTSAM's Pose2 odometry (Plaza data). The covariance of (x, y, θ) is
// propagated with P ← F P Fᵀ + G Q Gᵀ, σ_d = sigma_dist_frac·d + sigma_dist_m, σ_Δθ per step.
#ifndef WALKGRAPH_DEAD_RECKONING_H_
#define WALKGRAPH_DEAD_RECKONING_H_

#include "walkgraph/estimator.h"

namespace walkgraph {

struct OdometryDeadReckoningOptions {
  double sigma_dist_frac = 0.05;    // proportional distance noise
  double sigma_dist_m = 0.001;      // constant distance noise per increment
  double sigma_dheading_rad = 0.01; // heading-increment noise per increment

  // Every rule its YAML reader applies; Run refuses options that break one.
  Status Validate() const;
};

class OdometryDeadReckoning : public Estimator {
 public:
  explicit OdometryDeadReckoning(OdometryDeadReckoningOptions options) : options_(options) {}
  Status CheckApplicable(const Walk& walk) const override;
  StatusOr<EstimateResult> Run(const Walk& walk) const override;

 private:
  OdometryDeadReckoningOptions options_;
};

}  // namespace walkgraph

#endif  // WALKGRAPH_DEAD_RECKONING_H_
