// Writing a walk folder (io.h WriteWalk): walk.yaml and one CSV per stream, numbers in the
// shortest text that reads back to the same double.
#include <algorithm>
#include <filesystem>
#include <ostream>

#include <yaml-cpp/yaml.h>

#include "util/text.h"
#include "walkgraph/io.h"
#include "walkgraph/output.h"

namespace walkgraph {

namespace fs = std::filesystem;
using internal::ExactNum;

namespace {

// anchors.csv of a walk (FormatAnchorsCsv).
bool WriteAnchors(const Walk& walk, std::ostream& o) {
  FormatAnchorsCsv(walk.anchors, o);
  return true;
}
// walk.yaml of `walk` (walk-format.md).
bool WriteWalkYaml(const Walk& walk, std::ostream& o) {
  const WalkMeta& m = walk.meta;
  YAML::Emitter e;
  e << YAML::BeginMap;
  e << YAML::Key << "format_version" << YAML::Value << 1;
  e << YAML::Key << "name" << YAML::Value << m.name;
  e << YAML::Key << "source" << YAML::Value << m.source;
  e << YAML::Key << "licence" << YAML::Value << m.licence;
  if (m.storey_height_m != kDefaultStoreyHeightM) {
    e << YAML::Key << "storey_height_m" << YAML::Value << ExactNum(m.storey_height_m);
  }
  e << YAML::Key << "imu_placement" << YAML::Value << ToString(m.imu_placement);
  e << YAML::Key << "frame" << YAML::Value << "enu";
  e << YAML::Key << "truth" << YAML::Value << ToString(m.truth_kind);
  e << YAML::Key << "radio" << YAML::Value << YAML::BeginMap;
  e << YAML::Key << "kind" << YAML::Value << ToString(m.radio.kind);
  e << YAML::Key << "units" << YAML::Value << ToString(m.radio.units);
  e << YAML::Key << "A_dbm" << YAML::Value << ExactNum(m.radio.path_loss.A_dbm);
  e << YAML::Key << "eta" << YAML::Value << ExactNum(m.radio.path_loss.eta);
  e << YAML::Key << "d0_m" << YAML::Value << ExactNum(m.radio.path_loss.d0_m);
  e << YAML::Key << "sigma_db" << YAML::Value << ExactNum(m.radio.path_loss.sigma_db);
  if (m.radio.path_loss.floor_loss_db != 0.0 || (!walk.anchors.empty() && walk.anchors[0].floor)) {
    e << YAML::Key << "floor_loss_db" << YAML::Value << ExactNum(m.radio.path_loss.floor_loss_db);
  }
  e << YAML::Key << "range_sigma_m" << YAML::Value << ExactNum(m.radio.range_sigma_m);
  e << YAML::Key << "calibrated" << YAML::Value << m.radio.calibrated;
  e << YAML::EndMap;
  if (m.initial_pose) {
    const InitialPose& p = *m.initial_pose;
    e << YAML::Key << "initial_pose" << YAML::Value << YAML::BeginMap;
    e << YAML::Key << "x_m" << YAML::Value << ExactNum(p.x_m);
    e << YAML::Key << "y_m" << YAML::Value << ExactNum(p.y_m);
    if (p.heading_known) e << YAML::Key << "heading_rad" << YAML::Value << ExactNum(p.heading_rad);
    e << YAML::Key << "sigma_xy_m" << YAML::Value << ExactNum(p.sigma_xy_m);
    if (p.heading_known) {
      e << YAML::Key << "sigma_heading_rad" << YAML::Value << ExactNum(p.sigma_heading_rad);
    }
    if (p.floor) e << YAML::Key << "floor" << YAML::Value << *p.floor;
    e << YAML::EndMap;
  }
  if (!m.extra.empty()) {
    e << YAML::Key << "extra" << YAML::Value << YAML::BeginMap;
    for (const auto& [k, v] : m.extra) e << YAML::Key << k << YAML::Value << ExactNum(v);
    e << YAML::EndMap;
  }
  e << YAML::EndMap;
  o << e.c_str() << "\n";
  return e.good();
}

Status WriteWalkFiles(const Walk& walk, const fs::path& root) {
  WG_RETURN_IF_ERROR(WriteFileInOutput((root / "walk.yaml").string(),
                                       [&](std::ostream& o) { return WriteWalkYaml(walk, o); }));
  if (!walk.anchors.empty()) {
    WG_RETURN_IF_ERROR(WriteFileInOutput((root / "anchors.csv").string(),
                                         [&](std::ostream& o) { return WriteAnchors(walk, o); }));
  }
  if (!walk.imu.empty()) {
    const bool mag = walk.imu[0].has_mag;
    WG_RETURN_IF_ERROR(WriteFileInOutput((root / "imu.csv").string(), [&](std::ostream& o) {
      o << "t_s,ax,ay,az,gx,gy,gz" << (mag ? ",mx,my,mz" : "") << '\n';
      for (const ImuSample& s : walk.imu) {
        o << ExactNum(s.t_s);
        for (int i = 0; i < 3; ++i) o << ',' << ExactNum(s.acc_mps2[i]);
        for (int i = 0; i < 3; ++i) o << ',' << ExactNum(s.gyro_radps[i]);
        if (mag) {
          for (int i = 0; i < 3; ++i) o << ',' << ExactNum(s.mag_ut[i]);
        }
        o << '\n';
      }
      return true;
    }));
  }
  if (!walk.rss.empty()) {
    WG_RETURN_IF_ERROR(WriteFileInOutput((root / "rss.csv").string(), [&](std::ostream& o) {
      o << "t_s,anchor_id,rss\n";
      for (const RssSample& s : walk.rss)
        o << ExactNum(s.t_s) << ',' << s.anchor_id << ',' << ExactNum(s.rss) << '\n';
      return true;
    }));
  }
  if (!walk.ranges.empty()) {
    WG_RETURN_IF_ERROR(WriteFileInOutput((root / "range.csv").string(), [&](std::ostream& o) {
      o << "t_s,anchor_id,range_m\n";
      for (const RangeSample& s : walk.ranges) {
        o << ExactNum(s.t_s) << ',' << s.anchor_id << ',' << ExactNum(s.range_m) << '\n';
      }
      return true;
    }));
  }
  if (!walk.odometry.empty()) {
    WG_RETURN_IF_ERROR(WriteFileInOutput((root / "odometry.csv").string(), [&](std::ostream& o) {
      o << "t_s,dist_m,dheading_rad\n";
      for (const OdometrySample& s : walk.odometry) {
        o << ExactNum(s.t_s) << ',' << ExactNum(s.dist_m) << ',' << ExactNum(s.dheading_rad)
          << '\n';
      }
      return true;
    }));
  }
  if (!walk.truth.empty()) {
    const bool z = walk.truth[0].has_z, floor = walk.truth[0].floor.has_value();
    WG_RETURN_IF_ERROR(WriteFileInOutput((root / "truth.csv").string(), [&](std::ostream& o) {
      o << "t_s,x_m,y_m" << (z ? ",z_m" : "") << (floor ? ",floor" : "") << '\n';
      for (const TruthSample& s : walk.truth) {
        o << ExactNum(s.t_s) << ',' << ExactNum(s.position_m.x()) << ','
          << ExactNum(s.position_m.y());
        if (z) o << ',' << ExactNum(s.position_m.z());
        if (floor) o << ',' << *s.floor;
        o << '\n';
      }
      return true;
    }));
  }
  if (!walk.stance_truth.empty()) {
    WG_RETURN_IF_ERROR(
        WriteFileInOutput((root / "stance_truth.csv").string(), [&](std::ostream& o) {
          o << "t_s,stance\n";
          for (const StanceSample& s : walk.stance_truth) {
            o << ExactNum(s.t_s) << ',' << (s.stance ? 1 : 0) << '\n';
          }
          return true;
        }));
  }
  if (!walk.pressure.empty()) {
    WG_RETURN_IF_ERROR(WriteFileInOutput((root / "pressure.csv").string(), [&](std::ostream& o) {
      o << "t_s,hpa\n";
      for (const PressureSample& s : walk.pressure)
        o << ExactNum(s.t_s) << ',' << ExactNum(s.hpa) << '\n';
      return true;
    }));
  }
  if (!walk.waypoints.empty()) {
    WG_RETURN_IF_ERROR(WriteFileInOutput((root / "waypoints.csv").string(), [&](std::ostream& o) {
      o << "t_s,x_m,y_m,sigma_m\n";
      for (const Waypoint& w : walk.waypoints) {
        o << ExactNum(w.t_s) << ',' << ExactNum(w.position_m.x()) << ','
          << ExactNum(w.position_m.y()) << ',' << ExactNum(w.sigma_m) << '\n';
      }
      return true;
    }));
  }
  return Status::Ok();
}

}  // namespace

Status WriteWalk(const Walk& walk, const std::string& dir, const OutputOptions& options) {
  WG_RETURN_IF_ERROR(ValidateWalk(walk));
  return WriteOutputFolder(dir, options,
                           [&](const std::string& tmp) { return WriteWalkFiles(walk, tmp); });
}

void FormatAnchorsCsv(const std::vector<Anchor>& anchors, std::ostream& o) {
  // A floor column when every anchor has a floor (a walk's have all or none; a radio map merged
  // from walks with and without floors gets none).
  const bool floor = !anchors.empty() && std::all_of(anchors.begin(), anchors.end(),
                                                     [](const Anchor& a) { return a.floor; });
  bool sigma = false, group = false;
  for (const Anchor& a : anchors) {
    sigma = sigma || a.sigma_m > 0.0;
    group = group || !a.group.empty();
  }
  o << "id,x_m,y_m,z_m" << (floor ? ",floor" : "") << (sigma ? ",sigma_m" : "")
    << (group ? ",group" : "") << '\n';
  for (const Anchor& a : anchors) {
    o << a.id << ',';
    if (a.position_known) o << ExactNum(a.position_m.x()) << ',' << ExactNum(a.position_m.y());
    if (!a.position_known) o << ',';  // unknown: x_m and y_m empty
    o << ',' << ExactNum(a.position_m.z());
    if (floor) o << ',' << *a.floor;
    if (sigma) o << ',' << ExactNum(a.sigma_m);
    if (group) o << ',' << a.group;
    o << '\n';
  }
}

}  // namespace walkgraph
