#include "walkgraph/smoothers/fixed_lag_smoother.h"

#include <cmath>
#include <memory>
#include <string>
#include <vector>

#include <ceres/ceres.h>
#include <gtest/gtest.h>

namespace walkgraph {
namespace {

// r = (x − z) / σ on one scalar state.
struct Prior {
  double z, sigma;
  template <typename T>
  bool operator()(const T* x, T* r) const {
    r[0] = (x[0] - z) / sigma;
    return true;
  }
};
// r = (b − a − d) / σ between two scalar states.
struct Between {
  double d, sigma;
  template <typename T>
  bool operator()(const T* a, const T* b, T* r) const {
    r[0] = (b[0] - a[0] - d) / sigma;
    return true;
  }
};

GraphState Scalar(Key key, double t_s) {
  GraphState s;
  s.key = key;
  s.t_s = t_s;
  s.value = {0.0};
  return s;
}

GraphFactor PriorOn(Key key, double z, double sigma) {
  GraphFactor f;
  f.cost.reset(new ceres::AutoDiffCostFunction<Prior, 1, 1>(new Prior{z, sigma}));
  f.keys = {key};
  return f;
}

GraphFactor BetweenOf(Key a, Key b, double d, double sigma) {
  GraphFactor f;
  f.cost.reset(new ceres::AutoDiffCostFunction<Between, 1, 1, 1>(new Between{d, sigma}));
  f.keys = {a, b};
  return f;
}

// A 1-D chain x_k at t = k s: a prior on x_0, unit steps, a noisy "fix" on every state.
StatusOr<FixedLagSmoother::UpdateResult> AddState(FixedLagSmoother* s, int k) {
  std::vector<GraphState> states;
  std::vector<GraphFactor> factors;
  states.push_back(Scalar(k, k));
  factors.push_back(PriorOn(k, k + (k % 2 ? 0.3 : -0.3), 1.0));
  if (k > 0) factors.push_back(BetweenOf(k - 1, k, 1.0, 0.1));
  return s->Update(std::move(states), std::move(factors));
}

TEST(FixedLagSmoother, KeepsTheLagAndAHeldStretch) {
  FixedLagSmoother::Options o;
  o.lag_s = 2.0;
  FixedLagSmoother s(o);
  for (int k = 0; k <= 5; ++k) ASSERT_TRUE(AddState(&s, k).ok());
  // t_newest = 5, lag 2: states older than t = 3 have left.
  EXPECT_EQ(s.WindowKeys(), (std::vector<Key>{3, 4, 5}));
  s.HoldFrom(4.0);
  EXPECT_TRUE(s.holding());
  for (int k = 6; k <= 9; ++k) ASSERT_TRUE(AddState(&s, k).ok());
  // Held: nothing from t = 4 on leaves, however old (state 3 left at the lag).
  EXPECT_EQ(s.WindowKeys(), (std::vector<Key>{4, 5, 6, 7, 8, 9}));
  s.Release();
  EXPECT_FALSE(s.holding());
  ASSERT_TRUE(AddState(&s, 10).ok());
  EXPECT_EQ(s.WindowKeys(), (std::vector<Key>{8, 9, 10}));
}

TEST(FixedLagSmoother, RefusesNaNAndTimesBeforeTheWindowAndChangesNothing) {
  FixedLagSmoother::Options o;
  o.lag_s = 2.0;
  FixedLagSmoother s(o);
  for (int k = 0; k <= 5; ++k) ASSERT_TRUE(AddState(&s, k).ok());
  const std::vector<Key> window = s.WindowKeys();
  auto refused = [&](GraphState bad, const char* message) {
    std::vector<GraphState> states;
    states.push_back(Scalar(100, 6.0));  // a good state first: it must not be added either
    states.push_back(std::move(bad));
    auto r = s.Update(std::move(states), {});
    ASSERT_FALSE(r.ok()) << message;
    EXPECT_EQ(r.status().code(), StatusCode::kInvalidArgument);
    EXPECT_NE(r.status().message().find(message), std::string::npos) << r.status().message();
    EXPECT_FALSE(s.Contains(100));
    EXPECT_EQ(s.WindowKeys(), window);
  };
  refused(Scalar(101, std::nan("")), "non-finite time");
  refused(Scalar(102, 1.0), "goes back before the window");  // states before t = 3 are gone
  GraphState nan_value = Scalar(103, 6.0);
  nan_value.value = {std::nan("")};
  refused(nan_value, "non-finite value");
  refused(Scalar(100, 6.5), "added twice");  // the same key twice in one update
  // A factor naming one state twice (a Ceres abort before) or an unknown state: refused before
  // its update's states are added.
  std::vector<GraphState> with_bad_factor;
  with_bad_factor.push_back(Scalar(105, 6.0));
  auto twice = s.Update(std::move(with_bad_factor), {BetweenOf(105, 105, 1.0, 1.0)});
  ASSERT_FALSE(twice.ok());
  EXPECT_NE(twice.status().message().find("twice"), std::string::npos) << twice.status().message();
  EXPECT_FALSE(s.Contains(105));
  std::vector<GraphState> with_unknown;
  with_unknown.push_back(Scalar(106, 6.0));
  EXPECT_FALSE(s.Update(std::move(with_unknown), {BetweenOf(106, 999, 1.0, 1.0)}).ok());
  EXPECT_FALSE(s.Contains(106));
  EXPECT_EQ(s.WindowKeys(), window);
  // Inside the window (older than the newest state) is still fine.
  std::vector<GraphState> inside;
  inside.push_back(Scalar(104, 4.5));
  EXPECT_TRUE(s.Update(std::move(inside), {PriorOn(104, 4.5, 1.0)}).ok());
}

// Linear-Gaussian: the newest state's estimate equals the batch optimum on the data so far,
// with or without a hold (marginalization is exact here).
TEST(FixedLagSmoother, HoldDoesNotChangeALinearProblemsEstimate) {
  FixedLagSmoother::Options o;
  o.lag_s = 1.0;
  o.solver.function_tolerance = o.solver.parameter_tolerance = 1e-14;  // converged to the optimum
  FixedLagSmoother plain(o), held(o);
  held.HoldFrom(2.0);
  for (int k = 0; k <= 8; ++k) {
    ASSERT_TRUE(AddState(&plain, k).ok());
    ASSERT_TRUE(AddState(&held, k).ok());
    if (k == 5) held.Release();
    auto a = plain.Estimate(k), b = held.Estimate(k);
    ASSERT_TRUE(a.ok() && b.ok());
    EXPECT_NEAR((*a)[0], (*b)[0], 1e-6) << "state " << k;
  }
  EXPECT_LE(held.NumStates(), 3u);
}

// Options::held_max_iterations: while held, an update's solve may iterate past
// solver.max_iterations (here a start far from a prior with a small trust region, which LM
// needs many growing steps to cross); not held, the solver's own limit applies.
TEST(FixedLagSmoother, HeldSolvesIterateToHeldMaxIterations) {
  FixedLagSmoother::Options o;
  o.solver.max_iterations = 2;
  o.solver.initial_trust_region_radius = 1e-3;
  o.held_max_iterations = 100;
  auto first_update = [](FixedLagSmoother* s) {
    std::vector<GraphFactor> factors;
    factors.push_back(PriorOn(0, 1000.0, 1.0));
    return s->Update({Scalar(0, 0.0)}, std::move(factors));
  };
  FixedLagSmoother plain(o), held(o);
  held.HoldFrom(0.0);
  auto a = first_update(&plain);
  auto b = first_update(&held);
  ASSERT_TRUE(a.ok() && b.ok());
  EXPECT_LE(a->ceres_iterations, 3);  // iteration 0 and at most 2 steps
  EXPECT_FALSE(a->converged);
  EXPECT_GT(b->ceres_iterations, 3);
  EXPECT_TRUE(b->converged);
  auto xa = plain.Estimate(0), xb = held.Estimate(0);
  ASSERT_TRUE(xa.ok() && xb.ok());
  EXPECT_LT((*xa)[0], 100.0);  // cut short far from the optimum
  EXPECT_NEAR((*xb)[0], 1000.0, 1e-3);

  // 0 (the default): the solver's limit also while held.
  o.held_max_iterations = 0;
  FixedLagSmoother held_default(o);
  held_default.HoldFrom(0.0);
  auto c = first_update(&held_default);
  ASSERT_TRUE(c.ok());
  EXPECT_LE(c->ceres_iterations, 3);
}

}  // namespace
}  // namespace walkgraph
