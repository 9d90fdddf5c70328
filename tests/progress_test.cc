// walkgraph/progress.h: progress reports inside a running estimator.
#include "walkgraph/progress.h"

#include <cmath>
#include <limits>
#include <vector>

#include <gtest/gtest.h>

namespace walkgraph {
namespace {

TEST(EstimatorProgress, WithoutAScopeReportsGoNowhere) {
  ReportEstimatorProgress(0.5);  // no callback installed: nothing happens, nothing crashes
  SUCCEED();
}

TEST(EstimatorProgress, ReportsNeverGoBackAndStopAtOne) {
  std::vector<double> seen;
  {
    ScopedEstimatorProgress scope([&](double f) { seen.push_back(f); });
    for (double f : {0.2, 0.1, 0.6, std::numeric_limits<double>::quiet_NaN(), 3.0}) {
      ReportEstimatorProgress(f);
    }
  }
  EXPECT_EQ(seen, (std::vector<double>{0.2, 0.2, 0.6, 0.6, 1.0}));
  ReportEstimatorProgress(0.9);  // the scope is gone
  EXPECT_EQ(seen.size(), 5u);
}

TEST(EstimatorProgress, AnInnerScopeHidesTheOuterUntilItEnds) {
  std::vector<double> outer, inner;
  ScopedEstimatorProgress a([&](double f) { outer.push_back(f); });
  {
    ScopedEstimatorProgress b([&](double f) { inner.push_back(f); });
    ReportEstimatorProgress(0.3);
  }
  ReportEstimatorProgress(0.4);
  EXPECT_EQ(inner, (std::vector<double>{0.3}));
  EXPECT_EQ(outer, (std::vector<double>{0.4}));
}

}  // namespace
}  // namespace walkgraph
