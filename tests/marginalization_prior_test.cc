// factors/marginalization_prior.h, the one hand-written Jacobian: its Jacobians against central
// differences (ceres::GradientChecker) and its residual r₀ + J₀·(x ⊟ x_lin).
#include "factors/marginalization_prior.h"

#include <cmath>
#include <vector>

#include <ceres/gradient_checker.h>
#include <ceres/manifold.h>
#include <gtest/gtest.h>
#include <Eigen/Geometry>

#include "factors/angle_manifold.h"
#include "factors/nav_quaternion_manifold.h"
#include "walkgraph/angle.h"

namespace walkgraph {
namespace {

// A prior over three blocks: a Euclidean 2-vector, a heading (AngleManifold) and a quaternion
// (NavQuaternionManifold, 4 ambient, 3 tangent): J₀ is 5 × 6, dense and full-rank.
struct Prior {
  AngleManifold angle;
  NavQuaternionManifold quaternion;
  std::vector<double> p_lin = {1.0, -2.0};
  std::vector<double> yaw_lin = {3.0};
  std::vector<double> q_lin;
  Eigen::MatrixXd j0 = Eigen::MatrixXd(5, 6);
  Eigen::VectorXd r0 = Eigen::VectorXd(5);

  Prior() {
    const Eigen::Quaterniond q(Eigen::AngleAxisd(0.4, Eigen::Vector3d(1, 2, 3).normalized()));
    q_lin = {q.x(), q.y(), q.z(), q.w()};
    for (int i = 0; i < j0.rows(); ++i) {
      for (int k = 0; k < j0.cols(); ++k) j0(i, k) = std::sin(1.0 + 3.0 * i + 7.0 * k);
    }
    r0 << 0.1, -0.2, 0.3, 0.05, -0.4;
  }
  MarginalizationPrior Make() const {
    return MarginalizationPrior({{p_lin, nullptr}, {yaw_lin, &angle}, {q_lin, &quaternion}}, j0,
                                r0);
  }
  std::vector<const ceres::Manifold*> Manifolds() const { return {nullptr, &angle, &quaternion}; }
};

bool GradientsMatch(const ceres::CostFunction& f, std::vector<const ceres::Manifold*> manifolds,
                    std::vector<const double*> blocks, double precision) {
  ceres::NumericDiffOptions numeric;
  ceres::GradientChecker checker(&f, &manifolds, numeric);
  ceres::GradientChecker::ProbeResults results;
  const bool ok = checker.Probe(blocks.data(), precision, &results);
  EXPECT_TRUE(ok) << results.error_log;
  return ok;
}

TEST(MarginalizationPrior, JacobiansMatchCentralDifferencesAtTheLinearizationPoint) {
  const Prior p;
  const MarginalizationPrior f = p.Make();
  EXPECT_TRUE(
      GradientsMatch(f, p.Manifolds(), {p.p_lin.data(), p.yaw_lin.data(), p.q_lin.data()}, 1e-7));
}

// Away from x_lin the Euclidean and angle blocks are linear in x (x ⊟ x_lin = x − x_lin, wrapped
// for the angle), so their Jacobian is exact anywhere, also across the ±π seam.
TEST(MarginalizationPrior, EuclideanAndAngleJacobiansMatchAwayFromTheLinearizationPoint) {
  AngleManifold angle;
  const std::vector<double> p_lin = {1.0, -2.0}, yaw_lin = {3.0};
  Eigen::MatrixXd j0(2, 3);
  j0 << 1.0, 2.0, -0.5, 0.3, -1.5, 4.0;
  const MarginalizationPrior f({{p_lin, nullptr}, {yaw_lin, &angle}}, j0, Eigen::Vector2d(1, -1));
  const double p[] = {1.7, -3.1}, yaw[] = {-3.0};  // yaw 0.28 rad past +π from yaw_lin
  EXPECT_TRUE(GradientsMatch(f, {nullptr, &angle}, {p, yaw}, 1e-7));
}

// The quaternion block holds J₀ at the first estimate: at an attitude δ away from q_lin the true
// tangent Jacobian is J₀·J_l⁻¹(δ) = J₀·(I + [δ]×/2 + O(δ²)), so the two differ by about
// |δ|/2·|J₀| (entry-wise below |δ|) while the Euclidean and angle blocks stay exact.
TEST(MarginalizationPrior, QuaternionJacobianIsTheFirstEstimateOneCloseToTheLinearizationPoint) {
  const Prior p;
  const MarginalizationPrior f = p.Make();
  const Eigen::Quaterniond q_lin(p.q_lin[3], p.q_lin[0], p.q_lin[1], p.q_lin[2]);
  const double angle = 1e-4;
  const Eigen::Quaterniond q =
      Eigen::Quaterniond(Eigen::AngleAxisd(angle, Eigen::Vector3d::UnitY())) * q_lin;
  const double quat[] = {q.x(), q.y(), q.z(), q.w()};
  const double pos[] = {1.3, -2.2}, yaw[] = {3.1};
  std::vector<const double*> blocks = {pos, yaw, quat};
  const std::vector<const ceres::Manifold*> manifolds = p.Manifolds();
  ceres::NumericDiffOptions numeric;
  ceres::GradientChecker checker(&f, &manifolds, numeric);
  ceres::GradientChecker::ProbeResults results;
  checker.Probe(blocks.data(), 1e-7, &results);
  ASSERT_EQ(results.local_jacobians.size(), 3u);
  for (int b = 0; b < 2; ++b) {
    EXPECT_LT(
        (results.local_jacobians[b] - results.local_numeric_jacobians[b]).cwiseAbs().maxCoeff(),
        1e-8)
        << "block " << b;
  }
  const double quaternion_error =
      (results.local_jacobians[2] - results.local_numeric_jacobians[2]).cwiseAbs().maxCoeff();
  EXPECT_LT(quaternion_error, angle);
  EXPECT_GT(quaternion_error,
            1e-3 * angle);  // it is the first-estimate Jacobian, not the exact one
}

TEST(MarginalizationPrior, ResidualIsR0PlusJ0TimesTheTangentDifference) {
  const Prior p;
  const MarginalizationPrior f = p.Make();
  ASSERT_EQ(f.num_residuals(), 5);
  ASSERT_EQ(f.parameter_block_sizes(), (std::vector<int32_t>{2, 1, 4}));
  const Eigen::Quaterniond q_lin(p.q_lin[3], p.q_lin[0], p.q_lin[1], p.q_lin[2]);
  const Eigen::Vector3d dtheta(0.02, -0.01, 0.03);
  const Eigen::Quaterniond q =
      Eigen::Quaterniond(Eigen::AngleAxisd(dtheta.norm(), dtheta.normalized())) * q_lin;
  const double pos[] = {1.5, -2.25}, yaw[] = {-3.0}, quat[] = {q.x(), q.y(), q.z(), q.w()};
  const double* blocks[] = {pos, yaw, quat};
  Eigen::VectorXd r(5);
  ASSERT_TRUE(f.Evaluate(blocks, r.data(), nullptr));
  Eigen::VectorXd delta(6);
  delta << 0.5, -0.25, NormalizeAngle(-3.0 - 3.0), dtheta;
  const Eigen::VectorXd expected = p.r0 + p.j0 * delta;
  for (int i = 0; i < 5; ++i) EXPECT_NEAR(r[i], expected[i], 1e-9) << "residual " << i;

  const double* at_lin[] = {p.p_lin.data(), p.yaw_lin.data(), p.q_lin.data()};
  ASSERT_TRUE(f.Evaluate(at_lin, r.data(), nullptr));
  for (int i = 0; i < 5; ++i) EXPECT_NEAR(r[i], p.r0[i], 1e-12) << "residual " << i;
}

}  // namespace
}  // namespace walkgraph
