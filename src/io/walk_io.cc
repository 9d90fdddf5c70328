#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <limits>
#include <map>
#include <set>
#include <sstream>
#include <unordered_map>

#include "config/reader.h"
#include "io/plausibility.h"
#include "util/csv_reader.h"
#include "util/geodesy.h"
#include "util/input_file.h"
#include "util/text.h"
#include "walkgraph/angle.h"
#include "walkgraph/config.h"
#include "walkgraph/io.h"

namespace walkgraph {

namespace fs = std::filesystem;
using internal::CheckImu;
using internal::CheckRange;
using internal::CheckRss;
using internal::CsvReader;

namespace {

// A number for messages (%g).
std::string G(double v) { return internal::Num(v); }

// ----------------------------------------------------------------- row checks
// Each returns "" when the row is acceptable, else what was expected. Shared by the readers
// (which prefix "file:line: ") and ValidateWalk (which prefixes the stream and index).

// Timestamps are seconds; beyond kMaxTimeS (year 2286 as Unix time) they are in another unit.
constexpr double kMaxTimeS = 1e10;

std::string CheckTimeRange(double t) {
  if (t < 0.0) return "t_s must be >= 0, found " + G(t);
  if (t <= kMaxTimeS) return "";
  for (const auto& [factor, unit] : {std::pair<double, const char*>{1e3, "milliseconds"},
                                     {1e6, "microseconds"},
                                     {1e9, "nanoseconds"}}) {
    if (t / factor <= kMaxTimeS) {
      return "t_s " + G(t) + " is beyond " + G(kMaxTimeS) + " s; it looks like " + unit + " (" +
             G(t / factor) + " s); expected seconds";
    }
  }
  return "t_s " + G(t) + " is beyond " + G(kMaxTimeS) + " s; expected seconds";
}

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
    return "timestamp " + G(t) + " goes backwards (previous " + G(*last_t) +
           "); expected non-decreasing t_s";
  }
  auto it = last_by_anchor->find(anchor_id);
  if (it != last_by_anchor->end() && !(t > it->second)) {
    return "timestamp " + G(t) + " repeats for anchor " + std::to_string(anchor_id) +
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
  return "floor " + G(v) + " is not an integer level in [-" + std::to_string(kMaxAbsFloor) + ", " +
         std::to_string(kMaxAbsFloor) + "]";
}

// Barometer readings: sea-level pressure is ~1013 hPa; 300 hPa is above Everest's summit,
// 1100 hPa below the Dead Sea's shore.
constexpr double kMinPressureHpa = 300.0, kMaxPressureHpa = 1100.0;
std::string CheckPressure(const PressureSample& s, const PressureSample* previous) {
  if (!std::isfinite(s.t_s) || !std::isfinite(s.hpa)) return "non-finite value";
  std::string e = CheckTimeStrictlyIncreasing(s.t_s, previous ? &previous->t_s : nullptr);
  if (e.empty() && !(s.hpa >= kMinPressureHpa && s.hpa <= kMaxPressureHpa)) {
    e = "hpa " + G(s.hpa) + " outside [" + G(kMinPressureHpa) + ", " + G(kMaxPressureHpa) +
        "] hPa; expected a barometer reading in hectopascal";
  }
  return e;
}

// The storey height of walk.yaml (metres between consecutive floors).
std::string CheckStoreyHeight(double h) {
  if (std::isfinite(h) && h >= 1.0 && h <= 20.0) return "";
  return "storey_height_m " + G(h) + " outside [1, 20] m";
}

// ----------------------------------------------------------------- walk.yaml

template <typename E>
Status ParseEnum(const std::string& text, const EnumNames<E>& table, const std::string& where,
                 E* out) {
  std::string options;
  for (const auto& [name, value] : table) {
    if (text == name) {
      *out = value;
      return Status::Ok();
    }
    options += (options.empty() ? "" : "|") + name;
  }
  return InvalidArgument(where + ": " + internal::Quoted(text) + " is not one of " + options);
}

// walk.yaml's radio block.
Status ReadRadio(const YAML::Node& radio, const std::string& path, RadioDefaults* radio_out) {
  ConfigReader rr(radio, path + ": radio");
  std::string kind = "none", units = "dbm";
  rr.Read("kind", &kind);
  rr.Read("units", &units);
  rr.Read("A_dbm", &radio_out->path_loss.A_dbm);
  rr.Read("eta", &radio_out->path_loss.eta);
  rr.Read("d0_m", &radio_out->path_loss.d0_m);
  rr.Read("sigma_db", &radio_out->path_loss.sigma_db);
  rr.Read("floor_loss_db", &radio_out->path_loss.floor_loss_db);
  rr.Read("range_sigma_m", &radio_out->range_sigma_m);
  rr.Read("calibrated", &radio_out->calibrated);
  WG_RETURN_IF_ERROR(rr.Finish());
  WG_RETURN_IF_ERROR(ParseEnum(kind, RadioKindNames(), path + ": radio.kind", &radio_out->kind));
  WG_RETURN_IF_ERROR(ParseEnum(units, RssUnitsNames(), path + ": radio.units", &radio_out->units));
  const PathLossParams& pl = radio_out->path_loss;
  if (!(pl.eta > 0.0) || !(pl.d0_m > 0.0) || !(pl.sigma_db > 0.0) ||
      !(radio_out->range_sigma_m > 0.0) || !std::isfinite(pl.A_dbm)) {
    return InvalidArgument(path + ": radio: eta, d0_m, sigma_db and range_sigma_m must be > 0");
  }
  if (!(pl.floor_loss_db >= 0.0 && pl.floor_loss_db <= 100.0)) {
    return InvalidArgument(path + ": radio: floor_loss_db " + G(pl.floor_loss_db) +
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
  std::string placement = "none", truth = "none", frame = "enu";
  r.Read("imu_placement", &placement);
  r.Read("truth", &truth);
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
  WG_RETURN_IF_ERROR(
      ParseEnum(placement, ImuPlacementNames(), path + ": imu_placement", &meta->imu_placement));
  WG_RETURN_IF_ERROR(ParseEnum(truth, TruthKindNames(), path + ": truth", &meta->truth_kind));
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

// "" when the anchor's survey fields agree (sigma_m in [0, 1000] m, none on an unknown anchor).
std::string CheckAnchorSurvey(const Anchor& a) {
  if (!(a.sigma_m >= 0.0 && a.sigma_m <= kMaxAnchorSigmaM)) {
    return "sigma_m " + G(a.sigma_m) + " outside [0, 1000] m";
  }
  if (!a.position_known && a.sigma_m > 0.0) {
    return "sigma_m " + G(a.sigma_m) +
           " on an anchor of unknown position (empty x_m, y_m); expected 0 or empty";
  }
  return CheckAnchorGroup(a.group);
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
      return InvalidArgument(r.Where() + "coordinate beyond " + G(lim.max_abs_coordinate_m) + " m");
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
      e = "dist_m " + G(s.dist_m) + " outside [0, 100] m per increment";
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

// A waypoint's rule, for the reader and ValidateWalk alike ("" when it holds).
std::string CheckWaypoint(const Waypoint& w, const Waypoint* previous,
                          const ValidationLimits& lim) {
  if (!std::isfinite(w.t_s) || !w.position_m.allFinite() || !std::isfinite(w.sigma_m)) {
    return "non-finite value";
  }
  std::string e = CheckTimeStrictlyIncreasing(w.t_s, previous ? &previous->t_s : nullptr);
  if (e.empty() && w.position_m.cwiseAbs().maxCoeff() > lim.max_abs_coordinate_m) {
    e = "coordinate beyond " + G(lim.max_abs_coordinate_m) + " m";
  }
  if (e.empty() && !(w.sigma_m >= 1e-3 && w.sigma_m <= 1e3)) {
    e = "sigma_m " + G(w.sigma_m) + " outside [0.001, 1000] m";
  }
  return e;
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
      e = "coordinate beyond " + G(lim.max_abs_coordinate_m) + " m";
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

// Full precision, no trailing noise: shortest representation that round-trips.
std::string Num(double v) {
  // The shortest text that reads back to the same double (keeps files small and readable).
  char buf[64];
  const auto res = std::to_chars(buf, buf + sizeof(buf), v);
  return std::string(buf, res.ptr);
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

namespace {

// "non-finite value in <field> (<value>); expected a finite number" for the first field that is
// NaN or infinite, else "".
std::string NonFinite(std::initializer_list<std::pair<const char*, double>> fields) {
  for (const auto& [name, v] : fields) {
    if (!std::isfinite(v)) {
      return std::string("non-finite value in ") + name + " (" + G(v) +
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
                             G(limits.max_abs_coordinate_m) + " m");
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

namespace {

// anchors.csv: the optional columns only when some anchor needs them; an unknown position's
// x_m, y_m empty.
bool WriteAnchors(const Walk& walk, std::ostream& o) {
  const bool floor = walk.anchors[0].floor.has_value();
  bool sigma = false, group = false;
  for (const Anchor& a : walk.anchors) {
    sigma = sigma || a.sigma_m > 0.0;
    group = group || !a.group.empty();
  }
  o << "id,x_m,y_m,z_m" << (floor ? ",floor" : "") << (sigma ? ",sigma_m" : "")
    << (group ? ",group" : "") << '\n';
  for (const Anchor& a : walk.anchors) {
    o << a.id << ',';
    if (a.position_known) o << Num(a.position_m.x()) << ',' << Num(a.position_m.y());
    if (!a.position_known) o << ',';  // unknown: x_m and y_m empty
    o << ',' << Num(a.position_m.z());
    if (floor) o << ',' << *a.floor;
    if (sigma) o << ',' << Num(a.sigma_m);
    if (group) o << ',' << a.group;
    o << '\n';
  }
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
    e << YAML::Key << "storey_height_m" << YAML::Value << Num(m.storey_height_m);
  }
  e << YAML::Key << "imu_placement" << YAML::Value << ToString(m.imu_placement);
  e << YAML::Key << "frame" << YAML::Value << "enu";
  e << YAML::Key << "truth" << YAML::Value << ToString(m.truth_kind);
  e << YAML::Key << "radio" << YAML::Value << YAML::BeginMap;
  e << YAML::Key << "kind" << YAML::Value << ToString(m.radio.kind);
  e << YAML::Key << "units" << YAML::Value << ToString(m.radio.units);
  e << YAML::Key << "A_dbm" << YAML::Value << Num(m.radio.path_loss.A_dbm);
  e << YAML::Key << "eta" << YAML::Value << Num(m.radio.path_loss.eta);
  e << YAML::Key << "d0_m" << YAML::Value << Num(m.radio.path_loss.d0_m);
  e << YAML::Key << "sigma_db" << YAML::Value << Num(m.radio.path_loss.sigma_db);
  if (m.radio.path_loss.floor_loss_db != 0.0 || (!walk.anchors.empty() && walk.anchors[0].floor)) {
    e << YAML::Key << "floor_loss_db" << YAML::Value << Num(m.radio.path_loss.floor_loss_db);
  }
  e << YAML::Key << "range_sigma_m" << YAML::Value << Num(m.radio.range_sigma_m);
  e << YAML::Key << "calibrated" << YAML::Value << m.radio.calibrated;
  e << YAML::EndMap;
  if (m.initial_pose) {
    const InitialPose& p = *m.initial_pose;
    e << YAML::Key << "initial_pose" << YAML::Value << YAML::BeginMap;
    e << YAML::Key << "x_m" << YAML::Value << Num(p.x_m);
    e << YAML::Key << "y_m" << YAML::Value << Num(p.y_m);
    if (p.heading_known) e << YAML::Key << "heading_rad" << YAML::Value << Num(p.heading_rad);
    e << YAML::Key << "sigma_xy_m" << YAML::Value << Num(p.sigma_xy_m);
    if (p.heading_known) {
      e << YAML::Key << "sigma_heading_rad" << YAML::Value << Num(p.sigma_heading_rad);
    }
    if (p.floor) e << YAML::Key << "floor" << YAML::Value << *p.floor;
    e << YAML::EndMap;
  }
  if (!m.extra.empty()) {
    e << YAML::Key << "extra" << YAML::Value << YAML::BeginMap;
    for (const auto& [k, v] : m.extra) e << YAML::Key << k << YAML::Value << Num(v);
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
        o << Num(s.t_s);
        for (int i = 0; i < 3; ++i) o << ',' << Num(s.acc_mps2[i]);
        for (int i = 0; i < 3; ++i) o << ',' << Num(s.gyro_radps[i]);
        if (mag) {
          for (int i = 0; i < 3; ++i) o << ',' << Num(s.mag_ut[i]);
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
        o << Num(s.t_s) << ',' << s.anchor_id << ',' << Num(s.rss) << '\n';
      return true;
    }));
  }
  if (!walk.ranges.empty()) {
    WG_RETURN_IF_ERROR(WriteFileInOutput((root / "range.csv").string(), [&](std::ostream& o) {
      o << "t_s,anchor_id,range_m\n";
      for (const RangeSample& s : walk.ranges) {
        o << Num(s.t_s) << ',' << s.anchor_id << ',' << Num(s.range_m) << '\n';
      }
      return true;
    }));
  }
  if (!walk.odometry.empty()) {
    WG_RETURN_IF_ERROR(WriteFileInOutput((root / "odometry.csv").string(), [&](std::ostream& o) {
      o << "t_s,dist_m,dheading_rad\n";
      for (const OdometrySample& s : walk.odometry) {
        o << Num(s.t_s) << ',' << Num(s.dist_m) << ',' << Num(s.dheading_rad) << '\n';
      }
      return true;
    }));
  }
  if (!walk.truth.empty()) {
    const bool z = walk.truth[0].has_z, floor = walk.truth[0].floor.has_value();
    WG_RETURN_IF_ERROR(WriteFileInOutput((root / "truth.csv").string(), [&](std::ostream& o) {
      o << "t_s,x_m,y_m" << (z ? ",z_m" : "") << (floor ? ",floor" : "") << '\n';
      for (const TruthSample& s : walk.truth) {
        o << Num(s.t_s) << ',' << Num(s.position_m.x()) << ',' << Num(s.position_m.y());
        if (z) o << ',' << Num(s.position_m.z());
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
            o << Num(s.t_s) << ',' << (s.stance ? 1 : 0) << '\n';
          }
          return true;
        }));
  }
  if (!walk.pressure.empty()) {
    WG_RETURN_IF_ERROR(WriteFileInOutput((root / "pressure.csv").string(), [&](std::ostream& o) {
      o << "t_s,hpa\n";
      for (const PressureSample& s : walk.pressure) o << Num(s.t_s) << ',' << Num(s.hpa) << '\n';
      return true;
    }));
  }
  if (!walk.waypoints.empty()) {
    WG_RETURN_IF_ERROR(WriteFileInOutput((root / "waypoints.csv").string(), [&](std::ostream& o) {
      o << "t_s,x_m,y_m,sigma_m\n";
      for (const Waypoint& w : walk.waypoints) {
        o << Num(w.t_s) << ',' << Num(w.position_m.x()) << ',' << Num(w.position_m.y()) << ','
          << Num(w.sigma_m) << '\n';
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

void FormatTumTrajectory(const Trajectory& trajectory, std::ostream& o) {
  o << "# t x y z qx qy qz qw\n";
  for (const TrajectoryPoint& p : trajectory.points) {
    const double half = 0.5 * p.heading_rad;
    o << Num(p.t_s) << ' ' << Num(p.position_m.x()) << ' ' << Num(p.position_m.y()) << ' '
      << Num(p.position_m.z()) << " 0 0 " << Num(std::sin(half)) << ' ' << Num(std::cos(half))
      << '\n';
  }
}

void FormatTrajectoryCsv(const Trajectory& trajectory, std::ostream& o) {
  o << "t_s,x_m,y_m,yaw_rad,cov_xx,cov_xy,cov_yy,cov_xyaw,cov_yyaw,cov_yawyaw\n";
  for (const TrajectoryPoint& p : trajectory.points) {
    o << Num(p.t_s) << ',' << Num(p.position_m.x()) << ',' << Num(p.position_m.y()) << ','
      << Num(p.heading_rad);
    if (p.covariance) {
      const Eigen::Matrix3d& c = *p.covariance;
      o << ',' << Num(c(0, 0)) << ',' << Num(c(0, 1)) << ',' << Num(c(1, 1)) << ',' << Num(c(0, 2))
        << ',' << Num(c(1, 2)) << ',' << Num(c(2, 2)) << '\n';
    } else {
      o << ",,,,,,\n";
    }
  }
}

void FormatTruthTum(const std::vector<TruthSample>& truth, std::ostream& o) {
  o << "# t x y z qx qy qz qw (truth: position only, identity orientation)\n";
  for (const TruthSample& t : truth) {
    o << Num(t.t_s) << ' ' << Num(t.position_m.x()) << ' ' << Num(t.position_m.y()) << ' '
      << Num(t.position_m.z()) << " 0 0 0 1\n";
  }
}

Status WriteTumTrajectory(const Trajectory& trajectory, const std::string& path,
                          const OutputOptions& options) {
  return WriteOutputFile(path, options, [&](std::ostream& o) {
    FormatTumTrajectory(trajectory, o);
    return true;
  });
}

Status FormatIpinSubmission(const Walk& walk, const Trajectory& trajectory, std::ostream& o) {
  const auto lat = walk.meta.extra.find("ipin.origin_lat_deg");
  const auto lon = walk.meta.extra.find("ipin.origin_lon_deg");
  if (lat == walk.meta.extra.end() || lon == walk.meta.extra.end()) {
    return FailedPrecondition("IPIN submission: walk '" + walk.meta.name +
                              "' has no ipin.origin_lat_deg/_lon_deg (not from convert ipin)");
  }
  if (trajectory.empty()) return FailedPrecondition("IPIN submission: empty trajectory");
  const internal::LocalTangentPlane plane(lat->second, lon->second);
  const int start_floor = walk.StartFloor();
  double end = walk.EndTime();  // the last record, the barometer's included
  if (!walk.pressure.empty()) end = std::max(end, walk.pressure.back().t_s);
  char line[96];
  for (long k = 0; 0.5 * static_cast<double>(k) <= end; ++k) {
    const double t = 0.5 * static_cast<double>(k);
    if (t < trajectory.points.front().t_s) {
      o << "0,0,0\n";
      continue;
    }
    const Eigen::Vector3d p = trajectory.PositionAt(t);
    const Eigen::Vector2d ll = plane.LatLon(p.x(), p.y());
    std::snprintf(line, sizeof(line), "%.12f,%.12f,%d\n", ll.y(), ll.x(),
                  trajectory.FloorAt(t).value_or(start_floor));
    o << line;
  }
  return Status::Ok();
}

Status WriteIpinSubmission(const Walk& walk, const Trajectory& trajectory, const std::string& path,
                           const OutputOptions& options) {
  Status format = Status::Ok();
  WG_RETURN_IF_ERROR(WriteOutputFile(path, options, [&](std::ostream& o) {
    format = FormatIpinSubmission(walk, trajectory, o);
    return format.ok();
  }));
  return format;
}

StatusOr<Trajectory> ReadTumTrajectory(const std::string& path) {
  internal::LineReader in(path);
  WG_RETURN_IF_ERROR(in.Open());
  Trajectory traj;
  std::string line;
  while (true) {
    WG_ASSIGN_OR_RETURN(const bool more, in.Next(&line));
    if (!more) break;
    if (line.empty() || line[0] == '#') continue;
    std::istringstream ss(line);
    std::vector<double> v;
    std::string tok;
    while (ss >> tok && v.size() <= 8) {
      double x;
      if (!internal::ParseFiniteDouble(tok, &x)) {
        return InvalidArgument(in.Where() + internal::Quoted(tok) + " is not a number");
      }
      v.push_back(x);
    }
    if (v.size() != 8)
      return InvalidArgument(in.Where() + "expected 8 fields 't x y z qx qy qz qw'");
    TrajectoryPoint p;
    p.t_s = v[0];
    p.position_m = Eigen::Vector3d(v[1], v[2], v[3]);
    // yaw of the quaternion (x, y, z, w)
    p.heading_rad =
        std::atan2(2.0 * (v[7] * v[6] + v[4] * v[5]), 1.0 - 2.0 * (v[5] * v[5] + v[6] * v[6]));
    if (!traj.points.empty() && !(p.t_s > traj.points.back().t_s)) {
      return InvalidArgument(in.Where() + "timestamps must increase");
    }
    traj.points.push_back(p);
  }
  return traj;
}

}  // namespace walkgraph
