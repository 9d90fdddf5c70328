#include "walkgraph/pcrb.h"

#include <chrono>
#include <cmath>
#include <cstdio>
#include <random>

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <Eigen/Dense>

#include "eval/pcrb_yaml.h"
#include "test_util.h"
#include "walkgraph/compare.h"
#include "walkgraph/kalman.h"
#include "walkgraph/path_loss.h"

namespace walkgraph {
namespace {

using ::testing::HasSubstr;

double RelDiff(const Eigen::Matrix2d& a, const Eigen::Matrix2d& b) {
  return (a - b).norm() / b.norm();
}

// The linear-Gaussian preset as its exact linear model (simulate.h): the heading ψ0 is known,
// the odometry moves x by d_k·u, the ranges to the two anchors on the line are u_aᵀ(x − a) + n.
// The PCRB model of it (pcrb.h): Q = σ_d² u uᵀ + σ_min² u⊥u⊥ᵀ with σ_min = 1e-3 m.
struct LinearModel {
  Eigen::Vector2d u, n;
  double sigma_d, sigma_r, sigma_min = 1e-3;
  Eigen::Matrix2d Q() const {
    return sigma_d * sigma_d * u * u.transpose() + sigma_min * sigma_min * n * n.transpose();
  }
};

LinearModel ModelOf(const Walk& w) {
  LinearModel m;
  const double h = w.meta.extra.at("sim.heading_rad");
  m.u = Eigen::Vector2d(std::cos(h), std::sin(h));
  m.n = Eigen::Vector2d(-m.u.y(), m.u.x());
  m.sigma_d = w.meta.extra.at("sim.step_sigma_m");
  m.sigma_r = w.meta.radio.range_sigma_m;
  return m;
}

struct KfRun {
  std::vector<FilterEpoch> epochs;  // one per truth sample (node)
  std::vector<SmoothedState> smoothed;
};

// KF (Joseph form via KalmanUpdate) + RTS over the walk's nodes, started at x0 with P0.
KfRun RunLinearKf(const Walk& w, const LinearModel& m, const Eigen::Vector2d& x0, double sigma0) {
  KfRun out;
  Eigen::VectorXd x = x0;
  Eigen::MatrixXd P = Eigen::Matrix2d::Identity() * sigma0 * sigma0;
  size_t r = 0;
  for (size_t k = 0; k < w.truth.size(); ++k) {
    const double t = w.truth[k].t_s;
    FilterEpoch e;
    e.t_s = t;
    e.F = Eigen::Matrix2d::Identity();
    if (k > 0) {
      x += w.odometry[k - 1].dist_m * m.u;  // odometry k−1 ends at truth sample k
      P += m.Q();
    }
    e.x_prior = x;
    e.P_prior = P;
    for (; r < w.ranges.size() && w.ranges[r].t_s <= t + 1e-9; ++r) {
      const RangeSample& z = w.ranges[r];
      const Eigen::Vector2d a = w.anchors[w.AnchorIndex(z.anchor_id)].position_m.head<2>();
      // Anchor 1 is behind the start (range grows along u), anchor 2 beyond the end.
      const Eigen::Vector2d ua = z.anchor_id == 1 ? m.u : Eigen::Vector2d(-m.u);
      Eigen::MatrixXd H = ua.transpose();
      Eigen::VectorXd nu(1);
      nu << z.range_m - ua.dot(x.head<2>() - a);
      Eigen::MatrixXd R(1, 1);
      R << m.sigma_r * m.sigma_r;
      EXPECT_TRUE(KalmanUpdate(nu, H, R, 0.0, &x, &P).ok());
    }
    e.x_post = x;
    e.P_post = P;
    out.epochs.push_back(e);
  }
  auto s = RtsSmooth(out.epochs);
  EXPECT_TRUE(s.ok());
  out.smoothed = *s;
  return out;
}

TEST(Pcrb, LinearGaussianBoundIsTheKalmanAndRtsCovariance) {
  auto sim = SimulateScenarioDetailed("linear-gaussian", 3, YAML::Load("{duration_s: 30}"));
  ASSERT_TRUE(sim.ok()) << sim.status().message();
  const Walk& w = sim->walk;
  PcrbOptions options;
  options.prior_sigma_m = 0.0;  // the walk's initial_pose σ_xy, as the KF below
  auto info = PcrbInformationFromSimulation(*sim, options);
  ASSERT_TRUE(info.ok()) << info.status().message();
  auto bound = ComputePcrb(*info);
  ASSERT_TRUE(bound.ok()) << bound.status().message();
  ASSERT_EQ(bound->t_s.size(), w.truth.size());
  const LinearModel m = ModelOf(w);
  const KfRun kf =
      RunLinearKf(w, m, Eigen::Vector2d(w.meta.initial_pose->x_m, w.meta.initial_pose->y_m),
                  w.meta.initial_pose->sigma_xy_m);
  ASSERT_EQ(kf.smoothed.size(), w.truth.size());
  double worst_f = 0.0, worst_s = 0.0;
  for (size_t k = 0; k < w.truth.size(); ++k) {
    worst_f = std::max(worst_f, RelDiff(bound->filter[k], kf.epochs[k].P_post));
    worst_s = std::max(worst_s, RelDiff(bound->smoother[k], kf.smoothed[k].P));
  }
  EXPECT_LT(worst_f, 1e-6);
  EXPECT_LT(worst_s, 1e-6);
  // Ranges every 2nd step: the along-track variance falls below the prior's.
  EXPECT_LT(m.u.dot(bound->smoother[30] * m.u), 0.05);
}

// Dense reference: A assembled from the interval terms, inverted directly (small n only).
Eigen::MatrixXd DenseInformation(const PcrbInformation& in, size_t nodes) {
  Eigen::MatrixXd A = Eigen::MatrixXd::Zero(2 * nodes, 2 * nodes);
  A.block<2, 2>(0, 0) += in.J0;
  for (size_t k = 0; k + 1 < nodes; ++k) {
    A.block<2, 2>(2 * k, 2 * k) += in.D11[k];
    A.block<2, 2>(2 * k, 2 * k + 2) += in.D12[k];
    A.block<2, 2>(2 * k + 2, 2 * k) += in.D12[k].transpose();
    A.block<2, 2>(2 * k + 2, 2 * k + 2) += in.D22[k];
  }
  return A;
}

// A random but valid information: J0 > 0, each interval a PSD 4×4 block (process + readings).
PcrbInformation RandomInformation(size_t n, uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> U(-1.0, 1.0);
  PcrbInformation in;
  for (size_t k = 0; k < n; ++k) {
    in.t_s.push_back(0.5 * k);
    in.position_m.push_back(Eigen::Vector2d::Zero());
    in.score_t_s.push_back(0.5 * k);
  }
  in.J0 = Eigen::Matrix2d::Identity() * 4.0;
  for (size_t k = 0; k + 1 < n; ++k) {
    Eigen::Matrix4d G;
    for (int i = 0; i < 16; ++i) G.data()[i] = U(rng);
    Eigen::Matrix4d W = G * G.transpose();
    Eigen::Matrix2d Qi = Eigen::Matrix2d::Identity() * (50.0 + 40.0 * U(rng));
    W.block<2, 2>(0, 0) += Qi;
    W.block<2, 2>(0, 2) -= Qi;
    W.block<2, 2>(2, 0) -= Qi;
    W.block<2, 2>(2, 2) += Qi;
    in.D11.push_back(W.block<2, 2>(0, 0));
    in.D12.push_back(W.block<2, 2>(0, 2));
    in.D22.push_back(W.block<2, 2>(2, 2));
  }
  return in;
}

TEST(Pcrb, RecursionAndSparseSmootherMatchDenseInverses) {
  const size_t n = 25;
  const PcrbInformation in = RandomInformation(n, 11);
  auto bound = ComputePcrb(in);
  ASSERT_TRUE(bound.ok()) << bound.status().message();
  const Eigen::MatrixXd full = DenseInformation(in, n).inverse();
  for (size_t k = 0; k < n; ++k) {
    // Filtering bound at k: the information of nodes 0..k from the intervals before k only.
    const Eigen::MatrixXd upto = DenseInformation(in, k + 1).inverse();
    EXPECT_LT(RelDiff(bound->filter[k], upto.block<2, 2>(2 * k, 2 * k)), 1e-9) << k;
    EXPECT_LT(RelDiff(bound->smoother[k], full.block<2, 2>(2 * k, 2 * k)), 1e-9) << k;
  }
}

TEST(Pcrb, TenHourWalkIsSparseAndSmootherMeetsFilterAtTheEnd) {
  // 10 h of steps at 1.85 Hz: 66,600 nodes (a dense inverse would be 133k × 133k).
  const size_t n = 66600;
  const PcrbInformation in = RandomInformation(n, 5);
  const auto start = std::chrono::steady_clock::now();
  auto bound = ComputePcrb(in);
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  ASSERT_TRUE(bound.ok()) << bound.status().message();
  if (!testing::kSanitized) EXPECT_LT(seconds, 5.0);
  // (A⁻¹)_{n−1,n−1} = J_{n−1}⁻¹: the smoother has no future readings at the last node.
  EXPECT_LT(RelDiff(bound->smoother.back(), bound->filter.back()), 1e-8);
  for (size_t k = 0; k < n; k += 997) {
    EXPECT_LE(bound->smoother[k].trace(), bound->filter[k].trace() * (1.0 + 1e-12)) << k;
  }
}

// Information of one RSS reading: a numeric derivative of the mean RSS (PathLossModel) squared
// over σ² — the Gaussian Fisher information gᵀg/σ², independent of the closed form in pcrb.cc.
TEST(Pcrb, RssInformationIsTheSquaredGradientOfTheMeanRss) {
  Simulation sim;
  Walk& w = sim.walk;
  w.meta.name = "hand";
  w.meta.imu_placement = ImuPlacement::kWaist;
  w.meta.initial_pose = InitialPose{0, 0, 0, 0.5, 0.1};
  const PathLossParams pl{-50.0, 2.7, 1.0, 4.0};
  w.meta.radio.path_loss = pl;
  w.anchors = {{7, Eigen::Vector3d(3.0, 4.0, 2.0)}};
  sim.per_anchor = {pl};
  for (int k = 0; k <= 10; ++k) w.truth.push_back({0.5 * k, Eigen::Vector3d(0.6 * k, 0, 0), false});
  for (int k = 1; k <= 10; ++k) sim.steps.push_back({0.5 * k, 0.6, 0.5});
  auto without = PcrbInformationFromSimulation(sim);
  ASSERT_TRUE(without.ok()) << without.status().message();
  w.rss.push_back({2.0, 7, -70.0});  // exactly at node 4 (α = 1 of interval 3)
  auto with = PcrbInformationFromSimulation(sim);
  ASSERT_TRUE(with.ok()) << with.status().message();
  EXPECT_EQ(with->readings, 1.0);
  const Eigen::Matrix2d M = with->D22[3] - without->D22[3];
  const PathLossModel model(pl, RssUnits::kDbm);
  const Eigen::Vector3d p(2.4, 0.0, 0.0), a = w.anchors[0].position_m;
  Eigen::Vector2d g;
  const double h = 1e-6;
  for (int i = 0; i < 2; ++i) {
    Eigen::Vector3d dp = Eigen::Vector3d::Zero();
    dp[i] = h;
    g[i] =
        (model.ExpectedRss((p + dp - a).norm()) - model.ExpectedRss((p - dp - a).norm())) / (2 * h);
  }
  const Eigen::Matrix2d expected = g * g.transpose() / (pl.sigma_db * pl.sigma_db);
  EXPECT_LT(RelDiff(M, expected), 1e-6);
  EXPECT_TRUE(with->D11[3].isApprox(without->D11[3]));
}

TEST(Pcrb, ReadingBetweenNodesIsSharedByInterpolation) {
  Simulation sim;
  Walk& w = sim.walk;
  w.meta.imu_placement = ImuPlacement::kWaist;
  w.meta.initial_pose = InitialPose{0, 0, 0, 0.5, 0.1};
  w.meta.radio.range_sigma_m = 0.5;
  w.anchors = {{1, Eigen::Vector3d(0.0, 10.0, 0.0)}};
  for (int k = 0; k <= 4; ++k) w.truth.push_back({1.0 * k, Eigen::Vector3d(1.0 * k, 0, 0), false});
  for (int k = 1; k <= 4; ++k) sim.steps.push_back({1.0 * k, 1.0, 1.0});
  auto base = PcrbInformationFromSimulation(sim);
  ASSERT_TRUE(base.ok());
  w.ranges.push_back({1.25, 1, 10.0});  // α = 0.25 into interval 1
  auto info = PcrbInformationFromSimulation(sim);
  ASSERT_TRUE(info.ok());
  const Eigen::Vector3d r = Eigen::Vector3d(1.25, 0, 0) - w.anchors[0].position_m;
  const Eigen::Vector2d u = r.head<2>() / r.norm();
  const Eigen::Matrix2d M = u * u.transpose() / 0.25;
  EXPECT_LT(RelDiff(info->D11[1] - base->D11[1], 0.75 * 0.75 * M), 1e-12);
  EXPECT_LT(RelDiff(info->D12[1] - base->D12[1], 0.25 * 0.75 * M), 1e-12);
  EXPECT_LT(RelDiff(info->D22[1] - base->D22[1], 0.25 * 0.25 * M), 1e-12);
}

// An efficient estimator attains the bound: the KF/RTS of the linear-Gaussian preset, started
// from a prior mean drawn from the prior (as the Bayesian bound assumes), over N runs.
TEST(Pcrb, KalmanRmseOnLinearGaussianApproachesTheBound) {
  const int runs = testing::MonteCarloRuns(2000);
  const double sigma0 = 0.05;
  PcrbOptions options;
  options.prior_sigma_m = sigma0;
  std::mt19937_64 rng(99);
  std::normal_distribution<double> prior(0.0, sigma0);
  double se_f = 0.0, se_s = 0.0;
  long count = 0;
  std::optional<PcrbBound> bound;
  for (int i = 0; i < runs; ++i) {
    auto sim = SimulateScenarioDetailed("linear-gaussian", MonteCarloSeed(4, i),
                                        YAML::Load("{duration_s: 30}"));
    ASSERT_TRUE(sim.ok());
    const Walk& w = sim->walk;
    if (!bound) {
      auto info = PcrbInformationFromSimulation(*sim, options);
      ASSERT_TRUE(info.ok());
      auto b = ComputePcrb(*info);
      ASSERT_TRUE(b.ok());
      bound = *b;
    }
    const Eigen::Vector2d x0(w.meta.initial_pose->x_m + prior(rng),
                             w.meta.initial_pose->y_m + prior(rng));
    const KfRun kf = RunLinearKf(w, ModelOf(w), x0, sigma0);
    for (size_t k = 0; k < w.truth.size(); ++k) {
      const Eigen::Vector2d truth = w.truth[k].position_m.head<2>();
      se_f += (kf.epochs[k].x_post.head<2>() - truth).squaredNorm();
      se_s += (kf.smoothed[k].x.head<2>() - truth).squaredNorm();
      ++count;
    }
  }
  const double rmse_f = std::sqrt(se_f / count), rmse_s = std::sqrt(se_s / count);
  std::printf(
      "linear-gaussian, %d runs: KF RMSE %.4f m vs filtering PCRB %.4f m; RTS %.4f m vs "
      "smoothing PCRB %.4f m\n",
      runs, rmse_f, bound->filter_rmse_m, rmse_s, bound->smoother_rmse_m);
  // N = 2000: the RMSE estimates have ≈0.6 % standard error (3000 runs of another seed gave
  // 0.1251 vs 0.1252 m and 0.1000 vs 0.1002 m); 3 % is 5σ.
  const double tol = testing::kSanitized ? 0.08 : 0.03;
  EXPECT_NEAR(rmse_f / bound->filter_rmse_m, 1.0, tol) << rmse_f << " vs " << bound->filter_rmse_m;
  EXPECT_NEAR(rmse_s / bound->smoother_rmse_m, 1.0, tol)
      << rmse_s << " vs " << bound->smoother_rmse_m;
  EXPECT_LT(bound->smoother_rmse_m, 0.9 * bound->filter_rmse_m);
}

TEST(Pcrb, BoundShrinksWithAnchorsAndGrowsWithSigma) {
  auto bound = [](const std::string& overrides) {
    auto b = ScenarioPcrb("tarrio-circle", YAML::Load(overrides), 3, 1, 1);
    EXPECT_TRUE(b.ok()) << b.status().message();
    return b.ok() ? b->smoother_rmse_m : 0.0;
  };
  const double nine = bound("{laps: 1}");
  const double four = bound("{laps: 1, num_anchors: 4}");
  const double noisy = bound("{laps: 1, sigma_db: 8}");
  EXPECT_LT(nine, 0.95 * four) << nine << " " << four;
  EXPECT_GT(noisy, 1.1 * nine) << noisy << " " << nine;
  // A noisier step model (the estimators' σ) loosens the bound too.
  PcrbOptions loose;
  loose.step_sigma_frac = 0.3;
  auto b = ScenarioPcrb("tarrio-circle", YAML::Load("{laps: 1}"), 3, 1, 1, loose);
  ASSERT_TRUE(b.ok());
  EXPECT_GT(b->smoother_rmse_m, 1.1 * nine);
  EXPECT_GT(b->filter_rmse_m, b->smoother_rmse_m);
}

TEST(Pcrb, ScenarioBoundDoesNotDependOnThreads) {
  auto one = ScenarioPcrb("tarrio-circle", YAML::Load("{laps: 1}"), 4, 7, 1);
  auto two = ScenarioPcrb("tarrio-circle", YAML::Load("{laps: 1}"), 4, 7, 2);
  ASSERT_TRUE(one.ok() && two.ok());
  EXPECT_EQ(one->smoother_rmse_m, two->smoother_rmse_m);
  EXPECT_EQ(one->filter_rmse_m, two->filter_rmse_m);
  EXPECT_EQ(one->runs, 4);
  // The mean over runs equals MeanPcrbInformation of the runs simulated one by one.
  std::vector<PcrbInformation> infos;
  for (int i = 0; i < 4; ++i) {
    auto sim =
        SimulateScenarioDetailed("tarrio-circle", MonteCarloSeed(7, i), YAML::Load("{laps: 1}"));
    ASSERT_TRUE(sim.ok());
    auto info = PcrbInformationFromSimulation(*sim);
    ASSERT_TRUE(info.ok());
    infos.push_back(*info);
  }
  auto mean = MeanPcrbInformation(infos);
  ASSERT_TRUE(mean.ok());
  auto b = ComputePcrb(*mean);
  ASSERT_TRUE(b.ok());
  EXPECT_DOUBLE_EQ(b->smoother_rmse_m, one->smoother_rmse_m);
}

TEST(Pcrb, FootWalksAndBadInputsAreReported) {
  Simulation foot;
  foot.walk.meta.imu_placement = ImuPlacement::kFoot;
  auto f = PcrbInformationFromSimulation(foot);
  ASSERT_FALSE(f.ok());
  EXPECT_EQ(f.status().code(), StatusCode::kFailedPrecondition);
  EXPECT_THAT(f.status().message(), HasSubstr("foot"));
  EXPECT_FALSE(ScenarioPcrb("no-such-scenario", YAML::Node(), 1, 1, 1).ok());
  auto bad = PcrbOptionsFromYaml(YAML::Load("{step_sigma: 1}"), "pcrb");
  ASSERT_FALSE(bad.ok());
  EXPECT_THAT(bad.status().message(), HasSubstr("step_sigma"));
  auto good = PcrbOptionsFromYaml(YAML::Load("{prior_sigma_m: 0.2}"), "pcrb");
  ASSERT_TRUE(good.ok());
  EXPECT_EQ(good->prior_sigma_m, 0.2);
  PcrbInformation a = RandomInformation(5, 1), b = RandomInformation(6, 1);
  EXPECT_FALSE(MeanPcrbInformation({a, b}).ok());
}

}  // namespace
}  // namespace walkgraph
