#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <set>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "walkgraph/convert.h"
#include "walkgraph/io.h"

namespace walkgraph {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;

const fs::path kTracks = fs::path(WALKGRAPH_SHARED_DATASETS) / "ble_tracks";

std::vector<fs::path> Tracks() {
  std::vector<fs::path> t;
  for (const auto& e : fs::directory_iterator(kTracks / "trk")) {
    if (e.path().extension() == ".mbd") t.push_back(e.path());
  }
  std::sort(t.begin(), t.end());
  return t;
}

fs::path Scratch(const std::string& name) {
  const fs::path p = fs::temp_directory_path() / ("wg_blet_" + name + std::to_string(::getpid()));
  fs::remove_all(p);
  fs::create_directories(p / "trk");
  fs::create_directories(p / "cnf");
  return p;
}

// Lines and distinct timestamps of a track, counted without the converter.
std::pair<int, int> CountLines(const fs::path& track) {
  std::ifstream in(track);
  std::string line;
  int n = 0;
  std::set<std::string> times;
  while (std::getline(in, line)) {
    ++n;
    times.insert(line.substr(0, line.find(',')));
  }
  return {n, static_cast<int>(times.size())};
}

TEST(ConvertBleTracks, ConvertsEveryTrack) {
  if (!fs::exists(kTracks)) GTEST_SKIP() << kTracks << " not present";
  const auto tracks = Tracks();
  ASSERT_EQ(tracks.size(), 6u);
  for (const fs::path& track : tracks) {
    SCOPED_TRACE(track.string());
    const auto [lines, times] = CountLines(track);
    auto walk = Convert("bletracks", {track.string()});
    ASSERT_TRUE(walk.ok()) << walk.status().message();
    EXPECT_TRUE(ValidateWalk(*walk).ok());
    ASSERT_EQ(walk->anchors.size(), 12u);
    EXPECT_EQ(walk->anchors.front().id, 10);
    EXPECT_EQ(walk->anchors.front().position_m, Eigen::Vector3d(7.00, 7.09, 1.22));
    EXPECT_EQ(walk->anchors.back().id, 42);
    EXPECT_EQ(walk->anchors.back().position_m, Eigen::Vector3d(12.76, 0.27, 2.30));
    EXPECT_FALSE(walk->has_imu());
    EXPECT_EQ(walk->meta.truth_kind, TruthKind::kContinuous);
    EXPECT_EQ(static_cast<int>(walk->rss.size()) +
                  static_cast<int>(walk->meta.extra.at("convert.rss_duplicates_dropped")),
              lines);
    EXPECT_EQ(static_cast<int>(walk->truth.size()), times);
    // The camera keeps the beacon inside the 20.7 m × 17.6 m area.
    for (const TruthSample& s : walk->truth) {
      EXPECT_GT(s.position_m.x(), -1.0);
      EXPECT_LT(s.position_m.x(), 21.0);
      EXPECT_GT(s.position_m.y(), -1.0);
      EXPECT_LT(s.position_m.y(), 19.0);
    }
  }
}

TEST(ConvertBleTracks, ConvertsSlicesOfEveryTrack) {
  if (!fs::exists(kTracks)) GTEST_SKIP() << kTracks << " not present";
  const fs::path dir = Scratch("slice");
  fs::copy_file(kTracks / "cnf" / "tetam.dev", dir / "cnf" / "tetam.dev");
  for (const fs::path& track : Tracks()) {
    SCOPED_TRACE(track.string());
    std::ifstream in(track);
    std::ofstream out(dir / "trk" / track.filename());
    std::string line;
    for (int i = 0; i < 120 && std::getline(in, line); ++i) out << line << "\n";
    out.close();
    auto walk = Convert("bletracks", {(dir / "trk" / track.filename()).string()});
    ASSERT_TRUE(walk.ok()) << walk.status().message();
    EXPECT_TRUE(ValidateWalk(*walk).ok());
    EXPECT_EQ(walk->rss.size(), 120u);
    EXPECT_EQ(walk->truth.front().t_s, 0.0);
  }
  fs::remove_all(dir);
}

// The bundled walk datasets/ble_straight04 is this converter's output on the shared track.
TEST(ConvertBleTracks, BundledWalkMatchesConversion) {
  const fs::path track = kTracks / "trk" / "straight_04_all_sensors.mbd";
  if (!fs::exists(track)) GTEST_SKIP() << track << " not present";
  auto walk = Convert("bletracks", {track.string()});
  ASSERT_TRUE(walk.ok()) << walk.status().message();
  auto bundled = ReadWalk(std::string(WALKGRAPH_SOURCE_DIR) + "/datasets/ble_straight04");
  ASSERT_TRUE(bundled.ok()) << bundled.status().message();
  ASSERT_EQ(bundled->rss.size(), walk->rss.size());
  ASSERT_EQ(bundled->truth.size(), walk->truth.size());
  for (size_t i = 0; i < walk->rss.size(); ++i) {
    EXPECT_NEAR(bundled->rss[i].t_s, walk->rss[i].t_s, 1e-9);
    EXPECT_EQ(bundled->rss[i].anchor_id, walk->rss[i].anchor_id);
    EXPECT_EQ(bundled->rss[i].rss, walk->rss[i].rss);
  }
  for (size_t i = 0; i < walk->truth.size(); ++i) {
    EXPECT_NEAR((bundled->truth[i].position_m - walk->truth[i].position_m).norm(), 0.0, 1e-9);
  }
}

class ConvertBleTracksMalformed : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = Scratch("bad");
    std::ofstream(dir_ / "cnf" / "tetam.dev")
        << "Dongles:{\"b827eb4521b4\": [[7.00, 7.09, 1.22], 1, \"sensor10\"], "
           "\"000000000101\": [[7.18, 0.68, 2.30], 2, \"sensor11\"]}\n"
           "Beacons:{\"e78f135624ce\": [[], 1328790, \"beacon1\"] }\n";
  }
  void TearDown() override { fs::remove_all(dir_); }
  StatusOr<Walk> ConvertText(const std::string& body) {
    std::ofstream(dir_ / "trk" / "t.mbd")
        << "100.0,b827eb4521b4,e78f135624ce,-80,1,2,1.8,1,0,0,0,1,0,0,0,1\n"
        << body;
    return Convert("bletracks", {(dir_ / "trk" / "t.mbd").string()});
  }
  fs::path dir_;
};

TEST_F(ConvertBleTracksMalformed, ValidTrackConverts) {
  auto walk = ConvertText("100.5,000000000101,e78f135624ce,-70,2,2,1.8,1,0,0,0,1,0,0,0,1\n");
  ASSERT_TRUE(walk.ok()) << walk.status().message();
  ASSERT_EQ(walk->rss.size(), 2u);
  EXPECT_EQ(walk->rss[1].anchor_id, 11);
  EXPECT_DOUBLE_EQ(walk->rss[1].t_s, 0.5);
  EXPECT_EQ(walk->truth[1].position_m, Eigen::Vector3d(2, 2, 1.8));
}

TEST_F(ConvertBleTracksMalformed, ReorderedAndRepeatedLinesAreCounted) {
  auto walk = ConvertText(
      "100.5,000000000101,e78f135624ce,-70,2,2,1.8,1,0,0,0,1,0,0,0,1\n"
      "100.4,b827eb4521b4,e78f135624ce,-71,2,2,1.8,1,0,0,0,1,0,0,0,1\n"
      "100.5,000000000101,e78f135624ce,-72,2,2,1.8,1,0,0,0,1,0,0,0,1\n");
  ASSERT_TRUE(walk.ok()) << walk.status().message();
  EXPECT_EQ(walk->rss.size(), 3u);
  EXPECT_EQ(walk->meta.extra.at("convert.lines_out_of_order"), 1.0);
  EXPECT_EQ(walk->meta.extra.at("convert.rss_duplicates_dropped"), 1.0);
  EXPECT_TRUE(ValidateWalk(*walk).ok());
}

// A corrupted reading in a public track (+42 dBm) is dropped and counted, its position kept;
// --strict refuses the track, naming the line.
TEST_F(ConvertBleTracksMalformed, ImpossibleReadingsAreDroppedCountedAndNamed) {
  const std::string body =
      "100.5,000000000101,e78f135624ce,42,2,2,1.8,1,0,0,0,1,0,0,0,1\n"
      "100.6,b827eb4521b4,e78f135624ce,-70,2.1,2,1.8,1,0,0,0,1,0,0,0,1\n";
  std::ofstream(dir_ / "trk" / "t.mbd")
      << "100.0,b827eb4521b4,e78f135624ce,-80,1,2,1.8,1,0,0,0,1,0,0,0,1\n"
      << body;
  std::vector<std::string> warnings;
  auto walk = Convert("bletracks", {(dir_ / "trk" / "t.mbd").string()}, {}, &warnings);
  ASSERT_TRUE(walk.ok()) << walk.status().message();
  EXPECT_EQ(walk->rss.size(), 2u);
  EXPECT_EQ(walk->truth.size(), 3u);  // the line's position is still the truth
  EXPECT_EQ(walk->meta.extra.at("convert.rss_invalid_dropped"), 1.0);
  ASSERT_EQ(warnings.size(), 1u);
  EXPECT_THAT(warnings[0], HasSubstr("t.mbd:2: rss 42 outside [-150, 30] dBm; dropped"));
  EXPECT_TRUE(ValidateWalk(*walk).ok());
  ConvertOptions strict;
  strict.strict = true;
  auto refused = Convert("bletracks", {(dir_ / "trk" / "t.mbd").string()}, strict);
  ASSERT_FALSE(refused.ok());
  EXPECT_THAT(refused.status().message(), HasSubstr("t.mbd:2: rss 42 outside"));
}

// Two columns swapped show over the whole track: an RSS column of positive numbers (RSS and x
// swapped), positions far outside the receivers' room (a coordinate holding an RSS). One BLE
// reading >= 0 dBm among negative ones is dropped and counted instead.
TEST_F(ConvertBleTracksMalformed, SwappedColumnsAreRefusedNamingFileLineAndLayout) {
  std::ofstream(dir_ / "trk" / "t.mbd")
      << "100.0,b827eb4521b4,e78f135624ce,1,-80,2,1.8,1,0,0,0,1,0,0,0,1\n"
         "100.5,000000000101,e78f135624ce,2,-70,2,1.8,1,0,0,0,1,0,0,0,1\n";
  auto walk = Convert("bletracks", {(dir_ / "trk" / "t.mbd").string()});
  ASSERT_FALSE(walk.ok());
  EXPECT_THAT(walk.status().message(),
              HasSubstr("t.mbd:1: field 4 (RSS) is 1, not a negative BLE RSSI in dBm, in 2 of 2 "
                        "lines (the first here)"));
  EXPECT_THAT(walk.status().message(), HasSubstr("two columns swapped? the lines are time, "
                                                 "receiver MAC, beacon MAC, RSS (dBm), x, y"));
  walk = ConvertText(
      "100.5,000000000101,e78f135624ce,-70,-75,2,1.8,1,0,0,0,1,0,0,0,1\n"
      "100.6,000000000101,e78f135624ce,-70,-76,2,1.8,1,0,0,0,1,0,0,0,1\n");
  ASSERT_FALSE(walk.ok());
  EXPECT_THAT(walk.status().message(),
              HasSubstr("t.mbd:2: fields 5-6 (x, y) is (-75, 2), not a position within 30 m of "
                        "the receivers in "));
  EXPECT_THAT(walk.status().message(), HasSubstr("in 2 of 3 lines"));
  walk = ConvertText(
      "100.5,000000000101,e78f135624ce,0,2,2,1.8,1,0,0,0,1,0,0,0,1\n"
      "100.6,000000000101,e78f135624ce,-70,2,2,1.8,1,0,0,0,1,0,0,0,1\n");
  ASSERT_TRUE(walk.ok()) << walk.status().message();
  EXPECT_EQ(walk->meta.extra.at("convert.rss_invalid_dropped"), 1.0);
  EXPECT_EQ(walk->rss.size(), 2u);
}

TEST_F(ConvertBleTracksMalformed, BadFieldNamesFileAndLine) {
  auto walk = ConvertText("100.5,000000000101,e78f135624ce,loud,2,2,1.8,1,0,0,0,1,0,0,0,1\n");
  ASSERT_FALSE(walk.ok());
  EXPECT_THAT(walk.status().message(), HasSubstr("t.mbd:2: field 4 'loud'"));
  walk = ConvertText("100.5,000000000101,e78f135624ce,-70,2,2\n");
  ASSERT_FALSE(walk.ok());
  EXPECT_THAT(walk.status().message(), HasSubstr("t.mbd:2: expected 16 fields, found 6"));
}

TEST_F(ConvertBleTracksMalformed, UnknownDevices) {
  auto walk = ConvertText("100.5,0000000009ff,e78f135624ce,-70,2,2,1.8,1,0,0,0,1,0,0,0,1\n");
  ASSERT_FALSE(walk.ok());
  EXPECT_THAT(walk.status().message(), HasSubstr("t.mbd:2: receiver MAC '0000000009ff'"));
  walk = ConvertText("100.5,000000000101,aaaaaaaaaaaa,-70,2,2,1.8,1,0,0,0,1,0,0,0,1\n");
  ASSERT_FALSE(walk.ok());
  EXPECT_THAT(walk.status().message(), HasSubstr("t.mbd:2: beacon MAC 'aaaaaaaaaaaa'"));
}

TEST_F(ConvertBleTracksMalformed, BadDevicesFile) {
  std::ofstream(dir_ / "cnf" / "tetam.dev") << "Dongles:{\"b827eb4521b4\": [[7.00, 7.09], 1, "
                                               "\"sensor10\"]}\nBeacons:{\"e\": [[], 1, \"b\"]}\n";
  auto walk = ConvertText("");
  ASSERT_FALSE(walk.ok());
  EXPECT_THAT(walk.status().message(), HasSubstr("tetam.dev:1: b827eb4521b4: position"));
  std::ofstream(dir_ / "cnf" / "tetam.dev") << "Sensors:{}\n";
  walk = ConvertText("");
  ASSERT_FALSE(walk.ok());
  EXPECT_THAT(walk.status().message(), HasSubstr("tetam.dev:1: expected 'Dongles"));
}

}  // namespace
}  // namespace walkgraph
