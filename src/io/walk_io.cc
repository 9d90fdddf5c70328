#include <unistd.h>

#include <charconv>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <set>
#include <sstream>
#include <unordered_map>

#include "io/csv_reader.h"
#include "walkgraph/angle.h"
#include "walkgraph/config.h"
#include "walkgraph/io.h"

namespace walkgraph {

namespace fs = std::filesystem;
using internal::CsvReader;

namespace {

// Shortest "%g" rendering of a number for messages.
std::string G(double v) {
  char buf[32];
  std::snprintf(buf, sizeof(buf), "%g", v);
  return buf;
}

// ----------------------------------------------------------------- row checks
// Each returns "" when the row is acceptable, else what was expected. Shared by the readers
// (which prefix "file:line: ") and ValidateWalk (which prefixes the stream and index).

std::string CheckTimeStrictlyIncreasing(double t, const double* prev_t) {
  if (t < 0.0) return "t_s must be >= 0, found " + G(t);
  if (prev_t == nullptr || t > *prev_t) return "";
  std::ostringstream s;
  s << std::setprecision(15) << "timestamp " << t
    << (t == *prev_t ? " repeats the previous one" : " goes backwards (previous ");
  if (t != *prev_t) s << *prev_t << ")";
  s << "; expected strictly increasing t_s";
  return s.str();
}

std::string CheckImu(const ImuSample& s, const ValidationLimits& lim) {
  if (s.acc_mps2.cwiseAbs().maxCoeff() > lim.max_abs_acc_mps2) {
    return "acceleration component over " + G(lim.max_abs_acc_mps2) +
           " m/s^2 (physically absurd; units must be m/s^2)";
  }
  if (s.gyro_radps.cwiseAbs().maxCoeff() > lim.max_abs_gyro_radps) {
    return "angular rate component over " + G(lim.max_abs_gyro_radps) +
           " rad/s (physically absurd; units must be rad/s)";
  }
  return "";
}

std::string CheckRss(const RssSample& s, RssUnits units, const ValidationLimits& lim) {
  if (units == RssUnits::kDbm && (s.rss < lim.min_rss_dbm || s.rss > lim.max_rss_dbm)) {
    return "rss " + G(s.rss) + " outside [" + G(lim.min_rss_dbm) + ", " + G(lim.max_rss_dbm) +
           "] dBm";
  }
  return "";
}

std::string CheckRange(const RangeSample& s, const ValidationLimits& lim) {
  if (s.range_m < 0.0 || s.range_m > lim.max_range_m) {
    return "range_m " + G(s.range_m) + " outside [0, " + G(lim.max_range_m) + "] m";
  }
  return "";
}

// Multi-anchor streams: timestamps never go backwards; per anchor they strictly increase.
std::string CheckRadioTime(double t, int anchor_id, double* last_t,
                           std::unordered_map<int, double>* last_by_anchor, bool first) {
  if (t < 0.0) return "t_s must be >= 0";
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

// ----------------------------------------------------------------- walk.yaml

template <typename E>
Status ParseEnum(const std::string& text, const std::vector<std::pair<const char*, E>>& table,
                 const std::string& where, E* out) {
  std::string options;
  for (const auto& [name, value] : table) {
    if (text == name) {
      *out = value;
      return Status::Ok();
    }
    options += (options.empty() ? "" : "|") + std::string(name);
  }
  return InvalidArgument(where + ": '" + text + "' is not one of " + options);
}

Status ReadMeta(const std::string& path, WalkMeta* meta) {
  WG_ASSIGN_OR_RETURN(YAML::Node root, LoadYamlFile(path));
  if (!root.IsMap()) return InvalidArgument(path + ":1: expected a YAML map (walk.yaml)");
  ConfigReader r(root, path);
  r.Read("format_version", &meta->format_version);
  r.Read("name", &meta->name);
  r.Read("source", &meta->source);
  r.Read("licence", &meta->licence);
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
  if (frame != "enu") {
    return InvalidArgument(path + ": frame '" + frame + "'; expected 'enu' (x east, y north, m)");
  }
  WG_RETURN_IF_ERROR(ParseEnum<ImuPlacement>(placement,
                                             {{"none", ImuPlacement::kNone},
                                              {"foot", ImuPlacement::kFoot},
                                              {"waist", ImuPlacement::kWaist},
                                              {"hip", ImuPlacement::kHip},
                                              {"handheld", ImuPlacement::kHandheld}},
                                             path + ": imu_placement", &meta->imu_placement));
  WG_RETURN_IF_ERROR(ParseEnum<TruthKind>(truth,
                                          {{"none", TruthKind::kNone},
                                           {"continuous", TruthKind::kContinuous},
                                           {"checkpoints", TruthKind::kCheckpoints}},
                                          path + ": truth", &meta->truth_kind));
  if (radio.IsDefined() && !radio.IsNull()) {
    ConfigReader rr(radio, path + ": radio");
    std::string kind = "none", units = "dbm";
    rr.Read("kind", &kind);
    rr.Read("units", &units);
    rr.Read("A_dbm", &meta->radio.path_loss.A_dbm);
    rr.Read("eta", &meta->radio.path_loss.eta);
    rr.Read("d0_m", &meta->radio.path_loss.d0_m);
    rr.Read("sigma_db", &meta->radio.path_loss.sigma_db);
    rr.Read("range_sigma_m", &meta->radio.range_sigma_m);
    WG_RETURN_IF_ERROR(rr.Finish());
    WG_RETURN_IF_ERROR(ParseEnum<RadioKind>(
        kind, {{"none", RadioKind::kNone}, {"rss", RadioKind::kRss}, {"range", RadioKind::kRange}},
        path + ": radio.kind", &meta->radio.kind));
    WG_RETURN_IF_ERROR(ParseEnum<RssUnits>(units,
                                           {{"dbm", RssUnits::kDbm}, {"rfcode", RssUnits::kRfcode}},
                                           path + ": radio.units", &meta->radio.units));
    const PathLossParams& pl = meta->radio.path_loss;
    if (!(pl.eta > 0.0) || !(pl.d0_m > 0.0) || !(pl.sigma_db > 0.0) ||
        !(meta->radio.range_sigma_m > 0.0) || !std::isfinite(pl.A_dbm)) {
      return InvalidArgument(path + ": radio: eta, d0_m, sigma_db and range_sigma_m must be > 0");
    }
  }
  if (initial.IsDefined() && !initial.IsNull()) {
    InitialPose p;
    ConfigReader ri(initial, path + ": initial_pose");
    ri.Read("x_m", &p.x_m);
    ri.Read("y_m", &p.y_m);
    ri.Read("heading_rad", &p.heading_rad);
    ri.Read("sigma_xy_m", &p.sigma_xy_m);
    ri.Read("sigma_heading_rad", &p.sigma_heading_rad);
    WG_RETURN_IF_ERROR(ri.Finish());
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
      try {
        if (!kv.second.IsScalar()) throw YAML::Exception(kv.second.Mark(), "not a scalar");
        meta->extra[kv.first.Scalar()] = kv.second.as<double>();
      } catch (const YAML::Exception&) {
        return InvalidArgument(path + ":" + line + ": extra." + kv.first.Scalar() +
                               " must be a number");
      }
    }
  }
  return Status::Ok();
}

// ----------------------------------------------------------------- CSV streams

Status ReadAnchors(const std::string& path, const ValidationLimits& lim,
                   std::vector<Anchor>* anchors) {
  CsvReader r(path, {"id", "x_m", "y_m", "z_m"});
  WG_RETURN_IF_ERROR(r.Open());
  std::vector<double> f;
  std::set<int> ids;
  while (true) {
    WG_ASSIGN_OR_RETURN(bool more, r.Next(&f));
    if (!more) break;
    if (!IsIntegral(f[0]) || f[0] < 0) {
      return InvalidArgument(r.Where() + "id must be a non-negative integer");
    }
    Anchor a;
    a.id = static_cast<int>(f[0]);
    a.position_m = Eigen::Vector3d(f[1], f[2], f[3]);
    if (a.position_m.cwiseAbs().maxCoeff() > lim.max_abs_coordinate_m) {
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

Status ReadTruth(const std::string& path, const ValidationLimits& lim,
                 std::vector<TruthSample>* out) {
  CsvReader r(path, {"t_s", "x_m", "y_m"}, {"z_m"});
  WG_RETURN_IF_ERROR(r.Open());
  std::vector<double> f;
  while (true) {
    WG_ASSIGN_OR_RETURN(bool more, r.Next(&f));
    if (!more) break;
    TruthSample s;
    s.t_s = f[0];
    s.has_z = r.num_columns() == 4;
    s.position_m = Eigen::Vector3d(f[1], f[2], s.has_z ? f[3] : 0.0);
    std::string e = CheckTimeStrictlyIncreasing(s.t_s, out->empty() ? nullptr : &out->back().t_s);
    if (e.empty() && s.position_m.cwiseAbs().maxCoeff() > lim.max_abs_coordinate_m) {
      e = "coordinate beyond " + G(lim.max_abs_coordinate_m) + " m";
    }
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
  return Status::Ok();
}

bool Exists(const fs::path& p) {
  std::error_code ec;
  return fs::exists(p, ec);
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
  if (!Exists(yaml)) return NotFound(yaml.string() + ": missing (every walk needs walk.yaml)");
  WG_RETURN_IF_ERROR(ReadMeta(yaml.string(), &walk.meta));

  const fs::path anchors = root / "anchors.csv";
  if (Exists(anchors)) {
    WG_RETURN_IF_ERROR(ReadAnchors(anchors.string(), limits, &walk.anchors));
  }
  std::set<int> ids;
  for (const Anchor& a : walk.anchors) ids.insert(a.id);

  if (Exists(root / "imu.csv")) {
    WG_RETURN_IF_ERROR(ReadImu((root / "imu.csv").string(), limits, &walk.imu));
  }
  const RssUnits units = walk.meta.radio.units;
  for (const char* name : {"rss.csv", "range.csv"}) {
    if (Exists(root / name) && walk.anchors.empty()) {
      return InvalidArgument((root / name).string() + ": radio measurements need anchors.csv");
    }
  }
  if (Exists(root / "rss.csv")) {
    WG_RETURN_IF_ERROR(ReadRadioStream<RssSample>(
        (root / "rss.csv").string(), {"t_s", "anchor_id", "rss"}, ids,
        [](const std::vector<double>& f, RssSample* s) {
          *s = {f[0], static_cast<int>(f[1]), f[2]};
        },
        [&](const RssSample& s) { return CheckRss(s, units, limits); }, &walk.rss));
  }
  if (Exists(root / "range.csv")) {
    WG_RETURN_IF_ERROR(ReadRadioStream<RangeSample>(
        (root / "range.csv").string(), {"t_s", "anchor_id", "range_m"}, ids,
        [](const std::vector<double>& f, RangeSample* s) {
          *s = {f[0], static_cast<int>(f[1]), f[2]};
        },
        [&](const RangeSample& s) { return CheckRange(s, limits); }, &walk.ranges));
  }
  if (Exists(root / "odometry.csv")) {
    WG_RETURN_IF_ERROR(ReadOdometry((root / "odometry.csv").string(), &walk.odometry));
  }
  if (Exists(root / "truth.csv")) {
    WG_RETURN_IF_ERROR(ReadTruth((root / "truth.csv").string(), limits, &walk.truth));
  }
  if (Exists(root / "stance_truth.csv")) {
    WG_RETURN_IF_ERROR(ReadStanceTruth((root / "stance_truth.csv").string(), &walk.stance_truth));
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
  return walk;
}

Status ValidateWalk(const Walk& walk, const ValidationLimits& limits) {
  std::set<int> ids;
  for (size_t i = 0; i < walk.anchors.size(); ++i) {
    if (walk.anchors[i].id < 0)
      return InvalidArgument("anchors[" + std::to_string(i) + "]: negative id");
    if (!walk.anchors[i].position_m.allFinite()) {
      return InvalidArgument("anchors[" + std::to_string(i) + "]: non-finite position");
    }
    if (!ids.insert(walk.anchors[i].id).second) {
      return InvalidArgument("anchors: duplicate id " + std::to_string(walk.anchors[i].id));
    }
  }
  auto where = [](const char* stream, size_t i) {
    return std::string(stream) + "[" + std::to_string(i) + "]: ";
  };
  for (size_t i = 0; i < walk.imu.size(); ++i) {
    const ImuSample& s = walk.imu[i];
    if (!std::isfinite(s.t_s) || !s.acc_mps2.allFinite() || !s.gyro_radps.allFinite() ||
        (s.has_mag && !s.mag_ut.allFinite())) {
      return InvalidArgument(where("imu", i) + "non-finite value");
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
      if (!std::isfinite(s.t_s) || !std::isfinite(s.rss)) {
        return InvalidArgument(where("rss", i) + "non-finite value");
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
      if (!std::isfinite(s.t_s) || !std::isfinite(s.range_m)) {
        return InvalidArgument(where("range", i) + "non-finite value");
      }
      if (!ids.count(s.anchor_id)) return InvalidArgument(where("range", i) + "unknown anchor_id");
      std::string e = CheckRadioTime(s.t_s, s.anchor_id, &last, &by_anchor, i == 0);
      if (e.empty()) e = CheckRange(s, limits);
      if (!e.empty()) return InvalidArgument(where("range", i) + e);
    }
  }
  for (size_t i = 0; i < walk.odometry.size(); ++i) {
    const OdometrySample& s = walk.odometry[i];
    if (!std::isfinite(s.t_s) || !std::isfinite(s.dist_m) || !std::isfinite(s.dheading_rad)) {
      return InvalidArgument(where("odometry", i) + "non-finite value");
    }
    const std::string e =
        CheckTimeStrictlyIncreasing(s.t_s, i ? &walk.odometry[i - 1].t_s : nullptr);
    if (!e.empty()) return InvalidArgument(where("odometry", i) + e);
  }
  for (size_t i = 0; i < walk.truth.size(); ++i) {
    const TruthSample& s = walk.truth[i];
    if (!std::isfinite(s.t_s) || !s.position_m.allFinite()) {
      return InvalidArgument(where("truth", i) + "non-finite value");
    }
    const std::string e = CheckTimeStrictlyIncreasing(s.t_s, i ? &walk.truth[i - 1].t_s : nullptr);
    if (!e.empty()) return InvalidArgument(where("truth", i) + e);
  }
  if ((walk.meta.truth_kind == TruthKind::kNone) != walk.truth.empty()) {
    return InvalidArgument("truth kind and truth samples disagree");
  }
  return Status::Ok();
}

Status WriteFileAtomically(const std::string& path,
                           const std::function<bool(std::ostream&)>& write) {
  const std::string tmp = path + ".tmp-" + std::to_string(::getpid());
  bool ok = false;
  {
    std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
    if (!out) return IoError(path + ": cannot create temporary file " + tmp);
    ok = write(out);
    out.flush();
    ok = ok && out.good();
  }
  std::error_code ec;
  if (!ok) {
    fs::remove(tmp, ec);
    return IoError(path + ": write failed");
  }
  fs::rename(tmp, path, ec);
  if (ec) {
    fs::remove(tmp, ec);
    return IoError(path + ": cannot rename temporary file: " + ec.message());
  }
  return Status::Ok();
}

namespace {

Status WriteWalkFiles(const Walk& walk, const fs::path& root) {
  const WalkMeta& m = walk.meta;
  WG_RETURN_IF_ERROR(WriteFileAtomically((root / "walk.yaml").string(), [&](std::ostream& o) {
    YAML::Emitter e;
    e << YAML::BeginMap;
    e << YAML::Key << "format_version" << YAML::Value << 1;
    e << YAML::Key << "name" << YAML::Value << m.name;
    e << YAML::Key << "source" << YAML::Value << m.source;
    e << YAML::Key << "licence" << YAML::Value << m.licence;
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
    e << YAML::Key << "range_sigma_m" << YAML::Value << Num(m.radio.range_sigma_m);
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
  }));
  if (!walk.anchors.empty()) {
    WG_RETURN_IF_ERROR(WriteFileAtomically((root / "anchors.csv").string(), [&](std::ostream& o) {
      o << "id,x_m,y_m,z_m\n";
      for (const Anchor& a : walk.anchors) {
        o << a.id << ',' << Num(a.position_m.x()) << ',' << Num(a.position_m.y()) << ','
          << Num(a.position_m.z()) << '\n';
      }
      return true;
    }));
  }
  if (!walk.imu.empty()) {
    const bool mag = walk.imu[0].has_mag;
    WG_RETURN_IF_ERROR(WriteFileAtomically((root / "imu.csv").string(), [&](std::ostream& o) {
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
    WG_RETURN_IF_ERROR(WriteFileAtomically((root / "rss.csv").string(), [&](std::ostream& o) {
      o << "t_s,anchor_id,rss\n";
      for (const RssSample& s : walk.rss)
        o << Num(s.t_s) << ',' << s.anchor_id << ',' << Num(s.rss) << '\n';
      return true;
    }));
  }
  if (!walk.ranges.empty()) {
    WG_RETURN_IF_ERROR(WriteFileAtomically((root / "range.csv").string(), [&](std::ostream& o) {
      o << "t_s,anchor_id,range_m\n";
      for (const RangeSample& s : walk.ranges) {
        o << Num(s.t_s) << ',' << s.anchor_id << ',' << Num(s.range_m) << '\n';
      }
      return true;
    }));
  }
  if (!walk.odometry.empty()) {
    WG_RETURN_IF_ERROR(WriteFileAtomically((root / "odometry.csv").string(), [&](std::ostream& o) {
      o << "t_s,dist_m,dheading_rad\n";
      for (const OdometrySample& s : walk.odometry) {
        o << Num(s.t_s) << ',' << Num(s.dist_m) << ',' << Num(s.dheading_rad) << '\n';
      }
      return true;
    }));
  }
  if (!walk.truth.empty()) {
    const bool z = walk.truth[0].has_z;
    WG_RETURN_IF_ERROR(WriteFileAtomically((root / "truth.csv").string(), [&](std::ostream& o) {
      o << "t_s,x_m,y_m" << (z ? ",z_m" : "") << '\n';
      for (const TruthSample& s : walk.truth) {
        o << Num(s.t_s) << ',' << Num(s.position_m.x()) << ',' << Num(s.position_m.y());
        if (z) o << ',' << Num(s.position_m.z());
        o << '\n';
      }
      return true;
    }));
  }
  if (!walk.stance_truth.empty()) {
    WG_RETURN_IF_ERROR(
        WriteFileAtomically((root / "stance_truth.csv").string(), [&](std::ostream& o) {
          o << "t_s,stance\n";
          for (const StanceSample& s : walk.stance_truth) {
            o << Num(s.t_s) << ',' << (s.stance ? 1 : 0) << '\n';
          }
          return true;
        }));
  }
  return Status::Ok();
}

}  // namespace

Status WriteWalk(const Walk& walk, const std::string& dir) {
  WG_RETURN_IF_ERROR(ValidateWalk(walk));
  const fs::path root(dir);
  std::error_code ec;
  if (fs::exists(root, ec)) {
    if (!fs::is_directory(root, ec)) return IoError(dir + ": exists and is not a directory");
    // Each file is replaced atomically; stale optional streams from an older walk go away.
    for (const char* f : {"imu.csv", "rss.csv", "range.csv", "odometry.csv", "truth.csv",
                          "stance_truth.csv", "anchors.csv"}) {
      fs::remove(root / f, ec);
    }
    return WriteWalkFiles(walk, root);
  }
  // A new directory appears only when complete: write into a sibling, then rename.
  const fs::path tmp = root.string() + ".tmp-" + std::to_string(::getpid());
  fs::remove_all(tmp, ec);
  if (!fs::create_directories(tmp, ec)) {
    return IoError(dir + ": cannot create directory " + tmp.string() + ": " + ec.message());
  }
  Status s = WriteWalkFiles(walk, tmp);
  if (s.ok()) {
    fs::rename(tmp, root, ec);
    if (ec) s = IoError(dir + ": cannot rename " + tmp.string() + ": " + ec.message());
  }
  if (!s.ok()) fs::remove_all(tmp, ec);
  return s;
}

Status WriteTumTrajectory(const Trajectory& trajectory, const std::string& path) {
  return WriteFileAtomically(path, [&](std::ostream& o) {
    o << "# t x y z qx qy qz qw\n";
    for (const TrajectoryPoint& p : trajectory.points) {
      const double half = 0.5 * p.heading_rad;
      o << Num(p.t_s) << ' ' << Num(p.position_m.x()) << ' ' << Num(p.position_m.y()) << ' '
        << Num(p.position_m.z()) << " 0 0 " << Num(std::sin(half)) << ' ' << Num(std::cos(half))
        << '\n';
    }
    return true;
  });
}

StatusOr<Trajectory> ReadTumTrajectory(const std::string& path) {
  std::ifstream in(path);
  if (!in) return NotFound(path + ": cannot open file");
  Trajectory traj;
  std::string line;
  int n = 0;
  while (std::getline(in, line)) {
    ++n;
    internal::StripCarriageReturn(&line);
    if (line.empty() || line[0] == '#') continue;
    std::istringstream ss(line);
    std::vector<double> v;
    std::string tok;
    while (ss >> tok) {
      double x;
      if (!internal::ParseFiniteDouble(tok, &x)) {
        return InvalidArgument(path + ":" + std::to_string(n) + ": '" + tok + "' is not a number");
      }
      v.push_back(x);
    }
    if (v.size() != 8) {
      return InvalidArgument(path + ":" + std::to_string(n) +
                             ": expected 8 fields 't x y z qx qy qz qw'");
    }
    TrajectoryPoint p;
    p.t_s = v[0];
    p.position_m = Eigen::Vector3d(v[1], v[2], v[3]);
    // yaw of the quaternion (x, y, z, w)
    p.heading_rad =
        std::atan2(2.0 * (v[7] * v[6] + v[4] * v[5]), 1.0 - 2.0 * (v[5] * v[5] + v[6] * v[6]));
    if (!traj.points.empty() && !(p.t_s > traj.points.back().t_s)) {
      return InvalidArgument(path + ":" + std::to_string(n) + ": timestamps must increase");
    }
    traj.points.push_back(p);
  }
  return traj;
}

}  // namespace walkgraph
