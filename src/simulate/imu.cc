#include <algorithm>
#include <cmath>

#include "simulate/sim_models.h"
#include "walkgraph/angle.h"
#include "walkgraph/strapdown.h"

namespace walkgraph {
namespace sim {

// ------------------------------------------------------------------ gait

double StepLength(const GaitOptions& g, double speed_mps) {
  return g.step_length_a_m + g.step_length_b_s * speed_mps;
}
double StepFrequency(const GaitOptions& g, double speed_mps) {
  return speed_mps / StepLength(g, speed_mps);
}
double StepAmplitude(const GaitOptions& g, double step_length_m) {
  return 0.5 * std::pow(step_length_m / g.weinberg_k, 4.0);
}

namespace {

// Smooth 0→1 fade of the gait amplitude at walking onset (C¹ smoothstep of v / v_min).
double Activity(const GaitOptions& g, double v) {
  const double x = std::clamp(v / g.walking_speed_min_mps, 0.0, 1.0);
  return x * x * (3.0 - 2.0 * x);
}

// The step length whose Weinberg amplitude the waist shows: the step's own on level ground; on
// stairs (a fixed tread) that of a level step at the same cadence f, l = a/(1 − b·f) from
// l = a + b·v and f = v/l [a stair step shakes the pelvis like a level step of its rhythm, so
// Weinberg overestimates a tread, as on real stairs].
double BouncingLength(const GaitOptions& g, double l, double f, const BodyState& b) {
  if (!(b.step_length_m > 0.0)) return l;
  return g.step_length_a_m / std::max(0.1, 1.0 - g.step_length_b_s * f);
}

Eigen::Matrix3d Rz(double a) { return Eigen::AngleAxisd(a, Eigen::Vector3d::UnitZ()).matrix(); }

}  // namespace

// ------------------------------------------------------------------ magnetic field

MagneticField::MagneticField(const MagneticFieldOptions& options, Rng rng) : o_(options) {
  const double inc = DegToRad(o_.inclination_deg), dec = DegToRad(o_.declination_deg);
  const double h = o_.field_ut * std::cos(inc);
  earth_ = Eigen::Vector3d(h * std::sin(dec), h * std::cos(dec), -o_.field_ut * std::sin(inc));
  for (int i = 0; i < o_.disturbance_count; ++i) {
    Eigen::Vector2d c(rng.Uniform(o_.area_min.x(), o_.area_max.x()),
                      rng.Uniform(o_.area_min.y(), o_.area_max.y()));
    Eigen::Vector3d dir(rng.Gaussian(), rng.Gaussian(), rng.Gaussian());
    dir.normalize();
    blobs_.emplace_back(c, dir * o_.disturbance_ut * rng.Uniform(0.5, 1.0));
  }
}

Eigen::Vector3d MagneticField::At(const Eigen::Vector3d& p) const {
  Eigen::Vector3d m = earth_;
  const double inv = 1.0 / (2.0 * o_.disturbance_radius_m * o_.disturbance_radius_m);
  for (const auto& [c, v] : blobs_) m += v * std::exp(-(p.head<2>() - c).squaredNorm() * inv);
  return m;
}

// ------------------------------------------------------------------ IMU errors

std::vector<ImuSample> ApplyImuErrors(const std::vector<ImuTruth>& truth, const ImuNoiseOptions& n,
                                      const MagneticField* field, Rng rng, ImuBiasTrace* biases) {
  Rng acc_rng = rng.Fork(1), gyro_rng = rng.Fork(2), mag_rng = rng.Fork(3), bias_rng = rng.Fork(4);
  Eigen::Vector3d ba, bg;
  for (int i = 0; i < 3; ++i) ba[i] = bias_rng.Gaussian(0.0, n.acc_bias_sigma_mps2);
  for (int i = 0; i < 3; ++i) bg[i] = bias_rng.Gaussian(0.0, n.gyro_bias_sigma_radps);
  bg += n.gyro_bias_fixed_radps;
  std::vector<ImuSample> out;
  out.reserve(truth.size());
  long gyro_slot = -1, mag_slot = -1;
  Eigen::Vector3d gyro_hold = Eigen::Vector3d::Zero(), mag_hold = Eigen::Vector3d::Zero();
  for (size_t k = 0; k < truth.size(); ++k) {
    const ImuTruth& s = truth[k];
    if (k > 0) {
      const double sq = std::sqrt(std::max(0.0, s.t_s - truth[k - 1].t_s));
      for (int i = 0; i < 3; ++i) ba[i] += bias_rng.Gaussian(0.0, n.acc_bias_rw_mps2_sqrts * sq);
      for (int i = 0; i < 3; ++i) {
        bg[i] += bias_rng.Gaussian(0.0, n.gyro_bias_rw_radps_sqrts * sq);
      }
    }
    ImuSample m;
    m.t_s = s.t_s;
    for (int i = 0; i < 3; ++i) {
      m.acc_mps2[i] = s.specific_force_b[i] + ba[i] + acc_rng.Gaussian(0.0, n.acc_noise_mps2);
    }
    Eigen::Vector3d g;
    for (int i = 0; i < 3; ++i) {
      g[i] = s.angular_rate_b[i] + bg[i] + gyro_rng.Gaussian(0.0, n.gyro_noise_radps);
    }
    const long gs = n.gyro_rate_hz > 0 ? static_cast<long>(std::floor(s.t_s * n.gyro_rate_hz))
                                       : static_cast<long>(k);
    if (gs != gyro_slot) {
      gyro_slot = gs;
      gyro_hold = g;
    }
    m.gyro_radps = gyro_hold;
    if (field != nullptr) {
      Eigen::Vector3d mb = s.q_nb.conjugate() * field->At(s.position_n);
      for (int i = 0; i < 3; ++i) mb[i] += mag_rng.Gaussian(0.0, n.mag_noise_ut);
      const long ms = n.mag_rate_hz > 0 ? static_cast<long>(std::floor(s.t_s * n.mag_rate_hz))
                                        : static_cast<long>(k);
      if (ms != mag_slot) {
        mag_slot = ms;
        mag_hold = mb;
      }
      m.has_mag = true;
      m.mag_ut = mag_hold;
    }
    if (biases != nullptr) {
      biases->acc_bias.push_back(ba);
      biases->gyro_bias.push_back(bg);
    }
    out.push_back(m);
  }
  return out;
}

// ------------------------------------------------------------------ waist / hip

WaistImuResult SimulateWaistImu(const MotionPlan& plan, const WaistImuOptions& o) {
  WaistImuResult r;
  const long n = static_cast<long>(std::floor(plan.duration() * o.rate_hz + 1e-9)) + 1;
  r.truth.reserve(n);
  double phase = 0.0, dist = 0.0, prev_f = 0.0, prev_v = 0.0, prev_t = 0.0;
  double last_step_t = 0.0, last_step_dist = 0.0;
  const Eigen::Vector3d g_up(0.0, 0.0, kGravityMps2);
  for (long k = 0; k < n; ++k) {
    const double t = static_cast<double>(k) / o.rate_hz;
    const BodyState b = plan.At(t);
    const double v = b.speed_mps;
    const double l = b.step_length_m > 0.0 ? b.step_length_m : StepLength(o.gait, v);
    const double f = v > 0.0 ? v / l : 0.0;
    if (k > 0) {
      const double dt = t - prev_t;
      const double new_phase = phase + 0.5 * (f + prev_f) * dt;
      const double new_dist = dist + 0.5 * (v + prev_v) * dt;
      // Step events at integer crossings of the phase (linear interpolation inside the sample).
      for (double c = std::floor(phase) + 1.0; c <= new_phase; c += 1.0) {
        const double a = (c - phase) / (new_phase - phase);
        StepEvent e;
        e.t_s = prev_t + a * dt;
        const double d = dist + a * (new_dist - dist);
        e.length_m = d - last_step_dist;
        e.duration_s = e.t_s - last_step_t;
        last_step_dist = d;
        last_step_t = e.t_s;
        r.steps.push_back(e);
      }
      phase = new_phase;
      dist = new_dist;
    }
    prev_f = f;
    prev_v = v;
    prev_t = t;
    const double act = Activity(o.gait, v);
    const double two_pi_phi = 2.0 * kPi * phase;
    const double a_vert =
        act * StepAmplitude(o.gait, BouncingLength(o.gait, l, f, b)) * std::sin(two_pi_phi);
    // Pelvis sway at stride frequency f/2: lateral position S·sin(πφ), yaw Y·cos(πφ).
    const double w = kPi * f;
    const double a_lat = -act * o.lateral_sway_m * w * w * std::sin(0.5 * two_pi_phi);
    const double yaw_sway = act * o.yaw_sway_rad * std::cos(0.5 * two_pi_phi);
    const double yaw_sway_rate = -act * o.yaw_sway_rad * w * std::sin(0.5 * two_pi_phi);
    const Eigen::Vector3d fwd(std::cos(b.heading_rad), std::sin(b.heading_rad), 0.0);
    const Eigen::Vector3d left(-fwd.y(), fwd.x(), 0.0);
    const double a_swing = act * o.forward_swing_mps2 * std::cos(two_pi_phi);
    const double a_shake =
        (1.0 - act) * o.hand_shake_mps2 *
        (std::sin(2.0 * kPi * 1.3 * t) + 0.6 * std::sin(2.0 * kPi * 2.9 * t + 1.0));
    const Eigen::Vector3d a_n = (b.accel_mps2 + a_swing) * fwd +
                                (v * b.yaw_rate_radps + a_lat) * left +
                                Eigen::Vector3d(0.0, 0.0, a_vert + a_shake + b.az_mps2);
    ImuTruth s;
    s.t_s = t;
    s.position_n = Eigen::Vector3d(b.position_m.x(), b.position_m.y(), o.height_m + b.z_m);
    s.velocity_n = v * fwd + Eigen::Vector3d(0.0, 0.0, b.vz_mps);
    const Eigen::Matrix3d R = Rz(b.heading_rad + yaw_sway + o.device_yaw_rad);
    s.q_nb = Eigen::Quaterniond(R);
    s.specific_force_b = R.transpose() * (a_n + g_up);
    s.angular_rate_b = Eigen::Vector3d(0.0, 0.0, b.yaw_rate_radps + yaw_sway_rate);
    s.stance = !b.moving;
    r.truth.push_back(s);
  }
  return r;
}

// ------------------------------------------------------------------ foot

namespace {

// Progress σ(u) = 126u⁵ − 420u⁶ + 540u⁷ − 315u⁸ + 70u⁹ and its first two derivatives.
void Progress(double u, double* s, double* ds, double* dds) {
  const double q = u * (1.0 - u);
  *s = u * u * u * u * u * (126.0 + u * (-420.0 + u * (540.0 + u * (-315.0 + u * 70.0))));
  *ds = 630.0 * q * q * q * q;
  *dds = 2520.0 * q * q * q * (1.0 - 2.0 * u);
}

// Bump b(u) = (4u(1−u))⁵ and its first two derivatives.
void Bump(double u, double* b, double* db, double* ddb) {
  const double q = u * (1.0 - u), dq = 1.0 - 2.0 * u;
  const double q3 = q * q * q;
  *b = 1024.0 * q3 * q * q;
  *db = 5120.0 * q3 * q * dq;
  *ddb = 5120.0 * q3 * (4.0 * dq * dq - 2.0 * q);
}

// The height of the tread reached after `steps` steps of stairs: up flight_rises rises, down as
// many, and again (0 on level ground).
double StairHeight(const FootImuOptions& o, long steps) {
  if (!(o.stair_rise_m > 0.0)) return 0.0;
  const long f = std::max(1, o.flight_rises);
  const long m = steps % (2 * f);
  return o.stair_rise_m * static_cast<double>(m <= f ? m : 2 * f - m);
}

// The footprints of one leg, evenly spaced in arc length (a stride apart, or two treads on
// stairs), at the times the plan's profile passes them; *steps counts the walk's steps.
void LegFootprints(const MotionPlan::Phase& p, const FootImuOptions& o, long* steps,
                   std::vector<double>* times, std::vector<Footprint>* prints) {
  const bool stairs = o.stair_rise_m > 0.0;
  const double stride = stairs ? 2.0 * o.stair_tread_m : 2.0 * StepLength(o.gait, p.cruise_mps);
  const int n = std::max(1, static_cast<int>(std::lround(p.length_m / stride)));
  times->assign(n + 1, 0.0);
  prints->assign(n + 1, Footprint());
  for (int j = 0; j <= n; ++j) {
    const double target = p.length_m * j / n;
    double lo = 0.0, hi = p.t1_s - p.t0_s;
    if (j == 0) hi = 0.0;
    for (int it = 0; j > 0 && j < n && it < 60; ++it) {
      const double mid = 0.5 * (lo + hi);
      double s, v, a;
      MotionPlan::LegProfile(p, mid, &s, &v, &a);
      (s < target ? lo : hi) = mid;
    }
    (*times)[j] = p.t0_s + (j == n ? p.t1_s - p.t0_s : hi);
    // The footprint lies on the path at arc length `target`.
    size_t i = std::upper_bound(p.cumulative_m.begin(), p.cumulative_m.end(), target) -
               p.cumulative_m.begin();
    i = i == 0 ? 0 : i - 1;
    const PathSegment& seg = p.segments[i];
    const double ls = std::min(target - p.cumulative_m[i], seg.length_m);
    (*prints)[j].position = seg.PositionAt(ls);
    (*prints)[j].heading_rad = seg.HeadingAt(ls);
    (*prints)[j].z_m = StairHeight(o, *steps + 2L * j);
  }
  *steps += 2L * n;
}

}  // namespace

FootMotion::FootMotion(const MotionPlan& plan, const FootImuOptions& options) : o_(options) {
  duration_ = plan.duration();
  const double rho = o_.stance_fraction;
  first_.position = plan.At(0.0).position_m;
  first_.heading_rad = plan.At(0.0).heading_rad;
  long steps = 0;
  for (const auto& p : plan.phases()) {
    if (p.kind == MotionPlan::PhaseKind::kLeg) {
      std::vector<double> times;
      std::vector<Footprint> prints;
      LegFootprints(p, o_, &steps, &times, &prints);
      for (size_t j = 0; j + 1 < prints.size(); ++j) {
        const double gap = times[j + 1] - times[j];
        FootSwing s;
        s.t0_s = times[j] + 0.5 * rho * gap;
        s.t1_s = times[j + 1] - 0.5 * rho * gap;
        s.from = prints[j];
        s.to = prints[j + 1];
        swings_.push_back(s);
      }
    } else if (p.kind == MotionPlan::PhaseKind::kTurn) {
      const int n = std::max(
          1, static_cast<int>(
                 std::ceil(std::fabs(p.dheading_rad) / DegToRad(o_.max_pivot_deg) - 1e-9)));
      const double gap = (p.t1_s - p.t0_s) / n;
      for (int j = 0; j < n; ++j) {
        FootSwing s;
        s.t0_s = p.t0_s + j * gap + 0.5 * rho * gap;
        s.t1_s = p.t0_s + (j + 1) * gap - 0.5 * rho * gap;
        s.from.position = s.to.position = p.start;
        s.from.z_m = s.to.z_m = StairHeight(o_, steps);
        s.from.heading_rad = p.heading0_rad + p.dheading_rad * j / n;
        s.to.heading_rad = p.heading0_rad + p.dheading_rad * (j + 1) / n;
        swings_.push_back(s);
      }
    }
  }
  // Normalise the pitch shape b(u)·sin(2πu) to a peak of 1.
  double peak = 0.0;
  for (int i = 0; i <= 10000; ++i) {
    const double u = i / 10000.0;
    double b, db, ddb;
    Bump(u, &b, &db, &ddb);
    peak = std::max(peak, b * std::sin(2.0 * kPi * u));
  }
  pitch_norm_ = peak;
}

ImuTruth FootMotion::At(double t_s) const {
  ImuTruth s;
  s.t_s = t_s;
  auto it = std::upper_bound(swings_.begin(), swings_.end(), t_s,
                             [](double t, const FootSwing& w) { return t < w.t0_s; });
  const FootSwing* swing = nullptr;
  Footprint rest = first_;
  if (it != swings_.begin()) {
    const FootSwing& w = *(it - 1);
    if (t_s < w.t1_s) {
      swing = &w;
    } else {
      rest = w.to;
    }
  }
  const Eigen::Vector3d g_up(0.0, 0.0, kGravityMps2);
  if (swing == nullptr) {
    s.position_n = Eigen::Vector3d(rest.position.x(), rest.position.y(), rest.z_m);
    const Eigen::Matrix3d R = Rz(rest.heading_rad);
    s.q_nb = Eigen::Quaterniond(R);
    s.specific_force_b = R.transpose() * g_up;
    s.stance = true;
    return s;
  }
  const double T = swing->t1_s - swing->t0_s;
  const double u = (t_s - swing->t0_s) / T;
  double sg, dsg, ddsg, b, db, ddb;
  Progress(u, &sg, &dsg, &ddsg);
  Bump(u, &b, &db, &ddb);
  const Eigen::Vector2d dp = swing->to.position - swing->from.position;
  const double dpsi = swing->to.heading_rad - swing->from.heading_rad;
  const Eigen::Vector2d p = swing->from.position + sg * dp;
  const Eigen::Vector2d v = dsg / T * dp;
  const Eigen::Vector2d a = ddsg / (T * T) * dp;
  // Height: the straight line between the treads plus the lift bump.
  const double h = o_.lift_m, dz = swing->to.z_m - swing->from.z_m;
  s.position_n = Eigen::Vector3d(p.x(), p.y(), swing->from.z_m + sg * dz + h * b);
  s.velocity_n = Eigen::Vector3d(v.x(), v.y(), (dsg * dz + h * db) / T);
  const Eigen::Vector3d a_n(a.x(), a.y(), (ddsg * dz + h * ddb) / (T * T));
  const double psi = swing->from.heading_rad + dpsi * sg;
  const double psi_rate = dpsi * dsg / T;
  const double amp = DegToRad(o_.pitch_amplitude_deg) / pitch_norm_;
  const double su = std::sin(2.0 * kPi * u), cu = std::cos(2.0 * kPi * u);
  const double theta = amp * b * su;
  const double theta_rate = amp * (db * su + 2.0 * kPi * b * cu) / T;
  const Eigen::Matrix3d R = Rz(psi) * Eigen::AngleAxisd(theta, Eigen::Vector3d::UnitY()).matrix();
  s.q_nb = Eigen::Quaterniond(R);
  s.specific_force_b = R.transpose() * (a_n + g_up);
  // R = Rz(ψ)·Ry(θ)  ⇒  ω_b = Ry(θ)ᵀ·(0, 0, ψ̇) + (0, θ̇, 0).
  s.angular_rate_b =
      Eigen::Vector3d(-std::sin(theta) * psi_rate, theta_rate, std::cos(theta) * psi_rate);
  s.stance = false;
  return s;
}

std::vector<ImuTruth> SampleFootImu(const FootMotion& foot, double rate_hz, bool interval_average) {
  const long n = static_cast<long>(std::floor(foot.duration() * rate_hz + 1e-9)) + 1;
  std::vector<ImuTruth> out;
  out.reserve(n);
  const Eigen::Vector3d g_up(0.0, 0.0, kGravityMps2);
  for (long k = 0; k < n; ++k) {
    ImuTruth s = foot.At(static_cast<double>(k) / rate_hz);
    if (interval_average && k > 0) {
      const ImuTruth& p = out.back();
      const double dt = s.t_s - p.t_s;
      s.angular_rate_b = QuaternionLog(p.q_nb.conjugate() * s.q_nb) / dt;
      s.specific_force_b = p.q_nb.conjugate() * ((s.velocity_n - p.velocity_n) / dt + g_up);
    }
    out.push_back(s);
  }
  return out;
}

}  // namespace sim
}  // namespace walkgraph
