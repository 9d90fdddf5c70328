#include "walkgraph/smoothers/ins_window.h"

#include <algorithm>
#include <chrono>
#include <memory>
#include <optional>
#include <set>
#include <unordered_map>
#include <utility>
#include <vector>

#include <Eigen/Geometry>

#include "config/parsers.h"
#include "estimators/builtin.h"
#include "factors/nav_quaternion_manifold.h"
#include "smoothers/ins_graph_internal.h"
#include "walkgraph/angle.h"
#include "walkgraph/config.h"
#include "walkgraph/kalman.h"
#include "walkgraph/smoothers/fixed_lag_smoother.h"
#include "walkgraph/strides.h"

namespace walkgraph {

namespace {

// The keys of the states' and the walk-wide blocks: InsKeyMap (ins_graph_internal.h).
void SetBlock(InsState* s, InsBlock block, const std::vector<double>& v) {
  std::copy(v.begin(), v.begin() + InsBlockSize(block), InsBlockData(s, block));
}
bool IsPositionKey(Key key) { return InsBlockOfLetter(SymbolLetter(key)) == InsBlock::kP; }

const char* const kWindowKeys[] = {"lag_s",
                                   "window_update_s",
                                   "window_max_iterations",
                                   "window_output",
                                   "preintegration_bias",
                                   "window_marginalize_batch_s",
                                   "window_initial_trust_region_radius",
                                   "gap_hold_max_s",
                                   "gap_release_yaw_sigma_rad",
                                   "gap_max_iterations"};

// The front end's motion from state a to state b carried into the frame of `estimate_a` (the
// window's current estimate of a): see the top of ins_window.h.
InsState CarryForward(const InsState& front_a, const InsState& front_b,
                      const InsState& estimate_a) {
  InsState s = front_b;
  const double dpsi =
      NormalizeAngle(QuaternionYaw(estimate_a.attitude()) - QuaternionYaw(front_a.attitude()));
  const Eigen::Quaterniond rz(Eigen::AngleAxisd(dpsi, Eigen::Vector3d::UnitZ()));
  const Eigen::Vector3d p = estimate_a.position() + rz * (front_b.position() - front_a.position());
  const Eigen::Vector3d v = rz * front_b.velocity();
  const Eigen::Quaterniond q = (rz * front_b.attitude()).normalized();
  for (int k = 0; k < 3; ++k) {
    s.p[k] = p[k];
    s.v[k] = v[k];
  }
  s.q = {q.x(), q.y(), q.z(), q.w()};
  s.bg = estimate_a.bg;
  s.ba = estimate_a.ba;
  return s;
}

// Yaw σ of a state's attitude in the window (δθ_z of its tangent), when computable.
std::optional<double> YawSigma(FixedLagSmoother* smoother, Key q_key) {
  if (!smoother->Contains(q_key)) return std::nullopt;
  StatusOr<Eigen::MatrixXd> c = smoother->MarginalCovariance(q_key);
  if (!c.ok() || !((*c)(2, 2) >= 0.0)) return std::nullopt;
  return std::sqrt((*c)(2, 2));
}

}  // namespace

StatusOr<InsWindowOptions> InsWindowOptionsFromYaml(const YAML::Node& node,
                                                    const std::string& context,
                                                    WindowOutput default_output) {
  InsWindowOptions o;
  o.window_output = default_output;
  // The window's own keys are read here, the rest by InsGraphOptionsFromYaml.
  YAML::Node window(YAML::NodeType::Map);
  // A clone, never `rest = node; rest = Clone(node)`: yaml-cpp's assignment to a node that
  // aliases the caller's would rebind the caller's node to the clone, and the window keys
  // removed below would vanish from it (compare --config creates each estimator twice).
  YAML::Node rest = node.IsMap() ? YAML::Clone(node) : node;
  if (node.IsMap()) {
    for (const char* key : kWindowKeys) {
      if (node[key]) {
        window[key] = node[key];
        rest.remove(key);
      }
    }
  }
  ConfigReader r(window, context);
  r.Read("lag_s", &o.lag_s, "span of the fixed-lag window");
  r.Read("window_update_s", &o.window_update_s,
         "0: one update per state; > 0: states gathered per this period");
  r.Read("window_max_iterations", &o.window_max_iterations, "most LM iterations per window update");
  r.ReadEnum("window_output", &o.window_output, WindowOutputNames(),
             "each state's estimate when it leaves the window, or right after added");
  r.ReadEnum("preintegration_bias", &o.preintegration_bias, PreintegrationBiasNames(),
             "bias point of each IMU preintegration: the front end's or the window's");
  r.Read("window_marginalize_batch_s", &o.window_marginalize_batch_s,
         "states leave the window in batches of this span");
  r.Read("window_initial_trust_region_radius", &o.window_initial_trust_region_radius,
         "LM starting trust-region radius per window solve");
  r.Read("gap_hold_max_s", &o.gap_hold_max_s,
         "hold the window open this long at most after an IMU gap; 0 no hold");
  r.Read("gap_release_yaw_sigma_rad", &o.gap_release_yaw_sigma_rad,
         "release the hold at this yaw sigma when the pre-gap one is unknown");
  r.Read("gap_max_iterations", &o.gap_max_iterations,
         "most LM iterations per window update while held open after an IMU gap");
  WG_RETURN_IF_ERROR(r.Finish());
  StatusOr<InsGraphOptions> graph = InsGraphOptionsFromYaml(rest, o.graph);
  if (!graph.ok()) return InvalidArgument(context + ": " + graph.status().message());
  o.graph = *graph;
  WG_RETURN_IF_ERROR(o.Validate(context));
  return o;
}

Status InsWindowOptions::Validate(const std::string& context) const {
  const InsWindowOptions& o = *this;
  if (!(o.lag_s > 0) || !(o.window_update_s >= 0) || o.window_max_iterations < 1 ||
      !(o.window_marginalize_batch_s >= 0) || !(o.window_initial_trust_region_radius > 0) ||
      !(o.gap_hold_max_s >= 0) || !(o.gap_release_yaw_sigma_rad > 0) || o.gap_max_iterations < 1) {
    return InvalidArgument(context +
                           ": need lag_s > 0, window_update_s >= 0, window_max_iterations >= 1, "
                           "window_marginalize_batch_s >= 0, "
                           "window_initial_trust_region_radius > 0, gap_hold_max_s >= 0, "
                           "gap_release_yaw_sigma_rad > 0, gap_max_iterations >= 1");
  }
  WG_RETURN_IF_ERROR(
      CheckEnumOption(WindowOutputNames(), o.window_output, "window_output", context));
  WG_RETURN_IF_ERROR(CheckEnumOption(PreintegrationBiasNames(), o.preintegration_bias,
                                     "preintegration_bias", context));
  const Status graph = o.graph.Validate();
  if (!graph.ok()) return InvalidArgument(context + ": " + graph.message());
  return Status::Ok();
}

Status InsGraphWindow::CheckApplicable(const Walk& walk) const {
  const std::string id =
      options_.window_output == WindowOutput::kOnline ? "fg-ins-window-online" : "fg-ins-window";
  if (walk.meta.imu_placement != ImuPlacement::kFoot) {
    return FailedPrecondition(id + " needs a foot-mounted IMU (imu_placement: foot)");
  }
  if (walk.imu.size() < 10) return FailedPrecondition(id + " needs imu.csv");
  return Status::Ok();
}

namespace {

// The window pass; `lagged_out` (optional) receives every state's lagged estimate.
// One fg-ins-window run: states fed in time order, one update per node (or per
// window_update_s), the window held open across IMU gaps, lagged or online output.
class InsWindowRun {
 public:
  InsWindowRun(const Walk& walk, const InsWindowOptions& options)
      : walk_(walk),
        o_(options),
        g_(options.graph),
        online_(options.window_output == WindowOutput::kOnline),
        smoother_(SmootherOptions(options)) {}

  StatusOr<EstimateResult> Run(std::vector<InsState>* lagged_out);

 private:
  static FixedLagSmoother::Options SmootherOptions(const InsWindowOptions& o) {
    FixedLagSmoother::Options so;
    so.lag_s = o.lag_s;
    so.solver.max_iterations = o.window_max_iterations;
    so.solver.function_tolerance = o.graph.function_tolerance;
    so.solver.parameter_tolerance = o.graph.parameter_tolerance;
    so.marginalize_batch_s = o.window_marginalize_batch_s;
    so.solver.initial_trust_region_radius = o.window_initial_trust_region_radius;
    so.held_max_iterations = o.gap_max_iterations;
    return so;
  }
  Status Start();
  StatusOr<InsState> EstimateOf(size_t i);
  void StoreCovariances(const std::vector<size_t>& states);
  Status ToSmoother(std::vector<InsFactor>* factors);
  void HoldAcrossGap(size_t i);
  Status AddState(size_t i);
  Status Update(size_t i);
  EstimateResult Finish();

  const Walk& walk_;
  const InsWindowOptions& o_;
  const InsGraphOptions& g_;
  const bool online_;
  FixedLagSmoother smoother_;
  const std::shared_ptr<NavQuaternionManifold> manifold_ =
      std::make_shared<NavQuaternionManifold>();
  std::chrono::steady_clock::time_point run_start_ = std::chrono::steady_clock::now();
  ZuptInsSolution front_;
  // What the factor makers read: times, IMU indices and the front end's values (with
  // preintegration_bias: estimate, each state's biases become the window's estimate before the
  // next state's preintegration is built).
  std::vector<InsState> build_, front_states_, lagged_, current_;
  size_t n_ = 0;
  InsGraphContext context_;
  InsSharedBlocks radio_;
  std::unique_ptr<InsKeyMap> keys_;     // of build_'s and radio_'s blocks
  std::vector<double> magnetic_sigma_;  // StanceMagneticSigmas
  std::vector<std::optional<Eigen::Matrix3d>> cov_;
  std::vector<GraphState> new_states_;
  std::vector<GraphFactor> new_factors_;
  std::vector<std::vector<GraphFactor>> user_;  // InsGraphOptions::user_factors by newest state
  std::vector<double> latency_;
  std::vector<size_t> pending_;
  size_t num_radio_ = 0, num_magnetic_ = 0, max_keys_ = 0;
  int iterations_ = 0, solves_ = 0, unconverged_ = 0;
  double final_cost_ = 0.0;
  InsState last_;  // the newest state's estimate (its initial value until solved)
  double last_update_t_ = 0.0;
  // IMU gaps: the window is held open across them (InsWindowOptions::gap_hold_max_s).
  std::vector<ImuGap> gaps_;
  size_t next_gap_ = 0;
  std::optional<double> yaw_sigma_before_gap_;
  double hold_until_s_ = 0.0, held_s_ = 0.0;
  int holds_ = 0;
};

Status InsWindowRun::Start() {
  WG_ASSIGN_OR_RETURN(front_, RunZuptIns(walk_, g_.front_end));
  WG_ASSIGN_OR_RETURN(build_, InitialInsStates(walk_, front_, g_));
  front_states_ = build_;
  n_ = build_.size();
  context_.walk = &walk_;
  context_.imu_gap_s = ImuGapThresholdS(walk_.imu);
  context_.still = &front_.stance.still;
  context_.zupt = &front_.zupt;
  context_.scale_noise = &front_.scale_noise;
  context_.path = &front_.states;
  context_.options = g_;
  magnetic_sigma_ = StanceMagneticSigmas(walk_, front_, g_);
  context_.stance_magnetic_sigma = &magnetic_sigma_;
  keys_ = std::make_unique<InsKeyMap>(walk_, g_, &radio_);
  for (size_t i = 0; i < n_; ++i) keys_->RegisterState(i, &build_[i]);
  WG_ASSIGN_OR_RETURN(user_, InsUserFactors(context_, &build_));
  lagged_ = current_ = build_;
  cov_.assign(n_, std::nullopt);
  latency_.reserve(n_);
  last_ = build_[0];
  last_update_t_ = build_[0].t_s;
  gaps_ = walk_.ImuGaps();
  smoother_.set_before_marginalize([this](const std::vector<Key>& keys) {
    if (online_) return;
    std::vector<size_t> states;
    for (Key k : keys) {
      if (IsPositionKey(k)) states.push_back(SymbolIndex(k));
    }
    StoreCovariances(states);
  });
  smoother_.set_on_marginalize([this](Key key, double, const std::vector<double>& v) {
    const std::optional<InsBlock> block = InsBlockOfLetter(SymbolLetter(key));
    if (block) SetBlock(&lagged_[SymbolIndex(key)], *block, v);
  });
  return Status::Ok();
}

StatusOr<InsState> InsWindowRun::EstimateOf(size_t i) {
  InsState s = build_[i];
  for (int b = 0; b < kInsBlocksPerState; ++b) {
    const InsBlock block = static_cast<InsBlock>(b);
    WG_ASSIGN_OR_RETURN(std::vector<double> v, smoother_.Estimate(InsKey(i, block)));
    SetBlock(&s, block, v);
  }
  return s;
}

// (x, y, yaw) covariances of states in the current window: tangent (δp, δθ), δθ_z the yaw.
void InsWindowRun::StoreCovariances(const std::vector<size_t>& states) {
  if (!g_.compute_covariance || states.empty()) return;
  std::vector<std::vector<Key>> groups;
  for (size_t i : states) groups.push_back({InsKey(i, InsBlock::kP), InsKey(i, InsBlock::kQ)});
  StatusOr<std::vector<Eigen::MatrixXd>> c = smoother_.MarginalCovariances(groups);
  if (!c.ok()) return;  // rank-deficient window: these states go without covariance
  const int index[3] = {0, 1, 5};
  for (size_t m = 0; m < states.size(); ++m) {
    Eigen::MatrixXd xy_yaw(3, 3);
    for (int r = 0; r < 3; ++r) {
      for (int s = 0; s < 3; ++s) xy_yaw(r, s) = (*c)[m](index[r], index[s]);
    }
    Symmetrize(&xy_yaw);
    cov_[states[m]] = Eigen::Matrix3d(xy_yaw);
  }
}

Status InsWindowRun::ToSmoother(std::vector<InsFactor>* factors) {
  for (InsFactor& f : *factors) {
    WG_ASSIGN_OR_RETURN(GraphFactor sf, keys_->ToGraphFactor(&f, &new_states_));
    new_factors_.push_back(std::move(sf));
  }
  factors->clear();
  return Status::Ok();
}

// Before state i: a gap between i − 1 and i holds the window open from state i − 1 on.
void InsWindowRun::HoldAcrossGap(size_t i) {
  bool bridged = false;
  for (; next_gap_ < gaps_.size() && gaps_[next_gap_].t_begin_s < build_[i].t_s; ++next_gap_) {
    bridged = bridged || (i > 0 && gaps_[next_gap_].t_begin_s >= build_[i - 1].t_s);
  }
  if (!bridged || !(o_.gap_hold_max_s > 0)) return;
  if (!smoother_.holding()) {
    yaw_sigma_before_gap_ = YawSigma(&smoother_, InsKey(i - 1, InsBlock::kQ));
    smoother_.HoldFrom(build_[i - 1].t_s);
    ++holds_;
  }
  hold_until_s_ = build_[i].t_s + o_.gap_hold_max_s;
}

// State i's blocks (from the front end's motion carried onto the newest estimate) and factors.
Status InsWindowRun::AddState(size_t i) {
  InsState init = build_[i];
  if (i > 0) {
    init = CarryForward(front_states_[i - 1], front_states_[i], last_);
    if (o_.preintegration_bias == PreintegrationBias::kEstimate) {
      build_[i - 1].bg = last_.bg;
      build_[i - 1].ba = last_.ba;
    }
  }
  for (GraphState& st : InsStateBlocks(i, init, manifold_)) {
    st.t_s = build_[i].t_s;
    new_states_.push_back(std::move(st));
  }
  // State 0: the gauge and its unary factors; state i > 0: the segment i−1 → i alone
  // (InsSegmentFactors(·, 0, ·) would return the gauge again). The readings at t_0 come with
  // those of (t_0, t_1] (InsRadioFactors with k = 0 takes both), so none is added twice.
  std::vector<InsFactor> segment, readings;
  if (i == 0) {
    WG_ASSIGN_OR_RETURN(segment, InsSegmentFactors(context_, &build_, 0, 0));
  } else {
    WG_ASSIGN_OR_RETURN(segment, InsBetweenFactors(context_, &build_[i - 1], &build_[i]));
    for (InsFactor& f : InsStateFactors(context_, &build_[i])) segment.push_back(std::move(f));
  }
  if (i > 0 || n_ == 1) {
    WG_ASSIGN_OR_RETURN(
        readings, InsRadioFactors(context_, &build_, i == 0 ? 0 : i - 1, i == 0 ? 0 : 1, &radio_));
  }
  num_radio_ += readings.size();
  std::vector<InsFactor> magnetic =
      InsStanceMagneticFactors(context_, &build_, i == 0 ? 0 : i - 1, i == 0 ? 0 : 1, &radio_);
  num_magnetic_ += magnetic.size();
  WG_RETURN_IF_ERROR(ToSmoother(&segment));
  WG_RETURN_IF_ERROR(ToSmoother(&readings));
  WG_RETURN_IF_ERROR(ToSmoother(&magnetic));
  for (const GraphFactor& f : user_[i]) new_factors_.push_back(f);  // keys as the window's
  last_ = init;
  pending_.push_back(i);
  return Status::Ok();
}

// One smoother update with what is pending, ending at state i.
Status InsWindowRun::Update(size_t i) {
  const auto start = std::chrono::steady_clock::now();
  WG_ASSIGN_OR_RETURN(FixedLagSmoother::UpdateResult u,
                      smoother_.Update(std::move(new_states_), std::move(new_factors_)));
  new_states_.clear();
  new_factors_.clear();
  iterations_ += u.ceres_iterations;
  solves_ += u.solved ? 1 : 0;
  if (u.solved) final_cost_ = u.final_cost;
  unconverged_ += u.converged ? 0 : 1;
  max_keys_ = std::max(max_keys_, smoother_.WindowKeys().size());
  WG_ASSIGN_OR_RETURN(last_, EstimateOf(i));
  if (smoother_.holding()) {
    const std::optional<double> yaw_sigma = YawSigma(&smoother_, InsKey(i, InsBlock::kQ));
    const double release = yaw_sigma_before_gap_.value_or(o_.gap_release_yaw_sigma_rad);
    if (build_[i].t_s >= hold_until_s_ || (yaw_sigma && *yaw_sigma <= release)) {
      held_s_ = std::max(held_s_, build_[i].t_s - (hold_until_s_ - o_.gap_hold_max_s));
      smoother_.Release();
    }
  }
  if (online_) {
    std::vector<size_t> in_window;
    for (size_t j : pending_) {
      if (!smoother_.Contains(InsKey(j, InsBlock::kP))) {  // left already (window_update_s > lag_s)
        current_[j] = lagged_[j];
        continue;
      }
      WG_ASSIGN_OR_RETURN(current_[j], EstimateOf(j));
      in_window.push_back(j);
    }
    StoreCovariances(in_window);
  }
  latency_.push_back(
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
  pending_.clear();
  return Status::Ok();
}

EstimateResult InsWindowRun::Finish() {
  if (!online_) {
    // The states still in the window at the end: their final (smoothed) estimates.
    std::vector<size_t> states;
    for (Key key : smoother_.WindowKeys()) {
      if (IsPositionKey(key)) states.push_back(SymbolIndex(key));
    }
    StoreCovariances(states);
    smoother_.Flush();
  }
  EstimateResult result;
  result.trajectory = InsStatesTrajectory(walk_, online_ ? current_ : lagged_, cov_, g_, !online_);
  const size_t missing = static_cast<size_t>(
      std::count_if(cov_.begin(), cov_.end(), [](const auto& c) { return !c.has_value(); }));
  auto& d = result.diagnostics;
  d["num_states"] = static_cast<double>(n_);
  AddFrontEndDiagnostics(front_, &d);
  d["num_radio_factors"] = static_cast<double>(num_radio_);
  AddStanceMagneticDiagnostics(magnetic_sigma_, num_magnetic_, &d);
  d["ceres_iterations"] = iterations_;
  d["window_solves"] = solves_;
  d["window_unconverged_solves"] = unconverged_;
  d["ceres_final_cost"] = final_cost_;  // of the last solve
  d["window_max_keys"] = static_cast<double>(max_keys_);
  d["window_max_states"] = static_cast<double>(max_keys_ / kInsBlocksPerState);
  d["window_gap_holds"] = holds_;
  d["window_gap_hold_max_s"] = held_s_;  // longest time from a gap to its release
  d["states_without_covariance"] = g_.compute_covariance ? static_cast<double>(missing) : 0.0;
  d["covariance_ok"] = g_.compute_covariance && missing == 0 ? 1.0 : 0.0;
  if (radio_.estimate_path_loss) {  // the window's last estimates of the static blocks
    auto v = smoother_.Estimate(Symbol(radio_.per_anchor_path_loss ? 'm' : 'l', 0));
    if (v.ok() && v->size() == 2) radio_.path_loss = {(*v)[0], (*v)[1]};
    for (auto& [id, pl] : radio_.anchor_path_loss) {
      auto va = smoother_.Estimate(Symbol('l', static_cast<uint64_t>(walk_.AnchorIndex(id))));
      if (va.ok() && va->size() == 2) pl = {(*va)[0], (*va)[1]};
    }
  }
  AddInsPathLossDiagnostics(walk_, radio_, &d);
  AddUpdateLatencyTimings(latency_, &result.timings);
  const double run_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - run_start_).count();
  const double minutes = (walk_.imu.back().t_s - walk_.imu.front().t_s) / 60.0;
  result.timings["run_s"] = run_s;
  result.timings["run_s_per_walk_minute"] = minutes > 0 ? run_s / minutes : 0.0;
  return result;
}

StatusOr<EstimateResult> InsWindowRun::Run(std::vector<InsState>* lagged_out) {
  WG_RETURN_IF_ERROR(Start());
  for (size_t i = 0; i < n_; ++i) {
    HoldAcrossGap(i);
    WG_RETURN_IF_ERROR(AddState(i));
    if (i + 1 < n_ && build_[i].t_s - last_update_t_ < o_.window_update_s) continue;
    last_update_t_ = build_[i].t_s;
    WG_RETURN_IF_ERROR(Update(i));
  }
  EstimateResult result = Finish();
  if (lagged_out) *lagged_out = std::move(lagged_);
  return result;
}

StatusOr<EstimateResult> RunInsWindow(const Walk& walk, const InsWindowOptions& options,
                                      std::vector<InsState>* lagged_out) {
  WG_RETURN_IF_ERROR(options.Validate());
  return InsWindowRun(walk, options).Run(lagged_out);
}

}  // namespace

StatusOr<EstimateResult> InsGraphWindow::Run(const Walk& walk) const {
  WG_RETURN_IF_ERROR(CheckApplicable(walk));
  return RunInsWindow(walk, options_, nullptr);
}

StatusOr<std::vector<InsState>> InsWindowLaggedStates(const Walk& walk,
                                                      const InsWindowOptions& options) {
  InsWindowOptions o = options;
  o.window_output = WindowOutput::kLagged;
  WG_RETURN_IF_ERROR(InsGraphWindow(o).CheckApplicable(walk));
  std::vector<InsState> lagged;
  WG_RETURN_IF_ERROR(RunInsWindow(walk, o, &lagged).status());
  return lagged;
}

namespace internal {

Status RegisterInsGraphWindow(EstimatorRegistry* registry) {
  auto parse = [](const char* id, WindowOutput output) {
    return [id, output](const YAML::Node& config) {
      return InsWindowOptionsFromYaml(config, id, output);
    };
  };
  WG_RETURN_IF_ERROR(registry->Register(
      {"fg-ins-window",
       "foot-INS factor graph as a fixed-lag smoother (10 s lag, marginalization prior): lagged "
       "estimates (foot IMU)",
       OptionsFactory<InsGraphWindow>(parse("fg-ins-window", WindowOutput::kLagged))}));
  return registry->Register(
      {"fg-ins-window-online",
       "fg-ins-window's online output: each state right after its own update",
       OptionsFactory<InsGraphWindow>(parse("fg-ins-window-online", WindowOutput::kOnline))});
}

}  // namespace internal
}  // namespace walkgraph
