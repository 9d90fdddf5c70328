#include <algorithm>
#include <cmath>
#include <filesystem>
#include <set>

#include "convert/text_table.h"
#include "io/plausibility.h"
#include "util/text.h"
#include "walkgraph/angle.h"
#include "walkgraph/convert.h"

namespace walkgraph {

namespace fs = std::filesystem;

namespace {

// Finds "<prefix>_<suffix>" in dir for the single Plaza prefix present (Plaza1, Plaza2, ...).
StatusOr<std::string> FindPlazaFile(const fs::path& dir, const std::string& suffix, bool required) {
  std::error_code ec;
  std::vector<std::string> found;
  for (const auto& entry : fs::directory_iterator(dir, ec)) {
    const std::string name = entry.path().filename().string();
    if (name.size() > suffix.size() &&
        name.compare(name.size() - suffix.size(), suffix.size(), suffix) == 0 &&
        name.rfind("Plaza", 0) == 0) {
      found.push_back(entry.path().string());
    }
  }
  if (ec) return NotFound(dir.string() + ": cannot list directory: " + ec.message());
  std::sort(found.begin(), found.end());
  if (found.empty()) {
    if (!required) return std::string();
    return NotFound(dir.string() + ": no Plaza*" + suffix + " file");
  }
  if (found.size() > 1) {
    return InvalidArgument(dir.string() + ": several Plaza*" + suffix +
                           " files; pass a directory with one Plaza set");
  }
  return found.front();
}

bool IsIntegral(double v) { return std::floor(v) == v && std::fabs(v) < 2e9; }

// The start heading: the truth's heading column, checked against the direction of travel (from
// the first truth position to the first one kTravelCheckM away). A public range+odometry
// recording of this family ships its heading column π off the direction of travel (GTSAM's
// own example hard-codes the fix), so where the two disagree by more than 90° the direction of
// travel is used, with a warning naming the line, and convert.truth_heading_replaced = 1.
constexpr double kTravelCheckM = 1.0;
double StartHeading(const internal::TextTable& gt, const std::string& path, WalkMeta* meta,
                    std::vector<std::string>* warnings) {
  const double column = NormalizeAngle(gt.rows[0][3]);
  meta->extra["convert.truth_heading_replaced"] = 0;
  for (const auto& r : gt.rows) {
    const double dx = r[1] - gt.rows[0][1], dy = r[2] - gt.rows[0][2];
    if (std::hypot(dx, dy) < kTravelCheckM) continue;
    const double travel = std::atan2(dy, dx);
    if (std::abs(NormalizeAngle(travel - column)) <= kPi / 2) return column;
    meta->extra["convert.truth_heading_replaced"] = 1;
    if (warnings != nullptr) {
      warnings->push_back(
          path + ":" + std::to_string(gt.line_numbers[0]) + ": heading " + internal::Num(column) +
          " rad is " + internal::Num(RadToDeg(std::abs(NormalizeAngle(travel - column)))) +
          "° off the direction of travel (" + internal::Num(travel) + " rad over the first " +
          internal::Num(kTravelCheckM) + " m); the start heading is the direction of travel");
    }
    return travel;
  }
  return column;  // the truth never moves kTravelCheckM: nothing to check against
}

}  // namespace

StatusOr<Walk> ConvertPlaza(const std::string& dir_name, const ConvertOptions& options,
                            std::vector<std::string>* warnings) {
  internal::DroppedReadings dropped(options.strict);
  const fs::path dir(dir_name);
  std::error_code ec;
  if (!fs::is_directory(dir, ec)) return NotFound(dir_name + ": not a directory");
  WG_ASSIGN_OR_RETURN(const std::string dr_path, FindPlazaFile(dir, "_DR.txt", true));
  WG_ASSIGN_OR_RETURN(const std::string td_path, FindPlazaFile(dir, "_TD.txt", true));
  WG_ASSIGN_OR_RETURN(const std::string anchors_path, FindPlazaFile(dir, "_anchors.csv", true));
  WG_ASSIGN_OR_RETURN(const std::string gt_path, FindPlazaFile(dir, "_GT.csv", false));

  Walk walk;
  const std::string stem = fs::path(dr_path).filename().string();
  walk.meta.name =
      internal::ToValidUtf8(stem.substr(0, stem.size() - std::string("_DR.txt").size()));
  walk.meta.source =
      "Djugash, Singh, Kantor, Zhang: Navigating with ranging radios, CMU 2009; files as shipped "
      "in GTSAM examples/Data (borglab/gtsam @0ffe6c93)";
  walk.meta.licence = "BSD-2-Clause (GTSAM simplified BSD licence)";
  walk.meta.imu_placement = ImuPlacement::kNone;
  walk.meta.radio.kind = RadioKind::kRange;
  walk.meta.radio.range_sigma_m = 1.2;  // spread of range − true distance, datasets/README

  WG_ASSIGN_OR_RETURN(internal::TextTable anchors, internal::ReadTextTable(anchors_path, 3, true));
  std::set<int> ids;
  for (size_t i = 0; i < anchors.rows.size(); ++i) {
    const auto& r = anchors.rows[i];
    if (!IsIntegral(r[0]) || r[0] < 0 || !ids.insert(static_cast<int>(r[0])).second) {
      return InvalidArgument(anchors_path + ":" + std::to_string(anchors.line_numbers[i]) +
                             ": anchor id must be a unique non-negative integer");
    }
    walk.anchors.push_back(
        {static_cast<int>(r[0]), Eigen::Vector3d(r[1], r[2], 0.0), std::nullopt});
  }

  WG_ASSIGN_OR_RETURN(internal::TextTable dr, internal::ReadTextTable(dr_path, 3, false));
  for (size_t i = 0; i < dr.rows.size(); ++i) {
    const auto& r = dr.rows[i];
    if (!walk.odometry.empty() && !(r[0] > walk.odometry.back().t_s)) {
      return InvalidArgument(dr_path + ":" + std::to_string(dr.line_numbers[i]) +
                             ": time does not increase");
    }
    walk.odometry.push_back({r[0], r[1], r[2]});
  }

  // The TD file has two stretches out of time order and two repeated (time, anchor) readings:
  // sort stably by time and keep the first of each repeat, counting both in meta.extra.
  WG_ASSIGN_OR_RETURN(internal::TextTable td, internal::ReadTextTable(td_path, 4, false));
  std::vector<RangeSample> ranges;
  int reordered = 0;
  for (size_t i = 0; i < td.rows.size(); ++i) {
    const auto& r = td.rows[i];
    if (!IsIntegral(r[2]) || ids.count(static_cast<int>(r[2])) == 0) {
      return InvalidArgument(td_path + ":" + std::to_string(td.line_numbers[i]) +
                             ": anchor id (column 3) not in " + anchors_path);
    }
    const RangeSample sample{r[0], static_cast<int>(r[2]), r[3]};
    bool drop = false;
    WG_RETURN_IF_ERROR(dropped.Check("range",
                                     td_path + ":" + std::to_string(td.line_numbers[i]) + ": ",
                                     internal::CheckRange(sample, {}), &drop));
    if (drop) continue;
    if (!ranges.empty() && r[0] < ranges.back().t_s) ++reordered;
    ranges.push_back(sample);
  }
  std::stable_sort(ranges.begin(), ranges.end(),
                   [](const RangeSample& a, const RangeSample& b) { return a.t_s < b.t_s; });
  std::set<std::pair<double, int>> seen;
  int duplicates = 0;
  for (const RangeSample& s : ranges) {
    if (!seen.insert({s.t_s, s.anchor_id}).second) {
      ++duplicates;
      continue;
    }
    walk.ranges.push_back(s);
  }
  walk.meta.extra["convert.range_lines_out_of_order"] = reordered;
  walk.meta.extra["convert.range_duplicates_dropped"] = duplicates;
  dropped.Report(&walk.meta, warnings);

  if (!gt_path.empty()) {
    WG_ASSIGN_OR_RETURN(internal::TextTable gt, internal::ReadTextTable(gt_path, 4, true));
    for (size_t i = 0; i < gt.rows.size(); ++i) {
      const auto& r = gt.rows[i];
      if (!walk.truth.empty() && !(r[0] > walk.truth.back().t_s)) {
        return InvalidArgument(gt_path + ":" + std::to_string(gt.line_numbers[i]) +
                               ": time does not increase");
      }
      TruthSample s;
      s.t_s = r[0];
      s.position_m = Eigen::Vector3d(r[1], r[2], 0.0);
      walk.truth.push_back(s);
    }
    walk.meta.truth_kind = TruthKind::kContinuous;
    InitialPose p;
    p.x_m = gt.rows[0][1];
    p.y_m = gt.rows[0][2];
    p.heading_rad = StartHeading(gt, gt_path, &walk.meta, warnings);
    p.sigma_xy_m = 0.1;
    p.sigma_heading_rad = 0.05;
    walk.meta.initial_pose = p;
  }
  return walk;
}

}  // namespace walkgraph
