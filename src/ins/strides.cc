#include "walkgraph/strides.h"

#include <algorithm>
#include <cmath>
#include <iterator>
#include <limits>
#include <map>
#include <string>

#include "config/reader.h"
#include "ins/strides_yaml.h"
#include "stance/stance_yaml.h"
#include "util/enum_define.h"
#include "util/median.h"
#include "walkgraph/angle.h"
#include "walkgraph/config.h"
#include "walkgraph/kalman.h"
#include "walkgraph/kalman_driver.h"

namespace walkgraph {

WALKGRAPH_DEFINE_ENUM_NAMES(ScaleNoiseAdaptation, "scale_noise_adaptation",
                            {"fixed", ScaleNoiseAdaptation::kFixed},
                            {"walk", ScaleNoiseAdaptation::kWalk},
                            {"causal", ScaleNoiseAdaptation::kCausal})

namespace {

// A stance-compensating still run may begin this long after the walk's first sample
// (StrideOptions::gyro_bias_start_rest_only), else anywhere.
constexpr double kInitialRestStartS = 1.0;

// Error-state layout.
constexpr int kP = 0, kV = 3, kTh = 6, kBa = 9, kBg = 12, kN = 15;

// The scale noise's values (strides.h), and how many first ZUPTs the causal adaptation weighs.
constexpr double kScaleNoiseLadder[] = {0.0, 0.002, 0.005, 0.01, 0.02, 0.05};
constexpr size_t kCausalNisCount = 5;
constexpr size_t kBankStances = 10;
// The χ² gate of a stance hypothesis's ZUPT (stance.h).
constexpr double kHypothesisGate = 0.999;

// The ladder's first rung at or above `s` (the last rung when none is).
size_t LadderRung(double s) {
  size_t r = 0;
  while (r + 1 < std::size(kScaleNoiseLadder) && kScaleNoiseLadder[r] < s) ++r;
  return r;
}

// Yaw of a body-to-ENU rotation: the ENU angle of the body x axis on the horizontal.
double Yaw(const Eigen::Quaterniond& q) {
  const Eigen::Matrix3d r = q.toRotationMatrix();
  return std::atan2(r(1, 0), r(0, 0));
}

// R = Rz(ψ)·Ry(θ)·Rx(φ) with roll and pitch such that R·f̄ points up (f̄: specific force at rest).
Eigen::Quaterniond LevelledAttitude(const Eigen::Vector3d& f, double yaw) {
  const double roll = std::atan2(f.y(), f.z());
  const double pitch = std::atan2(-f.x(), std::hypot(f.y(), f.z()));
  return (Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()) *
          Eigen::AngleAxisd(pitch, Eigen::Vector3d::UnitY()) *
          Eigen::AngleAxisd(roll, Eigen::Vector3d::UnitX()))
      .normalized();
}

// Stance runs → phases: drop runs shorter than min_stance_s, merge runs whose gap is shorter
// than min_swing_s. `zupt` marks the samples of the kept runs.
std::vector<StancePhase> StancePhases(const std::vector<ImuSample>& imu, const StanceMask& mask,
                                      const StrideOptions& o, std::vector<bool>* zupt) {
  std::vector<StancePhase> runs;
  const std::vector<bool>& stance = mask.stance;
  const size_t n = stance.size();
  const bool cycles = mask.cycle_minimum.size() == n;
  for (size_t i = 0; i < n;) {
    if (!stance[i]) {
      ++i;
      continue;
    }
    size_t j = i;
    bool cycle_minimum = cycles && mask.cycle_minimum[i];
    while (j + 1 < n && stance[j + 1]) {
      ++j;
      cycle_minimum = cycle_minimum || (cycles && mask.cycle_minimum[j]);
    }
    // A gait cycle's stance is kept however short (a running foot is still for milliseconds).
    if (cycle_minimum || imu[j].t_s - imu[i].t_s >= o.min_stance_s) runs.push_back({i, j});
    i = j + 1;
  }
  zupt->assign(n, false);
  std::vector<StancePhase> phases;
  for (const StancePhase& r : runs) {
    for (size_t i = r.begin; i <= r.end; ++i) (*zupt)[i] = true;
    if (!phases.empty() && imu[r.begin].t_s - imu[phases.back().end].t_s < o.min_swing_s) {
      phases.back().end = r.end;
    } else {
      phases.push_back(r);
    }
  }
  return phases;
}

Status CheckOptions(const StrideOptions& o) {
  WG_RETURN_IF_ERROR(CheckEnumOption(ScaleNoiseAdaptationNames(), o.scale_noise_adaptation,
                                     "scale_noise_adaptation", "strides"));
  if (!(o.gravity_mps2 > 0) || !(o.acc_noise_mps2 > 0) || !(o.gyro_noise_radps > 0) ||
      o.acc_bias_sigma_mps2 < 0 || o.gyro_bias_sigma_radps < 0 || o.acc_bias_rw_mps2_sqrts < 0 ||
      o.gyro_bias_rw_radps_sqrts < 0 || !(o.zupt_sigma_mps > 0) || !(o.zaru_sigma_radps > 0) ||
      o.tilt_sigma_rad < 0 || o.min_stance_s < 0 || o.min_swing_s < 0 || o.min_sigma_length_m < 0 ||
      !(o.scale_noise >= 0 && o.scale_noise < 1) || !(o.max_median_zupt_nis > 0) ||
      !(o.zupt_gross_gate_ratio >= 0) || o.min_sigma_heading_rad < 0 ||
      o.min_sigma_dheading_rad < 0) {
    return InvalidArgument(
        "strides: need gravity, white noises, pseudo-measurement sigmas and "
        "max_median_zupt_nis > 0, scale_noise in [0, 1), zupt_gross_gate_ratio and every other "
        "sigma and duration >= 0");
  }
  return Status::Ok();
}

// Mean gyro over the first run of `flags` lasting at least min_s; false if none, or if that
// run begins more than start_max_s after the walk's first sample.
bool FirstRunGyroMean(const std::vector<ImuSample>& imu, const std::vector<bool>& flags,
                      double min_s, double start_max_s, Eigen::Vector3d* mean) {
  for (size_t i = 0; i < flags.size();) {
    if (!flags[i]) {
      ++i;
      continue;
    }
    size_t j = i;
    while (j + 1 < flags.size() && flags[j + 1]) ++j;
    if (imu[j].t_s - imu[i].t_s >= min_s) {
      if (imu[i].t_s - imu[0].t_s > start_max_s) return false;
      *mean = Eigen::Vector3d::Zero();
      for (size_t k = i; k <= j; ++k) *mean += imu[k].gyro_radps;
      *mean /= static_cast<double>(j - i + 1);
      return true;
    }
    i = j + 1;
  }
  return false;
}

// Mean gyro over the rest the walk starts with: consecutive 0.5 s windows from the first sample
// whose per-axis gyro std and ‖a‖ std stay below the still thresholds (spreads, not magnitudes:
// they do not depend on the bias). False when that rest lasts less than 1 s.
bool InitialRestGyroMean(const std::vector<ImuSample>& imu, const StanceOptions& o,
                         Eigen::Vector3d* mean) {
  size_t begin = 0, end = 0;  // accepted [0, end)
  while (begin < imu.size()) {
    size_t stop = begin;
    while (stop < imu.size() && imu[stop].t_s - imu[begin].t_s < 0.5) ++stop;
    if (stop == imu.size() || stop - begin < 3) break;
    Eigen::Vector3d m = Eigen::Vector3d::Zero(), m2 = Eigen::Vector3d::Zero();
    double a = 0.0, a2 = 0.0;
    for (size_t k = begin; k < stop; ++k) {
      m += imu[k].gyro_radps;
      m2 += imu[k].gyro_radps.cwiseAbs2();
      const double an = imu[k].acc_mps2.norm();
      a += an;
      a2 += an * an;
    }
    const double n = static_cast<double>(stop - begin);
    const Eigen::Vector3d var = m2 / n - (m / n).cwiseAbs2();
    const double acc_var = a2 / n - (a / n) * (a / n);
    if (var.maxCoeff() > o.still_gyro_radps * o.still_gyro_radps ||
        acc_var > o.still_acc_std_mps2 * o.still_acc_std_mps2) {
      break;
    }
    end = stop;
    begin = stop;
  }
  if (end == 0 || imu[end - 1].t_s - imu[0].t_s < 1.0) return false;
  *mean = Eigen::Vector3d::Zero();
  for (size_t k = 0; k < end; ++k) *mean += imu[k].gyro_radps;
  *mean /= static_cast<double>(end);
  return true;
}

Status CheckImu(const Walk& walk) {
  if (walk.imu.empty()) return FailedPrecondition("strides: the walk needs an IMU (imu.csv)");
  if (walk.imu.size() < 10) {
    return FailedPrecondition("strides: the walk has " + std::to_string(walk.imu.size()) +
                              " IMU samples; expected at least 10");
  }
  for (size_t i = 1; i < walk.imu.size(); ++i) {
    if (!(walk.imu[i].t_s > walk.imu[i - 1].t_s)) {
      return InvalidArgument("strides: IMU time does not increase at sample " + std::to_string(i));
    }
  }
  return Status::Ok();
}

// Stance of the walk; with compensate_gyro_bias, detected again on the gyro less the bias of
// the first still run (≥ 0.5 s), else of the rest the walk starts with (found by spreads, for
// when the bias itself keeps ‖ω‖ above the still threshold). `bg0` receives that bias (or 0).
StatusOr<StanceMask> StanceWithGyroBias(const Walk& walk, const StrideOptions& o,
                                        Eigen::Vector3d* bg0) {
  WG_ASSIGN_OR_RETURN(StanceMask stance, DetectStance(walk, o.stance));
  *bg0 = Eigen::Vector3d::Zero();
  if (o.compensate_gyro_bias &&
      (FirstRunGyroMean(walk.imu, stance.still, 0.5,
                        o.gyro_bias_start_rest_only ? kInitialRestStartS
                                                    : std::numeric_limits<double>::infinity(),
                        bg0) ||
       InitialRestGyroMean(walk.imu, o.stance, bg0))) {
    Walk compensated;
    compensated.meta = walk.meta;
    compensated.imu = walk.imu;
    for (ImuSample& s : compensated.imu) s.gyro_radps -= *bg0;
    return DetectStance(compensated, o.stance);
  }
  return stance;
}

// Mean specific force for the initial attitude: of the first stance phase (at most 2 s of it),
// else of the first 20 samples.
StatusOr<Eigen::Vector3d> LevellingForce(const std::vector<ImuSample>& imu,
                                         const std::vector<StancePhase>& phases) {
  const size_t n = imu.size();
  size_t lev_begin = 0, lev_end = std::min<size_t>(n - 1, 19);
  if (!phases.empty()) {
    lev_begin = phases[0].begin;
    lev_end = phases[0].end;
    while (lev_end > lev_begin && imu[lev_end].t_s - imu[lev_begin].t_s > 2.0) --lev_end;
  }
  Eigen::Vector3d f_mean = Eigen::Vector3d::Zero();
  for (size_t i = lev_begin; i <= lev_end; ++i) f_mean += imu[i].acc_mps2;
  f_mean /= static_cast<double>(lev_end - lev_begin + 1);
  if (f_mean.norm() < 1e-6) return FailedPrecondition("strides: zero specific force at rest");
  return f_mean;
}

Eigen::MatrixXd InitialCovariance(const StrideOptions& o) {
  Eigen::MatrixXd P = Eigen::MatrixXd::Zero(kN, kN);
  P.block<3, 3>(kV, kV).diagonal().setConstant(o.zupt_sigma_mps * o.zupt_sigma_mps);
  P(kTh, kTh) = P(kTh + 1, kTh + 1) = o.tilt_sigma_rad * o.tilt_sigma_rad;
  P.block<3, 3>(kBa, kBa).diagonal().setConstant(o.acc_bias_sigma_mps2 * o.acc_bias_sigma_mps2);
  P.block<3, 3>(kBg, kBg).diagonal().setConstant(o.gyro_bias_sigma_radps * o.gyro_bias_sigma_radps);
  return P;
}

// Error-state transition F and process noise Q over dt (see the header), from the attitude R
// and bias-corrected specific force f_b before the step. An IMU gap longer than max_dt_s is held
// by StrapdownStep: the walker went anywhere within walking speed (kImuGapSpeedMps × dt per
// axis), at any speed and heading.
void ErrorTransition(const Eigen::Matrix3d& R, const Eigen::Vector3d& f_b, double w_norm, double dt,
                     double max_dt_s, const StrideOptions& o, double scale_noise,
                     Eigen::MatrixXd* F, Eigen::MatrixXd* Q) {
  const double s2 = scale_noise * scale_noise;
  const double sa2 = o.acc_noise_mps2 * o.acc_noise_mps2 + s2 * f_b.squaredNorm();
  const double sg2 = o.gyro_noise_radps * o.gyro_noise_radps + s2 * w_norm * w_norm;
  const Eigen::Matrix3d fx = Skew(R * f_b);
  F->setIdentity();
  F->block<3, 3>(kP, kV) = Eigen::Matrix3d::Identity() * dt;
  F->block<3, 3>(kP, kTh) = -0.5 * fx * dt * dt;
  F->block<3, 3>(kP, kBa) = -0.5 * R * dt * dt;
  F->block<3, 3>(kV, kTh) = -fx * dt;
  F->block<3, 3>(kV, kBa) = -R * dt;
  F->block<3, 3>(kTh, kBg) = -R * dt;
  Q->setZero();
  const Eigen::Matrix3d I3 = Eigen::Matrix3d::Identity();
  Q->block<3, 3>(kP, kP) = 0.25 * sa2 * dt * dt * dt * dt * I3;
  Q->block<3, 3>(kP, kV) = 0.5 * sa2 * dt * dt * dt * I3;
  Q->block<3, 3>(kV, kP) = 0.5 * sa2 * dt * dt * dt * I3;
  Q->block<3, 3>(kV, kV) = sa2 * dt * dt * I3;
  Q->block<3, 3>(kTh, kTh) = sg2 * dt * dt * I3;
  Q->block<3, 3>(kBa, kBa) = o.acc_bias_rw_mps2_sqrts * o.acc_bias_rw_mps2_sqrts * dt * I3;
  Q->block<3, 3>(kBg, kBg) = o.gyro_bias_rw_radps_sqrts * o.gyro_bias_rw_radps_sqrts * dt * I3;
  if (dt > max_dt_s) {
    F->setIdentity();
    Q->block<3, 3>(kP, kP) += std::pow(kImuGapSpeedMps * dt, 2) * I3;
    Q->block<3, 3>(kV, kV) += kImuGapSpeedMps * kImuGapSpeedMps * I3;
    (*Q)(kTh + 2, kTh + 2) += kPi * kPi;
  }
}

// The filter's covariance of (δp_x, δp_y, δψ), symmetrized.
Eigen::Matrix3d StrideBlock(const Eigen::MatrixXd& P) {
  const int idx[3] = {kP, kP + 1, kTh + 2};
  Eigen::Matrix3d c;
  for (int a = 0; a < 3; ++a) {
    for (int b = 0; b < 3; ++b) c(a, b) = P(idx[a], idx[b]);
  }
  return 0.5 * (c + c.transpose());
}

// Position and yaw restart at a reset: their rows and columns of P are zeroed.
void ResetStrideRows(Eigen::MatrixXd* P) {
  for (int r : {kP, kP + 1, kP + 2, kTh + 2}) {
    P->row(r).setZero();
    P->col(r).setZero();
  }
}

// The stride ending at t_s: horizontal displacement d and yaw since the last reset (yaw_ref at
// t_ref), its length and direction σ from the filter's covariance c of (δp_x, δp_y, δψ);
// heading_var accumulates the yaw-change variances.
Step MakeStride(double t_s, double t_ref, const Eigen::Vector2d& d, double yaw, double yaw_ref,
                const Eigen::Matrix3d& c, const StrideOptions& o, double* heading_var) {
  Step s;
  s.t_s = t_s;
  s.duration_s = t_s - t_ref;
  s.length_m = d.norm();
  const Eigen::Vector2d u = s.length_m > 1e-9 ? Eigen::Vector2d(d / s.length_m)
                                              : Eigen::Vector2d(std::cos(yaw), std::sin(yaw));
  const Eigen::Vector2d nrm(-u.y(), u.x());
  s.heading_rad = NormalizeAngle(std::atan2(u.y(), u.x()));
  s.dheading_rad = NormalizeAngle(yaw - yaw_ref);
  const Eigen::Matrix2d cxy = c.topLeftCorner<2, 2>();
  s.sigma_length_m = std::max(std::sqrt(std::max(0.0, u.dot(cxy * u))), o.min_sigma_length_m);
  const double sigma_dir = std::sqrt(std::max(0.0, nrm.dot(cxy * nrm))) / std::max(s.length_m, 0.1);
  s.sigma_dheading_rad = std::max(std::sqrt(std::max(0.0, c(2, 2))), o.min_sigma_dheading_rad);
  *heading_var += s.sigma_dheading_rad * s.sigma_dheading_rad;
  s.sigma_heading_rad =
      std::max(std::sqrt(*heading_var + sigma_dir * sigma_dir), o.min_sigma_heading_rad);
  return s;
}

}  // namespace

StanceOptions StrideOptions::DefaultStance() {
  StanceOptions s;
  s.detector = StanceDetector::kGaitGlrt;
  s.glrt_threshold = 3e3;  // the adaptive detector's fallback (and the fixed GLRT's γ)
  return s;
}

StrideOptions StrideOptions::Causal() const {
  StrideOptions o = *this;
  if (o.scale_noise_adaptation == ScaleNoiseAdaptation::kWalk) {
    o.scale_noise_adaptation = ScaleNoiseAdaptation::kCausal;
  }
  o.stance.adaptive_causal = true;
  o.stance.adaptive_window_s = 60.0;
  o.gyro_bias_start_rest_only = true;
  return o;
}

StatusOr<StrideOptions> StrideOptionsFromYaml(const YAML::Node& node) {
  return StrideOptionsFromYaml(node, StrideOptions());
}

StatusOr<StrideOptions> StrideOptionsFromYaml(const YAML::Node& node, const StrideOptions& base) {
  StrideOptions o = base;
  ConfigReader r(node, "strides");
  r.ReadEnum("sampling", &o.sampling, ImuSamplingNames(),
             "IMU sample convention (strapdown.h): interval averages or instantaneous values");
  const YAML::Node stance = r.Child("stance");
  r.Read("compensate_gyro_bias", &o.compensate_gyro_bias,
         "subtract the gyro mean of the first still run before detecting stance again");
  r.Read("gyro_bias_start_rest_only", &o.gyro_bias_start_rest_only,
         "that still run only if it begins within 1 s of the walk's start");
  r.Read("gravity_mps2", &o.gravity_mps2, "local gravity magnitude");
  r.Read("acc_noise_mps2", &o.acc_noise_mps2,
         "accelerometer white noise per reading (Xsens MTi, 004 Table I)");
  r.Read("gyro_noise_radps", &o.gyro_noise_radps,
         "gyro white noise per reading (Xsens MTi, 004 Table I)");
  r.Read("acc_bias_sigma_mps2", &o.acc_bias_sigma_mps2,
         "turn-on accelerometer bias std-dev (004 Table I bias stability)");
  r.Read("gyro_bias_sigma_radps", &o.gyro_bias_sigma_radps,
         "turn-on gyro bias std-dev (004 Table I bias stability)");
  r.Read("acc_bias_rw_mps2_sqrts", &o.acc_bias_rw_mps2_sqrts,
         "accelerometer bias random walk per sqrt(s) (no paper value)");
  r.Read("gyro_bias_rw_radps_sqrts", &o.gyro_bias_rw_radps_sqrts,
         "gyro bias random walk per sqrt(s) (no paper value)");
  r.Read("scale_noise", &o.scale_noise,
         "scale-factor noise: each reading's sigma grows by this fraction of its norm (the least "
         "value tried when adapted)");
  r.ReadEnum("scale_noise_adaptation", &o.scale_noise_adaptation, ScaleNoiseAdaptationNames(),
             "scale_noise as given (fixed), or the least whose first-ZUPT NIS is plausible over "
             "the walk (walk) or, stepping up, over the last stances (causal)");
  r.Read("max_median_zupt_nis", &o.max_median_zupt_nis,
         "adapted scale noise: largest median NIS of the stances' first ZUPTs");
  r.Read("zupt_sigma_mps", &o.zupt_sigma_mps, "ZUPT std-dev per axis (OpenShoe)");
  r.Read("zupt_gross_gate_ratio", &o.zupt_gross_gate_ratio,
         "a stance run's ZUPTs are not applied while their NIS exceeds this many times the "
         "walk's median first-ZUPT NIS so far (0: no gate)");
  r.Read("zaru_sigma_radps", &o.zaru_sigma_radps, "ZARU std-dev per axis (the gyro's white noise)");
  r.Read("use_zaru", &o.use_zaru, "zero angular-rate updates when still");
  r.Read("tilt_sigma_rad", &o.tilt_sigma_rad, "std-dev of the levelled initial roll/pitch");
  r.Read("min_stance_s", &o.min_stance_s, "shorter stance runs are detector blips, not stances");
  r.Read("min_swing_s", &o.min_swing_s, "shorter swings between stances are no stride");
  r.Read("wait_for_first_stance", &o.wait_for_first_stance,
         "a walk that starts in a swing: the INS starts at its first stance phase (position held "
         "until then)");
  r.Read("min_sigma_length_m", &o.min_sigma_length_m,
         "floor on each stride's length std-dev (the filter is optimistic)");
  r.Read("min_sigma_heading_rad", &o.min_sigma_heading_rad,
         "floor on each stride's heading std-dev");
  r.Read("min_sigma_dheading_rad", &o.min_sigma_dheading_rad,
         "floor on each stride's heading-change std-dev");
  WG_RETURN_IF_ERROR(r.Finish());
  if (stance.IsDefined()) {
    // Keys absent from the map keep this front end's defaults (not stance.h's).
    WG_ASSIGN_OR_RETURN(o.stance, StanceOptionsFromYaml(stance, o.stance));
  }
  WG_RETURN_IF_ERROR(CheckOptions(o));
  return o;
}

Status StrideOptions::Validate() const { return CheckOptions(*this); }

namespace {

// The running filter: nominal state, biases and the error covariance. Each update of the error
// state is injected into the nominal state at once (the error resets). While the causal
// adaptation has not settled, `bank` holds the covariance at every rung of the ladder: the same
// transitions and updates with each rung's process noise (the mean follows P's gains), so that
// each first ZUPT's NIS is known at every rung.
struct ZuptInsFilter {
  NavState x;
  Eigen::Vector3d ba = Eigen::Vector3d::Zero(), bg = Eigen::Vector3d::Zero();
  Eigen::MatrixXd P;
  Eigen::MatrixXd F = Eigen::MatrixXd::Identity(kN, kN), Q = Eigen::MatrixXd::Zero(kN, kN);
  double scale_noise = 0.0;  // StrideOptions::scale_noise as adapted for the walk
  std::vector<Eigen::MatrixXd> bank;

  // The NIS an update would have with covariance `Pr` (nothing changes).
  static StatusOr<double> Nis(const Eigen::VectorXd& innovation, const Eigen::MatrixXd& H,
                              double sigma, Eigen::MatrixXd Pr) {
    const Eigen::MatrixXd R =
        Eigen::MatrixXd::Identity(innovation.size(), innovation.size()) * (sigma * sigma);
    Eigen::VectorXd dx = Eigen::VectorXd::Zero(kN);
    WG_ASSIGN_OR_RETURN(const UpdateOutcome o, KalmanUpdate(innovation, H, R, 0.0, &dx, &Pr));
    return o.nis;
  }

  // The NIS an update would have at each rung of the bank (nothing changes).
  StatusOr<std::vector<double>> BankNis(const Eigen::VectorXd& innovation, const Eigen::MatrixXd& H,
                                        double sigma) const {
    std::vector<double> out;
    for (const Eigen::MatrixXd& Pr : bank) {
      WG_ASSIGN_OR_RETURN(const double nis, Nis(innovation, H, sigma, Pr));
      out.push_back(nis);
    }
    return out;
  }

  // The update's NIS goes to *nis, the bank's (per rung) to *bank_nis, when given.
  // A gated update (its NIS above max_nis) changes nothing and returns false in *accepted.
  Status Update(const Eigen::VectorXd& innovation, const Eigen::MatrixXd& H, double sigma,
                double* nis = nullptr, std::vector<double>* bank_nis = nullptr,
                double max_nis = std::numeric_limits<double>::infinity(),
                bool* accepted = nullptr) {
    Eigen::VectorXd dx = Eigen::VectorXd::Zero(kN);
    const Eigen::MatrixXd R =
        Eigen::MatrixXd::Identity(innovation.size(), innovation.size()) * (sigma * sigma);
    if (bank_nis != nullptr) bank_nis->clear();
    if (std::isfinite(max_nis)) {
      WG_ASSIGN_OR_RETURN(const double test_nis, Nis(innovation, H, sigma, P));
      const bool pass = test_nis <= max_nis;
      if (accepted != nullptr) *accepted = pass;
      if (!pass) return Status::Ok();
    }
    for (Eigen::MatrixXd& Pr : bank) {
      Eigen::VectorXd dx_r = Eigen::VectorXd::Zero(kN);
      WG_ASSIGN_OR_RETURN(const UpdateOutcome o, KalmanUpdate(innovation, H, R, 0.0, &dx_r, &Pr));
      if (bank_nis != nullptr) bank_nis->push_back(o.nis);
    }
    WG_ASSIGN_OR_RETURN(const UpdateOutcome outcome, KalmanUpdate(innovation, H, R, 0.0, &dx, &P));
    if (nis != nullptr) *nis = outcome.nis;
    x.p_n += dx.segment<3>(kP);
    x.v_n += dx.segment<3>(kV);
    x.q_nb = (QuaternionExp(dx.segment<3>(kTh)) * x.q_nb).normalized();
    ba += dx.segment<3>(kBa);
    bg += dx.segment<3>(kBg);
    return Status::Ok();
  }

  // Strapdown mechanization over [prev, cur] and the error covariance with it.
  void Predict(const ImuSample& prev, const ImuSample& cur, const StrideOptions& o,
               StrapdownOptions* sd) {
    const double dt = cur.t_s - prev.t_s;
    const Eigen::Matrix3d R = x.q_nb.toRotationMatrix();
    const Eigen::Vector3d f_b = o.sampling == ImuSampling::kIntervalAverage
                                    ? Eigen::Vector3d(cur.acc_mps2 - ba)
                                    : Eigen::Vector3d(0.5 * (prev.acc_mps2 + cur.acc_mps2) - ba);
    const double w_norm = cur.gyro_radps.norm();
    for (size_t r = 0; r < bank.size(); ++r) {
      ErrorTransition(R, f_b, w_norm, dt, sd->max_dt_s, o, kScaleNoiseLadder[r], &F, &Q);
      bank[r] = F * bank[r] * F.transpose() + Q;
      Symmetrize(&bank[r]);
    }
    ErrorTransition(R, f_b, w_norm, dt, sd->max_dt_s, o, scale_noise, &F, &Q);
    sd->acc_bias_mps2 = ba;
    sd->gyro_bias_radps = bg;
    x = StrapdownStep(x, prev, cur, *sd);
    P = F * P * F.transpose() + Q;
    Symmetrize(&P);
  }
};

// The strides: at the reference sample the stride origin (position, yaw) is set, at the end of
// each later stance phase a stride is emitted; either way position and yaw restart (their rows
// of P are reset).
class StrideEmitter {
 public:
  StrideEmitter(const std::vector<ImuSample>& imu, const StrideOptions& o, size_t first_phase,
                const InitialPose* pose0, const NavState& x0)
      : imu_(imu),
        o_(o),
        next_phase_(first_phase),
        p_ref_(x0.p_n),
        yaw_ref_(Yaw(x0.q_nb)),
        t_ref_(imu[0].t_s),
        heading_var_(pose0 ? pose0->sigma_heading_rad * pose0->sigma_heading_rad : 0.0) {}

  void At(size_t k, ZuptInsFilter* f, ZuptInsSolution* out) {
    if (k != out->reference_index) {
      if (next_phase_ >= out->phases.size() || out->phases[next_phase_].end != k) return;
      ++next_phase_;
      const Eigen::Matrix3d& c = out->stride_covariance[k];
      out->strides.steps.push_back(MakeStride(imu_[k].t_s, t_ref_, (f->x.p_n - p_ref_).head<2>(),
                                              Yaw(f->x.q_nb), yaw_ref_, c, o_, &heading_var_));
      out->stride_end.push_back(k);
      out->stride_increment_covariance.push_back(c);
    }
    p_ref_ = f->x.p_n;
    yaw_ref_ = Yaw(f->x.q_nb);
    t_ref_ = imu_[k].t_s;
    ResetStrideRows(&f->P);
    for (Eigen::MatrixXd& Pr : f->bank) ResetStrideRows(&Pr);
  }

 private:
  const std::vector<ImuSample>& imu_;
  const StrideOptions& o_;
  size_t next_phase_;
  Eigen::Vector3d p_ref_;
  double yaw_ref_, t_ref_, heading_var_;
};

// The ZUPT-aided INS as an error-state model (kalman_driver.h): every sample is an output epoch
// whose output is the sample's record in the solution, then the stride reset or emission.
class ZuptInsModel final : public ErrorStateModel {
 public:
  // `start`: the sample the INS starts at (RunZuptInsWith); before it the state is held.
  ZuptInsModel(const std::vector<ImuSample>& imu, const StrideOptions& o, bool zaru, size_t rung,
               size_t start, ZuptInsFilter f, StrapdownOptions sd, StrideEmitter strides,
               ZuptInsSolution* out)
      : imu_(imu),
        o_(o),
        zaru_(zaru),
        start_(start),
        first_rung_(rung),
        rung_(rung),
        f_(std::move(f)),
        sd_(sd),
        strides_(std::move(strides)),
        out_(*out) {
    H_zupt_.block<3, 3>(0, kV).setIdentity();
    H_zaru_.block<3, 3>(0, kBg).setIdentity();
  }

  size_t size() const override { return imu_.size(); }
  double Time(size_t k) const override { return imu_[k].t_s; }

  Status Propagate(size_t k) override {
    if (k <= start_) {
      f_.x.t_s = imu_[k].t_s;  // waiting for the first stance: held
    } else {
      f_.Predict(imu_[k - 1], imu_[k], o_, &sd_);
    }
    return Status::Ok();
  }

  // ZUPT in the kept stance runs, ZARU when still.
  Status Update(size_t k) override {
    if (k < start_) return Status::Ok();
    if (out_.zupt[k]) {
      // The first ZUPT of a stance run tests the swing's propagation (its NIS). A stance
      // hypothesis (stance.h) only when its χ² test passes.
      double nis = 0.0;
      std::vector<double> bank_nis;
      const bool hypothesis = !out_.stance.hypothesis.empty() && out_.stance.hypothesis[k];
      if (k == 0 || !out_.zupt[k - 1]) run_applied_ = run_gated_ = false;
      bool accepted = true;
      const bool first = k > start_ && !out_.zupt[k - 1];
      const double gate = hypothesis ? ChiSquareQuantile(kHypothesisGate, 3) : GrossGate(k);
      if (first && !f_.bank.empty()) {
        // A first ZUPT the gate passes (at the rung so far) takes its update at the rung its NIS
        // selects: at the rung before, a swing the scale noise had to explain went into the
        // state at that rung's gains (a running walk without rest: its first ZUPT put 0.17
        // rad/s into the gyro bias, 10σ).
        WG_ASSIGN_OR_RETURN(const double nis_now,
                            ZuptInsFilter::Nis(-f_.x.v_n, H_zupt_, o_.zupt_sigma_mps, f_.P));
        if (nis_now <= gate) {
          WG_ASSIGN_OR_RETURN(const std::vector<double> now,
                              f_.BankNis(-f_.x.v_n, H_zupt_, o_.zupt_sigma_mps));
          rung_ = BankRung(now);
          f_.P = f_.bank[rung_];
          f_.scale_noise = kScaleNoiseLadder[rung_];
        }
      }
      WG_RETURN_IF_ERROR(
          f_.Update(-f_.x.v_n, H_zupt_, o_.zupt_sigma_mps, &nis, &bank_nis, gate, &accepted));
      if (!accepted && hypothesis) ++out_.hypotheses_gated;
      if (!accepted && !hypothesis && !run_gated_) ++out_.runs_gated;
      run_gated_ = run_gated_ || (!accepted && !hypothesis);
      if (accepted && first) FirstZupt(nis, bank_nis);
      if (accepted) {
        run_applied_ = true;
        last_applied_t_ = imu_[k].t_s;
      }
    }
    if (zaru_ && out_.stance.still[k]) {
      WG_RETURN_IF_ERROR(f_.Update(imu_[k].gyro_radps - f_.bg, H_zaru_, o_.zaru_sigma_radps));
    }
    return Status::Ok();
  }

  void Output(size_t k, std::vector<TrajectoryPoint>*) override {
    out_.scale_noise[k] = f_.scale_noise;
    out_.states[k] = f_.x;
    out_.acc_bias_mps2[k] = f_.ba;
    out_.gyro_bias_radps[k] = f_.bg;
    out_.stride_covariance[k] = StrideBlock(f_.P);
    strides_.At(k, &f_, &out_);
  }

 private:
  // The largest NIS of a ZUPT at sample k that is applied (StrideOptions::
  // zupt_gross_gate_ratio); infinity: no gate.
  double GrossGate(size_t k) const {
    const double inf = std::numeric_limits<double>::infinity();
    if (!(o_.zupt_gross_gate_ratio > 0.0) || run_applied_ ||
        !(imu_[k].t_s - last_applied_t_ <= o_.stance.gait_max_gap_s)) {
      return inf;
    }
    // The walk's NIS scale: its median first-ZUPT NIS once it has kBankStances of them; before,
    // the largest median the scale-noise adaptation accepts.
    const double scale = out_.first_zupt_nis.size() < kBankStances
                             ? o_.max_median_zupt_nis
                             : internal::Median(out_.first_zupt_nis);
    return o_.zupt_gross_gate_ratio * std::max(chi_square_3_median_, scale);
  }

  // Records a first-ZUPT NIS. Causal adaptation: at each of the first kBankStances first ZUPTs,
  // the least rung whose median NIS over them so far is at most max_median_zupt_nis (from the
  // bank); after them, one rung up whenever the median of the last kCausalNisCount exceeds it.
  void FirstZupt(double nis, const std::vector<double>& bank_nis) {
    out_.first_zupt_nis.push_back(nis);
    if (o_.scale_noise_adaptation != ScaleNoiseAdaptation::kCausal) return;
    if (!f_.bank.empty()) {
      // The rung was chosen before the update (Update), with this NIS.
      bank_nis_.resize(bank_nis.size());
      for (size_t r = 0; r < bank_nis.size(); ++r) bank_nis_[r].push_back(bank_nis[r]);
      if (bank_nis_[0].size() >= kBankStances) f_.bank.clear();
      return;
    }
    recent_nis_.push_back(nis);
    if (recent_nis_.size() < kCausalNisCount) return;
    const double median = internal::Median(recent_nis_);
    recent_nis_.erase(recent_nis_.begin());
    if (median <= o_.max_median_zupt_nis || rung_ + 1 >= std::size(kScaleNoiseLadder)) return;
    f_.scale_noise = kScaleNoiseLadder[++rung_];
    recent_nis_.clear();
  }

  // The least rung from first_rung_ whose median NIS over the bank's first ZUPTs so far and
  // `now` (this one's, per rung) is at most max_median_zupt_nis.
  size_t BankRung(const std::vector<double>& now) const {
    size_t r = first_rung_;
    for (; r + 1 < now.size(); ++r) {
      std::vector<double> nis = r < bank_nis_.size() ? bank_nis_[r] : std::vector<double>();
      nis.push_back(now[r]);
      if (internal::Median(nis) <= o_.max_median_zupt_nis) break;
    }
    return r;
  }

  const std::vector<ImuSample>& imu_;
  const StrideOptions& o_;
  const bool zaru_;
  const size_t start_;
  size_t first_rung_ = 0;  // the rung of StrideOptions::scale_noise
  size_t rung_ = 0;        // causal adaptation: index of f_.scale_noise in kScaleNoiseLadder
  std::vector<std::vector<double>> bank_nis_;  // per rung, the first ZUPTs' NIS so far
  std::vector<double> recent_nis_;
  bool run_applied_ = false;  // a ZUPT of the current stance run was applied
  bool run_gated_ = false;    // one was turned down by the gross-error gate
  double last_applied_t_ = -std::numeric_limits<double>::infinity();
  const double chi_square_3_median_ = ChiSquareQuantile(0.5, 3);  // 2.366
  ZuptInsFilter f_;
  StrapdownOptions sd_;
  StrideEmitter strides_;
  ZuptInsSolution& out_;
  Eigen::MatrixXd H_zupt_ = Eigen::MatrixXd::Zero(3, kN), H_zaru_ = Eigen::MatrixXd::Zero(3, kN);
};

}  // namespace

namespace {

// The ZUPT-aided INS with the given stance, gyro bias and scale noise (its rung of the ladder,
// or a value of the user's off it with kFixed).
StatusOr<ZuptInsSolution> RunZuptInsWith(const Walk& walk, const StrideOptions& o,
                                         const StanceMask& stance, const Eigen::Vector3d& bg0,
                                         size_t rung, double scale_noise) {
  const std::vector<ImuSample>& imu = walk.imu;
  const size_t n = imu.size();
  ZuptInsSolution out;
  out.stance = stance;
  out.scale_noise.assign(n, scale_noise);
  out.phases = StancePhases(imu, out.stance, o, &out.zupt);
  const bool zaru = o.use_zaru && out.stance.still.size() == n;

  // Reference: the end of a stance phase the walk starts in (or, wait_for_first_stance, the
  // one a walk that starts in a swing reaches first: the INS starts at its begin), else the
  // first sample.
  size_t first_phase = 0, start = 0;
  out.reference_index = 0;
  if (!out.phases.empty()) {
    const double lead = imu[out.phases[0].begin].t_s - imu[0].t_s;
    const bool waits = o.wait_for_first_stance && lead <= o.stance.gait_max_gap_s;
    if (lead < o.min_swing_s || waits) {
      out.reference_index = out.phases[0].end;
      first_phase = 1;
    }
    if (lead >= o.min_swing_s && waits) start = out.phases[0].begin;
  }
  out.start_index = start;

  WG_ASSIGN_OR_RETURN(const Eigen::Vector3d f_mean, LevellingForce(imu, out.phases));
  const InitialPose* pose0 = walk.meta.initial_pose ? &*walk.meta.initial_pose : nullptr;
  ZuptInsFilter f;
  f.x.t_s = imu[0].t_s;
  f.x.q_nb = LevelledAttitude(f_mean, pose0 ? pose0->heading_rad : 0.0);
  if (pose0) f.x.p_n = Eigen::Vector3d(pose0->x_m, pose0->y_m, 0.0);
  f.bg = bg0;
  f.scale_noise = scale_noise;
  f.P = InitialCovariance(o);
  if (o.scale_noise_adaptation == ScaleNoiseAdaptation::kCausal) {
    f.bank.assign(std::size(kScaleNoiseLadder), f.P);
  }

  StrapdownOptions sd;
  sd.gravity_mps2 = o.gravity_mps2;
  sd.sampling = o.sampling;
  sd.max_dt_s = ImuGapThresholdS(imu);  // IMU gaps are held, not integrated (walk.h)

  out.states.resize(n);
  out.acc_bias_mps2.resize(n);
  out.gyro_bias_radps.resize(n);
  out.stride_covariance.resize(n);
  out.strides.absolute_heading = pose0 != nullptr;

  // At each sample (the first without a prediction): ZUPT and ZARU, the sample's record, then
  // the stride reset or emission.
  StrideEmitter strides(imu, o, first_phase, pose0, f.x);
  ZuptInsModel model(imu, o, zaru, rung, start, std::move(f), sd, std::move(strides), &out);
  std::vector<TrajectoryPoint> none;  // the output epochs are recorded in `out`
  WG_RETURN_IF_ERROR(RunErrorStateFilter(&model, ErrorStateRunOptions(), &none));
  return out;
}

}  // namespace

StatusOr<ZuptInsSolution> RunZuptIns(const Walk& walk, const StrideOptions& o) {
  WG_RETURN_IF_ERROR(CheckOptions(o));
  WG_RETURN_IF_ERROR(CheckImu(walk));
  Eigen::Vector3d bg0;
  WG_ASSIGN_OR_RETURN(const StanceMask stance, StanceWithGyroBias(walk, o, &bg0));
  size_t rung = LadderRung(o.scale_noise);
  if (o.scale_noise_adaptation != ScaleNoiseAdaptation::kWalk) {
    const double s = o.scale_noise_adaptation == ScaleNoiseAdaptation::kFixed
                         ? o.scale_noise
                         : kScaleNoiseLadder[rung];
    return RunZuptInsWith(walk, o, stance, bg0, rung, s);
  }
  // The least rung whose first-ZUPT NIS is plausible over the whole walk (see strides.h).
  for (;; ++rung) {
    WG_ASSIGN_OR_RETURN(ZuptInsSolution sol,
                        RunZuptInsWith(walk, o, stance, bg0, rung, kScaleNoiseLadder[rung]));
    if (internal::Median(sol.first_zupt_nis) <= o.max_median_zupt_nis ||
        rung + 1 == std::size(kScaleNoiseLadder)) {
      return sol;
    }
  }
}

void AddFrontEndDiagnostics(const ZuptInsSolution& front,
                            std::map<std::string, double>* diagnostics) {
  auto& d = *diagnostics;
  d["num_strides"] = static_cast<double>(front.strides.steps.size());
  size_t cycles = 0, hypotheses = 0;
  for (size_t k = 0; k < front.stance.cycle_minimum.size(); ++k) {
    if (!front.stance.cycle_minimum[k]) continue;
    const bool hypothesis = k < front.stance.hypothesis.size() && front.stance.hypothesis[k];
    (hypothesis ? hypotheses : cycles) += 1;
  }
  d["stance_cycle_minima"] = static_cast<double>(cycles);
  d["stance_hypotheses"] = static_cast<double>(hypotheses);
  d["stance_hypotheses_gated"] = static_cast<double>(front.hypotheses_gated);
  d["stance_runs_gated"] = static_cast<double>(front.runs_gated);
  d["scale_noise"] = front.scale_noise.empty() ? 0.0 : front.scale_noise.back();
}

StatusOr<StepSequence> ComputeStrides(const Walk& walk, const StrideOptions& options) {
  WG_ASSIGN_OR_RETURN(ZuptInsSolution s, RunZuptIns(walk, options));
  return std::move(s.strides);
}

}  // namespace walkgraph
