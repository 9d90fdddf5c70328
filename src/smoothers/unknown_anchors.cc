#include "smoothers/unknown_anchors.h"

#include <map>
#include <set>
#include <utility>
#include <vector>

namespace walkgraph::internal {

StatusOr<EstimateResult> SolveWithUnknownAnchors(const Walk& walk, const UnknownAnchorPass& pass) {
  UnknownAnchorsDropped dropped;
  WG_ASSIGN_OR_RETURN(EstimateResult first,
                      pass.solve(WithoutUnknownAnchors(walk, &dropped), nullptr));
  Walk joint = walk;
  std::vector<AnchorEstimate> unobservable;
  std::map<std::string, double> verdicts;
  std::set<int> left_out;
  for (Anchor& a : joint.anchors) {
    if (a.position_known) continue;
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
