#include <cmath>
#include <vector>

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

// Poses on the line of LineWalk at times `t` (x = t), offset by `y` metres north.
Trajectory LineTrajectory(const std::vector<double>& t, double y) {
  Trajectory out;
  for (double ti : t) {
    TrajectoryPoint p;
    p.t_s = ti;
    p.position_m = Eigen::Vector3d(ti, y, 0.0);
    out.points.push_back(p);
  }
  return out;
}

TEST(Percentile, InterpolatesLikeNumpyLinear) {
  EXPECT_DOUBLE_EQ(Percentile({1, 2, 3, 4}, 50), 2.5);
  EXPECT_DOUBLE_EQ(Percentile({1, 2, 3, 4}, 75), 3.25);
  EXPECT_DOUBLE_EQ(Percentile({5}, 90), 5);
  EXPECT_DOUBLE_EQ(Percentile({}, 90), 0);
}

TEST(QuantileSketch, WithinItsRelativeAccuracyOfTheExactPercentileInAnyOrder) {
  // Errors spread over six decades, with exact zeros, added in two different orders.
  std::vector<double> v;
  uint64_t x = 12345;
  for (int i = 0; i < 20000; ++i) {
    x = x * 6364136223846793005ULL + 1442695040888963407ULL;
    const double u = static_cast<double>(x >> 11) / 9007199254740992.0;
    v.push_back(i % 97 == 0 ? 0.0 : std::pow(10.0, -3.0 + 6.0 * u));
  }
  QuantileSketch forward, backward;
  for (double e : v) forward.Add(e);
  for (auto it = v.rbegin(); it != v.rend(); ++it) backward.Add(*it);
  EXPECT_EQ(forward.count(), 20000);
  const double alpha = QuantileSketch::kDefaultRelativeAccuracy;
  for (double q : {0.0, 1.0, 25.0, 50.0, 75.0, 90.0, 99.0, 100.0}) {
    const double exact = Percentile(v, q);
    EXPECT_NEAR(forward.Percentile(q), exact, alpha * exact + 1e-12) << q;
    EXPECT_EQ(forward.Percentile(q), backward.Percentile(q)) << q;
  }
  EXPECT_EQ(QuantileSketch().Percentile(50.0), 0.0);
  // A coarse sketch is still within its own accuracy.
  QuantileSketch coarse(0.01);
  for (double e : v) coarse.Add(e);
  EXPECT_NEAR(coarse.Percentile(90.0), Percentile(v, 90.0), 0.01 * Percentile(v, 90.0));
}

TEST(ComputeErrors, ConstantOffsetAndInterpolation) {
  const Walk w = LineWalk();
  const Trajectory t = LineTrajectory({0, 2, 4, 6, 8, 10}, 1.0);  // every 2 s, 1 m north
  auto e = ComputeErrors(w, t);
  ASSERT_TRUE(e.ok());
  ASSERT_EQ(e->error_m.size(), 11u);
  for (double v : e->error_m) EXPECT_NEAR(v, 1.0, 1e-12);
  const ErrorStats s = SummarizeErrors(e->error_m, w.TruthDistance());
  EXPECT_NEAR(s.rmse_m, 1.0, 1e-12);
  EXPECT_NEAR(s.pct_distance, 10.0, 1e-12);
  EXPECT_EQ(s.n_points, 11);
}

// IPIN's score (technical annex 2023): the third quartile of error + 15 m × floors missed, and
// the floor hit rate; an estimate without floors is scored on the walk's start floor.
TEST(ComputeErrors, IpinScoreAddsFifteenMetresPerFloorMissed) {
  Walk w = LineWalk();  // 11 points, 1 m apart, t = 0..10 s
  for (size_t i = 0; i < w.truth.size(); ++i) w.truth[i].floor = i < 4 ? 0 : -2;
  Trajectory t = LineTrajectory({0, 2, 4, 6, 8, 10}, 1.0);             // 1 m error everywhere
  for (TrajectoryPoint& p : t.points) p.floor = p.t_s < 5.0 ? 0 : -1;  // nearest point's floor
  auto e = ComputeErrors(w, t);
  ASSERT_TRUE(e.ok());
  // Estimate on floor 0 up to t = 4 (t = 5 is nearer the point at 6), -1 after; truth 0 up to
  // t = 3, -2 after: right at t = 0..3, two floors off at t = 4, one at t = 5..10.
  const std::vector<int> missed = {0, 0, 0, 0, 2, 1, 1, 1, 1, 1, 1};
  ASSERT_EQ(e->floors_missed, missed);
  const ErrorStats s = SummarizeErrors(*e, w.TruthDistance());
  // Sample errors: 1 ×4, 31, 16 ×6 → sorted 1,1,1,1,16,16,16,16,16,16,31; p75 at rank 7.5 = 16.
  EXPECT_NEAR(s.ipin_score_m, 16.0, 1e-12);
  EXPECT_NEAR(s.floor_hit_rate, 4.0 / 11.0, 1e-12);
  // Without floors in the estimate: the start floor (the first truth floor, 0) throughout.
  for (TrajectoryPoint& p : t.points) p.floor.reset();
  const ErrorStats flat = SummarizeErrors(*ComputeErrors(w, t), w.TruthDistance());
  EXPECT_NEAR(flat.floor_hit_rate, 4.0 / 11.0, 1e-12);
  EXPECT_NEAR(flat.ipin_score_m, 31.0, 1e-12);
  // No truth floors: no floor figures.
  Walk plain = LineWalk();
  const ErrorStats none = SummarizeErrors(*ComputeErrors(plain, t), plain.TruthDistance());
  EXPECT_TRUE(std::isnan(none.ipin_score_m));
  EXPECT_TRUE(std::isnan(none.floor_hit_rate));
}

// 003's relative error: a constant 1-m offset on a 1 m/s line is 100/d % at d = 1..10 m
// (the start, d = 0, left out): the mean is 10·H_10 % (H_10 = 7381/2520).
TEST(ComputeErrors, RelativeErrorIsTheMeanOfErrorOverDistanceWalked) {
  const Walk w = LineWalk();
  const Trajectory t = LineTrajectory({0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10}, 1.0);
  auto e = ComputeErrors(w, t);
  ASSERT_TRUE(e.ok());
  ASSERT_EQ(e->distance_m.size(), 11u);
  for (int i = 0; i <= 10; ++i) EXPECT_NEAR(e->distance_m[i], i, 1e-12);
  const ErrorStats s = SummarizeErrors(*e, w.TruthDistance());
  EXPECT_NEAR(s.mean_pct_distance, 10.0 * 7381.0 / 2520.0, 1e-9);
  EXPECT_NEAR(s.pct_distance, 10.0, 1e-12);
  // Without distances (a bare error vector) there is no relative error.
  EXPECT_TRUE(std::isnan(SummarizeErrors(e->error_m, w.TruthDistance()).mean_pct_distance));
  // Nor when no point is 1 m from the start.
  Walk still = w;
  for (auto& x : still.truth) x.position_m.x() = 0.001 * x.t_s;
  auto e0 = ComputeErrors(still, t);
  ASSERT_TRUE(e0.ok());
  EXPECT_TRUE(std::isnan(SummarizeErrors(*e0, still.TruthDistance()).mean_pct_distance));
}

TEST(ComputeErrors, SkipsTruthOutsideEstimateSpan) {
  const Walk w = LineWalk();
  const Trajectory t = LineTrajectory({3, 4, 5, 6}, 0.0);
  auto e = ComputeErrors(w, t);
  ASSERT_TRUE(e.ok());
  EXPECT_EQ(e->error_m.size(), 4u);
  EXPECT_EQ(e->n_skipped, 7);
  // Distances count from the walk's first truth sample, not from the first scored one.
  ASSERT_EQ(e->distance_m.size(), 4u);
  EXPECT_NEAR(e->distance_m.front(), 3.0, 1e-12);
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

// Position NEES eᵀP⁻¹e with the (x, y) block interpolated between poses; none when a pose has
// no covariance or a non-positive-definite one.
TEST(ComputeErrors, PositionNeesWithInterpolatedCovariance) {
  const Walk w = LineWalk();
  Trajectory t;
  for (int i = 0; i <= 5; ++i) {  // poses every 2 s, offset (2, 1) m
    TrajectoryPoint p;
    p.t_s = 2.0 * i;
    p.position_m = Eigen::Vector3d(2.0 * i + 2.0, 1.0, 0.0);
    Eigen::Matrix3d c = Eigen::Matrix3d::Identity();
    c.topLeftCorner<2, 2>() = (i % 2 == 0 ? 4.0 : 2.0) * Eigen::Vector2d(1.0, 0.25).asDiagonal();
    c(0, 2) = c(2, 0) = 0.5;  // the heading block does not enter
    p.covariance = c;
    t.points.push_back(p);
  }
  auto e = ComputeErrors(w, t);
  ASSERT_TRUE(e.ok());
  ASSERT_EQ(e->nees.size(), 11u);
  EXPECT_NEAR(e->nees[0], 4.0 / 4.0 + 1.0 / 1.0, 1e-12);   // P = diag(4, 1)
  EXPECT_NEAR(e->nees[2], 4.0 / 2.0 + 1.0 / 0.5, 1e-12);   // P = diag(2, 0.5)
  EXPECT_NEAR(e->nees[1], 4.0 / 3.0 + 1.0 / 0.75, 1e-12);  // halfway: diag(3, 0.75)
  const ErrorStats s = SummarizeErrors(*e, 10.0);
  double sum = 0.0;
  for (double v : e->nees) sum += v;
  EXPECT_NEAR(s.anees, sum / 11.0, 1e-12);
  EXPECT_TRUE(std::isnan(SummarizeErrors(e->error_m, 10.0).anees));

  Trajectory missing = t;
  missing.points[3].covariance.reset();
  auto m = ComputeErrors(w, missing);
  ASSERT_TRUE(m.ok());
  EXPECT_TRUE(m->nees.empty());
  EXPECT_TRUE(std::isnan(SummarizeErrors(*m, 10.0).anees));
  Trajectory indefinite = t;
  (*indefinite.points[2].covariance)(1, 1) = -1.0;
  auto n = ComputeErrors(w, indefinite);
  ASSERT_TRUE(n.ok());
  EXPECT_TRUE(n->nees.empty());
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
