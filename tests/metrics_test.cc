#include <cmath>

#include <gtest/gtest.h>

#include "walkgraph/angle.h"
#include "walkgraph/metrics.h"

namespace walkgraph {
namespace {

Walk LineWalk() {
  Walk w;
  w.meta.truth_kind = TruthKind::kContinuous;
  for (int i = 0; i <= 10; ++i) {
    TruthSample s;
    s.t_s = i;
    s.position_m = Eigen::Vector3d(i, 0, 0);
    w.truth.push_back(s);
  }
  return w;
}

TEST(Percentile, InterpolatesLikeNumpyLinear) {
  EXPECT_DOUBLE_EQ(Percentile({1, 2, 3, 4}, 50), 2.5);
  EXPECT_DOUBLE_EQ(Percentile({1, 2, 3, 4}, 75), 3.25);
  EXPECT_DOUBLE_EQ(Percentile({5}, 90), 5);
  EXPECT_DOUBLE_EQ(Percentile({}, 90), 0);
}

TEST(ComputeErrors, ConstantOffsetAndInterpolation) {
  const Walk w = LineWalk();
  Trajectory t;
  for (int i = 0; i <= 5; ++i) {  // poses every 2 s, offset 1 m in y
    TrajectoryPoint p;
    p.t_s = 2.0 * i;
    p.position_m = Eigen::Vector3d(2.0 * i, 1.0, 0.0);
    t.points.push_back(p);
  }
  auto e = ComputeErrors(w, t);
  ASSERT_TRUE(e.ok());
  ASSERT_EQ(e->error_m.size(), 11u);
  for (double v : e->error_m) EXPECT_NEAR(v, 1.0, 1e-12);
  const ErrorStats s = SummarizeErrors(e->error_m, w.TruthDistance());
  EXPECT_NEAR(s.rmse_m, 1.0, 1e-12);
  EXPECT_NEAR(s.pct_distance, 10.0, 1e-12);
  EXPECT_EQ(s.n_points, 11);
}

TEST(ComputeErrors, SkipsTruthOutsideEstimateSpan) {
  const Walk w = LineWalk();
  Trajectory t;
  for (int i = 3; i <= 6; ++i) {
    TrajectoryPoint p;
    p.t_s = i;
    p.position_m = Eigen::Vector3d(i, 0, 0);
    t.points.push_back(p);
  }
  auto e = ComputeErrors(w, t);
  ASSERT_TRUE(e.ok());
  EXPECT_EQ(e->error_m.size(), 4u);
  EXPECT_EQ(e->n_skipped, 7);
}

TEST(ComputeErrors, Se2AlignmentRemovesRigidMotion) {
  const Walk w = [] {
    Walk w = LineWalk();
    for (auto& s : w.truth) s.position_m.y() = 0.1 * s.t_s * s.t_s;  // a curve
    return w;
  }();
  Trajectory t;
  const double a = 0.7;
  for (const TruthSample& s : w.truth) {
    TrajectoryPoint p;
    p.t_s = s.t_s;
    const double x = s.position_m.x(), y = s.position_m.y();
    p.position_m = Eigen::Vector3d(std::cos(a) * x - std::sin(a) * y + 3,
                                   std::sin(a) * x + std::cos(a) * y - 2, 0);
    t.points.push_back(p);
  }
  auto raw = ComputeErrors(w, t);
  auto aligned = ComputeErrors(w, t, Alignment::kSE2);
  ASSERT_TRUE(raw.ok() && aligned.ok());
  EXPECT_GT(SummarizeErrors(raw->error_m, 1).rmse_m, 1.0);
  EXPECT_LT(SummarizeErrors(aligned->error_m, 1).rmse_m, 1e-9);
}

TEST(ComputeErrors, NoTruthIsAnError) {
  Walk w;
  Trajectory t;
  t.points.push_back({});
  EXPECT_FALSE(ComputeErrors(w, t).ok());
}

TEST(NormalizeAngle, WrapsIntoHalfOpenInterval) {
  EXPECT_NEAR(NormalizeAngle(3 * kPi), -kPi, 1e-12);
  EXPECT_NEAR(NormalizeAngle(-3 * kPi / 2), kPi / 2, 1e-12);
  EXPECT_NEAR(NormalizeAngle(0.3), 0.3, 1e-15);
  for (double a = -20; a < 20; a += 0.37) {
    const double n = NormalizeAngle(a);
    EXPECT_GE(n, -kPi);
    EXPECT_LT(n, kPi);
    EXPECT_NEAR(std::remainder(a - n, 2 * kPi), 0.0, 1e-9);
  }
}

}  // namespace
}  // namespace walkgraph
