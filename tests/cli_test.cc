// The walkgraph CLI as a user meets it: exit codes, messages, no partial outputs.
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;
using ::testing::Not;

struct CliRun {
  int code;
  std::string output;  // stdout + stderr
};

CliRun Cli(const std::string& args) {
  const std::string cmd = std::string(WALKGRAPH_CLI) + " " + args + " 2>&1";
  FILE* p = popen(cmd.c_str(), "r");
  std::string out;
  char buf[4096];
  while (size_t n = fread(buf, 1, sizeof(buf), p)) out.append(buf, n);
  const int status = pclose(p);
  return {WIFEXITED(status) ? WEXITSTATUS(status) : -1, out};
}

const std::string kData = WALKGRAPH_TEST_DATA_DIR;

TEST(Cli, ValidateAcceptsAndRejects) {
  CliRun ok = Cli("validate " + kData + "/walks/valid_small");
  EXPECT_EQ(ok.code, 0) << ok.output;
  EXPECT_THAT(ok.output, HasSubstr("OK"));
  CliRun bad = Cli("validate " + kData + "/malformed/nan_value");
  EXPECT_EQ(bad.code, 1);
  EXPECT_THAT(bad.output, HasSubstr("imu.csv:2:"));
}

TEST(Cli, CompareWritesReportFolderAndPrintsTable) {
  const fs::path out = fs::temp_directory_path() / ("wg_cli_cmp_" + std::to_string(::getpid()));
  fs::remove_all(out);
  CliRun r = Cli("compare " + kData + "/walks/valid_small --out " + out.string());
  EXPECT_EQ(r.code, 0) << r.output;
  EXPECT_THAT(r.output, HasSubstr("odometry-dr"));
  EXPECT_THAT(r.output, HasSubstr("rmse_m"));
  EXPECT_TRUE(fs::exists(out / "results.json"));
  EXPECT_TRUE(fs::exists(out / "report.html"));
  fs::remove_all(out);
}

// compare on one walk reports its progress on stderr; in a log (not a terminal) a plain line
// every WALKGRAPH_PROGRESS_INTERVAL_S seconds (10 by default; 0 here: every report).
TEST(Cli, CompareOnOneWalkReportsProgressInALog) {
  const fs::path out = fs::temp_directory_path() / ("wg_cli_prog_" + std::to_string(::getpid()));
  fs::remove_all(out);
  const std::string cmd = "compare " + kData + "/walks/valid_small --out " + out.string();
  CliRun r = Cli(cmd);  // the default interval: a short run prints no progress
  EXPECT_EQ(r.code, 0) << r.output;
  EXPECT_THAT(r.output, Not(HasSubstr("estimators (")));
  fs::remove_all(out);
  ::setenv("WALKGRAPH_PROGRESS_INTERVAL_S", "0", 1);
  r = Cli(cmd);
  ::unsetenv("WALKGRAPH_PROGRESS_INTERVAL_S");
  EXPECT_EQ(r.code, 0) << r.output;
  EXPECT_THAT(r.output,
              ::testing::ContainsRegex("compare: 0/[0-9]+ estimators \\(0%\\), 0 s elapsed"));
  EXPECT_THAT(r.output,
              ::testing::ContainsRegex("compare: 1/[0-9]+ estimators \\([0-9]+%\\), [0-9]+ s "
                                       "elapsed, about [0-9]+ s left"));
  EXPECT_THAT(r.output, ::testing::ContainsRegex("compare: [0-9]+/[0-9]+ estimators \\(100%\\)"));
  fs::remove_all(out);
  // The same mechanism counts Monte Carlo runs.
  ::setenv("WALKGRAPH_PROGRESS_INTERVAL_S", "0", 1);
  r = Cli("compare --scenario linear-gaussian --runs 3 --estimators odometry-dr --out " +
          out.string());
  ::unsetenv("WALKGRAPH_PROGRESS_INTERVAL_S");
  EXPECT_EQ(r.code, 0) << r.output;
  EXPECT_THAT(r.output, ::testing::ContainsRegex("compare: 1/3 runs \\(33%\\), [0-9]+ s elapsed, "
                                                 "about [0-9]+ s left"));
  EXPECT_THAT(r.output, HasSubstr("compare: 3/3 runs (100%)"));
  fs::remove_all(out);
}

TEST(Cli, VersionListIdAndSpacedEstimatorList) {
  CliRun v = Cli("--version");
  EXPECT_EQ(v.code, 0) << v.output;
  EXPECT_THAT(v.output, ::testing::MatchesRegex("walkgraph [0-9]+\\.[0-9]+\\.[0-9]+\n"));
  CliRun list = Cli("list");
  EXPECT_THAT(list.output, HasSubstr("walkgraph list ID"));
  CliRun id = Cli("list fg-window");
  EXPECT_EQ(id.code, 0) << id.output;
  EXPECT_THAT(id.output, HasSubstr("fg-window  — "));
  // option, default, unit from the key, its doc; a string option's values and its doc
  EXPECT_THAT(id.output, ::testing::ContainsRegex(
                             "\n  lag_s +10 +s +fg-window: span of the fixed-lag window\n"));
  EXPECT_THAT(id.output,
              ::testing::ContainsRegex("\n  path_loss +'auto' +one of "
                                       "auto\\|fixed\\|global\\|per-anchor\\|hierarchical +"
                                       "self-calibration of the path loss"));
  EXPECT_THAT(id.output, ::testing::ContainsRegex("\n  pdr\\.detector +'vertical-peak' +one of "));
  CliRun bad = Cli("list nope");
  EXPECT_EQ(bad.code, 1);
  EXPECT_THAT(bad.output, HasSubstr("unknown estimator 'nope'"));
  const fs::path out = fs::temp_directory_path() / ("wg_cli_sp_" + std::to_string(::getpid()));
  fs::remove_all(out);
  CliRun r = Cli("compare " + kData +
                 "/walks/valid_small --estimators ' odometry-dr , fg-batch' "
                 "--out " +
                 out.string());
  EXPECT_EQ(r.code, 0) << r.output;
  EXPECT_TRUE(fs::exists(out / "trajectories" / "fg-batch.csv"));
  EXPECT_TRUE(fs::exists(out / "truth.tum"));
  CliRun empty = Cli("compare " + kData +
                     "/walks/valid_small --estimators 'odometry-dr, ,x' "
                     "--out " +
                     out.string());
  EXPECT_EQ(empty.code, 1);
  EXPECT_THAT(empty.output, HasSubstr("empty estimator id"));
  fs::remove_all(out);
}

TEST(Cli, FailureLeavesNoOutput) {
  const fs::path out = fs::temp_directory_path() / ("wg_cli_fail_" + std::to_string(::getpid()));
  fs::remove_all(out);
  CliRun r = Cli("compare " + kData + "/malformed/time_backwards --out " + out.string());
  EXPECT_EQ(r.code, 1);
  EXPECT_FALSE(fs::exists(out));
  r = Cli("smooth " + kData + "/walks/valid_small --estimator nope --out " + out.string() + ".tum");
  EXPECT_EQ(r.code, 1);
  EXPECT_THAT(r.output, HasSubstr("unknown estimator 'nope'"));
  EXPECT_FALSE(fs::exists(out.string() + ".tum"));
}

TEST(Cli, SmoothWritesTum) {
  const fs::path out =
      fs::temp_directory_path() / ("wg_cli_" + std::to_string(::getpid()) + ".tum");
  CliRun r =
      Cli("smooth " + kData + "/walks/valid_small --estimator odometry-dr --out " + out.string());
  EXPECT_EQ(r.code, 0) << r.output;
  EXPECT_TRUE(fs::exists(out));
  fs::remove(out);
}

// smooth --config takes compare's file shape (the section of its estimator) as well as one
// estimator's options alone; compare's error for the latter says which shape it expects.
TEST(Cli, SmoothAndCompareTakeTheSameConfigShape) {
  const fs::path dir = fs::temp_directory_path() / ("wg_cli_shape_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  auto write = [&](const std::string& name, const std::string& text) {
    std::ofstream(dir / name) << text;
    return (dir / name).string();
  };
  const std::string sections = write("sections.yaml", "fg-batch: {max_iterations: 20}\n");
  const std::string flat = write("flat.yaml", "max_iterations: 20\n");
  const std::string bad = write("bad.yaml", "fg-batch: {max_iterations: 0}\n");
  const std::string other = write("other.yaml", "odometry-dr: {}\n");
  int n = 0;  // a new output file each time
  auto smooth = [&](const std::string& config) {
    return Cli("smooth " + kData + "/walks/valid_small --estimator fg-batch --out " +
               (dir / ("t" + std::to_string(++n) + ".tum")).string() + " --config " + config);
  };
  EXPECT_EQ(smooth(sections).code, 0);
  EXPECT_EQ(smooth(flat).code, 0);
  CliRun r = smooth(bad);  // the section is what is read
  EXPECT_EQ(r.code, 1);
  EXPECT_THAT(r.output, HasSubstr("max_iterations"));
  r = smooth(other);
  EXPECT_EQ(r.code, 1);
  EXPECT_THAT(r.output, HasSubstr("without a section for 'fg-batch'"));
  r = Cli("compare " + kData + "/walks/valid_small --estimators fg-batch --out " +
          (dir / "c").string() + " --config " + flat);
  EXPECT_EQ(r.code, 1);
  EXPECT_THAT(r.output, HasSubstr("one section per estimator"));
  EXPECT_EQ(Cli("compare " + kData + "/walks/valid_small --estimators fg-batch --out " +
                (dir / "c").string() + " --config " + sections)
                .code,
            0);
  fs::remove_all(dir);
}

TEST(Cli, UsageErrorsAreNonZero) {
  EXPECT_NE(Cli("").code, 0);
  EXPECT_NE(Cli("validate").code, 0);
  EXPECT_NE(Cli("frobnicate x").code, 0);
  CliRun list = Cli("list");
  EXPECT_EQ(list.code, 0);
  EXPECT_THAT(list.output, HasSubstr("odometry-dr"));
  EXPECT_THAT(list.output, HasSubstr("plaza"));
}

TEST(Cli, CompareTakesScenarioOverridesAndReportsThePcrb) {
  const fs::path dir = fs::temp_directory_path() / ("wg_cli_sc_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  const fs::path good = dir / "short.yaml", bad = dir / "bad.yaml";
  { std::ofstream(good) << "duration_s: 20\nrange_sigma_m: 0.5\n"; }
  { std::ofstream(bad) << "duration_s: 20\nlapz: 2\n"; }
  const fs::path out = dir / "out";
  CliRun r = Cli("compare --scenario linear-gaussian --scenario-config " + good.string() +
                 " --runs 3 --out " + out.string());
  EXPECT_EQ(r.code, 0) << r.output;
  EXPECT_THAT(r.output, HasSubstr("PCRB smoother"));
  std::ifstream in(out / "results.json");
  const std::string json((std::istreambuf_iterator<char>(in)), {});
  EXPECT_THAT(json, HasSubstr("\"pcrb_filter_rmse_m\": 0."));
  EXPECT_THAT(json, HasSubstr("\"rmse_over_pcrb\""));
  r = Cli("compare --scenario linear-gaussian --scenario-config " + bad.string() + " --out " +
          (dir / "out2").string());
  EXPECT_EQ(r.code, 1);
  EXPECT_THAT(r.output, HasSubstr(bad.string() + ": simulate linear-gaussian (line 2)"));
  EXPECT_FALSE(fs::exists(dir / "out2"));
  r = Cli("compare " + kData + "/walks/valid_small --scenario-config " + good.string() + " --out " +
          (dir / "out3").string());
  EXPECT_NE(r.code, 0);
  r = Cli("pcrb --scenario linear-gaussian --scenario-config " + good.string() + " --runs 2");
  EXPECT_EQ(r.code, 0) << r.output;
  EXPECT_THAT(r.output, HasSubstr("smoother"));
  { std::ofstream(dir / "foot.yaml") << "laps: 1\n"; }
  r = Cli("pcrb --scenario prieto-laps --scenario-config " + (dir / "foot.yaml").string());
  EXPECT_EQ(r.code, 1);
  EXPECT_THAT(r.output, HasSubstr("foot"));
  fs::remove_all(dir);
}

TEST(Cli, StudyWritesCsvAndHtmlOrFailsWithTheManifestLine) {
  const fs::path dir = fs::temp_directory_path() / ("wg_cli_study_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  {
    std::ofstream(dir / "ok.yaml") << "name: cli\nestimators: [odometry-dr]\nruns: 2\nsweeps:\n"
                                      "  - name: step-noise\n    scenario: linear-gaussian\n"
                                      "    overrides: {duration_s: 10}\n"
                                      "    scenario_override: step_sigma_m\n"
                                      "    values: [0.02, 0.08]\n";
    std::ofstream(dir / "bad.yaml") << "name: cli\nestimators: [odometry-dr,\n  fg-nope]\n"
                                       "sweeps: []\n";
  }
  CliRun r =
      Cli("study " + (dir / "ok.yaml").string() + " --threads 2 --out " + (dir / "out").string());
  EXPECT_EQ(r.code, 0) << r.output;
  EXPECT_THAT(r.output, HasSubstr("sweep step-noise"));
  EXPECT_TRUE(fs::exists(dir / "out" / "study.csv"));
  EXPECT_TRUE(fs::exists(dir / "out" / "study.html"));
  r = Cli("study " + (dir / "bad.yaml").string() + " --out " + (dir / "out2").string());
  EXPECT_EQ(r.code, 1);
  EXPECT_THAT(r.output, HasSubstr((dir / "bad.yaml").string() + ":3: unknown estimator 'fg-nope'"));
  EXPECT_FALSE(fs::exists(dir / "out2"));
  fs::remove_all(dir);
}

// survey and --radio-map as a user meets them: two simulated walks with every other anchor's
// position blanked in anchors.csv give a radio map (anchors.csv, survey.csv) and its variance
// factor; compare on a third such walk takes the map. A walk that lost its truth, and a map that is
// not there, are errors naming the file, and leave no output.
TEST(Cli, SurveyWritesARadioMapThatCompareTakes) {
  const fs::path dir = fs::temp_directory_path() / ("wg_cli_survey_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  std::ofstream(dir / "laps.yaml") << "{laps: 1}\n";
  auto simulate = [&](int seed) {
    const fs::path w = dir / ("walk" + std::to_string(seed));
    CliRun r = Cli("simulate --scenario tarrio-circle --seed " + std::to_string(seed) +
                   " --config " + (dir / "laps.yaml").string() + " --out " + w.string());
    EXPECT_EQ(r.code, 0) << r.output;
    std::ifstream in(w / "anchors.csv");
    std::string line, text;
    for (int i = 0; std::getline(in, line); ++i) {
      if (i > 0 && i % 2 == 1) {  // id,,,z_m: position unknown
        const size_t c1 = line.find(','), c3 = line.rfind(',');
        line = line.substr(0, c1) + ",," + line.substr(c3);
      }
      text += line + "\n";
    }
    in.close();
    std::ofstream(w / "anchors.csv") << text;
    return w.string();
  };
  const std::string w1 = simulate(1), w2 = simulate(2), w3 = simulate(3);
  const std::string map = (dir / "map").string();
  CliRun r = Cli("survey " + w1 + " " + w2 + " --out " + map);
  ASSERT_EQ(r.code, 0) << r.output;
  EXPECT_THAT(r.output, HasSubstr("anchors placed from 2 walks"));
  EXPECT_THAT(r.output, HasSubstr("variance factor "));
  std::ifstream details(dir / "map" / "survey.csv");
  std::string header;
  std::getline(details, header);
  EXPECT_EQ(header, "id,x_m,y_m,cov_xx,cov_xy,cov_yy,walks,readings,disagreement");
  std::ifstream anchors(dir / "map" / "anchors.csv");
  std::getline(anchors, header);
  EXPECT_THAT(header, HasSubstr("sigma_m"));

  const std::string out = (dir / "cmp").string();
  r = Cli("compare " + w3 + " --radio-map " + map + " --estimators fg-batch --out " + out);
  EXPECT_EQ(r.code, 0) << r.output;
  EXPECT_THAT(r.output, HasSubstr("placed by the radio map"));
  EXPECT_TRUE(fs::exists(dir / "cmp" / "results.json"));

  fs::remove(fs::path(w1) / "truth.csv");
  r = Cli("survey " + w1 + " " + w2 + " --out " + (dir / "map2").string());
  EXPECT_EQ(r.code, 1);
  EXPECT_THAT(r.output, HasSubstr("truth.csv is missing"));
  EXPECT_FALSE(fs::exists(dir / "map2"));
  r = Cli("compare " + w3 + " --radio-map " + (dir / "nomap").string() +
          " --estimators fg-batch --out " + (dir / "cmp2").string());
  EXPECT_EQ(r.code, 1);
  EXPECT_THAT(r.output, HasSubstr("nomap"));
  EXPECT_FALSE(fs::exists(dir / "cmp2"));
  fs::remove_all(dir);
}

}  // namespace
