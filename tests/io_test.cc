// Walk format readers and writers: the malformed-input corpus, atomic writes, round trips.
#include <cmath>
#include <filesystem>
#include <fstream>
#include <string>

#include <sys/stat.h>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "walkgraph/angle.h"
#include "walkgraph/io.h"

namespace walkgraph {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;

const std::string kData = WALKGRAPH_TEST_DATA_DIR;

fs::path TempDir(const std::string& name) {
  fs::path p =
      fs::temp_directory_path() / ("walkgraph_io_test_" + name + "_" + std::to_string(::getpid()));
  fs::remove_all(p);
  return p;
}

TEST(ReadWalk, AcceptsTheValidFixture) {
  auto walk = ReadWalk(kData + "/walks/valid_small");
  ASSERT_TRUE(walk.ok()) << walk.status().message();
  EXPECT_EQ(walk->meta.name, "valid_small");
  EXPECT_EQ(walk->meta.imu_placement, ImuPlacement::kWaist);
  EXPECT_EQ(walk->meta.radio.kind, RadioKind::kRss);
  EXPECT_DOUBLE_EQ(walk->meta.radio.path_loss.eta, 2.5);
  ASSERT_EQ(walk->anchors.size(), 3u);
  EXPECT_EQ(walk->anchors[1].id, 2);
  EXPECT_DOUBLE_EQ(walk->anchors[1].position_m.x(), 10.0);
  EXPECT_EQ(walk->imu.size(), 4u);
  EXPECT_FALSE(walk->imu[0].has_mag);
  EXPECT_DOUBLE_EQ(walk->imu[1].acc_mps2.z(), 9.70);
  EXPECT_EQ(walk->rss.size(), 4u);
  EXPECT_EQ(walk->odometry.size(), 4u);
  EXPECT_EQ(walk->truth.size(), 5u);
  ASSERT_EQ(walk->waypoints.size(), 2u);
  EXPECT_EQ(walk->waypoints[1].t_s, 1.5);
  EXPECT_EQ(walk->waypoints[1].position_m, Eigen::Vector2d(2.1, 0.05));
  EXPECT_EQ(walk->waypoints[1].sigma_m, 0.5);
  ASSERT_TRUE(walk->meta.initial_pose.has_value());
  EXPECT_NEAR(walk->TruthDistance(), 2.8, 1e-12);
}

// What is not a regular file where a walk file should be is an error at once: a FIFO would
// block the reader, a link loop or a dangling link would look like a missing stream.
TEST(ReadWalk, RefusesSpecialFilesWhereAWalkFileShouldBe) {
  const fs::path dir = TempDir("special");
  fs::copy(kData + "/walks/valid_small", dir);
  fs::remove(dir / "rss.csv");
  ASSERT_EQ(::mkfifo((dir / "rss.csv").c_str(), 0600), 0);
  EXPECT_THAT(ReadWalk(dir.string()).status().message(), HasSubstr("rss.csv: is a FIFO"));
  fs::remove(dir / "rss.csv");
  fs::create_symlink("loop_b", dir / "rss.csv");
  fs::create_symlink("rss.csv", dir / "loop_b");
  EXPECT_THAT(ReadWalk(dir.string()).status().message(), HasSubstr("symbolic link loop"));
  fs::remove(dir / "rss.csv");
  fs::create_symlink("gone.csv", dir / "rss.csv");
  EXPECT_THAT(ReadWalk(dir.string()).status().message(), HasSubstr("symbolic link to nothing"));
  fs::remove(dir / "rss.csv");
  fs::create_directory(dir / "rss.csv");
  EXPECT_THAT(ReadWalk(dir.string()).status().message(), HasSubstr("rss.csv: is a folder"));
  fs::remove_all(dir);
}

// A file without line ends is refused after 1 MiB, and a message quotes at most 120 bytes.
TEST(ReadWalk, LongLinesAndFieldsGiveShortMessages) {
  const fs::path dir = TempDir("long");
  fs::copy(kData + "/walks/valid_small", dir);
  std::ofstream(dir / "imu.csv") << "t_s,ax,ay,az,gx,gy,gz\n" << std::string(3 << 20, '\0');
  auto walk = ReadWalk(dir.string());
  EXPECT_THAT(walk.status().message(), HasSubstr("imu.csv:2: line longer than 1 MiB"));
  std::ofstream(dir / "imu.csv") << "t_s,ax,ay,az,gx,gy,gz\n"
                                 << std::string(100000, '7') << "x,0,0,9.8,0,0,0\n";
  walk = ReadWalk(dir.string());
  EXPECT_THAT(walk.status().message(), HasSubstr("... (100001 bytes)"));
  EXPECT_LT(walk.status().message().size(), 200u);
  // A subnormal value is a finite number.
  std::ofstream(dir / "imu.csv") << "t_s,ax,ay,az,gx,gy,gz\n0,1e-320,0,9.8,0,0,0\n";
  EXPECT_TRUE(ReadWalk(dir.string()).ok());
  fs::remove_all(dir);
}

TEST(ReadWalk, AcceptsCrlfAndBom) {
  auto walk = ReadWalk(kData + "/accepted/crlf_and_bom");
  ASSERT_TRUE(walk.ok()) << walk.status().message();
  auto ref = ReadWalk(kData + "/walks/valid_small");
  ASSERT_TRUE(ref.ok());
  ASSERT_EQ(walk->imu.size(), ref->imu.size());
  EXPECT_EQ(walk->imu.back().gyro_radps, ref->imu.back().gyro_radps);
  EXPECT_EQ(walk->anchors.size(), ref->anchors.size());
}

struct MalformedCase {
  const char* name;
  const char* file_and_line;  // what the message must point at
  const char* expected;       // and what it must say was expected or wrong
};

// Every case in tests/data/malformed is listed here; CorpusIsFullyListed checks that.
const MalformedCase kCases[] = {
    {"missing_column", "imu.csv:3:", "expected 7 comma-separated columns, found 6"},
    {"extra_column", "rss.csv:2:", "expected 3 comma-separated columns, found 4"},
    {"non_numeric", "truth.csv:3:", "column 'x_m': expected a finite decimal number, found 'abc'"},
    {"nan_value", "imu.csv:2:", "column 'ax': expected a finite decimal number, found 'nan'"},
    {"inf_value", "rss.csv:3:", "expected a finite decimal number, found 'inf'"},
    {"empty_file", "odometry.csv:1:", "empty file"},
    {"header_only", "truth.csv:2:", "no samples"},
    {"time_backwards", "imu.csv:5:", "goes backwards"},
    {"time_repeats", "odometry.csv:3:", "repeats the previous one"},
    {"rss_repeat_same_anchor", "rss.csv:4:", "repeats for anchor 1"},
    {"unknown_anchor", "rss.csv:4:", "unknown anchor_id 9"},
    {"fractional_anchor_id", "rss.csv:4:", "anchor_id must be an integer"},
    {"duplicate_anchor", "anchors.csv:3:", "duplicate anchor id 1"},
    {"absurd_acceleration", "imu.csv:4:", "acceleration component over 300"},
    {"absurd_gyro", "imu.csv:5:", "angular rate component over 50"},
    {"rss_out_of_range", "rss.csv:5:", "outside [-150"},
    {"negative_range", "odometry.csv:5:", "dist_m -0.7"},
    {"wrong_header", "imu.csv:1:", "expected 't_s,ax,ay,az,gx,gy,gz'"},
    {"bad_yaml", "walk.yaml:", ""},
    {"unknown_yaml_key", "walk.yaml (line 5)", "unknown option 'colour'"},
    {"bad_enum", "walk.yaml (line 5)", "option 'imu_placement' must be one of"},
    {"truth_missing", "walk.yaml", "truth.csv is missing"},
    {"walk_yaml_missing", "walk.yaml", "missing"},
    {"blank_line_inside", "imu.csv:4:", "empty line inside the data"},
    {"no_measurements", "no_measurements", "no measurements"},
    {"bad_eta", "walk.yaml: radio", "must be > 0"},
    // Found by fuzz_readers: a mapping used as a key made yaml-cpp throw through the reader.
    {"complex_yaml_key", "walk.yaml: radio (line 15)", "option names must be plain words"},
    // Issue 16: silently accepted before.
    {"hex_anchor_id", "rss.csv:3:", "column 'anchor_id': expected a finite decimal number"},
    {"hex_float_time", "imu.csv:3:", "found '0x1p-6'"},
    {"nanosecond_time", "truth.csv:2:", "it looks like nanoseconds (1.7e+09 s)"},
    {"radio_none_with_rss", "walk.yaml", "radio.kind is 'none' but rss.csv is present"},
    {"imu_none_with_imu", "walk.yaml", "imu_placement is 'none' but imu.csv is present"},
    {"header_only_stance", "stance_truth.csv:2:", "no samples"},
    {"duplicate_yaml_key", "walk.yaml:3:", "duplicate key 'name'"},
    {"second_yaml_document", "walk.yaml:19:", "a second YAML document"},
    {"invalid_utf8_name", "walk.yaml", "is not valid UTF-8"},
    {"waypoint_bad_sigma", "waypoints.csv:3:", "sigma_m 0 outside [0.001, 1000] m"},
    {"waypoint_time_backwards", "waypoints.csv:4:", "goes backwards"},
};

TEST(ReadWalk, RejectsEveryMalformedCaseWithFileLineAndExpectation) {
  for (const MalformedCase& c : kCases) {
    SCOPED_TRACE(c.name);
    auto walk = ReadWalk(kData + "/malformed/" + c.name);
    ASSERT_FALSE(walk.ok());
    EXPECT_EQ(walk.status().code(), c.name == std::string("walk_yaml_missing")
                                        ? StatusCode::kNotFound
                                        : StatusCode::kInvalidArgument);
    EXPECT_THAT(walk.status().message(), HasSubstr(c.file_and_line));
    EXPECT_THAT(walk.status().message(), HasSubstr(c.expected));
  }
}

TEST(ReadWalk, CorpusIsFullyListed) {
  size_t n = 0;
  for (const auto& entry : fs::directory_iterator(kData + "/malformed")) {
    const std::string name = entry.path().filename().string();
    bool listed = false;
    for (const MalformedCase& c : kCases) listed |= name == c.name;
    EXPECT_TRUE(listed) << name << " has no expectation in kCases";
    ++n;
  }
  EXPECT_EQ(n, std::size(kCases));
}

TEST(ReadWalk, MissingDirectoryIsNotFound) {
  auto walk = ReadWalk(kData + "/does_not_exist");
  ASSERT_FALSE(walk.ok());
  EXPECT_EQ(walk.status().code(), StatusCode::kNotFound);
}

TEST(WriteWalk, RoundTripsExactly) {
  auto walk = ReadWalk(kData + "/walks/valid_small");
  ASSERT_TRUE(walk.ok());
  walk->meta.extra["sim.seed"] = 7;
  walk->imu[2].acc_mps2.x() = 0.1 + 1e-13;  // needs full precision to survive
  const fs::path out = TempDir("roundtrip");
  ASSERT_TRUE(WriteWalk(*walk, out.string()).ok());
  auto back = ReadWalk(out.string());
  ASSERT_TRUE(back.ok()) << back.status().message();
  EXPECT_EQ(back->imu[2].acc_mps2, walk->imu[2].acc_mps2);
  EXPECT_EQ(back->rss.size(), walk->rss.size());
  EXPECT_EQ(back->meta.extra.at("sim.seed"), 7.0);
  EXPECT_EQ(back->truth.back().position_m, walk->truth.back().position_m);
  EXPECT_DOUBLE_EQ(back->meta.initial_pose->x_m, walk->meta.initial_pose->x_m);
  ASSERT_EQ(back->waypoints.size(), walk->waypoints.size());
  for (size_t i = 0; i < walk->waypoints.size(); ++i) {
    EXPECT_EQ(back->waypoints[i].t_s, walk->waypoints[i].t_s);
    EXPECT_EQ(back->waypoints[i].position_m, walk->waypoints[i].position_m);
    EXPECT_EQ(back->waypoints[i].sigma_m, walk->waypoints[i].sigma_m);
  }
  // ValidateWalk holds a waypoint built in code to the reader's rule.
  Walk bad = *walk;
  bad.waypoints[1].sigma_m = -1.0;
  const Status refused = ValidateWalk(bad);
  ASSERT_FALSE(refused.ok());
  EXPECT_THAT(refused.message(), HasSubstr("waypoints[1]"));
  EXPECT_THAT(refused.message(), HasSubstr("sigma_m"));
  // Writing again over the same directory gives identical bytes.
  std::ifstream a(out / "imu.csv");
  const std::string first((std::istreambuf_iterator<char>(a)), {});
  ASSERT_TRUE(WriteWalk(*back, out.string()).ok());
  std::ifstream b(out / "imu.csv");
  const std::string second((std::istreambuf_iterator<char>(b)), {});
  EXPECT_EQ(first, second);
  fs::remove_all(out);
}

// A start of known position and unknown heading (IPIN's scoring trials): heading_rad left out.
TEST(WriteWalk, PositionOnlyStartRoundTrips) {
  auto walk = ReadWalk(kData + "/walks/valid_small");
  ASSERT_TRUE(walk.ok());
  walk->meta.initial_pose->heading_known = false;
  walk->meta.initial_pose->heading_rad = 0.0;
  walk->meta.initial_pose->sigma_heading_rad = kUnknownHeadingSigmaRad;
  walk->meta.initial_pose->x_m = 1.5;
  const fs::path out = TempDir("position_only");
  ASSERT_TRUE(WriteWalk(*walk, out.string()).ok());
  std::ifstream y(out / "walk.yaml");
  const std::string yaml((std::istreambuf_iterator<char>(y)), {});
  EXPECT_EQ(yaml.find("heading_rad"), std::string::npos) << yaml;
  auto back = ReadWalk(out.string());
  ASSERT_TRUE(back.ok()) << back.status().message();
  ASSERT_TRUE(back->meta.initial_pose.has_value());
  EXPECT_FALSE(back->meta.initial_pose->heading_known);
  EXPECT_EQ(back->meta.initial_pose->x_m, 1.5);
  EXPECT_NEAR(back->meta.initial_pose->sigma_heading_rad, kPi / std::sqrt(3.0), 1e-15);
  // A heading σ without a heading is refused, naming the file.
  {
    std::string bad = yaml;
    bad.replace(bad.find("sigma_xy_m"), 0, "sigma_heading_rad: 0.1\n  ");
    std::ofstream(out / "walk.yaml") << bad;
  }
  auto refused = ReadWalk(out.string());
  ASSERT_FALSE(refused.ok());
  EXPECT_NE(refused.status().message().find("walk.yaml"), std::string::npos);
  EXPECT_NE(refused.status().message().find("sigma_heading_rad without heading_rad"),
            std::string::npos)
      << refused.status().message();
  fs::remove_all(out);
}

// Issue 22: floors of anchors, truth and start, the storey height, the barometer, the floor
// loss: written, read back equal; each reader refuses a bad value naming file and line.
TEST(WriteWalk, FloorsAndPressureRoundTrip) {
  auto walk = ReadWalk(kData + "/walks/valid_small");
  ASSERT_TRUE(walk.ok());
  for (size_t i = 0; i < walk->anchors.size(); ++i) walk->anchors[i].floor = -2 + int(i % 3);
  for (size_t i = 0; i < walk->truth.size(); ++i) walk->truth[i].floor = i % 2 ? -1 : 0;
  walk->meta.initial_pose->floor = 0;
  walk->meta.storey_height_m = 4.5;
  walk->meta.radio.path_loss.floor_loss_db = 7.25;
  walk->pressure = {{0.0, 1013.25}, {0.1, 1013.2}, {0.25, 1012.9}};
  const fs::path out = TempDir("floors");
  ASSERT_TRUE(WriteWalk(*walk, out.string()).ok());
  auto back = ReadWalk(out.string());
  ASSERT_TRUE(back.ok()) << back.status().message();
  for (size_t i = 0; i < walk->anchors.size(); ++i) {
    EXPECT_EQ(back->anchors[i].floor, walk->anchors[i].floor);
  }
  for (size_t i = 0; i < walk->truth.size(); ++i) {
    EXPECT_EQ(back->truth[i].floor, walk->truth[i].floor);
  }
  EXPECT_EQ(back->meta.initial_pose->floor, std::optional<int>(0));
  EXPECT_EQ(back->meta.storey_height_m, 4.5);
  EXPECT_EQ(back->meta.radio.path_loss.floor_loss_db, 7.25);
  ASSERT_EQ(back->pressure.size(), 3u);
  EXPECT_EQ(back->pressure[2].hpa, 1012.9);
  EXPECT_EQ(back->StartFloor(), 0);
  EXPECT_TRUE(back->has_truth_floors());
  EXPECT_EQ(back->AnchorHeightM(back->anchors[0]), -2 * 4.5 + back->anchors[0].position_m.z());
  auto refused = [&](const char* file, const std::string& text, const char* where,
                     const char* what) {
    ASSERT_TRUE(WriteWalk(*walk, out.string()).ok());
    std::ofstream(out / file) << text;
    auto r = ReadWalk(out.string());
    ASSERT_FALSE(r.ok()) << file;
    EXPECT_THAT(r.status().message(), HasSubstr(where));
    EXPECT_THAT(r.status().message(), HasSubstr(what));
  };
  refused("pressure.csv", "t_s,hpa\n0,1013\n1,13.2\n", "pressure.csv:3:", "hectopascal");
  refused("pressure.csv", "t_s,hpa\n1,1013\n0.5,1013\n", "pressure.csv:3:", "goes backwards");
  refused("truth.csv", "t_s,x_m,y_m,floor\n0,0,0,0\n1,0,0,0.5\n",
          "truth.csv:3:", "not an integer level");
  refused("truth.csv", "t_s,x_m,y_m,storey\n0,0,0,0\n", "truth.csv:1:", "t_s,x_m,y_m,z_m,floor");
  // In code: a floor on some anchors only is refused.
  Walk mixed = *walk;
  mixed.anchors[1].floor.reset();
  EXPECT_THAT(ValidateWalk(mixed).message(), HasSubstr("anchors[1]"));
  fs::remove_all(out);
}

// IPIN's submission: 2 Hz from t = 0 to the walk's end, "0,0,0" before the estimate, WGS84 at
// 12 decimals; the origin maps back to itself and 100 m north to +0.000899° latitude.
TEST(IpinSubmission, TwoHertzFromZeroBackToWgs84) {
  Walk w;
  w.meta.name = "sub";
  w.meta.extra["ipin.origin_lat_deg"] = 49.460948188642;
  w.meta.extra["ipin.origin_lon_deg"] = 11.110539036217;
  w.pressure = {{0.0, 980.0}, {3.2, 980.0}};  // the walk ends at 3.2 s
  w.truth = {{1.0, Eigen::Vector3d::Zero(), false, -2}};
  Trajectory t;
  TrajectoryPoint a, b;
  a.t_s = 1.0;
  b.t_s = 2.0;
  b.position_m = Eigen::Vector3d(0.0, 100.0, 0.0);
  b.floor = 0;
  t.points = {a, b};
  std::ostringstream out;
  ASSERT_TRUE(FormatIpinSubmission(w, t, out).ok());
  std::vector<std::string> lines;
  std::istringstream in(out.str());
  for (std::string l; std::getline(in, l);) lines.push_back(l);
  ASSERT_EQ(lines.size(), 7u);  // t = 0, 0.5, ..., 3.0
  EXPECT_EQ(lines[0], "0,0,0");
  EXPECT_EQ(lines[1], "0,0,0");
  EXPECT_EQ(lines[2], "11.110539036217,49.460948188642,-2");  // t = 1: the origin, start floor
  double lon = 0, lat = 0;
  int floor = 9;
  ASSERT_EQ(std::sscanf(lines[4].c_str(), "%lf,%lf,%d", &lon, &lat, &floor), 3);  // t = 2
  // 111219.6 m per degree of latitude at 49.46° (WGS84 meridian arc).
  EXPECT_NEAR(lat - 49.460948188642, 100.0 / 111219.6, 3e-7);
  EXPECT_NEAR(lon, 11.110539036217, 1e-9);
  EXPECT_EQ(floor, 0);
  EXPECT_EQ(lines[6], lines[4]);  // held after the estimate ends
  Walk no_origin = w;
  no_origin.meta.extra.clear();
  std::ostringstream ignored;
  EXPECT_FALSE(FormatIpinSubmission(no_origin, t, ignored).ok());
}

TEST(WriteWalk, InvalidWalkWritesNothing) {
  auto walk = ReadWalk(kData + "/walks/valid_small");
  ASSERT_TRUE(walk.ok());
  walk->rss[1].anchor_id = 42;
  const fs::path out = TempDir("invalid");
  const Status s = WriteWalk(*walk, out.string());
  EXPECT_FALSE(s.ok());
  EXPECT_THAT(s.message(), HasSubstr("unknown anchor_id"));
  EXPECT_FALSE(fs::exists(out));
}

TEST(Tum, RoundTripsPositionAndHeading) {
  Trajectory t;
  for (int i = 0; i < 5; ++i) {
    TrajectoryPoint p;
    p.t_s = i * 0.5;
    p.position_m = Eigen::Vector3d(i, -i, 0.25);
    p.heading_rad = -3.0 + 1.4 * i;
    t.points.push_back(p);
  }
  const fs::path dir = TempDir("tum");
  fs::create_directories(dir);
  const std::string path = (dir / "t.tum").string();
  ASSERT_TRUE(WriteTumTrajectory(t, path).ok());
  auto back = ReadTumTrajectory(path);
  ASSERT_TRUE(back.ok()) << back.status().message();
  ASSERT_EQ(back->size(), t.size());
  for (size_t i = 0; i < t.size(); ++i) {
    EXPECT_NEAR(back->points[i].heading_rad, t.points[i].heading_rad, 1e-9);
    EXPECT_EQ(back->points[i].position_m, t.points[i].position_m);
  }
  fs::remove_all(dir);
}

}  // namespace
}  // namespace walkgraph
