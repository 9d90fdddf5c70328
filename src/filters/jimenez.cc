#include "walkgraph/filters/jimenez.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Cholesky>

#include "config/parsers.h"
#include "estimators/builtin.h"
#include "util/enum_define.h"
#include "walkgraph/angle.h"
#include "walkgraph/config.h"
#include "walkgraph/filters/ranges.h"
#include "walkgraph/kalman.h"
#include "walkgraph/kalman_driver.h"

namespace walkgraph {

WALKGRAPH_DEFINE_ENUM_NAMES(JimenezStanceSource, "stance_source",
                            {"detector", JimenezStanceSource::kDetector},
                            {"labels", JimenezStanceSource::kLabels})

namespace {

constexpr int N = kJimenezStateSize;

StrapdownOptions StrapdownFor(const JimenezNominal& nominal, ImuSampling sampling,
                              double gravity_mps2) {
  StrapdownOptions s;
  s.gravity_mps2 = gravity_mps2;
  s.sampling = sampling;
  s.acc_bias_mps2 = nominal.acc_bias;
  s.gyro_bias_radps = nominal.gyro_bias;
  return s;
}

// Azimuth (ENU, from east counter-clockwise) of the horizontal part of a nav-frame vector.
double Azimuth(const Eigen::Vector3d& v_n) { return std::atan2(v_n.y(), v_n.x()); }

// Angle of a nav-frame vector below the horizontal plane (the magnetic dip).
double Dip(const Eigen::Vector3d& v_n) { return std::atan2(-v_n.z(), v_n.head<2>().norm()); }

// Attitude with yaw `yaw` whose z axis is aligned with the mean specific force f̄ (levelling):
// roll = atan2(f_y, f_z), pitch = atan2(−f_x, √(f_y² + f_z²)), R = Rz(ψ)·Ry(θ)·Rx(φ).
Eigen::Quaterniond Level(const Eigen::Vector3d& f, double yaw) {
  const double roll = std::atan2(f.y(), f.z());
  const double pitch = std::atan2(-f.x(), std::hypot(f.y(), f.z()));
  return Eigen::Quaterniond(Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()) *
                            Eigen::AngleAxisd(pitch, Eigen::Vector3d::UnitY()) *
                            Eigen::AngleAxisd(roll, Eigen::Vector3d::UnitX()))
      .normalized();
}

// The running filter: nominal INS state, error estimate and covariance. With smoothing the
// error state is augmented by a clone of the error at the last epoch (dx, P are 30-dim).
struct FilterState {
  JimenezNominal nominal;
  Eigen::VectorXd dx;
  Eigen::MatrixXd P;
  bool corrected = false;  // an update was accepted at this sample (inject + reset pending)
};

// One measurement through kalman.h. `z_minus_h` is z − h(nominal); the errors estimated by
// earlier updates of this sample are taken into account (ν = z − h(nominal) − H·δx).
StatusOr<UpdateOutcome> Update(const Eigen::VectorXd& z_minus_h, const Eigen::MatrixXd& H15,
                               const Eigen::MatrixXd& R, double gate_probability, FilterState* f) {
  const Eigen::Index n = f->dx.size();
  Eigen::MatrixXd H = Eigen::MatrixXd::Zero(H15.rows(), n);
  H.leftCols(N) = H15;
  const Eigen::VectorXd nu = z_minus_h - H15 * f->dx.head(N);
  WG_ASSIGN_OR_RETURN(UpdateOutcome out, KalmanUpdate(nu, H, R, gate_probability, &f->dx, &f->P));
  if (out.accepted) f->corrected = true;
  return out;
}

// (x, y, ψ) and its covariance from a nominal state and the error covariance about it.
TrajectoryPoint OutputPoint(const JimenezNominal& nominal, const Eigen::MatrixXd& P15) {
  TrajectoryPoint pt;
  pt.t_s = nominal.nav.t_s;
  pt.position_m = nominal.nav.p_n;
  pt.heading_rad = JimenezYaw(nominal.nav.q_nb);
  Eigen::Matrix<double, 3, N> J = Eigen::Matrix<double, 3, N>::Zero();
  J(0, kJimenezPos) = 1.0;
  J(1, kJimenezPos + 1) = 1.0;
  J.block<1, 3>(2, kJimenezAtt) = JimenezYawJacobian(nominal.nav.q_nb);
  Eigen::Matrix3d C = J * P15.topLeftCorner(N, N) * J.transpose();
  pt.covariance = 0.5 * (C + C.transpose());
  return pt;
}

}  // namespace

StatusOr<JimenezIezOptions> JimenezIezOptionsFromYaml(const YAML::Node& node,
                                                      const std::string& context, bool use_rss,
                                                      bool smooth) {
  JimenezIezOptions o;
  o.use_rss = use_rss;
  o.smooth = smooth;
  o.stance = JimenezIezOptions().stance;
  ConfigReader r(node, context);
  r.Read(
      "acc_noise_density", &o.acc_noise_density,
      "accelerometer white noise density, m/s^2/sqrt(Hz) (Xsens MTi data sheet; 004 gives none)");
  r.Read("gyro_noise_density", &o.gyro_noise_density,
         "gyro white noise density, rad/s/sqrt(Hz) (Xsens MTi data sheet)");
  r.Read("acc_bias_rw", &o.acc_bias_rw,
         "accelerometer bias random walk, (m/s^2)/sqrt(s) (our choice; 004 gives none)");
  r.Read("gyro_bias_rw", &o.gyro_bias_rw,
         "gyro bias random walk, (rad/s)/sqrt(s) (our choice; 004 gives none)");
  r.Read("init_acc_bias_sigma_mps2", &o.init_acc_bias_sigma_mps2,
         "initial accelerometer bias std-dev (004 Table I bias stability)");
  r.Read("init_gyro_bias_sigma_radps", &o.init_gyro_bias_sigma_radps,
         "initial gyro bias std-dev (004 Table I bias stability)");
  r.Read("init_tilt_sigma_rad", &o.init_tilt_sigma_rad,
         "initial roll/pitch std-dev after levelling");
  r.Read("init_velocity_sigma_mps", &o.init_velocity_sigma_mps,
         "initial velocity std-dev (the walk starts still)");
  r.Read("init_height_sigma_m", &o.init_height_sigma_m, "initial height std-dev");
  r.Read("init_position_sigma_m", &o.init_position_sigma_m,
         "initial position std-dev without initial_pose (origin, or the anchors' centroid)");
  r.Read("init_yaw_sigma_rad", &o.init_yaw_sigma_rad,
         "initial yaw std-dev without initial_pose (unless the compass gives it)");
  r.Read("leveling_window_s", &o.leveling_window_s,
         "initial roll/pitch from the mean specific force over this first span");
  r.Read("initial_heading_from_pose", &o.initial_heading_from_pose,
         "initial_pose.heading_rad is the IMU x-axis yaw");
  r.ReadEnum("imu_sampling", &o.imu_sampling, ImuSamplingNames(),
             "IMU sample convention (strapdown.h): interval averages or instantaneous values");
  r.Read("imu_sampling_from_walk", &o.imu_sampling_from_walk,
         "a simulated walk's sim.imu_interval_average overrides imu_sampling");
  r.Read("gravity_mps2", &o.gravity_mps2, "local gravity magnitude");
  r.ReadEnum("stance_source", &o.stance_source, JimenezStanceSourceNames(),
             "stance from the detector (stance:) or the walk's stance_truth labels as an oracle");
  r.Read("zupt", &o.zupt, "zero-velocity update at stance (004 Algorithm 1)");
  r.Read("zupt_sigma_mps", &o.zupt_sigma_mps, "ZUPT std-dev per axis (IEZ+/OpenShoe)");
  r.Read("zaru", &o.zaru, "zero angular-rate update when still (004 Algorithm 1)");
  r.Read("zaru_sigma_radps", &o.zaru_sigma_radps,
         "ZARU std-dev per axis (the gyro's per-sample white noise at 100 Hz)");
  r.Read("compass", &o.compass, "compass heading update at stance (004 Algorithm 1 lines 10-11)");
  r.Read("compass_sigma_rad", &o.compass_sigma_rad,
         "compass heading std-dev (our choice; 004 gives none)");
  r.Read("compass_every_stance_sample", &o.compass_every_stance_sample,
         "compass update at every stance sample (as the pseudo-code) or once per stance");
  r.Read("declination_rad", &o.declination_rad,
         "magnetic declination added to the compass heading");
  r.Read("compass_max_field_deviation_ut", &o.compass_max_field_deviation_ut,
         "refuse the compass when |B| differs from the levelling window's by more; <= 0: off");
  r.Read("compass_max_dip_deviation_rad", &o.compass_max_dip_deviation_rad,
         "refuse the compass when the dip differs from the levelling window's by more; <= 0: off");
  r.Read("compass_gate_probability", &o.compass_gate_probability,
         "chi-square(1) gate on the heading innovation at this probability; 0: off");
  r.Read("rss0", &o.rss0,
         "RSS at d0 of the filter's own path-loss model (004 eq. 5; RFCode units)");
  r.Read("path_loss_exponent", &o.path_loss_exponent,
         "|p| of the filter's path-loss model (004 eq. 5)");
  r.Read("sigma_rss", &o.sigma_rss, "RSS std-dev for the range std-dev of 004 eq. 7");
  r.Read("d0_m", &o.d0_m, "reference distance of the path-loss model (004 eq. 5)");
  r.Read("path_loss_from_walk", &o.path_loss_from_walk,
         "use the walk's path-loss model instead of the paper's (RSS0 60, |p| 2.3)");
  r.Read("bias_corrected_ranges", &o.bias_corrected_ranges,
         "divide each range by exp(sigma_d^2/2) (001 eq. 17; not in 004)");
  r.Read("min_range_sigma_m", &o.min_range_sigma_m,
         "floor on the range std-dev of 004 eq. 7 (it vanishes as d -> 0)");
  r.Read("reader_height_m", &o.reader_height_m, "RFID reader (waist) height above the foot IMU");
  r.Read("planar_ranges", &o.planar_ranges,
         "2-D ranges as 004 eq. 1 is printed (else 3-D with the reader height)");
  r.Read("range_gate_probability", &o.range_gate_probability,
         "chi-square(1) gate per tag range at this probability; 0: off");
  r.Read("output_rate_hz", &o.output_rate_hz,
         "trajectory output rate (the filter runs at the IMU rate)");
  const YAML::Node stance = r.Child("stance");
  WG_RETURN_IF_ERROR(r.Finish());
  if (stance.IsDefined() && !stance.IsNull()) {
    auto s = StanceOptionsFromYaml(stance);
    if (!s.ok()) return InvalidArgument(context + ": " + s.status().message());
    o.stance = *s;
    // The filter's defaults (multi-condition detector, still_gyro_radps) stay unless named.
    if (!stance["detector"].IsDefined()) o.stance.detector = StanceDetector::kMultiCondition;
    if (!stance["still_gyro_radps"].IsDefined()) {
      o.stance.still_gyro_radps = JimenezIezOptions().stance.still_gyro_radps;
    }
  }
  WG_RETURN_IF_ERROR(o.Validate(context));
  return o;
}

Status JimenezIezOptions::Validate(const std::string& context) const {
  const JimenezIezOptions& o = *this;
  WG_RETURN_IF_ERROR(CheckEnumOption(ImuSamplingNames(), o.imu_sampling, "imu_sampling", context));
  WG_RETURN_IF_ERROR(
      CheckEnumOption(JimenezStanceSourceNames(), o.stance_source, "stance_source", context));
  auto positive = [](double v) { return v > 0.0 && std::isfinite(v); };
  for (double v : {o.acc_noise_density, o.gyro_noise_density, o.init_acc_bias_sigma_mps2,
                   o.init_gyro_bias_sigma_radps, o.init_tilt_sigma_rad, o.init_velocity_sigma_mps,
                   o.init_height_sigma_m, o.init_position_sigma_m, o.init_yaw_sigma_rad,
                   o.zupt_sigma_mps, o.zaru_sigma_radps, o.compass_sigma_rad, o.sigma_rss, o.d0_m,
                   o.min_range_sigma_m, o.output_rate_hz, o.gravity_mps2}) {
    if (!positive(v)) {
      return InvalidArgument(context +
                             ": noise densities, sigmas, d0_m, gravity_mps2 and "
                             "output_rate_hz must be positive");
    }
  }
  if (o.acc_bias_rw < 0 || o.gyro_bias_rw < 0 || o.leveling_window_s < 0) {
    return InvalidArgument(context + ": bias random walks and leveling_window_s must be >= 0");
  }
  if (!(o.path_loss_exponent > 0)) {
    return InvalidArgument(context + ": path_loss_exponent is |p| and must be > 0");
  }
  for (double g : {o.compass_gate_probability, o.range_gate_probability}) {
    if (g < 0 || g >= 1) return InvalidArgument(context + ": gate probabilities must be in [0, 1)");
  }
  return Status::Ok();
}

double JimenezYaw(const Eigen::Quaterniond& q_nb) {
  const Eigen::Vector3d c = q_nb * Eigen::Vector3d::UnitX();
  return NormalizeAngle(std::atan2(c.y(), c.x()));
}

Eigen::RowVector3d JimenezYawJacobian(const Eigen::Quaterniond& q_nb) {
  // δc = δAt × c for q = Exp(δAt) q̂, and δψ = (c_x δc_y − c_y δc_x)/ρ.
  const Eigen::Vector3d c = q_nb * Eigen::Vector3d::UnitX();
  const double rho = std::max(c.x() * c.x() + c.y() * c.y(), 1e-12);
  return Eigen::RowVector3d(-c.x() * c.z() / rho, -c.y() * c.z() / rho, 1.0);
}

double JimenezPredictedRange(const Eigen::Vector3d& p_n, const Eigen::Vector3d& anchor_m,
                             double reader_height_m, bool planar, Eigen::RowVector3d* jacobian) {
  Eigen::Vector3d delta = p_n + Eigen::Vector3d(0, 0, reader_height_m) - anchor_m;
  if (planar) delta.z() = 0.0;  // eq. 1 as printed
  const double range = std::max(delta.norm(), 1e-3);
  if (jacobian != nullptr) *jacobian = delta.transpose() / range;
  return range;
}

JimenezMatrix JimenezErrorTransition(const JimenezNominal& prior, const ImuSample& prev,
                                     const ImuSample& cur, const StrapdownOptions& strapdown) {
  const double dt = cur.t_s - prev.t_s;
  const Eigen::Matrix3d R0 = prior.nav.q_nb.toRotationMatrix();
  const Eigen::Vector3d w1 = cur.gyro_radps - strapdown.gyro_bias_radps;
  const Eigen::Matrix3d R1 = (prior.nav.q_nb * QuaternionExp(w1 * dt)).toRotationMatrix();
  Eigen::Vector3d specific_n;  // R̂ f̂ as the mechanization uses it
  Eigen::Matrix3d R_acc;       // the rotation that carries δa_b into the velocity
  if (strapdown.sampling == ImuSampling::kIntervalAverage) {
    specific_n = R0 * (cur.acc_mps2 - strapdown.acc_bias_mps2);
    R_acc = R0;
  } else {
    specific_n = 0.5 * (R0 * (prev.acc_mps2 - strapdown.acc_bias_mps2) +
                        R1 * (cur.acc_mps2 - strapdown.acc_bias_mps2));
    R_acc = 0.5 * (R0 + R1);
  }
  const Eigen::Matrix3d I = Eigen::Matrix3d::Identity();
  const Eigen::Matrix3d dv_datt = -Skew(specific_n) * dt;
  const Eigen::Matrix3d dv_dba = -R_acc * dt;
  JimenezMatrix F = JimenezMatrix::Identity();
  F.block<3, 3>(kJimenezAtt, kJimenezGyroBias) = -R1 * dt;
  F.block<3, 3>(kJimenezPos, kJimenezVel) = I * dt;
  F.block<3, 3>(kJimenezPos, kJimenezAtt) = 0.5 * dt * dv_datt;
  F.block<3, 3>(kJimenezPos, kJimenezAccBias) = 0.5 * dt * dv_dba;
  F.block<3, 3>(kJimenezVel, kJimenezAtt) = dv_datt;
  F.block<3, 3>(kJimenezVel, kJimenezAccBias) = dv_dba;
  return F;
}

void JimenezInjectError(const JimenezVector& dx, JimenezNominal* nominal, Eigen::MatrixXd* P) {
  const Eigen::Vector3d dtheta = dx.segment<3>(kJimenezAtt);
  nominal->nav.q_nb = (QuaternionExp(dtheta) * nominal->nav.q_nb).normalized();
  nominal->gyro_bias += dx.segment<3>(kJimenezGyroBias);
  nominal->nav.p_n += dx.segment<3>(kJimenezPos);
  nominal->nav.v_n += dx.segment<3>(kJimenezVel);
  nominal->acc_bias += dx.segment<3>(kJimenezAccBias);
  if (P == nullptr) return;
  // G = blkdiag(I + ½[δAt]×, I); only the attitude rows/columns change.
  const Eigen::Matrix3d G = Eigen::Matrix3d::Identity() + 0.5 * Skew(dtheta);
  P->middleRows(kJimenezAtt, 3) = (G * P->middleRows(kJimenezAtt, 3)).eval();
  P->middleCols(kJimenezAtt, 3) = (P->middleCols(kJimenezAtt, 3) * G.transpose()).eval();
  Symmetrize(P);
}

Status CheckJimenezApplicable(const Walk& walk, const JimenezIezOptions& options) {
  const char* id = options.use_rss ? "jimenez-iez-rss" : "jimenez-iez";
  if (walk.imu.size() < 2) return FailedPrecondition(std::string(id) + " needs imu.csv");
  if (options.stance_source == JimenezStanceSource::kLabels && walk.stance_truth.empty()) {
    return FailedPrecondition(std::string(id) + ": stance_source labels needs stance_truth.csv");
  }
  if (walk.meta.imu_placement != ImuPlacement::kFoot) {
    return FailedPrecondition(
        std::string(id) + " needs a foot-mounted IMU (imu_placement: foot): it relies on ZUPTs");
  }
  if (options.use_rss) {
    if (!walk.has_rss() && !walk.has_ranges()) {
      return FailedPrecondition(std::string(id) + " needs rss.csv (or range.csv)");
    }
    if (walk.has_rss() && !options.path_loss_from_walk &&
        walk.meta.radio.units != RssUnits::kRfcode) {
      return FailedPrecondition(
          std::string(id) +
          ": the paper's RSS model (RSS0 = 60, p = 2.3) is in RFCode units; this walk's RSS is "
          "in dBm: set path_loss_from_walk: true to use the walk's own path-loss model");
    }
  }
  return Status::Ok();
}

Status JimenezIez::CheckApplicable(const Walk& walk) const {
  return CheckJimenezApplicable(walk, options_);
}

StatusOr<EstimateResult> JimenezIez::Run(const Walk& walk) const {
  return RunJimenezIez(walk, options_);  // checks applicability first
}

namespace {

// Every radio reading as (d̂, σ_d) through eq. 5 and eq. 7 with the filter's path-loss model
// (the paper's RFCode model unless path_loss_from_walk).
StatusOr<std::vector<RangeMeasurement>> JimenezRanges(const Walk& walk,
                                                      const JimenezIezOptions& o) {
  Walk radio;
  radio.meta = walk.meta;
  if (!o.path_loss_from_walk) {
    radio.meta.radio.units = RssUnits::kRfcode;
    radio.meta.radio.path_loss = {o.rss0, o.path_loss_exponent, o.d0_m, o.sigma_rss};
  }
  radio.anchors = walk.anchors;
  radio.rss = walk.rss;
  radio.ranges = walk.ranges;
  RangeConversionOptions conv;
  conv.bias_corrected = o.bias_corrected_ranges;
  conv.min_sigma_m = o.min_range_sigma_m;
  return RangeMeasurementsFromWalk(radio, conv);  // eq. 5, eq. 7
}

// Compass samples: every stance sample, or the middle sample of each stance phase.
std::vector<bool> CompassSamples(const std::vector<bool>& stance, bool every_stance_sample) {
  const size_t n = stance.size();
  std::vector<bool> at(n, false);
  if (every_stance_sample) {
    for (size_t k = 0; k < n; ++k) at[k] = stance[k];
    return at;
  }
  for (size_t k = 0; k < n;) {
    if (!stance[k]) {
      ++k;
      continue;
    }
    size_t e = k;
    while (e < n && stance[e]) ++e;
    at[(k + e - 1) / 2] = true;
    k = e;
  }
  return at;
}

// Process noise per step (white-noise densities, bias random walks).
JimenezVector JimenezProcessNoise(const JimenezIezOptions& o, double dt) {
  JimenezVector q = JimenezVector::Zero();
  q.segment<3>(kJimenezAtt).setConstant(o.gyro_noise_density * o.gyro_noise_density * dt);
  q.segment<3>(kJimenezVel).setConstant(o.acc_noise_density * o.acc_noise_density * dt);
  q.segment<3>(kJimenezGyroBias).setConstant(o.gyro_bias_rw * o.gyro_bias_rw * dt);
  q.segment<3>(kJimenezAccBias).setConstant(o.acc_bias_rw * o.acc_bias_rw * dt);
  return q;
}

// The magnetic references of the start (for the compass and its disturbance test).
struct MagneticReference {
  bool have_mag = false;
  double north_azimuth = 0.0;  // α_N of the magnetic north in the nav frame
  double field_ut = 0.0, dip_rad = 0.0;
};

// Initial nominal state (levelling over the first leveling_window_s, heading from the pose or
// the compass, start from the pose or the anchors' centroid) and its covariance; with
// smoothing the error state carries a clone (2N).
FilterState JimenezInitialState(const Walk& walk, const JimenezIezOptions& o,
                                MagneticReference* mag) {
  const std::vector<ImuSample>& imu = walk.imu;
  const double t0 = imu.front().t_s;
  Eigen::Vector3d f_mean = Eigen::Vector3d::Zero(), m_mean = Eigen::Vector3d::Zero();
  int n_level = 0, n_mag = 0;
  for (size_t k = 0; k < imu.size() && (k == 0 || imu[k].t_s - t0 <= o.leveling_window_s); ++k) {
    f_mean += imu[k].acc_mps2;
    ++n_level;
    if (imu[k].has_mag) {
      m_mean += imu[k].mag_ut;
      ++n_mag;
    }
  }
  f_mean /= n_level;
  mag->have_mag = n_mag > 0;
  if (mag->have_mag) m_mean /= n_mag;
  mag->north_azimuth = kPi / 2.0 - o.declination_rad;

  FilterState f;
  double yaw0 = 0.0, yaw_sigma = o.init_yaw_sigma_rad;
  Eigen::Vector3d p0 = Eigen::Vector3d::Zero();
  double pos_sigma = o.init_position_sigma_m;
  if (walk.meta.initial_pose) {
    p0.head<2>() = Eigen::Vector2d(walk.meta.initial_pose->x_m, walk.meta.initial_pose->y_m);
    pos_sigma = walk.meta.initial_pose->sigma_xy_m;
  } else if (o.use_rss && !walk.anchors.empty()) {
    for (const Anchor& a : walk.anchors) p0.head<2>() += a.position_m.head<2>();
    p0.head<2>() /= static_cast<double>(walk.anchors.size());
  } else {
    pos_sigma = 1e-3;  // IMU only, no known start: the origin defines the frame
  }
  if (walk.meta.initial_pose && walk.meta.initial_pose->heading_known &&
      o.initial_heading_from_pose) {
    yaw0 = walk.meta.initial_pose->heading_rad;
    yaw_sigma = walk.meta.initial_pose->sigma_heading_rad;
  } else if (mag->have_mag && o.compass) {
    yaw0 = NormalizeAngle(mag->north_azimuth - Azimuth(Level(f_mean, 0.0) * m_mean));
    yaw_sigma = o.compass_sigma_rad;
  }
  f.nominal.nav.t_s = t0;
  f.nominal.nav.q_nb = Level(f_mean, yaw0);
  f.nominal.nav.p_n = p0;
  mag->field_ut = m_mean.norm();
  mag->dip_rad = Dip(f.nominal.nav.q_nb * m_mean);

  JimenezVector sig0;
  sig0 << o.init_tilt_sigma_rad, o.init_tilt_sigma_rad, yaw_sigma,
      Eigen::Vector3d::Constant(o.init_gyro_bias_sigma_radps), pos_sigma, pos_sigma,
      o.init_height_sigma_m, Eigen::Vector3d::Constant(o.init_velocity_sigma_mps),
      Eigen::Vector3d::Constant(o.init_acc_bias_sigma_mps2);
  // The tilt/yaw σ are about the levelled frame's axes; δAt is in the nav frame, whose z is the
  // yaw axis, so the diagonal form holds to first order.
  const int n_state = o.smooth ? 2 * N : N;
  f.dx = Eigen::VectorXd::Zero(n_state);
  f.P = Eigen::MatrixXd::Zero(n_state, n_state);
  f.P.topLeftCorner(N, N) = sig0.cwiseAbs2().asDiagonal();
  return f;
}

// INS mechanization and EKF prediction over one IMU interval (the clone's cross-covariance
// follows the transition).
void JimenezPredict(const ImuSample& prev, const ImuSample& cur, ImuSampling sampling,
                    const JimenezIezOptions& o, FilterState* f) {
  const double dt = cur.t_s - prev.t_s;
  const StrapdownOptions sd = StrapdownFor(f->nominal, sampling, o.gravity_mps2);
  const JimenezMatrix F = JimenezErrorTransition(f->nominal, prev, cur, sd);
  f->nominal.nav = StrapdownStep(f->nominal.nav, prev, cur, sd);
  const JimenezMatrix Pcc = f->P.topLeftCorner(N, N);
  JimenezMatrix Pn = F * Pcc * F.transpose();
  Pn.diagonal() += JimenezProcessNoise(o, dt);
  f->P.topLeftCorner(N, N) = 0.5 * (Pn + Pn.transpose());
  if (o.smooth) {
    f->P.topRightCorner(N, N) = F * f->P.topRightCorner(N, N);
    f->P.bottomLeftCorner(N, N) = f->P.topRightCorner(N, N).transpose();
  }
  f->corrected = false;
}

// The measurement models of 004 at one IMU sample (Algorithm 1), on the running filter.
class IezUpdates {
 public:
  IezUpdates(const Walk& walk, const JimenezIezOptions& o, const StanceMask& stance,
             std::vector<bool> compass_at, std::vector<RangeMeasurement> ranges,
             const MagneticReference& mag, JimenezDetails* d, std::map<std::string, double>* diag)
      : imu_(walk.imu),
        o_(o),
        stance_(stance),
        compass_at_(std::move(compass_at)),
        ranges_(std::move(ranges)),
        mag_(mag),
        d_(d),
        diag_(*diag) {
    R_zupt_ = Eigen::Matrix3d::Identity() * (o.zupt_sigma_mps * o.zupt_sigma_mps);
    R_zaru_ = Eigen::Matrix3d::Identity() * (o.zaru_sigma_radps * o.zaru_sigma_radps);
    H_zupt_ = Eigen::MatrixXd::Zero(3, N);
    H_zupt_.middleCols(kJimenezVel, 3).setIdentity();
    H_zaru_ = Eigen::MatrixXd::Zero(3, N);
    H_zaru_.middleCols(kJimenezGyroBias, 3).setIdentity();
  }

  // Every update due at sample k, in the paper's order.
  Status At(size_t k, FilterState* f) {
    WG_RETURN_IF_ERROR(ZuptZaru(k, f));
    if (o_.compass && compass_at_[k] && imu_[k].has_mag && mag_.have_mag) {
      WG_RETURN_IF_ERROR(Compass(k, f));
    }
    return Ranges(k, f);
  }

 private:
  // ZUPT at stance (Algorithm 1 line 9), ZARU when still (line 14).
  Status ZuptZaru(size_t k, FilterState* f) {
    if (o_.zupt && stance_.stance[k]) {
      const Eigen::VectorXd z = -f->nominal.nav.v_n;
      WG_ASSIGN_OR_RETURN(UpdateOutcome out, Update(z, H_zupt_, R_zupt_, 0.0, f));
      d_->nis_zupt.push_back(out.nis);
      if (!stance_.stance[k - 1]) d_->nis_zupt_first.push_back(out.nis);
      diag_["zupt_updates"] += 1;
    }
    if (o_.zaru && !stance_.still.empty() && stance_.still[k]) {
      const Eigen::VectorXd z = imu_[k].gyro_radps - f->nominal.gyro_bias;
      WG_ASSIGN_OR_RETURN(UpdateOutcome out, Update(z, H_zaru_, R_zaru_, 0.0, f));
      d_->nis_zaru.push_back(out.nis);
      diag_["zaru_updates"] += 1;
    }
    return Status::Ok();
  }

  // Compass heading at stance (lines 10–11), skipped where the field is disturbed.
  Status Compass(size_t k, FilterState* f) {
    const Eigen::Vector3d m_n = f->nominal.nav.q_nb * imu_[k].mag_ut;
    const bool disturbed =
        (o_.compass_max_field_deviation_ut > 0 &&
         std::fabs(imu_[k].mag_ut.norm() - mag_.field_ut) > o_.compass_max_field_deviation_ut) ||
        (o_.compass_max_dip_deviation_rad > 0 &&
         std::fabs(Dip(m_n) - mag_.dip_rad) > o_.compass_max_dip_deviation_rad);
    if (disturbed) {
      diag_["compass_disturbed"] += 1;
      return Status::Ok();
    }
    Eigen::MatrixXd H = Eigen::MatrixXd::Zero(1, N);
    H.block<1, 3>(0, kJimenezAtt) = JimenezYawJacobian(f->nominal.nav.q_nb);
    // θ_compass − θ_INS = α_N − α(R̂ m_b), wrapped.
    const Eigen::VectorXd z =
        Eigen::VectorXd::Constant(1, NormalizeAngle(mag_.north_azimuth - Azimuth(m_n)));
    const Eigen::MatrixXd R =
        Eigen::MatrixXd::Constant(1, 1, o_.compass_sigma_rad * o_.compass_sigma_rad);
    WG_ASSIGN_OR_RETURN(UpdateOutcome out, Update(z, H, R, o_.compass_gate_probability, f));
    Count(out, &d_->nis_compass, "compass");
    return Status::Ok();
  }

  // RFID range residuals at the reader's 10 Hz (eq. 1, 2, 5, 7): the readings up to sample k.
  Status Ranges(size_t k, FilterState* f) {
    for (; ri_ < ranges_.size() && ranges_[ri_].t_s <= imu_[k].t_s; ++ri_) {
      const RangeMeasurement& m = ranges_[ri_];
      Eigen::RowVector3d u;
      const double predicted = JimenezPredictedRange(f->nominal.nav.p_n, m.anchor_m,
                                                     o_.reader_height_m, o_.planar_ranges, &u);
      Eigen::MatrixXd H = Eigen::MatrixXd::Zero(1, N);
      H.block<1, 3>(0, kJimenezPos) = u;
      const Eigen::VectorXd z = Eigen::VectorXd::Constant(1, m.range_m - predicted);  // eq. 2
      const Eigen::MatrixXd R = Eigen::MatrixXd::Constant(1, 1, m.sigma_m * m.sigma_m);
      WG_ASSIGN_OR_RETURN(UpdateOutcome out, Update(z, H, R, o_.range_gate_probability, f));
      Count(out, &d_->nis_range, "range");
    }
    return Status::Ok();
  }

  // A gated update's bookkeeping: an accepted one's NIS in `nis` and a count in
  // <name>_updates, a gated one counted in <name>_gated.
  void Count(const UpdateOutcome& out, std::vector<double>* nis, const std::string& name) {
    if (out.accepted) {
      nis->push_back(out.nis);
      diag_[name + "_updates"] += 1;
    } else {
      diag_[name + "_gated"] += 1;
    }
  }

  const std::vector<ImuSample>& imu_;
  const JimenezIezOptions& o_;
  const StanceMask& stance_;
  const std::vector<bool> compass_at_;
  const std::vector<RangeMeasurement> ranges_;
  const MagneticReference mag_;
  JimenezDetails* d_;
  std::map<std::string, double>& diag_;
  Eigen::MatrixXd R_zupt_, R_zaru_, H_zupt_, H_zaru_;
  size_t ri_ = 0;
};

// The IEZ+ filter of 004 as an error-state model (kalman_driver.h): INS mechanization and EKF
// prediction at 100 Hz (Algorithm 1), the updates due at each sample, CORRECTINS. With
// smoothing the error state carries a clone of the error at the last output epoch.
class IezModel final : public ClonedErrorStateModel<JimenezNominal> {
 public:
  IezModel(const std::vector<ImuSample>& imu, ImuSampling sampling, const JimenezIezOptions& o,
           const std::vector<bool>& stance, FilterState f, IezUpdates* updates)
      : imu_(imu),
        sampling_(sampling),
        o_(o),
        stance_(stance),
        f_(std::move(f)),
        updates_(*updates) {}

  size_t size() const override { return imu_.size(); }
  double Time(size_t k) const override { return imu_[k].t_s; }
  long stance_samples() const { return stance_samples_; }

  Status Propagate(size_t k) override {
    JimenezPredict(imu_[k - 1], imu_[k], sampling_, o_, &f_);
    return Status::Ok();
  }

  Status Update(size_t k) override {
    if (k == 0) return Status::Ok();  // the first sample is the initial state
    if (stance_[k]) ++stance_samples_;
    WG_RETURN_IF_ERROR(updates_.At(k, &f_));
    // CORRECTINS: inject the error estimate and reset it.
    if (f_.corrected) {
      const JimenezVector dx = f_.dx.head(N);
      JimenezInjectError(dx, &f_.nominal, &f_.P);
      f_.dx.head(N).setZero();
    }
    return Status::Ok();
  }

  void Output(size_t, std::vector<TrajectoryPoint>* points) override {
    points->push_back(OutputPoint(f_.nominal, f_.P));
  }

  // The error-state RTS with stochastic cloning (kalman_driver.h): the clone of the error at
  // the previous output epoch closes that epoch; then a new clone of the current error (0
  // after the reset) starts.
  const JimenezNominal& nominal() const override { return f_.nominal; }
  Eigen::MatrixXd Covariance() const override { return f_.P.topLeftCorner(N, N); }
  const ErrorClone& Clone() override {
    clone_ = {f_.dx.tail(N), f_.P.bottomRightCorner(N, N),
              f_.P.topRightCorner(N, N)};  // Cov(δx_now, δx_k)
    return clone_;
  }
  void StartClone() override {
    f_.dx.tail(N).setZero();
    f_.P.bottomRightCorner(N, N) = f_.P.topLeftCorner(N, N);
    f_.P.topRightCorner(N, N) = f_.P.topLeftCorner(N, N);
    f_.P.bottomLeftCorner(N, N) = f_.P.topLeftCorner(N, N);
  }
  // Each smoothed error injected into its epoch's nominal state.
  TrajectoryPoint SmoothedPoint(const JimenezNominal& nominal,
                                const SmoothedState& smoothed) const override {
    JimenezNominal y = nominal;
    Eigen::MatrixXd P = smoothed.P;
    JimenezInjectError(smoothed.x, &y, &P);
    return OutputPoint(y, P);
  }

 private:
  const std::vector<ImuSample>& imu_;
  const ImuSampling sampling_;
  const JimenezIezOptions& o_;
  const std::vector<bool>& stance_;
  FilterState f_;
  IezUpdates& updates_;
  ErrorClone clone_;
  long stance_samples_ = 0;
};

// The IMU sample convention: the options', or a simulated walk's when imu_sampling_from_walk.
ImuSampling JimenezSampling(const Walk& walk, const JimenezIezOptions& o) {
  if (o.imu_sampling_from_walk) {
    auto it = walk.meta.extra.find("sim.imu_interval_average");
    if (it != walk.meta.extra.end()) {
      return it->second != 0.0 ? ImuSampling::kIntervalAverage : ImuSampling::kInstantaneous;
    }
  }
  return o.imu_sampling;
}

double Mean(const std::vector<double>& v) {
  double s = 0.0;
  for (double x : v) s += x;
  return v.empty() ? 0.0 : s / static_cast<double>(v.size());
}

}  // namespace

StatusOr<EstimateResult> RunJimenezIez(const Walk& walk, const JimenezIezOptions& o,
                                       JimenezDetails* details) {
  WG_RETURN_IF_ERROR(o.Validate(o.use_rss ? "jimenez-iez-rss" : "jimenez-iez"));
  WG_RETURN_IF_ERROR(CheckJimenezApplicable(walk, o));
  const std::vector<ImuSample>& imu = walk.imu;
  const size_t n_imu = imu.size();
  const ImuSampling sampling = JimenezSampling(walk, o);
  WG_ASSIGN_OR_RETURN(StanceMask stance, DetectStance(walk, o.stance));
  if (o.stance_source == JimenezStanceSource::kLabels) {
    WG_ASSIGN_OR_RETURN(stance.stance, StanceLabelsAtImu(walk));
  }
  const double imu_dt = (imu.back().t_s - imu.front().t_s) / static_cast<double>(n_imu - 1);
  std::vector<RangeMeasurement> ranges;
  if (o.use_rss) {
    WG_ASSIGN_OR_RETURN(ranges, JimenezRanges(walk, o));
  }

  MagneticReference mag;
  FilterState f = JimenezInitialState(walk, o, &mag);
  EstimateResult result;
  JimenezDetails local;
  JimenezDetails* d = details != nullptr ? details : &local;
  *d = JimenezDetails();
  std::map<std::string, double>& diag = result.diagnostics;
  for (const char* key : {"zupt_updates", "zaru_updates", "compass_updates", "compass_disturbed",
                          "compass_gated", "range_updates", "range_gated"}) {
    diag[key] = 0.0;
  }
  IezUpdates updates(walk, o, stance, CompassSamples(stance.stance, o.compass_every_stance_sample),
                     std::move(ranges), mag, d, &diag);
  IezModel model(imu, sampling, o, stance.stance, std::move(f), &updates);
  ErrorStateRunOptions run;  // 100 Hz loop (Algorithm 1), output decimated
  run.smooth = o.smooth;
  run.output_every = static_cast<size_t>(
      std::max(1, static_cast<int>(std::lround(1.0 / (o.output_rate_hz * imu_dt)))));
  size_t epochs = 0;
  const Status run_status = RunErrorStateFilter(&model, run, &result.trajectory.points, &epochs);
  if (!run_status.ok()) {
    return o.smooth ? Status(run_status.code(), "jimenez-iez-rts: " + run_status.message())
                    : run_status;
  }

  result.nis = o.use_rss ? d->nis_range : d->nis_zupt;
  diag["nis_mean_zupt"] = Mean(d->nis_zupt);
  diag["nis_mean_zupt_first"] = Mean(d->nis_zupt_first);
  diag["nis_mean_zaru"] = Mean(d->nis_zaru);
  diag["nis_mean_compass"] = Mean(d->nis_compass);
  diag["nis_mean_range"] = Mean(d->nis_range);
  diag["stance_fraction"] =
      static_cast<double>(model.stance_samples()) / static_cast<double>(n_imu - 1);
  diag["smoother_epochs"] = o.smooth ? static_cast<double>(epochs) : 0.0;
  d->stance = std::move(stance);
  d->stance_detector =
      o.stance_source == JimenezStanceSource::kLabels ? "labels" : ToString(o.stance.detector);
  return result;
}

namespace internal {

Status RegisterJimenezIez(EstimatorRegistry* registry) {
  struct Variant {
    const char* id;
    const char* description;
    bool use_rss, smooth;
  };
  for (const Variant& v : {
           Variant{"jimenez-iez",
                   "004 Sec. III-A (IEZ+): foot INS + 15-state error EKF, ZUPT/ZARU/compass", false,
                   false},
           Variant{"jimenez-iez-rss",
                   "004 Sec. III: IEZ+ with tight RFID range residuals (eq. 1-2, 5, 7) at 10 Hz",
                   true, false},
           Variant{"jimenez-iez-rts", "jimenez-iez + error-state RTS smoother", false, true},
           Variant{"jimenez-iez-rss-rts", "jimenez-iez-rss + error-state RTS smoother", true, true},
       }) {
    const std::string id = v.id;
    const bool use_rss = v.use_rss, smooth = v.smooth;
    auto parse = [id, use_rss, smooth](const YAML::Node& config) {
      return JimenezIezOptionsFromYaml(config, id, use_rss, smooth);
    };
    WG_RETURN_IF_ERROR(registry->Register({id, v.description, OptionsFactory<JimenezIez>(parse)}));
  }
  return Status::Ok();
}

}  // namespace internal
}  // namespace walkgraph
