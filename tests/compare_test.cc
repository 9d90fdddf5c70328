#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <yaml-cpp/yaml.h>
#include <nlohmann/json.hpp>

#include "walkgraph/compare.h"
#include "walkgraph/io.h"
#include "walkgraph/simulate.h"

namespace walkgraph {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;
using ::testing::Not;

Walk SmallWalk() {
  auto w = ReadWalk(std::string(WALKGRAPH_TEST_DATA_DIR) + "/walks/valid_small");
  EXPECT_TRUE(w.ok());
  return *w;
}

TEST(CompareOnWalk, RunsApplicableEstimatorsAndScoresThem) {
  auto c = CompareOnWalk(SmallWalk(), {});
  ASSERT_TRUE(c.ok()) << c.status().message();
  ASSERT_FALSE(c->outcomes.empty());
  const EstimatorOutcome& dr = c->outcomes.front();
  EXPECT_EQ(dr.id, "odometry-dr");
  ASSERT_TRUE(dr.status.ok());
  // The fixture's odometry traces its truth exactly except the turn, which the truth takes
  // one increment later than dead reckoning: errors are 0 up to t = 1.5 s.
  EXPECT_NEAR(dr.errors.error_m[1], 0.0, 1e-12);
  EXPECT_GT(dr.stats.n_points, 0);
}

TEST(CompareOnWalk, UnknownOrInapplicableEstimatorIsAnError) {
  CompareOptions o;
  o.estimator_ids = {"no-such-estimator"};
  EXPECT_FALSE(CompareOnWalk(SmallWalk(), o).ok());
  Walk w = SmallWalk();
  w.odometry.clear();
  o.estimator_ids = {"odometry-dr"};
  auto c = CompareOnWalk(w, o);
  ASSERT_FALSE(c.ok());
  EXPECT_THAT(c.status().message(), HasSubstr("odometry"));
}

TEST(CompareOnWalk, AppliesTheReadersRulesAndRefusesOptionsOfEstimatorsNotRun) {
  Walk w = SmallWalk();
  w.rss[3].rss = std::nan("");
  auto nan_rss = CompareOnWalk(w, {});
  ASSERT_FALSE(nan_rss.ok());
  EXPECT_THAT(nan_rss.status().message(), HasSubstr("rss[3]: non-finite value in rss"));
  w = SmallWalk();
  w.truth[2].t_s = w.truth[1].t_s;
  EXPECT_THAT(CompareOnWalk(w, {}).status().message(), HasSubstr("truth[2]: timestamp"));
  CompareOptions o;
  o.estimator_ids = {"odometry-dr"};
  o.configs["fg-batch"] = YAML::Load("{covariance: false}");
  auto not_run = CompareOnWalk(SmallWalk(), o);
  ASSERT_FALSE(not_run.ok());
  EXPECT_THAT(not_run.status().message(), HasSubstr("not among the estimators run"));
  o.estimator_ids.clear();  // every applicable estimator: options for any of them are fine
  EXPECT_TRUE(CompareOnWalk(SmallWalk(), o).ok());
}

// score_from_s drops the truth before t_first + score_from_s from every figure and counts it
// as skipped; the rest of the series is the whole walk's, unchanged.
// A long walk says how far it is: (estimators done, estimators) before the first and after each,
// and from inside a filter its driver's fraction (here zupt-ins's error-state loop, which reports
// every 4096 samples).
TEST(CompareOnWalk, ReportsProgressByEstimatorAndFromInsideAFilter) {
  auto w = SimulateScenario("jimenez-building", 3, *Config::Parse("{laps: 1}"));
  ASSERT_TRUE(w.ok()) << w.status().message();
  ASSERT_GT(w->imu.size(), 2u * 4096u);
  CompareOptions o;
  o.estimator_ids = {"odometry-dr", "zupt-ins"};
  w->odometry = {{w->imu.front().t_s, 0.0, 0.0}, {w->imu.back().t_s, 0.0, 0.0}};
  std::vector<double> calls;
  o.progress = [&](double done, int total) {
    EXPECT_EQ(total, 2);
    calls.push_back(done);
  };
  auto c = CompareOnWalk(*w, o);
  ASSERT_TRUE(c.ok()) << c.status().message();
  ASSERT_GE(calls.size(), 4u);
  EXPECT_EQ(calls.front(), 0.0);
  EXPECT_EQ(calls.back(), 2.0);
  EXPECT_TRUE(std::is_sorted(calls.begin(), calls.end()));
  EXPECT_TRUE(std::any_of(calls.begin(), calls.end(), [](double d) { return d > 1.0 && d < 2.0; }))
      << "no progress from inside zupt-ins";
  // Without a callback installed, a driver's report goes nowhere.
  ReportEstimatorProgress(0.5);
}

// The fraction reported inside an estimator never goes back (a loop without a fraction reports 0
// as a sign of life: the solver's iterations), and scopes nest.
TEST(ScopedEstimatorProgress, NeverGoesBackAndNests) {
  std::vector<double> outer, inner;
  {
    ScopedEstimatorProgress a([&](double f) { outer.push_back(f); });
    ReportEstimatorProgress(0.3);
    ReportEstimatorProgress(0.0);
    {
      ScopedEstimatorProgress b([&](double f) { inner.push_back(f); });
      ReportEstimatorProgress(0.5);
    }
    ReportEstimatorProgress(2.0);
  }
  ReportEstimatorProgress(0.7);  // none installed: nowhere
  EXPECT_EQ(outer, (std::vector<double>{0.3, 0.3, 1.0}));
  EXPECT_EQ(inner, (std::vector<double>{0.5}));
}

// A graph estimator's solver iterations are signs of life between its start and its end.
TEST(CompareOnWalk, AGraphEstimatorReportsEachSolverIteration) {
  CompareOptions o;
  o.estimator_ids = {"fg-batch"};
  std::vector<double> calls;
  o.progress = [&](double done, int) { calls.push_back(done); };
  auto c = CompareOnWalk(SmallWalk(), o);
  ASSERT_TRUE(c.ok()) << c.status().message();
  ASSERT_TRUE(c->outcomes[0].status.ok()) << c->outcomes[0].status.message();
  EXPECT_GT(std::count(calls.begin(), calls.end(), 0.0), 1) << "no report while fg-batch ran";
  EXPECT_EQ(calls.back(), 1.0);
}

// Warnings about the walk (io.h PlausibilityWarnings) are counted in results.json.
TEST(WriteComparison, CountsTheWalksWarningsInResultsJson) {
  Walk w = SmallWalk();
  w.meta.extra["convert.imu_invalid_dropped"] = 2;
  w.meta.extra["convert.rss_invalid_dropped"] = 1;
  auto c = CompareOnWalk(w, {});
  ASSERT_TRUE(c.ok()) << c.status().message();
  EXPECT_EQ(c->warning_count, 2);
  const nlohmann::json j = nlohmann::json::parse(ResultsJsonText(*c));
  EXPECT_EQ(j["warnings"]["count"], 2);
  ASSERT_EQ(j["warnings"]["messages"].size(), 2u);
  EXPECT_THAT(j["warnings"]["messages"][0].get<std::string>(),
              HasSubstr("walk.yaml: the converter dropped 2 imu reading(s)"));
  auto plain = CompareOnWalk(SmallWalk(), {});
  ASSERT_TRUE(plain.ok());
  const nlohmann::json k = nlohmann::json::parse(ResultsJsonText(*plain));
  EXPECT_EQ(k["warnings"]["count"], 0);
  EXPECT_TRUE(k["warnings"]["messages"].empty());
}

// Without a start, waypoints or two heard anchors of known position, errors against the truth
// hold an arbitrary offset: the comparison says so (not when scored with --align-se2).
TEST(CompareOnWalk, WarnsWhenNothingTiesTheWalkToTheTruthsFrame) {
  CompareOptions o;  // every estimator that runs without a start
  Walk w = SmallWalk();
  w.meta.initial_pose.reset();
  auto tied = CompareOnWalk(w, o);  // waypoints and three heard anchors still place it
  ASSERT_TRUE(tied.ok()) << tied.status().message();
  EXPECT_TRUE(tied->untied_frame.empty());
  w.waypoints.clear();
  for (Anchor& a : w.anchors) a.position_known = a.id == 1;  // one anchor of known position
  for (Anchor& a : w.anchors) a.sigma_m = 0.0;
  auto c = CompareOnWalk(w, o);
  ASSERT_TRUE(c.ok()) << c.status().message();
  EXPECT_THAT(c->untied_frame, HasSubstr("hears 1 anchor(s) of known position"));
  EXPECT_EQ(c->warning_count, 1);
  EXPECT_THAT(FormatComparisonTable(*c), HasSubstr("warning: walk.yaml has no initial_pose"));
  o.alignment = Alignment::kSE2;
  auto aligned = CompareOnWalk(w, o);
  ASSERT_TRUE(aligned.ok()) << aligned.status().message();
  EXPECT_TRUE(aligned->untied_frame.empty());
  EXPECT_EQ(aligned->warning_count, 0);
}

TEST(CompareOnWalk, ScoreFromLeavesOutTheStart) {
  CompareOptions o;
  o.estimator_ids = {"odometry-dr"};
  auto whole = CompareOnWalk(SmallWalk(), o);
  ASSERT_TRUE(whole.ok()) << whole.status().message();
  o.score_from_s = 1.2;  // the fixture's truth is at 0, 0.5, ..., 2.0 s
  auto late = CompareOnWalk(SmallWalk(), o);
  ASSERT_TRUE(late.ok()) << late.status().message();
  EXPECT_EQ(late->score_from_s, 1.2);
  const EstimatorOutcome &w = whole->outcomes.front(), &l = late->outcomes.front();
  ASSERT_TRUE(l.status.ok()) << l.status.message();
  ASSERT_EQ(w.errors.t_s.size(), 5u);
  EXPECT_EQ(l.errors.t_s, (std::vector<double>{1.5, 2.0}));
  EXPECT_EQ(l.errors.error_m, (std::vector<double>{w.errors.error_m[3], w.errors.error_m[4]}));
  EXPECT_EQ(l.errors.n_skipped, w.errors.n_skipped + 3);
  EXPECT_EQ(l.stats.n_points, 2);
  EXPECT_DOUBLE_EQ(l.stats.mean_m, 0.5 * (w.errors.error_m[3] + w.errors.error_m[4]));
  EXPECT_EQ(l.stats.final_m, w.stats.final_m);
  EXPECT_THAT(FormatComparisonTable(*late), HasSubstr("scored from 1.2 s"));
  for (double bad : {-1.0, std::nan(""), 2.5}) {
    o.score_from_s = bad;
    auto c = CompareOnWalk(SmallWalk(), o);
    ASSERT_FALSE(c.ok()) << bad;
    EXPECT_THAT(c.status().message(), HasSubstr("score_from_s")) << bad;
  }
}

TEST(WriteComparison, WritesEveryFileWithTheDocumentedSchema) {
  auto c = CompareOnWalk(SmallWalk(), {});
  ASSERT_TRUE(c.ok());
  const fs::path out = fs::temp_directory_path() / ("wg_compare_" + std::to_string(::getpid()));
  fs::remove_all(out);
  ASSERT_TRUE(WriteComparison(*c, out.string()).ok());
  for (const char* f : {"results.json", "errors.csv", "report.html", "truth.tum",
                        "trajectories/odometry-dr.tum", "trajectories/odometry-dr.csv"}) {
    EXPECT_TRUE(fs::exists(out / f)) << f;
  }
  EXPECT_FALSE(fs::exists(out / "checkpoints.csv"));  // the truth is continuous
  std::ifstream in(out / "results.json");
  const nlohmann::json j = nlohmann::json::parse(in);
  EXPECT_EQ(j["walk"], "valid_small");
  EXPECT_EQ(j["runs"], 1);
  EXPECT_EQ(j["truth_kind"], "continuous");
  const auto& e = j["estimators"]["odometry-dr"];
  for (const char* key :
       {"rmse_m", "mean_m", "median_m", "p75_m", "p90_m", "max_m", "final_m", "pct_distance",
        "mean_pct_distance", "anees", "runtime_s", "n_points", "scored_on_every_point"}) {
    EXPECT_TRUE(e.contains(key)) << key;
  }
  EXPECT_EQ(e["scored_on_every_point"], true);
  EXPECT_TRUE(j.contains("pcrb_rmse_m"));
  std::ifstream html(out / "report.html");
  const std::string page((std::istreambuf_iterator<char>(html)), {});
  EXPECT_THAT(page, HasSubstr("id=\"results\""));
  EXPECT_THAT(page, HasSubstr("id=\"wg-data\""));
  EXPECT_THAT(page, HasSubstr("\"anchors\":[["));
  EXPECT_THAT(page, ::testing::Not(HasSubstr(" src=")));  // nothing loaded from anywhere
  fs::remove_all(out);
}

std::vector<std::string> Lines(const fs::path& p) {
  std::ifstream in(p);
  std::vector<std::string> lines;
  for (std::string line; std::getline(in, line);) lines.push_back(line);
  return lines;
}

std::vector<std::string> Fields(const std::string& line) {
  std::vector<std::string> f;
  std::stringstream s(line);
  for (std::string x; std::getline(s, x, ',');) f.push_back(x);
  if (!line.empty() && line.back() == ',') f.push_back("");
  return f;
}

// trajectories/<id>.csv: the TUM trajectory's points with their (x, y, yaw) covariance; empty
// covariance fields for an estimator without one. truth.tum: every truth sample.
TEST(WriteComparison, WritesTrajectoryCsvWithCovariancesAndTruthTum) {
  auto walk = SimulateScenario("linear-gaussian", 3, YAML::Load("{duration_s: 60}"));
  ASSERT_TRUE(walk.ok());
  CompareOptions options;
  options.estimator_ids = {"odometry-dr", "fg-batch"};
  auto c = CompareOnWalk(*walk, options);
  ASSERT_TRUE(c.ok()) << c.status().message();
  const fs::path out = fs::temp_directory_path() / ("wg_csv_" + std::to_string(::getpid()));
  fs::remove_all(out);
  ASSERT_TRUE(WriteComparison(*c, out.string()).ok());
  for (const EstimatorOutcome& o : c->outcomes) {
    const std::vector<std::string> csv = Lines(out / "trajectories" / (o.id + ".csv"));
    const std::vector<std::string> tum = Lines(out / "trajectories" / (o.id + ".tum"));
    ASSERT_FALSE(csv.empty());
    EXPECT_EQ(csv[0], "t_s,x_m,y_m,yaw_rad,cov_xx,cov_xy,cov_yy,cov_xyaw,cov_yyaw,cov_yawyaw");
    ASSERT_EQ(csv.size(), o.result.trajectory.size() + 1) << o.id;
    EXPECT_EQ(tum.size(), csv.size()) << o.id;
    for (size_t i = 1; i < csv.size(); i += 97) {
      const std::vector<std::string> f = Fields(csv[i]);
      ASSERT_EQ(f.size(), 10u) << csv[i];
      const TrajectoryPoint& p = o.result.trajectory.points[i - 1];
      EXPECT_NEAR(std::stod(f[0]), p.t_s, 1e-9);
      EXPECT_NEAR(std::stod(f[1]), p.position_m.x(), 1e-9);
      EXPECT_NEAR(std::stod(f[3]), p.heading_rad, 1e-9);
      if (!p.covariance) {
        for (int j = 4; j < 10; ++j) EXPECT_EQ(f[j], "") << o.id << " " << csv[i];
        continue;
      }
      EXPECT_NEAR(std::stod(f[4]), (*p.covariance)(0, 0), 1e-12);
      EXPECT_NEAR(std::stod(f[5]), (*p.covariance)(0, 1), 1e-12);
      EXPECT_NEAR(std::stod(f[9]), (*p.covariance)(2, 2), 1e-12);
    }
  }
  bool fg_has_cov = false;
  for (const auto& p : c->outcomes[1].result.trajectory.points)
    fg_has_cov |= p.covariance.has_value();
  EXPECT_TRUE(fg_has_cov);  // the covariance fields above were checked on real values
  const std::vector<std::string> truth = Lines(out / "truth.tum");
  ASSERT_EQ(truth.size(), walk->truth.size() + 1);
  std::stringstream row(truth[5]);
  double t, x, y, z, qx, qy, qz, qw;
  row >> t >> x >> y >> z >> qx >> qy >> qz >> qw;
  EXPECT_NEAR(t, walk->truth[4].t_s, 1e-9);
  EXPECT_NEAR(x, walk->truth[4].position_m.x(), 1e-9);
  EXPECT_NEAR(y, walk->truth[4].position_m.y(), 1e-9);
  EXPECT_EQ(qw, 1.0);
  fs::remove_all(out);
}

TEST(WriteComparison, WritesCheckpointsCsvWhenTheTruthIsCheckpoints) {
  Walk walk = SmallWalk();
  walk.meta.truth_kind = TruthKind::kCheckpoints;
  auto c = CompareOnWalk(walk, {});
  ASSERT_TRUE(c.ok()) << c.status().message();
  const fs::path out = fs::temp_directory_path() / ("wg_ckpt_" + std::to_string(::getpid()));
  fs::remove_all(out);
  ASSERT_TRUE(WriteComparison(*c, out.string()).ok());
  const std::vector<std::string> rows = Lines(out / "checkpoints.csv");
  ASSERT_EQ(rows.size(), walk.truth.size() + 1);
  EXPECT_EQ(rows[0], "t_s,x_m,y_m");
  const std::vector<std::string> f = Fields(rows.back());
  ASSERT_EQ(f.size(), 3u);
  EXPECT_NEAR(std::stod(f[1]), walk.truth.back().position_m.x(), 1e-9);
  EXPECT_EQ(Lines(out / "truth.tum").size(), walk.truth.size() + 1);
  fs::remove_all(out);
}

// compact streams trajectories and errors to disk: the same files, thinner outcomes in memory.
TEST(WriteComparison, CompactWritesTheSameFilesAsFull) {
  auto walk = SimulateScenario("linear-gaussian", 3, YAML::Load("{duration_s: 3600}"));
  ASSERT_TRUE(walk.ok());
  CompareOptions full, compact;
  full.estimator_ids = compact.estimator_ids = {"odometry-dr", "fg-batch"};
  compact.compact = true;
  auto a = CompareOnWalk(*walk, full);
  auto b = CompareOnWalk(*walk, compact);
  ASSERT_TRUE(a.ok() && b.ok());
  ASSERT_EQ(a->outcomes.size(), b->outcomes.size());
  for (size_t k = 0; k < a->outcomes.size(); ++k) {
    const EstimatorOutcome &x = a->outcomes[k], &y = b->outcomes[k];
    EXPECT_GT(x.result.trajectory.size(), kCompactPoints);
    EXPECT_LE(y.result.trajectory.size(), kCompactPoints);
    EXPECT_LE(y.errors.t_s.size(), kCompactPoints);
    EXPECT_EQ(x.stats.p90_m, y.stats.p90_m);  // figures from every point, before thinning
    EXPECT_EQ(x.stats.n_points, y.stats.n_points);
    EXPECT_EQ(y.pooled_errors->count(), x.stats.n_points);
  }
  EXPECT_LE(b->truth.size(), kCompactPoints);
  const fs::path out = fs::temp_directory_path() / ("wg_compact_" + std::to_string(::getpid()));
  fs::remove_all(out);
  a->outcomes[0].runtime_s = b->outcomes[0].runtime_s = 0.0;
  a->outcomes[1].runtime_s = b->outcomes[1].runtime_s = 0.0;
  ASSERT_TRUE(WriteComparison(*a, (out / "full").string()).ok());
  ASSERT_TRUE(WriteComparison(*b, (out / "compact").string()).ok());
  auto read = [](const fs::path& p) {
    std::ifstream in(p);
    return std::string((std::istreambuf_iterator<char>(in)), {});
  };
  for (const char* f :
       {"results.json", "errors.csv", "truth.tum", "trajectories/odometry-dr.tum",
        "trajectories/fg-batch.tum", "trajectories/odometry-dr.csv", "trajectories/fg-batch.csv"}) {
    EXPECT_EQ(read(out / "full" / f), read(out / "compact" / f)) << f;
  }
  fs::remove_all(out);
}

TEST(FormatComparisonTable, MarksTheBestValuePerColumn) {
  Comparison c;
  c.walk_name = "w";
  EstimatorOutcome a, b;
  a.id = "a";
  a.stats.rmse_m = 2.0;
  a.stats.mean_m = 1.0;
  b.id = "b";
  b.stats.rmse_m = 1.5;
  b.stats.mean_m = 3.0;
  c.outcomes = {a, b};
  const std::string t = FormatComparisonTable(c);
  EXPECT_THAT(t, HasSubstr("1.500*"));
  EXPECT_THAT(t, HasSubstr("1.000*"));
  EXPECT_THAT(t, HasSubstr("2.000 "));
}

// An estimate that does not span the walk is scored on the truth inside its span: its figures
// are shown with its points ("7/13") and never marked best, however low (IPIN trial 01 without
// a known start: the EKFs that start at their first radio fix are scored on 7 of 13 landmarks).
TEST(FormatComparisonTable, NeverMarksBestAnEstimatorScoredOnPartOfTheWalk) {
  Comparison c;
  c.walk_name = "w";
  EstimatorOutcome full, part, failed;
  full.id = "full";
  full.stats.rmse_m = 2.0;
  full.stats.n_points = 13;
  part.id = "part";
  part.stats.rmse_m = 1.25;
  part.stats.n_points = 7;
  failed.id = "failed";
  failed.status = FailedPrecondition("no fix");
  c.outcomes = {full, part, failed};
  EXPECT_TRUE(ScoredOnEveryPoint(c, c.outcomes[0]));
  EXPECT_FALSE(ScoredOnEveryPoint(c, c.outcomes[1]));
  EXPECT_FALSE(ScoredOnEveryPoint(c, c.outcomes[2]));  // not ranked
  EXPECT_EQ(ScoredPointsLabel(c, c.outcomes[0]), "13");
  EXPECT_EQ(ScoredPointsLabel(c, c.outcomes[1]), "7/13");
  const std::string t = FormatComparisonTable(c);
  EXPECT_THAT(t, HasSubstr("2.000*"));
  EXPECT_THAT(t, HasSubstr("1.250 "));
  EXPECT_THAT(t, HasSubstr("7/13"));
  EXPECT_THAT(t, HasSubstr("not marked best"));

  // Monte Carlo: points per run that counts (a failed run is not a missed point).
  c.runs = 10;
  c.outcomes = {full, full};
  c.outcomes[0].stats.n_points = 130;
  c.outcomes[0].run_rmse_m.assign(10, 2.0);
  c.outcomes[1].stats.n_points = 104;
  c.outcomes[1].run_rmse_m.assign(8, 2.0);  // failed on two runs of 13 points
  EXPECT_TRUE(ScoredOnEveryPoint(c, c.outcomes[1]));
  c.outcomes[1].stats.n_points = 80;  // 10 points a run: it starts late
  EXPECT_FALSE(ScoredOnEveryPoint(c, c.outcomes[1]));
  EXPECT_EQ(ScoredPointsLabel(c, c.outcomes[1]), "80/104");
}

// rmse/pcrb below 1 from fewer than 30 runs is flagged with the ratio's 95 % interval:
// 5 runs, mean RMSE 0.9 m, std 0.1 m, PCRB 1.0 m: 0.9 ± 2.776 · 0.1/√5 = 0.78 to 1.02.
TEST(FormatComparisonTable, WarnsWhenFewRunsLandBelowTheBound) {
  Comparison c;
  c.walk_name = "w";
  c.runs = 5;
  c.pcrb_rmse_m = 1.0;
  EstimatorOutcome a, b;
  a.id = "a";
  a.stats.rmse_m = 0.9;
  a.stats_std = ErrorStats{};
  a.stats_std->rmse_m = 0.1;
  a.run_rmse_m = {0.8, 0.85, 0.9, 0.95, 1.0};
  b = a;
  b.id = "b";
  b.stats.rmse_m = 1.2;  // above the bound: no warning
  c.outcomes = {a, b};
  std::string t = FormatComparisonTable(c);
  EXPECT_THAT(t, HasSubstr("warning: a rmse/pcrb 0.90 < 1 from 5 runs (95 % interval 0.78 to "
                           "1.02)"));
  EXPECT_THAT(t, Not(HasSubstr("warning: b")));
  c.runs = 30;  // enough runs: no warning
  c.outcomes[0].run_rmse_m.resize(30, 0.9);
  EXPECT_THAT(FormatComparisonTable(c), Not(HasSubstr("warning")));
}

}  // namespace
}  // namespace walkgraph
