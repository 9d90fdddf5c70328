#include "walkgraph/smoothers/ins_graph.h"

#include "config/parsers.h"
#include "walkgraph/smoothers/chain_covariance.h"
#include "walkgraph/smoothers/ins_window.h"

#include <algorithm>
#include <cmath>
#include <set>
#include <utility>

#include <ceres/covariance.h>
#include <ceres/normal_prior.h>
#include <ceres/solver.h>

#include "estimators/builtin.h"
#include "factors/bias_random_walk_factor.h"
#include "factors/difference_prior_factor.h"
#include "factors/gap_reach_factor.h"
#include "factors/imu_preintegration_factor.h"
#include "factors/ins_prior_factor.h"
#include "factors/magnetic_heading_change_factor.h"
#include "factors/magnetic_heading_factor.h"
#include "factors/nav_quaternion_manifold.h"
#include "factors/position_prior_factor.h"
#include "factors/range_factor.h"
#include "factors/rss_factor.h"
#include "factors/zaru_factor.h"
#include "factors/zupt_factor.h"
#include "smoothers/anchor_search.h"
#include "smoothers/graph_internal.h"
#include "smoothers/ins_graph_internal.h"
#include "smoothers/unknown_anchors.h"
#include "util/enum_define.h"
#include "util/median.h"
#include "walkgraph/angle.h"
#include "walkgraph/config.h"
#include "walkgraph/kalman.h"

namespace walkgraph {

namespace {

NavState ToNavState(const InsState& s) {
  NavState n;
  n.t_s = s.t_s;
  n.p_n = s.position();
  n.v_n = s.velocity();
  n.q_nb = s.attitude().normalized();
  return n;
}

}  // namespace

namespace {
constexpr char kInsBlockLetters[kInsBlocksPerState + 1] = "xvqga";
}  // namespace

Key InsKey(size_t state, InsBlock block) {
  return Symbol(kInsBlockLetters[static_cast<int>(block)], state);
}

std::optional<InsBlock> InsBlockOfLetter(char letter) {
  for (int b = 0; b < kInsBlocksPerState; ++b) {
    if (letter == kInsBlockLetters[b]) return static_cast<InsBlock>(b);
  }
  return std::nullopt;
}

int InsBlockSize(InsBlock block) { return block == InsBlock::kQ ? 4 : 3; }

double* InsBlockData(InsState* s, InsBlock block) {
  switch (block) {
    case InsBlock::kP:
      return s->p.data();
    case InsBlock::kV:
      return s->v.data();
    case InsBlock::kQ:
      return s->q.data();
    case InsBlock::kBg:
      return s->bg.data();
    case InsBlock::kBa:
      break;
  }
  return s->ba.data();
}

std::vector<GraphState> InsStateBlocks(size_t i, const InsState& values,
                                       const std::shared_ptr<const ceres::Manifold>& q_manifold) {
  InsState copy = values;
  std::vector<GraphState> out;
  for (int b = 0; b < kInsBlocksPerState; ++b) {
    const InsBlock block = static_cast<InsBlock>(b);
    GraphState st;
    st.key = InsKey(i, block);
    st.t_s = values.t_s;
    const double* data = InsBlockData(&copy, block);
    st.value.assign(data, data + InsBlockSize(block));
    if (block == InsBlock::kQ) st.manifold = q_manifold;
    out.push_back(std::move(st));
  }
  return out;
}

double* InsBlockOfKey(std::vector<InsState>* states, Key key) {
  const uint64_t i = SymbolIndex(key);
  const std::optional<InsBlock> block = InsBlockOfLetter(SymbolLetter(key));
  if (i >= states->size() || !block) return nullptr;
  return InsBlockData(&(*states)[i], *block);
}

void InsKeyMap::RegisterState(size_t i, InsState* state) {
  for (int b = 0; b < kInsBlocksPerState; ++b) {
    const InsBlock block = static_cast<InsBlock>(b);
    double* data = InsBlockData(state, block);
    if (mapped_.emplace(data, Mapped{InsKey(i, block), data, InsBlockSize(block)}).second) {
      order_.push_back(data);
    }
  }
}

StatusOr<GraphState> InsKeyMap::SharedState(const double* block) {
  GraphState st;
  InsSharedBlocks& sh = *shared_;
  auto anchor_key = [&](char letter, int id) -> StatusOr<Key> {
    const int ai = walk_.AnchorIndex(id);
    if (ai < 0) return InternalError("foot-INS graph: a walk-wide block of an unknown anchor");
    return Symbol(letter, static_cast<uint64_t>(ai));
  };
  if (block == sh.path_loss.data()) {
    st.key = Symbol(sh.per_anchor_path_loss ? 'm' : 'l', 0);
    st.value.assign(sh.path_loss.begin(), sh.path_loss.end());
    st.constant = !sh.estimate_path_loss;
    return st;
  }
  if (block == &sh.field_yaw_rad) {
    st.key = Symbol('f', 0);
    st.value = {sh.field_yaw_rad};
    return st;
  }
  for (auto& [id, bias] : sh.range_bias_m) {
    if (&bias != block) continue;
    WG_ASSIGN_OR_RETURN(st.key, anchor_key('b', id));
    st.value = {bias};
    st.constant = !options_.estimate_range_bias;
    return st;
  }
  for (auto& [id, pl] : sh.anchor_path_loss) {
    if (pl.data() != block) continue;
    WG_ASSIGN_OR_RETURN(st.key, anchor_key('l', id));
    st.value.assign(pl.begin(), pl.end());
    return st;
  }
  for (auto& [id, p] : sh.anchor_position) {
    if (p.data() != block) continue;
    WG_ASSIGN_OR_RETURN(st.key, anchor_key('p', id));
    st.value.assign(p.begin(), p.end());
    return st;
  }
  if (block == &sh.zero_range_scale) {
    st.key = Symbol('s', 0);
    st.value = {0.0};
    st.constant = true;
    return st;
  }
  return InternalError("foot-INS graph: a factor on a block that is no state's");
}

StatusOr<GraphFactor> InsKeyMap::ToGraphFactor(InsFactor* f, std::vector<GraphState>* new_states) {
  GraphFactor out;
  for (double* block : f->blocks) {
    auto it = mapped_.find(block);
    if (it == mapped_.end()) {
      WG_ASSIGN_OR_RETURN(GraphState st, SharedState(block));
      it = mapped_.emplace(block, Mapped{st.key, block, static_cast<int>(st.value.size())}).first;
      order_.push_back(block);
      new_states->push_back(std::move(st));
    }
    out.keys.push_back(it->second.key);
  }
  out.cost = std::shared_ptr<ceres::CostFunction>(f->cost.release());
  out.loss = std::shared_ptr<const ceres::LossFunction>(f->loss.release());
  return out;
}

Status InsKeyMap::CopyValues(const std::function<StatusOr<std::vector<double>>(Key)>& value) const {
  for (const double* block : order_) {
    const Mapped& m = mapped_.at(block);
    WG_ASSIGN_OR_RETURN(std::vector<double> v, value(m.key));
    if (v.size() != static_cast<size_t>(m.size)) {
      return InternalError("foot-INS graph: " + KeyToString(m.key) + " has another size");
    }
    std::copy(v.begin(), v.end(), m.block);
  }
  return Status::Ok();
}

StatusOr<std::vector<std::vector<GraphFactor>>> InsUserFactors(const InsGraphContext& c,
                                                               std::vector<InsState>* states) {
  std::vector<double> times;
  for (const InsState& s : *states) times.push_back(s.t_s);
  WG_ASSIGN_OR_RETURN(std::vector<GraphFactor> factors,
                      internal::CallUserFactors(c.options.user_factors, *c.walk, times));
  std::vector<std::vector<GraphFactor>> out(states->size());
  for (size_t i = 0; i < factors.size(); ++i) {
    const std::string where = "user factor " + std::to_string(i) + ": ";
    const std::vector<int32_t>& sizes = factors[i].cost->parameter_block_sizes();
    uint64_t newest = 0;
    for (size_t b = 0; b < factors[i].keys.size(); ++b) {
      const Key key = factors[i].keys[b];
      if (InsBlockOfKey(states, key) == nullptr) {
        return InvalidArgument(where + "key " + KeyToString(key) + " names no state block");
      }
      const int size = SymbolLetter(key) == 'q' ? 4 : 3;
      if (sizes[b] != size) {
        return InvalidArgument(where + "block " + KeyToString(key) + " has size " +
                               std::to_string(size) + ", the cost function expects " +
                               std::to_string(sizes[b]));
      }
      newest = std::max(newest, SymbolIndex(key));
    }
    out[newest].push_back(std::move(factors[i]));
  }
  return out;
}

Trajectory InsStatesTrajectory(const Walk& walk, const std::vector<InsState>& states,
                               const std::vector<std::optional<Eigen::Matrix3d>>& cov,
                               const InsGraphOptions& o, bool close_segments) {
  Trajectory out;
  if (states.empty()) return out;
  const std::vector<ImuSample>& imu = walk.imu;
  StrapdownOptions sd;
  sd.gravity_mps2 = o.front_end.gravity_mps2;
  sd.sampling = o.front_end.sampling;
  sd.max_dt_s = ImuGapThresholdS(imu);  // held across IMU gaps: the output interpolates there
  const double period = 1.0 / o.output_rate_hz;
  double next_tick = imu[states.front().imu_index].t_s;
  auto emit = [&](double t, const Eigen::Vector3d& p, double yaw,
                  const std::optional<Eigen::Matrix3d>& c) {
    TrajectoryPoint pt;
    pt.t_s = t;
    pt.position_m = p;
    pt.heading_rad = NormalizeAngle(yaw);
    pt.covariance = c;
    out.points.push_back(pt);
  };
  emit(states[0].t_s, states[0].position(), QuaternionYaw(states[0].attitude()), cov[0]);
  next_tick += period;
  for (size_t s = 0; s + 1 < states.size(); ++s) {
    const InsState& a = states[s];
    const InsState& b = states[s + 1];
    sd.gyro_bias_radps = a.gyro_bias();
    sd.acc_bias_mps2 = a.acc_bias();
    std::vector<NavState> fwd;
    NavState x = ToNavState(a);
    for (size_t k = a.imu_index + 1; k <= b.imu_index; ++k) {
      x = StrapdownStep(x, imu[k - 1], imu[k], sd);
      if (k < b.imu_index && imu[k].t_s + 1e-9 >= next_tick) {
        fwd.push_back(x);
        while (next_tick <= imu[k].t_s + 1e-9) next_tick += period;
      }
    }
    const double w = close_segments ? 1.0 : 0.0;
    const Eigen::Vector3d dp = w * (b.position() - x.p_n);
    const double dyaw = w * NormalizeAngle(QuaternionYaw(b.attitude()) - QuaternionYaw(x.q_nb));
    const double span = b.t_s - a.t_s;
    for (const NavState& f : fwd) {
      const double alpha = (f.t_s - a.t_s) / span;
      std::optional<Eigen::Matrix3d> c;
      if (!close_segments) {
        c = cov[s];
      } else if (cov[s] && cov[s + 1]) {
        c = Eigen::Matrix3d((1.0 - alpha) * *cov[s] + alpha * *cov[s + 1]);
      }
      emit(f.t_s, f.p_n + alpha * dp, QuaternionYaw(f.q_nb) + alpha * dyaw, c);
    }
    emit(b.t_s, b.position(), QuaternionYaw(b.attitude()), cov[s + 1]);
    while (next_tick <= b.t_s + 1e-9) next_tick += period;
  }
  return out;
}

Status InsGraphBatch::CheckApplicable(const Walk& walk) const {
  if (walk.meta.imu_placement != ImuPlacement::kFoot) {
    return FailedPrecondition("fg-ins-batch needs a foot-mounted IMU (imu_placement: foot)");
  }
  if (walk.imu.size() < 10) return FailedPrecondition("fg-ins-batch needs imu.csv");
  return Status::Ok();
}

namespace {

// One build of the batch graph: the states (valued as they are now) with the walk's factors in
// the order the factor makers give them (segment, radio, stance magnetic, then the user's), the
// walk-wide blocks as static states in the order first named; and each RSS factor's anchor id
// and index in the graph (for TestInsAnchors).
struct InsBatchGraph {
  std::unique_ptr<FactorGraph> graph;
  std::unique_ptr<InsKeyMap> keys;
  size_t num_radio = 0, num_magnetic = 0;
  std::vector<std::pair<int, size_t>> rss;
};

StatusOr<InsBatchGraph> BuildInsBatch(const InsGraphContext& context, std::vector<InsState>* states,
                                      InsSharedBlocks* radio,
                                      const std::vector<std::vector<GraphFactor>>& user) {
  InsBatchGraph out;
  const size_t last = states->size() - 1;
  WG_ASSIGN_OR_RETURN(std::vector<InsFactor> factors, InsSegmentFactors(context, states, 0, last));
  radio->bias_prior_added.clear();  // a new graph: priors again, bias values kept
  radio->path_loss_prior_added = false;
  radio->anchor_path_loss_prior_added.clear();
  radio->anchor_position_prior_added.clear();
  WG_ASSIGN_OR_RETURN(std::vector<InsFactor> radio_factors,
                      InsRadioFactors(context, states, 0, last, radio));
  std::vector<InsFactor> magnetic = InsStanceMagneticFactors(context, states, 0, last, radio);
  out.num_radio = radio_factors.size();
  out.num_magnetic = magnetic.size();
  for (InsFactor& f : radio_factors) factors.push_back(std::move(f));
  for (InsFactor& f : magnetic) factors.push_back(std::move(f));

  out.keys = std::make_unique<InsKeyMap>(*context.walk, context.options, radio);
  for (size_t i = 0; i < states->size(); ++i) out.keys->RegisterState(i, &(*states)[i]);
  std::vector<GraphState> shared;
  std::vector<GraphFactor> graph_factors;
  for (InsFactor& f : factors) {
    if (f.kind == InsFactorKind::kRss) out.rss.emplace_back(f.anchor_id, graph_factors.size());
    WG_ASSIGN_OR_RETURN(GraphFactor g, out.keys->ToGraphFactor(&f, &shared));
    graph_factors.push_back(std::move(g));
  }
  out.graph = std::make_unique<FactorGraph>();
  const auto manifold = std::make_shared<NavQuaternionManifold>();
  for (size_t i = 0; i < states->size(); ++i) {
    for (GraphState& st : InsStateBlocks(i, (*states)[i], manifold)) {
      WG_RETURN_IF_ERROR(out.graph->AddState(std::move(st)));
    }
  }
  for (GraphState& st : shared) WG_RETURN_IF_ERROR(out.graph->AddState(std::move(st)));
  for (GraphFactor& f : graph_factors) WG_RETURN_IF_ERROR(out.graph->AddFactor(std::move(f)));
  for (const auto& at : user) {
    for (const GraphFactor& f : at) WG_RETURN_IF_ERROR(out.graph->AddFactor(f));
  }
  return out;
}

// One batch solve of the foot-INS graph, relinearized while the biases move
// (max_relinearizations): each round builds the graph again at the new biases (the
// preintegrations are made at their first state's), and its figures.
struct InsBatchSolve {
  InsBatchGraph built;
  int iterations = 0, relinearizations = 0;
  double initial_cost = 0.0, final_cost = 0.0;
  bool converged = false;
};

// The largest change of a gyro and of an accelerometer bias from `before`.
std::pair<double, double> BiasChange(const std::vector<InsState>& before,
                                     const std::vector<InsState>& after) {
  double dg = 0.0, da = 0.0;
  for (size_t i = 0; i < after.size(); ++i) {
    for (int k = 0; k < 3; ++k) {
      dg = std::max(dg, std::fabs(after[i].bg[k] - before[i].bg[k]));
      da = std::max(da, std::fabs(after[i].ba[k] - before[i].ba[k]));
    }
  }
  return {dg, da};
}

StatusOr<InsBatchSolve> SolveInsBatch(const InsGraphContext& context, std::vector<InsState>* states,
                                      InsSharedBlocks* radio,
                                      const std::vector<std::vector<GraphFactor>>& user,
                                      const SolverOptions& solver) {
  const InsGraphOptions& o = context.options;
  InsBatchSolve out;
  for (int round = 0; round <= o.max_relinearizations; ++round) {
    WG_ASSIGN_OR_RETURN(out.built, BuildInsBatch(context, states, radio, user));
    const std::vector<InsState> linearization = *states;
    FactorGraph* graph = out.built.graph.get();
    StatusOr<SolveSummary> summary = SolveBatch(graph, solver);
    if (!summary.ok()) {
      return Status(summary.status().code(), "fg-ins-batch: " + summary.status().message());
    }
    WG_RETURN_IF_ERROR(out.built.keys->CopyValues([graph](Key k) { return graph->Value(k); }));
    if (round == 0) out.initial_cost = summary->initial_cost;
    out.final_cost = summary->final_cost;
    out.iterations += summary->iterations;
    out.converged = summary->termination == Termination::kConverged;
    const auto [dg, da] = BiasChange(linearization, *states);
    if (dg <= o.relinearize_gyro_bias_radps && da <= o.relinearize_acc_bias_mps2) break;
    if (round < o.max_relinearizations) ++out.relinearizations;
  }
  return out;
}

// (x, y, yaw) covariance of every state (graph.h MarginalCovariances: the banded chain solve)
// in the tangent space of NavQuaternionManifold, δθ_z the yaw. False (and `out` untouched) when
// it cannot be computed (rank deficiency).
bool InsPoseCovariances(FactorGraph* graph, size_t num_states,
                        std::vector<std::optional<Eigen::Matrix3d>>* out) {
  std::vector<std::vector<Key>> groups;
  groups.reserve(num_states);
  for (size_t i = 0; i < num_states; ++i) {
    groups.push_back({InsKey(i, InsBlock::kP), InsKey(i, InsBlock::kQ)});
  }
  StatusOr<std::vector<Eigen::MatrixXd>> cov = MarginalCovariances(graph, groups);
  if (!cov.ok()) return false;
  std::vector<std::optional<Eigen::Matrix3d>> pose(num_states);
  for (size_t i = 0; i < num_states; ++i) {
    const Eigen::MatrixXd& c = (*cov)[i];
    if (c.rows() != 6) return false;  // p or q held constant: no pose covariance
    const int index[3] = {0, 1, 5};   // x, y of p; δθ_z of q (the yaw)
    Eigen::MatrixXd c3(3, 3);
    for (int r = 0; r < 3; ++r) {
      for (int k = 0; k < 3; ++k) c3(r, k) = c(index[r], index[k]);
    }
    Symmetrize(&c3);
    pose[i] = Eigen::Matrix3d(c3);
  }
  *out = std::move(pose);
  return true;
}

// auto's choice after a global solve (InsGraphOptions::path_loss): do the anchors' mean
// residuals disagree with the one path loss?
std::optional<internal::AnchorOffsetTest> TestInsAnchors(const InsGraphOptions& o,
                                                         const InsSharedBlocks& radio,
                                                         const InsBatchGraph& built) {
  if (o.path_loss != PathLossMode::kAuto || !radio.estimate_path_loss ||
      radio.per_anchor_path_loss || !(o.path_loss_anchor_test_z > 0) || built.rss.empty()) {
    return std::nullopt;
  }
  std::vector<std::pair<int, double>> residuals;
  for (const auto& [anchor, index] : built.rss) {
    StatusOr<Eigen::VectorXd> r = built.graph->FactorResiduals(index);
    if (r.ok()) residuals.emplace_back(anchor, (*r)[0]);
  }
  return internal::TestAnchorOffsets(residuals, o.path_loss_anchor_test_z);
}

// The anchors that are states (not surveyed) at their solved positions, with their marginal
// covariance when the graph gives it.
void AddInsAnchorEstimates(const Walk& walk, const InsSharedBlocks& radio, FactorGraph* graph,
                           std::vector<AnchorEstimate>* out) {
  for (const auto& [id, p] : radio.anchor_position) {
    const int ai = walk.AnchorIndex(id);
    if (ai < 0) continue;
    AnchorEstimate e;
    e.id = id;
    e.position_m = Eigen::Vector2d(p[0], p[1]);
    e.readings = walk.AnchorReadings(id);
    if (graph != nullptr) {
      auto c = MarginalCovariances(graph, {{Symbol('p', static_cast<uint64_t>(ai))}});
      if (c.ok() && (*c)[0].rows() == 2)
        e.covariance = Eigen::Matrix2d(0.5 * ((*c)[0] + (*c)[0].transpose()));
    }
    out->push_back(e);
  }
}

// fg-ins-batch on a walk whose anchors all have a position (surveyed, uncertain, or unknown and
// placed: the last two states of the graph).
StatusOr<EstimateResult> SolveInsWalk(const Walk& walk, const InsGraphOptions& o) {
  WG_ASSIGN_OR_RETURN(ZuptInsSolution front, RunZuptIns(walk, o.front_end));
  WG_ASSIGN_OR_RETURN(std::vector<InsState> states, InitialInsStates(walk, front, o));
  if (o.initialization == InsInitialization::kWindow) {
    InsWindowOptions wo;
    wo.graph = o;
    wo.graph.compute_covariance = false;
    wo.lag_s = o.init_lag_s;
    wo.window_marginalize_batch_s = o.init_marginalize_batch_s;
    wo.window_initial_trust_region_radius = o.initial_trust_region_radius;
    WG_ASSIGN_OR_RETURN(std::vector<InsState> lagged, InsWindowLaggedStates(walk, wo));
    if (lagged.size() != states.size()) {
      return InternalError("fg-ins-batch: window initialization returned a different state count");
    }
    states = std::move(lagged);
  }
  InsGraphContext context;
  context.walk = &walk;
  context.imu_gap_s = ImuGapThresholdS(walk.imu);
  context.still = &front.stance.still;
  context.zupt = &front.zupt;
  context.scale_noise = &front.scale_noise;
  context.path = &front.states;
  context.options = o;
  const std::vector<double> magnetic_sigma = StanceMagneticSigmas(walk, front, o);
  context.stance_magnetic_sigma = &magnetic_sigma;
  WG_ASSIGN_OR_RETURN(const std::vector<std::vector<GraphFactor>> user,
                      InsUserFactors(context, &states));

  SolverOptions so;  // single-threaded SPARSE_NORMAL_CHOLESKY: the same output for the same input
  so.max_iterations = o.max_iterations;
  so.function_tolerance = o.function_tolerance;
  so.parameter_tolerance = o.parameter_tolerance;
  so.gradient_tolerance = o.gradient_tolerance;
  so.initial_trust_region_radius = o.initial_trust_region_radius;
  WG_RETURN_IF_ERROR(so.Validate());

  InsSharedBlocks radio;
  WG_ASSIGN_OR_RETURN(InsBatchSolve solve, SolveInsBatch(context, &states, &radio, user, so));
  const std::optional<internal::AnchorOffsetTest> test = TestInsAnchors(o, radio, solve.built);
  if (test && test->disagree) {  // per anchor, from the global solution
    context.options.path_loss = PathLossMode::kHierarchical;
    const int iterations = solve.iterations;
    WG_ASSIGN_OR_RETURN(solve, SolveInsBatch(context, &states, &radio, user, so));
    solve.iterations += iterations;
  }

  EstimateResult result;
  std::vector<std::optional<Eigen::Matrix3d>> state_cov(states.size());
  bool cov_ok = false;
  if (o.compute_covariance) {
    cov_ok = InsPoseCovariances(solve.built.graph.get(), states.size(), &state_cov);
  }
  result.trajectory = InsStatesTrajectory(walk, states, state_cov, o, /*close_segments=*/true);
  auto& d = result.diagnostics;
  d["num_states"] = static_cast<double>(states.size());
  AddFrontEndDiagnostics(front, &d);
  d["num_radio_factors"] = static_cast<double>(solve.built.num_radio);
  AddStanceMagneticDiagnostics(magnetic_sigma, solve.built.num_magnetic, &d);
  AddInsPathLossDiagnostics(walk, radio, &d);
  if (test) {
    d["path_loss_anchor_chi2"] = test->statistic;
    d["path_loss_anchor_chi2_critical"] = test->critical;
    d["path_loss_per_anchor"] = test->disagree ? 1.0 : 0.0;
  }
  d["ceres_iterations"] = solve.iterations;
  d["ceres_initial_cost"] = solve.initial_cost;
  d["ceres_final_cost"] = solve.final_cost;
  d["ceres_converged"] = solve.converged ? 1.0 : 0.0;
  d["relinearizations"] = solve.relinearizations;
  d["covariance_ok"] = cov_ok ? 1.0 : 0.0;
  AddInsAnchorEstimates(walk, radio, solve.built.graph.get(), &result.anchors);
  return result;
}

// fg-batch's grid search (anchor_search.h, its default options) for one anchor of `walk` over
// the path `first` (fg-ins-batch without the unknown anchors), with the radio model that solve
// estimated.
internal::AnchorSearchResult SearchInsAnchor(const Walk& walk, const Anchor& a,
                                             const EstimateResult& first, const InsGraphOptions& o,
                                             int* readings) {
  std::vector<Eigen::Vector2d> q;
  std::vector<double> v, dz;
  for (const RangeSample& r : walk.ranges) {
    if (r.anchor_id != a.id || !o.use_ranges) continue;
    const Eigen::Vector3d p = first.trajectory.PositionAt(r.t_s);
    q.push_back(p.head<2>());
    v.push_back(r.range_m);
    dz.push_back(p.z());
  }
  const bool range = !v.empty();
  for (const RssSample& r : walk.rss) {
    if (range || r.anchor_id != a.id || !o.use_rss) continue;
    const Eigen::Vector3d p = first.trajectory.PositionAt(r.t_s);
    q.push_back(p.head<2>());
    v.push_back(r.rss);
    dz.push_back(p.z());
  }
  *readings = static_cast<int>(v.size());
  // An unknown anchor's height: anchors.csv z_m (0 when empty).
  const double z = std::isfinite(a.position_m.z()) ? a.position_m.z() : 0.0;
  for (double& h : dz) h -= z;
  internal::AnchorSearchOptions so;
  so.range = range;
  so.dz_m = dz.empty() ? 0.0 : internal::Median(dz);
  const auto& fd = first.diagnostics;
  if (range) {
    so.sigma = walk.meta.radio.range_sigma_m;
    so.loss_scale = o.range_loss_scale;
    so.level_prior_sigma = o.estimate_range_bias ? o.range_bias_sigma_m : 0.0;
  } else {
    const PathLossParams& pl = walk.meta.radio.path_loss;
    so.sigma = pl.sigma_db;
    so.loss_scale = o.rss_loss_scale;
    so.sign = walk.meta.radio.units == RssUnits::kRfcode ? -1.0 : 1.0;
    so.d0_m = pl.d0_m;
    const bool estimated = fd.count("path_loss_A") > 0;
    so.eta = estimated ? fd.at("path_loss_eta") : pl.eta;
    so.level_prior = estimated ? fd.at("path_loss_A") : pl.A_dbm;
    so.level_prior_sigma = estimated ? o.A_spread_prior_db : 0.0;  // calibrated: held
  }
  return internal::SearchAnchor(q, v, so);
}

// As fg-batch (unknown_anchors.h): each solve from the front end, the search along the first
// solve's foot path.
StatusOr<EstimateResult> SolveInsWithUnknownAnchors(const Walk& walk, const InsGraphOptions& o) {
  internal::UnknownAnchorPass pass;
  pass.solve = [&](const Walk& w, const EstimateResult*) { return SolveInsWalk(w, o); };
  pass.place = [&](const Anchor& a, const EstimateResult& first) {
    internal::AnchorPlacement out;
    out.found = SearchInsAnchor(walk, a, first, o, &out.readings);
    return out;
  };
  return internal::SolveWithUnknownAnchors(walk, pass);
}

}  // namespace

StatusOr<EstimateResult> InsGraphBatch::Run(const Walk& walk) const {
  WG_RETURN_IF_ERROR(CheckApplicable(walk));
  if (walk.has_unknown_anchors()) return SolveInsWithUnknownAnchors(walk, options_);
  return SolveInsWalk(walk, options_);
}

namespace internal {

Status RegisterInsGraphBatch(EstimatorRegistry* registry) {
  return registry->Register(
      {"fg-ins-batch",
       "foot-INS factor graph: Forster preintegration between stance states, ZUPT, ZARU, bias "
       "random walks; one Ceres problem (foot IMU)",
       OptionsFactory<InsGraphBatch>(
           [](const YAML::Node& config) { return InsGraphOptionsFromYaml(config); }),
       /*estimates_unknown_anchors=*/true});
}

}  // namespace internal
}  // namespace walkgraph
