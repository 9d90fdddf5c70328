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

TEST(Convert, UnknownFormatListsKnownOnes) {
  auto walk = Convert("nope", {"x"});
  ASSERT_FALSE(walk.ok());
  EXPECT_THAT(walk.status().message(), ::testing::HasSubstr("plaza"));
}

}  // namespace
}  // namespace walkgraph
