#include <algorithm>
#include <cmath>
#include <functional>

#include "config/reader.h"
#include "simulate/sim_models.h"
#include "util/text.h"
#include "walkgraph/angle.h"
#include "walkgraph/config.h"
#include "walkgraph/simulate.h"

namespace walkgraph {

namespace {

using sim::Rng;

// Limits on the size of a simulated walk, checked before allocating: far above any scenario
// (the longest preset walks 30 min), far below what exhausts a machine.
constexpr int kMaxLaps = 10000;
constexpr int kMaxAnchors = 10000;
constexpr double kMaxDurationS = 360000.0;  // 100 h
constexpr double kMaxImuSamples = 4e7;      // 111 h at 100 Hz: ~5 GB with its truth
constexpr double kMaxRadioReadings = 4e7;

// The foot presets' gait (override key `gait`): walking on level ground, running, or stairs.
enum class FootGait { kWalk, kRun, kStairs };
const std::vector<std::pair<std::string, FootGait>> kFootGaitNames = {
    {"walk", FootGait::kWalk}, {"run", FootGait::kRun}, {"stairs", FootGait::kStairs}};

// Everything a preset can set; the YAML overrides are read into it.
struct Params {
  std::string name, source;
  bool foot = false;
  ImuPlacement placement = ImuPlacement::kWaist;
  // walker
  double speed_mps = 1.0;
  int laps = 1;
  bool has_laps = false;
  double duration_s = 0.0;
  double start_still_s = 0.0, end_still_s = 0.0;
  double corner_radius_m = 0.6;
  // imu
  double imu_rate_hz = 100.0;
  sim::ImuNoiseOptions noise;
  double gyro_bias_dph = 0.0;
  bool mag = true;
  sim::MagneticFieldOptions field;
  sim::GaitOptions gait;
  double stance_fraction = 0.35;
  // a device in the hand (sim::WaistImuOptions): yaw on the walker, forward swing, hand shake
  double device_yaw_deg = 0.0, forward_swing_mps2 = 0.0, hand_shake_mps2 = 0.0;
  FootGait foot_gait = FootGait::kWalk;
  double lift_m = 0.10, pitch_amplitude_deg = 30.0;  // the foot's swing
  // radio
  bool rss_on = true, toa_on = false;
  sim::RadioOptions radio;
  int num_anchors = 0;
  double rx_height_offset_m = 0.0;
  // gadeke
  double run_length_m = 700.0, outage_start_frac = 0.3, outage_end_frac = 0.8;
  // multi-floor building (two-floor-building): storeys, stairs, anchors' mounting height, the
  // barometer; the radio's floor loss is radio.floor_loss_db
  bool building = false;
  double stair_rise_m = 0.175, stair_tread_m = 0.28, stair_speed_mps = 0.45;
  double anchor_mount_m = 2.5;
  sim::BarometerOptions baro;
  // initial pose
  double sigma_xy_m = 0.5, sigma_heading_deg = 5.0;
  std::map<std::string, double> extra;
};

// Rounds to a multiple of `quantum`; for 1/quantum integral the result is the double nearest
// to the decimal, so the files get short numbers.
double Q(double v, double quantum) {
  const double inv = std::round(1.0 / quantum);
  if (std::fabs(inv * quantum - 1.0) < 1e-12) return std::round(v * inv) / inv;
  return std::round(v / quantum) * quantum;
}

sim::ImuNoiseOptions XsensMti() {
  // 004 Table I: bias stability acc 0.02 m/s², gyro 1 °/s (used as turn-on σ); white noise from
  // the MTi noise densities (0.002 m/s²/√Hz, 0.05 °/s/√Hz) over the 30/40 Hz bandwidths.
  sim::ImuNoiseOptions n;
  n.acc_noise_mps2 = 0.011;
  n.gyro_noise_radps = 0.0055;
  n.acc_bias_sigma_mps2 = 0.02;
  n.gyro_bias_sigma_radps = DegToRad(1.0);
  n.acc_bias_rw_mps2_sqrts = 1e-4;
  n.gyro_bias_rw_radps_sqrts = 1e-4;
  n.mag_noise_ut = 0.16;
  return n;
}

sim::ImuNoiseOptions SparkfunStick() {
  sim::ImuNoiseOptions n;
  n.acc_noise_mps2 = 0.04;
  n.gyro_noise_radps = 0.0066;
  n.gyro_bias_sigma_radps = DegToRad(0.2);
  n.mag_noise_ut = 0.2;
  n.gyro_rate_hz = 15.0;
  n.mag_rate_hz = 15.0;
  return n;
}

// A fixed (seed-independent) jittered grid: the building does not change between runs.
std::vector<Anchor> JitteredGrid(int rows, int cols, double x0, double y0, double w, double h,
                                 double jitter, double z, int count, uint64_t layout_seed) {
  Rng rng(layout_seed);
  std::vector<Anchor> out;
  for (int i = 0; i < rows; ++i) {
    for (int j = 0; j < cols; ++j) {
      const double dx = rng.Uniform(-jitter, jitter), dy = rng.Uniform(-jitter, jitter);
      if (static_cast<int>(out.size()) >= count) continue;
      Anchor a;
      a.id = static_cast<int>(out.size()) + 1;
      a.position_m = Eigen::Vector3d(Q(x0 + w * (j + 0.5) / cols + dx, 0.01),
                                     Q(y0 + h * (i + 0.5) / rows + dy, 0.01), z);
      out.push_back(a);
    }
  }
  return out;
}

std::vector<Eigen::Vector2d> CutPolyline(const std::vector<Eigen::Vector2d>& w, double length) {
  std::vector<Eigen::Vector2d> out;
  if (w.empty()) return out;
  out.push_back(w[0]);
  double acc = 0.0;
  for (size_t i = 1; i < w.size(); ++i) {
    const double d = (w[i] - w[i - 1]).norm();
    if (acc + d >= length) {
      out.push_back(w[i - 1] + (w[i] - w[i - 1]) * ((length - acc) / d));
      return out;
    }
    acc += d;
    out.push_back(w[i]);
  }
  return out;
}

// ------------------------------------------------------------------ presets
// Each preset fills Params and returns the anchors plus a function building the motion plan.
struct Preset {
  std::string name, description;
  std::function<void(Params*)> defaults;
  // Builds anchors and plan from the (overridden) params.
  std::function<Status(Params*, std::vector<Anchor>*, sim::MotionPlan*)> build;
};

// Loops: enough laps to cover duration_s when it is set.
int LapsFor(const Params& p, double loop_length_m) {
  if (p.duration_s <= 0.0) return p.laps;
  return std::max(p.laps,
                  static_cast<int>(std::ceil(p.duration_s * p.speed_mps / loop_length_m)) + 1);
}

std::vector<Anchor> PickAnchors(const Params& p, std::vector<Anchor> all) {
  if (p.num_anchors > 0 && p.num_anchors < static_cast<int>(all.size())) {
    return sim::SpreadSubset(all, p.num_anchors);
  }
  return all;
}

const Preset* FindPreset(const std::string& name);

void TarrioCircleDefaults(Params* p) {
  p->source = "000 (Tarrio et al.) Sec. IV";
  p->placement = ImuPlacement::kWaist;
  p->imu_rate_hz = 50.0;
  p->laps = 4;
  p->has_laps = true;
  p->noise.acc_noise_mps2 = 5.7575e-2;
  p->gyro_bias_dph = 10.0;
  p->mag = false;
  p->gait.weinberg_k = 0.45;
  p->radio.path_loss = {-60.0, 2.5, 1.0, 5.0};
  p->radio.sensitivity = -95.0;
  p->radio.period_s = 0.5;
  p->num_anchors = 9;
  p->extra["sim.delta_t_s"] = 2.0;
}

Status TarrioCircleBuild(Params* p, std::vector<Anchor>* anchors, sim::MotionPlan* plan) {
  *anchors = sim::GridAnchors(p->num_anchors, 0.0, 0.0, 20.0, 20.0, 0.0);
  const double circumference = 2.0 * kPi * 8.0;
  const int laps = LapsFor(*p, circumference);
  *plan = sim::MotionPlan(Eigen::Vector2d(18.0, 10.0), 0.5 * kPi);
  plan->Stop(p->start_still_s);
  plan->Walk(sim::CirclePath({10.0, 10.0}, 8.0, 0.0, laps), p->speed_mps, p->start_still_s > 0.0,
             p->end_still_s > 0.0);
  plan->Stop(p->end_still_s);
  p->extra["sim.loop_length_m"] = circumference;
  p->extra["sim.laps"] = laps;
  return Status::Ok();
}

void CorreaClassroomDefaults(Params* p) {
  p->source = "001 (Correa et al.) Sec. IV, scenario 1";
  p->placement = ImuPlacement::kHip;
  p->speed_mps = 0.9;
  p->laps = 24;
  p->has_laps = true;
  p->start_still_s = 5.0;
  p->end_still_s = 5.0;
  p->noise = SparkfunStick();
  p->field.disturbance_ut = 5.0;
  p->field.disturbance_count = 6;
  p->field.area_max = Eigen::Vector2d(14.552, 10.648);
  p->radio.path_loss = {-45.0, 2.3, 1.0, 4.0};
  p->radio.sensitivity = -101.0;
  p->radio.period_s = 1.0;
}

Status CorreaClassroomBuild(Params* p, std::vector<Anchor>* anchors, sim::MotionPlan* plan) {
  const double W = 14.552, H = 10.648;
  std::vector<Anchor> all;
  const std::vector<Eigen::Vector2d> spots = {{0, 0},     {W, 0},     {W, H},     {0, H},
                                              {W / 2, 0}, {W, H / 2}, {W / 2, H}, {0, H / 2}};
  for (size_t i = 0; i < spots.size(); ++i) {
    all.push_back({static_cast<int>(i) + 1,
                   Eigen::Vector3d(Q(spots[i].x(), 1e-3), Q(spots[i].y(), 1e-3), 0.0),
                   std::nullopt});
  }
  *anchors = PickAnchors(*p, all);
  const auto rect = sim::RectangleLoop(0.5, 0.5, W - 1.0, H - 1.0);
  const int laps = LapsFor(*p, 46.4);
  *plan = sim::MotionPlan(rect[0], 0.0);
  plan->Stop(p->start_still_s);
  plan->WalkWaypoints(sim::RepeatLoop(rect, laps), p->speed_mps, p->corner_radius_m, 2.0);
  plan->Stop(p->end_still_s);
  p->extra["sim.loop_length_m"] = sim::PolylineLength(sim::RepeatLoop(rect, 1));
  p->extra["sim.laps"] = laps;
  return Status::Ok();
}

void CorreaCorridorDefaults(Params* p) {
  p->source = "001 (Correa et al.) Sec. IV, scenario 2";
  p->placement = ImuPlacement::kHip;
  p->speed_mps = 1.0;
  p->laps = 1;
  p->has_laps = true;
  p->start_still_s = 10.0;
  p->end_still_s = 10.0;
  p->noise = SparkfunStick();
  p->field.disturbance_ut = 5.0;
  p->field.disturbance_count = 10;
  p->field.area_max = Eigen::Vector2d(11.2, 47.6);
  p->radio.path_loss = {-45.0, 2.3, 1.0, 4.0};
  p->radio.sensitivity = -101.0;
  p->radio.period_s = 1.0;
}

Status CorreaCorridorBuild(Params* p, std::vector<Anchor>* anchors, sim::MotionPlan* plan) {
  std::vector<Anchor> all;
  const std::vector<Eigen::Vector2d> spots = {{0, 2},    {0, 16},    {0, 30},    {0, 45.6},
                                              {11.2, 9}, {11.2, 23}, {11.2, 37}, {5.6, 47.6}};
  for (size_t i = 0; i < spots.size(); ++i) {
    all.push_back(
        {static_cast<int>(i) + 1, Eigen::Vector3d(spots[i].x(), spots[i].y(), 0), std::nullopt});
  }
  *anchors = PickAnchors(*p, all);
  const Eigen::Vector2d A(1.0, 2.0), B(1.0, 45.6);
  std::vector<Eigen::Vector2d> w = {A};
  const int laps = LapsFor(*p, 2.0 * (B - A).norm());
  for (int i = 0; i < laps; ++i) {
    w.push_back(B);
    w.push_back(A);
  }
  *plan = sim::MotionPlan(A, 0.5 * kPi);
  plan->Stop(p->start_still_s);
  plan->WalkWaypoints(w, p->speed_mps, p->corner_radius_m, 10.0);
  plan->Stop(p->end_still_s);
  p->extra["sim.laps"] = laps;
  return Status::Ok();
}

void HandheldPhoneDefaults(Params* p) {
  // correa-corridor's walk, anchors and radio (below), a phone's carriage: body y forward
  // (the device yawed −90° on the walker), a forward swing leading the vertical (1 m/s²,
  // of the order of the vertical one), a shaking hand at the stops (0.45 m/s²: peaks
  // ~0.65 m/s², above the fixed 0.5, as IPIN's phones held still), a magnetometer. A test
  // walk for the PDR front end's 'auto' carriage, not a paper's set-up.
  p->source = "issue 41 (a handheld phone on 001's corridor, Sec. IV scenario 2)";
  p->placement = ImuPlacement::kHandheld;
  p->speed_mps = 1.0;
  p->laps = 1;
  p->has_laps = true;
  p->start_still_s = 20.0;
  p->end_still_s = 10.0;
  p->noise = SparkfunStick();
  p->field.disturbance_ut = 5.0;
  p->field.disturbance_count = 10;
  p->field.area_max = Eigen::Vector2d(11.2, 47.6);
  p->radio.path_loss = {-45.0, 2.3, 1.0, 4.0};
  p->radio.sensitivity = -101.0;
  p->radio.period_s = 1.0;
  p->device_yaw_deg = -90.0;
  p->forward_swing_mps2 = 1.0;
  p->hand_shake_mps2 = 0.45;
  // A hand's vertical swing is larger than a waist's: K = 0.4 gives 2.2 m/s² at these
  // 0.58-m steps (IPIN's phones: median step peaks 1.5-2.8 m/s²).
  p->gait.weinberg_k = 0.4;
}

Status HandheldPhoneBuild(Params* p, std::vector<Anchor>* anchors, sim::MotionPlan* plan) {
  return FindPreset("correa-corridor")->build(p, anchors, plan);
}

void GadekeOutageDefaults(Params* p) {
  p->source = "003 (Gaedeke et al.) Sec. 4-5";
  p->placement = ImuPlacement::kHip;
  p->imu_rate_hz = 10.0;
  p->speed_mps = 1.25;
  p->start_still_s = 5.0;
  p->end_still_s = 5.0;
  p->noise = XsensMti();
  p->field.disturbance_ut = 8.0;
  p->field.disturbance_count = 15;
  p->field.area_max = Eigen::Vector2d(60, 30);
  p->radio.path_loss = {-45.0, 2.8, 1.0, 5.0};
  p->radio.sensitivity = -95.0;
  p->radio.period_s = 0.25;
  p->radio.detection = {1.0, 25.0, 4.0};
  p->num_anchors = 62;
}

Status GadekeOutageBuild(Params* p, std::vector<Anchor>* anchors, sim::MotionPlan* plan) {
  *anchors = PickAnchors(*p, JitteredGrid(6, 11, 0, 0, 60, 30, 1.0, 0.0, 62, 3));
  const std::vector<Eigen::Vector2d> loop = {{5, 5},   {55, 5},  {55, 25}, {30, 25},
                                             {30, 15}, {20, 15}, {20, 25}, {5, 25}};
  const double loop_len = sim::PolylineLength(sim::RepeatLoop(loop, 1));
  const int laps = static_cast<int>(std::ceil(p->run_length_m / loop_len)) + 1;
  const auto path = CutPolyline(sim::RepeatLoop(loop, laps), p->run_length_m);
  *plan = sim::MotionPlan(loop[0], 0.0);
  plan->Stop(p->start_still_s);
  plan->WalkWaypoints(path, p->speed_mps, p->corner_radius_m, 2.0);
  plan->Stop(p->end_still_s);
  p->extra["sim.run_length_m"] = p->run_length_m;
  p->extra["sim.loop_length_m"] = loop_len;
  return Status::Ok();
}

void PrietoLapsDefaults(Params* p) {
  p->source = "002 (Prieto et al.) Sec. IV-A";
  p->foot = true;
  p->placement = ImuPlacement::kFoot;
  p->speed_mps = 0.975;
  p->laps = 8;
  p->has_laps = true;
  p->start_still_s = 10.0;
  p->end_still_s = 5.0;
  p->noise = XsensMti();
  p->field.disturbance_ut = 8.0;
  p->field.disturbance_count = 10;
  p->field.area_min = Eigen::Vector2d(0, 0);
  p->field.area_max = Eigen::Vector2d(40, 17.2);
  p->toa_on = true;
  p->radio.path_loss = {-40.0, 3.0, 1.0, 6.0};
  p->radio.sensitivity = -95.0;
  p->radio.period_s = 1.0;
  p->radio.jitter_s = 0.1;
  p->radio.nlos = {0.3, 15.0, 6.0, 3.0};
  p->radio.toa_sigma_m = 1.5;
}

Status PrietoLapsBuild(Params* p, std::vector<Anchor>* anchors, sim::MotionPlan* plan) {
  *anchors = PickAnchors(*p, {{1, {-3, -3, 0}, std::nullopt},
                              {2, {43, -3, 0}, std::nullopt},
                              {3, {43, 20.2, 0}, std::nullopt},
                              {4, {-3, 20.2, 0}, std::nullopt}});
  const auto rect = sim::RectangleLoop(0, 0, 40, 17.2);
  const int laps = LapsFor(*p, 114.4);
  *plan = sim::MotionPlan(rect[0], 0.0);
  plan->Stop(p->start_still_s);
  plan->WalkWaypoints(sim::RepeatLoop(rect, laps), p->speed_mps, p->corner_radius_m, 2.0);
  plan->Stop(p->end_still_s);
  p->extra["sim.loop_length_m"] = 114.4;
  p->extra["sim.laps"] = laps;
  return Status::Ok();
}

const std::vector<Preset>& Presets() {
  static const std::vector<Preset> presets = {
      {"tarrio-circle",
       "000 Sec. IV: 9 anchors over 400 m², r = 8 m circle at 1 m/s, waist IMU 50 Hz",
       TarrioCircleDefaults, TarrioCircleBuild},
      {"correa-classroom",
       "001 Sec. IV: 155 m² classroom, 8 motes, 46.4 m rectangle for > 20 min, hip IMU",
       CorreaClassroomDefaults, CorreaClassroomBuild},
      {"correa-corridor",
       "001 Sec. IV: 11.2 × 47.6 m corridor, 8 motes, A → B → A with stops, hip IMU",
       CorreaCorridorDefaults, CorreaCorridorBuild},
      {"handheld-phone",
       "issue 41: correa-corridor walked with a phone held in portrait (y forward), stops with "
       "a shaking hand",
       HandheldPhoneDefaults, HandheldPhoneBuild},
      {"gadeke-outage",
       "003: hip IMU 10 Hz, 62 anchors at 4 Hz, 700 m run, WSN outage 0.3·t to 0.8·t",
       GadekeOutageDefaults, GadekeOutageBuild},
      {"prieto-laps",
       "002 Sec. IV-A: foot IMU 100 Hz, 4 APs with RSS + TOA at ~1 Hz, 8 laps ≈ 915 m, NLOS",
       PrietoLapsDefaults, PrietoLapsBuild},
  };
  return presets;
}

// 004's building and loop (shared by the two jimenez presets).
void JimenezDefaults(Params* p) {
  p->source = "004 (Jimenez et al.) Sec. II-IV";
  p->foot = true;
  p->placement = ImuPlacement::kFoot;
  p->speed_mps = 1.0;
  p->laps = 8;
  p->has_laps = true;
  p->start_still_s = 10.0;
  p->end_still_s = 5.0;
  p->noise = XsensMti();
  p->field.disturbance_ut = 10.0;
  p->field.disturbance_count = 20;
  p->field.area_max = Eigen::Vector2d(55, 40);
  p->radio.units = RssUnits::kRfcode;
  p->radio.path_loss = {60.0, 2.3, 1.0, 6.0};
  p->radio.sensitivity = 110.0;
  p->radio.period_s = 1.0;
  p->radio.report_period_s = 0.1;
  p->radio.rss_quantum = 0.5;
  p->radio.detection = {0.95, 15.0, 4.0};
  p->rx_height_offset_m = 1.0;
}

Status JimenezBuild(Params* p, std::vector<Anchor>* anchors, sim::MotionPlan* plan) {
  *anchors = PickAnchors(*p, JitteredGrid(8, 9, 0, 0, 55, 40, 1.5, 2.0, 71, 4));
  const std::vector<Eigen::Vector2d> loop = {{5, 5},   {30, 5},  {30, 12}, {12, 12},
                                             {12, 18}, {12, 12}, {5, 12}};
  const double loop_len = sim::PolylineLength(sim::RepeatLoop(loop, 1));
  const int laps = LapsFor(*p, loop_len);
  *plan = sim::MotionPlan(loop[0], 0.0);
  plan->Stop(p->start_still_s);
  plan->WalkWaypoints(sim::RepeatLoop(loop, laps), p->speed_mps, p->corner_radius_m, 1.0);
  plan->Stop(p->end_still_s);
  p->extra["sim.loop_length_m"] = loop_len;
  p->extra["sim.laps"] = laps;
  return Status::Ok();
}

// ------------------------------------------------------------------ two-floor building
// Footprint 40 × 14 m; on each floor a corridor loop and, at the west end, a dog-leg staircase
// (flight, U-turn landing, flight) between floor 0 and floor 1 (simulate.h).
const std::vector<Eigen::Vector2d> kLoopFloor0 = {{6, 2}, {38, 2}, {38, 12}, {6, 12}};
const std::vector<Eigen::Vector2d> kLoopFloor1 = {{6, 3.4}, {6, 2}, {38, 2}, {38, 12}, {6, 12}};
const Eigen::Vector2d kStairFoot(5.0, 2.0);  // floor 0's end of the staircase

void BuildingDefaults(Params* p) {
  p->source = "[walkgraph's own two-floor building; IMU and radio after 000 Sec. IV]";
  p->building = true;
  p->placement = ImuPlacement::kWaist;
  p->imu_rate_hz = 50.0;
  p->laps = 2;
  p->has_laps = true;
  p->start_still_s = 5.0;
  p->end_still_s = 5.0;
  p->noise.acc_noise_mps2 = 5.7575e-2;
  p->gyro_bias_dph = 10.0;
  p->mag = false;
  p->gait.weinberg_k = 0.45;
  p->radio.path_loss = {-60.0, 2.5, 1.0, 5.0, 15.0};
  p->radio.sensitivity = -95.0;
  p->radio.period_s = 1.0;
  p->radio.storey_height_m = 3.5;
  p->num_anchors = 16;
  p->rx_height_offset_m = 1.0;
  p->baro.drift_hpa_per_h = 2.0;
  p->baro.drift_rw_hpa_per_sqrt_h = 0.3;
}

// A straight flight from a to b whose ground rises by rise_m, one tread per step.
std::vector<sim::PathSegment> Flight(const Eigen::Vector2d& a, const Eigen::Vector2d& b,
                                     double rise_m, double tread_m) {
  std::vector<sim::PathSegment> segs = sim::PolylinePath({a, b}, 0.0);
  for (sim::PathSegment& s : segs) {
    s.climb = rise_m / s.length_m;
    s.step_length_m = tread_m;
  }
  return segs;
}

// The staircase, up from kStairFoot or down to it: n = storey / stair_rise_m rises (rounded),
// the first flight from floor 0 ⌊(3n + 2)/5⌋ of them (the landing at 0.6 storey, away from
// the half storey where the floor of a height changes), a 0.6 × 1.4 m U-turn on the landing.
// Returns the segments and the floor-1 end (*top).
std::vector<sim::PathSegment> Staircase(const Params& p, bool up, Eigen::Vector2d* top) {
  const double storey = p.radio.storey_height_m, tread = p.stair_tread_m;
  const int n = std::max(2, static_cast<int>(std::lround(storey / p.stair_rise_m)));
  const int n1 = (3 * n + 2) / 5, n2 = n - n1;
  const double rise = storey / n, x1 = kStairFoot.x() - n1 * tread, xl = x1 - 0.6;
  const double y0 = kStairFoot.y(), y1 = y0 + 1.4;
  *top = Eigen::Vector2d(x1 + n2 * tread, y1);
  std::vector<sim::PathSegment> out;
  auto append = [&out](const std::vector<sim::PathSegment>& v) {
    out.insert(out.end(), v.begin(), v.end());
  };
  if (up) {
    append(Flight(kStairFoot, {x1, y0}, n1 * rise, tread));
    append(sim::PolylinePath({{x1, y0}, {xl, y0}, {xl, y1}, {x1, y1}}, 0.3));
    append(Flight({x1, y1}, *top, n2 * rise, tread));
  } else {
    append(Flight(*top, {x1, y1}, -n2 * rise, tread));
    append(sim::PolylinePath({{x1, y1}, {xl, y1}, {xl, y0}, {x1, y0}}, 0.3));
    append(Flight({x1, y0}, kStairFoot, -n1 * rise, tread));
  }
  return out;
}

// Anchors on both floors: num_anchors split between them (floor 0 gets the odd one), each
// floor's a jittered 2 × 4 grid over the footprint, mounted anchor_mount_m above its floor.
std::vector<Anchor> BuildingAnchors(const Params& p) {
  std::vector<Anchor> out;
  for (int floor = 0; floor < 2; ++floor) {
    Params q = p;
    q.num_anchors = floor == 0 ? (p.num_anchors + 1) / 2 : p.num_anchors / 2;
    if (q.num_anchors == 0) continue;
    const auto grid = JitteredGrid(2, 4, 0, 0, 40, 14, 1.5, p.anchor_mount_m, 8, 5 + floor);
    for (Anchor a : PickAnchors(q, grid)) {
      a.id = static_cast<int>(out.size()) + 1;
      a.floor = floor;
      out.push_back(a);
    }
  }
  return out;
}

// Floor 0: `laps` loops; up the stairs; floor 1: `laps` loops; down; floor 0: `laps` loops.
Status BuildingBuild(Params* p, std::vector<Anchor>* anchors, sim::MotionPlan* plan) {
  *anchors = BuildingAnchors(*p);
  Eigen::Vector2d top;
  std::vector<sim::PathSegment> up = Staircase(*p, true, &top), down = Staircase(*p, false, &top);
  *plan = sim::MotionPlan(kLoopFloor0[0], 0.0);
  plan->Stop(p->start_still_s);
  std::vector<Eigen::Vector2d> w = sim::RepeatLoop(kLoopFloor0, p->laps);
  w.push_back(kStairFoot);
  plan->WalkWaypoints(w, p->speed_mps, p->corner_radius_m, 2.0);
  plan->Walk(up, p->stair_speed_mps, true, true);
  w = {top};
  for (const auto& q : sim::RepeatLoop(kLoopFloor1, p->laps)) w.push_back(q);
  w.push_back(top);
  plan->WalkWaypoints(w, p->speed_mps, p->corner_radius_m, 2.0);
  plan->Walk(down, p->stair_speed_mps, true, true);
  w = {kStairFoot};
  for (const auto& q : sim::RepeatLoop(kLoopFloor0, p->laps)) w.push_back(q);
  plan->WalkWaypoints(w, p->speed_mps, p->corner_radius_m, 2.0);
  plan->Stop(p->end_still_s);
  p->extra["sim.loop_length_m"] = sim::PolylineLength(sim::RepeatLoop(kLoopFloor0, 1));
  p->extra["sim.laps"] = p->laps;
  return Status::Ok();
}

const Preset* FindPreset(const std::string& name) {
  static const std::vector<Preset> more = {
      {"jimenez-building",
       "004: 2200 m² building, 71 RFID tags (RFCode units), 600 m = 8 loops, foot IMU 100 Hz",
       [](Params* p) {
         JimenezDefaults(p);
         p->num_anchors = 71;
       },
       JimenezBuild},
      {"jimenez-building-8tags", "004 Table III: jimenez-building with 8 of the 71 tags",
       [](Params* p) {
         JimenezDefaults(p);
         p->num_anchors = 8;
       },
       JimenezBuild},
      {"two-floor-building",
       "two floors, a dog-leg staircase, 16 anchors with a floor loss, waist IMU 50 Hz, a "
       "drifting barometer",
       BuildingDefaults, BuildingBuild},
  };
  for (const auto& list : {&Presets(), &more}) {
    for (const Preset& p : *list) {
      if (p.name == name) return &p;
    }
  }
  return nullptr;
}

void ReadBuildingKeys(ConfigReader* r, Params* p) {
  r->Read("storey_height_m", &p->radio.storey_height_m);
  r->Read("stair_rise_m", &p->stair_rise_m);
  r->Read("stair_tread_m", &p->stair_tread_m);
  r->Read("stair_speed_mps", &p->stair_speed_mps);
  r->Read("floor_loss_db", &p->radio.path_loss.floor_loss_db);
  r->Read("anchor_mount_m", &p->anchor_mount_m);
  r->Read("baro_rate_hz", &p->baro.rate_hz);
  r->Read("baro_ref_hpa", &p->baro.ref_hpa);
  r->Read("baro_noise_hpa", &p->baro.noise_hpa);
  r->Read("baro_drift_hpa_per_h", &p->baro.drift_hpa_per_h);
  r->Read("baro_drift_rw_hpa_per_sqrt_h", &p->baro.drift_rw_hpa_per_sqrt_h);
}

struct Range {
  const char* key;
  double value, lo, hi;
};
// OK, or "simulate NAME: KEY VALUE outside [LO, HI]" for the first value outside its range.
Status CheckRanges(const std::string& name, std::initializer_list<Range> ranges) {
  for (const Range& r : ranges) {
    if (!(r.value >= r.lo && r.value <= r.hi)) {
      return InvalidArgument("simulate " + name + ": " + r.key + " " + internal::Num(r.value) +
                             " outside [" + internal::Num(r.lo) + ", " + internal::Num(r.hi) + "]");
    }
  }
  return Status::Ok();
}

// The two-floor building's own keys: physical ranges (a staircase that fits between floors,
// a barometer that reads).
Status CheckBuilding(const Params& p) {
  WG_RETURN_IF_ERROR(CheckRanges(
      p.name, {
                  {"storey_height_m", p.radio.storey_height_m, 2.4, 6.0},
                  {"stair_rise_m", p.stair_rise_m, 0.1, 0.25},
                  {"stair_tread_m", p.stair_tread_m, 0.2, 0.4},
                  {"stair_speed_mps", p.stair_speed_mps, 0.2, 1.0},
                  {"floor_loss_db", p.radio.path_loss.floor_loss_db, 0.0, 50.0},
                  {"anchor_mount_m", p.anchor_mount_m, 0.0, 6.0},
                  {"baro_rate_hz", p.baro.rate_hz, 0.1, 200.0},
                  {"baro_ref_hpa", p.baro.ref_hpa, 300.0, 1100.0},
                  {"baro_noise_hpa", p.baro.noise_hpa, 0.0, 1.0},
                  {"baro_drift_hpa_per_h", p.baro.drift_hpa_per_h, 0.0, 20.0},
                  {"baro_drift_rw_hpa_per_sqrt_h", p.baro.drift_rw_hpa_per_sqrt_h, 0.0, 10.0},
              }));
  if (!(p.anchor_mount_m < p.radio.storey_height_m)) {
    return InvalidArgument("simulate " + p.name + ": anchor_mount_m must be below storey_height_m");
  }
  return Status::Ok();
}

// The parameters' ranges once the overrides are read (the building's own in CheckBuilding).
Status CheckParams(const Params& p) {
  if (p.building) WG_RETURN_IF_ERROR(CheckBuilding(p));
  const std::string ctx = "simulate " + p.name + ": ";
  const double max_speed = p.foot_gait == FootGait::kRun ? 6.0 : 3.0;
  if (!(p.speed_mps > 0.1 && p.speed_mps < max_speed)) {
    return InvalidArgument(ctx + "speed_mps must be in (0.1, " + internal::Num(max_speed) + ")");
  }
  if (p.foot_gait == FootGait::kStairs) {
    WG_RETURN_IF_ERROR(CheckRanges(p.name, {{"stair_rise_m", p.stair_rise_m, 0.1, 0.25},
                                            {"stair_tread_m", p.stair_tread_m, 0.2, 0.4}}));
  }
  if (!(p.imu_rate_hz >= 5.0 && p.imu_rate_hz <= 2000.0)) {
    return InvalidArgument(ctx + "imu_rate_hz must be in [5, 2000]");
  }
  // Sizes are checked before anything is allocated (the walk's size is checked again once its
  // duration is known, in SimulateScenarioDetailed).
  if (p.laps < 1 || p.laps > kMaxLaps) {
    return InvalidArgument(ctx + "laps must be in [1, " + std::to_string(kMaxLaps) + "]");
  }
  if (!(p.duration_s >= 0.0 && p.duration_s <= kMaxDurationS) ||
      !(p.start_still_s >= 0.0 && p.start_still_s <= 3600.0) ||
      !(p.end_still_s >= 0.0 && p.end_still_s <= 3600.0)) {
    return InvalidArgument(ctx + "duration_s must be in [0, " + internal::Num(kMaxDurationS) +
                           "] s, start_still_s and end_still_s in [0, 3600] s");
  }
  if (p.num_anchors > kMaxAnchors) {
    return InvalidArgument(ctx + "num_anchors must be in [0, " + std::to_string(kMaxAnchors) + "]");
  }
  if (!(p.radio.period_s >= 0.01 && p.radio.period_s <= 3600.0)) {
    return InvalidArgument(ctx + "beacon_period_s must be in [0.01, 3600] s");
  }
  const PathLossParams& pl = p.radio.path_loss;
  if (!(pl.eta > 0.0) || !(pl.sigma_db > 0.0) || !(p.radio.period_s > 0.0)) {
    return InvalidArgument(ctx + "eta, sigma_db and beacon_period_s must be > 0");
  }
  // Physical plausibility: beyond these the simulated readings fail the walk's own validation.
  const bool rfcode = p.radio.units == RssUnits::kRfcode;  // 004's units: larger is weaker
  WG_RETURN_IF_ERROR(
      CheckRanges(p.name, {
                              {"A_dbm", pl.A_dbm, rfcode ? 0.0 : -150.0, rfcode ? 300.0 : 30.0},
                              {"eta", pl.eta, 0.0, 10.0},
                              {"sigma_db", pl.sigma_db, 0.0, 50.0},
                              {"A_spread_db", p.radio.A_spread_db, 0.0, 50.0},
                              {"eta_spread", p.radio.eta_spread, 0.0, 5.0},
                              {"acc_noise_mps2", p.noise.acc_noise_mps2, 0.0, 10.0},
                              {"gyro_noise_radps", p.noise.gyro_noise_radps, 0.0, 5.0},
                              {"acc_bias_sigma_mps2", p.noise.acc_bias_sigma_mps2, 0.0, 10.0},
                              {"gyro_bias_sigma_radps", p.noise.gyro_bias_sigma_radps, 0.0, 5.0},
                              {"gyro_bias_dph", p.gyro_bias_dph, -36000.0, 36000.0},
                              {"mag_noise_ut", p.noise.mag_noise_ut, 0.0, 1000.0},
                              {"mag_disturbance_ut", p.field.disturbance_ut, 0.0, 1000.0},
                              {"weinberg_k", p.gait.weinberg_k, 0.0, 2.0},
                          }));
  if (p.radio.nlos.fraction < 0.0 || p.radio.nlos.fraction > 1.0) {
    return InvalidArgument(ctx + "nlos_fraction must be in [0, 1]");
  }
  if (p.num_anchors < 0 || p.field.disturbance_count < 0 || p.field.disturbance_count > 1000) {
    return InvalidArgument(ctx + "num_anchors and mag_disturbance_count must be >= 0");
  }
  if (!(p.gait.weinberg_k > 0.0) || !(p.sigma_xy_m > 0.0) || !(p.sigma_heading_deg > 0.0)) {
    return InvalidArgument(ctx + "weinberg_k and initial sigmas must be > 0");
  }
  if (!(p.run_length_m >= 10.0 && p.run_length_m <= 20000.0) ||
      !(0.0 <= p.outage_start_frac && p.outage_start_frac <= p.outage_end_frac &&
        p.outage_end_frac <= 1.0)) {
    return InvalidArgument(ctx +
                           "run_length_m in [10, 20000], 0 <= outage_start_frac <= "
                           "outage_end_frac <= 1");
  }
  if (!(p.stance_fraction >= 0.1 && p.stance_fraction <= 0.7)) {
    return InvalidArgument(ctx + "stance_fraction must be in [0.1, 0.7]");
  }
  return Status::Ok();
}

// A foot preset's gait and the defaults it brings, which the other keys may then override:
// running 3 m/s with a short foot-flat (a fifth of the stride), a higher lift and more pitch;
// stairs at the building's stair speed (horizontal), treads of stair_tread_m. The numbers are
// typical values (running stance ~0.2-0.3 s of a ~0.7 s stride; foot-flat shorter), not fitted
// to any recording.
void ReadGait(ConfigReader* r, Params* p) {
  r->ReadEnum("gait", &p->foot_gait, kFootGaitNames);
  if (p->foot_gait == FootGait::kRun) {
    p->speed_mps = 3.0;
    p->stance_fraction = 0.2;
    p->lift_m = 0.15;
    p->pitch_amplitude_deg = 45.0;
  } else if (p->foot_gait == FootGait::kStairs) {
    p->speed_mps = p->stair_speed_mps;
  }
}

Status ReadOverrides(const YAML::Node& node, Params* p) {
  ConfigReader r(node, "simulate " + p->name);
  if (p->foot) ReadGait(&r, p);
  r.Read("speed_mps", &p->speed_mps);
  r.Read("duration_s", &p->duration_s);
  r.Read("start_still_s", &p->start_still_s);
  r.Read("end_still_s", &p->end_still_s);
  r.Read("imu_rate_hz", &p->imu_rate_hz);
  r.Read("acc_noise_mps2", &p->noise.acc_noise_mps2);
  r.Read("gyro_noise_radps", &p->noise.gyro_noise_radps);
  r.Read("acc_bias_sigma_mps2", &p->noise.acc_bias_sigma_mps2);
  r.Read("gyro_bias_sigma_radps", &p->noise.gyro_bias_sigma_radps);
  r.Read("gyro_bias_dph", &p->gyro_bias_dph);
  r.Read("acc_bias_rw", &p->noise.acc_bias_rw_mps2_sqrts);
  r.Read("gyro_bias_rw", &p->noise.gyro_bias_rw_radps_sqrts);
  r.Read("mag_noise_ut", &p->noise.mag_noise_ut);
  r.Read("mag_disturbance_ut", &p->field.disturbance_ut);
  r.Read("mag_disturbance_count", &p->field.disturbance_count);
  r.Read("weinberg_k", &p->gait.weinberg_k);
  r.Read("num_anchors", &p->num_anchors);
  r.Read("A_dbm", &p->radio.path_loss.A_dbm);
  r.Read("eta", &p->radio.path_loss.eta);
  r.Read("sigma_db", &p->radio.path_loss.sigma_db);
  r.Read("A_spread_db", &p->radio.A_spread_db);
  r.Read("eta_spread", &p->radio.eta_spread);
  r.Read("sensitivity", &p->radio.sensitivity);
  r.Read("use_sensitivity", &p->radio.use_sensitivity);
  r.Read("beacon_period_s", &p->radio.period_s);
  r.Read("detection_p_max", &p->radio.detection.p_max);
  r.Read("detection_d50_m", &p->radio.detection.d50_m);
  r.Read("detection_width_m", &p->radio.detection.width_m);
  r.Read("nlos_fraction", &p->radio.nlos.fraction);
  r.Read("nlos_episode_s", &p->radio.nlos.mean_episode_s);
  r.Read("nlos_rss_bias_db", &p->radio.nlos.rss_bias_db);
  r.Read("initial_sigma_xy_m", &p->sigma_xy_m);
  r.Read("initial_sigma_heading_deg", &p->sigma_heading_deg);
  if (p->has_laps) r.Read("laps", &p->laps);
  if (p->toa_on) {
    r.Read("toa_sigma_m", &p->radio.toa_sigma_m);
    r.Read("toa_alpha_m", &p->radio.toa_alpha_m);
    r.Read("toa_beta", &p->radio.toa_beta);
    r.Read("nlos_range_bias_m", &p->radio.nlos.range_bias_m);
  }
  if (p->name == "gadeke-outage") {
    r.Read("run_length_m", &p->run_length_m);
    r.Read("outage_start_frac", &p->outage_start_frac);
    r.Read("outage_end_frac", &p->outage_end_frac);
  }
  if (p->foot) r.Read("stance_fraction", &p->stance_fraction);
  if (p->foot_gait == FootGait::kStairs) {
    r.Read("stair_rise_m", &p->stair_rise_m);
    r.Read("stair_tread_m", &p->stair_tread_m);
  }
  if (p->building) ReadBuildingKeys(&r, p);
  WG_RETURN_IF_ERROR(r.Finish());
  return CheckParams(*p);
}

// ------------------------------------------------------------------ linear-gaussian

StatusOr<Simulation> SimulateLinearGaussian(uint64_t seed, const YAML::Node& overrides) {
  double duration_s = 60.0, step_period_s = 0.5, step_sigma_m = 0.05, range_sigma_m = 0.3;
  double heading_deg = 30.0;
  int range_every = 2;
  ConfigReader r(overrides, "simulate linear-gaussian");
  r.Read("duration_s", &duration_s);
  r.Read("step_period_s", &step_period_s);
  r.Read("step_sigma_m", &step_sigma_m);
  r.Read("range_sigma_m", &range_sigma_m);
  r.Read("heading_deg", &heading_deg);
  r.Read("range_every", &range_every);
  WG_RETURN_IF_ERROR(r.Finish());
  if (!(duration_s >= 1.0 && duration_s <= 3600.0) || !(step_period_s >= 0.1) ||
      !(step_sigma_m > 0.0 && step_sigma_m <= 0.1) || !(range_sigma_m > 0.0) || range_every < 1) {
    return InvalidArgument(
        "simulate linear-gaussian: need 1 <= duration_s <= 3600, "
        "step_period_s >= 0.1, 0 < step_sigma_m <= 0.1, range_sigma_m > 0, "
        "range_every >= 1");
  }
  Rng rng(seed);
  Rng step_rng = rng.Fork(1), range_rng = rng.Fork(2);
  const double h = DegToRad(heading_deg);
  const Eigen::Vector2d u(std::cos(h), std::sin(h)), start(2.0, 3.0);
  const int n = static_cast<int>(std::floor(duration_s / step_period_s + 1e-9));
  const double rate = 1.0 / step_period_s;
  Simulation s;
  Walk& w = s.walk;
  double along = 0.0;
  std::vector<double> along_at(n + 1, 0.0);
  for (int k = 1; k <= n; ++k) {
    const double l = 0.7 + 0.1 * std::sin(2.0 * kPi * k / 20.0);
    along += l;
    along_at[k] = along;
    // d_k = l_k + N(0, σ_d²); with σ_d ≤ 0.1 m the step stays positive (≥ 5σ margin).
    const double d = Q(l + step_rng.Gaussian(0.0, step_sigma_m), 1e-6);
    w.odometry.push_back({k / rate, d, 0.0});
  }
  const double behind = 10.0, beyond = along + 10.0;
  w.anchors = {{1,
                Eigen::Vector3d(Q(start.x() - behind * u.x(), 1e-9),
                                Q(start.y() - behind * u.y(), 1e-9), 0.0),
                std::nullopt},
               {2,
                Eigen::Vector3d(Q(start.x() + beyond * u.x(), 1e-9),
                                Q(start.y() + beyond * u.y(), 1e-9), 0.0),
                std::nullopt}};
  for (int k = 0; k <= n; ++k) {
    const Eigen::Vector2d p = start + along_at[k] * u;
    w.truth.push_back(
        {k / rate, Eigen::Vector3d(Q(p.x(), 1e-9), Q(p.y(), 1e-9), 0.0), false, std::nullopt});
    if (k > 0 && k % range_every == 0) {
      // Ranges measured along the line: affine in the along-track coordinate.
      const double r1 = behind + along_at[k] + range_rng.Gaussian(0.0, range_sigma_m);
      const double r2 = beyond - along_at[k] + range_rng.Gaussian(0.0, range_sigma_m);
      w.ranges.push_back({k / rate, 1, Q(std::max(0.0, r1), 1e-6)});
      w.ranges.push_back({k / rate, 2, Q(std::max(0.0, r2), 1e-6)});
    }
  }
  WalkMeta& m = w.meta;
  m.name = "linear-gaussian";
  m.source = "walkgraph simulate --scenario linear-gaussian --seed " + std::to_string(seed);
  m.licence = "CC0-1.0";
  m.truth_kind = TruthKind::kContinuous;
  m.radio.kind = RadioKind::kRange;
  m.radio.calibrated = true;
  m.radio.range_sigma_m = range_sigma_m;
  m.initial_pose = InitialPose{start.x(), start.y(), h, 0.5, 1e-6, true, std::nullopt};
  m.extra["sim.seed"] = static_cast<double>(seed);
  m.extra["sim.step_sigma_m"] = step_sigma_m;
  m.extra["sim.range_sigma_m"] = range_sigma_m;
  m.extra["sim.heading_rad"] = h;
  m.extra["sim.anchor_behind_m"] = behind;
  m.extra["sim.anchor_beyond_m"] = beyond;
  return s;
}

// Truth at every IMU sample (foot walks: and stance labels); the building's floors: the floor
// whose level is nearest (the estimators' rule), so on the stairs it changes at half a storey.
void AddTruth(const std::vector<sim::ImuTruth>& imu_truth, const Params& p, Walk* w) {
  for (const auto& t : imu_truth) {
    TruthSample ts;
    ts.t_s = t.t_s;
    ts.has_z = p.foot || p.building;
    for (int i = 0; i < 3; ++i) ts.position_m[i] = Q(t.position_n[i], 1e-6);
    if (p.building) {
      ts.floor = static_cast<int>(std::lround(t.position_n.z() / p.radio.storey_height_m));
    }
    w->truth.push_back(ts);
    if (p.foot) w->stance_truth.push_back({t.t_s, t.stance});
  }
}

// The two-floor building's barometer at the receiver (the waist) above floor 0, into
// walk.pressure; its numbers and the stairs' into p->extra.
void AddBarometer(const sim::MotionPlan& plan, double t_end, Rng rng, Params* p, Walk* w) {
  const sim::MotionPlan* pl = &plan;
  const double dz = p->rx_height_offset_m;
  auto baro = sim::SimulateBarometer([pl, dz](double t) { return pl->At(t).z_m + dz; }, 0.0, t_end,
                                     p->baro, rng);
  w->pressure = std::move(baro.pressure);
  auto& x = p->extra;
  x["sim.baro_drift_rate_hpa_per_h"] = baro.drift_rate_hpa_per_h;
  x["sim.baro_drift_end_hpa"] = baro.drift_hpa.empty() ? 0.0 : baro.drift_hpa.back();
  x["sim.baro_rate_hz"] = p->baro.rate_hz;
  x["sim.baro_ref_hpa"] = p->baro.ref_hpa;
  x["sim.baro_noise_hpa"] = p->baro.noise_hpa;
  x["sim.baro_drift_rw_hpa_per_sqrt_h"] = p->baro.drift_rw_hpa_per_sqrt_h;
  const double storey = p->radio.storey_height_m;
  x["sim.stair_rise_m"] = storey / std::max(2L, std::lround(storey / p->stair_rise_m));
  x["sim.stair_tread_m"] = p->stair_tread_m;
  x["sim.stair_speed_mps"] = p->stair_speed_mps;
}

}  // namespace

std::vector<ScenarioInfo> Scenarios() {
  std::vector<ScenarioInfo> out;
  for (const Preset& p : Presets()) out.push_back({p.name, p.description});
  for (const char* name : {"jimenez-building", "jimenez-building-8tags", "two-floor-building"}) {
    const Preset* p = FindPreset(name);
    out.push_back({p->name, p->description});
  }
  out.push_back({"linear-gaussian",
                 "straight walk, known heading, odometry + ranges to anchors on the line: "
                 "an exactly linear-Gaussian problem (KF+RTS == batch tests)"});
  return out;
}

namespace {

// The IMU's true motion and noiseless readings (foot presets: the foot, whose model the radio
// then needs too, returned; else the waist, with its steps).
std::unique_ptr<sim::FootMotion> SimulateImuTruth(const Params& p, const sim::MotionPlan& plan,
                                                  Simulation* sim) {
  Simulation& s = *sim;
  std::unique_ptr<sim::FootMotion> foot;
  if (p.foot) {
    sim::FootImuOptions fo;
    fo.rate_hz = p.imu_rate_hz;
    fo.gait = p.gait;
    fo.stance_fraction = p.stance_fraction;
    fo.lift_m = p.lift_m;
    fo.pitch_amplitude_deg = p.pitch_amplitude_deg;
    if (p.foot_gait == FootGait::kStairs) {
      fo.stair_rise_m = p.stair_rise_m;
      fo.stair_tread_m = p.stair_tread_m;
    }
    foot = std::make_unique<sim::FootMotion>(plan, fo);
    s.imu_truth = sim::SampleFootImu(*foot, p.imu_rate_hz);
  } else {
    sim::WaistImuOptions wo;
    wo.rate_hz = p.imu_rate_hz;
    wo.gait = p.gait;
    wo.device_yaw_rad = DegToRad(p.device_yaw_deg);
    wo.forward_swing_mps2 = p.forward_swing_mps2;
    wo.hand_shake_mps2 = p.hand_shake_mps2;
    auto waist = sim::SimulateWaistImu(plan, wo);
    // The truth: the walked path on the ground (its height changes on stairs only).
    for (auto& t : waist.truth) t.position_n.z() -= wo.height_m;
    s.imu_truth = std::move(waist.truth);
    s.steps = std::move(waist.steps);
  }
  return foot;
}

// The walk's metadata: where it comes from, its radio model, the true start (initial_pose)
// and, in extra, the simulator's numbers (sim.*).
void SetMeta(const std::string& name, uint64_t seed, const Params& p, const sim::MotionPlan& plan,
             size_t num_anchors, double t_end, Simulation* sim) {
  const Simulation& s = *sim;
  WalkMeta& m = sim->walk.meta;
  m.name = name;
  m.source = "walkgraph simulate --scenario " + name + " --seed " + std::to_string(seed) +
             "; follows " + p.source;
  m.licence = "CC0-1.0";
  m.imu_placement = p.placement;
  m.truth_kind = TruthKind::kContinuous;
  m.radio.kind = RadioKind::kRss;
  m.radio.units = p.radio.units;
  m.radio.path_loss = p.radio.path_loss;
  // Calibrated: the readings were drawn from this model — unless the anchors spread around it
  // (A_spread_db, eta_spread), when the declared model is only their mean.
  m.radio.calibrated = p.radio.A_spread_db == 0.0 && p.radio.eta_spread == 0.0;
  m.radio.range_sigma_m = p.radio.toa_sigma_m;
  const sim::BodyState b0 = plan.At(0.0);
  m.initial_pose = InitialPose{Q(s.imu_truth.front().position_n.x(), 1e-6),
                               Q(s.imu_truth.front().position_n.y(), 1e-6),
                               NormalizeAngle(b0.heading_rad),
                               p.sigma_xy_m,
                               DegToRad(p.sigma_heading_deg),
                               true,
                               p.building ? std::optional<int>(0) : std::nullopt};
  auto& x = m.extra;
  x = p.extra;
  x["sim.seed"] = static_cast<double>(seed);
  x["sim.speed_mps"] = p.speed_mps;
  x["sim.step_length_m"] = sim::StepLength(p.gait, p.speed_mps);
  x["sim.step_frequency_hz"] = sim::StepFrequency(p.gait, p.speed_mps);
  x["sim.weinberg_k"] = p.gait.weinberg_k;
  x["sim.imu_rate_hz"] = p.imu_rate_hz;
  x["sim.imu_interval_average"] = p.foot ? 1.0 : 0.0;
  x["sim.acc_noise_mps2"] = p.noise.acc_noise_mps2;
  x["sim.gyro_noise_radps"] = p.noise.gyro_noise_radps;
  x["sim.acc_bias_sigma_mps2"] = p.noise.acc_bias_sigma_mps2;
  x["sim.gyro_bias_sigma_radps"] = p.noise.gyro_bias_sigma_radps;
  x["sim.gyro_bias_fixed_radps"] = DegToRad(p.gyro_bias_dph) / 3600.0;
  x["sim.gravity_mps2"] = sim::kGravityMps2;
  x["sim.num_anchors"] = static_cast<double>(num_anchors);
  x["sim.beacon_period_s"] = p.radio.period_s;
  x["sim.sensitivity"] = p.radio.sensitivity;
  x["sim.nlos_fraction"] = p.radio.nlos.fraction;
  x["sim.rx_height_offset_m"] = p.rx_height_offset_m;
  x["sim.duration_s"] = t_end;
  if (p.radio.detection.d50_m > 0.0) x["sim.detection_d50_m"] = p.radio.detection.d50_m;
  if (p.foot) {
    x["sim.stance_fraction"] = p.stance_fraction;
    x["sim.foot_lift_m"] = p.lift_m;
    if (p.foot_gait == FootGait::kRun) x["sim.gait_run"] = 1.0;
    if (p.foot_gait == FootGait::kStairs) {
      x["sim.stair_rise_m"] = p.stair_rise_m;
      x["sim.step_length_m"] = p.stair_tread_m;
      x["sim.step_frequency_hz"] = p.speed_mps / p.stair_tread_m;
    }
  }
  if (p.toa_on) {
    x["sim.toa_alpha_m"] = p.radio.toa_alpha_m;
    x["sim.toa_beta"] = p.radio.toa_beta;
  }
}

}  // namespace

StatusOr<Simulation> SimulateScenarioDetailed(const std::string& name, uint64_t seed,
                                              const Config& config) {
  const YAML::Node& overrides = config.node();
  if (name == "linear-gaussian") return SimulateLinearGaussian(seed, overrides);
  const Preset* preset = FindPreset(name);
  if (preset == nullptr) {
    std::string names;
    for (const auto& s : Scenarios()) names += (names.empty() ? "" : ", ") + s.name;
    return NotFound("unknown scenario " + internal::Quoted(name) + "; known: " + names);
  }
  Params p;
  p.name = name;
  preset->defaults(&p);
  WG_RETURN_IF_ERROR(ReadOverrides(overrides, &p));
  p.noise.gyro_bias_fixed_radps = Eigen::Vector3d::Constant(DegToRad(p.gyro_bias_dph) / 3600.0);
  std::vector<Anchor> anchors;
  sim::MotionPlan plan(Eigen::Vector2d::Zero(), 0.0);
  WG_RETURN_IF_ERROR(preset->build(&p, &anchors, &plan));
  const double t_end =
      p.duration_s > 0.0 ? std::min(p.duration_s, plan.duration()) : plan.duration();
  if (t_end * p.imu_rate_hz > kMaxImuSamples) {
    return InvalidArgument("simulate " + name + ": the walk would last " + internal::Num(t_end) +
                           " s, " + internal::Num(t_end * p.imu_rate_hz) + " IMU samples at " +
                           internal::Num(p.imu_rate_hz) + " Hz; at most " +
                           internal::Num(kMaxImuSamples) + " (shorten duration_s or laps)");
  }
  if (t_end / p.radio.period_s * static_cast<double>(anchors.size()) > kMaxRadioReadings) {
    return InvalidArgument("simulate " + name + ": " + std::to_string(anchors.size()) +
                           " anchors every " + internal::Num(p.radio.period_s) + " s for " +
                           internal::Num(t_end) + " s exceed " + internal::Num(kMaxRadioReadings) +
                           " readings");
  }

  Rng rng(seed);
  Simulation s;
  // IMU truth, then errors.
  std::unique_ptr<sim::FootMotion> foot = SimulateImuTruth(p, plan, &s);
  while (!s.imu_truth.empty() && s.imu_truth.back().t_s > t_end + 1e-9) s.imu_truth.pop_back();
  while (!s.steps.empty() && s.steps.back().t_s > t_end) s.steps.pop_back();
  sim::MagneticFieldOptions field_options = p.field;
  std::unique_ptr<sim::MagneticField> field;
  if (p.mag) field = std::make_unique<sim::MagneticField>(field_options, rng.Fork(10));
  Walk& w = s.walk;
  w.imu = sim::ApplyImuErrors(s.imu_truth, p.noise, field.get(), rng.Fork(11));
  for (ImuSample& m : w.imu) {
    for (int i = 0; i < 3; ++i) {
      m.acc_mps2[i] = Q(m.acc_mps2[i], 1e-6);
      m.gyro_radps[i] = Q(m.gyro_radps[i], 1e-7);
      if (m.has_mag) m.mag_ut[i] = Q(m.mag_ut[i], 1e-4);
    }
  }
  AddTruth(s.imu_truth, p, &w);

  // Radio, received at the walker (foot presets: plus rx_height_offset_m above the foot).
  w.anchors = anchors;
  sim::ReceiverTrack rx;
  if (p.foot) {
    const sim::FootMotion* f = foot.get();
    const double dz = p.rx_height_offset_m;
    rx = [f, dz](double t) {
      return Eigen::Vector3d(f->At(t).position_n + Eigen::Vector3d(0, 0, dz));
    };
  } else {
    const sim::MotionPlan* pl = &plan;
    const double dz = p.rx_height_offset_m;
    rx = [pl, dz](double t) {
      const sim::BodyState b = pl->At(t);
      return Eigen::Vector3d(b.position_m.x(), b.position_m.y(), b.z_m + dz);
    };
  }
  if (p.name == "gadeke-outage") {
    p.radio.outages_s = {{p.outage_start_frac * t_end, p.outage_end_frac * t_end}};
    p.extra["sim.outage_start_s"] = p.outage_start_frac * t_end;
    p.extra["sim.outage_end_s"] = p.outage_end_frac * t_end;
  }
  // Anchors with a floor are mounted above it: the radio sees them at their height.
  if (p.building) w.meta.storey_height_m = p.radio.storey_height_m;
  std::vector<Anchor> placed = anchors;
  for (Anchor& a : placed) a.position_m.z() = w.AnchorHeightM(a);
  if (p.rss_on) {
    auto radio = sim::SimulateRss(placed, rx, 0.0, t_end, p.radio, rng.Fork(20));
    w.rss = std::move(radio.rss);
    s.rss_emissions = std::move(radio.emissions);
    s.per_anchor = std::move(radio.per_anchor);
  }
  if (p.toa_on) {
    auto radio = sim::SimulateToa(placed, rx, 0.0, t_end, p.radio, rng.Fork(20));
    w.ranges = std::move(radio.ranges);
    s.range_emissions = std::move(radio.emissions);
  }

  if (p.building) AddBarometer(plan, t_end, rng.Fork(30), &p, &w);

  SetMeta(name, seed, p, plan, anchors.size(), t_end, &s);
  return s;
}

StatusOr<Walk> SimulateScenario(const std::string& name, uint64_t seed, const Config& overrides) {
  WG_ASSIGN_OR_RETURN(Simulation s, SimulateScenarioDetailed(name, seed, overrides));
  return std::move(s.walk);
}

}  // namespace walkgraph
