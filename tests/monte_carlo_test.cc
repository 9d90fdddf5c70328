#include <unistd.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <random>
#include <set>
#include <sstream>

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <yaml-cpp/yaml.h>
#include <nlohmann/json.hpp>

#include "util/text_spill.h"
#include "walkgraph/compare.h"
#include "walkgraph/io.h"
#include "walkgraph/pcrb.h"
#include "walkgraph/simulate.h"

namespace walkgraph {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;

// A seeded walk: straight-line odometry with noisy increments, exact continuous truth, one
// anchor. Dead reckoning's error then grows like a random walk whose size depends on the seed.
Walk NoisyLine(uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> noise(0.0, 0.05);
  Walk w;
  w.meta.name = "noisy-line";
  w.meta.truth_kind = TruthKind::kContinuous;
  w.meta.initial_pose = InitialPose{};
  w.anchors.push_back({0, Eigen::Vector3d(5.0, 5.0, 0.0)});
  TruthSample t0;
  w.truth.push_back(t0);
  for (int k = 1; k <= 40; ++k) {
    OdometrySample o;
    o.t_s = 0.5 * k;
    o.dist_m = 0.5 + noise(rng);
    o.dheading_rad = noise(rng);
    w.odometry.push_back(o);
    TruthSample t;
    t.t_s = o.t_s;
    t.position_m = Eigen::Vector3d(0.5 * k, 0.0, 0.0);
    w.truth.push_back(t);
  }
  return w;
}

std::string ReadFile(const fs::path& p) {
  std::ifstream in(p);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

TEST(MonteCarloSeed, IsDeterministicAndDistinct) {
  EXPECT_EQ(MonteCarloSeed(7, 3), MonteCarloSeed(7, 3));
  std::set<uint64_t> seen;
  for (int i = 0; i < 1000; ++i) seen.insert(MonteCarloSeed(7, i));
  EXPECT_EQ(seen.size(), 1000u);
  EXPECT_NE(MonteCarloSeed(7, 0), MonteCarloSeed(8, 0));
  // SplitMix64's first output for state 0 (Vigna's reference: 0xE220A8397B1DCDAF).
  EXPECT_EQ(MonteCarloSeed(0, 0), 0xE220A8397B1DCDAFULL);
}

TEST(CompareMonteCarlo, AggregatesMeanStdAndPooledPercentiles) {
  MonteCarloOptions mc;
  mc.runs = 6;
  mc.seed = 42;
  mc.threads = 2;
  CompareOptions o;
  o.estimator_ids = {"odometry-dr"};
  auto c = CompareMonteCarlo(NoisyLine, o, mc);
  ASSERT_TRUE(c.ok()) << c.status().message();
  EXPECT_EQ(c->runs, 6);
  ASSERT_EQ(c->outcomes.size(), 1u);
  const EstimatorOutcome& agg = c->outcomes[0];
  ASSERT_TRUE(agg.stats_std.has_value());
  // Recompute from single-walk comparisons with the documented seeds.
  std::vector<double> rmse, pooled;
  for (int i = 0; i < 6; ++i) {
    auto one = CompareOnWalk(NoisyLine(MonteCarloSeed(42, i)), o);
    ASSERT_TRUE(one.ok());
    rmse.push_back(one->outcomes[0].stats.rmse_m);
    const auto& e = one->outcomes[0].errors.error_m;
    pooled.insert(pooled.end(), e.begin(), e.end());
  }
  double mean = 0.0;
  for (double r : rmse) mean += r / 6.0;
  double var = 0.0;
  for (double r : rmse) var += (r - mean) * (r - mean) / 5.0;
  EXPECT_NEAR(agg.stats.rmse_m, mean, 1e-12);
  EXPECT_NEAR(agg.stats_std->rmse_m, std::sqrt(var), 1e-12);
  EXPECT_GT(agg.stats_std->rmse_m, 0.0);  // the seeds really differ
  std::sort(pooled.begin(), pooled.end());
  EXPECT_EQ(agg.stats.n_points, static_cast<int>(pooled.size()));
  // Pooled percentiles come from the bounded-memory sketch: within its relative accuracy.
  const double p75 = Percentile(pooled, 75.0);
  EXPECT_NEAR(agg.stats.p75_m, p75, QuantileSketch::kDefaultRelativeAccuracy * p75);
  EXPECT_NE(agg.stats.p75_m, 0.0);
  ASSERT_TRUE(agg.pooled_errors.has_value());
  EXPECT_EQ(agg.pooled_errors->count(), static_cast<long long>(pooled.size()));
  // Only the first run's series is kept in memory; every run's rows go to errors.csv.
  auto first = CompareOnWalk(NoisyLine(MonteCarloSeed(42, 0)), o);
  ASSERT_TRUE(first.ok());
  EXPECT_EQ(agg.errors.error_m, first->outcomes[0].errors.error_m);
  // The table shows mean+-std of each figure.
  std::ostringstream cell;
  cell << std::fixed << std::setprecision(3) << mean << "+-" << std::sqrt(var);
  EXPECT_THAT(FormatComparisonTable(*c), HasSubstr(cell.str()));
  EXPECT_THAT(RenderHtmlReport(*c), HasSubstr("&plusmn;"));
}

TEST(CompareMonteCarlo, ResultsJsonIsIdenticalForOneAndTwoThreads) {
  CompareOptions o;
  const fs::path base = fs::temp_directory_path() / ("wg_mc_" + std::to_string(::getpid()));
  std::string json[2];
  for (int threads : {1, 2}) {
    MonteCarloOptions mc;
    mc.runs = 8;
    mc.seed = 2024;
    mc.threads = threads;
    int calls = 0;
    mc.progress = [&](int done, int total) {
      ++calls;
      EXPECT_EQ(total, 8);
      EXPECT_EQ(done, calls);
    };
    auto c = CompareMonteCarlo(NoisyLine, o, mc);
    ASSERT_TRUE(c.ok()) << c.status().message();
    EXPECT_EQ(calls, 8);
    const fs::path out = base / std::to_string(threads);
    ASSERT_TRUE(WriteComparison(*c, out.string()).ok());
    json[threads - 1] = ReadFile(out / "results.json");
    EXPECT_TRUE(fs::exists(out / "timing.json"));
    const std::string csv = ReadFile(out / "errors.csv");
    EXPECT_THAT(csv, HasSubstr("t_s,estimator,error_m,run\n"));
    // Every run's errors, in run order: one row per pooled point, the last from run 7.
    long long rows = 0;
    for (const EstimatorOutcome& agg : c->outcomes) rows += agg.pooled_errors->count();
    EXPECT_EQ(std::count(csv.begin(), csv.end(), '\n'), 1 + rows);
    EXPECT_THAT(csv.substr(csv.rfind('\n', csv.size() - 2)), ::testing::EndsWith(",7\n"));
  }
  EXPECT_EQ(json[0], json[1]);
  const nlohmann::json j = nlohmann::json::parse(json[0]);
  EXPECT_EQ(j["runs"], 8);
  EXPECT_EQ(j["seed"], 2024);
  const auto& e = j["estimators"]["odometry-dr"];
  for (const char* key : {"rmse_m", "rmse_m_std", "p75_m", "p75_m_std", "max_m_std",
                          "pct_distance_std", "mean_pct_distance", "mean_pct_distance_std", "anees",
                          "anees_std", "n_points", "failed_runs"}) {
    EXPECT_TRUE(e.contains(key)) << key;
  }
  EXPECT_TRUE(e["runtime_s"].is_null());
  fs::remove_all(base);
}

TEST(CompareMonteCarlo, GeneratorFailureNamesRunAndSeed) {
  MonteCarloOptions mc;
  mc.runs = 3;
  mc.seed = 5;
  const uint64_t bad = MonteCarloSeed(5, 1);
  auto gen = [bad](uint64_t seed) -> StatusOr<Walk> {
    if (seed == bad) return InvalidArgument("cannot simulate");
    return NoisyLine(seed);
  };
  auto c = CompareMonteCarlo(gen, {}, mc);
  ASSERT_FALSE(c.ok());
  EXPECT_THAT(c.status().message(), HasSubstr("run 1 (seed " + std::to_string(bad) + ")"));
  mc.runs = 0;
  EXPECT_FALSE(CompareMonteCarlo(NoisyLine, {}, mc).ok());
}

TEST(AggregateRuns, CountsFailedRunsAndKeepsTheOthers) {
  Comparison a, b;
  a.walk_name = b.walk_name = "w";
  EstimatorOutcome ok, bad;
  ok.id = bad.id = "x";
  ok.stats.rmse_m = 2.0;
  ok.errors.t_s = {0.0, 1.0};
  ok.errors.error_m = {1.0, 3.0};
  bad.status = NumericalError("diverged");
  a.outcomes = {ok};
  b.outcomes = {bad};
  auto c = AggregateRuns({a, b});
  ASSERT_TRUE(c.ok());
  ASSERT_EQ(c->outcomes.size(), 1u);
  EXPECT_TRUE(c->outcomes[0].status.ok());
  EXPECT_EQ(c->outcomes[0].failed_runs, 1);
  EXPECT_EQ(c->outcomes[0].stats.rmse_m, 2.0);
  EXPECT_EQ(c->outcomes[0].stats_std->rmse_m, 0.0);
  EXPECT_NEAR(c->outcomes[0].stats.median_m, 2.0, 2.0 * QuantileSketch::kDefaultRelativeAccuracy);
  auto all_bad = AggregateRuns({b, b});
  ASSERT_TRUE(all_bad.ok());
  EXPECT_FALSE(all_bad->outcomes[0].status.ok());
  EXPECT_THAT(all_bad->outcomes[0].status.message(), HasSubstr("run 0: diverged"));
}

// Test-only estimator: the walk's truth shifted by offset_m along x (error = offset_m exactly).
class TruthOffset : public Estimator {
 public:
  explicit TruthOffset(double offset_m) : offset_m_(offset_m) {}
  Status CheckApplicable(const Walk& walk) const override {
    return walk.has_truth() ? Status::Ok() : FailedPrecondition("needs truth");
  }
  StatusOr<EstimateResult> Run(const Walk& walk) const override {
    EstimateResult r;
    for (const TruthSample& t : walk.truth) {
      TrajectoryPoint p;
      p.t_s = t.t_s;
      p.position_m = Eigen::Vector3d(t.position_m.x() + offset_m_, t.position_m.y(), 0.0);
      r.trajectory.points.push_back(p);
    }
    return r;
  }

 private:
  double offset_m_;
};

EstimatorRegistry TestRegistry() {
  EstimatorRegistry r;
  EXPECT_TRUE(r.Register({"truth-offset", "test: truth + 0.25 m in x",
                          [](const Config&) -> StatusOr<std::unique_ptr<Estimator>> {
                            return std::unique_ptr<Estimator>(new TruthOffset(0.25));
                          }})
                  .ok());
  return r;
}

TEST(CompareScenario, AddsThePcrbOfTheSameRunsAndIsThreadIndependent) {
  ScenarioCompareOptions sc;
  sc.overrides = YAML::Load("{duration_s: 20, range_sigma_m: 0.5}");
  CompareOptions o;
  o.estimator_ids = {"odometry-dr"};
  const fs::path base = fs::temp_directory_path() / ("wg_sc_" + std::to_string(::getpid()));
  std::string json[2];
  std::optional<Comparison> first;
  for (int threads : {1, 2}) {
    MonteCarloOptions mc;
    mc.runs = 6;
    mc.seed = 3;
    mc.threads = threads;
    auto c = CompareScenario("linear-gaussian", sc, o, mc);
    ASSERT_TRUE(c.ok()) << c.status().message();
    ASSERT_TRUE(WriteComparison(*c, (base / std::to_string(threads)).string()).ok());
    json[threads - 1] = ReadFile(base / std::to_string(threads) / "results.json");
    if (!first) first = *c;
  }
  EXPECT_EQ(json[0], json[1]);
  const Comparison& c = *first;
  auto bound = ScenarioPcrb("linear-gaussian", sc.overrides, 6, 3, 1);
  ASSERT_TRUE(bound.ok());
  ASSERT_TRUE(c.pcrb_rmse_m.has_value());
  EXPECT_DOUBLE_EQ(*c.pcrb_rmse_m, bound->smoother_rmse_m);
  EXPECT_DOUBLE_EQ(*c.pcrb_filter_rmse_m, bound->filter_rmse_m);
  EXPECT_EQ(c.pcrb_t_s.size(), bound->t_s.size());
  const nlohmann::json j = nlohmann::json::parse(json[0]);
  const double rmse = j["estimators"]["odometry-dr"]["rmse_m"];
  EXPECT_DOUBLE_EQ(j["estimators"]["odometry-dr"]["rmse_over_pcrb"].get<double>(),
                   rmse / bound->smoother_rmse_m);
  EXPECT_DOUBLE_EQ(j["pcrb_filter_rmse_m"].get<double>(), bound->filter_rmse_m);
  // Dead reckoning from the known start ignores the ranges: it cannot beat the bound.
  EXPECT_GT(rmse, bound->smoother_rmse_m);
  EXPECT_THAT(FormatComparisonTable(c), HasSubstr("PCRB smoother"));
  EXPECT_THAT(FormatComparisonTable(c), HasSubstr("rmse/pcrb"));
  const std::string html = RenderHtmlReport(c);
  EXPECT_THAT(html, HasSubstr("\"pcrb\":{\"rmse\":"));  // the bound's curve and line
  EXPECT_THAT(html, HasSubstr("RMSE / PCRB"));
  // The per-run RMSE behind the report's box plot over runs: their mean is the table's RMSE.
  const EstimatorOutcome& dr = c.outcomes[0];
  ASSERT_EQ(dr.run_rmse_m.size(), static_cast<size_t>(c.runs));
  double sum = 0.0;
  for (double r : dr.run_rmse_m) sum += r;
  EXPECT_NEAR(sum / c.runs, dr.stats.rmse_m, 1e-12);
  EXPECT_THAT(html, HasSubstr("\"runs\":["));
  fs::remove_all(base);
}

TEST(CompareScenario, FootScenarioSaysWhyThereIsNoBound) {
  ScenarioCompareOptions sc;
  sc.overrides = YAML::Load("{laps: 1}");
  MonteCarloOptions mc;
  auto c = CompareScenario("prieto-laps", sc, {}, mc, TestRegistry());
  ASSERT_TRUE(c.ok()) << c.status().message();
  EXPECT_FALSE(c->pcrb_rmse_m.has_value());
  EXPECT_THAT(c->pcrb_note, HasSubstr("foot"));
  EXPECT_NEAR(c->outcomes[0].stats.rmse_m, 0.25, 1e-9);
  EXPECT_THAT(FormatComparisonTable(*c), HasSubstr("PCRB not computed"));
  sc.pcrb = false;
  auto off = CompareScenario("prieto-laps", sc, {}, mc, TestRegistry());
  ASSERT_TRUE(off.ok());
  EXPECT_TRUE(off->pcrb_note.empty());
}

TEST(CompareScenario, RunCountsThatCannotFinishAreRefused) {
  for (int runs : {0, kMaxMonteCarloRuns + 1, 2000000000}) {
    MonteCarloOptions mc;
    mc.runs = runs;
    auto c = CompareScenario("linear-gaussian", {}, {}, mc, TestRegistry());
    ASSERT_FALSE(c.ok()) << runs;
    EXPECT_THAT(c.status().message(), HasSubstr("runs must be in [1, 1000000]")) << runs;
  }
}

TEST(CompareScenario, OverrideErrorsNameTheirOrigin) {
  ScenarioCompareOptions sc;
  sc.overrides = YAML::Load("duration_s: 20\nlapz: 2\n");
  sc.overrides_origin = "my.yaml";
  MonteCarloOptions mc;
  auto c = CompareScenario("linear-gaussian", sc, {}, mc, TestRegistry());
  ASSERT_FALSE(c.ok());
  EXPECT_THAT(c.status().message(), HasSubstr("my.yaml: "));
  EXPECT_THAT(c.status().message(), HasSubstr("(line 2)"));
  EXPECT_THAT(c.status().message(), HasSubstr("lapz"));
  auto unknown = CompareScenario("no-such", {}, {}, mc, TestRegistry());
  ASSERT_FALSE(unknown.ok());
  EXPECT_THAT(unknown.status().message(), HasSubstr("tarrio-circle"));
}

// Test-only estimator that fails on about half the walks (by a bit of the first odometry
// increment, which the seed decides) and otherwise returns the truth + 0.5 m in y, with a
// covariance and a floor (all of which the shares' bytes must carry).
class FlakyOffset : public Estimator {
 public:
  Status CheckApplicable(const Walk& walk) const override {
    return walk.has_truth() && !walk.odometry.empty() ? Status::Ok()
                                                      : FailedPrecondition("needs odometry");
  }
  StatusOr<EstimateResult> Run(const Walk& walk) const override {
    uint64_t bits;
    std::memcpy(&bits, &walk.odometry.front().dist_m, sizeof(bits));
    if ((bits >> 20) & 1) return NumericalError("flaky: failed on this walk");
    EstimateResult r;
    for (const TruthSample& t : walk.truth) {
      TrajectoryPoint p;
      p.t_s = t.t_s;
      p.position_m = Eigen::Vector3d(t.position_m.x(), t.position_m.y() + 0.5, 0.0);
      p.covariance = Eigen::Matrix3d::Identity() * (0.1 + 0.01 * t.t_s);
      p.floor = 0;
      r.trajectory.points.push_back(p);
    }
    r.nis = {1.0, 2.5};
    r.diagnostics["points"] = static_cast<double>(r.trajectory.size());
    return r;
  }
};

EstimatorRegistry ShareRegistry() {
  EstimatorRegistry r = TestRegistry();
  EXPECT_TRUE(r.Register({"flaky-offset", "test: fails on some walks",
                          [](const Config&) -> StatusOr<std::unique_ptr<Estimator>> {
                            return std::unique_ptr<Estimator>(new FlakyOffset());
                          }})
                  .ok());
  return r;
}

std::string ErrorRowsOf(const Comparison& c) {
  std::ostringstream out;
  EXPECT_TRUE(c.errors_csv_rows && c.errors_csv_rows->CopyTo(out).ok());
  return out.str();
}

// Runs `n` shares (threads 2 each) and merges their runs in run order.
StatusOr<Comparison> MergedShares(int n, const ScenarioCompareOptions& sc, MonteCarloOptions mc,
                                  const EstimatorRegistry& registry) {
  std::vector<std::string> bytes(mc.runs);
  mc.threads = 2;
  for (int i = 0; i < n; ++i) {
    WG_RETURN_IF_ERROR(CompareScenarioShare(
        "linear-gaussian", sc, {}, mc, {i, n},
        [&](int run, std::string b) {
          EXPECT_EQ(run % n, i);
          bytes[run] = std::move(b);
          return Status::Ok();
        },
        registry));
  }
  ScenarioRunMerger merger(sc, mc);
  for (int run = 0; run < mc.runs; ++run) {
    WG_RETURN_IF_ERROR(merger.Add(bytes[run], "run " + std::to_string(run)));
  }
  return merger.Finish();
}

TEST(CompareScenarioShare, MergedSharesGiveCompareScenarioBitForBit) {
  const EstimatorRegistry registry = ShareRegistry();
  ScenarioCompareOptions sc;
  sc.overrides = YAML::Load("{duration_s: 20, range_sigma_m: 0.5}");
  MonteCarloOptions mc;
  mc.runs = 7;
  mc.seed = 4;
  auto whole = CompareScenario("linear-gaussian", sc, {}, mc, registry);
  ASSERT_TRUE(whole.ok()) << whole.status().message();
  ASSERT_EQ(whole->outcomes.size(), 2u);
  const EstimatorOutcome& flaky = whole->outcomes[1];
  // Run 0 fails for the flaky estimator, some later run does not: the kept trajectory comes
  // from a share other than run 0's.
  auto walk0 = SimulateScenario("linear-gaussian", MonteCarloSeed(mc.seed, 0), sc.overrides);
  ASSERT_TRUE(walk0.ok());
  ASSERT_FALSE(FlakyOffset().Run(*walk0).ok());
  ASSERT_GT(flaky.failed_runs, 0);
  ASSERT_LT(flaky.failed_runs, mc.runs);
  ASSERT_TRUE(whole->pcrb_rmse_m.has_value());
  for (int n : {1, 2, 3, 8}) {
    SCOPED_TRACE("shares: " + std::to_string(n));
    auto merged = MergedShares(n, sc, mc, registry);
    ASSERT_TRUE(merged.ok()) << merged.status().message();
    EXPECT_EQ(ResultsJsonText(*merged), ResultsJsonText(*whole));
    EXPECT_EQ(ErrorRowsOf(*merged), ErrorRowsOf(*whole));
    EXPECT_EQ(merged->pcrb_smoother_m, whole->pcrb_smoother_m);
    EXPECT_EQ(merged->truth.size(), whole->truth.size());
    EXPECT_EQ(merged->anchors.size(), whole->anchors.size());
    for (size_t k = 0; k < whole->outcomes.size(); ++k) {
      const EstimatorOutcome &a = whole->outcomes[k], &b = merged->outcomes[k];
      EXPECT_EQ(a.run_rmse_m, b.run_rmse_m);
      EXPECT_EQ(a.errors.error_m, b.errors.error_m);
      EXPECT_EQ(a.errors.nees, b.errors.nees);
      EXPECT_EQ(a.result.nis, b.result.nis);
      ASSERT_EQ(a.result.trajectory.size(), b.result.trajectory.size());
      for (size_t p = 0; p < a.result.trajectory.size(); ++p) {
        const TrajectoryPoint &x = a.result.trajectory.points[p],
                              &y = b.result.trajectory.points[p];
        EXPECT_EQ(x.position_m, y.position_m);
        EXPECT_EQ(x.covariance.has_value(), y.covariance.has_value());
        if (x.covariance && y.covariance) EXPECT_EQ(*x.covariance, *y.covariance);
        EXPECT_EQ(x.floor, y.floor);
      }
    }
  }
}

TEST(CompareScenarioShare, FailuresNameTheRunAndTheMergerKeepsRunOrder) {
  const EstimatorRegistry registry = TestRegistry();
  ScenarioCompareOptions sc;
  sc.overrides = YAML::Load("duration_s: 20\nlapz: 2\n");
  sc.overrides_origin = "my.yaml";
  MonteCarloOptions mc;
  mc.runs = 4;
  const auto keep = [](int, std::string) { return Status::Ok(); };
  Status s = CompareScenarioShare("linear-gaussian", sc, {}, mc, {1, 2}, keep, registry);
  ASSERT_FALSE(s.ok());
  EXPECT_THAT(s.message(), HasSubstr("run 1 (seed " + std::to_string(MonteCarloSeed(mc.seed, 1))));
  EXPECT_THAT(s.message(), HasSubstr("my.yaml: "));
  EXPECT_THAT(s.message(), HasSubstr("(line 2)"));
  // A share past the last run has nothing to do; a share outside 0..n-1 is refused.
  EXPECT_TRUE(CompareScenarioShare("linear-gaussian", sc, {}, mc, {5, 6}, keep, registry).ok());
  EXPECT_FALSE(CompareScenarioShare("linear-gaussian", sc, {}, mc, {2, 2}, keep, registry).ok());
  // A failing sink stops the share with its status.
  sc.overrides = YAML::Load("{duration_s: 20}");
  s = CompareScenarioShare(
      "linear-gaussian", sc, {}, mc, {0, 1}, [](int, std::string) { return IoError("disk full"); },
      registry);
  EXPECT_THAT(s.message(), HasSubstr("disk full"));
  // Runs must come in run order, each once, and all of them.
  std::vector<std::string> bytes(mc.runs);
  ASSERT_TRUE(CompareScenarioShare(
                  "linear-gaussian", sc, {}, mc, {0, 1},
                  [&](int run, std::string b) {
                    bytes[run] = std::move(b);
                    return Status::Ok();
                  },
                  registry)
                  .ok());
  ScenarioRunMerger skipped(sc, mc);
  EXPECT_THAT(skipped.Add(bytes[1], "rank 1").message(), HasSubstr("run 0 was due"));
  ScenarioRunMerger damaged(sc, mc);
  EXPECT_THAT(damaged.Add(bytes[0].substr(0, 100), "rank 0").message(), HasSubstr("damaged"));
  ScenarioRunMerger short_of_runs(sc, mc);
  ASSERT_TRUE(short_of_runs.Add(bytes[0], "rank 0").ok());
  EXPECT_THAT(short_of_runs.Finish().status().message(), HasSubstr("1 of 4 runs merged"));
}

}  // namespace
}  // namespace walkgraph
