#include "walkgraph/strapdown.h"

#include <cmath>

#include <gtest/gtest.h>

#include "walkgraph/angle.h"
#include "simulate/sim_models.h"

namespace walkgraph {
namespace {

std::vector<ImuSample> Noiseless(const std::vector<sim::ImuTruth>& truth) {
  std::vector<ImuSample> out;
  for (const auto& s : truth) {
    ImuSample m;
    m.t_s = s.t_s;
    m.acc_mps2 = s.specific_force_b;
    m.gyro_radps = s.angular_rate_b;
    out.push_back(m);
  }
  return out;
}

NavState TrueState(const sim::ImuTruth& s) {
  NavState n;
  n.t_s = s.t_s;
  n.q_nb = s.q_nb;
  n.v_n = s.velocity_n;
  n.p_n = s.position_n;
  return n;
}

TEST(QuaternionExpLog, RoundTripAndSmallAngles) {
  for (const Eigen::Vector3d phi :
       {Eigen::Vector3d(0.3, -0.2, 1.1), Eigen::Vector3d(1e-9, 0, 0), Eigen::Vector3d(0, 0, 3.0)}) {
    EXPECT_LT((QuaternionLog(QuaternionExp(phi)) - phi).norm(), 1e-12);
    const Eigen::AngleAxisd aa(phi.norm(),
                               phi.norm() > 0 ? phi.normalized() : Eigen::Vector3d::UnitX());
    EXPECT_LT((QuaternionExp(phi).toRotationMatrix() - aa.toRotationMatrix()).norm(), 1e-12);
  }
  const Eigen::Vector3d v(1, 2, 3), w(-0.5, 0.1, 2);
  EXPECT_LT((Skew(v) * w - v.cross(w)).norm(), 1e-15);
}

TEST(Strapdown, AtRestStaysPut) {
  std::vector<ImuSample> s(1001);
  const Eigen::Quaterniond q(Eigen::AngleAxisd(0.7, Eigen::Vector3d(0.2, -0.3, 1).normalized()));
  for (size_t k = 0; k < s.size(); ++k) {
    s[k].t_s = k * 0.01;
    s[k].acc_mps2 = q.conjugate() * Eigen::Vector3d(0, 0, 9.81);
  }
  NavState x0;
  x0.q_nb = q;
  const auto out = IntegrateStrapdown(x0, s);
  EXPECT_LT(out.back().p_n.norm(), 1e-9);
  EXPECT_LT(out.back().v_n.norm(), 1e-10);
}

TEST(Strapdown, InstantaneousModeIntegratesConstantRotationExactly) {
  // Rotating at a constant rate about a fixed axis while at rest in position: the specific force
  // follows gravity in the body frame; trapezoid + coning is exact for a constant rate.
  const Eigen::Vector3d w(0.0, 0.4, 0.9);
  std::vector<ImuSample> s(501);
  for (size_t k = 0; k < s.size(); ++k) {
    s[k].t_s = k * 0.01;
    s[k].gyro_radps = w;
    s[k].acc_mps2 = QuaternionExp(w * s[k].t_s).conjugate() * Eigen::Vector3d(0, 0, 9.81);
  }
  StrapdownOptions o;
  o.sampling = ImuSampling::kInstantaneous;
  const auto out = IntegrateStrapdown(NavState(), s, 0, o);
  EXPECT_LT(QuaternionLog(out.back().q_nb.conjugate() * QuaternionExp(w * 5.0)).norm(), 1e-10);
  EXPECT_LT(out.back().p_n.norm(), 1e-3);
}

// The required test: the noiseless simulated foot IMU, integrated from the true initial state,
// reproduces the true foot trajectory within 1 cm over 60 s (corners, a 180° turn in place).
TEST(Strapdown, RecoversSimulatedFootTrajectoryWithin1cmOver60s) {
  sim::MotionPlan plan(Eigen::Vector2d(0, 0), 0.0);
  plan.Stop(2.0);
  plan.WalkWaypoints({{0, 0}, {15, 0}, {15, 8}, {3, 8}, {3, 2}, {9, 2}, {3, 2}}, 1.1, 0.6, 2.0);
  plan.Stop(2.0);
  plan.Walk(sim::CirclePath(Eigen::Vector2d(3, 5), 3.0, -0.5 * kPi, 1.0), 1.0, true, true);
  ASSERT_GE(plan.duration(), 60.0);
  sim::FootMotion foot(plan, {});
  const auto truth = sim::SampleFootImu(foot, 100.0);
  const auto imu = Noiseless(truth);
  const auto nav = IntegrateStrapdown(TrueState(truth[0]), imu);
  double max_err = 0.0, max_att = 0.0;
  size_t n60 = 0;
  for (size_t k = 0; k < nav.size() && truth[k].t_s <= 60.0; ++k, ++n60) {
    max_err = std::max(max_err, (nav[k].p_n - truth[k].position_n).norm());
    max_att = std::max(max_att, QuaternionLog(truth[k].q_nb.conjugate() * nav[k].q_nb).norm());
  }
  EXPECT_EQ(n60, 6001u);
  RecordProperty("max_position_error_m", std::to_string(max_err));
  std::printf("max position error over 60 s: %.6f m, attitude %.3g rad\n", max_err, max_att);
  EXPECT_LT(max_err, 0.01);
  EXPECT_LT(max_att, 1e-4);
}

}  // namespace
}  // namespace walkgraph
