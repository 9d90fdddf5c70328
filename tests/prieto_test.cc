#include "walkgraph/filters/prieto.h"

#include <cmath>
#include <cstdio>
#include <random>

#include <gtest/gtest.h>
#include <Eigen/Dense>

#include "test_util.h"
#include "walkgraph/angle.h"
#include "walkgraph/estimator.h"
#include "walkgraph/metrics.h"
#include "walkgraph/simulate.h"

namespace walkgraph {
namespace {

using prieto::kFullDim;
using prieto::Measurement;
using prieto::MeasurementKind;
using prieto::MeasurementParams;
using prieto::NominalState;

NominalState RandomState(uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> n01(0.0, 1.0);
  auto vec = [&](double s) { return Eigen::Vector3d(s * n01(rng), s * n01(rng), s * n01(rng)); };
  NominalState y;
  y.x = vec(5.0);
  y.v = vec(1.0);
  y.a = vec(3.0);
  y.q_nb = QuaternionExp(vec(1.0));
  y.w = vec(2.0);
  y.b_f = vec(0.1);
  y.b_w = vec(0.01);
  return y;
}

// Central differences of g(δ) ∈ R^m at δ = 0 over the error coordinates.
template <typename G>
Eigen::MatrixXd NumericJacobian(const G& g, int dim, double h = 1e-6) {
  const Eigen::VectorXd g0 = g(Eigen::VectorXd::Zero(dim));
  Eigen::MatrixXd J(g0.size(), dim);
  for (int i = 0; i < dim; ++i) {
    Eigen::VectorXd d = Eigen::VectorXd::Zero(dim);
    d[i] = h;
    const Eigen::VectorXd plus = g(d);
    d[i] = -h;
    J.col(i) = (plus - g(d)) / (2.0 * h);
  }
  return J;
}

TEST(PrietoModels, RetractAndLocalAreInverse) {
  const NominalState y = RandomState(1);
  Eigen::VectorXd d(kFullDim);
  for (int i = 0; i < kFullDim; ++i) d[i] = 0.1 * std::sin(1.0 + i);
  const NominalState z = prieto::Retract(y, d);
  EXPECT_NEAR((prieto::Local(y, z, kFullDim) - d).norm(), 0.0, 1e-12);
  EXPECT_NEAR(z.q_nb.norm(), 1.0, 1e-15);
  EXPECT_NEAR(prieto::Local(y, y, kFullDim).norm(), 0.0, 1e-15);
}

TEST(PrietoModels, TransitionJacobianMatchesNumericDifferentiation) {
  for (uint64_t seed : {2, 3, 4}) {
    const NominalState y = RandomState(seed);
    for (double dt : {0.01, 0.3}) {
      const NominalState fy = prieto::Propagate(y, dt);
      auto g = [&](const Eigen::VectorXd& d) {
        return prieto::Local(fy, prieto::Propagate(prieto::Retract(y, d), dt), kFullDim);
      };
      const Eigen::MatrixXd F = prieto::TransitionJacobian(y, dt, kFullDim);
      const Eigen::MatrixXd Fn = NumericJacobian(g, kFullDim);
      EXPECT_LT((F - Fn).cwiseAbs().maxCoeff(), 1e-7) << "seed " << seed << " dt " << dt;
    }
  }
}

TEST(PrietoModels, MeasurementJacobiansMatchNumericDifferentiation) {
  MeasurementParams p;
  p.receiver_offset_z_m = 0.3;
  Measurement imu, stance, rss, toa;
  imu.kind = MeasurementKind::kImu;
  stance.kind = MeasurementKind::kImuStance;
  rss.kind = MeasurementKind::kRss;
  rss.anchor_m = Eigen::Vector3d(40, -3, 2);
  toa.kind = MeasurementKind::kToa;
  toa.anchor_m = Eigen::Vector3d(-3, 20, 0);
  p.toa_alpha_m = 0.5;
  p.toa_beta = 1.1;
  for (Measurement* m : {&imu, &stance, &rss, &toa}) {
    m->z = Eigen::VectorXd::Zero(m->kind == MeasurementKind::kImuStance ? 15
                                 : m->kind == MeasurementKind::kImu     ? 6
                                                                        : 1);
    m->R = Eigen::MatrixXd::Identity(m->z.size(), m->z.size());
  }
  const Measurement stack = prieto::StackMeasurements({rss, toa, imu});
  for (uint64_t seed : {5, 6, 7}) {
    const NominalState y = RandomState(seed);
    for (const Measurement* m :
         std::vector<const Measurement*>{&imu, &stance, &rss, &toa, &stack}) {
      auto g = [&](const Eigen::VectorXd& d) {
        return prieto::PredictMeasurement(p, *m, prieto::Retract(y, d));
      };
      const Eigen::MatrixXd H = prieto::MeasurementJacobian(p, *m, y, kFullDim);
      const Eigen::MatrixXd Hn = NumericJacobian(g, kFullDim);
      ASSERT_EQ(H.rows(), Hn.rows());
      EXPECT_LT((H - Hn).cwiseAbs().maxCoeff(), 1e-6 * std::max(1.0, Hn.cwiseAbs().maxCoeff()))
          << "kind " << static_cast<int>(m->kind) << " seed " << seed;
    }
    // RFCode units (larger is weaker): the sign of the slope flips.
    MeasurementParams rf = p;
    rf.rss_sign = -1.0;
    auto g = [&](const Eigen::VectorXd& d) {
      return prieto::PredictMeasurement(rf, rss, prieto::Retract(y, d));
    };
    EXPECT_LT((prieto::MeasurementJacobian(rf, rss, y, kFullDim) - NumericJacobian(g, kFullDim))
                  .cwiseAbs()
                  .maxCoeff(),
              1e-6);
  }
}

TEST(PrietoModels, AccelerometerModelReadsGravityAtRest) {
  // eq. 7 at rest, level, any yaw: f = C(q̄)(0 − g) = (0, 0, +g) plus the bias.
  NominalState y;
  y.q_nb = Eigen::Quaterniond(Eigen::AngleAxisd(1.2, Eigen::Vector3d::UnitZ()));
  y.b_f = Eigen::Vector3d(0.01, -0.02, 0.03);
  y.b_w = Eigen::Vector3d(0.001, 0.002, 0.003);
  MeasurementParams p;
  Measurement m;
  m.kind = MeasurementKind::kImuStance;
  const Eigen::VectorXd h = prieto::PredictMeasurement(p, m, y);
  EXPECT_NEAR(h[0], 0.01, 1e-12);
  EXPECT_NEAR(h[1], -0.02, 1e-12);
  EXPECT_NEAR(h[2], 9.81 + 0.03, 1e-12);
  EXPECT_NEAR((h.segment<3>(3) - y.b_w).norm(), 0.0, 1e-15);  // eq. 8 with ω = 0
  EXPECT_NEAR(h.tail<9>().norm(), 0.0, 1e-15);                // eq. 9 evidences
}

TEST(PrietoModels, HeadingCovarianceMatchesNumericDifferentiation) {
  const NominalState y = RandomState(8);
  Eigen::MatrixXd P = Eigen::MatrixXd::Identity(kFullDim, kFullDim) * 1e-4;
  const prieto::PlanarPose pose = prieto::ToPlanarPose(y, P);
  auto g = [&](const Eigen::VectorXd& d) {
    const prieto::PlanarPose q = prieto::ToPlanarPose(prieto::Retract(y, d), P);
    Eigen::VectorXd out = q.pose;
    out[2] = NormalizeAngle(out[2] - pose.pose[2]);
    return out;
  };
  const Eigen::MatrixXd J = NumericJacobian(g, kFullDim);
  const Eigen::Matrix3d expected = J * P * J.transpose();
  EXPECT_LT((pose.covariance - expected).cwiseAbs().maxCoeff(), 1e-9);
}

TEST(PrietoOptions, PaperDefaultsAndStrictYaml) {
  auto o = PrietoOptions::FromYaml(YAML::Node(), "prieto-ekf");
  ASSERT_TRUE(o.ok()) << o.status().message();
  EXPECT_EQ(o->sigma_jerk_mps3, 450.0);  // Sec. IV-A
  EXPECT_EQ(o->sigma_attitude_rate_ps, 1e-4);
  EXPECT_EQ(o->sigma_omega_rate_radps2, 10.0);
  EXPECT_EQ(o->sigma_acc_bias_mps2, 0.135);
  EXPECT_EQ(o->sigma_gyro_bias_radps, 6e-4);
  EXPECT_EQ(o->sigma_v0_mps, 1e-2);
  EXPECT_EQ(o->sigma_a0_mps2, 0.3);
  EXPECT_EQ(o->sigma_w0_radps, 5e-2);
  EXPECT_EQ(o->stance.detector, StanceDetector::kMultiCondition);  // [33]
  EXPECT_FALSE(PrietoOptions::FromYaml(YAML::Load("{sigma_q: 1}"), "p").ok());
  EXPECT_FALSE(PrietoOptions::FromYaml(YAML::Load("{imu_sampling: magic}"), "p").ok());
  EXPECT_FALSE(PrietoOptions::FromYaml(YAML::Load("{ukf_alpha: 0}"), "p").ok());
  EXPECT_FALSE(PrietoOptions::FromYaml(YAML::Load("{stance: {nope: 1}}"), "p").ok());
  EXPECT_FALSE(PrietoOptions::FromYaml(YAML::Load("{gate_probability: 1.5}"), "p").ok());
  auto custom = PrietoOptions::FromYaml(
      YAML::Load("{ukf_alpha: 0.5, gate_probability: 0.99, imu_sampling: instantaneous, "
                 "stance: {mc_acc_std_max_mps2: 0.7}}"),
      "p");
  ASSERT_TRUE(custom.ok()) << custom.status().message();
  EXPECT_EQ(custom->ukf_alpha, 0.5);
  EXPECT_EQ(custom->gate_probability, 0.99);
  EXPECT_EQ(custom->imu_sampling, ImuSampling::kInstantaneous);
  // A stance child keeps the paper's detector unless it names another one.
  EXPECT_EQ(custom->stance.detector, StanceDetector::kMultiCondition);
  EXPECT_EQ(custom->stance.mc_acc_std_max_mps2, 0.7);
  for (const char* id :
       {"prieto-ekf", "prieto-ukf", "prieto-ekf-rts", "prieto-ukf-rts", "prieto-ekf-imu",
        "prieto-ukf-imu", "prieto-ekf-wifi", "prieto-ukf-wifi"}) {
    EXPECT_TRUE(EstimatorRegistry::Builtin().Create(id, YAML::Node()).ok()) << id;
  }
  EXPECT_FALSE(EstimatorRegistry::Builtin().Create("prieto-ekf", YAML::Load("{x: 1}")).ok());
}

}  // namespace
}  // namespace walkgraph
