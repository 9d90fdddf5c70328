// ChainMarginalCovariances (smoothers/chain_covariance.h) against ceres::Covariance on a small
// chain with a manifold block per state and static blocks that touch the whole chain.
#include "walkgraph/smoothers/chain_covariance.h"

#include <array>
#include <cmath>
#include <memory>
#include <random>
#include <vector>

#include <ceres/ceres.h>
#include <gtest/gtest.h>

#include "factors/angle_manifold.h"

namespace walkgraph {
namespace {

// p_{k+1} = p_k + d·(cos θ_k, sin θ_k), θ_{k+1} = θ_k + δ: an odometry step between two states.
struct Step {
  double d, delta, sigma_p, sigma_t;
  template <typename T>
  bool operator()(const T* p0, const T* t0, const T* p1, const T* t1, T* r) const {
    using std::cos;
    using std::sin;
    r[0] = (p1[0] - p0[0] - d * cos(t0[0])) / sigma_p;
    r[1] = (p1[1] - p0[1] - d * sin(t0[0])) / sigma_p;
    r[2] = (t1[0] - t0[0] - delta) / sigma_t;
    return true;
  }
};

// ρ = ‖p − a‖ + b + s·‖p − a‖: a range through two static blocks (bias b, scale s).
struct Range {
  double ax, ay, rho, sigma;
  template <typename T>
  bool operator()(const T* p, const T* b, const T* s, T* r) const {
    using std::sqrt;
    const T dx = p[0] - ax, dy = p[1] - ay;
    const T dist = sqrt(dx * dx + dy * dy);
    r[0] = (dist * (1.0 + s[0]) + b[0] - rho) / sigma;
    return true;
  }
};

struct Chain {
  static constexpr int kStates = 15;
  std::vector<std::array<double, 2>> p = std::vector<std::array<double, 2>>(kStates);
  std::vector<double> theta = std::vector<double>(kStates);
  double bias = 0.3, scale = 0.02;
  std::unique_ptr<ceres::Problem> problem;
  std::vector<std::vector<double*>> groups;
  std::vector<double*> statics;
  ceres::ResidualBlockId outlier = nullptr;  // a range whose reading is 40 σ off

  // `loss` on the ranges; an outlier reading on state 7 when `with_outlier`.
  explicit Chain(bool robust, bool with_outlier = false) {
    std::mt19937 rng(7);
    std::normal_distribution<double> n01(0.0, 1.0);
    ceres::Problem::Options po;
    po.manifold_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
    problem = std::make_unique<ceres::Problem>(po);
    for (int k = 0; k < kStates; ++k) {
      p[k] = {0.8 * k + 0.05 * n01(rng), 0.1 * std::sin(0.3 * k)};
      theta[k] = 0.1 * std::cos(0.2 * k);
      problem->AddParameterBlock(p[k].data(), 2);
      problem->AddParameterBlock(&theta[k], 1, &angle_);
      groups.push_back({p[k].data(), &theta[k]});
    }
    problem->AddParameterBlock(&bias, 1);
    problem->AddParameterBlock(&scale, 1);
    statics = {&bias, &scale};
    // Priors: the first state and the static blocks.
    problem->AddResidualBlock(new ceres::AutoDiffCostFunction<Prior2, 2, 2>(new Prior2{0.1}),
                              nullptr, p[0].data());
    problem->AddResidualBlock(new ceres::AutoDiffCostFunction<Prior1, 1, 1>(new Prior1{0.05}),
                              nullptr, &theta[0]);
    problem->AddResidualBlock(new ceres::AutoDiffCostFunction<Prior1, 1, 1>(new Prior1{2.0}),
                              nullptr, &bias);
    problem->AddResidualBlock(new ceres::AutoDiffCostFunction<Prior1, 1, 1>(new Prior1{0.1}),
                              nullptr, &scale);
    for (int k = 0; k + 1 < kStates; ++k) {
      problem->AddResidualBlock(new ceres::AutoDiffCostFunction<Step, 3, 2, 1, 2, 1>(
                                    new Step{0.8, 0.02 * n01(rng), 0.05, 0.02}),
                                nullptr, p[k].data(), &theta[k], p[k + 1].data(), &theta[k + 1]);
    }
    const double anchors[3][2] = {{0.0, 5.0}, {6.0, -4.0}, {12.0, 5.0}};
    for (int k = 0; k < kStates; ++k) {
      for (const auto& a : anchors) {
        const double d = std::hypot(p[k][0] - a[0], p[k][1] - a[1]);
        const double rho = d * (1.0 + scale) + bias + 0.3 * n01(rng);
        ceres::LossFunction* loss = robust ? new ceres::CauchyLoss(1.0) : nullptr;
        problem->AddResidualBlock(
            new ceres::AutoDiffCostFunction<Range, 1, 2, 1, 1>(new Range{a[0], a[1], rho, 0.5}),
            loss, p[k].data(), &bias, &scale);
      }
    }
    if (with_outlier) {
      const double d = std::hypot(p[7][0] - anchors[0][0], p[7][1] - anchors[0][1]);
      outlier =
          problem->AddResidualBlock(new ceres::AutoDiffCostFunction<Range, 1, 2, 1, 1>(
                                        new Range{anchors[0][0], anchors[0][1], d + 20.0, 0.5}),
                                    new ceres::CauchyLoss(1.0), p[7].data(), &bias, &scale);
    }
  }

  struct Prior1 {
    double sigma;
    template <typename T>
    bool operator()(const T* x, T* r) const {
      r[0] = x[0] / sigma;
      return true;
    }
  };
  struct Prior2 {
    double sigma;
    template <typename T>
    bool operator()(const T* x, T* r) const {
      r[0] = x[0] / sigma;
      r[1] = x[1] / sigma;
      return true;
    }
  };

  // ceres::Covariance of group k (position then heading), in the tangent space.
  Eigen::Matrix3d CeresCovariance(int k) {
    ceres::Covariance::Options o;
    o.algorithm_type = ceres::DENSE_SVD;
    ceres::Covariance cov(o);
    std::vector<std::pair<const double*, const double*>> pairs = {
        {p[k].data(), p[k].data()}, {p[k].data(), &theta[k]}, {&theta[k], &theta[k]}};
    EXPECT_TRUE(cov.Compute(pairs, problem.get()));
    double pp[4], pt[2], tt[1];
    cov.GetCovarianceBlockInTangentSpace(p[k].data(), p[k].data(), pp);
    cov.GetCovarianceBlockInTangentSpace(p[k].data(), &theta[k], pt);
    cov.GetCovarianceBlockInTangentSpace(&theta[k], &theta[k], tt);
    Eigen::Matrix3d c;
    c << pp[0], pp[1], pt[0], pp[2], pp[3], pt[1], pt[0], pt[1], tt[0];
    return c;
  }

 private:
  AngleManifold angle_;
};

TEST(ChainCovarianceTest, EqualsCeresCovarianceOnEveryState) {
  Chain c(/*robust=*/false);
  auto cov = ChainMarginalCovariances(c.problem.get(), c.groups, c.statics);
  ASSERT_TRUE(cov.ok()) << cov.status().message();
  ASSERT_EQ(cov->size(), c.groups.size());
  double worst = 0.0;
  for (int k = 0; k < Chain::kStates; ++k) {
    const Eigen::Matrix3d ref = c.CeresCovariance(k);
    ASSERT_EQ((*cov)[k].rows(), 3);
    worst = std::max(worst, ((*cov)[k] - ref).norm() / ref.norm());
  }
  EXPECT_LT(worst, 1e-9);
}

TEST(ChainCovarianceTest, WantedSelectsGroupsWithTheSameValues) {
  Chain c(false);
  auto all = ChainMarginalCovariances(c.problem.get(), c.groups, c.statics);
  std::vector<bool> wanted(c.groups.size(), false);
  wanted[0] = wanted[1] = true;
  auto some = ChainMarginalCovariances(c.problem.get(), c.groups, c.statics, kChainInlierSigma,
                                       kChainMaxBandwidth, wanted);
  ASSERT_TRUE(all.ok() && some.ok());
  EXPECT_EQ(((*some)[0] - (*all)[0]).norm(), 0.0);
  EXPECT_EQ(((*some)[1] - (*all)[1]).norm(), 0.0);
  for (size_t g = 2; g < c.groups.size(); ++g) EXPECT_EQ((*some)[g].size(), 0) << g;
  EXPECT_FALSE(ChainMarginalCovariances(c.problem.get(), c.groups, c.statics, kChainInlierSigma,
                                        kChainMaxBandwidth, std::vector<bool>(3, true))
                   .ok());
}

// Inliers of a robust loss count as plain Gaussian information; an outlier the loss discounted
// carries (almost) none: the covariance is the one without it.
TEST(ChainCovarianceTest, RobustInliersCountFullyAndOutliersHardlyAtAll) {
  Chain plain(false), robust(true, /*with_outlier=*/true);
  auto a = ChainMarginalCovariances(plain.problem.get(), plain.groups, plain.statics);
  auto b = ChainMarginalCovariances(robust.problem.get(), robust.groups, robust.statics);
  ASSERT_TRUE(a.ok() && b.ok());
  // The inlier readings are within 3 σ here, so only the outlier's weight differs (ρ′ ≈ 6e-4).
  const double r = 20.0 / 0.5;
  const double weight = 1.0 / (1.0 + r * r);
  for (int k = 0; k < Chain::kStates; ++k) {
    const double rel = ((*a)[k] - (*b)[k]).norm() / (*a)[k].norm();
    EXPECT_LT(rel, 10 * weight) << k;
  }
  // Removing the loss makes the outlier full information: a visibly smaller covariance at 7.
  robust.problem->RemoveResidualBlock(robust.outlier);
  const double d = std::hypot(robust.p[7][0], robust.p[7][1] - 5.0);
  robust.problem->AddResidualBlock(
      new ceres::AutoDiffCostFunction<Range, 1, 2, 1, 1>(new Range{0.0, 5.0, d + 20.0, 0.5}),
      nullptr, robust.p[7].data(), &robust.bias, &robust.scale);
  auto full = ChainMarginalCovariances(robust.problem.get(), robust.groups, robust.statics);
  ASSERT_TRUE(full.ok());
  // Information adds linearly here, so the downweighted outlier moves state 7's covariance by
  // ≈ ρ′ times what the full-weight reading moves it.
  const double rel_full = ((*a)[7] - (*full)[7]).norm() / (*a)[7].norm();
  const double rel_down = ((*a)[7] - (*b)[7]).norm() / (*a)[7].norm();
  EXPECT_GT(rel_full, 0.01);
  EXPECT_LT(rel_down, 0.01 * rel_full);
  EXPECT_GT(rel_down, 0.0001 * rel_full);  // discounted, not dropped
}

TEST(ChainCovarianceTest, FailsCleanlyWhenUnobservableOrNotAChain) {
  {
    Chain c(false);
    // A second heading block with no factor at all: H is singular.
    double free_theta = 0.0;
    c.problem->AddParameterBlock(&free_theta, 1);
    c.groups.push_back({&free_theta});
    auto cov = ChainMarginalCovariances(c.problem.get(), c.groups, c.statics);
    EXPECT_FALSE(cov.ok());
  }
  {
    Chain c(false);
    // A loop closure from the last state to the first: the half-bandwidth is the whole chain.
    c.problem->AddResidualBlock(
        new ceres::AutoDiffCostFunction<Step, 3, 2, 1, 2, 1>(new Step{0.0, 0.0, 1.0, 1.0}), nullptr,
        c.p.back().data(), &c.theta.back(), c.p[0].data(), &c.theta[0]);
    auto cov = ChainMarginalCovariances(c.problem.get(), c.groups, c.statics, 3.0, 8);
    ASSERT_FALSE(cov.ok());
    EXPECT_NE(cov.status().message().find("not chain-structured"), std::string::npos);
  }
}

}  // namespace
}  // namespace walkgraph
