#include "walkgraph/smoothers/ins_graph.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <functional>
#include <map>
#include <memory>
#include <string>

#include <ceres/problem.h>
#include <gtest/gtest.h>
#include <Eigen/Eigenvalues>

#include "config/parsers.h"
#include "factors/nav_quaternion_manifold.h"
#include "factors/position_prior_factor.h"
#include "smoothers/ins_graph_internal.h"
#include "test_util.h"
#include "walkgraph/angle.h"
#include "walkgraph/convert.h"
#include "walkgraph/estimator.h"
#include "walkgraph/metrics.h"
#include "walkgraph/simulate.h"
#include "walkgraph/smoothers/ins_window.h"

namespace walkgraph {
namespace {

StatusOr<EstimateResult> RunEstimator(const std::string& id, const Walk& walk,
                                      const std::string& config = "{}") {
  WG_ASSIGN_OR_RETURN(auto est, EstimatorRegistry::Builtin().Create(id, YAML::Load(config)));
  return est->Run(walk);
}

double Rmse(const Walk& walk, const EstimateResult& r, Alignment a = Alignment::kNone) {
  auto e = ComputeErrors(walk, r.trajectory, a);
  EXPECT_TRUE(e.ok()) << e.status().ToString();
  if (!e.ok()) return 1e9;
  return SummarizeErrors(e->error_m, walk.TruthDistance()).rmse_m;
}

// The brief's accuracy criterion: with the walk's radio, the graph is well below the
// strapdown + ZUPT dead reckoning of the same front end.
TEST(InsGraphBatch, WellBelowZuptDeadReckoningOnSimulatedFootPresets) {
  const int runs = testing::MonteCarloRuns(3);
  const std::string laps = testing::kSanitized ? "{laps: 1}" : "{laps: 3}";
  // jimenez-building simulates the reader 1 m above the foot (sim.rx_height_offset_m).
  const std::map<std::string, std::string> config = {
      {"jimenez-building", "{receiver_offset_z_m: 1.0}"}, {"prieto-laps", "{}"}};
  for (const auto& [scenario, cfg] : config) {
    double dr = 0.0, graph = 0.0;
    for (int i = 0; i < runs; ++i) {
      auto w = SimulateScenario(scenario, 200 + i, YAML::Load(laps));
      ASSERT_TRUE(w.ok()) << w.status().ToString();
      auto a = RunEstimator("zupt-ins", *w);
      auto b = RunEstimator("fg-ins-batch", *w, cfg);
      ASSERT_TRUE(a.ok()) << a.status().ToString();
      ASSERT_TRUE(b.ok()) << b.status().ToString();
      EXPECT_GT(b->diagnostics.at("num_radio_factors"), 0.0);
      const double ra = Rmse(*w, *a), rb = Rmse(*w, *b);
      std::printf("%s seed %d %s: zupt-ins %.3f m, fg-ins-batch %.3f m RMSE\n", scenario.c_str(),
                  200 + i, laps.c_str(), ra, rb);
      dr += ra / runs;
      graph += rb / runs;
    }
    std::printf("%s mean RMSE: zupt-ins %.3f m, fg-ins-batch %.3f m (ratio %.2f)\n",
                scenario.c_str(), dr, graph, graph / dr);
    if (!testing::kSanitized) EXPECT_LT(graph, 0.6 * dr) << scenario;
  }
}

// Issue 21's target on the simulated foot presets: with every estimator's defaults, the mean
// RMSE of fg-ins-batch over 10 seeds (the presets' full walks: 8 laps) is at most 0.8x that of
// the best foot filter's RTS smoother. Measured: jimenez-building 0.194 m against
// prieto-ukf-rts 0.331 m (0.59x; per seed 0.34-0.87x, and 1.20x on seed 10);
// prieto-laps 0.304 m against 0.668 m (0.45x; per seed 0.44-0.59x). With the stance
// magnetometer (InsGraphOptions::use_stance_magnetometer): 0.149 m (0.45x) and 0.233 m (0.35x).
void ExpectBelowTheBestFootRts(const std::string& scenario, const std::vector<std::string>& rts,
                               const std::string& config = "{}") {
  const int runs = testing::MonteCarloRuns(10);
  std::map<std::string, double> mean;
  for (int seed = 1; seed <= runs; ++seed) {
    auto w = SimulateScenario(scenario, seed, YAML::Load(config));
    ASSERT_TRUE(w.ok()) << w.status().ToString();
    std::printf("%s %s seed %d:", scenario.c_str(), config.c_str(), seed);
    std::vector<std::string> ids = rts;
    ids.push_back("fg-ins-batch");
    for (const std::string& id : ids) {
      auto r = RunEstimator(id, *w);
      ASSERT_TRUE(r.ok()) << id << ": " << r.status().ToString();
      const double rmse = Rmse(*w, *r);
      std::printf(" %s %.3f", id.c_str(), rmse);
      mean[id] += rmse / runs;
    }
    std::printf("\n");
  }
  std::string best = rts.front();
  for (const std::string& id : rts) {
    if (mean[id] < mean[best]) best = id;
  }
  std::printf("%s %s mean RMSE over %d seeds: fg-ins-batch %.3f m, best RTS %s %.3f m (%.2fx)\n",
              scenario.c_str(), config.c_str(), runs, mean["fg-ins-batch"], best.c_str(),
              mean[best], mean["fg-ins-batch"] / mean[best]);
  if (!testing::kSanitized) EXPECT_LE(mean["fg-ins-batch"], 0.8 * mean[best]) << scenario;
}

TEST(InsGraphBatch, BelowTheBestFootRtsOnJimenezBuilding) {
  ExpectBelowTheBestFootRts("jimenez-building", {"prieto-ekf-rts", "prieto-ukf-rts",
                                                 "jimenez-iez-rts", "jimenez-iez-rss-rts"});
}

// jimenez-iez-rss holds 004's RFCode path-loss model, which prieto-laps' dBm radio does not fit.
TEST(InsGraphBatch, BelowTheBestFootRtsOnPrietoLaps) {
  ExpectBelowTheBestFootRts("prieto-laps", {"prieto-ekf-rts", "prieto-ukf-rts", "jimenez-iez-rts"});
}

// Issue 40's target on the simulator's other gaits (seeds 1-10; running 8 laps, stairs 3 laps
// to keep the slow set short): fg-ins-batch at most 0.8x the best foot filter's RTS. Measured:
// jimenez-building run 0.170 m against prieto-ekf-rts 0.233 m (0.73x), stairs 0.197 against
// prieto-ukf-rts 0.606 (0.33x); prieto-laps run 0.233 against jimenez-iez-rts 0.446 (0.52x),
// stairs 0.246 against prieto-ukf-rts 1.085 (0.23x). With `compare --runs 10 --seed 1` (other
// seeds) prieto-laps running gives 0.87x (docs/results.md): its jimenez-iez-rts (compass with
// the true north given) varies more than the graph.
TEST(InsGraphBatch, BelowTheBestFootRtsOnJimenezBuildingRunning) {
  ExpectBelowTheBestFootRts(
      "jimenez-building",
      {"prieto-ekf-rts", "prieto-ukf-rts", "jimenez-iez-rts", "jimenez-iez-rss-rts"},
      "{gait: run}");
}

TEST(InsGraphBatch, BelowTheBestFootRtsOnJimenezBuildingStairs) {
  ExpectBelowTheBestFootRts(
      "jimenez-building",
      {"prieto-ekf-rts", "prieto-ukf-rts", "jimenez-iez-rts", "jimenez-iez-rss-rts"},
      "{gait: stairs, laps: 3}");
}

TEST(InsGraphBatch, BelowTheBestFootRtsOnPrietoLapsRunning) {
  ExpectBelowTheBestFootRts("prieto-laps", {"prieto-ekf-rts", "prieto-ukf-rts", "jimenez-iez-rts"},
                            "{gait: run}");
}

TEST(InsGraphBatch, BelowTheBestFootRtsOnPrietoLapsStairs) {
  ExpectBelowTheBestFootRts("prieto-laps", {"prieto-ekf-rts", "prieto-ukf-rts", "jimenez-iez-rts"},
                            "{gait: stairs, laps: 3}");
}

// PyShoe VICON trial 2017-11-22-11-48-35. The converter negates the Vicon y (its x-y is
// left-handed; see src/convert/pyshoe.cc), so the walk is scored as converted. Stance
// threshold and point-sample convention for this 200 Hz VN-100.
TEST(InsGraphBatch, PyshoeViconTrial) {
  const std::string csv =
      std::string(WALKGRAPH_SHARED_DATASETS) + "/pyshoe_vicon/2017-11-22-11-48-35.csv";
  if (!std::filesystem::exists(csv)) GTEST_SKIP() << csv << " not present";
  auto w = Convert("pyshoe", {csv});
  ASSERT_TRUE(w.ok()) << w.status().ToString();
  const std::string front =
      "{front_end: {sampling: instantaneous, gyro_noise_radps: 0.01, stance: {glrt_threshold: "
      "1e5}}}";
  auto dr = RunEstimator("zupt-ins", *w, front);
  auto graph = RunEstimator("fg-ins-batch", *w, front);
  ASSERT_TRUE(dr.ok()) << dr.status().ToString();
  ASSERT_TRUE(graph.ok()) << graph.status().ToString();
  const double a = Rmse(*w, *dr, Alignment::kSE2), b = Rmse(*w, *graph, Alignment::kSE2);
  std::printf("pyshoe 2017-11-22-11-48-35 (align-se2): zupt-ins %.3f m, fg-ins-batch %.3f m\n", a,
              b);
  EXPECT_LT(b, 0.10);
  EXPECT_LT(b, a);
  // No initial_pose: the gauge prior holds the first state at the origin.
  EXPECT_LT(graph->trajectory.points.front().position_m.head<2>().norm(), 0.01);
}

// A stance detector that over-detects (its threshold moved toward the swing class) puts
// ZUPTs inside swings; the robust ZUPT (InsGraphOptions::zupt_loss, Cauchy at 10σ by default)
// turns them down: fg-ins-batch stays near its RMSE with the right detector, while the
// quadratic ZUPT stops the foot mid-swing (3-lap walks, 8 seeds: 0.94–1.17 m; robust within
// 0.003 m of the right detector's 0.15–0.40 m). The IMU's scale noise is held at 0 here
// (scale_noise_adaptation: fixed) so that the ZUPT loss alone is tested: its adaptation reads
// the false stances' first-ZUPT NIS as a model that does not fit and raises the IMU noise to
// 0.05, which lets the false ZUPTs pull harder (issue 40, seeds 1 / 2: robust ZUPT 0.254 /
// 0.445 m against the right detector's 0.106 / 0.277 m; quadratic 0.912 / 1.118 m).
TEST(InsGraphBatch, RobustZuptSurvivesFalseStanceDetections) {
  const std::string over =
      "front_end: {scale_noise_adaptation: fixed, stance: {adaptive_fraction: 0.8}}";
  for (int seed : {1, 2}) {
    auto w = SimulateScenario("jimenez-building", seed, YAML::Load("{laps: 1}"));
    ASSERT_TRUE(w.ok()) << w.status().ToString();
    auto right = RunEstimator("fg-ins-batch", *w, "{front_end: {scale_noise_adaptation: fixed}}");
    auto robust = RunEstimator("fg-ins-batch", *w, "{" + over + "}");
    auto quadratic = RunEstimator("fg-ins-batch", *w, "{zupt_loss: none, " + over + "}");
    ASSERT_TRUE(right.ok() && robust.ok() && quadratic.ok());
    const double r0 = Rmse(*w, *right), r1 = Rmse(*w, *robust), r2 = Rmse(*w, *quadratic);
    std::printf(
        "seed %d: right detector %.3f m; over-detecting: robust ZUPT %.3f m, "
        "quadratic %.3f m RMSE\n",
        seed, r0, r1, r2);
    EXPECT_LT(r1, 1.25 * r0) << "seed " << seed;
    EXPECT_GT(r2, 2.0 * r0) << "seed " << seed << ": the detector no longer over-detects";
  }
}

TEST(InsGraphBatch, CovarianceIsReportedAndRoughlyConsistent) {
  auto w = SimulateScenario("jimenez-building", 5, YAML::Load("{laps: 1}"));
  ASSERT_TRUE(w.ok());
  // The simulator's initial_pose is the true start with σ = 0.5 m, 5°: draw the start the
  // estimator is given from that σ, so that the prior is a fair one.
  InitialPose& p0 = *w->meta.initial_pose;
  p0.x_m += 0.5 * p0.sigma_xy_m;
  p0.y_m -= 0.8 * p0.sigma_xy_m;
  p0.heading_rad += 0.6 * p0.sigma_heading_rad;
  auto r = RunEstimator("fg-ins-batch", *w, "{receiver_offset_z_m: 1.0}");
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  EXPECT_EQ(r->diagnostics.at("covariance_ok"), 1.0);
  ASSERT_GT(r->trajectory.size(), 100u);
  double nees = 0.0;
  int n = 0;
  size_t j = 0;
  for (size_t i = 0; i < r->trajectory.size(); ++i) {
    const TrajectoryPoint& p = r->trajectory.points[i];
    if (i > 0) EXPECT_GT(p.t_s, r->trajectory.points[i - 1].t_s);
    ASSERT_TRUE(p.covariance.has_value());
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(*p.covariance);
    EXPECT_GT(eig.eigenvalues().minCoeff(), 0.0);
    EXPECT_LT((*p.covariance - p.covariance->transpose()).norm(), 1e-12);
    while (j + 1 < w->truth.size() && w->truth[j].t_s < p.t_s) ++j;
    const Eigen::Vector2d e = p.position_m.head<2>() - w->truth[j].position_m.head<2>();
    nees += e.dot(p.covariance->topLeftCorner<2, 2>().inverse() * e);
    ++n;
  }
  nees /= n;
  std::printf("mean position NEES %.2f (2 for a consistent estimate)\n", nees);
  // The errors of one walk are one draw, correlated in time: only a broad band around 2.
  // Measured 0.33 (0.56 with rss_loss: none; the Cauchy loss lowers every reading's weight).
  EXPECT_GT(nees, 0.1);
  EXPECT_LT(nees, 10.0);
}

TEST(InsGraphBatch, RankDeficientCovarianceIsADiagnosticNotAFailure) {
  // Standing still without bias priors or ZARU: the horizontal accelerometer bias trades with
  // the tilt, and the yaw of later states with the z gyro bias — the information is singular.
  Walk w;
  w.meta.imu_placement = ImuPlacement::kFoot;
  for (int i = 0; i < 400; ++i) {
    ImuSample s;
    s.t_s = 0.01 * i;
    s.acc_mps2 = Eigen::Vector3d(0.0, 0.0, 9.81);
    w.imu.push_back(s);
  }
  auto r = RunEstimator("fg-ins-batch", w, "{use_bias_prior: false, use_zaru: false}");
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  EXPECT_EQ(r->diagnostics.at("covariance_ok"), 0.0);
  ASSERT_FALSE(r->trajectory.empty());
  for (const TrajectoryPoint& p : r->trajectory.points) {
    EXPECT_FALSE(p.covariance.has_value());
    EXPECT_LT(p.position_m.norm(), 1e-3);
  }
}

// The incremental building blocks make the same graph as one batch call: same factors, same
// cost at the same values.
TEST(InsGraphBatch, SegmentFactorsComposeToTheBatchGraph) {
  auto w = SimulateScenario("prieto-laps", 9, YAML::Load("{duration_s: 40}"));
  ASSERT_TRUE(w.ok());
  InsGraphOptions o;
  auto front = RunZuptIns(*w, o.front_end);
  ASSERT_TRUE(front.ok());
  auto states = InitialInsStates(*w, *front, o);
  ASSERT_TRUE(states.ok());
  ASSERT_GT(states->size(), 12u);
  InsGraphContext c;
  c.walk = &*w;
  c.still = &front->stance.still;
  c.path = &front->states;
  c.options = o;
  auto cost_of = [&](const std::vector<std::pair<size_t, size_t>>& segments,
                     std::map<std::string, int>* counts) {
    std::vector<InsState> s = *states;
    InsSharedBlocks radio;
    InsKeyMap keys(*w, o, &radio);
    FactorGraph graph;
    const auto m = std::make_shared<NavQuaternionManifold>();
    for (size_t i = 0; i < s.size(); ++i) {
      keys.RegisterState(i, &s[i]);
      for (GraphState& st : InsStateBlocks(i, s[i], m)) EXPECT_TRUE(graph.AddState(st).ok());
    }
    for (const auto& [k, n] : segments) {
      auto f = InsSegmentFactors(c, &s, k, n);
      auto rf = InsRadioFactors(c, &s, k, n, &radio);
      EXPECT_TRUE(f.ok() && rf.ok());
      for (InsFactor& x : *f) rf->push_back(std::move(x));
      for (InsFactor& x : *rf) {
        ++(*counts)[ToString(x.kind)];
        std::vector<GraphState> shared;
        auto g = keys.ToGraphFactor(&x, &shared);
        EXPECT_TRUE(g.ok());
        for (GraphState& st : shared) EXPECT_TRUE(graph.AddState(st).ok());
        EXPECT_TRUE(graph.AddFactor(*g).ok());
      }
    }
    double cost = 0.0;  // ½ Σ ‖r‖², without the robust losses
    for (size_t i = 0; i < graph.num_factors(); ++i) {
      auto r = graph.FactorResiduals(i);
      EXPECT_TRUE(r.ok());
      cost += 0.5 * r->squaredNorm();
    }
    return cost;
  };
  const size_t last = states->size() - 1;
  std::map<std::string, int> whole, split;
  const double a = cost_of({{0, last}}, &whole);
  const double b = cost_of({{0, 5}, {5, 4}, {9, last - 9}}, &split);
  EXPECT_EQ(whole, split);
  EXPECT_NEAR(a, b, 1e-9 * a);
  EXPECT_EQ(whole["imu"], static_cast<int>(last));
  EXPECT_EQ(whole["prior"], 1);
  EXPECT_GT(whole["rss"] + whole["range"], 0);
  EXPECT_FALSE(InsSegmentFactors(c, &*states, last, 1).ok());
}

// A simulated walk with a hole in its IMU stream from begin_s after its start, for length_s;
// the front end on it, the graph's initial states, their factor context, and the last state
// before the hole. `edit` changes the walk before the front end runs. Heap-held: the context
// points into the walk and the front end.
struct GapSetup {
  Walk walk;
  ZuptInsSolution front;
  std::vector<InsState> states;
  InsGraphContext context;
  size_t before = 0;
  double gap_begin = 0.0, gap_end = 0.0;
};
std::unique_ptr<GapSetup> MakeGapSetup(const std::string& scenario, uint64_t seed,
                                       const std::string& overrides, double begin_s,
                                       double length_s, const InsGraphOptions& o,
                                       const std::function<void(Walk*)>& edit = nullptr) {
  auto w = SimulateScenario(scenario, seed, YAML::Load(overrides));
  EXPECT_TRUE(w.ok());
  if (!w.ok()) return nullptr;
  auto g = std::make_unique<GapSetup>();
  g->walk = std::move(*w);
  g->gap_begin = g->walk.StartTime() + begin_s;
  g->gap_end = g->gap_begin + length_s;
  std::vector<ImuSample> kept;
  for (const ImuSample& s : g->walk.imu) {
    if (s.t_s < g->gap_begin || s.t_s >= g->gap_end) kept.push_back(s);
  }
  g->walk.imu = kept;
  if (edit) edit(&g->walk);
  auto front = RunZuptIns(g->walk, o.front_end);
  EXPECT_TRUE(front.ok());
  if (!front.ok()) return nullptr;
  g->front = std::move(*front);
  auto states = InitialInsStates(g->walk, g->front, o);
  EXPECT_TRUE(states.ok());
  if (!states.ok()) return nullptr;
  g->states = std::move(*states);
  g->context.walk = &g->walk;
  g->context.still = &g->front.stance.still;
  g->context.path = &g->front.states;
  g->context.options = o;
  g->context.imu_gap_s = ImuGapThresholdS(g->walk.imu);
  while (g->before + 1 < g->states.size() && g->states[g->before + 1].t_s < g->gap_begin) {
    ++g->before;
  }
  EXPECT_LT(g->before + 1, g->states.size());
  EXPECT_GE(g->states[g->before + 1].t_s, g->gap_end);
  return g;
}

// A reading inside an IMU gap sits between the states around the gap, interpolated by time:
// the front end's path stands still across a gap, so its progress (the interpolation used
// elsewhere) would put every reading of the gap onto the state before it. Measured on the 10 s
// gap of Robustness.FootInsGraphBridgesAnImuGap: fg-ins-window-online 4.19x → 2.25x nominal.
TEST(InsGraphBatch, ReadingsInAnImuGapAreInterpolatedAcrossIt) {
  auto g = MakeGapSetup("prieto-laps", 9, "{duration_s: 40}", 15.0, 6.0, InsGraphOptions());
  ASSERT_TRUE(g);
  const Walk* w = &g->walk;
  const InsGraphContext& c = g->context;
  std::vector<InsState>* states = &g->states;
  const size_t before = g->before;
  const double gap_begin = g->gap_begin, gap_end = g->gap_end;
  InsSharedBlocks radio;
  auto f = InsRadioFactors(c, states, 0, states->size() - 1, &radio);
  ASSERT_TRUE(f.ok());
  std::vector<const RssSample*> readings;
  for (const RssSample& r : w->rss) {
    if (r.t_s >= (*states)[0].t_s && r.t_s <= states->back().t_s) readings.push_back(&r);
  }
  size_t next = 0, inside = 0;
  for (const InsFactor& x : *f) {
    if (x.kind != InsFactorKind::kRss) continue;
    ASSERT_LT(next, readings.size());
    const double t = readings[next++]->t_s;
    if (t < gap_begin + 1.0 || t > gap_end - 1.0) continue;
    ++inside;
    ASSERT_EQ(x.blocks.size(), 3u) << "t " << t << ": not interpolated";
    EXPECT_EQ(x.blocks[0], (*states)[before].p.data());
    EXPECT_EQ(x.blocks[1], (*states)[before + 1].p.data());
  }
  EXPECT_EQ(next, readings.size());
  EXPECT_GT(inside, 10u);
}

// Across an IMU gap the segment's factors include the reach bound and, with a magnetometer,
// the magnetic yaw tie (InsGraphOptions::use_gap_reach, use_gap_magnetometer), learnt from the
// walk before the gap; a segment without a gap has neither.
TEST(InsGraphBatch, GapFactorsTieTheStatesEitherSideOfAnImuGap) {
  auto count = [](const std::vector<InsFactor>& f, InsFactorKind kind) {
    return std::count_if(f.begin(), f.end(), [kind](const InsFactor& x) { return x.kind == kind; });
  };
  // The factors of the segment across the gap; those of the segment before it are the same
  // less the gap's.
  auto across_gap = [&count](GapSetup* g) {
    std::vector<InsState>& s = g->states;
    auto across = InsBetweenFactors(g->context, &s[g->before], &s[g->before + 1]);
    auto plain = InsBetweenFactors(g->context, &s[g->before - 1], &s[g->before]);
    EXPECT_TRUE(across.ok() && plain.ok());
    EXPECT_EQ(plain->size(), across->size() - count(*across, InsFactorKind::kGapReach) -
                                 count(*across, InsFactorKind::kGapMagneticHeading));
    return std::move(*across);
  };
  InsGraphOptions o;
  auto g = MakeGapSetup("jimenez-building", 4, "{duration_s: 80}", 45.0, 10.0, o);
  ASSERT_TRUE(g);
  std::vector<InsFactor> f = across_gap(g.get());
  ASSERT_EQ(count(f, InsFactorKind::kGapReach), 1);
  ASSERT_EQ(count(f, InsFactorKind::kGapMagneticHeading), 1);
  InsState a = g->states[g->before], b = g->states[g->before + 1];
  auto truth_at = [&g](double t) {  // the truth sample at or after t (100 Hz)
    auto it = std::lower_bound(g->walk.truth.begin(), g->walk.truth.end(), t,
                               [](const TruthSample& s, double x) { return s.t_s < x; });
    return it->position_m;
  };
  const double truth_chord = (truth_at(b.t_s) - truth_at(a.t_s)).head<2>().norm();
  for (const InsFactor& x : f) {
    double r = NAN;
    if (x.kind == InsFactorKind::kGapReach) {
      // The walker's own pace: the true chord (a straight leg) is within the reach, three
      // times it is not.
      a.p = {0, 0, 0};
      b.p = {truth_chord, 0, 0};
      double* blocks[2] = {a.p.data(), b.p.data()};
      ASSERT_TRUE(x.cost->Evaluate(blocks, &r, nullptr));
      EXPECT_EQ(r, 0.0) << "chord " << truth_chord;
      b.p = {0, 3.0 * truth_chord, 0};
      ASSERT_TRUE(x.cost->Evaluate(blocks, &r, nullptr));
      EXPECT_GT(r, 3.0);
    } else if (x.kind == InsFactorKind::kGapMagneticHeading) {
      // The gap is on a straight leg: the same yaw either side fits (within 3σ); a 90° turn
      // costs over 5σ (the σ learnt from 35 s of walking: 0.2 rad, measured).
      b.q = a.q;
      double* blocks[2] = {a.q.data(), b.q.data()};
      ASSERT_TRUE(x.cost->Evaluate(blocks, &r, nullptr));
      EXPECT_LT(std::fabs(r), 3.0);
      const Eigen::Quaterniond turned =
          Eigen::Quaterniond(Eigen::AngleAxisd(kPi / 2, Eigen::Vector3d::UnitZ())) * a.attitude();
      b.q = {turned.x(), turned.y(), turned.z(), turned.w()};
      ASSERT_TRUE(x.cost->Evaluate(blocks, &r, nullptr));
      EXPECT_GT(std::fabs(r), 5.0);
    }
  }
  o.use_gap_reach = false;
  f = across_gap(MakeGapSetup("jimenez-building", 4, "{duration_s: 80}", 45.0, 10.0, o).get());
  EXPECT_EQ(count(f, InsFactorKind::kGapReach), 0);
  EXPECT_EQ(count(f, InsFactorKind::kGapMagneticHeading), 1);
  o.use_gap_reach = true;
  f = across_gap(
      MakeGapSetup("jimenez-building", 4, "{duration_s: 80}", 45.0, 10.0, o, [](Walk* w) {
        for (ImuSample& s : w->imu) s.has_mag = false;
      }).get());
  EXPECT_EQ(count(f, InsFactorKind::kGapReach), 1);
  EXPECT_EQ(count(f, InsFactorKind::kGapMagneticHeading), 0);
}

// A walk with no standstill at all (jimenez-building, 40 s, start_still_s and end_still_s 0),
// the IMU alone (magnetometer, radio and start removed, scored after SE(2) alignment): no ZARU
// ties the gyro bias, and with one ZUPT per stance state the bias about the foot's vertical went
// unobserved. The levelling factor at every ZUPT state (use_stance_level) observes it through
// the tilt the stances show. Measured by the CLI, seeds 1-8 (RMSE, m): fg-ins-batch 0.006-0.028
// with it, 0.008-1.59 without; fg-ins-window 0.011-0.034 with, 0.074-1.56 without;
// jimenez-iez-rts 0.020-0.070.
TEST(InsGraphBatch, LevellingAtStancesHoldsAWalkWithoutRest) {
  const int runs = testing::kSanitized ? 1 : 3;
  for (int seed = 1; seed <= runs; ++seed) {
    auto w = testing::FootWalkWithoutRest(seed);
    ASSERT_TRUE(w.ok()) << w.status().ToString();
    std::map<std::string, double> with, without;
    for (const char* id : {"fg-ins-batch", "fg-ins-window"}) {
      auto a = RunEstimator(id, *w);
      auto b = RunEstimator(id, *w, "{use_stance_level: false}");
      ASSERT_TRUE(a.ok() && b.ok()) << id;
      with[id] = Rmse(*w, *a, Alignment::kSE2);
      without[id] = Rmse(*w, *b, Alignment::kSE2);
    }
    auto rts = RunEstimator("jimenez-iez-rts", *w);
    ASSERT_TRUE(rts.ok()) << rts.status().ToString();
    const double r = Rmse(*w, *rts, Alignment::kSE2);
    std::printf(
        "no rest, seed %d: fg-ins-batch %.3f m (%.3f without levelling), fg-ins-window %.3f "
        "(%.3f), jimenez-iez-rts %.3f\n",
        seed, with["fg-ins-batch"], without["fg-ins-batch"], with["fg-ins-window"],
        without["fg-ins-window"], r);
    EXPECT_LT(with["fg-ins-batch"], 0.05) << seed;
    EXPECT_LT(with["fg-ins-window"], 0.05) << seed;
    EXPECT_LE(with["fg-ins-batch"], r) << seed;
    EXPECT_GT(without["fg-ins-batch"], 0.2) << seed;  // the failure is still in the walk
  }
}

// The stance magnetometer on running (prieto-laps, 3 laps at a run): the heading no longer
// drifts. Measured on seeds 1-4: fg-ins-batch 0.266/0.171/0.258/0.235 m RMSE with it,
// 0.311/0.171/0.278/0.235 m without (mean 0.93x); 68 factors on 155 strides (stances 3 m
// apart, none before 20 pairs). (Before the levelling factor at stances, use_stance_level,
// which holds the gyro bias the heading drifts with: 0.312/0.179/0.265/0.232 with it,
// 0.476/0.179/0.348/0.233 without, 0.80x.) A walk without a magnetometer gets none.
TEST(InsGraphBatch, StanceMagnetometerHoldsTheHeadingOfARun) {
  const int runs = testing::kSanitized ? 1 : 4;
  double with = 0.0, without = 0.0;
  for (int seed = 1; seed <= runs; ++seed) {
    auto w = SimulateScenario("prieto-laps", seed, YAML::Load("{gait: run, laps: 3}"));
    ASSERT_TRUE(w.ok()) << w.status().ToString();
    auto a = RunEstimator("fg-ins-batch", *w);
    auto b = RunEstimator("fg-ins-batch", *w, "{use_stance_magnetometer: false}");
    ASSERT_TRUE(a.ok() && b.ok());
    const double strides = a->diagnostics.at("num_strides");
    const double factors = a->diagnostics.at("num_stance_magnetic_factors");
    EXPECT_GT(factors, 0.25 * strides);  // one per 3 m at most (a stride ~2 m), none before
    EXPECT_LE(factors, strides + 1.0);
    const double sigma = a->diagnostics.at("stance_magnetic_sigma_rad");
    EXPECT_GE(sigma, InsGraphOptions().stance_magnetic_min_sigma_rad);
    EXPECT_LT(sigma, 0.3);
    EXPECT_EQ(b->diagnostics.at("num_stance_magnetic_factors"), 0.0);
    const double ra = Rmse(*w, *a), rb = Rmse(*w, *b);
    std::printf(
        "prieto-laps run seed %d: fg-ins-batch %.3f m with the stance magnetometer, "
        "%.3f m without (sigma %.3f rad, %.0f factors)\n",
        seed, ra, rb, sigma, factors);
    EXPECT_LE(ra, 1.05 * rb) << seed;
    with += ra / runs;
    without += rb / runs;
  }
  if (!testing::kSanitized) EXPECT_LE(with, 0.96 * without);
  auto w = SimulateScenario("prieto-laps", 1, YAML::Load("{gait: run, laps: 1}"));
  ASSERT_TRUE(w.ok());
  for (ImuSample& s : w->imu) s.has_mag = false;
  auto c = RunEstimator("fg-ins-batch", *w);
  ASSERT_TRUE(c.ok()) << c.status().ToString();
  EXPECT_EQ(c->diagnostics.at("num_stance_magnetic_factors"), 0.0);
  EXPECT_EQ(c->diagnostics.count("stance_magnetic_sigma_rad"), 0u);
  // A magnetometer that reads zero, or a vertical field (no direction to read): no factor, and
  // the solve still succeeds.
  for (const Eigen::Vector3d& field :
       std::vector<Eigen::Vector3d>{Eigen::Vector3d::Zero(), Eigen::Vector3d(0, 0, -45)}) {
    for (ImuSample& s : w->imu) {
      s.has_mag = true;
      s.mag_ut = field;
    }
    auto z = RunEstimator("fg-ins-batch", *w);
    ASSERT_TRUE(z.ok()) << z.status().ToString();
    EXPECT_EQ(z->diagnostics.at("num_stance_magnetic_factors"), 0.0);
  }
}

TEST(InsGraphBatch, SameInputSameOutputAndEveryNPlacement) {
  auto w = SimulateScenario("jimenez-building", 2, YAML::Load("{duration_s: 30}"));
  ASSERT_TRUE(w.ok());
  auto a = RunEstimator("fg-ins-batch", *w);
  auto b = RunEstimator("fg-ins-batch", *w);
  ASSERT_TRUE(a.ok() && b.ok());
  ASSERT_EQ(a->trajectory.size(), b->trajectory.size());
  for (size_t i = 0; i < a->trajectory.size(); ++i) {
    EXPECT_EQ(a->trajectory.points[i].position_m, b->trajectory.points[i].position_m);
  }
  auto n = RunEstimator("fg-ins-batch", *w, "{placement: every-n, every_n_samples: 25}");
  ASSERT_TRUE(n.ok()) << n.status().ToString();
  // One state every 25 samples (plus the last).
  EXPECT_NEAR(n->diagnostics.at("num_states"), std::ceil(w->imu.size() / 25.0) + 1, 1.0);
  EXPECT_LT(Rmse(*w, *n), 1.0);
}

TEST(InsGraphBatch, OptionsAndApplicability) {
  EXPECT_FALSE(InsGraphOptionsFromYaml(YAML::Load("{placement: sometimes}")).ok());
  EXPECT_FALSE(InsGraphOptionsFromYaml(YAML::Load("{rss_loss: Tukey}")).ok());
  // The graphs share one list of losses.
  EXPECT_TRUE(InsGraphOptionsFromYaml(YAML::Load("{rss_loss: tukey}")).ok());
  EXPECT_FALSE(InsGraphOptionsFromYaml(YAML::Load("{every_n_samples: 0}")).ok());
  EXPECT_FALSE(InsGraphOptionsFromYaml(YAML::Load("{zupt_sigma: 0.01}")).ok());
  EXPECT_FALSE(InsGraphOptionsFromYaml(YAML::Load("{initialization: truth}")).ok());
  EXPECT_FALSE(InsGraphOptionsFromYaml(YAML::Load("{init_lag_s: 0}")).ok());
  EXPECT_FALSE(InsGraphOptionsFromYaml(YAML::Load("{initial_trust_region_radius: 0}")).ok());
  auto o = InsGraphOptionsFromYaml(
      YAML::Load("{front_end: {zupt_sigma_mps: 0.02}, output_rate_hz: 10, range_loss: huber}"));
  ASSERT_TRUE(o.ok()) << o.status().ToString();
  EXPECT_DOUBLE_EQ(o->front_end.zupt_sigma_mps, 0.02);
  EXPECT_EQ(o->range_loss, LossKind::kHuber);
  auto waist = SimulateScenario("tarrio-circle", 1, YAML::Load("{duration_s: 20}"));
  ASSERT_TRUE(waist.ok());
  auto est = EstimatorRegistry::Builtin().Create("fg-ins-batch");
  ASSERT_TRUE(est.ok());
  EXPECT_FALSE((*est)->CheckApplicable(*waist).ok());
  EXPECT_FALSE((*est)->Run(*waist).ok());
  EXPECT_NE(EstimatorRegistry::Builtin().Find("zupt-ins"), nullptr);
}

// Calibration-free by default (issue 17): with the declared exponent 50 % off and the radio not
// declared calibrated, the foot-INS graph estimates (A, η) and stays within 2× of its RMSE with
// the right, declared-measured model (measured 0.108 → 0.152 / 0.150 m on seed 1).
TEST(InsGraphBatch, AnUncalibratedWrongExponentIsEstimated) {
  auto w = SimulateScenario("jimenez-building", 1, YAML::Load("{laps: 1}"));
  ASSERT_TRUE(w.ok());
  ASSERT_TRUE(w->meta.radio.calibrated);
  auto nominal = RunEstimator("fg-ins-batch", *w);
  ASSERT_TRUE(nominal.ok()) << nominal.status().message();
  EXPECT_EQ(nominal->diagnostics.at("path_loss_estimated"), 0.0);
  for (double f : {0.5, 1.5}) {
    Walk v = *w;
    v.meta.radio.path_loss.eta *= f;
    v.meta.radio.calibrated = false;
    auto r = RunEstimator("fg-ins-batch", v);
    ASSERT_TRUE(r.ok()) << r.status().message();
    EXPECT_EQ(r->diagnostics.at("path_loss_estimated"), 1.0);
    // Identical anchors: auto's χ² test keeps one model for the walk (measured T = 49 for 66
    // anchors, critical 107).
    EXPECT_EQ(r->diagnostics.at("path_loss_per_anchor"), 0.0) << f;
    EXPECT_NEAR(r->diagnostics.at("path_loss_eta"), 2.3, 0.4) << f;  // the simulator's η
    std::printf("eta x%.1f: RMSE %.3f m (nominal %.3f m), estimated eta %.2f\n", f, Rmse(v, *r),
                Rmse(*w, *nominal), r->diagnostics.at("path_loss_eta"));
    EXPECT_LE(Rmse(v, *r), 2.0 * Rmse(*w, *nominal)) << f;
  }
  EXPECT_FALSE(
      EstimatorRegistry::Builtin().Create("fg-ins-batch", YAML::Load("{path_loss: x}")).ok());
}

// path_loss: hierarchical (an option for the foot INS): with anchors whose (A, η) spread
// ±4 dB / ±0.4 around the declared model, a path loss per anchor tied to the walk's mean beats
// one model for the walk, in the batch and in the window (which keys the anchors' blocks l(a)
// and the mean m(0)); each anchor's estimate is in the diagnostics. Measured on seed 1:
// fg-ins-batch 0.724 → 0.385 m, fg-ins-window 0.662 → 0.337 m; fg-ins-batch's auto 0.314 m.
TEST(InsGraphBatch, HierarchicalPathLossFitsAnchorsThatDiffer) {
  auto w = SimulateScenario("jimenez-building", 1,
                            YAML::Load("{laps: 1, A_spread_db: 4, eta_spread: 0.4}"));
  ASSERT_TRUE(w.ok());
  EXPECT_FALSE(w->meta.radio.calibrated);  // the declared model is only the anchors' mean
  for (const char* id : {"fg-ins-batch", "fg-ins-window"}) {
    auto global = RunEstimator(id, *w, "{path_loss: global}");
    auto per_anchor = RunEstimator(id, *w, "{path_loss: hierarchical}");
    ASSERT_TRUE(global.ok()) << global.status().message();
    ASSERT_TRUE(per_anchor.ok()) << per_anchor.status().message();
    EXPECT_EQ(global->diagnostics.count("path_loss_A." + std::to_string(w->anchors[0].id)), 0u);
    EXPECT_EQ(per_anchor->diagnostics.count("path_loss_A." + std::to_string(w->anchors[0].id)), 1u);
    std::printf("%s: RMSE %.3f m global, %.3f m hierarchical\n", id, Rmse(*w, *global),
                Rmse(*w, *per_anchor));
    EXPECT_LE(Rmse(*w, *per_anchor), 0.9 * Rmse(*w, *global)) << id;
  }
  // fg-ins-batch's auto sees the anchors disagree with one model (measured T = 9,880 against a
  // critical 107) and solves per anchor.
  auto chosen = RunEstimator("fg-ins-batch", *w);
  ASSERT_TRUE(chosen.ok()) << chosen.status().message();
  EXPECT_EQ(chosen->diagnostics.at("path_loss_per_anchor"), 1.0);
  EXPECT_GT(chosen->diagnostics.at("path_loss_anchor_chi2"),
            chosen->diagnostics.at("path_loss_anchor_chi2_critical"));
  auto global = RunEstimator("fg-ins-batch", *w, "{path_loss: global}");
  ASSERT_TRUE(global.ok());
  std::printf("fg-ins-batch auto: RMSE %.3f m\n", Rmse(*w, *chosen));
  EXPECT_LE(Rmse(*w, *chosen), 0.9 * Rmse(*w, *global));
  EXPECT_FALSE(EstimatorRegistry::Builtin()
                   .Create("fg-ins-batch", YAML::Load("{path_loss_anchor_test_z: -1}"))
                   .ok());
}

// Waypoints reach the foot-INS graph too (batch and window share InsRadioFactors): five truth
// points at σ = 1 cm put the estimate within 3 cm of each.
TEST(InsGraphBatch, WaypointsPullTheFootOntoThem) {
  auto w = SimulateScenario("jimenez-building", 3, YAML::Load("{laps: 1}"));
  ASSERT_TRUE(w.ok());
  const size_t n = w->truth.size();
  for (size_t i = 1; i <= 5; ++i) {
    const TruthSample& s = w->truth[i * (n - 1) / 6];
    w->waypoints.push_back(Waypoint{s.t_s, s.position_m.head<2>(), 0.01});
  }
  for (const char* id : {"fg-ins-batch", "fg-ins-window"}) {
    auto r = RunEstimator(id, *w);
    ASSERT_TRUE(r.ok()) << r.status().message();
    for (const Waypoint& p : w->waypoints) {
      const double e = (r->trajectory.PositionAt(p.t_s).head<2>() - p.position_m).norm();
      std::printf("%s waypoint t=%.1f s: error %.3f m\n", id, p.t_s, e);
      EXPECT_LT(e, 0.03) << id << " t = " << p.t_s;
    }
  }
}

// The user-factor hook on the foot-INS estimators: a position prior of the user's on the
// middle state's x(k) (3-D block) pulls batch and window onto it; keys that name no state block
// and wrong block sizes come back as errors.
TEST(InsGraphBatch, UserFactorsReachBatchAndWindow) {
  auto w = SimulateScenario("jimenez-building", 4, YAML::Load("{duration_s: 40}"));
  ASSERT_TRUE(w.ok());
  size_t state = 0;
  double t_state = 0.0;
  const Eigen::Vector2d target(2.0, -3.0);
  InsGraphOptions o;
  o.user_factors = [&](const Walk&, const std::vector<double>& times,
                       std::vector<GraphFactor>* out) {
    state = times.size() / 2;
    t_state = times[state];
    out->push_back(
        {std::shared_ptr<ceres::CostFunction>(PositionPriorFactor<3>::Create(target, 0.01)),
         nullptr,
         {InsKey(state, InsBlock::kP)}});
    return Status::Ok();
  };
  InsWindowOptions wo;
  wo.graph = o;
  auto batch = InsGraphBatch(o).Run(*w);
  auto window = InsGraphWindow(wo).Run(*w);
  ASSERT_TRUE(batch.ok()) << batch.status().message();
  ASSERT_TRUE(window.ok()) << window.status().message();
  EXPECT_LT((batch->trajectory.PositionAt(t_state).head<2>() - target).norm(), 0.03);
  EXPECT_LT((window->trajectory.PositionAt(t_state).head<2>() - target).norm(), 0.03);

  InsGraphOptions bad = o;
  bad.user_factors = [](const Walk&, const std::vector<double>& times,
                        std::vector<GraphFactor>* out) {
    out->push_back({std::shared_ptr<ceres::CostFunction>(
                        PositionPriorFactor<2>::Create(Eigen::Vector2d::Zero(), 1.0)),
                    nullptr,
                    {InsKey(0, InsBlock::kP)}});  // a 2-D factor on a 3-D block
    (void)times;
    return Status::Ok();
  };
  auto r = InsGraphBatch(bad).Run(*w);
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.status().message().find("has size 3, the cost function expects 2"), std::string::npos)
      << r.status().message();
  bad.user_factors = [](const Walk&, const std::vector<double>& times,
                        std::vector<GraphFactor>* out) {
    out->push_back({std::shared_ptr<ceres::CostFunction>(
                        PositionPriorFactor<3>::Create(Eigen::Vector2d::Zero(), 1.0)),
                    nullptr,
                    {InsKey(times.size(), InsBlock::kP)}});
    return Status::Ok();
  };
  wo.graph = bad;
  r = InsGraphWindow(wo).Run(*w);
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.status().message().find("names no state block"), std::string::npos)
      << r.status().message();
}

}  // namespace
}  // namespace walkgraph
