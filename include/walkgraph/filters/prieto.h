// Prieto, Mazuelas, Bahillo, Fernández, Lorenzo, Abril — pedestrian navigation in harsh
// environments by Bayesian fusion of wireless and inertial measurements (paper 002).
//
// State (Sec. II)  y = [x v a q ω b_f b_ω]: position, velocity, acceleration (navigation frame
// ENU), attitude, angular velocity, accelerometer and gyro biases.
// Dynamic model (Sec. III-A), Δ = t_{k+1} − t_k:
//   [x v a]_{k+1} = [I ΔI ½Δ²I; 0 I ΔI; 0 0 I] [x v a]_k + n^{d,1}                    (eq. 1)
//   q̄_{k+1} = exp(−½ ω̄_k Δ) ⊙ q̄_k + n̄^{d,2}                          (eq. 2 integrated, eq. 3)
//   [ω Θ]_{k+1} = [ω Θ]_k + n^{d,3}    (random walks, Θ = [b_f b_ω])                      (eq. 4)
// Measurement model (Sec. III-B, C), x_rx = x + (0, 0, receiver_offset_z_m):
//   RSS   z^s = α^s − 10 β^s log10(‖x^l − x_rx‖/d0) + n^s     (PathLossModel, walk units) (eq. 5)
//   TOA   z^τ = α^τ + β^τ ‖x^l − x_rx‖ + n^τ                                             (eq. 6)
//   acc   z^f = C(q̄)(a − g) + b_f + n^f,  g = (0, 0, −g)                                 (eq. 7)
//   gyro  z^ω = ω + b_ω + n^ω                                                            (eq. 8)
//   stance evidence  0 = [v a ω] + n^0, when the stance detector (Jiménez's multi-condition
//   detector [33], stance.h) declares stance                                             (eq. 9)
// The IMU readings are MEASUREMENTS of the state (eq. 7–8), not inputs: a filter epoch per IMU
// sample, with the stance evidence and the radio readings of that epoch.
//
// Conventions and readings of the text (each an option where it is a choice):
// - q̄ of the paper is the nav→body rotation, C(q̄) its matrix (Appendix). We keep its inverse
//   q_nb (body→nav, as strapdown.h): C(q̄) = R_nbᵀ, and eq. 3 conjugated reads
//   q_nb,k+1 = q_nb,k ⊗ Exp(ω_k Δ) (QuaternionExp(φ) = exp(½φ̄)). Eq. 2–3 and 8 make ω the
//   body-frame rate (what the gyro measures), although Sec. II says "navigation frame".
//   The text's eq. 3 omits Δ in exp(−½ω̄_k); the Appendix's exp has cos in both rows
//   (extraction garble): we use the standard exp(q̄) = e^{q0}[cos‖q‖; q/‖q‖ sin‖q‖].
// - The attitude lives on its manifold: the covariance is over a 21-D error state
//   δy = [δx δv δa δθ δω δb_f δb_ω] with the local (body) attitude error q = q̂ ⊗ Exp(δθ);
//   y ⊞ δy and y ⊟ y' are the retraction and its inverse; after every update the error is
//   injected, q renormalized (footnote 2) and P mapped by the reset Jacobian
//   G = blockdiag(I, I − ½[δθ]×, I). There is never a 4-D quaternion covariance.
// - Noise of Sec. IV-A as per-step (Δ) increments of a discrete Wiener process ([24]):
//   n^{d,1} = Γ·σ_j·Δ·w, Γ = [½Δ² Δ 1]ᵀ per axis (σ_j = σ_d(3) = 450 m/s³: jerk);
//   attitude: δθ increments of 2·σ_q'·Δ (σ_q' = 1e-4 /s is a rate of the quaternion's vector
//   part, whose small changes are half the rotation angle: the quaternion's 4-D noise n̄^{d,2}
//   becomes 3-D noise on δθ); ω: σ_ω'·Δ (σ_ω' = 10 rad/s²). The biases are given as
//   σ_bf = 0.135 m/s², σ_bω = 6e-4 rad/s without a time base; we read them like the others, as
//   rates per second (per-step increments σ·Δ) — taking them per step would let the biases
//   wander faster than the accelerometer can tell them from a.
// - IMU sampling (imu_sampling): "interval-average" (default; the simulator's foot IMU and
//   integrating IMUs): sample k averages (t_{k−1}, t_k], so it updates the state at t_{k−1}
//   before the prediction to t_k, which makes eq. 1 and 3 exact (as strapdown.h);
//   "instantaneous": predict to t_k, then update with sample k.
// - Radio readings update the first filter epoch at or after their time stamp (≤ 1/rate late:
//   10 ms at 100 Hz). NLOS: the paper names NLOS-aware error models (Sec. III-B, [5], [9],
//   [31]) but its filters are Gaussian, so by default eq. 5–6 are fused as they stand with the
//   walk's σ (this reproduces Table I's ≈1.0 m: prieto-laps, 10 runs, 1.04 / 1.06 / 1.09 m at
//   1 / 4 / 8 laps). Option: innovation gating, a radio reading is dropped when its NIS exceeds
//   the χ²(1) quantile at gate_probability (0.99: 0.54 / 0.60 / 0.62 m, NLOS readings mostly
//   rejected). IMU and stance updates are never gated.
//   EstimateResult::nis holds the NIS of each accepted radio update (χ²(1) per reading, χ²(m)
//   for a stacked set); diagnostics hold the mean NIS per kind ("nis_mean_imu": 6 dof,
//   "nis_mean_imu_stance": 15), and the state's health at the output epochs:
//   "quaternion_norm_error_max" = max |‖q‖ − 1|, "covariance_asymmetry_max" = max
//   |P − Pᵀ|/max|P|, "covariance_not_pd_epochs" = epochs whose P has no Cholesky factor.
// - Radio parameters default to the walk's (walk.yaml radio: A_dbm → α^s, eta → β^s,
//   sigma_db, range_sigma_m); α^τ = 0, β^τ = 1 (a calibrated TOA range).
// - Sec. IV-A gives no IMU noise: the paper takes it from the Xsens MTx datasheet (0.002
//   m/s²/√Hz over 30 Hz, 0.05 °/s/√Hz over 40 Hz): σ_f = 0.011 m/s², σ_ω = 0.0055 rad/s.
//   Initial uncertainties are ours (the paper gives none). The start is the walk's
//   initial_pose (heading = yaw of the IMU's x axis), roll and pitch from the mean specific
//   force over init_attitude_window_s; without initial_pose: the anchors' centroid,
//   init_sigma_m, yaw 0 with σ = π.
//
// EKF: analytic Jacobians F = ∂(y_{k+1} ⊟ f(ŷ))/∂δy_k and H = ∂h(ŷ ⊞ δy)/∂δy at δy = 0;
//   KalmanUpdate (Joseph form, gating, NIS).
// UKF: scaled sigma points (Julier 2002; α, β, κ): λ = α²(n + κ) − n, χ_i = ŷ ⊞ (±√(n+λ) L)_i,
//   L Lᵀ = P, W_0^m = λ/(n+λ), W_0^c = W_0^m + 1 − α² + β, W_i = 1/(2(n+λ)); additive Q.
//   Quaternion-aware mean of the propagated points: the vector parts by weights; the attitude
//   by the weighted mean of the error vectors e_i = Log(q̄⁻¹ q_i) about a reference q̄
//   (first the propagated central point), q̄ ← q̄ ⊗ Exp(Σ W_i^m e_i), iterated
//   ukf_mean_iterations times (1 = single step) or until ‖Σ W e‖ < 1e-12. The update:
//   S = Σ W^c ΔzΔzᵀ + R, C = Σ W^c δχ Δzᵀ, K = C S⁻¹, δy = K ν, P ← P − K S Kᵀ, symmetrized;
//   if P is not PD its eigenvalues are floored (counted in "pd_repairs").
// Both filters share Propagate (f), the measurement functions (h), ⊞/⊟, Q and R.
//
// Output: (x, y, heading) and its covariance every 1/output_rate_hz (10 Hz; the filter runs at
// the IMU rate). RTS (smooth = true, "-rts"): Rauch–Tung–Striebel at the output rate, so memory
// is O(output epochs), not O(IMU samples): ≈14 KB each (P_prior, P_post, the map F and the
// smoothed P, 21×21 doubles), ≈0.14 MB per second of walk at 10 Hz (measured process peak for
// 8 laps, 16 min: 0.17 GB, 0.03 GB without RTS); 10× that if it kept every 100 Hz epoch.
// Lower output_rate_hz for longer walks. Between two stored epochs j < m the filter also carries a
// clone of the state at j (stochastic cloning): its correction δ_j, P_{j|m} and the
// cross-covariance P_{mj|m}, updated by every measurement (EKF: with F and H; UKF: with their
// statistical linearizations F = Dᵀ P⁻¹, H = C_xzᵀ P⁻¹ from the same sigma points — the URTS
// assumption of jointly Gaussian states). Since future measurements are independent of x_j given
// x_m,
//   x_{j|N} = x_{j|m} ⊞ J (x_{m|N} ⊟ x_{m|m}),  J = P_{jm|m} P_{m|m}⁻¹,
//   P_{j|N} = P_{j|m} + J (P_{m|N} − P_{m|m}) Jᵀ,
// which is RtsSmooth (kalman.h) with the cross-covariance P_{mj|m} (FilterEpoch::P_cross) in
// place of F P, in the error chart of each stored filter state (x_prior = 0, x_post = δ_j).
//
// Variants (ids): sensors = fusion (IMU + stance + RSS + TOA), imu (IMU + stance: the
// paper's EKF-IMU/UKF-IMU), radio (RSS + TOA only: EKF-WiFi/UKF-WiFi, on the 9-D state
// [x v a], the rest being unobserved and decoupled, stepped at the IMU times when the walk has
// an IMU, else every radio_only_step_s). Sec. IV-A's σ_d(3) = 450 m/s³ is the jerk of a foot as
// the accelerometer sees it; without the accelerometer it leaves no memory between radio
// readings and the filter extrapolates noise (measured, 1 lap: 44 m RMSE with single readings,
// 339 m with 1 s sets), so the radio-only ids default to a walker's jerk σ_d(3) = 1 m/s³
// (0.3–3 give 2.9–3.1 m) and fuse each ~1 s set jointly (radio_epoch_s = 1; do not gate it:
// gating an extrapolating prior locks it out); their trajectory holds the estimates at the radio
// epochs (the positions "obtained by only fusing RSS and TOA").
// Its vertical axis has no process noise and starts with known (zero) vertical velocity and
// acceleration: no radio reading observes the height (the APs and the receiver are near one
// plane), and an unobserved jerk random walk in z grows without bound (t^2.5) until it spreads
// the UKF's sigma points kilometres away (measured: 13–16 m RMSE instead of 3).
#ifndef WALKGRAPH_FILTERS_PRIETO_H_
#define WALKGRAPH_FILTERS_PRIETO_H_

#include <limits>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "walkgraph/estimator.h"
#include "walkgraph/stance.h"
#include "walkgraph/strapdown.h"

namespace walkgraph {

enum class PrietoFilterKind { kEkf, kUkf };
enum class PrietoSensors { kFusion, kImuOnly, kRadioOnly };
// The stance detector 002 uses: Jiménez's multi-condition detector [33] (stance.h values).
StanceOptions PrietoDefaultStance();

struct PrietoOptions {
  // Fixed by the estimator id (not YAML keys).
  PrietoFilterKind filter = PrietoFilterKind::kEkf;
  PrietoSensors sensors = PrietoSensors::kFusion;
  bool smooth = false;

  // Dynamic model, Sec. IV-A (per-second rates; see the top of this file).
  double sigma_jerk_mps3 = 4.5e2;         // σ_d(3), eq. 1 (radio-only ids: 1, see top)
  double sigma_attitude_rate_ps = 1e-4;   // σ_q̄', eq. 3
  double sigma_omega_rate_radps2 = 10.0;  // σ_ω', eq. 4
  double sigma_acc_bias_mps2 = 13.5e-2;   // σ_bf, eq. 4
  double sigma_gyro_bias_radps = 6e-4;    // σ_bω, eq. 4
  // Stance evidences, Sec. IV-A (eq. 9).
  double sigma_v0_mps = 1e-2;
  double sigma_a0_mps2 = 3e-1;
  double sigma_w0_radps = 5e-2;
  // IMU noise (Xsens MTx datasheet; eq. 7–8).
  double sigma_acc_mps2 = 0.011;
  double sigma_gyro_radps = 0.0055;
  ImuSampling imu_sampling = ImuSampling::kIntervalAverage;
  double gravity_mps2 = 9.81;
  // Radio (eq. 5–6). NaN: the walk's value (walk.yaml radio section).
  bool use_rss = true;
  bool use_toa = true;
  double rss_alpha_dbm = std::numeric_limits<double>::quiet_NaN();  // α^s
  double rss_beta = std::numeric_limits<double>::quiet_NaN();       // β^s
  double rss_sigma_db = std::numeric_limits<double>::quiet_NaN();
  double toa_alpha_m = 0.0;  // α^τ
  double toa_beta = 1.0;     // β^τ
  double toa_sigma_m = std::numeric_limits<double>::quiet_NaN();
  double receiver_offset_z_m = 0.0;  // receiver above the IMU
  double gate_probability = 0.0;     // χ²(1) gate per radio reading; 0 = off (paper; see top)
  // > 0: the readings within radio_epoch_s of a group's first one are fused as one vector
  // (eq. 5–6 with z^s ∈ R^{L^s}, z^τ ∈ R^{L^τ}, as the paper's ~1 s measurement sets) at the
  // group's last time stamp; 0: every reading at its own time. Default 0, radio-only 1 s.
  double radio_epoch_s = 0.0;
  // UKF (scaled unscented transform).
  // α ≈ √(3/21): sigma points at ±√3·σ, the spread of [34]'s rule n + κ = 3 (whose central
  // weight is as negative, W_0^m = 1 − 1/α² ≈ −5.9; the scaled form adds β to W_0^c). Measured
  // on prieto-laps (1 lap, 5 runs): α = 1 puts the UKF 4.5 % behind the EKF, α ≤ 0.5 within 1 %.
  double ukf_alpha = 0.38;
  double ukf_beta = 2.0;
  double ukf_kappa = 0.0;
  int ukf_mean_iterations = 3;
  // Initial uncertainty (ours) and start.
  double init_sigma_m = 10.0;  // without initial_pose
  double init_sigma_z_m = 0.1;
  double init_sigma_v_mps = 0.1;
  double init_sigma_a_mps2 = 1.0;
  double init_sigma_tilt_rad = 0.035;
  double init_sigma_omega_radps = 0.1;
  double init_sigma_acc_bias_mps2 = 0.05;
  double init_sigma_gyro_bias_radps = 0.02;
  double init_attitude_window_s = 0.5;
  // Timeline and output.
  double radio_only_step_s = 0.01;  // Δ_k of Sec. IV-A, radio-only walks without an IMU
  double output_rate_hz = 10.0;     // trajectory (and RTS) epochs
  // Stance detector (stance: child map); default Jiménez's multi-condition detector [33].
  StanceOptions stance = PrietoDefaultStance();

  // Every rule its YAML reader applies; the filter refuses options that break one.
  Status Validate(const std::string& context = "prieto") const;
};

// Why `options`' variant cannot run on `walk` (missing sensors, an IMU not on a foot), or OK.
Status CheckPrietoApplicable(const Walk& walk, const PrietoOptions& options);
// The filter on a walk (fusion / IMU-only / radio-only; EKF / UKF; optional RTS). Fails, like
// PrietoFilter::Run, where CheckPrietoApplicable does.
StatusOr<EstimateResult> RunPrietoFilter(const Walk& walk, const PrietoOptions& options);

class PrietoFilter : public Estimator {
 public:
  explicit PrietoFilter(PrietoOptions options) : options_(std::move(options)) {}
  Status CheckApplicable(const Walk& walk) const override;
  StatusOr<EstimateResult> Run(const Walk& walk) const override;
  const PrietoOptions& options() const { return options_; }

 private:
  PrietoOptions options_;
};

}  // namespace walkgraph

#endif  // WALKGRAPH_FILTERS_PRIETO_H_
