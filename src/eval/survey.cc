#include "walkgraph/survey.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <string>

#include <Eigen/Eigenvalues>

#include "util/median.h"
#include "util/rigid2d.h"
#include "util/text.h"
#include "walkgraph/estimator.h"

namespace walkgraph {

namespace {

constexpr double kMaxMapSigmaM = 1000.0;  // anchors.csv's largest sigma_m (walk-format.md)

// `walk` with its truth as waypoints (SurveyOptions), at most one per checkpoint_spacing_s.
Walk WithTruthWaypoints(const Walk& walk, const SurveyOptions& o) {
  Walk out = walk;
  double last = -std::numeric_limits<double>::infinity();
  for (const TruthSample& t : walk.truth) {
    if (t.t_s - last < o.checkpoint_spacing_s) continue;
    last = t.t_s;
    out.waypoints.push_back({t.t_s, t.position_m.head<2>(), o.checkpoint_sigma_m});
  }
  std::sort(out.waypoints.begin(), out.waypoints.end(),
            [](const Waypoint& a, const Waypoint& b) { return a.t_s < b.t_s; });
  return out;
}

// The planar rigid motion p_to = R p_from + t that maps one anchor frame onto another, from the
// anchors surveyed in both (by id): Umeyama's least squares for two or more, a translation for
// one, the identity for none; rms: the surveyed anchors' residual after it.
struct FrameMap {
  Eigen::Matrix2d R = Eigen::Matrix2d::Identity();
  Eigen::Vector2d t = Eigen::Vector2d::Zero();
  int shared = 0;
  double rms_m = 0.0;
  Eigen::Vector2d operator()(const Eigen::Vector2d& p) const { return R * p + t; }
};

FrameMap FrameBetween(const std::vector<Anchor>& from, const std::vector<Anchor>& to) {
  std::map<int, Eigen::Vector2d> target;
  for (const Anchor& a : to) {
    if (a.surveyed()) target[a.id] = a.position_m.head<2>();
  }
  std::vector<std::pair<Eigen::Vector2d, Eigen::Vector2d>> pairs;
  for (const Anchor& a : from) {
    const auto it = target.find(a.id);
    if (a.surveyed() && it != target.end()) pairs.emplace_back(a.position_m.head<2>(), it->second);
  }
  FrameMap f;
  f.shared = static_cast<int>(pairs.size());
  if (pairs.size() == 1) f.t = pairs[0].second - pairs[0].first;
  if (pairs.size() >= 2) {
    std::vector<Eigen::Vector2d> src, dst;
    for (const auto& [p, q] : pairs) src.push_back(p), dst.push_back(q);
    const internal::Rigid2d fit = internal::FitRigid2d(src, dst, pairs.size());
    f.R = fit.R;
    f.t = fit.t;
  }
  double ss = 0.0;
  for (const auto& [p, q] : pairs) ss += (f(p) - q).squaredNorm();
  f.rms_m = pairs.empty() ? 0.0 : std::sqrt(ss / static_cast<double>(pairs.size()));
  return f;
}

// Surveyed anchors that disagree by more than this after the best rigid motion are not one
// building's: the walks (or the map and the walk) are refused. Our choice: a survey's own error
// is centimetres; converters' frames differ by a shift of metres to kilometres.
constexpr double kMaxFrameRmsM = 0.5;

// The frame map of `walk` onto the survey's reference anchors, or an error naming the walk by
// `label`.
StatusOr<FrameMap> ToReference(const Walk& walk, const std::string& label,
                               const std::vector<Anchor>& reference) {
  const FrameMap f = FrameBetween(walk.anchors, reference);
  const bool any_surveyed = std::any_of(walk.anchors.begin(), walk.anchors.end(),
                                        [](const Anchor& a) { return a.surveyed(); });
  if (f.shared == 0 && any_surveyed && !reference.empty()) {
    return InvalidArgument("survey: " + label +
                           " shares no surveyed anchor with the first walk: their frames cannot "
                           "be related");
  }
  if (f.rms_m > kMaxFrameRmsM) {
    return InvalidArgument("survey: " + label +
                           ": its surveyed anchors differ "
                           "from the first walk's by " +
                           internal::Num(f.rms_m) +
                           " m rms after the best rigid motion (not the same building?)");
  }
  return f;
}

// One walk's estimate of an anchor.
struct WalkEstimate {
  Eigen::Vector2d p;
  Eigen::Matrix2d c;
  int readings = 0;
};

// The information-weighted mean of `e`, its covariance (not yet scaled) and the disagreement.
SurveyedAnchor Fuse(int id, const std::vector<WalkEstimate>& e) {
  SurveyedAnchor out;
  out.id = id;
  out.walks = static_cast<int>(e.size());
  Eigen::Matrix2d info = Eigen::Matrix2d::Zero();
  Eigen::Vector2d v = Eigen::Vector2d::Zero();
  for (const WalkEstimate& w : e) {
    const Eigen::Matrix2d inv = w.c.inverse();
    info += inv;
    v += inv * w.p;
    out.readings += w.readings;
  }
  out.covariance = info.inverse();
  out.position_m = out.covariance * v;
  if (e.size() > 1) {
    double chi2 = 0.0;
    for (const WalkEstimate& w : e) {
      const Eigen::Vector2d d = w.p - out.position_m;
      chi2 += d.dot(w.c.inverse() * d);
    }
    out.disagreement = chi2 / (2.0 * static_cast<double>(e.size() - 1));
  }
  return out;
}

// The map's variance factor (RadioMap::variance_factor) of the fused anchors.
double VarianceFactor(const std::map<int, SurveyedAnchor>& fused) {
  std::vector<double> d;
  for (const auto& [id, s] : fused) {
    if (s.walks > 1) d.push_back(s.disagreement);
  }
  return d.empty() ? 1.0 : std::max(1.0, internal::Median(std::move(d)));
}

// A covariance usable for fusion: finite and positive definite.
bool Usable(const Eigen::Matrix2d& c) {
  if (!c.allFinite()) return false;
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> es(c);
  return es.eigenvalues().minCoeff() > 0.0;
}

}  // namespace

Status SurveyOptions::Validate() const {
  if (!(checkpoint_sigma_m > 0.0 && checkpoint_sigma_m <= kMaxMapSigmaM)) {
    return InvalidArgument("survey: checkpoint_sigma_m must be in (0, 1000] m, not " +
                           internal::Num(checkpoint_sigma_m));
  }
  if (!(checkpoint_spacing_s >= 0.0 && checkpoint_spacing_s <= 3600.0)) {
    return InvalidArgument("survey: checkpoint_spacing_s must be in [0, 3600] s, not " +
                           internal::Num(checkpoint_spacing_s));
  }
  return Status::Ok();
}

StatusOr<RadioMap> SurveyRadioMap(const std::vector<Walk>& walks, const SurveyOptions& o) {
  WG_RETURN_IF_ERROR(o.Validate());
  if (walks.empty()) return InvalidArgument("survey: no walk");
  WG_ASSIGN_OR_RETURN(std::unique_ptr<Estimator> fg,
                      EstimatorRegistry::Builtin().Create("fg-batch"));
  RadioMap map;
  std::map<int, std::vector<WalkEstimate>> estimates;
  std::map<int, Anchor> anchor_of;  // the first walk's anchor record of each id
  // The map's frame: the first walk with surveyed anchors (walks of one building may come in
  // frames of their own: a converter's origin per walk). Each walk's estimates are moved into it
  // by the rigid motion that its surveyed anchors give.
  std::vector<Anchor> reference;
  for (const Walk& walk : walks) {
    for (const Anchor& a : walk.anchors) {
      if (a.surveyed()) reference.push_back(a);
    }
    if (!reference.empty()) break;
  }
  for (size_t i = 0; i < walks.size(); ++i) {
    const Walk& walk = walks[i];
    // The walks' names may repeat (copies of one recording): their place in the list as well.
    const std::string label = "walk " + std::to_string(i + 1) + " of " +
                              std::to_string(walks.size()) + " ('" + walk.meta.name + "')";
    WG_ASSIGN_OR_RETURN(const FrameMap to_map, ToReference(walk, label, reference));
    if (!walk.has_truth()) return InvalidArgument("survey: " + label + " has no truth.csv");
    for (Anchor a : walk.anchors) {
      if (a.position_known) a.position_m.head<2>() = to_map(a.position_m.head<2>());
      anchor_of.emplace(a.id, a);
    }
    if (!std::any_of(walk.anchors.begin(), walk.anchors.end(),
                     [](const Anchor& a) { return !a.surveyed(); })) {
      continue;  // nothing to place
    }
    const Walk w = WithTruthWaypoints(walk, o);
    if (const Status s = fg->CheckApplicable(w); !s.ok()) {
      return Status(s.code(), "survey: " + label + ": " + s.message());
    }
    StatusOr<EstimateResult> r = fg->Run(w);
    if (!r.ok()) return Status(r.status().code(), "survey: " + label + ": " + r.status().message());
    for (const AnchorEstimate& e : r->anchors) {
      if (!e.observable || !e.covariance || !Usable(*e.covariance) || !e.position_m.allFinite()) {
        ++map.unobservable;
        continue;
      }
      estimates[e.id].push_back(
          {to_map(e.position_m), to_map.R * *e.covariance * to_map.R.transpose(), e.readings});
    }
  }
  std::map<int, SurveyedAnchor> fused;
  for (const auto& [id, e] : estimates) fused[id] = Fuse(id, e);
  if (o.pool_disagreement) map.variance_factor = VarianceFactor(fused);
  for (auto& [id, s] : fused) {
    s.covariance *= std::max({1.0, s.disagreement, map.variance_factor});
    s.covariance = 0.5 * (s.covariance + s.covariance.transpose());
  }
  for (const auto& [id, a] : anchor_of) {
    if (a.surveyed()) {
      map.anchors.push_back(a);
      continue;
    }
    const auto it = fused.find(id);
    if (it == fused.end()) continue;
    const SurveyedAnchor& s = it->second;
    const double sigma =
        std::sqrt(Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d>(s.covariance).eigenvalues()(1));
    if (!(sigma > 0.0 && sigma <= kMaxMapSigmaM)) continue;
    Anchor m = a;
    m.position_known = true;
    m.position_m.head<2>() = s.position_m;
    if (!std::isfinite(m.position_m.z())) m.position_m.z() = 0.0;
    m.sigma_m = sigma;
    map.anchors.push_back(m);
    map.details.push_back(s);
  }
  return map;
}

StatusOr<int> ApplyRadioMap(const std::vector<Anchor>& map, Walk* walk) {
  const FrameMap to_walk = FrameBetween(map, walk->anchors);
  if (to_walk.rms_m > kMaxFrameRmsM) {
    return InvalidArgument("radio map: its surveyed anchors differ from the walk's by " +
                           internal::Num(to_walk.rms_m) +
                           " m rms after the best rigid motion (not the same building?)");
  }
  std::map<int, const Anchor*> by_id;
  for (const Anchor& a : map) {
    if (a.position_known) by_id[a.id] = &a;
  }
  int changed = 0;
  for (Anchor& a : walk->anchors) {
    if (a.surveyed()) continue;
    const auto it = by_id.find(a.id);
    if (it == by_id.end()) continue;
    const Anchor& m = *it->second;
    if (a.position_known && m.sigma_m >= a.sigma_m && !m.surveyed()) continue;  // no better
    a.position_known = true;
    a.position_m.head<2>() = to_walk(m.position_m.head<2>());
    a.sigma_m = m.sigma_m;  // isotropic: a rotation keeps it
    ++changed;
  }
  return changed;
}

}  // namespace walkgraph
