// fg-batch (StepGraphBatch), what it shares with fg-window (step_graph_run.h) and the
// registration of the step-graph smoothers.
#include <algorithm>
#include <array>
#include <cmath>
#include <functional>
#include <limits>
#include <map>
#include <set>
#include <string>

#include "config/parsers.h"
#include "estimators/builtin.h"
#include "smoothers/anchor_search.h"
#include "smoothers/step_graph_impl.h"
#include "smoothers/step_graph_run.h"
#include "smoothers/unknown_anchors.h"
#include "walkgraph/smoothers/step_graph.h"

namespace walkgraph {
namespace internal {

SearchSetup SearchOptions(const Walk& walk, const StepGraphOptions& o,
                          const std::map<std::string, double>& fd) {
  const PathLossParams& pl = walk.meta.radio.path_loss;
  internal::AnchorSearchOptions so;
  so.margin_m = o.anchor_search_margin_m;
  so.step_m = o.anchor_search_step_m;
  so.min_readings = o.anchor_min_readings;
  so.min_spread_m = o.anchor_min_spread_m;
  so.distinct_radius_m = o.anchor_distinct_radius_m;
  so.min_cost_gap = o.anchor_min_cost_gap;
  SearchSetup out{so, so};
  internal::AnchorSearchOptions& r = out.range;
  r.range = true;
  r.sigma = o.range_sigma_m > 0 ? o.range_sigma_m : walk.meta.radio.range_sigma_m;
  r.loss_scale = o.range_loss_scale;
  r.range_scale = fd.count("range_scale") ? fd.at("range_scale") : 0.0;
  // The anchor's bias: held where the graph holds it (at the walk's estimate when there is
  // one bias for the walk), else free with its prior.
  r.level_prior_sigma = o.range_bias == CalibrationScope::kNone ? 0.0 : o.range_bias_prior_sigma_m;
  if (o.range_bias == CalibrationScope::kGlobal && fd.count("range_bias_m")) {
    r.level_prior = fd.at("range_bias_m");
    r.level_prior_sigma = 0.0;
  }
  // An RSS anchor's transmit level A: the walk's (held: σ 0), or the first solve's estimate with
  // the spread one anchor may have around it, else the prior.
  internal::AnchorSearchOptions& q = out.rss;
  q.range = false;
  q.sigma = o.sigma_db > 0 ? o.sigma_db : pl.sigma_db;
  q.loss_scale = o.rss_loss_scale;
  q.sign = walk.meta.radio.units == RssUnits::kDbm ? 1.0 : -1.0;
  q.d0_m = pl.d0_m;
  bool held_radio_only = false;
  const PathLossMode mode = ResolvePathLoss(walk, o, &held_radio_only);
  const bool A_estimated = fd.count("path_loss_A") > 0;
  q.level_prior = A_estimated ? fd.at("path_loss_A") : std::isfinite(o.A_dbm) ? o.A_dbm : pl.A_dbm;
  q.eta = fd.count("path_loss_eta") ? fd.at("path_loss_eta") : o.eta > 0 ? o.eta : pl.eta;
  q.level_prior_sigma = o.A_prior_sigma_db;
  if (mode == PathLossMode::kFixed || (mode == PathLossMode::kGlobal && A_estimated)) {
    q.level_prior_sigma = 0.0;
  } else if (mode == PathLossMode::kHierarchical) {
    q.level_prior_sigma =
        A_estimated ? o.A_spread_prior_db : std::hypot(o.A_prior_sigma_db, o.A_spread_prior_db);
  }
  return out;
}

Status CheckStepWalk(const Walk& walk) {
  if (!walk.has_odometry() && !walk.has_imu() &&
      (!(walk.has_rss() || walk.has_ranges()) || walk.anchors.size() < 3)) {
    return FailedPrecondition(
        "the step graph needs odometry.csv or an IMU (steps), or radio to >= 3 anchors");
  }
  return Status::Ok();
}

void AddStaticDiagnostics(const StepGraph& graph,
                          const std::function<std::vector<double>(Key)>& value_of, const Walk& walk,
                          const StepGraphOptions& o, std::map<std::string, double>* d) {
  // Name: "<what>" for a walk-wide block, "<what>.<anchor id>" per anchor.
  auto name = [&](const std::string& what, bool per_anchor, int group) {
    return per_anchor ? what + "." + std::to_string(walk.anchors[group].id) : what;
  };
  for (const GraphState& s : graph.StaticStates()) {
    if (s.constant) continue;
    const std::vector<double> v = value_of(s.key);
    if (v.empty()) continue;  // not in the graph (fg-window: an anchor never placed)
    const char letter = SymbolLetter(s.key);
    const int g = static_cast<int>(SymbolIndex(s.key));
    if (s.key == kGyroBiasKey) {
      (*d)["gyro_bias_radps"] = v[0];
    } else if (s.key == internal::kStepScaleKey) {
      (*d)["step_length_scale"] = 1.0 + v[0];
    } else if (letter == 'p') {  // an anchor's position (fg-batch: anchors_estimated too)
      (*d)[name("anchor_x_m", true, g)] = v[0];
      (*d)[name("anchor_y_m", true, g)] = v[1];
    } else if (letter == 's') {
      (*d)[name("range_scale", o.range_scale == CalibrationScope::kPerAnchor, g)] = v[0];
    } else if (letter == 'b') {
      (*d)[name("range_bias_m", o.range_bias == CalibrationScope::kPerAnchor, g)] = v[0];
    } else {  // l(g): per anchor unless global; m(0): hierarchical's walk-wide mean
      const bool per_anchor = letter == 'l' && graph.path_loss_per_anchor();
      (*d)[name("path_loss_A", per_anchor, g)] = v[0];
      (*d)[name("path_loss_eta", per_anchor, g)] = v[1];
    }
  }
}

void AddGraphDiagnostics(const StepGraph& graph, const Walk& walk,
                         std::map<std::string, double>* d) {
  if (walk.has_rss()) {
    (*d)["path_loss_estimated"] = graph.path_loss_estimated() ? 1.0 : 0.0;
    if (graph.path_loss_held_radio_only()) (*d)["path_loss_held_radio_only"] = 1.0;
  }
  if (graph.start_heading_contradicted_rad() > 0.0) {
    (*d)["start_heading_contradicted_rad"] = graph.start_heading_contradicted_rad();
  }
  if (graph.has_floors()) (*d)["stair_steps"] = graph.stair_steps();
  if (graph.radio_start_floor()) (*d)["start_floor_from_radio"] = *graph.radio_start_floor();
  if (walk.has_imu() && !walk.has_odometry()) AddFrontEndDiagnostics(graph.front_end_report(), d);
}

// A node's height and the floor it is on.
void SetHeight(const StepGraph& graph, double z_m, TrajectoryPoint* point) {
  point->position_m.z() = z_m;
  point->floor = graph.FloorOfHeight(z_m);
}

TrajectoryPoint MakePoint(double t, const double* p, double theta) {
  TrajectoryPoint pt;
  pt.t_s = t;
  pt.position_m = Eigen::Vector3d(p[0], p[1], 0.0);
  pt.heading_rad = NormalizeAngle(theta);
  return pt;
}

// (x, y, θ) covariance from a node's tangent-space covariance: 3×3, or 2×2 when the heading
// is not a state (radio-only walks: θ uniform, variance π²/3).
// c is the marginal of a node's variable blocks (position 2, heading 1); a constant block (the
// gauge node of a walk with neither a known start nor radio) is exact and drops out of c.
Eigen::Matrix3d PoseCovariance(const Eigen::MatrixXd& c) {
  if (c.rows() == 3) return Eigen::Matrix3d(c);
  Eigen::Matrix3d out = Eigen::Matrix3d::Zero();
  if (c.rows() == 0) return out;  // both blocks constant
  if (c.rows() == 1) {            // position constant, heading free
    out(2, 2) = c(0, 0);
    return out;
  }
  out.topLeftCorner<2, 2>() = c.topLeftCorner<2, 2>();
  out(2, 2) = kPi * kPi / 3.0;
  return out;
}

// The graph's own motion model between nodes: a step moves the walker only during its last
// max_step_duration_s, so across a longer gap (a stop) the walker stays at the previous node
// until then. An extra output point there keeps interpolated positions on that model. A
// bridged step (across an IMU gap) moves over its whole interval: no stop.
void InsertStops(const Walk& walk, double max_step_duration_s, Trajectory* trajectory) {
  std::vector<double> t;
  for (const TrajectoryPoint& p : trajectory->points) t.push_back(p.t_s);
  const std::vector<bool> bridged = BridgedNodes(walk, walk.has_imu() && !walk.has_odometry(), t);
  std::vector<TrajectoryPoint> out;
  out.reserve(trajectory->points.size());
  for (size_t k = 0; k < trajectory->points.size(); ++k) {
    const TrajectoryPoint& p = trajectory->points[k];
    if (k > 0 && !bridged[k]) {
      const TrajectoryPoint& prev = trajectory->points[k - 1];
      const double start = p.t_s - max_step_duration_s;
      if (start > prev.t_s + 1e-6) {
        TrajectoryPoint still = prev;
        still.t_s = start;
        out.push_back(still);
      }
    }
    out.push_back(p);
  }
  trajectory->points = std::move(out);
}

// fg-batch's solver options.
SolverOptions BatchSolverOptions(const StepGraphOptions& o) {
  SolverOptions so;
  so.max_iterations = o.max_iterations;
  so.initial_trust_region_radius = o.initial_trust_region_radius;
  so.function_tolerance = o.function_tolerance;
  so.parameter_tolerance = o.parameter_tolerance;
  so.num_threads = o.num_threads;
  SetLinearSolver(o.linear_solver, &so);
  return so;
}

void SetLinearSolver(WindowLinearSolver choice, SolverOptions* so) {
  so->linear_solver = choice == WindowLinearSolver::kDense ? LinearSolver::kDenseNormalCholesky
                                                           : LinearSolver::kSparseNormalCholesky;
  so->eigen_sparse = choice == WindowLinearSolver::kEigenSparse;
}

// The start hypotheses of StepGraphOptions::start_estimators (StepGraph::HypothesesFrom) over
// the nodes with t <= until_s; causal: the filters only (an id ending in "-rts" gives its
// filter's, the id without it). An estimator
// that cannot run on the walk, or fails, gives none; an id the registry does not know is an
// error.
StatusOr<std::vector<NamedStart>> EstimatorStarts(const Walk& walk, const StepGraph& graph,
                                                  const StepGraphOptions& o, bool causal,
                                                  double until_s) {
  std::vector<NamedStart> out;
  if (walk.meta.initial_pose || !(walk.has_rss() || walk.has_ranges()) ||
      !(walk.has_imu() || walk.has_odometry())) {
    return out;
  }
  const std::vector<std::string> ids = StartEstimatorIds(o.start_estimators);
  for (size_t i = 0; i < ids.size(); ++i) {
    const std::string& id = ids[i];
    const bool smoother = id.size() > 4 && id.compare(id.size() - 4, 4, "-rts") == 0;
    const std::string run = causal && smoother ? id.substr(0, id.size() - 4) : id;
    WG_ASSIGN_OR_RETURN(std::unique_ptr<Estimator> e, EstimatorRegistry::Builtin().Create(run));
    if (!e->CheckApplicable(walk).ok()) continue;
    StatusOr<EstimateResult> r = e->Run(walk);
    if (!r.ok()) continue;  // the other hypotheses still stand
    auto h = graph.HypothesesFrom(r->trajectory, until_s);
    if (h.size() != 2) continue;
    out.push_back({run + "/aligned", std::move(h[0]), static_cast<int>(i) + 1});
    out.push_back({run, std::move(h[1]), static_cast<int>(i) + 1});
  }
  return out;
}

}  // namespace internal

using internal::AddGraphDiagnostics;
using internal::AddStaticDiagnostics;
using internal::BatchSolverOptions;
using internal::CheckStepWalk;
using internal::EstimatorStarts;
using internal::InsertStops;
using internal::kGyroBiasKey;
using internal::MakePoint;
using internal::NamedStart;
using internal::PoseCovariance;
using internal::ResolvePathLoss;
using internal::RunWindowNodes;
using internal::SetHeight;

namespace {

// fg-batch's start hypotheses on a walk with no start: StartHypotheses' turns (named 1..n),
// then EstimatorStarts; on a start of known position but unknown heading (issue 41: a phone
// without a magnetometer), the dead reckoning and StartHeadingTurns (named 1..n): fg-batch
// starts from the fast window pass, whose result is one basin; these are the others.
StatusOr<std::vector<NamedStart>> BatchStarts(const Walk& walk, const StepGraph& graph,
                                              const StepGraphOptions& o) {
  std::vector<NamedStart> starts;
  for (auto& h : graph.StartHypotheses(walk, o.start_hypotheses)) {
    starts.push_back({std::to_string(starts.size() + 1), std::move(h), 0});
  }
  std::vector<std::vector<Eigen::Vector3d>> turns = graph.StartHeadingTurns(o.start_hypotheses);
  if (!turns.empty()) turns.insert(turns.begin(), graph.initial_nodes());  // turn 0
  for (auto& h : turns) starts.push_back({std::to_string(starts.size() + 1), std::move(h), 0});
  WG_ASSIGN_OR_RETURN(
      std::vector<NamedStart> more,
      EstimatorStarts(walk, graph, o, /*causal=*/false, std::numeric_limits<double>::infinity()));
  for (NamedStart& h : more) starts.push_back(std::move(h));
  return starts;
}

// fg-batch's start hypotheses (BatchStarts): each solved from its own initial nodes; returns
// the graph of the lowest final cost when one beats `*best` (whose summary it then takes),
// else null. Diagnostics: start_hypothesis (0: fg-batch's own initialization, k: the k-th
// hypothesis), start_hypothesis_cost.<name> per hypothesis (.0 its own) and
// start_hypothesis_estimator (NamedStart::estimator of the winner).
StatusOr<std::unique_ptr<FactorGraph>> SolveStartHypotheses(const StepGraph& graph,
                                                            const std::vector<NamedStart>& starts,
                                                            const SolverOptions& so,
                                                            SolveSummary* best,
                                                            std::map<std::string, double>* d) {
  std::unique_ptr<FactorGraph> winner;
  if (starts.empty()) return winner;
  (*d)["start_hypothesis"] = 0;
  (*d)["start_hypothesis_estimator"] = 0;
  (*d)["start_hypothesis_cost.0"] = best->final_cost;
  for (size_t h = 0; h < starts.size(); ++h) {
    auto fg = std::make_unique<FactorGraph>();
    WG_RETURN_IF_ERROR(graph.AddTo(fg.get()));
    for (size_t k = 0; k < starts[h].nodes.size(); ++k) {
      const Eigen::Vector3d& x = starts[h].nodes[k];
      const int node = static_cast<int>(k);
      WG_RETURN_IF_ERROR(fg->SetValue(StepGraph::PositionKey(node), {x[0], x[1]}));
      WG_RETURN_IF_ERROR(fg->SetValue(StepGraph::HeadingKey(node), {x[2]}));
    }
    StatusOr<SolveSummary> summary = SolveBatch(fg.get(), so);
    if (!summary.ok()) continue;  // a hypothesis that fails to solve is not taken
    (*d)["start_hypothesis_cost." + starts[h].name] = summary->final_cost;
    if (summary->final_cost < best->final_cost) {
      *best = *summary;
      (*d)["start_hypothesis"] = static_cast<double>(h + 1);
      (*d)["start_hypothesis_estimator"] = starts[h].estimator;
      winner = std::move(fg);
    }
  }
  return winner;
}

}  // namespace

Status StepGraphBatch::CheckApplicable(const Walk& walk) const { return CheckStepWalk(walk); }

Status StepGraph::AddTo(FactorGraph* fg) const {
  for (GraphState& s : StaticStates()) WG_RETURN_IF_ERROR(fg->AddState(std::move(s)));
  for (int k = 0; k < num_nodes(); ++k) {
    const Eigen::Vector3d& x = init_[k];
    for (GraphState& s : NodeStates(k, x.head<2>(), x[2])) {
      if (k > 0 && s.key == PositionKey(k)) s.value = {x[0], x[1]};
      if (k > 0 && s.key == HeadingKey(k)) s.value = {x[2]};
      WG_RETURN_IF_ERROR(fg->AddState(std::move(s)));
    }
  }
  for (int k = 0; k < num_nodes(); ++k) {
    for (GraphFactor& f : FactorsAt(k)) WG_RETURN_IF_ERROR(fg->AddFactor(std::move(f)));
  }
  return Status::Ok();
}

namespace {

// The anchors that are states (StepGraph::AnchorIsState) at their solved positions, into `out`;
// returns their indices.
std::vector<int> AnchorEstimates(const Walk& walk, const StepGraph& graph,
                                 const std::function<std::vector<double>(Key)>& value,
                                 std::vector<AnchorEstimate>* out) {
  std::vector<int> states;
  for (size_t a = 0; a < walk.anchors.size(); ++a) {
    if (!graph.AnchorIsState(static_cast<int>(a))) continue;
    states.push_back(static_cast<int>(a));
    AnchorEstimate e;
    e.id = walk.anchors[a].id;
    const std::vector<double> v = value(StepGraph::AnchorKey(static_cast<int>(a)));
    e.position_m = Eigen::Vector2d(v[0], v[1]);
    e.readings = walk.AnchorReadings(e.id);
    out->push_back(e);
  }
  return states;
}

// Multiplies the σ of step-graph noise group `g` (internal::StepNoiseGroup) in `o` by `s`.
void ScaleNoise(int g, double s, const Walk& walk, StepGraphOptions* o) {
  switch (g) {
    case internal::kStepNoise:
      o->step_sigma_scale *= s;
      o->sigma_cross_m *= s;
      break;
    case internal::kHeadingIncrementNoise:
      o->dheading_sigma_scale *= s;
      break;
    case internal::kMagHeadingNoise:
      o->mag_heading_sigma_rad *= s;
      break;
    case internal::kRssNoise:
      o->sigma_db = s * (o->sigma_db > 0 ? o->sigma_db : walk.meta.radio.path_loss.sigma_db);
      break;
    case internal::kRangeNoise:
      o->range_sigma_m =
          s * (o->range_sigma_m > 0 ? o->range_sigma_m : walk.meta.radio.range_sigma_m);
      break;
    default:
      break;
  }
}

constexpr const char* kNoiseGroupNames[internal::kStepNoiseGroups] = {
    "step", "heading_increment", "mag_heading", "rss", "range"};
constexpr double kNoiseScaleMin = 0.1, kNoiseScaleMax = 10.0, kNoiseScaleMove = 0.05;

// StepGraphOptions::noise_scale_rounds: the solved graph's noise scales (EstimateNoiseScales),
// the step graph rebuilt with them and solved again from the solution, round by round. Each
// round that solves replaces *o, *graph, *fg and *summary; one whose scales cannot be estimated,
// whose graph cannot be built or whose solve fails ends the rounds with the last solution kept.
Status RefineNoiseScales(const Walk& walk, StepGraphOptions* o, std::unique_ptr<StepGraph>* graph,
                         std::unique_ptr<FactorGraph>* fg, SolveSummary* summary,
                         std::map<std::string, double>* d) {
  std::array<double, internal::kStepNoiseGroups> total;
  total.fill(1.0);
  int rounds = 0;
  for (; rounds < o->noise_scale_rounds; ++rounds) {
    StatusOr<std::map<int, NoiseScale>> est = EstimateNoiseScales(fg->get());
    if (!est.ok()) break;
    StepGraphOptions next = *o;
    std::array<double, internal::kStepNoiseGroups> moved = total;
    for (const auto& [g, ns] : *est) {
      if (g < 0 || g >= internal::kStepNoiseGroups) continue;
      // Magnetic disturbances, shadowing and multipath persist along the walk: their residuals
      // look tighter than the independent information they carry, so these σ are only raised
      // (IPIN known start without it: the magnetometer's scale came out 0.40-0.49 and trial 05
      // went 2.22 -> 2.60 m p75).
      const bool persistent =
          g == internal::kMagHeadingNoise || g == internal::kRssNoise || g == internal::kRangeNoise;
      const double scale = persistent || !o->noise_scale_lower ? std::max(ns.scale, 1.0) : ns.scale;
      moved[g] = std::clamp(total[g] * scale, kNoiseScaleMin, kNoiseScaleMax);
      if (std::fabs(moved[g] / total[g] - 1.0) <= kNoiseScaleMove) moved[g] = total[g];
      if (moved[g] != total[g]) ScaleNoise(g, moved[g] / total[g], walk, &next);
    }
    if (moved == total) break;
    StatusOr<std::unique_ptr<StepGraph>> rebuilt = StepGraph::Build(walk, next);
    if (!rebuilt.ok()) break;
    auto refit = std::make_unique<FactorGraph>();
    WG_RETURN_IF_ERROR((*rebuilt)->AddTo(refit.get()));
    std::vector<Key> keys = (*fg)->TimedKeys();
    for (Key k : (*fg)->StaticKeys()) keys.push_back(k);
    for (Key k : keys) {
      if (refit->Contains(k)) WG_RETURN_IF_ERROR(refit->SetValue(k, *(*fg)->Value(k)));
    }
    StatusOr<SolveSummary> solved = SolveBatch(refit.get(), BatchSolverOptions(next));
    if (!solved.ok()) break;
    *o = next;
    *graph = std::move(*rebuilt);
    *fg = std::move(refit);
    *summary = *solved;
    total = moved;
  }
  (*d)["noise_scale_rounds"] = rounds;
  for (int g = 0; g < internal::kStepNoiseGroups && o->noise_scale_rounds > 0; ++g) {
    (*d)[std::string("noise_scale.") + kNoiseGroupNames[g]] = total[g];
  }
  return Status::Ok();
}

// fg-batch's output from its solved graph: diagnostics, trajectory (and the nodes' (p, θ) and
// times when asked), the anchors that are states and the covariances.
StatusOr<EstimateResult> BatchResult(const Walk& walk, const StepGraphOptions& o,
                                     const StepGraph& graph, FactorGraph* fg,
                                     std::vector<Eigen::Vector3d>* nodes,
                                     std::vector<double>* node_t) {
  const int n = graph.num_nodes();
  EstimateResult result;
  auto& d = result.diagnostics;
  d["nodes"] = n;
  d["residual_blocks"] = static_cast<double>(fg->num_factors());
  auto value = [&](Key k) { return *fg->Value(k); };  // every key below is in the graph
  AddStaticDiagnostics(graph, value, walk, o, &d);
  AddGraphDiagnostics(graph, walk, &d);
  for (int k = 0; k < n; ++k) {
    result.trajectory.points.push_back(MakePoint(graph.node_time(k),
                                                 value(StepGraph::PositionKey(k)).data(),
                                                 value(StepGraph::HeadingKey(k))[0]));
    if (graph.has_floors())
      SetHeight(graph, value(StepGraph::HeightKey(k))[0], &result.trajectory.points.back());
  }
  if (nodes != nullptr) {
    nodes->clear();
    for (const TrajectoryPoint& p : result.trajectory.points) {
      nodes->emplace_back(p.position_m.x(), p.position_m.y(), p.heading_rad);
      if (node_t != nullptr) node_t->push_back(p.t_s);
    }
  }
  const std::vector<int> anchor_states = AnchorEstimates(walk, graph, value, &result.anchors);
  if (!anchor_states.empty()) {
    // The frame the anchors are in: 0 the known start's, 1 the anchors' of given position,
    // 2 the walk's own (node 0 held where it started).
    d["gauge"] = walk.meta.initial_pose ? 0.0 : graph.fix_first_node() ? 2.0 : 1.0;
  }
  if (o.covariance) {
    std::vector<std::vector<Key>> groups;
    for (int k = 0; k < n; ++k) {
      groups.push_back({StepGraph::PositionKey(k), StepGraph::HeadingKey(k)});
    }
    for (int a : anchor_states) groups.push_back({StepGraph::AnchorKey(a)});
    auto cov = MarginalCovariances(fg, groups);
    if (!cov.ok()) {
      d["covariance_failed"] = 1.0;  // e.g. rank-deficient: trajectory without covariances
    } else {
      for (int k = 0; k < n; ++k) {
        result.trajectory.points[k].covariance = PoseCovariance((*cov)[k]);
      }
      for (size_t i = 0; i < anchor_states.size(); ++i) {
        const Eigen::MatrixXd& c = (*cov)[n + i];
        result.anchors[i].covariance = Eigen::Matrix2d(0.5 * (c + c.transpose()));
      }
    }
  }
  InsertStops(walk, o.max_step_duration_s, &result.trajectory);
  return result;
}

// One fg-batch solve of `walk`. `from` (not null): start every node there (a previous solve's
// nodes) instead of fg-batch's own initialization, with no start hypotheses. `nodes` (not
// null): the solution's (p, θ) per node, and their times in `node_t` (not null). Anchors that
// are states (StepGraph::AnchorIsState) come back in result.anchors with their covariance.
StatusOr<EstimateResult> SolveBatchWalk(const Walk& walk, const StepGraphOptions& options_,
                                        const std::vector<Eigen::Vector3d>* from,
                                        std::vector<Eigen::Vector3d>* nodes,
                                        std::vector<double>* node_t = nullptr) {
  WG_ASSIGN_OR_RETURN(std::unique_ptr<StepGraph> graph, StepGraph::Build(walk, options_));
  const int n = graph->num_nodes();

  auto fg = std::make_unique<FactorGraph>();
  WG_RETURN_IF_ERROR(graph->AddTo(fg.get()));
  const SolverOptions so = BatchSolverOptions(options_);
  // auto: dead reckoning for odometry walks (wheel odometry barely drifts), the window for
  // IMU steps (a gyro's heading drift over a long walk leaves dead reckoning in a wrong basin:
  // measured on correa-classroom 0.85 → 0.23 m RMSE, gadeke-outage 18.8 → 0.71 m).
  const bool window_init =
      from == nullptr &&
      (options_.initialization == StepGraphInit::kWindow ||
       (options_.initialization == StepGraphInit::kAuto && !walk.has_odometry()));
  if (from != nullptr) {
    if (static_cast<int>(from->size()) != n) {
      return InternalError("fg-batch: a previous solve has a different node count");
    }
    for (int k = 0; k < n; ++k) {
      const Eigen::Vector3d& x = (*from)[k];
      WG_RETURN_IF_ERROR(fg->SetValue(StepGraph::PositionKey(k), {x[0], x[1]}));
      WG_RETURN_IF_ERROR(fg->SetValue(StepGraph::HeadingKey(k), {x[2]}));
    }
  }
  if (window_init) {
    // Start from the fixed-lag smoother's lagged estimates (it grows the solution
    // incrementally, so it does not get lost).
    StepGraphOptions wo = options_;
    wo.covariance = false;
    wo.window_output = WindowOutput::kLagged;
    wo.lag_s = options_.init_lag_s;
    wo.window_update_s = options_.init_update_s;
    wo.window_max_iterations = options_.init_max_iterations;
    // fg-batch's own stop; fg-window's looser one moves fg-batch's local optimum on robust
    // walks (BLE straight_03 1.231 → 1.254 m).
    wo.window_function_tolerance = options_.function_tolerance;
    WG_ASSIGN_OR_RETURN(EstimateResult w, RunWindowNodes(walk, wo));
    if (static_cast<int>(w.trajectory.size()) != n) {
      return InternalError("fg-batch: window initialization returned a different node count");
    }
    for (int k = 0; k < n; ++k) {
      const TrajectoryPoint& pt = w.trajectory.points[k];
      WG_RETURN_IF_ERROR(
          fg->SetValue(StepGraph::PositionKey(k), {pt.position_m.x(), pt.position_m.y()}));
      WG_RETURN_IF_ERROR(fg->SetValue(StepGraph::HeadingKey(k), {pt.heading_rad}));
    }
  }
  StatusOr<SolveSummary> summary = SolveBatch(fg.get(), so);
  if (!summary.ok()) return NumericalError("fg-batch: " + summary.status().message());
  std::map<std::string, double> d;
  std::vector<NamedStart> starts;
  if (from == nullptr) {
    WG_ASSIGN_OR_RETURN(starts, BatchStarts(walk, *graph, options_));
  }
  WG_ASSIGN_OR_RETURN(std::unique_ptr<FactorGraph> better,
                      SolveStartHypotheses(*graph, starts, so, &*summary, &d));
  if (better) fg = std::move(better);
  StepGraphOptions o = options_;
  WG_RETURN_IF_ERROR(RefineNoiseScales(walk, &o, &graph, &fg, &*summary, &d));
  WG_ASSIGN_OR_RETURN(EstimateResult result, BatchResult(walk, o, *graph, fg.get(), nodes, node_t));
  d["ceres_iterations"] = summary->iterations;
  d["ceres_converged"] = summary->termination == Termination::kConverged ? 1.0 : 0.0;
  d["final_cost"] = summary->final_cost;
  d["normalized_cost"] = summary->normalized_cost();  // 2F/(m − n), ≈ 1 if consistent
  d["initialized_from_window"] = window_init ? 1.0 : 0.0;
  result.diagnostics.insert(d.begin(), d.end());
  return result;
}

// Where the path was at time t: the nodes' positions, interpolated.
Eigen::Vector2d PathAt(const std::vector<double>& t, const std::vector<Eigen::Vector3d>& x,
                       double ts) {
  const auto it = std::lower_bound(t.begin(), t.end(), ts);
  if (it == t.begin()) return x.front().head<2>();
  if (it == t.end()) return x.back().head<2>();
  const size_t b = static_cast<size_t>(it - t.begin());
  const double w = (ts - t[b - 1]) / (t[b] - t[b - 1]);
  return (1.0 - w) * x[b - 1].head<2>() + w * x[b].head<2>();
}

// fg-batch on a walk with anchors of unknown position (step_graph.h, "Anchors of unknown
// position"; unknown_anchors.h): the joint solve starts from the first solve's nodes, and each
// anchor is searched along those nodes (the first solve's trajectory carries the stops
// InsertStops added).
StatusOr<EstimateResult> SolveWithUnknownAnchors(const Walk& walk, const StepGraphOptions& o) {
  std::vector<Eigen::Vector3d> first_nodes;
  std::vector<double> node_t;
  internal::UnknownAnchorPass pass;
  pass.solve = [&](const Walk& w, const EstimateResult* first) -> StatusOr<EstimateResult> {
    if (first == nullptr) return SolveBatchWalk(w, o, nullptr, &first_nodes, &node_t);
    WG_ASSIGN_OR_RETURN(EstimateResult r, SolveBatchWalk(w, o, &first_nodes, nullptr));
    r.diagnostics["unknown_anchors_first_pass_cost"] =
        first->diagnostics.count("final_cost") ? first->diagnostics.at("final_cost") : 0.0;
    return r;
  };
  const bool radio_only = !walk.has_odometry() && !walk.has_imu();
  pass.place = [&](const Anchor& a, const EstimateResult& first) {
    internal::AnchorPlacement out;
    std::vector<Eigen::Vector2d> q;
    std::vector<double> v;
    // Its ranges (a ranging radio); an anchor without ranges, its RSS readings.
    for (const RangeSample& r : walk.ranges) {
      if (r.anchor_id != a.id) continue;
      q.push_back(PathAt(node_t, first_nodes, r.t_s));
      v.push_back(r.range_m);
    }
    const bool range = !v.empty();
    for (const RssSample& r : walk.rss) {
      if (range || r.anchor_id != a.id) continue;
      q.push_back(PathAt(node_t, first_nodes, r.t_s));
      v.push_back(r.rss);
    }
    out.readings = static_cast<int>(v.size());
    if (radio_only) {  // no path without its anchors to search along
      out.verdict = "radio_only";
      return out;
    }
    const internal::SearchSetup search = internal::SearchOptions(walk, o, first.diagnostics);
    internal::AnchorSearchOptions so = range ? search.range : search.rss;
    so.dz_m = o.receiver_height_m - a.position_m.z();  // on its floor (step_graph_pending.cc)
    out.found = internal::SearchAnchor(q, v, so);
    return out;
  };
  WG_ASSIGN_OR_RETURN(EstimateResult result, internal::SolveWithUnknownAnchors(walk, pass));
  auto& d = result.diagnostics;
  if (!d.count("gauge")) {  // nothing placed: the first solve's frame
    int placed = 0;
    std::set<int> heard;
    for (const RssSample& r : walk.rss) heard.insert(r.anchor_id);
    for (const RangeSample& r : walk.ranges) heard.insert(r.anchor_id);
    for (const Anchor& a : walk.anchors) placed += a.position_known && heard.count(a.id) ? 1 : 0;
    d["gauge"] = walk.meta.initial_pose ? 0.0 : placed >= 2 ? 1.0 : 2.0;
  }
  return result;
}

}  // namespace

StatusOr<EstimateResult> StepGraphBatch::Run(const Walk& walk) const {
  WG_RETURN_IF_ERROR(CheckApplicable(walk));
  const bool not_surveyed = std::any_of(walk.anchors.begin(), walk.anchors.end(),
                                        [](const Anchor& a) { return !a.surveyed(); });
  if (not_surveyed) return SolveWithUnknownAnchors(walk, options_);
  return SolveBatchWalk(walk, options_, nullptr, nullptr);
}

namespace internal {

Status RegisterStepGraphSmoothers(EstimatorRegistry* registry) {
  auto parse = [](const char* id, StepGraphOptions defaults) {
    return [id, defaults](const YAML::Node& config) {
      return StepGraphOptionsFromYaml(config, id, defaults);
    };
  };
  StepGraphOptions selfcal;
  selfcal.path_loss = PathLossMode::kGlobal;
  StepGraphOptions online;
  online.window_output = WindowOutput::kOnline;
  WG_RETURN_IF_ERROR(registry->Register(
      {"fg-batch",
       "factor graph, full batch: steps/odometry + RSS (dB) / ranges (bias, robust), Ceres "
       "sparse Cholesky",
       OptionsFactory<StepGraphBatch>(parse("fg-batch", StepGraphOptions())),
       /*estimates_unknown_anchors=*/true}));
  WG_RETURN_IF_ERROR(registry->Register(
      {"fg-batch-selfcal", "fg-batch with path-loss self-calibration (A, η estimated; weak prior)",
       OptionsFactory<StepGraphBatch>(parse("fg-batch-selfcal", selfcal)),
       /*estimates_unknown_anchors=*/true}));
  WG_RETURN_IF_ERROR(registry->Register(
      {"fg-window",
       "factor graph, fixed-lag smoother (10 s lag, marginalization prior): lagged estimates",
       OptionsFactory<StepGraphWindow>(parse("fg-window", StepGraphOptions())),
       /*estimates_unknown_anchors=*/true}));
  return registry->Register({"fg-window-online",
                             "fg-window's online output: each node right after its own update",
                             OptionsFactory<StepGraphWindow>(parse("fg-window-online", online)),
                             /*estimates_unknown_anchors=*/true});
}

}  // namespace internal
}  // namespace walkgraph
