#include "walkgraph/smoothers/fixed_lag_smoother.h"

#include <algorithm>
#include <cmath>
#include <set>
#include <string>

#include "smoothers/graph_internal.h"
#include "walkgraph/cancel.h"

namespace walkgraph {

namespace {

std::string KeyName(Key k) { return "state " + KeyToString(k); }

}  // namespace

FixedLagSmoother::FixedLagSmoother(Options options)
    : options_(options),
      problem_(std::make_unique<ceres::Problem>(
          internal::BorrowingProblemOptions(/*fast_removal=*/true))) {}

FixedLagSmoother::~FixedLagSmoother() {
  problem_.reset();  // before the cost functions and manifolds it points to
}

Status FixedLagSmoother::AddFactor(GraphFactor f) {
  if (!f.cost) return InvalidArgument("fixed-lag smoother: factor without a cost function");
  if (f.cost->parameter_block_sizes().size() != f.keys.size()) {
    return InvalidArgument("fixed-lag smoother: factor has " +
                           std::to_string(f.cost->parameter_block_sizes().size()) +
                           " parameter blocks but " + std::to_string(f.keys.size()) + " keys");
  }
  std::vector<double*> blocks;
  for (size_t i = 0; i < f.keys.size(); ++i) {
    auto it = states_.find(f.keys[i]);
    if (it == states_.end()) {
      return InvalidArgument("fixed-lag smoother: factor on " + KeyName(f.keys[i]) +
                             ", which is not in the window (unknown or already marginalized)");
    }
    if (static_cast<int>(it->second.value.size()) != f.cost->parameter_block_sizes()[i]) {
      return InvalidArgument("fixed-lag smoother: block size mismatch on " + KeyName(f.keys[i]));
    }
    if (std::find(blocks.begin(), blocks.end(), it->second.value.data()) != blocks.end()) {
      return InvalidArgument("fixed-lag smoother: a factor names " + KeyName(f.keys[i]) +
                             " twice");  // Ceres aborts on a repeated parameter block
    }
    blocks.push_back(it->second.value.data());
  }
  const int id = next_factor_id_++;
  Factor& stored = factors_[id];
  stored.spec = std::move(f);
  stored.residual = problem_->AddResidualBlock(
      stored.spec.cost.get(), const_cast<ceres::LossFunction*>(stored.spec.loss.get()), blocks);
  for (Key k : stored.spec.keys) states_[k].factors.insert(id);
  return Status::Ok();
}

Status FixedLagSmoother::CheckNewFactors(const std::vector<GraphState>& new_states,
                                         const std::vector<GraphFactor>& new_factors) const {
  for (const GraphFactor& f : new_factors) {
    if (!f.cost) return InvalidArgument("fixed-lag smoother: factor without a cost function");
    const std::vector<int32_t>& sizes = f.cost->parameter_block_sizes();
    if (sizes.size() != f.keys.size()) {
      return InvalidArgument("fixed-lag smoother: factor has " + std::to_string(sizes.size()) +
                             " parameter blocks but " + std::to_string(f.keys.size()) + " keys");
    }
    for (size_t i = 0; i < f.keys.size(); ++i) {
      const Key k = f.keys[i];
      if (std::find(f.keys.begin(), f.keys.begin() + i, k) != f.keys.begin() + i) {
        return InvalidArgument("fixed-lag smoother: a factor names " + KeyName(k) + " twice");
      }
      size_t size = 0;
      if (auto it = states_.find(k); it != states_.end()) {
        size = it->second.value.size();
      } else {
        auto n = std::find_if(new_states.begin(), new_states.end(),
                              [k](const GraphState& s) { return s.key == k; });
        if (n == new_states.end()) {
          return InvalidArgument("fixed-lag smoother: factor on " + KeyName(k) +
                                 ", which is not in the window (unknown or already marginalized)");
        }
        size = n->value.size();
      }
      if (static_cast<int>(size) != sizes[i]) {
        return InvalidArgument("fixed-lag smoother: block size mismatch on " + KeyName(k));
      }
    }
  }
  return Status::Ok();
}

Status FixedLagSmoother::CheckNewStates(const std::vector<GraphState>& new_states) const {
  std::set<Key> added;
  for (const GraphState& s : new_states) {
    const std::string name = "fixed-lag smoother: " + KeyName(s.key);
    if (states_.count(s.key) || !added.insert(s.key).second) {
      return InvalidArgument(name + " added twice");
    }
    if (s.value.empty()) return InvalidArgument("fixed-lag smoother: empty " + KeyName(s.key));
    if (s.manifold && s.manifold->AmbientSize() != static_cast<int>(s.value.size())) {
      return InvalidArgument("fixed-lag smoother: manifold size mismatch on " + KeyName(s.key));
    }
    for (double v : s.value) {
      if (!std::isfinite(v)) return InvalidArgument(name + " has a non-finite value");
    }
    if (s.t_s && !std::isfinite(*s.t_s)) {
      return InvalidArgument(name + " has a non-finite time; expected a finite t_s");
    }
    if (s.t_s && marginalized_before_s_ && *s.t_s < *marginalized_before_s_) {
      return InvalidArgument(name + " at t = " + std::to_string(*s.t_s) +
                             " s goes back before the window (states before t = " +
                             std::to_string(*marginalized_before_s_) +
                             " s are already marginalized); expected times inside the window");
    }
  }
  return Status::Ok();
}

StatusOr<FixedLagSmoother::UpdateResult> FixedLagSmoother::Update(
    std::vector<GraphState> new_states, std::vector<GraphFactor> new_factors) {
  if (CancelRequested()) return Cancelled("fixed-lag smoother: interrupted");
  WG_RETURN_IF_ERROR(CheckNewStates(new_states));
  WG_RETURN_IF_ERROR(CheckNewFactors(new_states, new_factors));  // nothing changes on failure
  for (GraphState& s : new_states) {
    State& st = states_[s.key];
    st.order = next_state_order_++;
    st.value = s.value;
    st.spec = std::move(s);
    problem_->AddParameterBlock(st.value.data(), static_cast<int>(st.value.size()),
                                const_cast<ceres::Manifold*>(st.spec.manifold.get()));
    if (st.spec.constant) problem_->SetParameterBlockConstant(st.value.data());
    if (st.spec.t_s) newest_t_ = std::max(newest_t_.value_or(*st.spec.t_s), *st.spec.t_s);
  }
  // New factors that all vanish at the current estimate (new states at their initial values)
  // cannot move the optimum: the old terms are at their minimum and the new ones at zero, so the
  // sum is minimal too (e.g. an odometry step with no reading). Then the solve is skipped.
  bool informative = !solved_;
  for (GraphFactor& f : new_factors) {
    if (!informative) {
      std::vector<const double*> blocks;
      for (Key k : f.keys) {
        auto it = states_.find(k);
        if (it == states_.end()) break;
        blocks.push_back(it->second.value.data());
      }
      std::vector<double> r(f.cost ? f.cost->num_residuals() : 0);
      double r2 = 0.0;
      const bool ok = f.cost && blocks.size() == f.keys.size() &&
                      f.cost->Evaluate(blocks.data(), r.data(), nullptr);
      for (double v : r) r2 += v * v;
      informative = !ok || !(r2 <= options_.vanishing_residual_sq);
    }
    WG_RETURN_IF_ERROR(AddFactor(std::move(f)));
  }

  UpdateResult result;
  result.solved = informative;
  if (informative && problem_->NumResidualBlocks() > 0) {
    solved_ = true;
    ceres::Solver::Summary summary;
    SolverOptions solver = options_.solver;
    if (hold_from_s_ && options_.held_max_iterations > 0) {
      solver.max_iterations = options_.held_max_iterations;
    }
    ceres::Solve(internal::ToCeres(solver), problem_.get(), &summary);
    WG_ASSIGN_OR_RETURN(const Termination termination,
                        internal::CheckSummary(summary, "fixed-lag smoother"));
    result.ceres_iterations = static_cast<int>(summary.iterations.size());
    result.final_cost = summary.final_cost;
    result.converged = termination == Termination::kConverged;
  }
  if (newest_t_) {
    double cutoff = *newest_t_ - options_.lag_s;
    if (hold_from_s_) cutoff = std::min(cutoff, *hold_from_s_);
    std::optional<double> oldest;
    for (const auto& [key, st] : states_) {
      if (st.spec.t_s) oldest = std::min(oldest.value_or(*st.spec.t_s), *st.spec.t_s);
    }
    if (oldest && *oldest < cutoff - options_.marginalize_batch_s) {
      WG_RETURN_IF_ERROR(MarginalizeOlderThan(cutoff, &result.marginalized_states));
    }
  }
  return result;
}

Status FixedLagSmoother::MarginalizeOlderThan(double cutoff_s, int* count) {
  std::set<Key> old;
  for (const auto& [key, st] : states_) {
    if (st.spec.t_s && *st.spec.t_s < cutoff_s) old.insert(key);
  }
  *count = static_cast<int>(old.size());
  if (old.empty()) return Status::Ok();
  marginalized_before_s_ = std::max(marginalized_before_s_.value_or(cutoff_s), cutoff_s);

  std::set<int> touching;
  for (Key k : old) touching.insert(states_[k].factors.begin(), states_[k].factors.end());
  std::vector<FactorRef> refs;
  for (int id : touching) {
    const Factor& f = factors_[id];
    FactorRef r;
    r.cost = f.spec.cost.get();
    r.loss = f.spec.loss.get();
    for (Key k : f.spec.keys) {
      State& st = states_[k];
      BlockRef b;
      b.key = k;
      b.values = st.value.data();
      b.ambient_size = static_cast<int>(st.value.size());
      b.manifold = st.spec.manifold.get();
      b.constant = st.spec.constant;
      r.blocks.push_back(b);
    }
    refs.push_back(std::move(r));
  }
  WG_ASSIGN_OR_RETURN(MarginalPrior prior, Marginalize(refs, old, options_.eigenvalue_tolerance));

  if (before_marginalize_) before_marginalize_(std::vector<Key>(old.begin(), old.end()));
  for (Key k : old) {
    const State& st = states_[k];
    if (on_marginalize_) on_marginalize_(k, *st.spec.t_s, st.value);
  }
  for (int id : touching) {
    problem_->RemoveResidualBlock(factors_[id].residual);
    for (Key k : factors_[id].spec.keys) {
      auto it = states_.find(k);
      if (it != states_.end()) it->second.factors.erase(id);
    }
    factors_.erase(id);
  }
  for (Key k : old) {
    problem_->RemoveParameterBlock(states_[k].value.data());
    states_.erase(k);
  }
  if (!prior.empty()) {
    GraphFactor f;
    for (const BlockRef& b : prior.blocks) f.keys.push_back(b.key);
    f.cost = prior.MakeCostFunction();
    WG_RETURN_IF_ERROR(AddFactor(std::move(f)));
  }
  return Status::Ok();
}

StatusOr<std::vector<double>> FixedLagSmoother::Estimate(Key key) const {
  auto it = states_.find(key);
  if (it == states_.end())
    return NotFound("fixed-lag smoother: " + KeyName(key) + " not in window");
  return it->second.value;
}

StatusOr<Eigen::MatrixXd> FixedLagSmoother::MarginalCovariance(Key key) {
  return MarginalCovariance(std::vector<Key>{key});
}

namespace {
template <class States>
internal::KeyedBlocks BlocksOf(States* states) {
  internal::KeyedBlocks blocks;
  blocks.reserve(states->size());
  for (auto& [key, st] : *states) {
    blocks.push_back({key, st.value.data(), st.spec.t_s, st.order});
  }
  return blocks;  // in key order: a std::map's
}
}  // namespace

StatusOr<Eigen::MatrixXd> FixedLagSmoother::MarginalCovariance(const std::vector<Key>& keys) {
  WG_ASSIGN_OR_RETURN(Eigen::MatrixXd c,
                      internal::CeresMarginalCovariance(problem_.get(), BlocksOf(&states_), keys,
                                                        "fixed-lag smoother"));
  WG_RETURN_IF_ERROR(internal::CheckDefinedCovariances({c}, {keys}, "fixed-lag smoother"));
  return c;
}

StatusOr<std::vector<Eigen::MatrixXd>> FixedLagSmoother::MarginalCovariances(
    const std::vector<std::vector<Key>>& groups) {
  WG_ASSIGN_OR_RETURN(std::vector<Eigen::MatrixXd> out,
                      internal::KeyedMarginalCovariances(problem_.get(), BlocksOf(&states_), groups,
                                                         "fixed-lag smoother"));
  WG_RETURN_IF_ERROR(internal::CheckDefinedCovariances(out, groups, "fixed-lag smoother"));
  return out;
}

std::vector<Key> FixedLagSmoother::WindowKeys() const { return internal::KeysByTime(states_); }

void FixedLagSmoother::Flush() const {
  if (!on_marginalize_) return;
  for (Key k : WindowKeys()) {
    const State& st = states_.at(k);
    on_marginalize_(k, *st.spec.t_s, st.value);
  }
}

void AddUpdateLatencyTimings(std::vector<double> latency_s,
                             std::map<std::string, double>* timings) {
  std::sort(latency_s.begin(), latency_s.end());
  auto pct = [&](double q) {
    return latency_s.empty() ? 0.0
                             : latency_s[std::min(latency_s.size() - 1,
                                                  static_cast<size_t>(q * latency_s.size()))];
  };
  (*timings)["update_latency_median_s"] = pct(0.5);
  (*timings)["update_latency_p99_s"] = pct(0.99);
  (*timings)["update_latency_max_s"] = latency_s.empty() ? 0.0 : latency_s.back();
}

}  // namespace walkgraph
