#include <algorithm>
#include <cmath>

#include "walkgraph/angle.h"
#include "simulate/sim_models.h"

namespace walkgraph {
namespace sim {

namespace {

// Angle from direction a to direction b, in (-π, π].
double TurnAngle(const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
  return std::atan2(a.x() * b.y() - a.y() * b.x(), a.dot(b));
}

// The value of `angle` + 2πk closest to `reference` (keeps headings continuous).
double Unwrap(double angle, double reference) {
  return reference + NormalizeAngle(angle - reference);
}

}  // namespace

Eigen::Vector2d PathSegment::PositionAt(double s) const {
  if (std::fabs(curvature_1pm) < 1e-12) {
    return start + s * Eigen::Vector2d(std::cos(heading0_rad), std::sin(heading0_rad));
  }
  const double k = curvature_1pm, h1 = heading0_rad + k * s;
  return start + Eigen::Vector2d((std::sin(h1) - std::sin(heading0_rad)) / k,
                                 (std::cos(heading0_rad) - std::cos(h1)) / k);
}

std::vector<PathSegment> CirclePath(const Eigen::Vector2d& center, double radius_m,
                                    double start_angle_rad, double laps, bool ccw) {
  PathSegment arc;
  arc.start =
      center + radius_m * Eigen::Vector2d(std::cos(start_angle_rad), std::sin(start_angle_rad));
  arc.heading0_rad = start_angle_rad + (ccw ? 0.5 : -0.5) * kPi;
  arc.length_m = 2.0 * kPi * radius_m * laps;
  arc.curvature_1pm = (ccw ? 1.0 : -1.0) / radius_m;
  return {arc};
}

double PolylineLength(const std::vector<Eigen::Vector2d>& w) {
  double length = 0.0;
  for (size_t i = 1; i < w.size(); ++i) length += (w[i] - w[i - 1]).norm();
  return length;
}

std::vector<PathSegment> PolylinePath(const std::vector<Eigen::Vector2d>& waypoints,
                                      double corner_radius_m) {
  std::vector<Eigen::Vector2d> w;
  for (const auto& p : waypoints) {
    if (w.empty() || (p - w.back()).norm() > 1e-9) w.push_back(p);
  }
  std::vector<PathSegment> segs;
  if (w.size() < 2) return segs;
  double heading = std::atan2(w[1].y() - w[0].y(), w[1].x() - w[0].x());
  Eigen::Vector2d cursor = w[0];
  auto add_line = [&](const Eigen::Vector2d& to) {
    const double len = (to - cursor).norm();
    if (len < 1e-9) return;
    PathSegment s;
    s.start = cursor;
    s.heading0_rad = heading;
    s.length_m = len;
    segs.push_back(s);
    cursor = to;
  };
  for (size_t i = 1; i + 1 < w.size(); ++i) {
    const Eigen::Vector2d din = (w[i] - w[i - 1]).normalized();
    const Eigen::Vector2d dout = (w[i + 1] - w[i]).normalized();
    const double alpha = TurnAngle(din, dout);
    if (std::fabs(alpha) < 1e-9) continue;
    const double max_tangent = 0.5 * std::min((w[i] - w[i - 1]).norm(), (w[i + 1] - w[i]).norm());
    double r = corner_radius_m;
    double tangent = r * std::tan(0.5 * std::fabs(alpha));
    if (tangent > max_tangent) {
      tangent = max_tangent;
      r = tangent / std::tan(0.5 * std::fabs(alpha));
    }
    add_line(w[i] - tangent * din);
    PathSegment arc;
    arc.start = cursor;
    arc.heading0_rad = heading;
    arc.curvature_1pm = (alpha > 0 ? 1.0 : -1.0) / r;
    arc.length_m = r * std::fabs(alpha);
    segs.push_back(arc);
    heading += alpha;
    cursor = arc.PositionAt(arc.length_m);
  }
  add_line(w.back());
  return segs;
}

std::vector<std::vector<Eigen::Vector2d>> SplitAtSharpTurns(
    const std::vector<Eigen::Vector2d>& waypoints, double max_turn_rad) {
  std::vector<std::vector<Eigen::Vector2d>> pieces(1);
  for (size_t i = 0; i < waypoints.size(); ++i) {
    pieces.back().push_back(waypoints[i]);
    if (i == 0 || i + 1 >= waypoints.size()) continue;
    const Eigen::Vector2d din = waypoints[i] - waypoints[i - 1];
    const Eigen::Vector2d dout = waypoints[i + 1] - waypoints[i];
    if (din.norm() < 1e-9 || dout.norm() < 1e-9) continue;
    if (std::fabs(TurnAngle(din, dout)) > max_turn_rad) pieces.push_back({waypoints[i]});
  }
  return pieces;
}

std::vector<Eigen::Vector2d> RepeatLoop(const std::vector<Eigen::Vector2d>& polygon, int laps) {
  std::vector<Eigen::Vector2d> w;
  for (int lap = 0; lap < laps; ++lap) {
    for (const auto& p : polygon) w.push_back(p);
  }
  if (!polygon.empty()) w.push_back(polygon.front());
  return w;
}

std::vector<Eigen::Vector2d> RectangleLoop(double x0, double y0, double w, double h) {
  return {{x0, y0}, {x0 + w, y0}, {x0 + w, y0 + h}, {x0, y0 + h}};
}

// ------------------------------------------------------------------ MotionPlan

MotionPlan::MotionPlan(const Eigen::Vector2d& start, double heading_rad)
    : position_(start), heading_(heading_rad) {}

void MotionPlan::Stop(double duration_s) {
  if (!(duration_s > 0.0)) return;
  Phase p;
  p.kind = PhaseKind::kStop;
  p.t0_s = duration();
  p.t1_s = p.t0_s + duration_s;
  p.start = position_;
  p.heading0_rad = heading_;
  p.z0_m = height_;
  phases_.push_back(p);
}

void MotionPlan::Turn(double dheading_rad, double duration_s) {
  if (std::fabs(dheading_rad) < 1e-12 || !(duration_s > 0.0)) return;
  Phase p;
  p.kind = PhaseKind::kTurn;
  p.t0_s = duration();
  p.t1_s = p.t0_s + duration_s;
  p.start = position_;
  p.heading0_rad = heading_;
  p.z0_m = height_;
  p.dheading_rad = dheading_rad;
  phases_.push_back(p);
  heading_ += dheading_rad;
}

void MotionPlan::Walk(std::vector<PathSegment> segments, double speed_mps, bool from_rest,
                      bool to_rest, double ramp_s) {
  if (segments.empty() || !(speed_mps > 0.0)) return;
  // Headings stay continuous: shift by 2πk; a real mismatch becomes a turn in place.
  const double h0 = Unwrap(segments.front().heading0_rad, heading_);
  const double shift = h0 - segments.front().heading0_rad;
  for (auto& s : segments) s.heading0_rad += shift;
  if (std::fabs(h0 - heading_) > 1e-6) {
    const double d = h0 - heading_;
    Turn(d, 0.5 + std::fabs(d) / (0.5 * kPi));
  }
  Phase p;
  p.kind = PhaseKind::kLeg;
  p.t0_s = duration();
  p.start = segments.front().start;
  p.heading0_rad = h0;
  p.z0_m = height_;
  double total = 0.0, rise = 0.0;
  for (const auto& s : segments) {
    p.cumulative_m.push_back(total);
    p.cumulative_z_m.push_back(rise);
    total += s.length_m;
    rise += s.climb * s.length_m;
  }
  height_ += rise;
  p.segments = std::move(segments);
  p.length_m = total;
  p.ramp_up_s = from_rest ? ramp_s : 0.0;
  p.ramp_down_s = to_rest ? ramp_s : 0.0;
  double v = speed_mps;
  const double ramp_dist = 0.5 * v * (p.ramp_up_s + p.ramp_down_s);
  double cruise_s = (total - ramp_dist) / v;
  if (cruise_s < 0.0) {
    v = total / (0.5 * (p.ramp_up_s + p.ramp_down_s));
    cruise_s = 0.0;
  }
  p.cruise_mps = v;
  p.t1_s = p.t0_s + p.ramp_up_s + cruise_s + p.ramp_down_s;
  const PathSegment& last = p.segments.back();
  position_ = last.PositionAt(last.length_m);
  heading_ = last.HeadingAt(last.length_m);
  phases_.push_back(std::move(p));
}

void MotionPlan::WalkWaypoints(const std::vector<Eigen::Vector2d>& waypoints, double speed_mps,
                               double corner_radius_m, double pause_s) {
  std::vector<Eigen::Vector2d> w = waypoints;
  if (w.empty()) return;
  if ((w.front() - position_).norm() > 1e-9) w.insert(w.begin(), position_);
  const auto pieces = SplitAtSharpTurns(w, DegToRad(120.0));
  for (size_t i = 0; i < pieces.size(); ++i) {
    if (i > 0) Stop(0.5 * pause_s);
    auto segs = PolylinePath(pieces[i], corner_radius_m);
    if (segs.empty()) continue;
    Walk(std::move(segs), speed_mps, true, true);
    if (i + 1 < pieces.size()) Stop(0.5 * pause_s);
  }
}

void MotionPlan::LegProfile(const Phase& leg, double tau, double* s, double* v, double* a) {
  const double vc = leg.cruise_mps, tu = leg.ramp_up_s, td = leg.ramp_down_s;
  const double duration = leg.t1_s - leg.t0_s;
  const double tc = duration - tu - td;
  tau = std::clamp(tau, 0.0, duration);
  if (tau < tu) {
    const double x = kPi * tau / tu;
    *s = 0.5 * vc * (tau - tu / kPi * std::sin(x));
    *v = 0.5 * vc * (1.0 - std::cos(x));
    *a = 0.5 * vc * kPi / tu * std::sin(x);
  } else if (tau <= tu + tc) {
    *s = 0.5 * vc * tu + vc * (tau - tu);
    *v = vc;
    *a = 0.0;
  } else {
    const double tt = tau - tu - tc, x = kPi * tt / td;
    *s = 0.5 * vc * tu + vc * tc + 0.5 * vc * (tt + td / kPi * std::sin(x));
    *v = 0.5 * vc * (1.0 + std::cos(x));
    *a = -0.5 * vc * kPi / td * std::sin(x);
  }
  *s = std::min(*s, leg.length_m);
}

BodyState MotionPlan::At(double t_s) const {
  BodyState b;
  b.t_s = t_s;
  b.position_m = position_;
  b.heading_rad = heading_;
  b.z_m = height_;
  if (phases_.empty()) return b;
  auto it = std::upper_bound(phases_.begin(), phases_.end(), t_s,
                             [](double t, const Phase& p) { return t < p.t0_s; });
  if (it != phases_.begin()) --it;
  const Phase& p = *it;
  if (t_s >= p.t1_s && it + 1 == phases_.end()) return b;  // after the end: at rest
  const double tau = std::max(0.0, t_s - p.t0_s);
  b.position_m = p.start;
  b.heading_rad = p.heading0_rad;
  b.z_m = p.z0_m;
  if (p.kind == PhaseKind::kTurn) {
    const double d = p.t1_s - p.t0_s, x = kPi * std::min(tau, d) / d;
    b.heading_rad = p.heading0_rad + p.dheading_rad * 0.5 * (1.0 - std::cos(x));
    b.yaw_rate_radps = p.dheading_rad * 0.5 * kPi / d * std::sin(x);
  } else if (p.kind == PhaseKind::kLeg) {
    double s, v, a;
    LegProfile(p, tau, &s, &v, &a);
    size_t i =
        std::upper_bound(p.cumulative_m.begin(), p.cumulative_m.end(), s) - p.cumulative_m.begin();
    i = i == 0 ? 0 : i - 1;
    const PathSegment& seg = p.segments[i];
    const double ls = std::min(s - p.cumulative_m[i], seg.length_m);
    b.position_m = seg.PositionAt(ls);
    b.heading_rad = seg.HeadingAt(ls);
    b.speed_mps = v;
    b.accel_mps2 = a;
    b.curvature_1pm = seg.curvature_1pm;
    b.yaw_rate_radps = seg.curvature_1pm * v;
    b.moving = v > 0.0;
    b.z_m = p.z0_m + p.cumulative_z_m[i] + seg.climb * ls;
    b.vz_mps = seg.climb * v;
    b.az_mps2 = seg.climb * a;
    b.step_length_m = seg.step_length_m;
  }
  return b;
}

}  // namespace sim
}  // namespace walkgraph
