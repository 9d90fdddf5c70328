#include "walkgraph/divergence.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

#include <Eigen/Eigenvalues>

#include "util/median.h"
#include "util/text.h"

namespace walkgraph {

Status DivergenceOptions::Validate() const {
  if (!(min_margin_m >= 0.0) || !(margin_fraction >= 0.0) || !(nees_window_s > 0.0) ||
      !(nees_limit > 2.0) || !(nees_min_error_m >= 0.0) ||
      !std::isfinite(min_margin_m + margin_fraction + nees_window_s + nees_min_error_m)) {
    return InvalidArgument(
        "divergence: need min_margin_m >= 0, margin_fraction >= 0, nees_window_s > 0, "
        "nees_limit > 2 (the χ²(2) mean) and nees_min_error_m >= 0, all finite");
  }
  return Status::Ok();
}

namespace {

struct Box {
  double x0 = std::numeric_limits<double>::infinity(), y0 = x0;
  double x1 = -std::numeric_limits<double>::infinity(), y1 = x1;
  void Grow(double x, double y) {
    x0 = std::min(x0, x);
    x1 = std::max(x1, x);
    y0 = std::min(y0, y);
    y1 = std::max(y1, y);
  }
  bool Empty() const { return !(x1 >= x0); }
  // Distance from (x, y) to the box (0 inside).
  double Outside(double x, double y) const {
    const double dx = std::max({x0 - x, 0.0, x - x1});
    const double dy = std::max({y0 - y, 0.0, y - y1});
    return std::hypot(dx, dy);
  }
};

Box SceneBox(const Walk& walk) {
  Box box;
  for (const Anchor& a : walk.anchors) {
    if (a.position_known) box.Grow(a.position_m.x(), a.position_m.y());
  }
  for (const TruthSample& t : walk.truth) box.Grow(t.position_m.x(), t.position_m.y());
  if (walk.meta.initial_pose) box.Grow(walk.meta.initial_pose->x_m, walk.meta.initial_pose->y_m);
  return box;
}

std::string Distance(double m) {
  return m >= 1000.0 ? internal::Num(std::round(m / 100.0) / 10.0) + " km"
                     : internal::Num(std::round(m)) + " m";
}

// The first point of the trajectory (from from_t_s on) that breaks one of the point rules.
std::optional<Divergence> FirstBadPoint(const Trajectory& trajectory, const Box& box, double margin,
                                        double from_t_s) {
  for (const TrajectoryPoint& p : trajectory.points) {
    if (p.t_s < from_t_s) continue;
    if (!p.position_m.allFinite() || !std::isfinite(p.heading_rad) ||
        (p.covariance && !p.covariance->allFinite())) {
      return Divergence{p.t_s, "a position, heading or covariance is NaN or infinite"};
    }
    if (p.covariance) {
      // Positive semi-definite: a point held constant to fix the gauge (the step graph's
      // first node without a known start) has a zero covariance by construction, which is no
      // divergence; a negative eigenvalue beyond rounding is.
      const Eigen::Matrix2d P = p.covariance->topLeftCorner<2, 2>();
      const Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> eig(0.5 * (P + P.transpose()),
                                                               Eigen::EigenvaluesOnly);
      const Eigen::Vector2d ev = eig.eigenvalues();
      if (ev.minCoeff() < -1e-9 * std::max(1.0, ev.cwiseAbs().maxCoeff())) {
        return Divergence{p.t_s, "its position covariance is not positive semi-definite"};
      }
    }
    const double out = box.Empty() ? 0.0 : box.Outside(p.position_m.x(), p.position_m.y());
    if (out > margin) {
      return Divergence{p.t_s, Distance(out) + " outside the scene (anchors, truth and start; " +
                                   "margin " + Distance(margin) + ")"};
    }
  }
  return std::nullopt;
}

using internal::Median;

// The first window of nees_window_s (scored from from_t_s on) in which more than half of the
// points have a NEES above nees_limit at an error above nees_min_error_m: a median test, so one
// spike (left to the point rules) does not make a window.
std::optional<Divergence> FirstOverconfidentWindow(const ErrorSeries& e, double from_t_s,
                                                   const DivergenceOptions& o) {
  if (e.nees.size() != e.t_s.size() || e.error_m.size() != e.t_s.size()) return std::nullopt;
  const auto bad = [&](size_t i) {
    return e.nees[i] > o.nees_limit && e.error_m[i] > o.nees_min_error_m;
  };
  size_t begin = 0, n_bad = 0;
  while (begin < e.t_s.size() && e.t_s[begin] < from_t_s) ++begin;
  for (size_t end = begin; end < e.t_s.size(); ++end) {
    n_bad += bad(end) ? 1 : 0;
    while (e.t_s[end] - e.t_s[begin] > o.nees_window_s) n_bad -= bad(begin++) ? 1 : 0;
    const size_t n = end - begin + 1;
    const bool full = e.t_s[end] - e.t_s[begin] >= 0.5 * o.nees_window_s;
    if (n < kMinNeesPoints || !full || 2 * n_bad <= n) continue;
    size_t first = begin;
    while (!bad(first)) ++first;
    const auto span = [&](const std::vector<double>& v) {
      return std::vector<double>(v.begin() + static_cast<std::ptrdiff_t>(begin),
                                 v.begin() + static_cast<std::ptrdiff_t>(end + 1));
    };
    return Divergence{e.t_s[first], "median position NEES " + internal::Num(Median(span(e.nees))) +
                                        " at a median error of " +
                                        internal::Num(Median(span(e.error_m))) + " m over " +
                                        internal::Num(e.t_s[end] - e.t_s[begin]) +
                                        " s (a consistent estimator's NEES is about 2; limit " +
                                        internal::Num(o.nees_limit) + ")"};
  }
  return std::nullopt;
}

}  // namespace

std::string ToString(const Divergence& d) {
  return "diverged at " + internal::Num(d.t_s) + " s: " + d.reason;
}

std::optional<Divergence> CheckDivergence(const Walk& walk, const Trajectory& trajectory,
                                          const ErrorSeries& errors, double from_t_s,
                                          const DivergenceOptions& options) {
  if (!options.enabled) return std::nullopt;
  const Box box = SceneBox(walk);
  const double diagonal = box.Empty() ? 0.0 : std::hypot(box.x1 - box.x0, box.y1 - box.y0);
  const double margin = std::max(options.min_margin_m, options.margin_fraction * diagonal);
  std::optional<Divergence> a = FirstBadPoint(trajectory, box, margin, from_t_s);
  std::optional<Divergence> b = FirstOverconfidentWindow(errors, from_t_s, options);
  if (a && b) return a->t_s <= b->t_s ? a : b;
  return a ? a : b;
}

}  // namespace walkgraph
