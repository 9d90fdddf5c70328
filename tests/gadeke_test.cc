#include "walkgraph/filters/gadeke.h"

#include <cmath>
#include <random>

#include <gtest/gtest.h>

#include "walkgraph/path_loss.h"

namespace walkgraph {
namespace {

// A 30 m × 20 m rectangle walked at 1.2 m/s; 9 anchors on a grid; RSS at 4 Hz per anchor
// (A = −60 dBm, η = 2.5, σ = 4 dB); steps every 0.6 s with a 5 % length bias and heading noise.
Eigen::Vector2d RectPoint(double s) {
  const double L = 100.0;
  s = std::fmod(s, L);
  if (s < 30) return {5 + s, 5};
  if (s < 50) return {35, 5 + (s - 30)};
  if (s < 80) return {35 - (s - 50), 25};
  return {5, 25 - (s - 80)};
}

struct Synth {
  Walk walk;
  StepSequence steps;
  double speed = 1.2, duration = 300.0;
  Eigen::Vector2d Truth(double t) const { return RectPoint(speed * t); }
};

Synth MakeWalk(uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> n01(0.0, 1.0);
  Synth s;
  s.walk.meta.radio.kind = RadioKind::kRss;
  s.walk.meta.radio.path_loss = {-60.0, 2.5, 1.0, 4.0};
  int id = 0;
  for (double ax : {0.0, 20.0, 40.0}) {
    for (double ay : {0.0, 15.0, 30.0}) s.walk.anchors.push_back({id++, {ax, ay, 0.0}});
  }
  const PathLossModel model(s.walk.meta.radio.path_loss, RssUnits::kDbm);
  for (double t = 0.0; t <= s.duration; t += 0.25) {
    for (const Anchor& a : s.walk.anchors) {
      const double d = (s.Truth(t) - a.position_m.head<2>()).norm();
      s.walk.rss.push_back({t, a.id, model.ExpectedRss(d) + 4.0 * n01(rng)});
    }
  }
  for (double t = 0.6; t <= s.duration; t += 0.6) {
    const Eigen::Vector2d d = s.Truth(t) - s.Truth(t - 0.6);
    Step st;
    st.t_s = t;
    st.duration_s = 0.6;
    st.length_m = 1.05 * d.norm();
    st.heading_rad = std::atan2(d.y(), d.x()) + 0.02 + 0.03 * n01(rng);
    s.steps.steps.push_back(st);
  }
  return s;
}

double MeanError(const Synth& s, const Trajectory& traj, double t0, double t1) {
  double sum = 0.0;
  int n = 0;
  for (double t = t0; t <= t1; t += 0.5, ++n) {
    sum += (traj.PositionAt(t).head<2>() - s.Truth(t)).norm();
  }
  return sum / n;
}

TEST(GadekeKfOptionsTest, PaperDefaultsAndValidation) {
  auto o = GadekeKfOptions::FromYaml(YAML::Node(), "gadeke-kf");
  ASSERT_TRUE(o.ok());
  EXPECT_EQ(o->velocity_factor, 0.99);
  EXPECT_EQ(o->processing_rate_hz, 10.0);
  EXPECT_EQ(o->pdr_sigma_frac, 0.05);
  EXPECT_FALSE(GadekeKfOptions::FromYaml(YAML::Load("{velocity_factor: 1.5}"), "g").ok());
  EXPECT_FALSE(GadekeKfOptions::FromYaml(YAML::Load("{outage_start_frac: 0.5}"), "g").ok());
  EXPECT_FALSE(GadekeKfOptions::FromYaml(YAML::Load("{nope: 1}"), "g").ok());
}

TEST(RangeMeasurementsTest, ConvertsRssThroughThePathLossModel) {
  const Synth s = MakeWalk(1);
  auto r = RangeMeasurementsFromWalk(s.walk);
  ASSERT_TRUE(r.ok());
  ASSERT_EQ(r->size(), s.walk.rss.size());
  const RssSample& first = s.walk.rss.front();
  // d̂ = 10^((A − RSS)/(10η)) (001 eq. 14), σ_r = σ·ln10·d̂/(10η) (004 eq. 7).
  const double d = std::pow(10.0, (-60.0 - first.rss) / 25.0);
  EXPECT_NEAR(r->front().range_m, d, 1e-9 * d);
  EXPECT_NEAR(r->front().sigma_m, std::max(0.1, 4.0 * std::log(10.0) * d / 25.0), 1e-9 * d);
  Walk bad = s.walk;
  bad.rss.front().anchor_id = 99;
  EXPECT_FALSE(RangeMeasurementsFromWalk(bad).ok());
}

TEST(GadekeKfTest, BridgesAnOutageWithPdrAndRecovers) {
  const Synth s = MakeWalk(21);
  auto all = RangeMeasurementsFromWalk(s.walk);
  ASSERT_TRUE(all.ok());
  // Outage of Sec. 5: radio lost from 0.3·T to 0.8·T.
  const double t_out0 = 0.3 * s.duration, t_out1 = 0.8 * s.duration;
  std::vector<RangeMeasurement> kept;
  for (const RangeMeasurement& m : *all) {
    if (m.t_s < t_out0 || m.t_s > t_out1) kept.push_back(m);
  }
  GadekeKfOptions o;
  GadekeStart start{Eigen::Vector2d(20, 15), 10.0, 0.0};
  auto kf = RunGadekeKf(s.steps, kept, start, o);
  ASSERT_TRUE(kf.ok()) << kf.status().message();
  const double before = MeanError(s, kf->trajectory, 30.0, t_out0);
  const double end_of_outage =
      (kf->trajectory.PositionAt(t_out1).head<2>() - s.Truth(t_out1)).norm();
  const double after = MeanError(s, kf->trajectory, t_out1 + 30.0, s.duration);
  EXPECT_LT(before, 2.0);
  // 150 s at 1.2 m/s = 180 m of PDR with a 5 % length bias and 0.02 rad heading bias.
  EXPECT_GT(end_of_outage, before);
  EXPECT_LT(end_of_outage, 0.1 * 180.0 + before);
  EXPECT_LT(after, 1.5 * before + 0.3);
  EXPECT_EQ(kf->nis.size(), kept.size());
  RecordProperty("mean_error_before_m", std::to_string(before));
  RecordProperty("error_end_of_outage_m", std::to_string(end_of_outage));
  RecordProperty("mean_error_after_m", std::to_string(after));
  // Smoothing improves the whole-walk error.
  o.smooth = true;
  auto sm = RunGadekeKf(s.steps, kept, start, o);
  ASSERT_TRUE(sm.ok()) << sm.status().message();
  EXPECT_LT(MeanError(s, sm->trajectory, 1.0, s.duration),
            MeanError(s, kf->trajectory, 1.0, s.duration));
}

}  // namespace
}  // namespace walkgraph
