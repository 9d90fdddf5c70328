// src/smoothers/graph.cc: the anchors' χ² test of one shared path loss
// (internal::TestAnchorOffsets), on residuals drawn here with known offsets and correlation;
// the marginal covariances of a FactorGraph's key groups (banded chain solve) against
// ceres::Covariance.
#include <cmath>
#include <cstring>
#include <map>
#include <memory>
#include <random>
#include <utility>
#include <vector>

#include <ceres/autodiff_cost_function.h>
#include <gtest/gtest.h>

#include "smoothers/graph_internal.h"
#include "walkgraph/graph.h"

namespace walkgraph {
namespace {

// `anchors` anchors with `n` whitened residuals each, AR(1) in time with lag-1 correlation rho
// (unit variance), plus offset(a) for anchor a; interleaved in time as a walk hears them.
std::vector<std::pair<int, double>> Residuals(int anchors, int n, double rho,
                                              const std::vector<double>& offset, uint32_t seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> g(0.0, 1.0);
  std::vector<double> state(static_cast<size_t>(anchors), 0.0);
  std::vector<std::pair<int, double>> out;
  for (int k = 0; k < n; ++k) {
    for (int a = 0; a < anchors; ++a) {
      double& x = state[static_cast<size_t>(a)];
      x = k == 0 ? g(rng) : rho * x + std::sqrt(1.0 - rho * rho) * g(rng);
      out.emplace_back(a, x + offset[static_cast<size_t>(a)]);
    }
  }
  return out;
}

TEST(AnchorOffsetTest, AgreeingAnchorsPassAtTheTestsLevel) {
  int rejected = 0;
  const int trials = 200;
  for (int t = 0; t < trials; ++t) {
    const auto r = Residuals(30, 100, 0.0, std::vector<double>(30, 0.0), 100u + t);
    const internal::AnchorOffsetTest test = internal::TestAnchorOffsets(r, 2.326);  // p = 0.01
    EXPECT_EQ(test.anchors, 30);
    rejected += test.disagree ? 1 : 0;
  }
  // Expected 1 % of 200 = 2; Binomial(200, 0.01) exceeds 8 with probability < 1e-3.
  EXPECT_LE(rejected, 8);
}

TEST(AnchorOffsetTest, CorrelatedResidualsAreNotMistakenForOffsets) {
  // Shadowing correlated along the walk (ρ = 0.9): the raw √n would reject nearly always.
  int rejected = 0;
  for (int t = 0; t < 100; ++t) {
    const auto r = Residuals(30, 300, 0.9, std::vector<double>(30, 0.0), 500u + t);
    rejected += internal::TestAnchorOffsets(r, 3.09).disagree ? 1 : 0;
  }
  EXPECT_LE(rejected, 10);
}

TEST(AnchorOffsetTest, AnchorsThatDifferAreFound) {
  std::vector<double> offset(30, 0.0);
  for (size_t a = 0; a < offset.size(); ++a) offset[a] = a % 2 == 0 ? 0.4 : -0.4;  // ±2.4 dB at σ 6
  const auto r = Residuals(30, 100, 0.5, offset, 7u);
  const internal::AnchorOffsetTest test = internal::TestAnchorOffsets(r, 3.09);
  EXPECT_TRUE(test.disagree) << test.statistic << " vs " << test.critical;
  // Wilson–Hilferty's χ²(30) 0.999 quantile: 59.70 exactly, 59.6 approximated.
  EXPECT_NEAR(test.critical, 59.7, 0.5);
}

TEST(AnchorOffsetTest, FewReadingsAndOutliers) {
  // Anchors heard fewer than 5 times are not tested.
  std::vector<std::pair<int, double>> r = {{1, 0.1}, {1, -0.2}, {1, 0.3}, {1, 0.0}};
  EXPECT_EQ(internal::TestAnchorOffsets(r, 3.09).anchors, 0);
  EXPECT_FALSE(internal::TestAnchorOffsets(r, 3.09).disagree);
  // A wild reading counts as one at +3 σ (clipped), not with its own size.
  auto wild = Residuals(10, 50, 0.0, std::vector<double>(10, 0.0), 3u);
  auto clipped = wild;
  wild[5].second = 1e6;
  clipped[5].second = 3.0;
  const internal::AnchorOffsetTest a = internal::TestAnchorOffsets(wild, 3.09);
  const internal::AnchorOffsetTest b = internal::TestAnchorOffsets(clipped, 3.09);
  EXPECT_EQ(a.anchors, 10);
  EXPECT_DOUBLE_EQ(a.statistic, b.statistic);
  EXPECT_FALSE(a.disagree);
}

// r = (x − z) / σ on an N-vector state.
template <int N>
struct PriorN {
  Eigen::Matrix<double, N, 1> z;
  double sigma;
  template <typename T>
  bool operator()(const T* x, T* r) const {
    for (int i = 0; i < N; ++i) r[i] = (x[i] - z[i]) / sigma;
    return true;
  }
};
// r = (x_b − x_a − d) / σ between two 2-vectors, and (h_b − h_a − dh) / σ_h between their
// headings-like 1-vectors; and a tie of state k's two blocks: (x0 + x1 − h − c) / σ.
struct Between2 {
  double d0, d1, sigma;
  template <typename T>
  bool operator()(const T* a, const T* b, T* r) const {
    r[0] = (b[0] - a[0] - d0) / sigma;
    r[1] = (b[1] - a[1] - d1) / sigma;
    return true;
  }
};
struct Tie {
  double c, sigma;
  template <typename T>
  bool operator()(const T* x, const T* h, T* r) const {
    r[0] = (x[0] + x[1] - h[0] - c) / sigma;
    return true;
  }
};

// A chain of 5 timestamps, each with a 2-D block x(k) and a 1-D block h(k) (h sorts before x by
// key; `x_first` adds x first), linked step to step; solved.
std::unique_ptr<FactorGraph> TwoBlockChain(bool x_first) {
  auto g = std::make_unique<FactorGraph>();
  for (int k = 0; k < 5; ++k) {
    const Key x = Symbol('x', k), h = Symbol('h', k);
    GraphState sx{x, double(k), {0.0, 0.0}}, sh{h, double(k), {0.0}};
    EXPECT_TRUE(g->AddState(x_first ? sx : sh).ok());
    EXPECT_TRUE(g->AddState(x_first ? sh : sx).ok());
    auto add = [&](ceres::CostFunction* c, std::vector<Key> keys) {
      EXPECT_TRUE(g->AddFactor({std::shared_ptr<ceres::CostFunction>(c), nullptr, keys}).ok());
    };
    add(new ceres::AutoDiffCostFunction<Tie, 1, 2, 1>(new Tie{0.1 * k, 0.5}), {x, h});
    if (k == 0) {
      add(new ceres::AutoDiffCostFunction<PriorN<2>, 2, 2>(
              new PriorN<2>{Eigen::Vector2d(0.2, -0.1), 0.3}),
          {x});
      add(new ceres::AutoDiffCostFunction<PriorN<1>, 1, 1>(
              new PriorN<1>{Eigen::Matrix<double, 1, 1>(0.05), 0.2}),
          {h});
    } else {
      add(new ceres::AutoDiffCostFunction<Between2, 2, 2, 2>(
              new Between2{1.0, 0.2 * std::sin(k), 0.4}),
          {Symbol('x', k - 1), x});
      add(new ceres::AutoDiffCostFunction<PriorN<1>, 1, 1>(
              new PriorN<1>{Eigen::Matrix<double, 1, 1>(0.1 * k), 0.7}),
          {h});
    }
  }
  EXPECT_TRUE(SolveBatch(g.get(), SolverOptions()).ok());
  return g;
}

// Public-API guards (issue 42): a key named twice (a Ceres CHECK abort before), an
// unconstrained state's covariance (zeros before) and non-finite values are errors.
TEST(MarginalCovariancesTest, KeyTwiceUnconstrainedStateAndNaNValuesAreErrors) {
  std::unique_ptr<FactorGraph> g = TwoBlockChain(true);
  auto twice = MarginalCovariances(g.get(), {{Symbol('x', 1), Symbol('x', 1)}});
  ASSERT_FALSE(twice.ok());
  EXPECT_EQ(twice.status().code(), StatusCode::kInvalidArgument);
  EXPECT_NE(twice.status().message().find("x1 named twice"), std::string::npos);
  // Across timestamps (the ceres::Covariance path) too.
  auto across = MarginalCovariances(g.get(), {{Symbol('x', 1), Symbol('x', 2), Symbol('x', 1)}});
  EXPECT_FALSE(across.ok());
  ASSERT_TRUE(g->AddState({Symbol('u', 0), 9.0, {0.0, 0.0}}).ok());  // no factor on it
  auto free_state = MarginalCovariances(g.get(), {{Symbol('u', 0)}});
  ASSERT_FALSE(free_state.ok());
  EXPECT_NE(free_state.status().message().find("u0"), std::string::npos);
  EXPECT_NE(free_state.status().message().find("unconstrained"), std::string::npos);
  EXPECT_TRUE(MarginalCovariances(g.get(), {{Symbol('x', 3)}}).ok());  // the others still work
  EXPECT_FALSE(g->AddState({Symbol('v', 0), 1.0, {std::nan(""), 0.0}}).ok());
  EXPECT_FALSE(g->SetValue(Symbol('x', 0), {0.0, INFINITY}).ok());
}

// FactorResiduals: a factor's whitened residuals at the current values (no loss), by the index
// it was added at; an index past the last is NotFound.
TEST(FactorGraphTest, FactorResidualsAtTheCurrentValues) {
  std::unique_ptr<FactorGraph> g = TwoBlockChain(true);
  // Factor 1 is x0's prior, z = (0.2, -0.1), σ 0.3.
  ASSERT_TRUE(g->SetValue(Symbol('x', 0), {0.2, 0.5}).ok());
  auto r = g->FactorResiduals(1);
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  ASSERT_EQ(r->size(), 2);
  EXPECT_NEAR((*r)[0], 0.0, 1e-15);
  EXPECT_NEAR((*r)[1], 0.6 / 0.3, 1e-12);
  ASSERT_TRUE(g->SetValue(Symbol('x', 0), {0.5, -0.1}).ok());
  r = g->FactorResiduals(1);
  ASSERT_TRUE(r.ok());
  EXPECT_NEAR((*r)[0], 0.3 / 0.3, 1e-12);
  EXPECT_NEAR((*r)[1], 0.0, 1e-15);
  auto past = g->FactorResiduals(g->num_factors());
  ASSERT_FALSE(past.ok());
  EXPECT_EQ(past.status().code(), StatusCode::kNotFound);
}

// Groups within one timestamp take the banded chain solve; a group across two timestamps sends
// every group to ceres::Covariance (sparse QR). Both must agree, whatever the layout (the
// blocks of a timestamp go in the order they were added) and however a group lists its keys:
// a whole timestamp in layout order, in the other order, one block, one timestamp asked twice.
TEST(MarginalCovariancesTest, BandedChainAgreesWithCeresForEveryGroupShape) {
  const std::vector<std::vector<Key>> groups = {{Symbol('x', 1), Symbol('h', 1)},
                                                {Symbol('h', 2), Symbol('x', 2)},
                                                {Symbol('x', 3)},
                                                {Symbol('h', 0)},
                                                {Symbol('x', 4), Symbol('h', 4)},
                                                {Symbol('x', 4), Symbol('h', 4)}};
  std::vector<std::vector<Key>> with_cross = groups;
  with_cross.push_back({Symbol('x', 0), Symbol('x', 4)});
  for (bool x_first : {true, false}) {
    auto g = TwoBlockChain(x_first);
    auto banded = MarginalCovariances(g.get(), groups);
    auto ceres = MarginalCovariances(g.get(), with_cross);
    ASSERT_TRUE(banded.ok() && ceres.ok()) << banded.status().message();
    for (size_t i = 0; i < groups.size(); ++i) {
      const Eigen::MatrixXd& a = (*banded)[i];
      const Eigen::MatrixXd& b = (*ceres)[i];
      ASSERT_EQ(a.rows(), b.rows()) << i;
      EXPECT_LT((a - b).cwiseAbs().maxCoeff(), 1e-9 * b.cwiseAbs().maxCoeff())
          << "group " << i << (x_first ? ", x added first" : ", h added first");
    }
    EXPECT_EQ(MarginalCovariances(g.get(), {{Symbol('x', 9)}}).status().code(),
              StatusCode::kNotFound);
  }
}

// A group across timestamps (the general path) gives the same bytes however the graph was
// built: its columns follow the keys, not where the blocks live in memory (ceres::Covariance
// orders them by address, so a window's anchor prior depended on what the process had
// allocated before, by up to 1.1e-5 m on Plaza1).
TEST(MarginalCovariancesTest, GeneralPathIsTheSameWhateverTheMemoryLayout) {
  const std::vector<std::vector<Key>> groups = {{Symbol('x', 0), Symbol('x', 4), Symbol('h', 2)},
                                                {Symbol('h', 3), Symbol('x', 1)}};
  auto a = MarginalCovariances(TwoBlockChain(true).get(), groups);
  std::vector<std::unique_ptr<double[]>> ballast;  // moves the second graph's blocks elsewhere
  for (int i = 0; i < 64; ++i) ballast.emplace_back(new double[3 + i % 5]);
  auto b = MarginalCovariances(TwoBlockChain(false).get(), groups);
  ASSERT_TRUE(a.ok() && b.ok());
  for (size_t i = 0; i < groups.size(); ++i) {
    ASSERT_EQ((*a)[i].size(), (*b)[i].size());
    EXPECT_EQ(std::memcmp((*a)[i].data(), (*b)[i].data(), sizeof(double) * (*a)[i].size()), 0)
        << "group " << i;
    EXPECT_TRUE((*a)[i].isApprox((*a)[i].transpose(), 0.0)) << "symmetric, group " << i;
  }
}

}  // namespace
}  // namespace walkgraph

namespace walkgraph {
namespace {

// r = (x_b − x_a − d) / σ between two 1-vectors.
struct Between1 {
  double d, sigma;
  template <typename T>
  bool operator()(const T* a, const T* b, T* r) const {
    r[0] = (b[0] - a[0] - d) / sigma;
    return true;
  }
};

// A 1-D walk of 1500 states: increments with noise 0.1 (group 0, modelled with σ = sigma0) and
// a position fix at each state with noise 1.0 (group 1, σ = sigma1), plus outliers of +20 on
// every tenth fix when `outliers` (then under a Cauchy loss); solved.
std::unique_ptr<FactorGraph> Chain(double sigma0, double sigma1, bool outliers, uint32_t seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> g(0.0, 1.0);
  auto graph = std::make_unique<FactorGraph>();
  double truth = 0.0;
  for (int k = 0; k < 1500; ++k) {
    const Key x = Symbol('x', k);
    EXPECT_TRUE(graph->AddState({x, double(k), {0.0}}).ok());
    if (k > 0) {
      const double step = 1.0 + 0.5 * std::sin(0.01 * k);
      truth += step;
      GraphFactor f{std::make_shared<ceres::AutoDiffCostFunction<Between1, 1, 1, 1>>(
                        new Between1{step + 0.1 * g(rng), sigma0}),
                    nullptr,
                    {Symbol('x', k - 1), x}};
      f.noise_group = 0;
      EXPECT_TRUE(graph->AddFactor(std::move(f)).ok());
    }
    double z = truth + 1.0 * g(rng);
    if (outliers && k % 10 == 5) z += 20.0;
    GraphFactor fix{std::make_shared<ceres::AutoDiffCostFunction<PriorN<1>, 1, 1>>(
                        new PriorN<1>{Eigen::Matrix<double, 1, 1>(z), sigma1}),
                    outliers ? std::make_shared<ceres::CauchyLoss>(1.0) : nullptr,
                    {x}};
    fix.noise_group = 1;
    EXPECT_TRUE(graph->AddFactor(std::move(fix)).ok());
  }
  EXPECT_TRUE(SolveBatch(graph.get(), SolverOptions()).ok());
  return graph;
}

// Variance-component estimation: a scale is the residuals' noise over the assumed σ at the
// current weights; iterated (σ ← σ · scale, solved again: Förstner's iteration) from σ 0.3 and
// 0.5, it ends near the true noise, 0.1 and 1.0, on three seeds (slowly: 0.101 after 12 rounds
// on seed 1; the increments, which the fixes check little (redundancy 74 of 1499), within 25 %:
// 0.122 on seed 3), and outliers of 20σ on a tenth of the fixes move the robust group's σ
// by less than 30 %. The first step moves the fixes' σ the right way.
TEST(EstimateNoiseScalesTest, IteratedItFindsEachGroupsTrueNoise) {
  for (uint32_t seed : {1u, 2u, 3u}) {
    for (bool outliers : {false, true}) {
      SCOPED_TRACE(testing::Message() << "seed " << seed << " outliers " << outliers);
      double sigma0 = 0.3, sigma1 = 0.5;
      for (int round = 0; round < 25; ++round) {
        auto graph = Chain(sigma0, sigma1, outliers, seed);
        StatusOr<std::map<int, NoiseScale>> s = EstimateNoiseScales(graph.get());
        ASSERT_TRUE(s.ok()) << s.status().ToString();
        ASSERT_EQ(s->size(), 2u);
        EXPECT_GT(s->at(0).redundancy, 2.0);
        EXPECT_EQ(s->at(1).rows, 500);  // of 1500: at most 500 read, evenly spread
        if (round == 0) EXPECT_GT(s->at(1).scale, 1.0);
        sigma0 *= s->at(0).scale;
        sigma1 *= s->at(1).scale;
      }
      // With outliers the median is contaminated (one-sided, a tenth of the fixes): measured
      // σ1 1.15-1.24 and σ0 0.059-0.072 then.
      EXPECT_NEAR(sigma0, 0.1, outliers ? 0.05 : 0.025);
      EXPECT_NEAR(sigma1, 1.0, outliers ? 0.3 : 0.1);
    }
  }
}

// A group the rest of the graph does not check (here the only factors on their states) has no
// redundancy: it is left out. A graph without noise groups gives an empty map.
TEST(EstimateNoiseScalesTest, LeavesOutAGroupWithoutRedundancy) {
  FactorGraph g;
  for (int k = 0; k < 50; ++k) {
    ASSERT_TRUE(g.AddState({Symbol('x', k), double(k), {0.0}}).ok());
    GraphFactor f{std::make_shared<ceres::AutoDiffCostFunction<PriorN<1>, 1, 1>>(
                      new PriorN<1>{Eigen::Matrix<double, 1, 1>(0.1 * k), 0.5}),
                  nullptr,
                  {Symbol('x', k)}};
    f.noise_group = 0;
    ASSERT_TRUE(g.AddFactor(std::move(f)).ok());
  }
  ASSERT_TRUE(SolveBatch(&g, SolverOptions()).ok());
  auto s = EstimateNoiseScales(&g);
  ASSERT_TRUE(s.ok());
  EXPECT_TRUE(s->empty());
  FactorGraph none;
  ASSERT_TRUE(none.AddState({Symbol('x', 0), 0.0, {1.0}}).ok());
  auto e = EstimateNoiseScales(&none);
  ASSERT_TRUE(e.ok());
  EXPECT_TRUE(e->empty());
}

}  // namespace
}  // namespace walkgraph
