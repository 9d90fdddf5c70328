// StepGraph: the graph of a walk (nodes, their initial values, stairs and heights, start
// hypotheses); its states and factors node by node are in step_graph_factors.cc.
#include "walkgraph/smoothers/step_graph.h"

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <map>

#include <Eigen/Geometry>

#include "factors/barometric_height_factor.h"
#include "smoothers/graph_internal.h"
#include "smoothers/step_graph_impl.h"
#include "util/rigid2d.h"
#include "util/text.h"
#include "walkgraph/kalman.h"
#include "walkgraph/radio.h"

namespace walkgraph {

using internal::BridgedNodes;
using internal::kGyroBiasKey;
using internal::ResolvePathLoss;

// ------------------------------------------------------------------ the graph

namespace internal {

// path_loss "auto": see StepGraphOptions::path_loss. *held_radio_only: auto held it because
// the walk has neither steps nor odometry.
PathLossMode ResolvePathLoss(const Walk& walk, const StepGraphOptions& o, bool* held_radio_only) {
  *held_radio_only = false;
  if (o.path_loss != PathLossMode::kAuto) return o.path_loss;
  if (walk.meta.radio.calibrated || o.rss_residual != RssResidual::kDb) return PathLossMode::kFixed;
  *held_radio_only = !walk.has_odometry() && !walk.has_imu();
  return *held_radio_only ? PathLossMode::kFixed : PathLossMode::kHierarchical;
}

}  // namespace internal

namespace {

// The rigid transform taking the dead reckoning `init` of the first align_window_s onto the
// radio position fixes there (Umeyama, no scale), with how well it is determined: the spread
// of the dead-reckoned points and the RMS residual after alignment.
struct Alignment {
  Eigen::Matrix2d R;
  Eigen::Vector2d t;
  double rotation_rad = 0.0;
  double spread_m = 0.0;    // RMS distance of the aligned points from their mean
  double residual_m = 0.0;  // RMS fix − aligned point
};

Alignment Align(const std::vector<Eigen::Vector2d>& src, const std::vector<Eigen::Vector2d>& dst,
                size_t count) {
  const internal::Rigid2d f = internal::FitRigid2d(src, dst, count);
  Alignment a;
  a.R = f.R;
  a.t = f.t;
  a.rotation_rad = std::atan2(f.R(1, 0), f.R(0, 0));
  Eigen::Vector2d mean = Eigen::Vector2d::Zero();
  for (size_t i = 0; i < count; ++i) mean += src[i];
  mean /= static_cast<double>(count);
  double residual = 0.0, spread = 0.0;
  for (size_t i = 0; i < count; ++i) {
    residual += (dst[i] - f(src[i])).squaredNorm();
    spread += (src[i] - mean).squaredNorm();
  }
  const double n = static_cast<double>(count);
  a.residual_m = std::sqrt(residual / n);
  a.spread_m = std::sqrt(spread / n);
  return a;
}

// Fixes of the first align_window_s — or, while the walker has not moved enough there for the
// rotation to be determined (spread ≤ 2 × residual: e.g. standing at the start), of a window
// doubled until it has, up to the whole walk.
std::optional<Alignment> AlignToFirstFixes(const Walk& walk, const StepGraphOptions& o,
                                           const std::vector<double>& node_t,
                                           const std::vector<Eigen::Vector3d>& init) {
  if (walk.rss.empty() && walk.ranges.empty()) return std::nullopt;
  EpochOptions eo;
  eo.receiver_height_m = o.receiver_height_m;
  auto fixes = PositionWalk(walk, eo, PositioningMethod::kNonlinearLs);
  if (!fixes.ok()) return std::nullopt;
  std::vector<Eigen::Vector2d> src, dst;
  std::vector<double> t;
  for (const FixResult& f : *fixes) {
    if (!f.ok()) continue;
    const auto it = std::lower_bound(node_t.begin(), node_t.end(), f.fix.t_s);
    Eigen::Vector2d q;
    if (it == node_t.begin()) {
      q = init.front().head<2>();
    } else if (it == node_t.end()) {
      q = init.back().head<2>();
    } else {
      const size_t b = static_cast<size_t>(it - node_t.begin());
      const double w = (f.fix.t_s - node_t[b - 1]) / (node_t[b] - node_t[b - 1]);
      q = (1 - w) * init[b - 1].head<2>() + w * init[b].head<2>();
    }
    src.push_back(q);
    dst.push_back(f.fix.position_m);
    t.push_back(f.fix.t_s);
  }
  if (src.size() < 3) return std::nullopt;
  std::optional<Alignment> a;
  for (double window = o.align_window_s;; window *= 2.0) {
    size_t count = 0;
    while (count < t.size() && (t[count] <= node_t.front() + window || count < 3)) ++count;
    a = Align(src, dst, count);
    if (a->spread_m > 2.0 * a->residual_m || count == t.size()) return a;
  }
}

}  // namespace

namespace internal {

// Nodes whose interval (t_{k−1}, t_k] overlaps an IMU gap, on walks whose steps come from the
// IMU (odometry and radio-only walks have none).
std::vector<bool> BridgedNodes(const Walk& walk, bool imu_steps, const std::vector<double>& t) {
  std::vector<bool> out(t.size(), false);
  if (!imu_steps) return out;
  for (const ImuGap& gap : walk.ImuGaps()) {
    const auto first = std::upper_bound(t.begin(), t.end(), gap.t_begin_s);
    for (auto it = first; it != t.end(); ++it) {
      const size_t k = static_cast<size_t>(it - t.begin());
      if (k == 0) continue;
      if (t[k - 1] >= gap.t_end_s) break;
      out[k] = true;
    }
  }
  return out;
}

}  // namespace internal

StepGraph::~StepGraph() = default;

// A known start whose heading the radio contradicts (issue 17: a recording's truth heading
// column π off the direction of travel): the dead reckoning of the first align_window_s,
// aligned to the radio fixes there, says by how much the start heading is off. When that is
// more than max(start_check_rad, start_check_sigmas × σ_heading) and the alignment is well
// determined (the walker moved: spread > 2 × residual), the start heading is treated as
// unknown (no heading prior) and the dead reckoning is rotated about the start position by
// that angle. A position-only start on a walk whose steps carry no heading (odometry) takes
// its heading from the same alignment instead of 0.
// StepGraphOptions::user_factors, called once; each factor goes with its newest node (static
// keys only: node 0), so the window adds it when every pose it names is there.
Status StepGraph::Impl::AddUserFactors(const Walk& walk, const std::vector<double>& node_t) {
  user_at.assign(node_t.size(), {});
  WG_ASSIGN_OR_RETURN(std::vector<GraphFactor> factors,
                      internal::CallUserFactors(o.user_factors, walk, node_t));
  for (size_t i = 0; i < factors.size(); ++i) {
    uint64_t newest = 0;
    for (const Key key : factors[i].keys) {
      const char letter = SymbolLetter(key);
      if (letter != 'x' && letter != 'h') continue;
      if (SymbolIndex(key) >= node_t.size()) {
        return InvalidArgument("user factor " + std::to_string(i) + ": key " + KeyToString(key) +
                               " beyond the last pose (" + std::to_string(node_t.size() - 1) + ")");
      }
      newest = std::max(newest, SymbolIndex(key));
    }
    user_at[newest].push_back(std::move(factors[i]));
  }
  return Status::Ok();
}

void StepGraph::Impl::CheckStartHeading(const Walk& walk, StepGraph* g) {
  Impl* m = this;
  const bool no_heading = !m->start->heading_known && (m->odometry || m->steps.empty());
  if (!(m->start->heading_known && o.start_check) && !no_heading) return;
  const std::optional<Alignment> a = AlignToFirstFixes(walk, o, g->node_t_, g->init_);
  if (!a || !(a->spread_m > 2.0 * a->residual_m)) return;
  const double limit =
      std::max(o.start_check_rad, o.start_check_sigmas * m->start->sigma_heading_rad);
  const double off = std::abs(NormalizeAngle(a->rotation_rad));
  if (!no_heading && off <= limit) return;
  if (!no_heading) {
    m->start->heading_known = false;
    g->start_heading_contradicted_ = off;
  }
  m->start_heading_from_fixes = no_heading;
  const Eigen::Vector2d s(m->start->x_m, m->start->y_m);
  const Eigen::Rotation2Dd R(a->rotation_rad);
  for (Eigen::Vector3d& p : g->init_) {
    p.head<2>() = s + R * (p.head<2>() - s);
    p[2] = NormalizeAngle(p[2] + a->rotation_rad);
  }
}

Status StepGraph::Impl::MakeNodes(const Walk& walk, StepGraph* g) {
  const StepGraphOptions& o = this->o;
  std::vector<double> t;
  radio_only = !walk.has_odometry() && !walk.has_imu();
  if (radio_only) {
    // No steps: one node per radio epoch (a new node once radio_epoch_s has passed), joined by
    // the random-walk motion model; the first reading's time is node 0.
    std::vector<double> rt;
    for (const RssSample& s : walk.rss) rt.push_back(s.t_s);
    for (const RangeSample& s : walk.ranges) rt.push_back(s.t_s);
    std::sort(rt.begin(), rt.end());
    if (rt.empty()) return FailedPrecondition("step graph: the walk has no steps and no radio");
    double node = rt.front();
    for (double x : rt) {
      if (x >= node + o.radio_epoch_s) t.push_back(node = x);
    }
    if (t.empty()) t.push_back(rt.back() + o.radio_epoch_s);
  } else if (odometry) {
    odom = walk.odometry;
    for (const OdometrySample& s : odom) t.push_back(s.t_s);
  } else {
    WG_ASSIGN_OR_RETURN(StepSequence seq, StepsForWalk(walk, o.pdr));
    steps = std::move(seq.steps);
    front_end = seq.report;
    for (const Step& s : steps) t.push_back(s.t_s);
  }
  if (t.empty()) return FailedPrecondition("step graph: the walk has no steps or odometry");
  for (size_t i = 1; i < t.size(); ++i) {
    if (!(t[i] > t[i - 1])) {
      return InvalidArgument("step graph: step times must increase (step " + std::to_string(i) +
                             " at " + internal::Num(t[i]) + " s)");
    }
  }
  const double first_duration = odometry || radio_only ? 0.0 : steps.front().duration_s;
  const double t0 =
      radio_only
          ? t.front() - o.radio_epoch_s
          : std::min(walk.StartTime(), t.front() - std::max(std::min(first_duration, 1.0), 0.01));
  g->node_t_.push_back(t0);
  g->node_t_.insert(g->node_t_.end(), t.begin(), t.end());

  return Status::Ok();
}

void StepGraph::Impl::DeadReckon(const Walk& walk, StepGraph* g) {
  const int n = g->num_nodes();
  // Dead reckoning from the start (or the origin), θ the node heading.
  bridged = BridgedNodes(walk, !odometry && !radio_only, g->node_t_);
  Eigen::Vector3d x = Eigen::Vector3d::Zero();
  if (start) {
    // A position-only start: the front end's heading at the start (before the first step).
    const double heading =
        start->heading_known || steps.empty()
            ? start->heading_rad
            : NormalizeAngle(steps.front().heading_rad - steps.front().dheading_rad);
    x = Eigen::Vector3d(start->x_m, start->y_m, heading);
  }
  g->init_.push_back(x);
  for (int k = 1; k < n; ++k) {
    x = Predict(k, x);  // radio-only walks: positions come from the radio fixes below
    g->init_.push_back(x);
  }
}

Status StepGraph::Impl::AttachReadings(const Walk& walk, StepGraph* g) {
  const StepGraphOptions& o = this->o;
  const int n = g->num_nodes();
  // Radio readings, attached to the node(s) around them.
  anchor_has_rss.assign(walk.anchors.size(), false);
  anchor_has_range.assign(walk.anchors.size(), false);
  readings_at.assign(n, {});
  auto attach = [&](double ts, Reading r) {
    if (radio_only) {  // the epoch's node: the last node at or before the reading
      const auto up = std::upper_bound(g->node_t_.begin(), g->node_t_.end(), ts);
      r.node_a = std::max(0, static_cast<int>(up - g->node_t_.begin()) - 1);
      readings_at[r.node_a].push_back(r);
      return;
    }
    const auto it = std::lower_bound(g->node_t_.begin(), g->node_t_.end(), ts);
    if (it == g->node_t_.begin()) {
      r.node_a = 0;
    } else if (it == g->node_t_.end()) {
      r.node_a = n - 1;
    } else {
      const int b = static_cast<int>(it - g->node_t_.begin()), a = b - 1;
      const double tb = g->node_t_[b];
      const double ta =
          bridged[b] ? g->node_t_[a] : std::max(g->node_t_[a], tb - o.max_step_duration_s);
      const double alpha = ts <= ta ? 0.0 : std::min(1.0, (ts - ta) / (tb - ta));
      if (alpha <= 1e-9) {
        r.node_a = a;
      } else if (alpha >= 1.0 - 1e-9) {
        r.node_a = b;
      } else {
        r.node_a = a, r.node_b = b, r.alpha = alpha;
      }
    }
    readings_at[r.node_b >= 0 ? r.node_b : r.node_a].push_back(r);
  };
  for (const RssSample& s : walk.rss) {
    const int a = walk.AnchorIndex(s.anchor_id);
    if (a < 0)
      return InvalidArgument("step graph: RSS from unknown anchor " + std::to_string(s.anchor_id));
    anchor_has_rss[a] = true;
    any_rss = true;
    attach(s.t_s, Reading{a, Reading::Kind::kRss, s.rss});
  }
  for (const RangeSample& s : walk.ranges) {
    const int a = walk.AnchorIndex(s.anchor_id);
    if (a < 0)
      return InvalidArgument("step graph: range from unknown anchor " +
                             std::to_string(s.anchor_id));
    anchor_has_range[a] = true;
    any_range = true;
    attach(s.t_s, Reading{a, Reading::Kind::kRange, s.range_m});
  }
  for (size_t i = 0; i < walk.waypoints.size(); ++i) {
    attach(walk.waypoints[i].t_s, Reading{static_cast<int>(i), Reading::Kind::kWaypoint});
  }

  return Status::Ok();
}

void StepGraph::Impl::PlaceStart(const Walk& full_walk, StepGraph* g) {
  const StepGraphOptions& o = this->o;
  const int n = g->num_nodes();
  // The radio fixes below use the anchors of given position only (an unknown one's position is
  // a guess being estimated: fg-batch's).
  const Walk known = full_walk.has_unknown_anchors() ? WithoutUnknownAnchors(full_walk) : Walk();
  const Walk& walk = full_walk.has_unknown_anchors() ? known : full_walk;
  if (radio_only) {
    // Initial positions: the radio position fixes, interpolated in time (the anchors' centroid
    // where no fix exists); headings are not states of a radio-only walk (held at 0).
    Eigen::Vector2d centroid = Eigen::Vector2d::Zero();
    for (const Anchor& a : walk.anchors) centroid += a.position_m.head<2>();
    if (!walk.anchors.empty()) centroid /= static_cast<double>(walk.anchors.size());
    std::vector<std::pair<double, Eigen::Vector2d>> fixes;
    EpochOptions eo;
    eo.receiver_height_m = o.receiver_height_m;
    eo.window_s = std::max(o.radio_epoch_s, 1.0);
    auto result = PositionWalk(walk, eo, PositioningMethod::kNonlinearLs);
    if (result.ok()) {
      for (const FixResult& f : *result) {
        if (f.ok()) fixes.emplace_back(f.fix.t_s, f.fix.position_m);
      }
    }
    for (int k = 0; k < n; ++k) {
      Eigen::Vector2d q = centroid;
      if (!fixes.empty()) {
        const double tk = g->node_t_[k];
        auto it = std::lower_bound(fixes.begin(), fixes.end(), tk,
                                   [](const auto& f, double t) { return f.first < t; });
        if (it == fixes.begin()) {
          q = fixes.front().second;
        } else if (it == fixes.end()) {
          q = fixes.back().second;
        } else {
          const auto& a = *(it - 1);
          const double w = (tk - a.first) / (it->first - a.first);
          q = (1 - w) * a.second + w * it->second;
        }
      }
      g->init_[k] = Eigen::Vector3d(q.x(), q.y(), 0.0);
    }
  } else if (!start) {
    // Without a known start: align the dead reckoning to the first radio fixes; with no radio
    // either, node 0 is the gauge.
    const std::optional<Alignment> a = AlignToFirstFixes(walk, o, g->node_t_, g->init_);
    if (a) {
      for (Eigen::Vector3d& p : g->init_) {
        p.head<2>() = a->R * p.head<2>() + a->t;
        p[2] = NormalizeAngle(p[2] + a->rotation_rad);
      }
    } else {
      g->fix_first_node_ = !(any_rss || any_range) || walk.anchors.size() < 3;
    }
    // Anchors that are states (walk.h Anchor) do not fix the frame by themselves: with fewer
    // than 2 heard anchors of given position, node 0 is the gauge (the walk's own frame).
    int placed = 0;
    for (size_t i = 0; i < anchors.size(); ++i) {
      const bool heard = anchor_has_rss[i] || anchor_has_range[i];
      placed += heard && anchors[i].position_known ? 1 : 0;
    }
    if (placed < 2) g->fix_first_node_ = true;
  } else if (any_rss || any_range) {
    CheckStartHeading(walk, g);
  }
}

StatusOr<std::unique_ptr<StepGraph>> StepGraph::Build(const Walk& walk, const StepGraphOptions& o) {
  WG_RETURN_IF_ERROR(o.Validate());  // options set in C++ meet the YAML's rules
  std::unique_ptr<StepGraph> g(new StepGraph());
  g->impl_ = std::make_unique<Impl>();
  Impl& m = *g->impl_;
  m.o = o;
  m.anchors = walk.anchors;
  for (const Anchor& a : walk.anchors) {
    bool state = !a.surveyed();
    if (!a.position_known && !a.position_m.head<2>().allFinite()) {
      return InvalidArgument("step graph: anchor " + std::to_string(a.id) +
                             " has no position (anchors.csv x_m, y_m empty); fg-batch estimates "
                             "it, the other estimators run without it (registry)");
    }
    if (state && o.rss_residual == RssResidual::kRange) {
      // The range-domain RSS residual has no path-loss block: uncertain anchors are held at
      // their mean there; unknown ones need the dB residual.
      if (!a.position_known) {
        return InvalidArgument("step graph: anchor " + std::to_string(a.id) +
                               " of unknown position needs rss_residual: db");
      }
      state = false;
    }
    m.anchor_state.push_back(state);
  }
  m.waypoints = walk.waypoints;
  m.radio = walk.meta.radio;
  if (std::isfinite(o.A_dbm)) m.radio.path_loss.A_dbm = o.A_dbm;
  if (o.eta > 0) m.radio.path_loss.eta = o.eta;
  if (o.sigma_db > 0) m.radio.path_loss.sigma_db = o.sigma_db;
  m.start = walk.meta.initial_pose;
  m.odometry = walk.has_odometry();
  m.o.path_loss = ResolvePathLoss(walk, o, &g->path_loss_held_radio_only_);
  m.rss_loss = internal::MakeLoss(o.rss_loss, o.rss_loss_scale);
  m.range_loss = internal::MakeLoss(o.range_loss, o.range_loss_scale);
  m.mag_loss = internal::MakeLoss(o.mag_heading_loss, o.mag_heading_loss_scale);

  WG_RETURN_IF_ERROR(m.MakeNodes(walk, g.get()));
  m.MakeHeights(walk, g->node_t_);
  m.stair_steps = m.MarkStairs(walk, g->node_t_);
  m.DeadReckon(walk, g.get());
  WG_RETURN_IF_ERROR(m.ChainHeights(g->node_t_));  // after DeadReckon: bridged
  // Not for fg-window's online output: the vote takes readings it has not seen yet.
  if (!(m.start && m.start->floor) && o.window_output != WindowOutput::kOnline) {
    m.radio_start_floor = m.RadioStartFloor(walk, g->node_t_);
    if (m.radio_start_floor && *m.radio_start_floor != 0) {  // the chain again, from that floor
      m.start_z = *m.radio_start_floor * m.storey_m;
      WG_RETURN_IF_ERROR(m.ChainHeights(g->node_t_));
    }
  }
  for (const Anchor& a : walk.anchors) {
    m.anchor_z.push_back(walk.AnchorHeightM(a));
    m.anchor_floor.push_back(a.floor);
    m.anchor_at_floor.push_back(a.floor && (m.radio.path_loss.floor_loss_db > 0.0 ||
                                            (!m.radio.calibrated && a.surveyed())));
  }
  WG_RETURN_IF_ERROR(m.AttachReadings(walk, g.get()));
  m.PlaceStart(walk, g.get());
  WG_RETURN_IF_ERROR(m.AddUserFactors(walk, g->node_t_));
  return g;
}

bool StepGraph::path_loss_per_anchor() const { return impl_->PathLossPerAnchor(); }

bool StepGraph::AnchorIsState(int anchor_index) const { return impl_->AnchorIsState(anchor_index); }

bool StepGraph::has_floors() const { return impl_->floors; }

std::optional<int> StepGraph::radio_start_floor() const { return impl_->radio_start_floor; }

int StepGraph::FloorOfHeight(double z_m) const { return impl_->Floor(z_m); }

int StepGraph::stair_steps() const { return impl_->stair_steps; }

const StepFrontEndReport& StepGraph::front_end_report() const { return impl_->front_end; }

std::vector<std::vector<Eigen::Vector3d>> StepGraph::StartHypotheses(const Walk& walk,
                                                                     int n) const {
  const Impl& m = *impl_;
  std::vector<std::vector<Eigen::Vector3d>> out;
  if (n <= 0 || m.start || m.radio_only || !(m.any_rss || m.any_range)) return out;
  StepGraphOptions all = m.o;
  all.align_window_s = std::numeric_limits<double>::infinity();  // every fix
  const std::optional<Alignment> a = AlignToFirstFixes(walk, all, node_t_, init_);
  if (!a) return out;
  std::vector<Eigen::Vector3d> aligned = init_;
  Eigen::Vector2d centroid = Eigen::Vector2d::Zero();
  for (Eigen::Vector3d& p : aligned) {
    p.head<2>() = a->R * p.head<2>() + a->t;
    p[2] = NormalizeAngle(p[2] + a->rotation_rad);
    centroid += p.head<2>();
  }
  centroid /= static_cast<double>(aligned.size());
  for (int k = 0; k < n; ++k) {
    const double turn = 2.0 * kPi * k / n;
    const Eigen::Rotation2Dd R(turn);
    std::vector<Eigen::Vector3d> h = aligned;
    for (Eigen::Vector3d& p : h) {
      p.head<2>() = centroid + R * (p.head<2>() - centroid);
      p[2] = NormalizeAngle(p[2] + turn);
    }
    out.push_back(std::move(h));
  }
  return out;
}

bool StepGraph::has_heading_reference() const {
  const Impl& m = *impl_;
  if (!m.o.use_mag_heading) return false;
  return std::any_of(m.steps.begin(), m.steps.end(),
                     [](const Step& s) { return s.has_mag_heading; });
}

std::vector<std::vector<Eigen::Vector3d>> StepGraph::StartHeadingTurns(int n,
                                                                       double until_s) const {
  const Impl& m = *impl_;
  std::vector<std::vector<Eigen::Vector3d>> out;
  const bool relative =
      m.odometry || (!m.steps.empty() && m.front_end.heading_source == HeadingSource::kRelative);
  if (n <= 1 || !m.start || m.start->heading_known || !relative || m.radio_only ||
      m.start_heading_from_fixes || !(m.any_rss || m.any_range)) {
    return out;
  }
  size_t last = 0;  // nodes [0, last): t <= until_s
  while (last < node_t_.size() && node_t_[last] <= until_s) ++last;
  const Eigen::Vector2d s(m.start->x_m, m.start->y_m);
  for (int k = 1; k < n; ++k) {
    const double turn = 2.0 * kPi * k / n;
    const Eigen::Rotation2Dd R(turn);
    std::vector<Eigen::Vector3d> h(init_.begin(), init_.begin() + static_cast<long>(last));
    for (Eigen::Vector3d& p : h) {
      p.head<2>() = s + R * (p.head<2>() - s);
      p[2] = NormalizeAngle(p[2] + turn);
    }
    out.push_back(std::move(h));
  }
  return out;
}

std::vector<std::vector<Eigen::Vector3d>> StepGraph::HypothesesFrom(const Trajectory& trajectory,
                                                                    double until_s) const {
  const Impl& m = *impl_;
  std::vector<std::vector<Eigen::Vector3d>> out;
  if (m.start || m.radio_only || trajectory.empty()) return out;
  const double t0 = trajectory.points.front().t_s, t1 = trajectory.points.back().t_s;
  std::vector<Eigen::Vector2d> src, dst;
  size_t last = 0;  // nodes [0, last) are hypothesized: t <= until_s
  for (size_t k = 0; k < node_t_.size() && node_t_[k] <= until_s; ++k) {
    last = k + 1;
    if (node_t_[k] < t0 || node_t_[k] > t1) continue;
    src.push_back(init_[k].head<2>());
    dst.push_back(trajectory.PositionAt(node_t_[k]).head<2>());
  }
  if (src.size() < 3) return out;
  const Alignment a = Align(src, dst, src.size());  // Procrustes (Umeyama, no scale)
  std::vector<Eigen::Vector3d> aligned(init_.begin(), init_.begin() + static_cast<long>(last));
  for (Eigen::Vector3d& p : aligned) {
    p.head<2>() = a.R * p.head<2>() + a.t;
    p[2] = NormalizeAngle(p[2] + a.rotation_rad);
  }
  std::vector<Eigen::Vector3d> positions = aligned;
  for (size_t k = 0; k < last; ++k) {
    positions[k].head<2>() = trajectory.PositionAt(node_t_[k]).head<2>();
  }
  out.push_back(std::move(aligned));
  out.push_back(std::move(positions));
  return out;
}

namespace {

// The mean pressure of the readings within ±window/2 of t, else the reading nearest in time.
double PressureAt(const std::vector<PressureSample>& p, double t, double window_s) {
  auto by_time = [](const PressureSample& s, double x) { return s.t_s < x; };
  auto lo = std::lower_bound(p.begin(), p.end(), t - 0.5 * window_s, by_time);
  auto hi = std::lower_bound(p.begin(), p.end(), t + 0.5 * window_s, by_time);
  if (lo == hi) {
    auto it = std::lower_bound(p.begin(), p.end(), t, by_time);
    if (it == p.end() || (it != p.begin() && t - (it - 1)->t_s < it->t_s - t)) --it;
    return it->hpa;
  }
  double sum = 0.0;
  for (auto it = lo; it != hi; ++it) sum += it->hpa;
  return sum / static_cast<double>(hi - lo);
}

}  // namespace

// Candidates (dir[k] = ±1 for node k's step): steps whose barometric height changes at the
// rate of stairs, one way.
std::vector<int> StepGraph::Impl::StairCandidates(const Walk& walk,
                                                  const std::vector<double>& node_t) const {
  const std::vector<bool> gap = BridgedNodes(walk, true, node_t);
  const double p0 = PressureAt(walk.pressure, node_t[0], o.baro_window_s);
  auto height = [&](double t) {  // above node 0, as baro_z
    return BarometricHeightM(PressureAt(walk.pressure, t, o.baro_window_s), p0);
  };
  std::vector<int> dir(node_t.size(), 0);
  for (size_t k = 1; k < node_t.size(); ++k) {
    if (gap[k]) continue;
    const double t = 0.5 * (node_t[k - 1] + node_t[k]), h = 0.5 * o.stair_window_s;
    const double rate = (height(t + h) - height(t - h)) / o.stair_window_s;
    if (std::fabs(rate) >= o.stair_rate_mps) dir[k] = rate > 0 ? 1 : -1;
  }
  return dir;
}

int StepGraph::Impl::MarkStairs(const Walk& walk, const std::vector<double>& node_t) {
  on_stairs.assign(node_t.size(), false);
  if (!floors || odometry || radio_only) return 0;
  const std::vector<int> dir = StairCandidates(walk, node_t);
  struct Run {
    size_t a, b;  // candidate steps of nodes [a, b), one way
  };
  std::vector<Run> runs;
  for (size_t a = 1; a < node_t.size();) {
    size_t b = a;
    while (b < node_t.size() && dir[b] != 0 && dir[b] == dir[a]) ++b;
    if (b > a) runs.push_back({a, b});
    a = std::max(b, a + 1);
  }
  // A staircase: runs one way, each starting within stair_landing_s of the previous one's end
  // (a landing between flights), that together change the height by a floor transition's
  // worth (stair_min_rise_storeys × storey); shorter ones are the phone lifted or lowered.
  int n = 0;
  for (size_t i = 0; i < runs.size();) {
    size_t j = i + 1;
    while (j < runs.size() && dir[runs[j].a] == dir[runs[i].a] &&
           node_t[runs[j].a - 1] - node_t[runs[j - 1].b - 1] <= o.stair_landing_s) {
      ++j;
    }
    const double rise = baro_z[runs[j - 1].b - 1] - baro_z[runs[i].a - 1];
    for (size_t r = i; r < j && std::fabs(rise) >= o.stair_min_rise_storeys * storey_m; ++r) {
      for (size_t k = runs[r].a; k < runs[r].b; ++k) {
        on_stairs[k] = true;  // no level factor (also with stairs: false)
        if (!o.stairs) continue;
        steps[k - 1].length_m = o.stair_tread_m;
        steps[k - 1].sigma_length_m = o.stair_tread_sigma_m;
        ++n;
      }
    }
    i = j;
  }
  return n;
}

// The heights' causal estimate: a scalar Kalman filter along the height chain with the
// graph's own height factors — node 0 at the start height (σ start_height_sigma_m); each step
// the barometric change, on a level walking step combined with the level factor's 0 by their
// information; a level node whose filtered height lies within floor_snap_storeys of a floor's
// level f × storey gets that level as a measurement (σ floor_sigma_m), and the graph the same
// prior (floor_level). Forward only, so fg-window's online output stays causal. Its heights
// are the readings' receiver heights and the height states' initial values.
Status StepGraph::Impl::ChainHeights(const std::vector<double>& node_t) {
  node_z.assign(node_t.size(), start_z);
  floor_level.assign(node_t.size(), std::numeric_limits<double>::quiet_NaN());
  if (!floors) return Status::Ok();
  Eigen::VectorXd x = Eigen::VectorXd::Constant(1, start_z);
  Eigen::MatrixXd P = Eigen::MatrixXd::Constant(1, 1, std::pow(o.start_height_sigma_m, 2));
  const Eigen::MatrixXd H = Eigen::MatrixXd::Identity(1, 1);
  const Eigen::MatrixXd R = Eigen::MatrixXd::Constant(1, 1, std::pow(o.floor_sigma_m, 2));
  for (size_t k = 1; k < node_t.size(); ++k) {
    const double dt = node_t[k] - node_t[k - 1];
    const bool level = LevelStep(static_cast<int>(k), dt);
    double dz = baro_z[k] - baro_z[k - 1], var = std::pow(BaroSigma(dt), 2);
    if (level) {
      const double info = 1.0 / var + 1.0 / (o.level_sigma_m * o.level_sigma_m);
      dz *= 1.0 / (var * info);
      var = 1.0 / info;
    }
    x[0] += dz;
    P(0, 0) += var;
    const double z_floor = Floor(x[0]) * storey_m;
    if (level && o.floor_sigma_m > 0 &&
        std::fabs(x[0] - z_floor) <= o.floor_snap_storeys * storey_m) {
      floor_level[k] = z_floor;
      WG_RETURN_IF_ERROR(
          KalmanUpdate(Eigen::VectorXd::Constant(1, z_floor - x[0]), H, R, 0.0, &x, &P).status());
    }
    node_z[k] = x[0];
  }
  return Status::Ok();
}

// Each node's pressure: PressureAt (±baro_window_s/2); heights above node 0's by the standard
// atmosphere.
void StepGraph::Impl::MakeHeights(const Walk& walk, const std::vector<double>& node_t) {
  storey_m = walk.meta.storey_height_m;
  const int start_floor =
      start && start->floor ? *start->floor : 0;  // the truth's floors are not an input
  start_z = start_floor * storey_m;
  floors = o.floors && !walk.pressure.empty();
  if (!floors) return;
  std::vector<double> hpa;
  for (double t : node_t) hpa.push_back(PressureAt(walk.pressure, t, o.baro_window_s));
  baro_z.clear();
  for (double v : hpa) baro_z.push_back(BarometricHeightM(v, hpa.front()));
}

std::optional<int> StepGraph::Impl::RadioStartFloor(const Walk& walk,
                                                    const std::vector<double>& node_t) const {
  std::map<int, int> anchor_floor_of;
  for (const Anchor& a : walk.anchors) {
    if (a.floor && a.surveyed()) anchor_floor_of[a.id] = *a.floor;  // others' floors: guesses
  }
  if (anchor_floor_of.empty() || node_t.empty()) return std::nullopt;
  const double sign = walk.meta.radio.units == RssUnits::kDbm ? 1.0 : -1.0;  // larger: stronger
  std::map<int, std::vector<double>> votes;  // start floor -> sign · RSS of its readings
  for (const RssSample& r : walk.rss) {
    const auto f = anchor_floor_of.find(r.anchor_id);
    if (f == anchor_floor_of.end() || !std::isfinite(r.rss)) continue;
    const size_t k = std::min<size_t>(
        std::lower_bound(node_t.begin(), node_t.end(), r.t_s) - node_t.begin(), node_t.size() - 1);
    const int climbed = Floor(node_z[k]) - Floor(start_z);
    votes[f->second - climbed].push_back(sign * r.rss);
  }
  std::optional<int> best;
  double best_level = -std::numeric_limits<double>::infinity();
  for (auto& [floor, v] : votes) {
    const size_t top = std::min<size_t>(3, v.size());
    std::partial_sort(v.begin(), v.begin() + top, v.end(), std::greater<double>());
    double level = 0.0;
    for (size_t i = 0; i < top; ++i) level += v[i] / static_cast<double>(top);
    if (level > best_level) {
      best_level = level;
      best = floor;
    }
  }
  return best;
}

bool StepGraph::path_loss_estimated() const {
  return impl_->any_rss && impl_->o.rss_residual == RssResidual::kDb &&
         impl_->o.path_loss != PathLossMode::kFixed;
}

}  // namespace walkgraph
