// A fixed-lag smoother over Ceres cost functions, with the shape of GTSAM's
// BatchFixedLagSmoother:
//
//   FixedLagSmoother s(options);                      // lag in seconds
//   s.Update(new_states, new_factors);                // add, solve, marginalize
//   s.Estimate(key);  s.MarginalCovariance(key);
//
// States are parameter blocks identified by a Key, each with a timestamp (or none: a
// "static" state such as a path-loss or bias block, which stays in the window for the whole
// run) and an optional ceres::Manifold. Factors are cost functions over states by key, with an
// optional robust loss.
//
// Update(): adds the new states and factors to one persistent ceres::Problem (built once and
// edited in place, never rebuilt), solves it, then marginalizes every timed state older than
// t_newest − lag (at once per Options::marginalize_batch_s when that is set): the factors touching
// those states (including the previous prior) are linearized at the just-solved estimate and
// replaced by one MarginalizationPrior on their Markov blanket (smoothers/marginalization.h). A
// marginalized state's estimate at that moment is its lagged (smoothed with `lag` seconds of future
// data) estimate; it is handed to `on_marginalize`, and the state and its factors are freed, so
// memory stays bounded.
//
// Linearization-point policy: the prior's Jacobian is fixed at its linearization point (first
// estimate, in each block's tangent space); every other factor is relinearized at each solve,
// including those on the blanket states (so the prior and the remaining factors can be
// linearized at slightly different points — the usual sliding-window approximation, exact for
// linear-Gaussian problems, where fixed-lag equals batch on the data seen so far).
// Guards: an update with nothing old enough marginalizes nothing; a window that stops moving
// (no new states) keeps its states; factors on an unknown or already-marginalized key are an
// error; a marginalized state with only a prior just moves that prior to its blanket (or drops
// it if it had none).
#ifndef WALKGRAPH_SMOOTHERS_FIXED_LAG_SMOOTHER_H_
#define WALKGRAPH_SMOOTHERS_FIXED_LAG_SMOOTHER_H_

#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include <ceres/ceres.h>
#include <Eigen/Core>

#include "walkgraph/graph.h"
#include "walkgraph/smoothers/marginalization.h"
#include "walkgraph/status.h"

namespace walkgraph {

class FixedLagSmoother {
 public:
  static SolverOptions WindowSolverDefaults() {
    SolverOptions o;
    o.max_iterations = 10;
    return o;
  }
  struct Options {
    double lag_s = 10.0;
    // Each update's solve (graph.h). A warm-started window can take the Gauss–Newton step
    // at once: set solver.initial_trust_region_radius high (Ceres' default, 1e4, suits a cold
    // start; with it the soft modes of a long chain, eigenvalues ≪ 1e-4 · diagonal, are damped
    // and LM needs several growing steps).
    SolverOptions solver = WindowSolverDefaults();
    double eigenvalue_tolerance = 1e-12;  // marginalization (see marginalization.h)
    // An update whose new factors all have ‖r‖² ≤ this at the current estimate is not solved
    // (it cannot move the optimum; see Update). Negative: always solve.
    double vanishing_residual_sq = 1e-20;
    // States leave in batches: marginalization runs once the oldest timed state is older than
    // t_newest − lag_s − marginalize_batch_s, and then takes every state older than
    // t_newest − lag_s. Every state is still smoothed with at least lag_s of future data; the
    // window spans lag_s … lag_s + marginalize_batch_s, and the marginalization (and any
    // covariance query in before_marginalize) runs once per batch instead of once per state.
    // 0: every update marginalizes what is older than the lag (GTSAM's behaviour).
    double marginalize_batch_s = 0.0;
    // > 0: the iteration limit of an update's solve while the window is held (HoldFrom): the
    // linearization point there is poor (e.g. after an IMU gap), and a solve cut short leaves
    // states far from the optimum that later updates start from. 0: solver.max_iterations.
    int held_max_iterations = 0;
  };
  struct UpdateResult {
    int ceres_iterations = 0;
    int marginalized_states = 0;
    double final_cost = 0.0;
    bool converged = true;
    bool solved = true;  // false when the update carried no information (see Options)
  };
  // Called for each state as it leaves the window: key, time, final (lagged) estimate.
  using MarginalizeCallback =
      std::function<void(Key key, double t_s, const std::vector<double>& value)>;

  explicit FixedLagSmoother(Options options);
  ~FixedLagSmoother();
  FixedLagSmoother(const FixedLagSmoother&) = delete;
  FixedLagSmoother& operator=(const FixedLagSmoother&) = delete;

  void set_on_marginalize(MarginalizeCallback cb) { on_marginalize_ = std::move(cb); }
  // Called with the keys about to be marginalized while they are still in the window (before
  // on_marginalize), e.g. to query their MarginalCovariance.
  void set_before_marginalize(std::function<void(const std::vector<Key>& keys)> cb) {
    before_marginalize_ = std::move(cb);
  }

  // Holds the window open: while set, no state at or after `t_s` is marginalized, whatever the
  // lag (the window grows until Release). For a stretch the linearization point of which is
  // still poor, e.g. the states after an IMU gap while their heading is undetermined: a prior
  // taken there would lock the error in.
  void HoldFrom(double t_s) { hold_from_s_ = t_s; }
  void Release() { hold_from_s_.reset(); }
  bool holding() const { return hold_from_s_.has_value(); }

  StatusOr<UpdateResult> Update(std::vector<GraphState> new_states,
                                std::vector<GraphFactor> new_factors);

  // Current estimate of a state in the window (or a static state).
  StatusOr<std::vector<double>> Estimate(Key key) const;
  // Marginal covariance of a state in its tangent space, given everything in the window
  // (including the marginalization prior). Fails (never aborts) when it is not positive
  // definite, e.g. an unobservable direction.
  StatusOr<Eigen::MatrixXd> MarginalCovariance(Key key);
  // Joint marginal covariance of several states (tangent spaces stacked in `keys` order).
  StatusOr<Eigen::MatrixXd> MarginalCovariance(const std::vector<Key>& keys);
  // Several joint covariances at once, each group the states of one timestamp (or a subset):
  // one banded solve over the window (chain_covariance.h) when the window is chain-structured,
  // else one MarginalCovariance per group.
  StatusOr<std::vector<Eigen::MatrixXd>> MarginalCovariances(
      const std::vector<std::vector<Key>>& groups);
  // Timed states still in the window, oldest first.
  std::vector<Key> WindowKeys() const;
  bool Contains(Key key) const { return states_.count(key) > 0; }
  // What the window holds now (timed and static states; factors including the prior): the
  // smoother's memory, bounded by the lag however long the walk.
  size_t NumStates() const { return states_.size(); }
  size_t NumFactors() const { return factors_.size(); }
  // Finishes a run: hands every timed state still in the window to on_marginalize (oldest
  // first, with its current estimate) without removing it.
  void Flush() const;

 private:
  struct State {
    GraphState spec;
    std::vector<double> value;  // the solver's parameter block (stable address)
    std::set<int> factors;      // ids of factors touching it
    std::uint64_t order = 0;    // states added before it (marginalized ones included)
  };
  struct Factor {
    GraphFactor spec;
    ceres::ResidualBlockId residual = nullptr;
  };

  Status CheckNewStates(const std::vector<GraphState>& new_states) const;
  Status CheckNewFactors(const std::vector<GraphState>& new_states,
                         const std::vector<GraphFactor>& new_factors) const;
  Status AddFactor(GraphFactor f);
  Status MarginalizeOlderThan(double cutoff_s, int* count);

  Options options_;
  std::unique_ptr<ceres::Problem> problem_;
  std::map<Key, State> states_;
  std::map<int, Factor> factors_;
  int next_factor_id_ = 0;
  std::uint64_t next_state_order_ = 0;
  std::optional<double> newest_t_;
  std::optional<double> marginalized_before_s_;  // states before it have left the window
  std::optional<double> hold_from_s_;
  bool solved_ = false;  // a solve has run: the estimate is (near) optimal
  MarginalizeCallback on_marginalize_;
  std::function<void(const std::vector<Key>&)> before_marginalize_;
};

// Wall-clock figures of a run's updates (seconds each): update_latency_median_s, _p99_s and
// _max_s into `timings` (EstimateResult::timings), nearest-rank percentiles; 0 when empty.
void AddUpdateLatencyTimings(std::vector<double> latency_s, std::map<std::string, double>* timings);

}  // namespace walkgraph

#endif  // WALKGRAPH_SMOOTHERS_FIXED_LAG_SMOOTHER_H_
