// The step-level factor graph: the equivalences that catch marginalization bugs (batch ==
// KF + RTS, window(lag > walk) == batch, window(finite lag) == the fixed-lag linear smoother)
// on the exactly linear-Gaussian walk, then accuracy on simulated and real walks.
#include "walkgraph/smoothers/step_graph.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <map>
#include <string>
#include <vector>

#include <ceres/normal_prior.h>
#include <gtest/gtest.h>
#include <yaml-cpp/yaml.h>

#include "test_util.h"
#include "walkgraph/angle.h"
#include "walkgraph/compare.h"
#include "walkgraph/io.h"
#include "walkgraph/kalman.h"
#include "walkgraph/metrics.h"
#include "walkgraph/simulate.h"

namespace walkgraph {
namespace {

// Options that make the graph's model the linear walk's: odometry σ_d = 0.05 m, ranges at
// face value with the walk's σ, no robust loss, no bias. The walk is linear only along its
// line: off it, a range to an anchor on the line curves as √(s² + l²), which with a weak
// lateral constraint turns the on-line solution into a saddle (seen: the window slid off it).
// Rigid heading increments and cross-track steps keep the lateral direction pinned, so the
// 2-D graph is the 1-D linear problem.
YAML::Node LinearConfig(double lag_s = 10.0) {
  YAML::Node n;
  n["odometry_sigma_dheading_rad"] = 1e-6;
  n["odometry_sigma_cross_m"] = 1e-3;
  n["odometry_sigma_dist_frac"] = 0.0;
  n["odometry_sigma_dist_m"] = 0.05;
  n["range_loss"] = "none";
  n["range_bias"] = "none";
  n["range_scale"] = "none";
  n["lag_s"] = lag_s;
  n["window_max_iterations"] = 50;
  n["function_tolerance"] = 1e-14;  // converge fully: the comparisons are at 1e-6
  n["window_function_tolerance"] = 1e-14;
  n["parameter_tolerance"] = 1e-14;
  return n;
}

// KF + RTS over the along-track coordinate s of the linear walk, using only the readings up to
// node `last` (all when last < 0). Returns the smoothed s and its variance per node.
struct Along {
  std::vector<double> s, var;
};
Along LinearRts(const Walk& w, int last = -1) {
  const Eigen::Vector2d start(w.meta.initial_pose->x_m, w.meta.initial_pose->y_m);
  const double h = w.meta.initial_pose->heading_rad;
  const Eigen::Vector2d u(std::cos(h), std::sin(h));
  const double sa1 = (w.anchors[0].position_m.head<2>() - start).dot(u);
  const double sa2 = (w.anchors[1].position_m.head<2>() - start).dot(u);
  const int n = static_cast<int>(w.odometry.size()) + 1;
  if (last < 0) last = n - 1;
  const double sr = w.meta.radio.range_sigma_m;
  std::vector<FilterEpoch> epochs;
  Eigen::VectorXd x = Eigen::VectorXd::Zero(1);
  Eigen::MatrixXd P = Eigen::MatrixXd::Constant(1, 1, std::pow(w.meta.initial_pose->sigma_xy_m, 2));
  size_t ri = 0;
  for (int k = 0; k < n; ++k) {
    const double t = k == 0 ? 0.0 : w.odometry[k - 1].t_s;
    FilterEpoch e;
    e.t_s = t;
    e.F = Eigen::MatrixXd::Identity(1, 1);
    if (k > 0) {
      x[0] += w.odometry[k - 1].dist_m;
      P(0, 0) += 0.05 * 0.05;
    }
    e.x_prior = x;
    e.P_prior = P;
    while (ri < w.ranges.size() && w.ranges[ri].t_s <= t + 1e-9) {
      const RangeSample& r = w.ranges[ri++];
      if (k > last) continue;
      const double sa = r.anchor_id == w.anchors[0].id ? sa1 : sa2;
      const double sign = x[0] > sa ? 1.0 : -1.0;  // r = |s − s_a|, affine on each side
      Eigen::VectorXd nu(1);
      nu[0] = r.range_m - sign * (x[0] - sa);
      auto out = KalmanUpdate(nu, Eigen::MatrixXd::Constant(1, 1, sign),
                              Eigen::MatrixXd::Constant(1, 1, sr * sr), 0.0, &x, &P);
      EXPECT_TRUE(out.ok());
    }
    e.x_post = x;
    e.P_post = P;
    epochs.push_back(e);
  }
  auto sm = RtsSmooth(epochs);
  EXPECT_TRUE(sm.ok());
  Along a;
  for (const SmoothedState& s : *sm) {
    a.s.push_back(s.x[0]);
    a.var.push_back(s.P(0, 0));
  }
  return a;
}

double AlongOf(const Walk& w, const TrajectoryPoint& p) {
  const Eigen::Vector2d start(w.meta.initial_pose->x_m, w.meta.initial_pose->y_m);
  const double h = w.meta.initial_pose->heading_rad;
  return (p.position_m.head<2>() - start).dot(Eigen::Vector2d(std::cos(h), std::sin(h)));
}

StatusOr<EstimateResult> RunId(const std::string& id, const Walk& walk, const YAML::Node& cfg) {
  WG_ASSIGN_OR_RETURN(auto est, EstimatorRegistry::Builtin().Create(id, cfg));
  return est->Run(walk);
}

TEST(StepGraphTest, BatchEqualsKalmanPlusRtsOnLinearGaussianWalk) {
  auto w = SimulateScenario("linear-gaussian", 3, YAML::Load("{duration_s: 40}"));
  ASSERT_TRUE(w.ok()) << w.status().message();
  auto r = RunId("fg-batch", *w, LinearConfig());
  ASSERT_TRUE(r.ok()) << r.status().message();
  const Along rts = LinearRts(*w);
  ASSERT_EQ(r->trajectory.size(), rts.s.size());
  double worst = 0.0, worst_var = 0.0;
  for (size_t k = 0; k < rts.s.size(); ++k) {
    const TrajectoryPoint& p = r->trajectory.points[k];
    worst = std::max(worst, std::fabs(AlongOf(*w, p) - rts.s[k]));
    ASSERT_TRUE(p.covariance.has_value());
    const double h = w->meta.initial_pose->heading_rad;
    const Eigen::Vector2d u(std::cos(h), std::sin(h));
    const double var = u.dot(p.covariance->topLeftCorner<2, 2>() * u);
    worst_var = std::max(worst_var, std::fabs(var - rts.var[k]) / rts.var[k]);
  }
  EXPECT_LT(worst, 1e-6);
  EXPECT_LT(worst_var, 1e-6);  // the marginal covariances are the RTS variances
}

TEST(StepGraphTest, WindowLongerThanTheWalkEqualsBatch) {
  auto w = SimulateScenario("linear-gaussian", 4, YAML::Load("{duration_s: 30}"));
  ASSERT_TRUE(w.ok());
  auto batch = RunId("fg-batch", *w, LinearConfig());
  auto window = RunId("fg-window", *w, LinearConfig(1000.0));
  ASSERT_TRUE(batch.ok() && window.ok());
  ASSERT_EQ(batch->trajectory.size(), window->trajectory.size());
  for (size_t k = 0; k < batch->trajectory.size(); ++k) {
    EXPECT_LT(
        (batch->trajectory.points[k].position_m - window->trajectory.points[k].position_m).norm(),
        1e-6);
  }
}

TEST(StepGraphTest, FiniteLagEqualsFixedLagLinearSmoother) {
  // Lag 3 s at 2 steps/s. Per-update marginalization (batch 0): node k leaves the window in
  // the update of the first node j with t_j − 3 > t_k, and its lagged estimate must be
  // E[s_k | readings up to node j]. Batched (batch b): it leaves with the update that first
  // finds the oldest node older than t_j − 3 − b, so j lies between that first node and the
  // first with t_j − 3 − b > t_k; the estimate must equal one of those conditional means.
  auto w = SimulateScenario("linear-gaussian", 5, YAML::Load("{duration_s: 25}"));
  ASSERT_TRUE(w.ok());
  const double lag = 3.0;
  const int n = static_cast<int>(w->odometry.size()) + 1;
  auto node_t = [&](int k) { return k == 0 ? 0.0 : w->odometry[k - 1].t_s; };
  for (double batch : {0.0, 1.2}) {
    YAML::Node config = LinearConfig(lag);
    config["window_marginalize_batch_s"] = batch;
    auto window = RunId("fg-window", *w, config);
    ASSERT_TRUE(window.ok()) << window.status().message();
    ASSERT_EQ(static_cast<int>(window->trajectory.size()), n);
    double worst = 0.0;
    int batched = 0;  // nodes that left later than the first eligible update
    for (int k = 0; k < n; ++k) {
      const double est = AlongOf(*w, window->trajectory.points[k]);
      int j = k;
      while (j < n && !(node_t(j) - lag > node_t(k))) ++j;
      double best = std::fabs(est - LinearRts(*w, j < n ? j : n - 1).s[k]);
      int best_j = j;
      for (int jj = j + 1; jj < n && !(node_t(jj - 1) - lag - batch > node_t(k)); ++jj) {
        const double e = std::fabs(est - LinearRts(*w, jj).s[k]);
        if (e < best) best = e, best_j = jj;
      }
      if (best_j > j && j < n) ++batched;
      worst = std::max(worst, best);
    }
    EXPECT_LT(worst, 1e-6) << "batch " << batch;
    if (batch > 0.0) EXPECT_GT(batched, n / 4) << "the batch setting changed nothing";
    // And it is not the full smoother (the test would pass vacuously if the lag were ignored).
    const Along full = LinearRts(*w);
    double diff = 0.0;
    for (int k = 0; k < n; ++k) {
      diff = std::max(diff, std::fabs(AlongOf(*w, window->trajectory.points[k]) - full.s[k]));
    }
    EXPECT_GT(diff, 1e-3) << "batch " << batch;
  }
}

TEST(StepGraphTest, OnlineOutputUsesOnlyPastData) {
  // The online estimate of node k equals the filtered (not smoothed) KF estimate at k.
  auto w = SimulateScenario("linear-gaussian", 6, YAML::Load("{duration_s: 15}"));
  ASSERT_TRUE(w.ok());
  auto online = RunId("fg-window-online", *w, LinearConfig());
  ASSERT_TRUE(online.ok()) << online.status().message();
  const int n = static_cast<int>(w->odometry.size()) + 1;
  double worst = 0.0;
  for (int k = 0; k < n; ++k) {
    const Along ref = LinearRts(*w, k);  // data up to k, smoothed: at k itself = filtered
    worst = std::max(worst, std::fabs(AlongOf(*w, online->trajectory.points[k]) - ref.s[k]));
  }
  EXPECT_LT(worst, 1e-6);
}

// Memory: the window holds the nodes (and their factors) of the last lag_s +
// window_marginalize_batch_s seconds however long the walk: a 10-minute walk's largest window
// is within one batch of a 2-minute one's, far below the walk's size.
TEST(StepGraphTest, WindowStaysBoundedOnALongWalk) {
  std::map<double, std::pair<double, double>> largest;  // duration → (states, factors)
  double nodes_long = 0.0;
  for (double duration : {120.0, 600.0}) {
    auto w = SimulateScenario("tarrio-circle", 4,
                              YAML::Load("{duration_s: " + std::to_string(duration) + "}"));
    ASSERT_TRUE(w.ok());
    auto r = RunId("fg-window", *w, YAML::Load("{covariance: false}"));
    ASSERT_TRUE(r.ok()) << r.status().message();
    largest[duration] = {r->diagnostics.at("window_max_states"),
                         r->diagnostics.at("window_max_factors")};
    nodes_long = r->diagnostics.at("nodes");
    std::printf("%.0f s walk: %.0f nodes, window at most %.0f states, %.0f factors\n", duration,
                nodes_long, largest[duration].first, largest[duration].second);
  }
  // ≈ 1.7 steps/s: 10-11 s of nodes (2 states each) plus the static states.
  const auto& [states_short, factors_short] = largest[120.0];
  const auto& [states_long, factors_long] = largest[600.0];
  EXPECT_GE(states_short, 2.0 * 1.7 * 10.0 * 0.8);
  EXPECT_LE(states_long, states_short + 2.0 * 2.0 * 1.7);  // at most ~one batch more
  EXPECT_LE(factors_long, 1.25 * factors_short);
  EXPECT_LT(states_long, 0.1 * 2.0 * nodes_long);
}

// A position-only start (heading_known = false) puts a prior on the position only: the start
// heading is left to the steps' magnetometer headings and the radio. With the same position
// and a wrong heading held tight (1 rad off, σ 0.01), node 0 keeps the wrong heading.
TEST(StepGraphTest, PositionOnlyStartLeavesTheHeadingFree) {
  auto sim = SimulateScenario("correa-classroom", 3, YAML::Load("{laps: 1}"));
  ASSERT_TRUE(sim.ok()) << sim.status().message();
  ASSERT_TRUE(sim->meta.initial_pose.has_value());
  const double true_heading = sim->meta.initial_pose->heading_rad;
  const YAML::Node cfg = YAML::Load("{pdr: {heading: complementary}, covariance: false}");
  auto start_heading = [&](const Walk& w) {
    auto r = RunId("fg-batch", w, cfg);
    EXPECT_TRUE(r.ok()) << r.status().message();
    return r.ok() ? r->trajectory.points.front().heading_rad : 1e9;
  };
  Walk free = *sim;
  free.meta.initial_pose->heading_known = false;
  free.meta.initial_pose->heading_rad = 0.0;
  free.meta.initial_pose->sigma_heading_rad = kUnknownHeadingSigmaRad;
  Walk wrong = *sim;
  wrong.meta.initial_pose->heading_rad = NormalizeAngle(true_heading + 1.0);
  wrong.meta.initial_pose->sigma_heading_rad = 0.01;
  const double h_free = start_heading(free), h_wrong = start_heading(wrong);
  std::printf("start heading: truth %.3f, position-only %.3f, wrong prior %.3f rad\n", true_heading,
              h_free, h_wrong);
  EXPECT_LT(std::abs(NormalizeAngle(h_free - true_heading)), 0.2);
  EXPECT_LT(std::abs(NormalizeAngle(h_wrong - true_heading - 1.0)), 0.1);
  // The position prior still holds.
  auto r = RunId("fg-batch", free, cfg);
  ASSERT_TRUE(r.ok());
  const Eigen::Vector2d p0 = r->trajectory.points.front().position_m.head<2>();
  EXPECT_LT((p0 - Eigen::Vector2d(free.meta.initial_pose->x_m, free.meta.initial_pose->y_m)).norm(),
            3.0 * free.meta.initial_pose->sigma_xy_m);
}

// Issue 41: with no start at all, fg-batch also solves the dead reckoning aligned to every radio
// fix, turned four ways, and keeps the lowest final cost: the diagnostics name the choice, the
// chosen cost is the least, and a walk with a start has no hypotheses.
TEST(StepGraphTest, NoStartSolvesEveryStartHypothesisAndKeepsTheLeastCost) {
  auto sim = SimulateScenario("tarrio-circle", 2, YAML::Load("{duration_s: 60}"));
  ASSERT_TRUE(sim.ok()) << sim.status().message();
  StepGraphOptions o;
  o.covariance = false;
  auto with_start = StepGraph::Build(*sim, o);
  ASSERT_TRUE(with_start.ok());
  EXPECT_TRUE((*with_start)->StartHypotheses(*sim, 4).empty());
  Walk none = *sim;
  none.meta.initial_pose.reset();
  auto graph = StepGraph::Build(none, o);
  ASSERT_TRUE(graph.ok());
  const auto starts = (*graph)->StartHypotheses(none, 4);
  ASSERT_EQ(starts.size(), 4u);
  for (size_t h = 1; h < starts.size(); ++h) {  // each a quarter turn on from the one before
    EXPECT_NEAR(NormalizeAngle(starts[h][5][2] - starts[h - 1][5][2]), kPi / 2, 1e-9);
    EXPECT_NEAR((starts[h][5].head<2>() - starts[h][0].head<2>()).norm(),
                (starts[0][5].head<2>() - starts[0][0].head<2>()).norm(), 1e-9);
  }
  auto r = RunId("fg-batch", none, YAML::Load("{covariance: false}"));
  ASSERT_TRUE(r.ok()) << r.status().message();
  const auto& d = r->diagnostics;
  ASSERT_TRUE(d.count("start_hypothesis"));
  for (int h = 0; h <= 4; ++h) {
    const std::string key = "start_hypothesis_cost." + std::to_string(h);
    ASSERT_TRUE(d.count(key)) << key;
  }
  double least = std::numeric_limits<double>::infinity();  // the turns' and the estimators'
  for (const auto& [key, cost] : d) {
    if (key.rfind("start_hypothesis_cost.", 0) == 0) least = std::min(least, cost);
  }
  EXPECT_EQ(d.at("final_cost"), least);
  auto off = RunId("fg-batch", none,
                   YAML::Load("{covariance: false, start_hypotheses: 0, start_estimators: ''}"));
  ASSERT_TRUE(off.ok());
  EXPECT_FALSE(off->diagnostics.count("start_hypothesis"));
  // Not below to the last bit: the two start from different window passes (the window's
  // first window takes the estimators' hypotheses too) and stop at the solver's relative
  // cost-change tolerance (function_tolerance, 1e-6).
  EXPECT_LE(d.at("final_cost"), off->diagnostics.at("final_cost") * (1.0 + 1e-6));
  std::printf("no start: final cost %.9g with the hypotheses, %.9g without\n", d.at("final_cost"),
              off->diagnostics.at("final_cost"));
  EXPECT_FALSE(RunId("fg-batch", none, YAML::Load("{start_hypotheses: -1}")).ok());
}

// Issue 41: a trajectory (a filter's) as a start hypothesis. The dead reckoning turned by 0.7 rad
// and shifted is found again by Procrustes ([0]) and its positions are taken as they are ([1]);
// until_s keeps the first nodes; a walk with a start, or a trajectory over fewer than 3 nodes,
// gives none.
TEST(StepGraphTest, HypothesesFromATrajectoryAlignTheDeadReckoning) {
  auto sim = SimulateScenario("tarrio-circle", 3, YAML::Load("{duration_s: 60}"));
  ASSERT_TRUE(sim.ok()) << sim.status().message();
  StepGraphOptions o;
  o.covariance = false;
  Walk none = *sim;
  none.meta.initial_pose.reset();
  auto graph = StepGraph::Build(none, o);
  ASSERT_TRUE(graph.ok());
  const StepGraph& g = **graph;
  const Eigen::Rotation2Dd R(0.7);
  const Eigen::Vector2d shift(12.0, -5.0);
  Trajectory moved;
  for (int k = 0; k < g.num_nodes(); ++k) {
    TrajectoryPoint p;
    p.t_s = g.node_time(k);
    p.position_m.head<2>() = R * g.initial_nodes()[k].head<2>() + shift;
    moved.points.push_back(p);
  }
  const auto h = g.HypothesesFrom(moved);
  ASSERT_EQ(h.size(), 2u);
  ASSERT_EQ(h[0].size(), static_cast<size_t>(g.num_nodes()));
  for (int k = 0; k < g.num_nodes(); k += 7) {
    const Eigen::Vector3d& x = g.initial_nodes()[k];
    EXPECT_LT((h[0][k].head<2>() - moved.points[k].position_m.head<2>()).norm(), 1e-6) << k;
    EXPECT_NEAR(NormalizeAngle(h[0][k][2] - x[2] - 0.7), 0.0, 1e-6) << k;
    EXPECT_EQ(h[1][k].head<2>(), moved.points[k].position_m.head<2>()) << k;
    EXPECT_EQ(h[1][k][2], h[0][k][2]) << k;
  }
  const auto first = g.HypothesesFrom(moved, g.node_time(10));
  ASSERT_EQ(first.size(), 2u);
  EXPECT_EQ(first[0].size(), 11u);
  Trajectory short_span;
  short_span.points.assign(moved.points.begin() + 3, moved.points.begin() + 5);
  EXPECT_TRUE(g.HypothesesFrom(short_span).empty());
  auto with_start = StepGraph::Build(*sim, o);
  ASSERT_TRUE(with_start.ok());
  EXPECT_TRUE((*with_start)->HypothesesFrom(moved).empty());
}

// Issue 41: with no start, fg-batch also solves from the trajectories of start_estimators and
// fg-window solves its first align_window_s from them; the least cost wins and the diagnostics
// say which (start_hypothesis_estimator, first_window_estimator). A walk with a start runs no
// estimator; the step graph's own ids and unknown ids are refused.
TEST(StepGraphTest, NoStartTakesTheEstimatorsTrajectoriesAsHypotheses) {
  // Correa's hip walk (its EKF and RTS run there without a start; Gädeke's front end finds no
  // step in it), the list spelled with spaces.
  auto sim = SimulateScenario("correa-corridor", 4, YAML::Node());
  ASSERT_TRUE(sim.ok()) << sim.status().message();
  Walk none = *sim;
  none.meta.initial_pose.reset();
  auto least_of = [](const std::map<std::string, double>& d, const std::string& prefix) {
    double least = std::numeric_limits<double>::infinity();
    int n = 0;
    for (const auto& [key, cost] : d) {
      if (key.rfind(prefix, 0) == 0) least = std::min(least, cost), ++n;
    }
    return std::make_pair(least, n);
  };
  const YAML::Node cfg =
      YAML::Load("{covariance: false, start_estimators: 'correa-ekf-rts, prieto-ekf-wifi'}");
  auto batch = RunId("fg-batch", none, cfg);
  ASSERT_TRUE(batch.ok()) << batch.status().message();
  const auto& d = batch->diagnostics;
  for (const char* key :
       {"start_hypothesis_cost.correa-ekf-rts", "start_hypothesis_cost.correa-ekf-rts/aligned",
        "start_hypothesis_cost.prieto-ekf-wifi", "start_hypothesis_estimator"}) {
    EXPECT_TRUE(d.count(key)) << key;
  }
  EXPECT_EQ(d.at("final_cost"), least_of(d, "start_hypothesis_cost.").first);
  auto window = RunId("fg-window", none, cfg);
  ASSERT_TRUE(window.ok()) << window.status().message();
  const auto& w = window->diagnostics;
  const auto [first_least, first_n] = least_of(w, "first_window_cost.");
  EXPECT_EQ(first_n, 5);  // its own + correa-ekf's two + prieto-ekf-wifi's two (causal)
  EXPECT_TRUE(w.count("first_window_cost.correa-ekf"));
  EXPECT_FALSE(w.count("first_window_cost.correa-ekf-rts"));
  ASSERT_TRUE(w.count("first_window_estimator"));
  const int chosen = static_cast<int>(w.at("first_window_hypothesis"));
  EXPECT_EQ(chosen == 0, w.at("first_window_estimator") == 0);
  EXPECT_LE(first_least, w.at("first_window_cost.0"));
  auto with_start = RunId("fg-window", *sim, cfg);
  ASSERT_TRUE(with_start.ok());
  EXPECT_FALSE(with_start->diagnostics.count("first_window_estimator"));
  // The online output is causal: no first-window look-ahead.
  auto online = RunId("fg-window-online", none, cfg);
  ASSERT_TRUE(online.ok()) << online.status().message();
  EXPECT_FALSE(online->diagnostics.count("first_window_estimator"));
  EXPECT_FALSE(online->diagnostics.count("first_window_cost.0"));
  auto none_listed = RunId("fg-window", none, YAML::Load("{start_estimators: ''}"));
  ASSERT_TRUE(none_listed.ok());
  EXPECT_FALSE(none_listed->diagnostics.count("first_window_estimator"));
  EXPECT_FALSE(RunId("fg-batch", none, YAML::Load("{start_estimators: 'fg-window'}")).ok());
  EXPECT_FALSE(RunId("fg-batch", none, YAML::Load("{start_estimators: 'gadeke-kf,,'}")).ok());
  EXPECT_FALSE(RunId("fg-batch", none, YAML::Load("{start_estimators: 'no-such-filter'}")).ok());
}

// Issue 41: a phone without a magnetometer, its start position known but not its heading (the
// gyro gives the heading relative to a frame nobody knows). fg-window's first window and
// fg-batch solve from the dead reckoning turned about the start by k·90° and keep the least
// cost (start_hypotheses: 4), and the window holds the gyro bias (no heading reference:
// window_gyro_bias_without_heading). Measured RMSE on the simulated handheld phone, seeds 1-4,
// before -> now: fg-window 9.60 3.64 2.11 2.90 -> 2.59 3.17 2.13 2.88 m, fg-batch 4.66 1.66
// 1.32 2.26 -> 2.21 2.35 1.32 1.62 m (seed 2: its window start and the turns end in a higher
// cost than the old window start's, 1.42x there).
// fg-batch's noise scales (StepGraphOptions::noise_scale_rounds): on the simulated handheld
// phone the step lengths scatter 2.1-2.8x more than the front end's σ says, and raising it lets
// the radio correct them: RMSE 1.556 / 1.647 / 1.299 -> 0.554 / 0.658 / 0.367 m (seeds 1-3;
// 10 runs: 1.648 -> 0.680). Only raised by default: no scale below 1.
TEST(StepGraphTest, NoiseScalesRaiseTheStepSigmaTheResidualsShowTooTight) {
  for (int seed = 1; seed <= 3; ++seed) {
    auto w = SimulateScenario("handheld-phone", seed, YAML::Node());
    ASSERT_TRUE(w.ok()) << w.status().message();
    auto given = RunId("fg-batch", *w, YAML::Load("{noise_scale_rounds: 0}"));
    auto scaled = RunId("fg-batch", *w, YAML::Node());
    ASSERT_TRUE(given.ok() && scaled.ok());
    auto rmse = [&](const EstimateResult& r) {
      auto e = ComputeErrors(*w, r.trajectory);
      EXPECT_TRUE(e.ok());
      return SummarizeErrors(e->error_m, w->TruthDistance()).rmse_m;
    };
    const double a = rmse(*given), b = rmse(*scaled);
    std::printf(
        "handheld phone seed %d: fg-batch RMSE %.3f m with the sigma given, %.3f m scaled "
        "(step x%.2f)\n",
        seed, a, b, scaled->diagnostics.at("noise_scale.step"));
    EXPECT_LT(b, 0.6 * a) << seed;
    EXPECT_GT(scaled->diagnostics.at("noise_scale.step"), 1.5) << seed;
    for (const auto& [key, v] : scaled->diagnostics) {
      if (key.rfind("noise_scale.", 0) == 0) EXPECT_GE(v, 1.0) << key;
    }
    EXPECT_EQ(given->diagnostics.at("noise_scale_rounds"), 0.0);
    EXPECT_EQ(given->diagnostics.count("noise_scale.step"), 0u);
  }
  auto lower = RunId("fg-batch", *SimulateScenario("tarrio-circle", 1, YAML::Node()),
                     YAML::Load("{noise_scale_lower: true}"));
  ASSERT_TRUE(lower.ok());
  EXPECT_LT(lower->diagnostics.at("noise_scale.heading_increment"), 0.5);
  EXPECT_FALSE(RunId("fg-batch", *SimulateScenario("tarrio-circle", 1, YAML::Node()),
                     YAML::Load("{noise_scale_rounds: 11}"))
                   .ok());
}

// The walk's step-length scale (StepGraphOptions::estimate_step_scale, asked for): the
// handheld-phone preset walks with Weinberg K 0.40 and the front end assumes 0.45, so the steps
// are 1 − 0.40/0.45 = 11 % long; fg-batch finds 0.886-0.903 (seeds 1-3) and RMSE 0.352 / 0.313 /
// 0.258 m against 0.554 / 0.658 / 0.367 without the scale. On tarrio-circle, whose K is the front
// end's, it finds 0.944-0.955: the radio's biases pull the walk in (why it is off by default).
TEST(StepGraphTest, EstimatesTheWalksStepLengthScale) {
  for (int seed = 1; seed <= 3; ++seed) {
    auto phone = SimulateScenario("handheld-phone", seed, YAML::Node());
    auto circle = SimulateScenario("tarrio-circle", seed, YAML::Node());
    ASSERT_TRUE(phone.ok() && circle.ok());
    const YAML::Node on = YAML::Load("{estimate_step_scale: true}");
    auto a = RunId("fg-batch", *phone, on);
    auto b = RunId("fg-batch", *circle, on);
    auto held = RunId("fg-batch", *phone, YAML::Node());
    ASSERT_TRUE(a.ok() && b.ok() && held.ok());
    const double sa = a->diagnostics.at("step_length_scale");
    const double sb = b->diagnostics.at("step_length_scale");
    std::printf("seed %d: step-length scale %.3f (handheld phone), %.3f (tarrio-circle)\n", seed,
                sa, sb);
    EXPECT_NEAR(sa, 0.40 / 0.45, 0.03) << seed;
    EXPECT_NEAR(sb, 1.0, 0.08) << seed;
    EXPECT_EQ(held->diagnostics.count("step_length_scale"), 0u);
    auto rmse = [&](const EstimateResult& r) {
      auto e = ComputeErrors(*phone, r.trajectory);
      EXPECT_TRUE(e.ok());
      return SummarizeErrors(e->error_m, phone->TruthDistance()).rmse_m;
    };
    EXPECT_LT(rmse(*a), 0.8 * rmse(*held)) << seed;
  }
}

TEST(StepGraphTest, StartWithoutHeadingTriesTurnsAboutTheStart) {
  const double window_bound[] = {3.0, 3.6, 2.5, 3.3}, batch_bound[] = {2.6, 2.7, 1.6, 2.0};
  for (int seed = 1; seed <= 4; ++seed) {
    auto sim = SimulateScenario("handheld-phone", seed, YAML::Node());
    ASSERT_TRUE(sim.ok()) << sim.status().message();
    Walk w = *sim;
    for (ImuSample& s : w.imu) s.has_mag = false;
    w.meta.initial_pose->heading_known = false;
    for (const char* id : {"fg-window", "fg-batch"}) {
      auto r = RunId(id, w, YAML::Node());
      ASSERT_TRUE(r.ok()) << r.status().message();
      auto e = ComputeErrors(w, r->trajectory);
      ASSERT_TRUE(e.ok());
      const double rmse = SummarizeErrors(e->error_m, w.TruthDistance()).rmse_m;
      std::printf("handheld phone, no magnetometer, no start heading, seed %d: %s RMSE %.3f m\n",
                  seed, id, rmse);
      const bool window = std::string(id) == "fg-window";
      EXPECT_LE(rmse, window ? window_bound[seed - 1] : batch_bound[seed - 1]) << id << seed;
      EXPECT_EQ(r->diagnostics.count("gyro_bias_held_no_heading_reference"), window ? 1u : 0u);
      const auto& d = r->diagnostics;
      for (int k = 1; k <= 4; ++k) {  // the window's own start is turn 0
        const std::string key = window ? "first_window_cost.turn" + std::to_string(k)
                                       : "start_hypothesis_cost." + std::to_string(k);
        EXPECT_EQ(d.count(key), window && k == 4 ? 0u : 1u) << key;
      }
    }
  }
  // A start heading given and a magnetometer: no turns, the bias estimated; asked for, the
  // window estimates it without a heading reference too.
  auto sim = SimulateScenario("handheld-phone", 1, YAML::Node());
  ASSERT_TRUE(sim.ok());
  auto r = RunId("fg-window", *sim, YAML::Node());
  ASSERT_TRUE(r.ok());
  EXPECT_FALSE(r->diagnostics.count("first_window_cost.turn1"));
  EXPECT_FALSE(r->diagnostics.count("gyro_bias_held_no_heading_reference"));
  EXPECT_TRUE(r->diagnostics.count("gyro_bias_radps"));
  Walk w = *sim;
  for (ImuSample& s : w.imu) s.has_mag = false;
  auto asked = RunId("fg-window", w, YAML::Load("{window_gyro_bias_without_heading: true}"));
  ASSERT_TRUE(asked.ok());
  EXPECT_FALSE(asked->diagnostics.count("gyro_bias_held_no_heading_reference"));
  EXPECT_TRUE(asked->diagnostics.count("gyro_bias_radps"));
  // An odometry walk whose start heading the radio fixes settle (start_check): no turns. Plaza1
  // without its start heading took 2.25 s in fg-batch with them, 0.21 s without, same result.
  auto plaza = ReadWalk(std::string(WALKGRAPH_SOURCE_DIR) + "/datasets/plaza1");
  ASSERT_TRUE(plaza.ok());
  plaza->meta.initial_pose->heading_known = false;
  auto graph = StepGraph::Build(*plaza, StepGraphOptions());
  ASSERT_TRUE(graph.ok());
  EXPECT_TRUE((*graph)->StartHeadingTurns(4).empty());
}

// Waypoints (known positions at known times) pull the estimate onto them. Five points taken
// from the truth, on three seeds: at σ = 0.5 m (a foot on a surveyed mark, the graph's position
// being the body's) fg-batch's error at each is below σ and their sum is below 0.8× that
// without them; at σ = 0.01 m the estimate goes through them (< 2 cm), batch and window alike
// (one factor list). Measured at σ = 0.3 m: up to 0.36 m at two corners where the
// error without the waypoint is 0.9 m and the pull is weaker than σ alone would give (the
// graph's own uncertainty there, inferred from the pull, is ~0.3 m: overconfident).
class StepGraphWaypointTest : public ::testing::TestWithParam<int> {};

TEST_P(StepGraphWaypointTest, WaypointsPullTheEstimateOntoThem) {
  auto sim = SimulateScenario("jimenez-building", GetParam(), YAML::Load("{laps: 1}"));
  ASSERT_TRUE(sim.ok()) << sim.status().message();
  for (const double sigma : {0.5, 0.01}) {
    Walk with = *sim;
    const size_t n = sim->truth.size();
    for (size_t i = 1; i <= 5; ++i) {
      const TruthSample& s = sim->truth[i * (n - 1) / 6];
      with.waypoints.push_back(Waypoint{s.t_s, s.position_m.head<2>(), sigma});
    }
    ASSERT_TRUE(ValidateWalk(with).ok());
    for (const char* id : {"fg-batch", "fg-window"}) {
      auto plain = RunId(id, *sim, YAML::Node());
      auto pulled = RunId(id, with, YAML::Node());
      ASSERT_TRUE(plain.ok() && pulled.ok());
      double sum_plain = 0.0, sum_pulled = 0.0;
      for (const Waypoint& w : with.waypoints) {
        const double e_plain =
            (plain->trajectory.PositionAt(w.t_s).head<2>() - w.position_m).norm();
        const double e_pulled =
            (pulled->trajectory.PositionAt(w.t_s).head<2>() - w.position_m).norm();
        std::printf("%s σ %.2f waypoint t=%.1f s: error %.3f m without, %.3f m with\n", id, sigma,
                    w.t_s, e_plain, e_pulled);
        if (sigma < 0.1) {
          EXPECT_LT(e_pulled, 0.02) << id << " t = " << w.t_s;
        } else if (std::string(id) == "fg-batch") {
          EXPECT_LT(e_pulled, sigma) << "t = " << w.t_s;
        }
        sum_plain += e_plain;
        sum_pulled += e_pulled;
      }
      EXPECT_LT(sum_pulled, (sigma < 0.1 ? 0.1 : 0.8) * sum_plain) << id;
    }
  }
}

INSTANTIATE_TEST_SUITE_P(Seeds, StepGraphWaypointTest, ::testing::Values(1, 2, 3));

// The user-factor hook: its factors reach the batch and the window; its failures and keys
// beyond the graph come back as a Status naming them.
TEST(StepGraphTest, UserFactorsReachBatchAndWindow) {
  auto sim = SimulateScenario("tarrio-circle", 2, YAML::Load("{duration_s: 40}"));
  ASSERT_TRUE(sim.ok()) << sim.status().message();
  const Eigen::Vector2d target(3.0, -2.0);  // far from the walk: a pull that must show
  size_t pose = 0;
  StepGraphOptions o;
  o.user_factors = [&](const Walk&, const std::vector<double>& times,
                       std::vector<GraphFactor>* out) {
    pose = times.size() / 2;
    out->push_back({std::shared_ptr<ceres::CostFunction>(
                        new ceres::NormalPrior(ceres::Matrix::Identity(2, 2) / 0.01, target)),
                    nullptr,
                    {StepGraph::PositionKey(static_cast<int>(pose))}});
    return Status::Ok();
  };
  auto batch = StepGraphBatch(o).Run(*sim);
  auto window = StepGraphWindow(o).Run(*sim);
  ASSERT_TRUE(batch.ok() && window.ok());
  EXPECT_LT((batch->trajectory.points[pose].position_m.head<2>() - target).norm(), 0.03);
  EXPECT_LT((window->trajectory.points[pose].position_m.head<2>() - target).norm(), 0.03);

  StepGraphOptions failing;
  failing.user_factors = [](const Walk&, const std::vector<double>&, std::vector<GraphFactor>*) {
    return InvalidArgument("no gate map");
  };
  auto r = StepGraphBatch(failing).Run(*sim);
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.status().message().find("user factors: no gate map"), std::string::npos);
  StepGraphOptions beyond;
  beyond.user_factors = [&](const Walk&, const std::vector<double>& times,
                            std::vector<GraphFactor>* out) {
    out->push_back({std::shared_ptr<ceres::CostFunction>(
                        new ceres::NormalPrior(ceres::Matrix::Identity(2, 2), target)),
                    nullptr,
                    {StepGraph::PositionKey(static_cast<int>(times.size()))}});
    return Status::Ok();
  };
  r = StepGraphWindow(beyond).Run(*sim);
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.status().message().find("beyond the last pose"), std::string::npos)
      << r.status().message();
  StepGraphOptions miscounted;  // a 1-block cost function given two keys
  miscounted.user_factors = [&](const Walk&, const std::vector<double>&,
                                std::vector<GraphFactor>* out) {
    out->push_back({std::shared_ptr<ceres::CostFunction>(
                        new ceres::NormalPrior(ceres::Matrix::Identity(2, 2), target)),
                    nullptr,
                    {StepGraph::PositionKey(0), StepGraph::PositionKey(1)}});
    return Status::Ok();
  };
  r = StepGraphBatch(miscounted).Run(*sim);
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.status().message().find("user factor 0: the cost function has 1 blocks, 2 keys"),
            std::string::npos)
      << r.status().message();
}

TEST(StepGraphTest, OptionsAreStrict) {
  const auto& reg = EstimatorRegistry::Builtin();
  for (const char* id : {"fg-batch", "fg-batch-selfcal", "fg-window", "fg-window-online"}) {
    EXPECT_TRUE(reg.Create(id, YAML::Node()).ok()) << id;
    EXPECT_FALSE(reg.Create(id, YAML::Load("{no_such_option: 1}")).ok()) << id;
  }
  EXPECT_FALSE(reg.Create("fg-batch", YAML::Load("{rss_loss: magic}")).ok());
  EXPECT_FALSE(reg.Create("fg-batch", YAML::Load("{path_loss: global, rss_residual: range}")).ok());
  EXPECT_FALSE(reg.Create("fg-batch", YAML::Load("{lag_s: 0}")).ok());
  EXPECT_FALSE(reg.Create("fg-window", YAML::Load("{window_marginalize_batch_s: -1}")).ok());
  EXPECT_FALSE(reg.Create("fg-window", YAML::Load("{window_initial_trust_region_radius: 0}")).ok());
  EXPECT_FALSE(reg.Create("fg-window", YAML::Load("{window_function_tolerance: 0}")).ok());
  EXPECT_TRUE(reg.Create("fg-window", YAML::Load("{window_function_tolerance: 1e-6}")).ok());
  EXPECT_FALSE(reg.Create("fg-window", YAML::Load("{window_linear_solver: cg}")).ok());
  EXPECT_TRUE(reg.Create("fg-window", YAML::Load("{window_linear_solver: sparse}")).ok());
  EXPECT_FALSE(reg.Create("fg-batch", YAML::Load("{linear_solver: cg}")).ok());
  EXPECT_TRUE(reg.Create("fg-batch", YAML::Load("{linear_solver: sparse}")).ok());
  EXPECT_FALSE(reg.Create("fg-batch", YAML::Load("{pdr: {detector: nope}}")).ok());
  EXPECT_FALSE(reg.Create("fg-batch", YAML::Load("{level_sigma_m: -0.1}")).ok());
  EXPECT_FALSE(reg.Create("fg-batch", YAML::Load("{floor_sigma_m: -1}")).ok());
  EXPECT_FALSE(reg.Create("fg-batch", YAML::Load("{floor_snap_storeys: 0.5}")).ok());
  EXPECT_FALSE(reg.Create("fg-batch", YAML::Load("{stair_landing_s: -1}")).ok());
  EXPECT_TRUE(reg.Create("fg-batch", YAML::Load("{level_sigma_m: 0, floor_sigma_m: 0}")).ok());
  // Set in C++, the same rules hold at Run: a value outside the enum's table is refused ("Huber"
  // used to mean no loss; the name is refused by LossKindFromString, config_test).
  StepGraphOptions o;
  EXPECT_TRUE(o.Validate().ok());
  o.rss_loss = static_cast<LossKind>(17);
  auto walk = SimulateScenario("tarrio-circle", 1, YAML::Load("{duration_s: 10}"));
  ASSERT_TRUE(walk.ok());
  for (const auto& r : {StepGraphBatch(o).Run(*walk), StepGraphWindow(o).Run(*walk)}) {
    ASSERT_FALSE(r.ok());
    EXPECT_NE(r.status().message().find("rss_loss must be one of none, huber"), std::string::npos)
        << r.status().message();
  }
}

TEST(StepGraphTest, WalkWithoutStepsNeedsThreeAnchors) {
  Walk w;
  w.meta.name = "radio only";
  w.anchors = {{1, Eigen::Vector3d::Zero()}};
  w.ranges = {{0.0, 1, 3.0}};
  auto est = EstimatorRegistry::Builtin().Create("fg-batch");
  ASSERT_TRUE(est.ok());
  EXPECT_FALSE((*est)->CheckApplicable(w).ok());
  w.anchors.push_back({2, Eigen::Vector3d(10, 0, 0)});
  w.anchors.push_back({3, Eigen::Vector3d(0, 10, 0)});
  EXPECT_TRUE((*est)->CheckApplicable(w).ok());
}

// A radio-only walk (no steps): the random-walk graph tracks a walker from exact ranges.
TEST(StepGraphTest, RadioOnlyWalkFollowsTheRanges) {
  Walk w;
  w.meta.name = "radio only";
  w.meta.radio.kind = RadioKind::kRange;
  w.meta.radio.range_sigma_m = 0.1;
  w.anchors = {{1, Eigen::Vector3d(0, 0, 0)},
               {2, Eigen::Vector3d(20, 0, 0)},
               {3, Eigen::Vector3d(0, 20, 0)},
               {4, Eigen::Vector3d(20, 20, 0)}};
  for (int k = 0; k <= 200; ++k) {  // 0.5 m/s along y = 10 for 20 s, a reading every 0.1 s
    const double t = 0.1 * k;
    const Eigen::Vector3d p(0.5 * t, 10.0, 0.0);
    const Anchor& a = w.anchors[k % 4];
    w.ranges.push_back({t, a.id, (p - a.position_m).norm()});
    w.truth.push_back({t, p, false});
  }
  auto r = RunId("fg-batch", w, YAML::Load("{range_bias: none, range_scale: none}"));
  ASSERT_TRUE(r.ok()) << r.status().message();
  auto e = ComputeErrors(w, r->trajectory);
  ASSERT_TRUE(e.ok());
  // A node per 0.5 s holds the position between nodes; at 0.5 m/s that is ≤ 0.25 m.
  EXPECT_LT(SummarizeErrors(e->error_m, 10.0).max_m, 0.3);
  EXPECT_TRUE(r->trajectory.points.front().covariance.has_value());
}

TEST(StepGraphRealData, Plaza1BatchWithRangeBiasesAndRobustLoss) {
  auto w = ReadWalk(std::string(WALKGRAPH_SOURCE_DIR) + "/datasets/plaza1");
  ASSERT_TRUE(w.ok()) << w.status().message();
  auto r = RunId("fg-batch", *w, YAML::Node());
  ASSERT_TRUE(r.ok()) << r.status().message();
  auto e = ComputeErrors(*w, r->trajectory);
  ASSERT_TRUE(e.ok());
  const ErrorStats s = SummarizeErrors(e->error_m, w->TruthDistance());
  std::printf("Plaza1 fg-batch: RMSE %.3f m, mean %.3f m, p90 %.3f m\n", s.rmse_m, s.mean_m,
              s.p90_m);
  for (const auto& [k, v] : r->diagnostics) {
    if (k.rfind("range_", 0) == 0) std::printf("  %s = %.3f\n", k.c_str(), v);
  }
  // Issue 8's target is 1.0 m (dead reckoning alone gives 1.97 m, ranges at face value
  // 3.1-3.3 m); with the affine range model (bias + scale) this walk reaches ≈0.31 m, so hold
  // it well below the target, where a regression in the range model would show.
  EXPECT_LE(s.rmse_m, 0.5);
  EXPECT_NEAR(r->diagnostics.at("range_scale"), 0.07, 0.03);  // range − d grows ≈7 % of d
}

// A robust start (issue 17): Plaza1 with its start heading turned by π (as a public recording
// of this family ships its truth heading column). Without the start check fg-window went 67 m
// off and took ~150 s to come back (RMSE 20.8 m); the radio contradicts the prior, which is
// left out: lag-end RMSE within 1.5× of the right heading's, and fg-batch as good.
TEST(StepGraphRealData, Plaza1StartHeadingTurnedByPiIsCaught) {
  auto w = ReadWalk(std::string(WALKGRAPH_SOURCE_DIR) + "/datasets/plaza1");
  ASSERT_TRUE(w.ok()) << w.status().message();
  Walk flipped = *w;
  flipped.meta.initial_pose->heading_rad = NormalizeAngle(w->meta.initial_pose->heading_rad + kPi);
  for (const char* id : {"fg-window", "fg-batch"}) {
    double rmse[2];
    for (int i = 0; i < 2; ++i) {
      const Walk& v = i == 0 ? *w : flipped;
      auto r = RunId(id, v, YAML::Node());
      ASSERT_TRUE(r.ok()) << r.status().message();
      auto e = ComputeErrors(v, r->trajectory);
      ASSERT_TRUE(e.ok());
      rmse[i] = SummarizeErrors(e->error_m, v.TruthDistance()).rmse_m;
      EXPECT_EQ(r->diagnostics.count("start_heading_contradicted_rad"), i == 0 ? 0u : 1u) << id;
      if (i == 1) EXPECT_GT(r->diagnostics.at("start_heading_contradicted_rad"), 2.8) << id;
    }
    std::printf("Plaza1 %s: RMSE %.3f m with the start heading right, %.3f m turned by pi\n", id,
                rmse[0], rmse[1]);
    EXPECT_LE(rmse[1], 1.5 * rmse[0]) << id;
  }
}

// ---------------------------------------------------------------- accuracy on the presets

struct PresetCase {
  const char* scenario;
  const char* overrides;  // shorter walks than the presets' defaults, for the suite's time
  std::vector<std::string> causal, smoothed;  // the papers' filters that fit the preset
  int runs;
};

void PrintTo(const PresetCase& c, std::ostream* os) { *os << c.scenario; }

class StepGraphPresetTest : public ::testing::TestWithParam<PresetCase> {};

// Issue 6: fg-batch RMSE ≤ 0.70 × the best causal filter and ≤ 0.90 × the best RTS-smoothed
// one; fg-window's lagged output ≤ 0.80 × and its online output ≤ 1.0 × the best causal.
// RMSE = mean over the seeded runs of each run's RMSE (CompareMonteCarlo).
TEST_P(StepGraphPresetTest, SmoothersBeatThePapersFilters) {
  const PresetCase& c = GetParam();
  const YAML::Node overrides = YAML::Load(c.overrides);
  CompareOptions options;
  options.estimator_ids = c.causal;
  options.estimator_ids.insert(options.estimator_ids.end(), c.smoothed.begin(), c.smoothed.end());
  for (const char* id : {"fg-batch", "fg-window", "fg-window-online"}) {
    options.estimator_ids.push_back(id);
  }
  MonteCarloOptions mc;
  mc.runs = testing::MonteCarloRuns(c.runs);
  mc.seed = 6;
  mc.threads = 1;
  const std::string name = c.scenario;
  auto cmp = CompareMonteCarlo(
      [&](uint64_t seed) { return SimulateScenario(name, seed, overrides); }, options, mc);
  ASSERT_TRUE(cmp.ok()) << cmp.status().message();
  std::map<std::string, double> rmse;
  for (const EstimatorOutcome& o : cmp->outcomes) {
    ASSERT_TRUE(o.status.ok()) << o.id << ": " << o.status.message();
    EXPECT_EQ(o.failed_runs, 0) << o.id;
    rmse[o.id] = o.stats.rmse_m;
  }
  double best_causal = 1e9, best_smoothed = 1e9;
  for (const auto& id : c.causal) best_causal = std::min(best_causal, rmse.at(id));
  for (const auto& id : c.smoothed) best_smoothed = std::min(best_smoothed, rmse.at(id));
  std::printf(
      "%s (%d runs): best causal %.3f, best RTS %.3f, fg-batch %.3f, fg-window %.3f, "
      "online %.3f m\n",
      c.scenario, mc.runs, best_causal, best_smoothed, rmse["fg-batch"], rmse["fg-window"],
      rmse["fg-window-online"]);
  if (testing::kSanitized) return;  // accuracy is judged on the full run count
  EXPECT_LE(rmse["fg-batch"], 0.70 * best_causal);
  EXPECT_LE(rmse["fg-batch"], 0.90 * best_smoothed);
  EXPECT_LE(rmse["fg-window"], 0.80 * best_causal);
  EXPECT_LE(rmse["fg-window-online"], 1.0 * best_causal);
}

INSTANTIATE_TEST_SUITE_P(
    Presets, StepGraphPresetTest,
    ::testing::Values(
        PresetCase{"tarrio-circle",
                   "{duration_s: 60}",
                   {"rss-only", "rss-pdr-reset", "tarrio-kf"},
                   {"tarrio-kf-rts"},
                   50},
        PresetCase{"correa-corridor",
                   "{}",
                   {"correa-ls", "correa-ekf", "correa-scmt-ekf", "tarrio-kf"},
                   {"correa-ekf-rts", "correa-scmt-ekf-rts", "tarrio-kf-rts"},
                   50},
        PresetCase{"correa-classroom",
                   "{laps: 2}",
                   {"correa-ls", "correa-ekf", "correa-scmt-ekf", "tarrio-kf"},
                   {"correa-ekf-rts", "correa-scmt-ekf-rts", "tarrio-kf-rts"},
                   50},
        // 62 anchors at 4 Hz make ≈250 readings/s; at 1 Hz the suite stays in its time budget.
        PresetCase{"gadeke-outage",
                   "{run_length_m: 200, beacon_period_s: 1.0}",
                   {"rss-only", "tarrio-kf", "gadeke-kf"},
                   {"tarrio-kf-rts", "gadeke-kf-rts"},
                   50}),
    [](const ::testing::TestParamInfo<PresetCase>& info) {
      std::string n = info.param.scenario;
      for (char& ch : n) {
        if (ch == '-') ch = '_';
      }
      return n;
    });

// With 20 % of the readings in NLOS episodes 15 dB weaker, the robust smoother stays within
// 1.3× of its clean RMSE (the same seeds, so the same walks apart from the NLOS).
TEST(StepGraphRobustness, NlosOutliersCostAtMostThirtyPercent) {
  CompareOptions options;
  options.estimator_ids = {"fg-batch"};
  MonteCarloOptions mc;
  mc.runs = testing::MonteCarloRuns(50);
  mc.seed = 9;
  double rmse[2] = {0, 0};
  for (int nlos = 0; nlos < 2; ++nlos) {
    const YAML::Node o = YAML::Load(
        nlos ? "{duration_s: 60, nlos_fraction: 0.2, nlos_rss_bias_db: 15}" : "{duration_s: 60}");
    auto cmp = CompareMonteCarlo(
        [&](uint64_t seed) { return SimulateScenario("tarrio-circle", seed, o); }, options, mc);
    ASSERT_TRUE(cmp.ok()) << cmp.status().message();
    ASSERT_TRUE(cmp->outcomes[0].status.ok());
    EXPECT_EQ(cmp->outcomes[0].failed_runs, 0);
    rmse[nlos] = cmp->outcomes[0].stats.rmse_m;
    EXPECT_LT(cmp->outcomes[0].stats.max_m, 5.0);  // never diverges
  }
  std::printf("fg-batch clean %.3f m, 20%% NLOS %.3f m (%.2fx)\n", rmse[0], rmse[1],
              rmse[1] / rmse[0]);
  if (!testing::kSanitized) EXPECT_LE(rmse[1], 1.3 * rmse[0]);
}

// Consistency: the position NEES εₖ = eₖᵀ Pₖ⁻¹ eₖ (2 dof) of fg-batch, averaged over the runs
// at each node and then over the walk, lies in the two-sided 95 % band of χ²(2N)/N.
// The PDR front end's default step-length σ (10 % + 2 cm, for real walkers) is 16× the
// simulated walker's (measured on tarrio-circle: 0.4 cm for 0.45 m steps); a consistency test
// needs the model's σ, so it is set to 1 % + 0.5 cm here.
TEST(StepGraphConsistency, BatchNeesInsideTheChiSquareBand) {
  const int runs = testing::MonteCarloRuns(50);
  auto est = EstimatorRegistry::Builtin().Create(
      "fg-batch", YAML::Load("{pdr: {sigma_length_frac: 0.01, sigma_length_m: 0.005}}"));
  ASSERT_TRUE(est.ok());
  std::vector<double> sum_nees;
  for (int i = 0; i < runs; ++i) {
    auto w =
        SimulateScenario("tarrio-circle", MonteCarloSeed(11, i), YAML::Load("{duration_s: 60}"));
    ASSERT_TRUE(w.ok());
    auto r = (*est)->Run(*w);
    ASSERT_TRUE(r.ok()) << r.status().message();
    size_t j = 0, node = 0;
    for (const TrajectoryPoint& p : r->trajectory.points) {
      if (!p.covariance) continue;
      while (j + 1 < w->truth.size() && w->truth[j + 1].t_s <= p.t_s) ++j;
      if (std::fabs(w->truth[j].t_s - p.t_s) > 1e-3) continue;  // truth at the IMU rate
      const Eigen::Vector2d e = p.position_m.head<2>() - w->truth[j].position_m.head<2>();
      const Eigen::Matrix2d P = p.covariance->topLeftCorner<2, 2>();
      if (sum_nees.size() <= node) sum_nees.resize(node + 1, 0.0);
      sum_nees[node++] += e.dot(P.ldlt().solve(e));
    }
  }
  ASSERT_GT(sum_nees.size(), 50u);
  double mean = 0.0;
  for (double s : sum_nees) mean += s / runs;
  mean /= static_cast<double>(sum_nees.size());
  const double lo = ChiSquareQuantile(0.025, 2 * runs) / runs;
  const double hi = ChiSquareQuantile(0.975, 2 * runs) / runs;
  std::printf("fg-batch ANEES %.3f (95%% band %.3f..%.3f, %d runs)\n", mean, lo, hi, runs);
  if (!testing::kSanitized) {
    EXPECT_GE(mean, lo);
    EXPECT_LE(mean, hi);
  }
}

// Path-loss self-calibration (004 Table II's sweep): the exponent the smoother is configured
// with goes from 1.5 to 4.0 while the simulated building keeps p = 2.3; fg-batch-selfcal's
// RMSE varies by at most 15 % across the sweep and it recovers p within ±0.2 every time.
// 1-lap walks and 10 runs per value keep the suite's time (docs/results.md has the 8-lap figures).
TEST(StepGraphSelfCalibration, ExponentSweepOnTheSimulatedBuilding) {
  const int runs = testing::MonteCarloRuns(10);
  std::vector<double> rmse;
  for (double eta : {1.5, 2.3, 3.0, 4.0}) {
    auto est = EstimatorRegistry::Builtin().Create(
        "fg-batch-selfcal",
        YAML::Load("{receiver_height_m: 1.0, eta: " + std::to_string(eta) + "}"));
    ASSERT_TRUE(est.ok()) << est.status().message();
    double sum_rmse = 0.0, sum_eta = 0.0;
    for (int i = 0; i < runs; ++i) {
      auto w = SimulateScenario("jimenez-building", MonteCarloSeed(4, i), YAML::Load("{laps: 1}"));
      ASSERT_TRUE(w.ok());
      auto r = (*est)->Run(*w);
      ASSERT_TRUE(r.ok()) << r.status().message();
      auto e = ComputeErrors(*w, r->trajectory);
      ASSERT_TRUE(e.ok());
      sum_rmse += SummarizeErrors(e->error_m, w->TruthDistance()).rmse_m;
      sum_eta += r->diagnostics.at("path_loss_eta");
      if (!testing::kSanitized) EXPECT_NEAR(r->diagnostics.at("path_loss_eta"), 2.3, 0.2) << eta;
    }
    rmse.push_back(sum_rmse / runs);
    std::printf("configured eta %.1f: RMSE %.3f m, estimated eta %.3f\n", eta, rmse.back(),
                sum_eta / runs);
  }
  const double lo = *std::min_element(rmse.begin(), rmse.end());
  const double hi = *std::max_element(rmse.begin(), rmse.end());
  if (!testing::kSanitized) EXPECT_LE(hi, 1.15 * lo);
}

// Calibration-free by default (issue 17): a walk whose declared path-loss exponent is 50 % off
// and not declared measured (radio.calibrated: false) is smoothed with (A, η) estimated, so
// fg-batch and fg-window stay within 2× of their RMSE with the right, measured model (mean over
// seeds); declared measured, the wrong model is held exactly as `path_loss: fixed` holds it.
// jimenez-building with 1 lap (the suite's time); docs/walk-format.md has the figures per scenario.
TEST(StepGraphSelfCalibration, AnUncalibratedWrongExponentCostsAtMostTwice) {
  const int runs = testing::MonteCarloRuns(10);
  const auto& reg = EstimatorRegistry::Builtin();
  for (const char* scenario : {"tarrio-circle", "jimenez-building"}) {
    for (const char* id : {"fg-batch", "fg-window"}) {
      auto est = reg.Create(id, YAML::Node());
      auto fixed = reg.Create(id, YAML::Load("{path_loss: fixed}"));
      ASSERT_TRUE(est.ok() && fixed.ok());
      std::map<double, double> rmse;  // by the factor on η (1: nominal)
      for (int i = 0; i < runs; ++i) {
        auto w = SimulateScenario(scenario, MonteCarloSeed(17, i), YAML::Load("{laps: 1}"));
        ASSERT_TRUE(w.ok());
        ASSERT_TRUE(w->meta.radio.calibrated);  // the simulator's model is the true one
        for (double f : {1.0, 0.5, 1.5}) {
          Walk v = *w;
          v.meta.radio.path_loss.eta *= f;
          v.meta.radio.calibrated = f == 1.0;
          auto r = (*est)->Run(v);
          ASSERT_TRUE(r.ok()) << r.status().message();
          EXPECT_EQ(r->diagnostics.at("path_loss_estimated"), f == 1.0 ? 0.0 : 1.0);
          auto e = ComputeErrors(v, r->trajectory);
          ASSERT_TRUE(e.ok());
          rmse[f] += SummarizeErrors(e->error_m, v.TruthDistance()).rmse_m / runs;
        }
        if (i == 0) {  // declared measured: held, as before
          Walk v = *w;
          v.meta.radio.path_loss.eta *= 0.5;
          auto a = (*est)->Run(v);
          auto b = (*fixed)->Run(v);
          ASSERT_TRUE(a.ok() && b.ok());
          ASSERT_EQ(a->trajectory.points.size(), b->trajectory.points.size());
          for (size_t k = 0; k < a->trajectory.points.size(); ++k) {
            ASSERT_EQ(a->trajectory.points[k].position_m, b->trajectory.points[k].position_m);
          }
        }
      }
      std::printf("%s %s: RMSE %.3f m nominal, %.3f m with eta x0.5, %.3f m with eta x1.5\n",
                  scenario, id, rmse[1.0], rmse[0.5], rmse[1.5]);
      EXPECT_LE(rmse[0.5], 2.0 * rmse[1.0]) << scenario << " " << id;
      EXPECT_LE(rmse[1.5], 2.0 * rmse[1.0]) << scenario << " " << id;
    }
  }
}

// Per anchor where the data supports it (issue 17): anchors whose (A, η) spread around the
// declared model (±4 dB, ±0.4, as beacons of one make do) get their own model under auto
// (hierarchical), which must at least halve fg-batch's RMSE against one model for the walk;
// with identical anchors it must cost at most 15 % over the one model (the mean over seeds).
TEST(StepGraphSelfCalibration, AnchorsThatDifferGetTheirOwnPathLoss) {
  const int runs = testing::MonteCarloRuns(6);
  const auto& reg = EstimatorRegistry::Builtin();
  auto est = reg.Create("fg-batch", YAML::Node());
  auto global = reg.Create("fg-batch", YAML::Load("{path_loss: global}"));
  ASSERT_TRUE(est.ok() && global.ok());
  for (const char* spread : {"{A_spread_db: 4, eta_spread: 0.4}", "{}"}) {
    double rmse_auto = 0.0, rmse_global = 0.0;
    for (int i = 0; i < runs; ++i) {
      auto w = SimulateScenario("tarrio-circle", MonteCarloSeed(23, i), YAML::Load(spread));
      ASSERT_TRUE(w.ok());
      w->meta.radio.calibrated = false;  // (the simulator declares a spread walk uncalibrated)
      auto a = (*est)->Run(*w);
      auto g = (*global)->Run(*w);
      ASSERT_TRUE(a.ok() && g.ok());
      EXPECT_EQ(a->diagnostics.count("path_loss_A." + std::to_string(w->anchors[0].id)), 1u);
      EXPECT_EQ(g->diagnostics.count("path_loss_A." + std::to_string(w->anchors[0].id)), 0u);
      for (auto [r, sum] : {std::pair{&*a, &rmse_auto}, std::pair{&*g, &rmse_global}}) {
        auto e = ComputeErrors(*w, r->trajectory);
        ASSERT_TRUE(e.ok());
        *sum += SummarizeErrors(e->error_m, w->TruthDistance()).rmse_m / runs;
      }
    }
    std::printf("tarrio-circle %s: fg-batch RMSE %.3f m per anchor (auto), %.3f m global\n", spread,
                rmse_auto, rmse_global);
    if (std::string(spread) == "{}") {
      EXPECT_LE(rmse_auto, 1.15 * rmse_global);
    } else {
      EXPECT_LE(rmse_auto, 0.5 * rmse_global);
    }
  }
}

// A radio-only walk cannot separate η from the distances: auto holds the path loss there and
// says so.
TEST(StepGraphSelfCalibration, RadioOnlyWalksHoldThePathLossAndSaySo) {
  Walk w;
  w.meta.name = "radio only";
  w.meta.radio.kind = RadioKind::kRss;
  w.anchors = {{1, Eigen::Vector3d(0, 0, 0)},
               {2, Eigen::Vector3d(20, 0, 0)},
               {3, Eigen::Vector3d(0, 20, 0)},
               {4, Eigen::Vector3d(20, 20, 0)}};
  const PathLossParams pl = w.meta.radio.path_loss;
  for (int k = 0; k <= 200; ++k) {
    const double t = 0.1 * k;
    const Eigen::Vector3d p(5.0 + 0.05 * k, 10.0, 0.0);
    w.truth.push_back({t, p, false});
    const Anchor& a = w.anchors[static_cast<size_t>(k % 4)];
    const double d = (a.position_m - p).norm();
    w.rss.push_back({t, a.id, pl.A_dbm - 10.0 * pl.eta * std::log10(d / pl.d0_m)});
  }
  auto est = EstimatorRegistry::Builtin().Create("fg-batch");
  ASSERT_TRUE(est.ok());
  auto r = (*est)->Run(w);
  ASSERT_TRUE(r.ok()) << r.status().message();
  EXPECT_EQ(r->diagnostics.at("path_loss_estimated"), 0.0);
  EXPECT_EQ(r->diagnostics.at("path_loss_held_radio_only"), 1.0);
  EXPECT_EQ(r->diagnostics.count("path_loss_eta"), 0u);
}

// ------------------------------------------------------------------ floors

// fg-batch / fg-window on one seed of the two-floor building: horizontal RMSE, IPIN score,
// floor hit rate over every truth sample (continuous truth at 50 Hz).
ErrorStats FloorRun(const std::string& id, uint64_t seed, const std::string& overrides,
                    const YAML::Node& cfg = YAML::Node(), int* stair_steps = nullptr) {
  auto w = SimulateScenario("two-floor-building", seed, YAML::Load(overrides));
  EXPECT_TRUE(w.ok()) << w.status().message();
  if (!w.ok()) return {};
  auto r = RunId(id, *w, cfg);
  EXPECT_TRUE(r.ok()) << id << ": " << r.status().message();
  if (!r.ok()) return {};
  if (stair_steps != nullptr) *stair_steps = static_cast<int>(r->diagnostics.at("stair_steps"));
  auto e = ComputeErrors(*w, r->trajectory);
  EXPECT_TRUE(e.ok()) << e.status().message();
  return e.ok() ? SummarizeErrors(*e, w->TruthDistance()) : ErrorStats{};
}

// Issue 22: on the simulated two-floor walk (up a dog-leg staircase and back down, the
// barometer drifting 2 hPa/h ≈ 4.7 mm/s plus a random walk) the floor hit rate is ≥ 99 % per
// seed, for fg-batch and fg-window; the horizontal error stays that of a flat walk.
TEST(StepGraphFloors, TwoFloorBuildingHitsTheFloorWithADriftingBarometer) {
  const int seeds = testing::kSanitized ? 1 : 5;
  for (uint64_t seed = 1; seed <= static_cast<uint64_t>(seeds); ++seed) {
    for (const char* id : {"fg-batch", "fg-window"}) {
      int stairs = 0;
      const ErrorStats s = FloorRun(id, seed, "{}", YAML::Node(), &stairs);
      std::printf("seed %d %-9s floor hit %.4f, RMSE %.3f m, IPIN score %.3f m, %d stair steps\n",
                  static_cast<int>(seed), id, s.floor_hit_rate, s.rmse_m, s.ipin_score_m, stairs);
      EXPECT_GE(s.floor_hit_rate, 0.99) << id << " seed " << seed;
      EXPECT_GE(stairs, 30) << id << " seed " << seed;  // of the 40 stair steps
      // Measured (seeds 1–5): fg-batch RMSE 0.64–0.74 m, IPIN 0.63–0.76 m; fg-window
      // 1.15–1.41 m, 1.21–1.65 m.
      const bool batch = std::string(id) == "fg-batch";
      EXPECT_LE(s.rmse_m, batch ? 1.0 : 2.0) << id << " seed " << seed;
      EXPECT_LE(s.ipin_score_m, batch ? 1.0 : 2.0) << id << " seed " << seed;
    }
  }
}

// The drift model matters: with level_sigma_m 0 (the barometer's changes taken as height
// throughout, no floor levels) the drift carries the height off its floor; with the level
// steps it stays, as with a barometer that does not drift.
TEST(StepGraphFloors, LevelStepsHoldTheBarometersDrift) {
  const std::string still = "{baro_drift_hpa_per_h: 0, baro_drift_rw_hpa_per_sqrt_h: 0}";
  const YAML::Node no_level = YAML::Load("{level_sigma_m: 0}");
  const int seeds = testing::kSanitized ? 1 : 5;
  double raw_sum = 0.0;
  for (uint64_t seed = 1; seed <= static_cast<uint64_t>(seeds); ++seed) {
    const ErrorStats drift = FloorRun("fg-batch", seed, "{}");
    const ErrorStats steady = FloorRun("fg-batch", seed, still);
    const ErrorStats drift_raw = FloorRun("fg-batch", seed, "{}", no_level);
    const ErrorStats steady_raw = FloorRun("fg-batch", seed, still, no_level);
    std::printf(
        "seed %d fg-batch floor hit / RMSE / IPIN: drift %.4f %.3f %.3f, no drift %.4f %.3f "
        "%.3f; level off: drift %.4f %.3f %.3f, no drift %.4f %.3f %.3f\n",
        static_cast<int>(seed), drift.floor_hit_rate, drift.rmse_m, drift.ipin_score_m,
        steady.floor_hit_rate, steady.rmse_m, steady.ipin_score_m, drift_raw.floor_hit_rate,
        drift_raw.rmse_m, drift_raw.ipin_score_m, steady_raw.floor_hit_rate, steady_raw.rmse_m,
        steady_raw.ipin_score_m);
    EXPECT_GE(steady.floor_hit_rate, 0.99);
    EXPECT_GE(steady_raw.floor_hit_rate, 0.99);
    EXPECT_GE(drift.floor_hit_rate, 0.99);
    raw_sum += drift_raw.floor_hit_rate;
  }
  if (!testing::kSanitized) EXPECT_LT(raw_sum / seeds, 0.9);
}

// A walk that gives no start floor is not assumed to start on floor 0: the strongest beacons'
// floor is the start's (StepGraph::radio_start_floor). The two-floor walk renumbered to start
// on floor 1 (anchors and truth one floor up) and run without its start: before, fg-batch put it
// on floor 0 (floor hit 0.000-0.002 on seeds 1-3, RMSE 2.18-2.56 m, the beacons a storey off);
// now floor hit 0.997-0.999, RMSE 0.69-0.79 m, as the walk numbered from floor 0 gives. Not the
// online output: it would need readings it has not seen yet (floor 0 there, as before).
TEST(StepGraphFloors, AWalkWithoutAStartFloorTakesTheStrongestBeaconsFloor) {
  const int seeds = testing::kSanitized ? 1 : 3;
  for (uint64_t seed = 1; seed <= static_cast<uint64_t>(seeds); ++seed) {
    auto w = SimulateScenario("two-floor-building", seed, YAML::Load("{}"));
    ASSERT_TRUE(w.ok()) << w.status().message();
    for (const int up : {0, 1}) {
      Walk walk = *w;
      walk.meta.initial_pose.reset();
      for (Anchor& a : walk.anchors) a.floor = *a.floor + up;
      for (TruthSample& t : walk.truth) {
        t.floor = *t.floor + up;
        t.position_m.z() += up * walk.meta.storey_height_m;
      }
      for (const char* id : {"fg-batch", "fg-window"}) {
        auto r = RunId(id, walk, YAML::Node());
        ASSERT_TRUE(r.ok()) << id << ": " << r.status().message();
        auto e = ComputeErrors(walk, r->trajectory);
        ASSERT_TRUE(e.ok()) << e.status().message();
        const ErrorStats s = SummarizeErrors(*e, walk.TruthDistance());
        std::printf(
            "seed %d, start on floor %d, %-9s: start floor found %g, floor hit %.4f, "
            "RMSE %.3f m\n",
            static_cast<int>(seed), up, id, r->diagnostics.at("start_floor_from_radio"),
            s.floor_hit_rate, s.rmse_m);
        EXPECT_EQ(r->diagnostics.at("start_floor_from_radio"), up) << id << " seed " << seed;
        EXPECT_GE(s.floor_hit_rate, 0.99) << id << " seed " << seed << " up " << up;
        EXPECT_LE(s.rmse_m, std::string(id) == "fg-batch" ? 1.0 : 2.0) << id << " seed " << seed;
      }
    }
  }
}

}  // namespace
}  // namespace walkgraph
