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
  // 6 of the first 200 Vicon samples repeat the previous one exactly (counted with numpy).
  ASSERT_EQ(walk->truth.size(), 194u);
  EXPECT_EQ(walk->meta.extra.at("convert.truth_held_dropped"), 6.0);
  ASSERT_EQ(walk->stance_truth.size(), 200u);
  EXPECT_EQ(walk->meta.imu_placement, ImuPlacement::kFoot);
  EXPECT_EQ(walk->meta.truth_kind, TruthKind::kContinuous);
  // Line 2 of the file: 0.0051913,-2.781892,0.2996585,-9.352644,0.003968967,0.01233494,
  // -0.008478473,-0.02758145,0.06342755,0.125979,1
  EXPECT_DOUBLE_EQ(walk->imu[0].t_s, 0.0051913);
  EXPECT_DOUBLE_EQ(walk->imu[0].acc_mps2.z(), -9.352644);
  EXPECT_DOUBLE_EQ(walk->imu[0].gyro_radps.y(), 0.01233494);
  EXPECT_DOUBLE_EQ(walk->truth[0].position_m.z(), 0.125979);
  // Left-handed Vicon x-y → ENU: y negated, x and z kept (see src/convert/pyshoe.cc).
  EXPECT_DOUBLE_EQ(walk->truth[0].position_m.x(), -0.02758145);
  EXPECT_DOUBLE_EQ(walk->truth[0].position_m.y(), -0.06342755);
  // Line 4 repeats line 3's position: dropped, so truth[2] is line 5's (t = 0.02013436).
  EXPECT_DOUBLE_EQ(walk->truth[1].t_s, 0.01016036);
  EXPECT_DOUBLE_EQ(walk->truth[2].t_s, 0.02013436);
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
  // 3955 labels of 1 in the file; over the Vicon dropout (13.24–13.61 s: 75 held samples in
  // mid-swing) zv_vicon reads 1, and those labels become the swing label before the hold.
  EXPECT_EQ(walk->meta.extra.at("convert.truth_held_dropped"), 108.0);  // numpy count
  EXPECT_EQ(walk->truth.size(), 6490u - 108u);
  EXPECT_LT(stance, 3955 - 60);
  // Labels change both ways near a hold (a stance repeat can also turn a 0 into the last 1), so
  // the changed-label count bounds the net loss of stance labels from above.
  EXPECT_GE(walk->meta.extra.at("convert.stance_labels_held"), static_cast<double>(3955 - stance));
  for (const auto& s : walk->stance_truth) {
    if (s.t_s > 13.30 && s.t_s < 13.60) EXPECT_FALSE(s.stance) << s.t_s;
  }
}

// A held position in swing (zv_vicon 1 from the stale velocity) becomes swing; a held position
// inside a stance stays stance; the held samples leave the truth.
TEST(ConvertPyshoe, HeldTruthIsDroppedAndItsLabelsRepeatTheLastFreshOne) {
  const fs::path dir = Scratch("held");
  std::string text =
      "t_s,ax_mps2,ay_mps2,az_mps2,gx_radps,gy_radps,gz_radps,gt_x_m,gt_y_m,gt_z_m,zv_vicon\n";
  // Samples 0..9 stance, moving by 10 µm; sample 5 repeats sample 4. Samples 10..29 swing
  // moving 1 cm per sample, except 15..24 holding sample 14's position with zv_vicon 1.
  for (int i = 0; i < 30; ++i) {
    double x = i < 10 ? 1e-5 * i : 1e-4 + 0.01 * (i - 9);
    if (i == 5) x = 1e-5 * 4;
    if (i >= 15 && i <= 24) x = 1e-4 + 0.01 * (14 - 9);
    const int zv = i < 10 || (i >= 15 && i <= 24) ? 1 : 0;
    text += std::to_string(0.005 * (i + 1)) + ",0,0,-9.8,0,0,0," + std::to_string(x) + ",0.5,0.1," +
            std::to_string(zv) + "\n";
  }
  std::ofstream(dir / "h.csv") << text;
  auto walk = Convert("pyshoe", {(dir / "h.csv").string()});
  ASSERT_TRUE(walk.ok()) << walk.status().ToString();
  EXPECT_EQ(walk->truth.size(), 30u - 11u);
  EXPECT_EQ(walk->meta.extra.at("convert.truth_held_dropped"), 11.0);
  for (const auto& t : walk->truth) EXPECT_DOUBLE_EQ(t.position_m.y(), -0.5);
  ASSERT_EQ(walk->stance_truth.size(), 30u);
  for (int i = 0; i < 10; ++i) EXPECT_TRUE(walk->stance_truth[i].stance) << i;
  for (int i = 10; i < 30; ++i) EXPECT_FALSE(walk->stance_truth[i].stance) << i;
  EXPECT_EQ(walk->meta.extra.at("convert.stance_labels_held"), 10.0);
  fs::remove_all(dir);
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
