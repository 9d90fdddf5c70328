// Gädeke, Schmid, Stork, Müller-Glaser — PDR complementing WSN localization (paper 003,
// Sec. 3.2): a Kalman filter over x = [p v] (2-D position and velocity) with the PDR
// displacement as control input and RSS ranges fused by an EKF update.
//   x_k⁻ = A x_{k−1} + B u_k + w_k                                            (eq. 6)
//   A = [I  Δt·I; 0  f·I],  B = [I; 0],  u_k = PDR displacement of the steps in (t_{k−1}, t_k]
// f = velocity prediction factor 0.99 per 10 Hz processing epoch (f^(10·Δt) for other Δt), so
// the velocity decays when no sensor reading arrives. The paper keeps v in the state also with
// PDR ("position and velocity"); we read v as the motion the PDR does not explain (it is 0
// without RSS evidence) — the most plausible reading of eq. 6 with both terms; pdr_input=false
// gives the paper's constant-velocity model for localization without an IMU.
//   Q = diag((σ_pdr·|u_k|)² + q_p·Δt, q_v·Δt)  (σ_pdr = 5 % of distance: the paper's PDR error)
// Range update (EKF, log-distance model of Schmid et al. via PathLossModel):
//   z = d̂,  h(x) = ‖(p, h_tag) − a‖,  H = [(p − a_xy)ᵀ/h  0],  R = σ_r²  (004 eq. 7 σ_r)
// Outage test of Sec. 5: optionally drop every radio reading in [t0 + a·T, t0 + b·T].
//
// Estimators on a Walk (GadekeEstimator; ids gadeke-kf, gadeke-kf-rts) gather the inputs from
// the shared front ends with 003's choices:
//   steps (StepsForWalk): acceleration-energy detector, 10 (m/s²)² threshold, 300 ms lockout
//     (eq. 1), Weinberg length (eq. 2, K = 0.45: 003 gives no W), step direction from a PCA of
//     the horizontal acceleration (eq. 3-5); heading: gyro blended with the magnetometer (003
//     uses the Xsens attitude with its magnetometer on: the "aerospace" profile, Sec. 4.1) —
//     the complementary heading of pdr.h is the nearest shared front end;
//   ranges: every RSS reading as an ML range with the 004 eq. 7 σ (RangeMeasurementsFromWalk);
//   start: the walk's initial_pose (position, σ_xy), else the anchors' centroid, init_sigma_m.
// Config: GadekeKfOptions keys (except `smooth`, chosen by the id), a `pdr:` child map and a
// `radio:` child map with min_sigma_m (floor on σ_r).
#ifndef WALKGRAPH_FILTERS_GADEKE_H_
#define WALKGRAPH_FILTERS_GADEKE_H_

#include <optional>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "walkgraph/estimator.h"
#include "walkgraph/filters/front_end.h"
#include "walkgraph/filters/ranges.h"
#include "walkgraph/measurements.h"

namespace walkgraph {

struct GadekeKfOptions {
  double velocity_factor = 0.99;     // eq. 6, per processing epoch
  double processing_rate_hz = 10.0;  // Sec. 4.2
  bool pdr_input = true;             // PDR displacement as control input (eq. 6)
  double pdr_sigma_frac = 0.05;      // Sec. 5: PDR error ≈ 5 % of the distance
  double q_position_m2ps = 0.01;     // position random walk
  double q_velocity_m2ps3 = 0.05;    // velocity random walk
  double init_sigma_m = 10.0;        // without initial_pose: anchor centroid, this σ
  double init_sigma_v_mps = 1.0;
  double tag_height_m = 0.0;
  bool bias_corrected_ranges = false;
  double gate_probability = 0.0;    // χ²(1) quantile gate on each range; 0 = off
  double outage_start_frac = -1.0;  // < 0: no simulated outage
  double outage_end_frac = -1.0;
  bool smooth = false;  // RTS ("gadeke-kf-rts")

  // Every rule its YAML reader applies; the filter refuses options that break one.
  Status Validate(const std::string& context = "gadeke-kf") const;
};

struct GadekeStart {
  Eigen::Vector2d position_m = Eigen::Vector2d::Zero();
  double sigma_m = 10.0;
  double t_s = 0.0;
};

// The filter on front-end outputs; ranges sorted by time. Outage dropping is done by the caller
// (GadekeKf::Run) so that this core sees exactly the readings it fuses.
StatusOr<EstimateResult> RunGadekeKf(const StepSequence& steps,
                                     const std::vector<RangeMeasurement>& ranges,
                                     const GadekeStart& start, const GadekeKfOptions& options);

struct GadekeEstimatorOptions {
  GadekeKfOptions filter;
  PdrOptions pdr;                 // 003 Sec. 3.1: energy steps, Weinberg, PCA direction
  RangeConversionOptions ranges;  // bias_corrected = filter.bias_corrected_ranges

  static GadekeEstimatorOptions PaperDefaults();
  // Every rule its YAML reader applies (filter and front ends); Run refuses options that break one.
  Status Validate(const std::string& id = "gadeke-kf") const;
};

class GadekeEstimator : public Estimator {
 public:
  GadekeEstimator(std::string id, GadekeEstimatorOptions options)
      : id_(std::move(id)), options_(std::move(options)) {}
  Status CheckApplicable(const Walk& walk) const override;
  StatusOr<EstimateResult> Run(const Walk& walk) const override;

 private:
  std::string id_;
  GadekeEstimatorOptions options_;
};

}  // namespace walkgraph

#endif  // WALKGRAPH_FILTERS_GADEKE_H_
