#include <cmath>
#include <random>

#include <gtest/gtest.h>

#include "walkgraph/path_loss.h"

namespace walkgraph {
namespace {

TEST(PathLossModel, DbmAndRfcodeAreMirrorImages) {
  const PathLossModel dbm({-60, 2.5, 1.0, 5.0}, RssUnits::kDbm);
  EXPECT_NEAR(dbm.ExpectedRss(10.0), -85.0, 1e-12);
  EXPECT_NEAR(dbm.MlRange(-85.0), 10.0, 1e-9);
  const PathLossModel rf({60, 2.3, 1.0, 6.0}, RssUnits::kRfcode);
  EXPECT_NEAR(rf.ExpectedRss(10.0), 83.0, 1e-12);  // larger is weaker (004)
  EXPECT_NEAR(rf.MlRange(83.0), 10.0, 1e-9);
}

TEST(PathLossModel, BiasCorrectionRemovesLogNormalBias) {
  const PathLossModel m({-60, 2.0, 1.0, 6.0}, RssUnits::kDbm);
  std::mt19937 rng(3);
  std::normal_distribution<double> n(0.0, 6.0);
  const double d = 12.0;
  double ml = 0.0, corrected = 0.0;
  const int kN = 200000;
  for (int i = 0; i < kN; ++i) {
    const double rss = m.ExpectedRss(d) + n(rng);
    ml += m.MlRange(rss);
    corrected += m.BiasCorrectedRange(rss);
  }
  ml /= kN;
  corrected /= kN;
  const double s = m.LogRangeSigma();
  EXPECT_NEAR(ml / d, std::exp(0.5 * s * s), 0.01);  // 001 eq. 15: biased by e^{σ_d²/2}
  EXPECT_NEAR(corrected / d, 1.0, 0.01);
  EXPECT_NEAR(m.RangeSigma(d), s * d, 1e-12);
}

}  // namespace
}  // namespace walkgraph
