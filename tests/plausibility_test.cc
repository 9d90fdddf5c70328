// src/io/plausibility.cc: the one set of physical-plausibility rules (issue 42's additions):
// path-loss parameters (walk.yaml's radio and fit-path-loss's fits), walk.yaml's initial pose,
// and the rules across a walk's streams (time spans, ranges, RFCode units, waypoints).
#include "io/plausibility.h"

#include <cmath>
#include <string>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

namespace walkgraph::internal {
namespace {

using ::testing::HasSubstr;
using ::testing::IsEmpty;

TEST(CheckPathLoss, RefusesAbsurdFitsAndKeepsPlausibleOnes) {
  const ValidationLimits lim;
  EXPECT_THAT(CheckPathLoss(PathLossParams(), RssUnits::kDbm, lim), IsEmpty());
  PathLossParams p;
  p.A_dbm = -9.9e6;  // issue 42's fit
  EXPECT_THAT(CheckPathLoss(p, RssUnits::kDbm, lim), HasSubstr("A_dbm -9.9e+06 outside"));
  p = PathLossParams();
  for (double eta : {0.0, -2.5, 10.5, std::nan("")}) {
    p.eta = eta;
    EXPECT_THAT(CheckPathLoss(p, RssUnits::kDbm, lim), HasSubstr("outside (0, 10]")) << eta;
  }
  p = PathLossParams();
  p.sigma_db = 0.0;
  EXPECT_THAT(CheckPathLoss(p, RssUnits::kDbm, lim), HasSubstr("sigma_db 0 outside"));
  p = PathLossParams();
  p.d0_m = 1e6;
  EXPECT_THAT(CheckPathLoss(p, RssUnits::kDbm, lim), HasSubstr("d0_m"));
  // RFCode units: positive, larger is weaker.
  p = PathLossParams();
  p.A_dbm = 120.0;
  EXPECT_THAT(CheckPathLoss(p, RssUnits::kRfcode, lim), IsEmpty());
  EXPECT_THAT(CheckPathLoss(p, RssUnits::kDbm, lim), HasSubstr("A_dbm 120 outside"));
  RadioDefaults r;
  r.range_sigma_m = 0.0;
  EXPECT_THAT(CheckRadioDefaults(r, lim), HasSubstr("range_sigma_m 0 outside"));
}

TEST(CheckInitialPose, RadiansCoordinatesAndSigmasWithinReason) {
  const ValidationLimits lim;
  InitialPose p;
  EXPECT_THAT(CheckInitialPose(p, lim), IsEmpty());
  p.heading_rad = 2.0 * M_PI;  // a full turn is still an angle in radians
  EXPECT_THAT(CheckInitialPose(p, lim), IsEmpty());
  p.heading_rad = 90.0;  // degrees
  EXPECT_THAT(CheckInitialPose(p, lim), HasSubstr("heading_rad 90 outside [-2*pi, 2*pi]"));
  p = InitialPose();
  p.y_m = -1e9;
  EXPECT_THAT(CheckInitialPose(p, lim), HasSubstr("y_m -1e+09 outside"));
  // Projected coordinates stay legal: a UTM start in the southern hemisphere (Sydney: easting
  // 334 000 m, northing 6 250 000 m; near the equator a northing just under 10^7 m).
  p = InitialPose();
  p.x_m = 334000.0;
  p.y_m = 9999999.0;
  EXPECT_THAT(CheckInitialPose(p, lim), IsEmpty());
  p.y_m = 1.0000001e7;
  EXPECT_THAT(CheckInitialPose(p, lim), HasSubstr("y_m 1e+07 outside"));
  p = InitialPose();
  p.sigma_xy_m = 1e-9;
  EXPECT_THAT(CheckInitialPose(p, lim), HasSubstr("sigma_xy_m 1e-09 outside"));
  p = InitialPose();
  p.sigma_heading_rad = 1e-6;  // the linear-gaussian preset's exactly known heading
  EXPECT_THAT(CheckInitialPose(p, lim), IsEmpty());
  p.sigma_heading_rad = 0.0;
  EXPECT_THAT(CheckInitialPose(p, lim), HasSubstr("sigma_heading_rad 0 outside"));
}

Walk TwoStreams(double imu_from, double rss_from) {
  Walk w;
  w.anchors.push_back({1, {0.0, 0.0, 0.0}});
  for (int k = 0; k < 10; ++k) {
    ImuSample s;
    s.t_s = imu_from + k;
    w.imu.push_back(s);
    w.rss.push_back({rss_from + k, 1, -60.0});
  }
  return w;
}

TEST(CheckStreamSpans, NamesStreamsThatDoNotOverlap) {
  EXPECT_THAT(CheckStreamSpans(TwoStreams(0.0, 5.0), true), IsEmpty());
  EXPECT_THAT(CheckStreamSpans(TwoStreams(0.0, 1000.0), true),
              HasSubstr("imu.csv spans [0, 9] s and rss.csv [1000, 1009] s: the streams do not "
                        "overlap in time"));
  EXPECT_THAT(CheckStreamSpans(TwoStreams(1000.0, 0.0), false), HasSubstr("imu spans"));
}

TEST(CheckStreamSpans, RangesRfcodeUnitsAndWaypoints) {
  Walk w = TwoStreams(0.0, 0.0);
  w.rss.clear();
  w.ranges = {{0.0, 1, 0.0}, {1.0, 1, 0.0}};
  EXPECT_THAT(CheckStreamSpans(w, true), HasSubstr("range.csv: every range_m is 0"));
  w.ranges[1].range_m = 3.0;  // one real distance is enough
  EXPECT_THAT(CheckStreamSpans(w, true), IsEmpty());

  w = TwoStreams(0.0, 0.0);
  w.meta.radio.units = RssUnits::kRfcode;
  EXPECT_THAT(CheckStreamSpans(w, true), HasSubstr("every reading is negative (dBm-like)"));
  for (RssSample& s : w.rss) s.rss = 80.0;
  EXPECT_THAT(CheckStreamSpans(w, true), IsEmpty());

  w = TwoStreams(0.0, 0.0);
  w.waypoints = {{0.5, {0.0, 0.0}, 1.0}, {1e9, {0.0, 0.0}, 1.0}};
  EXPECT_THAT(CheckStreamSpans(w, true),
              HasSubstr("waypoints.csv:3: t_s 1e+09 outside the walk's time span [0, 9] s"));
  EXPECT_THAT(CheckStreamSpans(w, false), HasSubstr("waypoints[1]: t_s 1e+09"));
  w.waypoints[1].t_s = 9.5;  // within the 1 s tolerance
  EXPECT_THAT(CheckStreamSpans(w, true), IsEmpty());
}

TEST(CheckStreamSpans, TruthWaypointsAndStartInTheAnchorsFrame) {
  Walk w = TwoStreams(0.0, 0.0);
  w.anchors.push_back({2, {50.0, 20.0, 0.0}});
  w.truth = {{0.0, {10.0, 5.0, 0.0}}, {1.0, {4.8e6, 5.0, 0.0}}};  // latitude, longitude swapped
  EXPECT_THAT(CheckStreamSpans(w, true), HasSubstr("truth.csv:3: (4.8e+06, 5) is "));
  EXPECT_THAT(CheckStreamSpans(w, true), HasSubstr("one frame"));
  w.truth[1].position_m.x() = 60.0;  // 10 m outside the anchors' box: the same frame
  EXPECT_THAT(CheckStreamSpans(w, true), IsEmpty());
  w.waypoints = {{1.0, {0.0, -2e5}, 1.0}};
  EXPECT_THAT(CheckStreamSpans(w, false), HasSubstr("waypoints[0]: (0, -200000) is"));
  w.waypoints.clear();
  w.meta.initial_pose = InitialPose();
  w.meta.initial_pose->x_m = 3e5;
  EXPECT_THAT(CheckStreamSpans(w, true), HasSubstr("walk.yaml: initial_pose: (300000, 0)"));
  w.rss.clear();  // without radio readings the anchors place nothing
  EXPECT_THAT(CheckStreamSpans(w, true), IsEmpty());
}

TEST(ColumnCheck, RefusesAColumnWhereMostLinesFailAndNamesTheFirst) {
  ColumnCheck c("field 4 (RSS)", "a negative BLE RSSI in dBm");
  c.Add(true, "t:1: ", "-70");
  c.Add(false, "t:2: ", "3");
  EXPECT_TRUE(c.Check("t, rss").ok());  // one bad reading of two: for the per-reading rules
  c.Add(false, "t:3: ", "4");
  const Status s = c.Check("t, rss");
  ASSERT_FALSE(s.ok());
  EXPECT_EQ(s.message(),
            "t:2: field 4 (RSS) is 3, not a negative BLE RSSI in dBm, in 2 of 3 lines (the first "
            "here); expected a negative BLE RSSI in dBm in every line (two columns swapped? the "
            "lines are t, rss)");
  EXPECT_THAT(CheckBleRss(-70.0), IsEmpty());
  EXPECT_THAT(CheckBleRss(0.0), HasSubstr("BLE rss 0 dBm is not below 0 dBm"));
}

// What a real recording may hold: printed and counted in results.json, not refused.
TEST(PlausibilityWarnings, EachKindNamesItsFileAndAPlainWalkHasNone) {
  Walk w = TwoStreams(0.0, 0.0);
  EXPECT_THAT(PlausibilityWarnings(w), IsEmpty());

  for (ImuSample& s : w.imu) s.t_s *= 0.01;  // 100 Hz, then a hole before the last sample
  w.imu.back().t_s = 200.0;
  auto warnings = PlausibilityWarnings(w);
  ASSERT_THAT(warnings, testing::SizeIs(1));
  EXPECT_THAT(warnings[0], HasSubstr("imu.csv: 1 gap(s) longer than 10x the median"));
  // The radio's 9 s lie inside the IMU's: only the gap. A radio long after the IMU's end:
  w = TwoStreams(0.0, 0.0);
  for (int k = 0; k < 10; ++k) w.rss[k].t_s = 5.0 + 10.0 * k;  // [5, 95] s, IMU [0, 9] s
  warnings = PlausibilityWarnings(w);
  ASSERT_THAT(warnings, testing::SizeIs(1));
  EXPECT_THAT(warnings[0], HasSubstr("imu.csv spans [0, 9] s and rss.csv [5, 95] s: the IMU "
                                     "covers 4.4% of the radio's span"));

  w = TwoStreams(0.0, 0.0);
  w.meta.extra["convert.rss_invalid_dropped"] = 3;
  w.meta.extra["convert.lines_out_of_order"] = 7;  // not a plausibility finding
  w.meta.radio.path_loss.eta = 8.0;
  w.rss[3].rss = 4.0;
  w.rss[6].rss = 12.0;
  warnings = PlausibilityWarnings(w);
  ASSERT_THAT(warnings, testing::SizeIs(3));
  EXPECT_EQ(warnings[0],
            "walk.yaml: the converter dropped 3 rss reading(s) of the recording as physically "
            "impossible (convert.rss_invalid_dropped)");
  EXPECT_THAT(warnings[1], HasSubstr("walk.yaml: radio: eta 8 outside [1.5, 6]"));
  EXPECT_THAT(warnings[2], HasSubstr("rss.csv:5: 2 reading(s) above 0 dBm, the first 4 dBm"));
  w.meta.radio.units = RssUnits::kRfcode;  // positive by definition
  w.meta.radio.path_loss.eta = 2.0;
  EXPECT_THAT(PlausibilityWarnings(w), testing::SizeIs(1));
}

}  // namespace
}  // namespace walkgraph::internal
