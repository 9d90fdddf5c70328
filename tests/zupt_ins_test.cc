#include "walkgraph/zupt_ins.h"

#include <cstdio>

#include <gtest/gtest.h>
#include <Eigen/Eigenvalues>

#include "config/parsers.h"
#include "walkgraph/metrics.h"
#include "walkgraph/simulate.h"

namespace walkgraph {
namespace {

TEST(ZuptIns, DeadReckoningDriftAndCovarianceOnJimenezBuilding) {
  auto w = SimulateScenario("jimenez-building", 21, YAML::Load("{laps: 2}"));
  ASSERT_TRUE(w.ok()) << w.status().ToString();
  auto est = EstimatorRegistry::Builtin().Create("zupt-ins");
  ASSERT_TRUE(est.ok());
  auto r = (*est)->Run(*w);
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  auto e = ComputeErrors(*w, r->trajectory);
  ASSERT_TRUE(e.ok());
  const ErrorStats s = SummarizeErrors(e->error_m, w->TruthDistance());
  std::printf("zupt-ins jimenez-building 2 laps: RMSE %.3f m, final %.3f m = %.2f %% of %.0f m\n",
              s.rmse_m, s.final_m, s.pct_distance, w->TruthDistance());
  // 004: IMU-only IEZ+ ≈ 1.27 % of the distance travelled.
  EXPECT_LT(s.pct_distance, 1.5);
  // ≈ 20 Hz output over the walk.
  const double span = r->trajectory.points.back().t_s - r->trajectory.points.front().t_s;
  EXPECT_NEAR(r->trajectory.size() / span, 20.0, 2.0);
  // The composed covariance starts at initial_pose's and grows with the distance walked.
  const Eigen::Matrix3d& c0 = *r->trajectory.points.front().covariance;
  const Eigen::Matrix3d& c1 = *r->trajectory.points.back().covariance;
  EXPECT_NEAR(c0(0, 0), w->meta.initial_pose->sigma_xy_m * w->meta.initial_pose->sigma_xy_m, 1e-6);
  EXPECT_GT(c1(0, 0) + c1(1, 1), c0(0, 0) + c0(1, 1));
  EXPECT_GT(c1(2, 2), c0(2, 2));
  for (const TrajectoryPoint& p : r->trajectory.points) {
    ASSERT_TRUE(p.covariance.has_value());
    EXPECT_GT(
        Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(*p.covariance).eigenvalues().minCoeff(),
        0.0);
  }
  int swings = 0;  // of the simulated foot, from its stance labels
  for (size_t i = 1; i < w->stance_truth.size(); ++i) {
    swings += w->stance_truth[i - 1].stance && !w->stance_truth[i].stance;
  }
  EXPECT_NEAR(r->diagnostics.at("num_strides"), swings, 1.0);
}

TEST(ZuptIns, OptionsAndApplicability) {
  EXPECT_FALSE(ZuptInsOptionsFromYaml(YAML::Load("{output_rate: 10}")).ok());
  EXPECT_FALSE(ZuptInsOptionsFromYaml(YAML::Load("{output_rate_hz: 0}")).ok());
  auto o = ZuptInsOptionsFromYaml(YAML::Load("{front_end: {use_zaru: false}}"));
  ASSERT_TRUE(o.ok()) << o.status().ToString();
  EXPECT_FALSE(o->front_end.use_zaru);
  Walk waist;
  waist.meta.imu_placement = ImuPlacement::kWaist;
  EXPECT_FALSE(ZuptInsDeadReckoning(*o).CheckApplicable(waist).ok());
}

}  // namespace
}  // namespace walkgraph
