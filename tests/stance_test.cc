#include "walkgraph/stance.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <random>

#include <gtest/gtest.h>

#include "config/parsers.h"
#include "walkgraph/angle.h"
#include "walkgraph/convert.h"
#include "walkgraph/simulate.h"
#include "walkgraph/strides.h"

namespace walkgraph {
namespace {

// A synthetic foot IMU at 200 Hz: 1 s gait cycles, the first 0.4 s of each flat on the floor
// (specific force = g up, no rotation, sensor noise), the rest swinging (a rotating foot with
// large accelerations); after 10 cycles a 3 s standstill. Labels are the true stance phases.
Walk MakeFootWalk(uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> n01(0.0, 1.0);
  Walk w;
  w.meta.imu_placement = ImuPlacement::kFoot;
  const double rate = 200.0;
  for (int i = 0; i < static_cast<int>(13.0 * rate); ++i) {
    const double t = i / rate;
    const double phase = std::fmod(t, 1.0);
    const bool stance = t >= 10.0 || phase < 0.4;
    ImuSample s;
    s.t_s = t;
    s.acc_mps2 = Eigen::Vector3d(0, 0, 9.81);
    if (!stance) {
      const double u = (phase - 0.4) / 0.6;  // 0..1 through the swing
      const double bump = std::sin(kPi * u);
      s.acc_mps2 += Eigen::Vector3d(15.0 * std::sin(2 * kPi * u), 0.0, 8.0 * bump);
      s.gyro_radps = Eigen::Vector3d(0.0, 4.0 * std::sin(2 * kPi * u) + 1.0 * bump, 0.0);
    }
    for (int k = 0; k < 3; ++k) {
      s.acc_mps2[k] += 0.03 * n01(rng);
      s.gyro_radps[k] += 0.003 * n01(rng);
    }
    w.imu.push_back(s);
    w.stance_truth.push_back({t, stance});
  }
  return w;
}

TEST(StanceTest, EveryDetectorFindsSyntheticStance) {
  const Walk w = MakeFootWalk(1);
  auto labels = StanceLabelsAtImu(w);
  ASSERT_TRUE(labels.ok());
  for (StanceDetector d : {StanceDetector::kGlrt, StanceDetector::kMv, StanceDetector::kMag,
                           StanceDetector::kAre, StanceDetector::kMultiCondition}) {
    StanceOptions o;
    o.detector = d;
    auto m = DetectStance(w, o);
    ASSERT_TRUE(m.ok()) << m.status().ToString();
    ASSERT_EQ(m->stance.size(), w.imu.size());
    ASSERT_EQ(m->statistic.size(), w.imu.size());
    const StanceScore s = ScoreStance(m->stance, *labels);
    EXPECT_GE(s.recall(), 0.95) << ToString(d);
    // MV and MAG see only the accelerometer, and this swing's acceleration has smooth turning
    // points (locally constant a, or ‖a‖ crossing g) that they must take for stance; the
    // detectors that also use the gyro do not.
    const bool acc_only = d == StanceDetector::kMv || d == StanceDetector::kMag;
    EXPECT_GE(s.precision(), acc_only ? 0.6 : 0.9) << ToString(d);
  }
}

TEST(StanceTest, GlrtStatisticMatchesTheFormulaAtRest) {
  // A perfectly still sensor with only gyro offset ω: T = ‖ω‖²/σ_g² exactly.
  Walk w;
  for (int i = 0; i < 50; ++i) {
    ImuSample s;
    s.t_s = i * 0.005;
    s.acc_mps2 = Eigen::Vector3d(0.0, 3.0, 9.0).normalized() * 9.81;
    s.gyro_radps = Eigen::Vector3d(0.001, 0.0, 0.0);
    w.imu.push_back(s);
  }
  StanceOptions o;
  auto m = DetectStance(w, o);
  ASSERT_TRUE(m.ok());
  const double expected = 1e-6 / (o.sigma_gyro_radps * o.sigma_gyro_radps);
  for (double t : m->statistic) EXPECT_NEAR(t, expected, 1e-6 * expected);
  EXPECT_TRUE(m->stance[10]);
  EXPECT_TRUE(m->still[25]);
}

TEST(StanceTest, StillOnlyDuringTheStandstill) {
  const Walk w = MakeFootWalk(2);
  auto m = DetectStance(w, StanceOptions());
  ASSERT_TRUE(m.ok());
  int still_walking = 0, still_standing = 0, standing = 0;
  for (size_t i = 0; i < w.imu.size(); ++i) {
    const double t = w.imu[i].t_s;
    if (t < 9.5 && m->still[i]) ++still_walking;
    if (t > 10.6 && t < 12.4) {
      ++standing;
      if (m->still[i]) ++still_standing;
    }
  }
  EXPECT_EQ(still_walking, 0);
  EXPECT_EQ(still_standing, standing);
}

// A gyro 3.6× noisier than the presets' (0.02 rad/s per reading): ‖ω‖ at rest reaches past the
// fixed 0.05 rad/s, so without still_adaptive no sample of the 10-s standstill the walk starts
// with is still; with it the standstill is, and no sample of the swings.
TEST(StanceTest, StillFollowsTheGyrosOwnNoise) {
  auto w = SimulateScenario("jimenez-building", 1,
                            YAML::Load("{duration_s: 60, gyro_noise_radps: 0.02}"));
  ASSERT_TRUE(w.ok()) << w.status().ToString();
  auto labels = StanceLabelsAtImu(*w, 0.02);
  ASSERT_TRUE(labels.ok());
  for (const bool causal : {false, true}) {
    for (const bool adaptive : {true, false}) {
      StanceOptions o = StrideOptions::DefaultStance();
      o.still_adaptive = adaptive;
      o.adaptive_causal = causal;
      if (causal) o.adaptive_window_s = 60.0;
      auto m = DetectStance(*w, o);
      ASSERT_TRUE(m.ok()) << m.status().ToString();
      int still_standing = 0, standing = 0, still_swing = 0;
      for (size_t i = 0; i < w->imu.size(); ++i) {
        const double t = w->imu[i].t_s;
        if (t > 1.0 && t < 9.0) {
          ++standing;
          still_standing += m->still[i];
        }
        still_swing += m->still[i] && !(*labels)[i];
      }
      std::printf("causal %d adaptive %d: still %d of %d standstill samples, %d in swings\n",
                  causal, adaptive, still_standing, standing, still_swing);
      EXPECT_EQ(still_swing, 0);
      if (adaptive) {
        EXPECT_GT(still_standing, 0.75 * standing);  // measured 698 of 799
      } else {
        EXPECT_LT(still_standing, 0.1 * standing);  // the failure the adaptation is for
      }
    }
  }
  // The presets' gyro: the thresholds stay the options' (5σ ≈ 0.03 < 0.05 rad/s).
  auto quiet = SimulateScenario("jimenez-building", 1, YAML::Load("{duration_s: 30}"));
  ASSERT_TRUE(quiet.ok());
  StanceOptions fixed = StrideOptions::DefaultStance();
  fixed.still_adaptive = false;
  auto a = DetectStance(*quiet, StrideOptions::DefaultStance());
  auto b = DetectStance(*quiet, fixed);
  ASSERT_TRUE(a.ok() && b.ok());
  EXPECT_EQ(a->still, b->still);
}

TEST(StanceTest, ThresholdSearchTradesPrecisionForRecall) {
  const Walk w = MakeFootWalk(3);
  StanceOptions o;
  auto scores = StanceThresholdSearch(w, o, {1.0, 1e4, 1e6, 1e8});
  ASSERT_TRUE(scores.ok()) << scores.status().ToString();
  ASSERT_EQ(scores->size(), 4u);
  for (size_t i = 1; i < scores->size(); ++i) {
    EXPECT_GE((*scores)[i].recall(), (*scores)[i - 1].recall());
  }
  EXPECT_LT(scores->front().recall(), 0.5);    // γ = 1 is below the noise floor (≈ 36)
  EXPECT_LT(scores->back().precision(), 0.7);  // γ = 1e8 calls swing stance
  auto automatic = StanceThresholdSearch(w, o);
  ASSERT_TRUE(automatic.ok());
  EXPECT_EQ(automatic->size(), 40u);
  Walk unlabelled = w;
  unlabelled.stance_truth.clear();
  EXPECT_FALSE(StanceThresholdSearch(unlabelled, o).ok());
}

TEST(StanceTest, OptionsFromYaml) {
  auto o = StanceOptionsFromYaml(YAML::Load("{detector: are, window: 7, are_threshold: 1e4}"));
  ASSERT_TRUE(o.ok()) << o.status().ToString();
  EXPECT_EQ(o->detector, StanceDetector::kAre);
  EXPECT_EQ(o->window, 7);
  EXPECT_DOUBLE_EQ(o->threshold(), 1e4);
  EXPECT_FALSE(StanceOptionsFromYaml(YAML::Load("{detector: shoe}")).ok());
  EXPECT_FALSE(StanceOptionsFromYaml(YAML::Load("{window: 0}")).ok());
  EXPECT_FALSE(StanceOptionsFromYaml(YAML::Load("{gamma: 3}")).ok());
}

// Real data: PyShoe VICON trials against zv_vicon. Prints the best-F1 threshold per detector
// (the closing note reports these) and checks the GLRT reaches a useful operating point.
TEST(StanceTest, PyshoeTrialsAgainstViconLabels) {
  const std::string dir = std::string(WALKGRAPH_SHARED_DATASETS) + "/pyshoe_vicon";
  if (!std::filesystem::exists(dir)) GTEST_SKIP() << dir << " not present";
  for (const char* trial : {"2017-11-22-11-22-03.csv", "2017-11-22-11-48-35.csv"}) {
    auto w = Convert("pyshoe", {dir + "/" + trial});
    ASSERT_TRUE(w.ok()) << w.status().ToString();
    for (StanceDetector d : {StanceDetector::kGlrt, StanceDetector::kMv, StanceDetector::kMag,
                             StanceDetector::kAre, StanceDetector::kMultiCondition}) {
      StanceOptions o;
      o.detector = d;
      auto scores = StanceThresholdSearch(*w, o);
      ASSERT_TRUE(scores.ok()) << scores.status().ToString();
      const StanceScore* best = &scores->front();
      auto f1 = [](const StanceScore& s) {
        return 2 * s.precision() * s.recall() / std::max(s.precision() + s.recall(), 1e-12);
      };
      for (const StanceScore& s : *scores) {
        if (f1(s) > f1(*best)) best = &s;
      }
      std::printf("pyshoe %s %-15s best threshold %.4g precision %.3f recall %.3f F1 %.3f\n", trial,
                  ToString(d), best->threshold, best->precision(), best->recall(), f1(*best));
      if (d == StanceDetector::kGlrt) EXPECT_GT(f1(*best), 0.8) << trial;
    }
  }
}

// What the adaptive default reaches against zv_vicon on both shared trials (issue 21's target
// is 0.9; the trials' labels disagree on what stance is: the Vicon foot speed that best
// reproduces them is 0.72 m/s on 11-22-03 and 0.033 m/s on 11-48-35, and with one speed
// threshold the Vicon speed itself reaches F1 0.75 on both, so no single detector setting can
// reach 0.9 on both).
constexpr double kAdaptivePyshoeF1 = 0.65;

double F1(const StanceScore& s) {
  return 2 * s.precision() * s.recall() / std::max(s.precision() + s.recall(), 1e-12);
}

// The adaptive detector finds the synthetic stance with no threshold given: its statistic's
// clusters are where no fixed γ of the other tests was tuned (noise ×30: the stance cluster
// moves up three decades), and a fixed GLRT at its default misses every stance there.
TEST(StanceTest, AdaptiveFollowsTheWalksOwnStatistic) {
  Walk w = MakeFootWalk(2);
  std::mt19937_64 rng(3);
  std::normal_distribution<double> n01(0.0, 1.0);
  for (ImuSample& s : w.imu) {
    for (int k = 0; k < 3; ++k) s.gyro_radps[k] += 0.1 * n01(rng);  // a noisy gyro
  }
  auto labels = StanceLabelsAtImu(w);
  ASSERT_TRUE(labels.ok());
  StanceOptions fixed = StrideOptions::DefaultStance();
  fixed.detector = StanceDetector::kGlrt;
  auto mf = DetectStance(w, fixed);
  ASSERT_TRUE(mf.ok());
  EXPECT_LT(ScoreStance(mf->stance, *labels).recall(), 0.1);
  // With a 5 s window the final 3 s standstill has no swing inside its windows: they take the
  // walk's γ.
  for (double window_s : {0.0, 5.0}) {
    StanceOptions o = StrideOptions::DefaultStance();
    o.detector = StanceDetector::kAdaptiveGlrt;  // the gait detector's base split
    o.adaptive_window_s = window_s;
    auto m = DetectStance(w, o);
    ASSERT_TRUE(m.ok()) << m.status().ToString();
    const StanceScore s = ScoreStance(m->stance, *labels);
    EXPECT_GE(F1(s), 0.9) << "window " << window_s << " precision " << s.precision() << " recall "
                          << s.recall();
  }
}

// The causal adaptive detector (StrideOptions::Causal: γ from the trailing window only): a walk
// cut at t gets the same stances up to t (but for the GLRT's own W-sample window at the cut),
// the noisy walk above is still found, and a causal detector without a window is refused.
TEST(StanceTest, CausalAdaptiveUsesOnlyThePast) {
  Walk w = MakeFootWalk(5);
  std::mt19937_64 rng(6);
  std::normal_distribution<double> n01(0.0, 1.0);
  for (ImuSample& s : w.imu) {
    for (int k = 0; k < 3; ++k) s.gyro_radps[k] += 0.1 * n01(rng);  // γ far from the fallback
  }
  StanceOptions o = StrideOptions().Causal().stance;
  ASSERT_TRUE(o.adaptive_causal);
  o.detector = StanceDetector::kAdaptiveGlrt;  // the gait detector: GaitCausalLooksAheadBounded
  auto full = DetectStance(w, o);
  ASSERT_TRUE(full.ok()) << full.status().ToString();
  auto labels = StanceLabelsAtImu(w);
  ASSERT_TRUE(labels.ok());
  // The first second falls back to glrt_threshold (fewer than adaptive_min_samples samples).
  const StanceScore score = ScoreStance(full->stance, *labels);
  EXPECT_GE(F1(score), 0.85) << "precision " << score.precision() << " recall " << score.recall();
  // The same window centred (not causal) looks ahead: cutting the walk changes its stances.
  StanceOptions centred = o;
  centred.adaptive_causal = false;
  auto centred_full = DetectStance(w, centred);
  ASSERT_TRUE(centred_full.ok());
  size_t centred_differ = 0;
  for (double cut_s : {2.5, 6.2, 9.0}) {
    Walk cut = w;
    cut.imu.erase(std::remove_if(cut.imu.begin(), cut.imu.end(),
                                 [&](const ImuSample& s) { return s.t_s > cut_s; }),
                  cut.imu.end());
    auto part = DetectStance(cut, o);
    auto centred_part = DetectStance(cut, centred);
    ASSERT_TRUE(part.ok() && centred_part.ok());
    const size_t upto = part->stance.size() - static_cast<size_t>(o.window);
    size_t differ = 0;
    for (size_t i = 0; i < upto; ++i) {
      differ += part->stance[i] != full->stance[i];
      centred_differ += centred_part->stance[i] != centred_full->stance[i];
    }
    EXPECT_EQ(differ, 0u) << "cut at " << cut_s << " s";
  }
  EXPECT_GT(centred_differ, 0u);
  StanceOptions bad = o;  // causal needs the trailing window
  bad.adaptive_window_s = 0.0;
  EXPECT_FALSE(bad.Validate().ok());
}

// A standstill has no swing cluster: the adaptive detector falls back to glrt_threshold (with
// Otsu's split alone it would call half of the still samples swing).
TEST(StanceTest, AdaptiveFallsBackWithoutTwoClusters) {
  Walk w = MakeFootWalk(4);
  Walk still;
  for (const ImuSample& s : w.imu) {
    if (s.t_s >= 10.0) still.imu.push_back(s);
  }
  StanceOptions o = StrideOptions::DefaultStance();
  o.glrt_threshold = 1e9;
  auto m = DetectStance(still, o);
  ASSERT_TRUE(m.ok());
  for (bool b : m->stance) ASSERT_TRUE(b);
  o.adaptive_fraction = 1.5;
  EXPECT_FALSE(DetectStance(still, o).ok());
}

// The foot front end's stance (the adaptive default after the turn-on gyro bias is removed) on
// simulated walk `name` (seed 5, `overrides`) against the simulator's truth.
StanceScore SimulatedFrontEndScore(const char* name, const std::string& overrides = "{}") {
  auto w = SimulateScenario(name, 5, YAML::Load(overrides));
  EXPECT_TRUE(w.ok()) << w.status().ToString();
  if (!w.ok()) return {};
  auto labels = StanceLabelsAtImu(*w);
  auto front = RunZuptIns(*w, StrideOptions());
  EXPECT_TRUE(labels.ok() && front.ok());
  if (!labels.ok() || !front.ok()) return {};
  return ScoreStance(front->stance.stance, *labels);
}

// The default detector of the foot front end against the simulator's truth on both foot
// presets (walking at 100 Hz, the Xsens noise of 004 Table I).
TEST(StanceTest, AdaptiveOnTheSimulatedFootPresets) {
  for (const char* scenario : {"jimenez-building", "prieto-laps"}) {
    const StanceScore s = SimulatedFrontEndScore(scenario);
    std::printf("%s adaptive: precision %.3f recall %.3f F1 %.3f\n", scenario, s.precision(),
                s.recall(), F1(s));
    // Measured (seed 5): precision 0.836 / 0.830, recall 1.000 / 1.000, F1 0.911 / 0.907; the
    // false stance samples are the slow first and last instants of each swing.
    EXPECT_GE(F1(s), 0.9) << scenario;
    EXPECT_GE(s.precision(), 0.8) << scenario;
    EXPECT_GE(s.recall(), 0.99) << scenario;
  }
}

// The same detector on the simulator's other gaits (SimulateScenario's `gait`): running (a
// fifth of each 0.7 s stride flat) and stairs (every leg up and down twelve rises).
TEST(StanceTest, AdaptiveOnSimulatedRunAndStairs) {
  for (const char* gait : {"run", "stairs"}) {
    const StanceScore s =
        SimulatedFrontEndScore("jimenez-building", std::string("{gait: ") + gait + "}");
    std::printf("%s adaptive: precision %.3f recall %.3f F1 %.3f\n", gait, s.precision(),
                s.recall(), F1(s));
    // Measured (seed 5): run precision 0.791 recall 1.000 F1 0.884; stairs 0.810 / 1.000 /
    // 0.895 (walking 0.836 / 1.000 / 0.911): as on level ground the false stance samples are the
    // slow first and last instants of each swing, a larger share of a running stride's short
    // foot-flat. (3 laps, seeds 1-3, RMSE m: run fg-ins-batch 0.18-0.22, jimenez-iez-rts
    // 0.08-0.12, fg-ins-batch without RSS 0.05-0.19; stairs fg-ins-batch 0.23-0.27,
    // jimenez-iez-rts 1.73-2.77.)
    EXPECT_GE(F1(s), 0.85) << gait;
    EXPECT_GE(s.precision(), 0.75) << gait;
    EXPECT_GE(s.recall(), 0.99) << gait;
  }
}

// The shared PyShoe trials with every detector at its default setting (the closing note's F1
// table) and the adaptive default against its targets.
TEST(StanceTest, PyshoeDefaultsAgainstViconLabels) {
  const std::string dir = std::string(WALKGRAPH_SHARED_DATASETS) + "/pyshoe_vicon";
  if (!std::filesystem::exists(dir)) GTEST_SKIP() << dir << " not present";
  for (const char* trial : {"2017-11-22-11-22-03.csv", "2017-11-22-11-48-35.csv"}) {
    auto w = Convert("pyshoe", {dir + "/" + trial});
    ASSERT_TRUE(w.ok()) << w.status().ToString();
    auto labels = StanceLabelsAtImu(*w);
    ASSERT_TRUE(labels.ok());
    for (StanceDetector d :
         {StanceDetector::kGlrt, StanceDetector::kMv, StanceDetector::kMag, StanceDetector::kAre,
          StanceDetector::kMultiCondition, StanceDetector::kAdaptiveGlrt}) {
      StanceOptions o = StrideOptions::DefaultStance();
      o.detector = d;
      auto m = DetectStance(*w, o);
      ASSERT_TRUE(m.ok());
      const StanceScore s = ScoreStance(m->stance, *labels);
      std::printf("pyshoe %s %-15s default: precision %.3f recall %.3f F1 %.3f\n", trial,
                  ToString(d), s.precision(), s.recall(), F1(s));
      if (d == StanceDetector::kAdaptiveGlrt) {
        EXPECT_GE(F1(s), kAdaptivePyshoeF1) << trial;
      }
    }
  }
}

// Stance events: the walk's labelled stance runs, runs closer than min_swing_s merged (the Vicon
// labels of a running stance are broken into 5–50 ms pieces), as [begin, end] times.
std::vector<std::pair<double, double>> LabelledStances(const Walk& w, double min_swing_s) {
  std::vector<std::pair<double, double>> events;
  for (size_t i = 0; i < w.stance_truth.size(); ++i) {
    if (!w.stance_truth[i].stance) continue;
    const double t = w.stance_truth[i].t_s;
    if (!events.empty() && t - events.back().second < min_swing_s) {
      events.back().second = t;
    } else {
      events.push_back({t, t});
    }
  }
  return events;
}

struct EventScore {
  double recall = 0.0;         // labelled stances that a ZUPT phase touches (±slack)
  double precision = 0.0;      // ZUPT phases that touch a labelled stance (±slack)
  double longest_gap_s = 0.0;  // longest time between consecutive phases
};

// The front end's stance phases (what the graph puts its ZUPT states on) against the labels.
EventScore ScorePhases(const Walk& w, const ZuptInsSolution& front, double slack_s) {
  const auto events = LabelledStances(w, StrideOptions().min_swing_s);
  auto touches = [&](double a, double b, double c, double d) {
    return a <= d + slack_s && c <= b + slack_s;
  };
  EventScore s;
  size_t hit = 0, good = 0;
  for (const auto& [a, b] : events) {
    for (const StancePhase& p : front.phases) {
      if (touches(a, b, w.imu[p.begin].t_s, w.imu[p.end].t_s)) {
        ++hit;
        break;
      }
    }
  }
  for (size_t k = 0; k < front.phases.size(); ++k) {
    const double c = w.imu[front.phases[k].begin].t_s, d = w.imu[front.phases[k].end].t_s;
    for (const auto& [a, b] : events) {
      if (touches(a, b, c, d)) {
        ++good;
        break;
      }
    }
    if (k > 0) {
      s.longest_gap_s = std::max(s.longest_gap_s, c - w.imu[front.phases[k - 1].end].t_s);
    }
  }
  s.recall = events.empty() ? 1.0 : static_cast<double>(hit) / static_cast<double>(events.size());
  s.precision = front.phases.empty()
                    ? 1.0
                    : static_cast<double>(good) / static_cast<double>(front.phases.size());
  return s;
}

// Issue 40: every detector at its default on all five shared PyShoe trials (two walking, three
// running), scored as the graph uses them — stance phases against the Vicon stance events. The
// adaptive split finds almost none of the running stances (their GLRT statistic stays decades
// above a standstill's); the gait detector (the front end's default) finds them all.
TEST(StanceTest, EveryDetectorOnEveryPyshoeGait) {
  const std::string dir = std::string(WALKGRAPH_SHARED_DATASETS) + "/pyshoe_vicon";
  if (!std::filesystem::exists(dir)) GTEST_SKIP() << dir << " not present";
  for (const char* trial : {"2017-11-22-11-22-03", "2017-11-22-11-48-35", "2017-11-27-11-11-53",
                            "2017-11-27-11-13-10", "2017-12-15-18-02-28"}) {
    auto w = Convert("pyshoe", {dir + "/" + trial + ".csv"});
    ASSERT_TRUE(w.ok()) << w.status().ToString();
    const bool running = std::string(trial) > "2017-11-27";
    for (StanceDetector d : {StanceDetector::kGlrt, StanceDetector::kMv, StanceDetector::kMag,
                             StanceDetector::kAre, StanceDetector::kMultiCondition,
                             StanceDetector::kAdaptiveGlrt, StanceDetector::kGaitGlrt}) {
      StrideOptions o;
      o.stance.detector = d;
      auto front = RunZuptIns(*w, o);
      ASSERT_TRUE(front.ok()) << front.status().ToString();
      const EventScore s = ScorePhases(*w, *front, 0.05);
      std::printf(
          "pyshoe %s %-15s: %3zu phases, event recall %.3f precision %.3f, longest gap "
          "%.2f s\n",
          trial, ToString(d), front->phases.size(), s.recall, s.precision, s.longest_gap_s);
      if (d == StanceDetector::kGaitGlrt) {
        EXPECT_GE(s.recall, 0.9) << trial;
        EXPECT_GE(s.precision, 0.95) << trial;
      }
      if (d == StanceDetector::kAdaptiveGlrt && running) EXPECT_LT(s.recall, 0.5) << trial;
    }
  }
}

// The gait detector is the front end's default, and on the simulated gaits it finds what the
// adaptive split finds (their stances are as quiet as walking ones: every cycle minimum falls
// inside an adaptive run, so the stance samples are the same).
TEST(StanceTest, GaitOnTheSimulatedGaits) {
  ASSERT_EQ(StrideOptions().stance.detector, StanceDetector::kGaitGlrt);
  for (const char* gait : {"walk", "run", "stairs"}) {
    auto w = SimulateScenario("jimenez-building", 5,
                              YAML::Load(std::string("{laps: 1, gait: ") + gait + "}"));
    ASSERT_TRUE(w.ok()) << w.status().ToString();
    StanceOptions adaptive = StrideOptions().stance;
    adaptive.detector = StanceDetector::kAdaptiveGlrt;
    auto a = DetectStance(*w, adaptive);
    auto g = DetectStance(*w, StrideOptions().stance);
    ASSERT_TRUE(a.ok() && g.ok());
    size_t minima = 0, differ = 0;
    for (size_t i = 0; i < g->stance.size(); ++i) {
      minima += g->cycle_minimum[i] ? 1 : 0;
      differ += g->stance[i] != a->stance[i] ? 1 : 0;
    }
    std::printf("%s: %zu cycle minima, %zu stance samples differ from the adaptive split\n", gait,
                minima, differ);
    EXPECT_GT(minima, 20u) << gait;
    EXPECT_EQ(differ, 0u) << gait;
  }
}

// The causal gait detector looks ahead by at most gait_step_s + gait_half_fraction ·
// gait_period_max_s (2 s at the defaults): a walk cut at t gets the same stance up to t − 2 s.
TEST(StanceTest, GaitCausalLooksAheadBounded) {
  const Walk w = MakeFootWalk(7);
  const StanceOptions o = StrideOptions().Causal().stance;
  ASSERT_EQ(o.detector, StanceDetector::kGaitGlrt);
  auto full = DetectStance(w, o);
  ASSERT_TRUE(full.ok()) << full.status().ToString();
  const double lookahead = o.gait_step_s + o.gait_half_fraction * o.gait_period_max_s;
  for (double cut_s : {4.3, 6.9, 9.5}) {
    Walk cut = w;
    cut.imu.erase(std::remove_if(cut.imu.begin(), cut.imu.end(),
                                 [&](const ImuSample& s) { return s.t_s > cut_s; }),
                  cut.imu.end());
    auto part = DetectStance(cut, o);
    ASSERT_TRUE(part.ok());
    size_t compared = 0, differ = 0;
    for (size_t i = 0; i < part->stance.size() && w.imu[i].t_s < cut_s - lookahead; ++i) {
      ++compared;
      differ += (part->stance[i] != full->stance[i]) ||
                (part->cycle_minimum[i] != full->cycle_minimum[i]);
    }
    EXPECT_GT(compared, 200u);
    EXPECT_EQ(differ, 0u) << "cut at " << cut_s << " s";
  }
}

// A synthetic run: 0.7 s strides whose "stance" (the quietest part of each stride) keeps
// 0.3 rad/s of roll and 1 m/s² of shock, never as quiet as a standstill, after a 3 s
// standstill; 23 s at 200 Hz.
Walk MakeRunWalk(uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> n01(0.0, 1.0);
  Walk w;
  w.meta.imu_placement = ImuPlacement::kFoot;
  const double rate = 200.0, period = 0.7;
  for (int i = 0; i < static_cast<int>(23.0 * rate); ++i) {
    const double t = i / rate;
    ImuSample s;
    s.t_s = t;
    s.acc_mps2 = Eigen::Vector3d(0, 0, 9.81);
    if (t >= 3.0) {
      const double u = std::fmod(t - 3.0, period) / period;  // 0..1 through the stride
      // Roll-through "stance" around u = 0.1, swing elsewhere.
      const double contact = std::exp(-std::pow((u - 0.1) / 0.05, 2));
      const double swing = 1.0 - contact;
      s.acc_mps2 += Eigen::Vector3d(30.0 * swing * std::sin(2 * kPi * u), 0.0,
                                    20.0 * swing * std::sin(kPi * u) + 1.0 * contact);
      s.gyro_radps =
          Eigen::Vector3d(0.0, 8.0 * swing * std::sin(2 * kPi * u) + swing + 0.3 * contact, 0.0);
      w.stance_truth.push_back({t, u > 0.05 && u < 0.15});
    } else {
      w.stance_truth.push_back({t, true});
    }
    for (int k = 0; k < 3; ++k) {
      s.acc_mps2[k] += 0.03 * n01(rng);
      s.gyro_radps[k] += 0.003 * n01(rng);
    }
    w.imu.push_back(s);
  }
  return w;
}

// Running: the adaptive split alone marks no stance in the synthetic run; the gait detector
// puts one stance in every stride.
TEST(StanceTest, GaitFindsEveryStrideOfASyntheticRun) {
  const Walk w = MakeRunWalk(11);
  const size_t strides = static_cast<size_t>((23.0 - 3.0) / 0.7) + 1;  // the last one cut
  for (StanceDetector d : {StanceDetector::kAdaptiveGlrt, StanceDetector::kGaitGlrt}) {
    StrideOptions o;
    o.stance.detector = d;
    auto front = RunZuptIns(w, o);
    ASSERT_TRUE(front.ok()) << front.status().ToString();
    std::printf("synthetic run, %zu strides: %s %zu stance phases\n", strides, ToString(d),
                front->phases.size());
    if (d == StanceDetector::kAdaptiveGlrt) {
      EXPECT_LT(front->phases.size(), strides / 4);
    } else {
      EXPECT_GE(front->phases.size(), strides - 1);
      EXPECT_LE(front->phases.size(), strides + 2);
    }
  }
}

// Without a rhythm to follow (gait_min_periodicity 1: no stride period is accepted), the gait
// detector still puts a stance hypothesis in every gait_max_gap_s of motion without stance,
// at the stillest sample there: here inside a contact (measured: 13 of 14, the last stretch
// ends with the walk).
TEST(StanceTest, GaitHypothesesFillStretchesWithoutStance) {
  const Walk w = MakeRunWalk(12);
  StanceOptions o = StrideOptions().stance;
  o.gait_min_periodicity = 1.0;
  auto m = DetectStance(w, o);
  ASSERT_TRUE(m.ok()) << m.status().ToString();
  auto labels = StanceLabelsAtImu(w);
  ASSERT_TRUE(labels.ok());
  size_t hypotheses = 0, in_contact = 0;
  for (size_t i = 0; i < m->stance.size(); ++i) {
    if (!m->hypothesis[i]) continue;
    ++hypotheses;
    EXPECT_TRUE(m->cycle_minimum[i] && m->stance[i]);
    in_contact += (*labels)[i] ? 1 : 0;
  }
  std::printf("%zu hypotheses over 20 s of running, %zu in a contact\n", hypotheses, in_contact);
  EXPECT_GE(hypotheses, 13u);  // 20 s / 1.5 s
  EXPECT_LE(hypotheses, 15u);
  EXPECT_GE(in_contact + 1, hypotheses);  // the last stretch may end before its contact
}

// A walk with a long IMU gap (10^7 s: 5·10^8 bins of 20 ms) gets no stride period rather than
// a vector that does not fit in memory; its stances are still found, and every stretch without
// stance on either side of the gap is taken alone.
TEST(StanceTest, GaitSurvivesALongImuGap) {
  Walk w = MakeFootWalk(13);
  for (size_t i = w.imu.size() / 2; i < w.imu.size(); ++i) w.imu[i].t_s += 1e7;
  for (size_t i = w.stance_truth.size() / 2; i < w.stance_truth.size(); ++i) {
    w.stance_truth[i].t_s += 1e7;
  }
  auto m = DetectStance(w, StrideOptions().stance);
  ASSERT_TRUE(m.ok()) << m.status().ToString();
  auto labels = StanceLabelsAtImu(w);
  ASSERT_TRUE(labels.ok());
  EXPECT_GE(F1(ScoreStance(m->stance, *labels)), 0.85);
  EXPECT_EQ(std::count(m->hypothesis.begin(), m->hypothesis.end(), true), 0);
}

}  // namespace
}  // namespace walkgraph
