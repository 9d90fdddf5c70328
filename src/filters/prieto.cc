#include "walkgraph/filters/prieto.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>

#include "config/parsers.h"
#include "estimators/builtin.h"
#include "filters/prieto_model.h"
#include "walkgraph/angle.h"
#include "walkgraph/config.h"
#include "walkgraph/filters/ranges.h"
#include "walkgraph/kalman.h"
#include "walkgraph/kalman_driver.h"
#include "walkgraph/path_loss.h"

namespace walkgraph {

namespace {

// The prieto stance defaults as StanceOptions keys: Jiménez's multi-condition detector [33]
// (Sec. III-C), with its thresholds as in stance.h. User keys under `stance:` override these.
const char* const kStanceDefaults = "{detector: multi-condition}";

StatusOr<StanceOptions> StanceFromYaml(const YAML::Node& user) {
  YAML::Node merged = YAML::Load(kStanceDefaults);
  if (user.IsDefined() && !user.IsNull()) {
    if (!user.IsMap()) return StanceOptionsFromYaml(user);  // reports the type error
    for (const auto& kv : user) {
      if (!kv.first.IsScalar()) return StanceOptionsFromYaml(user);
      merged[kv.first.Scalar()] = kv.second;
    }
  }
  return StanceOptionsFromYaml(merged);
}

}  // namespace

StanceOptions PrietoDefaultStance() {
  // kStanceDefaults as a struct, not parsed: PrietoOptions' member initializer calls this on
  // every construction (a test checks that the two agree).
  StanceOptions s;
  s.detector = StanceDetector::kMultiCondition;
  return s;
}

StatusOr<PrietoOptions> PrietoOptionsFromYaml(const YAML::Node& node, const std::string& context) {
  return PrietoOptionsFromYaml(node, context, PrietoOptions());
}

StatusOr<PrietoOptions> PrietoOptionsFromYaml(const YAML::Node& node, const std::string& context,
                                              const PrietoOptions& defaults) {
  PrietoOptions o = defaults;
  ConfigReader r(node, context);
  r.Read("sigma_jerk_mps3", &o.sigma_jerk_mps3,
         "jerk noise sigma_d(3) of the constant-acceleration model (002 eq. 1)");
  r.Read("sigma_attitude_rate_ps", &o.sigma_attitude_rate_ps,
         "attitude quaternion noise sigma_q' (002 eq. 3)");
  r.Read("sigma_omega_rate_radps2", &o.sigma_omega_rate_radps2,
         "angular acceleration noise sigma_w' (002 eq. 4)");
  r.Read("sigma_acc_bias_mps2", &o.sigma_acc_bias_mps2,
         "accelerometer bias noise sigma_bf (002 eq. 4)");
  r.Read("sigma_gyro_bias_radps", &o.sigma_gyro_bias_radps, "gyro bias noise sigma_bw (002 eq. 4)");
  r.Read("sigma_v0_mps", &o.sigma_v0_mps, "stance evidence of zero velocity, std-dev (002 eq. 9)");
  r.Read("sigma_a0_mps2", &o.sigma_a0_mps2,
         "stance evidence of zero acceleration, std-dev (002 eq. 9)");
  r.Read("sigma_w0_radps", &o.sigma_w0_radps,
         "stance evidence of zero angular rate, std-dev (002 eq. 9)");
  r.Read("sigma_acc_mps2", &o.sigma_acc_mps2,
         "accelerometer measurement noise (002 eq. 7; Xsens MTx data sheet)");
  r.Read("sigma_gyro_radps", &o.sigma_gyro_radps,
         "gyro measurement noise (002 eq. 8; Xsens MTx data sheet)");
  r.ReadEnum("imu_sampling", &o.imu_sampling, ImuSamplingNames(),
             "IMU sample convention (strapdown.h): interval averages or instantaneous values");
  r.Read("gravity_mps2", &o.gravity_mps2, "local gravity magnitude");
  r.Read("use_rss", &o.use_rss, "fuse RSS readings (002 eq. 5); set by the -imu/-wifi ids");
  r.Read("use_toa", &o.use_toa, "fuse TOA ranges (002 eq. 6); set by the -imu/-wifi ids");
  r.Read("rss_alpha_dbm", &o.rss_alpha_dbm,
         "alpha^s of the RSS model (002 eq. 5); NaN: the walk's");
  r.Read("rss_beta", &o.rss_beta, "beta^s of the RSS model (002 eq. 5); NaN: the walk's");
  r.Read("rss_sigma_db", &o.rss_sigma_db, "RSS std-dev; NaN: the walk's");
  r.Read("toa_alpha_m", &o.toa_alpha_m, "alpha^tau offset of the TOA model (002 eq. 6)");
  r.Read("toa_beta", &o.toa_beta, "beta^tau scale of the TOA model (002 eq. 6)");
  r.Read("toa_sigma_m", &o.toa_sigma_m, "TOA range std-dev; NaN: the walk's");
  r.Read("receiver_offset_z_m", &o.receiver_offset_z_m, "radio receiver height above the IMU");
  r.Read("gate_probability", &o.gate_probability,
         "chi-square(1) gate per radio reading at this probability; 0: off (as the paper)");
  r.Read("radio_epoch_s", &o.radio_epoch_s,
         "fuse the readings within this span as one vector (002 eq. 5-6); 0: each at its time");
  r.Read("ukf_alpha", &o.ukf_alpha, "UKF sigma-point spread alpha (scaled unscented transform)");
  r.Read("ukf_beta", &o.ukf_beta, "UKF beta (2: Gaussian prior)");
  r.Read("ukf_kappa", &o.ukf_kappa, "UKF kappa");
  r.Read("ukf_mean_iterations", &o.ukf_mean_iterations,
         "iterations of the UKF's quaternion mean of the sigma points");
  r.Read("init_sigma_m", &o.init_sigma_m,
         "initial horizontal position std-dev without initial_pose");
  r.Read("init_sigma_z_m", &o.init_sigma_z_m, "initial height std-dev");
  r.Read("init_sigma_v_mps", &o.init_sigma_v_mps, "initial velocity std-dev");
  r.Read("init_sigma_a_mps2", &o.init_sigma_a_mps2, "initial acceleration std-dev");
  r.Read("init_sigma_tilt_rad", &o.init_sigma_tilt_rad,
         "initial roll/pitch std-dev after levelling");
  r.Read("init_sigma_omega_radps", &o.init_sigma_omega_radps, "initial angular rate std-dev");
  r.Read("init_sigma_acc_bias_mps2", &o.init_sigma_acc_bias_mps2,
         "initial accelerometer bias std-dev");
  r.Read("init_sigma_gyro_bias_radps", &o.init_sigma_gyro_bias_radps, "initial gyro bias std-dev");
  r.Read("init_attitude_window_s", &o.init_attitude_window_s,
         "initial roll/pitch from the mean specific force over this first span");
  r.Read("radio_only_step_s", &o.radio_only_step_s,
         "prediction step Delta_k of radio-only walks without an IMU (002 Sec. IV-A)");
  r.Read("output_rate_hz", &o.output_rate_hz, "trajectory (and RTS) output rate");
  const YAML::Node stance = r.Child("stance");
  WG_RETURN_IF_ERROR(r.Finish());
  if (stance.IsDefined()) {
    auto s = StanceFromYaml(stance);
    if (!s.ok()) return InvalidArgument(context + ": " + s.status().message());
    o.stance = *s;
  }
  WG_RETURN_IF_ERROR(o.Validate(context));
  return o;
}

Status PrietoOptions::Validate(const std::string& context) const {
  const PrietoOptions& o = *this;
  const double positive[] = {o.sigma_jerk_mps3,
                             o.sigma_omega_rate_radps2,
                             o.sigma_v0_mps,
                             o.sigma_a0_mps2,
                             o.sigma_w0_radps,
                             o.sigma_acc_mps2,
                             o.sigma_gyro_radps,
                             o.gravity_mps2,
                             o.toa_beta,
                             o.ukf_alpha,
                             o.init_sigma_m,
                             o.init_sigma_z_m,
                             o.init_sigma_v_mps,
                             o.init_sigma_a_mps2,
                             o.init_sigma_tilt_rad,
                             o.init_sigma_omega_radps,
                             o.init_sigma_acc_bias_mps2,
                             o.init_sigma_gyro_bias_radps,
                             o.radio_only_step_s,
                             o.output_rate_hz};
  for (double v : positive) {
    if (!(v > 0.0) || !std::isfinite(v)) {
      return InvalidArgument(context + ": sigmas, gravity, toa_beta, ukf_alpha, steps and rates " +
                             "must be finite and > 0");
    }
  }
  if (!(o.sigma_attitude_rate_ps >= 0) || !(o.sigma_acc_bias_mps2 >= 0) ||
      !(o.sigma_gyro_bias_radps >= 0) || !(o.init_attitude_window_s >= 0)) {
    return InvalidArgument(context + ": attitude and bias noise, init window must be >= 0");
  }
  for (double v : {o.rss_beta, o.rss_sigma_db, o.toa_sigma_m}) {
    if (!std::isnan(v) && !(v > 0.0)) {
      return InvalidArgument(context + ": rss_beta, rss_sigma_db, toa_sigma_m must be > 0");
    }
  }
  if (!(o.radio_epoch_s >= 0 && o.radio_epoch_s <= 60)) {
    return InvalidArgument(context + ": radio_epoch_s must be in [0, 60]");
  }
  if (o.gate_probability < 0 || o.gate_probability >= 1) {
    return InvalidArgument(context + ": gate_probability must be in [0, 1)");
  }
  if (o.ukf_mean_iterations < 1 || o.ukf_mean_iterations > 50) {
    return InvalidArgument(context + ": ukf_mean_iterations must be in [1, 50]");
  }
  if (!(o.ukf_beta >= 0) || !(o.ukf_alpha <= 1.0)) {
    return InvalidArgument(context + ": need 0 < ukf_alpha <= 1 and ukf_beta >= 0");
  }
  return Status::Ok();
}

namespace prieto {

namespace {

// Right Jacobian of SO(3): Exp(φ + δ) ≈ Exp(φ) Exp(J_r(φ) δ).
Eigen::Matrix3d RightJacobian(const Eigen::Vector3d& phi) {
  const double t = phi.norm();
  const Eigen::Matrix3d K = Skew(phi);
  if (t < 1e-6) return Eigen::Matrix3d::Identity() - 0.5 * K + K * K / 6.0;
  return Eigen::Matrix3d::Identity() - (1.0 - std::cos(t)) / (t * t) * K +
         (t - std::sin(t)) / (t * t * t) * K * K;
}

Eigen::Vector3d Gravity(double g) { return Eigen::Vector3d(0.0, 0.0, -g); }

Eigen::Vector3d ReceiverOffset(const MeasurementParams& p) {
  return Eigen::Vector3d(0.0, 0.0, p.receiver_offset_z_m);
}

}  // namespace

NominalState Retract(const NominalState& y, const Eigen::Ref<const Eigen::VectorXd>& d) {
  NominalState out = y;
  out.x += d.segment<3>(kPos);
  out.v += d.segment<3>(kVel);
  out.a += d.segment<3>(kAcc);
  if (d.size() >= kFullDim) {
    out.q_nb = (y.q_nb * QuaternionExp(d.segment<3>(kAtt))).normalized();  // footnote 2
    out.w += d.segment<3>(kOmega);
    out.b_f += d.segment<3>(kAccBias);
    out.b_w += d.segment<3>(kGyroBias);
  }
  return out;
}

Eigen::VectorXd Local(const NominalState& from, const NominalState& to, int dim) {
  Eigen::VectorXd d(dim);
  LocalInto(from, to, d);
  return d;
}

void LocalInto(const NominalState& from, const NominalState& to, Eigen::Ref<Eigen::VectorXd> d) {
  const int dim = static_cast<int>(d.size());
  d.segment<3>(kPos) = to.x - from.x;
  d.segment<3>(kVel) = to.v - from.v;
  d.segment<3>(kAcc) = to.a - from.a;
  if (dim >= kFullDim) {
    d.segment<3>(kAtt) = QuaternionLog(from.q_nb.conjugate() * to.q_nb);
    d.segment<3>(kOmega) = to.w - from.w;
    d.segment<3>(kAccBias) = to.b_f - from.b_f;
    d.segment<3>(kGyroBias) = to.b_w - from.b_w;
  }
}

NominalState Propagate(const NominalState& y, double dt) {
  NominalState out = y;
  out.x = y.x + dt * y.v + 0.5 * dt * dt * y.a;  // eq. 1
  out.v = y.v + dt * y.a;
  out.q_nb = (y.q_nb * QuaternionExp(y.w * dt)).normalized();  // eq. 3 (conjugated, renormalized)
  return out;                                                  // ω, b_f, b_ω: eq. 4
}

Eigen::MatrixXd TransitionJacobian(const NominalState& y, double dt, int dim) {
  Eigen::MatrixXd F = Eigen::MatrixXd::Identity(dim, dim);
  const Eigen::Matrix3d I = Eigen::Matrix3d::Identity();
  F.block<3, 3>(kPos, kVel) = dt * I;  // eq. 1
  F.block<3, 3>(kPos, kAcc) = 0.5 * dt * dt * I;
  F.block<3, 3>(kVel, kAcc) = dt * I;
  if (dim >= kFullDim) {
    const Eigen::Vector3d phi = y.w * dt;  // eq. 3: δθ' = Exp(ωΔ)ᵀ δθ + J_r(ωΔ) Δ δω
    F.block<3, 3>(kAtt, kAtt) = QuaternionExp(phi).toRotationMatrix().transpose();
    F.block<3, 3>(kAtt, kOmega) = RightJacobian(phi) * dt;
  }
  return F;
}

Eigen::MatrixXd ProcessNoise(const PrietoOptions& o, double dt, int dim) {
  Eigen::MatrixXd Q = Eigen::MatrixXd::Zero(dim, dim);
  // eq. 1: discrete Wiener process acceleration, increment σ_j·Δ through Γ = [½Δ², Δ, 1].
  const double sv = o.sigma_jerk_mps3 * dt;
  const Eigen::Vector3d gamma(0.5 * dt * dt, dt, 1.0);
  const Eigen::Matrix3d Qa = sv * sv * gamma * gamma.transpose();
  const int base[3] = {kPos, kVel, kAcc};
  // The radio-only state keeps its height: with the anchors' heights fixed nothing observes the
  // vertical axis, and its jerk random walk would grow without bound (see prieto.h).
  const int axes = dim >= kFullDim ? 3 : 2;
  for (int axis = 0; axis < axes; ++axis) {
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 3; ++c) Q(base[r] + axis, base[c] + axis) = Qa(r, c);
    }
  }
  if (dim >= kFullDim) {
    const double s_att = 2.0 * o.sigma_attitude_rate_ps * dt;  // eq. 3 noise on δθ
    const double s_w = o.sigma_omega_rate_radps2 * dt;         // eq. 4
    const double s_bf = o.sigma_acc_bias_mps2 * dt;
    const double s_bw = o.sigma_gyro_bias_radps * dt;
    for (int i = 0; i < 3; ++i) {
      Q(kAtt + i, kAtt + i) = s_att * s_att;
      Q(kOmega + i, kOmega + i) = s_w * s_w;
      Q(kAccBias + i, kAccBias + i) = s_bf * s_bf;
      Q(kGyroBias + i, kGyroBias + i) = s_bw * s_bw;
    }
  }
  return Q;
}

Eigen::MatrixXd ResetJacobian(const Eigen::VectorXd& delta) {
  const int dim = static_cast<int>(delta.size());
  Eigen::MatrixXd G = Eigen::MatrixXd::Identity(dim, dim);
  if (dim >= kFullDim) {
    G.block<3, 3>(kAtt, kAtt) -= 0.5 * Skew(delta.segment<3>(kAtt));
  }
  return G;
}

Measurement StackMeasurements(std::vector<Measurement> parts) {
  Measurement out;
  out.kind = MeasurementKind::kStack;
  int rows = 0;
  for (const Measurement& m : parts) rows += static_cast<int>(m.z.size());
  out.z.resize(rows);
  out.R = Eigen::MatrixXd::Zero(rows, rows);
  int r = 0;
  for (const Measurement& m : parts) {
    const int k = static_cast<int>(m.z.size());
    out.z.segment(r, k) = m.z;
    out.R.block(r, r, k, k) = m.R;
    r += k;
  }
  out.parts = std::move(parts);
  return out;
}

Eigen::VectorXd PredictMeasurement(const MeasurementParams& p, const Measurement& m,
                                   const NominalState& y) {
  switch (m.kind) {
    case MeasurementKind::kStack: {
      Eigen::VectorXd h(m.z.size());
      int r = 0;
      for (const Measurement& part : m.parts) {
        const Eigen::VectorXd hp = PredictMeasurement(p, part, y);
        h.segment(r, hp.size()) = hp;
        r += static_cast<int>(hp.size());
      }
      return h;
    }
    case MeasurementKind::kImu:
    case MeasurementKind::kImuStance: {
      const bool stance = m.kind == MeasurementKind::kImuStance;
      Eigen::VectorXd h(stance ? 15 : 6);
      const Eigen::Matrix3d R = y.q_nb.toRotationMatrix();
      h.segment<3>(0) = R.transpose() * (y.a - Gravity(p.gravity_mps2)) + y.b_f;  // eq. 7
      h.segment<3>(3) = y.w + y.b_w;                                              // eq. 8
      if (stance) {                                                               // eq. 9
        h.segment<3>(6) = y.v;
        h.segment<3>(9) = y.a;
        h.segment<3>(12) = y.w;
      }
      return h;
    }
    case MeasurementKind::kRss: {
      const PathLossModel model({p.rss_alpha_dbm, p.rss_beta, p.rss_d0_m, 1.0},
                                p.rss_sign > 0 ? RssUnits::kDbm : RssUnits::kRfcode);
      const double d = (y.x + ReceiverOffset(p) - m.anchor_m).norm();
      return Eigen::VectorXd::Constant(1, model.ExpectedRss(d));  // eq. 5
    }
    case MeasurementKind::kToa: {
      const double d = (y.x + ReceiverOffset(p) - m.anchor_m).norm();
      return Eigen::VectorXd::Constant(1, p.toa_alpha_m + p.toa_beta * d);  // eq. 6
    }
  }
  return Eigen::VectorXd();
}

Eigen::MatrixXd MeasurementJacobian(const MeasurementParams& p, const Measurement& m,
                                    const NominalState& y, int dim) {
  const Eigen::Matrix3d I = Eigen::Matrix3d::Identity();
  switch (m.kind) {
    case MeasurementKind::kStack: {
      Eigen::MatrixXd H(m.z.size(), dim);
      int r = 0;
      for (const Measurement& part : m.parts) {
        const Eigen::MatrixXd Hp = MeasurementJacobian(p, part, y, dim);
        H.middleRows(r, Hp.rows()) = Hp;
        r += static_cast<int>(Hp.rows());
      }
      return H;
    }
    case MeasurementKind::kImu:
    case MeasurementKind::kImuStance: {
      const bool stance = m.kind == MeasurementKind::kImuStance;
      Eigen::MatrixXd H = Eigen::MatrixXd::Zero(stance ? 15 : 6, dim);
      const Eigen::Matrix3d Rt = y.q_nb.toRotationMatrix().transpose();
      // eq. 7: h = Exp(−δθ) R̂ᵀ (a − g) + b_f ⇒ ∂h/∂δθ = [R̂ᵀ(a − g)]×.
      H.block<3, 3>(0, kAcc) = Rt;
      H.block<3, 3>(0, kAtt) = Skew(Rt * (y.a - Gravity(p.gravity_mps2)));
      H.block<3, 3>(0, kAccBias) = I;
      H.block<3, 3>(3, kOmega) = I;  // eq. 8
      H.block<3, 3>(3, kGyroBias) = I;
      if (stance) {  // eq. 9
        H.block<3, 3>(6, kVel) = I;
        H.block<3, 3>(9, kAcc) = I;
        H.block<3, 3>(12, kOmega) = I;
      }
      return H;
    }
    case MeasurementKind::kRss:
    case MeasurementKind::kToa: {
      Eigen::MatrixXd H = Eigen::MatrixXd::Zero(1, dim);
      const Eigen::Vector3d r = y.x + ReceiverOffset(p) - m.anchor_m;
      const double d = std::max(r.norm(), 1e-3);
      if (m.kind == MeasurementKind::kRss) {
        // eq. 5: ∂/∂x of −s·10β·log10(d) = −s·10β/(ln10·d²)·rᵀ
        H.block<1, 3>(0, kPos) =
            -p.rss_sign * 10.0 * p.rss_beta / (std::log(10.0) * d * d) * r.transpose();
      } else {
        H.block<1, 3>(0, kPos) = p.toa_beta / d * r.transpose();  // eq. 6
      }
      return H;
    }
  }
  return Eigen::MatrixXd();
}

PlanarPose ToPlanarPose(const NominalState& y, const Eigen::MatrixXd& P) {
  const int dim = static_cast<int>(P.rows());
  PlanarPose out;
  Eigen::MatrixXd J = Eigen::MatrixXd::Zero(3, dim);
  J(0, kPos) = 1.0;
  J(1, kPos + 1) = 1.0;
  double heading_var_cap = kPi * kPi;
  if (dim >= kFullDim) {
    // Heading of the body x axis r = R̂ Exp(δθ) e_x: ∂r/∂δθ = −R̂ [e_x]×.
    const Eigen::Matrix3d R = y.q_nb.toRotationMatrix();
    const Eigen::Vector3d r = R.col(0);
    const double n2 = std::max(r.x() * r.x() + r.y() * r.y(), 1e-12);
    out.pose = Eigen::Vector3d(y.x.x(), y.x.y(), NormalizeAngle(std::atan2(r.y(), r.x())));
    const Eigen::RowVector3d dpsi_dr(-r.y() / n2, r.x() / n2, 0.0);
    J.block<1, 3>(2, kAtt) = dpsi_dr * (-R * Skew(Eigen::Vector3d::UnitX()));
  } else {
    // Radio-only: the direction of the velocity (undefined at rest: variance capped at π²).
    const Eigen::Vector2d v = y.v.head<2>();
    const double n2 = std::max(v.squaredNorm(), 1e-12);
    out.pose = Eigen::Vector3d(y.x.x(), y.x.y(), NormalizeAngle(std::atan2(v.y(), v.x())));
    J(2, kVel) = -v.y() / n2;
    J(2, kVel + 1) = v.x() / n2;
  }
  out.covariance = J * P * J.transpose();
  out.covariance = 0.5 * (out.covariance + out.covariance.transpose()).eval();
  if (!(out.covariance(2, 2) <= heading_var_cap)) {
    out.covariance.row(2).setZero();
    out.covariance.col(2).setZero();
    out.covariance(2, 2) = heading_var_cap;
  }
  return out;
}

}  // namespace prieto

namespace {

using prieto::Measurement;
using prieto::MeasurementKind;
using prieto::MeasurementParams;
using prieto::NominalState;

// P ← (P + Pᵀ)/2 and its Cholesky factor; when P is not positive definite its eigenvalues are
// floored at 1e-12·max(λ_max, 1) first. Returns true when a repair was needed.
bool MakePositiveDefinite(Eigen::MatrixXd* P, Eigen::LLT<Eigen::MatrixXd>* llt) {
  Symmetrize(P);
  llt->compute(*P);
  if (llt->info() == Eigen::Success) return false;
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es(*P);
  const double floor = 1e-12 * std::max(es.eigenvalues().maxCoeff(), 1.0);
  const Eigen::VectorXd lambda = es.eigenvalues().cwiseMax(floor);
  *P = es.eigenvectors() * lambda.asDiagonal() * es.eigenvectors().transpose();
  Symmetrize(P);
  llt->compute(*P);
  return true;
}

// The state at the last stored (RTS) epoch j, carried along with the filter (see prieto.h).
using Clone = ErrorClone;

class PrietoCore {
 public:
  PrietoCore(const PrietoOptions& o, const MeasurementParams& mp, int dim, NominalState y,
             Eigen::MatrixXd P)
      : o_(o), mp_(mp), n_(dim), y_(std::move(y)), P_(std::move(P)) {
    const double n = n_;
    lambda_ = o.ukf_alpha * o.ukf_alpha * (n + o.ukf_kappa) - n;
    wm0_ = lambda_ / (n + lambda_);
    wc0_ = wm0_ + 1.0 - o.ukf_alpha * o.ukf_alpha + o.ukf_beta;
    wi_ = 1.0 / (2.0 * (n + lambda_));
  }

  const NominalState& y() const { return y_; }
  const Eigen::MatrixXd& P() const { return P_; }
  double pd_repairs() const { return pd_repairs_; }
  bool cloning() const { return clone_ != nullptr; }
  const Clone& clone() const { return *clone_; }

  Status CheckUkfWeights() const {
    if (o_.filter == PrietoFilterKind::kUkf && !(n_ + lambda_ > 1e-12)) {
      return InvalidArgument("prieto-ukf: α²(n + κ) must be > 0");
    }
    return Status::Ok();
  }

  // Starts a new clone of the current state (RTS epoch).
  void StartClone() {
    clone_ = std::make_unique<Clone>();
    clone_->delta = Eigen::VectorXd::Zero(n_);
    clone_->P_jj = P_;
    clone_->P_cj = P_;
  }

  Status Predict(double dt) {
    if (!(dt > 0.0)) return Status::Ok();
    return o_.filter == PrietoFilterKind::kEkf ? PredictEkf(dt) : PredictUkf(dt);
  }

  StatusOr<UpdateOutcome> Update(const Measurement& m, double gate) {
    return o_.filter == PrietoFilterKind::kEkf ? UpdateEkf(m, gate) : UpdateUkf(m, gate);
  }

  // NIS of a measurement against the current prior, without updating (for gating the rows of
  // a stacked radio set one by one).
  StatusOr<double> Nis(const Measurement& m) {
    Eigen::VectorXd nu;
    Eigen::MatrixXd S;
    if (o_.filter == PrietoFilterKind::kEkf) {
      nu = m.z - prieto::PredictMeasurement(mp_, m, y_);
      const Eigen::MatrixXd H = prieto::MeasurementJacobian(mp_, m, y_, n_);
      S = H * P_ * H.transpose() + m.R;
    } else {
      WG_ASSIGN_OR_RETURN(const Eigen::MatrixXd Sg, SigmaOffsets());
      Eigen::MatrixXd C;
      Eigen::VectorXd zbar;
      UnscentedMeasurement(m, Sg, &zbar, &S, &C);
      nu = m.z - zbar;
    }
    Symmetrize(&S);
    const Eigen::LLT<Eigen::MatrixXd> llt(S);
    if (llt.info() != Eigen::Success) {
      return NumericalError("prieto: innovation covariance is not positive definite");
    }
    return nu.dot(llt.solve(nu));
  }

 private:
  // M ← F M for F = TransitionJacobian (identity but the rows of x, v and δθ), in O(n²).
  void LeftMultiplyTransition(const Eigen::MatrixXd& F, Eigen::MatrixXd* M) const {
    using prieto::kAcc, prieto::kAtt, prieto::kOmega, prieto::kPos, prieto::kVel;
    const double dt = F(kPos, kVel), half_dt2 = F(kPos, kAcc);
    M->middleRows<3>(kPos) += dt * M->middleRows<3>(kVel) + half_dt2 * M->middleRows<3>(kAcc);
    M->middleRows<3>(kVel) += dt * M->middleRows<3>(kAcc);
    if (n_ >= prieto::kFullDim) {
      const Eigen::MatrixXd att = F.block<3, 3>(kAtt, kAtt) * M->middleRows<3>(kAtt) +
                                  F.block<3, 3>(kAtt, kOmega) * M->middleRows<3>(kOmega);
      M->middleRows<3>(kAtt) = att;
    }
  }

  Status PredictEkf(double dt) {
    const Eigen::MatrixXd F = prieto::TransitionJacobian(y_, dt, n_);
    y_ = prieto::Propagate(y_, dt);
    llt_current_ = false;
    // P ← F P Fᵀ + Q, as F (F P)ᵀ with P symmetric.
    LeftMultiplyTransition(F, &P_);
    Eigen::MatrixXd FPt = P_.transpose();
    LeftMultiplyTransition(F, &FPt);
    P_ = FPt + prieto::ProcessNoise(o_, dt, n_);
    Symmetrize(&P_);
    if (clone_) LeftMultiplyTransition(F, &clone_->P_cj);
    return Status::Ok();
  }

  // Symmetrizes P (repairing it if needed) and caches its Cholesky factor llt_.
  Status FactorCovariance() {
    if (MakePositiveDefinite(&P_, &llt_)) pd_repairs_ += 1.0;
    if (llt_.info() != Eigen::Success) {
      return NumericalError("prieto-ukf: covariance is not positive definite");
    }
    llt_current_ = true;
    return Status::Ok();
  }

  // Columns: the sigma-point offsets in the error chart at y_ (column 0 is zero).
  StatusOr<Eigen::MatrixXd> SigmaOffsets() {
    if (!llt_current_) WG_RETURN_IF_ERROR(FactorCovariance());
    const Eigen::MatrixXd L = std::sqrt(n_ + lambda_) * llt_.matrixL().toDenseMatrix();
    Eigen::MatrixXd S = Eigen::MatrixXd::Zero(n_, 2 * n_ + 1);
    S.middleCols(1, n_) = L;
    S.rightCols(n_) = -L;
    return S;
  }

  double Wm(int i) const { return i == 0 ? wm0_ : wi_; }
  double Wc(int i) const { return i == 0 ? wc0_ : wi_; }

  // Quaternion-aware weighted mean of sigma points (prieto.h): vector parts by weights, the
  // attitude by iterating the weighted mean of Log(q̄⁻¹ q_i) about q̄ (start: point 0).
  NominalState SigmaMean(const std::vector<NominalState>& pts) const {
    NominalState mean = pts[0];
    mean.x.setZero();
    mean.v.setZero();
    mean.a.setZero();
    mean.w.setZero();
    mean.b_f.setZero();
    mean.b_w.setZero();
    for (size_t i = 0; i < pts.size(); ++i) {
      const double w = Wm(static_cast<int>(i));
      mean.x += w * pts[i].x;
      mean.v += w * pts[i].v;
      mean.a += w * pts[i].a;
      mean.w += w * pts[i].w;
      mean.b_f += w * pts[i].b_f;
      mean.b_w += w * pts[i].b_w;
    }
    if (n_ >= prieto::kFullDim) {
      for (int it = 0; it < o_.ukf_mean_iterations; ++it) {
        Eigen::Vector3d e = Eigen::Vector3d::Zero();
        for (size_t i = 0; i < pts.size(); ++i) {
          e += Wm(static_cast<int>(i)) * QuaternionLog(mean.q_nb.conjugate() * pts[i].q_nb);
        }
        mean.q_nb = (mean.q_nb * QuaternionExp(e)).normalized();
        if (e.norm() < 1e-12) break;
      }
    }
    return mean;
  }

  Status PredictUkf(double dt) {
    WG_ASSIGN_OR_RETURN(const Eigen::MatrixXd S, SigmaOffsets());
    const int m = 2 * n_ + 1;
    std::vector<NominalState> pts(m);
    for (int i = 0; i < m; ++i) {
      pts[i] = prieto::Propagate(prieto::Retract(y_, S.col(i)), dt);
    }
    const NominalState mean = SigmaMean(pts);
    Eigen::MatrixXd dev(n_, m);
    for (int i = 0; i < m; ++i) prieto::LocalInto(mean, pts[i], dev.col(i));
    Eigen::VectorXd wc(m);
    for (int i = 0; i < m; ++i) wc[i] = Wc(i);
    Eigen::MatrixXd P_new =
        dev * wc.asDiagonal() * dev.transpose() + prieto::ProcessNoise(o_, dt, n_);
    if (clone_) {
      // Statistically linearized transition F = Dᵀ P⁻¹, D = Σ W^c s_i dev_iᵀ.
      const Eigen::MatrixXd D = S * wc.asDiagonal() * dev.transpose();
      clone_->P_cj = D.transpose() * llt_.solve(clone_->P_cj);  // llt_: the prior P
    }
    y_ = mean;
    P_ = std::move(P_new);
    return FactorCovariance();
  }

  // Applies an accepted correction δ to the clone (M = Cov(z, e_j), K = current gain).
  void UpdateClone(const Eigen::MatrixXd& M, const Eigen::MatrixXd& K,
                   const Eigen::LLT<Eigen::MatrixXd>& S_llt, const Eigen::VectorXd& nu) {
    const Eigen::MatrixXd SinvM = S_llt.solve(M);  // S⁻¹ M
    clone_->delta += SinvM.transpose() * nu;       // K_j ν, K_j = Mᵀ S⁻¹
    clone_->P_jj -= M.transpose() * SinvM;         // K_j S K_jᵀ
    Symmetrize(&clone_->P_jj);
    clone_->P_cj -= K * M;
  }

  // y ← y ⊞ δ, P ← G P Gᵀ (and the clone's cross-covariance ← G P_cj).
  void Inject(const Eigen::VectorXd& delta) {
    llt_current_ = false;
    y_ = prieto::Retract(y_, delta);
    if (n_ >= prieto::kFullDim) {
      // G = ResetJacobian(δ) differs from I only in its attitude block: G P Gᵀ in O(n²).
      const Eigen::Matrix3d Ga =  // the attitude block of prieto::ResetJacobian(δ)
          Eigen::Matrix3d::Identity() - 0.5 * Skew(delta.segment<3>(prieto::kAtt));
      P_.middleRows<3>(prieto::kAtt) = (Ga * P_.middleRows<3>(prieto::kAtt)).eval();
      P_.middleCols<3>(prieto::kAtt) = (P_.middleCols<3>(prieto::kAtt) * Ga.transpose()).eval();
      Symmetrize(&P_);
      if (clone_) {
        clone_->P_cj.middleRows<3>(prieto::kAtt) =
            (Ga * clone_->P_cj.middleRows<3>(prieto::kAtt)).eval();
      }
    }
  }

  StatusOr<UpdateOutcome> UpdateEkf(const Measurement& m, double gate) {
    const Eigen::VectorXd nu = m.z - prieto::PredictMeasurement(mp_, m, y_);
    const Eigen::MatrixXd H = prieto::MeasurementJacobian(mp_, m, y_, n_);
    Eigen::MatrixXd M, K;
    Eigen::LLT<Eigen::MatrixXd> S_llt;
    if (clone_) {
      M = H * clone_->P_cj;
      Eigen::MatrixXd S = H * P_ * H.transpose() + m.R;
      Symmetrize(&S);
      S_llt.compute(S);
      K = S_llt.solve(H * P_).transpose();
    }
    Eigen::VectorXd delta = Eigen::VectorXd::Zero(n_);
    WG_ASSIGN_OR_RETURN(UpdateOutcome out, KalmanUpdate(nu, H, m.R, gate, &delta, &P_));
    llt_current_ = false;
    if (!out.accepted) return out;
    if (clone_) UpdateClone(M, K, S_llt, nu);
    Inject(delta);
    return out;
  }

  // Unscented transform of h over the sigma offsets Sg: mean z̄, S = Σ W^c ΔzΔzᵀ + R and the
  // cross-covariance C = Σ W^c s_i Δz_iᵀ.
  void UnscentedMeasurement(const Measurement& m, const Eigen::MatrixXd& Sg, Eigen::VectorXd* zbar,
                            Eigen::MatrixXd* S, Eigen::MatrixXd* C) const {
    const int np = 2 * n_ + 1;
    const int nz = static_cast<int>(m.z.size());
    Eigen::MatrixXd Z(nz, np);
    for (int i = 0; i < np; ++i) {
      Z.col(i) = prieto::PredictMeasurement(mp_, m, prieto::Retract(y_, Sg.col(i)));
    }
    *zbar = Eigen::VectorXd::Zero(nz);
    Eigen::VectorXd wc(np);
    for (int i = 0; i < np; ++i) {
      *zbar += Wm(i) * Z.col(i);
      wc[i] = Wc(i);
    }
    const Eigen::MatrixXd dZ = Z.colwise() - *zbar;
    *S = dZ * wc.asDiagonal() * dZ.transpose() + m.R;
    Symmetrize(S);
    *C = Sg * wc.asDiagonal() * dZ.transpose();  // n × nz
  }

  StatusOr<UpdateOutcome> UpdateUkf(const Measurement& m, double gate) {
    WG_ASSIGN_OR_RETURN(const Eigen::MatrixXd Sg, SigmaOffsets());
    const int nz = static_cast<int>(m.z.size());
    Eigen::VectorXd zbar;
    Eigen::MatrixXd S, C;
    UnscentedMeasurement(m, Sg, &zbar, &S, &C);
    const Eigen::LLT<Eigen::MatrixXd> S_llt(S);
    if (S_llt.info() != Eigen::Success) {
      return NumericalError("prieto-ukf: innovation covariance is not positive definite");
    }
    const Eigen::VectorXd nu = m.z - zbar;
    UpdateOutcome out;
    out.nis = nu.dot(S_llt.solve(nu));
    if (!std::isfinite(out.nis)) return NumericalError("prieto-ukf: non-finite NIS");
    if (gate > 0.0 && out.nis > ChiSquareQuantile(gate, nz)) return out;
    out.accepted = true;
    const Eigen::MatrixXd K = S_llt.solve(C.transpose()).transpose();  // C S⁻¹
    if (clone_) {
      // Statistically linearized H = Cᵀ P⁻¹: Cov(z, e_j) = Cᵀ P⁻¹ P_cj.
      const Eigen::MatrixXd M = C.transpose() * llt_.solve(clone_->P_cj);  // llt_: prior P
      UpdateClone(M, K, S_llt, nu);
    }
    const Eigen::VectorXd delta = K * nu;
    P_ -= K * S * K.transpose();
    Inject(delta);
    WG_RETURN_IF_ERROR(FactorCovariance());
    return out;
  }

  const PrietoOptions& o_;
  const MeasurementParams mp_;
  const int n_;
  NominalState y_;
  Eigen::MatrixXd P_;
  std::unique_ptr<Clone> clone_;
  double lambda_ = 0.0, wm0_ = 0.0, wc0_ = 0.0, wi_ = 0.0;
  double pd_repairs_ = 0.0;
  Eigen::LLT<Eigen::MatrixXd> llt_;  // of P_, when llt_current_ (UKF)
  bool llt_current_ = false;
};

struct RadioReading {
  double t_s = 0.0;
  Measurement m;
};

// Initial state and covariance (see prieto.h).
void InitialState(const Walk& walk, const PrietoOptions& o, int dim, NominalState* y,
                  Eigen::MatrixXd* P) {
  Eigen::VectorXd var = Eigen::VectorXd::Zero(dim);
  double yaw = 0.0, sigma_yaw = kPi;
  double sigma_xy = o.init_sigma_m;
  if (walk.meta.initial_pose) {
    const InitialPose& p = *walk.meta.initial_pose;
    y->x = Eigen::Vector3d(p.x_m, p.y_m, 0.0);
    yaw = p.heading_rad;
    sigma_yaw = p.sigma_heading_rad;
    sigma_xy = p.sigma_xy_m;
  } else {
    Eigen::Vector3d c = Eigen::Vector3d::Zero();
    for (const Anchor& a : walk.anchors) c += a.position_m;
    if (!walk.anchors.empty()) c /= static_cast<double>(walk.anchors.size());
    y->x = Eigen::Vector3d(c.x(), c.y(), 0.0);
  }
  var.segment<3>(prieto::kPos) = Eigen::Vector3d(sigma_xy * sigma_xy, sigma_xy * sigma_xy,
                                                 o.init_sigma_z_m * o.init_sigma_z_m);
  var.segment<3>(prieto::kVel).setConstant(o.init_sigma_v_mps * o.init_sigma_v_mps);
  var.segment<3>(prieto::kAcc).setConstant(o.init_sigma_a_mps2 * o.init_sigma_a_mps2);
  if (dim < prieto::kFullDim) {
    // Radio-only: the height is held (no vertical noise, see ProcessNoise), so its velocity and
    // acceleration start known; their uncertainty would otherwise grow z as t²·σ_a.
    var[prieto::kVel + 2] = var[prieto::kAcc + 2] = 1e-12;
    *P = var.asDiagonal();
    return;
  }
  *P = var.asDiagonal();
  // Roll and pitch from the mean specific force at the start: f ∝ R_nbᵀ (0, 0, g).
  Eigen::Vector3d f = Eigen::Vector3d::Zero();
  int count = 0;
  const double t0 = walk.imu.front().t_s;
  for (const ImuSample& s : walk.imu) {
    if (s.t_s > t0 + o.init_attitude_window_s && count > 0) break;
    f += s.acc_mps2;
    ++count;
  }
  const double roll = std::atan2(f.y(), f.z());
  const double pitch = std::atan2(-f.x(), std::hypot(f.y(), f.z()));
  const Eigen::Matrix3d R = (Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()) *
                             Eigen::AngleAxisd(pitch, Eigen::Vector3d::UnitY()) *
                             Eigen::AngleAxisd(roll, Eigen::Vector3d::UnitX()))
                                .toRotationMatrix();
  y->q_nb = Eigen::Quaterniond(R).normalized();
  // Nav-frame attitude errors φ_n (tilt, tilt, yaw) map to the body-frame δθ = Rᵀ φ_n.
  const Eigen::Vector3d nav_var(o.init_sigma_tilt_rad * o.init_sigma_tilt_rad,
                                o.init_sigma_tilt_rad * o.init_sigma_tilt_rad,
                                sigma_yaw * sigma_yaw);
  P->block<3, 3>(prieto::kAtt, prieto::kAtt) = R.transpose() * nav_var.asDiagonal() * R;
  for (int i = 0; i < 3; ++i) {
    (*P)(prieto::kOmega + i, prieto::kOmega + i) =
        o.init_sigma_omega_radps * o.init_sigma_omega_radps;
    (*P)(prieto::kAccBias + i, prieto::kAccBias + i) =
        o.init_sigma_acc_bias_mps2 * o.init_sigma_acc_bias_mps2;
    (*P)(prieto::kGyroBias + i, prieto::kGyroBias + i) =
        o.init_sigma_gyro_bias_radps * o.init_sigma_gyro_bias_radps;
  }
}

TrajectoryPoint ToPoint(double t, const NominalState& y, const Eigen::MatrixXd& P) {
  const prieto::PlanarPose pose = prieto::ToPlanarPose(y, P);
  TrajectoryPoint pt;
  pt.t_s = t;
  pt.position_m = Eigen::Vector3d(pose.pose.x(), pose.pose.y(), 0.0);
  pt.heading_rad = pose.pose.z();
  pt.covariance = pose.covariance;
  return pt;
}

// Parameters of the radio models (eq. 5–6): the walk's path-loss model and TOA σ unless set.
StatusOr<MeasurementParams> PrietoMeasurementParams(const Walk& walk, const PrietoOptions& o,
                                                    double* rss_sigma, double* toa_sigma) {
  const PathLossParams& pl = walk.meta.radio.path_loss;
  MeasurementParams mp;
  mp.gravity_mps2 = o.gravity_mps2;
  mp.rss_alpha_dbm = std::isnan(o.rss_alpha_dbm) ? pl.A_dbm : o.rss_alpha_dbm;
  mp.rss_beta = std::isnan(o.rss_beta) ? pl.eta : o.rss_beta;
  mp.rss_d0_m = pl.d0_m;
  mp.rss_sign = PathLossModel(pl, walk.meta.radio.units).sign();
  mp.toa_alpha_m = o.toa_alpha_m;
  mp.toa_beta = o.toa_beta;
  mp.receiver_offset_z_m = o.receiver_offset_z_m;
  *rss_sigma = std::isnan(o.rss_sigma_db) ? pl.sigma_db : o.rss_sigma_db;
  *toa_sigma = std::isnan(o.toa_sigma_m) ? walk.meta.radio.range_sigma_m : o.toa_sigma_m;
  if (!(*rss_sigma > 0) || !(*toa_sigma > 0)) {
    return FailedPrecondition("prieto: the walk's sigma_db and range_sigma_m must be > 0");
  }
  return mp;
}

// The walk's RSS and TOA readings the options fuse, as measurements (eq. 5–6).
StatusOr<std::vector<RadioReading>> PrietoRadioReadings(const Walk& walk, const PrietoOptions& o,
                                                        double rss_sigma, double toa_sigma) {
  WG_ASSIGN_OR_RETURN(const std::vector<RangeMeasurement> readings,
                      RangeMeasurementsFromWalk(walk));
  std::vector<RadioReading> radio;
  for (const RangeMeasurement& r : readings) {
    if (r.from_rss ? !o.use_rss : !o.use_toa) continue;
    RadioReading rr;
    rr.t_s = r.t_s;
    rr.m.kind = r.from_rss ? MeasurementKind::kRss : MeasurementKind::kToa;
    rr.m.z = Eigen::VectorXd::Constant(1, r.from_rss ? r.rss : r.range_m);
    const double s = r.from_rss ? rss_sigma : toa_sigma;
    rr.m.R = Eigen::MatrixXd::Constant(1, 1, s * s);
    rr.m.anchor_m = r.anchor_m;
    radio.push_back(rr);
  }
  if (radio.empty()) return FailedPrecondition("prieto: no RSS or TOA readings to fuse");
  return radio;
}

// A radio set: readings within radio_epoch_s of the set's first one, fused at its last time.
struct RadioGroup {
  double t_s = 0.0;
  std::vector<Measurement> parts;
};

std::vector<RadioGroup> GroupRadio(const std::vector<RadioReading>& radio, double epoch_s) {
  std::vector<RadioGroup> groups;
  for (size_t i = 0; i < radio.size();) {
    RadioGroup g;
    const double t_first = radio[i].t_s;
    do {
      g.t_s = radio[i].t_s;
      g.parts.push_back(radio[i].m);
      ++i;
    } while (epoch_s > 0 && i < radio.size() && radio[i].t_s < t_first + epoch_s);
    groups.push_back(std::move(g));
  }
  return groups;
}

// Timeline: the IMU samples (also for radio-only, when the walk has them), else a grid.
// Radio-only: an IMU gap (Walk::ImuGaps) is filled with the radio_only_step_s grid, so the
// [x v a] model is propagated in steps over its true duration and the readings in it are fused
// at their own times, not all at its end.
StatusOr<std::vector<double>> PrietoTimeline(const Walk& walk, const PrietoOptions& o, bool use_imu,
                                             const std::vector<RadioReading>& radio) {
  std::vector<double> times;
  if (walk.imu.size() >= 2) {
    std::vector<ImuGap> gaps = use_imu ? std::vector<ImuGap>() : walk.ImuGaps();
    size_t next_gap = 0;
    for (const ImuSample& s : walk.imu) {
      if (next_gap < gaps.size() && s.t_s >= gaps[next_gap].t_end_s) {
        const ImuGap& g = gaps[next_gap++];
        for (double t = g.t_begin_s + o.radio_only_step_s; t < g.t_end_s;
             t += o.radio_only_step_s) {
          times.push_back(t);
        }
      }
      times.push_back(s.t_s);
    }
    return times;
  }
  const double t0 = radio.front().t_s, t1 = radio.back().t_s;
  const long n = static_cast<long>(std::ceil((t1 - t0) / o.radio_only_step_s - 1e-9));
  if (n > 50'000'000) return InvalidArgument("prieto: radio_only_step_s too small");
  for (long i = 0; i <= n; ++i) times.push_back(t0 + static_cast<double>(i) * o.radio_only_step_s);
  return times;
}

// The IMU measurement blocks (eq. 7–8) and, at stance, with the stance evidences (eq. 9).
void ImuMeasurements(const PrietoOptions& o, Measurement* imu_only, Measurement* imu_stance) {
  Eigen::VectorXd r_imu(15);
  r_imu << Eigen::Vector3d::Constant(o.sigma_acc_mps2 * o.sigma_acc_mps2),
      Eigen::Vector3d::Constant(o.sigma_gyro_radps * o.sigma_gyro_radps),
      Eigen::Vector3d::Constant(o.sigma_v0_mps * o.sigma_v0_mps),
      Eigen::Vector3d::Constant(o.sigma_a0_mps2 * o.sigma_a0_mps2),
      Eigen::Vector3d::Constant(o.sigma_w0_radps * o.sigma_w0_radps);
  imu_only->kind = MeasurementKind::kImu;
  imu_only->R = r_imu.head<6>().asDiagonal();
  imu_only->z = Eigen::VectorXd::Zero(6);
  imu_stance->kind = MeasurementKind::kImuStance;
  imu_stance->R = r_imu.asDiagonal();
  imu_stance->z = Eigen::VectorXd::Zero(15);
}

// The filter's updates with their NIS bookkeeping (per measurement kind; the radio NIS also in
// `nis`) and innovation gating (kalman.h).
class UpdateBook {
 public:
  UpdateBook(PrietoCore* core, double gate_probability, std::vector<double>* nis)
      : core_(*core),
        gate_probability_(gate_probability),
        gate_quantile_(gate_probability > 0 ? ChiSquareQuantile(gate_probability, 1) : 0.0),
        nis_(*nis) {}

  Status Update(const Measurement& m, double gate) {
    WG_ASSIGN_OR_RETURN(const UpdateOutcome out, core_.Update(m, gate));
    const int kind = static_cast<int>(m.kind);
    if (!out.accepted) {
      gated_ += 1.0;
      return Status::Ok();
    }
    nis_sum_[kind] += out.nis;
    nis_n_[kind] += 1.0;
    if (m.kind != MeasurementKind::kImu && m.kind != MeasurementKind::kImuStance) {
      nis_.push_back(out.nis);
    }
    return Status::Ok();
  }

  // A radio set: one reading alone (gated by Update), or the stacked readings, each row gated
  // against the prior first.
  Status Radio(const std::vector<Measurement>& parts) {
    if (parts.size() == 1) return Update(parts[0], gate_probability_);
    std::vector<Measurement> kept;
    for (const Measurement& m : parts) {
      if (gate_probability_ > 0) {
        WG_ASSIGN_OR_RETURN(const double nis, core_.Nis(m));
        if (nis > gate_quantile_) {
          gated_ += 1.0;
          continue;
        }
      }
      kept.push_back(m);
    }
    if (kept.empty()) return Status::Ok();
    return Update(kept.size() == 1 ? kept[0] : prieto::StackMeasurements(std::move(kept)), 0.0);
  }

  // updates_<kind>, nis_mean_<kind> (where there were updates), gated_updates.
  void Report(std::map<std::string, double>* diagnostics) const {
    const char* names[5] = {"imu", "imu_stance", "rss", "toa", "radio_set"};
    for (int i = 0; i < 5; ++i) {
      (*diagnostics)[std::string("updates_") + names[i]] = nis_n_[i];
      if (nis_n_[i] > 0) {
        (*diagnostics)[std::string("nis_mean_") + names[i]] = nis_sum_[i] / nis_n_[i];
      }
    }
    (*diagnostics)["gated_updates"] = gated_;
  }

 private:
  PrietoCore& core_;
  const double gate_probability_, gate_quantile_;
  std::vector<double>& nis_;
  double nis_sum_[5] = {0, 0, 0, 0, 0}, nis_n_[5] = {0, 0, 0, 0, 0};
  double gated_ = 0.0;
};

// Health of the state at the output epochs: unit quaternion, P symmetric PD.
struct StateHealth {
  double q_norm_error = 0.0, asymmetry = 0.0, not_pd = 0.0;
  void Check(const NominalState& y, const Eigen::MatrixXd& P) {
    q_norm_error = std::max(q_norm_error, std::fabs(y.q_nb.norm() - 1.0));
    asymmetry = std::max(asymmetry, (P - P.transpose()).cwiseAbs().maxCoeff() /
                                        std::max(P.cwiseAbs().maxCoeff(), 1e-300));
    if (Eigen::LLT<Eigen::MatrixXd>(P).info() != Eigen::Success) not_pd += 1.0;
  }
};

// The filter of 002 as an error-state model (kalman_driver.h) over its timeline: the IMU sample
// as a measurement (eq. 7–9; an interval average before the prediction over its interval, an
// instantaneous sample after it), the radio sets due at each time (eq. 5–6). The RTS epochs are
// the filter state x_{m|m} (chart origin) and, in that chart, x_prior = 0, x_post = δ (the
// clone's correction), the clone's cross-covariance (see prieto.h).
class PrietoModel final : public ClonedErrorStateModel<NominalState> {
 public:
  PrietoModel(const Walk& walk, const PrietoOptions& o, std::vector<double> times,
              std::vector<RadioGroup> groups, StanceMask stance, PrietoCore* core, UpdateBook* book)
      : imu_(walk.imu),
        use_imu_(o.sensors != PrietoSensors::kRadioOnly),
        interval_(o.imu_sampling == ImuSampling::kIntervalAverage),
        output_at_radio_(o.sensors == PrietoSensors::kRadioOnly),
        times_(std::move(times)),
        groups_(std::move(groups)),
        stance_(std::move(stance)),
        core_(*core),
        book_(*book) {
    ImuMeasurements(o, &imu_only_, &imu_stance_);  // eq. 7–9
  }

  size_t size() const override { return times_.size(); }
  double Time(size_t k) const override { return times_[k]; }
  const StateHealth& health() const { return health_; }

  Status Propagate(size_t k) override {
    if (use_imu_ && interval_) WG_RETURN_IF_ERROR(ImuUpdate(k));
    return core_.Predict(times_[k] - times_[k - 1]);
  }

  Status Update(size_t k) override {
    if (use_imu_ && !interval_) WG_RETURN_IF_ERROR(ImuUpdate(k));
    radio_epoch_ = false;
    for (; ri_ < groups_.size() && groups_[ri_].t_s <= times_[k]; ++ri_) {
      WG_RETURN_IF_ERROR(book_.Radio(groups_[ri_].parts));
      radio_epoch_ = true;
    }
    return Status::Ok();
  }

  // Radio-only: the trajectory holds the estimates at the radio epochs (see prieto.h). The
  // state's health is checked at each output epoch.
  bool IsOutputEpoch(size_t, bool scheduled) override {
    const bool output = output_at_radio_ ? radio_epoch_ : scheduled;
    if (output) health_.Check(core_.y(), core_.P());
    return output;
  }

  void Output(size_t k, std::vector<TrajectoryPoint>* points) override {
    points->push_back(ToPoint(times_[k], core_.y(), core_.P()));
  }

  // The clone's P_{mj|m} closes the last epoch: RtsSmooth's C = P_{mj|m}ᵀ P_{m|m}⁻¹.
  const NominalState& nominal() const override { return core_.y(); }
  Eigen::MatrixXd Covariance() const override { return core_.P(); }
  const ErrorClone& Clone() override { return core_.clone(); }
  void StartClone() override { core_.StartClone(); }
  TrajectoryPoint SmoothedPoint(const NominalState& y, const SmoothedState& s) const override {
    return ToPoint(s.t_s, prieto::Retract(y, s.x), s.P);
  }

 private:
  Status ImuUpdate(size_t k) {
    const ImuSample& s = imu_[k];
    Measurement& m = stance_.stance[k] ? imu_stance_ : imu_only_;
    m.z.head<3>() = s.acc_mps2;        // eq. 7
    m.z.segment<3>(3) = s.gyro_radps;  // eq. 8 (stance rows stay 0: eq. 9)
    return book_.Update(m, 0.0);
  }

  const std::vector<ImuSample>& imu_;
  const bool use_imu_, interval_, output_at_radio_;
  const std::vector<double> times_;
  const std::vector<RadioGroup> groups_;
  const StanceMask stance_;
  PrietoCore& core_;
  UpdateBook& book_;
  Measurement imu_only_, imu_stance_;
  StateHealth health_;
  size_t ri_ = 0;
  bool radio_epoch_ = false;
};

}  // namespace

Status CheckPrietoApplicable(const Walk& walk, const PrietoOptions& options) {
  const bool use_imu = options.sensors != PrietoSensors::kRadioOnly;
  const bool use_radio = options.sensors != PrietoSensors::kImuOnly;
  if (use_imu && walk.imu.size() < 2) return FailedPrecondition("prieto: needs imu.csv");
  // 002 Sec. III-C: the stance evidences (zero v, a, ω) hold only on a foot.
  if (use_imu && walk.meta.imu_placement != ImuPlacement::kFoot) {
    return FailedPrecondition(
        "prieto: needs a foot-mounted IMU (imu_placement: foot): its stance evidences of zero "
        "velocity hold only on a foot (radio-only: prieto-ekf-wifi / prieto-ukf-wifi)");
  }
  if (use_radio) {
    const bool rss = options.use_rss && walk.has_rss();
    const bool toa = options.use_toa && walk.has_ranges();
    if (!rss && !toa) return FailedPrecondition("prieto: needs rss.csv or range.csv");
  }
  if (!use_radio && !walk.meta.initial_pose) {
    return FailedPrecondition("prieto IMU-only: needs initial_pose in walk.yaml (a known start)");
  }
  return Status::Ok();
}

StatusOr<EstimateResult> RunPrietoFilter(const Walk& walk, const PrietoOptions& o) {
  WG_RETURN_IF_ERROR(o.Validate());
  WG_RETURN_IF_ERROR(CheckPrietoApplicable(walk, o));
  const bool use_imu = o.sensors != PrietoSensors::kRadioOnly;
  const bool use_radio = o.sensors != PrietoSensors::kImuOnly;
  const int dim = use_imu ? prieto::kFullDim : prieto::kKinematicDim;
  if (use_imu && walk.imu.size() < 2) {
    return FailedPrecondition("prieto: needs imu.csv (>= 2 samples)");
  }
  double rss_sigma = 0.0, toa_sigma = 0.0;
  WG_ASSIGN_OR_RETURN(const MeasurementParams mp,
                      PrietoMeasurementParams(walk, o, &rss_sigma, &toa_sigma));
  std::vector<RadioReading> radio;
  if (use_radio) {
    WG_ASSIGN_OR_RETURN(radio, PrietoRadioReadings(walk, o, rss_sigma, toa_sigma));
  }
  std::vector<RadioGroup> groups = GroupRadio(radio, o.radio_epoch_s);
  WG_ASSIGN_OR_RETURN(std::vector<double> times, PrietoTimeline(walk, o, use_imu, radio));

  StanceMask stance;
  if (use_imu) {
    WG_ASSIGN_OR_RETURN(stance, DetectStance(walk, o.stance));
  }

  NominalState y0;
  Eigen::MatrixXd P0;
  InitialState(walk, o, dim, &y0, &P0);  // reads the IMU only for the full state
  PrietoCore core(o, mp, dim, y0, P0);
  WG_RETURN_IF_ERROR(core.CheckUkfWeights());

  EstimateResult result;
  UpdateBook book(&core, o.gate_probability, &result.nis);
  PrietoModel model(walk, o, std::move(times), std::move(groups), std::move(stance), &core, &book);
  ErrorStateRunOptions run;
  run.smooth = o.smooth;
  run.output_period_s = 1.0 / o.output_rate_hz;
  size_t epochs = 0;
  WG_RETURN_IF_ERROR(RunErrorStateFilter(&model, run, &result.trajectory.points, &epochs));
  if (o.smooth) result.diagnostics["rts_epochs"] = static_cast<double>(epochs);

  book.Report(&result.diagnostics);
  result.diagnostics["pd_repairs"] = core.pd_repairs();
  const StateHealth& health = model.health();
  result.diagnostics["quaternion_norm_error_max"] = health.q_norm_error;
  result.diagnostics["covariance_asymmetry_max"] = health.asymmetry;
  result.diagnostics["covariance_not_pd_epochs"] = health.not_pd;
  result.diagnostics["filter_epochs"] = static_cast<double>(model.size());
  return result;
}

Status PrietoFilter::CheckApplicable(const Walk& walk) const {
  return CheckPrietoApplicable(walk, options_);
}

StatusOr<EstimateResult> PrietoFilter::Run(const Walk& walk) const {
  return RunPrietoFilter(walk, options_);  // checks applicability first
}

namespace internal {

Status RegisterPrieto(EstimatorRegistry* registry) {
  struct Variant {
    const char* id;
    const char* description;
    PrietoFilterKind filter;
    PrietoSensors sensors;
    bool smooth;
  };
  const Variant variants[] = {
      {"prieto-ekf", "002 eq. 1-9: EKF, foot IMU as measurements + stance evidences + RSS/TOA",
       PrietoFilterKind::kEkf, PrietoSensors::kFusion, false},
      {"prieto-ukf",
       "002 eq. 1-9: UKF (scaled sigma points, quaternion mean), IMU + stance + RSS/TOA",
       PrietoFilterKind::kUkf, PrietoSensors::kFusion, false},
      {"prieto-ekf-rts", "002: prieto-ekf + RTS smoother at the output rate (stochastic cloning)",
       PrietoFilterKind::kEkf, PrietoSensors::kFusion, true},
      {"prieto-ukf-rts", "002: prieto-ukf + unscented RTS at the output rate (stochastic cloning)",
       PrietoFilterKind::kUkf, PrietoSensors::kFusion, true},
      {"prieto-ekf-imu", "002 Table I EKF-IMU: IMU + stance evidences only (no radio)",
       PrietoFilterKind::kEkf, PrietoSensors::kImuOnly, false},
      {"prieto-ukf-imu", "002 Table I UKF-IMU: IMU + stance evidences only (no radio)",
       PrietoFilterKind::kUkf, PrietoSensors::kImuOnly, false},
      {"prieto-ekf-wifi", "002 Table I EKF-WiFi: RSS + TOA only, state [x v a]",
       PrietoFilterKind::kEkf, PrietoSensors::kRadioOnly, false},
      {"prieto-ukf-wifi", "002 Table I UKF-WiFi: RSS + TOA only, state [x v a]",
       PrietoFilterKind::kUkf, PrietoSensors::kRadioOnly, false},
  };
  for (const Variant& v : variants) {
    PrietoOptions defaults;
    defaults.filter = v.filter;
    defaults.sensors = v.sensors;
    defaults.smooth = v.smooth;
    if (v.sensors == PrietoSensors::kRadioOnly) {  // see prieto.h
      defaults.sigma_jerk_mps3 = 1.0;
      defaults.radio_epoch_s = 1.0;
    }
    const std::string id = v.id;
    auto parse = [id, defaults](const YAML::Node& config) {
      return PrietoOptionsFromYaml(config, id, defaults);
    };
    WG_RETURN_IF_ERROR(
        registry->Register({id, v.description, OptionsFactory<PrietoFilter>(parse)}));
  }
  return Status::Ok();
}

}  // namespace internal
}  // namespace walkgraph
