#include "walkgraph/zupt_ins.h"

#include <algorithm>
#include <cstdio>
#include <map>
#include <string>

#include <gtest/gtest.h>
#include <Eigen/Eigenvalues>

#include "config/parsers.h"
#include "test_util.h"
#include "walkgraph/estimator.h"
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

// The gait detector's one stance per stride period lands inside the swing of a stride longer
// than the period (the first from a standstill); its ZUPT at a predicted 0.8–3.8 m/s is a gross
// error the gate turns down (strides.h zupt_gross_gate_ratio): running with short stances, and
// a slow walk whose first strides from the standstill get them before the walk has a NIS scale
// of its own. Measured (seed 1): RMSE 0.068 / 0.097 m with the gate, 1.286 / 0.774 m without.
TEST(ZuptIns, GrossErrorGateTurnsDownAStanceInsideASwing) {
  const char* walks[] = {
      "{gait: run, speed_mps: 3.5, stance_fraction: 0.1, duration_s: 60, imu_rate_hz: 200}",
      "{speed_mps: 0.4, duration_s: 60}"};
  for (const char* overrides : walks) {
    auto w = SimulateScenario("jimenez-building", 1, YAML::Load(overrides));
    ASSERT_TRUE(w.ok()) << w.status().ToString();
    for (const double ratio : {100.0, 0.0}) {
      ZuptInsOptions o;
      o.front_end.zupt_gross_gate_ratio = ratio;
      auto r = ZuptInsDeadReckoning(o).Run(*w);
      ASSERT_TRUE(r.ok()) << r.status().ToString();
      auto e = ComputeErrors(*w, r->trajectory);
      ASSERT_TRUE(e.ok());
      const double rmse = SummarizeErrors(e->error_m, w->TruthDistance()).rmse_m;
      std::printf("zupt-ins %s, gross gate ratio %.0f: RMSE %.3f m, %.0f runs gated\n", overrides,
                  ratio, rmse, r->diagnostics.at("stance_runs_gated"));
      if (ratio > 0) {
        EXPECT_LT(rmse, 0.2);
        EXPECT_GE(r->diagnostics.at("stance_runs_gated"), 1.0);
      } else {
        EXPECT_GT(rmse, 0.5);  // the failure the gate is for is still in the simulated walk
        EXPECT_EQ(r->diagnostics.at("stance_runs_gated"), 0.0);
      }
    }
  }
}

// A walk that starts in a swing (strides.h wait_for_first_stance): the INS starts at the first
// stance instead of integrating the swing from a levelled attitude that is not the foot's.
// jimenez-building without rest, IMU alone, cut at the middle of its first swing of 0.3 s or
// more after 5 s. Measured (seeds 1-3, RMSE after SE(2) alignment): zupt-ins 0.034 / 0.023 /
// 0.024 m (0.510 / 0.306 / 0.135 integrating the swing), fg-ins-window 0.017 / 0.016 / 0.016
// (0.582 / 0.357 / 0.038).
TEST(ZuptIns, AWalkThatStartsInASwingStartsAtItsFirstStance) {
  const int runs = testing::kSanitized ? 1 : 3;
  for (int seed = 1; seed <= runs; ++seed) {
    auto w = testing::FootWalkWithoutRest(seed);
    ASSERT_TRUE(w.ok()) << w.status().ToString();
    double swing_begin = -1.0, cut = -1.0;
    for (const StanceSample& s : w->stance_truth) {
      if (s.t_s < 5.0) continue;
      if (!s.stance && swing_begin < 0) swing_begin = s.t_s;
      if (s.stance && swing_begin >= 0) {
        if (s.t_s - swing_begin >= 0.3) {
          cut = 0.5 * (swing_begin + s.t_s);
          break;
        }
        swing_begin = -1.0;
      }
    }
    ASSERT_GT(cut, 0.0);
    auto before = [cut](const auto& sample) { return sample.t_s < cut; };
    w->imu.erase(std::remove_if(w->imu.begin(), w->imu.end(), before), w->imu.end());
    w->truth.erase(std::remove_if(w->truth.begin(), w->truth.end(), before), w->truth.end());
    w->stance_truth.erase(std::remove_if(w->stance_truth.begin(), w->stance_truth.end(), before),
                          w->stance_truth.end());
    std::map<std::string, double> with, without;
    for (const char* id : {"zupt-ins", "fg-ins-window"}) {
      for (const bool wait : {true, false}) {
        YAML::Node config;
        config["front_end"]["wait_for_first_stance"] = wait;
        auto est = EstimatorRegistry::Builtin().Create(id, config);
        ASSERT_TRUE(est.ok()) << est.status().ToString();
        auto r = (*est)->Run(*w);
        ASSERT_TRUE(r.ok()) << r.status().ToString();
        auto e = ComputeErrors(*w, r->trajectory, Alignment::kSE2);
        ASSERT_TRUE(e.ok()) << e.status().ToString();
        (wait ? with : without)[id] = SummarizeErrors(e->error_m, w->TruthDistance()).rmse_m;
      }
    }
    std::printf(
        "cut at %.2f s, seed %d: zupt-ins %.3f m (%.3f integrating the swing), "
        "fg-ins-window %.3f (%.3f)\n",
        cut, seed, with["zupt-ins"], without["zupt-ins"], with["fg-ins-window"],
        without["fg-ins-window"]);
    EXPECT_LT(with["zupt-ins"], 0.08) << seed;
    EXPECT_LT(with["fg-ins-window"], 0.05) << seed;
    EXPECT_GT(without["zupt-ins"], 0.1) << seed;  // the failure is still in the walk
  }
}

TEST(ZuptIns, OptionsAndApplicability) {
  EXPECT_FALSE(ZuptInsOptionsFromYaml(YAML::Load("{output_rate: 10}")).ok());
  EXPECT_FALSE(ZuptInsOptionsFromYaml(YAML::Load("{output_rate_hz: 0}")).ok());
  EXPECT_FALSE(ZuptInsOptionsFromYaml(YAML::Load("{front_end: {zupt_gross_gate_ratio: -1}}")).ok());
  auto gate = ZuptInsOptionsFromYaml(YAML::Load("{front_end: {zupt_gross_gate_ratio: 0}}"));
  ASSERT_TRUE(gate.ok()) << gate.status().ToString();
  EXPECT_EQ(gate->front_end.zupt_gross_gate_ratio, 0.0);
  auto o = ZuptInsOptionsFromYaml(YAML::Load("{front_end: {use_zaru: false}}"));
  ASSERT_TRUE(o.ok()) << o.status().ToString();
  EXPECT_FALSE(o->front_end.use_zaru);
  Walk waist;
  waist.meta.imu_placement = ImuPlacement::kWaist;
  EXPECT_FALSE(ZuptInsDeadReckoning(*o).CheckApplicable(waist).ok());
}

}  // namespace
}  // namespace walkgraph
