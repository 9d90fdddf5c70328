// ValidateWalk (io.h): a walk built in code held to the rules its files are read by
// (walk_rules.h), each failure naming the stream and index.
#include <cmath>
#include <set>
#include <unordered_map>

#include "io/plausibility.h"
#include "io/walk_rules.h"
#include "util/text.h"
#include "walkgraph/angle.h"
#include "walkgraph/io.h"

namespace walkgraph {

using internal::CheckAnchorSurvey;
using internal::CheckDeclaredStreams;
using internal::CheckFloor;
using internal::CheckImu;
using internal::CheckMetaText;
using internal::CheckPressure;
using internal::CheckRadioTime;
using internal::CheckRange;
using internal::CheckRss;
using internal::CheckStoreyHeight;
using internal::CheckTimeStrictlyIncreasing;
using internal::CheckWaypoint;
using internal::Num;

namespace {

// "non-finite value in <field> (<value>); expected a finite number" for the first field that is
// NaN or infinite, else "".
std::string NonFinite(std::initializer_list<std::pair<const char*, double>> fields) {
  for (const auto& [name, v] : fields) {
    if (!std::isfinite(v)) {
      return std::string("non-finite value in ") + name + " (" + Num(v) +
             "); expected a finite number";
    }
  }
  return "";
}

// ValidateWalk's rules on walk.yaml's values.
Status ValidateMeta(const Walk& walk, const ValidationLimits& limits) {
  WG_RETURN_IF_ERROR(CheckMetaText(walk.meta, "walk meta"));
  WG_RETURN_IF_ERROR(CheckDeclaredStreams(walk, "walk meta"));
  if (const std::string e = CheckStoreyHeight(walk.meta.storey_height_m); !e.empty()) {
    return InvalidArgument("walk meta: " + e);
  }
  if (const std::string e = internal::CheckRadioDefaults(walk.meta.radio, limits); !e.empty()) {
    return InvalidArgument("walk meta: radio: " + e);
  }
  if (walk.meta.initial_pose) {
    if (const std::string e = internal::CheckInitialPose(*walk.meta.initial_pose, limits);
        !e.empty()) {
      return InvalidArgument("walk meta: initial_pose: " + e);
    }
  }
  for (const auto& [key, value] : walk.meta.extra) {
    if (!std::isfinite(value)) return InvalidArgument("walk meta: extra." + key + " is not finite");
  }
  if (walk.meta.initial_pose && walk.meta.initial_pose->floor) {
    if (const std::string e = CheckFloor(*walk.meta.initial_pose->floor); !e.empty()) {
      return InvalidArgument("walk meta: initial_pose: " + e);
    }
  }
  return Status::Ok();
}

// ValidateWalk's rules on the anchors; fills `ids`.
Status ValidateAnchors(const Walk& walk, const ValidationLimits& limits, std::set<int>* ids) {
  for (size_t i = 0; i < walk.anchors.size(); ++i) {
    if (walk.anchors[i].id < 0)
      return InvalidArgument("anchors[" + std::to_string(i) + "]: negative id");
    const Anchor& a = walk.anchors[i];
    // An unknown position's x and y are not read (NaN from the reader, anything in code).
    const Eigen::Vector3d p =
        a.position_known ? a.position_m : Eigen::Vector3d(0.0, 0.0, a.position_m.z());
    if (!p.allFinite()) {
      return InvalidArgument("anchors[" + std::to_string(i) + "]: non-finite position");
    }
    if (const std::string e = CheckAnchorSurvey(a); !e.empty()) {
      return InvalidArgument("anchors[" + std::to_string(i) + "]: " + e);
    }
    if (p.cwiseAbs().maxCoeff() > limits.max_abs_coordinate_m) {
      return InvalidArgument("anchors[" + std::to_string(i) + "]: coordinate beyond " +
                             Num(limits.max_abs_coordinate_m) + " m");
    }
    if (!ids->insert(walk.anchors[i].id).second) {
      return InvalidArgument("anchors: duplicate id " + std::to_string(walk.anchors[i].id));
    }
    if (walk.anchors[i].floor.has_value() != walk.anchors[0].floor.has_value()) {
      return InvalidArgument("anchors[" + std::to_string(i) +
                             "]: a floor on some anchors only; expected every anchor or none");
    }
    if (walk.anchors[i].floor) {
      if (const std::string e = CheckFloor(*walk.anchors[i].floor); !e.empty()) {
        return InvalidArgument("anchors[" + std::to_string(i) + "]: " + e);
      }
    }
  }
  return Status::Ok();
}

}  // namespace

Status ValidateWalk(const Walk& walk, const ValidationLimits& limits) {
  WG_RETURN_IF_ERROR(ValidateMeta(walk, limits));
  std::set<int> ids;
  WG_RETURN_IF_ERROR(ValidateAnchors(walk, limits, &ids));
  auto where = [](const char* stream, size_t i) {
    return std::string(stream) + "[" + std::to_string(i) + "]: ";
  };
  for (size_t i = 0; i < walk.imu.size(); ++i) {
    const ImuSample& s = walk.imu[i];
    if (const std::string e = NonFinite({{"t_s", s.t_s},
                                         {"ax", s.acc_mps2.x()},
                                         {"ay", s.acc_mps2.y()},
                                         {"az", s.acc_mps2.z()},
                                         {"gx", s.gyro_radps.x()},
                                         {"gy", s.gyro_radps.y()},
                                         {"gz", s.gyro_radps.z()},
                                         {"mx", s.has_mag ? s.mag_ut.x() : 0.0},
                                         {"my", s.has_mag ? s.mag_ut.y() : 0.0},
                                         {"mz", s.has_mag ? s.mag_ut.z() : 0.0}});
        !e.empty()) {
      return InvalidArgument(where("imu", i) + e);
    }
    std::string e = CheckTimeStrictlyIncreasing(s.t_s, i ? &walk.imu[i - 1].t_s : nullptr);
    if (e.empty()) e = CheckImu(s, limits);
    if (e.empty() && s.has_mag != walk.imu[0].has_mag)
      e = "magnetometer present on some samples only";
    if (!e.empty()) return InvalidArgument(where("imu", i) + e);
  }
  {
    double last = 0.0;
    std::unordered_map<int, double> by_anchor;
    for (size_t i = 0; i < walk.rss.size(); ++i) {
      const RssSample& s = walk.rss[i];
      if (const std::string e = NonFinite({{"t_s", s.t_s}, {"rss", s.rss}}); !e.empty()) {
        return InvalidArgument(where("rss", i) + e);
      }
      if (!ids.count(s.anchor_id)) return InvalidArgument(where("rss", i) + "unknown anchor_id");
      std::string e = CheckRadioTime(s.t_s, s.anchor_id, &last, &by_anchor, i == 0);
      if (e.empty()) e = CheckRss(s, walk.meta.radio.units, limits);
      if (!e.empty()) return InvalidArgument(where("rss", i) + e);
    }
  }
  {
    double last = 0.0;
    std::unordered_map<int, double> by_anchor;
    for (size_t i = 0; i < walk.ranges.size(); ++i) {
      const RangeSample& s = walk.ranges[i];
      if (const std::string e = NonFinite({{"t_s", s.t_s}, {"range_m", s.range_m}}); !e.empty()) {
        return InvalidArgument(where("range", i) + e);
      }
      if (!ids.count(s.anchor_id)) return InvalidArgument(where("range", i) + "unknown anchor_id");
      std::string e = CheckRadioTime(s.t_s, s.anchor_id, &last, &by_anchor, i == 0);
      if (e.empty()) e = CheckRange(s, limits);
      if (!e.empty()) return InvalidArgument(where("range", i) + e);
    }
  }
  for (size_t i = 0; i < walk.odometry.size(); ++i) {
    const OdometrySample& s = walk.odometry[i];
    if (const std::string e =
            NonFinite({{"t_s", s.t_s}, {"dist_m", s.dist_m}, {"dheading_rad", s.dheading_rad}});
        !e.empty()) {
      return InvalidArgument(where("odometry", i) + e);
    }
    const std::string e =
        CheckTimeStrictlyIncreasing(s.t_s, i ? &walk.odometry[i - 1].t_s : nullptr);
    if (!e.empty()) return InvalidArgument(where("odometry", i) + e);
    if (!(s.dist_m >= 0.0 && s.dist_m <= 100.0) || std::fabs(s.dheading_rad) > 2.0 * kPi) {
      return InvalidArgument(where("odometry", i) +
                             "dist_m outside [0, 100] m or dheading_rad beyond 2*pi");
    }
  }
  for (size_t i = 0; i < walk.stance_truth.size(); ++i) {
    const std::string e = CheckTimeStrictlyIncreasing(walk.stance_truth[i].t_s,
                                                      i ? &walk.stance_truth[i - 1].t_s : nullptr);
    if (!e.empty()) return InvalidArgument(where("stance_truth", i) + e);
  }
  for (size_t i = 0; i < walk.waypoints.size(); ++i) {
    const std::string e =
        CheckWaypoint(walk.waypoints[i], i ? &walk.waypoints[i - 1] : nullptr, limits);
    if (!e.empty()) return InvalidArgument(where("waypoints", i) + e);
  }
  for (size_t i = 0; i < walk.pressure.size(); ++i) {
    const std::string e = CheckPressure(walk.pressure[i], i ? &walk.pressure[i - 1] : nullptr);
    if (!e.empty()) return InvalidArgument(where("pressure", i) + e);
  }
  for (size_t i = 0; i < walk.truth.size(); ++i) {
    const TruthSample& s = walk.truth[i];
    if (const std::string e = NonFinite({{"t_s", s.t_s},
                                         {"x_m", s.position_m.x()},
                                         {"y_m", s.position_m.y()},
                                         {"z_m", s.position_m.z()}});
        !e.empty()) {
      return InvalidArgument(where("truth", i) + e);
    }
    if (s.floor.has_value() != walk.truth[0].floor.has_value()) {
      return InvalidArgument(where("truth", i) +
                             "a floor on some samples only; expected every sample or none");
    }
    if (s.floor) {
      if (const std::string e = CheckFloor(*s.floor); !e.empty()) {
        return InvalidArgument(where("truth", i) + e);
      }
    }
    const std::string e = CheckTimeStrictlyIncreasing(s.t_s, i ? &walk.truth[i - 1].t_s : nullptr);
    if (!e.empty()) return InvalidArgument(where("truth", i) + e);
  }
  if ((walk.meta.truth_kind == TruthKind::kNone) != walk.truth.empty()) {
    return InvalidArgument("truth kind and truth samples disagree");
  }
  if (const std::string e = internal::CheckStreamSpans(walk, false); !e.empty()) {
    return InvalidArgument(e);
  }
  return Status::Ok();
}

}  // namespace walkgraph
