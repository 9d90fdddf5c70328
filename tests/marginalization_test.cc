// Marginalize (the Schur complement behind the fixed-lag smoother's prior), on its own and
// through the smoother against the full batch — GTSAM's testBatchFixedLagSmoother is the model:
// a linear 2-D problem where marginalization is exact, so after every update the window must
// reproduce the batch optimum and covariance over everything seen so far.
#include "walkgraph/smoothers/marginalization.h"

#include <cmath>
#include <memory>
#include <set>
#include <vector>

#include <ceres/autodiff_cost_function.h>
#include <ceres/loss_function.h>
#include <gtest/gtest.h>

#include "walkgraph/graph.h"
#include "walkgraph/smoothers/fixed_lag_smoother.h"

namespace walkgraph {
namespace {

// r = (x − z) / σ on a 2-D state.
struct Prior2 {
  Eigen::Vector2d z;
  double sigma;
  template <typename T>
  bool operator()(const T* x, T* r) const {
    r[0] = (x[0] - z.x()) / sigma;
    r[1] = (x[1] - z.y()) / sigma;
    return true;
  }
};
// r = (b − a − d) / σ between two 2-D states.
struct Between2 {
  Eigen::Vector2d d;
  double sigma;
  template <typename T>
  bool operator()(const T* a, const T* b, T* r) const {
    r[0] = (b[0] - a[0] - d.x()) / sigma;
    r[1] = (b[1] - a[1] - d.y()) / sigma;
    return true;
  }
};

GraphFactor PriorOn(Key k, Eigen::Vector2d z, double sigma) {
  return {std::make_shared<ceres::AutoDiffCostFunction<Prior2, 2, 2>>(new Prior2{z, sigma}),
          nullptr,
          {k}};
}
GraphFactor BetweenOf(Key a, Key b, Eigen::Vector2d d, double sigma) {
  return {std::make_shared<ceres::AutoDiffCostFunction<Between2, 2, 2, 2>>(new Between2{d, sigma}),
          nullptr,
          {a, b}};
}

// The linear walk: x_k at t = k, a prior on x_0, steps d_k between consecutive states, a fix
// every third state, and a loop factor x_{k−2} → x_k (so the window's prior couples two
// states). Values from a fixed formula: no randomness.
std::vector<GraphFactor> FactorsOf(int k) {
  std::vector<GraphFactor> f;
  const Key x = Symbol('x', static_cast<uint64_t>(k));
  if (k == 0) f.push_back(PriorOn(x, {0.1, -0.2}, 0.1));
  if (k > 0) {
    f.push_back(
        BetweenOf(Symbol('x', k - 1), x, {1.0 + 0.05 * std::sin(k), 0.3 * std::cos(k)}, 0.2));
  }
  if (k % 3 == 2) f.push_back(PriorOn(x, {k + 0.4 * std::cos(3.0 * k), 0.2 * k}, 1.5));
  if (k >= 2) {
    f.push_back(BetweenOf(Symbol('x', k - 2), x, {2.1, 0.1 * std::sin(2.0 * k)}, 0.5));
  }
  return f;
}

GraphState StateOf(int k) { return {Symbol('x', static_cast<uint64_t>(k)), double(k), {0.0, 0.0}}; }

SolverOptions Tight() {
  SolverOptions o;
  o.function_tolerance = o.parameter_tolerance = o.gradient_tolerance = 1e-15;
  return o;
}

TEST(FixedLagVersusBatch, WindowEqualsBatchAfterEveryUpdate) {
  FixedLagSmoother::Options o;
  o.lag_s = 3.0;
  o.marginalize_batch_s = 0.0;  // GTSAM's behaviour: marginalize at every update
  o.solver = Tight();
  FixedLagSmoother window(o);
  for (int k = 0; k < 15; ++k) {
    std::vector<GraphState> states = {StateOf(k)};
    ASSERT_TRUE(window.Update(std::move(states), FactorsOf(k)).ok()) << k;
    FactorGraph batch;
    for (int j = 0; j <= k; ++j) {
      ASSERT_TRUE(batch.AddState(StateOf(j)).ok());
      for (GraphFactor& f : FactorsOf(j)) ASSERT_TRUE(batch.AddFactor(std::move(f)).ok());
    }
    ASSERT_TRUE(SolveBatch(&batch, Tight()).ok());
    // Every state still in the window: the batch optimum, and the newest one's covariance.
    for (const Key key : window.WindowKeys()) {
      auto w = window.Estimate(key);
      auto b = batch.Value(key);
      ASSERT_TRUE(w.ok() && b.ok());
      EXPECT_NEAR((*w)[0], (*b)[0], 1e-7) << KeyToString(key) << " after update " << k;
      EXPECT_NEAR((*w)[1], (*b)[1], 1e-7) << KeyToString(key) << " after update " << k;
    }
    const Key newest = Symbol('x', static_cast<uint64_t>(k));
    auto cw = window.MarginalCovariance(newest);
    auto cb = MarginalCovariances(&batch, {{newest}});
    ASSERT_TRUE(cw.ok() && cb.ok());
    EXPECT_LT(((*cw) - (*cb)[0]).norm(), 1e-8 * (*cb)[0].norm()) << "update " << k;
    EXPECT_LE(window.NumStates(), 5u);  // lag 3 s at 1 s per state: 4 states (+ the newest)
    // States have left (the comparison covers the marginalized prior, not just a full window).
    if (k >= 5) EXPECT_GE(SymbolIndex(window.WindowKeys().front()), static_cast<uint64_t>(k - 4));
  }
}

// A window that stops moving (updates adding factors but no newer state) marginalizes
// nothing and still equals the batch.
TEST(FixedLagVersusBatch, AWindowThatStopsMovingKeepsItsStates) {
  FixedLagSmoother::Options o;
  o.lag_s = 2.0;
  o.marginalize_batch_s = 0.0;
  o.solver = Tight();
  FixedLagSmoother window(o);
  FactorGraph batch;
  for (int k = 0; k < 6; ++k) {
    ASSERT_TRUE(window.Update({StateOf(k)}, FactorsOf(k)).ok());
    ASSERT_TRUE(batch.AddState(StateOf(k)).ok());
    for (GraphFactor& f : FactorsOf(k)) ASSERT_TRUE(batch.AddFactor(std::move(f)).ok());
  }
  const std::vector<Key> before = window.WindowKeys();
  for (int extra = 0; extra < 3; ++extra) {
    std::vector<GraphFactor> more;
    more.push_back(PriorOn(Symbol('x', 5), {5.2, 1.1}, 0.5));
    ASSERT_TRUE(window.Update({}, std::move(more)).ok());
    ASSERT_TRUE(batch.AddFactor(PriorOn(Symbol('x', 5), {5.2, 1.1}, 0.5)).ok());
    EXPECT_EQ(window.WindowKeys(), before);
  }
  ASSERT_TRUE(SolveBatch(&batch, Tight()).ok());
  for (const Key key : before) {
    EXPECT_NEAR((*window.Estimate(key))[0], (*batch.Value(key))[0], 1e-7) << KeyToString(key);
    EXPECT_NEAR((*window.Estimate(key))[1], (*batch.Value(key))[1], 1e-7) << KeyToString(key);
  }
}

// Unknown keys are errors that name them, and change nothing.
TEST(FixedLagVersusBatch, UnknownKeysAreRefused) {
  FixedLagSmoother window(FixedLagSmoother::Options{});
  ASSERT_TRUE(window.Update({StateOf(0)}, FactorsOf(0)).ok());
  std::vector<GraphFactor> bad;
  bad.push_back(BetweenOf(Symbol('x', 0), Symbol('x', 7), {1.0, 0.0}, 0.2));
  auto r = window.Update({}, std::move(bad));
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(window.WindowKeys(), std::vector<Key>{Symbol('x', 0)});
  EXPECT_FALSE(window.Estimate(Symbol('x', 7)).ok());
}

// ---------------------------------------------------------------- Marginalize itself

struct Blocks {
  std::vector<Eigen::Vector2d> x;
  BlockRef Ref(int k) { return {Symbol('x', static_cast<uint64_t>(k)), x[k].data(), 2}; }
};

// The prior is the Schur complement of the factors' normal equations: J₀ᵀJ₀ = H*, J₀ᵀr₀ = b*,
// with H and b assembled here from the same (linear) factors' Jacobians written out by hand.
TEST(Marginalize, IsTheSchurComplementOfTheNormalEquations) {
  Blocks b;
  b.x = {{0.3, -0.1}, {1.2, 0.4}, {2.5, 0.2}};
  const auto p0 = PriorOn(b.Ref(0).key, {0.0, 0.0}, 0.1);
  const auto b01 = BetweenOf(b.Ref(0).key, b.Ref(1).key, {1.0, 0.2}, 0.2);
  const auto b02 = BetweenOf(b.Ref(0).key, b.Ref(2).key, {2.0, 0.1}, 0.5);
  std::vector<FactorRef> factors = {{p0.cost.get(), nullptr, {b.Ref(0)}},
                                    {b01.cost.get(), nullptr, {b.Ref(0), b.Ref(1)}},
                                    {b02.cost.get(), nullptr, {b.Ref(0), b.Ref(2)}}};
  auto prior = Marginalize(factors, {b.Ref(0).key});
  ASSERT_TRUE(prior.ok()) << prior.status().message();
  ASSERT_EQ(prior->blocks.size(), 2u);
  EXPECT_EQ(prior->blocks[0].key, b.Ref(1).key);
  EXPECT_EQ(prior->blocks[1].key, b.Ref(2).key);

  // By hand: state order (x0, x1, x2), each 2-D; whitened Jacobians and residuals.
  const Eigen::Matrix2d I = Eigen::Matrix2d::Identity();
  Eigen::MatrixXd H = Eigen::MatrixXd::Zero(6, 6);
  Eigen::VectorXd g = Eigen::VectorXd::Zero(6);
  auto add = [&](int i, int j, const Eigen::Vector2d& d, double s) {  // between i → j, or prior
    Eigen::MatrixXd J = Eigen::MatrixXd::Zero(2, 6);
    Eigen::Vector2d r;
    if (j < 0) {
      J.middleCols(2 * i, 2) = I / s;
      r = (b.x[i] - d) / s;
    } else {
      J.middleCols(2 * i, 2) = -I / s;
      J.middleCols(2 * j, 2) = I / s;
      r = (b.x[j] - b.x[i] - d) / s;
    }
    H += J.transpose() * J;
    g += J.transpose() * r;
  };
  add(0, -1, {0.0, 0.0}, 0.1);
  add(0, 1, {1.0, 0.2}, 0.2);
  add(0, 2, {2.0, 0.1}, 0.5);
  const Eigen::MatrixXd Hmm = H.topLeftCorner(2, 2), Hrm = H.bottomLeftCorner(4, 2);
  const Eigen::MatrixXd Hs = H.bottomRightCorner(4, 4) - Hrm * Hmm.inverse() * Hrm.transpose();
  const Eigen::VectorXd bs = g.tail(4) - Hrm * Hmm.inverse() * g.head(2);
  EXPECT_LT((prior->j0.transpose() * prior->j0 - Hs).norm(), 1e-9 * Hs.norm());
  EXPECT_LT((prior->j0.transpose() * prior->r0 - bs).norm(), 1e-9 * bs.norm());
  // The cost function it makes: residual r₀ at the linearization point.
  auto cost = prior->MakeCostFunction();
  const double* params[] = {b.x[1].data(), b.x[2].data()};
  Eigen::VectorXd r(cost->num_residuals());
  ASSERT_TRUE(cost->Evaluate(params, r.data(), nullptr));
  EXPECT_LT((r - prior->r0).norm(), 1e-12);
}

// A state touched only by its own prior leaves nothing to constrain; a key no factor touches
// marginalizes nothing; both give an empty prior rather than an error.
TEST(Marginalize, PriorOnlyStatesAndUntouchedKeysGiveAnEmptyPrior) {
  Blocks b;
  b.x = {{0.3, -0.1}, {1.2, 0.4}};
  const auto p0 = PriorOn(b.Ref(0).key, {0.0, 0.0}, 0.1);
  const auto p1 = PriorOn(b.Ref(1).key, {1.0, 0.0}, 0.1);
  auto only = Marginalize({{p0.cost.get(), nullptr, {b.Ref(0)}}}, {b.Ref(0).key});
  ASSERT_TRUE(only.ok());
  EXPECT_TRUE(only->empty());
  auto untouched = Marginalize({{p1.cost.get(), nullptr, {b.Ref(1)}}}, {Symbol('x', 9)});
  ASSERT_TRUE(untouched.ok());
  EXPECT_TRUE(untouched->empty());
}

// A robust factor enters with its IRLS weight √ρ′ at the current residual: a Cauchy(1) loss on
// a residual of norm² s scales the information by ρ′(s) = 1/(1 + s).
TEST(Marginalize, RobustFactorsEnterWithTheirIrlsWeight) {
  Blocks b;
  b.x = {{0.0, 0.0}, {3.0, 0.0}};  // residual of the between (d = (1, 0), σ 1): (2, 0), s = 4
  const auto p0 = PriorOn(b.Ref(0).key, {0.0, 0.0}, 1.0);
  const auto b01 = BetweenOf(b.Ref(0).key, b.Ref(1).key, {1.0, 0.0}, 1.0);
  ceres::CauchyLoss cauchy(1.0);
  auto plain = Marginalize(
      {{p0.cost.get(), nullptr, {b.Ref(0)}}, {b01.cost.get(), nullptr, {b.Ref(0), b.Ref(1)}}},
      {b.Ref(0).key});
  auto robust = Marginalize(
      {{p0.cost.get(), nullptr, {b.Ref(0)}}, {b01.cost.get(), &cauchy, {b.Ref(0), b.Ref(1)}}},
      {b.Ref(0).key});
  ASSERT_TRUE(plain.ok() && robust.ok());
  // Plain: H* on x1 = 1 − 1·(1 + 1)⁻¹·1 = 0.5 per axis; robust: w = 0.2 →
  // H* = w − w²/(1 + w) = 0.2 − 0.04/1.2.
  const Eigen::Matrix2d hp = plain->j0.transpose() * plain->j0;
  const Eigen::Matrix2d hr = robust->j0.transpose() * robust->j0;
  EXPECT_NEAR(hp(0, 0), 0.5, 1e-12);
  EXPECT_NEAR(hr(0, 0), 0.2 - 0.04 / 1.2, 1e-12);
}

}  // namespace
}  // namespace walkgraph
