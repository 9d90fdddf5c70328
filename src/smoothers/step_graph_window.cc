// fg-window and fg-window-online (StepGraphWindow): the step graph on the fixed-lag smoother.
#include <algorithm>
#include <chrono>
#include <limits>
#include <map>
#include <string>

#include "smoothers/step_graph_impl.h"
#include "smoothers/step_graph_pending.h"
#include "smoothers/step_graph_run.h"
#include "walkgraph/smoothers/step_graph.h"

namespace walkgraph {

using internal::AddGraphDiagnostics;
using internal::AddStaticDiagnostics;
using internal::BatchSolverOptions;
using internal::CheckStepWalk;
using internal::EstimatorStarts;
using internal::InsertStops;
using internal::MakePoint;
using internal::NamedStart;
using internal::PendingAnchors;
using internal::PoseCovariance;
using internal::RunWindowNodes;
using internal::SetHeight;

Status StepGraphWindow::CheckApplicable(const Walk& walk) const { return CheckStepWalk(walk); }

StatusOr<EstimateResult> StepGraphWindow::Run(const Walk& walk) const {
  WG_RETURN_IF_ERROR(CheckApplicable(walk));
  // Anchors of unknown position: the window places them itself (step_graph_pending.h); until
  // then they sit at a placeholder the graph never uses (it holds them out).
  Walk placeholders;
  if (walk.has_unknown_anchors()) {
    placeholders = walk;
    for (Anchor& a : placeholders.anchors) {
      if (!a.position_known) a.position_m.head<2>().setZero();
    }
  }
  const Walk& w = walk.has_unknown_anchors() ? placeholders : walk;
  WG_ASSIGN_OR_RETURN(EstimateResult result, RunWindowNodes(w, options_));
  InsertStops(walk, options_.max_step_duration_s, &result.trajectory);
  return result;
}

namespace {

// fg-window's estimates, one point per graph node.
// The static states' and the graph's diagnostics, from the window's final estimates.
void AddWindowGraphDiagnostics(const StepGraph& graph, const FixedLagSmoother& smoother,
                               const Walk& walk, const StepGraphOptions& o,
                               std::map<std::string, double>* d) {
  AddStaticDiagnostics(
      graph,
      [&](Key k) {
        auto v = smoother.Estimate(k);
        return v.ok() ? *v : std::vector<double>{};
      },
      walk, o, d);
  AddGraphDiagnostics(graph, walk, d);
}

// fg-window's smoother: the lag and the window_* solver options.
FixedLagSmoother::Options WindowSmootherOptions(const StepGraphOptions& o) {
  FixedLagSmoother::Options so;
  so.lag_s = o.lag_s;
  so.marginalize_batch_s = o.window_marginalize_batch_s;
  so.solver.initial_trust_region_radius = o.window_initial_trust_region_radius;
  so.solver.max_iterations = o.window_max_iterations;
  internal::SetLinearSolver(o.window_linear_solver, &so.solver);
  so.solver.function_tolerance = o.window_function_tolerance;
  so.solver.parameter_tolerance = o.parameter_tolerance;
  so.solver.num_threads = o.num_threads;
  return so;
}

// The graph of nodes 0..last (states and every factor whose newest node is among them), the
// nodes at `start` (every node's (p, θ) up to last) or else at their dead-reckoning values.
Status AddFirstNodes(const StepGraph& graph, int last, const std::vector<Eigen::Vector3d>& start,
                     const PendingAnchors& unknown, FactorGraph* fg) {
  for (GraphState& s : graph.StaticStates()) {
    if (!unknown.Holds(s.key)) WG_RETURN_IF_ERROR(fg->AddState(std::move(s)));
  }
  const std::vector<Eigen::Vector3d>& x = start.empty() ? graph.initial_nodes() : start;
  for (int k = 0; k <= last; ++k) {
    for (GraphState& s : graph.NodeStates(k, x[k].head<2>(), x[k][2])) {
      if (s.key == StepGraph::PositionKey(k)) s.value = {x[k][0], x[k][1]};
      if (s.key == StepGraph::HeadingKey(k)) s.value = {x[k][2]};
      WG_RETURN_IF_ERROR(fg->AddState(std::move(s)));
    }
  }
  for (int k = 0; k <= last; ++k) {
    for (GraphFactor& f : graph.FactorsAt(k)) {
      if (!unknown.HoldsAny(f.keys)) WG_RETURN_IF_ERROR(fg->AddFactor(std::move(f)));
    }
  }
  return Status::Ok();
}

// fg-window's first window on a walk with no start (issue 41): the nodes of the first
// align_window_s, when it holds at least 3 radio readings, solved as one batch (fg-batch's solver
// options) from the window's own initialization and from each causal start estimator's hypotheses
// (EstimatorStarts), the least final cost kept: the window starts its nodes there. On a start of
// known position whose heading nothing gives, the same from the dead reckoning turned about the
// start (StepGraph::StartHeadingTurns; named turn<k>): a window commits to the heading of its
// first nodes before the radio has seen the walker move, and its marginalization prior then
// holds it (simulated phone without magnetometer, seed 1: 9.60 m RMSE, 2.29 m with the turns
// alone, 2.59 m with the gyro bias also held: BuildWindowGraph).
// Empty when the walk has a start with a heading or no estimator gives a hypothesis. Diagnostics
// first_window_hypothesis (0: its own, k: the k-th), first_window_estimator
// (NamedStart::estimator), first_window_cost.<name>.
StatusOr<std::vector<Eigen::Vector3d>> FirstWindowStart(const Walk& walk, const StepGraph& graph,
                                                        const StepGraphOptions& o,
                                                        const PendingAnchors& unknown,
                                                        std::map<std::string, double>* d) {
  std::vector<Eigen::Vector3d> out;
  const double until = graph.node_time(0) + o.align_window_s;
  int readings = 0;  // fewer than 3 in the span: the radio cannot tell the hypotheses apart
  for (const RssSample& r : walk.rss) readings += r.t_s <= until ? 1 : 0;
  for (const RangeSample& r : walk.ranges) readings += r.t_s <= until ? 1 : 0;
  if (readings < 3) return out;
  WG_ASSIGN_OR_RETURN(std::vector<NamedStart> starts,
                      EstimatorStarts(walk, graph, o, /*causal=*/true, until));
  for (auto& h : graph.StartHeadingTurns(o.start_hypotheses, until)) {
    starts.push_back({"turn" + std::to_string(starts.size() + 1), std::move(h), 0});
  }
  if (starts.empty()) return out;
  const int last = static_cast<int>(starts.front().nodes.size()) - 1;
  starts.insert(starts.begin(), NamedStart{"0", {}, 0});  // its own initialization
  double best = std::numeric_limits<double>::infinity();
  for (size_t h = 0; h < starts.size(); ++h) {
    FactorGraph fg;
    WG_RETURN_IF_ERROR(AddFirstNodes(graph, last, starts[h].nodes, unknown, &fg));
    StatusOr<SolveSummary> s = SolveBatch(&fg, BatchSolverOptions(o));
    if (!s.ok()) continue;  // a hypothesis that fails to solve is not taken
    (*d)["first_window_cost." + starts[h].name] = s->final_cost;
    if (!(s->final_cost < best)) continue;
    best = s->final_cost;
    (*d)["first_window_hypothesis"] = static_cast<double>(h);
    (*d)["first_window_estimator"] = starts[h].estimator;
    out.clear();
    for (int k = 0; k <= last; ++k) {
      const std::vector<double> p = *fg.Value(StepGraph::PositionKey(k));
      out.emplace_back(p[0], p[1], (*fg.Value(StepGraph::HeadingKey(k)))[0]);
    }
  }
  return out;
}

// The window's step graph. PDR steps without a heading reference (no step with a magnetometer
// heading): rebuilt with the gyro bias held (StepGraphOptions::window_gyro_bias_without_heading),
// `*o` changed to say so and `*held` set.
StatusOr<std::unique_ptr<StepGraph>> BuildWindowGraph(const Walk& walk, StepGraphOptions* o,
                                                      bool* held) {
  WG_ASSIGN_OR_RETURN(std::unique_ptr<StepGraph> graph, StepGraph::Build(walk, *o));
  const std::vector<GraphState> statics = graph->StaticStates();
  *held = !o->window_gyro_bias_without_heading && !graph->has_heading_reference() &&
          walk.meta.imu_placement != ImuPlacement::kFoot &&
          std::any_of(statics.begin(), statics.end(),
                      [](const GraphState& s) { return s.key == internal::kGyroBiasKey; });
  if (!*held) return graph;
  o->estimate_gyro_bias = false;
  return StepGraph::Build(walk, *o);
}

// fg-window-online's output of the nodes just updated: each one's estimate right after its update.
Status OnlinePoints(const StepGraph& graph, const FixedLagSmoother& smoother,
                    const std::vector<int>& nodes, std::vector<TrajectoryPoint>* points,
                    std::vector<bool>* have) {
  for (int j : nodes) {
    WG_ASSIGN_OR_RETURN(std::vector<double> pj, smoother.Estimate(StepGraph::PositionKey(j)));
    WG_ASSIGN_OR_RETURN(std::vector<double> hj, smoother.Estimate(StepGraph::HeadingKey(j)));
    (*points)[j] = MakePoint(graph.node_time(j), pj.data(), hj[0]);
    if (graph.has_floors()) {
      WG_ASSIGN_OR_RETURN(std::vector<double> zj, smoother.Estimate(StepGraph::HeightKey(j)));
      SetHeight(graph, zj[0], &(*points)[j]);
    }
    (*have)[j] = true;
  }
  return Status::Ok();
}

// fg-window's lagged output: a node's state (x, h or z) as it leaves the window.
void SetLagged(const StepGraph& graph, Key key, double t, const std::vector<double>& v,
               std::vector<TrajectoryPoint>* points, std::vector<bool>* have) {
  const int k = static_cast<int>(SymbolIndex(key));
  TrajectoryPoint& p = (*points)[k];
  p.t_s = t;
  if (SymbolLetter(key) == 'x') {
    p.position_m.head<2>() = Eigen::Vector2d(v[0], v[1]);
    (*have)[k] = true;
  } else if (SymbolLetter(key) == 'z') {
    SetHeight(graph, v[0], &p);
  } else {
    p.heading_rad = NormalizeAngle(v[0]);
  }
}

}  // namespace

namespace internal {

StatusOr<EstimateResult> RunWindowNodes(const Walk& walk, const StepGraphOptions& given) {
  StepGraphOptions options_ = given;
  bool hold_bias = false;
  WG_ASSIGN_OR_RETURN(std::unique_ptr<StepGraph> graph,
                      BuildWindowGraph(walk, &options_, &hold_bias));
  const int n = graph->num_nodes();
  const bool online = options_.window_output == WindowOutput::kOnline;
  std::map<std::string, double> first_d;
  PendingAnchors unknown(walk, *graph, options_);
  std::vector<Eigen::Vector3d> first;  // the online output is causal: no first-window look-ahead
  if (!online) {
    WG_ASSIGN_OR_RETURN(first, FirstWindowStart(walk, *graph, options_, unknown, &first_d));
  }
  FixedLagSmoother smoother(WindowSmootherOptions(options_));

  std::vector<TrajectoryPoint> points(n);
  std::vector<bool> have(n, false);
  auto node_of = [](Key key) { return static_cast<int>(SymbolIndex(key)); };
  // (x, y, θ) covariances of the given nodes from the current window, in one banded solve.
  auto store_covariances = [&](const std::vector<int>& nodes) {
    if (!options_.covariance || nodes.empty()) return;
    std::vector<std::vector<Key>> groups;
    for (int k : nodes) groups.push_back({StepGraph::PositionKey(k), StepGraph::HeadingKey(k)});
    auto c = smoother.MarginalCovariances(groups);
    if (!c.ok()) return;  // rank-deficient window: these nodes go without covariance
    for (size_t i = 0; i < nodes.size(); ++i) {
      points[nodes[i]].covariance = PoseCovariance(0.5 * ((*c)[i] + (*c)[i].transpose()));
    }
  };
  smoother.set_before_marginalize([&](const std::vector<Key>& keys) {
    if (online) return;
    std::vector<int> nodes;
    for (Key key : keys) {
      if (SymbolLetter(key) == 'x') nodes.push_back(node_of(key));
    }
    store_covariances(nodes);
  });
  smoother.set_on_marginalize([&](Key key, double t, const std::vector<double>& v) {
    if (!online) SetLagged(*graph, key, t, v, &points, &have);
  });

  std::vector<double> latency;
  latency.reserve(n);
  int iterations = 0, solves = 0;
  size_t max_states = 0, max_factors = 0;  // the window's largest size (its memory)
  Eigen::Vector2d prev_p = graph->initial_nodes()[0].head<2>();
  double prev_theta = graph->initial_nodes()[0][2];
  // Nodes are fed one update each, or (window_update_s > 0) gathered into one update per
  // period; new nodes start from dead reckoning off the previous node's estimate.
  std::vector<GraphState> states;
  std::vector<GraphFactor> factors;
  std::vector<int> pending;
  double last_update_t = graph->node_time(0);
  for (int k = 0; k < n; ++k) {
    if (k == 0) states = unknown.Filter(graph->StaticStates());
    std::vector<GraphState> node = graph->NodeStates(k, prev_p, prev_theta);
    if (k < static_cast<int>(first.size())) {  // the first window's chosen start
      node[0].value = {first[k][0], first[k][1]};
      node[1].value = {first[k][2]};
    }
    prev_p = Eigen::Vector2d(node[0].value[0], node[0].value[1]);
    prev_theta = node[1].value[0];
    for (GraphState& st : node) states.push_back(std::move(st));
    for (GraphFactor& f : unknown.Filter(k, graph->FactorsAt(k))) factors.push_back(std::move(f));
    pending.push_back(k);
    if (k + 1 < n && graph->node_time(k) - last_update_t < options_.window_update_s) continue;
    last_update_t = graph->node_time(k);
    const auto start = std::chrono::steady_clock::now();
    WG_ASSIGN_OR_RETURN(FixedLagSmoother::UpdateResult u,
                        smoother.Update(std::move(states), std::move(factors)));
    states.clear();
    factors.clear();
    WG_RETURN_IF_ERROR(
        unknown.AfterUpdate(pending, graph->node_time(k), &smoother, &states, &factors));
    latency.push_back(
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
    iterations += u.ceres_iterations;
    solves += u.solved ? 1 : 0;
    max_states = std::max(max_states, smoother.NumStates());
    max_factors = std::max(max_factors, smoother.NumFactors());
    WG_ASSIGN_OR_RETURN(std::vector<double> p, smoother.Estimate(StepGraph::PositionKey(k)));
    WG_ASSIGN_OR_RETURN(std::vector<double> h, smoother.Estimate(StepGraph::HeadingKey(k)));
    prev_p = Eigen::Vector2d(p[0], p[1]);
    prev_theta = h[0];
    if (online) {
      WG_RETURN_IF_ERROR(OnlinePoints(*graph, smoother, pending, &points, &have));
      store_covariances(pending);
    }
    pending.clear();
  }
  EstimateResult result;
  unknown.Report(&smoother, &result);
  if (!online) {
    // The nodes still in the window at the end: their final (smoothed) estimates.
    std::vector<int> nodes;
    for (Key key : smoother.WindowKeys()) {
      if (SymbolLetter(key) == 'x') nodes.push_back(node_of(key));
    }
    store_covariances(nodes);
    smoother.Flush();
  }

  for (int k = 0; k < n; ++k) {
    if (have[k]) result.trajectory.points.push_back(points[k]);
  }
  auto& d = result.diagnostics;
  d.insert({{"ceres_iterations", iterations},
            {"window_solves", solves},
            {"window_max_states", static_cast<double>(max_states)},
            {"window_max_factors", static_cast<double>(max_factors)},
            {"nodes", n}});
  d.insert(first_d.begin(), first_d.end());
  if (hold_bias) d["gyro_bias_held_no_heading_reference"] = 1.0;
  AddUpdateLatencyTimings(latency, &result.timings);
  AddWindowGraphDiagnostics(*graph, smoother, walk, options_, &d);
  return result;
}

}  // namespace internal

}  // namespace walkgraph
