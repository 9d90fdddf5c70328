// The foot-INS graph's internals (ins_graph.h describes the graph): its states, the factor
// makers the batch (fg-ins-batch) and the window (fg-ins-window) share, and the one mapping of
// a state's and the walk-wide blocks to the graph's keys (InsKeyMap). Not part of the public
// API: tests and src/smoothers only.
#ifndef WALKGRAPH_SRC_SMOOTHERS_INS_GRAPH_INTERNAL_H_
#define WALKGRAPH_SRC_SMOOTHERS_INS_GRAPH_INTERNAL_H_

#include <array>
#include <functional>
#include <limits>
#include <map>
#include <memory>
#include <optional>
#include <set>
#include <string>
#include <unordered_map>
#include <vector>

#include <ceres/cost_function.h>
#include <ceres/loss_function.h>
#include <ceres/manifold.h>
#include <ceres/problem.h>
#include <Eigen/Core>
#include <Eigen/Geometry>

#include "walkgraph/graph.h"
#include "walkgraph/smoothers/ins_graph.h"
#include "walkgraph/smoothers/ins_window.h"
#include "walkgraph/status.h"
#include "walkgraph/strides.h"
#include "walkgraph/walk.h"

namespace walkgraph {

// One state's parameter blocks (the caller owns them; they must not move while an InsKeyMap
// maps them). q is q_nb in Eigen storage order (x, y, z, w).
struct InsState {
  double t_s = 0.0;
  size_t imu_index = 0;
  bool zupt = false;  // the front end applied a ZUPT at this sample
  std::array<double, 3> p{}, v{};
  std::array<double, 4> q{0.0, 0.0, 0.0, 1.0};
  std::array<double, 3> bg{}, ba{};

  Eigen::Vector3d position() const { return Eigen::Vector3d(p[0], p[1], p[2]); }
  Eigen::Vector3d velocity() const { return Eigen::Vector3d(v[0], v[1], v[2]); }
  Eigen::Quaterniond attitude() const { return Eigen::Quaterniond(q[3], q[0], q[1], q[2]); }
  Eigen::Vector3d gyro_bias() const { return Eigen::Vector3d(bg[0], bg[1], bg[2]); }
  Eigen::Vector3d acc_bias() const { return Eigen::Vector3d(ba[0], ba[1], ba[2]); }
};

// What an InsFactor is (its name: imu, bias_rw_gyro, …, waypoint).
enum class InsFactorKind {
  kImu,
  kBiasRwGyro,
  kBiasRwAcc,
  kZupt,
  kZaru,
  kPrior,
  kBiasPriorGyro,
  kBiasPriorAcc,
  kPathLossSpread,
  kPathLossPrior,
  kRss,
  kRange,
  kRangeBiasPrior,
  kAnchorPrior,
  kWaypoint,
  kGapReach,
  kGapMagneticHeading,
  kStanceMagneticHeading,
  kStanceLevel
};
const EnumNames<InsFactorKind>& InsFactorKindNames();
const char* ToString(InsFactorKind k);
StatusOr<InsFactorKind> InsFactorKindFromString(const std::string& name);

// A cost function with its (optional) loss and the parameter blocks it acts on.
struct InsFactor {
  InsFactorKind kind = InsFactorKind::kImu;
  int anchor_id = -1;  // rss, range: the reading's anchor
  std::unique_ptr<ceres::CostFunction> cost;
  std::unique_ptr<ceres::LossFunction> loss;
  std::vector<double*> blocks;
};

// What the factor makers read: the walk (IMU, initial_pose), per-sample still flags and the
// options. The referenced objects must outlive the context.
struct InsGraphContext {
  const Walk* walk = nullptr;
  const std::vector<bool>* still = nullptr;  // per IMU sample; null or empty: no ZARU
  const std::vector<bool>* zupt = nullptr;   // per IMU sample, ZUPT applied; null: no levelling
  // Per IMU sample, the front end's path (radio interpolation); null: α = time fraction.
  const std::vector<NavState>* path = nullptr;
  InsGraphOptions options;
  // Per IMU sample, the preintegration's scale-factor noise (the front end's,
  // ZuptInsSolution::scale_noise; a segment takes its first sample's); null: none.
  const std::vector<double>* scale_noise = nullptr;
  // Longer IMU intervals are gaps (ImuGapThresholdS): bridged, not integrated.
  double imu_gap_s = std::numeric_limits<double>::infinity();
  // Per IMU sample, σ of the stance magnetic heading factor of a state there (NaN: none;
  // StanceMagneticSigmas); null: none.
  const std::vector<double>* stance_magnetic_sigma = nullptr;
};

// The walk-wide parameter blocks the factors share (owned by the caller, stable addresses): the
// radio's and the magnetic field's direction.
struct InsSharedBlocks {
  std::array<double, 2> path_loss{};   // (A, η): walk.yaml's radio, then the estimate (the
                                       // walk-wide block, or hierarchical's mean)
  bool path_loss_set = false;          // path_loss holds walk.yaml's values or an estimate
  bool estimate_path_loss = false;     // InsGraphOptions::path_loss resolved for the walk
  bool per_anchor_path_loss = false;   // resolved to hierarchical
  bool path_loss_prior_added = false;  // its prior is in the current problem
  std::map<int, std::array<double, 2>> anchor_path_loss;  // hierarchical: per anchor id
  std::set<int> anchor_path_loss_prior_added;             // their ties to the mean in the problem
  std::map<int, double> range_bias_m;  // per anchor id (0 and constant unless estimated)
  std::set<int> bias_prior_added;      // anchors whose bias prior is in the current problem
  // Anchors not surveyed (walk.h Anchor: unknown, placed by fg-ins-batch's search, or uncertain):
  // their horizontal position, a state (per anchor id), and whether an uncertain one's prior is
  // in the current problem; AnchorRangeFactor's scale block, held at 0 (the INS graph has none).
  std::map<int, std::array<double, 2>> anchor_position;
  std::set<int> anchor_position_prior_added;
  double zero_range_scale = 0.0;
  double field_yaw_rad = 0.0;  // ψ_f of the stance magnetic heading factors
  bool field_yaw_set = false;  // initialised (from the first factor's state)
};

// The graph's states initialised from the front end's INS solution (placement per options).
StatusOr<std::vector<InsState>> InitialInsStates(const Walk& walk, const ZuptInsSolution& front,
                                                 const InsGraphOptions& options);

// Unary factors of a state: ZUPT when state->zupt.
std::vector<InsFactor> InsStateFactors(const InsGraphContext& context, InsState* state);

// Between consecutive states a, b (a->imu_index < b->imu_index): the preintegration of the
// IMU intervals (a, b] at the biases a holds now, both bias random walks and the ZARU on b.
StatusOr<std::vector<InsFactor>> InsBetweenFactors(const InsGraphContext& context, InsState* a,
                                                   InsState* b);

// The gauge of the first state (InsPriorFactor, bias priors, ZARU on its own sample).
std::vector<InsFactor> InsGaugeFactors(const InsGraphContext& context, InsState* first);

// Factors of the segment k..k+n of `states` (see the top of this file).
StatusOr<std::vector<InsFactor>> InsSegmentFactors(const InsGraphContext& context,
                                                   std::vector<InsState>* states, size_t k,
                                                   size_t n);

// RSS and range factors of the readings in (t_k, t_{k+n}] (and at t_0 when k == 0), plus, with
// estimate_range_bias, the prior of each anchor's bias not yet in blocks->bias_prior_added.
StatusOr<std::vector<InsFactor>> InsRadioFactors(const InsGraphContext& context,
                                                 std::vector<InsState>* states, size_t k, size_t n,
                                                 InsSharedBlocks* blocks);

// Per IMU sample of the walk, σ of a stance magnetic heading factor at a state there (see
// InsGraphOptions::use_stance_magnetometer), learnt causally on the front end's path; NaN where
// there is none (no stance, no magnetometer reading, too few pairs yet, or the option off).
std::vector<double> StanceMagneticSigmas(const Walk& walk, const ZuptInsSolution& front,
                                         const InsGraphOptions& options);

// diagnostics num_stance_magnetic_factors and, when any, stance_magnetic_sigma_rad (the last σ).
void AddStanceMagneticDiagnostics(const std::vector<double>& sigma, size_t factors,
                                  std::map<std::string, double>* diagnostics);

// The stance magnetic heading factor of each state of (t_k, t_{k+n}] (and t_0 when k == 0)
// that has a σ (InsGraphContext::stance_magnetic_sigma) and a magnetometer reading, on its q
// and blocks->field_yaw_rad (initialised from the first such state's current attitude).
std::vector<InsFactor> InsStanceMagneticFactors(const InsGraphContext& context,
                                                std::vector<InsState>* states, size_t k, size_t n,
                                                InsSharedBlocks* blocks);

// InsGraphOptions::path_loss resolved for a walk's radio: fixed, global or hierarchical.
PathLossMode ResolveInsPathLoss(const InsGraphOptions& options, const RadioDefaults& radio);

// diagnostics path_loss_estimated (walks with RSS), and path_loss_A / path_loss_eta when
// estimated (hierarchical: the mean, and path_loss_A.<id> / path_loss_eta.<id> per anchor).
void AddInsPathLossDiagnostics(const Walk& walk, const InsSharedBlocks& blocks,
                               std::map<std::string, double>* diagnostics);

// The block of `key` (InsKey below) among `states`, or null when it names none.
double* InsBlockOfKey(std::vector<InsState>* states, Key key);

// A state's five blocks, in the graph's order, and their keys x(i), v(i), q(i), g(i), a(i).
enum class InsBlock { kP = 0, kV = 1, kQ = 2, kBg = 3, kBa = 4 };
inline constexpr int kInsBlocksPerState = 5;
Key InsKey(size_t state, InsBlock block);
std::optional<InsBlock> InsBlockOfLetter(char letter);  // none: a walk-wide block's key
int InsBlockSize(InsBlock block);                       // 4 for q, else 3
double* InsBlockData(InsState* state, InsBlock block);
// State i's five blocks as graph states, valued from `values`, q on `q_manifold`.
std::vector<GraphState> InsStateBlocks(size_t i, const InsState& values,
                                       const std::shared_ptr<const ceres::Manifold>& q_manifold);

// The one mapping of the foot graph's parameter blocks to the graph's keys (graph.h), for the
// batch (a FactorGraph) and the window (a FixedLagSmoother): the blocks of the registered states
// (the ones the factor makers name) by InsKey, the walk-wide blocks of InsSharedBlocks as static
// states — l(0) the path loss (hierarchical: m(0) the mean, l(a) anchor index a's), b(a) anchor
// index a's range bias, f(0) the magnetic field's direction — each made a state when a factor
// first names it, held constant as both graphs hold it (the path loss unless estimated, the
// range biases unless estimate_range_bias).
class InsKeyMap {
 public:
  InsKeyMap(const Walk& walk, const InsGraphOptions& options, InsSharedBlocks* shared)
      : walk_(walk), options_(options), shared_(shared) {}
  // State i's blocks are `state`'s (stable addresses).
  void RegisterState(size_t i, InsState* state);
  // The factor on keys; a walk-wide block named for the first time is appended to `new_states`.
  StatusOr<GraphFactor> ToGraphFactor(InsFactor* factor, std::vector<GraphState>* new_states);
  // Every mapped block set from value(key) (e.g. FactorGraph::Value after a solve); keys that
  // `value` does not know are an error.
  Status CopyValues(const std::function<StatusOr<std::vector<double>>(Key)>& value) const;

 private:
  struct Mapped {
    Key key = 0;
    double* block = nullptr;
    int size = 0;
  };
  StatusOr<GraphState> SharedState(const double* block);

  const Walk& walk_;
  const InsGraphOptions& options_;
  InsSharedBlocks* shared_;
  std::unordered_map<const double*, Mapped> mapped_;
  std::vector<const double*> order_;  // mapped_ in the order mapped (CopyValues' order)
};
// InsGraphOptions::user_factors for `states`, each factor's keys checked to name a state block;
// by the index of the newest state it names.
StatusOr<std::vector<std::vector<GraphFactor>>> InsUserFactors(const InsGraphContext& context,
                                                               std::vector<InsState>* states);
// The output trajectory of a set of state estimates (time order): a pose at every state and
// every 1/output_rate_hz between, by strapdown from state i with its biases. close_segments:
// the end mismatch to state i+1 is spread linearly in time (fg-ins-batch, the lagged window
// output; see the top of this file), else not (the online output, where state i+1 is the
// future). cov[i]: (x, y, yaw) covariance of state i or none; between states it is
// interpolated (close_segments) or state i's, and none where a state it needs has none.
Trajectory InsStatesTrajectory(const Walk& walk, const std::vector<InsState>& states,
                               const std::vector<std::optional<Eigen::Matrix3d>>& cov,
                               const InsGraphOptions& options, bool close_segments);

// Every state's lagged estimate from a window pass (lagged output, whatever
// options.window_output says), in InitialInsStates(walk, ·, options.graph)'s order: what
// fg-ins-batch starts from with initialization: window.
StatusOr<std::vector<InsState>> InsWindowLaggedStates(const Walk& walk,
                                                      const InsWindowOptions& options);

}  // namespace walkgraph

#endif  // WALKGRAPH_SRC_SMOOTHERS_INS_GRAPH_INTERNAL_H_
