#include <filesystem>
#include <fstream>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "walkgraph/convert.h"
#include "walkgraph/io.h"

namespace walkgraph {
namespace {

namespace fs = std::filesystem;
const std::string kPlaza = std::string(WALKGRAPH_SHARED_DATASETS) + "/plaza";

fs::path Scratch(const std::string& name) {
  const fs::path p = fs::temp_directory_path() / ("wg_plaza_" + name + std::to_string(::getpid()));
  fs::remove_all(p);
  fs::create_directories(p);
  return p;
}

TEST(ConvertPlaza, ConvertsTheSharedRecording) {
  if (!fs::exists(kPlaza)) GTEST_SKIP() << kPlaza << " not present";
  auto walk = Convert("plaza", {kPlaza});
  ASSERT_TRUE(walk.ok()) << walk.status().message();
  EXPECT_EQ(walk->anchors.size(), 4u);
  EXPECT_EQ(walk->odometry.size(), 9657u);
  EXPECT_EQ(walk->ranges.size(), 3529u - 2u);  // two exact repeats dropped
  EXPECT_EQ(walk->meta.extra.at("convert.range_duplicates_dropped"), 2.0);
  EXPECT_EQ(walk->truth.size(), 9658u);
  EXPECT_TRUE(ValidateWalk(*walk).ok());
  ASSERT_TRUE(walk->meta.initial_pose.has_value());
  EXPECT_NEAR(walk->meta.initial_pose->heading_rad, 4.222432 - 2 * 3.14159265358979, 1e-6);
}

TEST(ConvertPlaza, MalformedLineNamesFileAndLine) {
  if (!fs::exists(kPlaza)) GTEST_SKIP() << kPlaza << " not present";
  const fs::path dir = Scratch("bad");
  for (const char* f : {"Plaza1_DR.txt", "Plaza1_anchors.csv", "Plaza1_GT.csv"}) {
    fs::copy_file(kPlaza + "/" + f, dir / f);
  }
  std::ofstream(dir / "Plaza1_TD.txt") << "1.0 2 5 10.0\n2.0 2 5 oops\n";
  auto walk = Convert("plaza", {dir.string()});
  ASSERT_FALSE(walk.ok());
  EXPECT_THAT(walk.status().message(), ::testing::HasSubstr("Plaza1_TD.txt:2: column 4"));
  std::ofstream(dir / "Plaza1_TD.txt") << "1.0 2 5 10.0\n2.0 2 77 10.0\n";
  walk = Convert("plaza", {dir.string()});
  ASSERT_FALSE(walk.ok());
  EXPECT_THAT(walk.status().message(), ::testing::HasSubstr("Plaza1_TD.txt:2: anchor id"));
  fs::remove_all(dir);
}

// A heading column π off the direction of travel (as a public recording of this family ships
// it) is replaced by the direction of travel, with a warning naming the line.
TEST(ConvertPlaza, HeadingColumnAgainstTheDirectionOfTravelIsReplaced) {
  if (!fs::exists(kPlaza)) GTEST_SKIP() << kPlaza << " not present";
  const fs::path dir = Scratch("flip");
  for (const char* f : {"Plaza1_DR.txt", "Plaza1_anchors.csv", "Plaza1_TD.txt"}) {
    fs::copy_file(kPlaza + "/" + f, dir / f);
  }
  std::ifstream in(kPlaza + "/Plaza1_GT.csv");
  std::ofstream out(dir / "Plaza1_GT.csv");
  std::string line;
  std::getline(in, line);
  out << line << "\n";
  while (std::getline(in, line)) {  // t_s,x_m,y_m,heading_rad with the heading turned by π
    const size_t c = line.rfind(',');
    out << line.substr(0, c + 1) << std::stod(line.substr(c + 1)) + 3.141592653589793 << "\n";
  }
  out.close();
  std::vector<std::string> warnings;
  auto walk = Convert("plaza", {dir.string()}, {}, &warnings);
  ASSERT_TRUE(walk.ok()) << walk.status().message();
  ASSERT_EQ(warnings.size(), 1u);
  EXPECT_THAT(warnings[0], ::testing::HasSubstr("Plaza1_GT.csv:2: heading"));
  EXPECT_THAT(warnings[0], ::testing::HasSubstr("off the direction of travel"));
  EXPECT_EQ(walk->meta.extra.at("convert.truth_heading_replaced"), 1.0);
  // The direction of travel over the first metre, 7.5° from the recording's own column.
  EXPECT_NEAR(walk->meta.initial_pose->heading_rad, -1.9287, 1e-3);
  auto shared = Convert("plaza", {kPlaza}, {}, &warnings);
  ASSERT_TRUE(shared.ok());
  EXPECT_EQ(shared->meta.extra.at("convert.truth_heading_replaced"), 0.0);
  fs::remove_all(dir);
}

TEST(Convert, UnknownFormatListsKnownOnes) {
  auto walk = Convert("nope", {"x"});
  ASSERT_FALSE(walk.ok());
  EXPECT_THAT(walk.status().message(), ::testing::HasSubstr("plaza"));
}

}  // namespace
}  // namespace walkgraph
