// The report's estimator styles: a family per id prefix, a hue band per family, and distinct
// colours however many estimators a report holds.
#include "report/estimator_style.h"

#include <cstdlib>
#include <set>
#include <string>
#include <vector>

#include <gtest/gtest.h>

namespace walkgraph::report {
namespace {

struct Rgb {
  int r, g, b;
};
Rgb Parse(const std::string& hex) {
  const long v = std::strtol(hex.c_str() + 1, nullptr, 16);
  return {static_cast<int>(v >> 16), static_cast<int>((v >> 8) & 255), static_cast<int>(v & 255)};
}

TEST(EstimatorStyle, FamiliesFollowTheIdPrefix) {
  const auto& f = EstimatorFamilies();
  EXPECT_STREQ(f[FamilyOf("fg-batch")].key, "fg");
  EXPECT_STREQ(f[FamilyOf("fg-ins-window-online")].key, "fg");
  EXPECT_STREQ(f[FamilyOf("tarrio-kf-rts")].key, "tarrio");
  EXPECT_STREQ(f[FamilyOf("correa-scmt-ekf")].key, "correa");
  EXPECT_STREQ(f[FamilyOf("prieto-ukf-imu")].key, "prieto");
  EXPECT_STREQ(f[FamilyOf("gadeke-kf")].key, "gadeke");
  EXPECT_STREQ(f[FamilyOf("jimenez-iez-rss")].key, "jimenez");
  for (const char* id : {"odometry-dr", "pdr-only", "rss-pdr-reset", "zupt-ins", "fgx", "fg"}) {
    EXPECT_STREQ(f[FamilyOf(id)].key, "baseline") << id;
  }
}

TEST(EstimatorStyle, HslToHexKnownColours) {
  EXPECT_EQ(HslToHex(0, 1, 0.5), "#ff0000");
  EXPECT_EQ(HslToHex(120, 1, 0.25), "#008000");
  EXPECT_EQ(HslToHex(240, 1, 0.5), "#0000ff");
  EXPECT_EQ(HslToHex(-120, 1, 0.5), "#0000ff");
  EXPECT_EQ(HslToHex(0, 0, 1), "#ffffff");
}

// 30 estimators in each family (210 in all): every colour distinct, every (colour, dash) too;
// a family's colours stay in its hue band (factor graph blue: b the largest channel).
TEST(EstimatorStyle, DistinctColoursForManyEstimatorsPerFamily) {
  std::vector<std::string> ids;
  for (const char* prefix : {"fg-", "tarrio-", "correa-", "prieto-", "gadeke-", "jimenez-", "x"}) {
    for (int k = 0; k < 30; ++k) ids.push_back(prefix + std::to_string(k));
  }
  const std::vector<LineStyle> styles = AssignStyles(ids);
  ASSERT_EQ(styles.size(), ids.size());
  std::set<std::string> colours;
  for (size_t i = 0; i < styles.size(); ++i) {
    EXPECT_EQ(styles[i].color.size(), 7u);
    EXPECT_TRUE(colours.insert(styles[i].color).second) << ids[i] << " " << styles[i].color;
  }
  for (int k = 0; k < 30; ++k) {
    const Rgb c = Parse(styles[k].color);
    EXPECT_GT(c.b, c.r) << ids[k] << " " << styles[k].color;
    EXPECT_GT(c.b, c.g) << ids[k] << " " << styles[k].color;
  }
  // Within a family, the first four differ in dash as well as shade.
  std::set<std::string> dashes;
  for (int k = 0; k < 4; ++k) dashes.insert(styles[k].dash);
  EXPECT_EQ(dashes.size(), 4u);
}

// The same ids get the same styles (the report is the same bytes for the same comparison).
TEST(EstimatorStyle, Deterministic) {
  const std::vector<std::string> ids = {"fg-batch", "tarrio-kf", "fg-window", "odometry-dr"};
  const auto a = AssignStyles(ids), b = AssignStyles(ids);
  for (size_t i = 0; i < ids.size(); ++i) EXPECT_EQ(a[i].color, b[i].color);
  EXPECT_NE(a[0].color, a[2].color);
}

}  // namespace
}  // namespace walkgraph::report
