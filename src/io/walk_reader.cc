// Reading a walk folder (io.h ReadWalk): walk.yaml and each CSV stream, every row checked by
// the rules of walk_rules.h; errors name the file and line.
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <limits>
#include <map>
#include <set>
#include <unordered_map>

#include "config/reader.h"
#include "io/plausibility.h"
#include "io/walk_rules.h"
#include "util/csv_reader.h"
#include "util/input_file.h"
#include "util/text.h"
#include "walkgraph/angle.h"
#include "walkgraph/config.h"
#include "walkgraph/io.h"

namespace walkgraph {

namespace fs = std::filesystem;
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
using internal::CsvReader;
using internal::IsIntegral;
using internal::Num;

namespace {

// ----------------------------------------------------------------- walk.yaml

// walk.yaml's radio block.
Status ReadRadio(const YAML::Node& radio, const std::string& path, RadioDefaults* radio_out) {
  ConfigReader rr(radio, path + ": radio");
  rr.ReadEnum("kind", &radio_out->kind, RadioKindNames());
  rr.ReadEnum("units", &radio_out->units, RssUnitsNames());
  rr.Read("A_dbm", &radio_out->path_loss.A_dbm);
  rr.Read("eta", &radio_out->path_loss.eta);
  rr.Read("d0_m", &radio_out->path_loss.d0_m);
  rr.Read("sigma_db", &radio_out->path_loss.sigma_db);
  rr.Read("floor_loss_db", &radio_out->path_loss.floor_loss_db);
  rr.Read("range_sigma_m", &radio_out->range_sigma_m);
  rr.Read("calibrated", &radio_out->calibrated);
  WG_RETURN_IF_ERROR(rr.Finish());
  const PathLossParams& pl = radio_out->path_loss;
  if (!(pl.eta > 0.0) || !(pl.d0_m > 0.0) || !(pl.sigma_db > 0.0) ||
      !(radio_out->range_sigma_m > 0.0) || !std::isfinite(pl.A_dbm)) {
    return InvalidArgument(path + ": radio: eta, d0_m, sigma_db and range_sigma_m must be > 0");
  }
  if (!(pl.floor_loss_db >= 0.0 && pl.floor_loss_db <= 100.0)) {
    return InvalidArgument(path + ": radio: floor_loss_db " + Num(pl.floor_loss_db) +
                           " outside [0, 100] dB");
  }
  if (const std::string e = internal::CheckRadioDefaults(*radio_out, {}); !e.empty()) {
    return InvalidArgument(path + ": radio: " + e);
  }
  return Status::Ok();
}

Status ReadMeta(const std::string& path, WalkMeta* meta) {
  WG_ASSIGN_OR_RETURN(YAML::Node root, LoadYamlFile(path));
  if (!root.IsMap()) return InvalidArgument(path + ":1: expected a YAML map (walk.yaml)");
  ConfigReader r(root, path);
  r.Read("format_version", &meta->format_version);
  r.Read("name", &meta->name);
  r.Read("source", &meta->source);
  r.Read("licence", &meta->licence);
  r.Read("storey_height_m", &meta->storey_height_m);
  std::string frame = "enu";
  r.ReadEnum("imu_placement", &meta->imu_placement, ImuPlacementNames());
  r.ReadEnum("truth", &meta->truth_kind, TruthKindNames());
  r.Read("frame", &frame);
  YAML::Node radio = r.Child("radio");
  YAML::Node initial = r.Child("initial_pose");
  YAML::Node extra = r.Child("extra");
  WG_RETURN_IF_ERROR(r.Finish());
  if (meta->format_version != 1) {
    return InvalidArgument(path + ": format_version " + std::to_string(meta->format_version) +
                           " is not supported; expected 1");
  }
  if (const std::string e = CheckStoreyHeight(meta->storey_height_m); !e.empty()) {
    return InvalidArgument(path + ": " + e);
  }
  if (frame != "enu") {
    return InvalidArgument(path + ": frame '" + frame + "'; expected 'enu' (x east, y north, m)");
  }
  if (radio.IsDefined() && !radio.IsNull()) {
    WG_RETURN_IF_ERROR(ReadRadio(radio, path, &meta->radio));
  }
  if (initial.IsDefined() && !initial.IsNull()) {
    InitialPose p;
    ConfigReader ri(initial, path + ": initial_pose");
    ri.Read("x_m", &p.x_m);
    ri.Read("y_m", &p.y_m);
    ri.Read("heading_rad", &p.heading_rad);
    ri.Read("sigma_xy_m", &p.sigma_xy_m);
    ri.Read("sigma_heading_rad", &p.sigma_heading_rad);
    double floor = 0.0;
    ri.Read("floor", &floor);
    WG_RETURN_IF_ERROR(ri.Finish());
    if (initial["floor"]) {
      if (const std::string e = CheckFloor(floor); !e.empty()) {
        return InvalidArgument(path + ": initial_pose: " + e);
      }
      p.floor = static_cast<int>(floor);
    }
    // A position-only start: heading_rad left out (and then sigma_heading_rad too).
    const bool has_heading = static_cast<bool>(initial["heading_rad"]);
    if (!has_heading && initial["sigma_heading_rad"]) {
      return InvalidArgument(path +
                             ": initial_pose: sigma_heading_rad without heading_rad (leave both "
                             "out for a start of known position, unknown heading)");
    }
    if (!has_heading) {
      p.heading_known = false;
      p.heading_rad = 0.0;
      p.sigma_heading_rad = kUnknownHeadingSigmaRad;
    }
    if (!(p.sigma_xy_m > 0.0) || !(p.sigma_heading_rad > 0.0)) {
      return InvalidArgument(path + ": initial_pose: sigmas must be > 0");
    }
    if (const std::string e = internal::CheckInitialPose(p, {}); !e.empty()) {
      return InvalidArgument(path + ": initial_pose: " + e);
    }
    p.heading_rad = NormalizeAngle(p.heading_rad);
    meta->initial_pose = p;
  }
  if (extra.IsDefined() && !extra.IsNull()) {
    if (!extra.IsMap()) return InvalidArgument(path + ": extra must be a map of numbers");
    for (const auto& kv : extra) {
      const std::string line = std::to_string(kv.first.Mark().line + 1);
      if (!kv.first.IsScalar()) {
        return InvalidArgument(path + ":" + line + ": extra: keys must be plain words");
      }
      double v = 0.0;
      if (!kv.second.IsScalar() || !internal::ParseFiniteDouble(kv.second.Scalar(), &v)) {
        return InvalidArgument(path + ":" + line + ": extra." + kv.first.Scalar() +
                               " must be a finite decimal number");
      }
      meta->extra[kv.first.Scalar()] = v;
    }
  }
  return Status::Ok();
}

// ----------------------------------------------------------------- CSV streams

// anchors.csv: id,x_m,y_m,z_m, then any of floor, sigma_m, group in that order.
internal::CsvHeaders AnchorHeaders() {
  internal::CsvHeaders h;
  const std::vector<std::string> base = {"id", "x_m", "y_m", "z_m"};
  const std::vector<std::string> optional = {"floor", "sigma_m", "group"};
  for (int mask = 0; mask < 8; ++mask) {
    std::vector<std::string> header = base;
    for (int i = 0; i < 3; ++i) {
      if (mask & (1 << i)) header.push_back(optional[i]);
    }
    h.accepted.push_back(std::move(header));
  }
  return h;
}

Status ReadAnchors(const std::string& path, const ValidationLimits& lim,
                   std::vector<Anchor>* anchors) {
  CsvReader r(path, AnchorHeaders());
  WG_RETURN_IF_ERROR(r.Open());
  const int floor_col = r.Column("floor"), sigma_col = r.Column("sigma_m"),
            group_col = r.Column("group");
  std::vector<std::string> f;
  std::set<int> ids;
  // Column i as a finite number.
  auto number = [&](int i, double* v) -> Status {
    if (internal::ParseFiniteDouble(f[i], v)) return Status::Ok();
    return InvalidArgument(r.Where() + "column '" + r.ColumnName(i) +
                           "': expected a finite decimal number, found " +
                           internal::QuotedNumber(f[i]));
  };
  while (true) {
    WG_ASSIGN_OR_RETURN(bool more, r.NextText(&f));
    if (!more) break;
    double id = 0.0;
    WG_RETURN_IF_ERROR(number(0, &id));
    if (!IsIntegral(id) || id < 0) {
      return InvalidArgument(r.Where() + "id must be a non-negative integer");
    }
    Anchor a;
    a.id = static_cast<int>(id);
    a.position_known = !(f[1].empty() && f[2].empty());
    if (a.position_known) {
      if (f[1].empty() || f[2].empty()) {
        return InvalidArgument(r.Where() +
                               "x_m and y_m must both be numbers (a surveyed or uncertain "
                               "position) or both empty (an unknown position)");
      }
      WG_RETURN_IF_ERROR(number(1, &a.position_m.x()));
      WG_RETURN_IF_ERROR(number(2, &a.position_m.y()));
    } else {
      const double nan = std::numeric_limits<double>::quiet_NaN();
      a.position_m.x() = a.position_m.y() = nan;
    }
    if (f[3].empty()) {
      if (a.position_known) {
        return InvalidArgument(r.Where() +
                               "column 'z_m' empty; expected a number (it may be empty only "
                               "with x_m and y_m, for an anchor of unknown position)");
      }
      a.position_m.z() = 0.0;
    } else {
      WG_RETURN_IF_ERROR(number(3, &a.position_m.z()));
    }
    if (floor_col >= 0) {
      double floor = 0.0;
      WG_RETURN_IF_ERROR(number(floor_col, &floor));
      if (const std::string e = CheckFloor(floor); !e.empty()) {
        return InvalidArgument(r.Where() + e);
      }
      a.floor = static_cast<int>(floor);
    }
    if (sigma_col >= 0 && !f[sigma_col].empty()) WG_RETURN_IF_ERROR(number(sigma_col, &a.sigma_m));
    if (group_col >= 0) a.group = f[group_col];
    if (const std::string e = CheckAnchorSurvey(a); !e.empty()) {
      return InvalidArgument(r.Where() + e);
    }
    const double largest =
        a.position_known ? a.position_m.cwiseAbs().maxCoeff() : std::fabs(a.position_m.z());
    if (largest > lim.max_abs_coordinate_m) {
      return InvalidArgument(r.Where() + "coordinate beyond " + Num(lim.max_abs_coordinate_m) +
                             " m");
    }
    if (!ids.insert(a.id).second) {
      return InvalidArgument(r.Where() + "duplicate anchor id " + std::to_string(a.id));
    }
    anchors->push_back(a);
  }
  if (anchors->empty()) return InvalidArgument(path + ":2: no anchors; expected at least one row");
  return Status::Ok();
}

Status ReadImu(const std::string& path, const ValidationLimits& lim, std::vector<ImuSample>* out) {
  CsvReader r(path, {"t_s", "ax", "ay", "az", "gx", "gy", "gz"}, {"mx", "my", "mz"});
  WG_RETURN_IF_ERROR(r.Open());
  std::vector<double> f;
  while (true) {
    WG_ASSIGN_OR_RETURN(bool more, r.Next(&f));
    if (!more) break;
    ImuSample s;
    s.t_s = f[0];
    s.acc_mps2 = Eigen::Vector3d(f[1], f[2], f[3]);
    s.gyro_radps = Eigen::Vector3d(f[4], f[5], f[6]);
    if (r.num_columns() == 10) {
      s.has_mag = true;
      s.mag_ut = Eigen::Vector3d(f[7], f[8], f[9]);
    }
    std::string e = CheckTimeStrictlyIncreasing(s.t_s, out->empty() ? nullptr : &out->back().t_s);
    if (e.empty()) e = CheckImu(s, lim);
    if (!e.empty()) return InvalidArgument(r.Where() + e);
    out->push_back(s);
  }
  if (out->empty()) return InvalidArgument(path + ":2: no samples; expected at least one row");
  return Status::Ok();
}

template <typename Sample, typename Fill, typename Check>
Status ReadRadioStream(const std::string& path, const std::vector<std::string>& columns,
                       const std::set<int>& anchor_ids, Fill fill, Check check,
                       std::vector<Sample>* out) {
  CsvReader r(path, columns);
  WG_RETURN_IF_ERROR(r.Open());
  std::vector<double> f;
  double last_t = 0.0;
  std::unordered_map<int, double> last_by_anchor;
  while (true) {
    WG_ASSIGN_OR_RETURN(bool more, r.Next(&f));
    if (!more) break;
    if (!IsIntegral(f[1])) return InvalidArgument(r.Where() + "anchor_id must be an integer");
    Sample s;
    fill(f, &s);
    if (anchor_ids.count(s.anchor_id) == 0) {
      return InvalidArgument(r.Where() + "unknown anchor_id " + std::to_string(s.anchor_id) +
                             "; expected an id listed in anchors.csv");
    }
    std::string e = CheckRadioTime(s.t_s, s.anchor_id, &last_t, &last_by_anchor, out->empty());
    if (e.empty()) e = check(s);
    if (!e.empty()) return InvalidArgument(r.Where() + e);
    out->push_back(s);
  }
  if (out->empty()) return InvalidArgument(path + ":2: no samples; expected at least one row");
  return Status::Ok();
}

Status ReadOdometry(const std::string& path, std::vector<OdometrySample>* out) {
  CsvReader r(path, {"t_s", "dist_m", "dheading_rad"});
  WG_RETURN_IF_ERROR(r.Open());
  std::vector<double> f;
  while (true) {
    WG_ASSIGN_OR_RETURN(bool more, r.Next(&f));
    if (!more) break;
    OdometrySample s{f[0], f[1], f[2]};
    std::string e = CheckTimeStrictlyIncreasing(s.t_s, out->empty() ? nullptr : &out->back().t_s);
    if (e.empty() && (s.dist_m < 0.0 || s.dist_m > 100.0)) {
      e = "dist_m " + Num(s.dist_m) + " outside [0, 100] m per increment";
    }
    if (e.empty() && std::fabs(s.dheading_rad) > 2.0 * kPi) {
      e = "dheading_rad beyond 2*pi per increment";
    }
    if (!e.empty()) return InvalidArgument(r.Where() + e);
    out->push_back(s);
  }
  if (out->empty()) return InvalidArgument(path + ":2: no samples; expected at least one row");
  return Status::Ok();
}

Status ReadWaypoints(const std::string& path, const ValidationLimits& lim,
                     std::vector<Waypoint>* out) {
  CsvReader r(path, {"t_s", "x_m", "y_m", "sigma_m"});
  WG_RETURN_IF_ERROR(r.Open());
  std::vector<double> f;
  while (true) {
    WG_ASSIGN_OR_RETURN(bool more, r.Next(&f));
    if (!more) break;
    const Waypoint w{f[0], Eigen::Vector2d(f[1], f[2]), f[3]};
    const std::string e = CheckWaypoint(w, out->empty() ? nullptr : &out->back(), lim);
    if (!e.empty()) return InvalidArgument(r.Where() + e);
    out->push_back(w);
  }
  return Status::Ok();
}

Status ReadTruth(const std::string& path, const ValidationLimits& lim,
                 std::vector<TruthSample>* out) {
  CsvReader r(path, internal::CsvHeaders{{{"t_s", "x_m", "y_m"},
                                          {"t_s", "x_m", "y_m", "z_m"},
                                          {"t_s", "x_m", "y_m", "floor"},
                                          {"t_s", "x_m", "y_m", "z_m", "floor"}}});
  WG_RETURN_IF_ERROR(r.Open());
  const int z_column = r.Column("z_m"), floor_column = r.Column("floor");
  std::vector<double> f;
  while (true) {
    WG_ASSIGN_OR_RETURN(bool more, r.Next(&f));
    if (!more) break;
    TruthSample s;
    s.t_s = f[0];
    s.has_z = z_column >= 0;
    s.position_m = Eigen::Vector3d(f[1], f[2], s.has_z ? f[z_column] : 0.0);
    std::string e = CheckTimeStrictlyIncreasing(s.t_s, out->empty() ? nullptr : &out->back().t_s);
    if (e.empty() && floor_column >= 0) {
      e = CheckFloor(f[floor_column]);
      if (e.empty()) s.floor = static_cast<int>(f[floor_column]);
    }
    if (e.empty() && s.position_m.cwiseAbs().maxCoeff() > lim.max_abs_coordinate_m) {
      e = "coordinate beyond " + Num(lim.max_abs_coordinate_m) + " m";
    }
    if (!e.empty()) return InvalidArgument(r.Where() + e);
    out->push_back(s);
  }
  if (out->empty()) return InvalidArgument(path + ":2: no samples; expected at least one row");
  return Status::Ok();
}

Status ReadPressure(const std::string& path, std::vector<PressureSample>* out) {
  CsvReader r(path, {"t_s", "hpa"});
  WG_RETURN_IF_ERROR(r.Open());
  std::vector<double> f;
  while (true) {
    WG_ASSIGN_OR_RETURN(bool more, r.Next(&f));
    if (!more) break;
    const PressureSample s{f[0], f[1]};
    const std::string e = CheckPressure(s, out->empty() ? nullptr : &out->back());
    if (!e.empty()) return InvalidArgument(r.Where() + e);
    out->push_back(s);
  }
  if (out->empty()) return InvalidArgument(path + ":2: no samples; expected at least one row");
  return Status::Ok();
}

Status ReadStanceTruth(const std::string& path, std::vector<StanceSample>* out) {
  CsvReader r(path, {"t_s", "stance"});
  WG_RETURN_IF_ERROR(r.Open());
  std::vector<double> f;
  while (true) {
    WG_ASSIGN_OR_RETURN(bool more, r.Next(&f));
    if (!more) break;
    std::string e = CheckTimeStrictlyIncreasing(f[0], out->empty() ? nullptr : &out->back().t_s);
    if (e.empty() && f[1] != 0.0 && f[1] != 1.0) e = "stance must be 0 or 1";
    if (!e.empty()) return InvalidArgument(r.Where() + e);
    out->push_back({f[0], f[1] == 1.0});
  }
  if (out->empty()) return InvalidArgument(path + ":2: no samples; expected at least one row");
  return Status::Ok();
}

}  // namespace

// ----------------------------------------------------------------- public API

StatusOr<Walk> ReadWalk(const std::string& dir, const ValidationLimits& limits) {
  const fs::path root(dir);
  std::error_code ec;
  if (!fs::is_directory(root, ec)) return NotFound(dir + ": not a walk directory");
  Walk walk;
  const fs::path yaml = root / "walk.yaml";
  const Status yaml_file = internal::CheckInputFile(yaml.string());
  if (yaml_file.code() == StatusCode::kNotFound) {
    return NotFound(yaml.string() + ": missing (every walk needs walk.yaml)");
  }
  WG_RETURN_IF_ERROR(yaml_file);
  WG_RETURN_IF_ERROR(ReadMeta(yaml.string(), &walk.meta));
  WG_RETURN_IF_ERROR(CheckMetaText(walk.meta, yaml.string()));

  // Which streams are there: each must be a regular file or absent.
  std::map<std::string, bool> present;
  for (const char* name : {"anchors.csv", "imu.csv", "rss.csv", "range.csv", "odometry.csv",
                           "truth.csv", "stance_truth.csv", "waypoints.csv", "pressure.csv"}) {
    WG_ASSIGN_OR_RETURN(present[name], internal::OptionalInputFile((root / name).string()));
  }
  const auto path = [&](const char* name) { return (root / name).string(); };
  if (present["anchors.csv"]) {
    WG_RETURN_IF_ERROR(ReadAnchors(path("anchors.csv"), limits, &walk.anchors));
  }
  std::set<int> ids;
  for (const Anchor& a : walk.anchors) ids.insert(a.id);

  if (present["imu.csv"]) WG_RETURN_IF_ERROR(ReadImu(path("imu.csv"), limits, &walk.imu));
  const RssUnits units = walk.meta.radio.units;
  for (const char* name : {"rss.csv", "range.csv"}) {
    if (present[name] && walk.anchors.empty()) {
      return InvalidArgument(path(name) + ": radio measurements need anchors.csv");
    }
  }
  if (present["rss.csv"]) {
    WG_RETURN_IF_ERROR(ReadRadioStream<RssSample>(
        path("rss.csv"), {"t_s", "anchor_id", "rss"}, ids,
        [](const std::vector<double>& f, RssSample* s) {
          *s = {f[0], static_cast<int>(f[1]), f[2]};
        },
        [&](const RssSample& s) { return CheckRss(s, units, limits); }, &walk.rss));
  }
  if (present["range.csv"]) {
    WG_RETURN_IF_ERROR(ReadRadioStream<RangeSample>(
        path("range.csv"), {"t_s", "anchor_id", "range_m"}, ids,
        [](const std::vector<double>& f, RangeSample* s) {
          *s = {f[0], static_cast<int>(f[1]), f[2]};
        },
        [&](const RangeSample& s) { return CheckRange(s, limits); }, &walk.ranges));
  }
  if (present["odometry.csv"]) {
    WG_RETURN_IF_ERROR(ReadOdometry(path("odometry.csv"), &walk.odometry));
  }
  if (present["truth.csv"]) WG_RETURN_IF_ERROR(ReadTruth(path("truth.csv"), limits, &walk.truth));
  if (present["stance_truth.csv"]) {
    WG_RETURN_IF_ERROR(ReadStanceTruth(path("stance_truth.csv"), &walk.stance_truth));
  }
  if (present["waypoints.csv"]) {
    WG_RETURN_IF_ERROR(ReadWaypoints(path("waypoints.csv"), limits, &walk.waypoints));
  }
  if (present["pressure.csv"]) {
    WG_RETURN_IF_ERROR(ReadPressure(path("pressure.csv"), &walk.pressure));
  }
  if (walk.meta.truth_kind != TruthKind::kNone && walk.truth.empty()) {
    return InvalidArgument(yaml.string() + ": truth is '" + ToString(walk.meta.truth_kind) +
                           "' but truth.csv is missing");
  }
  if (walk.meta.truth_kind == TruthKind::kNone && !walk.truth.empty()) {
    return InvalidArgument(yaml.string() +
                           ": truth.csv present; expected truth: "
                           "continuous|checkpoints in walk.yaml");
  }
  if (walk.imu.empty() && walk.rss.empty() && walk.ranges.empty() && walk.odometry.empty()) {
    return InvalidArgument(dir +
                           ": no measurements; expected at least one of imu.csv, rss.csv, "
                           "range.csv, odometry.csv");
  }
  WG_RETURN_IF_ERROR(CheckDeclaredStreams(walk, yaml.string()));
  if (const std::string e = internal::CheckStreamSpans(walk, true); !e.empty()) {
    return InvalidArgument(dir + ": " + e);
  }
  return walk;
}

StatusOr<std::vector<Anchor>> ReadAnchorsFile(const std::string& path,
                                              const ValidationLimits& limits) {
  std::vector<Anchor> anchors;
  WG_RETURN_IF_ERROR(ReadAnchors(path, limits, &anchors));
  if (anchors.empty()) return InvalidArgument(path + ": no anchor");
  return anchors;
}

}  // namespace walkgraph
