// The factor-graph core that walkgraph's smoothers and users' code share, in the shape of
// GTSAM's NonlinearFactorGraph + Values, over Ceres cost functions:
//
//   FactorGraph graph;
//   graph.AddState({Symbol('x', 0), 0.0, {0.0, 0.0}});          // key, time, initial value
//   graph.AddFactor({std::move(cost), nullptr, {Symbol('x', 0)}});
//   StatusOr<SolveSummary> s = SolveBatch(&graph, SolverOptions());
//   graph.Value(Symbol('x', 0));  MarginalCovariances(&graph, {{Symbol('x', 0)}});
//
// States are parameter blocks named by a Key (a letter and an index, GTSAM's Symbol), each with
// an optional timestamp (none: a "static" state such as a path-loss or bias block), an optional
// ceres::Manifold, and a constant flag. Factors are cost functions (factors/) over states by key,
// with an optional robust loss. The same GraphState/GraphFactor feed the FixedLagSmoother
// (smoothers/fixed_lag_smoother.h), which is this container's sliding-window solver.
//
// The keys walkgraph's own graphs use (the letters are reserved for them; a user's factor may
// refer to any of them):
//   step graph (fg-batch, fg-window):  x(k) position (x, y) of node k,  h(k) heading θ_k,
//     l(g) path loss (A, η) of group g (0, or the anchor index with path_loss: per-anchor or
//     hierarchical), m(0) hierarchical's walk-wide mean path loss (A, η),
//     b(g) range bias, s(g) range scale, g(0) gyro bias, c(0) step-length scale, p(a)
//     horizontal position (x, y) of anchor index a when it is not surveyed (unknown or
//     uncertain: walk.h Anchor).
//   foot-INS graph (fg-ins-batch, fg-ins-window):  x(i) position (x, y, z) of state
//     i, v(i) velocity, q(i) attitude (NavQuaternionManifold), g(i) gyro bias, a(i) accelerometer
//     bias; l(0) path loss (A, η) (hierarchical: m(0) the mean, l(a) anchor index a's), b(a)
//     range bias of anchor index a, f(0) the magnetic field's direction (stance magnetometer),
//     p(a) horizontal position of anchor index a when it is not surveyed, s(0) the range scale
//     its range factor takes (held at 0).
#ifndef WALKGRAPH_GRAPH_H_
#define WALKGRAPH_GRAPH_H_

#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <ceres/cost_function.h>
#include <ceres/loss_function.h>
#include <ceres/manifold.h>
#include <Eigen/Core>

#include "walkgraph/status.h"

namespace ceres {
class Problem;
}

namespace walkgraph {

// A state's name: Symbol(letter, index) packs a letter (any char but '\0') and an index below
// 2⁵⁶ into one integer, so keys sort by letter, then index.
using Key = std::int64_t;
inline constexpr std::uint64_t kMaxSymbolIndex = (std::uint64_t{1} << 56) - 1;
constexpr Key Symbol(char letter, std::uint64_t index) {
  return static_cast<Key>((static_cast<std::uint64_t>(static_cast<unsigned char>(letter)) << 56) |
                          (index & kMaxSymbolIndex));
}
constexpr char SymbolLetter(Key key) {
  return static_cast<char>(static_cast<std::uint64_t>(key) >> 56);
}
constexpr std::uint64_t SymbolIndex(Key key) {
  return static_cast<std::uint64_t>(key) & kMaxSymbolIndex;
}
std::string KeyToString(Key key);  // "x12"

struct GraphState {
  Key key = 0;
  std::optional<double> t_s;                        // none: static (never marginalized)
  std::vector<double> value;                        // initial estimate (ambient)
  std::shared_ptr<const ceres::Manifold> manifold;  // nullptr = Euclidean
  bool constant = false;                            // held fixed by the solver
};

// A factor owns its cost function jointly (a user's factor may be handed to the batch solve and
// to a window pass of the same walk).
struct GraphFactor {
  std::shared_ptr<ceres::CostFunction> cost;
  std::shared_ptr<const ceres::LossFunction> loss;  // nullptr = squared loss
  std::vector<Key> keys;                            // in the cost function's block order
  // >= 0: the factors whose noise model one scale multiplies (EstimateNoiseScales); -1: none.
  int noise_group = -1;
};

// The extension hook of every factor-graph estimator (StepGraphOptions::user_factors for fg-batch
// and fg-window, InsGraphOptions::user_factors for fg-ins-batch and fg-ins-window): called
// once per walk, after the built-in factors are made, with the times of the graph's poses
// (pose_times[k] is the time of pose k, whose position key is Symbol('x', k)); the factors it
// appends are added after the built-in ones, by the batch solve and by the window alike. A
// window adds a factor with its newest pose, so there it may span at most the lag. A non-OK
// Status stops the run with that message.
struct Walk;
using UserFactorsFn = std::function<Status(const Walk& walk, const std::vector<double>& pose_times,
                                           std::vector<GraphFactor>* factors)>;

// Ceres' options for a batch solve or a window update, in one place.
enum class LinearSolver { kSparseNormalCholesky, kDenseNormalCholesky, kDenseQr };
struct SolverOptions {
  int max_iterations = 100;
  double function_tolerance = 1e-6;
  double parameter_tolerance = 1e-8;
  double gradient_tolerance = 1e-10;
  // Levenberg–Marquardt's starting trust-region radius (Ceres' default 1e4).
  double initial_trust_region_radius = 1e4;
  LinearSolver linear_solver = LinearSolver::kSparseNormalCholesky;
  // With kSparseNormalCholesky: SuiteSparse (CHOLMOD), or Eigen's SimplicialLDLT (less set-up
  // per solve, which pays on small, repeatedly solved windows).
  bool eigen_sparse = false;
  int num_threads = 1;
  Status Validate() const;
};

enum class Termination { kConverged, kNoConvergence, kFailure };
const char* ToString(Termination t);

struct SolveSummary {
  int iterations = 0;
  double initial_cost = 0.0, final_cost = 0.0;
  Termination termination = Termination::kConverged;
  double time_s = 0.0;
  int num_residuals = 0, num_parameters = 0;  // tangent dimensions, reduced (constants out)
  // 2F/(m − n): ≈ 1 when the residuals are as large as their noise models say.
  double normalized_cost() const;
};

// How far a group of factors' noise model is from its residuals at the current values.
struct NoiseScale {
  double scale = 1.0;       // σ the residuals show / σ the factors assume
  int rows = 0;             // residual rows the scale was taken from
  double redundancy = 0.0;  // Σ (1 − h_i) over the group's rows
};

class FactorGraph {
 public:
  FactorGraph();
  ~FactorGraph();
  FactorGraph(const FactorGraph&) = delete;
  FactorGraph& operator=(const FactorGraph&) = delete;

  // Errors: a key already present, an empty value, a manifold whose ambient size differs.
  Status AddState(GraphState state);
  // Errors: no cost function, a key not in the graph, a block size that differs from the
  // cost function's.
  Status AddFactor(GraphFactor factor);

  bool Contains(Key key) const { return states_.count(key) > 0; }
  StatusOr<std::vector<double>> Value(Key key) const;
  Status SetValue(Key key, const std::vector<double>& value);  // same size
  Status SetConstant(Key key, bool constant);
  // The keys with a timestamp, by time (then key); the static ones.
  std::vector<Key> TimedKeys() const;
  std::vector<Key> StaticKeys() const;
  std::optional<double> Time(Key key) const;
  size_t num_states() const { return states_.size(); }
  size_t num_factors() const { return factors_.size(); }
  // The residuals of factor `index` (in the order added) at the current values, without its
  // robust loss. Errors: no such factor, or its cost function fails to evaluate.
  StatusOr<Eigen::VectorXd> FactorResiduals(size_t index) const;

 private:
  friend StatusOr<SolveSummary> SolveBatch(FactorGraph* graph, const SolverOptions& options);
  friend StatusOr<std::vector<Eigen::MatrixXd>> MarginalCovariances(
      FactorGraph* graph, const std::vector<std::vector<Key>>& groups);
  friend StatusOr<std::map<int, NoiseScale>> EstimateNoiseScales(FactorGraph* graph, int min_rows);
  struct State {
    GraphState spec;          // spec.value is the solver's parameter block (stable address)
    std::uint64_t order = 0;  // states added before it
  };
  std::map<Key, State> states_;
  std::vector<GraphFactor> factors_;
  std::unique_ptr<ceres::Problem> problem_;
};

// Solves the whole graph (Levenberg–Marquardt) from the states' current values and leaves the
// optimum in them. Fails (never aborts) on invalid options, and when Ceres reports a failure
// or a solution that is not usable; an iteration limit is not a failure (termination says).
StatusOr<SolveSummary> SolveBatch(FactorGraph* graph, const SolverOptions& options);

// Joint marginal covariances at the current values, one per group of keys (tangent spaces
// stacked in the group's order; constant states contribute nothing). A graph whose timed
// states form a chain (each factor on nearby times, plus static states) takes the banded
// solve of smoothers/chain_covariance.h; any other, ceres::Covariance. Fails (never aborts)
// when the information is not positive definite (an unobservable direction).
StatusOr<std::vector<Eigen::MatrixXd>> MarginalCovariances(
    FactorGraph* graph, const std::vector<std::vector<Key>>& groups);

// Variance-component estimation (Förstner 1979; Koch & Kusche, J. Geodesy 76, 2002): for each
// noise group (GraphFactor::noise_group), the scale by which its factors' σ should be multiplied
// for their whitened residuals to be as large as they assume, at the current values. A row's
// redundancy is 1 − h_i, h_i = j_iᵀ H⁻¹ j_i its leverage under the information H the solver
// sees (losses applied); r_i is its residual without the robust loss.
//   - A group without a robust loss: scale² = Σ r_i² / Σ (1 − h_i) (Förstner's estimate), when
//     Σ (1 − h_i) >= 2: a group the other factors barely check (a heading-increment chain with
//     radio alone to hold it) has little redundancy, and its scale is then left out.
//   - A group with a robust loss on some factor: scale = 1.4826 · median |r_i| / √(1 − h_i)
//     over the rows with 1 − h_i >= 0.05, when there are at least `min_rows` (MAD: NLOS-like
//     outliers do not inflate it).
// At most 500 rows per group are read, evenly spread (deterministic). Groups left out are not
// in the map. Fails when H is singular or the Jacobian cannot be evaluated.
StatusOr<std::map<int, NoiseScale>> EstimateNoiseScales(FactorGraph* graph, int min_rows = 30);

}  // namespace walkgraph

#endif  // WALKGRAPH_GRAPH_H_
