// fg-window's anchors of unknown position (internal; step_graph.h "Anchors of unknown
// position"). A sliding window cannot search a path it has already marginalized, so it places
// an anchor as SLAM front ends place a landmark, by delayed initialization:
//   - until placed, the anchor's states (StepGraph::AnchorOwnKeys), their priors and its
//     readings' factors are held out of the window; each reading is kept with its receiver
//     where the window put it right after the update that added it (causal);
//   - once the anchor has anchor_min_readings readings (and then each time a quarter more, at
//     least 5, arrived), fg-batch's grid search (anchor_search.h) runs over them, with the path
//     loss or range calibration the window holds now;
//   - placed: its states join the window at the next update with their priors, p(a) at the
//     search's place with the prior N(place, Σ_search + σ_r² I) standing for the readings so far
//     (Σ_search from the search's confidence region, σ_r² the newest node's position variance:
//     the receivers' own uncertainty); later readings enter as factors.
// Placement waits for a search region of σ ≤ window_anchor_max_sigma_m (step_graph.h). An anchor
// never placed is reported unobservable with its verdict (or "uncertain"), its readings unused.
// Where the start or two heard surveyed anchors fix the walk's frame (SurveyFixesTheFrame), an
// uncertain anchor (sigma_m > 0: e.g. from a radio map) waits the same way, and joins with its
// own prior as well once the search places it where that prior allows (χ²(2) at 99.9 % of
// Σ_search + σ_m² I); elsewhere it waits on ("inconsistent" if never): the window's path and
// the prior disagree (IPIN 01 and 21 with a radio map and no start: with the map's access
// points states from the start, fg-window left the building by kilometres).
#ifndef WALKGRAPH_SRC_SMOOTHERS_STEP_GRAPH_PENDING_H_
#define WALKGRAPH_SRC_SMOOTHERS_STEP_GRAPH_PENDING_H_

#include <map>
#include <set>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "smoothers/anchor_search.h"
#include "walkgraph/estimate_result.h"
#include "walkgraph/graph.h"
#include "walkgraph/smoothers/fixed_lag_smoother.h"
#include "walkgraph/smoothers/step_graph.h"
#include "walkgraph/walk.h"

namespace walkgraph::internal {

class PendingAnchors {
 public:
  PendingAnchors(const Walk& walk, const StepGraph& graph, const StepGraphOptions& o);

  // Whether `key` belongs to an anchor not (yet) placed.
  bool Holds(Key key) const;
  bool HoldsAny(const std::vector<Key>& keys) const;
  // `states` without the held ones (kept for the placement).
  std::vector<GraphState> Filter(std::vector<GraphState> states);
  // Node k's factors without those on held states: readings (kept as readings) and priors
  // (kept for the placement).
  std::vector<GraphFactor> Filter(int k, std::vector<GraphFactor> factors);
  // After the update that added `nodes`: their held readings' receivers from the window, then
  // the search; each anchor placed now adds its states and factors to *states / *factors.
  Status AfterUpdate(const std::vector<int>& nodes, double t_s, FixedLagSmoother* window,
                     std::vector<GraphState>* states, std::vector<GraphFactor>* factors);
  // Every anchor that is a state (uncertain, unknown placed: estimate and covariance from the
  // window; unknown never placed: unobservable) into r->anchors; with unknown anchors the
  // diagnostics unknown_anchors, unknown_anchors_estimated,
  // unknown_anchors_unobservable(.<verdict>), anchor_placed_t_s.<id>.
  void Report(FixedLagSmoother* window, EstimateResult* r) const;

 private:
  struct Pending {
    std::vector<GraphState> states;
    std::vector<GraphFactor> priors;
    std::vector<StepGraph::AnchorReading> waiting;  // no receiver yet
    std::vector<Eigen::Vector2d> at;
    std::vector<double> value;
    bool range = false;  // heard by ranges: searched over its ranges only (as fg-batch)
    size_t tried = 0;    // readings at the last search
    AnchorSearchResult last;
    bool too_uncertain = false;  // placed by the search, σ above window_anchor_max_sigma_m
    bool inconsistent = false;   // uncertain: placed by the search where its prior says not
    bool placed = false;
    double placed_t_s = 0.0;
  };
  AnchorSearchOptions SearchFor(int a, const FixedLagSmoother& window) const;
  Status Place(int a, const AnchorSearchResult& found, FixedLagSmoother* window, int newest,
               std::vector<GraphState>* states, std::vector<GraphFactor>* factors);

  const Walk& walk_;
  const StepGraph& graph_;
  const StepGraphOptions& o_;
  std::map<int, Pending> pending_;  // by anchor index
  std::map<Key, int> owner_;        // held key → anchor index
};

}  // namespace walkgraph::internal

#endif  // WALKGRAPH_SRC_SMOOTHERS_STEP_GRAPH_PENDING_H_
