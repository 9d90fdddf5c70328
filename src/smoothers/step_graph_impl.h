// StepGraph's internals shared by step_graph_build.cc (building the graph), step_graph_run.cc,
// step_graph_window.cc and step_graph_factors.cc (its states and factors, node by node). The
// factors' autodiff (Jet) code is instantiated in step_graph_factors.cc alone, which CMakeLists.txt
// compiles with room to inline it (WALKGRAPH_JET_UNITS: GCC left the odometry factor's Jet
// arithmetic as calls, ~2x its instructions, once its unit's inlining budget was spent).
#ifndef WALKGRAPH_SRC_SMOOTHERS_STEP_GRAPH_IMPL_H_
#define WALKGRAPH_SRC_SMOOTHERS_STEP_GRAPH_IMPL_H_

#include <algorithm>
#include <cmath>
#include <memory>
#include <optional>
#include <vector>

#include <ceres/ceres.h>
#include <ceres/normal_prior.h>
#include <Eigen/Core>

#include "factors/angle_manifold.h"
#include "walkgraph/angle.h"
#include "walkgraph/graph.h"
#include "walkgraph/smoothers/step_graph.h"
#include "walkgraph/walk.h"

namespace walkgraph {
namespace internal {

// σ-whitened Gaussian prior r = diag(1/σ)(x − μ) (Ceres' NormalPrior).
inline std::unique_ptr<ceres::CostFunction> DiagonalPrior(const Eigen::VectorXd& mean,
                                                          const Eigen::VectorXd& sigma) {
  ceres::Matrix A = sigma.cwiseInverse().asDiagonal();
  return std::make_unique<ceres::NormalPrior>(A, mean);
}

// The static states' keys (graph.h lists the letters); group: the anchor index or 0.
inline constexpr Key kGyroBiasKey = Symbol('g', 0);
inline constexpr Key kStepScaleKey = Symbol('c', 0);  // the walk's step-length scale c
inline Key PathLossKey(int group) { return Symbol('l', static_cast<uint64_t>(group)); }
inline constexpr Key kPathLossMeanKey = Symbol('m', 0);  // hierarchical: the walk's mean (A, η)
inline Key RangeBiasKey(int group) { return Symbol('b', static_cast<uint64_t>(group)); }
inline Key RangeScaleKey(int group) { return Symbol('s', static_cast<uint64_t>(group)); }
// p(a): the horizontal position of anchor index a, a state when it is not surveyed.
inline Key AnchorPositionKey(int anchor) { return Symbol('p', static_cast<uint64_t>(anchor)); }

// The step graph's noise groups (GraphFactor::noise_group; EstimateNoiseScales): each the
// factors whose σ one option scales (StepGraphOptions::noise_scale_rounds). Odometry has none:
// its rows mix a wheel's scale error, which persists, with its heading noise (one scale for the
// three took Plaza1 from 0.311 to 0.344 m RMSE).
enum StepNoiseGroup : int {
  kStepNoise = 0,          // StepFactor: step_sigma_scale and sigma_cross_m
  kHeadingIncrementNoise,  // HeadingIncrementFactor of a step: dheading_sigma_scale
  kMagHeadingNoise,        // HeadingFactor of a step's magnetometer: mag_heading_sigma_rad
  kRssNoise,               // RSS readings: the path loss' sigma_db
  kRangeNoise,             // ranges: range_sigma_m
  kStepNoiseGroups
};

// path_loss "auto" resolved for `walk`; *held_radio_only: auto held it (neither steps nor
// odometry).
PathLossMode ResolvePathLoss(const Walk& walk, const StepGraphOptions& o, bool* held_radio_only);
// Nodes whose interval (t_{k−1}, t_k] overlaps an IMU gap, on walks whose steps come from the
// IMU (imu_steps; odometry and radio-only walks have none).
std::vector<bool> BridgedNodes(const Walk& walk, bool imu_steps, const std::vector<double>& t);

}  // namespace internal

struct StepGraph::Impl {
  // A measurement at one instant, attached to the node(s) around it.
  struct Reading {
    enum class Kind { kRss, kRange, kWaypoint };
    int index = 0;  // into walk.anchors (RSS, range) or walk.waypoints
    Kind kind = Kind::kRss;
    double value = 0.0;           // RSS or range
    int node_a = 0, node_b = -1;  // node_b < 0: at node_a alone
    double alpha = 0.0;
  };

  StepGraphOptions o;
  bool odometry = false;
  bool radio_only = false;           // no steps: random-walk motion between radio epochs
  std::vector<Step> steps;           // node k ≥ 1 ends steps[k − 1] (PDR walks)
  StepFrontEndReport front_end;      // the front end's choices (PDR walks)
  std::vector<bool> bridged;         // node k's step spans an IMU gap (Walk::ImuGaps)
  std::vector<OdometrySample> odom;  // node k ≥ 1 ends odom[k − 1] (odometry walks)
  std::vector<Anchor> anchors;
  std::vector<Waypoint> waypoints;
  RadioDefaults radio;
  std::optional<InitialPose> start;
  std::vector<std::vector<Reading>> readings_at;  // by newest node
  bool any_rss = false, any_range = false;
  // CheckStartHeading turned the dead reckoning onto the radio fixes (a start without heading):
  // the start heading is settled, StartHeadingTurns gives none.
  bool start_heading_from_fixes = false;
  // Floors: the barometric height of each node above node 0's, the start height, the storey.
  bool floors = false;
  std::vector<double> baro_z;
  double start_z = 0.0, storey_m = kDefaultStoreyHeightM;
  void MakeHeights(const Walk& walk, const std::vector<double>& node_t);
  // The start floor where the walk does not give one: each RSS reading of a surveyed anchor
  // with a floor votes for that floor less the floors the height chain has climbed by then
  // (node_z), and the floor whose three strongest votes are strongest on average is the start's —
  // the nearest beacons are on one's own floor, a floor slab costs several dB (IPIN trial 21 starts
  // on level -2: 203 readings of a level -2 beacon, none of level 0). nullopt: no such reading.
  std::optional<int> RadioStartFloor(const Walk& walk, const std::vector<double>& node_t) const;
  std::optional<int> radio_start_floor;
  // Staircases: on_stairs[k] for node k's step; with StepGraphOptions::stairs their horizontal
  // length is a tread. Returns how many steps were given a tread.
  int MarkStairs(const Walk& walk, const std::vector<double>& node_t);
  std::vector<int> StairCandidates(const Walk& walk, const std::vector<double>& node_t) const;
  int stair_steps = 0;
  std::vector<bool> on_stairs;
  // σ of the barometric height change over dt (BarometricHeightFactor).
  double BaroSigma(double dt) const {
    return std::sqrt(2.0 * o.baro_sigma_m * o.baro_sigma_m + o.baro_drift_m2ps * std::max(dt, 0.0));
  }
  // The heights' causal estimate (ChainHeights): the readings' receiver heights; the floor
  // level each level node is held at (NaN: none).
  std::vector<double> node_z, floor_level;
  Status ChainHeights(const std::vector<double>& node_t);
  // Whether node k's step is a walking step on the level (StepGraphOptions::level_sigma_m).
  bool LevelStep(int k, double dt) const {
    return floors && o.level_sigma_m > 0 && !odometry && !radio_only && !bridged[k] &&
           !on_stairs[k] && dt <= o.max_step_duration_s;
  }
  // Anchors with floors: each anchor's height (Walk::AnchorHeightM) and floor.
  std::vector<double> anchor_z;
  std::vector<std::optional<int>> anchor_floor;
  int Floor(double z_m) const { return static_cast<int>(std::lround(z_m / storey_m)); }
  // A reading's receiver height: its nodes' estimated heights (node_z; the start floor's
  // height without a barometer).
  double ReceiverHeight(int node_a, int node_b, double alpha) const {
    if (!floors) return start_z;
    const double za = node_z[node_a];
    return node_b < 0 ? za : (1.0 - alpha) * za + alpha * node_z[node_b];
  }
  // An RSS reading of anchor a with a floor: the anchor at its height, the receiver
  // receiver_height_m above its nodes' estimated height, and the reading raised by the floor loss
  // of the floors in between (the expected RSS lowered by it). Leaves `rss`, `anchor_m`,
  // `receiver_m` as they are for an anchor without a floor, and for every anchor while the
  // walk's radio has no floor loss (floor_loss_db 0), except a surveyed anchor of a walk whose
  // path loss is not calibrated: a calibrated one is the planar model its A and η were fitted
  // for (`fit-path-loss` without --floors), and an unsurveyed anchor's floor is a guess (the
  // IPIN converter's for WiFi access points). Where the graph estimates the path loss a surveyed
  // beacon two storeys down is that far away (IPIN, four of six beacons on level -2 heard from
  // level 0: fg-batch p75 without a start 10.56 -> 9.42 m on trial 01).
  std::vector<bool> anchor_at_floor;  // anchor index -> FloorAware applies
  void FloorAware(int a, int node_a, int node_b, double alpha, double sign, double* rss,
                  Eigen::Vector3d* anchor_m, double* receiver_m) const {
    if (!anchor_at_floor[a]) return;
    const double z = ReceiverHeight(node_a, node_b, alpha);
    anchor_m->z() = anchor_z[a];
    *receiver_m += z;  // receiver_height_m above the floor
    *rss += sign * radio.path_loss.floor_loss_db * std::abs(Floor(z) - *anchor_floor[a]);
  }
  std::vector<bool> anchor_has_rss, anchor_has_range;
  // anchor_state[a]: anchor index a's (x, y) is the state p(a) (an unknown or uncertain anchor:
  // walk.h Anchor), starting at its position_m; uncertain ones get a prior N(position_m, σ²).
  std::vector<bool> anchor_state;
  // The walk's step-length scale is a state (StepGraphOptions::estimate_step_scale): steps from
  // the IMU (not odometry, not radio alone).
  bool EstimatesStepScale() const { return !odometry && !radio_only && o.estimate_step_scale; }
  bool AnchorIsState(int a) const {
    return anchor_state[a] && (anchor_has_rss[a] || anchor_has_range[a]);
  }
  std::shared_ptr<const ceres::Manifold> angle = std::make_shared<AngleManifold>();
  std::shared_ptr<const ceres::LossFunction> rss_loss, range_loss, mag_loss;

  bool PathLossPerAnchor() const {
    return o.path_loss == PathLossMode::kPerAnchor || o.path_loss == PathLossMode::kHierarchical;
  }
  int PathLossGroup(int anchor) const { return PathLossPerAnchor() ? anchor : 0; }
  void CheckStartHeading(const Walk& walk, StepGraph* g);
  Status AddUserFactors(const Walk& walk, const std::vector<double>& node_t);
  // Build's steps, in order: node times; dead-reckoned initial values; the readings attached
  // to their nodes; the start placed (radio fixes, alignment or the start check).
  Status MakeNodes(const Walk& walk, StepGraph* g);
  void DeadReckon(const Walk& walk, StepGraph* g);
  Status AttachReadings(const Walk& walk, StepGraph* g);
  void PlaceStart(const Walk& walk, StepGraph* g);
  void AddReadingFactors(int k, std::vector<GraphFactor>* out) const;
  void AddReading(const Reading& r, std::vector<GraphFactor>* out) const;
  // The priors of the static states (node 0's factors): gyro bias, step-length scale, anchors of
  // surveyed σ, range scale and bias, path loss.
  void AddStaticPriors(const std::vector<GraphState>& statics, std::vector<GraphFactor>* out) const;
  std::vector<std::vector<GraphFactor>> user_at;  // the user's factors, by newest node

  // Dead reckoning: node k's (p, θ) from node k − 1's by its increment (odometry: move along
  // the heading, then turn; a step: turn, then move along the new heading; radio-only: stay).
  Eigen::Vector3d Predict(int k, Eigen::Vector3d x) const {
    if (odometry) {
      const OdometrySample& s = odom[k - 1];
      x.head<2>() += s.dist_m * Eigen::Vector2d(std::cos(x[2]), std::sin(x[2]));
      x[2] = NormalizeAngle(x[2] + s.dheading_rad);
    } else if (!radio_only) {
      const Step& s = steps[k - 1];
      x[2] = NormalizeAngle(x[2] + s.dheading_rad);
      x.head<2>() += s.length_m * Eigen::Vector2d(std::cos(x[2]), std::sin(x[2]));
    }
    return x;
  }
  int RangeBiasGroup(int anchor) const {
    return o.range_bias == CalibrationScope::kPerAnchor ? anchor : 0;
  }
  int RangeScaleGroup(int anchor) const {
    return o.range_scale == CalibrationScope::kPerAnchor ? anchor : 0;
  }
};

}  // namespace walkgraph

#endif  // WALKGRAPH_SRC_SMOOTHERS_STEP_GRAPH_IMPL_H_
