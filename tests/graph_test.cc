// src/smoothers/graph.cc's statistics: the anchors' χ² test of one shared path loss
// (internal::TestAnchorOffsets), on residuals drawn here with known offsets and correlation.
#include <cmath>
#include <random>
#include <utility>
#include <vector>

#include <gtest/gtest.h>

#include "smoothers/graph_internal.h"

namespace walkgraph {
namespace {

// `anchors` anchors with `n` whitened residuals each, AR(1) in time with lag-1 correlation rho
// (unit variance), plus offset(a) for anchor a; interleaved in time as a walk hears them.
std::vector<std::pair<int, double>> Residuals(int anchors, int n, double rho,
                                              const std::vector<double>& offset, uint32_t seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> g(0.0, 1.0);
  std::vector<double> state(static_cast<size_t>(anchors), 0.0);
  std::vector<std::pair<int, double>> out;
  for (int k = 0; k < n; ++k) {
    for (int a = 0; a < anchors; ++a) {
      double& x = state[static_cast<size_t>(a)];
      x = k == 0 ? g(rng) : rho * x + std::sqrt(1.0 - rho * rho) * g(rng);
      out.emplace_back(a, x + offset[static_cast<size_t>(a)]);
    }
  }
  return out;
}

TEST(AnchorOffsetTest, AgreeingAnchorsPassAtTheTestsLevel) {
  int rejected = 0;
  const int trials = 200;
  for (int t = 0; t < trials; ++t) {
    const auto r = Residuals(30, 100, 0.0, std::vector<double>(30, 0.0), 100u + t);
    const internal::AnchorOffsetTest test = internal::TestAnchorOffsets(r, 2.326);  // p = 0.01
    EXPECT_EQ(test.anchors, 30);
    rejected += test.disagree ? 1 : 0;
  }
  // Expected 1 % of 200 = 2; Binomial(200, 0.01) exceeds 8 with probability < 1e-3.
  EXPECT_LE(rejected, 8);
}

TEST(AnchorOffsetTest, CorrelatedResidualsAreNotMistakenForOffsets) {
  // Shadowing correlated along the walk (ρ = 0.9): the raw √n would reject nearly always.
  int rejected = 0;
  for (int t = 0; t < 100; ++t) {
    const auto r = Residuals(30, 300, 0.9, std::vector<double>(30, 0.0), 500u + t);
    rejected += internal::TestAnchorOffsets(r, 3.09).disagree ? 1 : 0;
  }
  EXPECT_LE(rejected, 10);
}

TEST(AnchorOffsetTest, AnchorsThatDifferAreFound) {
  std::vector<double> offset(30, 0.0);
  for (size_t a = 0; a < offset.size(); ++a) offset[a] = a % 2 == 0 ? 0.4 : -0.4;  // ±2.4 dB at σ 6
  const auto r = Residuals(30, 100, 0.5, offset, 7u);
  const internal::AnchorOffsetTest test = internal::TestAnchorOffsets(r, 3.09);
  EXPECT_TRUE(test.disagree) << test.statistic << " vs " << test.critical;
  // Wilson–Hilferty's χ²(30) 0.999 quantile: 59.70 exactly, 59.6 approximated.
  EXPECT_NEAR(test.critical, 59.7, 0.5);
}

TEST(AnchorOffsetTest, FewReadingsAndOutliers) {
  // Anchors heard fewer than 5 times are not tested.
  std::vector<std::pair<int, double>> r = {{1, 0.1}, {1, -0.2}, {1, 0.3}, {1, 0.0}};
  EXPECT_EQ(internal::TestAnchorOffsets(r, 3.09).anchors, 0);
  EXPECT_FALSE(internal::TestAnchorOffsets(r, 3.09).disagree);
  // A wild reading counts as one at +3 σ (clipped), not with its own size.
  auto wild = Residuals(10, 50, 0.0, std::vector<double>(10, 0.0), 3u);
  auto clipped = wild;
  wild[5].second = 1e6;
  clipped[5].second = 3.0;
  const internal::AnchorOffsetTest a = internal::TestAnchorOffsets(wild, 3.09);
  const internal::AnchorOffsetTest b = internal::TestAnchorOffsets(clipped, 3.09);
  EXPECT_EQ(a.anchors, 10);
  EXPECT_DOUBLE_EQ(a.statistic, b.statistic);
  EXPECT_FALSE(a.disagree);
}

}  // namespace
}  // namespace walkgraph
