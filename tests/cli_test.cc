// The walkgraph CLI as a user meets it: exit codes, messages, no partial outputs.
#include <cstdio>
#include <filesystem>
#include <string>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;

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

TEST(Cli, FailureLeavesNoOutput) {
  const fs::path out = fs::temp_directory_path() / ("wg_cli_fail_" + std::to_string(::getpid()));
  fs::remove_all(out);
  CliRun r = Cli("compare " + kData + "/malformed/time_backwards --out " + out.string());
  EXPECT_EQ(r.code, 1);
  EXPECT_FALSE(fs::exists(out));
  r = Cli("smooth " + kData + "/walks/valid_small --estimator nope --out " + out.string() +
          ".tum");
  EXPECT_EQ(r.code, 1);
  EXPECT_THAT(r.output, HasSubstr("unknown estimator 'nope'"));
  EXPECT_FALSE(fs::exists(out.string() + ".tum"));
}

TEST(Cli, SmoothWritesTum) {
  const fs::path out = fs::temp_directory_path() / ("wg_cli_" + std::to_string(::getpid()) + ".tum");
  CliRun r = Cli("smooth " + kData + "/walks/valid_small --estimator odometry-dr --out " +
              out.string());
  EXPECT_EQ(r.code, 0) << r.output;
  EXPECT_TRUE(fs::exists(out));
  fs::remove(out);
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

}  // namespace
