#include "smoothers/unknown_anchors.h"

#include <map>
#include <optional>
#include <set>
#include <utility>
#include <vector>

#include <Eigen/Cholesky>

#include "util/median.h"

namespace walkgraph::internal {

namespace {

// The median over the output points of the joint solve's shift from the first pass, in the
// first pass's position covariance (d' P⁻¹ d); nullopt when the two outputs are not point by
// point alike or the first has no usable covariance.
std::optional<double> MedianShiftNees(const Trajectory& first, const Trajectory& joint) {
  if (first.size() != joint.size() || first.empty()) return std::nullopt;
  std::vector<double> nees;
  for (size_t i = 0; i < first.size(); ++i) {
    const TrajectoryPoint& a = first.points[i];
    const TrajectoryPoint& b = joint.points[i];
    if (a.t_s != b.t_s || !a.covariance) return std::nullopt;
    const Eigen::Matrix2d P = a.covariance->topLeftCorner<2, 2>();
    const Eigen::Vector2d d = (b.position_m - a.position_m).head<2>();
    const Eigen::LDLT<Eigen::Matrix2d> ldlt(0.5 * (P + P.transpose()));
    if (ldlt.info() != Eigen::Success || !(ldlt.vectorD().minCoeff() > 0.0)) continue;
    nees.push_back(d.dot(ldlt.solve(d)));
  }
  if (nees.size() < first.size() / 2) return std::nullopt;
  return Median(std::move(nees));
}

// Every anchor of `walk` not surveyed and not yet in *left_out joins it, as inconsistent.
void LeaveOutInconsistent(const Walk& walk, std::set<int>* left_out,
                          std::vector<AnchorEstimate>* unobservable,
                          std::map<std::string, double>* verdicts) {
  for (const Anchor& a : walk.anchors) {
    if (a.surveyed() || left_out->count(a.id)) continue;
    AnchorEstimate e;
    e.id = a.id;
    e.observable = false;
    e.readings = walk.AnchorReadings(a.id);
    unobservable->push_back(e);
    left_out->insert(a.id);
    (*verdicts)["unknown_anchors_unobservable.inconsistent"] += 1.0;
  }
}

}  // namespace

bool SurveyFixesTheFrame(const Walk& walk) {
  if (walk.meta.initial_pose) return true;
  int heard = 0;
  for (const Anchor& a : walk.anchors) heard += a.surveyed() && walk.AnchorReadings(a.id) > 0;
  return heard >= 2;
}

StatusOr<EstimateResult> SolveWithUnknownAnchors(const Walk& walk, const UnknownAnchorPass& pass) {
  UnknownAnchorsDropped dropped;
  std::set<int> not_surveyed;
  for (const Anchor& a : walk.anchors) {
    if (!a.surveyed()) not_surveyed.insert(a.id);
  }
  const Walk surveyed = WithoutAnchors(walk, not_surveyed, &dropped);
  WG_ASSIGN_OR_RETURN(EstimateResult first, pass.solve(surveyed, nullptr));
  Walk joint = walk;
  std::vector<AnchorEstimate> unobservable;
  std::map<std::string, double> verdicts;
  std::set<int> left_out;
  for (Anchor& a : joint.anchors) {
    if (a.position_known) continue;  // surveyed, or uncertain: its prior
    const AnchorPlacement p = pass.place(a, first);
    using Verdict = AnchorSearchResult::Verdict;
    if (p.verdict.empty() && p.found.verdict != Verdict::kFewReadings &&
        p.found.verdict != Verdict::kNarrowGeometry) {
      verdicts["anchor_search_gap." + std::to_string(a.id)] = p.found.second_cost - p.found.cost;
    }
    if (p.verdict.empty() && p.found.placed()) {
      a.position_m.head<2>() = p.found.position_m;
      continue;
    }
    AnchorEstimate e;
    e.id = a.id;
    e.observable = false;
    e.readings = p.readings;
    unobservable.push_back(e);
    left_out.insert(a.id);
    verdicts["unknown_anchors_unobservable." +
             (p.verdict.empty() ? std::string(ToString(p.found.verdict)) : p.verdict)] += 1.0;
  }
  // The unobservable anchors leave the walk with their readings.
  UnknownAnchorsDropped left;
  const Walk solved = WithoutAnchors(joint, left_out, &left);
  EstimateResult result;
  if (static_cast<int>(left_out.size()) == dropped.anchors) {
    result = std::move(first);  // nothing placed: the first solve is the answer
  } else {
    WG_ASSIGN_OR_RETURN(result, pass.solve(solved, &first));
    const std::optional<double> shift = SurveyFixesTheFrame(walk)
                                            ? MedianShiftNees(first.trajectory, result.trajectory)
                                            : std::nullopt;
    if (shift) verdicts["unknown_anchors_shift_nees"] = *shift;
    if (shift && *shift > kChiSquare2At999) {  // inconsistent: the first solve is the answer
      LeaveOutInconsistent(joint, &left_out, &unobservable, &verdicts);
      left = dropped;  // every anchor not surveyed is out now, as in the first solve
      result = std::move(first);
    }
  }
  auto& d = result.diagnostics;
  d.insert(verdicts.begin(), verdicts.end());
  d["unknown_anchors"] = dropped.anchors;
  d["unknown_anchors_estimated"] = dropped.anchors - static_cast<double>(left_out.size());
  d["unknown_anchors_unobservable"] = static_cast<double>(left_out.size());
  d["unknown_anchor_readings_ignored"] = left.rss_readings + left.range_readings;
  for (AnchorEstimate& e : unobservable) result.anchors.push_back(e);
  return result;
}

}  // namespace walkgraph::internal
