// What the batch solve and the fixed-lag smoother share beyond graph.h: Ceres' solver options
// and the marginal-covariance extractor over keyed parameter blocks.
#ifndef WALKGRAPH_SRC_SMOOTHERS_GRAPH_INTERNAL_H_
#define WALKGRAPH_SRC_SMOOTHERS_GRAPH_INTERNAL_H_

#include <algorithm>
#include <cstdint>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include <ceres/loss_function.h>
#include <ceres/problem.h>
#include <ceres/solver.h>
#include <Eigen/Core>

#include "walkgraph/graph.h"
#include "walkgraph/smoothers/graph_options.h"
#include "walkgraph/status.h"

namespace walkgraph {
namespace internal {

// The robust loss `kind` (graph_options.h) at `scale` (in σ of the whitened residual); nullptr
// for LossKind::kNone.
std::unique_ptr<ceres::LossFunction> MakeLoss(LossKind kind, double scale);

// A problem over blocks and costs its owner keeps (FactorGraph, FixedLagSmoother: they own
// every cost function, loss and manifold); fast_removal for one that removes blocks.
ceres::Problem::Options BorrowingProblemOptions(bool fast_removal);

// Calls a user's factor hook (graph.h UserFactorsFn) with the graph's pose times and checks
// what it returned: each factor a cost function with one key per parameter block. Errors are
// prefixed "user factors: " (the hook's) or "user factor i: ".
StatusOr<std::vector<GraphFactor>> CallUserFactors(const UserFactorsFn& fn, const Walk& walk,
                                                   const std::vector<double>& pose_times);

// The one place that fills ceres::Solver::Options (silent, LM).
ceres::Solver::Options ToCeres(const SolverOptions& options);
// Termination of a Ceres summary; a failure or an unusable solution is an error naming `who`.
StatusOr<Termination> CheckSummary(const ceres::Solver::Summary& summary, const char* who);

// The timed keys of a key → state map (FactorGraph's, the FixedLagSmoother's) by time, then key.
template <typename StateMap>
std::vector<Key> KeysByTime(const StateMap& states) {
  std::vector<std::pair<double, Key>> timed;
  for (const auto& [key, st] : states) {
    if (st.spec.t_s) timed.emplace_back(*st.spec.t_s, key);
  }
  std::sort(timed.begin(), timed.end());
  std::vector<Key> keys;
  for (const auto& tk : timed) keys.push_back(tk.second);
  return keys;
}

// A keyed parameter block of a problem: its key, storage and time (none: static), and its
// place among the blocks of its time in the chain layout (KeyedMarginalCovariances; ties: key
// order): the order the states were added. A chain's half-bandwidth, and with it the banded
// solve's cost, depends on it: the INS states added p, v, q, b_g, b_a span 23 columns per
// IMU segment, in key order (a, g, q, v, x) 29.
struct KeyedBlock {
  Key key = 0;
  double* value = nullptr;
  std::optional<double> t_s;
  std::uint64_t order = 0;
};
// A problem's keyed blocks, sorted by key, each key once (SortKeyedBlocks).
using KeyedBlocks = std::vector<KeyedBlock>;

// Sorts `blocks` by key (their keys must be distinct).
void SortKeyedBlocks(KeyedBlocks* blocks);

// The block of `key` in sorted `blocks`, nullptr when there is none.
const KeyedBlock* FindKeyedBlock(const KeyedBlocks& blocks, Key key);

// Joint marginal covariances of `groups` (see MarginalCovariances in graph.h): the banded chain
// solve when every group lies at one timestamp (the timed blocks by time, then `order`), else
// ceres::Covariance per group.
StatusOr<std::vector<Eigen::MatrixXd>> KeyedMarginalCovariances(
    ceres::Problem* problem, const KeyedBlocks& blocks, const std::vector<std::vector<Key>>& groups,
    const char* who);

// NumericalError naming the group when a marginal covariance has a diagonal entry that is not
// positive and finite (a state no factor constrains: the banded solve gives zeros for it).
Status CheckDefinedCovariances(const std::vector<Eigen::MatrixXd>& covariances,
                               const std::vector<std::vector<Key>>& groups, const char* who);

// InvalidArgument when a key appears twice in `keys` (Ceres aborts on a repeated block pair).
Status CheckDistinctKeys(const std::vector<Key>& keys, const char* who);

// One group of keys' joint marginal covariance from the Ceres-evaluated Jacobian (losses applied
// as ceres::Covariance applies them), columns in key order, so the result does not depend on
// where the blocks live in memory: the fallback, and small queries.
StatusOr<Eigen::MatrixXd> CeresMarginalCovariance(ceres::Problem* problem,
                                                  const KeyedBlocks& blocks,
                                                  const std::vector<Key>& keys, const char* who);

// Do the anchors disagree with one walk-wide path loss? `residuals` holds each RSS reading's
// anchor and whitened residual (measured − model) / σ in time order. Per anchor with at least
// 5 readings, z = mean / (s / √n_eff), s the residuals' standard deviation and
// n_eff = n (1 − ρ) / (1 + ρ) with ρ > 0 their lag-1 autocorrelation (shadowing along a walk is
// correlated: n readings are worth fewer); residuals are clipped at ±3 (NLOS). Under one shared
// model T = Σ z² ~ χ²(anchors); the anchors disagree when T exceeds its quantile at the normal
// quantile z_level (Wilson–Hilferty: k (1 − 2/(9k) + z √(2/(9k)))³).
struct AnchorOffsetTest {
  double statistic = 0.0;  // T
  int anchors = 0;         // degrees of freedom
  double critical = 0.0;   // χ²(anchors) quantile
  bool disagree = false;
};
AnchorOffsetTest TestAnchorOffsets(const std::vector<std::pair<int, double>>& residuals,
                                   double z_level);

}  // namespace internal
}  // namespace walkgraph

#endif  // WALKGRAPH_SRC_SMOOTHERS_GRAPH_INTERNAL_H_
