#include <filesystem>
#include <fstream>
#include <string>

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include "walkgraph/convert.h"
#include "walkgraph/io.h"

namespace walkgraph {
namespace {

namespace fs = std::filesystem;
const std::string kDir = std::string(WALKGRAPH_SHARED_DATASETS) + "/pyshoe_vicon";
const std::string kTrial = kDir + "/2017-11-22-11-22-03.csv";

fs::path Scratch(const std::string& name) {
  const fs::path p = fs::temp_directory_path() / ("wg_pyshoe_" + name + std::to_string(::getpid()));
  fs::remove_all(p);
  fs::create_directories(p);
  return p;
}

// The first `n` data lines of the real trial.
std::string Slice(int n) {
  std::ifstream in(kTrial);
  std::string line, out;
  for (int i = 0; i <= n && std::getline(in, line); ++i) out += line + "\n";
  return out;
}

TEST(ConvertPyshoe, ConvertsASliceOfTheRealTrial) {
  if (!fs::exists(kTrial)) GTEST_SKIP() << kTrial << " not present";
  const fs::path dir = Scratch("slice");
  std::ofstream(dir / "slice.csv") << Slice(200);
  auto walk = Convert("pyshoe", {(dir / "slice.csv").string()});
  ASSERT_TRUE(walk.ok()) << walk.status().ToString();
  ASSERT_EQ(walk->imu.size(), 200u);
  ASSERT_EQ(walk->truth.size(), 200u);
  ASSERT_EQ(walk->stance_truth.size(), 200u);
  EXPECT_EQ(walk->meta.imu_placement, ImuPlacement::kFoot);
  EXPECT_EQ(walk->meta.truth_kind, TruthKind::kContinuous);
  // Line 2 of the file: 0.0051913,-2.781892,0.2996585,-9.352644,0.003968967,0.01233494,
  // -0.008478473,-0.02758145,0.06342755,0.125979,1
  EXPECT_DOUBLE_EQ(walk->imu[0].t_s, 0.0051913);
  EXPECT_DOUBLE_EQ(walk->imu[0].acc_mps2.z(), -9.352644);
  EXPECT_DOUBLE_EQ(walk->imu[0].gyro_radps.y(), 0.01233494);
  EXPECT_DOUBLE_EQ(walk->truth[0].position_m.z(), 0.125979);
  EXPECT_TRUE(walk->truth[0].has_z);
  EXPECT_TRUE(walk->stance_truth[0].stance);
  EXPECT_TRUE(ValidateWalk(*walk).ok());
  // Round trip through the walk format.
  ASSERT_TRUE(WriteWalk(*walk, (dir / "walk").string()).ok());
  auto back = ReadWalk((dir / "walk").string());
  ASSERT_TRUE(back.ok()) << back.status().ToString();
  EXPECT_EQ(back->stance_truth.size(), 200u);
  EXPECT_EQ(back->imu.size(), 200u);
  fs::remove_all(dir);
}

TEST(ConvertPyshoe, WholeTrialsConvert) {
  if (!fs::exists(kDir)) GTEST_SKIP() << kDir << " not present";
  auto walk = Convert("pyshoe", {kTrial});
  ASSERT_TRUE(walk.ok()) << walk.status().ToString();
  EXPECT_EQ(walk->imu.size(), 6490u);
  long stance = 0;
  for (const auto& s : walk->stance_truth) stance += s.stance ? 1 : 0;
  EXPECT_EQ(stance, 3955);
}

TEST(ConvertPyshoe, MalformedInputNamesFileAndLine) {
  const fs::path dir = Scratch("bad");
  const std::string header =
      "t_s,ax_mps2,ay_mps2,az_mps2,gx_radps,gy_radps,gz_radps,gt_x_m,gt_y_m,gt_z_m,zv_vicon\n";
  const std::string row1 = "0.005,0,0,-9.8,0,0,0,0,0,0.1,1\n";
  auto convert = [&](const std::string& text) {
    std::ofstream(dir / "t.csv") << text;
    return Convert("pyshoe", {(dir / "t.csv").string()});
  };
  auto w = convert(header + row1 + "0.010,0,0,-9.8,0,0,0,0,0,0.1,2\n");
  ASSERT_FALSE(w.ok());
  EXPECT_THAT(w.status().message(), ::testing::HasSubstr("t.csv:3: zv_vicon"));
  w = convert(header + row1 + "0.004,0,0,-9.8,0,0,0,0,0,0.1,1\n");
  ASSERT_FALSE(w.ok());
  EXPECT_THAT(w.status().message(), ::testing::HasSubstr("t.csv:3: time does not increase"));
  w = convert(header + row1 + "0.010,0,0,-9.8,0,0,0,0,0,0.1\n");
  ASSERT_FALSE(w.ok());
  EXPECT_THAT(w.status().message(), ::testing::HasSubstr("t.csv:3"));
  w = convert("t,ax,ay,az,gx,gy,gz,x,y,z,zv\n" + row1);
  ASSERT_FALSE(w.ok());
  EXPECT_THAT(w.status().message(), ::testing::HasSubstr("t.csv:1: expected the header"));
  w = convert(header);
  EXPECT_FALSE(w.ok());
  EXPECT_FALSE(Convert("pyshoe", {}).ok());
  fs::remove_all(dir);
}

}  // namespace
}  // namespace walkgraph
