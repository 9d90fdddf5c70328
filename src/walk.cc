#include "walkgraph/walk.h"

#include <algorithm>
#include <limits>
#include <set>
#include <utility>

#include "util/median.h"
#include "walkgraph/trajectory.h"

namespace walkgraph {

const EnumNames<ImuPlacement>& ImuPlacementNames() {
  static const EnumNames<ImuPlacement> names = {{"none", ImuPlacement::kNone},
                                                {"foot", ImuPlacement::kFoot},
                                                {"waist", ImuPlacement::kWaist},
                                                {"hip", ImuPlacement::kHip},
                                                {"handheld", ImuPlacement::kHandheld}};
  return names;
}
const EnumNames<TruthKind>& TruthKindNames() {
  static const EnumNames<TruthKind> names = {{"none", TruthKind::kNone},
                                             {"continuous", TruthKind::kContinuous},
                                             {"checkpoints", TruthKind::kCheckpoints}};
  return names;
}
const EnumNames<RadioKind>& RadioKindNames() {
  static const EnumNames<RadioKind> names = {
      {"none", RadioKind::kNone}, {"rss", RadioKind::kRss}, {"range", RadioKind::kRange}};
  return names;
}
const EnumNames<RssUnits>& RssUnitsNames() {
  static const EnumNames<RssUnits> names = {{"dbm", RssUnits::kDbm}, {"rfcode", RssUnits::kRfcode}};
  return names;
}
const char* ToString(ImuPlacement p) { return EnumName(ImuPlacementNames(), p); }
const char* ToString(TruthKind k) { return EnumName(TruthKindNames(), k); }
const char* ToString(RadioKind k) { return EnumName(RadioKindNames(), k); }
const char* ToString(RssUnits u) { return EnumName(RssUnitsNames(), u); }

int Walk::StartFloor() const {
  if (meta.initial_pose && meta.initial_pose->floor) return *meta.initial_pose->floor;
  if (!truth.empty() && truth.front().floor) return *truth.front().floor;
  return 0;
}

bool Walk::has_truth_floors() const {
  for (const TruthSample& s : truth) {
    if (s.floor) return true;
  }
  return false;
}

double Walk::AnchorHeightM(const Anchor& a) const {
  return a.floor ? *a.floor * meta.storey_height_m + a.position_m.z() : a.position_m.z();
}

int Walk::AnchorReadings(int id) const {
  int n = 0;
  for (const RssSample& s : rss) n += s.anchor_id == id ? 1 : 0;
  for (const RangeSample& s : ranges) n += s.anchor_id == id ? 1 : 0;
  return n;
}

int Walk::AnchorIndex(int id) const {
  for (size_t i = 0; i < anchors.size(); ++i) {
    if (anchors[i].id == id) return static_cast<int>(i);
  }
  return -1;
}

bool Walk::has_unknown_anchors() const {
  return std::any_of(anchors.begin(), anchors.end(),
                     [](const Anchor& a) { return !a.position_known; });
}

Walk WithoutAnchors(const Walk& walk, const std::set<int>& ids, UnknownAnchorsDropped* dropped) {
  UnknownAnchorsDropped d;
  Walk out = walk;
  out.anchors.clear();
  for (const Anchor& a : walk.anchors) {
    if (ids.count(a.id) == 0) out.anchors.push_back(a);
  }
  d.anchors = static_cast<int>(walk.anchors.size() - out.anchors.size());
  auto drop = [&](auto* samples) {
    const size_t before = samples->size();
    samples->erase(std::remove_if(samples->begin(), samples->end(),
                                  [&](const auto& s) { return ids.count(s.anchor_id) > 0; }),
                   samples->end());
    return static_cast<int>(before - samples->size());
  };
  if (d.anchors > 0) {
    d.rss_readings = drop(&out.rss);
    d.range_readings = drop(&out.ranges);
  }
  if (dropped) *dropped = d;
  return out;
}

Walk WithoutUnknownAnchors(const Walk& walk, UnknownAnchorsDropped* dropped) {
  std::set<int> unknown;
  for (const Anchor& a : walk.anchors) {
    if (!a.position_known) unknown.insert(a.id);
  }
  return WithoutAnchors(walk, unknown, dropped);
}

double MedianImuIntervalS(const std::vector<ImuSample>& imu) {
  if (imu.size() < 2) return 0.0;
  std::vector<double> dt;
  dt.reserve(imu.size() - 1);
  for (size_t i = 1; i < imu.size(); ++i) dt.push_back(imu[i].t_s - imu[i - 1].t_s);
  return internal::Median(std::move(dt));
}

double ImuGapThresholdS(const std::vector<ImuSample>& imu) {
  if (imu.size() < 3) return std::numeric_limits<double>::infinity();
  return kImuGapFactor * MedianImuIntervalS(imu);
}

std::vector<ImuGap> Walk::ImuGaps() const {
  std::vector<ImuGap> gaps;
  const double limit = ImuGapThresholdS(imu);
  for (size_t i = 1; i < imu.size(); ++i) {
    if (imu[i].t_s - imu[i - 1].t_s > limit) gaps.push_back({imu[i - 1].t_s, imu[i].t_s});
  }
  return gaps;
}

double Walk::StartTime() const {
  double t = std::numeric_limits<double>::infinity();
  if (!imu.empty()) t = std::min(t, imu.front().t_s);
  if (!rss.empty()) t = std::min(t, rss.front().t_s);
  if (!ranges.empty()) t = std::min(t, ranges.front().t_s);
  if (!odometry.empty()) t = std::min(t, odometry.front().t_s);
  if (!truth.empty()) t = std::min(t, truth.front().t_s);
  return std::isfinite(t) ? t : 0.0;
}

double Walk::EndTime() const {
  double t = -std::numeric_limits<double>::infinity();
  if (!imu.empty()) t = std::max(t, imu.back().t_s);
  if (!rss.empty()) t = std::max(t, rss.back().t_s);
  if (!ranges.empty()) t = std::max(t, ranges.back().t_s);
  if (!odometry.empty()) t = std::max(t, odometry.back().t_s);
  if (!truth.empty()) t = std::max(t, truth.back().t_s);
  return std::isfinite(t) ? t : 0.0;
}

std::vector<double> Walk::TruthDistances() const {
  std::vector<double> d;
  d.reserve(truth.size());
  for (size_t i = 0; i < truth.size(); ++i) {
    d.push_back(
        i == 0 ? 0.0 : d.back() + (truth[i].position_m - truth[i - 1].position_m).head<2>().norm());
  }
  return d;
}

double Walk::TruthDistance() const {
  const std::vector<double> d = TruthDistances();
  return d.empty() ? 0.0 : d.back();
}

Trajectory::Bracket Trajectory::BracketAt(double t_s) const {
  if (t_s <= points.front().t_s) return {0, 0, 0.0};
  const size_t last = points.size() - 1;
  if (t_s >= points.back().t_s) return {last, last, 0.0};
  const auto it = std::lower_bound(points.begin(), points.end(), t_s,
                                   [](const TrajectoryPoint& p, double t) { return p.t_s < t; });
  const size_t b = static_cast<size_t>(it - points.begin());
  return {b - 1, b, (t_s - points[b - 1].t_s) / (points[b].t_s - points[b - 1].t_s)};
}

Eigen::Vector3d Trajectory::PositionAt(double t_s) const {
  const Bracket k = BracketAt(t_s);
  return (1.0 - k.w) * points[k.a].position_m + k.w * points[k.b].position_m;
}

std::optional<int> Trajectory::FloorAt(double t_s) const {
  const Bracket k = BracketAt(t_s);
  return points[k.w < 0.5 ? k.a : k.b].floor;
}

std::optional<Eigen::Matrix2d> Trajectory::PositionCovarianceAt(double t_s) const {
  const Bracket k = BracketAt(t_s);
  const auto& ca = points[k.a].covariance;
  const auto& cb = points[k.b].covariance;
  if (!ca || !cb) return std::nullopt;
  return Eigen::Matrix2d((1.0 - k.w) * ca->topLeftCorner<2, 2>() + k.w * cb->topLeftCorner<2, 2>());
}

}  // namespace walkgraph
