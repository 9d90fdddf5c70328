// Pedestrian dead reckoning front end: IMU (waist/hip/handheld) → steps (length, heading).
//
// Attitude: a complementary (Mahony-style) filter integrates the gyro, q̇ = ½ q ⊗ (ω + k·e),
// with the tilt error e = â × ĝ_b (measured vs predicted gravity direction, accelerometer
// trusted only while |‖a‖ − g| is small). R(q) maps body to the ENU navigation frame.
//
// Step detectors (each yields step events with time, a_max, a_min, duration):
//  (a) kVerticalPeak — the vertical acceleration a_z^n = (R a)_z − g, low-pass filtered,
//      local maxima above a threshold, a_min the minimum between consecutive maxima
//      (000 Sec. III-B: "smoothing the signal with a low-pass filter and then searching for
//      local maxima and minima").
//  (b) kFirMagnitude — ‖a‖ filtered by a linear-phase FIR low-pass of order 20 at 3 Hz, local
//      maxima of ‖a‖_f − g above a threshold counted as steps (001 eq. 6).
//  (c) kEnergy — E_k = ‖a_k^n − g‖² (003 eq. 1; gravity removed, else the 10 (m/s²)² threshold
//      would always be exceeded), the first local maximum above 10 (m/s²)², later maxima within
//      300 ms rejected.
// Step length:
//   Weinberg  l = K·(a_max − a_min)^{1/4}               (000 eq. 3, 003 eq. 2), K = 0.45 (000 IV)
//   constant  l = l_step                                 (001, per-user constant)
//   linear    l = c0 + c1·f_step, f_step = 1/duration    (optional speed model)
// Heading:
//   kGyro           θ_i = θ_{i−1} + δT·ω_z^n, ω^n = R ω (000 eq. 4, gyro projected on the vertical)
//   kComplementary  θ = (1 − W)(θ + ω̄T) + W·θ_mag, blended on the circle, with θ_mag from the
//                   tilt-compensated magnetometer (001 eq. 7)
// Step direction: the body's forward axis in the horizontal plane is either given
// (forward_axis) or found by PCA of the horizontal acceleration a^b − g^b − a_z^n (003 eq. 3–5),
// its sign chosen from the correlation of forward and vertical acceleration (Kourogi & Kurata).
#ifndef WALKGRAPH_PDR_H_
#define WALKGRAPH_PDR_H_

#include <map>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "walkgraph/enum_names.h"
#include "walkgraph/measurements.h"
#include "walkgraph/status.h"
#include "walkgraph/strides.h"
#include "walkgraph/walk.h"

namespace walkgraph {

enum class StepDetector { kVerticalPeak, kFirMagnitude, kEnergy };
enum class StepLengthModel { kWeinberg, kConstant, kLinearFrequency };
// kAuto: kComplementary when the walk has a magnetometer and walk.yaml gives no start heading
// (the magnetometer is then the only absolute heading the walk has), else kGyro.
enum class HeadingMethod { kGyro, kComplementary, kAuto };
// The walking direction in the levelled body frame: the body x axis, the body y axis (a phone
// held in portrait in front of the walker: Android's y runs along the screen to its top), or
// the main axis of horizontal acceleration (PCA, 003) over the first pca_window_s, or kAuto: the
// horizontal direction whose acceleration leads the vertical one step after step (pdr.cc:
// AutoForwardAngle), snapped to the nearest body axis within forward_axis_snap_rad (the
// carriage found from the walk itself; a lateral sway at the stride frequency does not pass).
// Which maximum of an energy lockout span is the step (PdrOptions::energy_lockout_keep).
enum class EnergyLockoutKeep { kFirst, kStrongest };
const EnumNames<EnergyLockoutKeep>& EnergyLockoutKeepNames();  // first, strongest
const char* ToString(EnergyLockoutKeep k);
StatusOr<EnergyLockoutKeep> EnergyLockoutKeepFromString(const std::string& name);

enum class ForwardAxisMethod { kBodyX, kBodyY, kPca, kAuto };
// Vertical-peak thresholds: the options' values (kFixed), or raised above the walk's own
// standstill noise (kAuto; the options' values are then the least thresholds).
enum class StepThresholdMethod { kFixed, kAuto };

struct PdrOptions {
  StepDetector detector = StepDetector::kVerticalPeak;
  // (a) vertical peaks: low-pass cut-off (000 gives none; 5 Hz keeps steps of up to 3 Hz
  // undamped, which Weinberg's a_max − a_min needs) and the minimum peak of filtered a_z^n and
  // minimum a_max − a_min.
  double vertical_cutoff_hz = 5.0;
  double vertical_peak_mps2 = 0.5;
  double vertical_min_swing_mps2 = 1.0;
  // kAuto (our choice; no paper gives one): a phone held still in the hand shakes (σ 0.1-0.2
  // m/s² of filtered vertical acceleration on IPIN trials 01/05/52) and its peaks pass 0.5/1.0
  // as false steps. σ_still is the median σ of the walk's quieter 1-s windows (Otsu's split of
  // log σ into still and walking). When the walk has such a standstill — σ_still below
  // auto_still_ratio × the median peak of the steps the fixed thresholds find, and lively enough
  // to be a hand rather than a sensor at rest, auto_noise_sigmas·σ_still ≥ vertical_peak_mps2 —
  // a step must reach auto_step_fraction of the walk's median step peak and swing (the options'
  // values stay the least thresholds); other walks keep the options' values. auto_noise_sigmas
  // = 8 (σ_still ≥ 0.0625 m/s²) was chosen between a sensor at rest (simulated correa-corridor's
  // stops: 0.011) and the quietest hand seen (IPIN trial 21: 0.050, which does not need the
  // raise; trial 05: 0.125, which does).
  StepThresholdMethod step_thresholds = StepThresholdMethod::kAuto;
  double auto_still_ratio = 0.25;
  double auto_noise_sigmas = 8.0;
  double auto_step_fraction = 0.5;
  // (b) FIR order 20, 3 Hz (001 eq. 6); threshold on ‖a‖_f − g (001 does not give its value).
  int fir_order = 20;
  double fir_cutoff_hz = 3.0;
  double fir_peak_mps2 = 0.5;
  // (c) energy threshold and lockout (003 eq. 1).
  double energy_threshold_m2ps4 = 10.0;
  double energy_lockout_s = 0.3;  // maxima at most this long after a step are rejected
  // Which maximum of a lockout span is the step: "first" (003's wording read literally: maxima
  // within 300 ms after a step are rejected) or "strongest" (a larger maximum within 300 ms
  // replaces the step: one step per energy burst whatever its shape; the span still runs from
  // the burst's first maximum). 003 does not say which.
  EnergyLockoutKeep energy_lockout_keep = EnergyLockoutKeep::kFirst;
  // Shortest time between two steps for (a) and (b) (no paper value; 0.25 s ≈ 4 steps/s).
  double min_step_interval_s = 0.25;

  StepLengthModel length_model = StepLengthModel::kWeinberg;
  double weinberg_k = 0.45;  // 000 Sec. IV
  double constant_length_m = 0.7;
  double linear_c0_m = 0.25;  // l = c0 + c1·f_step
  double linear_c1_m_s = 0.25;
  double sigma_length_frac = 0.1;  // σ_l = frac·l + sigma_length_m
  double sigma_length_m = 0.02;

  HeadingMethod heading = HeadingMethod::kAuto;
  double complementary_w = 0.05;  // W of 001 eq. 7, applied once per step (001 gives no value)
  double mag_declination_rad = 0.0;
  ForwardAxisMethod forward_axis = ForwardAxisMethod::kAuto;
  double pca_window_s = 10.0;  // walking time used for the PCA (003: at initialisation)
  // kAuto: a device is carried along one of its axes (a waist IMU along x, a phone in portrait
  // along y), so a direction within this of a body axis is that axis. Our choice, 30°: the data's
  // direction on the IPIN hand-held walks lies 1-29° off body y (trials 21 and 52: 15-29°, where
  // body y gives the lower error); 0 keeps the data's direction. The steps must agree on the
  // direction by Rayleigh's test, z = n·R² ≥ auto_forward_min_z (6.9: p ≈ e^−z = 0.001 for
  // directions at random), else the device's default axis (body y handheld, else body x).
  double forward_axis_snap_rad = 0.52;
  double auto_forward_min_z = 6.9;
  // Per-step heading-increment σ and initial absolute heading σ (when not from initial_pose).
  double sigma_dheading_rad = 0.02;
  double sigma_heading0_rad = 0.1;

  double attitude_gain = 0.5;           // Mahony proportional gain (1/s)
  double attitude_acc_gate_mps2 = 1.5;  // use the accelerometer only if |‖a‖ − g| below this
  double gravity_mps2 = 9.81;

  // Foot-mounted IMUs: the stride front end (strides.h) that StepsForWalk uses instead.
  StrideOptions stride;

  // Every rule its YAML reader applies (ranges, enum values); DetectSteps and ComputeSteps refuse
  // options that break one.
  Status Validate() const;
};

// A detected step before length and heading are attached.
struct StepEvent {
  double t_s = 0.0;
  size_t imu_index = 0;
  double a_max_mps2 = 0.0;  // max / min of low-pass vertical acceleration since the last step
  double a_min_mps2 = 0.0;
  double duration_s = 0.0;  // since the previous step (0 for the first)
};

// Body-to-ENU attitude per IMU sample from the complementary filter (yaw starts at 0, or at
// the magnetometer heading when `use_mag` and the walk has a magnetometer).
StatusOr<std::vector<Eigen::Quaterniond>> EstimateAttitude(const std::vector<ImuSample>& imu,
                                                           const PdrOptions& options);

// Linear-phase FIR low-pass (Hamming-windowed sinc, `order`+1 taps, unit DC gain).
std::vector<double> DesignLowPassFir(int order, double cutoff_hz, double rate_hz);
// Applies `taps` with the group delay removed (edges padded with the end values).
std::vector<double> FilterZeroDelay(const std::vector<double>& x, const std::vector<double>& taps);

// Steps only (the chosen detector).
StatusOr<std::vector<StepEvent>> DetectSteps(const Walk& walk, const PdrOptions& options);

// The full front end: steps with length, absolute heading and heading increment. The heading
// starts at walk.meta.initial_pose (absolute_heading = true) or, with kComplementary and a
// magnetometer, at the magnetometer heading; otherwise at 0 (absolute_heading = false).
StatusOr<StepSequence> ComputeSteps(const Walk& walk, const PdrOptions& options);

// The heading method ComputeSteps applies to `walk`: options.heading with kAuto resolved.
HeadingMethod ResolveHeadingMethod(const Walk& walk, const PdrOptions& options);

// The front end's choices as estimator diagnostics: pdr_heading_source (0 relative, 1 walk.yaml
// initial_pose, 2 magnetometer) and, where the walk set them, pdr_forward_axis_deg (from body
// x, counter-clockwise), pdr_forward_axis_pca_deg, pdr_forward_sign_evidence,
// pdr_standstill_sigma_mps2, pdr_step_peak_mps2, pdr_vertical_peak_mps2,
// pdr_vertical_min_swing_mps2.
void AddFrontEndDiagnostics(const StepFrontEndReport& report, std::map<std::string, double>* d);

// One Step per odometry increment: the increment moves dist_m along the current heading and
// then turns dheading_rad, so step k has heading θ0 + Σ_{j<k} Δθ_j and dheading Δθ_{k−1}.
// θ0 is initial_pose.heading_rad when present (absolute_heading = true), else 0.
StepSequence StepsFromOdometry(const Walk& walk);

// The steps every step-level estimator consumes, so that a comparison differs only in the
// estimator: the odometry increments when the walk has odometry.csv, else the strides of
// ComputeStrides (options.stride) on a foot-mounted IMU, else ComputeSteps on a
// waist/hip/handheld IMU. Fails for a walk with neither odometry nor an IMU.
StatusOr<StepSequence> StepsForWalk(const Walk& walk, const PdrOptions& options);

}  // namespace walkgraph

#endif  // WALKGRAPH_PDR_H_
