#include "smoothers/step_graph_pending.h"

#include <algorithm>
#include <cmath>
#include <utility>

#include <ceres/normal_prior.h>
#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>

#include "smoothers/step_graph_impl.h"
#include "smoothers/step_graph_run.h"
#include "smoothers/unknown_anchors.h"

namespace walkgraph::internal {

namespace {

// An uncertain anchor (a prior N(μ, σ_m² I)) whose search place x lies beyond χ²(2) at 99.9 %
// of it: (x − μ)ᵀ(Σ_search + σ_m² I)⁻¹(x − μ) > 13.82. An unknown one never does.
bool ContradictsItsPrior(const Anchor& anchor, const AnchorSearchResult& found) {
  if (!anchor.position_known) return false;
  const Eigen::Vector2d d = found.position_m - anchor.position_m.head<2>();
  const Eigen::Matrix2d S =
      found.covariance + anchor.sigma_m * anchor.sigma_m * Eigen::Matrix2d::Identity();
  const Eigen::LDLT<Eigen::Matrix2d> ldlt(0.5 * (S + S.transpose()));
  return ldlt.info() != Eigen::Success || !(d.dot(ldlt.solve(d)) <= kChiSquare2At999);
}

}  // namespace

PendingAnchors::PendingAnchors(const Walk& walk, const StepGraph& graph, const StepGraphOptions& o)
    : walk_(walk), graph_(graph), o_(o) {
  // Uncertain anchors wait only where the start and the surveyed anchors give the window a
  // frame to test them in; else they are that frame, states from the start.
  const bool test_uncertain = SurveyFixesTheFrame(walk);
  for (size_t a = 0; a < walk.anchors.size(); ++a) {
    const Anchor& anchor = walk.anchors[a];
    if (anchor.surveyed() || (anchor.position_known && !test_uncertain)) continue;
    const std::vector<Key> keys = graph.AnchorOwnKeys(static_cast<int>(a));
    if (keys.empty()) continue;  // not heard
    Pending& p = pending_[static_cast<int>(a)];
    p.last.verdict = AnchorSearchResult::Verdict::kFewReadings;
    p.range = std::any_of(walk.ranges.begin(), walk.ranges.end(),
                          [&](const RangeSample& r) { return r.anchor_id == walk.anchors[a].id; });
    for (Key k : keys) owner_[k] = static_cast<int>(a);
  }
}

bool PendingAnchors::Holds(Key key) const {
  const auto it = owner_.find(key);
  return it != owner_.end() && !pending_.at(it->second).placed;
}

bool PendingAnchors::HoldsAny(const std::vector<Key>& keys) const {
  return std::any_of(keys.begin(), keys.end(), [&](Key key) { return Holds(key); });
}

std::vector<GraphState> PendingAnchors::Filter(std::vector<GraphState> states) {
  std::vector<GraphState> out;
  for (GraphState& s : states) {
    if (Holds(s.key)) {
      pending_[owner_.at(s.key)].states.push_back(std::move(s));
    } else {
      out.push_back(std::move(s));
    }
  }
  return out;
}

std::vector<GraphFactor> PendingAnchors::Filter(int k, std::vector<GraphFactor> factors) {
  if (owner_.empty()) return factors;
  std::vector<GraphFactor> out;
  for (GraphFactor& f : factors) {
    const auto held =
        std::find_if(f.keys.begin(), f.keys.end(), [&](Key key) { return Holds(key); });
    if (held == f.keys.end()) {
      out.push_back(std::move(f));
      continue;
    }
    const bool timed = std::any_of(f.keys.begin(), f.keys.end(), [](Key key) {
      const char c = SymbolLetter(key);
      return c == 'x' || c == 'h' || c == 'z';  // a node's (graph.h)
    });
    // A prior on its own states waits for the placement; a reading's factor is replaced by the
    // reading itself (below).
    if (!timed) pending_[owner_.at(*held)].priors.push_back(std::move(f));
  }
  for (const StepGraph::AnchorReading& r : graph_.AnchorReadingsAt(k)) {
    const auto it = pending_.find(r.anchor_index);
    if (it != pending_.end() && !it->second.placed) it->second.waiting.push_back(r);
  }
  return out;
}

AnchorSearchOptions PendingAnchors::SearchFor(int a, const FixedLagSmoother& window) const {
  // The path loss the window holds now (its walk-wide block, or hierarchical's mean).
  std::map<std::string, double> fd;
  if (graph_.path_loss_estimated()) {
    const Key key = graph_.path_loss_per_anchor() ? kPathLossMeanKey : PathLossKey(0);
    if (StatusOr<std::vector<double>> v = window.Estimate(key); v.ok() && v->size() == 2) {
      fd["path_loss_A"] = (*v)[0];
      fd["path_loss_eta"] = (*v)[1];
    }
  }
  const SearchSetup setup = SearchOptions(walk_, o_, fd);
  AnchorSearchOptions so = pending_.at(a).range ? setup.range : setup.rss;
  // The walker taken on the anchor's floor: an unsurveyed anchor's floor is a guess and the
  // graph keeps it planar (StepGraph::Impl::FloorAware).
  so.dz_m = o_.receiver_height_m - walk_.anchors[a].position_m.z();
  return so;
}

Status PendingAnchors::AfterUpdate(const std::vector<int>& nodes, double t_s,
                                   FixedLagSmoother* window, std::vector<GraphState>* states,
                                   std::vector<GraphFactor>* factors) {
  if (pending_.empty() || nodes.empty()) return Status::Ok();
  auto position = [&](int k) -> std::optional<Eigen::Vector2d> {
    StatusOr<std::vector<double>> p = window->Estimate(StepGraph::PositionKey(k));
    if (!p.ok()) return std::nullopt;  // already marginalized
    return Eigen::Vector2d((*p)[0], (*p)[1]);
  };
  for (auto& [a, p] : pending_) {
    if (p.placed) continue;
    for (const StepGraph::AnchorReading& r : p.waiting) {
      if (r.range != p.range) continue;
      const std::optional<Eigen::Vector2d> qa = position(r.node_a);
      const std::optional<Eigen::Vector2d> qb = r.node_b >= 0 ? position(r.node_b) : qa;
      if (!qa || !qb) continue;
      p.at.push_back((1.0 - r.alpha) * *qa + r.alpha * *qb);
      p.value.push_back(r.value);
    }
    p.waiting.clear();
    const size_t n = p.at.size();
    if (static_cast<int>(n) < o_.anchor_min_readings ||
        n < p.tried + std::max<size_t>(5, p.tried / 4)) {
      continue;
    }
    const AnchorSearchOptions so = SearchFor(a, *window);
    p.tried = n;
    p.last = SearchAnchor(p.at, p.value, so);
    if (!p.last.placed()) continue;
    const double sigma = std::sqrt(std::max(
        0.0, Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d>(p.last.covariance).eigenvalues()(1)));
    // An uncertain anchor's prior places it where a wide search region does not.
    const bool prior = walk_.anchors[a].position_known;
    p.too_uncertain = !prior && !(sigma <= o_.window_anchor_max_sigma_m);
    if (p.too_uncertain) continue;
    p.inconsistent = ContradictsItsPrior(walk_.anchors[a], p.last);
    if (p.inconsistent) continue;
    p.placed = true;
    p.placed_t_s = t_s;
    WG_RETURN_IF_ERROR(Place(a, p.last, window, nodes.back(), states, factors));
  }
  return Status::Ok();
}

Status PendingAnchors::Place(int a, const AnchorSearchResult& found, FixedLagSmoother* window,
                             int newest, std::vector<GraphState>* states,
                             std::vector<GraphFactor>* factors) {
  Pending& p = pending_.at(a);
  const Key key = StepGraph::AnchorKey(a);
  for (GraphState& s : p.states) {
    if (s.key == key) s.value = {found.position_m.x(), found.position_m.y()};
    states->push_back(std::move(s));
  }
  for (GraphFactor& f : p.priors) factors->push_back(std::move(f));
  p.states.clear();
  p.priors.clear();
  // The receivers' own uncertainty: the newest node's position variance (largest axis).
  double receiver_var = 0.0;
  if (StatusOr<Eigen::MatrixXd> c = window->MarginalCovariance(StepGraph::PositionKey(newest));
      c.ok() && c->rows() >= 2) {
    receiver_var = std::max(0.0, 0.5 * (c->topLeftCorner<2, 2>().trace()));
  }
  Eigen::Matrix2d cov = found.covariance + receiver_var * Eigen::Matrix2d::Identity();
  cov = 0.5 * (cov + cov.transpose());
  const Eigen::LLT<Eigen::Matrix2d> info(cov.inverse());
  if (info.info() != Eigen::Success) {
    return InternalError("fg-window: anchor " + std::to_string(walk_.anchors[a].id) +
                         ": its search covariance is not positive definite");
  }
  GraphFactor prior;
  const ceres::Matrix A = info.matrixU();  // ‖A (x − μ)‖² = (x − μ)ᵀ Σ⁻¹ (x − μ)
  prior.cost = std::make_unique<ceres::NormalPrior>(A, found.position_m);
  prior.keys = {key};
  factors->push_back(std::move(prior));
  return Status::Ok();
}

void PendingAnchors::Report(FixedLagSmoother* window, EstimateResult* r) const {
  auto& d = r->diagnostics;
  if (!pending_.empty()) {
    d["unknown_anchors"] = static_cast<double>(pending_.size());
    d["unknown_anchors_estimated"] = 0.0;
    d["unknown_anchors_unobservable"] = 0.0;
  }
  // Every anchor that is a state (uncertain, or unknown), in the walk's order.
  for (size_t i = 0; i < walk_.anchors.size(); ++i) {
    const int a = static_cast<int>(i);
    if (!graph_.AnchorIsState(a)) continue;
    const auto it = pending_.find(a);
    AnchorEstimate e;
    e.id = walk_.anchors[i].id;
    e.readings = walk_.AnchorReadings(e.id);
    const Key key = StepGraph::AnchorKey(a);
    StatusOr<std::vector<double>> v = window->Estimate(key);
    const bool placed = it == pending_.end() || it->second.placed;
    if (placed && v.ok()) {
      e.position_m = Eigen::Vector2d((*v)[0], (*v)[1]);
      if (StatusOr<Eigen::MatrixXd> c = window->MarginalCovariance(key); c.ok()) {
        e.covariance = Eigen::Matrix2d(0.5 * (*c + c->transpose()));
      }
      if (it != pending_.end()) {
        d["unknown_anchors_estimated"] += 1.0;
        d["anchor_placed_t_s." + std::to_string(e.id)] = it->second.placed_t_s;
      }
    } else if (it == pending_.end()) {
      e.observable = false;  // an uncertain anchor the window does not hold (not expected)
    } else {
      e.observable = false;
      d["unknown_anchors_unobservable"] += 1.0;
      const Pending& p = it->second;
      const std::string why = p.inconsistent    ? "inconsistent"
                              : p.too_uncertain ? "uncertain"
                                                : ToString(p.last.verdict);
      d["unknown_anchors_unobservable." + why] += 1.0;
    }
    r->anchors.push_back(e);
  }
}

}  // namespace walkgraph::internal
