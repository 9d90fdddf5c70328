#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <random>
#include <set>
#include <sstream>

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "walkgraph/compare.h"
#include "walkgraph/io.h"

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
  EXPECT_NEAR(agg.stats.p75_m, Percentile(pooled, 75.0), 1e-12);
  EXPECT_EQ(agg.error_run.size(), pooled.size());
  EXPECT_EQ(agg.error_run.back(), 5);
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
    EXPECT_THAT(ReadFile(out / "errors.csv"), HasSubstr("t_s,estimator,error_m,run\n"));
  }
  EXPECT_EQ(json[0], json[1]);
  const nlohmann::json j = nlohmann::json::parse(json[0]);
  EXPECT_EQ(j["runs"], 8);
  EXPECT_EQ(j["seed"], 2024);
  const auto& e = j["estimators"]["odometry-dr"];
  for (const char* key : {"rmse_m", "rmse_m_std", "p75_m", "p75_m_std", "max_m_std",
                          "pct_distance_std", "n_points", "failed_runs"}) {
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
  EXPECT_EQ(c->outcomes[0].stats.median_m, 2.0);
  auto all_bad = AggregateRuns({b, b});
  ASSERT_TRUE(all_bad.ok());
  EXPECT_FALSE(all_bad->outcomes[0].status.ok());
  EXPECT_THAT(all_bad->outcomes[0].status.message(), HasSubstr("run 0: diverged"));
}

}  // namespace
}  // namespace walkgraph
