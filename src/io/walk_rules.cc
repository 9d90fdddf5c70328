// The walk's row rules (walk_rules.h): shared by the readers (walk_reader.cc), which prefix
// "file:line: ", and ValidateWalk (walk_validation.cc), which prefixes the stream and index.
#include "io/walk_rules.h"

#include <cctype>
#include <cmath>
#include <iomanip>
#include <sstream>

#include "util/text.h"
#include "walkgraph/angle.h"

namespace walkgraph::internal {

namespace {

// Timestamps are seconds; beyond kMaxTimeS (year 2286 as Unix time) they are in another unit.
constexpr double kMaxTimeS = 1e10;

std::string CheckTimeRange(double t) {
  if (t < 0.0) return "t_s must be >= 0, found " + Num(t);
  if (t <= kMaxTimeS) return "";
  for (const auto& [factor, unit] : {std::pair<double, const char*>{1e3, "milliseconds"},
                                     {1e6, "microseconds"},
                                     {1e9, "nanoseconds"}}) {
    if (t / factor <= kMaxTimeS) {
      return "t_s " + Num(t) + " is beyond " + Num(kMaxTimeS) + " s; it looks like " + unit + " (" +
             Num(t / factor) + " s); expected seconds";
    }
  }
  return "t_s " + Num(t) + " is beyond " + Num(kMaxTimeS) + " s; expected seconds";
}

constexpr double kMaxAnchorSigmaM = 1000.0;
constexpr size_t kMaxGroupBytes = 32;

// "" when `group` is a plain word (letters, digits, '_', '-', '.'; at most 32 bytes).
std::string CheckAnchorGroup(const std::string& group) {
  if (group.size() > kMaxGroupBytes) return "group longer than 32 characters";
  for (char c : group) {
    if (!(std::isalnum(static_cast<unsigned char>(c)) || c == '_' || c == '-' || c == '.')) {
      return "group " + internal::Quoted(group) +
             " is not a plain word; expected letters, digits, '_', '-' or '.' (e.g. ble, wifi)";
    }
  }
  return "";
}

}  // namespace

std::string CheckTimeStrictlyIncreasing(double t, const double* prev_t) {
  if (std::string e = CheckTimeRange(t); !e.empty()) return e;
  if (prev_t == nullptr || t > *prev_t) return "";
  std::ostringstream s;
  s << std::setprecision(15) << "timestamp " << t
    << (t == *prev_t ? " repeats the previous one" : " goes backwards (previous ");
  if (t != *prev_t) s << *prev_t << ")";
  s << "; expected strictly increasing t_s";
  return s.str();
}

// Multi-anchor streams: timestamps never go backwards; per anchor they strictly increase.
std::string CheckRadioTime(double t, int anchor_id, double* last_t,
                           std::unordered_map<int, double>* last_by_anchor, bool first) {
  if (std::string e = CheckTimeRange(t); !e.empty()) return e;
  if (!first && t < *last_t) {
    return "timestamp " + Num(t) + " goes backwards (previous " + Num(*last_t) +
           "); expected non-decreasing t_s";
  }
  auto it = last_by_anchor->find(anchor_id);
  if (it != last_by_anchor->end() && !(t > it->second)) {
    return "timestamp " + Num(t) + " repeats for anchor " + std::to_string(anchor_id) +
           "; expected one reading per anchor per time";
  }
  (*last_by_anchor)[anchor_id] = t;
  *last_t = t;
  return "";
}

bool IsIntegral(double v) { return std::floor(v) == v && std::fabs(v) < 2.0e9; }

// A floor number: an integer level, 0 the ground floor, negative below ("" when it is one).
constexpr int kMaxAbsFloor = 200;
std::string CheckFloor(double v) {
  if (IsIntegral(v) && std::fabs(v) <= kMaxAbsFloor) return "";
  return "floor " + Num(v) + " is not an integer level in [-" + std::to_string(kMaxAbsFloor) +
         ", " + std::to_string(kMaxAbsFloor) + "]";
}

// Barometer readings: sea-level pressure is ~1013 hPa; 300 hPa is above Everest's summit,
// 1100 hPa below the Dead Sea's shore.
constexpr double kMinPressureHpa = 300.0, kMaxPressureHpa = 1100.0;
std::string CheckPressure(const PressureSample& s, const PressureSample* previous) {
  if (!std::isfinite(s.t_s) || !std::isfinite(s.hpa)) return "non-finite value";
  std::string e = CheckTimeStrictlyIncreasing(s.t_s, previous ? &previous->t_s : nullptr);
  if (e.empty() && !(s.hpa >= kMinPressureHpa && s.hpa <= kMaxPressureHpa)) {
    e = "hpa " + Num(s.hpa) + " outside [" + Num(kMinPressureHpa) + ", " + Num(kMaxPressureHpa) +
        "] hPa; expected a barometer reading in hectopascal";
  }
  return e;
}

// The storey height of walk.yaml (metres between consecutive floors).
std::string CheckStoreyHeight(double h) {
  if (std::isfinite(h) && h >= 1.0 && h <= 20.0) return "";
  return "storey_height_m " + Num(h) + " outside [1, 20] m";
}

// "" when the anchor's survey fields agree (sigma_m in [0, 1000] m, none on an unknown anchor).
std::string CheckAnchorSurvey(const Anchor& a) {
  if (!(a.sigma_m >= 0.0 && a.sigma_m <= kMaxAnchorSigmaM)) {
    return "sigma_m " + Num(a.sigma_m) + " outside [0, 1000] m";
  }
  if (!a.position_known && a.sigma_m > 0.0) {
    return "sigma_m " + Num(a.sigma_m) +
           " on an anchor of unknown position (empty x_m, y_m); expected 0 or empty";
  }
  return CheckAnchorGroup(a.group);
}

// A waypoint's rule, for the reader and ValidateWalk alike ("" when it holds).
std::string CheckWaypoint(const Waypoint& w, const Waypoint* previous,
                          const ValidationLimits& lim) {
  if (!std::isfinite(w.t_s) || !w.position_m.allFinite() || !std::isfinite(w.sigma_m)) {
    return "non-finite value";
  }
  std::string e = CheckTimeStrictlyIncreasing(w.t_s, previous ? &previous->t_s : nullptr);
  if (e.empty() && w.position_m.cwiseAbs().maxCoeff() > lim.max_abs_coordinate_m) {
    e = "coordinate beyond " + Num(lim.max_abs_coordinate_m) + " m";
  }
  if (e.empty() && !(w.sigma_m >= 1e-3 && w.sigma_m <= 1e3)) {
    e = "sigma_m " + Num(w.sigma_m) + " outside [0.001, 1000] m";
  }
  return e;
}

// The text fields of walk.yaml end up in JSON and HTML: they must be UTF-8.
Status CheckMetaText(const WalkMeta& m, const std::string& where) {
  for (const auto& [key, value] : {std::pair<const char*, const std::string*>{"name", &m.name},
                                   {"source", &m.source},
                                   {"licence", &m.licence}}) {
    if (!internal::IsValidUtf8(*value)) {
      return InvalidArgument(where + ": " + key + " " + internal::Quoted(*value) +
                             " is not valid UTF-8; expected UTF-8 text");
    }
  }
  for (const auto& [key, value] : m.extra) {
    if (!internal::IsValidUtf8(key)) {
      return InvalidArgument(where + ": extra key " + internal::Quoted(key) +
                             " is not valid UTF-8");
    }
  }
  return Status::Ok();
}

// The streams a walk.yaml declares must be the ones present (a file the header says is not
// there would be silently ignored by some estimators and used by others).
Status CheckDeclaredStreams(const Walk& walk, const std::string& yaml) {
  // radio.kind names the primary radio stream; a walk may also carry the other (002: RSS + TOA).
  const RadioKind kind = walk.meta.radio.kind;
  if (kind == RadioKind::kNone && (!walk.rss.empty() || !walk.ranges.empty())) {
    return InvalidArgument(yaml + ": radio.kind is 'none' but " +
                           (walk.rss.empty() ? "range.csv" : "rss.csv") +
                           " is present; expected radio.kind: rss|range");
  }
  if (kind == RadioKind::kRss && walk.rss.empty()) {
    return InvalidArgument(yaml + ": radio.kind is 'rss' but rss.csv is missing");
  }
  if (kind == RadioKind::kRange && walk.ranges.empty()) {
    return InvalidArgument(yaml + ": radio.kind is 'range' but range.csv is missing");
  }
  const ImuPlacement placement = walk.meta.imu_placement;
  if (placement == ImuPlacement::kNone && !walk.imu.empty()) {
    return InvalidArgument(yaml +
                           ": imu_placement is 'none' but imu.csv is present; expected "
                           "foot|waist|hip|handheld");
  }
  if (placement != ImuPlacement::kNone && walk.imu.empty()) {
    return InvalidArgument(yaml + ": imu_placement is '" + ToString(placement) +
                           "' but imu.csv is missing; expected imu_placement: none");
  }
  return Status::Ok();
}

}  // namespace walkgraph::internal
