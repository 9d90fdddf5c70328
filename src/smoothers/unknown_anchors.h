// The pass both batch graphs run on a walk with anchors of unknown position (internal;
// step_graph.h "Anchors of unknown position"; fg-batch and fg-ins-batch; fg-batch also on a
// walk with uncertain ones, e.g. from a radio map): the walk without the anchors that are not
// surveyed solved first; each unknown one placed on that path by the grid search
// (anchor_search.h) or declared unobservable and left out with its readings; then one solve
// with the placed and the uncertain ones as states. That solve updates the first: where it
// moves the walk beyond the first solve's covariance (median over the output points of the
// shift's d'P⁻¹d above 13.82, χ²(2) at 99.9 %) those anchors contradict the surveyed ones —
// on a walk with no start, 13 WiFi access points of IPIN trial 05 carried the walk 45 m from
// where its BLE beacons put it (median shift NEES 1268; with the start given, 0.0-0.9 on the
// four trials) — and the first solve is the answer, those anchors left out as unobservable
// ("inconsistent"). No test where the first solve has no covariance, or no frame of the walk's
// (no start and fewer than two heard surveyed anchors: its node 0 held where it started).
#ifndef WALKGRAPH_SRC_SMOOTHERS_UNKNOWN_ANCHORS_H_
#define WALKGRAPH_SRC_SMOOTHERS_UNKNOWN_ANCHORS_H_

#include <functional>
#include <string>

#include "smoothers/anchor_search.h"
#include "walkgraph/estimate_result.h"
#include "walkgraph/status.h"
#include "walkgraph/walk.h"

namespace walkgraph::internal {

// Where the search put one anchor, or why it could not.
struct AnchorPlacement {
  AnchorSearchResult found;
  int readings = 0;     // the readings it searched
  std::string verdict;  // the unobservable verdict's name when not found's (e.g. "radio_only")
};

struct UnknownAnchorPass {
  // Solves a walk whose anchors all have a position; `first`: null on the first pass (the walk
  // without its unknown anchors), else the first pass's result (the joint solve may start there).
  std::function<StatusOr<EstimateResult>(const Walk& walk, const EstimateResult* first)> solve;
  // Places an unknown anchor of the walk on the first pass's path.
  std::function<AnchorPlacement(const Anchor& anchor, const EstimateResult& first)> place;
};

// Whether the walk's start and surveyed anchors fix its frame without the others: a known start,
// or two or more heard surveyed anchors (the step graph's gauge; else node 0 is held where it
// started, and anchors that are not surveyed are what places the walk).
bool SurveyFixesTheFrame(const Walk& walk);

// The pass on `walk`. Diagnostics: unknown_anchors, unknown_anchors_estimated,
// unknown_anchors_unobservable(.<verdict>), unknown_anchor_readings_ignored,
// anchor_search_gap.<id> (how far the best place's cost stood below any other's; inf: none),
// unknown_anchors_shift_nees (the median above);
// unobservable anchors in result.anchors with observable false.
StatusOr<EstimateResult> SolveWithUnknownAnchors(const Walk& walk, const UnknownAnchorPass& pass);

}  // namespace walkgraph::internal

#endif  // WALKGRAPH_SRC_SMOOTHERS_UNKNOWN_ANCHORS_H_
