#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "walkgraph/convert.h"
#include "walkgraph/io.h"

namespace walkgraph {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;

const fs::path kIpin = fs::path(WALKGRAPH_SHARED_DATASETS) / "ipin2023_t3";

std::vector<fs::path> Logs() {
  std::vector<fs::path> logs;
  for (const auto& e : fs::directory_iterator(kIpin)) {
    const std::string name = e.path().filename().string();
    if (name.rfind("IPIN", 0) == 0 && e.path().extension() == ".txt") logs.push_back(e.path());
  }
  std::sort(logs.begin(), logs.end());
  return logs;
}

fs::path Scratch(const std::string& name) {
  const fs::path p = fs::temp_directory_path() / ("wg_ipin_" + name + std::to_string(::getpid()));
  fs::remove_all(p);
  fs::create_directories(p);
  return p;
}

// Counts of the record types in a log (or its lines with AppTimestamp in [t0, t1]), read
// independently of the converter.
struct Counts {
  int acce = 0, posi = 0, ble = 0;
  std::vector<std::pair<double, double>> posi_lat_lon;
};

Counts Count(const fs::path& log, double t0 = -1.0, double t1 = 1e9,
             const fs::path& slice_out = {}) {
  std::ifstream in(log);
  std::ofstream out;
  if (!slice_out.empty()) out.open(slice_out);
  Counts c;
  std::string line;
  while (std::getline(in, line)) {
    if (line.empty() || line[0] == '%') {
      if (out.is_open()) out << line << "\n";
      continue;
    }
    const double t = std::stod(line.substr(5, line.find(';', 5) - 5));
    if (t < t0 || t > t1) continue;
    if (out.is_open()) out << line << "\n";
    const std::string type = line.substr(0, 4);
    if (type == "ACCE") ++c.acce;
    if (type == "BLE4") ++c.ble;
    if (type == "POSI") {
      ++c.posi;
      std::stringstream s(line);
      std::string f[7];
      for (auto& x : f) std::getline(s, x, ';');
      c.posi_lat_lon.push_back({std::stod(f[3]), std::stod(f[4])});
    }
  }
  return c;
}

// East/north by the equirectangular approximation (an independent check of the tangent plane:
// the two agree to millimetres over the 60 m of the venue).
Eigen::Vector2d Equirectangular(double lat, double lon, double lat0, double lon0) {
  constexpr double kDeg = 3.14159265358979323846 / 180.0;
  const double r_n = 6378137.0 * (1 - 0.00669438) /
                     std::pow(1 - 0.00669438 * std::sin(lat0 * kDeg) * std::sin(lat0 * kDeg), 1.5);
  const double r_e =
      6378137.0 / std::sqrt(1 - 0.00669438 * std::sin(lat0 * kDeg) * std::sin(lat0 * kDeg));
  return {(lon - lon0) * kDeg * r_e * std::cos(lat0 * kDeg), (lat - lat0) * kDeg * r_n};
}

TEST(ConvertIpin, ConvertsEveryLogCompletely) {
  if (!fs::exists(kIpin)) GTEST_SKIP() << kIpin << " not present";
  const auto logs = Logs();
  ASSERT_FALSE(logs.empty());
  for (const fs::path& log : logs) {
    SCOPED_TRACE(log.string());
    const Counts c = Count(log);
    auto walk = Convert("ipin", {log.string()});
    ASSERT_TRUE(walk.ok()) << walk.status().message();
    EXPECT_TRUE(ValidateWalk(*walk).ok());
    EXPECT_EQ(walk->anchors.size(), 6u);
    EXPECT_EQ(walk->meta.truth_kind, TruthKind::kCheckpoints);
    EXPECT_EQ(walk->meta.imu_placement, ImuPlacement::kHandheld);
    ASSERT_EQ(walk->truth.size(), static_cast<size_t>(c.posi));
    EXPECT_EQ(walk->rss.size(), static_cast<size_t>(c.ble));
    // A few ACCE lines at the ends fall outside the GYRO/MAGN span.
    EXPECT_GE(walk->imu.size() + 3, static_cast<size_t>(c.acce));
    EXPECT_LE(walk->imu.size(), static_cast<size_t>(c.acce));
    ASSERT_TRUE(walk->imu.front().has_mag);
    // ~50 Hz accelerometer time base.
    const double rate = (walk->imu.size() - 1) / (walk->imu.back().t_s - walk->imu.front().t_s);
    EXPECT_NEAR(rate, 50.0, 1.0);
    const auto& o = c.posi_lat_lon.front();
    for (size_t k = 0; k < walk->truth.size(); ++k) {
      const Eigen::Vector2d en =
          Equirectangular(c.posi_lat_lon[k].first, c.posi_lat_lon[k].second, o.first, o.second);
      EXPECT_NEAR(walk->truth[k].position_m.x(), en.x(), 0.01);
      EXPECT_NEAR(walk->truth[k].position_m.y(), en.y(), 0.01);
      EXPECT_TRUE(walk->truth[k].floor.has_value());
    }
    ASSERT_GE(walk->AnchorIndex(3), 0);
    EXPECT_EQ(walk->anchors[walk->AnchorIndex(3)].floor, std::optional<int>(-2));
    EXPECT_EQ(walk->anchors[walk->AnchorIndex(1)].floor, std::optional<int>(0));
    // ~10 Hz barometer over the walk.
    ASSERT_GE(walk->pressure.size(), 100u);
    EXPECT_NEAR(walk->pressure.front().hpa, 980.0, 30.0);
  }
}

TEST(ConvertIpin, ConvertsSlicesOfEveryLog) {
  if (!fs::exists(kIpin)) GTEST_SKIP() << kIpin << " not present";
  const fs::path dir = Scratch("slice");
  fs::copy_file(kIpin / "BLE_Locations.csv", dir / "BLE_Locations.csv");
  for (const fs::path& log : Logs()) {
    SCOPED_TRACE(log.string());
    const fs::path slice = dir / log.filename();
    const Counts c = Count(log, 60.0, 90.0, slice);
    ASSERT_GT(c.posi, 0);
    auto walk = Convert("ipin", {slice.string()});
    ASSERT_TRUE(walk.ok()) << walk.status().message();
    EXPECT_TRUE(ValidateWalk(*walk).ok());
    EXPECT_EQ(walk->truth.size(), static_cast<size_t>(c.posi));
    EXPECT_EQ(walk->rss.size(), static_cast<size_t>(c.ble));
    EXPECT_NEAR(static_cast<double>(walk->imu.size()), c.acce, 3.0);
    EXPECT_EQ(walk->truth.front().position_m.head<2>().norm(), 0.0);  // origin: 1st landmark
    const Status s = WriteWalk(*walk, (dir / "walk").string());
    EXPECT_TRUE(s.ok()) << s.message();
    auto back = ReadWalk((dir / "walk").string());
    ASSERT_TRUE(back.ok()) << back.status().message();
    EXPECT_EQ(back->imu.size(), walk->imu.size());
    fs::remove_all(dir / "walk");
  }
  fs::remove_all(dir);
}

// --known-start: the walk begins at the first POSI landmark with its position as a
// position-only initial_pose; what came before is dropped and counted.
TEST(ConvertIpin, KnownStartBeginsAtTheFirstLandmark) {
  if (!fs::exists(kIpin)) GTEST_SKIP() << kIpin << " not present";
  const fs::path dir = Scratch("known");
  fs::copy_file(kIpin / "BLE_Locations.csv", dir / "BLE_Locations.csv");
  const fs::path log = kIpin / "IPIN2023_T3_TrainingTrial01_repetition01.txt";
  const fs::path slice = dir / log.filename();
  Count(log, 40.0, 90.0, slice);  // the first landmark at 61.4 s, phone handling before it
  auto whole = Convert("ipin", {slice.string()});
  ConvertOptions o;
  o.known_start = true;
  o.known_start_sigma_m = 0.7;
  auto known = Convert("ipin", {slice.string()}, o);
  ASSERT_TRUE(whole.ok()) << whole.status().message();
  ASSERT_TRUE(known.ok()) << known.status().message();
  EXPECT_TRUE(ValidateWalk(*known).ok());
  EXPECT_FALSE(whole->meta.initial_pose.has_value());
  ASSERT_TRUE(known->meta.initial_pose.has_value());
  const InitialPose& p = *known->meta.initial_pose;
  EXPECT_FALSE(p.heading_known);
  EXPECT_EQ(p.x_m, known->truth.front().position_m.x());
  EXPECT_EQ(p.y_m, known->truth.front().position_m.y());
  EXPECT_EQ(p.sigma_xy_m, 0.7);
  const double t0 = known->truth.front().t_s;
  EXPECT_GE(known->imu.front().t_s, t0);
  EXPECT_GE(known->rss.front().t_s, t0);
  const double dropped_imu = known->meta.extra.at("convert.imu_samples_before_start_dropped");
  const double dropped_ble = known->meta.extra.at("convert.ble_before_start_dropped");
  EXPECT_GT(dropped_imu, 500);  // ≈ 21 s at 50 Hz
  EXPECT_EQ(known->imu.size() + dropped_imu, whole->imu.size());
  EXPECT_EQ(known->rss.size() + dropped_ble, whole->rss.size());
  EXPECT_EQ(known->truth.size(), whole->truth.size());
  // The option belongs to ipin only.
  auto plaza = Convert("plaza", {dir.string()}, o);
  ASSERT_FALSE(plaza.ok());
  EXPECT_THAT(plaza.status().message(), HasSubstr("ipin logs only"));
  fs::remove_all(dir);
}

// The Minor → BLE mapping, checked on the data: in TrainingTrial21 (level −2) the first
// landmark is 2 m from BLE3, and the beacon heard loudest around it is Minor 2.
TEST(ConvertIpin, MinorTwoIsTheBeaconAtBle3) {
  const fs::path log = kIpin / "IPIN2023_T3_TrainingTrial21_repetition01.txt";
  if (!fs::exists(log)) GTEST_SKIP() << log << " not present";
  auto walk = Convert("ipin", {log.string()});
  ASSERT_TRUE(walk.ok()) << walk.status().message();
  const TruthSample& lm = walk->truth.front();
  const Anchor& ble3 = walk->anchors[walk->AnchorIndex(3)];
  EXPECT_LT((ble3.position_m - lm.position_m).head<2>().norm(), 3.0);
  double best = -1e9;
  int best_id = -1;
  for (const RssSample& s : walk->rss) {
    if (std::fabs(s.t_s - lm.t_s) <= 2.0 && s.rss > best) {
      best = s.rss;
      best_id = s.anchor_id;
    }
  }
  EXPECT_EQ(best_id, 3);
  EXPECT_GT(best, -75.0);
  EXPECT_EQ(IpinMinorToBleId(2), 3);
  EXPECT_EQ(IpinMinorToBleId(3), 2);
  EXPECT_EQ(IpinMinorToBleId(1), 1);
  EXPECT_EQ(IpinMinorToBleId(7), -1);
}

class ConvertIpinMalformed : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = Scratch("bad");
    std::ofstream(dir_ / "BLE_Locations.csv")
        << "bleID,Lat,Lon,floor\n\"BLE1\",49.46129,11.11120,00\n\"BLE2\",49.46107,11.11121,00\n"
           "\"BLE3\",49.46129,11.11152,-2\n";
  }
  void TearDown() override { fs::remove_all(dir_); }
  StatusOr<Walk> ConvertText(const std::string& body) {
    std::ofstream(dir_ / "log.txt")
        << "% header\n"
        << "ACCE;0.01;100.00;0.1;0.2;9.8;3\nGYRO;0.01;100.00;0.0;0.0;0.1;3\n"
        << "MAGN;0.01;100.00;10;20;30;3\n"
        << "ACCE;0.03;100.02;0.1;0.2;9.8;3\nGYRO;0.03;100.02;0.0;0.0;0.1;3\n"
        << "MAGN;0.03;100.02;10;20;30;3\n"
        << "POSI;0.5;1;49.46128;11.11110;0;100\n"
        << body;
    return Convert("ipin", {(dir_ / "log.txt").string()});
  }
  fs::path dir_;
};

TEST_F(ConvertIpinMalformed, MinimalLogConverts) {
  auto walk = ConvertText("BLE4;0.6;iBeacon;BE:AC:20:23:00:02;-70;0;1;2;UUID\n");
  ASSERT_TRUE(walk.ok()) << walk.status().message();
  EXPECT_EQ(walk->imu.size(), 2u);
  ASSERT_EQ(walk->rss.size(), 1u);
  EXPECT_EQ(walk->rss[0].anchor_id, 3);
}

TEST_F(ConvertIpinMalformed, BadNumberNamesFileLineAndField) {
  auto walk = ConvertText("ACCE;0.05;100.04;0.1;oops;9.8;3\n");
  ASSERT_FALSE(walk.ok());
  EXPECT_THAT(walk.status().message(), HasSubstr("log.txt:9: field 5 'oops'"));
}

TEST_F(ConvertIpinMalformed, WrongFieldCount) {
  auto walk = ConvertText("GYRO;0.05;100.04;0.1;9.8;3\n");
  ASSERT_FALSE(walk.ok());
  EXPECT_THAT(walk.status().message(), HasSubstr("log.txt:9: expected 7 fields, found 6"));
}

TEST_F(ConvertIpinMalformed, GarbageLine) {
  auto walk = ConvertText("hello world\n");
  ASSERT_FALSE(walk.ok());
  EXPECT_THAT(walk.status().message(), HasSubstr("log.txt:9: expected a '%' comment"));
}

TEST_F(ConvertIpinMalformed, UnknownMinorAndMismatchedMac) {
  auto walk = ConvertText("BLE4;0.6;iBeacon;BE:AC:20:23:00:05;-70;0;1;5;UUID\n");
  ASSERT_FALSE(walk.ok());  // BLE5 is not in this BLE_Locations.csv
  EXPECT_THAT(walk.status().message(), HasSubstr("log.txt:9: iBeacon Minor 5"));
  walk = ConvertText("BLE4;0.6;iBeacon;BE:AC:20:23:00:01;-70;0;1;2;UUID\n");
  ASSERT_FALSE(walk.ok());
  EXPECT_THAT(walk.status().message(), HasSubstr("log.txt:9: MAC 'BE:AC:20:23:00:01'"));
}

TEST_F(ConvertIpinMalformed, TimeGoingBackwards) {
  auto walk = ConvertText("ACCE;0.05;100.01;0.1;0.2;9.8;3\n");
  ASSERT_FALSE(walk.ok());
  EXPECT_THAT(walk.status().message(), HasSubstr("log.txt:9: ACCE SensorTimestamp"));
  walk = ConvertText("POSI;0.4;2;49.46128;11.11110;0;100\n");
  ASSERT_FALSE(walk.ok());
  EXPECT_THAT(walk.status().message(), HasSubstr("log.txt:9: POSI timestamp"));
}

TEST_F(ConvertIpinMalformed, BadLocationsFile) {
  std::ofstream(dir_ / "BLE_Locations.csv") << "bleID,Lat,Lon,floor\n\"BLE1\",49.4,north,0\n";
  auto walk = ConvertText("");
  ASSERT_FALSE(walk.ok());
  EXPECT_THAT(walk.status().message(), HasSubstr("BLE_Locations.csv:2: field 3 'north'"));
  std::ofstream(dir_ / "BLE_Locations.csv") << "bleID,Lat,Lon,floor\n\"Beacon\",49.4,11.1,0\n";
  walk = ConvertText("");
  ASSERT_FALSE(walk.ok());
  EXPECT_THAT(walk.status().message(), HasSubstr("BLE_Locations.csv:2: bleID"));
}

// RSS swapped with TxPower (0) in the BLE4 lines, Lat and Lon swapped in BLE_Locations.csv:
// refused, naming the file, the line and what was expected. One 0 dBm reading (iOS's unknown)
// among real ones is dropped and counted.
TEST_F(ConvertIpinMalformed, SwappedColumnsAreRefusedNamingFileAndLine) {
  auto walk = ConvertText(
      "BLE4;0.6;iBeacon;BE:AC:20:23:00:02;0;-70;1;2;UUID\n"
      "BLE4;0.7;iBeacon;BE:AC:20:23:00:02;0;-71;1;2;UUID\n");
  ASSERT_FALSE(walk.ok());
  EXPECT_THAT(walk.status().message(),
              HasSubstr("log.txt:9: field 5 (RSS) of the BLE4 lines is 0, not a negative BLE "
                        "RSSI in dBm, in 2 of 2 lines"));
  EXPECT_THAT(walk.status().message(), HasSubstr("BLE4;AppTimestamp;iBeacon;MAC;RSS;TxPower"));
  walk = ConvertText(
      "BLE4;0.6;iBeacon;BE:AC:20:23:00:02;0;-70;1;2;UUID\n"
      "BLE4;0.7;iBeacon;BE:AC:20:23:00:02;-71;0;1;2;UUID\n"
      "BLE4;0.8;iBeacon;BE:AC:20:23:00:02;-72;0;1;2;UUID\n");
  ASSERT_TRUE(walk.ok()) << walk.status().message();
  EXPECT_EQ(walk->rss.size(), 2u);
  EXPECT_EQ(walk->meta.extra.at("convert.rss_invalid_dropped"), 1.0);

  std::ofstream(dir_ / "BLE_Locations.csv")
      << "bleID,Lat,Lon,floor\n\"BLE1\",49.46129,11.11120,00\n\"BLE2\",11.11121,49.46107,00\n";
  walk = ConvertText("");
  ASSERT_FALSE(walk.ok());
  EXPECT_THAT(walk.status().message(),
              HasSubstr("BLE_Locations.csv:3: BLE2 at Lat 11.1112, Lon 49.4611 is "));
  EXPECT_THAT(walk.status().message(),
              HasSubstr("expected every beacon within 1000 m of the walk (Lat and Lon swapped"));
}

TEST_F(ConvertIpinMalformed, NoGroundTruth) {
  std::ofstream(dir_ / "log.txt") << "ACCE;0.01;100.00;0.1;0.2;9.8;3\n";
  auto walk = Convert("ipin", {(dir_ / "log.txt").string()});
  ASSERT_FALSE(walk.ok());
  EXPECT_THAT(walk.status().message(), HasSubstr("no POSI"));
}

// Issue 44: `convert ipin --wifi` (ConvertOptions::ipin_wifi): each access point an anchor of
// unknown position, group wifi, id kIpinWifiAnchorIdBase + the BSSID's last three bytes; the
// readings of one scan (one SensorTimeStamp) at one time; an access point heard fewer than
// ipin_wifi_min_readings times dropped and counted; without the option WIFI lines are skipped.
TEST_F(ConvertIpinMalformed, WifiAccessPointsAreAnchorsOfUnknownPosition) {
  const std::string body =
      "BLE4;0.6;iBeacon;BE:AC:20:23:00:02;-70;0;1;2;UUID\n"
      "WIFI;0.61;65094.18;SSID1;20:23:00:00:00:01;2437;-60\n"
      "WIFI;0.62;65094.18;SSID2;20:23:00:00:00:15;2452;-63\n"  // same scan: t 0.61
      "WIFI;0.90;65095.18;SSID1;20:23:00:00:00:01;2437;-61\n"
      "WIFI;0.90;65095.18;OTHER;AA:BB:CC:00:00:01;2437;-80\n";  // same last 3 bytes as SSID1
  auto plain = ConvertText(body);
  ASSERT_TRUE(plain.ok()) << plain.status().message();
  EXPECT_EQ(plain->anchors.size(), 3u);
  EXPECT_EQ(plain->rss.size(), 1u);
  ConvertOptions o;
  o.ipin_wifi = true;
  o.ipin_wifi_min_readings = 2;
  auto walk = Convert("ipin", {(dir_ / "log.txt").string()}, o);
  ASSERT_TRUE(walk.ok()) << walk.status().message();
  const int ap1 = kIpinWifiAnchorIdBase + 0x000001, ap2 = kIpinWifiAnchorIdBase + 0x000015;
  ASSERT_GE(walk->AnchorIndex(ap1), 0);
  EXPECT_LT(walk->AnchorIndex(ap2), 0);  // one reading: below the minimum
  const Anchor& a = walk->anchors[static_cast<size_t>(walk->AnchorIndex(ap1))];
  EXPECT_FALSE(a.position_known);
  EXPECT_EQ(a.group, "wifi");
  EXPECT_FALSE(std::isfinite(a.position_m.x()));
  std::vector<std::pair<double, int>> rss;
  for (const RssSample& r : walk->rss) rss.emplace_back(r.t_s, r.anchor_id);
  const std::vector<std::pair<double, int>> expected = {{0.6, 3}, {0.61, ap1}, {0.90, ap1}};
  EXPECT_EQ(rss, expected);
  EXPECT_EQ(walk->meta.extra.at("convert.wifi_access_points"), 1.0);
  EXPECT_EQ(walk->meta.extra.at("convert.wifi_access_points_too_few_readings"), 1.0);
  EXPECT_EQ(walk->meta.extra.at("convert.wifi_id_collisions_dropped"), 1.0);
  // The scan's second line took the scan's time: with min 1, SSID2 is read at 0.61.
  o.ipin_wifi_min_readings = 1;
  walk = Convert("ipin", {(dir_ / "log.txt").string()}, o);
  ASSERT_TRUE(walk.ok());
  ASSERT_GE(walk->AnchorIndex(ap2), 0);
  for (const RssSample& r : walk->rss) {
    if (r.anchor_id == ap2) EXPECT_EQ(r.t_s, 0.61);
  }
}

TEST_F(ConvertIpinMalformed, WifiBadBssidNamesFileAndLine) {
  ConvertText("WIFI;0.61;65094.18;SSID1;20:23:00:00:01;2437;-60\n");
  ConvertOptions o;
  o.ipin_wifi = true;
  auto walk = Convert("ipin", {(dir_ / "log.txt").string()}, o);
  ASSERT_FALSE(walk.ok());
  EXPECT_THAT(walk.status().message(), HasSubstr("log.txt:9: MAC_BSSID '20:23:00:00:01'"));
  o.ipin_wifi_min_readings = 0;
  EXPECT_FALSE(Convert("ipin", {(dir_ / "log.txt").string()}, o).ok());
}

// The shared trials with --wifi: every access point heard >= 10 times is an anchor of unknown
// position; the BLE readings and beacons are as without it.
TEST(ConvertIpin, WifiOfTheSharedTrials) {
  if (!fs::exists(kIpin)) GTEST_SKIP() << kIpin << " not present";
  ConvertOptions o;
  o.ipin_wifi = true;
  for (const fs::path& log : Logs()) {
    SCOPED_TRACE(log.string());
    auto ble = Convert("ipin", {log.string()});
    auto walk = Convert("ipin", {log.string()}, o);
    ASSERT_TRUE(ble.ok() && walk.ok()) << walk.status().message();
    EXPECT_TRUE(ValidateWalk(*walk).ok()) << ValidateWalk(*walk).message();
    size_t wifi_anchors = 0, wifi_readings = 0;
    for (const Anchor& a : walk->anchors) {
      if (a.group != "wifi") continue;
      ++wifi_anchors;
      EXPECT_FALSE(a.position_known);
    }
    for (const RssSample& r : walk->rss) wifi_readings += r.anchor_id >= kIpinWifiAnchorIdBase;
    EXPECT_EQ(walk->anchors.size(), ble->anchors.size() + wifi_anchors);
    EXPECT_EQ(walk->rss.size(), ble->rss.size() + wifi_readings);
    EXPECT_GE(wifi_anchors, 10u);
    EXPECT_GE(wifi_readings, 10 * wifi_anchors);
    EXPECT_TRUE(
        std::is_sorted(walk->rss.begin(), walk->rss.end(),
                       [](const RssSample& a, const RssSample& b) { return a.t_s < b.t_s; }));
    std::printf("%s: %zu access points, %zu readings\n", log.filename().c_str(), wifi_anchors,
                wifi_readings);
    // Their floor, a guess: without --known-start not the truth's (not an input then) but the
    // floor of the beacon heard strongest; with it, the start's.
    const RssSample* strongest = nullptr;
    for (const RssSample& r : ble->rss) {
      if (strongest == nullptr || r.rss > strongest->rss) strongest = &r;
    }
    ASSERT_NE(strongest, nullptr);
    const std::optional<int> beacon_floor =
        ble->anchors[static_cast<size_t>(ble->AnchorIndex(strongest->anchor_id))].floor;
    ConvertOptions known = o;
    known.known_start = true;
    auto started = Convert("ipin", {log.string()}, known);
    ASSERT_TRUE(started.ok()) << started.status().message();
    for (const Anchor& a : walk->anchors) {
      if (a.group == "wifi") EXPECT_EQ(a.floor, beacon_floor);
    }
    for (const Anchor& a : started->anchors) {
      if (a.group == "wifi") EXPECT_EQ(a.floor, started->meta.initial_pose->floor);
    }
  }
}

}  // namespace
}  // namespace walkgraph
