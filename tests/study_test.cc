#include "walkgraph/study.h"

#include <unistd.h>

#include <atomic>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <set>
#include <sstream>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "config/reader.h"
#include "walkgraph/config.h"
#include "walkgraph/simulate.h"

namespace walkgraph {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;

std::atomic<int> g_runs{0};  // estimator runs, to check that validation runs nothing

// Test-only estimator: the truth shifted along x by an offset, so every error equals it.
//   offset      offset_m (option, default 0.3)
//   sigma       gain × the walk's radio.range_sigma_m (a simulator override)
//   seeded      (sim.seed mod 1000) / 1000 m: differs from run to run
class Shifted : public Estimator {
 public:
  enum Kind { kOffset, kSigma, kSeeded, kFails };
  Shifted(Kind kind, double value) : kind_(kind), value_(value) {}
  Status CheckApplicable(const Walk& w) const override {
    return w.has_truth() ? Status::Ok() : FailedPrecondition("needs truth");
  }
  StatusOr<EstimateResult> Run(const Walk& w) const override {
    ++g_runs;
    if (kind_ == kFails) return NumericalError("diverged on purpose");
    double d = value_;
    if (kind_ == kSigma) d = value_ * w.meta.radio.range_sigma_m;
    if (kind_ == kSeeded) d = Offset(static_cast<uint64_t>(w.meta.extra.at("sim.seed")));
    EstimateResult r;
    for (const TruthSample& t : w.truth) {
      TrajectoryPoint p;
      p.t_s = t.t_s;
      p.position_m = Eigen::Vector3d(t.position_m.x() + d, t.position_m.y(), 0.0);
      r.trajectory.points.push_back(p);
    }
    return r;
  }
  static double Offset(uint64_t seed) { return static_cast<double>(seed % 1000) / 1000.0; }

 private:
  Kind kind_;
  double value_;
};

EstimatorFactory Factory(Shifted::Kind kind, const char* key, double def) {
  return [kind, key, def](const Config& config) -> StatusOr<std::unique_ptr<Estimator>> {
    double v = def;
    ConfigReader r(config.node(), "test");
    if (key != nullptr) r.Read(key, &v);
    WG_RETURN_IF_ERROR(r.Finish());
    return std::unique_ptr<Estimator>(new Shifted(kind, v));
  };
}

const EstimatorRegistry& TestRegistry() {
  static const EstimatorRegistry* r = [] {
    auto* reg = new EstimatorRegistry();
    EXPECT_TRUE(reg->Register({"offset", "test", Factory(Shifted::kOffset, "offset_m", 0.3)}).ok());
    EXPECT_TRUE(reg->Register({"sigma", "test", Factory(Shifted::kSigma, "gain", 2.0)}).ok());
    EXPECT_TRUE(reg->Register({"seeded", "test", Factory(Shifted::kSeeded, nullptr, 0)}).ok());
    EXPECT_TRUE(reg->Register({"fails", "test", Factory(Shifted::kFails, nullptr, 0)}).ok());
    return reg;
  }();
  return *r;
}

const char* const kManifest = R"(name: unit
description: test study
estimators: [offset, seeded]
runs: 3
seed: 5
sweeps:
  - name: opt
    title: offset option
    scenario: linear-gaussian
    overrides: {duration_s: 10}
    estimator_option: {offset: offset_m}
    values: [0.1, 0.25, 0.5]
  - name: sim
    scenario: linear-gaussian
    overrides: {duration_s: 10}
    scenario_override: range_sigma_m
    estimators: [sigma, fails]
    values: [0.2, 0.4]
    runs: 2
)";

// study.csv as rows of fields (no quoted commas in these tests).
std::vector<std::map<std::string, std::string>> ParseCsv(const std::string& text) {
  std::istringstream in(text);
  std::string line;
  std::getline(in, line);
  std::vector<std::string> header;
  std::stringstream hs(line);
  for (std::string f; std::getline(hs, f, ',');) header.push_back(f);
  std::vector<std::map<std::string, std::string>> rows;
  while (std::getline(in, line)) {
    std::map<std::string, std::string> row;
    std::stringstream ls(line);
    size_t i = 0;
    std::string f;
    while (i < header.size()) {
      if (!std::getline(ls, f, ',')) f.clear();
      row[header[i++]] = f;
    }
    rows.push_back(row);
  }
  return rows;
}

double Num(const std::map<std::string, std::string>& row, const std::string& key) {
  EXPECT_FALSE(row.at(key).empty()) << key;
  return row.at(key).empty() ? NAN : std::stod(row.at(key));
}

TEST(Study, CsvMatchesIndependentlyComputedFigures) {
  auto m = ParseStudyManifest(kManifest, "unit.yaml", TestRegistry());
  ASSERT_TRUE(m.ok()) << m.status().message();
  auto r = RunStudy(*m, {}, TestRegistry());
  ASSERT_TRUE(r.ok()) << r.status().message();
  const auto rows = ParseCsv(StudyCsv(*r));
  ASSERT_EQ(rows.size(), 3u * 2u + 2u * 2u);
  // The seeded estimator's offsets over runs 0..2 of seed 5: mean and sample std.
  double o[3], mean = 0.0, var = 0.0;
  // (The walk keeps its seed as a double, sim.seed: the estimator sees it rounded.)
  for (int i = 0; i < 3; ++i) {
    const double seed = static_cast<double>(MonteCarloSeed(5, i));
    mean += (o[i] = Shifted::Offset(static_cast<uint64_t>(seed))) / 3.0;
  }
  for (double v : o) var += (v - mean) * (v - mean) / 2.0;
  auto distance = [](double sigma) {
    auto w = SimulateScenario(
        "linear-gaussian", MonteCarloSeed(5, 0),
        YAML::Load("{duration_s: 10, range_sigma_m: " + std::to_string(sigma) + "}"));
    EXPECT_TRUE(w.ok());
    return w->TruthDistance();
  };
  const double dist = distance(0.3);  // the preset's range σ; the walker does not depend on it
  const double values[] = {0.1, 0.25, 0.5};
  for (int v = 0; v < 3; ++v) {
    const auto& off = rows[2 * v];
    const auto& seeded = rows[2 * v + 1];
    EXPECT_EQ(off.at("sweep"), "opt");
    EXPECT_EQ(off.at("parameter"), "offset_m");
    EXPECT_EQ(off.at("estimator"), "offset");
    EXPECT_EQ(seeded.at("estimator"), "seeded");
    EXPECT_EQ(off.at("runs"), "3");
    EXPECT_EQ(off.at("seed"), "5");
    EXPECT_NEAR(std::stod(off.at("value")), values[v], 0.0);
    for (const char* k : {"rmse_m", "mean_m", "median_m", "p90_m", "max_m", "final_m"}) {
      // median and p90 pool the runs through the Monte Carlo sketch (relative accuracy 1e-4).
      const bool pooled = std::string(k) == "median_m" || std::string(k) == "p90_m";
      EXPECT_NEAR(Num(off, k), values[v], pooled ? 1e-4 * values[v] : 1e-9) << k;
      EXPECT_NEAR(Num(off, std::string(k) + "_std"), 0.0, 1e-9) << k;
    }
    EXPECT_NEAR(Num(off, "pct_distance"), 100.0 * values[v] / dist, 1e-6);
    EXPECT_EQ(off.at("n_points"), "63");  // 3 runs × 21 truth samples
    EXPECT_NEAR(Num(seeded, "rmse_m"), mean, 1e-9);
    EXPECT_NEAR(Num(seeded, "rmse_m_std"), std::sqrt(var), 1e-9);
    const double pcrb = Num(off, "pcrb_rmse_m");
    EXPECT_NEAR(Num(off, "rmse_over_pcrb"), values[v] / pcrb, 1e-8);
    EXPECT_TRUE(off.at("error").empty());
    EXPECT_TRUE(off.at("anees").empty());  // the test estimator reports no covariance
  }
  // The simulator sweep: the estimator sees range σ = value; the bound grows with it.
  auto b2 =
      ScenarioPcrb("linear-gaussian", YAML::Load("{duration_s: 10, range_sigma_m: 0.2}"), 2, 5, 1);
  ASSERT_TRUE(b2.ok());
  const auto& s2 = rows[6];
  const auto& f2 = rows[7];
  const auto& s4 = rows[8];
  EXPECT_EQ(s2.at("parameter"), "range_sigma_m");
  EXPECT_NEAR(Num(s2, "rmse_m"), 0.4, 1e-9);
  EXPECT_NEAR(Num(s4, "rmse_m"), 0.8, 1e-9);
  EXPECT_NEAR(Num(s2, "pcrb_rmse_m") / b2->smoother_rmse_m, 1.0, 1e-9);
  EXPECT_NEAR(Num(s2, "pcrb_filter_rmse_m") / b2->filter_rmse_m, 1.0, 1e-9);
  EXPECT_GT(Num(s4, "pcrb_rmse_m"), Num(s2, "pcrb_rmse_m"));
  EXPECT_EQ(f2.at("estimator"), "fails");
  EXPECT_EQ(f2.at("failed_runs"), "2");
  EXPECT_TRUE(f2.at("rmse_m").empty());
  EXPECT_THAT(f2.at("error"), HasSubstr("diverged on purpose"));
  const std::string table = FormatStudyTable(*r);
  EXPECT_THAT(table, HasSubstr("sweep opt (rmse_m, runs 3)"));
  EXPECT_THAT(table, HasSubstr("failed"));
}

// score_from_s (top level, overridden per sweep) leaves the start of every cell's walk out.
TEST(Study, ScoreFromLeavesOutTheStartOfEachCell) {
  const std::string manifest = R"(name: late
estimators: [offset]
runs: 3
seed: 5
score_from_s: 5
sweeps:
  - name: late
    scenario: linear-gaussian
    overrides: {duration_s: 10}
    estimator_option: offset_m
    values: [0.1]
  - name: whole
    scenario: linear-gaussian
    overrides: {duration_s: 10}
    estimator_option: offset_m
    values: [0.1]
    score_from_s: 0
)";
  auto m = ParseStudyManifest(manifest, "late.yaml", TestRegistry());
  ASSERT_TRUE(m.ok()) << m.status().message();
  EXPECT_EQ(m->sweeps[0].score_from_s, 5.0);
  EXPECT_EQ(m->sweeps[1].score_from_s, 0.0);
  auto r = RunStudy(*m, {}, TestRegistry());
  ASSERT_TRUE(r.ok()) << r.status().message();
  const auto rows = ParseCsv(StudyCsv(*r));
  ASSERT_EQ(rows.size(), 2u);
  EXPECT_EQ(rows[0].at("n_points"), "33");  // 3 runs × the 11 truth samples at t >= 5 s
  EXPECT_EQ(rows[1].at("n_points"), "63");  // 3 runs × 21
  EXPECT_NEAR(Num(rows[0], "rmse_m"), 0.1, 1e-9);
}

TEST(Study, DeterministicForThreadsAndWrittenAtomically) {
  auto m = ParseStudyManifest(kManifest, "unit.yaml", TestRegistry());
  ASSERT_TRUE(m.ok());
  StudyOptions one, two;
  two.threads = 2;
  int calls = 0;
  two.progress = [&](int done, int total) {
    EXPECT_EQ(done, ++calls);
    EXPECT_EQ(total, 5);
  };
  auto a = RunStudy(*m, one, TestRegistry());
  auto b = RunStudy(*m, two, TestRegistry());
  ASSERT_TRUE(a.ok() && b.ok());
  EXPECT_EQ(calls, 5);
  EXPECT_EQ(StudyCsv(*a), StudyCsv(*b));
  const fs::path out = fs::temp_directory_path() / ("wg_study_" + std::to_string(::getpid()));
  fs::remove_all(out);
  ASSERT_TRUE(WriteStudy(*a, out.string()).ok());
  for (const char* f : {"study.csv", "study.html", "timing.csv"}) {
    EXPECT_TRUE(fs::exists(out / f)) << f;
  }
  std::ifstream in(out / "study.html");
  const std::string html((std::istreambuf_iterator<char>(in)), {});
  EXPECT_THAT(html, HasSubstr("<svg id=\"sweep-opt\""));
  EXPECT_THAT(html, HasSubstr("<svg id=\"sweep-sim\""));
  EXPECT_THAT(html, HasSubstr("class=\"estimator-curve\""));
  EXPECT_THAT(html, HasSubstr("class=\"pcrb-curve\""));
  EXPECT_THAT(html, HasSubstr("class=\"std-bar\""));
  EXPECT_THAT(html, ::testing::Not(HasSubstr("<script")));
  EXPECT_THAT(html, ::testing::Not(HasSubstr("href=\"http")));  // no network
  EXPECT_FALSE(fs::exists(out.string() + ".tmp-" + std::to_string(::getpid())));
  // An unwritable destination leaves nothing behind.
  EXPECT_FALSE(WriteStudy(*a, "/proc/walkgraph-no/such/dir").ok());
  fs::remove_all(out);
}

// study.html: each estimator of a sweep in its own colour (the report's styles), and every
// legend entry right of the plot area, not over the data.
TEST(Study, PageStylesEstimatorsApartWithTheLegendOutsideThePlot) {
  auto m = ParseStudyManifest(kManifest, "unit.yaml", TestRegistry());
  ASSERT_TRUE(m.ok());
  auto r = RunStudy(*m, StudyOptions(), TestRegistry());
  ASSERT_TRUE(r.ok());
  const std::string html = RenderStudyHtml(*r);
  auto attr = [](const std::string& s, size_t from, const std::string& name) {
    const size_t at = s.find(" " + name + "=\"", from) + name.size() + 3;
    return s.substr(at, s.find('"', at) - at);
  };
  int plots = 0;
  for (size_t svg = html.find("<svg"); svg != std::string::npos; svg = html.find("<svg", svg + 1)) {
    const size_t end = html.find("</svg>", svg);
    const size_t area = html.find("class=\"plot-area\"", svg);
    ASSERT_LT(area, end);
    const double right = std::stod(attr(html, area, "x")) + std::stod(attr(html, area, "width"));
    std::set<std::string> colours;
    int curves = 0, legends = 0;
    for (size_t c = html.find("class=\"estimator-curve\"", svg); c < end;
         c = html.find("class=\"estimator-curve\"", c + 1)) {
      colours.insert(attr(html, c, "stroke"));
      ++curves;
    }
    for (size_t g = html.find("<g class=\"legend\">", svg); g < end;
         g = html.find("<g class=\"legend\">", g + 1)) {
      EXPECT_GT(std::stod(attr(html, g, "x1")), right);
      ++legends;
    }
    EXPECT_EQ(static_cast<int>(colours.size()), curves);
    EXPECT_GE(legends, curves);
    EXPECT_GE(curves, 2);
    ++plots;
  }
  EXPECT_EQ(plots, 2);
}

TEST(Study, WalkSweepsRunOnceOnTheRecordedWalk) {
  const std::string manifest = R"(name: walk
sweeps:
  - name: w
    walk: walks/valid_small
    estimators: [offset]
    estimator_option: offset_m
    values: [0.5, 1]
)";
  auto m = ParseStudyManifest(manifest, std::string(WALKGRAPH_TEST_DATA_DIR) + "/study.yaml",
                              TestRegistry());
  ASSERT_TRUE(m.ok()) << m.status().message();
  auto r = RunStudy(*m, {}, TestRegistry());
  ASSERT_TRUE(r.ok()) << r.status().message();
  const auto rows = ParseCsv(StudyCsv(*r));
  ASSERT_EQ(rows.size(), 2u);
  EXPECT_EQ(rows[0].at("runs"), "1");
  EXPECT_NEAR(Num(rows[0], "rmse_m"), 0.5, 1e-9);
  EXPECT_NEAR(Num(rows[1], "rmse_m"), 1.0, 1e-9);
  EXPECT_TRUE(rows[0].at("rmse_m_std").empty());
  EXPECT_TRUE(rows[0].at("pcrb_rmse_m").empty());
}

struct BadCase {
  const char* text;
  const char* message;  // expected in the error
  int line;             // expected "unit.yaml:<line>:"
};

TEST(Study, BadManifestsNameFileAndLine) {
  const std::string head = "name: bad\nestimators: [offset]\nsweeps:\n";
  const std::string sweep = "  - name: s\n    scenario: linear-gaussian\n";
  const BadCase cases[] = {
      {"nmae: x\n", "unknown key 'nmae'", 1},
      {"name: x\nsweeps: []\n", "non-empty list of sweeps", 2},
      {"name: x\nestimators: [offset, fg-batch-selfcal]\nsweeps: []\n",
       "unknown estimator 'fg-batch-selfcal'", 2},
      {"name: x\nruns: 0\nsweeps: []\n", "runs must be >= 1", 2},
      {"name: x\nruns: 1000001\nsweeps: []\n", "runs 1000001 over the cap of 1000000", 2},
      {"name: x\nmetric: accuracy\nsweeps: []\n", "unknown metric 'accuracy'", 2},
      {"name: x\nscore_from_s: -1\nsweeps: []\n", "score_from_s must be a number >= 0", 2},
      {"name: x\nsweeps: [\n", "", 0},  // YAML syntax error: still file:line
  };
  for (const BadCase& c : cases) {
    auto m = ParseStudyManifest(c.text, "unit.yaml", TestRegistry());
    ASSERT_FALSE(m.ok()) << c.text;
    EXPECT_THAT(m.status().message(), HasSubstr(c.message)) << c.text;
    EXPECT_THAT(m.status().message(), ::testing::StartsWith("unit.yaml:")) << c.text;
    if (c.line > 0) {
      EXPECT_THAT(m.status().message(),
                  ::testing::StartsWith("unit.yaml:" + std::to_string(c.line) + ":"))
          << m.status().message();
    }
  }
  const BadCase sweeps[] = {
      {"    scenario_override: duration_s\n    values: [a]\n", "must be a number", 7},
      {"    values: [1]\n", "exactly one of 'scenario_override' or 'estimator_option'", 4},
      {"    walk: x\n    estimator_option: offset_m\n    values: [1]\n", "exactly one of", 4},
      {"    estimator_option: offset_m\n    values: [1, 1.0]\n", "given twice", 7},
      {"    estimator_option: nope\n    values: [1, 2]\n", "unknown option 'nope'", 7},
      {"    estimator_option: {sigma: gain}\n    values: [1]\n", "not in the sweep's list", 6},
      {"    estimator_option: offset_m\n    values: [1]\n    colour: red\n", "unknown key 'colour'",
       8},
      {"    overrides: {duration_s: 5}\n    scenario_override: duration_s\n    values: [1]\n",
       "both swept and in overrides", 7},
      {"    estimator_option: offset_m\n    values: []\n", "non-empty list of numbers", 7},
  };
  for (const BadCase& c : sweeps) {
    const std::string text = head + sweep + c.text;
    auto m = ParseStudyManifest(text, "unit.yaml", TestRegistry());
    ASSERT_FALSE(m.ok()) << text;
    EXPECT_THAT(m.status().message(), HasSubstr(c.message)) << text;
    EXPECT_THAT(m.status().message(),
                ::testing::StartsWith("unit.yaml:" + std::to_string(c.line) + ":"))
        << m.status().message();
  }
  std::string many = "0";  // a sweep that cannot finish: one value over the cap
  for (size_t i = 1; i <= kMaxSweepValues; ++i) many += "," + std::to_string(i);
  auto capped = ParseStudyManifest(
      head + sweep + "    estimator_option: offset_m\n    values: [" + many + "]\n", "unit.yaml",
      TestRegistry());
  ASSERT_FALSE(capped.ok());
  EXPECT_THAT(capped.status().message(),
              ::testing::StartsWith("unit.yaml:7: sweep 's': 10001 values, over the cap of 10000"));
  auto unknown_scenario = ParseStudyManifest(
      head +
          "  - name: s\n    scenario: moon-walk\n    estimator_option: offset_m\n"
          "    values: [1]\n",
      "unit.yaml", TestRegistry());
  ASSERT_FALSE(unknown_scenario.ok());
  EXPECT_THAT(unknown_scenario.status().message(), HasSubstr("unit.yaml:5: unknown scenario"));
  auto twice =
      ParseStudyManifest(head + sweep + "    estimator_option: offset_m\n    values: [1]\n" +
                             sweep + "    estimator_option: offset_m\n    values: [1]\n",
                         "unit.yaml", TestRegistry());
  ASSERT_FALSE(twice.ok());
  EXPECT_THAT(twice.status().message(), HasSubstr("unit.yaml:8: sweep name 's' used twice"));
  auto missing_walk =
      ParseStudyManifest(head +
                             "  - name: s\n    walk: no/such/walk\n    estimator_option: offset_m\n"
                             "    values: [1]\n",
                         "unit.yaml", TestRegistry());
  ASSERT_FALSE(missing_walk.ok());
  EXPECT_THAT(missing_walk.status().message(), HasSubstr("does not exist"));
}

TEST(Study, BadSimulatorValueFailsBeforeAnythingRuns) {
  const std::string text =
      "name: bad\nestimators: [offset]\nsweeps:\n"
      "  - name: ok\n    scenario: linear-gaussian\n    overrides: {duration_s: 5}\n"
      "    estimator_option: offset_m\n    values: [1]\n"
      "  - name: s\n    scenario: linear-gaussian\n    overrides: {duration_s: 5}\n"
      "    scenario_override: range_sigma_m\n    values: [0.5, -1]\n";
  auto m = ParseStudyManifest(text, "unit.yaml", TestRegistry());
  ASSERT_TRUE(m.ok()) << m.status().message();
  g_runs = 0;
  auto r = RunStudy(*m, {}, TestRegistry());
  ASSERT_FALSE(r.ok());
  EXPECT_THAT(r.status().message(),
              ::testing::StartsWith("unit.yaml:13: sweep 's', value -1: simulate linear-gaussian"));
  EXPECT_EQ(g_runs.load(), 0);
}

// The 004 tables manifest: estimators other helpers are writing. With the built-in registry it
// either parses (they exist) or names the missing id with its line; with stand-ins accepting
// any options its sweeps are 004 Tables II and III.
TEST(Study, JimenezTablesManifestIsWellFormed) {
  const std::string path =
      std::string(WALKGRAPH_SOURCE_DIR) + "/datasets/studies/jimenez_tables.yaml";
  const EstimatorRegistry& builtin = EstimatorRegistry::Builtin();
  auto real = ReadStudyManifest(path, builtin);
  if (builtin.Find("jimenez-iez-rss") == nullptr || builtin.Find("fg-batch-selfcal") == nullptr) {
    ASSERT_FALSE(real.ok());
    EXPECT_THAT(real.status().message(), ::testing::MatchesRegex(".*jimenez_tables.yaml:[0-9]+: "
                                                                 "unknown estimator '.*"));
  } else {
    EXPECT_TRUE(real.ok()) << real.status().message();
  }
  EstimatorRegistry stand_ins;
  for (const char* id : {"jimenez-iez-rss", "fg-batch-selfcal"}) {
    ASSERT_TRUE(stand_ins
                    .Register({id, "stand-in",
                               [](const Config&) -> StatusOr<std::unique_ptr<Estimator>> {
                                 return std::unique_ptr<Estimator>(
                                     new Shifted(Shifted::kOffset, 0.0));
                               }})
                    .ok());
  }
  auto m = ReadStudyManifest(path, stand_ins);
  ASSERT_TRUE(m.ok()) << m.status().message();
  ASSERT_EQ(m->sweeps.size(), 2u);
  const StudySweep& t2 = m->sweeps[0];
  const StudySweep& t3 = m->sweeps[1];
  EXPECT_EQ(t2.scenario, "jimenez-building");
  EXPECT_EQ(t2.x.front(), 1.5);
  EXPECT_EQ(t2.x.back(), 4.0);
  EXPECT_EQ(t2.option_keys.at("jimenez-iez-rss"), "path_loss_exponent");
  EXPECT_TRUE(t2.scenario_override.empty());
  EXPECT_EQ(t3.scenario_override, "num_anchors");
  EXPECT_EQ(t3.x.front(), 5.0);
  EXPECT_EQ(t3.x.back(), 71.0);
}

}  // namespace
}  // namespace walkgraph
