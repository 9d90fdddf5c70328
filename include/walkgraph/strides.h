// Stride front end for a foot-mounted IMU: a ZUPT/ZARU-aided strapdown INS whose error-state
// EKF is reset at every stance, the "step-wise dead reckoning" of Nilsson, Skog, Händel
// (OpenShoe, "Foot-mounted INS for everybody", EURASIP J. Embedded Syst. 2014) — one Step per
// stride, stance to stance, with σ from the filter's covariance.
//
// Nominal state: strapdown.h (q_nb, v_n, p_n) driven by the bias-corrected readings, plus the
// bias estimates b_a, b_g. Error state (15), navigation-frame attitude error δθ with
// R = Exp(δθ)·R̂:  δx = [δp, δv, δθ, δb_a, δb_g].
// Continuous error dynamics (f̂_n = R̂(f̃ − b̂_a)):
//   δṗ = δv,   δv̇ = −[f̂_n]× δθ − R̂ δb_a − R̂ n_a,   δθ̇ = −R̂ δb_g − R̂ n_g,
//   δḃ_a = n_ba,   δḃ_g = n_bg,
// discretized per IMU interval dt as F = I + A·dt (plus the ½dt² terms of δp), with the
// per-sample white noises σ_a, σ_g (the readings' σ, so Δv noise is σ_a·dt) and the bias random
// walks σ_ba, σ_bg (per √s).
// Updates (Joseph form, kalman.h KalmanUpdate):
//   ZUPT at stance samples:  0 = v + n,   H = [0 I 0 0 0],  R = σ_zupt² I
//   ZARU at still samples:   ω̃ = b_g + n, H = [0 0 0 0 I],  R = σ_zaru² I
// then p += δp, v += δv, q ← Exp(δθ)⊗q, b += δb.
// Initial attitude: roll and pitch levelled from the mean specific force of the first stance
// phase (a walk that starts in a swing starts there: wait_for_first_stance); yaw (the ENU angle
// of the body x axis) = initial_pose.heading_rad, else 0. Initial gyro
// bias: the mean gyro of the first still run (compensate_gyro_bias;
// gyro_bias_start_rest_only), else 0.
//
// Strides. The detector's stance samples form runs; runs shorter than min_stance_s are dropped
// (neither ZUPT nor stride), runs separated by less than min_swing_s are one stance phase. A
// stride ends at the last sample of each stance phase after the first (the first phase, or the
// first sample when the walk starts moving, is the reference). At the end of stride k
// (Nilsson et al. 2014 Sec. 4, step-wise dead reckoning):
//   d_k = p_k − p_{k−1} (horizontal),  length = ‖d_k‖,  heading = atan2(d_y, d_x),
//   dheading = ψ_k − ψ_{k−1} (yaw of the foot, gyro-integrated),
//   C_k = Cov(δp_xy, δψ) from P (since the reset at k−1),
//   σ_length = √(uᵀ C_xy u), σ_dir = √(nᵀ C_xy n)/max(length, 0.1 m)  (u ∥ d_k, n ⊥ u),
//   σ_dheading = √C_ψψ,  σ_heading = √(σ_ψ0² + Σ_{j≤k} σ_dheading,j² + σ_dir²),
// each floored by the options; then the rows and columns of P for δp and δψ = δθ_z are zeroed
// (the reset: position and heading are unobservable, so the next stride starts from a known
// reference and the strides' errors are independent). The reset changes only P; the nominal
// trajectory is that of the ordinary ZUPT-aided INS.
#ifndef WALKGRAPH_STRIDES_H_
#define WALKGRAPH_STRIDES_H_

#include <map>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "walkgraph/enum_names.h"
#include "walkgraph/measurements.h"
#include "walkgraph/stance.h"
#include "walkgraph/status.h"
#include "walkgraph/strapdown.h"
#include "walkgraph/walk.h"

namespace walkgraph {

// StrideOptions::scale_noise_adaptation: fixed | walk | causal.
enum class ScaleNoiseAdaptation { kFixed, kWalk, kCausal };
const EnumNames<ScaleNoiseAdaptation>& ScaleNoiseAdaptationNames();
const char* ToString(ScaleNoiseAdaptation a);
StatusOr<ScaleNoiseAdaptation> ScaleNoiseAdaptationFromString(const std::string& name);

struct StrideOptions {
  // Stance detector: the adaptive GLRT (stance.h: γ from the walk's own statistic, α = 0.3),
  // fallback γ = 3e3 instead of OpenShoe's 3e5. A fixed γ does not carry over: at 3e5 the
  // simulated foot presets get ZUPTs while the foot still moves (precision 0.73 vs the truth
  // labels on jimenez-building) and the EKF's accelerometer bias runs off to 0.4 m/s²; at 3e3
  // PyShoe trial 11-48-35 keeps too few ZUPTs and fg-ins-batch ends at 0.825 m RMSE (0.054 m
  // adaptive). The adaptive γ lands at ≈1.4e3 on the presets and 1.3e4 / 4.4e4 on the two
  // PyShoe trials (a numpy check of the same statistic); fg-ins-batch RMSE is flat for α in 0.2–0.5
  // on all four (issue 21). The causal estimators (zupt-ins, fg-ins-window and its online
  // output) take γ from the past 60 s only (Causal() below); on the two PyShoe trials that cost
  // fg-ins-window 0.037 → 0.043 m and 0.056 → 0.056 m, zupt-ins 0.040 → 0.040 m and
  // 0.090 → 0.065 m (RMSE after SE(2) alignment).
  StanceOptions stance = DefaultStance();
  // Subtract the mean gyro of the first still run (≥ 0.5 s of `still` samples; else of the
  // rest the walk starts with, ≥ 1 s of 0.5 s windows whose gyro and ‖a‖ spreads stay below the
  // still thresholds) before detecting stance again: the GLRT assumes ω = 0 at rest, and a
  // 1 °/s turn-on bias alone adds ≈ 300 to its statistic (≈ 3 °/s hides every still sample).
  // The same mean initialises the gyro-bias estimate.
  bool compensate_gyro_bias = true;
  // Take that first still run only if it begins within 1 s of the walk's first sample (Causal()
  // sets it). A walk that starts in motion otherwise took the bias of a rest tens of seconds
  // later, so a causal estimate at t depended on the walk after t. Measured on simulated walks
  // that start in motion with a rest at 56 s (jimenez-building, IMU alone, seeds 1 / 2):
  // zupt-ins 0.120 / 0.045 -> 0.231 / 0.015 m, fg-ins-window 0.052 / 0.064 -> 0.047 / 0.059.
  bool gyro_bias_start_rest_only = false;
  double gravity_mps2 = 9.81;
  ImuSampling sampling = ImuSampling::kIntervalAverage;  // strapdown.h conventions
  // IMU errors. Defaults: the Xsens MTi of 004 Table I as the foot presets simulate it
  // (white noise per reading; turn-on bias σ = bias stability 0.02 m/s², 1 °/s; the bias random
  // walks have no paper value: 1e-4 per √s).
  double acc_noise_mps2 = 0.011;
  double gyro_noise_radps = 0.0055;
  double acc_bias_sigma_mps2 = 0.02;
  double gyro_bias_sigma_radps = 0.017453292519943295;  // 1 °/s
  double acc_bias_rw_mps2_sqrts = 1e-4;
  double gyro_bias_rw_radps_sqrts = 1e-4;
  // Scale-factor noise: each reading's σ² gains (scale_noise·‖reading‖)² (for what the white
  // noise leaves out and grows with the motion: scale factor, misalignment, g-sensitivity, heel
  // strike; ImuPreintegration::SetScaleNoise — the foot-INS graph's preintegration takes the
  // front end's value). Adapted to the walk by default: the NIS of each stance phase's first
  // ZUPT is the velocity error the swing accumulated against what the model predicted (χ²(3),
  // median 2.37, when the model holds), so the value is a rung of the ladder 0, 0.002, 0.005,
  // 0.01, 0.02, 0.05 (from the first rung at or above scale_noise):
  //   walk:   the least rung whose median first-ZUPT NIS over the walk is at most
  //           max_median_zupt_nis (else the last), the filter run once per rung tried;
  //   causal: (Causal(), for zupt-ins and the window) one rung up whenever the median of the
  //           last 5 first-ZUPT NIS at the current rung exceeds it — the value at a sample
  //           depends on the past only;
  //   fixed:  scale_noise as given.
  // Measured (issue 40): the median first-ZUPT NIS without scale noise is 0.16–0.37 on the
  // simulated foot presets (walk, run, stairs: the rung stays 0), 12–14 on the two walking
  // PyShoe trials and 150–290 on the three running ones (their heel strikes reach 8–9 g);
  // 10 gives 0.005 walking and 0.02–0.05 running there.
  double scale_noise = 0.0;
  ScaleNoiseAdaptation scale_noise_adaptation = ScaleNoiseAdaptation::kWalk;
  double max_median_zupt_nis = 10.0;
  // Pseudo-measurements: OpenShoe's ZUPT σ 0.01 m/s; ZARU σ = the gyro's white noise.
  double zupt_sigma_mps = 0.01;
  // Gross-error gate of a stance's ZUPTs (issue 40; 0 = none): until one of a stance run's
  // samples has been applied, a ZUPT whose NIS exceeds zupt_gross_gate_ratio times the walk's
  // median first-ZUPT NIS so far (at least χ²(3)'s median 2.366; before the walk has 10 of
  // them, max_median_zupt_nis) is not applied: the filter is sure the foot moves there. Only
  // within stance.gait_max_gap_s of the last applied ZUPT: after longer without one the predicted
  // velocity is no longer trusted, and the ZUPT is applied whatever its NIS. Why: the gait
  // detector puts one stance in every stride period, so a stride longer than the period (the
  // first from a standstill, a leap) gets one inside its swing, which the filter took at full
  // weight. Measured on simulated running (jimenez-building, gait run, IMU alone, stance
  // fraction 0.1, 2–3.5 m/s, seeds 1–2): zupt-ins 0.42–0.94 m RMSE against jimenez-iez's
  // 0.04–0.11 m, from two or three ZUPTs at a predicted 3.8 m/s, NIS 1.7e4–3e4 (3000–6000× the
  // walk's median). The real stances' first-ZUPT NIS on the five shared PyShoe trials stay
  // within 9× their walk's median (within 20× with the causal scale noise of zupt-ins).
  double zupt_gross_gate_ratio = 100.0;
  double zaru_sigma_radps = 0.0055;
  bool use_zaru = true;
  // Initial attitude: σ of the levelled roll/pitch (the acc bias, 0.02/g ≈ 0.12°, rounded up).
  double tilt_sigma_rad = 0.0087;  // 0.5°
  // Stance phases (no paper value: a stance shorter than 50 ms is a detector blip, a swing
  // shorter than 0.2 s is no stride).
  double min_stance_s = 0.05;
  double min_swing_s = 0.2;
  // A walk that starts in a swing (its first stance phase begins min_swing_s or more, and at
  // most stance.gait_max_gap_s, after the first sample): the INS waits at its first stance
  // phase and starts there (velocity zero, attitude levelled from that phase), its position
  // held where it starts until then. Integrating the swing from a levelled attitude that is
  // not the foot's (the foot is tilted mid-swing) left a velocity error the first ZUPTs put
  // into the tilt and biases: the five PyShoe trials cut to start 3, 6 and 10 s in, zupt-ins
  // up to 2.96 m RMSE, 0.84 m cut at a stance instead (docs/results.md). false: integrate
  // from the first sample.
  bool wait_for_first_stance = true;
  // Floors of the emitted σ (the filter's covariance is optimistic about unmodelled errors).
  double min_sigma_length_m = 0.01;
  double min_sigma_heading_rad = 0.002;
  double min_sigma_dheading_rad = 0.002;

  // Every rule its YAML reader applies; ComputeStrides and RunZuptIns refuse options that break
  // one.
  Status Validate() const;
  static StanceOptions DefaultStance();
  // These options for a causal estimator (zupt-ins, the fg-ins window): the adaptive detector's
  // γ from the 60 s before each sample only (StanceOptions::adaptive_causal), and the gyro bias
  // from a rest the walk starts with only (gyro_bias_start_rest_only), so that an
  // estimate at t does not depend on the walk after t. (On the two shared PyShoe trials the
  // trailing window's length hardly matters: 20, 60 and 300 s gave the same RMSE to 1 mm.)
  StrideOptions Causal() const;
};

// A stance phase [begin, end] (IMU sample indices, inclusive).
struct StancePhase {
  size_t begin = 0;
  size_t end = 0;
};

// Everything the front end computed: the per-sample INS solution (after the updates), the
// stance detection and phases, and the strides.
struct ZuptInsSolution {
  std::vector<NavState> states;                // one per IMU sample
  std::vector<Eigen::Vector3d> acc_bias_mps2;  // estimates per IMU sample
  std::vector<Eigen::Vector3d> gyro_bias_radps;
  // Per IMU sample: the filter's covariance of (δp_x, δp_y, δψ) since the last stride reset.
  std::vector<Eigen::Matrix3d> stride_covariance;
  StanceMask stance;
  std::vector<bool> zupt;  // ZUPT applied at this sample (stance in a kept run)
  std::vector<StancePhase> phases;
  StepSequence strides;            // one per phase after the reference
  std::vector<size_t> stride_end;  // IMU index of each stride's end
  size_t reference_index = 0;      // IMU index where the first stride starts
  // IMU index where the INS starts (StrideOptions::wait_for_first_stance: the first stance
  // phase's begin on a walk that starts in a swing; its state held before), else 0.
  size_t start_index = 0;
  // Per stride: Cov of (d_x, d_y, dheading) from the filter (floored σ not applied).
  std::vector<Eigen::Matrix3d> stride_increment_covariance;
  std::vector<double> scale_noise;     // per IMU sample, StrideOptions::scale_noise as adapted
  std::vector<double> first_zupt_nis;  // NIS of each stance phase's first ZUPT
  size_t hypotheses_gated = 0;         // stance hypotheses (stance.h) the χ² gate turned down
  size_t runs_gated = 0;  // stance runs whose first ZUPTs the gross-error gate turned down
};

// Runs the ZUPT-aided INS over a foot-mounted walk's IMU.
StatusOr<ZuptInsSolution> RunZuptIns(const Walk& walk, const StrideOptions& options);

// The front end's diagnostics for an estimator that uses it: num_strides, stance_cycle_minima,
// stance_hypotheses (stance.h), stance_hypotheses_gated, stance_runs_gated (the gross-error
// gate's), scale_noise (the last value used).
void AddFrontEndDiagnostics(const ZuptInsSolution& front,
                            std::map<std::string, double>* diagnostics);

// The strides alone (RunZuptIns(...).strides). absolute_heading = the walk has initial_pose.
StatusOr<StepSequence> ComputeStrides(const Walk& walk, const StrideOptions& options);

}  // namespace walkgraph

#endif  // WALKGRAPH_STRIDES_H_
