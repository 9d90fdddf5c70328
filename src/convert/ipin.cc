// IPIN 2023 Track 3 converter (see ConvertIpin in walkgraph/convert.h for the conventions).
//
// Beacon identity, checked against the data because the organisers do not document it. The
// six iBeacons broadcast MAC BE:AC:20:23:00:0N with Minor N (N = 1..6). Over the three training
// logs in ../shared/datasets/ipin2023_t3 (TrainingTrial01/05/21 rep. 01), with each BLE4 reading
// placed on the straight line between the POSI landmarks around it, the correlation of RSS with
// log10(horizontal distance) to each BLE_Locations.csv row was (most negative = best):
//   Minor 1: BLE1 −0.73 (n = 265; heard at −63 dBm 1.5 m from BLE1), every other row > −0.70
//   Minor 2: BLE3 −0.63 (n = 129; −69 dBm 2 m from BLE3 on level −2), BLE2 only −0.09
//   Minor 3: BLE2 −0.64 (n = 150, level 0 only, the level of BLE2); BLE4 −0.63, BLE6 −0.61
//   Minor 4: BLE4 −0.51 (n = 93), BLE2 −0.47 (taken by Minor 3), others > −0.41
//   Minor 5: BLE5 −0.46 (n = 170), every other row > −0.11
//   Minor 6: no evidence (n = 31, |corr| < 0.06 for every row): kept as BLE6 by elimination.
// With Minor N = BLE N the correlation pooled over the landmarks is −0.30 (rank 107 of the 720
// assignments); Minors 2 and 3 are swapped relative to that belief. The mapping below is what
// the data supports; Minors 4 and 6 rest partly on elimination.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <limits>
#include <map>
#include <optional>
#include <set>

#include "convert/line_fields.h"
#include "io/plausibility.h"
#include "util/geodesy.h"
#include "util/input_file.h"
#include "util/text.h"
#include "walkgraph/convert.h"

namespace walkgraph {

namespace fs = std::filesystem;

int IpinMinorToBleId(int minor) {
  switch (minor) {
    case 1:
      return 1;
    case 2:
      return 3;
    case 3:
      return 2;
    case 4:
      return 4;
    case 5:
      return 5;
    case 6:
      return 6;
    default:
      return -1;
  }
}

namespace {

using internal::LocalTangentPlane;

struct Beacon {
  int id = 0;
  double lat_deg = 0.0, lon_deg = 0.0;
  int floor = 0;
  int line = 0;  // in BLE_Locations.csv
};

StatusOr<std::vector<Beacon>> ReadBleLocations(const std::string& path) {
  internal::LineReader in(path);
  WG_RETURN_IF_ERROR(in.Open());
  std::string line;
  int n = 0;
  std::vector<Beacon> beacons;
  std::set<int> ids;
  while (true) {
    WG_ASSIGN_OR_RETURN(const bool more, in.Next(&line));
    if (!more) break;
    ++n;
    internal::LineFields f(path, n, line, ',');
    if (n == 1) {
      if (line.rfind("bleID,Lat,Lon,floor", 0) != 0) {
        return f.Error("expected the header 'bleID,Lat,Lon,floor'");
      }
      continue;
    }
    if (f.size() == 1 && f.field(0).empty()) continue;
    WG_RETURN_IF_ERROR(f.ExpectCount(4));
    std::string name = f.field(0);
    if (name.size() >= 2 && name.front() == '"' && name.back() == '"') {
      name = name.substr(1, name.size() - 2);
    }
    Beacon b;
    if (name.rfind("BLE", 0) != 0 || name.size() == 3 ||
        name.find_first_not_of("0123456789", 3) != std::string::npos || name.size() > 6) {
      return f.Error("bleID '" + f.field(0) + "'; expected BLE<number>");
    }
    b.id = std::stoi(name.substr(3));
    b.line = n;
    WG_ASSIGN_OR_RETURN(b.lat_deg, f.Number(1));
    WG_ASSIGN_OR_RETURN(b.lon_deg, f.Number(2));
    WG_ASSIGN_OR_RETURN(const long long floor, f.Integer(3));
    b.floor = static_cast<int>(floor);
    if (std::fabs(b.lat_deg) > 90.0 || std::fabs(b.lon_deg) > 180.0) {
      return f.Error("latitude/longitude out of range");
    }
    if (!ids.insert(b.id).second) return f.Error("duplicate bleID " + name);
    beacons.push_back(b);
  }
  if (beacons.empty()) return InvalidArgument(path + ": no beacons");
  return beacons;
}

struct Vec3Stamped {
  double sensor_t = 0.0;
  Eigen::Vector3d v;
};

// Linear interpolation of a strictly increasing stamped series at t (inside its span).
Eigen::Vector3d Interpolate(const std::vector<Vec3Stamped>& s, double t) {
  auto it = std::lower_bound(s.begin(), s.end(), t,
                             [](const Vec3Stamped& a, double x) { return a.sensor_t < x; });
  if (it == s.begin()) return it->v;
  if (it == s.end()) return s.back().v;
  const Vec3Stamped& b = *it;
  const Vec3Stamped& a = *(it - 1);
  const double w = (t - a.sensor_t) / (b.sensor_t - a.sensor_t);
  return a.v + w * (b.v - a.v);
}

// The beacons are heard in the building the walk is in: each within kMaxBeaconDistanceM of
// the log's first POSI landmark (the frame's origin). Bluetooth LE carries about 100 m; farther,
// a file's latitude and longitude are swapped (4.8e6 m off in Nuremberg) or the files are of two
// venues.
Status CheckBeaconsNearTheWalk(const std::vector<Beacon>& beacons, const std::string& locations,
                               const std::string& log_path, double lat0_deg, double lon0_deg) {
  constexpr double kMaxBeaconDistanceM = 1000.0;
  const internal::LocalTangentPlane plane(lat0_deg, lon0_deg);
  for (const Beacon& b : beacons) {
    const double d = plane.EastNorth(b.lat_deg, b.lon_deg).norm();
    if (d <= kMaxBeaconDistanceM) continue;
    return InvalidArgument(locations + ":" + std::to_string(b.line) + ": BLE" +
                           std::to_string(b.id) + " at Lat " + internal::Num(b.lat_deg) + ", Lon " +
                           internal::Num(b.lon_deg) + " is " + internal::Num(d) +
                           " m from the first POSI landmark of " + log_path + " (lat " +
                           internal::Num(lat0_deg) + ", lon " + internal::Num(lon0_deg) +
                           "); expected every beacon within " + internal::Num(kMaxBeaconDistanceM) +
                           " m of the walk (Lat and Lon swapped in one of the two files?)");
  }
  return Status::Ok();
}

bool IsRecordType(const std::string& s) {
  return s.size() == 4 && std::all_of(s.begin(), s.end(), [](char c) {
           return (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9');
         });
}

struct Posi {
  double t_s, lat_deg, lon_deg;
  int floor;
};

// What a GetSensorData log holds that the walk uses, as read.
struct IpinLog {
  std::vector<Posi> posi;
  std::vector<Vec3Stamped> acc, gyro, mag;
  std::vector<double> acc_app_t;
  std::vector<RssSample> rss;
  std::vector<PressureSample> pressure;
  std::set<std::pair<double, int>> rss_seen;
  int rss_duplicates = 0, non_ibeacon = 0, pressure_repeats = 0;
  // WIFI (ConvertOptions::ipin_wifi): readings by access point, on the app clock; the BSSID
  // of each anchor id; the last line's scan (SensorTimeStamp, AppTimestamp).
  std::vector<RssSample> wifi;
  std::map<int, std::string> wifi_bssid;
  std::set<std::string> wifi_id_collisions;
  int wifi_duplicates = 0;
  std::optional<std::pair<double, double>> wifi_scan;
};

// ACCE, GYRO, MAGN: TYPE;AppTimestamp;SensorTimestamp;x;y;z;accuracy.
Status ReadInertialLine(const internal::LineFields& f, internal::DroppedReadings* dropped,
                        IpinLog* log) {
  const std::string& type = f.field(0);
  WG_RETURN_IF_ERROR(f.ExpectCount(7));
  Vec3Stamped s;
  WG_ASSIGN_OR_RETURN(const double app_t, f.Number(1));
  WG_ASSIGN_OR_RETURN(s.sensor_t, f.Number(2));
  for (int k = 0; k < 3; ++k) {
    WG_ASSIGN_OR_RETURN(s.v[k], f.Number(3 + k));
  }
  WG_RETURN_IF_ERROR(f.Integer(6).status());
  if (type != "MAGN") {  // an accelerometer or gyro reading past any phone's range
    ImuSample check;
    (type == "ACCE" ? check.acc_mps2 : check.gyro_radps) = s.v;
    bool drop = false;
    WG_RETURN_IF_ERROR(dropped->Check("imu", f.Where(), internal::CheckImu(check, {}), &drop));
    if (drop) return Status::Ok();
  }
  std::vector<Vec3Stamped>& series = type == "ACCE"   ? log->acc
                                     : type == "GYRO" ? log->gyro
                                                      : log->mag;
  if (!series.empty() && !(s.sensor_t > series.back().sensor_t)) {
    return f.Error(type + " SensorTimestamp does not increase");
  }
  series.push_back(s);
  if (type == "ACCE") log->acc_app_t.push_back(app_t);
  return Status::Ok();
}

// 2023 logs: POSI;AppTS;counter;lat;lon;floor;building. Technical annex: no counter.
Status ReadPosiLine(const internal::LineFields& f, IpinLog* log) {
  WG_RETURN_IF_ERROR(f.ExpectCount(7, 6));
  const size_t k = f.size() == 7 ? 3 : 2;
  Posi p;
  WG_ASSIGN_OR_RETURN(p.t_s, f.Number(1));
  WG_ASSIGN_OR_RETURN(p.lat_deg, f.Number(k));
  WG_ASSIGN_OR_RETURN(p.lon_deg, f.Number(k + 1));
  WG_ASSIGN_OR_RETURN(const long long floor, f.Integer(k + 2));
  WG_RETURN_IF_ERROR(f.Integer(k + 3).status());
  p.floor = static_cast<int>(floor);
  if (std::fabs(p.lat_deg) > 90.0 || std::fabs(p.lon_deg) > 180.0) {
    return f.Error("latitude/longitude out of range");
  }
  if (!log->posi.empty() && !(p.t_s > log->posi.back().t_s)) {
    return f.Error("POSI timestamp does not increase");
  }
  log->posi.push_back(p);
  return Status::Ok();
}

// BLE4;AppTimestamp;iBeacon;MAC;RSS;TxPower;Major;Minor;UUID.
Status ReadBle4Line(const internal::LineFields& f, const std::map<int, const Beacon*>& beacons,
                    const std::string& locations, internal::DroppedReadings* dropped,
                    internal::ColumnCheck* rss_column, IpinLog* log) {
  if (f.size() >= 3 && f.field(2) != "iBeacon") {
    ++log->non_ibeacon;  // Eddystone frames carry no Minor; none in the 2023 logs
    return Status::Ok();
  }
  WG_RETURN_IF_ERROR(f.ExpectCount(9));
  WG_ASSIGN_OR_RETURN(const double t, f.Number(1));
  WG_ASSIGN_OR_RETURN(const double value, f.Number(4));
  WG_ASSIGN_OR_RETURN(const long long minor, f.Integer(7));
  const int id = IpinMinorToBleId(static_cast<int>(minor));
  if (id < 0 || beacons.count(id) == 0) {
    return f.Error("iBeacon Minor " + std::to_string(minor) +
                   " is not one of the deployed beacons in " + locations);
  }
  const std::string& mac = f.field(3);
  const std::string expected_mac = "BE:AC:20:23:00:0" + std::to_string(minor);
  if (mac != expected_mac) {
    return f.Error("MAC '" + mac + "' with Minor " + std::to_string(minor) + "; expected " +
                   expected_mac);
  }
  std::string problem = internal::CheckRss({t, id, value}, RssUnits::kDbm, {});
  if (problem.empty()) problem = internal::CheckBleRss(value);
  rss_column->Add(value < 0.0, f.Where(), internal::Num(value));
  bool drop = false;
  WG_RETURN_IF_ERROR(dropped->Check("rss", f.Where(), problem, &drop));
  if (drop) return Status::Ok();
  if (!log->rss.empty() && t < log->rss.back().t_s) {
    return f.Error("BLE4 AppTimestamp goes backwards");
  }
  if (!log->rss_seen.insert({t, id}).second) {
    ++log->rss_duplicates;
    return Status::Ok();
  }
  log->rss.push_back({t, id, value});
  return Status::Ok();
}

// A BSSID "aa:bb:cc:dd:ee:ff" (hex, either case) as a 48-bit number; none when malformed.
std::optional<uint64_t> ParseBssid(const std::string& s) {
  if (s.size() != 17) return std::nullopt;
  uint64_t v = 0;
  for (size_t i = 0; i < s.size(); ++i) {
    const char c = s[i];
    if (i % 3 == 2) {
      if (c != ':') return std::nullopt;
      continue;
    }
    int d = -1;
    if (c >= '0' && c <= '9') d = c - '0';
    if (c >= 'a' && c <= 'f') d = c - 'a' + 10;
    if (c >= 'A' && c <= 'F') d = c - 'A' + 10;
    if (d < 0) return std::nullopt;
    v = v * 16 + static_cast<uint64_t>(d);
  }
  return v;
}

// WIFI;AppTimestamp;SensorTimeStamp;Name_SSID;MAC_BSSID;Frequency;RSS (technical annex). An
// access point is an anchor of unknown position, id kIpinWifiAnchorIdBase + the BSSID's last
// three bytes (the same in every walk of a building; two BSSIDs that share them: the second
// is dropped, counted). The readings of one scan (one SensorTimeStamp on consecutive lines)
// keep the first line's AppTimestamp, so they stay one radio epoch.
Status ReadWifiLine(const internal::LineFields& f, internal::DroppedReadings* dropped,
                    IpinLog* log) {
  WG_RETURN_IF_ERROR(f.ExpectCount(7));
  WG_ASSIGN_OR_RETURN(double t, f.Number(1));
  WG_ASSIGN_OR_RETURN(const double sensor_t, f.Number(2));
  WG_ASSIGN_OR_RETURN(const double value, f.Number(6));
  const std::optional<uint64_t> bssid = ParseBssid(f.field(4));
  if (!bssid) {
    return f.Error("MAC_BSSID '" + f.field(4) + "'; expected six hex bytes as aa:bb:cc:dd:ee:ff");
  }
  if (log->wifi_scan && log->wifi_scan->first == sensor_t) t = log->wifi_scan->second;
  log->wifi_scan = std::make_pair(sensor_t, t);
  const int id = kIpinWifiAnchorIdBase + static_cast<int>(*bssid & 0xFFFFFF);
  auto [it, added] = log->wifi_bssid.emplace(id, f.field(4));
  if (!added && it->second != f.field(4)) {
    log->wifi_id_collisions.insert(f.field(4));
    return Status::Ok();
  }
  std::string problem = internal::CheckRss({t, id, value}, RssUnits::kDbm, {});
  if (problem.empty() && !(value < 0.0))
    problem = "a WiFi RSS of " + internal::Num(value) + " dBm; expected a negative dBm";
  bool drop = false;
  WG_RETURN_IF_ERROR(dropped->Check("wifi", f.Where(), problem, &drop));
  if (drop) return Status::Ok();
  if (!log->wifi.empty() && t < log->wifi.back().t_s) {
    return f.Error("WIFI AppTimestamp goes backwards");
  }
  if (!log->rss_seen.insert({t, id}).second) {
    ++log->wifi_duplicates;
    return Status::Ok();
  }
  log->wifi.push_back({t, id, value});
  return Status::Ok();
}

// PRES;AppTimestamp;SensorTimestamp;pressure(hPa);accuracy — on the app clock.
Status ReadPresLine(const internal::LineFields& f, IpinLog* log) {
  WG_RETURN_IF_ERROR(f.ExpectCount(5));
  PressureSample p;
  WG_ASSIGN_OR_RETURN(p.t_s, f.Number(1));
  WG_ASSIGN_OR_RETURN(p.hpa, f.Number(3));
  if (!(p.hpa >= 300.0 && p.hpa <= 1100.0)) {
    return f.Error("pressure outside [300, 1100] hPa");
  }
  if (!log->pressure.empty() && !(p.t_s > log->pressure.back().t_s)) {
    ++log->pressure_repeats;  // a repeated AppTimestamp: the first reading kept
    return Status::Ok();
  }
  log->pressure.push_back(p);
  return Status::Ok();
}

StatusOr<IpinLog> ReadIpinLog(const std::string& log_path,
                              const std::map<int, const Beacon*>& beacons,
                              const std::string& locations, bool wifi,
                              internal::DroppedReadings* dropped) {
  internal::LineReader in(log_path);
  WG_RETURN_IF_ERROR(in.Open());
  IpinLog log;
  // RSS swapped with another field of the BLE4 line (TxPower 0, Major, Minor) shows over the
  // whole log: an RSS column mostly >= 0 dBm.
  internal::ColumnCheck rss_column("field 5 (RSS) of the BLE4 lines", "a negative BLE RSSI in dBm");
  std::string line;
  int n = 0;
  while (true) {
    WG_ASSIGN_OR_RETURN(const bool more, in.Next(&line));
    if (!more) break;
    ++n;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    if (line.empty() || line[0] == '%') continue;
    internal::LineFields f(log_path, n, line, ';');
    if (f.size() < 2 || !IsRecordType(f.field(0))) {
      return f.Error(
          "expected a '%' comment or a record 'TYPE;AppTimestamp;...' with a "
          "4-character type");
    }
    const std::string& type = f.field(0);
    if (type == "ACCE" || type == "GYRO" || type == "MAGN") {
      WG_RETURN_IF_ERROR(ReadInertialLine(f, dropped, &log));
    } else if (type == "POSI") {
      WG_RETURN_IF_ERROR(ReadPosiLine(f, &log));
    } else if (type == "BLE4") {
      WG_RETURN_IF_ERROR(ReadBle4Line(f, beacons, locations, dropped, &rss_column, &log));
    } else if (type == "PRES") {
      WG_RETURN_IF_ERROR(ReadPresLine(f, &log));
    } else if (type == "WIFI" && wifi) {
      WG_RETURN_IF_ERROR(ReadWifiLine(f, dropped, &log));
    }
    // Other record types (AHRS, GNSS, LIGH, SOUN, PROX, ...; WIFI unless asked) are not used.
  }
  WG_RETURN_IF_ERROR(rss_column.Check(
      "BLE4;AppTimestamp;iBeacon;MAC;RSS;TxPower;Major;Minor;UUID (technical annex)"));
  if (log.posi.empty()) return InvalidArgument(log_path + ": no POSI lines (no ground truth)");
  if (log.acc.size() < 2 || log.gyro.size() < 2) {
    return InvalidArgument(log_path + ": fewer than two ACCE or GYRO lines");
  }
  return log;
}

// The IMU stream: each ACCE sample inside the GYRO (and MAGN) span, with the gyro (and
// magnetometer) interpolated at its time, on the app clock (see convert.h).
Status BuildImu(const IpinLog& log, const std::string& log_path, Walk* walk) {
  // Sensor clock → app clock.
  double offset = log.acc_app_t[0] - log.acc[0].sensor_t;
  for (size_t i = 0; i < log.acc.size(); ++i) {
    offset = std::min(offset, log.acc_app_t[i] - log.acc[i].sensor_t);
  }
  // The common span of the three inertial streams (a magnetometer that is absent or has
  // fewer than two lines is left out).
  const bool use_mag = log.mag.size() >= 2;
  double lo = log.gyro.front().sensor_t, hi = log.gyro.back().sensor_t;
  if (use_mag) {
    lo = std::max(lo, log.mag.front().sensor_t);
    hi = std::min(hi, log.mag.back().sensor_t);
  }
  int outside = 0;
  for (const Vec3Stamped& a : log.acc) {
    if (a.sensor_t < lo || a.sensor_t > hi || a.sensor_t + offset < 0.0) {
      ++outside;
      continue;
    }
    ImuSample s;
    s.t_s = a.sensor_t + offset;
    s.acc_mps2 = a.v;
    s.gyro_radps = Interpolate(log.gyro, a.sensor_t);
    if (use_mag) {
      s.has_mag = true;
      s.mag_ut = Interpolate(log.mag, a.sensor_t);
    }
    walk->imu.push_back(s);
  }
  if (walk->imu.empty()) {
    return InvalidArgument(log_path + ": no ACCE line inside the GYRO/MAGN span");
  }
  walk->meta.extra["convert.imu_sensor_to_app_offset_s"] = offset;
  walk->meta.extra["convert.imu_samples_outside_span"] = outside;
  walk->meta.extra["convert.gyro_lines"] = static_cast<double>(log.gyro.size());
  walk->meta.extra["convert.magn_lines"] = static_cast<double>(log.mag.size());
  return Status::Ok();
}

// --known-start: the first landmark is the frame's origin and the start (heading unknown); the
// recording before it is dropped.
Status ApplyKnownStart(const ConvertOptions& options, const std::string& log_path, Walk* walk) {
  if (!(options.known_start_sigma_m > 0.0) || !std::isfinite(options.known_start_sigma_m)) {
    return InvalidArgument("ipin: the known start's sigma must be finite and > 0");
  }
  const double t0 = walk->truth.front().t_s;
  const auto imu_end = std::find_if(walk->imu.begin(), walk->imu.end(),
                                    [t0](const ImuSample& s) { return s.t_s >= t0; });
  const auto rss_end = std::find_if(walk->rss.begin(), walk->rss.end(),
                                    [t0](const RssSample& s) { return s.t_s >= t0; });
  walk->meta.extra["convert.imu_samples_before_start_dropped"] =
      static_cast<double>(imu_end - walk->imu.begin());
  walk->meta.extra["convert.ble_before_start_dropped"] =
      static_cast<double>(rss_end - walk->rss.begin());
  const auto pressure_end = std::find_if(walk->pressure.begin(), walk->pressure.end(),
                                         [t0](const PressureSample& s) { return s.t_s >= t0; });
  walk->imu.erase(walk->imu.begin(), imu_end);
  walk->rss.erase(walk->rss.begin(), rss_end);
  walk->pressure.erase(walk->pressure.begin(), pressure_end);
  if (walk->imu.size() < 2) {
    return InvalidArgument(log_path + ": fewer than two IMU samples after the first POSI");
  }
  InitialPose start;
  start.x_m = walk->truth.front().position_m.x();
  start.y_m = walk->truth.front().position_m.y();
  start.sigma_xy_m = options.known_start_sigma_m;
  start.heading_known = false;
  start.heading_rad = 0.0;
  start.sigma_heading_rad = kUnknownHeadingSigmaRad;
  start.floor = walk->truth.front().floor;
  walk->meta.initial_pose = start;
  return Status::Ok();
}

// walk.yaml's description of an IPIN walk, the beacons and landmarks in the local frame whose
// origin is the first landmark.
void DescribeAndPlace(const std::string& log_path, const std::vector<Beacon>& beacons,
                      const std::vector<Posi>& posi, Walk* walk) {
  walk->meta.name = internal::ToValidUtf8(fs::path(log_path).stem().string());
  walk->meta.source =
      "IPIN 2023 competition Track 3 (Torres-Sospedra et al., Zenodo 10.5281/zenodo.8362205), "
      "GetSensorData log " +
      fs::path(log_path).filename().string();
  walk->meta.licence = "none stated by the organisers (cite; do not redistribute)";
  walk->meta.imu_placement = ImuPlacement::kHandheld;
  walk->meta.truth_kind = TruthKind::kCheckpoints;
  walk->meta.radio.kind = RadioKind::kRss;
  walk->meta.radio.units = RssUnits::kDbm;
  const LocalTangentPlane plane(posi.front().lat_deg, posi.front().lon_deg);
  walk->meta.extra["ipin.origin_lat_deg"] = posi.front().lat_deg;
  walk->meta.extra["ipin.origin_lon_deg"] = posi.front().lon_deg;
  for (const Beacon& b : beacons) {
    const Eigen::Vector2d en = plane.EastNorth(b.lat_deg, b.lon_deg);
    walk->anchors.push_back({b.id, Eigen::Vector3d(en.x(), en.y(), 0.0), b.floor});
  }
  for (const Posi& p : posi) {
    TruthSample s;
    s.t_s = p.t_s;
    const Eigen::Vector2d en = plane.EastNorth(p.lat_deg, p.lon_deg);
    s.position_m = Eigen::Vector3d(en.x(), en.y(), 0.0);
    s.floor = p.floor;
    walk->truth.push_back(s);
  }
}

// The floor of the beacon whose reading is the walk's strongest (nullopt: none heard, or the
// beacons have no floors).
std::optional<int> StrongestBeaconFloor(const Walk& walk) {
  std::optional<int> floor;
  double best = -std::numeric_limits<double>::infinity();
  for (const RssSample& r : walk.rss) {
    const int a = walk.AnchorIndex(r.anchor_id);
    if (a < 0 || !walk.anchors[a].floor || !(r.rss > best)) continue;
    best = r.rss;
    floor = walk.anchors[a].floor;
  }
  return floor;
}

// The access points heard at least `min_readings` times become anchors of unknown position
// (group wifi), their readings join the BLE ones in time order (a scan's after the BLE readings
// of the same time); the others are dropped, counted. Their floor is not known either: on a
// walk whose beacons have floors they are given the start's with --known-start (the first
// landmark's, which IPIN's scoring trials give with the start), else the floor of the beacon
// heard strongest (not the truth's: it is not an input then), else 0 — guesses that a
// multi-floor walk can get wrong (the step graph keeps such an anchor planar unless the walk
// has a floor loss: walk-format.md, Floors).
void AddWifi(IpinLog* log, int min_readings, bool known_start, Walk* walk) {
  std::optional<int> floor;
  const bool floors = std::any_of(walk->anchors.begin(), walk->anchors.end(),
                                  [](const Anchor& a) { return a.floor.has_value(); });
  if (floors) {
    floor = known_start && !log->posi.empty() ? log->posi.front().floor
                                              : StrongestBeaconFloor(*walk).value_or(0);
  }
  std::map<int, int> count;
  for (const RssSample& r : log->wifi) ++count[r.anchor_id];
  int kept = 0, few = 0, few_readings = 0;
  for (const auto& [id, n] : count) {
    if (n < min_readings) {
      ++few;
      few_readings += n;
      continue;
    }
    Anchor a;
    a.id = id;
    const double nan = std::numeric_limits<double>::quiet_NaN();
    a.position_m = Eigen::Vector3d(nan, nan, 0.0);  // x, y unknown; z unknown too: floor 0's
    a.position_known = false;
    a.group = "wifi";
    a.floor = floor;
    walk->anchors.push_back(a);
    ++kept;
  }
  std::vector<RssSample> merged;
  merged.reserve(walk->rss.size() + log->wifi.size());
  std::merge(walk->rss.begin(), walk->rss.end(), log->wifi.begin(), log->wifi.end(),
             std::back_inserter(merged),
             [](const RssSample& a, const RssSample& b) { return a.t_s < b.t_s; });
  merged.erase(std::remove_if(merged.begin(), merged.end(),
                              [&](const RssSample& r) {
                                return r.anchor_id >= kIpinWifiAnchorIdBase &&
                                       count[r.anchor_id] < min_readings;
                              }),
               merged.end());
  walk->rss = std::move(merged);
  auto& x = walk->meta.extra;
  x["convert.wifi_access_points"] = kept;
  x["convert.wifi_access_points_too_few_readings"] = few;
  x["convert.wifi_readings_of_those_dropped"] = few_readings;
  x["convert.wifi_duplicates_dropped"] = log->wifi_duplicates;
  x["convert.wifi_id_collisions_dropped"] = static_cast<double>(log->wifi_id_collisions.size());
}

}  // namespace

StatusOr<Walk> ConvertIpin(const std::string& log_path, const std::string& ble_locations_csv,
                           const ConvertOptions& options, std::vector<std::string>* warnings) {
  if (options.ipin_wifi_min_readings < 1) {
    return InvalidArgument(
        "ipin: the minimum number of WiFi readings per access point must be >= 1");
  }
  internal::DroppedReadings dropped(options.strict);
  std::string locations = ble_locations_csv;
  if (locations.empty()) {
    locations = (fs::path(log_path).parent_path() / "BLE_Locations.csv").string();
  }
  WG_ASSIGN_OR_RETURN(const std::vector<Beacon> beacons, ReadBleLocations(locations));
  std::map<int, const Beacon*> beacon_by_id;
  for (const Beacon& b : beacons) beacon_by_id[b.id] = &b;
  WG_ASSIGN_OR_RETURN(IpinLog log,
                      ReadIpinLog(log_path, beacon_by_id, locations, options.ipin_wifi, &dropped));
  WG_RETURN_IF_ERROR(CheckBeaconsNearTheWalk(beacons, locations, log_path, log.posi.front().lat_deg,
                                             log.posi.front().lon_deg));
  Walk walk;
  DescribeAndPlace(log_path, beacons, log.posi, &walk);
  WG_RETURN_IF_ERROR(BuildImu(log, log_path, &walk));
  walk.meta.extra["convert.ble_duplicates_dropped"] = log.rss_duplicates;
  walk.meta.extra["convert.ble_non_ibeacon_skipped"] = log.non_ibeacon;
  walk.rss = std::move(log.rss);
  if (options.ipin_wifi) {
    AddWifi(&log, options.ipin_wifi_min_readings, options.known_start, &walk);
  }
  walk.pressure = std::move(log.pressure);
  walk.meta.extra["convert.pres_repeated_timestamps_dropped"] = log.pressure_repeats;
  if (options.known_start) WG_RETURN_IF_ERROR(ApplyKnownStart(options, log_path, &walk));
  dropped.Report(&walk.meta, warnings);
  // A slice of a log may hold no BLE reading: then the walk declares no radio.
  if (walk.rss.empty()) walk.meta.radio.kind = RadioKind::kNone;
  return walk;
}

}  // namespace walkgraph
