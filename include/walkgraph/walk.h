// A recorded or simulated walk: the input every estimator sees.
//
// Simulated and real walks are the same type; only the truth differs (continuous samples or
// surveyed checkpoints). Everything is SI inside: seconds, metres, m/s², rad/s, µT, dBm (or the
// RFCode unit of 004, where larger is weaker), radians. Frame: local, x east, y north, z up.
#ifndef WALKGRAPH_WALK_H_
#define WALKGRAPH_WALK_H_

#include <map>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "walkgraph/enum_names.h"

namespace walkgraph {

enum class ImuPlacement { kNone, kFoot, kWaist, kHip, kHandheld };
enum class TruthKind { kNone, kContinuous, kCheckpoints };
enum class RadioKind { kNone, kRss, kRange };
enum class RssUnits { kDbm, kRfcode };

// Each enum's one table of names (walk.yaml's spelling), read by ToString and by the walk reader.
const EnumNames<ImuPlacement>& ImuPlacementNames();
const EnumNames<TruthKind>& TruthKindNames();
const EnumNames<RadioKind>& RadioKindNames();
const EnumNames<RssUnits>& RssUnitsNames();
const char* ToString(ImuPlacement p);
const char* ToString(TruthKind k);
const char* ToString(RadioKind k);
const char* ToString(RssUnits u);

// Log-distance path loss: RSS = A − 10·η·log10(d/d0) + N(0, σ²)
// (000 eq. 1, 001 eq. 13, 002 eq. 5, 004 eq. 4). In RFCode units (004) RSS grows as the signal
// weakens, so there RSS = A + 10·η·log10(d/d0); `units` in RadioDefaults says which.
struct PathLossParams {
  double A_dbm = -60.0;   // RSS at d0 (RFCode: RSS0)
  double eta = 2.5;       // path-loss exponent (> 0)
  double d0_m = 1.0;      // reference distance
  double sigma_db = 5.0;  // shadowing standard deviation
  // Multi-floor walks: the RSS lost per floor between anchor and receiver (dB, >= 0), the
  // floor attenuation factor of Seidel & Rappaport's multi-floor model; estimators that model
  // floors subtract floor_loss_db × |floors crossed| from the expected RSS.
  double floor_loss_db = 0.0;
};

struct RadioDefaults {
  RadioKind kind = RadioKind::kNone;
  RssUnits units = RssUnits::kDbm;
  PathLossParams path_loss;
  // Whether path_loss was measured for this walk's radios (walk.yaml `radio.calibrated`,
  // default false). false: the numbers are a guess (a converter's default, a datasheet, a fit
  // on another site) and the factor-graph estimators estimate A and η from the walk itself,
  // with path_loss as their prior mean; true: the estimators trust path_loss as given.
  bool calibrated = false;
  double range_sigma_m = 1.0;  // for kind == kRange
};

// Optional known start (a surveyed start point): dead reckoning needs it to be in the anchors'
// frame when nothing else fixes the gauge. A start may give the position only (IPIN's scoring
// trials: "we provide the initial position"): heading_known = false, and then heading_rad = 0
// with sigma_heading_rad = kUnknownHeadingSigmaRad (the σ of a heading uniform on the circle)
// for estimators that only read the numbers; the PDR front end takes its start heading from
// the magnetometer instead and the step graph puts no prior on it.
inline constexpr double kUnknownHeadingSigmaRad = 1.8137993642342178;  // π/√3
struct InitialPose {
  double x_m = 0.0;
  double y_m = 0.0;
  double heading_rad = 0.0;
  double sigma_xy_m = 0.5;
  double sigma_heading_rad = 0.1;
  bool heading_known = true;
  // The start's floor (walk.yaml initial_pose.floor; multi-floor walks, see Walk::StartFloor).
  std::optional<int> floor;
};

inline constexpr double kDefaultStoreyHeightM = 3.0;

struct WalkMeta {
  int format_version = 1;
  std::string name;
  std::string source;  // citation / where the data came from
  std::string licence;
  ImuPlacement imu_placement = ImuPlacement::kNone;
  TruthKind truth_kind = TruthKind::kNone;
  RadioDefaults radio;
  std::optional<InitialPose> initial_pose;
  // Multi-floor walks: floor f (an integer level, 0 the ground floor, negative below) lies at
  // height f × storey_height_m above floor 0 (walk.yaml `storey_height_m`; 3 m, a common
  // storey, when the walk does not say). Estimators map their height to a floor with it.
  double storey_height_m = kDefaultStoreyHeightM;
  // Free-form numeric facts a simulator or converter wants to keep (e.g. "sim.seed").
  std::map<std::string, double> extra;
};

// A radio transmitter. Its position is surveyed (sigma_m 0: known exactly), uncertain
// (sigma_m > 0: position_m is a mean with σ sigma_m per horizontal axis) or unknown
// (position_known false: anchors.csv leaves x_m and y_m empty; position_m's x and y are then
// NaN, so that nothing can take it for a place). Estimators that need surveyed anchors (the
// papers' filters) leave the unknown ones and their readings out (WithoutUnknownAnchors);
// fg-batch makes unknown and uncertain anchors states (step_graph.h).
struct Anchor {
  int id = 0;
  Eigen::Vector3d position_m = Eigen::Vector3d::Zero();
  std::optional<int> floor;  // anchors.csv `floor` column (multi-floor walks)
  bool position_known = true;
  double sigma_m = 0.0;    // anchors.csv `sigma_m`: 0 surveyed, > 0 uncertain (metres, 1σ)
  std::string group = "";  // anchors.csv `group`: e.g. ble, wifi, uwb ("" none)

  bool surveyed() const { return position_known && sigma_m == 0.0; }
};

struct ImuSample {
  double t_s = 0.0;
  Eigen::Vector3d acc_mps2 = Eigen::Vector3d::Zero();    // specific force, body frame
  Eigen::Vector3d gyro_radps = Eigen::Vector3d::Zero();  // angular rate, body frame
  bool has_mag = false;
  Eigen::Vector3d mag_ut = Eigen::Vector3d::Zero();
};

struct RssSample {
  double t_s = 0.0;
  int anchor_id = 0;
  double rss = 0.0;  // dBm or RFCode units (RadioDefaults::units)
};

struct RangeSample {
  double t_s = 0.0;
  int anchor_id = 0;
  double range_m = 0.0;
};

// A step or wheel increment: move dist_m along the current heading, then turn dheading_rad.
struct OdometrySample {
  double t_s = 0.0;
  double dist_m = 0.0;
  double dheading_rad = 0.0;
};

struct TruthSample {
  double t_s = 0.0;
  Eigen::Vector3d position_m = Eigen::Vector3d::Zero();
  bool has_z = false;
  std::optional<int> floor;  // truth.csv `floor` column (multi-floor walks)
};

// A barometer reading (pressure.csv: t_s,hpa), hectopascal.
struct PressureSample {
  double t_s = 0.0;
  double hpa = 0.0;
};

// A known position at a known time (waypoints.csv: t_s,x_m,y_m,sigma_m), e.g. a surveyed
// landmark the walker stepped on: every factor-graph estimator adds it as a position factor
// (σ sigma_m per axis) on its estimate interpolated at t_s.
struct Waypoint {
  double t_s = 0.0;
  Eigen::Vector2d position_m = Eigen::Vector2d::Zero();
  double sigma_m = 1.0;
};

struct StanceSample {
  double t_s = 0.0;
  bool stance = false;
};

// A hole in the IMU stream: no sample in (t_begin_s, t_end_s), longer than kImuGapFactor ×
// the stream's median sample interval (dropped samples, a logger pause). Estimators do not
// integrate across it: the PDR front end holds its attitude and heading there, the step graph
// bridges it with a random-walk motion model, the filters propagate over its true duration.
struct ImuGap {
  double t_begin_s = 0.0;  // the last sample before the hole
  double t_end_s = 0.0;    // the first sample after it
  double duration_s() const { return t_end_s - t_begin_s; }
};
inline constexpr double kImuGapFactor = 10.0;
// How far a walker may have gone across a gap: this speed × its duration, 1σ per axis (a
// brisk walk), the bridge of the estimators that do not integrate across it.
inline constexpr double kImuGapSpeedMps = 1.5;
// The median sample interval of an IMU stream (0 with fewer than 2 samples).
double MedianImuIntervalS(const std::vector<ImuSample>& imu);
// The longest sample interval that is not a gap: kImuGapFactor × the median interval
// (infinity with fewer than 3 samples).
double ImuGapThresholdS(const std::vector<ImuSample>& imu);

struct Walk {
  WalkMeta meta;
  std::vector<Anchor> anchors;
  std::vector<ImuSample> imu;
  std::vector<RssSample> rss;
  std::vector<RangeSample> ranges;
  std::vector<OdometrySample> odometry;
  std::vector<TruthSample> truth;
  std::vector<StanceSample> stance_truth;  // optional labels (e.g. PyShoe's zv_vicon)
  std::vector<Waypoint> waypoints;         // optional known positions (not truth: an input)
  std::vector<PressureSample> pressure;    // optional barometer

  // The floor the walk starts on: initial_pose.floor, else the first truth sample's floor
  // (IPIN gives the first landmark, floor included), else 0. An estimator without a floor
  // estimate is scored on this floor throughout.
  int StartFloor() const;
  // Whether the walk has floors to score (a truth sample with a floor).
  bool has_truth_floors() const;

  bool has_imu() const { return !imu.empty(); }
  bool has_rss() const { return !rss.empty(); }
  bool has_ranges() const { return !ranges.empty(); }
  bool has_odometry() const { return !odometry.empty(); }
  bool has_truth() const { return !truth.empty(); }

  // An anchor's height above floor 0: with a floor, floor × storey_height_m + z_m (z_m is then
  // the mounting height above its floor); without, z_m.
  double AnchorHeightM(const Anchor& a) const;
  // Index into `anchors` of the anchor with this id, or -1.
  int AnchorIndex(int id) const;
  // How many RSS and range readings the anchor with this id has.
  int AnchorReadings(int id) const;
  // Whether an anchor's position is unknown (Anchor::position_known false).
  bool has_unknown_anchors() const;
  // First and last timestamp over every stream (0, 0 for an empty walk).
  double StartTime() const;
  // The holes in `imu` (see ImuGap), in time order; empty with fewer than 3 samples.
  std::vector<ImuGap> ImuGaps() const;
  double EndTime() const;
  // Horizontal length of the truth path, metres (0 without truth).
  double TruthDistance() const;
  // Horizontal length of the truth path from its first sample to each sample (0 at the first;
  // empty without truth); TruthDistance() is its last element.
  std::vector<double> TruthDistances() const;
};

// What WithoutUnknownAnchors left out.
struct UnknownAnchorsDropped {
  int anchors = 0;
  int rss_readings = 0;
  int range_readings = 0;
};
// `walk` without its anchors of unknown position and their RSS and range readings (the walk
// the estimators that need surveyed anchors see; uncertain anchors stay, at their mean).
Walk WithoutUnknownAnchors(const Walk& walk, UnknownAnchorsDropped* dropped = nullptr);
// `walk` without the anchors of these ids and their RSS and range readings.
Walk WithoutAnchors(const Walk& walk, const std::set<int>& ids,
                    UnknownAnchorsDropped* dropped = nullptr);

}  // namespace walkgraph

#endif  // WALKGRAPH_WALK_H_
