#include "walkgraph/kalman.h"

#include <cmath>
#include <map>
#include <random>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <Eigen/Dense>

namespace walkgraph {
namespace {

TEST(ChiSquareQuantileTest, MatchesTabulatedValues) {
  // Reference values from standard chi-square tables (e.g. NIST/SEMATECH handbook).
  EXPECT_NEAR(ChiSquareQuantile(0.95, 1), 3.841458820694124, 1e-9);
  EXPECT_NEAR(ChiSquareQuantile(0.95, 2), 5.991464547107979, 1e-9);
  EXPECT_NEAR(ChiSquareQuantile(0.99, 2), 9.210340371976183, 1e-9);
  EXPECT_NEAR(ChiSquareQuantile(0.95, 3), 7.814727903251178, 1e-9);
  EXPECT_NEAR(ChiSquareQuantile(0.999, 4), 18.46682695290317, 1e-8);
  EXPECT_NEAR(ChiSquareQuantile(0.05, 2), 0.1025865887751011, 1e-10);
  // dof = 2 has the closed form −2 ln(1 − p).
  EXPECT_NEAR(ChiSquareQuantile(0.7, 2), -2.0 * std::log(0.3), 1e-10);
  EXPECT_TRUE(std::isnan(ChiSquareQuantile(1.0, 2)));
  EXPECT_TRUE(std::isnan(ChiSquareQuantile(0.5, 0)));
}

TEST(KalmanUpdateTest, JosephFormEqualsStandardFormAtOptimalGain) {
  Eigen::VectorXd x(3);
  x << 1.0, -2.0, 0.5;
  Eigen::MatrixXd A(3, 3);
  A << 2.0, 0.3, 0.1, 0.3, 1.0, -0.2, 0.1, -0.2, 0.5;
  Eigen::MatrixXd P = A * A.transpose();
  Eigen::MatrixXd H(2, 3);
  H << 1.0, 0.0, 0.5, 0.0, 1.0, -1.0;
  Eigen::MatrixXd R = Eigen::Vector2d(0.4, 0.9).asDiagonal();
  Eigen::VectorXd nu = Eigen::Vector2d(0.7, -0.3);

  const Eigen::MatrixXd S = H * P * H.transpose() + R;
  const Eigen::MatrixXd K = P * H.transpose() * S.inverse();
  const Eigen::VectorXd x_expected = x + K * nu;
  const Eigen::MatrixXd P_expected = (Eigen::MatrixXd::Identity(3, 3) - K * H) * P;
  const double nis_expected = nu.dot(S.inverse() * nu);

  auto out = KalmanUpdate(nu, H, R, 0.0, &x, &P);
  ASSERT_TRUE(out.ok()) << out.status().message();
  EXPECT_TRUE(out->accepted);
  EXPECT_NEAR(out->nis, nis_expected, 1e-12);
  EXPECT_LT((x - x_expected).norm(), 1e-12);
  EXPECT_LT((P - P_expected).norm(), 1e-12);
  EXPECT_EQ(P, P.transpose());
}

TEST(KalmanUpdateTest, GateRejectsOutlierAtChiSquareQuantile) {
  Eigen::VectorXd x = Eigen::Vector2d::Zero();
  Eigen::MatrixXd P = Eigen::Matrix2d::Identity();
  const Eigen::MatrixXd H = Eigen::Matrix2d::Identity();
  const Eigen::MatrixXd R = Eigen::Matrix2d::Identity();
  // S = 2 I; NIS = |ν|²/2. The 95 % gate for 2 dof is 5.991: |ν|² = 12.2 fails, 11.8 passes.
  auto rejected = KalmanUpdate(Eigen::Vector2d(std::sqrt(12.2), 0.0), H, R, 0.95, &x, &P);
  ASSERT_TRUE(rejected.ok());
  EXPECT_FALSE(rejected->accepted);
  EXPECT_NEAR(rejected->nis, 6.1, 1e-12);
  EXPECT_EQ(x, Eigen::VectorXd(Eigen::Vector2d::Zero()));
  auto accepted = KalmanUpdate(Eigen::Vector2d(std::sqrt(11.8), 0.0), H, R, 0.95, &x, &P);
  ASSERT_TRUE(accepted.ok());
  EXPECT_TRUE(accepted->accepted);
  EXPECT_NEAR(x[0], 0.5 * std::sqrt(11.8), 1e-12);
}

TEST(KalmanUpdateTest, ReportsSizeMismatchAndIndefiniteS) {
  Eigen::VectorXd x = Eigen::Vector2d::Zero();
  Eigen::MatrixXd P = Eigen::Matrix2d::Identity();
  EXPECT_FALSE(KalmanUpdate(Eigen::Vector3d::Zero(), Eigen::Matrix2d::Identity(),
                            Eigen::Matrix2d::Identity(), 0.0, &x, &P)
                   .ok());
  EXPECT_FALSE(KalmanUpdate(Eigen::Vector2d::Zero(), Eigen::Matrix2d::Identity(),
                            -3.0 * Eigen::Matrix2d::Identity(), 0.0, &x, &P)
                   .ok());
}

// The key test: on a linear-Gaussian problem the KF + RTS smoother equals the batch
// least-squares (MAP) solution over all states.
TEST(RtsSmoothTest, EqualsBatchLeastSquaresOnLinearGaussianProblem) {
  std::mt19937_64 rng(42);
  std::normal_distribution<double> n01(0.0, 1.0);
  const int N = 30, n = 4;  // constant-velocity model, state [x y vx vy]
  const double dt = 0.5;
  Eigen::MatrixXd F = Eigen::MatrixXd::Identity(n, n);
  F(0, 2) = F(1, 3) = dt;
  Eigen::MatrixXd Q = 0.05 * Eigen::MatrixXd::Identity(n, n);
  Q(0, 2) = Q(2, 0) = Q(1, 3) = Q(3, 1) = 0.01;
  Eigen::MatrixXd H = Eigen::MatrixXd::Zero(2, n);
  H(0, 0) = H(1, 1) = 1.0;
  const Eigen::MatrixXd R = Eigen::Vector2d(0.8, 1.3).asDiagonal();
  Eigen::VectorXd x0(n);
  x0 << 1.0, 2.0, 0.5, -0.2;
  const Eigen::MatrixXd P0 = Eigen::Vector4d(1.0, 1.0, 0.3, 0.3).asDiagonal();
  std::vector<Eigen::VectorXd> u(N, Eigen::VectorXd::Zero(n)), z(N);
  std::vector<bool> has_z(N);
  Eigen::VectorXd truth = x0;
  for (int k = 0; k < N; ++k) {
    if (k > 0) {
      u[k] << 0.01 * k, -0.02, 0.0, 0.01;
      truth = F * truth + u[k] + 0.2 * Eigen::Vector4d(n01(rng), n01(rng), n01(rng), n01(rng));
    }
    has_z[k] = (k % 3 != 1);  // some epochs without a measurement
    z[k] = H * truth + Eigen::Vector2d(n01(rng), n01(rng));
  }

  std::vector<FilterEpoch> epochs;
  Eigen::VectorXd x = x0;
  Eigen::MatrixXd P = P0;
  for (int k = 0; k < N; ++k) {
    FilterEpoch e;
    e.t_s = k * dt;
    if (k > 0) {
      x = F * x + u[k];
      P = F * P * F.transpose() + Q;
      e.F = F;
    }
    e.x_prior = x;
    e.P_prior = P;
    if (has_z[k]) ASSERT_TRUE(KalmanUpdate(z[k] - H * x, H, R, 0.0, &x, &P).ok());
    e.x_post = x;
    e.P_post = P;
    epochs.push_back(e);
  }
  auto smoothed = RtsSmooth(epochs);
  ASSERT_TRUE(smoothed.ok()) << smoothed.status().message();

  // Batch: minimize |x_0 − x̄0|²_P0 + Σ|x_k − F x_{k−1} − u_k|²_Q + Σ|z_k − H x_k|²_R.
  Eigen::MatrixXd Lam = Eigen::MatrixXd::Zero(N * n, N * n);
  Eigen::VectorXd eta = Eigen::VectorXd::Zero(N * n);
  auto add = [&](const Eigen::MatrixXd& J, const Eigen::VectorXd& r, const Eigen::MatrixXd& W,
                 const std::vector<int>& blocks) {
    // Residual r − J·[x_blocks]; J is split column-wise over blocks of size n.
    for (size_t a = 0; a < blocks.size(); ++a) {
      eta.segment(blocks[a] * n, n) += J.middleCols(a * n, n).transpose() * W * r;
      for (size_t b = 0; b < blocks.size(); ++b) {
        Lam.block(blocks[a] * n, blocks[b] * n, n, n) +=
            J.middleCols(a * n, n).transpose() * W * J.middleCols(b * n, n);
      }
    }
  };
  add(Eigen::MatrixXd::Identity(n, n), x0, P0.inverse(), {0});
  for (int k = 1; k < N; ++k) {
    Eigen::MatrixXd J(n, 2 * n);
    J << -F, Eigen::MatrixXd::Identity(n, n);
    add(J, u[k], Q.inverse(), {k - 1, k});
  }
  for (int k = 0; k < N; ++k) {
    if (has_z[k]) add(H, z[k], R.inverse(), {k});
  }
  const Eigen::VectorXd batch = Lam.ldlt().solve(eta);
  const Eigen::MatrixXd batch_cov = Lam.inverse();
  for (int k = 0; k < N; ++k) {
    EXPECT_LT(((*smoothed)[k].x - batch.segment(k * n, n)).cwiseAbs().maxCoeff(), 1e-6) << k;
    EXPECT_LT(((*smoothed)[k].P - batch_cov.block(k * n, k * n, n, n)).cwiseAbs().maxCoeff(), 1e-6)
        << k;
  }
  // The last smoothed state is the filter's posterior, earlier ones differ from it.
  EXPECT_LT(((*smoothed)[0].x - epochs[0].x_post).norm(), 10.0);
  EXPECT_GT(((*smoothed)[0].x - epochs[0].x_post).norm(), 1e-3);
}

TEST(RtsSmoothTest, WrapsAngleDifferences) {
  // Scalar angle state near ±π: the smoothed value must stay near π, not jump through 0.
  std::vector<FilterEpoch> epochs(2);
  for (FilterEpoch& e : epochs) {
    e.x_prior = e.x_post = Eigen::VectorXd::Constant(1, 3.1);
    e.P_prior = e.P_post = Eigen::MatrixXd::Constant(1, 1, 0.1);
    e.F = Eigen::MatrixXd::Identity(1, 1);
  }
  epochs[1].x_prior[0] = 3.1;
  epochs[1].P_prior(0, 0) = 0.2;
  epochs[1].x_post[0] = -3.1;  // 0.083 rad past π
  epochs[1].P_post(0, 0) = 0.05;
  auto s = RtsSmooth(epochs, {0});
  ASSERT_TRUE(s.ok());
  // C = 0.1/0.2 = 0.5; x_0|N = 3.1 + 0.5·wrap(−3.1 − 3.1) = 3.1 + 0.5·0.0832 → wrapped.
  EXPECT_NEAR(std::abs((*s)[0].x[0]), 3.1 + 0.5 * (2 * M_PI - 6.2), 1e-12);
  EXPECT_FALSE(RtsSmooth({}).ok());
}

TEST(KalmanUpdateTest, RecordOutcomeKeepsAcceptedNisAndCountsGated) {
  std::vector<double> nis;
  std::map<std::string, double> diagnostics;
  UpdateOutcome accepted;
  accepted.accepted = true;
  accepted.nis = 2.5;
  UpdateOutcome gated;
  gated.nis = 40.0;
  RecordOutcome(accepted, &nis, &diagnostics);
  RecordOutcome(gated, &nis, &diagnostics);
  RecordOutcome(gated, &nis, &diagnostics);
  ASSERT_EQ(nis.size(), 1u);
  EXPECT_EQ(nis[0], 2.5);
  EXPECT_EQ(diagnostics.at("gated_updates"), 2.0);
}

// Stochastic cloning: a filter that records an epoch only every third step (with several
// updates in between) and carries a clone of its state at the last epoch gives, through
// FilterEpoch::P_cross, the same smoothed states at its epochs as the textbook RTS over every
// step.
TEST(RtsSmoothTest, ClonedCrossCovarianceEqualsFullRateRts) {
  const double q = 0.5, r = 1.0;
  const std::vector<double> z = {0.3, 0.9, 1.4, 1.1, 2.0, 2.6, 2.2, 3.1, 3.9, 3.5, 4.4, 5.0};
  const Eigen::MatrixXd H_full = Eigen::MatrixXd::Identity(1, 1);
  const Eigen::MatrixXd R = Eigen::MatrixXd::Constant(1, 1, r);
  // Full rate: an epoch at every step.
  std::vector<FilterEpoch> full;
  Eigen::VectorXd x = Eigen::VectorXd::Zero(1);
  Eigen::MatrixXd P = Eigen::MatrixXd::Constant(1, 1, 4.0);
  // Cloned: state [x_now; x_clone].
  Eigen::VectorXd xa = Eigen::VectorXd::Zero(2);
  Eigen::MatrixXd Pa = Eigen::MatrixXd::Constant(2, 2, 4.0);
  Eigen::MatrixXd H_aug = Eigen::MatrixXd::Zero(1, 2);
  H_aug(0, 0) = 1.0;
  std::vector<FilterEpoch> cloned;
  std::vector<size_t> cloned_steps;
  for (size_t k = 0; k < z.size(); ++k) {
    FilterEpoch e;
    e.t_s = static_cast<double>(k);
    e.F = Eigen::MatrixXd::Identity(1, 1);
    if (k > 0) {
      P(0, 0) += q;
      Pa(0, 0) += q;
    }
    e.x_prior = x;
    e.P_prior = P;
    Eigen::VectorXd nu = Eigen::VectorXd::Constant(1, z[k] - x[0]);
    ASSERT_TRUE(KalmanUpdate(nu, H_full, R, 0.0, &x, &P).ok());
    e.x_post = x;
    e.P_post = P;
    full.push_back(e);
    nu = Eigen::VectorXd::Constant(1, z[k] - xa[0]);
    ASSERT_TRUE(KalmanUpdate(nu, H_aug, R, 0.0, &xa, &Pa).ok());
    if (k % 3 != 0 && k + 1 != z.size()) continue;
    FilterEpoch c;
    c.t_s = e.t_s;
    c.x_prior = c.x_post = xa.head(1);
    c.P_prior = c.P_post = Pa.topLeftCorner(1, 1);
    if (!cloned.empty()) {
      cloned.back().x_post = xa.tail(1);  // x_{j|k}
      cloned.back().P_post = Pa.bottomRightCorner(1, 1);
      c.P_cross = Pa.topRightCorner(1, 1);  // Cov(x_k, x_j)
    }
    cloned.push_back(c);
    cloned_steps.push_back(k);
    xa[1] = xa[0];  // new clone
    Pa.col(1) = Pa.col(0);
    Pa.row(1) = Pa.row(0);
  }
  auto a = RtsSmooth(full);
  auto b = RtsSmooth(cloned);
  ASSERT_TRUE(a.ok() && b.ok());
  ASSERT_EQ(b->size(), 5u);
  for (size_t i = 0; i < cloned_steps.size(); ++i) {
    const SmoothedState& s = (*a)[cloned_steps[i]];
    EXPECT_NEAR((*b)[i].x[0], s.x[0], 1e-12) << i;
    EXPECT_NEAR((*b)[i].P(0, 0), s.P(0, 0), 1e-12) << i;
  }
  // The smoother changed the cloned filter's earlier estimates (the test is not vacuous).
  EXPECT_GT(std::fabs((*b)[1].x[0] - cloned[1].x_prior[0]), 1e-3);
  cloned.back().P_cross = Eigen::MatrixXd::Zero(2, 2);  // wrong size
  EXPECT_FALSE(RtsSmooth(cloned).ok());
}

}  // namespace
}  // namespace walkgraph
