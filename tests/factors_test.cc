// The step-level and radio cost functions: residuals against independently computed values,
// Jacobians against numeric differentiation (ceres::GradientChecker), angle wrapping.
#include <cmath>
#include <memory>
#include <vector>

#include <ceres/gradient_checker.h>
#include <ceres/manifold.h>
#include <ceres/manifold_test_utils.h>
#include <gtest/gtest.h>

#include "factors/angle_manifold.h"
#include "factors/barometric_height_factor.h"
#include "factors/difference_prior_factor.h"
#include "factors/heading_factor.h"
#include "factors/heading_increment_factor.h"
#include "factors/odometry_factor.h"
#include "factors/position_prior_factor.h"
#include "factors/position_random_walk_factor.h"
#include "factors/range_factor.h"
#include "factors/rss_factor.h"
#include "factors/rss_range_factor.h"
#include "factors/step_factor.h"
#include "walkgraph/angle.h"
#include "walkgraph/path_loss.h"

namespace walkgraph {
namespace {

std::vector<double> Residuals(const ceres::CostFunction& f, std::vector<const double*> blocks) {
  std::vector<double> r(f.num_residuals());
  EXPECT_TRUE(f.Evaluate(blocks.data(), r.data(), nullptr));
  return r;
}

// Checks f's Jacobians at `blocks` against central differences; heading blocks (size 1 in
// `angle_blocks`) get the AngleManifold.
void ExpectGradientsMatch(const ceres::CostFunction& f, std::vector<const double*> blocks,
                          std::vector<int> angle_blocks = {}) {
  AngleManifold angle;
  std::vector<const ceres::Manifold*> manifolds(blocks.size(), nullptr);
  for (int i : angle_blocks) manifolds[i] = &angle;
  ceres::NumericDiffOptions numeric;
  ceres::GradientChecker checker(&f, &manifolds, numeric);
  ceres::GradientChecker::ProbeResults results;
  EXPECT_TRUE(checker.Probe(blocks.data(), 1e-7, &results)) << results.error_log;
}

TEST(AngleManifoldTest, PlusAndMinusWrap) {
  AngleManifold m;
  double x = 3.0, d = 0.5, y = 0.0;
  m.Plus(&x, &d, &y);
  EXPECT_NEAR(y, 3.5 - 2 * kPi, 1e-12);
  double a = -3.1, b = 3.1, diff = 0.0;
  m.Minus(&a, &b, &diff);  // a ⊟ b: the short way round
  EXPECT_NEAR(diff, 2 * kPi - 6.2, 1e-12);
}

// Ceres' manifold invariants (ceres/manifold_test_utils.h): x ⊞ 0 = x, x ⊟ x = 0,
// (x ⊞ δ) ⊟ x = δ, x ⊞ (y ⊟ x) = y, and Plus/Minus Jacobians against numeric ones — at points
// across the circle with |δ| < π (the chart's domain). x stays 0.04 rad from ±π: Ceres'
// numeric Jacobian steps ~1.4e-3 either side, and at x = −3.14 its difference straddles the wrap
// (it reads 2π/2h ≈ −2290 where the derivative is 1).
TEST(AngleManifoldTest, CeresManifoldInvariantsHold) {
  using namespace ceres;  // NOLINT: the macro names ceres' matchers and Vector unqualified
  const AngleManifold manifold;
  for (const double x0 : {-3.1, -2.0, 0.0, 0.5, 3.1}) {
    for (const double d0 : {0.3, -2.5, 3.0}) {
      for (const double y0 : {2.9, -3.1, 0.0}) {
        SCOPED_TRACE(::testing::Message() << "x " << x0 << " delta " << d0 << " y " << y0);
        const Vector x = Vector::Constant(1, x0), delta = Vector::Constant(1, d0);
        const Vector y = Vector::Constant(1, y0);
        EXPECT_THAT_MANIFOLD_INVARIANTS_HOLD(manifold, x, delta, y, 1e-9);
      }
    }
  }
}

TEST(StepFactorTest, ResidualIsAlongAndCrossTrackError) {
  std::unique_ptr<ceres::CostFunction> f(StepFactor::Create(0.7, 0.1, 0.05));
  const double p0[2] = {1.0, 2.0}, theta[1] = {kPi / 2};
  const double p1[2] = {1.0 + 0.02, 2.0 + 0.75};  // 0.75 along north, 0.02 east (right)
  const auto r = Residuals(*f, {p0, p1, theta});
  EXPECT_NEAR(r[0], (0.75 - 0.7) / 0.1, 1e-12);
  EXPECT_NEAR(r[1], -0.02 / 0.05, 1e-12);  // cross-track positive to the left
  const double generic[1] = {1.3};         // away from exact zeros, where relative errors mislead
  ExpectGradientsMatch(*f, {p0, p1, generic}, {2});
}

TEST(HeadingFactorsTest, ResidualsWrapAcrossPi) {
  std::unique_ptr<ceres::CostFunction> inc(HeadingIncrementFactor::Create(0.1, 0.02));
  const double a[1] = {3.1}, b[1] = {-3.1};  // true change 2π − 6.2 ≈ 0.0832
  EXPECT_NEAR(Residuals(*inc, {a, b})[0], (2 * kPi - 6.2 - 0.1) / 0.02, 1e-9);
  ExpectGradientsMatch(*inc, {a, b}, {0, 1});
  // A gyro bias of 0.01 rad/s over 2 s explains 0.02 rad of the measured increment.
  std::unique_ptr<ceres::CostFunction> biased(
      HeadingIncrementFactor::CreateWithBias(0.1, 2.0, 0.02));
  const double bias[1] = {0.01};
  EXPECT_NEAR(Residuals(*biased, {a, b, bias})[0], (2 * kPi - 6.2 - 0.08) / 0.02, 1e-9);
  ExpectGradientsMatch(*biased, {a, b, bias}, {0, 1});
  std::unique_ptr<ceres::CostFunction> abs(HeadingFactor::Create(-3.1, 0.1));
  EXPECT_NEAR(Residuals(*abs, {a})[0], (6.2 - 2 * kPi) / 0.1, 1e-9);
  ExpectGradientsMatch(*abs, {a}, {0});
}

TEST(OdometryFactorTest, MatchesPose2Between) {
  std::unique_ptr<ceres::CostFunction> f(OdometryFactor::Create(1.0, 0.3, 0.05, 0.02, 0.01));
  const double p0[2] = {0.0, 0.0}, t0[1] = {kPi / 4};
  // Exactly the increment: 1 m along 45°, then turn 0.3 rad.
  const double p1[2] = {std::cos(kPi / 4), std::sin(kPi / 4)}, t1[1] = {kPi / 4 + 0.3};
  for (double v : Residuals(*f, {p0, t0, p1, t1})) EXPECT_NEAR(v, 0.0, 1e-12);
  const double p2[2] = {p1[0] + 0.1, p1[1]};
  const auto r = Residuals(*f, {p0, t0, p2, t1});
  EXPECT_NEAR(r[0], 0.1 * std::cos(kPi / 4) / 0.05, 1e-12);
  EXPECT_NEAR(r[1], -0.1 * std::sin(kPi / 4) / 0.02, 1e-12);
  ExpectGradientsMatch(*f, {p0, t0, p2, t1}, {1, 3});
}

TEST(PositionRandomWalkFactorTest, WhitensByTheDiffusion) {
  std::unique_ptr<ceres::CostFunction> f(PositionRandomWalkFactor::Create(0.25, 1.0));
  const double a[2] = {1.0, 2.0}, b[2] = {1.3, 1.6};  // σ = 1·√0.25 = 0.5 m
  const auto r = Residuals(*f, {a, b});
  EXPECT_NEAR(r[0], 0.6, 1e-12);
  EXPECT_NEAR(r[1], -0.8, 1e-12);
  ExpectGradientsMatch(*f, {a, b});
}

TEST(BarometricHeightFactorTest, WhitensTheHeightChangeError) {
  std::unique_ptr<ceres::CostFunction> f(BarometricHeightFactor::Create(-3.0, 0.5));
  const double a[1] = {1.0}, b[1] = {-1.6};  // moved −2.6 m, the barometer says −3 m
  const auto r = Residuals(*f, {a, b});
  EXPECT_NEAR(r[0], 0.4 / 0.5, 1e-12);
  ExpectGradientsMatch(*f, {a, b});
}

TEST(BarometricHeightFactorTest, HeightFromPressureFollowsTheStandardAtmosphere) {
  EXPECT_NEAR(BarometricHeightM(1013.25, 1013.25), 0.0, 1e-12);
  // ICAO standard atmosphere: 898.76 hPa at 1000 m, 795.01 hPa at 2000 m (tabulated).
  EXPECT_NEAR(BarometricHeightM(898.76, 1013.25), 1000.0, 2.0);
  EXPECT_NEAR(BarometricHeightM(795.01, 1013.25), 2000.0, 4.0);
  // Near the ground: about 8.3 m per hPa; lower pressure is higher.
  EXPECT_NEAR(BarometricHeightM(979.3, 980.0), 0.7 * 8.4, 0.2);
}

TEST(BarometricHeightFactorTest, PressureFromHeightInvertsIt) {
  EXPECT_NEAR(BarometricPressureHpa(1000.0, 1013.25), 898.76, 0.25);  // ICAO table
  for (double h : {-10.0, 0.0, 3.5, 7.0, 250.0}) {
    EXPECT_NEAR(BarometricHeightM(BarometricPressureHpa(h, 1013.25), 1013.25), h, 1e-9);
  }
}

TEST(PositionPriorFactorTest, OneNodeIsTheWhitenedOffset) {
  std::unique_ptr<ceres::CostFunction> f(
      PositionPriorFactor<2>::Create(Eigen::Vector2d(3.0, -1.0), 0.5));
  const double p[2] = {3.4, -1.3};
  const auto r = Residuals(*f, {p});
  EXPECT_NEAR(r[0], 0.8, 1e-12);
  EXPECT_NEAR(r[1], -0.6, 1e-12);
  ExpectGradientsMatch(*f, {p});
}

TEST(PositionPriorFactorTest, TwoNodesInterpolateLinearly) {
  // α = 0.25: the estimate at t is 0.75 p_a + 0.25 p_b = (1.5, 2.5); z = (1, 3), σ = 2.
  std::unique_ptr<ceres::CostFunction> f(
      PositionPriorFactor<2>::CreateInterpolated(Eigen::Vector2d(1.0, 3.0), 2.0, 0.25));
  const double a[2] = {1.0, 2.0}, b[2] = {3.0, 4.0};
  const auto r = Residuals(*f, {a, b});
  EXPECT_NEAR(r[0], 0.25, 1e-12);
  EXPECT_NEAR(r[1], -0.25, 1e-12);
  ExpectGradientsMatch(*f, {a, b});
  // α = 0 and α = 1 reduce to the one-node factor on p_a and p_b.
  std::unique_ptr<ceres::CostFunction> at_b(
      PositionPriorFactor<2>::CreateInterpolated(Eigen::Vector2d(1.0, 3.0), 2.0, 1.0));
  const auto rb = Residuals(*at_b, {a, b});
  EXPECT_NEAR(rb[0], 1.0, 1e-12);
  EXPECT_NEAR(rb[1], 0.5, 1e-12);
  // On 3-D positions (the foot INS) z is free: same residual, zero Jacobian column for z.
  std::unique_ptr<ceres::CostFunction> f3(
      PositionPriorFactor<3>::CreateInterpolated(Eigen::Vector2d(1.0, 3.0), 2.0, 0.25));
  const double a3[3] = {1.0, 2.0, 7.0}, b3[3] = {3.0, 4.0, -2.0};
  const auto r3 = Residuals(*f3, {a3, b3});
  EXPECT_NEAR(r3[0], 0.25, 1e-12);
  EXPECT_NEAR(r3[1], -0.25, 1e-12);
  ExpectGradientsMatch(*f3, {a3, b3});
}

TEST(DifferencePriorFactorTest, WhitensTheOffsetFromTheMean) {
  // An anchor's (A, η) = (−62, 2.5) against the mean (−58, 2.0), σ = (4 dB, 0.4):
  // r = (−1, 1.25).
  std::unique_ptr<ceres::CostFunction> f(
      DifferencePriorFactor<2>::Create(Eigen::Vector2d(4.0, 0.4)));
  const double a[2] = {-62.0, 2.5}, m[2] = {-58.0, 2.0};
  const auto r = Residuals(*f, {a, m});
  EXPECT_NEAR(r[0], -1.0, 1e-12);
  EXPECT_NEAR(r[1], 1.25, 1e-12);
  ExpectGradientsMatch(*f, {a, m});
}

TEST(RssFactorTest, ResidualMatchesPathLossModelInBothUnits) {
  for (RssUnits units : {RssUnits::kDbm, RssUnits::kRfcode}) {
    PathLossParams params;
    params.A_dbm = units == RssUnits::kDbm ? -60.0 : 60.0;
    params.eta = 2.3;
    params.sigma_db = 6.0;
    const PathLossModel model(params, units);
    RssFactor<2>::Reading reading;
    reading.rss = units == RssUnits::kDbm ? -75.0 : 75.0;
    reading.anchor_m = Eigen::Vector3d(3.0, 4.0, 2.0);
    reading.sigma_db = 6.0;
    reading.sign = model.sign();
    reading.receiver_height_m = 1.0;
    const double p[2] = {0.0, 0.0}, pl[2] = {params.A_dbm, params.eta};
    const double d = std::sqrt(9.0 + 16.0 + 1.0);
    std::unique_ptr<ceres::CostFunction> f(RssFactor<2>::Create(reading));
    EXPECT_NEAR(Residuals(*f, {p, pl})[0], (reading.rss - model.ExpectedRss(d)) / 6.0, 1e-6);
    ExpectGradientsMatch(*f, {p, pl});

    // Interpolated: halfway between (−1, 0) and (1, 0) is the origin again.
    const double pa[2] = {-1.0, 0.0}, pb[2] = {1.0, 0.0};
    std::unique_ptr<ceres::CostFunction> fi(RssFactor<2>::CreateInterpolated(reading, 0.5));
    EXPECT_NEAR(Residuals(*fi, {pa, pb, pl})[0], (reading.rss - model.ExpectedRss(d)) / 6.0, 1e-6);
    ExpectGradientsMatch(*fi, {pa, pb, pl});
  }
}

TEST(RssFactorTest, ThreeDimensionalPositionUsesItsOwnHeight) {
  RssFactor<3>::Reading reading;
  reading.rss = -70.0;
  reading.anchor_m = Eigen::Vector3d(0.0, 0.0, 3.0);
  reading.receiver_height_m = 99.0;  // ignored for 3-D blocks
  const double p[3] = {0.0, 0.0, 1.0}, pl[2] = {-60.0, 2.0};
  std::unique_ptr<ceres::CostFunction> f(RssFactor<3>::Create(reading));
  EXPECT_NEAR(Residuals(*f, {p, pl})[0], (-70.0 - (-60.0 - 20.0 * std::log10(2.0))) / 5.0, 1e-6);
  ExpectGradientsMatch(*f, {p, pl});
}

TEST(RssRangeFactorTest, UsesMlRangeAndEquation7Sigma) {
  PathLossParams params;
  params.A_dbm = -60.0;
  params.eta = 2.5;
  params.sigma_db = 5.0;
  const PathLossModel model(params, RssUnits::kDbm);
  RssRangeFactor<2>::Reading reading;
  reading.rss = -80.0;
  reading.anchor_m = Eigen::Vector3d(10.0, 0.0, 0.0);
  std::unique_ptr<ceres::CostFunction> f(RssRangeFactor<2>::Create(reading));
  const double p[2] = {0.0, 0.0};
  const double d_hat = model.MlRange(-80.0);
  EXPECT_NEAR(Residuals(*f, {p})[0], (d_hat - 10.0) / model.RangeSigma(d_hat), 1e-6);
  ExpectGradientsMatch(*f, {p});
  reading.bias_corrected = true;
  RssRangeFactor<2> corrected(reading, 0.0);
  EXPECT_NEAR(corrected.range_m(), model.BiasCorrectedRange(-80.0), 1e-9);
}

TEST(RangeFactorTest, BiasIsAdditive) {
  std::unique_ptr<ceres::CostFunction> f(
      RangeFactor<2>::Create(7.8, Eigen::Vector3d(3.0, 4.0, 0.0), 1.2));
  const double p[2] = {0.0, 0.0}, b[1] = {2.8};
  EXPECT_NEAR(Residuals(*f, {p, b})[0], 0.0, 1e-6);
  const double b0[1] = {0.0};
  EXPECT_NEAR(Residuals(*f, {p, b0})[0], 2.8 / 1.2, 1e-6);
  ExpectGradientsMatch(*f, {p, b});
  std::unique_ptr<ceres::CostFunction> fi(
      RangeFactor<3>::CreateInterpolated(5.0, Eigen::Vector3d(0.0, 0.0, 0.0), 1.0, 0.25));
  const double pa[3] = {0.0, 0.0, 0.0}, pb[3] = {4.0, 0.0, 0.0};  // received at (1, 0, 0)
  EXPECT_NEAR(Residuals(*fi, {pa, pb, b0})[0], 4.0, 1e-6);
  ExpectGradientsMatch(*fi, {pa, pb, b});
}

TEST(RangeFactorTest, ScaledRangeIsTheAffineToaModel) {
  // ρ = (1 + s)·d + b (002 eq. 6): d = 5, s = 0.07, b = 0.9 → ρ = 6.25.
  std::unique_ptr<ceres::CostFunction> f(
      ScaledRangeFactor<2>::Create(6.25, Eigen::Vector3d(3.0, 4.0, 0.0), 0.5));
  const double p[2] = {0.0, 0.0}, b[1] = {0.9}, sc[1] = {0.07}, zero[1] = {0.0};
  EXPECT_NEAR(Residuals(*f, {p, b, sc})[0], 0.0, 1e-6);
  EXPECT_NEAR(Residuals(*f, {p, b, zero})[0], 0.35 / 0.5, 1e-6);
  ExpectGradientsMatch(*f, {p, b, sc});
  std::unique_ptr<ceres::CostFunction> fi(
      ScaledRangeFactor<3>::CreateInterpolated(5.0, Eigen::Vector3d::Zero(), 1.0, 0.5));
  const double pa[3] = {1.0, 0.0, 0.0}, pb[3] = {3.0, 0.0, 0.0};  // received at (2, 0, 0)
  EXPECT_NEAR(Residuals(*fi, {pa, pb, b, sc})[0], 5.0 - 1.07 * 2.0 - 0.9, 1e-6);
  ExpectGradientsMatch(*fi, {pa, pb, b, sc});
}

}  // namespace
}  // namespace walkgraph
