#include "io/plausibility.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>

#include "util/text.h"

namespace walkgraph::internal {

std::string CheckImu(const ImuSample& s, const ValidationLimits& lim) {
  if (s.acc_mps2.cwiseAbs().maxCoeff() > lim.max_abs_acc_mps2) {
    return "acceleration component over " + Num(lim.max_abs_acc_mps2) +
           " m/s^2 (physically absurd; units must be m/s^2)";
  }
  if (s.gyro_radps.cwiseAbs().maxCoeff() > lim.max_abs_gyro_radps) {
    return "angular rate component over " + Num(lim.max_abs_gyro_radps) +
           " rad/s (physically absurd; units must be rad/s)";
  }
  return "";
}

std::string CheckRss(const RssSample& s, RssUnits units, const ValidationLimits& lim) {
  if (units == RssUnits::kDbm && (s.rss < lim.min_rss_dbm || s.rss > lim.max_rss_dbm)) {
    return "rss " + Num(s.rss) + " outside [" + Num(lim.min_rss_dbm) + ", " + Num(lim.max_rss_dbm) +
           "] dBm";
  }
  return "";
}

std::string CheckRange(const RangeSample& s, const ValidationLimits& lim) {
  if (s.range_m < 0.0 || s.range_m > lim.max_range_m) {
    return "range_m " + Num(s.range_m) + " outside [0, " + Num(lim.max_range_m) + "] m";
  }
  return "";
}

std::string CheckBleRss(double rss_dbm) {
  if (rss_dbm < 0.0) return "";
  return "BLE rss " + Num(rss_dbm) +
         " dBm is not below 0 dBm (a Bluetooth LE reading is negative; 0 means unknown)";
}

void ColumnCheck::Add(bool ok, const std::string& where, const std::string& value) {
  ++lines_;
  if (ok) return;
  if (failed_++ == 0) {
    first_where_ = where;
    first_value_ = value;
  }
}

Status ColumnCheck::Check(const std::string& layout) const {
  if (2 * failed_ <= lines_) return Status::Ok();
  return InvalidArgument(first_where_ + column_ + " is " + first_value_ + ", not " + expected_ +
                         ", in " + std::to_string(failed_) + " of " + std::to_string(lines_) +
                         " lines (the first here); expected " + expected_ +
                         " in every line (two columns swapped? the lines are " + layout + ")");
}

namespace {

// "name v outside [lo, hi] unit" when v is not in [lo, hi] (NaN included), else "".
std::string Outside(const char* name, double v, double lo, double hi, const char* unit) {
  if (v >= lo && v <= hi) return "";
  return std::string(name) + " " + Num(v) + " outside [" + Num(lo) + ", " + Num(hi) + "] " + unit +
         " (physically absurd)";
}

}  // namespace

std::string CheckPathLoss(const PathLossParams& p, RssUnits units, const ValidationLimits& lim) {
  const bool rfcode = units == RssUnits::kRfcode;
  std::string e = rfcode ? Outside("A_dbm", p.A_dbm, 0.0, 300.0, "(RFCode units)")
                         : Outside("A_dbm", p.A_dbm, lim.min_rss_dbm, lim.max_rss_dbm, "dBm");
  if (e.empty() && !(p.eta > 0.0 && p.eta <= 10.0)) {
    e = "eta " + Num(p.eta) + " outside (0, 10] (a path-loss exponent; physically absurd)";
  }
  if (e.empty()) e = Outside("sigma_db", p.sigma_db, 1e-3, 50.0, "dB");
  if (e.empty()) e = Outside("d0_m", p.d0_m, 0.01, 100.0, "m");
  return e;
}

std::string CheckRadioDefaults(const RadioDefaults& r, const ValidationLimits& lim) {
  std::string e = CheckPathLoss(r.path_loss, r.units, lim);
  if (e.empty()) e = Outside("range_sigma_m", r.range_sigma_m, 1e-3, 1e3, "m");
  return e;
}

std::string CheckInitialPose(const InitialPose& p, const ValidationLimits& lim) {
  // 10^7 m by default, not less: UTM northings reach it (see ValidationLimits).
  const double c = lim.max_abs_coordinate_m, two_pi = 6.283185307179586;
  std::string e = Outside("x_m", p.x_m, -c, c, "m");
  if (e.empty()) e = Outside("y_m", p.y_m, -c, c, "m");
  if (e.empty() && !(std::fabs(p.heading_rad) <= two_pi + 1e-9)) {
    e = "heading_rad " + Num(p.heading_rad) + " outside [-2*pi, 2*pi]; expected radians";
  }
  if (e.empty()) e = Outside("sigma_xy_m", p.sigma_xy_m, 1e-6, 1e4, "m");
  if (e.empty()) e = Outside("sigma_heading_rad", p.sigma_heading_rad, 1e-6, two_pi, "rad");
  return e;
}

namespace {

struct Span {
  const char* stream;
  const char* file;
  double first, last;
};

template <typename T>
std::optional<Span> SpanOf(const std::vector<T>& v, const char* stream, const char* file) {
  if (v.empty()) return std::nullopt;
  return Span{stream, file, v.front().t_s, v.back().t_s};
}

std::string Disjoint(const std::optional<Span>& a, const std::optional<Span>& b, bool files) {
  if (!a || !b || (a->last >= b->first && b->last >= a->first)) return "";
  return std::string(files ? a->file : a->stream) + " spans [" + Num(a->first) + ", " +
         Num(a->last) + "] s and " + (files ? b->file : b->stream) + " [" + Num(b->first) + ", " +
         Num(b->last) +
         "] s: the streams do not overlap in time; expected every stream on one clock";
}

}  // namespace

namespace {

// Horizontal distance from `p` to the anchors' bounding box (0 inside it).
double DistanceToAnchors(const Eigen::Vector2d& p, const Eigen::Vector2d& lo,
                         const Eigen::Vector2d& hi) {
  return (p.cwiseMax(lo).cwiseMin(hi) - p).norm();
}

// With radio readings, the truth, waypoints and start must lie within kMaxAnchorDistanceM of the
// anchors: farther, the two are in different frames (latitude and longitude swapped, another
// origin).
std::string CheckFrames(const Walk& w, bool files) {
  constexpr double kMaxAnchorDistanceM = 1e5;
  if (w.anchors.empty() || (w.rss.empty() && w.ranges.empty())) return "";
  // The anchors with a position (an unknown one is in the walk's frame by definition).
  const Eigen::Vector2d inf = Eigen::Vector2d::Constant(std::numeric_limits<double>::infinity());
  Eigen::Vector2d lo = inf, hi = -inf;
  for (const Anchor& a : w.anchors) {
    if (!a.position_known) continue;
    lo = lo.cwiseMin(a.position_m.head<2>());
    hi = hi.cwiseMax(a.position_m.head<2>());
  }
  if (!(lo.x() <= hi.x())) return "";
  auto far = [&](const Eigen::Vector2d& p, const std::string& where) -> std::string {
    const double d = DistanceToAnchors(p, lo, hi);
    if (d <= kMaxAnchorDistanceM) return "";
    return where + ": (" + Num(p.x()) + ", " + Num(p.y()) + ") is " + Num(d) +
           " m from the anchors; expected it and the anchors in one frame (latitude and "
           "longitude swapped? another origin?)";
  };
  for (size_t i = 0; i < w.truth.size(); ++i) {
    const std::string where =
        files ? "truth.csv:" + std::to_string(i + 2) : "truth[" + std::to_string(i) + "]";
    if (std::string e = far(w.truth[i].position_m.head<2>(), where); !e.empty()) return e;
  }
  for (size_t i = 0; i < w.waypoints.size(); ++i) {
    const std::string where =
        files ? "waypoints.csv:" + std::to_string(i + 2) : "waypoints[" + std::to_string(i) + "]";
    if (std::string e = far(w.waypoints[i].position_m, where); !e.empty()) return e;
  }
  if (const auto& p = w.meta.initial_pose) {
    return far(Eigen::Vector2d(p->x_m, p->y_m), files ? "walk.yaml: initial_pose" : "initial_pose");
  }
  return "";
}

}  // namespace

std::string CheckStreamSpans(const Walk& w, bool files) {
  const auto imu = SpanOf(w.imu, "imu", "imu.csv");
  const auto odo = SpanOf(w.odometry, "odometry", "odometry.csv");
  for (const auto& radio :
       {SpanOf(w.rss, "rss", "rss.csv"), SpanOf(w.ranges, "range", "range.csv")}) {
    if (std::string e = Disjoint(imu, radio, files); !e.empty()) return e;
    if (std::string e = Disjoint(odo, radio, files); !e.empty()) return e;
  }
  const bool all_zero =
      !w.ranges.empty() && std::all_of(w.ranges.begin(), w.ranges.end(),
                                       [](const RangeSample& r) { return r.range_m == 0.0; });
  if (all_zero) {
    return std::string(files ? "range.csv" : "range") +
           ": every range_m is 0; expected distances in metres (an empty column?)";
  }
  const bool negative =
      w.meta.radio.units == RssUnits::kRfcode && !w.rss.empty() &&
      std::all_of(w.rss.begin(), w.rss.end(), [](const RssSample& r) { return r.rss < 0.0; });
  if (negative) {
    return std::string(files ? "rss.csv" : "rss") +
           ": every reading is negative (dBm-like) but radio.units is rfcode (RFCode units are "
           "positive, larger is weaker); expected radio.units: dbm";
  }
  if (std::string e = CheckFrames(w, files); !e.empty()) return e;
  const double start = w.StartTime() - 1.0, end = w.EndTime() + 1.0;
  for (size_t i = 0; i < w.waypoints.size(); ++i) {
    const double t = w.waypoints[i].t_s;
    if (t < start || t > end) {
      const std::string where = files ? "waypoints.csv:" + std::to_string(i + 2)  // header: 1
                                      : "waypoints[" + std::to_string(i) + "]";
      return where + ": t_s " + Num(t) + " outside the walk's time span [" + Num(start + 1.0) +
             ", " + Num(end - 1.0) + "] s (1 s tolerance)";
    }
  }
  return "";
}

namespace {

std::string ImuGapWarning(const Walk& w) {
  const std::vector<ImuGap> gaps = w.ImuGaps();
  if (gaps.empty()) return "";
  const auto longest = std::max_element(
      gaps.begin(), gaps.end(),
      [](const ImuGap& a, const ImuGap& b) { return a.duration_s() < b.duration_s(); });
  return "imu.csv: " + std::to_string(gaps.size()) + " gap(s) longer than " + Num(kImuGapFactor) +
         "x the median sample interval; the longest " + Num(longest->duration_s()) +
         " s after t = " + Num(longest->t_begin_s) + " s (bridged, not integrated across)";
}

// The radio's span covered by the IMU's, when they overlap (disjoint spans are an error:
// CheckStreamSpans) for less than half of the radio's, leaving over 10 s without the IMU.
std::string CoverageWarning(const Walk& w) {
  const auto imu = SpanOf(w.imu, "imu", "imu.csv");
  for (const auto& radio :
       {SpanOf(w.rss, "rss", "rss.csv"), SpanOf(w.ranges, "range", "range.csv")}) {
    if (!imu || !radio || !(radio->last > radio->first)) continue;
    const double common = std::min(imu->last, radio->last) - std::max(imu->first, radio->first);
    const double share = common / (radio->last - radio->first);
    const double uncovered = radio->last - radio->first - common;
    if (share >= 0.5 || common < 0.0 || uncovered < 10.0) continue;
    return std::string("imu.csv spans [") + Num(imu->first) + ", " + Num(imu->last) + "] s and " +
           radio->file + " [" + Num(radio->first) + ", " + Num(radio->last) +
           "] s: the IMU covers " + Num(std::round(share * 1000) / 10) +
           "% of the radio's span; expected both recorded together";
  }
  return "";
}

}  // namespace

}  // namespace walkgraph::internal

namespace walkgraph {

std::vector<std::string> PlausibilityWarnings(const Walk& w) {
  std::vector<std::string> out;
  if (std::string e = internal::ImuGapWarning(w); !e.empty()) out.push_back(e);
  const std::string prefix = "convert.", suffix = "_invalid_dropped";
  for (const auto& [key, n] : w.meta.extra) {
    if (!(n > 0) || key.rfind(prefix, 0) != 0 || key.size() <= prefix.size() + suffix.size() ||
        key.compare(key.size() - suffix.size(), suffix.size(), suffix) != 0) {
      continue;
    }
    const std::string stream =
        key.substr(prefix.size(), key.size() - prefix.size() - suffix.size());
    out.push_back("walk.yaml: the converter dropped " + internal::Num(n) + " " + stream +
                  " reading(s) of the recording as physically impossible (" + key + ")");
  }
  const double eta = w.meta.radio.path_loss.eta;
  if (!w.rss.empty() && !(eta >= 1.5 && eta <= 6.0)) {
    out.push_back("walk.yaml: radio: eta " + internal::Num(eta) +
                  " outside [1.5, 6], the indoor path-loss exponents reported in the literature "
                  "(accepted up to 10)");
  }
  if (w.meta.radio.units == RssUnits::kDbm) {
    size_t n = 0, first = 0;
    for (size_t i = 0; i < w.rss.size(); ++i) {
      if (w.rss[i].rss > 0.0 && n++ == 0) first = i;
    }
    if (n > 0) {
      out.push_back("rss.csv:" + std::to_string(first + 2) + ": " + std::to_string(n) +
                    " reading(s) above 0 dBm, the first " + internal::Num(w.rss[first].rss) +
                    " dBm; expected received powers below 0 dBm (a receiver touching its "
                    "transmitter?)");
    }
  }
  if (std::string e = internal::CoverageWarning(w); !e.empty()) out.push_back(e);
  return out;
}

}  // namespace walkgraph

namespace walkgraph::internal {

Status DroppedReadings::Check(const std::string& stream, const std::string& where,
                              const std::string& problem, bool* drop) {
  *drop = !problem.empty();
  if (!*drop) return Status::Ok();
  if (strict_) {
    return InvalidArgument(where + problem +
                           " (strict conversion: without --strict such a "
                           "reading is dropped and counted)");
  }
  if (++counts_[stream] <= kMaxWarnings) first_[stream].push_back(where + problem + "; dropped");
  return Status::Ok();
}

void DroppedReadings::Report(WalkMeta* meta, std::vector<std::string>* warnings) const {
  for (const auto& [stream, n] : counts_) {
    meta->extra["convert." + stream + "_invalid_dropped"] = n;
    if (warnings == nullptr) continue;
    const auto& first = first_.at(stream);
    warnings->insert(warnings->end(), first.begin(), first.end());
    if (n > kMaxWarnings) {
      warnings->push_back(std::to_string(n - kMaxWarnings) + " more " + stream +
                          " readings dropped as physically impossible");
    }
  }
}

}  // namespace walkgraph::internal
