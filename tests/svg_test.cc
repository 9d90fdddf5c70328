// The inline-SVG building blocks of study.html: round ticks, the plot area beside its legend.
#include "report/svg.h"

#include <cmath>

#include <gtest/gtest.h>

namespace walkgraph::report {
namespace {

// The step of consecutive ticks, and whether it is 1, 2 or 5 × 10^k.
bool IsRoundStep(double step) {
  const double mag = std::pow(10.0, std::floor(std::log10(step) + 1e-9));
  const double f = step / mag;
  return std::abs(f - 1) < 1e-9 || std::abs(f - 2) < 1e-9 || std::abs(f - 5) < 1e-9;
}

TEST(Svg, TicksAreRoundMultiplesInsideTheRange) {
  // The ranges of the complaint (ticks at −76, −44, −12, 19, 51) and a few others.
  for (const auto& [lo, hi] : std::vector<std::pair<double, double>>{
           {-76.3, 51.2}, {0.0, 0.537}, {0.0, 30.0}, {1e-4, 3.3e-4}, {-2.0, 2.0}, {100, 10000}}) {
    const Ticks t = NiceTicks(lo, hi);
    ASSERT_GE(t.values.size(), 3u) << lo << " " << hi;
    EXPECT_LE(t.values.size(), 11u) << lo << " " << hi;
    const double step = t.values[1] - t.values[0];
    EXPECT_TRUE(IsRoundStep(step)) << step;
    for (size_t i = 0; i < t.values.size(); ++i) {
      EXPECT_GE(t.values[i], lo - 1e-12);
      EXPECT_LE(t.values[i], hi + 1e-12);
      EXPECT_NEAR(t.values[i] / step, std::round(t.values[i] / step), 1e-6);
      if (i > 0) EXPECT_NEAR(t.values[i] - t.values[i - 1], step, 1e-9 * step);
    }
    // Printed with t.decimals digits, the step survives (1e-4 → 4 decimals).
    EXPECT_NEAR(std::round(step * std::pow(10.0, t.decimals)) / std::pow(10.0, t.decimals), step,
                1e-12);
  }
  EXPECT_EQ(NiceTicks(-76.3, 51.2).values.front(), -60.0);
  EXPECT_EQ(NiceTicks(0.0, 0.537).decimals, 1);
  EXPECT_EQ(NiceTicks(1.0, 1.0).values.size(), 1u);  // an empty range: one tick, no loop
}

TEST(Svg, LegendColumnLiesRightOfThePlotArea) {
  Axes a{0, 10, 0, 5};
  a.legend_w = 120;
  a.w += a.legend_w;
  a.Fix();
  const double plot_right = a.m + a.PlotW();
  EXPECT_NEAR(a.X(10), plot_right, 1e-9);
  const std::string entry = LegendEntry(a, 0, "fg-batch", "#123456", "4,2");
  const double x1 = std::stod(entry.substr(entry.find("x1=\"") + 4));
  EXPECT_GT(x1, plot_right);
  EXPECT_LT(x1 + 28 + 6.5 * 8, a.w);
}

}  // namespace
}  // namespace walkgraph::report
