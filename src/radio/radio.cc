#include "walkgraph/radio.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <set>

#include <Eigen/Dense>

namespace walkgraph {

namespace {

FixResult NoFix(FixStatus status, std::string reason) {
  FixResult r;
  r.status = status;
  r.reason = std::move(reason);
  return r;
}

// Distinct anchors (the first reading of each) and a geometry check.
FixResult CheckGeometry(const std::vector<AnchorRange>& in, const PositioningOptions& o,
                        std::vector<AnchorRange>* out) {
  out->clear();
  for (const AnchorRange& m : in) {
    if (!std::isfinite(m.range_m) || m.range_m < 0 || !m.anchor_m.allFinite()) continue;
    const bool seen = std::any_of(out->begin(), out->end(), [&](const AnchorRange& x) {
      return x.anchor_id == m.anchor_id || (x.anchor_m - m.anchor_m).norm() < 1e-6;
    });
    if (!seen) out->push_back(m);
  }
  if (out->size() < 3) {
    return NoFix(FixStatus::kTooFewAnchors,
                 "need 3 anchors at distinct places, have " + std::to_string(out->size()));
  }
  Eigen::Vector2d mean = Eigen::Vector2d::Zero();
  for (const auto& m : *out) mean += m.anchor_m;
  mean /= static_cast<double>(out->size());
  Eigen::Matrix2d c = Eigen::Matrix2d::Zero();
  for (const auto& m : *out) c += (m.anchor_m - mean) * (m.anchor_m - mean).transpose();
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> eig(c);
  const double small = std::sqrt(std::max(eig.eigenvalues()(0), 0.0));
  const double large = std::sqrt(std::max(eig.eigenvalues()(1), 0.0));
  if (large <= 0 || small < o.collinear_ratio * large) {
    return NoFix(FixStatus::kCollinear, "anchors are (nearly) collinear");
  }
  FixResult ok;
  ok.status = FixStatus::kOk;
  return ok;
}

// Inverse of a 2×2 information matrix, or false when it is not safely positive definite.
bool InvertInformation(const Eigen::Matrix2d& info, Eigen::Matrix2d* cov) {
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> eig(info);
  const Eigen::Vector2d ev = eig.eigenvalues();
  if (!(ev(0) > 1e-12 * std::max(ev(1), 1e-300)) || !ev.allFinite()) return false;
  *cov = eig.eigenvectors() * ev.cwiseInverse().asDiagonal() * eig.eigenvectors().transpose();
  *cov = 0.5 * (*cov + cov->transpose());
  return cov->allFinite();
}

}  // namespace

const char* ToString(FixStatus s) {
  switch (s) {
    case FixStatus::kOk:
      return "ok";
    case FixStatus::kTooFewAnchors:
      return "too-few-anchors";
    case FixStatus::kCollinear:
      return "collinear";
    case FixStatus::kIllConditioned:
      return "ill-conditioned";
    case FixStatus::kNoConvergence:
      return "no-convergence";
  }
  return "?";
}

FixResult HyperbolicFix(const std::vector<AnchorRange>& ranges, const PositioningOptions& o) {
  std::vector<AnchorRange> m;
  FixResult g = CheckGeometry(ranges, o, &m);
  if (!g.ok()) return g;
  const int n = static_cast<int>(m.size()) - 1;
  const Eigen::Vector2d p1 = m[0].anchor_m;
  const double d1 = m[0].range_m;
  const double s1 = std::max(m[0].sigma_m, o.min_sigma_m);
  Eigen::MatrixXd h(n, 2);
  Eigen::VectorXd b(n);
  Eigen::MatrixXd s = Eigen::MatrixXd::Constant(n, n, 4.0 * d1 * d1 * s1 * s1);
  for (int i = 0; i < n; ++i) {
    const AnchorRange& r = m[i + 1];
    const Eigen::Vector2d p = r.anchor_m - p1;
    const double si = std::max(r.sigma_m, o.min_sigma_m);
    h.row(i) = 2.0 * p.transpose();
    b(i) = p.squaredNorm() - r.range_m * r.range_m + d1 * d1;  // 000 eq. 2, b̃
    s(i, i) += 4.0 * r.range_m * r.range_m * si * si;
  }
  // A zero range makes S singular: floor the diagonal at the σ-only term.
  for (int i = 0; i < n; ++i)
    s(i, i) = std::max(s(i, i), 4.0 * o.min_sigma_m * o.min_sigma_m * 1e-2);
  Eigen::LLT<Eigen::MatrixXd> llt(s);
  if (llt.info() != Eigen::Success)
    return NoFix(FixStatus::kIllConditioned, "S not positive definite");
  const Eigen::MatrixXd sinv_h = llt.solve(h);
  const Eigen::Matrix2d info = h.transpose() * sinv_h;
  Eigen::Matrix2d cov;
  if (!InvertInformation(info, &cov)) {
    return NoFix(FixStatus::kIllConditioned, "HᵀS⁻¹H is singular");
  }
  const Eigen::Vector2d x = cov * (sinv_h.transpose() * b);  // (HᵀS⁻¹H)⁻¹HᵀS⁻¹b̃
  if (!x.allFinite()) return NoFix(FixStatus::kIllConditioned, "non-finite solution");
  FixResult r;
  r.status = FixStatus::kOk;
  r.fix.position_m = p1 + x;
  r.fix.covariance = cov;
  r.fix.num_anchors = static_cast<int>(m.size());
  return r;
}

FixResult NonlinearLsFix(const std::vector<AnchorRange>& ranges, const PositioningOptions& o) {
  std::vector<AnchorRange> m;
  FixResult g = CheckGeometry(ranges, o, &m);
  if (!g.ok()) return g;
  Eigen::Vector2d x = Eigen::Vector2d::Zero();
  const FixResult start = HyperbolicFix(m, o);
  if (start.ok()) {
    x = start.fix.position_m;
  } else {
    for (const auto& r : m) x += r.anchor_m;
    x /= static_cast<double>(m.size());
  }
  Eigen::Matrix2d info = Eigen::Matrix2d::Zero();
  bool converged = false;
  // 001 eq. 5 by Gauss–Newton with step halving (cost never increases).
  auto cost = [&](const Eigen::Vector2d& p) {
    double c = 0.0;
    for (const auto& r : m) {
      const double s = std::max(r.sigma_m, o.min_sigma_m);
      const double e = (r.range_m - (p - r.anchor_m).norm()) / s;
      c += e * e;
    }
    return c;
  };
  for (int it = 0; it < o.max_iterations && !converged; ++it) {
    Eigen::Vector2d grad = Eigen::Vector2d::Zero();
    info.setZero();
    for (const auto& r : m) {
      const double s = std::max(r.sigma_m, o.min_sigma_m);
      Eigen::Vector2d diff = x - r.anchor_m;
      double dist = diff.norm();
      if (dist < 1e-9) {  // at an anchor: any direction is a valid sub-gradient
        diff = Eigen::Vector2d(1e-9, 0.0);
        dist = 1e-9;
      }
      const Eigen::Vector2d j = diff / dist;  // ∂‖x − s‖/∂x
      const double e = r.range_m - dist;
      info += j * j.transpose() / (s * s);
      grad += j * e / (s * s);
    }
    Eigen::Matrix2d inv;
    if (!InvertInformation(info, &inv)) {
      return NoFix(FixStatus::kIllConditioned, "JᵀWJ is singular at the iterate");
    }
    Eigen::Vector2d dx = inv * grad;
    const double c0 = cost(x);
    double step = 1.0;
    while (step > 1e-4 && cost(x + step * dx) > c0) step *= 0.5;
    x += step * dx;
    if ((step * dx).norm() < o.tolerance_m) converged = true;
  }
  if (!x.allFinite()) return NoFix(FixStatus::kNoConvergence, "non-finite iterate");
  if (!converged) return NoFix(FixStatus::kNoConvergence, "Gauss–Newton did not converge");
  Eigen::Matrix2d cov;
  if (!InvertInformation(info, &cov)) return NoFix(FixStatus::kIllConditioned, "singular JᵀWJ");
  FixResult r;
  r.status = FixStatus::kOk;
  r.fix.position_m = x;
  r.fix.covariance = cov;
  r.fix.num_anchors = static_cast<int>(m.size());
  return r;
}

StatusOr<std::vector<RangeEpoch>> BuildRangeEpochs(const Walk& walk, const EpochOptions& o) {
  if (!(o.window_s > 0)) return InvalidArgument("radio: window_s must be > 0");
  const bool rss =
      walk.meta.radio.kind == RadioKind::kRss || (walk.has_rss() && !walk.has_ranges());
  if (rss ? !walk.has_rss() : !walk.has_ranges()) {
    return FailedPrecondition("radio: the walk has no " + std::string(rss ? "rss" : "range") +
                              " readings");
  }
  const PathLossModel model(walk.meta.radio.path_loss, walk.meta.radio.units);
  struct Reading {
    double t_s;
    int anchor_id;
    double value;
  };
  std::vector<Reading> readings;
  if (rss) {
    for (const RssSample& s : walk.rss) {
      if (walk.meta.radio.units == RssUnits::kDbm && s.rss < o.sensitivity) continue;
      readings.push_back({s.t_s, s.anchor_id, s.rss});
    }
  } else {
    for (const RangeSample& s : walk.ranges) readings.push_back({s.t_s, s.anchor_id, s.range_m});
  }
  std::stable_sort(readings.begin(), readings.end(),
                   [](const Reading& a, const Reading& b) { return a.t_s < b.t_s; });
  std::vector<RangeEpoch> epochs;
  if (readings.empty()) return epochs;
  const double t0 = readings.front().t_s;
  size_t i = 0;
  while (i < readings.size()) {
    const long k = static_cast<long>(std::floor((readings[i].t_s - t0) / o.window_s));
    std::map<int, std::pair<double, int>> sums;  // anchor → (sum, count)
    double tsum = 0.0;
    int tcount = 0;
    while (i < readings.size() &&
           static_cast<long>(std::floor((readings[i].t_s - t0) / o.window_s)) == k) {
      auto& acc = sums[readings[i].anchor_id];
      acc.first += readings[i].value;
      acc.second += 1;
      tsum += readings[i].t_s;
      ++tcount;
      ++i;
    }
    RangeEpoch e;
    e.t_s = tsum / tcount;
    bool first_rss = true;
    for (const auto& [id, acc] : sums) {
      const int idx = walk.AnchorIndex(id);
      if (idx < 0)
        return InvalidArgument("radio: reading from unknown anchor " + std::to_string(id));
      const Eigen::Vector3d& a = walk.anchors[idx].position_m;
      const double v = acc.first / acc.second;
      AnchorRange r;
      r.anchor_id = id;
      r.anchor_m = a.head<2>();
      double range;
      if (rss) {
        range = o.bias_corrected ? model.BiasCorrectedRange(v) : model.MlRange(v);  // 001 eq. 14/17
        // Averaging n readings in dB divides σ by √n (000 Sec. IV averages the readings).
        r.sigma_m = model.RangeSigma(range) / std::sqrt(static_cast<double>(acc.second));
        const double strength = model.sign() * v;
        if (first_rss || strength > model.sign() * e.max_rss) e.max_rss = v;
        first_rss = false;
      } else {
        range = v;
        r.sigma_m = walk.meta.radio.range_sigma_m / std::sqrt(static_cast<double>(acc.second));
      }
      const double dz = a.z() - o.receiver_height_m;
      r.range_m = std::sqrt(std::max(range * range - dz * dz, 0.0));
      e.ranges.push_back(r);
    }
    epochs.push_back(std::move(e));
  }
  return epochs;
}

StatusOr<std::vector<FixResult>> PositionWalk(const Walk& walk, const EpochOptions& eo,
                                              PositioningMethod method,
                                              const PositioningOptions& options) {
  WG_ASSIGN_OR_RETURN(const std::vector<RangeEpoch> epochs, BuildRangeEpochs(walk, eo));
  std::vector<FixResult> out;
  out.reserve(epochs.size());
  for (const RangeEpoch& e : epochs) {
    FixResult r = method == PositioningMethod::kHyperbolic ? HyperbolicFix(e.ranges, options)
                                                           : NonlinearLsFix(e.ranges, options);
    r.fix.t_s = e.t_s;
    out.push_back(r);
  }
  return out;
}

StatusOr<PathLossFit> FitPathLoss(const std::vector<PathLossObservation>& obs, RssUnits units,
                                  double d0_m) {
  std::vector<const PathLossObservation*> use;
  for (const auto& o : obs) {
    if (std::isfinite(o.rss) && std::isfinite(o.distance_m) && o.distance_m > 0) use.push_back(&o);
  }
  if (use.size() < 3) return FailedPrecondition("path-loss fit: need at least 3 observations");
  const double s = units == RssUnits::kDbm ? 1.0 : -1.0;
  std::set<int> crossings;
  for (const PathLossObservation* o : use) crossings.insert(o->floors_crossed);
  const int n = crossings.size() > 1 ? 3 : 2;  // the floor loss only where floors differ
  Eigen::MatrixXd a(use.size(), n);
  Eigen::VectorXd y(use.size());
  for (size_t i = 0; i < use.size(); ++i) {
    a(i, 0) = 1.0;
    a(i, 1) = -s * 10.0 * std::log10(std::max(use[i]->distance_m, 0.1) / d0_m);
    if (n == 3) a(i, 2) = -s * use[i]->floors_crossed;
    y(i) = use[i]->rss;
  }
  const Eigen::ColPivHouseholderQR<Eigen::MatrixXd> qr(a);
  if (qr.rank() < n) {
    return FailedPrecondition(
        "path-loss fit: all distances equal (or tied to the floors), η is not observable");
  }
  const Eigen::VectorXd x = qr.solve(y);
  const double ssr = (a * x - y).squaredNorm();
  if (static_cast<int>(use.size()) <= n) {
    return FailedPrecondition("path-loss fit: too few observations for the model");
  }
  PathLossFit fit;
  fit.params.A_dbm = x(0);
  fit.params.eta = x(1);
  fit.params.floor_loss_db = n == 3 ? std::max(x(2), 0.0) : 0.0;
  fit.params.d0_m = d0_m;
  fit.params.sigma_db = std::sqrt(ssr / static_cast<double>(static_cast<int>(use.size()) - n));
  fit.num_observations = static_cast<int>(use.size());
  return fit;
}

StatusOr<std::vector<PathLossFit>> FitPathLossPerAnchor(const std::vector<PathLossObservation>& obs,
                                                        RssUnits units, double d0_m,
                                                        int min_observations) {
  std::map<int, std::vector<PathLossObservation>> by_anchor;
  for (const auto& o : obs) by_anchor[o.anchor_id].push_back(o);
  std::vector<PathLossFit> fits;
  for (const auto& [id, list] : by_anchor) {
    if (static_cast<int>(list.size()) < std::max(min_observations, 3)) continue;
    StatusOr<PathLossFit> f = FitPathLoss(list, units, d0_m);
    if (!f.ok()) continue;  // e.g. one anchor heard at a single distance
    f->anchor_id = id;
    fits.push_back(*f);
  }
  if (fits.empty()) return FailedPrecondition("path-loss fit: no anchor has enough readings");
  return fits;
}

}  // namespace walkgraph
