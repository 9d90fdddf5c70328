// Position-annotated BLE RSSI tracks converter (see ConvertBleTracks in walkgraph/convert.h).
//
// Receiver ids: tetam.dev names each receiver "sensorRK" (R = room quadrant 1..4, K = 0..2);
// the anchor id is the number RK, so the 12 receivers are anchors 10, 11, 12, 20, ..., 42:
//   10 b827eb4521b4  11 000000000101  12 000000000102   20 b827eb917e19  21 000000000201
//   22 000000000202  30 b827ebf7d096  31 000000000301   32 000000000302  40 b827ebfd7811
//   41 000000000401  42 000000000402
// (K = 0 are the Raspberry Pi receivers at 1.22 m, K = 1, 2 the dongles at 2.30 m.)
// The merged track files are "merged respecting the time order" but a few lines step back by
// less than a millisecond: they are sorted stably by time and counted in
// meta.extra "convert.lines_out_of_order"; a repeated (time, receiver) reading keeps the first
// ("convert.rss_duplicates_dropped"), and truth keeps one sample per distinct time.
#include <algorithm>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>

#include <nlohmann/json.hpp>

#include "convert/line_fields.h"
#include "io/plausibility.h"
#include "util/input_file.h"
#include "util/text.h"
#include "walkgraph/convert.h"

namespace walkgraph {

namespace fs = std::filesystem;

namespace {

struct Devices {
  std::map<std::string, Anchor> receivers;  // by lower-case MAC without separators
  std::set<std::string> beacons;
};

std::string NormalizeMac(std::string mac) {
  mac.erase(std::remove(mac.begin(), mac.end(), ':'), mac.end());
  std::transform(mac.begin(), mac.end(), mac.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return mac;
}

StatusOr<Devices> ReadDevices(const std::string& path) {
  internal::LineReader in(path);
  WG_RETURN_IF_ERROR(in.Open());
  Devices d;
  std::string line;
  int n = 0;
  bool saw_dongles = false;
  std::set<int> ids;
  while (true) {
    WG_ASSIGN_OR_RETURN(const bool more, in.Next(&line));
    if (!more) break;
    ++n;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    if (line.empty()) continue;
    const std::string where = path + ":" + std::to_string(n) + ": ";
    const size_t colon = line.find(':');
    const std::string key = colon == std::string::npos ? "" : line.substr(0, colon);
    if (key != "Dongles" && key != "Beacons") {
      return InvalidArgument(where + "expected 'Dongles:{...}' or 'Beacons:{...}'");
    }
    const nlohmann::json j = nlohmann::json::parse(line.substr(colon + 1), nullptr, false);
    if (j.is_discarded() || !j.is_object()) {
      return InvalidArgument(where + "expected a dictionary {MAC: [position, colour, alias]}");
    }
    for (const auto& [mac, dev] : j.items()) {
      if (!dev.is_array() || dev.size() != 3 || !dev[0].is_array() || !dev[2].is_string()) {
        return InvalidArgument(where + mac + ": expected [[x, y, z], colour, alias]");
      }
      if (key == "Beacons") {
        d.beacons.insert(NormalizeMac(mac));
        continue;
      }
      saw_dongles = true;
      const std::string alias = dev[2].get<std::string>();
      if (alias.rfind("sensor", 0) != 0 || alias.size() == 6 ||
          alias.find_first_not_of("0123456789", 6) != std::string::npos || alias.size() > 12) {
        return InvalidArgument(where + mac + ": alias '" + alias + "'; expected sensor<number>");
      }
      if (dev[0].size() != 3 || !dev[0][0].is_number() || !dev[0][1].is_number() ||
          !dev[0][2].is_number()) {
        return InvalidArgument(where + mac + ": position must be [x, y, z] in metres");
      }
      Anchor a;
      a.id = std::stoi(alias.substr(6));
      a.position_m = Eigen::Vector3d(dev[0][0].get<double>(), dev[0][1].get<double>(),
                                     dev[0][2].get<double>());
      if (!ids.insert(a.id).second) return InvalidArgument(where + "duplicate alias " + alias);
      d.receivers[NormalizeMac(mac)] = a;
    }
  }
  if (!saw_dongles || d.receivers.empty()) return InvalidArgument(path + ": no Dongles line");
  if (d.beacons.empty()) return InvalidArgument(path + ": no Beacons line");
  return d;
}

constexpr char kTrackLayout[] =
    "time, receiver MAC, beacon MAC, RSS (dBm), x, y, z (m), then 9 numbers";

// The walker's positions lie in the receivers' room: a position more than kMaxOutsideM outside
// the receivers' bounding box (x-y) in more than half of the lines is a swapped column (an RSS
// of -80 read as x), or a devices file of another room.
template <typename Line>
Status CheckPositions(const std::string& track, const std::string& dev_path, const Devices& d,
                      const std::vector<Line>& lines) {
  constexpr double kMaxOutsideM = 30.0;
  Eigen::Vector2d lo = d.receivers.begin()->second.position_m.head<2>(), hi = lo;
  for (const auto& [mac, a] : d.receivers) {
    lo = lo.cwiseMin(a.position_m.template head<2>());
    hi = hi.cwiseMax(a.position_m.template head<2>());
  }
  internal::ColumnCheck column(
      "fields 5-6 (x, y)", "a position within " + internal::Num(kMaxOutsideM) +
                               " m of the receivers in " + dev_path + " (x " +
                               internal::Num(lo.x()) + " to " + internal::Num(hi.x()) + " m, y " +
                               internal::Num(lo.y()) + " to " + internal::Num(hi.y()) + " m)");
  for (const Line& l : lines) {
    const Eigen::Vector2d p = l.position.template head<2>();
    const double outside = (p.cwiseMax(lo).cwiseMin(hi) - p).norm();
    column.Add(outside <= kMaxOutsideM, track + ":" + std::to_string(l.line) + ": ",
               "(" + internal::Num(p.x()) + ", " + internal::Num(p.y()) + ")");
  }
  return column.Check(kTrackLayout);
}

}  // namespace

StatusOr<Walk> ConvertBleTracks(const std::string& track_mbd, const std::string& devices_dev,
                                const ConvertOptions& options, std::vector<std::string>* warnings) {
  internal::DroppedReadings dropped(options.strict);
  std::string dev_path = devices_dev;
  if (dev_path.empty()) {
    dev_path = (fs::path(track_mbd).parent_path().parent_path() / "cnf" / "tetam.dev").string();
  }
  WG_ASSIGN_OR_RETURN(const Devices devices, ReadDevices(dev_path));

  internal::LineReader in(track_mbd);
  WG_RETURN_IF_ERROR(in.Open());
  struct Line {
    double t_unix;
    int anchor_id;
    double rss;
    bool rss_ok;  // false: a physically impossible reading, dropped (the position stays)
    Eigen::Vector3d position;
    int line;
  };
  // Two columns swapped (RSS and a coordinate, say) show over the whole file: an RSS column
  // mostly >= 0 dBm, positions mostly far outside the receivers' room.
  internal::ColumnCheck rss_column("field 4 (RSS)", "a negative BLE RSSI in dBm");
  std::vector<Line> lines;
  std::string text;
  int n = 0, out_of_order = 0;
  while (true) {
    WG_ASSIGN_OR_RETURN(const bool more, in.Next(&text));
    if (!more) break;
    ++n;
    internal::LineFields f(track_mbd, n, text, ',');
    if (f.size() == 1 && f.field(0).empty()) return f.Error("empty line");
    WG_RETURN_IF_ERROR(f.ExpectCount(16));
    Line l;
    WG_ASSIGN_OR_RETURN(l.t_unix, f.Number(0));
    auto it = devices.receivers.find(NormalizeMac(f.field(1)));
    if (it == devices.receivers.end()) {
      return f.Error("receiver MAC '" + f.field(1) + "' is not a Dongle in " + dev_path);
    }
    l.anchor_id = it->second.id;
    if (devices.beacons.count(NormalizeMac(f.field(2))) == 0) {
      return f.Error("beacon MAC '" + f.field(2) + "' is not a Beacon in " + dev_path);
    }
    WG_ASSIGN_OR_RETURN(l.rss, f.Number(3));
    std::string problem = internal::CheckRss({0.0, l.anchor_id, l.rss}, RssUnits::kDbm, {});
    if (problem.empty()) problem = internal::CheckBleRss(l.rss);
    rss_column.Add(l.rss < 0.0, f.Where(), internal::Num(l.rss));
    bool drop = false;
    WG_RETURN_IF_ERROR(dropped.Check("rss", f.Where(), problem, &drop));
    l.rss_ok = !drop;
    l.line = n;
    for (int k = 0; k < 3; ++k) {
      WG_ASSIGN_OR_RETURN(l.position[k], f.Number(4 + k));
    }
    for (size_t k = 7; k < 16; ++k) WG_RETURN_IF_ERROR(f.Number(k).status());
    if (!lines.empty() && l.t_unix < lines.back().t_unix) ++out_of_order;
    lines.push_back(l);
  }
  if (lines.empty()) return InvalidArgument(track_mbd + ": no readings");
  WG_RETURN_IF_ERROR(rss_column.Check(kTrackLayout));
  WG_RETURN_IF_ERROR(CheckPositions(track_mbd, dev_path, devices, lines));
  std::stable_sort(lines.begin(), lines.end(),
                   [](const Line& a, const Line& b) { return a.t_unix < b.t_unix; });

  Walk walk;
  walk.meta.name = internal::ToValidUtf8(fs::path(track_mbd).stem().string());
  walk.meta.source =
      "Danis, Naskali, Cemgil, Ersoy: An indoor localization dataset and data collection "
      "framework with high precision position annotation, Pervasive and Mobile Computing 81, "
      "2022 (philotuxo/Position-Annotated-BLE-RSSI-Dataset @77474b69), track " +
      fs::path(track_mbd).filename().string();
  walk.meta.licence = "CC0-1.0";
  walk.meta.imu_placement = ImuPlacement::kNone;
  walk.meta.truth_kind = TruthKind::kContinuous;
  walk.meta.radio.kind = RadioKind::kRss;
  walk.meta.radio.units = RssUnits::kDbm;
  for (const auto& [mac, a] : devices.receivers) walk.anchors.push_back(a);
  std::sort(walk.anchors.begin(), walk.anchors.end(),
            [](const Anchor& a, const Anchor& b) { return a.id < b.id; });

  const double t0 = lines.front().t_unix;
  walk.meta.extra["bletracks.t0_unix_s"] = t0;
  std::set<std::pair<double, int>> seen;
  int duplicates = 0;
  for (const Line& l : lines) {
    const double t = l.t_unix - t0;
    if (!l.rss_ok) {
      // dropped above, counted in DroppedReadings
    } else if (!seen.insert({t, l.anchor_id}).second) {
      ++duplicates;
    } else {
      walk.rss.push_back({t, l.anchor_id, l.rss});
    }
    if (walk.truth.empty() || t > walk.truth.back().t_s) {
      TruthSample s;
      s.t_s = t;
      s.position_m = l.position;
      s.has_z = true;
      walk.truth.push_back(s);
    }
  }
  walk.meta.extra["convert.lines_out_of_order"] = out_of_order;
  walk.meta.extra["convert.rss_duplicates_dropped"] = duplicates;
  dropped.Report(&walk.meta, warnings);
  return walk;
}

}  // namespace walkgraph
