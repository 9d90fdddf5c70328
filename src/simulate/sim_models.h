// Building blocks of the walk simulator (internal; simulate.h assembles them into the papers'
// scenarios, sim_truth.h holds the truth records a Simulation returns).
//
// Frames: ENU navigation frame n (x east, y north, z up); body frame b of an IMU: x forward,
// y left, z up when the wearer stands level. Rotations are body→nav (R_nb, q_nb).
// Specific force f_b = R_nbᵀ (a_n − g_n) with g_n = (0, 0, −g): a resting IMU reads +g on z.
//
// Walker: a MotionPlan is a time line of phases — legs (walk along straight/arc segments with a
// raised-cosine speed ramp from/to rest), stops, and turns in place. Everything is analytic in t.
//
// Gait (000 Sec. IV): step length l = 0.32 + 0.26·v (000's least-squares fit), step frequency
// f = v / l, step phase φ(t) = ∫ f dt (a step at each integer φ). Waist/hip vertical acceleration
// a_z = A·sin(2πφ) with A = (l/K)⁴ / 2 — Weinberg (000 eq. 3) inverted, so that
// a_max − a_min = (l/K)⁴ over each step.
//
// Foot (right foot): footprints every stride (2 steps) along each leg; during stance the foot
// is flat and still; the swing from footprint k to k+1 uses polynomials whose first four
// derivatives vanish at both ends: progress σ(u) = 126u⁵−420u⁶+540u⁷−315u⁸+70u⁹, lift
// h·(4u(1−u))⁵, pitch Θ·(4u(1−u))⁵·sin(2πu)/c (toe-off nose down, heel strike nose up),
// yaw ψ_k + Δψ·σ(u). R_nb = Rz(ψ)·Ry(θ).
//
// Radio: log-distance RSS (PathLossModel) per emission, minus a floor loss per floor slab
// between anchor and receiver, per-anchor A/η spread, NLOS episodes
// (two-state Markov chain per anchor), outage windows, logistic detection probability
// p(d) = p_max / (1 + exp((d − d50)/w)), sensitivity threshold; TOA ranges z = α + β·d + n
// (002 eq. 6) with exponential NLOS bias.
#ifndef WALKGRAPH_SRC_SIMULATE_SIM_MODELS_H_
#define WALKGRAPH_SRC_SIMULATE_SIM_MODELS_H_

#include <cstdint>
#include <functional>
#include <random>
#include <utility>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "walkgraph/path_loss.h"
#include "walkgraph/sim_truth.h"
#include "walkgraph/walk.h"

namespace walkgraph {
namespace sim {

inline constexpr double kGravityMps2 = 9.81;  // also StrapdownOptions' default

// ------------------------------------------------------------------ random numbers
// mt19937_64 with its own uniform/Gaussian transforms, so a seed gives the same numbers with
// every standard library. Fork(stream) derives an independent generator (SplitMix64 of seed and
// stream), so e.g. the radio noise does not change when the IMU options change.
class Rng {
 public:
  explicit Rng(uint64_t seed);
  double Uniform();  // [0, 1)
  double Uniform(double a, double b) { return a + (b - a) * Uniform(); }
  double Gaussian();  // N(0, 1), Box–Muller
  double Gaussian(double mean, double sigma) { return mean + sigma * Gaussian(); }
  double Exponential(double mean);
  bool Bernoulli(double p) { return Uniform() < p; }
  Rng Fork(uint64_t stream) const;
  uint64_t seed() const { return seed_; }

 private:
  uint64_t seed_;
  std::mt19937_64 engine_;
};

// ------------------------------------------------------------------ trajectory
// A straight line (curvature 0) or a circular arc, parametrized by arc length s ∈ [0, length].
struct PathSegment {
  Eigen::Vector2d start = Eigen::Vector2d::Zero();
  double heading0_rad = 0.0;
  double length_m = 0.0;
  double curvature_1pm = 0.0;  // > 0 turns left (counter-clockwise)
  // Stairs: the ground rises by climb per metre along the segment (negative: down), and each
  // step moves step_length_m (a tread) instead of the gait model's length (0: level ground).
  double climb = 0.0;
  double step_length_m = 0.0;
  Eigen::Vector2d PositionAt(double s) const;
  double HeadingAt(double s) const { return heading0_rad + curvature_1pm * s; }
};

// `laps` full circles of radius r around `center`, starting at angle `start_angle_rad`,
// counter-clockwise when ccw.
std::vector<PathSegment> CirclePath(const Eigen::Vector2d& center, double radius_m,
                                    double start_angle_rad, double laps, bool ccw = true);

// One leg through the waypoints; corners are rounded with arcs of radius corner_radius_m
// (shrunk when the adjacent lines are short). Turns sharper than 179° are not allowed here
// (SplitAtSharpTurns handles them as turns in place).
std::vector<PathSegment> PolylinePath(const std::vector<Eigen::Vector2d>& waypoints,
                                      double corner_radius_m);

// Splits a waypoint list where the heading changes by more than max_turn_rad: each piece is
// walked as its own leg, separated by a stop and a turn in place.
std::vector<std::vector<Eigen::Vector2d>> SplitAtSharpTurns(
    const std::vector<Eigen::Vector2d>& waypoints, double max_turn_rad);

// `laps` repetitions of a closed polygon (the first waypoint is not repeated in `polygon`).
std::vector<Eigen::Vector2d> RepeatLoop(const std::vector<Eigen::Vector2d>& polygon, int laps);

// Axis-aligned rectangle loop [x0, x0+w] × [y0, y0+h], counter-clockwise from (x0, y0).
std::vector<Eigen::Vector2d> RectangleLoop(double x0, double y0, double w, double h);

// Length of a polyline.
double PolylineLength(const std::vector<Eigen::Vector2d>& waypoints);

struct BodyState {
  double t_s = 0.0;
  Eigen::Vector2d position_m = Eigen::Vector2d::Zero();
  double heading_rad = 0.0;  // direction of travel (continuous, not wrapped)
  double speed_mps = 0.0;
  double accel_mps2 = 0.0;      // dv/dt along the heading
  double yaw_rate_radps = 0.0;  // dψ/dt
  double curvature_1pm = 0.0;
  bool moving = false;
  // Height of the ground under the walker above the plan's start (stairs change it) and its
  // first two time derivatives.
  double z_m = 0.0, vz_mps = 0.0, az_mps2 = 0.0;
  // > 0 on stairs: every step moves the walker this far horizontally (a tread) instead of the
  // gait model's length.
  double step_length_m = 0.0;
};

class MotionPlan {
 public:
  enum class PhaseKind { kLeg, kStop, kTurn };
  struct Phase {
    PhaseKind kind = PhaseKind::kStop;
    double t0_s = 0.0, t1_s = 0.0;
    Eigen::Vector2d start = Eigen::Vector2d::Zero();
    double heading0_rad = 0.0;
    // Leg
    std::vector<PathSegment> segments;
    std::vector<double> cumulative_m;  // start arc length of each segment
    double length_m = 0.0, cruise_mps = 0.0, ramp_up_s = 0.0, ramp_down_s = 0.0;
    // Turn
    double dheading_rad = 0.0;
    // Height of the ground at the phase's start; a leg's height change before each segment.
    double z0_m = 0.0;
    std::vector<double> cumulative_z_m;
  };

  MotionPlan(const Eigen::Vector2d& start, double heading_rad);

  // Walks along `segments` (which must start at the current position) at `speed_mps`, with a
  // raised-cosine speed ramp of ramp_s from rest (from_rest) and to rest (to_rest).
  // Segments with a climb change the ground's height (stairs).
  void Walk(std::vector<PathSegment> segments, double speed_mps, bool from_rest, bool to_rest,
            double ramp_s = 1.5);
  void Stop(double duration_s);
  // Turns by dheading (radians, signed) in place, raised-cosine heading profile.
  void Turn(double dheading_rad, double duration_s);
  // Walks a waypoint list (starting at the current position): legs between sharp turns
  // (> 120°), each from rest to rest, with a stop of pause_s and a turn in place between them.
  void WalkWaypoints(const std::vector<Eigen::Vector2d>& waypoints, double speed_mps,
                     double corner_radius_m, double pause_s);

  double duration() const { return phases_.empty() ? 0.0 : phases_.back().t1_s; }
  const std::vector<Phase>& phases() const { return phases_; }
  Eigen::Vector2d end_position() const { return position_; }
  double end_heading() const { return heading_; }
  double end_height() const { return height_; }
  BodyState At(double t_s) const;
  // Arc length walked within a leg phase at local time tau (and speed, accel).
  static void LegProfile(const Phase& leg, double tau, double* s, double* v, double* a);

 private:
  std::vector<Phase> phases_;
  Eigen::Vector2d position_;
  double heading_;
  double height_ = 0.0;
};

// ------------------------------------------------------------------ gait
struct GaitOptions {
  double step_length_a_m = 0.32;  // l = a + b·v (000 Sec. IV)
  double step_length_b_s = 0.26;
  double weinberg_k = 0.45;            // K of 000 eq. 3 (000 Sec. IV: 0.45)
  double walking_speed_min_mps = 0.3;  // below this the step amplitude fades out smoothly
};
double StepLength(const GaitOptions& g, double speed_mps);
double StepFrequency(const GaitOptions& g, double speed_mps);
// Amplitude A of the vertical sinusoid: A = (l/K)⁴ / 2.
double StepAmplitude(const GaitOptions& g, double step_length_m);

// ------------------------------------------------------------------ IMU error model
struct ImuNoiseOptions {
  double acc_noise_mps2 = 0.0;  // white, per sample, each axis
  double gyro_noise_radps = 0.0;
  double acc_bias_sigma_mps2 = 0.0;  // turn-on bias ~ N(0, σ²) per axis
  double gyro_bias_sigma_radps = 0.0;
  Eigen::Vector3d gyro_bias_fixed_radps = Eigen::Vector3d::Zero();  // added deterministically
  double acc_bias_rw_mps2_sqrts = 0.0;                              // bias random walk density
  double gyro_bias_rw_radps_sqrts = 0.0;
  double mag_noise_ut = 0.0;
  double gyro_rate_hz = 0.0;  // > 0: gyro sampled at this rate and held (001: 15 Hz)
  double mag_rate_hz = 0.0;   // > 0: magnetometer sampled at this rate and held
};

// Earth field plus indoor disturbances: Gaussian blobs of random direction around fixed points.
struct MagneticFieldOptions {
  double field_ut = 45.0;         // total intensity (Madrid ≈ 45 µT)
  double inclination_deg = 58.0;  // dip, positive downwards
  double declination_deg = 0.0;   // magnetic north east of true north (y)
  double disturbance_ut = 0.0;    // peak magnitude of each disturbance blob
  int disturbance_count = 0;
  double disturbance_radius_m = 2.0;
  Eigen::Vector2d area_min = Eigen::Vector2d::Zero();  // blob centres drawn in this box
  Eigen::Vector2d area_max = Eigen::Vector2d(20, 20);
};

class MagneticField {
 public:
  MagneticField(const MagneticFieldOptions& options, Rng rng);
  Eigen::Vector3d At(const Eigen::Vector3d& position_n) const;  // nav frame, µT
  Eigen::Vector3d Earth() const { return earth_; }

 private:
  MagneticFieldOptions o_;
  Eigen::Vector3d earth_;
  std::vector<std::pair<Eigen::Vector2d, Eigen::Vector3d>> blobs_;
};

// Adds noise, biases and sample-and-hold to true samples; the magnetometer reads
// R_nbᵀ·field(position) + noise (has_mag when `field` is given). Returns the true biases used.
struct ImuBiasTrace {
  std::vector<Eigen::Vector3d> acc_bias, gyro_bias;  // per sample
};
std::vector<ImuSample> ApplyImuErrors(const std::vector<ImuTruth>& truth,
                                      const ImuNoiseOptions& noise, const MagneticField* field,
                                      Rng rng, ImuBiasTrace* biases = nullptr);

// ------------------------------------------------------------------ waist / hip IMU (000 Sec. IV)
struct WaistImuOptions {
  double rate_hz = 50.0;
  GaitOptions gait;
  double lateral_sway_m = 0.02;  // pelvis side-to-side amplitude, at stride frequency f/2
  double yaw_sway_rad = 0.05;    // pelvis yaw oscillation amplitude, at f/2
  double height_m = 1.0;         // truth z (unused when the truth is planar)
  // A device held in the hand (issue 41): yawed on the walker by device_yaw_rad (a phone in
  // portrait, its y axis forward: −π/2), a forward swing forward_swing_mps2·cos(2πφ) leading
  // the vertical sin(2πφ) by a quarter step (the body brakes at heel strike), and, while the
  // walker stands, a shaking hand: vertical hand_shake_mps2·(sin(2π·1.3 t) + 0.6·sin(2π·2.9 t
  // + 1)) (peaks of ~1.4× the amplitude, at tremor-like 1-3 Hz). All 0: a waist/hip IMU.
  double device_yaw_rad = 0.0;
  double forward_swing_mps2 = 0.0;
  double hand_shake_mps2 = 0.0;
};
struct WaistImuResult {
  std::vector<ImuTruth> truth;  // pose of the walker (the path), noiseless sensor readings
  std::vector<StepEvent> steps;
};
WaistImuResult SimulateWaistImu(const MotionPlan& plan, const WaistImuOptions& options);

// ------------------------------------------------------------------ foot IMU
struct FootImuOptions {
  double rate_hz = 100.0;
  GaitOptions gait;
  double stance_fraction = 0.35;  // of each stride's time, foot flat and still
  double lift_m = 0.10;           // peak foot height in swing
  double pitch_amplitude_deg = 30.0;
  double max_pivot_deg = 90.0;  // turns in place: at most this much yaw per pivot swing
  // Stairs (stair_rise_m > 0): every leg is a run of stair flights, flight_rises rises up, then
  // as many down (a landing at the top), one tread stair_tread_m per step, so a stride climbs
  // or descends two rises; turns in place stay on their tread. 0: level ground.
  double stair_rise_m = 0.0;
  double stair_tread_m = 0.28;
  int flight_rises = 12;
};
struct Footprint {
  Eigen::Vector2d position = Eigen::Vector2d::Zero();
  double heading_rad = 0.0;
  double z_m = 0.0;  // height of the tread the foot stands on
};
struct FootSwing {
  double t0_s = 0.0, t1_s = 0.0;  // lift-off, touch-down
  Footprint from, to;
};
class FootMotion {
 public:
  FootMotion(const MotionPlan& plan, const FootImuOptions& options);
  ImuTruth At(double t_s) const;  // exact pose, velocity and noiseless readings
  const std::vector<FootSwing>& swings() const { return swings_; }
  double duration() const { return duration_; }

 private:
  FootImuOptions o_;
  std::vector<FootSwing> swings_;
  Footprint first_;
  double duration_ = 0.0;
  double pitch_norm_ = 1.0;
};
// Samples the foot IMU at t_k = k / rate. interval_average: readings are the averages over
// (t_{k−1}, t_k] — ω_k = Log(q_{k−1}⁻¹ q_k)/dt, f_k = R_{k−1}ᵀ((v_k − v_{k−1})/dt − g_n) —
// as integrating IMUs output them (strapdown.h kIntervalAverage integrates them exactly);
// otherwise instantaneous readings at t_k. The first sample is always instantaneous.
std::vector<ImuTruth> SampleFootImu(const FootMotion& foot, double rate_hz,
                                    bool interval_average = true);

// ------------------------------------------------------------------ radio
struct DetectionModel {
  double p_max = 1.0;
  double d50_m = 0.0;  // <= 0: no range dependence (p = p_max)
  double width_m = 4.0;
  double At(double d_m) const;
};

struct NlosOptions {
  double fraction = 0.0;         // long-run share of time an anchor is NLOS
  double mean_episode_s = 10.0;  // mean NLOS episode length
  double rss_bias_db = 8.0;      // mean extra attenuation (exponential) while NLOS
  double range_bias_m = 3.0;     // mean positive TOA bias (exponential) while NLOS
};

struct RadioOptions {
  PathLossParams path_loss;  // true model
  RssUnits units = RssUnits::kDbm;
  double A_spread_db = 0.0;  // per-anchor A ~ N(A, spread²)
  double eta_spread = 0.0;   // per-anchor η ~ N(η, spread²)
  bool use_sensitivity = true;
  double sensitivity = -95.0;  // dBm: weaker (lower) readings lost; RFCode: higher ones lost
  DetectionModel detection;
  NlosOptions nlos;
  std::vector<std::pair<double, double>> outages_s;  // no reception inside [t0, t1)
  double period_s = 1.0;         // beacon period of each anchor (random phase per anchor)
  double jitter_s = 0.0;         // uniform ± jitter of each emission (kept inside the period)
  double report_period_s = 0.0;  // > 0: timestamps rounded up to the reader's polling grid
  double rss_quantum = 0.0;      // > 0: readings rounded to this step
  // Multi-floor buildings: floor f's slab lies at height f × storey_height_m; each slab
  // between an anchor and the receiver takes path_loss.floor_loss_db off the RSS (Seidel &
  // Rappaport's floor attenuation factor). Anchors and receiver are given at their heights
  // above floor 0.
  double storey_height_m = kDefaultStoreyHeightM;
  // TOA (002 eq. 6): z = alpha + beta·d + N(0, sigma²) (+ NLOS bias)
  double toa_alpha_m = 0.0, toa_beta = 1.0, toa_sigma_m = 1.0;
};

using ReceiverTrack = std::function<Eigen::Vector3d(double t_s)>;

struct RadioResult {
  std::vector<RssSample> rss;
  std::vector<RangeSample> ranges;
  std::vector<Emission> emissions;
  std::vector<PathLossParams> per_anchor;  // true per-anchor parameters (RSS)
};
RadioResult SimulateRss(const std::vector<Anchor>& anchors, const ReceiverTrack& rx,
                        double t_begin_s, double t_end_s, const RadioOptions& options, Rng rng);
RadioResult SimulateToa(const std::vector<Anchor>& anchors, const ReceiverTrack& rx,
                        double t_begin_s, double t_end_s, const RadioOptions& options, Rng rng);

// ------------------------------------------------------------------ barometer
// A phone barometer at height h(t) above the reference level: p_k = P(h(t_k)) + d(t_k) + n_k,
// P the standard atmosphere (BarometricPressureHpa, the inverse of the estimators'
// BarometricHeightM), n_k ~ N(0, noise_hpa²) white, d(t) the drift: weather, a linear trend of
// ±drift_hpa_per_h (the sign drawn from the seed), plus building air (ventilation, doors), a
// random walk of drift_rw_hpa_per_sqrt_h. Readings at t = k / rate_hz, rounded to 1e-4 hPa.
struct BarometerOptions {
  double rate_hz = 10.0;
  double ref_hpa = 1013.25;  // pressure at height 0
  double noise_hpa = 0.03;
  double drift_hpa_per_h = 0.0;
  double drift_rw_hpa_per_sqrt_h = 0.0;
};
struct BarometerResult {
  std::vector<PressureSample> pressure;
  std::vector<double> drift_hpa;      // d(t_k), per reading
  double drift_rate_hpa_per_h = 0.0;  // the signed trend
};
BarometerResult SimulateBarometer(const std::function<double(double t_s)>& height_m,
                                  double t_begin_s, double t_end_s, const BarometerOptions& options,
                                  Rng rng);

// Anchors on the most square r×c grid with r·c = n, covering [x0,x0+w]×[y0,y0+h] (000 Sec. IV).
std::vector<Anchor> GridAnchors(int n, double x0, double y0, double w, double h, double z);
// `count` of `all` spread out by farthest-point sampling from the first (deterministic).
std::vector<Anchor> SpreadSubset(const std::vector<Anchor>& all, int count);

}  // namespace sim
}  // namespace walkgraph

#endif  // WALKGRAPH_SRC_SIMULATE_SIM_MODELS_H_
