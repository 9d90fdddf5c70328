// The foot-INS factors: nav-frame quaternion manifold, IMU preintegration (bias Jacobians and
// covariance against re-integration and Monte Carlo, residual against strapdown.h), ZUPT,
// ZARU, bias random walk / prior, gauge prior; every cost function through
// ceres::GradientChecker with its manifolds.
#include <cmath>
#include <memory>
#include <random>
#include <vector>

#include <ceres/gradient_checker.h>
#include <ceres/manifold_test_utils.h>
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "factors/bias_random_walk_factor.h"
#include "factors/gap_reach_factor.h"
#include "factors/imu_preintegration_factor.h"
#include "factors/ins_prior_factor.h"
#include "factors/magnetic_heading_change_factor.h"
#include "factors/magnetic_heading_factor.h"
#include "factors/nav_quaternion_manifold.h"
#include "factors/stance_level_factor.h"
#include "factors/zaru_factor.h"
#include "factors/zupt_factor.h"
#include "walkgraph/angle.h"
#include "walkgraph/strapdown.h"

namespace walkgraph {
namespace {

constexpr double kG = 9.81;

Eigen::Vector3d RandomVector(std::mt19937_64* rng, double scale) {
  std::normal_distribution<double> n(0.0, scale);
  return Eigen::Vector3d(n(*rng), n(*rng), n(*rng));
}

Eigen::Quaterniond RandomRotation(std::mt19937_64* rng) {
  return QuaternionExp(RandomVector(rng, 1.0));
}

// Readings of a swinging foot-like motion: rates of a few rad/s, specific force around g.
struct Readings {
  std::vector<Eigen::Vector3d> gyro, acc;
  double dt = 0.01;
};
Readings MakeReadings(int n, uint64_t seed) {
  std::mt19937_64 rng(seed);
  Readings r;
  for (int k = 0; k < n; ++k) {
    const double t = k * r.dt;
    r.gyro.push_back(Eigen::Vector3d(0.3 * std::sin(3 * t), 4.0 * std::sin(6 * t), 0.5) +
                     RandomVector(&rng, 0.2));
    r.acc.push_back(Eigen::Vector3d(5.0 * std::cos(6 * t), 0.5, kG + 3.0 * std::sin(6 * t)) +
                    RandomVector(&rng, 0.5));
  }
  return r;
}

ImuPreintegration Preintegrate(const Readings& r, const Eigen::Vector3d& bg,
                               const Eigen::Vector3d& ba, double sg = 0.005, double sa = 0.01) {
  ImuPreintegration p(bg, ba, sg, sa);
  for (size_t k = 0; k < r.gyro.size(); ++k) p.Integrate(r.dt, r.gyro[k], r.acc[k]);
  return p;
}

std::array<double, 4> Coeffs(const Eigen::Quaterniond& q) { return {q.x(), q.y(), q.z(), q.w()}; }

TEST(NavQuaternionManifold, ExpLogAgreeWithStrapdownAndRoundTrip) {
  std::mt19937_64 rng(1);
  for (int i = 0; i < 50; ++i) {
    Eigen::Vector3d phi = RandomVector(&rng, i < 10 ? 1e-5 : 1.0);
    if (phi.norm() > 3.0) phi *= 3.0 / phi.norm();  // Log returns angles in [0, π]
    const Eigen::Quaterniond a = SO3Exp<double>(phi), b = QuaternionExp(phi);
    EXPECT_NEAR(std::fabs(a.coeffs().dot(b.coeffs())), 1.0, 1e-12);
    EXPECT_LT((SO3Log<double>(a) - phi).norm(), 1e-9 * std::max(1.0, phi.norm()));
    EXPECT_LT((SO3Log<double>(b) - QuaternionLog(b)).norm(), 1e-9);
  }
  // The tangent is a full-angle rotation vector in the navigation frame: δ = (0, 0, a) turns
  // a level body's yaw by a.
  const Eigen::Quaterniond level(Eigen::AngleAxisd(0.4, Eigen::Vector3d::UnitZ()));
  NavQuaternionManifold m;
  const std::array<double, 4> x = Coeffs(level);
  const double delta[3] = {0.0, 0.0, 0.25};
  std::array<double, 4> y{};
  ASSERT_TRUE(m.Plus(x.data(), delta, y.data()));
  const Eigen::Quaterniond qy(y[3], y[0], y[1], y[2]);
  EXPECT_NEAR(QuaternionYaw(qy), 0.65, 1e-12);
}

TEST(NavQuaternionManifold, InvariantsHold) {
  using namespace ceres;  // NOLINT: the invariants macro names ceres' matchers unqualified
  std::mt19937_64 rng(2);
  NavQuaternionManifold m;
  for (int i = 0; i < 10; ++i) {
    const Eigen::Quaterniond qx = RandomRotation(&rng);
    // y within less than π of x, so that Minus inverts Plus.
    const Eigen::Quaterniond qy = SO3Exp<double>(RandomVector(&rng, 0.5)) * qx;
    const Eigen::Vector4d x(qx.x(), qx.y(), qx.z(), qx.w()), y(qy.x(), qy.y(), qy.z(), qy.w());
    const Eigen::Vector3d d = RandomVector(&rng, 0.3);
    EXPECT_THAT_MANIFOLD_INVARIANTS_HOLD(m, x, d, y, 1e-9);
  }
}

TEST(ImuPreintegration, BiasJacobiansMatchReintegration) {
  const Readings r = MakeReadings(60, 3);
  const Eigen::Vector3d bg(0.01, -0.02, 0.015), ba(0.05, -0.03, 0.02);
  const ImuPreintegration p = Preintegrate(r, bg, ba);
  const double h = 1e-6;
  for (int i = 0; i < 3; ++i) {
    Eigen::Vector3d e = Eigen::Vector3d::Zero();
    e[i] = h;
    const ImuPreintegration gp = Preintegrate(r, bg + e, ba), gm = Preintegrate(r, bg - e, ba);
    const ImuPreintegration ap = Preintegrate(r, bg, ba + e), am = Preintegrate(r, bg, ba - e);
    // ∂ΔR/∂b_g: ΔR(b + h e_i) = ΔR(b)·Exp(J e_i h).
    const Eigen::Vector3d dR = (SO3Log<double>(p.delta_q().conjugate() * gp.delta_q()) -
                                SO3Log<double>(p.delta_q().conjugate() * gm.delta_q())) /
                               (2 * h);
    EXPECT_LT((dR - p.dR_dbg().col(i)).norm(), 1e-6 * (1.0 + dR.norm())) << i;
    const Eigen::Vector3d dv_g = (gp.delta_v() - gm.delta_v()) / (2 * h);
    const Eigen::Vector3d dp_g = (gp.delta_p() - gm.delta_p()) / (2 * h);
    const Eigen::Vector3d dv_a = (ap.delta_v() - am.delta_v()) / (2 * h);
    const Eigen::Vector3d dp_a = (ap.delta_p() - am.delta_p()) / (2 * h);
    EXPECT_LT((dv_g - p.dv_dbg().col(i)).norm(), 1e-6 * (1.0 + dv_g.norm())) << i;
    EXPECT_LT((dp_g - p.dp_dbg().col(i)).norm(), 1e-6 * (1.0 + dp_g.norm())) << i;
    EXPECT_LT((dv_a - p.dv_dba().col(i)).norm(), 1e-6 * (1.0 + dv_a.norm())) << i;
    EXPECT_LT((dp_a - p.dp_dba().col(i)).norm(), 1e-6 * (1.0 + dp_a.norm())) << i;
  }
}

TEST(ImuPreintegration, CovarianceMatchesMonteCarlo) {
  const Readings r = MakeReadings(40, 4);
  const double sg = 0.005, sa = 0.02;
  const ImuPreintegration truth =
      Preintegrate(r, Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero(), sg, sa);
  std::mt19937_64 rng(5);
  const int n = 4000;
  Eigen::Matrix<double, 9, 9> c = Eigen::Matrix<double, 9, 9>::Zero();
  for (int m = 0; m < n; ++m) {
    Readings noisy = r;
    for (size_t k = 0; k < r.gyro.size(); ++k) {
      noisy.gyro[k] += RandomVector(&rng, sg);
      noisy.acc[k] += RandomVector(&rng, sa);
    }
    const ImuPreintegration p =
        Preintegrate(noisy, Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero(), sg, sa);
    Eigen::Matrix<double, 9, 1> e;
    e << SO3Log<double>(truth.delta_q().conjugate() * p.delta_q()), p.delta_v() - truth.delta_v(),
        p.delta_p() - truth.delta_p();
    c += e * e.transpose() / n;
  }
  const Eigen::Matrix<double, 9, 9>& model = truth.covariance();
  for (int i = 0; i < 9; ++i) {
    // 4000 samples: the sample variance is within ±5 % (2σ) of the true one.
    EXPECT_NEAR(c(i, i) / model(i, i), 1.0, 0.07) << "diagonal " << i;
  }
  // Correlations too (δv with δp along the same axis are strongly correlated).
  for (int i = 0; i < 3; ++i) {
    const double rho_model =
        model(3 + i, 6 + i) / std::sqrt(model(3 + i, 3 + i) * model(6 + i, 6 + i));
    const double rho_mc = c(3 + i, 6 + i) / std::sqrt(c(3 + i, 3 + i) * c(6 + i, 6 + i));
    EXPECT_NEAR(rho_mc, rho_model, 0.03) << i;
  }
}

// State storage for the factor tests.
struct State {
  std::array<double, 3> p{}, v{};
  std::array<double, 4> q{0, 0, 0, 1};
  std::array<double, 3> bg{}, ba{};
};

TEST(ImuPreintegrationFactor, ZeroResidualOnStrapdownIntegratedStates) {
  // An independent integrator (strapdown.h, interval-average convention) carries state i to j
  // with the same bias-corrected readings; the residual must vanish.
  const Readings r = MakeReadings(80, 6);
  const Eigen::Vector3d bg(0.003, -0.002, 0.004), ba(0.02, 0.01, -0.03);
  std::mt19937_64 rng(7);
  NavState x;
  x.q_nb = RandomRotation(&rng);
  x.v_n = RandomVector(&rng, 1.0);
  x.p_n = RandomVector(&rng, 5.0);
  const NavState xi = x;
  StrapdownOptions so;
  so.gravity_mps2 = kG;
  so.gyro_bias_radps = bg;
  so.acc_bias_mps2 = ba;
  ImuSample prev;
  for (size_t k = 0; k < r.gyro.size(); ++k) {
    ImuSample cur;
    cur.t_s = prev.t_s + r.dt;
    cur.gyro_radps = r.gyro[k];
    cur.acc_mps2 = r.acc[k];
    x.t_s = prev.t_s;
    x = StrapdownStep(x, prev, cur, so);
    prev = cur;
  }
  const ImuPreintegration p = Preintegrate(r, bg, ba);
  ImuPreintegrationFactor f(p, kG);
  State a, b;
  for (int i = 0; i < 3; ++i) {
    a.p[i] = xi.p_n[i];
    a.v[i] = xi.v_n[i];
    a.bg[i] = bg[i];
    a.ba[i] = ba[i];
    b.p[i] = x.p_n[i];
    b.v[i] = x.v_n[i];
  }
  a.q = Coeffs(xi.q_nb);
  b.q = Coeffs(x.q_nb);
  double res[9];
  ASSERT_TRUE(f(a.p.data(), a.v.data(), a.q.data(), a.bg.data(), a.ba.data(), b.p.data(),
                b.v.data(), b.q.data(), res));
  for (double v : res) EXPECT_NEAR(v, 0.0, 1e-5);
  // Predict() reproduces state j as well.
  Eigen::Vector3d pj, vj;
  Eigen::Quaterniond qj;
  p.Predict(xi.p_n, xi.v_n, xi.q_nb, bg, ba, kG, &pj, &vj, &qj);
  EXPECT_LT((pj - x.p_n).norm(), 1e-9);
  EXPECT_LT((vj - x.v_n).norm(), 1e-9);
  EXPECT_LT(SO3Log<double>(qj * x.q_nb.conjugate()).norm(), 1e-9);
}

void ExpectGradientsMatch(const ceres::CostFunction& cost,
                          const std::vector<const ceres::Manifold*>& manifolds,
                          std::vector<double*> blocks, double tolerance = 1e-6) {
  ceres::NumericDiffOptions options;
  ceres::GradientChecker checker(&cost, &manifolds, options);
  ceres::GradientChecker::ProbeResults results;
  EXPECT_TRUE(checker.Probe(blocks.data(), tolerance, &results)) << results.error_log;
}

TEST(InsFactorGradients, ImuPreintegrationFactor) {
  const Readings r = MakeReadings(50, 8);
  const ImuPreintegration p =
      Preintegrate(r, Eigen::Vector3d(0.01, 0, 0), Eigen::Vector3d(0, 0.02, 0), 0.01, 0.05);
  std::unique_ptr<ceres::CostFunction> cost(ImuPreintegrationFactor::Create(p, kG));
  std::mt19937_64 rng(9);
  NavQuaternionManifold m;
  for (int trial = 0; trial < 5; ++trial) {
    State a, b;
    for (int i = 0; i < 3; ++i) {
      a.p[i] = RandomVector(&rng, 3.0)[i];
      a.v[i] = RandomVector(&rng, 1.0)[i];
      a.bg[i] = RandomVector(&rng, 0.01)[i];
      a.ba[i] = RandomVector(&rng, 0.05)[i];
      b.p[i] = RandomVector(&rng, 3.0)[i];
      b.v[i] = RandomVector(&rng, 1.0)[i];
    }
    a.q = Coeffs(RandomRotation(&rng));
    b.q = Coeffs(RandomRotation(&rng));
    ExpectGradientsMatch(*cost, {nullptr, nullptr, &m, nullptr, nullptr, nullptr, nullptr, &m},
                         {a.p.data(), a.v.data(), a.q.data(), a.bg.data(), a.ba.data(), b.p.data(),
                          b.v.data(), b.q.data()},
                         1e-5);
  }
}

TEST(InsFactorGradients, UnaryAndBiasFactors) {
  std::mt19937_64 rng(10);
  NavQuaternionManifold m;
  State s, t;
  for (int i = 0; i < 3; ++i) {
    s.p[i] = RandomVector(&rng, 2.0)[i];
    s.v[i] = RandomVector(&rng, 0.1)[i];
    s.bg[i] = RandomVector(&rng, 0.01)[i];
    t.bg[i] = RandomVector(&rng, 0.01)[i];
  }
  s.q = Coeffs(RandomRotation(&rng));
  std::unique_ptr<ceres::CostFunction> zupt(ZuptFactor::Create(0.01));
  ExpectGradientsMatch(*zupt, {nullptr}, {s.v.data()});
  std::unique_ptr<ceres::CostFunction> zaru(
      ZaruFactor::Create(Eigen::Vector3d(0.01, -0.02, 0.005), 0.001));
  ExpectGradientsMatch(*zaru, {nullptr}, {s.bg.data()});
  std::unique_ptr<ceres::CostFunction> rw(BiasRandomWalkFactor::Create(1e-4, 0.8));
  ExpectGradientsMatch(*rw, {nullptr, nullptr}, {s.bg.data(), t.bg.data()});
  std::unique_ptr<ceres::CostFunction> prior(
      BiasPriorFactor::Create(Eigen::Vector3d(0.001, 0, 0), 0.02));
  ExpectGradientsMatch(*prior, {nullptr}, {s.bg.data()});
  // Near-level attitudes (the yaw of a body x axis pointing up is undefined), yaws across the
  // ±π branch cut of atan2, the prior within 0.5 rad of the state: GradientChecker's Ridders
  // steps start at 1 % of each coordinate, and a residual angle within that of ±π would jump by
  // 2π inside its difference quotients (the residual itself is continuous there).
  for (int trial = 0; trial < 6; ++trial) {
    const double yaw = (trial % 2 == 0 ? kPi - 0.02 : -kPi + 0.02) + 0.7 * (trial / 2 - 1);
    s.q =
        Coeffs(QuaternionExp(Eigen::Vector3d(0, 0, yaw)) * QuaternionExp(RandomVector(&rng, 0.3)));
    std::unique_ptr<ceres::CostFunction> gauge(InsPriorFactor::Create(
        Eigen::Vector3d(1, 2, 0), Eigen::Vector3d(0.5, 0.5, 0.01), yaw + 0.4 - 0.15 * trial, 0.05));
    // 1e-3: Ridders' differences of atan2 of a 4-vector reach ≈ 1e-4 here; the exact yaw
    // column (a nav-frame rotation δ_z turns the yaw by δ_z at any tilt) is checked below.
    ExpectGradientsMatch(*gauge, {nullptr, &m}, {s.p.data(), s.q.data()}, 1e-3);
    double r[4], jp[12], jq[16], lift[12];
    double* params[2] = {s.p.data(), s.q.data()};
    double* jac[2] = {jp, jq};
    ASSERT_TRUE(gauge->Evaluate(params, r, jac));
    ASSERT_TRUE(m.PlusJacobian(s.q.data(), lift));
    double dyaw_dz = 0.0;  // row 3 of J_q (row-major 4×4) times column 2 of the 4×3 lift
    for (int k = 0; k < 4; ++k) dyaw_dz += jq[3 * 4 + k] * lift[k * 3 + 2];
    EXPECT_NEAR(dyaw_dz, 1.0 / 0.05, 1e-9);
  }
}

TEST(InsFactors, ResidualValues) {
  double v[3] = {0.01, -0.02, 0.0}, r3[3];
  ZuptFactor zupt(0.01);
  ASSERT_TRUE(zupt(v, r3));
  EXPECT_DOUBLE_EQ(r3[0], 1.0);
  EXPECT_DOUBLE_EQ(r3[1], -2.0);
  ZaruFactor zaru(Eigen::Vector3d(0.003, 0, 0), 0.001);
  double bg[3] = {0.001, 0.0, 0.0};
  ASSERT_TRUE(zaru(bg, r3));
  EXPECT_NEAR(r3[0], 2.0, 1e-12);
  BiasRandomWalkFactor rw(1e-4, 4.0);  // σ = 2e-4 over 4 s
  double b1[3] = {0, 0, 0}, b2[3] = {4e-4, 0, 0};
  ASSERT_TRUE(rw(b1, b2, r3));
  EXPECT_NEAR(r3[0], 2.0, 1e-9);
  // The yaw residual is wrapped: ψ̄ = π − 0.1, ψ = −π + 0.1 differ by 0.2 rad.
  InsPriorFactor gauge(Eigen::Vector3d::Zero(), Eigen::Vector3d::Ones(), kPi - 0.1, 0.1);
  const std::array<double, 4> q =
      Coeffs(Eigen::Quaterniond(Eigen::AngleAxisd(-kPi + 0.1, Eigen::Vector3d::UnitZ())));
  double p[3] = {0, 0, 0}, r4[4];
  ASSERT_TRUE(gauge(p, q.data(), r4));
  EXPECT_NEAR(r4[3], 2.0, 1e-9);
}

// Across an IMU gap: the reach bound is zero inside the reach and the excess distance / σ
// beyond it; the magnetic tie is the yaw between the field's horizontal directions at the two
// states (any tilt, any field dip), so turning b by δ about the vertical moves it by δ / σ.
TEST(InsFactors, GapReachAndMagneticHeadingResiduals) {
  GapReachFactor reach(10.0, 0.5);
  double pa[3] = {1, 2, 0}, pb[3] = {1 + 6, 2 + 8, 3}, r = -1.0;  // 10 m away (z ignored)
  ASSERT_TRUE(reach(pa, pb, &r));
  EXPECT_EQ(r, 0.0);
  pb[0] = 1 + 9;  // √(81 + 64) m
  ASSERT_TRUE(reach(pa, pb, &r));
  EXPECT_NEAR(r, (std::sqrt(145.0) - 10.0) / 0.5, 1e-12);
  pb[0] = 1, pb[1] = 2;  // the same point: inside, no NaN
  ASSERT_TRUE(reach(pa, pb, &r));
  EXPECT_EQ(r, 0.0);

  std::mt19937_64 rng(11);
  const Eigen::Vector3d field_n(18.0, 7.0, -40.0);  // µT, dip ~64°
  for (int trial = 0; trial < 8; ++trial) {
    const Eigen::Quaterniond qa = RandomRotation(&rng), qb = RandomRotation(&rng);
    const double delta = -3.0 + 0.8 * trial;  // past ±π too: the residual wraps
    const Eigen::Quaterniond turn(Eigen::AngleAxisd(delta, Eigen::Vector3d::UnitZ()));
    // Readings of the same field at both states; b's read as if b were turned by −δ.
    MagneticHeadingChangeFactor f(qa.conjugate() * field_n, (turn * qb).conjugate() * field_n, 0.1);
    const std::array<double, 4> ca = Coeffs(qa), cb = Coeffs(qb), cb_turned = Coeffs(turn * qb);
    ASSERT_TRUE(f(ca.data(), cb_turned.data(), &r));
    EXPECT_NEAR(r, 0.0, 1e-9);
    ASSERT_TRUE(f(ca.data(), cb.data(), &r));
    EXPECT_NEAR(r, NormalizeAngle(-delta) / 0.1, 1e-9) << delta;
  }
}

// The stance factor: zero when the reading, rotated by the state's attitude, points along ψ_f;
// the angle from ψ_f to it otherwise, wrapped, whatever the tilt.
TEST(InsFactors, StanceMagneticHeadingResidual) {
  std::mt19937_64 rng(13);
  const Eigen::Vector3d field_n(18.0, 7.0, -40.0);  // µT, navigation frame
  const double field_yaw = std::atan2(7.0, 18.0);
  for (int trial = 0; trial < 8; ++trial) {
    const Eigen::Quaterniond q = RandomRotation(&rng);
    MagneticHeadingFactor f(q.conjugate() * field_n, 0.05);  // the reading at attitude q
    const std::array<double, 4> c = Coeffs(q);
    double r = -1.0, psi = field_yaw;
    ASSERT_TRUE(f(c.data(), &psi, &r));
    EXPECT_NEAR(r, 0.0, 1e-9);
    const double delta = -3.0 + 0.8 * trial;  // past ±π too: the residual wraps
    psi = field_yaw + delta;
    ASSERT_TRUE(f(c.data(), &psi, &r));
    EXPECT_NEAR(r, NormalizeAngle(-delta) / 0.05, 1e-9) << delta;
    // The state turned by δ about the vertical: the reading's direction turns by δ.
    const Eigen::Quaterniond turned =
        Eigen::Quaterniond(Eigen::AngleAxisd(delta, Eigen::Vector3d::UnitZ())) * q;
    const std::array<double, 4> ct = Coeffs(turned);
    psi = field_yaw;
    ASSERT_TRUE(f(ct.data(), &psi, &r));
    EXPECT_NEAR(r, NormalizeAngle(delta) / 0.05, 1e-9) << delta;
  }
}

// The levelling factor: zero when the reading less the bias is gravity seen from the state's
// attitude (any yaw: a turn about the vertical leaves it unchanged); a tilt δ about the body
// x axis moves the reading's y component by g·sin δ; its gradients match numeric ones.
TEST(InsFactors, StanceLevelResidualAndGradients) {
  std::mt19937_64 rng(14);
  NavQuaternionManifold m;
  for (int trial = 0; trial < 6; ++trial) {
    const Eigen::Quaterniond q = RandomRotation(&rng);
    const Eigen::Vector3d ba = RandomVector(&rng, 0.05);
    const Eigen::Vector3d f = q.conjugate() * Eigen::Vector3d(0, 0, kG) + ba;
    StanceLevelFactor factor(f, kG, 0.01);
    std::array<double, 4> c = Coeffs(q);
    std::array<double, 3> b = {ba[0], ba[1], ba[2]};
    double r[3];
    ASSERT_TRUE(factor(c.data(), b.data(), r));
    for (double v : r) EXPECT_NEAR(v, 0.0, 1e-9);
    const std::array<double, 4> turned =
        Coeffs(Eigen::Quaterniond(Eigen::AngleAxisd(0.3 + trial, Eigen::Vector3d::UnitZ())) * q);
    ASSERT_TRUE(factor(turned.data(), b.data(), r));
    for (double v : r) EXPECT_NEAR(v, 0.0, 1e-9);
    // Compared in absolute terms: the yaw column is exactly zero, and GradientChecker's relative
    // error of two round-off values there (1e-14 against -3e-15) fails it.
    std::unique_ptr<ceres::CostFunction> cost(StanceLevelFactor::Create(f, kG, 0.01));
    const std::vector<const ceres::Manifold*> manifolds = {&m, nullptr};
    ceres::GradientChecker checker(cost.get(), &manifolds, ceres::NumericDiffOptions());
    ceres::GradientChecker::ProbeResults results;
    std::vector<double*> blocks = {c.data(), b.data()};
    checker.Probe(blocks.data(), 1e-6, &results);
    for (size_t k = 0; k < 2; ++k) {
      const Eigen::MatrixXd& a = results.local_jacobians[k];
      const Eigen::MatrixXd& n = results.local_numeric_jacobians[k];
      EXPECT_LT((a - n).cwiseAbs().maxCoeff(), 1e-6 * a.cwiseAbs().maxCoeff()) << k;
    }
  }
  // Level, then rolled by δ about body x: R(q)ᵀ·(0, 0, g) = (0, g sin δ, g cos δ).
  const double delta = 0.02;
  StanceLevelFactor level(Eigen::Vector3d(0, 0, kG), kG, 0.01);
  const std::array<double, 4> rolled =
      Coeffs(Eigen::Quaterniond(Eigen::AngleAxisd(delta, Eigen::Vector3d::UnitX())));
  double b0[3] = {0, 0, 0}, r[3];
  ASSERT_TRUE(level(rolled.data(), b0, r));
  EXPECT_NEAR(r[0], 0.0, 1e-12);
  EXPECT_NEAR(r[1], kG * std::sin(delta) / 0.01, 1e-9);
  EXPECT_NEAR(r[2], kG * (std::cos(delta) - 1.0) / 0.01, 1e-9);
}

TEST(InsFactorGradients, GapFactors) {
  std::mt19937_64 rng(12);
  NavQuaternionManifold m;
  std::unique_ptr<ceres::CostFunction> reach(GapReachFactor::Create(2.0, 0.3));
  for (int trial = 0; trial < 4; ++trial) {
    State a, b;
    for (int i = 0; i < 3; ++i) {
      a.p[i] = RandomVector(&rng, 1.0)[i];
      b.p[i] = a.p[i] + RandomVector(&rng, 3.0)[i];
    }
    double d = std::hypot(b.p[0] - a.p[0], b.p[1] - a.p[1]);
    if (std::fabs(d - 2.0) < 0.1) continue;  // the kink, where no difference quotient holds
    ExpectGradientsMatch(*reach, {nullptr, nullptr}, {a.p.data(), b.p.data()});
    // Any yaw, tilts of a foot (within ~0.3 rad): at large tilts the field's horizontal part
    // shrinks and the angle curves too fast for the difference quotients.
    auto attitude = [&rng](double yaw) {
      const Eigen::Vector3d tilt = RandomVector(&rng, 0.15);
      return QuaternionExp(Eigen::Vector3d(0, 0, yaw)) *
             QuaternionExp(Eigen::Vector3d(tilt.x(), tilt.y(), 0));
    };
    a.q = Coeffs(attitude(-2.0 + 1.1 * trial));
    b.q = Coeffs(attitude(0.5 + 0.9 * trial));
    std::unique_ptr<ceres::CostFunction> mag(MagneticHeadingChangeFactor::Create(
        Eigen::Vector3d(20, -5, -35), Eigen::Vector3d(-10, 15, -38), 0.05));
    // GradientChecker's default difference quotients miss this atan2 by up to 10 % (measured);
    // central differences on the manifold (Plus by ±1e-6 along each tangent axis) agree with
    // the autodiff Jacobian lifted by PlusJacobian to 1e-6.
    double r0, ja[4], jb[4], lift[12];
    double* blocks[2] = {a.q.data(), b.q.data()};
    double* jac[2] = {ja, jb};
    ASSERT_TRUE(mag->Evaluate(blocks, &r0, jac));
    for (int blk = 0; blk < 2; ++blk) {
      double* q = blocks[blk];
      ASSERT_TRUE(m.PlusJacobian(q, lift));
      for (int c = 0; c < 3; ++c) {
        double analytic = 0.0;
        for (int k = 0; k < 4; ++k) analytic += jac[blk][k] * lift[k * 3 + c];
        double delta[3] = {0, 0, 0}, plus[4], minus[4], r_plus, r_minus;
        delta[c] = 1e-6;
        ASSERT_TRUE(m.Plus(q, delta, plus));
        delta[c] = -1e-6;
        ASSERT_TRUE(m.Plus(q, delta, minus));
        double* bp[2] = {blocks[0], blocks[1]};
        bp[blk] = plus;
        ASSERT_TRUE(mag->Evaluate(bp, &r_plus, nullptr));
        bp[blk] = minus;
        ASSERT_TRUE(mag->Evaluate(bp, &r_minus, nullptr));
        EXPECT_NEAR(analytic, (r_plus - r_minus) / 2e-6, 1e-6 * (1.0 + std::fabs(analytic)))
            << "block " << blk << " axis " << c;
      }
    }
  }
}

}  // namespace
}  // namespace walkgraph
