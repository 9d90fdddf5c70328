#include <cmath>
#include <filesystem>
#include <fstream>

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "walkgraph/compare.h"
#include "walkgraph/io.h"
#include "walkgraph/simulate.h"

namespace walkgraph {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;

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

// score_from_s drops the truth before t_first + score_from_s from every figure and counts it
// as skipped; the rest of the series is the whole walk's, unchanged.
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
  for (const char* f :
       {"results.json", "errors.csv", "report.html", "trajectories/odometry-dr.tum"}) {
    EXPECT_TRUE(fs::exists(out / f)) << f;
  }
  std::ifstream in(out / "results.json");
  const nlohmann::json j = nlohmann::json::parse(in);
  EXPECT_EQ(j["walk"], "valid_small");
  EXPECT_EQ(j["runs"], 1);
  EXPECT_EQ(j["truth_kind"], "continuous");
  const auto& e = j["estimators"]["odometry-dr"];
  for (const char* key : {"rmse_m", "mean_m", "median_m", "p75_m", "p90_m", "max_m", "final_m",
                          "pct_distance", "mean_pct_distance", "anees", "runtime_s", "n_points"}) {
    EXPECT_TRUE(e.contains(key)) << key;
  }
  EXPECT_TRUE(j.contains("pcrb_rmse_m"));
  std::ifstream html(out / "report.html");
  const std::string page((std::istreambuf_iterator<char>(html)), {});
  EXPECT_THAT(page, HasSubstr("id=\"trajectories\""));
  EXPECT_THAT(page, HasSubstr("id=\"error-cdf\""));
  EXPECT_THAT(page, HasSubstr("class=\"anchor\""));
  EXPECT_THAT(page, ::testing::Not(HasSubstr("http://www.w3.org/2000/svg\" src")));
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
  for (const char* f : {"results.json", "errors.csv", "trajectories/odometry-dr.tum",
                        "trajectories/fg-batch.tum"}) {
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

}  // namespace
}  // namespace walkgraph
