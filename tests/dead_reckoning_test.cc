#include <cmath>

#include <gtest/gtest.h>
#include <Eigen/Eigenvalues>

#include "config/parsers.h"
#include "walkgraph/angle.h"
#include "walkgraph/dead_reckoning.h"
#include "walkgraph/io.h"
#include "walkgraph/metrics.h"

namespace walkgraph {
namespace {

TEST(OdometryDeadReckoning, SquareClosesAndCovarianceGrows) {
  Walk w;
  w.meta.initial_pose = InitialPose{1.0, 2.0, 0.0, 0.1, 0.01};
  double t = 0.0;
  for (int side = 0; side < 4; ++side) {
    for (int k = 0; k < 10; ++k) {
      t += 0.5;
      w.odometry.push_back({t, 0.5, k == 9 ? kPi / 2 : 0.0});
    }
  }
  OdometryDeadReckoning dr({});
  ASSERT_TRUE(dr.CheckApplicable(w).ok());
  auto r = dr.Run(w);
  ASSERT_TRUE(r.ok());
  const auto& pts = r->trajectory.points;
  ASSERT_EQ(pts.size(), 40u);
  // After the first side: 5 m east of the start.
  EXPECT_NEAR(pts[9].position_m.x(), 6.0, 1e-12);
  EXPECT_NEAR(pts[9].position_m.y(), 2.0, 1e-12);
  EXPECT_NEAR(pts.back().position_m.x(), 1.0, 1e-9);
  EXPECT_NEAR(pts.back().position_m.y(), 2.0, 1e-9);
  EXPECT_NEAR(NormalizeAngle(pts.back().heading_rad), 0.0, 1e-12);
  EXPECT_GT(pts.back().covariance->trace(), pts.front().covariance->trace());
  const Eigen::Matrix3d P = *pts.back().covariance;
  EXPECT_LT((P - P.transpose()).norm(), 1e-15);
  EXPECT_GT(Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(P).eigenvalues().minCoeff(), 0.0);
}

TEST(OdometryDeadReckoning, NeedsOdometryAndStart) {
  Walk w;
  OdometryDeadReckoning dr({});
  EXPECT_FALSE(dr.CheckApplicable(w).ok());
  w.odometry.push_back({1.0, 0.1, 0.0});
  EXPECT_FALSE(dr.CheckApplicable(w).ok());
  EXPECT_FALSE(dr.Run(w).ok());
}

TEST(OdometryDeadReckoningOptions, RejectsNegativeSigma) {
  EXPECT_FALSE(OdometryDeadReckoningOptionsFromYaml(YAML::Load("sigma_dist_m: -1")).ok());
  EXPECT_FALSE(OdometryDeadReckoningOptionsFromYaml(YAML::Load("sigma_typo: 1")).ok());
}

// Real data: the bundled Plaza1 walk. The issue tracker reports 1.97 m RMSE for dead reckoning
// alone on this walk (measured with another library); ours must agree.
TEST(OdometryDeadReckoning, Plaza1MatchesPublishedDeadReckoningError) {
  auto walk = ReadWalk(std::string(WALKGRAPH_SOURCE_DIR) + "/datasets/plaza1");
  ASSERT_TRUE(walk.ok()) << walk.status().message();
  OdometryDeadReckoning dr({});
  auto r = dr.Run(*walk);
  ASSERT_TRUE(r.ok());
  auto e = ComputeErrors(*walk, r->trajectory);
  ASSERT_TRUE(e.ok());
  const ErrorStats s = SummarizeErrors(e->error_m, walk->TruthDistance());
  EXPECT_NEAR(s.rmse_m, 1.97, 0.02);
  EXPECT_NEAR(walk->TruthDistance(), 1860.0, 40.0);
}

}  // namespace
}  // namespace walkgraph
