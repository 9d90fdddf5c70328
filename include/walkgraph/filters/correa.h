// Correa, Barceló, Morell, Vicario — distance-based tuning of the EKF (paper 001).
//
// State x = [x y V θ]ᵀ (position, speed modulus, speed direction)                    (eq. 1)
//   x_{k+1} = F(θ_k) x_k + v,  F = [1 0 T·cosθ 0; 0 1 T·sinθ 0; 0 0 1 0; 0 0 0 1]      (eq. 2–3)
//   prediction x⁻ = F(θ)x (eq. 8), P⁻ = M P Mᵀ + Q (eq. 9), M = ∂(F(θ)x)/∂x:
//     M(0,2) = T cosθ, M(0,3) = −T V sinθ, M(1,2) = T sinθ, M(1,3) = T V cosθ.
//   measurement z = [x̂ ŷ V̂ θ̂] = H x + w, H = I (eq. 4), Kalman update (eq. 10–12, Joseph form)
//   x̂, ŷ: the LS position fix from the ranges (eq. 5, radio front end)
//   V̂ = N_steps/T · l_step (eq. 6), θ̂ = the front end's gyro/magnetometer heading (eq. 7)
// SCMT-EKF (Sec. III): P_max = strongest RSS of the epoch; if P_max ≥ P_Th the position
// measurement is the strongest anchor's position with R_pos = ε·I, else the LS fix with
// σ_p²·I (eq. 21). P_Th solves P_FA(P_Th) = 5 % (eq. 19):
//   P_FA = 1/(d_max − 1) ∫_1^{d_max} Q((P_Th − μ(x))/σ_γ) dx,  μ(x) = P_1m − 10α·log10 x,
// evaluated with composite Simpson's rule and solved by bisection (P_FA falls with P_Th).
// The paper gives no values for σ_p, σ_V, σ_θ, Q (its EKF is "manually configured"); the
// defaults below are ours and are options.
//
// Estimators on a Walk (CorreaEstimator; ids correa-ls, correa-ekf, correa-scmt-ekf,
// correa-ekf-rts, correa-scmt-ekf-rts) gather the inputs from the shared front ends with 001's
// choices (Sec. II, IV):
//   fixes: RSS averaged per anchor over 1 s epochs (motes beacon at 1 Hz; one EKF epoch per
//     second), ML ranges (eq. 14), nonlinear LS position (eq. 5) with equal weights as
//     written (radio: {weighted: true} for the 1/σ² weights), Gauss–Newton to 1 mm;
//   steps (StepsForWalk): ‖a‖ low-passed by an order-20, 3 Hz linear-phase FIR, local maxima
//     above a threshold (eq. 6); constant step length l_step (eq. 6); heading from the
//     complementary gyro/magnetometer blend (eq. 7);
//   P_max (SCMT, "max R" of the epoch's readings): the epoch's strongest RSS (averaged per
//     anchor in dB; one reading per mote at 1 Hz) at the fix time, with that anchor's position.
// On a walk with odometry.csv the steps are its increments, and V̂ sums their lengths instead of
// counting l_step per step. correa-ls outputs the LS fixes themselves. Config: CorreaEkfOptions
// keys (except `scmt` and `smooth`, which the id chooses), `pdr:` and `radio:` child maps
// (filters/front_end.h); correa-ls takes only `radio:`.
#ifndef WALKGRAPH_FILTERS_CORREA_H_
#define WALKGRAPH_FILTERS_CORREA_H_

#include <string>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "walkgraph/estimator.h"
#include "walkgraph/filters/front_end.h"
#include "walkgraph/filters/ranges.h"
#include "walkgraph/measurements.h"
#include "walkgraph/path_loss.h"

namespace walkgraph {

struct CorreaEkfOptions {
  bool scmt = false;             // SCMT switch of eq. 21 ("correa-scmt-ekf")
  double p_fa = 0.05;            // eq. 19 false-alarm probability for P_Th
  double d_max_m = 0.0;          // eq. 19; 0: diagonal of the anchors' bounding box
  double epsilon_m2 = 1e-4;      // eq. 21 ε ≪ 1
  double sigma_p_m = 3.0;        // eq. 21 σ_p
  double sigma_v_mps = 0.2;      // eq. 21 σ_V̂
  double sigma_theta_rad = 0.2;  // eq. 21 σ_θ̂
  double step_length_m = 0.7;    // eq. 6 l_step (per user); ≤ 0: use the front end's lengths
  double q_position_m = 0.1;     // Q = diag(q_p², q_p², q_V², q_θ²) per epoch
  double q_speed_mps = 0.2;
  double q_heading_rad = 0.1;
  double gate_probability = 0.0;  // χ²(4) gate on the full innovation; 0 = off
  bool smooth = false;            // RTS ("-rts")

  // Every rule its YAML reader applies; the filter refuses options that break one.
  Status Validate(const std::string& context = "correa-ekf") const;
};

// P_FA(P_Th) of eq. 19 and its inverse for the model `model` (dBm) and d_max.
double CorreaFalseAlarmProbability(const PathLossModel& model, double p_th, double d_max_m);
StatusOr<double> CorreaPowerThreshold(const PathLossModel& model, double p_fa, double d_max_m);

// F(θ)x of eq. 3/8 and its Jacobian M of eq. 9 (M may be null).
Eigen::Vector4d CorreaPredict(const Eigen::Vector4d& x, double T, Eigen::Matrix4d* M);

struct CorreaInputs {
  std::vector<PositionFix> fixes;          // the LS fixes; one EKF epoch per fix (1 Hz in 001)
  StepSequence steps;                      // speed (eq. 6) and heading (eq. 7)
  std::vector<RangeMeasurement> rss;       // readings with from_rss, for P_max (SCMT)
  PathLossModel model;                     // for P_Th
  std::vector<Eigen::Vector2d> anchor_xy;  // for the default d_max
};

StatusOr<EstimateResult> RunCorreaEkf(const CorreaInputs& in, const CorreaEkfOptions& options);

enum class CorreaVariant { kLs, kEkf, kScmtEkf };

struct CorreaEstimatorOptions {
  CorreaEkfOptions filter;
  PdrOptions pdr;              // 001 eq. 6-7: FIR-magnitude steps, complementary heading
  RadioFrontEndOptions radio;  // 001: 1 s epochs, nonlinear LS (eq. 5) on ML ranges (eq. 14)

  static CorreaEstimatorOptions PaperDefaults();
  // Every rule its YAML reader applies (filter and front ends); Run refuses options that break one.
  Status Validate(const std::string& id = "correa") const;
};

class CorreaEstimator : public Estimator {
 public:
  CorreaEstimator(std::string id, CorreaVariant variant, CorreaEstimatorOptions options)
      : id_(std::move(id)), variant_(variant), options_(std::move(options)) {}
  Status CheckApplicable(const Walk& walk) const override;
  StatusOr<EstimateResult> Run(const Walk& walk) const override;

 private:
  std::string id_;
  CorreaVariant variant_;
  CorreaEstimatorOptions options_;
};

}  // namespace walkgraph

#endif  // WALKGRAPH_FILTERS_CORREA_H_
