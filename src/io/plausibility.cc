#include "io/plausibility.h"

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
