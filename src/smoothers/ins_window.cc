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

#include "estimators/builtin.h"
#include "factors/nav_quaternion_manifold.h"
#include "walkgraph/angle.h"
#include "walkgraph/config.h"
#include "walkgraph/filters/kalman.h"
#include "walkgraph/smoothers/fixed_lag_smoother.h"
#include "walkgraph/strides.h"

namespace walkgraph {

namespace {

// State i's blocks have keys 5i + block; the static states negative keys.
constexpr int kBlocksPerState = 5;
enum InsBlock { kP = 0, kV = 1, kQ = 2, kBg = 3, kBa = 4 };
constexpr StateKey kPathLossKey = -1;
StateKey Key(size_t i, int block) { return kBlocksPerState * static_cast<StateKey>(i) + block; }
StateKey RangeBiasKey(int anchor_index) { return -2 - static_cast<StateKey>(anchor_index); }

double* BlockOf(InsState* s, int block) {
  switch (block) {
    case kP:
      return s->p.data();
    case kV:
      return s->v.data();
    case kQ:
      return s->q.data();
    case kBg:
      return s->bg.data();
    default:
      return s->ba.data();
  }
}
int BlockSize(int block) { return block == kQ ? 4 : 3; }

void SetBlock(InsState* s, int block, const std::vector<double>& v) {
  std::copy(v.begin(), v.begin() + BlockSize(block), BlockOf(s, block));
}

const char* const kWindowKeys[] = {"lag_s",
                                   "window_update_s",
                                   "window_max_iterations",
                                   "window_output",
                                   "preintegration_bias",
                                   "window_marginalize_batch_s",
                                   "window_initial_trust_region_radius",
                                   "gap_hold_max_s",
                                   "gap_release_yaw_sigma_rad"};

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
std::optional<double> YawSigma(FixedLagSmoother* smoother, StateKey q_key) {
  if (!smoother->Contains(q_key)) return std::nullopt;
  StatusOr<Eigen::MatrixXd> c = smoother->MarginalCovariance(q_key);
  if (!c.ok() || !((*c)(2, 2) >= 0.0)) return std::nullopt;
  return std::sqrt((*c)(2, 2));
}

}  // namespace

StatusOr<InsWindowOptions> InsWindowOptions::FromYaml(const YAML::Node& node,
                                                      const std::string& context,
                                                      const std::string& default_output) {
  InsWindowOptions o;
  o.window_output = default_output;
  // The window's own keys are read here, the rest by InsGraphOptions::FromYaml.
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
  r.Read("lag_s", &o.lag_s);
  r.Read("window_update_s", &o.window_update_s);
  r.Read("window_max_iterations", &o.window_max_iterations);
  r.Read("window_output", &o.window_output);
  r.Read("preintegration_bias", &o.preintegration_bias);
  r.Read("window_marginalize_batch_s", &o.window_marginalize_batch_s);
  r.Read("window_initial_trust_region_radius", &o.window_initial_trust_region_radius);
  r.Read("gap_hold_max_s", &o.gap_hold_max_s);
  r.Read("gap_release_yaw_sigma_rad", &o.gap_release_yaw_sigma_rad);
  WG_RETURN_IF_ERROR(r.Finish());
  StatusOr<InsGraphOptions> graph = InsGraphOptions::FromYaml(rest);
  if (!graph.ok()) return InvalidArgument(context + ": " + graph.status().message());
  o.graph = *graph;
  if (!(o.lag_s > 0) || !(o.window_update_s >= 0) || o.window_max_iterations < 1 ||
      !(o.window_marginalize_batch_s >= 0) || !(o.window_initial_trust_region_radius > 0) ||
      !(o.gap_hold_max_s >= 0) || !(o.gap_release_yaw_sigma_rad > 0)) {
    return InvalidArgument(context +
                           ": need lag_s > 0, window_update_s >= 0, window_max_iterations >= 1, "
                           "window_marginalize_batch_s >= 0, "
                           "window_initial_trust_region_radius > 0, gap_hold_max_s >= 0, "
                           "gap_release_yaw_sigma_rad > 0");
  }
  if (o.window_output != "lagged" && o.window_output != "online") {
    return InvalidArgument(context + ": window_output must be lagged|online");
  }
  if (o.preintegration_bias != "front-end" && o.preintegration_bias != "estimate") {
    return InvalidArgument(context + ": preintegration_bias must be front-end|estimate");
  }
  return o;
}

Status InsGraphWindow::CheckApplicable(const Walk& walk) const {
  const std::string id =
      options_.window_output == "online" ? "fg-ins-window-online" : "fg-ins-window";
  if (walk.meta.imu_placement != ImuPlacement::kFoot) {
    return FailedPrecondition(id + " needs a foot-mounted IMU (imu_placement: foot)");
  }
  if (walk.imu.size() < 10) return FailedPrecondition(id + " needs imu.csv");
  return Status::Ok();
}

namespace {

// The window pass; `lagged_out` (optional) receives every state's lagged estimate.
StatusOr<EstimateResult> RunInsWindow(const Walk& walk, const InsWindowOptions& options_,
                                      std::vector<InsState>* lagged_out) {
  using Clock = std::chrono::steady_clock;
  const Clock::time_point run_start = Clock::now();
  const InsGraphOptions& g = options_.graph;
  const bool online = options_.window_output == "online";
  const bool bias_from_estimate = options_.preintegration_bias == "estimate";
  WG_ASSIGN_OR_RETURN(ZuptInsSolution front, RunZuptIns(walk, g.front_end));
  // What the factor makers read: times, IMU indices and the front end's values (with
  // preintegration_bias: estimate, each state's biases become the window's estimate before the
  // next state's preintegration is built).
  WG_ASSIGN_OR_RETURN(std::vector<InsState> build, InitialInsStates(walk, front, g));
  const std::vector<InsState> front_states = build;
  const size_t n = build.size();
  InsGraphContext context;
  context.walk = &walk;
  context.imu_gap_s = ImuGapThresholdS(walk.imu);
  context.still = &front.stance.still;
  context.path = &front.states;
  context.options = g;

  FixedLagSmoother::Options so;
  so.lag_s = options_.lag_s;
  so.solver.max_iterations = options_.window_max_iterations;
  so.solver.function_tolerance = g.function_tolerance;
  so.solver.parameter_tolerance = g.parameter_tolerance;
  so.marginalize_batch_s = options_.window_marginalize_batch_s;
  so.solver.initial_trust_region_radius = options_.window_initial_trust_region_radius;
  FixedLagSmoother smoother(so);
  const auto manifold = std::make_shared<NavQuaternionManifold>();

  std::unordered_map<const double*, StateKey> key_of;
  for (size_t i = 0; i < n; ++i) {
    for (int b = 0; b < kBlocksPerState; ++b) key_of[BlockOf(&build[i], b)] = Key(i, b);
  }
  InsRadioBlocks radio;
  key_of[radio.path_loss.data()] = kPathLossKey;
  std::set<StateKey> statics_added;

  std::vector<InsState> lagged = build, current = build;
  std::vector<std::optional<Eigen::Matrix3d>> cov(n);
  auto estimate_of = [&](size_t i) -> StatusOr<InsState> {
    InsState s = build[i];
    for (int b = 0; b < kBlocksPerState; ++b) {
      WG_ASSIGN_OR_RETURN(std::vector<double> v, smoother.Estimate(Key(i, b)));
      SetBlock(&s, b, v);
    }
    return s;
  };
  // (x, y, yaw) covariances of states in the current window: tangent (δp, δθ), δθ_z the yaw.
  auto store_covariances = [&](const std::vector<size_t>& states) {
    if (!g.compute_covariance || states.empty()) return;
    std::vector<std::vector<StateKey>> groups;
    for (size_t i : states) groups.push_back({Key(i, kP), Key(i, kQ)});
    StatusOr<std::vector<Eigen::MatrixXd>> c = smoother.MarginalCovariances(groups);
    if (!c.ok()) return;  // rank-deficient window: these states go without covariance
    const int index[3] = {0, 1, 5};
    for (size_t m = 0; m < states.size(); ++m) {
      Eigen::MatrixXd xy_yaw(3, 3);
      for (int r = 0; r < 3; ++r) {
        for (int s = 0; s < 3; ++s) xy_yaw(r, s) = (*c)[m](index[r], index[s]);
      }
      Symmetrize(&xy_yaw);
      cov[states[m]] = Eigen::Matrix3d(xy_yaw);
    }
  };
  smoother.set_before_marginalize([&](const std::vector<StateKey>& keys) {
    if (online) return;
    std::vector<size_t> states;
    for (StateKey k : keys) {
      if (k >= 0 && k % kBlocksPerState == kP) states.push_back(k / kBlocksPerState);
    }
    store_covariances(states);
  });
  smoother.set_on_marginalize([&](StateKey key, double, const std::vector<double>& v) {
    if (key >= 0) SetBlock(&lagged[key / kBlocksPerState], key % kBlocksPerState, v);
  });

  std::vector<SmootherState> new_states;
  std::vector<SmootherFactor> new_factors;
  // Factors by key; a block met for the first time that is not a state's is a static state
  // (the path loss or an anchor's range bias), added to the same update.
  auto to_smoother = [&](std::vector<InsFactor>* factors) -> Status {
    for (InsFactor& f : *factors) {
      SmootherFactor sf;
      for (double* block : f.blocks) {
        auto it = key_of.find(block);
        if (it == key_of.end()) {
          for (auto& [id, bias] : radio.range_bias_m) {
            if (&bias != block) continue;
            const int ai = walk.AnchorIndex(id);
            if (ai < 0) return InternalError("fg-ins-window: range bias of an unknown anchor");
            it = key_of.emplace(block, RangeBiasKey(ai)).first;
            SmootherState st;
            st.key = it->second;
            st.value = std::vector<double>(1, bias);
            st.constant = !g.estimate_range_bias;
            new_states.push_back(std::move(st));
            break;
          }
          if (it == key_of.end()) return InternalError("fg-ins-window: factor on an unknown block");
        }
        if (it->second == kPathLossKey && statics_added.insert(kPathLossKey).second) {
          SmootherState st;
          st.key = kPathLossKey;
          st.value = std::vector<double>(radio.path_loss.begin(), radio.path_loss.end());
          st.constant = !radio.estimate_path_loss;  // as in fg-ins-batch
          new_states.push_back(std::move(st));
        }
        sf.keys.push_back(it->second);
      }
      sf.cost = std::move(f.cost);
      sf.loss = std::shared_ptr<const ceres::LossFunction>(f.loss.release());
      new_factors.push_back(std::move(sf));
    }
    factors->clear();
    return Status::Ok();
  };

  std::vector<double> latency;
  latency.reserve(n);
  std::vector<size_t> pending;
  size_t num_radio = 0, max_keys = 0;
  int iterations = 0, solves = 0, unconverged = 0;
  double final_cost = 0.0;
  InsState last = build[0];  // the newest state's estimate (its initial value until solved)
  double last_update_t = build[0].t_s;
  // IMU gaps: the window is held open across them (InsWindowOptions::gap_hold_max_s).
  const std::vector<ImuGap> gaps = walk.ImuGaps();
  size_t next_gap = 0;
  std::optional<double> yaw_sigma_before_gap;
  double hold_until_s = 0.0, held_s = 0.0;
  int holds = 0;
  for (size_t i = 0; i < n; ++i) {
    InsState init = build[i];
    bool bridged = false;
    for (; next_gap < gaps.size() && gaps[next_gap].t_begin_s < build[i].t_s; ++next_gap) {
      bridged = bridged || (i > 0 && gaps[next_gap].t_begin_s >= build[i - 1].t_s);
    }
    if (bridged && options_.gap_hold_max_s > 0) {
      if (!smoother.holding()) {
        yaw_sigma_before_gap = YawSigma(&smoother, Key(i - 1, kQ));
        smoother.HoldFrom(build[i - 1].t_s);
        ++holds;
      }
      hold_until_s = build[i].t_s + options_.gap_hold_max_s;
    }
    if (i > 0) {
      init = CarryForward(front_states[i - 1], front_states[i], last);
      if (bias_from_estimate) {
        build[i - 1].bg = last.bg;
        build[i - 1].ba = last.ba;
      }
    }
    for (int b = 0; b < kBlocksPerState; ++b) {
      SmootherState st;
      st.key = Key(i, b);
      st.t_s = build[i].t_s;
      st.value.resize(static_cast<size_t>(BlockSize(b)));
      std::copy_n(BlockOf(&init, b), BlockSize(b), st.value.begin());
      if (b == kQ) st.manifold = manifold;
      new_states.push_back(std::move(st));
    }
    // State 0: the gauge and its unary factors; state i > 0: the segment i−1 → i alone
    // (InsSegmentFactors(·, 0, ·) would return the gauge again). The readings at t_0 come with
    // those of (t_0, t_1] (InsRadioFactors with k = 0 takes both), so none is added twice.
    std::vector<InsFactor> segment, readings;
    if (i == 0) {
      WG_ASSIGN_OR_RETURN(segment, InsSegmentFactors(context, &build, 0, 0));
    } else {
      WG_ASSIGN_OR_RETURN(segment, InsBetweenFactors(context, &build[i - 1], &build[i]));
      for (InsFactor& f : InsStateFactors(context, &build[i])) segment.push_back(std::move(f));
    }
    if (i > 0 || n == 1) {
      WG_ASSIGN_OR_RETURN(
          readings, InsRadioFactors(context, &build, i == 0 ? 0 : i - 1, i == 0 ? 0 : 1, &radio));
    }
    num_radio += readings.size();
    WG_RETURN_IF_ERROR(to_smoother(&segment));
    WG_RETURN_IF_ERROR(to_smoother(&readings));
    last = init;
    pending.push_back(i);
    if (i + 1 < n && build[i].t_s - last_update_t < options_.window_update_s) continue;
    last_update_t = build[i].t_s;

    const Clock::time_point start = Clock::now();
    WG_ASSIGN_OR_RETURN(FixedLagSmoother::UpdateResult u,
                        smoother.Update(std::move(new_states), std::move(new_factors)));
    new_states.clear();
    new_factors.clear();
    iterations += u.ceres_iterations;
    solves += u.solved ? 1 : 0;
    if (u.solved) final_cost = u.final_cost;
    unconverged += u.converged ? 0 : 1;
    max_keys = std::max(max_keys, smoother.WindowKeys().size());
    WG_ASSIGN_OR_RETURN(last, estimate_of(i));
    if (smoother.holding()) {
      const std::optional<double> yaw_sigma = YawSigma(&smoother, Key(i, kQ));
      const double release = yaw_sigma_before_gap.value_or(options_.gap_release_yaw_sigma_rad);
      if (build[i].t_s >= hold_until_s || (yaw_sigma && *yaw_sigma <= release)) {
        held_s = std::max(held_s, build[i].t_s - (hold_until_s - options_.gap_hold_max_s));
        smoother.Release();
      }
    }
    if (online) {
      std::vector<size_t> in_window;
      for (size_t j : pending) {
        if (!smoother.Contains(Key(j, kP))) {  // left already (window_update_s > lag_s)
          current[j] = lagged[j];
          continue;
        }
        WG_ASSIGN_OR_RETURN(current[j], estimate_of(j));
        in_window.push_back(j);
      }
      store_covariances(in_window);
    }
    latency.push_back(std::chrono::duration<double>(Clock::now() - start).count());
    pending.clear();
  }
  if (!online) {
    // The states still in the window at the end: their final (smoothed) estimates.
    std::vector<size_t> states;
    for (StateKey key : smoother.WindowKeys()) {
      if (key % kBlocksPerState == kP) states.push_back(key / kBlocksPerState);
    }
    store_covariances(states);
    smoother.Flush();
  }

  EstimateResult result;
  result.trajectory = InsStatesTrajectory(walk, online ? current : lagged, cov, g, !online);
  const size_t missing = static_cast<size_t>(
      std::count_if(cov.begin(), cov.end(), [](const auto& c) { return !c.has_value(); }));
  auto& d = result.diagnostics;
  d["num_states"] = static_cast<double>(n);
  d["num_strides"] = static_cast<double>(front.strides.steps.size());
  d["num_radio_factors"] = static_cast<double>(num_radio);
  d["ceres_iterations"] = iterations;
  d["window_solves"] = solves;
  d["window_unconverged_solves"] = unconverged;
  d["ceres_final_cost"] = final_cost;  // of the last solve
  d["window_max_keys"] = static_cast<double>(max_keys);
  d["window_max_states"] = static_cast<double>(max_keys / kBlocksPerState);
  d["window_gap_holds"] = holds;
  d["window_gap_hold_max_s"] = held_s;  // longest time from a gap to its release
  d["states_without_covariance"] = g.compute_covariance ? static_cast<double>(missing) : 0.0;
  d["covariance_ok"] = g.compute_covariance && missing == 0 ? 1.0 : 0.0;
  if (radio.estimate_path_loss) {  // the window's last estimate of the static block
    auto v = smoother.Estimate(kPathLossKey);
    if (v.ok() && v->size() == 2) radio.path_loss = {(*v)[0], (*v)[1]};
  }
  AddInsPathLossDiagnostics(walk, radio, &d);

  AddUpdateLatencyTimings(latency, &result.timings);
  const double run_s = std::chrono::duration<double>(Clock::now() - run_start).count();
  const double minutes = (walk.imu.back().t_s - walk.imu.front().t_s) / 60.0;
  result.timings["run_s"] = run_s;
  result.timings["run_s_per_walk_minute"] = minutes > 0 ? run_s / minutes : 0.0;
  if (lagged_out) *lagged_out = std::move(lagged);
  return result;
}

}  // namespace

StatusOr<EstimateResult> InsGraphWindow::Run(const Walk& walk) const {
  WG_RETURN_IF_ERROR(CheckApplicable(walk));
  return RunInsWindow(walk, options_, nullptr);
}

StatusOr<std::vector<InsState>> InsWindowLaggedStates(const Walk& walk,
                                                      const InsWindowOptions& options) {
  InsWindowOptions o = options;
  o.window_output = "lagged";
  WG_RETURN_IF_ERROR(InsGraphWindow(o).CheckApplicable(walk));
  std::vector<InsState> lagged;
  WG_RETURN_IF_ERROR(RunInsWindow(walk, o, &lagged).status());
  return lagged;
}

namespace internal {

void RegisterInsGraphWindow(EstimatorRegistry* registry) {
  auto make = [](const char* id, const char* output) {
    return [id, output](const YAML::Node& config) -> StatusOr<std::unique_ptr<Estimator>> {
      WG_ASSIGN_OR_RETURN(InsWindowOptions o, InsWindowOptions::FromYaml(config, id, output));
      return std::unique_ptr<Estimator>(new InsGraphWindow(o));
    };
  };
  registry->Register({"fg-ins-window",
                      "foot-INS factor graph as a fixed-lag smoother (10 s lag, marginalization "
                      "prior): lagged estimates (foot IMU)",
                      make("fg-ins-window", "lagged")});
  registry->Register({"fg-ins-window-online",
                      "fg-ins-window's online output: each state right after its own update",
                      make("fg-ins-window-online", "online")});
}

}  // namespace internal
}  // namespace walkgraph
