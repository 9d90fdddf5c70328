#include "walkgraph/pdr.h"

#include <cmath>
#include <random>

#include <gtest/gtest.h>

#include "config/parsers.h"
#include "walkgraph/angle.h"
#include "walkgraph/metrics.h"
#include "walkgraph/simulate.h"

namespace walkgraph {
namespace {

// A synthetic hip IMU (independent of the code under test): the wearer walks a circle of radius
// r at speed v, the body x axis forward, the sensor pitched by `pitch`; the vertical acceleration
// is a sinusoid with one period per step (000 Sec. IV's step model), plus white noise.
struct CircleWalk {
  double radius_m = 8.0;
  double speed_mps = 1.0;
  double step_hz = 2.0;
  double vertical_amp_mps2 = 0.762;  // Weinberg K = 0.45 → 0.5 m steps
  double pitch_rad = 0.15;
  double duration_s = 60.0;
  double rate_hz = 100.0;
  double acc_noise = 0.05;
  double gyro_noise = 0.002;
  double heading0_rad = 0.3;
  bool with_mag = false;
};

Walk MakeCircleWalk(const CircleWalk& c, uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> n01(0.0, 1.0);
  Walk w;
  w.meta.imu_placement = ImuPlacement::kHip;
  InitialPose p0;
  p0.heading_rad = c.heading0_rad;
  w.meta.initial_pose = p0;
  const double omega = c.speed_mps / c.radius_m;
  const Eigen::Matrix3d tilt = Eigen::AngleAxisd(c.pitch_rad, Eigen::Vector3d::UnitY()).matrix();
  const int n = static_cast<int>(c.duration_s * c.rate_hz);
  for (int i = 0; i < n; ++i) {
    const double t = i / c.rate_hz;
    const double yaw = c.heading0_rad + omega * std::max(t - 1.0, 0.0);
    const Eigen::Matrix3d r = Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()).matrix() * tilt;
    // Nav-frame acceleration: centripetal + vertical step oscillation (starting after 1 s still).
    Eigen::Vector3d a_n(0, 0, 0);
    if (t > 1.0) {
      a_n.head<2>() = c.speed_mps * omega * Eigen::Vector2d(-std::sin(yaw), std::cos(yaw));
      a_n.z() = c.vertical_amp_mps2 * std::sin(2 * kPi * c.step_hz * (t - 1.0));
    }
    ImuSample s;
    s.t_s = t;
    s.acc_mps2 = r.transpose() * (a_n + Eigen::Vector3d(0, 0, 9.81));
    s.gyro_radps = r.transpose() * Eigen::Vector3d(0, 0, t > 1.0 ? omega : 0.0);
    for (int k = 0; k < 3; ++k) {
      s.acc_mps2[k] += c.acc_noise * n01(rng);
      s.gyro_radps[k] += c.gyro_noise * n01(rng);
    }
    if (c.with_mag) {
      s.has_mag = true;
      s.mag_ut = r.transpose() * Eigen::Vector3d(0.0, 20.0, -40.0);
    }
    w.imu.push_back(s);
  }
  return w;
}

TEST(PdrTest, FirIsLowPassWithUnitGain) {
  const std::vector<double> taps = DesignLowPassFir(20, 3.0, 100.0);
  ASSERT_EQ(taps.size(), 21u);
  double sum = 0.0;
  for (double t : taps) sum += t;
  EXPECT_NEAR(sum, 1.0, 1e-12);
  for (size_t i = 0; i < taps.size(); ++i) EXPECT_NEAR(taps[i], taps[20 - i], 1e-15);
  // A 1 Hz sine passes nearly unchanged and in phase, a 30 Hz sine is strongly attenuated.
  std::vector<double> slow(1000), fast(1000);
  for (int i = 0; i < 1000; ++i) {
    slow[i] = std::sin(2 * kPi * 1.0 * i / 100.0);
    fast[i] = std::sin(2 * kPi * 30.0 * i / 100.0);
  }
  const auto ys = FilterZeroDelay(slow, taps), yf = FilterZeroDelay(fast, taps);
  for (int i = 100; i < 900; ++i) {
    EXPECT_NEAR(ys[i], slow[i], 0.1);
    EXPECT_LT(std::fabs(yf[i]), 0.1);
  }
}

TEST(PdrTest, EveryDetectorCountsSyntheticSteps) {
  CircleWalk c;
  c.vertical_amp_mps2 = 4.0;  // strong enough for the 10 (m/s²)² energy threshold of 003
  const Walk w = MakeCircleWalk(c, 1);
  const double expected = (c.duration_s - 1.0) * c.step_hz;  // 118 steps
  for (StepDetector d :
       {StepDetector::kVerticalPeak, StepDetector::kFirMagnitude, StepDetector::kEnergy}) {
    PdrOptions o;
    o.detector = d;
    auto events = DetectSteps(w, o);
    ASSERT_TRUE(events.ok()) << events.status().ToString();
    EXPECT_NEAR(static_cast<double>(events->size()), expected, 0.02 * expected)
        << "detector " << static_cast<int>(d);
  }
}

TEST(PdrTest, WeinbergLengthAndGyroHeadingOnCircle) {
  CircleWalk c;  // 0.5 m steps by construction, K = 0.45
  const Walk w = MakeCircleWalk(c, 2);
  auto seq = ComputeSteps(w, PdrOptions());
  ASSERT_TRUE(seq.ok()) << seq.status().ToString();
  ASSERT_TRUE(seq->absolute_heading);
  const double expected_steps = (c.duration_s - 1.0) * c.step_hz;
  EXPECT_NEAR(static_cast<double>(seq->steps.size()), expected_steps, 0.02 * expected_steps);
  double distance = 0.0;
  for (const Step& s : seq->steps) distance += s.length_m;
  const double truth = c.speed_mps * (c.duration_s - 1.0);
  EXPECT_NEAR(distance, truth, 0.05 * truth);
  // Heading of each step vs the true heading at that time (tilted sensor: needs projection).
  double max_err = 0.0;
  for (const Step& s : seq->steps) {
    const double truth_heading =
        c.heading0_rad + c.speed_mps / c.radius_m * std::max(s.t_s - 1.0, 0.0);
    max_err = std::max(max_err, std::fabs(NormalizeAngle(s.heading_rad - truth_heading)));
  }
  EXPECT_LT(max_err, 0.05);
  // Increments add up to the heading change.
  double sum = 0.0;
  for (const Step& s : seq->steps) sum += s.dheading_rad;
  EXPECT_NEAR(NormalizeAngle(seq->steps.front().heading_rad + sum -
                             seq->steps.front().dheading_rad - seq->steps.back().heading_rad),
              0.0, 1e-9);
}

TEST(PdrTest, ComplementaryHeadingFollowsMagnetometerWithoutInitialPose) {
  CircleWalk c;
  c.with_mag = true;
  c.heading0_rad = -1.2;
  Walk w = MakeCircleWalk(c, 3);
  w.meta.initial_pose.reset();
  // A gyro z bias that pure integration would turn into 0.02·59 ≈ 1.2 rad of drift.
  for (ImuSample& s : w.imu) s.gyro_radps.z() += 0.02;
  PdrOptions o;
  o.heading = HeadingMethod::kComplementary;
  o.complementary_w = 0.2;
  auto seq = ComputeSteps(w, o);
  ASSERT_TRUE(seq.ok()) << seq.status().ToString();
  EXPECT_TRUE(seq->absolute_heading);
  const Step& last = seq->steps.back();
  const double truth_heading = c.heading0_rad + c.speed_mps / c.radius_m * (last.t_s - 1.0);
  EXPECT_LT(std::fabs(NormalizeAngle(last.heading_rad - truth_heading)), 0.08);

  o.heading = HeadingMethod::kGyro;
  auto gyro = ComputeSteps(w, o);
  ASSERT_TRUE(gyro.ok());
  EXPECT_FALSE(gyro->absolute_heading);

  // auto (the default): the magnetometer blend when walk.yaml gives no start heading, the gyro
  // from a known one; the report says which.
  o.heading = HeadingMethod::kAuto;
  auto automatic = ComputeSteps(w, o);
  ASSERT_TRUE(automatic.ok());
  EXPECT_TRUE(automatic->absolute_heading);
  EXPECT_EQ(automatic->report.heading_source, HeadingSource::kMagnetometer);
  EXPECT_EQ(automatic->steps.back().heading_rad, seq->steps.back().heading_rad);
  EXPECT_EQ(ResolveHeadingMethod(w, o), HeadingMethod::kComplementary);
  Walk known = w;
  known.meta.initial_pose = InitialPose();
  known.meta.initial_pose->heading_rad = c.heading0_rad;
  EXPECT_EQ(ResolveHeadingMethod(known, o), HeadingMethod::kGyro);
  auto from_start = ComputeSteps(known, o);
  ASSERT_TRUE(from_start.ok());
  EXPECT_EQ(from_start->report.heading_source, HeadingSource::kInitialPose);
  Walk no_mag = w;
  for (ImuSample& s : no_mag.imu) s.has_mag = false;
  EXPECT_EQ(ResolveHeadingMethod(no_mag, o), HeadingMethod::kGyro);
}

TEST(PdrTest, PcaFindsTheForwardAxis) {
  // Sensor yawed by 1.0 rad on the body; forward acceleration leads vertical by a quarter step.
  CircleWalk c;
  c.radius_m = 1e6;  // straight line
  c.pitch_rad = 0.0;
  c.with_mag = true;
  c.heading0_rad = 0.0;
  Walk w = MakeCircleWalk(c, 4);
  const double mount = 1.0;
  const Eigen::Matrix3d m = Eigen::AngleAxisd(mount, Eigen::Vector3d::UnitZ()).matrix();
  for (size_t i = 0; i < w.imu.size(); ++i) {
    const double t = w.imu[i].t_s;
    if (t > 1.0) {  // forward oscillation a_f = 1.5·cos(2π f (t − 1)): leads a_z = sin(...)
      w.imu[i].acc_mps2.x() += 1.5 * std::cos(2 * kPi * c.step_hz * (t - 1.0));
    }
    // Body x forward → sensor axes rotated by −mount about z.
    w.imu[i].acc_mps2 = m.transpose() * w.imu[i].acc_mps2;
    w.imu[i].gyro_radps = m.transpose() * w.imu[i].gyro_radps;
    w.imu[i].mag_ut = m.transpose() * w.imu[i].mag_ut;
  }
  w.meta.initial_pose.reset();
  PdrOptions o;
  o.heading = HeadingMethod::kComplementary;
  o.forward_axis = ForwardAxisMethod::kPca;
  auto seq = ComputeSteps(w, o);
  ASSERT_TRUE(seq.ok()) << seq.status().ToString();
  ASSERT_GT(seq->steps.size(), 50u);
  EXPECT_LT(std::fabs(NormalizeAngle(seq->steps[60].heading_rad - 0.0)), 0.1);
  o.forward_axis = ForwardAxisMethod::kBodyX;
  auto raw = ComputeSteps(w, o);
  ASSERT_TRUE(raw.ok());
  EXPECT_LT(std::fabs(NormalizeAngle(raw->steps[60].heading_rad - mount)), 0.1);
  // Body y (a handheld phone's top edge) points 90° counter-clockwise of body x.
  o.forward_axis = ForwardAxisMethod::kBodyY;
  auto by = ComputeSteps(w, o);
  ASSERT_TRUE(by.ok());
  EXPECT_LT(std::fabs(NormalizeAngle(by->steps[60].heading_rad - (mount + kPi / 2))), 0.1);
  EXPECT_TRUE(PdrOptionsFromYaml(YAML::Load("{forward_axis: body-y}")).ok());
}

// The straight walk of PcaFindsTheForwardAxis with the sensor yawed by `mount` on the body and,
// with `forward`, a forward oscillation leading the vertical one by a quarter step; with
// `sway`, a lateral sway at half the step frequency (one period per stride).
Walk YawedStraightWalk(double mount, bool forward, bool sway) {
  CircleWalk c;
  c.radius_m = 1e6;
  c.pitch_rad = 0.0;
  c.with_mag = true;
  c.heading0_rad = 0.0;
  Walk w = MakeCircleWalk(c, 4);
  const Eigen::Matrix3d m = Eigen::AngleAxisd(mount, Eigen::Vector3d::UnitZ()).matrix();
  for (ImuSample& s : w.imu) {
    const double phase = 2 * kPi * c.step_hz * (s.t_s - 1.0);
    if (s.t_s > 1.0 && forward) s.acc_mps2.x() += 1.5 * std::cos(phase);
    if (s.t_s > 1.0 && sway) s.acc_mps2.y() += 1.5 * std::sin(0.5 * phase);
    s.acc_mps2 = m.transpose() * s.acc_mps2;
    s.gyro_radps = m.transpose() * s.gyro_radps;
    s.mag_ut = m.transpose() * s.mag_ut;
  }
  w.meta.initial_pose.reset();
  return w;
}

TEST(PdrTest, AutoForwardAxisIsTheDirectionThatLeadsTheVertical) {
  // Yawed by 1 rad (no body axis near): the data's direction, the steps heading east.
  auto yawed = ComputeSteps(YawedStraightWalk(1.0, true, true), PdrOptions());
  ASSERT_TRUE(yawed.ok()) << yawed.status().ToString();
  ASSERT_GT(yawed->steps.size(), 50u);
  EXPECT_LT(std::fabs(NormalizeAngle(yawed->report.forward_axis_rad + 1.0)), 0.1);
  EXPECT_GT(yawed->report.forward_axis_consistency, 0.5);
  EXPECT_LT(std::fabs(NormalizeAngle(yawed->steps[60].heading_rad)), 0.1);
  // A phone in portrait, 0.1 rad off its y axis: snapped to body y exactly.
  auto portrait = ComputeSteps(YawedStraightWalk(-kPi / 2 - 0.1, true, false), PdrOptions());
  ASSERT_TRUE(portrait.ok());
  EXPECT_EQ(portrait->report.forward_axis_rad, kPi / 2);
  EXPECT_NEAR(portrait->report.forward_axis_data_rad, kPi / 2 + 0.1, 0.05);
  // Only a lateral sway (the simulated hips): the steps do not agree on a direction, so the
  // device's default axis — body x, or body y for a handheld device.
  Walk sway = YawedStraightWalk(0.0, false, true);
  auto hip = ComputeSteps(sway, PdrOptions());
  ASSERT_TRUE(hip.ok());
  EXPECT_EQ(hip->report.forward_axis_rad, 0.0);
  EXPECT_LT(hip->report.forward_axis_consistency, 0.2);
  EXPECT_TRUE(std::isnan(hip->report.forward_axis_data_rad));
  sway.meta.imu_placement = ImuPlacement::kHandheld;
  auto phone = ComputeSteps(sway, PdrOptions());
  ASSERT_TRUE(phone.ok());
  EXPECT_EQ(phone->report.forward_axis_rad, kPi / 2);
  PdrOptions bad;
  bad.forward_axis_snap_rad = 1.0;
  EXPECT_FALSE(bad.Validate().ok());
  EXPECT_FALSE(PdrOptionsFromYaml(YAML::Load("{auto_forward_min_z: -1}")).ok());
}

// A circle walk after `shake_s` of standing with the device in a shaking hand: vertical
// acceleration 0.4·sin(2π·1.3 t) + 0.25·sin(2π·2.9 t) (peaks ≈ 0.6 m/s², above the fixed 0.5).
Walk WithHandShake(const CircleWalk& c, double shake_s, uint64_t seed) {
  Walk walk = MakeCircleWalk(c, seed);
  std::mt19937_64 rng(seed + 100);
  std::normal_distribution<double> n01(0.0, 1.0);
  const Eigen::Matrix3d r = Eigen::AngleAxisd(c.heading0_rad, Eigen::Vector3d::UnitZ()).matrix() *
                            Eigen::AngleAxisd(c.pitch_rad, Eigen::Vector3d::UnitY()).matrix();
  std::vector<ImuSample> imu;
  for (int i = 0; i < static_cast<int>(shake_s * c.rate_hz); ++i) {
    ImuSample s;
    s.t_s = i / c.rate_hz;
    const double az =
        0.4 * std::sin(2 * kPi * 1.3 * s.t_s) + 0.25 * std::sin(2 * kPi * 2.9 * s.t_s);
    s.acc_mps2 = r.transpose() * Eigen::Vector3d(0, 0, 9.81 + az);
    for (int k = 0; k < 3; ++k) {
      s.acc_mps2[k] += c.acc_noise * n01(rng);
      s.gyro_radps[k] = c.gyro_noise * n01(rng);
    }
    imu.push_back(s);
  }
  for (ImuSample s : walk.imu) {
    s.t_s += shake_s;
    imu.push_back(s);
  }
  walk.imu = imu;
  return walk;
}

TEST(PdrTest, AutoThresholdsRejectAShakingHandAndKeepASensorAtRest) {
  CircleWalk c;
  c.vertical_amp_mps2 = 3.0;
  const double walking = (c.duration_s - 1.0) * c.step_hz;  // 118 steps
  const Walk hand = WithHandShake(c, 30.0, 5);
  PdrOptions fixed;
  fixed.step_thresholds = StepThresholdMethod::kFixed;
  auto false_steps = DetectSteps(hand, fixed);
  ASSERT_TRUE(false_steps.ok());
  EXPECT_GT(static_cast<double>(false_steps->size()), walking + 20);  // the shake passes
  auto seq = ComputeSteps(hand, PdrOptions());
  ASSERT_TRUE(seq.ok()) << seq.status().ToString();
  EXPECT_NEAR(static_cast<double>(seq->steps.size()), walking, 0.02 * walking);
  EXPECT_GT(seq->report.vertical_peak_mps2, 1.0);
  EXPECT_GT(seq->report.standstill_sigma_mps2, 0.2);
  // The same walk standing still on a table (sensor noise only): the fixed thresholds, whose
  // weaker steps (here 0.9 m/s² of amplitude) all pass.
  c.vertical_amp_mps2 = 0.9;
  c.duration_s = 90.0;
  auto rest = ComputeSteps(MakeCircleWalk(c, 6), PdrOptions());
  ASSERT_TRUE(rest.ok());
  EXPECT_EQ(rest->report.vertical_peak_mps2, PdrOptions().vertical_peak_mps2);
  EXPECT_NEAR(static_cast<double>(rest->steps.size()), 89.0 * c.step_hz, 2.0);
}

TEST(PdrTest, StepsFromOdometryFollowTheIncrementConvention) {
  Walk w;
  InitialPose p0;
  p0.heading_rad = 0.5;
  w.meta.initial_pose = p0;
  w.odometry = {{1.0, 1.0, 0.1}, {2.0, 2.0, -0.3}, {3.5, 0.5, 0.0}};
  const StepSequence seq = StepsFromOdometry(w);
  ASSERT_EQ(seq.steps.size(), 3u);
  EXPECT_TRUE(seq.absolute_heading);
  EXPECT_DOUBLE_EQ(seq.steps[0].heading_rad, 0.5);
  EXPECT_DOUBLE_EQ(seq.steps[1].heading_rad, 0.6);
  EXPECT_NEAR(seq.steps[2].heading_rad, 0.3, 1e-12);
  EXPECT_NEAR(seq.steps[2].dheading_rad, -0.3, 1e-12);
  EXPECT_DOUBLE_EQ(seq.steps[1].length_m, 2.0);
  EXPECT_DOUBLE_EQ(seq.steps[2].duration_s, 1.5);
}

TEST(PdrTest, OptionsFromYamlAreStrict) {
  auto ok =
      PdrOptionsFromYaml(YAML::Load("{detector: energy, length_model: constant, "
                                    "constant_length_m: 0.65, heading: complementary}"));
  ASSERT_TRUE(ok.ok()) << ok.status().ToString();
  EXPECT_EQ(ok->detector, StepDetector::kEnergy);
  EXPECT_EQ(ok->length_model, StepLengthModel::kConstant);
  EXPECT_DOUBLE_EQ(ok->constant_length_m, 0.65);
  EXPECT_FALSE(PdrOptionsFromYaml(YAML::Load("{detector: peaks}")).ok());
  EXPECT_FALSE(PdrOptionsFromYaml(YAML::Load("{weinberg: 0.4}")).ok());
  EXPECT_FALSE(PdrOptionsFromYaml(YAML::Load("{complementary_w: 2.0}")).ok());
}

// Issue 4 on the simulator's hip walks: detected step count within 2 % of the true steps.
// 000's vertical-peak detector (K = 0.45) everywhere; on gadeke-outage (10 Hz, 003's rate) also
// 003's energy detector in both lockout readings, with threshold 2 (m/s^2)^2 and body-x (the
// departures the simulated hip forces; see gadeke_test.cc): 1066 / 1065 of 1072 steps (seeds
// 1 / 2). Before the lockout was made inclusive and anchored at the step's first maximum it
// over-counted by 6.2 % (first) and 2.05 % (strongest): at 10 Hz the second energy peak of a
// step (the vertical minimum) falls 0.3 s after the first, and 0.1 + 0.2 > 0.3 in floating
// point let it through. The PDR-only final error (from the true start, over the distance
// walked) is printed; it is not a drift measure on one walk (gadeke-outage seed 3: 0.25 % with
// a 15-m largest error; closed paths cancel), see RelativeErrorOfEachPapersFrontEndOnItsHipWalk.
// PDR-only dead reckoning from the true start as a trajectory (a point at the start and one at
// each step's end), for the metrics.
Trajectory DeadReckonFromTruth(const Walk& walk, const StepSequence& seq) {
  Trajectory out;
  Eigen::Vector3d p = walk.truth.front().position_m;
  p.z() = 0.0;
  out.points.push_back({walk.truth.front().t_s, p, 0.0, std::nullopt});
  for (const Step& st : seq.steps) {
    p.head<2>() +=
        st.length_m * Eigen::Vector2d(std::cos(st.heading_rad), std::sin(st.heading_rad));
    if (!(st.t_s > out.points.back().t_s)) continue;
    out.points.push_back({st.t_s, p, 0.0, std::nullopt});
  }
  return out;
}

struct PdrCase {
  const char* scenario;
  const char* overrides;
  const char* pdr;
};

// Issue 41's simulated phone (scenario handheld-phone: y forward, a shaking hand at the stops):
// the defaults find its carriage — body y, thresholds raised above the shake — and count its
// steps within 2 %, where the old defaults (body x, fixed thresholds) count the shake as steps.
// Without a start heading (the magnetometer's then), body x walks 90° off: its dead reckoning
// ends several times further from the truth.
TEST(PdrTest, HandheldPhonePresetFindsItsCarriage) {
  for (uint64_t seed : {1, 2}) {
    auto sim = SimulateScenarioDetailed("handheld-phone", seed);
    ASSERT_TRUE(sim.ok()) << sim.status().message();
    EXPECT_EQ(sim->walk.meta.imu_placement, ImuPlacement::kHandheld);
    const double true_steps = static_cast<double>(sim->steps.size());
    const double distance = sim->walk.TruthDistance();
    Walk no_heading = sim->walk;
    no_heading.meta.initial_pose->heading_known = false;
    no_heading.meta.initial_pose->sigma_heading_rad = kUnknownHeadingSigmaRad;
    auto run = [&](const PdrOptions& o, StepSequence* seq) {
      auto s = ComputeSteps(no_heading, o);
      EXPECT_TRUE(s.ok()) << s.status().message();
      if (s.ok()) *seq = *s;
      auto errors = ComputeErrors(sim->walk, DeadReckonFromTruth(sim->walk, *seq));
      EXPECT_TRUE(errors.ok());
      return errors.ok() ? SummarizeErrors(*errors, distance) : ErrorStats{};
    };
    StepSequence seq, old_seq;
    const ErrorStats e = run(PdrOptions(), &seq);
    PdrOptions old;
    old.forward_axis = ForwardAxisMethod::kBodyX;
    old.step_thresholds = StepThresholdMethod::kFixed;
    const ErrorStats e_old = run(old, &old_seq);
    std::printf(
        "handheld-phone seed %d: auto %zu steps / %.0f true, forward %.1f deg, peak %.2f m/s^2, "
        "PDR mean error %.2f m over %.0f m; old defaults %zu steps, %.2f m\n",
        static_cast<int>(seed), seq.steps.size(), true_steps,
        seq.report.forward_axis_rad * 180.0 / kPi, seq.report.vertical_peak_mps2, e.mean_m,
        distance, old_seq.steps.size(), e_old.mean_m);
    EXPECT_EQ(seq.report.forward_axis_rad, kPi / 2);
    EXPECT_GT(seq.report.vertical_peak_mps2, PdrOptions().vertical_peak_mps2);
    EXPECT_LT(std::abs(static_cast<double>(seq.steps.size()) - true_steps) / true_steps, 0.02);
    EXPECT_GT(static_cast<double>(old_seq.steps.size()), 1.1 * true_steps);
    EXPECT_EQ(seq.report.heading_source, HeadingSource::kMagnetometer);
    EXPECT_GT(e_old.mean_m, 4.0 * e.mean_m);
  }
}

TEST(PdrTest, StepCountOnSimulatedHipWalks) {
  const char* energy = "{detector: energy, energy_threshold_m2ps4: 2, forward_axis: body-x}";
  const char* strongest =
      "{detector: energy, energy_threshold_m2ps4: 2, forward_axis: body-x, "
      "energy_lockout_keep: strongest}";
  for (const PdrCase& c :
       {PdrCase{"tarrio-circle", "{duration_s: 300}", "{}"}, PdrCase{"gadeke-outage", "{}", "{}"},
        PdrCase{"gadeke-outage", "{}", energy}, PdrCase{"gadeke-outage", "{}", strongest},
        PdrCase{"correa-classroom", "{laps: 6}", "{}"}, PdrCase{"correa-corridor", "{}", "{}"}}) {
    for (uint64_t seed : {1, 2}) {
      auto sim = SimulateScenarioDetailed(c.scenario, seed, YAML::Load(c.overrides));
      ASSERT_TRUE(sim.ok()) << sim.status().message();
      auto options = PdrOptionsFromYaml(YAML::Load(c.pdr));
      ASSERT_TRUE(options.ok()) << options.status().message();
      auto seq = ComputeSteps(sim->walk, *options);
      ASSERT_TRUE(seq.ok()) << seq.status().message();
      const double true_steps = static_cast<double>(sim->steps.size());
      const double count_error = std::abs(seq->steps.size() - true_steps) / true_steps;
      auto errors = ComputeErrors(sim->walk, DeadReckonFromTruth(sim->walk, *seq));
      ASSERT_TRUE(errors.ok()) << errors.status().message();
      const double distance = sim->walk.TruthDistance();
      const ErrorStats e = SummarizeErrors(*errors, distance);
      std::printf(
          "%s %s seed %d: %zu steps detected / %.0f true (%.2f %%), PDR final error "
          "%.2f %% of %.0f m (largest %.2f m)\n",
          c.scenario, c.pdr, static_cast<int>(seed), seq->steps.size(), true_steps,
          100.0 * count_error, e.pct_distance, distance, e.max_m);
      EXPECT_TRUE(seq->absolute_heading) << c.scenario;
      EXPECT_LT(count_error, 0.02) << c.scenario;
    }
  }
}

// Issue 4's drift band with 003's relative error (Sec. 5, Fig. 6: the error at each truth
// point over the distance walked to it, averaged over the walk, then over runs; 003 reports
// 3.5-10 % for its hip PDR), mean of seeds 1-10, each paper's own front end on its scenario:
//   gadeke-outage: 003's (energy detector with the departures the simulated hip forces,
//     threshold 2 and body-x, see gadeke_test.cc; Weinberg; magnetometer-aided heading);
//   correa presets: 001's (FIR |a| maxima, constant step length, complementary heading eq. 7)
//     with the per-user length calibrated to the simulated walker (sim.step_length_m);
//   tarrio-circle: 000's (vertical peaks, Weinberg K = 0.45, gyro heading eq. 4). 000's
//     simulation (Sec. IV) draws the step amplitude from eq. 3 with the same K and has a 10 °/h
//     gyro, so its walker drifts less than the band by construction: held below 1 %.
// 000's front end on the other presets is printed (gyro-only heading drifts out of the band
// on the 691-m gadeke walk).
TEST(PdrTest, RelativeErrorOfEachPapersFrontEndOnItsHipWalk) {
  struct Case {
    const char* scenario;
    const char* overrides;
    const char* pdr;  // "correa": 001's front end with the walker's step length
    double lo_pct, hi_pct;
  };
  constexpr double kNone = -1.0;  // printed only
  const char* gadeke =
      "{detector: energy, energy_threshold_m2ps4: 2, forward_axis: body-x, "
      "heading: complementary}";
  for (const Case& c : {Case{"tarrio-circle", "{duration_s: 300}", "{}", 0.0, 1.0},
                        Case{"gadeke-outage", "{}", gadeke, 1.0, 10.0},
                        Case{"correa-classroom", "{laps: 6}", "correa", 1.0, 10.0},
                        Case{"correa-corridor", "{}", "correa", 1.0, 10.0},
                        Case{"gadeke-outage", "{}", "{}", kNone, kNone},
                        Case{"correa-classroom", "{laps: 6}", "{}", kNone, kNone},
                        Case{"correa-corridor", "{}", "{}", kNone, kNone}}) {
    std::vector<double> rel;
    double final_pct = 0.0;
    constexpr int kSeeds = 10;
    for (uint64_t seed = 1; seed <= kSeeds; ++seed) {
      auto sim = SimulateScenarioDetailed(c.scenario, seed, YAML::Load(c.overrides));
      ASSERT_TRUE(sim.ok()) << sim.status().message();
      std::string pdr = c.pdr;
      if (pdr == "correa") {
        pdr =
            "{detector: fir-magnitude, length_model: constant, heading: complementary, "
            "constant_length_m: " +
            std::to_string(sim->walk.meta.extra.at("sim.step_length_m")) + "}";
      }
      auto options = PdrOptionsFromYaml(YAML::Load(pdr));
      ASSERT_TRUE(options.ok()) << options.status().message();
      auto seq = ComputeSteps(sim->walk, *options);
      ASSERT_TRUE(seq.ok()) << seq.status().message();
      auto errors = ComputeErrors(sim->walk, DeadReckonFromTruth(sim->walk, *seq));
      ASSERT_TRUE(errors.ok()) << errors.status().message();
      const ErrorStats s = SummarizeErrors(*errors, sim->walk.TruthDistance());
      ASSERT_TRUE(std::isfinite(s.mean_pct_distance)) << c.scenario;
      rel.push_back(s.mean_pct_distance);
      final_pct += s.pct_distance / kSeeds;
    }
    double mean = 0.0, lo = rel.front(), hi = rel.front();
    for (double v : rel) {
      mean += v / kSeeds;
      lo = std::min(lo, v);
      hi = std::max(hi, v);
    }
    std::printf(
        "%s %s: relative error %.2f %% of the distance walked (seeds 1-10: %.2f-%.2f %%); "
        "final error %.2f %% of the walk\n",
        c.scenario, c.pdr, mean, lo, hi, final_pct);
    if (c.lo_pct != kNone) {
      EXPECT_GT(mean, c.lo_pct) << c.scenario << " " << c.pdr;
      EXPECT_LT(mean, c.hi_pct) << c.scenario << " " << c.pdr;
    }
  }
}

// A position-only start (heading_known = false) leaves the start heading to the magnetometer,
// as if there were no initial_pose; a known heading is taken as given.
TEST(PdrTest, PositionOnlyStartTakesTheMagnetometerHeading) {
  auto sim = SimulateScenarioDetailed("correa-classroom", 1, YAML::Load("{laps: 1}"));
  ASSERT_TRUE(sim.ok()) << sim.status().message();
  auto options = PdrOptionsFromYaml(YAML::Load("{heading: complementary}"));
  ASSERT_TRUE(options.ok());
  Walk none = sim->walk;
  none.meta.initial_pose.reset();
  Walk position_only = sim->walk;
  position_only.meta.initial_pose = InitialPose{3.0,
                                                4.0,
                                                0.0,
                                                0.5,
                                                kUnknownHeadingSigmaRad,
                                                /*heading_known=*/false};
  Walk with_heading = position_only;
  with_heading.meta.initial_pose->heading_known = true;
  with_heading.meta.initial_pose->heading_rad = 2.0;
  with_heading.meta.initial_pose->sigma_heading_rad = 0.01;
  auto a = ComputeSteps(none, *options);
  auto b = ComputeSteps(position_only, *options);
  auto c = ComputeSteps(with_heading, *options);
  ASSERT_TRUE(a.ok() && b.ok() && c.ok());
  ASSERT_EQ(a->steps.size(), b->steps.size());
  EXPECT_TRUE(b->absolute_heading);
  for (size_t i = 0; i < a->steps.size(); ++i) {
    EXPECT_EQ(a->steps[i].heading_rad, b->steps[i].heading_rad) << i;
  }
  // The known heading (2 rad, far from the walk's true start) is where the third one starts
  // (its first step already blended a little towards the magnetometer, eq. 7).
  auto off = [](const Step& s) {
    return std::abs(NormalizeAngle(s.heading_rad - s.dheading_rad - 2.0));
  };
  EXPECT_LT(off(c->steps.front()), 0.15);
  EXPECT_GT(off(a->steps.front()), 0.5);
}

TEST(PdrTest, NoImuIsAnError) {
  Walk w;
  EXPECT_FALSE(ComputeSteps(w, PdrOptions()).ok());
}

}  // namespace
}  // namespace walkgraph
