#include "walkgraph/filters/gadeke.h"

#include <algorithm>
#include <cmath>
#include <random>

#include <gtest/gtest.h>

#include "config/parsers.h"
#include "test_util.h"
#include "walkgraph/compare.h"
#include "walkgraph/estimator.h"
#include "walkgraph/metrics.h"
#include "walkgraph/path_loss.h"
#include "walkgraph/pdr.h"
#include "walkgraph/simulate.h"

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
  auto o = GadekeKfOptionsFromYaml(YAML::Node(), "gadeke-kf");
  ASSERT_TRUE(o.ok());
  EXPECT_EQ(o->velocity_factor, 0.99);
  EXPECT_EQ(o->processing_rate_hz, 10.0);
  EXPECT_EQ(o->pdr_sigma_frac, 0.05);
  EXPECT_FALSE(GadekeKfOptionsFromYaml(YAML::Load("{velocity_factor: 1.5}"), "g").ok());
  EXPECT_FALSE(GadekeKfOptionsFromYaml(YAML::Load("{outage_start_frac: 0.5}"), "g").ok());
  EXPECT_FALSE(GadekeKfOptionsFromYaml(YAML::Load("{nope: 1}"), "g").ok());
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

// ------------------------------------------------------------------ simulator preset
// 003 Sec. 5.2 on SimulateScenario("gadeke-outage") (700 m at 1.25 m/s, 62 anchors at 4 Hz, no
// radio from 0.3·t_run to 0.8·t_run), through the full front ends, seeded Monte Carlo.
//
// PDR front end: 003's energy detector and Weinberg length, with two departures the simulated
// hip forces, stated here rather than hidden in the defaults (which stay 003's):
//  - threshold 2 (m/s²)² instead of 10: the simulated hip's vertical acceleration is the
//    Weinberg-consistent sinusoid of amplitude (l/K)⁴/2 ≈ 2.1 m/s² (l = 0.645 m, K = 0.45), so
//    its energy peaks at ≈ 4.5 (m/s²)² and 10 detects ≈ 4 % of the steps; 2 = (1.41 m/s²)²;
//  - forward axis body-x instead of the PCA (eq. 3-5): the simulated hip has lateral sway but
//    no forward acceleration swing, so the PCA picks the lateral axis (≈ 80° heading error).
constexpr const char* kSimulatedHipPdr = "{energy_threshold_m2ps4: 2, forward_axis: body-x}";

double MeanIn(const ErrorSeries& e, double t0, double t1) {
  double sum = 0.0;
  int n = 0;
  for (size_t i = 0; i < e.t_s.size(); ++i) {
    if (e.t_s[i] >= t0 && e.t_s[i] <= t1) {
      sum += e.error_m[i];
      ++n;
    }
  }
  EXPECT_GT(n, 0) << "no truth in [" << t0 << ", " << t1 << "]";
  return n > 0 ? sum / n : 0.0;
}

double Rmse(const ErrorSeries& e) {
  double sum = 0.0;
  for (double v : e.error_m) sum += v * v;
  return std::sqrt(sum / e.error_m.size());
}

// Issue 5: during the outage gadeke-kf moves like PDR (its error grows like PDR's) while the
// RSS-only track freezes; after recovery it is back at its pre-outage error level within 30 s;
// the RTS smoother's RMSE ≤ the filter's. The RSS-only track is 003's own "WSN alone" filter:
// the same KF without the PDR input (pdr_input: false), whose velocity decays with the 0.99
// factor per 0.1 s (time constant ≈ 10 s), so "the position converges" (Sec. 5.2).
TEST(GadekePresetTest, BridgesTheOutageLikePdrAndRecoversWithin30s) {
  const EstimatorRegistry& reg = EstimatorRegistry::Builtin();
  const std::string pdr = kSimulatedHipPdr;
  auto kf = reg.Create("gadeke-kf", YAML::Load("{pdr: " + pdr + "}"));
  auto rts = reg.Create("gadeke-kf-rts", YAML::Load("{pdr: " + pdr + "}"));
  auto wsn = reg.Create("gadeke-kf", YAML::Load("{pdr_input: false, pdr: " + pdr + "}"));
  auto pdr_options = PdrOptionsFromYaml(
      YAML::Load("{detector: energy, length_model: weinberg, heading: complementary, "
                 "energy_threshold_m2ps4: 2, forward_axis: body-x}"));
  ASSERT_TRUE(kf.ok() && rts.ok() && wsn.ok() && pdr_options.ok());
  const int runs = testing::MonteCarloRuns(50), wsn_runs = std::min(runs, 10);
  double pre = 0, end_of_outage = 0, post = 0, outage_kf = 0, outage_m = 0;
  double outage_kf_first = 0, outage_wsn = 0;
  double rmse_kf = 0, rmse_rts = 0, worst_pdr_gap = 0, worst_wsn_motion = 0;
  for (int run = 0; run < runs; ++run) {
    auto walk = SimulateScenario("gadeke-outage", MonteCarloSeed(3, run));
    ASSERT_TRUE(walk.ok()) << walk.status().message();
    const double t_start = walk->StartTime();
    const double t_out0 = walk->meta.extra.at("sim.outage_start_s");
    const double t_out1 = walk->meta.extra.at("sim.outage_end_s");
    const double t_end = walk->meta.extra.at("sim.duration_s");
    auto r_kf = (*kf)->Run(*walk);
    auto r_rts = (*rts)->Run(*walk);
    ASSERT_TRUE(r_kf.ok() && r_rts.ok()) << r_kf.status().message();
    auto e_kf = ComputeErrors(*walk, r_kf->trajectory);
    auto e_rts = ComputeErrors(*walk, r_rts->trajectory);
    ASSERT_TRUE(e_kf.ok() && e_rts.ok());
    pre += MeanIn(*e_kf, t_start + 30.0, t_out0) / runs;  // after the filter converged
    end_of_outage += MeanIn(*e_kf, t_out1 - 20.0, t_out1) / runs;
    post += MeanIn(*e_kf, t_out1 + 30.0, t_end) / runs;
    outage_kf += MeanIn(*e_kf, t_out0, t_out1) / runs;
    rmse_kf += Rmse(*e_kf) / runs;
    rmse_rts += Rmse(*e_rts) / runs;
    Trajectory truth;
    for (const TruthSample& t : walk->truth) truth.points.push_back({t.t_s, t.position_m});
    double walked = 0.0;
    for (size_t i = 1; i < truth.size(); ++i) {
      if (truth.points[i].t_s > t_out0 && truth.points[i].t_s <= t_out1) {
        walked += (truth.points[i].position_m - truth.points[i - 1].position_m).norm();
      }
    }
    outage_m += walked / runs;
    // From 60 s into the outage (six velocity time constants τ = 0.1 s/ln(1/0.99) ≈ 10 s) the
    // filter's displacement is the sum of the PDR step vectors and the WSN-only track stands
    // still: the velocity term left moves either by at most |v|·τ·e⁻⁶ < 0.1 m for |v| < 4 m/s.
    // The reference is the filter's own state at its last epoch by then (an interpolated
    // position would already hold part of the next epoch's step).
    const double t_ref = t_out0 + 60.0;
    double ta = t_ref;
    Eigen::Vector3d kf_a = r_kf->trajectory.points.front().position_m;
    for (const TrajectoryPoint& p : r_kf->trajectory.points) {
      if (p.t_s > t_ref) break;
      kf_a = p.position_m;
      ta = p.t_s;
    }
    auto steps = StepsForWalk(*walk, *pdr_options);
    ASSERT_TRUE(steps.ok());
    Eigen::Vector2d pdr_moved = Eigen::Vector2d::Zero();
    size_t si = 0;
    for (const TrajectoryPoint& p : r_kf->trajectory.points) {
      if (p.t_s <= ta || p.t_s > t_out1) continue;
      for (; si < steps->steps.size() && steps->steps[si].t_s <= p.t_s; ++si) {
        const Step& s = steps->steps[si];
        if (s.t_s > ta) {
          pdr_moved +=
              s.length_m * Eigen::Vector2d(std::cos(s.heading_rad), std::sin(s.heading_rad));
        }
      }
      const Eigen::Vector2d kf_moved = (p.position_m - kf_a).head<2>();
      worst_pdr_gap = std::max(worst_pdr_gap, (kf_moved - pdr_moved).norm());
    }
    if (run >= wsn_runs) continue;
    // The WSN-only track (on the first runs: its figures do not need all of them).
    auto r_wsn = (*wsn)->Run(*walk);
    ASSERT_TRUE(r_wsn.ok()) << r_wsn.status().message();
    auto e_wsn = ComputeErrors(*walk, r_wsn->trajectory);
    ASSERT_TRUE(e_wsn.ok());
    outage_kf_first += MeanIn(*e_kf, t_out0, t_out1) / wsn_runs;
    outage_wsn += MeanIn(*e_wsn, t_out0, t_out1) / wsn_runs;
    double wsn_motion = 0.0;
    const Trajectory& w = r_wsn->trajectory;
    for (size_t i = 1; i < w.size(); ++i) {
      if (w.points[i - 1].t_s >= ta && w.points[i].t_s <= t_out1) {
        wsn_motion += (w.points[i].position_m - w.points[i - 1].position_m).norm();
      }
    }
    worst_wsn_motion = std::max(worst_wsn_motion, wsn_motion);
  }
  RecordProperty("pre_outage_mean_error_m", std::to_string(pre));
  RecordProperty("end_of_outage_mean_error_m", std::to_string(end_of_outage));
  RecordProperty("post_recovery_mean_error_m", std::to_string(post));
  RecordProperty("outage_mean_error_kf_m", std::to_string(outage_kf));
  RecordProperty("outage_mean_error_wsn_only_m", std::to_string(outage_wsn));
  RecordProperty("outage_mean_error_kf_same_runs_m", std::to_string(outage_kf_first));
  RecordProperty("outage_distance_m", std::to_string(outage_m));
  RecordProperty("rmse_kf_m", std::to_string(rmse_kf));
  RecordProperty("rmse_rts_m", std::to_string(rmse_rts));
  RecordProperty("worst_kf_minus_pdr_displacement_m", std::to_string(worst_pdr_gap));
  RecordProperty("worst_wsn_only_motion_m", std::to_string(worst_wsn_motion));
  EXPECT_LE(worst_pdr_gap, 0.1);     // the filter dead-reckons with the PDR during the outage
  EXPECT_LE(worst_wsn_motion, 0.1);  // while the RSS-only track freezes
  if (testing::kSanitized) return;   // accuracy is judged on the full Release run count
  // The error grows during the outage, within 003's PDR error of 3.5–10 % of the distance.
  EXPECT_GT(end_of_outage, 2.0 * pre);
  EXPECT_LE(end_of_outage, pre + 0.10 * outage_m);
  EXPECT_LT(outage_kf_first, outage_wsn);  // PDR bridging beats the frozen track (Fig. 7/8)
  EXPECT_LE(post, 1.2 * pre);              // back at the pre-outage level 30 s after recovery
  EXPECT_LE(rmse_rts, rmse_kf);
}

}  // namespace
}  // namespace walkgraph
