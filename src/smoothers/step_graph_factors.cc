// StepGraph's states and factors, node by node (StaticStates, NodeStates, FactorsAt): the one
// unit that instantiates the step graph's autodiff factors (step_graph_impl.h says why).
#include <memory>
#include <set>
#include <utility>
#include <vector>

#include "factors/anchor_state_factors.h"
#include "factors/barometric_height_factor.h"
#include "factors/difference_prior_factor.h"
#include "factors/heading_factor.h"
#include "factors/heading_increment_factor.h"
#include "factors/odometry_factor.h"
#include "factors/position_prior_factor.h"
#include "factors/position_random_walk_factor.h"
#include "factors/range_factor.h"
#include "factors/rss_factor.h"
#include "factors/rss_range_factor.h"
#include "factors/step_factor.h"
#include "smoothers/step_graph_impl.h"
#include "walkgraph/smoothers/step_graph.h"

namespace walkgraph {

using internal::DiagonalPrior;
using internal::kGyroBiasKey;
using internal::kPathLossMeanKey;
using internal::PathLossKey;
using internal::RangeBiasKey;
using internal::RangeScaleKey;

std::vector<GraphState> StepGraph::StaticStates() const {
  const Impl& m = *impl_;
  std::vector<GraphState> out;
  // One state per calibration group of the anchors with that kind of reading (group: the
  // anchor index or 0), each starting at `value`.
  auto per_group = [&](const std::vector<bool>& has, int (Impl::*group)(int) const, Key (*key)(int),
                       std::vector<double> value, bool constant) {
    std::set<int> groups;
    for (size_t a = 0; a < m.anchors.size(); ++a) {
      if (has[a]) groups.insert((m.*group)(static_cast<int>(a)));
    }
    for (int gr : groups) {
      GraphState s;
      s.key = key(gr);
      s.value = value;
      s.constant = constant;
      out.push_back(std::move(s));
    }
  };
  const PathLossParams& pl = m.radio.path_loss;
  if (m.any_rss && m.o.rss_residual == RssResidual::kDb) {
    per_group(m.anchor_has_rss, &Impl::PathLossGroup, PathLossKey, {pl.A_dbm, pl.eta},
              m.o.path_loss == PathLossMode::kFixed);
    if (m.o.path_loss == PathLossMode::kHierarchical) {
      GraphState s;
      s.key = kPathLossMeanKey;
      s.value = {pl.A_dbm, pl.eta};
      out.push_back(std::move(s));
    }
  }
  if (m.any_range) {
    per_group(m.anchor_has_range, &Impl::RangeBiasGroup, RangeBiasKey, {0.0},
              m.o.range_bias == CalibrationScope::kNone);
    per_group(m.anchor_has_range, &Impl::RangeScaleGroup, RangeScaleKey, {0.0},
              m.o.range_scale == CalibrationScope::kNone);
  }
  for (size_t a = 0; a < m.anchors.size(); ++a) {
    if (!m.AnchorIsState(static_cast<int>(a))) continue;
    GraphState s;
    s.key = internal::AnchorPositionKey(static_cast<int>(a));
    s.value = {m.anchors[a].position_m.x(), m.anchors[a].position_m.y()};
    out.push_back(std::move(s));
  }
  if (!m.odometry && !m.radio_only && m.o.estimate_gyro_bias) {
    GraphState s;
    s.key = kGyroBiasKey;
    s.value = {0.0};
    out.push_back(std::move(s));
  }
  if (m.EstimatesStepScale()) {
    GraphState s;
    s.key = internal::kStepScaleKey;
    s.value = {0.0};
    out.push_back(std::move(s));
  }
  return out;
}

std::vector<GraphState> StepGraph::NodeStates(int k, const Eigen::Vector2d& prev_p,
                                              double prev_theta) const {
  const Impl& m = *impl_;
  const Eigen::Vector3d x =
      k > 0 ? m.Predict(k, Eigen::Vector3d(prev_p.x(), prev_p.y(), prev_theta)) : init_[0];
  GraphState p, th;
  p.key = PositionKey(k);
  p.t_s = node_t_[k];
  p.value = {x[0], x[1]};
  th.key = HeadingKey(k);
  th.t_s = node_t_[k];
  th.value = {x[2]};
  th.manifold = m.angle;
  if (k == 0 && fix_first_node_) p.constant = th.constant = true;
  if (m.radio_only) th.constant = true;  // no heading information without steps
  if (!m.floors) return {p, th};
  GraphState z;
  z.key = HeightKey(k);
  z.t_s = node_t_[k];
  z.value = {m.node_z[k]};
  return {p, th, z};
}

namespace {

// A factor that takes ownership of `cost`.
void AppendFactor(ceres::CostFunction* cost, std::vector<Key> keys,
                  std::shared_ptr<const ceres::LossFunction> loss, std::vector<GraphFactor>* out) {
  GraphFactor f;
  f.cost.reset(cost);
  f.keys = std::move(keys);
  f.loss = std::move(loss);
  out->push_back(std::move(f));
}

}  // namespace

// The factors of the readings whose newest node is k (radio, waypoints).
void StepGraph::Impl::AddReadingFactors(int k, std::vector<GraphFactor>* out) const {
  for (const Reading& r : readings_at[k]) {
    const size_t before = out->size();
    AddReading(r, out);
    if (out->size() > before && r.kind != Reading::Kind::kWaypoint) {
      out->back().noise_group =
          r.kind == Reading::Kind::kRss ? internal::kRssNoise : internal::kRangeNoise;
    }
  }
}

// The factor of one reading (radio, waypoint).
void StepGraph::Impl::AddReading(const Reading& r, std::vector<GraphFactor>* out) const {
  auto add = [&](ceres::CostFunction* cost, std::vector<Key> keys,
                 std::shared_ptr<const ceres::LossFunction> loss = nullptr) {
    AppendFactor(cost, std::move(keys), std::move(loss), out);
  };
  const PathLossParams& pl = radio.path_loss;
  const double sign = radio.units == RssUnits::kDbm ? 1.0 : -1.0;
  const double range_sigma = o.range_sigma_m > 0 ? o.range_sigma_m : radio.range_sigma_m;
  std::vector<Key> keys = {PositionKey(r.node_a)};
  if (r.node_b >= 0) keys.push_back(PositionKey(r.node_b));
  const bool two = r.node_b >= 0;
  if (r.kind == Reading::Kind::kWaypoint) {
    const Waypoint& w = waypoints[r.index];
    add(two ? PositionPriorFactor<2>::CreateInterpolated(w.position_m, w.sigma_m, r.alpha)
            : PositionPriorFactor<2>::Create(w.position_m, w.sigma_m),
        keys);
    return;
  }
  const Eigen::Vector3d& anchor = anchors[r.index].position_m;
  const bool anchor_state = AnchorIsState(r.index);
  // The dB-domain reading (RssFactor, AnchorRssFactor), floors taken into account.
  auto rss_reading = [&] {
    RssFactor<2>::Reading rd;
    rd.rss = r.value;
    rd.anchor_m = anchor;
    rd.sigma_db = pl.sigma_db;
    rd.sign = sign;
    rd.d0_m = pl.d0_m;
    rd.receiver_height_m = o.receiver_height_m;
    FloorAware(r.index, r.node_a, r.node_b, r.alpha, sign, &rd.rss, &rd.anchor_m,
               &rd.receiver_height_m);
    return rd;
  };
  if (anchor_state && r.kind == Reading::Kind::kRss) {  // Build: RSS in dB then
    const RssFactor<2>::Reading rd = rss_reading();
    keys.push_back(internal::AnchorPositionKey(r.index));
    keys.push_back(PathLossKey(PathLossGroup(r.index)));
    add(two ? AnchorRssFactor<2>::CreateInterpolated(rd, r.alpha) : AnchorRssFactor<2>::Create(rd),
        keys, rss_loss);
  } else if (anchor_state) {
    keys.push_back(internal::AnchorPositionKey(r.index));
    keys.push_back(RangeBiasKey(RangeBiasGroup(r.index)));
    keys.push_back(RangeScaleKey(RangeScaleGroup(r.index)));
    add(two ? AnchorRangeFactor<2>::CreateInterpolated(r.value, anchor.z(), range_sigma, r.alpha,
                                                       o.receiver_height_m)
            : AnchorRangeFactor<2>::Create(r.value, anchor.z(), range_sigma, o.receiver_height_m),
        keys, range_loss);
  } else if (r.kind == Reading::Kind::kRss && o.rss_residual == RssResidual::kDb) {
    const RssFactor<2>::Reading rd = rss_reading();
    keys.push_back(PathLossKey(PathLossGroup(r.index)));
    add(two ? RssFactor<2>::CreateInterpolated(rd, r.alpha) : RssFactor<2>::Create(rd), keys,
        rss_loss);
  } else if (r.kind == Reading::Kind::kRss) {
    RssRangeFactor<2>::Reading rd;
    rd.rss = r.value;
    rd.anchor_m = anchor;
    rd.A = pl.A_dbm;
    rd.eta = pl.eta;
    rd.d0_m = pl.d0_m;
    rd.sigma_db = pl.sigma_db;
    rd.sign = sign;
    rd.receiver_height_m = o.receiver_height_m;
    FloorAware(r.index, r.node_a, r.node_b, r.alpha, sign, &rd.rss, &rd.anchor_m,
               &rd.receiver_height_m);
    add(two ? RssRangeFactor<2>::CreateInterpolated(rd, r.alpha) : RssRangeFactor<2>::Create(rd),
        keys, rss_loss);
  } else {
    keys.push_back(RangeBiasKey(RangeBiasGroup(r.index)));
    keys.push_back(RangeScaleKey(RangeScaleGroup(r.index)));
    add(two ? ScaledRangeFactor<2>::CreateInterpolated(r.value, anchor, range_sigma, r.alpha,
                                                       o.receiver_height_m)
            : ScaledRangeFactor<2>::Create(r.value, anchor, range_sigma, o.receiver_height_m),
        keys, range_loss);
  }
}

std::vector<StepGraph::AnchorReading> StepGraph::AnchorReadingsAt(int k) const {
  std::vector<AnchorReading> out;
  for (const Impl::Reading& r : impl_->readings_at[k]) {
    if (r.kind == Impl::Reading::Kind::kWaypoint) continue;
    out.push_back(
        {r.index, r.kind == Impl::Reading::Kind::kRange, r.value, r.node_a, r.node_b, r.alpha});
  }
  return out;
}

std::vector<Key> StepGraph::AnchorOwnKeys(int a) const {
  const Impl& m = *impl_;
  std::vector<Key> out;
  if (!m.AnchorIsState(a)) return out;
  out.push_back(internal::AnchorPositionKey(a));
  if (m.anchor_has_rss[a] && m.PathLossPerAnchor()) out.push_back(PathLossKey(a));
  if (m.anchor_has_range[a] && m.o.range_bias == CalibrationScope::kPerAnchor) {
    out.push_back(RangeBiasKey(a));
  }
  if (m.anchor_has_range[a] && m.o.range_scale == CalibrationScope::kPerAnchor) {
    out.push_back(RangeScaleKey(a));
  }
  return out;
}

// The priors of a step graph's static states (its first node's factors): gyro bias, step-length
// scale, anchors of surveyed σ, range scale and bias, path loss.
void StepGraph::Impl::AddStaticPriors(const std::vector<GraphState>& statics,
                                      std::vector<GraphFactor>* out) const {
  const Impl& m = *this;
  auto add = [&](ceres::CostFunction* cost, std::vector<Key> keys) {
    AppendFactor(cost, std::move(keys), nullptr, out);
  };
  auto add_owned = [&](std::unique_ptr<ceres::CostFunction> cost, std::vector<Key> keys) {
    GraphFactor f;
    f.cost = std::move(cost);
    f.keys = std::move(keys);
    out->push_back(std::move(f));
  };
  for (const GraphState& s : statics) {
    if (s.constant) continue;
    const char letter = SymbolLetter(s.key);
    if (s.key == kGyroBiasKey) {
      add_owned(DiagonalPrior(Eigen::VectorXd::Zero(1),
                              Eigen::VectorXd::Constant(1, o.gyro_bias_prior_sigma_radps)),
                {s.key});
    } else if (s.key == internal::kStepScaleKey) {
      add_owned(DiagonalPrior(Eigen::VectorXd::Zero(1),
                              Eigen::VectorXd::Constant(1, o.step_scale_prior_sigma)),
                {s.key});
    } else if (letter == 'p') {  // an anchor's position: its survey's σ (none if unknown)
      const Anchor& a = m.anchors[SymbolIndex(s.key)];
      if (a.position_known && a.sigma_m > 0.0) {
        add_owned(DiagonalPrior(a.position_m.head<2>(), Eigen::Vector2d::Constant(a.sigma_m)),
                  {s.key});
      }
    } else if (letter == 's') {
      add_owned(DiagonalPrior(Eigen::VectorXd::Zero(1),
                              Eigen::VectorXd::Constant(1, o.range_scale_prior_sigma)),
                {s.key});
    } else if (letter == 'b') {
      add_owned(DiagonalPrior(Eigen::VectorXd::Zero(1),
                              Eigen::VectorXd::Constant(1, o.range_bias_prior_sigma_m)),
                {s.key});
    } else if (letter == 'l' && o.path_loss == PathLossMode::kHierarchical) {  // tied to the mean
      add(DifferencePriorFactor<2>::Create(
              Eigen::Vector2d(o.A_spread_prior_db, o.eta_spread_prior)),
          {s.key, kPathLossMeanKey});
    } else {  // path loss (a block, or hierarchical's mean): weak prior at the walk's model
      add_owned(DiagonalPrior(Eigen::Vector2d(s.value[0], s.value[1]),
                              Eigen::Vector2d(o.A_prior_sigma_db, o.eta_prior_sigma)),
                {s.key});
    }
  }
}

std::vector<GraphFactor> StepGraph::FactorsAt(int k) const {
  const Impl& m = *impl_;
  const StepGraphOptions& o = m.o;
  std::vector<GraphFactor> out;
  auto add = [&](ceres::CostFunction* cost, std::vector<Key> keys,
                 std::shared_ptr<const ceres::LossFunction> loss = nullptr) {
    AppendFactor(cost, std::move(keys), std::move(loss), &out);
  };
  auto add_owned = [&](std::unique_ptr<ceres::CostFunction> cost, std::vector<Key> keys) {
    GraphFactor f;
    f.cost = std::move(cost);
    f.keys = std::move(keys);
    out.push_back(std::move(f));
  };

  if (k == 0) {
    if (m.start) {  // the known start pose
      add_owned(DiagonalPrior(Eigen::Vector2d(m.start->x_m, m.start->y_m),
                              Eigen::Vector2d::Constant(m.start->sigma_xy_m)),
                {PositionKey(0)});
      if (m.start->heading_known) {
        add(HeadingFactor::Create(m.start->heading_rad, m.start->sigma_heading_rad),
            {HeadingKey(0)});
      }
    }
    m.AddStaticPriors(StaticStates(), &out);
  } else if (m.radio_only) {
    add(PositionRandomWalkFactor::Create(node_t_[k] - node_t_[k - 1], o.motion_sigma_mps),
        {PositionKey(k - 1), PositionKey(k)});
  } else if (m.odometry) {
    const OdometrySample& s = m.odom[k - 1];
    const double sd =
        std::max(o.odometry_sigma_dist_frac * std::fabs(s.dist_m) + o.odometry_sigma_dist_m, 1e-6);
    add(OdometryFactor::Create(s.dist_m, s.dheading_rad, sd, o.odometry_sigma_cross_m,
                               o.odometry_sigma_dheading_rad),
        {PositionKey(k - 1), HeadingKey(k - 1), PositionKey(k), HeadingKey(k)});
  } else if (m.bridged[k]) {
    // Across an IMU gap: no step and no gyro to integrate. The walker moved at most about
    // bridge_speed_mps × Δt (1σ) and may have turned any way.
    const double dt = node_t_[k] - node_t_[k - 1];
    add(PositionRandomWalkFactor::Create(dt, o.bridge_speed_mps * std::sqrt(dt)),
        {PositionKey(k - 1), PositionKey(k)});
    add(HeadingIncrementFactor::Create(0.0, kPi), {HeadingKey(k - 1), HeadingKey(k)});
  } else {
    const Step& s = m.steps[k - 1];
    const double sl = std::max(o.step_sigma_scale * s.sigma_length_m, o.min_sigma_length_m);
    if (m.EstimatesStepScale()) {
      add(StepFactor::CreateWithScale(s.length_m, sl, o.sigma_cross_m),
          {PositionKey(k - 1), PositionKey(k), HeadingKey(k), internal::kStepScaleKey});
    } else {
      add(StepFactor::Create(s.length_m, sl, o.sigma_cross_m),
          {PositionKey(k - 1), PositionKey(k), HeadingKey(k)});
    }
    out.back().noise_group = internal::kStepNoise;
    const double sh =
        std::max(o.dheading_sigma_scale * s.sigma_dheading_rad, o.min_sigma_dheading_rad);
    if (o.estimate_gyro_bias) {
      add(HeadingIncrementFactor::CreateWithBias(s.dheading_rad, node_t_[k] - node_t_[k - 1], sh),
          {HeadingKey(k - 1), HeadingKey(k), kGyroBiasKey});
    } else {
      add(HeadingIncrementFactor::Create(s.dheading_rad, sh), {HeadingKey(k - 1), HeadingKey(k)});
    }
    out.back().noise_group = internal::kHeadingIncrementNoise;
    if (o.use_mag_heading && s.has_mag_heading) {
      add(HeadingFactor::Create(s.mag_heading_rad, o.mag_heading_sigma_rad), {HeadingKey(k)},
          m.mag_loss);
      out.back().noise_group = internal::kMagHeadingNoise;
    }
  }

  if (m.floors && k == 0) {
    add_owned(DiagonalPrior(Eigen::VectorXd::Constant(1, m.start_z),
                            Eigen::VectorXd::Constant(1, o.start_height_sigma_m)),
              {HeightKey(0)});
  } else if (m.floors) {
    const double dt = node_t_[k] - node_t_[k - 1];
    add(BarometricHeightFactor::Create(m.baro_z[k] - m.baro_z[k - 1], m.BaroSigma(dt)),
        {HeightKey(k - 1), HeightKey(k)});
    // A walking step off the stairs keeps the height: the barometer's drift stays out of it;
    // and it is on a floor (ChainHeights).
    if (m.LevelStep(k, dt)) {
      add(BarometricHeightFactor::Create(0.0, o.level_sigma_m), {HeightKey(k - 1), HeightKey(k)});
    }
    if (std::isfinite(m.floor_level[k])) {
      add_owned(DiagonalPrior(Eigen::VectorXd::Constant(1, m.floor_level[k]),
                              Eigen::VectorXd::Constant(1, o.floor_sigma_m)),
                {HeightKey(k)});
    }
  }
  m.AddReadingFactors(k, &out);
  for (const GraphFactor& f : m.user_at[k]) out.push_back(f);  // shared cost functions
  return out;
}

}  // namespace walkgraph
