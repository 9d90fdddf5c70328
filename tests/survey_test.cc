// Radio maps learnt from walks (issue 44 item 4): SurveyRadioMap, ApplyRadioMap and the map's
// file (io.h ReadAnchorsFile / FormatAnchorsCsv).
#include "walkgraph/survey.h"

#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <string>

#include <gtest/gtest.h>
#include <yaml-cpp/yaml.h>

#include "walkgraph/convert.h"
#include "walkgraph/estimator.h"
#include "walkgraph/io.h"
#include "walkgraph/metrics.h"
#include "walkgraph/simulate.h"

namespace walkgraph {
namespace {

namespace fs = std::filesystem;

// Every other anchor's position removed (anchors.csv x_m, y_m empty).
Walk HalfUnknown(Walk walk) {
  for (size_t i = 0; i < walk.anchors.size(); i += 2) {
    walk.anchors[i].position_known = false;
    walk.anchors[i].position_m.head<2>().setConstant(std::nan(""));
  }
  return walk;
}

// `walk` in a frame shifted by d: its anchors of known position, truth, waypoints and start.
Walk Shifted(Walk walk, const Eigen::Vector2d& d) {
  for (Anchor& a : walk.anchors) {
    if (a.position_known) a.position_m.head<2>() += d;
  }
  for (TruthSample& t : walk.truth) t.position_m.head<2>() += d;
  for (Waypoint& w : walk.waypoints) w.position_m += d;
  if (walk.meta.initial_pose) {
    walk.meta.initial_pose->x_m += d.x();
    walk.meta.initial_pose->y_m += d.y();
  }
  return walk;
}

TEST(SurveyOptionsTest, ValidateRefusesWhatCannotBeASigmaOrASpacing) {
  EXPECT_TRUE(SurveyOptions().Validate().ok());
  for (double s : {0.0, -1.0, 1001.0, std::nan("")}) {
    SurveyOptions o;
    o.checkpoint_sigma_m = s;
    EXPECT_FALSE(o.Validate().ok()) << s;
  }
  SurveyOptions o;
  o.checkpoint_spacing_s = -1.0;
  EXPECT_FALSE(o.Validate().ok());
  EXPECT_FALSE(SurveyRadioMap({}, SurveyOptions()).ok());  // no walk
}

TEST(ApplyRadioMapTest, PlacesOnlyUnsurveyedAnchorsAndKeepsTheSmallerSigma) {
  Walk walk;
  Anchor surveyed{1, Eigen::Vector3d(1, 2, 0)};
  Anchor unknown{2, Eigen::Vector3d(std::nan(""), std::nan(""), 0.5)};
  unknown.position_known = false;
  Anchor tight{3, Eigen::Vector3d(5, 5, 0)};
  tight.sigma_m = 0.2;
  Anchor loose{4, Eigen::Vector3d(6, 6, 0)};
  loose.sigma_m = 5.0;
  Anchor absent{5, Eigen::Vector3d(std::nan(""), std::nan(""), 0)};
  absent.position_known = false;
  walk.anchors = {surveyed, unknown, tight, loose, absent};
  std::vector<Anchor> map;
  for (int id : {1, 2, 3, 4}) {
    Anchor m{id, Eigen::Vector3d(10.0 * id, -10.0 * id, 9.0)};
    m.sigma_m = 1.0;
    map.push_back(m);
  }
  EXPECT_EQ(ApplyRadioMap(map, &walk).value(), 2);
  EXPECT_EQ(walk.anchors[0].position_m.x(), 1.0);  // surveyed: untouched
  EXPECT_TRUE(walk.anchors[1].position_known);
  EXPECT_EQ(walk.anchors[1].position_m, Eigen::Vector3d(20, -20, 0.5));  // its own height kept
  EXPECT_EQ(walk.anchors[1].sigma_m, 1.0);
  EXPECT_EQ(walk.anchors[2].position_m.x(), 5.0);   // its own σ 0.2 < the map's 1
  EXPECT_EQ(walk.anchors[3].position_m.x(), 40.0);  // σ 5 > 1: the map's
  EXPECT_EQ(walk.anchors[3].sigma_m, 1.0);
  EXPECT_FALSE(walk.anchors[4].position_known);  // not in the map
  EXPECT_TRUE(ValidateWalk(walk).ok());
}

TEST(RadioMapFile, RoundTripsThroughAnchorsCsvAndRefusesAnEmptyMap) {
  const fs::path dir =
      fs::temp_directory_path() / ("walkgraph_survey_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  Anchor a{7, Eigen::Vector3d(1.25, -3.5, 2)};
  a.sigma_m = 0.75;
  a.group = "wifi";
  Anchor b{8, Eigen::Vector3d(4, 5, 0)};
  std::ostringstream text;
  FormatAnchorsCsv({a, b}, text);
  std::ofstream(dir / "anchors.csv") << text.str();
  auto read = ReadAnchorsFile((dir / "anchors.csv").string());
  ASSERT_TRUE(read.ok()) << read.status().message();
  ASSERT_EQ(read->size(), 2u);
  EXPECT_EQ((*read)[0].position_m, a.position_m);
  EXPECT_EQ((*read)[0].sigma_m, 0.75);
  EXPECT_EQ((*read)[0].group, "wifi");
  EXPECT_TRUE((*read)[1].surveyed());
  // A map merged from walks with and without floors: no floor column (none dereferenced).
  Anchor with_floor = b;
  with_floor.floor = -2;
  std::ostringstream mixed;
  FormatAnchorsCsv({with_floor, a}, mixed);
  EXPECT_EQ(mixed.str().substr(0, mixed.str().find('\n')), "id,x_m,y_m,z_m,sigma_m,group");
  std::ofstream(dir / "empty.csv") << "id,x_m,y_m,z_m\n";
  auto empty = ReadAnchorsFile((dir / "empty.csv").string());
  ASSERT_FALSE(empty.ok());
  EXPECT_NE(empty.status().message().find("empty.csv"), std::string::npos);
  std::ofstream(dir / "bad.csv") << "id,x_m,y_m,z_m\n1,2,x,0\n";
  auto bad = ReadAnchorsFile((dir / "bad.csv").string());
  ASSERT_FALSE(bad.ok());
  EXPECT_NE(bad.status().message().find("bad.csv:2"), std::string::npos) << bad.status().message();
  fs::remove_all(dir);
}

// Two simulated circles (seeds 1, 2; one lap of r = 8 m among 9 anchors over 400 m²) with every
// other anchor unknown: the map places them, on average within 3 m of where the simulator put
// them (measured: 0.74 / 0.77 / 2.39 / 2.86 / 5.73 m, mean 2.50; the 5.73 m one 6.1σ off its
// map σ: one lap of RSS does not fix an anchor outside the circle, and its covariance says less
// than that), most of them from both walks; surveyed anchors pass through; a walk without truth
// is refused. A third walk (seed 3) with the map applied: fg-batch no worse than with those
// anchors unknown (+5 %; measured 0.345 m against 0.388 m).
TEST(SurveyRadioMapTest, PlacesTheUnknownAnchorsOfTwoSimulatedWalks) {
  std::vector<Walk> walks;
  for (int seed : {1, 2}) {
    auto w = SimulateScenario("tarrio-circle", seed, YAML::Load("{laps: 1}"));
    ASSERT_TRUE(w.ok());
    walks.push_back(HalfUnknown(*w));
  }
  const std::vector<Anchor> truth =
      SimulateScenario("tarrio-circle", 1, YAML::Load("{laps: 1}"))->anchors;
  auto map = SurveyRadioMap(walks, SurveyOptions());
  ASSERT_TRUE(map.ok()) << map.status().message();
  ASSERT_EQ(map->anchors.size(), truth.size());
  int placed = 0;
  double sum_err = 0.0;
  for (size_t i = 0; i < map->anchors.size(); ++i) {
    const Anchor& m = map->anchors[i];
    const Anchor& t = truth[i];
    ASSERT_EQ(m.id, t.id);
    const double err = (m.position_m.head<2>() - t.position_m.head<2>()).norm();
    if (walks[0].anchors[i].surveyed()) {
      EXPECT_EQ(err, 0.0);
      EXPECT_EQ(m.sigma_m, 0.0);
      continue;
    }
    ++placed;
    sum_err += err;
    std::printf("anchor %d: %.3f m from the simulator's, sigma %.3f m\n", m.id, err, m.sigma_m);
    EXPECT_LT(err, 10.0) << m.id;  // inside the walk's 20 m square
  }
  EXPECT_EQ(placed, static_cast<int>(map->details.size()));
  EXPECT_GE(placed, 4);
  EXPECT_LE(sum_err / placed, 3.0);
  int both = 0;
  for (const SurveyedAnchor& s : map->details) both += s.walks == 2 ? 1 : 0;
  EXPECT_GE(2 * both, placed);

  auto third = SimulateScenario("tarrio-circle", 3, YAML::Load("{laps: 1}"));
  ASSERT_TRUE(third.ok());
  const Walk unknown = HalfUnknown(*third);
  Walk mapped = unknown;
  EXPECT_EQ(ApplyRadioMap(map->anchors, &mapped).value(), placed);
  auto fg = EstimatorRegistry::Builtin().Create("fg-batch");
  ASSERT_TRUE(fg.ok());
  auto rmse = [&](const Walk& w) {
    auto r = (*fg)->Run(w);
    EXPECT_TRUE(r.ok());
    auto e = ComputeErrors(w, r->trajectory);
    return SummarizeErrors(e->error_m, w.TruthDistance()).rmse_m;
  };
  const double with_map = rmse(mapped), without = rmse(unknown), surveyed = rmse(*third);
  std::printf("seed 3: fg-batch RMSE %.3f m surveyed, %.3f m half unknown, %.3f m with the map\n",
              surveyed, without, with_map);
  EXPECT_LE(with_map, 1.05 * without);

  // Walks in frames of their own (IPIN's converter: an origin per walk): the second walk shifted
  // by (100, -50) m gives the same map, in the first walk's frame; a walk shifted by (-30, 20) m
  // gets the map moved into its frame. Surveyed anchors that disagree beyond a rigid motion are
  // an error.
  const Eigen::Vector2d d(100.0, -50.0);
  auto moved = SurveyRadioMap({walks[0], Shifted(walks[1], d)}, SurveyOptions());
  ASSERT_TRUE(moved.ok()) << moved.status().message();
  ASSERT_EQ(moved->anchors.size(), map->anchors.size());
  for (size_t i = 0; i < map->anchors.size(); ++i) {
    EXPECT_LT((moved->anchors[i].position_m - map->anchors[i].position_m).norm(), 0.05) << i;
  }
  const Eigen::Vector2d e(-30.0, 20.0);
  Walk shifted_third = Shifted(unknown, e);
  ASSERT_EQ(ApplyRadioMap(map->anchors, &shifted_third).value(), placed);
  for (size_t i = 0; i < mapped.anchors.size(); ++i) {
    EXPECT_LT((shifted_third.anchors[i].position_m.head<2>() -
               (mapped.anchors[i].position_m.head<2>() + e))
                  .norm(),
              1e-9)
        << i;
  }
  Walk off = walks[1];
  off.anchors[1].position_m.x() += 5.0;  // a surveyed anchor 5 m off the first walk's
  const auto refused = SurveyRadioMap({walks[0], off}, SurveyOptions());
  ASSERT_FALSE(refused.ok());
  EXPECT_NE(refused.status().message().find("rms"), std::string::npos)
      << refused.status().message();
  Walk off_third = unknown;
  off_third.anchors[1].position_m.x() += 5.0;
  EXPECT_FALSE(ApplyRadioMap(map->anchors, &off_third).ok());

  // The map's variance factor: the median disagreement of the anchors both walks placed (at
  // least 1); every anchor's covariance is the larger of it and its own disagreement times the
  // fused covariance that pool_disagreement = false leaves (its own disagreement only).
  // The second walk's receiver reading 8 dB loud (another phone): the walks disagree.
  std::vector<Walk> loud = walks;
  for (RssSample& r : loud[1].rss) r.rss += 8.0;
  auto pooled = SurveyRadioMap(loud, SurveyOptions());
  ASSERT_TRUE(pooled.ok());
  SurveyOptions own;
  own.pool_disagreement = false;
  auto unpooled = SurveyRadioMap(loud, own);
  ASSERT_TRUE(unpooled.ok());
  EXPECT_EQ(unpooled->variance_factor, 1.0);
  std::vector<double> dis;
  for (const SurveyedAnchor& s : pooled->details) {
    if (s.walks == 2) dis.push_back(s.disagreement);
  }
  ASSERT_FALSE(dis.empty());
  std::sort(dis.begin(), dis.end());
  const double median = dis[dis.size() / 2];  // the upper one of an even count
  EXPECT_NEAR(pooled->variance_factor, std::max(1.0, median), 1e-12);
  EXPECT_GT(pooled->variance_factor, 1.0);
  std::printf("variance factor %.3f (median of %zu disagreements); the walks as simulated %.3f\n",
              pooled->variance_factor, dis.size(), map->variance_factor);
  int single = 0;
  ASSERT_EQ(unpooled->details.size(), pooled->details.size());
  for (size_t i = 0; i < pooled->details.size(); ++i) {
    const SurveyedAnchor& a = unpooled->details[i];
    const SurveyedAnchor& b = pooled->details[i];
    ASSERT_EQ(a.id, b.id);
    EXPECT_EQ(a.position_m, b.position_m);
    single += a.walks == 1 ? 1 : 0;
    const double own_scale = std::max(1.0, a.disagreement);
    const double scale = std::max(own_scale, pooled->variance_factor) / own_scale;
    EXPECT_TRUE(b.covariance.isApprox(scale * a.covariance, 1e-12)) << a.id;
  }
  std::printf("%d of %zu anchors placed by one walk only\n", single, pooled->details.size());

  Walk no_truth = walks[0];
  no_truth.truth.clear();
  EXPECT_FALSE(SurveyRadioMap({no_truth}, SurveyOptions()).ok());
}

// IPIN 2023 Track 3, leave one out (issue 44's target): the four shared trials converted with
// --known-start --wifi (walk.yaml's path loss; each walk in a frame of its own, related by the
// BLE beacons); a map surveyed from three, the fourth run by fg-batch with it, against BLE
// alone. Target: p75 better than BLE alone on each trial. Met on 01 (5.94 against 6.12), 21
// (2.49 against 2.50) and 52 (2.42 against 3.08 m); not on 05 (2.34 against 2.23 m). The test
// holds each trial to today's figure (+5 %) and says where the target is not met. (Before the
// map's variance factor, SurveyRadioMap: 7.27 / 2.36 / 2.62 / 2.44; before the beacons stood at
// their floors' heights, StepGraph::Impl::FloorAware: 6.82 / 2.64 / 2.57 / 2.45 against 6.39 /
// 2.22 / 2.50 / 3.08 alone; before fg-batch's noise scales, whose fg-batch runs start the survey:
// 6.85 / 2.45 / 2.57 / 2.70; before fg-batch solved a walk without its map's anchors first: 6.79
// / 2.67 / 2.57 / 2.67.)
TEST(SurveyRealData, IpinLeaveOneOutMapAgainstBleAlone) {
  const std::string dir = std::string(WALKGRAPH_SHARED_DATASETS) + "/ipin2023_t3";
  if (!fs::exists(dir)) GTEST_SKIP() << dir << " not present";
  const std::string ble = dir + "/BLE_Locations.csv";
  const std::vector<std::string> trials = {"01", "05", "21", "52"};
  const std::map<std::string, double> held = {
      {"01", 5.94}, {"05", 2.34}, {"21", 2.49}, {"52", 2.42}};
  std::map<std::string, Walk> wifi, ble_only;
  for (const std::string& n : trials) {
    ConvertOptions o;
    o.known_start = true;
    const std::vector<std::string> src = {
        dir + "/IPIN2023_T3_TrainingTrial" + n + "_repetition01.txt", ble};
    auto b = Convert("ipin", src, o);
    o.ipin_wifi = true;
    auto w = Convert("ipin", src, o);
    ASSERT_TRUE(b.ok() && w.ok()) << n;
    ble_only[n] = *b;
    wifi[n] = *w;
  }
  auto fg = EstimatorRegistry::Builtin().Create("fg-batch");
  ASSERT_TRUE(fg.ok());
  auto p75 = [&](const Walk& w) {
    auto r = (*fg)->Run(w);
    EXPECT_TRUE(r.ok()) << r.status().message();
    auto e = ComputeErrors(w, r->trajectory);
    return SummarizeErrors(e->error_m, w.TruthDistance()).p75_m;
  };
  for (const std::string& n : trials) {
    std::vector<Walk> others;
    for (const std::string& m : trials) {
      if (m != n) others.push_back(wifi[m]);
    }
    auto map = SurveyRadioMap(others, SurveyOptions());
    ASSERT_TRUE(map.ok()) << map.status().message();
    Walk w = wifi[n];
    const int placed = ApplyRadioMap(map->anchors, &w).value();
    const double with_map = p75(w), alone = p75(ble_only[n]);
    std::printf(
        "trial %s: fg-batch p75 %.2f m BLE alone, %.2f m BLE + WiFi + map (%d access "
        "points placed by the map)%s\n",
        n.c_str(), alone, with_map, placed, with_map < alone ? "" : " -- target not met");
    EXPECT_GE(placed, 5) << n;
    EXPECT_LE(with_map, 1.05 * held.at(n)) << n;
  }
}

}  // namespace
}  // namespace walkgraph
