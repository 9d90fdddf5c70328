#include "walkgraph/graph.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <map>
#include <numeric>
#include <set>
#include <string>
#include <tuple>
#include <utility>

#include <ceres/ceres.h>
#include <Eigen/SparseCholesky>

#include "smoothers/graph_internal.h"
#include "walkgraph/cancel.h"
#include "walkgraph/progress.h"
#include "walkgraph/smoothers/chain_covariance.h"

namespace walkgraph {

std::string KeyToString(Key key) {
  const char c = SymbolLetter(key);
  const std::string letter = c >= 33 && c < 127 ? std::string(1, c) : "#" + std::to_string(+c);
  return letter + std::to_string(SymbolIndex(key));
}

Status SolverOptions::Validate() const {
  if (max_iterations < 1 || !(function_tolerance >= 0) || !(parameter_tolerance >= 0) ||
      !(gradient_tolerance >= 0) || !(initial_trust_region_radius > 0) || num_threads < 1 ||
      num_threads > 256) {
    return InvalidArgument(
        "solver options: need max_iterations >= 1, tolerances >= 0, "
        "initial_trust_region_radius > 0, num_threads in [1, 256]");
  }
  return Status::Ok();
}

const char* ToString(Termination t) {
  switch (t) {
    case Termination::kConverged:
      return "converged";
    case Termination::kNoConvergence:
      return "no-convergence";
    default:
      return "failure";
  }
}

double SolveSummary::normalized_cost() const {
  return 2.0 * final_cost / std::max(1, num_residuals - num_parameters);
}

namespace internal {

std::unique_ptr<ceres::LossFunction> MakeLoss(LossKind kind, double scale) {
  switch (kind) {
    case LossKind::kHuber:
      return std::make_unique<ceres::HuberLoss>(scale);
    case LossKind::kCauchy:
      return std::make_unique<ceres::CauchyLoss>(scale);
    case LossKind::kSoftL1:
      return std::make_unique<ceres::SoftLOneLoss>(scale);
    case LossKind::kArctan:
      return std::make_unique<ceres::ArctanLoss>(scale);
    case LossKind::kTukey:
      return std::make_unique<ceres::TukeyLoss>(scale);
    default:
      return nullptr;
  }
}

namespace {

// Every solve stops at the end of the iteration in which cancellation was requested
// (RequestCancel: a signal in the CLI, Ctrl-C in Python); CheckSummary reports it as kCancelled.
// After each solver iteration: a signal stops the solve; the iteration is a sign of life for a
// long walk's progress report (progress.h ReportEstimatorProgress: the solver cannot tell its
// fraction, so the fraction reached so far is repeated).
class CancelCallback : public ceres::IterationCallback {
 public:
  ceres::CallbackReturnType operator()(const ceres::IterationSummary&) override {
    ReportEstimatorProgress(0.0);
    return CancelRequested() ? ceres::SOLVER_ABORT : ceres::SOLVER_CONTINUE;
  }
};

}  // namespace

ceres::Solver::Options ToCeres(const SolverOptions& o) {
  static CancelCallback cancel;
  ceres::Solver::Options so;
  so.callbacks.push_back(&cancel);
  switch (o.linear_solver) {
    case LinearSolver::kDenseNormalCholesky:
      so.linear_solver_type = ceres::DENSE_NORMAL_CHOLESKY;
      break;
    case LinearSolver::kDenseQr:
      so.linear_solver_type = ceres::DENSE_QR;
      break;
    default:
      so.linear_solver_type = ceres::SPARSE_NORMAL_CHOLESKY;
      so.sparse_linear_algebra_library_type =
          o.eigen_sparse ? ceres::EIGEN_SPARSE : ceres::SUITE_SPARSE;
  }
  so.max_num_iterations = o.max_iterations;
  so.function_tolerance = o.function_tolerance;
  so.parameter_tolerance = o.parameter_tolerance;
  so.gradient_tolerance = o.gradient_tolerance;
  so.initial_trust_region_radius = o.initial_trust_region_radius;
  so.num_threads = o.num_threads;
  so.logging_type = ceres::SILENT;
  so.minimizer_progress_to_stdout = false;
  return so;
}

StatusOr<Termination> CheckSummary(const ceres::Solver::Summary& s, const char* who) {
  if (s.termination_type == ceres::USER_FAILURE && CancelRequested()) {
    return Cancelled(std::string(who) + ": interrupted");
  }
  if (s.termination_type == ceres::FAILURE || !s.IsSolutionUsable()) {
    return NumericalError(std::string(who) + ": Ceres failed: " + s.message);
  }
  return s.termination_type == ceres::CONVERGENCE ? Termination::kConverged
                                                  : Termination::kNoConvergence;
}

void SortKeyedBlocks(KeyedBlocks* blocks) {
  auto by_key = [](const KeyedBlock& a, const KeyedBlock& b) { return a.key < b.key; };
  if (!std::is_sorted(blocks->begin(), blocks->end(), by_key)) {
    std::sort(blocks->begin(), blocks->end(), by_key);
  }
}

const KeyedBlock* FindKeyedBlock(const KeyedBlocks& blocks, Key key) {
  auto it = std::lower_bound(blocks.begin(), blocks.end(), key,
                             [](const KeyedBlock& b, Key k) { return b.key < k; });
  return it != blocks.end() && it->key == key ? &*it : nullptr;
}

Status CheckDistinctKeys(const std::vector<Key>& keys, const char* who) {
  std::vector<Key> sorted = keys;
  std::sort(sorted.begin(), sorted.end());
  const auto twice = std::adjacent_find(sorted.begin(), sorted.end());
  if (twice == sorted.end()) return Status::Ok();
  return InvalidArgument(std::string(who) + ": " + KeyToString(*twice) +
                         " named twice in one covariance request; expected distinct keys");
}

namespace {

// The problem's variable blocks in an order that does not depend on where they live in memory:
// the keyed ones by key, then any others in the order the problem holds them (ceres::Covariance
// orders its columns by address, so its round-off — and a window's bytes — would depend on what
// else the process allocated before).
std::vector<double*> VariableBlocksByKey(ceres::Problem* problem, const KeyedBlocks& keyed) {
  std::vector<double*> all;
  problem->GetParameterBlocks(&all);
  std::vector<double*> keyed_values;
  keyed_values.reserve(keyed.size());
  for (const KeyedBlock& kb : keyed) keyed_values.push_back(kb.value);
  std::vector<double*> sorted_keyed = keyed_values;
  std::sort(sorted_keyed.begin(), sorted_keyed.end());
  for (double* b : all) {
    if (!std::binary_search(sorted_keyed.begin(), sorted_keyed.end(), b)) {
      keyed_values.push_back(b);
    }
  }
  std::vector<double*> order;
  order.reserve(keyed_values.size());
  for (double* b : keyed_values) {
    if (problem->HasParameterBlock(b) && !problem->IsParameterBlockConstant(b) &&
        problem->ParameterBlockTangentSize(b) > 0) {
      order.push_back(b);
    }
  }
  return order;
}

// H = JᵀJ of a Jacobian (CRS, `total` columns) and its sparse LDLᵀ. A column no row touches is
// left out of H (as ceres::Covariance leaves it): keep maps a Jacobian column to its column of
// H, or -1. jac is empty (no column) when no row touches any.
struct Information {
  Eigen::SparseMatrix<double, Eigen::RowMajor> jac;
  std::vector<int> keep;
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> ldlt;
};

Status FactorInformation(const ceres::CRSMatrix& crs, int total, const char* who,
                         Information* out) {
  out->keep.assign(total, -1);
  for (int c : crs.cols) out->keep[c] = 0;
  int kept = 0;
  for (int& k : out->keep) k = k == 0 ? kept++ : -1;
  std::vector<Eigen::Triplet<double>> entries;
  entries.reserve(crs.values.size());
  for (int r = 0; r < crs.num_rows; ++r) {
    for (int i = crs.rows[r]; i < crs.rows[r + 1]; ++i) {
      entries.emplace_back(r, out->keep[crs.cols[i]], crs.values[i]);
    }
  }
  out->jac.resize(crs.num_rows, kept);
  if (kept == 0) return Status::Ok();
  out->jac.setFromTriplets(entries.begin(), entries.end());
  const Eigen::SparseMatrix<double> info = out->jac.transpose() * out->jac;
  out->ldlt.compute(info);
  const Eigen::VectorXd d =
      out->ldlt.info() == Eigen::Success ? out->ldlt.vectorD() : Eigen::VectorXd();
  if (d.size() != kept || !d.allFinite() || !(d.minCoeff() > 1e-14 * d.maxCoeff())) {
    return NumericalError(std::string(who) + ": covariance not computable (rank-deficient)");
  }
  return Status::Ok();
}

}  // namespace

// The information H = JᵀJ (Jacobian in the tangent spaces, losses applied as the solver applies
// them: what ceres::Covariance uses) in VariableBlocksByKey's order, factored by a sparse LDLᵀ
// (AMD ordering, from the pattern alone), and solved for the requested blocks' columns.
// Rank-deficient as ceres::Covariance's DENSE_SVD judges it: the smallest pivot below 1e-14 of
// the largest (its default min_reciprocal_condition_number).
StatusOr<Eigen::MatrixXd> CeresMarginalCovariance(ceres::Problem* problem,
                                                  const KeyedBlocks& blocks_by_key,
                                                  const std::vector<Key>& keys, const char* who) {
  WG_RETURN_IF_ERROR(CheckDistinctKeys(keys, who));
  ceres::Problem::EvaluateOptions eo;
  eo.parameter_blocks = VariableBlocksByKey(problem, blocks_by_key);
  std::map<const double*, int> column;  // each variable block's first column in H
  int total = 0;
  for (double* b : eo.parameter_blocks) {
    column[b] = total;
    total += problem->ParameterBlockTangentSize(b);
  }
  std::vector<int> cols, sizes;  // per requested key
  int n = 0;
  for (Key key : keys) {
    const KeyedBlock* kb = FindKeyedBlock(blocks_by_key, key);
    if (kb == nullptr) {
      return NotFound(std::string(who) + ": " + KeyToString(key) + " not in the graph");
    }
    if (problem->IsParameterBlockConstant(kb->value)) {
      return FailedPrecondition(std::string(who) + ": " + KeyToString(key) + " is held constant");
    }
    const auto it = column.find(kb->value);
    if (it == column.end()) {
      return NumericalError(std::string(who) + ": " + KeyToString(key) + " has no tangent space");
    }
    cols.push_back(it->second);
    sizes.push_back(problem->ParameterBlockTangentSize(kb->value));
    n += sizes.back();
  }
  ceres::CRSMatrix crs;
  if (!problem->Evaluate(eo, nullptr, nullptr, nullptr, &crs)) {
    return NumericalError(std::string(who) + ": the Jacobian could not be evaluated");
  }
  // A requested block no factor touches comes back zero (CheckDefinedCovariances names it).
  Information info;
  WG_RETURN_IF_ERROR(FactorInformation(crs, total, who, &info));
  const std::vector<int>& keep = info.keep;
  const int kept = static_cast<int>(info.jac.cols());
  if (kept == 0) return Eigen::MatrixXd(Eigen::MatrixXd::Zero(n, n));
  Eigen::MatrixXd unit = Eigen::MatrixXd::Zero(kept, n);
  for (size_t i = 0, c = 0; i < cols.size(); c += sizes[i], ++i) {
    for (int j = 0; j < sizes[i]; ++j) {
      if (keep[cols[i] + j] >= 0) unit(keep[cols[i] + j], c + j) = 1.0;
    }
  }
  const Eigen::MatrixXd x = info.ldlt.solve(unit);
  Eigen::MatrixXd out = Eigen::MatrixXd::Zero(n, n);
  for (size_t i = 0, r = 0; i < cols.size(); r += sizes[i], ++i) {
    for (int j = 0; j < sizes[i]; ++j) {
      if (keep[cols[i] + j] >= 0) out.row(r + j) = x.row(keep[cols[i] + j]);
    }
  }
  return Eigen::MatrixXd(0.5 * (out + out.transpose()));
}

namespace {

// A keyed block's place in the chain (KeyedMarginalCovariances): its chain state (kStatic:
// none), tangent offset in it and size, and whether it is held constant (each asked of Ceres
// once: its lookups dominate on long walks).
constexpr size_t kStatic = static_cast<size_t>(-1);
struct ChainPlace {
  size_t state = kStatic;
  int offset = 0, size = 0;
  bool constant = false;
};

// The graph as a chain: timed blocks grouped by timestamp, in time order (each timestamp's
// blocks by KeyedBlock::order, then key); the rest static. Fills `place` (by index into `blocks`).
std::vector<std::vector<double*>> ChainOf(ceres::Problem* problem, const KeyedBlocks& blocks,
                                          std::vector<ChainPlace>* place,
                                          std::vector<double*>* statics) {
  std::vector<std::tuple<double, std::uint64_t, size_t>> timed;  // (t, order, index in blocks)
  timed.reserve(blocks.size());
  for (size_t i = 0; i < blocks.size(); ++i) {
    if (blocks[i].t_s) {
      timed.emplace_back(*blocks[i].t_s, blocks[i].order, i);
    } else {
      statics->push_back(blocks[i].value);
    }
  }
  std::sort(timed.begin(), timed.end());
  place->assign(blocks.size(), ChainPlace{});
  std::vector<std::vector<double*>> chain;
  for (size_t i = 0; i < timed.size();) {
    size_t j = i;
    while (j < timed.size() && std::get<0>(timed[j]) == std::get<0>(timed[i])) ++j;
    std::vector<double*> g;
    g.reserve(j - i);
    int off = 0;
    for (; i < j; ++i) {
      const size_t b = std::get<2>(timed[i]);
      double* v = blocks[b].value;
      ChainPlace& p = (*place)[b];
      p = {chain.size(), off, problem->ParameterBlockTangentSize(v),
           problem->IsParameterBlockConstant(v)};
      if (!p.constant) off += p.size;
      g.push_back(v);
    }
    chain.push_back(std::move(g));
  }
  return chain;
}

// A group's joint marginal from its chain state's (`banded`, by chain state): the state's
// whole marginal itself (moved when no other group needs it) when the group is all of the
// state's variable blocks in order, else its rows and columns.
Eigen::MatrixXd GroupMarginal(const std::vector<ChainPlace>& place, const size_t* first,
                              const size_t* last, const std::vector<int>& uses,
                              std::vector<Eigen::MatrixXd>* banded) {
  const size_t state = place[*first].state;
  Eigen::MatrixXd& full = (*banded)[state];
  int n = 0;
  bool whole = true;
  for (const size_t* b = first; b != last; ++b) {
    whole = whole && place[*b].offset == n;
    n += place[*b].size;
  }
  if (whole && n == full.rows()) {
    if (uses[state] == 1) return std::move(full);
    return full;
  }
  Eigen::MatrixXd c(n, n);
  int r = 0;
  for (const size_t* bi = first; bi != last; ++bi) {
    const ChainPlace& pi = place[*bi];
    int col = 0;
    for (const size_t* bj = first; bj != last; ++bj) {
      const ChainPlace& pj = place[*bj];
      c.block(r, col, pi.size, pj.size) = full.block(pi.offset, pj.offset, pi.size, pj.size);
      col += pj.size;
    }
    r += pi.size;
  }
  return c;
}

}  // namespace

Status CheckDefinedCovariances(const std::vector<Eigen::MatrixXd>& covariances,
                               const std::vector<std::vector<Key>>& groups, const char* who) {
  for (size_t i = 0; i < covariances.size() && i < groups.size(); ++i) {
    const Eigen::VectorXd d = covariances[i].diagonal();
    if ((d.array() > 0.0).all() && d.allFinite()) continue;
    std::string keys;
    for (Key k : groups[i]) keys += (keys.empty() ? "" : ", ") + KeyToString(k);
    return NumericalError(std::string(who) + ": the covariance of {" + keys +
                          "} is not defined: a direction of it no factor constrains "
                          "(unconstrained or unobservable)");
  }
  return Status::Ok();
}

StatusOr<std::vector<Eigen::MatrixXd>> KeyedMarginalCovariances(
    ceres::Problem* problem, const KeyedBlocks& blocks, const std::vector<std::vector<Key>>& groups,
    const char* who) {
  std::vector<ChainPlace> place;
  std::vector<double*> statics;
  const std::vector<std::vector<double*>> chain = ChainOf(problem, blocks, &place, &statics);
  // Each group's variable blocks (constant ones contribute nothing; unknown keys are an
  // error), group after group: group i is var[begin[i], begin[i + 1]).
  std::vector<size_t> var, begin;
  var.reserve(blocks.size());
  begin.reserve(groups.size() + 1);
  // Every group within one chain state (one timestamp), or one static block alone (its
  // marginal is the Schur complement's inverse: ChainMarginalCovariances' static_covariances).
  bool usable = true;
  std::vector<int> static_of(groups.size(), -1);  // a one-static group: its place in `statics`
  for (size_t gi = 0; gi < groups.size(); ++gi) {
    const std::vector<Key>& g = groups[gi];
    WG_RETURN_IF_ERROR(CheckDistinctKeys(g, who));
    begin.push_back(var.size());
    for (Key k : g) {
      const KeyedBlock* kb = FindKeyedBlock(blocks, k);
      if (kb == nullptr) {
        return NotFound(std::string(who) + ": " + KeyToString(k) + " not in the graph");
      }
      const size_t b = static_cast<size_t>(kb - blocks.data());
      if (place[b].state == kStatic) {
        if (!problem->IsParameterBlockConstant(kb->value)) {
          var.push_back(b);
          const auto it = std::find(statics.begin(), statics.end(), kb->value);
          if (g.size() == 1 && it != statics.end()) {
            static_of[gi] = static_cast<int>(it - statics.begin());
          } else {
            usable = false;
          }
        }
      } else if (!place[b].constant) {
        var.push_back(b);
      }
    }
  }
  begin.push_back(var.size());
  // Only the chain states of requested groups get their marginals formed.
  std::vector<bool> wanted(chain.size(), false);
  std::vector<int> uses(chain.size(), 0);
  for (size_t i = 0; usable && i < groups.size(); ++i) {
    if (begin[i] == begin[i + 1] || static_of[i] >= 0) continue;
    const size_t state = place[var[begin[i]]].state;
    for (size_t v = begin[i]; v < begin[i + 1]; ++v)
      usable = usable && place[var[v]].state == state;
    if (usable) {
      wanted[state] = true;
      ++uses[state];
    }
  }
  StatusOr<std::vector<Eigen::MatrixXd>> banded = InternalError("not computed");
  std::vector<Eigen::MatrixXd> static_cov;
  if (usable) {
    banded = ChainMarginalCovariances(problem, chain, statics, kChainInlierSigma,
                                      kChainMaxBandwidth, wanted, &static_cov);
    usable = banded.ok() && static_cov.size() == statics.size();
  }
  std::vector<Eigen::MatrixXd> out;
  out.reserve(groups.size());
  for (size_t i = 0; i < groups.size(); ++i) {
    if (begin[i] == begin[i + 1]) {
      out.emplace_back(0, 0);
    } else if (!usable) {  // fall back to Ceres, one group at a time
      std::vector<Key> keys;
      for (size_t v = begin[i]; v < begin[i + 1]; ++v) keys.push_back(blocks[var[v]].key);
      WG_ASSIGN_OR_RETURN(Eigen::MatrixXd c, CeresMarginalCovariance(problem, blocks, keys, who));
      out.push_back(std::move(c));
    } else if (static_of[i] >= 0) {
      out.push_back(static_cov[static_of[i]]);
    } else {
      out.push_back(
          GroupMarginal(place, var.data() + begin[i], var.data() + begin[i + 1], uses, &*banded));
    }
  }
  return out;
}

StatusOr<std::vector<GraphFactor>> CallUserFactors(const UserFactorsFn& fn, const Walk& walk,
                                                   const std::vector<double>& pose_times) {
  std::vector<GraphFactor> factors;
  if (!fn) return factors;
  const Status s = fn(walk, pose_times, &factors);
  if (!s.ok()) return Status(s.code(), "user factors: " + s.message());
  for (size_t i = 0; i < factors.size(); ++i) {
    const std::string where = "user factor " + std::to_string(i) + ": ";
    if (!factors[i].cost) return InvalidArgument(where + "no cost function");
    const size_t blocks = factors[i].cost->parameter_block_sizes().size();
    if (blocks != factors[i].keys.size()) {
      return InvalidArgument(where + "the cost function has " + std::to_string(blocks) +
                             " blocks, " + std::to_string(factors[i].keys.size()) + " keys given");
    }
  }
  return factors;
}

ceres::Problem::Options BorrowingProblemOptions(bool fast_removal) {
  ceres::Problem::Options o;
  o.cost_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  o.loss_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  o.manifold_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  o.enable_fast_removal = fast_removal;
  return o;
}

}  // namespace internal

FactorGraph::FactorGraph()
    : problem_(std::make_unique<ceres::Problem>(internal::BorrowingProblemOptions(false))) {}

FactorGraph::~FactorGraph() {
  problem_.reset();  // before the cost functions and manifolds it points to
}

Status FactorGraph::AddState(GraphState s) {
  auto name = [&s] { return KeyToString(s.key); };  // for messages only
  if (states_.count(s.key)) return InvalidArgument("factor graph: " + name() + " added twice");
  if (s.value.empty()) return InvalidArgument("factor graph: " + name() + " has an empty value");
  if (s.manifold && s.manifold->AmbientSize() != static_cast<int>(s.value.size())) {
    return InvalidArgument("factor graph: the manifold of " + name() + " has another size");
  }
  if (s.t_s && !std::isfinite(*s.t_s)) {
    return InvalidArgument("factor graph: " + name() + " has a non-finite time");
  }
  for (double v : s.value) {
    if (!std::isfinite(v))
      return InvalidArgument("factor graph: " + name() + " has a non-finite value");
  }
  State& st = states_[s.key];
  st.spec = std::move(s);
  st.order = states_.size() - 1;
  problem_->AddParameterBlock(st.spec.value.data(), static_cast<int>(st.spec.value.size()),
                              const_cast<ceres::Manifold*>(st.spec.manifold.get()));
  if (st.spec.constant) problem_->SetParameterBlockConstant(st.spec.value.data());
  return Status::Ok();
}

Status FactorGraph::AddFactor(GraphFactor f) {
  if (!f.cost) return InvalidArgument("factor graph: a factor without a cost function");
  const std::vector<int32_t>& sizes = f.cost->parameter_block_sizes();
  if (sizes.size() != f.keys.size()) {
    return InvalidArgument("factor graph: a factor with " + std::to_string(sizes.size()) +
                           " parameter blocks but " + std::to_string(f.keys.size()) + " keys");
  }
  std::vector<double*> blocks;
  for (size_t i = 0; i < f.keys.size(); ++i) {
    auto it = states_.find(f.keys[i]);
    if (it == states_.end()) {
      return InvalidArgument("factor graph: a factor on " + KeyToString(f.keys[i]) +
                             ", which is not in the graph");
    }
    if (static_cast<int>(it->second.spec.value.size()) != sizes[i]) {
      return InvalidArgument("factor graph: block " + std::to_string(i) + " of a factor has size " +
                             std::to_string(sizes[i]) + " but " + KeyToString(f.keys[i]) + " has " +
                             std::to_string(it->second.spec.value.size()));
    }
    if (std::find(blocks.begin(), blocks.end(), it->second.spec.value.data()) != blocks.end()) {
      return InvalidArgument("factor graph: a factor names " + KeyToString(f.keys[i]) + " twice");
    }
    blocks.push_back(it->second.spec.value.data());
  }
  problem_->AddResidualBlock(f.cost.get(), const_cast<ceres::LossFunction*>(f.loss.get()), blocks);
  factors_.push_back(std::move(f));
  return Status::Ok();
}

StatusOr<std::vector<double>> FactorGraph::Value(Key key) const {
  auto it = states_.find(key);
  if (it == states_.end()) return NotFound("factor graph: no state " + KeyToString(key));
  return it->second.spec.value;
}

Status FactorGraph::SetValue(Key key, const std::vector<double>& value) {
  auto it = states_.find(key);
  if (it == states_.end()) return NotFound("factor graph: no state " + KeyToString(key));
  if (value.size() != it->second.spec.value.size()) {
    return InvalidArgument("factor graph: a value of another size for " + KeyToString(key));
  }
  for (double v : value) {
    if (!std::isfinite(v)) {
      return InvalidArgument("factor graph: a non-finite value for " + KeyToString(key));
    }
  }
  std::copy(value.begin(), value.end(), it->second.spec.value.begin());
  return Status::Ok();
}

Status FactorGraph::SetConstant(Key key, bool constant) {
  auto it = states_.find(key);
  if (it == states_.end()) return NotFound("factor graph: no state " + KeyToString(key));
  it->second.spec.constant = constant;
  double* block = it->second.spec.value.data();
  if (constant) {
    problem_->SetParameterBlockConstant(block);
  } else {
    problem_->SetParameterBlockVariable(block);
  }
  return Status::Ok();
}

StatusOr<Eigen::VectorXd> FactorGraph::FactorResiduals(size_t index) const {
  if (index >= factors_.size()) {
    return NotFound("factor graph: no factor " + std::to_string(index));
  }
  const GraphFactor& f = factors_[index];
  std::vector<const double*> blocks;
  for (Key key : f.keys) blocks.push_back(states_.at(key).spec.value.data());
  Eigen::VectorXd r(f.cost->num_residuals());
  if (!f.cost->Evaluate(blocks.data(), r.data(), nullptr)) {
    return NumericalError("factor graph: factor " + std::to_string(index) +
                          " could not be evaluated");
  }
  return r;
}

std::vector<Key> FactorGraph::TimedKeys() const { return internal::KeysByTime(states_); }

std::vector<Key> FactorGraph::StaticKeys() const {
  std::vector<Key> keys;
  for (const auto& [key, st] : states_) {
    if (!st.spec.t_s) keys.push_back(key);
  }
  return keys;
}

std::optional<double> FactorGraph::Time(Key key) const {
  auto it = states_.find(key);
  return it == states_.end() ? std::nullopt : it->second.spec.t_s;
}

StatusOr<SolveSummary> SolveBatch(FactorGraph* graph, const SolverOptions& options) {
  WG_RETURN_IF_ERROR(options.Validate());
  SolveSummary out;
  if (graph->problem_->NumResidualBlocks() == 0) return out;  // nothing to solve
  const auto start = std::chrono::steady_clock::now();
  ceres::Solver::Summary summary;
  ceres::Solve(internal::ToCeres(options), graph->problem_.get(), &summary);
  WG_ASSIGN_OR_RETURN(out.termination, internal::CheckSummary(summary, "batch solve"));
  out.iterations = static_cast<int>(summary.iterations.size());
  out.initial_cost = summary.initial_cost;
  out.final_cost = summary.final_cost;
  out.num_residuals = summary.num_residuals_reduced;
  out.num_parameters = summary.num_effective_parameters_reduced;
  out.time_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return out;
}

StatusOr<std::vector<Eigen::MatrixXd>> MarginalCovariances(
    FactorGraph* graph, const std::vector<std::vector<Key>>& groups) {
  internal::KeyedBlocks blocks;
  blocks.reserve(graph->states_.size());
  for (auto& [key, st] : graph->states_) {  // in key order
    blocks.push_back({key, st.spec.value.data(), st.spec.t_s, st.order});
  }
  WG_ASSIGN_OR_RETURN(
      std::vector<Eigen::MatrixXd> out,
      internal::KeyedMarginalCovariances(graph->problem_.get(), blocks, groups, "factor graph"));
  WG_RETURN_IF_ERROR(internal::CheckDefinedCovariances(out, groups, "factor graph"));
  return out;
}

namespace {

constexpr int kNoiseScaleMaxRows = 500;  // per group, evenly spread
constexpr double kNoiseScaleMinRedundancy = 0.05;
constexpr double kNoiseScaleMinGaussianRedundancy = 2.0;
constexpr int kLeverageBatch = 32;

// Leverage h = jᵀH⁻¹j of each listed Jacobian row: ‖D^-½ L⁻¹ P jᵀ‖² with P H Pᵀ = L D Lᵀ.
std::vector<double> Leverages(const internal::Information& info, const std::vector<int>& rows) {
  const Eigen::Index kept = info.jac.cols();
  const Eigen::VectorXd inv_d = info.ldlt.vectorD().cwiseInverse();
  std::vector<double> h(rows.size(), 0.0);
  for (size_t b = 0; b < rows.size(); b += kLeverageBatch) {
    const size_t m = std::min<size_t>(kLeverageBatch, rows.size() - b);
    Eigen::MatrixXd x = Eigen::MatrixXd::Zero(kept, static_cast<Eigen::Index>(m));
    for (size_t j = 0; j < m; ++j) {
      for (decltype(info.jac)::InnerIterator it(info.jac, rows[b + j]); it; ++it) {
        x(it.col(), static_cast<Eigen::Index>(j)) = it.value();
      }
    }
    x = info.ldlt.permutationP() * x;
    info.ldlt.matrixL().solveInPlace(x);
    for (size_t j = 0; j < m; ++j) {
      h[b + j] = x.col(static_cast<Eigen::Index>(j)).cwiseAbs2().dot(inv_d);
    }
  }
  return h;
}

// Up to kNoiseScaleMaxRows of `rows`, evenly spread.
std::vector<int> SpreadRows(const std::vector<int>& rows) {
  if (rows.size() <= kNoiseScaleMaxRows) return rows;
  std::vector<int> out;
  for (size_t k = 0; k < kNoiseScaleMaxRows; ++k) {
    out.push_back(rows[k * rows.size() / kNoiseScaleMaxRows]);
  }
  return out;
}

}  // namespace

StatusOr<std::map<int, NoiseScale>> EstimateNoiseScales(FactorGraph* graph, int min_rows) {
  std::map<int, NoiseScale> out;
  ceres::Problem* problem = graph->problem_.get();
  std::vector<ceres::ResidualBlockId> ids;
  problem->GetResidualBlocks(&ids);  // in the order added: FactorGraph never removes one
  if (ids.size() != graph->factors_.size()) {
    return InternalError("noise scales: residual blocks and factors differ in number");
  }
  std::map<int, std::vector<int>> rows;  // group → its Jacobian rows
  std::set<int> robust;                  // groups with a robust loss on some factor
  for (size_t i = 0, row = 0; i < ids.size(); ++i) {
    const int m = graph->factors_[i].cost->num_residuals();
    const int g = graph->factors_[i].noise_group;
    for (int j = 0; g >= 0 && j < m; ++j) rows[g].push_back(static_cast<int>(row) + j);
    if (g >= 0 && graph->factors_[i].loss) robust.insert(g);
    row += static_cast<size_t>(m);
  }
  if (rows.empty()) return out;
  internal::KeyedBlocks blocks;
  for (auto& [key, st] : graph->states_)
    blocks.push_back({key, st.spec.value.data(), st.spec.t_s, st.order});
  ceres::Problem::EvaluateOptions eo;
  eo.parameter_blocks = internal::VariableBlocksByKey(problem, blocks);
  eo.residual_blocks = ids;
  int total = 0;
  for (double* b : eo.parameter_blocks) total += problem->ParameterBlockTangentSize(b);
  std::vector<double> raw;
  ceres::CRSMatrix crs;
  eo.apply_loss_function = false;
  const bool evaluated = problem->Evaluate(eo, nullptr, &raw, nullptr, nullptr);
  eo.apply_loss_function = true;
  if (!evaluated || !problem->Evaluate(eo, nullptr, nullptr, nullptr, &crs)) {
    return NumericalError("noise scales: the residuals could not be evaluated");
  }
  internal::Information info;
  WG_RETURN_IF_ERROR(internal::FactorInformation(crs, total, "noise scales", &info));
  if (info.jac.cols() == 0) return out;
  for (const auto& [g, all] : rows) {
    const std::vector<int> chosen = SpreadRows(all);
    const std::vector<double> h = Leverages(info, chosen);
    const double spread = static_cast<double>(all.size()) / static_cast<double>(chosen.size());
    double squares = 0.0, redundancy = 0.0;
    std::vector<double> t;
    for (size_t i = 0; i < chosen.size(); ++i) {
      const double r = raw[static_cast<size_t>(chosen[i])], free = std::max(1.0 - h[i], 0.0);
      squares += r * r;
      redundancy += free;
      if (free >= kNoiseScaleMinRedundancy) t.push_back(std::fabs(r) / std::sqrt(free));
    }
    NoiseScale ns;
    ns.redundancy = redundancy * spread;
    if (robust.count(g) > 0) {
      if (static_cast<int>(t.size()) < std::max(min_rows, 1)) continue;
      std::nth_element(t.begin(), t.begin() + t.size() / 2, t.end());
      ns.scale = 1.4826 * t[t.size() / 2];
      ns.rows = static_cast<int>(t.size());
    } else {
      if (!(ns.redundancy >= kNoiseScaleMinGaussianRedundancy)) continue;
      ns.scale = std::sqrt(squares / redundancy);
      ns.rows = static_cast<int>(chosen.size());
    }
    out[g] = ns;
  }
  return out;
}

namespace internal {

AnchorOffsetTest TestAnchorOffsets(const std::vector<std::pair<int, double>>& residuals,
                                   double z_level) {
  std::map<int, std::vector<double>> by_anchor;
  for (const auto& [id, r] : residuals) by_anchor[id].push_back(std::clamp(r, -3.0, 3.0));
  AnchorOffsetTest t;
  for (const auto& [id, e] : by_anchor) {
    const double n = static_cast<double>(e.size());
    if (e.size() < 5) continue;
    const double mean = std::accumulate(e.begin(), e.end(), 0.0) / n;
    double ss = 0.0, lag1 = 0.0;
    for (size_t k = 0; k < e.size(); ++k) {
      ss += (e[k] - mean) * (e[k] - mean);
      if (k > 0) lag1 += (e[k] - mean) * (e[k - 1] - mean);
    }
    const double rho = ss > 0.0 ? std::max(0.0, lag1 / ss) : 0.0;
    const double n_eff = std::max(1.0, n * (1.0 - rho) / (1.0 + rho));
    const double s = std::max(std::sqrt(ss / (n - 1.0)), 1e-3);
    const double z = mean / (s / std::sqrt(n_eff));
    t.statistic += z * z;
    ++t.anchors;
  }
  if (t.anchors == 0) return t;
  const double k = t.anchors, c = 2.0 / (9.0 * k);
  t.critical = k * std::pow(1.0 - c + z_level * std::sqrt(c), 3);
  t.disagree = t.statistic > t.critical;
  return t;
}

}  // namespace internal

}  // namespace walkgraph
