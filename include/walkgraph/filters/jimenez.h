// Jiménez, Seco, Prieto, Guevara — tight INS/RFID integration with a foot-mounted IMU
// (paper 004, Sec. III; IMU-alone part = the IEZ+ method of its ref. [14]).
//
// Strapdown INS (strapdown.h) on the foot IMU, corrected by a complementary error-state EKF
// over the 15-element error vector of 004 Sec. III-A, in the paper's order:
//   X = [δAt, δω_b, δPo, δVe, δa_b]  (attitude, gyro bias, position, velocity, acc bias)
// Error definitions (nominal ^, true without ^): q_nb = Exp(δAt) ⊗ q̂_nb (attitude error in the
// navigation frame), b_ω = b̂_ω + δω_b, p = p̂ + δPo, v = v̂ + δVe, b_a = b̂_a + δa_b.
// Error dynamics per IMU step (f̂, ω̂ bias-compensated, R̂ = R(q̂) before the step, dt):
//   δAt⁺ = δAt − R̂⁺ δω_b dt
//   δVe⁺ = δVe − [R̂ f̂]× δAt dt − R̂ δa_b dt
//   δPo⁺ = δPo + δVe dt + ½(−[R̂ f̂]× δAt − R̂ δa_b) dt²      (trapezoidal position of strapdown.h)
//   δω_b⁺ = δω_b + w_ω,  δa_b⁺ = δa_b + w_a                  (bias random walks)
//   Q = diag(σ_g² dt I, 0, 0, σ_a² dt I, 0) + diag(0, q_ω² dt I, 0, 0, q_a² dt I),
// σ_g, σ_a white-noise densities, q_ω, q_a bias random-walk densities.
// Measurements (004 Algorithm 1; every update is kalman.h's Joseph KalmanUpdate):
//   ZUPT at stance:      z = 0 − v̂,                   H = [0 0 0 I 0],   R = σ_zupt² I
//   ZARU when still:     z = ω_meas − b̂_ω,            H = [0 I 0 0 0],   R = σ_zaru² I
//   compass at stance:   z = NormalizeAngle(α_N − α(R̂ m_b)), H = [h_ψ 0 0 0 0], R = σ_ψ²,
//     α(·) the azimuth of the horizontal part, α_N = π/2 − declination (ENU: north = +y), and
//     h_ψ = ∂ψ/∂δAt = [−c_x c_z/ρ, −c_y c_z/ρ, 1] with c = R̂ e_x, ρ = c_x² + c_y², the yaw
//     ψ = atan2(c_y, c_x) of the body x axis. Optionally only when ‖m‖ and the dip agree with
//     the reference field learnt during the initial standstill (disturbance check).
//   RFID range at the 10 Hz reader rate, one scalar update per detected tag i:
//     d̂_i = d0·10^((RSS_i − RSS0)/(10|p|))           (eq. 5, RFCode units: larger is weaker)
//     σ_d,i = σ_RSS·ln10·d̂_i/(10|p|)                  (eq. 7)
//     z = d̂_i − ‖p_rx − a_i‖ (eq. 2, as z − h),  H = [0 0 u_iᵀ 0 0],  R = σ_d,i²,
//     p_rx = p̂ + (0, 0, h_reader) (reader on the waist above the foot IMU), u_i the unit
//     vector from tag to reader. Eq. 1 prints the predicted range in 2-D (tags at ≈2 m); we
//     predict it in 3-D with the tag's and the reader's heights (planar_ranges: true = eq. 1).
//     RSS → (d̂, σ_d) goes through filters/ranges.h (RangeMeasurementsFromWalk); measured
//     ranges (range.csv) are fused the same way with the walk's range_sigma_m.
// All updates of one IMU sample are linearized at the same nominal state (the innovation of
// a later update subtracts H·δx of the earlier ones, so the sequence equals one joint update),
// then the error is injected and reset:
//   q̂ ← Exp(δAt) ⊗ q̂, b̂_ω ← b̂_ω + δω_b, p̂ ← p̂ + δPo, v̂ ← v̂ + δVe, b̂_a ← b̂_a + δa_b, δx ← 0,
//   P ← G P Gᵀ,  G = blkdiag(I + ½[δAt]×, I₁₂)  (first-order reset Jacobian of the left error).
//
// RTS smoothing ("-rts"): the filter records epochs at the output rate. Between epochs k and
// k+1 there are many steps and measurement updates, so the textbook RTS (prior/posterior and
// one transition) does not apply; instead the forward pass carries a clone of the error at
// epoch k (augmented state [δx_now; δx_k], updated by the same KalmanUpdate, the clone having
// zero H and no dynamics). At epoch k+1 this gives the joint Gaussian of (δx_k, δx_{k+1})
// given all data up to k+1, hence (Markov: later data act on δx_k only through δx_{k+1})
//   C_k = Cov(δx_k, δx_{k+1}) P_{k+1|k+1}⁻¹,
//   δx_{k|N} = δx_{k|k+1} + C_k δx_{k+1|N},   P_{k|N} = D_k + C_k P_{k+1|N} C_kᵀ,
//   D_k = P_{k|k+1} − C_k P_{k+1|k+1} C_kᵀ,
// all errors relative to epoch k's recorded nominal state (which is what makes the error-state
// backward pass consistent); δx_{N|N} = 0. The smoothed state is nominal_k ⊕ δx_{k|N}. This is
// kalman.h's RtsSmooth with the cross-covariance Cov(δx_{k+1}, δx_k) of the clone in place of
// F P (P_{k|N} = P_{k|k+1} + C_k (P_{k+1|N} − P_{k+1|k+1}) C_kᵀ, the same as above). Memory: one
// nominal state, δx_{k|k+1}, P_{k|k+1}, P_{k+1|k+1} and the cross-covariance per epoch
// (≈5.6 KB; at 10 Hz ≈ 200 MB per hour of walk: lower output_rate_hz for very long walks). The
// smoother is only as good as the noise models: with the default compass at every stance sample (a
// spatially correlated disturbance fused as if white, ≈35 times per stance) it gains 8 % RMSE on
// the 8-lap preset, with the compass once per stance 19 % (jimenez_test
// JimenezTables.CompassVariantsAndSmoother).
//
// Output: the foot's planar position and the yaw of its x axis with the (x, y, ψ) covariance
// J P Jᵀ (J picks δPo_x, δPo_y and h_ψ), at output_rate_hz (and the last sample).
#ifndef WALKGRAPH_FILTERS_JIMENEZ_H_
#define WALKGRAPH_FILTERS_JIMENEZ_H_

#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "walkgraph/estimator.h"
#include "walkgraph/stance.h"
#include "walkgraph/strapdown.h"

namespace walkgraph {

// Offsets of the blocks of 004's error state X = [δAt, δω_b, δPo, δVe, δa_b].
inline constexpr int kJimenezStateSize = 15;
inline constexpr int kJimenezAtt = 0;
inline constexpr int kJimenezGyroBias = 3;
inline constexpr int kJimenezPos = 6;
inline constexpr int kJimenezVel = 9;
inline constexpr int kJimenezAccBias = 12;

using JimenezMatrix = Eigen::Matrix<double, kJimenezStateSize, kJimenezStateSize>;
using JimenezVector = Eigen::Matrix<double, kJimenezStateSize, 1>;

// JimenezIezOptions::stance_source: detector | labels.
enum class JimenezStanceSource { kDetector, kLabels };
const EnumNames<JimenezStanceSource>& JimenezStanceSourceNames();
const char* ToString(JimenezStanceSource s);
StatusOr<JimenezStanceSource> JimenezStanceSourceFromString(const std::string& name);

struct JimenezIezOptions {
  // Process noise. 004 Table I lists only bias stability; the white-noise densities are the
  // Xsens MTi data-sheet values (the paper's IMU): 0.002 m/s²/√Hz, 0.05 °/s/√Hz. The bias
  // random-walk densities are our choice (the paper gives none).
  double acc_noise_density = 0.002;                                   // σ_a, m/s²/√Hz
  double gyro_noise_density = 0.05 * 3.14159265358979323846 / 180.0;  // σ_g, rad/s/√Hz
  double acc_bias_rw = 1e-4;                                          // q_a, (m/s²)/√s
  double gyro_bias_rw = 1e-4;                                         // q_ω, (rad/s)/√s
  // Initial uncertainty: biases from Table I's bias stability (acc 0.02 m/s², gyro 1 °/s).
  double init_acc_bias_sigma_mps2 = 0.02;
  double init_gyro_bias_sigma_radps = 3.14159265358979323846 / 180.0;
  double init_tilt_sigma_rad = 3.14159265358979323846 / 180.0;  // roll/pitch after levelling
  double init_velocity_sigma_mps = 0.01;
  double init_height_sigma_m = 0.01;
  // Used when the walk has no initial_pose: position σ (IMU only: start at the origin; with
  // radio: at the anchors' centroid) and yaw σ (start at 0 unless the compass gives it).
  double init_position_sigma_m = 10.0;
  double init_yaw_sigma_rad = 3.14159265358979323846;
  double leveling_window_s = 1.0;         // initial attitude from the mean specific force over this
  bool initial_heading_from_pose = true;  // initial_pose.heading_rad is the IMU x-axis yaw
  // IMU sample convention of strapdown.h ("interval-average" | "instantaneous"); a simulated
  // walk's sim.imu_interval_average overrides it when imu_sampling_from_walk.
  ImuSampling imu_sampling = ImuSampling::kIntervalAverage;
  bool imu_sampling_from_walk = true;
  double gravity_mps2 = 9.81;

  // ZUPT (σ as IEZ+/OpenShoe: 0.01 m/s) and ZARU (σ = the gyro's per-sample white noise at
  // 100 Hz, σ_g·√100).
  bool zupt = true;
  double zupt_sigma_mps = 0.01;
  bool zaru = true;
  double zaru_sigma_radps = 0.0087;
  // Stance/still detection (stance.h); 004 uses Jiménez's multi-condition detector, which is
  // the default here (a `stance:` child map may change any StanceOptions field). The still
  // (ZARU) gyro threshold is raised from stance.h's 0.05 to 0.1 rad/s: the raw gyro norm
  // includes the turn-on bias (Table I: 1 °/s per axis, so up to ≈0.05 rad/s at 2σ in norm).
  StanceOptions stance = [] {
    StanceOptions s;
    s.detector = StanceDetector::kMultiCondition;
    s.still_gyro_radps = 0.1;
    return s;
  }();
  // "detector" (stance.h) or "labels": the walk's stance_truth (e.g. PyShoe's Vicon zv labels,
  // the simulator's truth) as an oracle, for studies that separate detection from filtering.
  // ZARU's still flags always come from the detector.
  JimenezStanceSource stance_source = JimenezStanceSource::kDetector;

  // Compass heading update at stance (004 Algorithm 1 lines 10–11). The paper gives no σ;
  // 10° is our choice. compass_every_stance_sample (default, as the pseudo-code: inside the
  // 100 Hz stance branch); false applies it once per stance (its middle sample), which avoids
  // fusing the same spatially correlated disturbance ≈35 times per stance. The paper shows no
  // disturbance check, so it is off by default (thresholds ≤ 0).
  bool compass = true;
  double compass_sigma_rad = 10.0 * 3.14159265358979323846 / 180.0;
  bool compass_every_stance_sample = true;
  double declination_rad = 0.0;
  // Disturbance check against the field seen during the initial leveling window (≤ 0: off;
  // e.g. 2 µT and 3° reject most of the simulator's indoor disturbances).
  double compass_max_field_deviation_ut = 0.0;
  double compass_max_dip_deviation_rad = 0.0;
  double compass_gate_probability = 0.0;  // χ²(1) gate on the heading innovation; 0 = off

  // RFID ranges (004 Sec. III-B/C): RSS → range with eq. 5 and σ_d with eq. 7 using THIS model
  // (paper: RSS0 = 60 at d0 = 1 m, |p| = 2.3, σ_RSS = 6, RFCode units), not the walk's, unless
  // path_loss_from_walk. The walk must then be in RFCode units.
  double rss0 = 60.0;
  double path_loss_exponent = 2.3;  // |p|
  double sigma_rss = 6.0;
  double d0_m = 1.0;
  bool path_loss_from_walk = false;
  bool bias_corrected_ranges = false;   // divide d̂ by e^{σ_d²/2} (001 eq. 17; not in 004)
  double min_range_sigma_m = 0.1;       // floor on eq. 7 (it vanishes as d̂ → 0)
  double reader_height_m = 1.0;         // reader (waist) above the foot IMU
  bool planar_ranges = false;           // true: eq. 1 as printed (2-D)
  double range_gate_probability = 0.0;  // χ²(1) gate per tag reading; 0 = off

  double output_rate_hz = 10.0;

  // Set by the estimator id, not by YAML.
  bool use_rss = false;
  bool smooth = false;

  // Every rule its YAML reader applies; RunJimenezIez refuses options that break one.
  Status Validate(const std::string& context = "jimenez-iez") const;
};

// The INS nominal state the error state is defined about.
struct JimenezNominal {
  NavState nav;
  Eigen::Vector3d gyro_bias = Eigen::Vector3d::Zero();
  Eigen::Vector3d acc_bias = Eigen::Vector3d::Zero();
};

// Yaw ψ of the body x axis (ENU, from east counter-clockwise, via NormalizeAngle) and its
// Jacobian h_ψ with respect to the navigation-frame attitude error δAt.
double JimenezYaw(const Eigen::Quaterniond& q_nb);
Eigen::RowVector3d JimenezYawJacobian(const Eigen::Quaterniond& q_nb);

// Range from the tag at `anchor_m` to the reader p_rx = p_n + (0, 0, h_reader) (eq. 1 in 3-D;
// planar: horizontal only) and its Jacobian with respect to δPo.
double JimenezPredictedRange(const Eigen::Vector3d& p_n, const Eigen::Vector3d& anchor_m,
                             double reader_height_m, bool planar, Eigen::RowVector3d* jacobian);

// Error-state transition Φ of one strapdown step from `prior` over (prev, cur] (see above).
JimenezMatrix JimenezErrorTransition(const JimenezNominal& prior, const ImuSample& prev,
                                     const ImuSample& cur, const StrapdownOptions& strapdown);

// Injects the error `dx` (first 15 components) into `nominal` and resets it: applies G to the
// first 15 rows and columns of P (P may be augmented with clones: then it is 15+m square).
// Keeps P symmetric.
void JimenezInjectError(const JimenezVector& dx, JimenezNominal* nominal, Eigen::MatrixXd* P);

// Per-measurement-type figures of one run (for consistency checks and reports).
struct JimenezDetails {
  std::vector<double> nis_zupt;        // every accepted ZUPT (dof 3)
  std::vector<double> nis_zupt_first;  // the first ZUPT of each stance (dof 3)
  std::vector<double> nis_zaru;        // dof 3
  std::vector<double> nis_compass;     // dof 1
  std::vector<double> nis_range;       // dof 1
  StanceMask stance;
  std::string stance_detector;
};

// Why `options`' variant cannot run on `walk` (no IMU, not on a foot, no radio, stance labels
// or RSS units missing), or OK.
Status CheckJimenezApplicable(const Walk& walk, const JimenezIezOptions& options);
// The filter on a walk (EstimateResult::nis holds the range NIS when use_rss, else the ZUPT
// NIS). `details` may be null. Fails, like JimenezIez::Run, where CheckJimenezApplicable does.
StatusOr<EstimateResult> RunJimenezIez(const Walk& walk, const JimenezIezOptions& options,
                                       JimenezDetails* details = nullptr);

class JimenezIez : public Estimator {
 public:
  explicit JimenezIez(JimenezIezOptions options) : options_(std::move(options)) {}
  Status CheckApplicable(const Walk& walk) const override;
  StatusOr<EstimateResult> Run(const Walk& walk) const override;

 private:
  JimenezIezOptions options_;
};

}  // namespace walkgraph

#endif  // WALKGRAPH_FILTERS_JIMENEZ_H_
