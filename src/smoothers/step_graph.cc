#include "walkgraph/smoothers/step_graph.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <map>
#include <set>

#include <ceres/ceres.h>
#include <Eigen/Geometry>

#include "config/parsers.h"
#include "estimators/builtin.h"
#include "factors/barometric_height_factor.h"
#include "smoothers/anchor_search.h"
#include "smoothers/graph_internal.h"
#include "smoothers/step_graph_impl.h"
#include "util/text.h"
#include "walkgraph/angle.h"
#include "walkgraph/config.h"
#include "walkgraph/kalman.h"
#include "walkgraph/path_loss.h"
#include "walkgraph/radio.h"
#include "walkgraph/smoothers/chain_covariance.h"

namespace walkgraph {

using internal::kGyroBiasKey;

namespace {
Status CheckStepGraphOptions(const StepGraphOptions& o, const std::string& context);

// StepGraphOptions::start_estimators as ids: split at commas, spaces trimmed; "" none.
std::vector<std::string> SplitIds(const std::string& list) {
  std::vector<std::string> ids;
  if (list.find_first_not_of(' ') == std::string::npos) return ids;
  size_t begin = 0;
  while (true) {
    const size_t end = std::min(list.find(',', begin), list.size());
    const size_t a = list.find_first_not_of(' ', begin);
    const size_t b = list.find_last_not_of(' ', end == 0 ? 0 : end - 1);
    ids.push_back(a < end && b != std::string::npos && b >= a ? list.substr(a, b - a + 1) : "");
    if (end == list.size()) return ids;
    begin = end + 1;
  }
}
}  // namespace

namespace {

// The keys of StepGraphOptionsFromYaml, in the order `walkgraph list` prints them: the motion
// model (steps, heights, stairs, odometry), the radio, the solvers.
void ReadMotionKeys(ConfigReader& r, StepGraphOptions* o) {
  r.Read("sigma_cross_m", &o->sigma_cross_m,
         "lateral sigma of each StepFactor (across the step direction)");
  r.Read("floors", &o->floors,
         "estimate a height per node from pressure.csv (barometric height factors)");
  r.Read("baro_sigma_m", &o->baro_sigma_m,
         "barometric height noise per node (sigma^2 = 2 baro_sigma^2 + drift dt)");
  r.Read("baro_drift_m2ps", &o->baro_drift_m2ps,
         "barometric height drift rate, a random walk between consecutive nodes");
  r.Read("baro_window_s", &o->baro_window_s, "span of pressure readings averaged around each node");
  r.Read("start_height_sigma_m", &o->start_height_sigma_m,
         "sigma of the start height prior at the start floor");
  r.Read("stairs", &o->stairs,
         "stair steps (fast barometric climb) move one tread instead of the PDR length");
  r.Read("stair_rate_mps", &o->stair_rate_mps,
         "vertical speed above which a step counts as a stair step");
  r.Read("stair_window_s", &o->stair_window_s,
         "span around a step over which the vertical speed is measured");
  r.Read("stair_tread_m", &o->stair_tread_m, "horizontal length of a stair step (one tread)");
  r.Read("stair_tread_sigma_m", &o->stair_tread_sigma_m, "sigma of the stair step length");
  r.Read("stair_min_rise_storeys", &o->stair_min_rise_storeys,
         "least height change of a run of stair steps, in storeys");
  r.Read("stair_landing_s", &o->stair_landing_s,
         "stair runs one way starting within this span are one staircase (landings)");
  r.Read("level_sigma_m", &o->level_sigma_m,
         "sigma of the height change over a level walking step (0: the barometer alone)");
  r.Read("floor_sigma_m", &o->floor_sigma_m,
         "sigma of the pull of a level step near a floor onto that floor's height");
  r.Read("floor_snap_storeys", &o->floor_snap_storeys,
         "a level step this close to a floor's height (in storeys) is pulled onto it");
  r.Read("step_sigma_scale", &o->step_sigma_scale,
         "factor on each step's length sigma (Step::sigma_length_m)");
  r.Read("dheading_sigma_scale", &o->dheading_sigma_scale,
         "factor on each step's heading-increment sigma");
  r.Read("min_sigma_length_m", &o->min_sigma_length_m, "floor on the step length sigma");
  r.Read("min_sigma_dheading_rad", &o->min_sigma_dheading_rad,
         "floor on the step heading-increment sigma");
  r.Read("max_step_duration_s", &o->max_step_duration_s,
         "a step moves the walker only in its last span this long (stops)");
  r.Read("radio_epoch_s", &o->radio_epoch_s, "radio-only walks: one node per this period");
  r.Read("motion_sigma_mps", &o->motion_sigma_mps,
         "radio-only walks: sigma_v of the position random walk between nodes");
  r.Read("bridge_speed_mps", &o->bridge_speed_mps,
         "across an IMU gap: displacement sigma per axis = this x gap duration");
  r.Read("estimate_gyro_bias", &o->estimate_gyro_bias,
         "estimate a constant vertical gyro bias in the heading increments");
  r.Read("gyro_bias_prior_sigma_radps", &o->gyro_bias_prior_sigma_radps,
         "prior sigma of the vertical gyro bias");
  r.Read("use_mag_heading", &o->use_mag_heading,
         "add a magnetometer HeadingFactor per step when the steps carry one");
  r.Read("mag_heading_sigma_rad", &o->mag_heading_sigma_rad,
         "sigma of the magnetometer heading factor");
  r.ReadEnum("mag_heading_loss", &o->mag_heading_loss, LossKindNames(),
             "robust loss of the magnetometer heading factor");
  r.Read("mag_heading_loss_scale", &o->mag_heading_loss_scale,
         "scale of that loss, in sigma of the whitened residual");
  r.Read("odometry_sigma_dist_frac", &o->odometry_sigma_dist_frac,
         "odometry walks: distance sigma per increment, fraction of its length");
  r.Read("odometry_sigma_dist_m", &o->odometry_sigma_dist_m,
         "odometry walks: constant distance sigma per increment");
  r.Read("odometry_sigma_cross_m", &o->odometry_sigma_cross_m,
         "odometry walks: lateral sigma per increment");
  r.Read("odometry_sigma_dheading_rad", &o->odometry_sigma_dheading_rad,
         "odometry walks: heading-increment sigma per increment");
}

void ReadRadioKeys(ConfigReader& r, StepGraphOptions* o) {
  r.ReadEnum("rss_residual", &o->rss_residual, RssResidualNames(),
             "RSS residual in dB (RssFactor) or as a range (RssRangeFactor, 004 eq. 7)");
  r.ReadEnum("rss_loss", &o->rss_loss, LossKindNames(), "robust loss of the RSS factors");
  r.Read("rss_loss_scale", &o->rss_loss_scale,
         "scale of the RSS loss, in sigma of the whitened residual");
  r.ReadEnum("range_loss", &o->range_loss, LossKindNames(), "robust loss of the range factors");
  r.Read("range_loss_scale", &o->range_loss_scale,
         "scale of the range loss, in sigma of the whitened residual");
  r.Read("receiver_height_m", &o->receiver_height_m,
         "receiver height for the planar graph's ranges and RSS");
  r.Read("range_sigma_m", &o->range_sigma_m,
         "range sigma; > 0 overrides walk.yaml radio.range_sigma_m");
  r.Read("A_dbm", &o->A_dbm,
         "path loss A; unset (NaN): walk.yaml radio's; prior mean when self-calibrating");
  r.Read("eta", &o->eta,
         "path loss exponent; 0: walk.yaml radio's; prior mean when self-calibrating");
  r.Read("sigma_db", &o->sigma_db, "RSS noise sigma; 0: walk.yaml radio's");
  r.ReadEnum("path_loss", &o->path_loss, PathLossModeNames(),
             "self-calibration of the path loss (A, eta) of the RSS factors");
  r.Read("A_prior_sigma_db", &o->A_prior_sigma_db,
         "prior sigma of estimated A around the walk's value");
  r.Read("eta_prior_sigma", &o->eta_prior_sigma,
         "prior sigma of estimated eta around the walk's value");
  r.Read("A_spread_prior_db", &o->A_spread_prior_db,
         "hierarchical: sigma of one anchor's A around the walk-wide mean");
  r.Read("eta_spread_prior", &o->eta_spread_prior,
         "hierarchical: sigma of one anchor's eta around the walk-wide mean");
  r.ReadEnum("range_bias", &o->range_bias, CalibrationScopeNames(),
             "additive range bias b estimated: none, one for the walk, or per anchor");
  r.Read("range_bias_prior_sigma_m", &o->range_bias_prior_sigma_m,
         "prior sigma of the range bias b");
  r.ReadEnum("range_scale", &o->range_scale, CalibrationScopeNames(),
             "range scale error s (rho = (1 + s) d + b): none, global or per anchor");
  r.Read("range_scale_prior_sigma", &o->range_scale_prior_sigma,
         "prior sigma of the range scale error s");
  r.Read("anchor_search_margin_m", &o->anchor_search_margin_m,
         "fg-batch, unknown anchors: grid search over the path's extent plus this margin");
  r.Read("anchor_search_step_m", &o->anchor_search_step_m,
         "fg-batch, unknown anchors: the coarse grid's spacing");
  r.Read("anchor_min_readings", &o->anchor_min_readings,
         "fg-batch, unknown anchors: fewer readings leave an anchor unobservable");
  r.Read("anchor_min_spread_m", &o->anchor_min_spread_m,
         "fg-batch, unknown anchors: least spread (1 sigma) of the path across its narrowest "
         "direction at the anchor's readings");
  r.Read("anchor_distinct_radius_m", &o->anchor_distinct_radius_m,
         "fg-batch, unknown anchors: another grid minimum farther than this is another place");
  r.Read("anchor_min_cost_gap", &o->anchor_min_cost_gap,
         "fg-batch, unknown anchors: least cost by which the best place beats any other");
  r.Read("align_window_s", &o->align_window_s,
         "span of dead reckoning aligned to the radio fixes for the start check");
  r.Read("start_check", &o->start_check, "drop a known start heading that the radio contradicts");
  r.Read("start_check_rad", &o->start_check_rad,
         "start check: least turn of the aligned dead reckoning to drop it");
  r.Read("start_check_sigmas", &o->start_check_sigmas,
         "start check: least turn in heading sigmas to drop it");
}

void ReadSolverKeys(ConfigReader& r, StepGraphOptions* o) {
  r.ReadEnum("initialization", &o->initialization, StepGraphInitNames(),
             "fg-batch start: dead reckoning, a fast fixed-lag pass, or by walk");
  r.Read("max_iterations", &o->max_iterations, "fg-batch: most Levenberg-Marquardt iterations");
  r.Read("initial_trust_region_radius", &o->initial_trust_region_radius,
         "fg-batch: LM starting trust-region radius");
  r.Read("function_tolerance", &o->function_tolerance, "fg-batch: Ceres relative cost-change stop");
  r.Read("parameter_tolerance", &o->parameter_tolerance, "fg-batch: Ceres relative step-size stop");
  r.Read("num_threads", &o->num_threads, "Ceres threads per solve");
  r.Read("covariance", &o->covariance,
         "compute each node's (position, heading) covariance for the output");
  r.Read("lag_s", &o->lag_s, "fg-window: span of the fixed-lag window");
  r.Read("window_max_iterations", &o->window_max_iterations,
         "fg-window: most LM iterations per window update");
  r.ReadEnum("window_output", &o->window_output, WindowOutputNames(),
             "fg-window: each node's estimate when it leaves the window, or right after added");
  r.ReadEnum("window_linear_solver", &o->window_linear_solver, WindowLinearSolverNames(),
             "fg-window: linear solver of each window solve");
  r.Read("window_update_s", &o->window_update_s,
         "fg-window: 0 one update per node; > 0 nodes gathered per this period");
  r.Read("window_marginalize_batch_s", &o->window_marginalize_batch_s,
         "fg-window: nodes leave the window in batches of this span");
  r.Read("window_initial_trust_region_radius", &o->window_initial_trust_region_radius,
         "fg-window: LM starting trust-region radius per solve");
  r.Read("window_function_tolerance", &o->window_function_tolerance,
         "fg-window: Ceres relative cost-change stop per solve");
  r.Read("init_lag_s", &o->init_lag_s, "initialization window: lag of the fast fixed-lag pass");
  r.Read("start_hypotheses", &o->start_hypotheses,
         "no start: dead reckoning aligned to every fix, turned n ways, each solved (0: off)");
  r.Read("start_estimators", &o->start_estimators,
         "no start: comma-separated estimator ids whose trajectories are more start hypotheses");
  r.Read("init_update_s", &o->init_update_s, "initialization window: one update per this period");
  r.Read("init_max_iterations", &o->init_max_iterations,
         "initialization window: LM iterations per update");
}

}  // namespace

StatusOr<StepGraphOptions> StepGraphOptionsFromYaml(const YAML::Node& node,
                                                    const std::string& context,
                                                    StepGraphOptions o) {
  ConfigReader r(node, context);
  const YAML::Node pdr = r.Child("pdr");
  ReadMotionKeys(r, &o);
  ReadRadioKeys(r, &o);
  ReadSolverKeys(r, &o);
  WG_RETURN_IF_ERROR(r.Finish());
  if (pdr.IsDefined()) {
    WG_ASSIGN_OR_RETURN(o.pdr, PdrOptionsFromYaml(pdr));
  }
  WG_RETURN_IF_ERROR(CheckStepGraphOptions(o, context));
  return o;
}

Status StepGraphOptions::Validate() const { return CheckStepGraphOptions(*this, "step graph"); }

namespace {

// Every rule of the options, messages prefixed with `context`.
Status CheckStepGraphOptions(const StepGraphOptions& o, const std::string& context) {
  auto positive = [&](double v, const char* name) -> Status {
    if (!(v > 0)) return InvalidArgument(context + ": " + name + " must be > 0");
    return Status::Ok();
  };
  WG_RETURN_IF_ERROR(positive(o.sigma_cross_m, "sigma_cross_m"));
  WG_RETURN_IF_ERROR(positive(o.baro_sigma_m, "baro_sigma_m"));
  WG_RETURN_IF_ERROR(positive(o.baro_window_s, "baro_window_s"));
  WG_RETURN_IF_ERROR(positive(o.start_height_sigma_m, "start_height_sigma_m"));
  WG_RETURN_IF_ERROR(positive(o.stair_rate_mps, "stair_rate_mps"));
  WG_RETURN_IF_ERROR(positive(o.stair_window_s, "stair_window_s"));
  WG_RETURN_IF_ERROR(positive(o.stair_tread_m, "stair_tread_m"));
  WG_RETURN_IF_ERROR(positive(o.stair_tread_sigma_m, "stair_tread_sigma_m"));
  WG_RETURN_IF_ERROR(positive(o.stair_min_rise_storeys, "stair_min_rise_storeys"));
  if (!(o.stair_landing_s >= 0)) return InvalidArgument(context + ": stair_landing_s must be >= 0");
  if (!(o.level_sigma_m >= 0)) return InvalidArgument(context + ": level_sigma_m must be >= 0");
  if (!(o.floor_sigma_m >= 0)) return InvalidArgument(context + ": floor_sigma_m must be >= 0");
  if (!(o.floor_snap_storeys >= 0 && o.floor_snap_storeys < 0.5)) {
    return InvalidArgument(context + ": floor_snap_storeys must be in [0, 0.5)");
  }
  if (!(o.baro_drift_m2ps >= 0)) return InvalidArgument(context + ": baro_drift_m2ps must be >= 0");
  WG_RETURN_IF_ERROR(positive(o.step_sigma_scale, "step_sigma_scale"));
  WG_RETURN_IF_ERROR(positive(o.dheading_sigma_scale, "dheading_sigma_scale"));
  WG_RETURN_IF_ERROR(positive(o.min_sigma_length_m, "min_sigma_length_m"));
  WG_RETURN_IF_ERROR(positive(o.min_sigma_dheading_rad, "min_sigma_dheading_rad"));
  WG_RETURN_IF_ERROR(positive(o.max_step_duration_s, "max_step_duration_s"));
  WG_RETURN_IF_ERROR(positive(o.radio_epoch_s, "radio_epoch_s"));
  WG_RETURN_IF_ERROR(positive(o.motion_sigma_mps, "motion_sigma_mps"));
  WG_RETURN_IF_ERROR(positive(o.bridge_speed_mps, "bridge_speed_mps"));
  WG_RETURN_IF_ERROR(positive(o.gyro_bias_prior_sigma_radps, "gyro_bias_prior_sigma_radps"));
  WG_RETURN_IF_ERROR(positive(o.mag_heading_sigma_rad, "mag_heading_sigma_rad"));
  WG_RETURN_IF_ERROR(positive(o.mag_heading_loss_scale, "mag_heading_loss_scale"));
  WG_RETURN_IF_ERROR(positive(o.odometry_sigma_cross_m, "odometry_sigma_cross_m"));
  WG_RETURN_IF_ERROR(positive(o.odometry_sigma_dheading_rad, "odometry_sigma_dheading_rad"));
  WG_RETURN_IF_ERROR(positive(o.rss_loss_scale, "rss_loss_scale"));
  WG_RETURN_IF_ERROR(positive(o.range_loss_scale, "range_loss_scale"));
  WG_RETURN_IF_ERROR(positive(o.A_prior_sigma_db, "A_prior_sigma_db"));
  WG_RETURN_IF_ERROR(positive(o.eta_prior_sigma, "eta_prior_sigma"));
  WG_RETURN_IF_ERROR(positive(o.A_spread_prior_db, "A_spread_prior_db"));
  WG_RETURN_IF_ERROR(positive(o.eta_spread_prior, "eta_spread_prior"));
  WG_RETURN_IF_ERROR(positive(o.range_bias_prior_sigma_m, "range_bias_prior_sigma_m"));
  WG_RETURN_IF_ERROR(positive(o.range_scale_prior_sigma, "range_scale_prior_sigma"));
  WG_RETURN_IF_ERROR(positive(o.align_window_s, "align_window_s"));
  WG_RETURN_IF_ERROR(positive(o.anchor_search_margin_m, "anchor_search_margin_m"));
  WG_RETURN_IF_ERROR(positive(o.anchor_search_step_m, "anchor_search_step_m"));
  WG_RETURN_IF_ERROR(positive(o.anchor_distinct_radius_m, "anchor_distinct_radius_m"));
  if (o.anchor_min_readings < 3 || o.anchor_min_spread_m < 0 || !(o.anchor_min_cost_gap >= 0)) {
    return InvalidArgument(context +
                           ": anchor_min_readings must be >= 3, anchor_min_spread_m and "
                           "anchor_min_cost_gap >= 0");
  }
  if (!(o.anchor_search_margin_m <= 1e4 && o.anchor_search_step_m >= 0.01 &&
        (o.anchor_search_margin_m / o.anchor_search_step_m) <= 1e4)) {
    return InvalidArgument(context +
                           ": anchor_search_margin_m <= 10 km, anchor_search_step_m >= 0.01 m, "
                           "margin/step <= 10000");
  }
  WG_RETURN_IF_ERROR(positive(o.start_check_rad, "start_check_rad"));
  WG_RETURN_IF_ERROR(positive(o.start_check_sigmas, "start_check_sigmas"));
  WG_RETURN_IF_ERROR(positive(o.lag_s, "lag_s"));
  WG_RETURN_IF_ERROR(
      positive(o.window_initial_trust_region_radius, "window_initial_trust_region_radius"));
  WG_RETURN_IF_ERROR(positive(o.initial_trust_region_radius, "initial_trust_region_radius"));
  WG_RETURN_IF_ERROR(positive(o.function_tolerance, "function_tolerance"));
  WG_RETURN_IF_ERROR(positive(o.window_function_tolerance, "window_function_tolerance"));
  WG_RETURN_IF_ERROR(positive(o.parameter_tolerance, "parameter_tolerance"));
  if (o.odometry_sigma_dist_frac < 0 || o.odometry_sigma_dist_m < 0 ||
      o.odometry_sigma_dist_frac + o.odometry_sigma_dist_m <= 0) {
    return InvalidArgument(context + ": odometry_sigma_dist_frac/_m must be >= 0, not both 0");
  }
  if (o.range_sigma_m < 0) return InvalidArgument(context + ": range_sigma_m must be >= 0");
  if (o.eta < 0 || o.sigma_db < 0 || std::isinf(o.A_dbm)) {
    return InvalidArgument(context +
                           ": eta, sigma_db must be > 0 (0: the walk's) and A_dbm finite");
  }
  if (o.max_iterations < 1 || o.window_max_iterations < 1 || o.init_max_iterations < 1 ||
      o.num_threads < 1) {
    return InvalidArgument(
        context + ": max_iterations, window_max_iterations, init_max_iterations, num_threads >= 1");
  }
  WG_RETURN_IF_ERROR(
      CheckEnumOption(LossKindNames(), o.mag_heading_loss, "mag_heading_loss", context));
  WG_RETURN_IF_ERROR(CheckEnumOption(RssResidualNames(), o.rss_residual, "rss_residual", context));
  WG_RETURN_IF_ERROR(CheckEnumOption(LossKindNames(), o.rss_loss, "rss_loss", context));
  WG_RETURN_IF_ERROR(CheckEnumOption(LossKindNames(), o.range_loss, "range_loss", context));
  WG_RETURN_IF_ERROR(CheckEnumOption(PathLossModeNames(), o.path_loss, "path_loss", context));
  WG_RETURN_IF_ERROR(CheckEnumOption(CalibrationScopeNames(), o.range_bias, "range_bias", context));
  WG_RETURN_IF_ERROR(
      CheckEnumOption(CalibrationScopeNames(), o.range_scale, "range_scale", context));
  WG_RETURN_IF_ERROR(
      CheckEnumOption(StepGraphInitNames(), o.initialization, "initialization", context));
  WG_RETURN_IF_ERROR(
      CheckEnumOption(WindowOutputNames(), o.window_output, "window_output", context));
  WG_RETURN_IF_ERROR(CheckEnumOption(WindowLinearSolverNames(), o.window_linear_solver,
                                     "window_linear_solver", context));
  if (o.path_loss != PathLossMode::kAuto && o.path_loss != PathLossMode::kFixed &&
      o.rss_residual != RssResidual::kDb) {
    return InvalidArgument(context + ": path-loss self-calibration needs rss_residual 'db'");
  }
  WG_RETURN_IF_ERROR(positive(o.init_lag_s, "init_lag_s"));
  if (o.start_hypotheses < 0 || o.start_hypotheses > 360) {
    return InvalidArgument(context + ": start_hypotheses must be in [0, 360]");
  }
  for (const std::string& id : SplitIds(o.start_estimators)) {
    if (id.empty() || id.rfind("fg-", 0) == 0) {
      return InvalidArgument(context +
                             ": start_estimators must list estimator ids (none of "
                             "the step graph's own, fg-*), comma-separated: '" +
                             o.start_estimators + "'");
    }
  }
  if (o.window_update_s < 0 || o.init_update_s < 0 || o.window_marginalize_batch_s < 0) {
    return InvalidArgument(context +
                           ": window_update_s, init_update_s, window_marginalize_batch_s must "
                           "be >= 0");
  }
  return Status::Ok();
}

}  // namespace

// ------------------------------------------------------------------ the graph

namespace {

// path_loss "auto": see StepGraphOptions::path_loss. *held_radio_only: auto held it because
// the walk has neither steps nor odometry.
PathLossMode ResolvePathLoss(const Walk& walk, const StepGraphOptions& o, bool* held_radio_only) {
  *held_radio_only = false;
  if (o.path_loss != PathLossMode::kAuto) return o.path_loss;
  if (walk.meta.radio.calibrated || o.rss_residual != RssResidual::kDb) return PathLossMode::kFixed;
  *held_radio_only = !walk.has_odometry() && !walk.has_imu();
  return *held_radio_only ? PathLossMode::kFixed : PathLossMode::kHierarchical;
}

}  // namespace

namespace {

// The rigid transform taking the dead reckoning `init` of the first align_window_s onto the
// radio position fixes there (Umeyama, no scale), with how well it is determined: the spread
// of the dead-reckoned points and the RMS residual after alignment.
struct Alignment {
  Eigen::Matrix2d R;
  Eigen::Vector2d t;
  double rotation_rad = 0.0;
  double spread_m = 0.0;    // RMS distance of the aligned points from their mean
  double residual_m = 0.0;  // RMS fix − aligned point
};

Alignment Align(const std::vector<Eigen::Vector2d>& src, const std::vector<Eigen::Vector2d>& dst,
                size_t count) {
  Eigen::Matrix2Xd S(2, count), D(2, count);
  for (size_t i = 0; i < count; ++i) {
    S.col(static_cast<Eigen::Index>(i)) = src[i];
    D.col(static_cast<Eigen::Index>(i)) = dst[i];
  }
  const Eigen::Matrix3d T = Eigen::umeyama(S, D, /*with_scaling=*/false);
  Alignment a;
  a.R = T.topLeftCorner<2, 2>();
  a.t = T.topRightCorner<2, 1>();
  a.rotation_rad = std::atan2(T(1, 0), T(0, 0));
  const Eigen::Matrix2Xd aligned = (a.R * S).colwise() + a.t;
  const double n = static_cast<double>(count);
  a.residual_m = std::sqrt((D - aligned).colwise().squaredNorm().sum() / n);
  a.spread_m = std::sqrt((S.colwise() - S.rowwise().mean()).colwise().squaredNorm().sum() / n);
  return a;
}

// Fixes of the first align_window_s — or, while the walker has not moved enough there for the
// rotation to be determined (spread ≤ 2 × residual: e.g. standing at the start), of a window
// doubled until it has, up to the whole walk.
std::optional<Alignment> AlignToFirstFixes(const Walk& walk, const StepGraphOptions& o,
                                           const std::vector<double>& node_t,
                                           const std::vector<Eigen::Vector3d>& init) {
  if (walk.rss.empty() && walk.ranges.empty()) return std::nullopt;
  EpochOptions eo;
  eo.receiver_height_m = o.receiver_height_m;
  auto fixes = PositionWalk(walk, eo, PositioningMethod::kNonlinearLs);
  if (!fixes.ok()) return std::nullopt;
  std::vector<Eigen::Vector2d> src, dst;
  std::vector<double> t;
  for (const FixResult& f : *fixes) {
    if (!f.ok()) continue;
    const auto it = std::lower_bound(node_t.begin(), node_t.end(), f.fix.t_s);
    Eigen::Vector2d q;
    if (it == node_t.begin()) {
      q = init.front().head<2>();
    } else if (it == node_t.end()) {
      q = init.back().head<2>();
    } else {
      const size_t b = static_cast<size_t>(it - node_t.begin());
      const double w = (f.fix.t_s - node_t[b - 1]) / (node_t[b] - node_t[b - 1]);
      q = (1 - w) * init[b - 1].head<2>() + w * init[b].head<2>();
    }
    src.push_back(q);
    dst.push_back(f.fix.position_m);
    t.push_back(f.fix.t_s);
  }
  if (src.size() < 3) return std::nullopt;
  std::optional<Alignment> a;
  for (double window = o.align_window_s;; window *= 2.0) {
    size_t count = 0;
    while (count < t.size() && (t[count] <= node_t.front() + window || count < 3)) ++count;
    a = Align(src, dst, count);
    if (a->spread_m > 2.0 * a->residual_m || count == t.size()) return a;
  }
}

}  // namespace

// Nodes whose interval (t_{k−1}, t_k] overlaps an IMU gap, on walks whose steps come from the
// IMU (odometry and radio-only walks have none).
std::vector<bool> BridgedNodes(const Walk& walk, bool imu_steps, const std::vector<double>& t) {
  std::vector<bool> out(t.size(), false);
  if (!imu_steps) return out;
  for (const ImuGap& gap : walk.ImuGaps()) {
    const auto first = std::upper_bound(t.begin(), t.end(), gap.t_begin_s);
    for (auto it = first; it != t.end(); ++it) {
      const size_t k = static_cast<size_t>(it - t.begin());
      if (k == 0) continue;
      if (t[k - 1] >= gap.t_end_s) break;
      out[k] = true;
    }
  }
  return out;
}

StepGraph::~StepGraph() = default;

// A known start whose heading the radio contradicts (issue 17: a recording's truth heading
// column π off the direction of travel): the dead reckoning of the first align_window_s,
// aligned to the radio fixes there, says by how much the start heading is off. When that is
// more than max(start_check_rad, start_check_sigmas × σ_heading) and the alignment is well
// determined (the walker moved: spread > 2 × residual), the start heading is treated as
// unknown (no heading prior) and the dead reckoning is rotated about the start position by
// that angle. A position-only start on a walk whose steps carry no heading (odometry) takes
// its heading from the same alignment instead of 0.
// StepGraphOptions::user_factors, called once; each factor goes with its newest node (static
// keys only: node 0), so the window adds it when every pose it names is there.
Status StepGraph::Impl::AddUserFactors(const Walk& walk, const std::vector<double>& node_t) {
  user_at.assign(node_t.size(), {});
  WG_ASSIGN_OR_RETURN(std::vector<GraphFactor> factors,
                      internal::CallUserFactors(o.user_factors, walk, node_t));
  for (size_t i = 0; i < factors.size(); ++i) {
    uint64_t newest = 0;
    for (const Key key : factors[i].keys) {
      const char letter = SymbolLetter(key);
      if (letter != 'x' && letter != 'h') continue;
      if (SymbolIndex(key) >= node_t.size()) {
        return InvalidArgument("user factor " + std::to_string(i) + ": key " + KeyToString(key) +
                               " beyond the last pose (" + std::to_string(node_t.size() - 1) + ")");
      }
      newest = std::max(newest, SymbolIndex(key));
    }
    user_at[newest].push_back(std::move(factors[i]));
  }
  return Status::Ok();
}

void StepGraph::Impl::CheckStartHeading(const Walk& walk, StepGraph* g) {
  Impl* m = this;
  const bool no_heading = !m->start->heading_known && (m->odometry || m->steps.empty());
  if (!(m->start->heading_known && o.start_check) && !no_heading) return;
  const std::optional<Alignment> a = AlignToFirstFixes(walk, o, g->node_t_, g->init_);
  if (!a || !(a->spread_m > 2.0 * a->residual_m)) return;
  const double limit =
      std::max(o.start_check_rad, o.start_check_sigmas * m->start->sigma_heading_rad);
  const double off = std::abs(NormalizeAngle(a->rotation_rad));
  if (!no_heading && off <= limit) return;
  if (!no_heading) {
    m->start->heading_known = false;
    g->start_heading_contradicted_ = off;
  }
  const Eigen::Vector2d s(m->start->x_m, m->start->y_m);
  const Eigen::Rotation2Dd R(a->rotation_rad);
  for (Eigen::Vector3d& p : g->init_) {
    p.head<2>() = s + R * (p.head<2>() - s);
    p[2] = NormalizeAngle(p[2] + a->rotation_rad);
  }
}

Status StepGraph::Impl::MakeNodes(const Walk& walk, StepGraph* g) {
  const StepGraphOptions& o = this->o;
  std::vector<double> t;
  radio_only = !walk.has_odometry() && !walk.has_imu();
  if (radio_only) {
    // No steps: one node per radio epoch (a new node once radio_epoch_s has passed), joined by
    // the random-walk motion model; the first reading's time is node 0.
    std::vector<double> rt;
    for (const RssSample& s : walk.rss) rt.push_back(s.t_s);
    for (const RangeSample& s : walk.ranges) rt.push_back(s.t_s);
    std::sort(rt.begin(), rt.end());
    if (rt.empty()) return FailedPrecondition("step graph: the walk has no steps and no radio");
    double node = rt.front();
    for (double x : rt) {
      if (x >= node + o.radio_epoch_s) t.push_back(node = x);
    }
    if (t.empty()) t.push_back(rt.back() + o.radio_epoch_s);
  } else if (odometry) {
    odom = walk.odometry;
    for (const OdometrySample& s : odom) t.push_back(s.t_s);
  } else {
    WG_ASSIGN_OR_RETURN(StepSequence seq, StepsForWalk(walk, o.pdr));
    steps = std::move(seq.steps);
    front_end = seq.report;
    for (const Step& s : steps) t.push_back(s.t_s);
  }
  if (t.empty()) return FailedPrecondition("step graph: the walk has no steps or odometry");
  for (size_t i = 1; i < t.size(); ++i) {
    if (!(t[i] > t[i - 1])) {
      return InvalidArgument("step graph: step times must increase (step " + std::to_string(i) +
                             " at " + internal::Num(t[i]) + " s)");
    }
  }
  const double first_duration = odometry || radio_only ? 0.0 : steps.front().duration_s;
  const double t0 =
      radio_only
          ? t.front() - o.radio_epoch_s
          : std::min(walk.StartTime(), t.front() - std::max(std::min(first_duration, 1.0), 0.01));
  g->node_t_.push_back(t0);
  g->node_t_.insert(g->node_t_.end(), t.begin(), t.end());

  return Status::Ok();
}

void StepGraph::Impl::DeadReckon(const Walk& walk, StepGraph* g) {
  const int n = g->num_nodes();
  // Dead reckoning from the start (or the origin), θ the node heading.
  bridged = BridgedNodes(walk, !odometry && !radio_only, g->node_t_);
  Eigen::Vector3d x = Eigen::Vector3d::Zero();
  if (start) {
    // A position-only start: the front end's heading at the start (before the first step).
    const double heading =
        start->heading_known || steps.empty()
            ? start->heading_rad
            : NormalizeAngle(steps.front().heading_rad - steps.front().dheading_rad);
    x = Eigen::Vector3d(start->x_m, start->y_m, heading);
  }
  g->init_.push_back(x);
  for (int k = 1; k < n; ++k) {
    x = Predict(k, x);  // radio-only walks: positions come from the radio fixes below
    g->init_.push_back(x);
  }
}

Status StepGraph::Impl::AttachReadings(const Walk& walk, StepGraph* g) {
  const StepGraphOptions& o = this->o;
  const int n = g->num_nodes();
  // Radio readings, attached to the node(s) around them.
  anchor_has_rss.assign(walk.anchors.size(), false);
  anchor_has_range.assign(walk.anchors.size(), false);
  readings_at.assign(n, {});
  auto attach = [&](double ts, Reading r) {
    if (radio_only) {  // the epoch's node: the last node at or before the reading
      const auto up = std::upper_bound(g->node_t_.begin(), g->node_t_.end(), ts);
      r.node_a = std::max(0, static_cast<int>(up - g->node_t_.begin()) - 1);
      readings_at[r.node_a].push_back(r);
      return;
    }
    const auto it = std::lower_bound(g->node_t_.begin(), g->node_t_.end(), ts);
    if (it == g->node_t_.begin()) {
      r.node_a = 0;
    } else if (it == g->node_t_.end()) {
      r.node_a = n - 1;
    } else {
      const int b = static_cast<int>(it - g->node_t_.begin()), a = b - 1;
      const double tb = g->node_t_[b];
      const double ta =
          bridged[b] ? g->node_t_[a] : std::max(g->node_t_[a], tb - o.max_step_duration_s);
      const double alpha = ts <= ta ? 0.0 : std::min(1.0, (ts - ta) / (tb - ta));
      if (alpha <= 1e-9) {
        r.node_a = a;
      } else if (alpha >= 1.0 - 1e-9) {
        r.node_a = b;
      } else {
        r.node_a = a, r.node_b = b, r.alpha = alpha;
      }
    }
    readings_at[r.node_b >= 0 ? r.node_b : r.node_a].push_back(r);
  };
  for (const RssSample& s : walk.rss) {
    const int a = walk.AnchorIndex(s.anchor_id);
    if (a < 0)
      return InvalidArgument("step graph: RSS from unknown anchor " + std::to_string(s.anchor_id));
    anchor_has_rss[a] = true;
    any_rss = true;
    attach(s.t_s, Reading{a, Reading::Kind::kRss, s.rss});
  }
  for (const RangeSample& s : walk.ranges) {
    const int a = walk.AnchorIndex(s.anchor_id);
    if (a < 0)
      return InvalidArgument("step graph: range from unknown anchor " +
                             std::to_string(s.anchor_id));
    anchor_has_range[a] = true;
    any_range = true;
    attach(s.t_s, Reading{a, Reading::Kind::kRange, s.range_m});
  }
  for (size_t i = 0; i < walk.waypoints.size(); ++i) {
    attach(walk.waypoints[i].t_s, Reading{static_cast<int>(i), Reading::Kind::kWaypoint});
  }

  return Status::Ok();
}

void StepGraph::Impl::PlaceStart(const Walk& full_walk, StepGraph* g) {
  const StepGraphOptions& o = this->o;
  const int n = g->num_nodes();
  // The radio fixes below use the anchors of given position only (an unknown one's position is
  // a guess being estimated: fg-batch's).
  const Walk known = full_walk.has_unknown_anchors() ? WithoutUnknownAnchors(full_walk) : Walk();
  const Walk& walk = full_walk.has_unknown_anchors() ? known : full_walk;
  if (radio_only) {
    // Initial positions: the radio position fixes, interpolated in time (the anchors' centroid
    // where no fix exists); headings are not states of a radio-only walk (held at 0).
    Eigen::Vector2d centroid = Eigen::Vector2d::Zero();
    for (const Anchor& a : walk.anchors) centroid += a.position_m.head<2>();
    if (!walk.anchors.empty()) centroid /= static_cast<double>(walk.anchors.size());
    std::vector<std::pair<double, Eigen::Vector2d>> fixes;
    EpochOptions eo;
    eo.receiver_height_m = o.receiver_height_m;
    eo.window_s = std::max(o.radio_epoch_s, 1.0);
    auto result = PositionWalk(walk, eo, PositioningMethod::kNonlinearLs);
    if (result.ok()) {
      for (const FixResult& f : *result) {
        if (f.ok()) fixes.emplace_back(f.fix.t_s, f.fix.position_m);
      }
    }
    for (int k = 0; k < n; ++k) {
      Eigen::Vector2d q = centroid;
      if (!fixes.empty()) {
        const double tk = g->node_t_[k];
        auto it = std::lower_bound(fixes.begin(), fixes.end(), tk,
                                   [](const auto& f, double t) { return f.first < t; });
        if (it == fixes.begin()) {
          q = fixes.front().second;
        } else if (it == fixes.end()) {
          q = fixes.back().second;
        } else {
          const auto& a = *(it - 1);
          const double w = (tk - a.first) / (it->first - a.first);
          q = (1 - w) * a.second + w * it->second;
        }
      }
      g->init_[k] = Eigen::Vector3d(q.x(), q.y(), 0.0);
    }
  } else if (!start) {
    // Without a known start: align the dead reckoning to the first radio fixes; with no radio
    // either, node 0 is the gauge.
    const std::optional<Alignment> a = AlignToFirstFixes(walk, o, g->node_t_, g->init_);
    if (a) {
      for (Eigen::Vector3d& p : g->init_) {
        p.head<2>() = a->R * p.head<2>() + a->t;
        p[2] = NormalizeAngle(p[2] + a->rotation_rad);
      }
    } else {
      g->fix_first_node_ = !(any_rss || any_range) || walk.anchors.size() < 3;
    }
    // Anchors that are states (walk.h Anchor) do not fix the frame by themselves: with fewer
    // than 2 heard anchors of given position, node 0 is the gauge (the walk's own frame).
    int placed = 0;
    for (size_t i = 0; i < anchors.size(); ++i) {
      const bool heard = anchor_has_rss[i] || anchor_has_range[i];
      placed += heard && anchors[i].position_known ? 1 : 0;
    }
    if (placed < 2) g->fix_first_node_ = true;
  } else if (any_rss || any_range) {
    CheckStartHeading(walk, g);
  }
}

StatusOr<std::unique_ptr<StepGraph>> StepGraph::Build(const Walk& walk, const StepGraphOptions& o) {
  WG_RETURN_IF_ERROR(o.Validate());  // options set in C++ meet the YAML's rules
  std::unique_ptr<StepGraph> g(new StepGraph());
  g->impl_ = std::make_unique<Impl>();
  Impl& m = *g->impl_;
  m.o = o;
  m.anchors = walk.anchors;
  for (const Anchor& a : walk.anchors) {
    bool state = !a.surveyed();
    if (!a.position_known && !a.position_m.head<2>().allFinite()) {
      return InvalidArgument("step graph: anchor " + std::to_string(a.id) +
                             " has no position (anchors.csv x_m, y_m empty); fg-batch estimates "
                             "it, the other estimators run without it (registry)");
    }
    if (state && o.rss_residual == RssResidual::kRange) {
      // The range-domain RSS residual has no path-loss block: uncertain anchors are held at
      // their mean there; unknown ones need the dB residual.
      if (!a.position_known) {
        return InvalidArgument("step graph: anchor " + std::to_string(a.id) +
                               " of unknown position needs rss_residual: db");
      }
      state = false;
    }
    m.anchor_state.push_back(state);
  }
  m.waypoints = walk.waypoints;
  m.radio = walk.meta.radio;
  if (std::isfinite(o.A_dbm)) m.radio.path_loss.A_dbm = o.A_dbm;
  if (o.eta > 0) m.radio.path_loss.eta = o.eta;
  if (o.sigma_db > 0) m.radio.path_loss.sigma_db = o.sigma_db;
  m.start = walk.meta.initial_pose;
  m.odometry = walk.has_odometry();
  m.o.path_loss = ResolvePathLoss(walk, o, &g->path_loss_held_radio_only_);
  m.rss_loss = internal::MakeLoss(o.rss_loss, o.rss_loss_scale);
  m.range_loss = internal::MakeLoss(o.range_loss, o.range_loss_scale);
  m.mag_loss = internal::MakeLoss(o.mag_heading_loss, o.mag_heading_loss_scale);

  WG_RETURN_IF_ERROR(m.MakeNodes(walk, g.get()));
  m.MakeHeights(walk, g->node_t_);
  m.stair_steps = m.MarkStairs(walk, g->node_t_);
  m.DeadReckon(walk, g.get());
  WG_RETURN_IF_ERROR(m.ChainHeights(g->node_t_));  // after DeadReckon: bridged
  for (const Anchor& a : walk.anchors) {
    m.anchor_z.push_back(walk.AnchorHeightM(a));
    m.anchor_floor.push_back(a.floor);
  }
  WG_RETURN_IF_ERROR(m.AttachReadings(walk, g.get()));
  m.PlaceStart(walk, g.get());
  WG_RETURN_IF_ERROR(m.AddUserFactors(walk, g->node_t_));
  return g;
}

bool StepGraph::path_loss_per_anchor() const { return impl_->PathLossPerAnchor(); }

bool StepGraph::AnchorIsState(int anchor_index) const { return impl_->AnchorIsState(anchor_index); }

bool StepGraph::has_floors() const { return impl_->floors; }

int StepGraph::FloorOfHeight(double z_m) const { return impl_->Floor(z_m); }

int StepGraph::stair_steps() const { return impl_->stair_steps; }

const StepFrontEndReport& StepGraph::front_end_report() const { return impl_->front_end; }

std::vector<std::vector<Eigen::Vector3d>> StepGraph::StartHypotheses(const Walk& walk,
                                                                     int n) const {
  const Impl& m = *impl_;
  std::vector<std::vector<Eigen::Vector3d>> out;
  if (n <= 0 || m.start || m.radio_only || !(m.any_rss || m.any_range)) return out;
  StepGraphOptions all = m.o;
  all.align_window_s = std::numeric_limits<double>::infinity();  // every fix
  const std::optional<Alignment> a = AlignToFirstFixes(walk, all, node_t_, init_);
  if (!a) return out;
  std::vector<Eigen::Vector3d> aligned = init_;
  Eigen::Vector2d centroid = Eigen::Vector2d::Zero();
  for (Eigen::Vector3d& p : aligned) {
    p.head<2>() = a->R * p.head<2>() + a->t;
    p[2] = NormalizeAngle(p[2] + a->rotation_rad);
    centroid += p.head<2>();
  }
  centroid /= static_cast<double>(aligned.size());
  for (int k = 0; k < n; ++k) {
    const double turn = 2.0 * kPi * k / n;
    const Eigen::Rotation2Dd R(turn);
    std::vector<Eigen::Vector3d> h = aligned;
    for (Eigen::Vector3d& p : h) {
      p.head<2>() = centroid + R * (p.head<2>() - centroid);
      p[2] = NormalizeAngle(p[2] + turn);
    }
    out.push_back(std::move(h));
  }
  return out;
}

std::vector<std::vector<Eigen::Vector3d>> StepGraph::HypothesesFrom(const Trajectory& trajectory,
                                                                    double until_s) const {
  const Impl& m = *impl_;
  std::vector<std::vector<Eigen::Vector3d>> out;
  if (m.start || m.radio_only || trajectory.empty()) return out;
  const double t0 = trajectory.points.front().t_s, t1 = trajectory.points.back().t_s;
  std::vector<Eigen::Vector2d> src, dst;
  size_t last = 0;  // nodes [0, last) are hypothesized: t <= until_s
  for (size_t k = 0; k < node_t_.size() && node_t_[k] <= until_s; ++k) {
    last = k + 1;
    if (node_t_[k] < t0 || node_t_[k] > t1) continue;
    src.push_back(init_[k].head<2>());
    dst.push_back(trajectory.PositionAt(node_t_[k]).head<2>());
  }
  if (src.size() < 3) return out;
  const Alignment a = Align(src, dst, src.size());  // Procrustes (Umeyama, no scale)
  std::vector<Eigen::Vector3d> aligned(init_.begin(), init_.begin() + static_cast<long>(last));
  for (Eigen::Vector3d& p : aligned) {
    p.head<2>() = a.R * p.head<2>() + a.t;
    p[2] = NormalizeAngle(p[2] + a.rotation_rad);
  }
  std::vector<Eigen::Vector3d> positions = aligned;
  for (size_t k = 0; k < last; ++k) {
    positions[k].head<2>() = trajectory.PositionAt(node_t_[k]).head<2>();
  }
  out.push_back(std::move(aligned));
  out.push_back(std::move(positions));
  return out;
}

namespace {

// The mean pressure of the readings within ±window/2 of t, else the reading nearest in time.
double PressureAt(const std::vector<PressureSample>& p, double t, double window_s) {
  auto by_time = [](const PressureSample& s, double x) { return s.t_s < x; };
  auto lo = std::lower_bound(p.begin(), p.end(), t - 0.5 * window_s, by_time);
  auto hi = std::lower_bound(p.begin(), p.end(), t + 0.5 * window_s, by_time);
  if (lo == hi) {
    auto it = std::lower_bound(p.begin(), p.end(), t, by_time);
    if (it == p.end() || (it != p.begin() && t - (it - 1)->t_s < it->t_s - t)) --it;
    return it->hpa;
  }
  double sum = 0.0;
  for (auto it = lo; it != hi; ++it) sum += it->hpa;
  return sum / static_cast<double>(hi - lo);
}

}  // namespace

// Candidates (dir[k] = ±1 for node k's step): steps whose barometric height changes at the
// rate of stairs, one way.
std::vector<int> StepGraph::Impl::StairCandidates(const Walk& walk,
                                                  const std::vector<double>& node_t) const {
  const std::vector<bool> gap = BridgedNodes(walk, true, node_t);
  const double p0 = PressureAt(walk.pressure, node_t[0], o.baro_window_s);
  auto height = [&](double t) {  // above node 0, as baro_z
    return BarometricHeightM(PressureAt(walk.pressure, t, o.baro_window_s), p0);
  };
  std::vector<int> dir(node_t.size(), 0);
  for (size_t k = 1; k < node_t.size(); ++k) {
    if (gap[k]) continue;
    const double t = 0.5 * (node_t[k - 1] + node_t[k]), h = 0.5 * o.stair_window_s;
    const double rate = (height(t + h) - height(t - h)) / o.stair_window_s;
    if (std::fabs(rate) >= o.stair_rate_mps) dir[k] = rate > 0 ? 1 : -1;
  }
  return dir;
}

int StepGraph::Impl::MarkStairs(const Walk& walk, const std::vector<double>& node_t) {
  on_stairs.assign(node_t.size(), false);
  if (!floors || odometry || radio_only) return 0;
  const std::vector<int> dir = StairCandidates(walk, node_t);
  struct Run {
    size_t a, b;  // candidate steps of nodes [a, b), one way
  };
  std::vector<Run> runs;
  for (size_t a = 1; a < node_t.size();) {
    size_t b = a;
    while (b < node_t.size() && dir[b] != 0 && dir[b] == dir[a]) ++b;
    if (b > a) runs.push_back({a, b});
    a = std::max(b, a + 1);
  }
  // A staircase: runs one way, each starting within stair_landing_s of the previous one's end
  // (a landing between flights), that together change the height by a floor transition's
  // worth (stair_min_rise_storeys × storey); shorter ones are the phone lifted or lowered.
  int n = 0;
  for (size_t i = 0; i < runs.size();) {
    size_t j = i + 1;
    while (j < runs.size() && dir[runs[j].a] == dir[runs[i].a] &&
           node_t[runs[j].a - 1] - node_t[runs[j - 1].b - 1] <= o.stair_landing_s) {
      ++j;
    }
    const double rise = baro_z[runs[j - 1].b - 1] - baro_z[runs[i].a - 1];
    for (size_t r = i; r < j && std::fabs(rise) >= o.stair_min_rise_storeys * storey_m; ++r) {
      for (size_t k = runs[r].a; k < runs[r].b; ++k) {
        on_stairs[k] = true;  // no level factor (also with stairs: false)
        if (!o.stairs) continue;
        steps[k - 1].length_m = o.stair_tread_m;
        steps[k - 1].sigma_length_m = o.stair_tread_sigma_m;
        ++n;
      }
    }
    i = j;
  }
  return n;
}

// The heights' causal estimate: a scalar Kalman filter along the height chain with the
// graph's own height factors — node 0 at the start height (σ start_height_sigma_m); each step
// the barometric change, on a level walking step combined with the level factor's 0 by their
// information; a level node whose filtered height lies within floor_snap_storeys of a floor's
// level f × storey gets that level as a measurement (σ floor_sigma_m), and the graph the same
// prior (floor_level). Forward only, so fg-window's online output stays causal. Its heights
// are the readings' receiver heights and the height states' initial values.
Status StepGraph::Impl::ChainHeights(const std::vector<double>& node_t) {
  node_z.assign(node_t.size(), start_z);
  floor_level.assign(node_t.size(), std::numeric_limits<double>::quiet_NaN());
  if (!floors) return Status::Ok();
  Eigen::VectorXd x = Eigen::VectorXd::Constant(1, start_z);
  Eigen::MatrixXd P = Eigen::MatrixXd::Constant(1, 1, std::pow(o.start_height_sigma_m, 2));
  const Eigen::MatrixXd H = Eigen::MatrixXd::Identity(1, 1);
  const Eigen::MatrixXd R = Eigen::MatrixXd::Constant(1, 1, std::pow(o.floor_sigma_m, 2));
  for (size_t k = 1; k < node_t.size(); ++k) {
    const double dt = node_t[k] - node_t[k - 1];
    const bool level = LevelStep(static_cast<int>(k), dt);
    double dz = baro_z[k] - baro_z[k - 1], var = std::pow(BaroSigma(dt), 2);
    if (level) {
      const double info = 1.0 / var + 1.0 / (o.level_sigma_m * o.level_sigma_m);
      dz *= 1.0 / (var * info);
      var = 1.0 / info;
    }
    x[0] += dz;
    P(0, 0) += var;
    const double z_floor = Floor(x[0]) * storey_m;
    if (level && o.floor_sigma_m > 0 &&
        std::fabs(x[0] - z_floor) <= o.floor_snap_storeys * storey_m) {
      floor_level[k] = z_floor;
      WG_RETURN_IF_ERROR(
          KalmanUpdate(Eigen::VectorXd::Constant(1, z_floor - x[0]), H, R, 0.0, &x, &P).status());
    }
    node_z[k] = x[0];
  }
  return Status::Ok();
}

// Each node's pressure: PressureAt (±baro_window_s/2); heights above node 0's by the standard
// atmosphere.
void StepGraph::Impl::MakeHeights(const Walk& walk, const std::vector<double>& node_t) {
  storey_m = walk.meta.storey_height_m;
  const int start_floor =
      start && start->floor ? *start->floor : 0;  // the truth's floors are not an input
  start_z = start_floor * storey_m;
  floors = o.floors && !walk.pressure.empty();
  if (!floors) return;
  std::vector<double> hpa;
  for (double t : node_t) hpa.push_back(PressureAt(walk.pressure, t, o.baro_window_s));
  baro_z.clear();
  for (double v : hpa) baro_z.push_back(BarometricHeightM(v, hpa.front()));
}

bool StepGraph::path_loss_estimated() const {
  return impl_->any_rss && impl_->o.rss_residual == RssResidual::kDb &&
         impl_->o.path_loss != PathLossMode::kFixed;
}

// ------------------------------------------------------------------ estimators

namespace {

Status CheckStepWalk(const Walk& walk) {
  if (!walk.has_odometry() && !walk.has_imu() &&
      (!(walk.has_rss() || walk.has_ranges()) || walk.anchors.size() < 3)) {
    return FailedPrecondition(
        "the step graph needs odometry.csv or an IMU (steps), or radio to >= 3 anchors");
  }
  return Status::Ok();
}

void AddStaticDiagnostics(const StepGraph& graph,
                          const std::function<std::vector<double>(Key)>& value_of, const Walk& walk,
                          const StepGraphOptions& o, std::map<std::string, double>* d) {
  // Name: "<what>" for a walk-wide block, "<what>.<anchor id>" per anchor.
  auto name = [&](const std::string& what, bool per_anchor, int group) {
    return per_anchor ? what + "." + std::to_string(walk.anchors[group].id) : what;
  };
  for (const GraphState& s : graph.StaticStates()) {
    if (s.constant) continue;
    const std::vector<double> v = value_of(s.key);
    const char letter = SymbolLetter(s.key);
    const int g = static_cast<int>(SymbolIndex(s.key));
    if (s.key == kGyroBiasKey) {
      (*d)["gyro_bias_radps"] = v[0];
    } else if (letter == 'p') {  // an anchor's position (fg-batch: anchors_estimated too)
      (*d)[name("anchor_x_m", true, g)] = v[0];
      (*d)[name("anchor_y_m", true, g)] = v[1];
    } else if (letter == 's') {
      (*d)[name("range_scale", o.range_scale == CalibrationScope::kPerAnchor, g)] = v[0];
    } else if (letter == 'b') {
      (*d)[name("range_bias_m", o.range_bias == CalibrationScope::kPerAnchor, g)] = v[0];
    } else {  // l(g): per anchor unless global; m(0): hierarchical's walk-wide mean
      const bool per_anchor = letter == 'l' && graph.path_loss_per_anchor();
      (*d)[name("path_loss_A", per_anchor, g)] = v[0];
      (*d)[name("path_loss_eta", per_anchor, g)] = v[1];
    }
  }
}

void AddGraphDiagnostics(const StepGraph& graph, const Walk& walk,
                         std::map<std::string, double>* d) {
  if (walk.has_rss()) {
    (*d)["path_loss_estimated"] = graph.path_loss_estimated() ? 1.0 : 0.0;
    if (graph.path_loss_held_radio_only()) (*d)["path_loss_held_radio_only"] = 1.0;
  }
  if (graph.start_heading_contradicted_rad() > 0.0) {
    (*d)["start_heading_contradicted_rad"] = graph.start_heading_contradicted_rad();
  }
  if (graph.has_floors()) (*d)["stair_steps"] = graph.stair_steps();
  if (walk.has_imu() && !walk.has_odometry()) AddFrontEndDiagnostics(graph.front_end_report(), d);
}

// A node's height and the floor it is on.
void SetHeight(const StepGraph& graph, double z_m, TrajectoryPoint* point) {
  point->position_m.z() = z_m;
  point->floor = graph.FloorOfHeight(z_m);
}

TrajectoryPoint MakePoint(double t, const double* p, double theta) {
  TrajectoryPoint pt;
  pt.t_s = t;
  pt.position_m = Eigen::Vector3d(p[0], p[1], 0.0);
  pt.heading_rad = NormalizeAngle(theta);
  return pt;
}

// (x, y, θ) covariance from a node's tangent-space covariance: 3×3, or 2×2 when the heading
// is not a state (radio-only walks: θ uniform, variance π²/3).
// c is the marginal of a node's variable blocks (position 2, heading 1); a constant block (the
// gauge node of a walk with neither a known start nor radio) is exact and drops out of c.
Eigen::Matrix3d PoseCovariance(const Eigen::MatrixXd& c) {
  if (c.rows() == 3) return Eigen::Matrix3d(c);
  Eigen::Matrix3d out = Eigen::Matrix3d::Zero();
  if (c.rows() == 0) return out;  // both blocks constant
  if (c.rows() == 1) {            // position constant, heading free
    out(2, 2) = c(0, 0);
    return out;
  }
  out.topLeftCorner<2, 2>() = c.topLeftCorner<2, 2>();
  out(2, 2) = kPi * kPi / 3.0;
  return out;
}

// The graph's own motion model between nodes: a step moves the walker only during its last
// max_step_duration_s, so across a longer gap (a stop) the walker stays at the previous node
// until then. An extra output point there keeps interpolated positions on that model. A
// bridged step (across an IMU gap) moves over its whole interval: no stop.
void InsertStops(const Walk& walk, double max_step_duration_s, Trajectory* trajectory) {
  std::vector<double> t;
  for (const TrajectoryPoint& p : trajectory->points) t.push_back(p.t_s);
  const std::vector<bool> bridged = BridgedNodes(walk, walk.has_imu() && !walk.has_odometry(), t);
  std::vector<TrajectoryPoint> out;
  out.reserve(trajectory->points.size());
  for (size_t k = 0; k < trajectory->points.size(); ++k) {
    const TrajectoryPoint& p = trajectory->points[k];
    if (k > 0 && !bridged[k]) {
      const TrajectoryPoint& prev = trajectory->points[k - 1];
      const double start = p.t_s - max_step_duration_s;
      if (start > prev.t_s + 1e-6) {
        TrajectoryPoint still = prev;
        still.t_s = start;
        out.push_back(still);
      }
    }
    out.push_back(p);
  }
  trajectory->points = std::move(out);
}

}  // namespace

namespace {
StatusOr<EstimateResult> RunWindowNodes(const Walk& walk, const StepGraphOptions& options);
}  // namespace

namespace {

// fg-batch's solver options.
SolverOptions BatchSolverOptions(const StepGraphOptions& o) {
  SolverOptions so;
  so.max_iterations = o.max_iterations;
  so.initial_trust_region_radius = o.initial_trust_region_radius;
  so.function_tolerance = o.function_tolerance;
  so.parameter_tolerance = o.parameter_tolerance;
  so.num_threads = o.num_threads;
  return so;
}

// A start hypothesis: its name in the diagnostics (start_hypothesis_cost.<name>), every node's
// initial (p, θ) (or the first nodes'), and 1 + its estimator's place in start_estimators (0:
// not an estimator's).
struct NamedStart {
  std::string name;
  std::vector<Eigen::Vector3d> nodes;
  int estimator = 0;
};

// The start hypotheses of StepGraphOptions::start_estimators (StepGraph::HypothesesFrom) over
// the nodes with t <= until_s; causal: the filters only (an id ending in "-rts" gives its
// filter's, the id without it). An estimator
// that cannot run on the walk, or fails, gives none; an id the registry does not know is an
// error.
StatusOr<std::vector<NamedStart>> EstimatorStarts(const Walk& walk, const StepGraph& graph,
                                                  const StepGraphOptions& o, bool causal,
                                                  double until_s) {
  std::vector<NamedStart> out;
  if (walk.meta.initial_pose || !(walk.has_rss() || walk.has_ranges()) ||
      !(walk.has_imu() || walk.has_odometry())) {
    return out;
  }
  const std::vector<std::string> ids = SplitIds(o.start_estimators);
  for (size_t i = 0; i < ids.size(); ++i) {
    const std::string& id = ids[i];
    const bool smoother = id.size() > 4 && id.compare(id.size() - 4, 4, "-rts") == 0;
    const std::string run = causal && smoother ? id.substr(0, id.size() - 4) : id;
    WG_ASSIGN_OR_RETURN(std::unique_ptr<Estimator> e, EstimatorRegistry::Builtin().Create(run));
    if (!e->CheckApplicable(walk).ok()) continue;
    StatusOr<EstimateResult> r = e->Run(walk);
    if (!r.ok()) continue;  // the other hypotheses still stand
    auto h = graph.HypothesesFrom(r->trajectory, until_s);
    if (h.size() != 2) continue;
    out.push_back({run + "/aligned", std::move(h[0]), static_cast<int>(i) + 1});
    out.push_back({run, std::move(h[1]), static_cast<int>(i) + 1});
  }
  return out;
}

// fg-batch's start hypotheses on a walk with no start: StartHypotheses' turns (named 1..n),
// then EstimatorStarts.
StatusOr<std::vector<NamedStart>> BatchStarts(const Walk& walk, const StepGraph& graph,
                                              const StepGraphOptions& o) {
  std::vector<NamedStart> starts;
  for (auto& h : graph.StartHypotheses(walk, o.start_hypotheses)) {
    starts.push_back({std::to_string(starts.size() + 1), std::move(h), 0});
  }
  WG_ASSIGN_OR_RETURN(
      std::vector<NamedStart> more,
      EstimatorStarts(walk, graph, o, /*causal=*/false, std::numeric_limits<double>::infinity()));
  for (NamedStart& h : more) starts.push_back(std::move(h));
  return starts;
}

// fg-batch's start hypotheses (BatchStarts): each solved from its own initial nodes; returns
// the graph of the lowest final cost when one beats `*best` (whose summary it then takes),
// else null. Diagnostics: start_hypothesis (0: fg-batch's own initialization, k: the k-th
// hypothesis), start_hypothesis_cost.<name> per hypothesis (.0 its own) and
// start_hypothesis_estimator (NamedStart::estimator of the winner).
StatusOr<std::unique_ptr<FactorGraph>> SolveStartHypotheses(const StepGraph& graph,
                                                            const std::vector<NamedStart>& starts,
                                                            const SolverOptions& so,
                                                            SolveSummary* best,
                                                            std::map<std::string, double>* d) {
  std::unique_ptr<FactorGraph> winner;
  if (starts.empty()) return winner;
  (*d)["start_hypothesis"] = 0;
  (*d)["start_hypothesis_estimator"] = 0;
  (*d)["start_hypothesis_cost.0"] = best->final_cost;
  for (size_t h = 0; h < starts.size(); ++h) {
    auto fg = std::make_unique<FactorGraph>();
    WG_RETURN_IF_ERROR(graph.AddTo(fg.get()));
    for (size_t k = 0; k < starts[h].nodes.size(); ++k) {
      const Eigen::Vector3d& x = starts[h].nodes[k];
      const int node = static_cast<int>(k);
      WG_RETURN_IF_ERROR(fg->SetValue(StepGraph::PositionKey(node), {x[0], x[1]}));
      WG_RETURN_IF_ERROR(fg->SetValue(StepGraph::HeadingKey(node), {x[2]}));
    }
    StatusOr<SolveSummary> summary = SolveBatch(fg.get(), so);
    if (!summary.ok()) continue;  // a hypothesis that fails to solve is not taken
    (*d)["start_hypothesis_cost." + starts[h].name] = summary->final_cost;
    if (summary->final_cost < best->final_cost) {
      *best = *summary;
      (*d)["start_hypothesis"] = static_cast<double>(h + 1);
      (*d)["start_hypothesis_estimator"] = starts[h].estimator;
      winner = std::move(fg);
    }
  }
  return winner;
}

}  // namespace

Status StepGraphBatch::CheckApplicable(const Walk& walk) const { return CheckStepWalk(walk); }

Status StepGraph::AddTo(FactorGraph* fg) const {
  for (GraphState& s : StaticStates()) WG_RETURN_IF_ERROR(fg->AddState(std::move(s)));
  for (int k = 0; k < num_nodes(); ++k) {
    const Eigen::Vector3d& x = init_[k];
    for (GraphState& s : NodeStates(k, x.head<2>(), x[2])) {
      if (k > 0 && s.key == PositionKey(k)) s.value = {x[0], x[1]};
      if (k > 0 && s.key == HeadingKey(k)) s.value = {x[2]};
      WG_RETURN_IF_ERROR(fg->AddState(std::move(s)));
    }
  }
  for (int k = 0; k < num_nodes(); ++k) {
    for (GraphFactor& f : FactorsAt(k)) WG_RETURN_IF_ERROR(fg->AddFactor(std::move(f)));
  }
  return Status::Ok();
}

namespace {

// The anchors that are states (StepGraph::AnchorIsState) at their solved positions, into `out`;
// returns their indices.
std::vector<int> AnchorEstimates(const Walk& walk, const StepGraph& graph,
                                 const std::function<std::vector<double>(Key)>& value,
                                 std::vector<AnchorEstimate>* out) {
  std::vector<int> states;
  for (size_t a = 0; a < walk.anchors.size(); ++a) {
    if (!graph.AnchorIsState(static_cast<int>(a))) continue;
    states.push_back(static_cast<int>(a));
    AnchorEstimate e;
    e.id = walk.anchors[a].id;
    const std::vector<double> v = value(StepGraph::AnchorKey(static_cast<int>(a)));
    e.position_m = Eigen::Vector2d(v[0], v[1]);
    for (const RssSample& r : walk.rss) e.readings += r.anchor_id == e.id ? 1 : 0;
    for (const RangeSample& r : walk.ranges) e.readings += r.anchor_id == e.id ? 1 : 0;
    out->push_back(e);
  }
  return states;
}

// One fg-batch solve of `walk`. `from` (not null): start every node there (a previous solve's
// nodes) instead of fg-batch's own initialization, with no start hypotheses. `nodes` (not
// null): the solution's (p, θ) per node. Anchors that are states (StepGraph::AnchorIsState)
// come back in result.anchors with their covariance.
StatusOr<EstimateResult> SolveBatchWalk(const Walk& walk, const StepGraphOptions& options_,
                                        const std::vector<Eigen::Vector3d>* from,
                                        std::vector<Eigen::Vector3d>* nodes) {
  WG_ASSIGN_OR_RETURN(std::unique_ptr<StepGraph> graph, StepGraph::Build(walk, options_));
  const int n = graph->num_nodes();

  FactorGraph fg;
  WG_RETURN_IF_ERROR(graph->AddTo(&fg));
  const SolverOptions so = BatchSolverOptions(options_);
  // auto: dead reckoning for odometry walks (wheel odometry barely drifts), the window for
  // IMU steps (a gyro's heading drift over a long walk leaves dead reckoning in a wrong basin:
  // measured on correa-classroom 0.85 → 0.23 m RMSE, gadeke-outage 18.8 → 0.71 m).
  const bool window_init =
      from == nullptr &&
      (options_.initialization == StepGraphInit::kWindow ||
       (options_.initialization == StepGraphInit::kAuto && !walk.has_odometry()));
  if (from != nullptr) {
    if (static_cast<int>(from->size()) != n) {
      return InternalError("fg-batch: a previous solve has a different node count");
    }
    for (int k = 0; k < n; ++k) {
      const Eigen::Vector3d& x = (*from)[k];
      WG_RETURN_IF_ERROR(fg.SetValue(StepGraph::PositionKey(k), {x[0], x[1]}));
      WG_RETURN_IF_ERROR(fg.SetValue(StepGraph::HeadingKey(k), {x[2]}));
    }
  }
  if (window_init) {
    // Start from the fixed-lag smoother's lagged estimates (it grows the solution
    // incrementally, so it does not get lost).
    StepGraphOptions wo = options_;
    wo.covariance = false;
    wo.window_output = WindowOutput::kLagged;
    wo.lag_s = options_.init_lag_s;
    wo.window_update_s = options_.init_update_s;
    wo.window_max_iterations = options_.init_max_iterations;
    // fg-batch's own stop; fg-window's looser one moves fg-batch's local optimum on robust
    // walks (BLE straight_03 1.231 → 1.254 m).
    wo.window_function_tolerance = options_.function_tolerance;
    WG_ASSIGN_OR_RETURN(EstimateResult w, RunWindowNodes(walk, wo));
    if (static_cast<int>(w.trajectory.size()) != n) {
      return InternalError("fg-batch: window initialization returned a different node count");
    }
    for (int k = 0; k < n; ++k) {
      const TrajectoryPoint& pt = w.trajectory.points[k];
      WG_RETURN_IF_ERROR(
          fg.SetValue(StepGraph::PositionKey(k), {pt.position_m.x(), pt.position_m.y()}));
      WG_RETURN_IF_ERROR(fg.SetValue(StepGraph::HeadingKey(k), {pt.heading_rad}));
    }
  }
  StatusOr<SolveSummary> summary = SolveBatch(&fg, so);
  if (!summary.ok()) return NumericalError("fg-batch: " + summary.status().message());
  std::map<std::string, double> start_d;
  std::vector<NamedStart> starts;
  if (from == nullptr) {
    WG_ASSIGN_OR_RETURN(starts, BatchStarts(walk, *graph, options_));
  }
  WG_ASSIGN_OR_RETURN(std::unique_ptr<FactorGraph> better,
                      SolveStartHypotheses(*graph, starts, so, &*summary, &start_d));
  FactorGraph& fg_best = better ? *better : fg;

  EstimateResult result;
  auto& d = result.diagnostics;
  d.insert(start_d.begin(), start_d.end());
  d["ceres_iterations"] = summary->iterations;
  d["ceres_converged"] = summary->termination == Termination::kConverged ? 1.0 : 0.0;
  d["final_cost"] = summary->final_cost;
  d["normalized_cost"] = summary->normalized_cost();  // 2F/(m − n), ≈ 1 if consistent
  d["initialized_from_window"] = window_init ? 1.0 : 0.0;
  d["nodes"] = n;
  d["residual_blocks"] = static_cast<double>(fg_best.num_factors());
  auto value = [&](Key k) { return *fg_best.Value(k); };  // every key below is in the graph
  AddStaticDiagnostics(*graph, value, walk, options_, &d);
  AddGraphDiagnostics(*graph, walk, &d);
  for (int k = 0; k < n; ++k) {
    result.trajectory.points.push_back(MakePoint(graph->node_time(k),
                                                 value(StepGraph::PositionKey(k)).data(),
                                                 value(StepGraph::HeadingKey(k))[0]));
    if (graph->has_floors())
      SetHeight(*graph, value(StepGraph::HeightKey(k))[0], &result.trajectory.points.back());
  }
  if (nodes != nullptr) {
    nodes->clear();
    for (const TrajectoryPoint& p : result.trajectory.points) {
      nodes->emplace_back(p.position_m.x(), p.position_m.y(), p.heading_rad);
    }
  }
  const std::vector<int> anchor_states = AnchorEstimates(walk, *graph, value, &result.anchors);
  if (!anchor_states.empty()) {
    // The frame the anchors are in: 0 the known start's, 1 the anchors' of given position,
    // 2 the walk's own (node 0 held where it started).
    d["gauge"] = walk.meta.initial_pose ? 0.0 : graph->fix_first_node() ? 2.0 : 1.0;
  }
  if (options_.covariance) {
    std::vector<std::vector<Key>> groups;
    for (int k = 0; k < n; ++k) {
      groups.push_back({StepGraph::PositionKey(k), StepGraph::HeadingKey(k)});
    }
    for (int a : anchor_states) groups.push_back({StepGraph::AnchorKey(a)});
    auto cov = MarginalCovariances(&fg_best, groups);
    if (!cov.ok()) {
      d["covariance_failed"] = 1.0;  // e.g. rank-deficient: trajectory without covariances
    } else {
      for (int k = 0; k < n; ++k) {
        result.trajectory.points[k].covariance = PoseCovariance((*cov)[k]);
      }
      for (size_t i = 0; i < anchor_states.size(); ++i) {
        const Eigen::MatrixXd& c = (*cov)[n + i];
        result.anchors[i].covariance = Eigen::Matrix2d(0.5 * (c + c.transpose()));
      }
    }
  }
  InsertStops(walk, options_.max_step_duration_s, &result.trajectory);
  return result;
}

// Where the path was at time t: the nodes' positions, interpolated.
Eigen::Vector2d PathAt(const std::vector<double>& t, const std::vector<Eigen::Vector3d>& x,
                       double ts) {
  const auto it = std::lower_bound(t.begin(), t.end(), ts);
  if (it == t.begin()) return x.front().head<2>();
  if (it == t.end()) return x.back().head<2>();
  const size_t b = static_cast<size_t>(it - t.begin());
  const double w = (ts - t[b - 1]) / (t[b] - t[b - 1]);
  return (1.0 - w) * x[b - 1].head<2>() + w * x[b].head<2>();
}

// The grid search's options for a range anchor and for an RSS one (anchor_search.h), from the
// graph's options and the first solve's estimates (diagnostics `fd`).
struct SearchSetup {
  internal::AnchorSearchOptions range, rss;
};
SearchSetup SearchOptions(const Walk& walk, const StepGraphOptions& o,
                          const std::map<std::string, double>& fd) {
  const PathLossParams& pl = walk.meta.radio.path_loss;
  internal::AnchorSearchOptions so;
  so.margin_m = o.anchor_search_margin_m;
  so.step_m = o.anchor_search_step_m;
  so.min_readings = o.anchor_min_readings;
  so.min_spread_m = o.anchor_min_spread_m;
  so.distinct_radius_m = o.anchor_distinct_radius_m;
  so.min_cost_gap = o.anchor_min_cost_gap;
  SearchSetup out{so, so};
  internal::AnchorSearchOptions& r = out.range;
  r.range = true;
  r.sigma = o.range_sigma_m > 0 ? o.range_sigma_m : walk.meta.radio.range_sigma_m;
  r.loss_scale = o.range_loss_scale;
  r.range_scale = fd.count("range_scale") ? fd.at("range_scale") : 0.0;
  // The anchor's bias: held where the graph holds it (at the walk's estimate when there is
  // one bias for the walk), else free with its prior.
  r.level_prior_sigma = o.range_bias == CalibrationScope::kNone ? 0.0 : o.range_bias_prior_sigma_m;
  if (o.range_bias == CalibrationScope::kGlobal && fd.count("range_bias_m")) {
    r.level_prior = fd.at("range_bias_m");
    r.level_prior_sigma = 0.0;
  }
  // An RSS anchor's transmit level A: the walk's (held: σ 0), or the first solve's estimate with
  // the spread one anchor may have around it, else the prior.
  internal::AnchorSearchOptions& q = out.rss;
  q.range = false;
  q.sigma = o.sigma_db > 0 ? o.sigma_db : pl.sigma_db;
  q.loss_scale = o.rss_loss_scale;
  q.sign = walk.meta.radio.units == RssUnits::kDbm ? 1.0 : -1.0;
  q.d0_m = pl.d0_m;
  bool held_radio_only = false;
  const PathLossMode mode = ResolvePathLoss(walk, o, &held_radio_only);
  const bool A_estimated = fd.count("path_loss_A") > 0;
  q.level_prior = A_estimated ? fd.at("path_loss_A") : std::isfinite(o.A_dbm) ? o.A_dbm : pl.A_dbm;
  q.eta = fd.count("path_loss_eta") ? fd.at("path_loss_eta") : o.eta > 0 ? o.eta : pl.eta;
  q.level_prior_sigma = o.A_prior_sigma_db;
  if (mode == PathLossMode::kFixed || (mode == PathLossMode::kGlobal && A_estimated)) {
    q.level_prior_sigma = 0.0;
  } else if (mode == PathLossMode::kHierarchical) {
    q.level_prior_sigma =
        A_estimated ? o.A_spread_prior_db : std::hypot(o.A_prior_sigma_db, o.A_spread_prior_db);
  }
  return out;
}

// fg-batch on a walk with anchors of unknown position (step_graph.h, "Anchors of unknown
// position"): the walk without them solved first; each placed on that path by a grid search
// (anchor_search.h) or declared unobservable and left out; then every placed anchor a state
// in one joint solve from the first solution.
StatusOr<EstimateResult> SolveWithUnknownAnchors(const Walk& walk, const StepGraphOptions& o) {
  UnknownAnchorsDropped dropped;
  const Walk known = WithoutUnknownAnchors(walk, &dropped);
  std::vector<Eigen::Vector3d> first_nodes;
  WG_ASSIGN_OR_RETURN(EstimateResult first, SolveBatchWalk(known, o, nullptr, &first_nodes));
  std::vector<double> node_t;
  // The node times: the first solve's trajectory without the stops InsertStops added.
  WG_ASSIGN_OR_RETURN(std::unique_ptr<StepGraph> first_graph, StepGraph::Build(known, o));
  for (int k = 0; k < first_graph->num_nodes(); ++k) node_t.push_back(first_graph->node_time(k));

  const bool radio_only = !walk.has_odometry() && !walk.has_imu();
  const SearchSetup search = SearchOptions(walk, o, first.diagnostics);
  Walk joint = walk;
  std::vector<AnchorEstimate> unobservable;
  std::map<std::string, double> verdicts;
  std::set<int> left_out;
  for (Anchor& a : joint.anchors) {
    if (a.position_known) continue;
    std::vector<Eigen::Vector2d> q;
    std::vector<double> v;
    // Its ranges (a ranging radio); an anchor without ranges, its RSS readings.
    for (const RangeSample& r : walk.ranges) {
      if (r.anchor_id != a.id) continue;
      q.push_back(PathAt(node_t, first_nodes, r.t_s));
      v.push_back(r.range_m);
    }
    const bool range = !v.empty();
    for (const RssSample& r : walk.rss) {
      if (range || r.anchor_id != a.id) continue;
      q.push_back(PathAt(node_t, first_nodes, r.t_s));
      v.push_back(r.rss);
    }
    internal::AnchorSearchOptions so = range ? search.range : search.rss;
    so.dz_m = o.receiver_height_m - walk.AnchorHeightM(a);
    // A radio-only walk has no path without its anchors to search along.
    const internal::AnchorSearchResult found =
        radio_only ? internal::AnchorSearchResult{} : internal::SearchAnchor(q, v, so);
    if (!radio_only && found.verdict != internal::AnchorSearchResult::Verdict::kFewReadings &&
        found.verdict != internal::AnchorSearchResult::Verdict::kNarrowGeometry) {
      // How clearly the best place stood out (the other basin's cost above it; inf: none).
      verdicts["anchor_search_gap." + std::to_string(a.id)] = found.second_cost - found.cost;
    }
    if (!radio_only && found.placed()) {
      a.position_m.head<2>() = found.position_m;
      continue;
    }
    AnchorEstimate e;
    e.id = a.id;
    e.observable = false;
    e.readings = static_cast<int>(v.size());
    unobservable.push_back(e);
    left_out.insert(a.id);
    verdicts[std::string("unknown_anchors_unobservable.") +
             (radio_only ? "radio_only" : internal::ToString(found.verdict))] += 1.0;
  }
  // The unobservable anchors leave the walk with their readings.
  UnknownAnchorsDropped left;
  const Walk solved = WithoutAnchors(joint, left_out, &left);
  EstimateResult result;
  if (static_cast<int>(left_out.size()) == dropped.anchors) {
    result = std::move(first);  // nothing placed: the first solve is the answer
  } else {
    WG_ASSIGN_OR_RETURN(result, SolveBatchWalk(solved, o, &first_nodes, nullptr));
    result.diagnostics["unknown_anchors_first_pass_cost"] = first.diagnostics["final_cost"];
  }
  auto& d = result.diagnostics;
  d.insert(verdicts.begin(), verdicts.end());
  d["unknown_anchors"] = dropped.anchors;
  d["unknown_anchors_estimated"] = dropped.anchors - static_cast<double>(left_out.size());
  d["unknown_anchors_unobservable"] = static_cast<double>(left_out.size());
  d["unknown_anchor_readings_ignored"] = left.rss_readings + left.range_readings;
  if (!d.count("gauge")) {  // nothing placed: the first solve's frame
    int placed = 0;
    std::set<int> heard;
    for (const RssSample& r : known.rss) heard.insert(r.anchor_id);
    for (const RangeSample& r : known.ranges) heard.insert(r.anchor_id);
    for (const Anchor& a : known.anchors) placed += heard.count(a.id) ? 1 : 0;
    d["gauge"] = walk.meta.initial_pose ? 0.0 : placed >= 2 ? 1.0 : 2.0;
  }
  for (AnchorEstimate& e : unobservable) result.anchors.push_back(e);
  return result;
}

}  // namespace

StatusOr<EstimateResult> StepGraphBatch::Run(const Walk& walk) const {
  WG_RETURN_IF_ERROR(CheckApplicable(walk));
  if (walk.has_unknown_anchors()) return SolveWithUnknownAnchors(walk, options_);
  return SolveBatchWalk(walk, options_, nullptr, nullptr);
}

Status StepGraphWindow::CheckApplicable(const Walk& walk) const { return CheckStepWalk(walk); }

StatusOr<EstimateResult> StepGraphWindow::Run(const Walk& walk) const {
  WG_RETURN_IF_ERROR(CheckApplicable(walk));
  WG_ASSIGN_OR_RETURN(EstimateResult result, RunWindowNodes(walk, options_));
  InsertStops(walk, options_.max_step_duration_s, &result.trajectory);
  return result;
}

namespace {

// fg-window's estimates, one point per graph node.
// The static states' and the graph's diagnostics, from the window's final estimates.
void AddWindowGraphDiagnostics(const StepGraph& graph, const FixedLagSmoother& smoother,
                               const Walk& walk, const StepGraphOptions& o,
                               std::map<std::string, double>* d) {
  AddStaticDiagnostics(
      graph,
      [&](Key k) {
        auto v = smoother.Estimate(k);
        return v.ok() ? *v : std::vector<double>{0.0, 0.0};
      },
      walk, o, d);
  AddGraphDiagnostics(graph, walk, d);
}

// fg-window's smoother: the lag and the window_* solver options.
FixedLagSmoother::Options WindowSmootherOptions(const StepGraphOptions& o) {
  FixedLagSmoother::Options so;
  so.lag_s = o.lag_s;
  so.marginalize_batch_s = o.window_marginalize_batch_s;
  so.solver.initial_trust_region_radius = o.window_initial_trust_region_radius;
  so.solver.max_iterations = o.window_max_iterations;
  so.solver.linear_solver = o.window_linear_solver == WindowLinearSolver::kDense
                                ? LinearSolver::kDenseNormalCholesky
                                : LinearSolver::kSparseNormalCholesky;
  so.solver.eigen_sparse = o.window_linear_solver == WindowLinearSolver::kEigenSparse;
  so.solver.function_tolerance = o.window_function_tolerance;
  so.solver.parameter_tolerance = o.parameter_tolerance;
  so.solver.num_threads = o.num_threads;
  return so;
}

// The graph of nodes 0..last (states and every factor whose newest node is among them), the
// nodes at `start` (every node's (p, θ) up to last) or else at their dead-reckoning values.
Status AddFirstNodes(const StepGraph& graph, int last, const std::vector<Eigen::Vector3d>& start,
                     FactorGraph* fg) {
  for (GraphState& s : graph.StaticStates()) WG_RETURN_IF_ERROR(fg->AddState(std::move(s)));
  const std::vector<Eigen::Vector3d>& x = start.empty() ? graph.initial_nodes() : start;
  for (int k = 0; k <= last; ++k) {
    for (GraphState& s : graph.NodeStates(k, x[k].head<2>(), x[k][2])) {
      if (s.key == StepGraph::PositionKey(k)) s.value = {x[k][0], x[k][1]};
      if (s.key == StepGraph::HeadingKey(k)) s.value = {x[k][2]};
      WG_RETURN_IF_ERROR(fg->AddState(std::move(s)));
    }
  }
  for (int k = 0; k <= last; ++k) {
    for (GraphFactor& f : graph.FactorsAt(k)) WG_RETURN_IF_ERROR(fg->AddFactor(std::move(f)));
  }
  return Status::Ok();
}

// fg-window's first window on a walk with no start (issue 41): the nodes of the first
// align_window_s, when it holds at least 3 radio readings, solved as one batch (fg-batch's solver
// options) from the window's own initialization and from each causal start estimator's hypotheses
// (EstimatorStarts), the least final cost kept: the window starts its nodes there. Empty when the
// walk has a start or no estimator gives a hypothesis. Diagnostics first_window_hypothesis (0: its
// own, k: the k-th), first_window_estimator (NamedStart::estimator), first_window_cost.<name>.
StatusOr<std::vector<Eigen::Vector3d>> FirstWindowStart(const Walk& walk, const StepGraph& graph,
                                                        const StepGraphOptions& o,
                                                        std::map<std::string, double>* d) {
  std::vector<Eigen::Vector3d> out;
  const double until = graph.node_time(0) + o.align_window_s;
  int readings = 0;  // fewer than 3 in the span: the radio cannot tell the hypotheses apart
  for (const RssSample& r : walk.rss) readings += r.t_s <= until ? 1 : 0;
  for (const RangeSample& r : walk.ranges) readings += r.t_s <= until ? 1 : 0;
  if (readings < 3) return out;
  WG_ASSIGN_OR_RETURN(std::vector<NamedStart> starts,
                      EstimatorStarts(walk, graph, o, /*causal=*/true, until));
  if (starts.empty()) return out;
  const int last = static_cast<int>(starts.front().nodes.size()) - 1;
  starts.insert(starts.begin(), NamedStart{"0", {}, 0});  // its own initialization
  double best = std::numeric_limits<double>::infinity();
  for (size_t h = 0; h < starts.size(); ++h) {
    FactorGraph fg;
    WG_RETURN_IF_ERROR(AddFirstNodes(graph, last, starts[h].nodes, &fg));
    StatusOr<SolveSummary> s = SolveBatch(&fg, BatchSolverOptions(o));
    if (!s.ok()) continue;  // a hypothesis that fails to solve is not taken
    (*d)["first_window_cost." + starts[h].name] = s->final_cost;
    if (!(s->final_cost < best)) continue;
    best = s->final_cost;
    (*d)["first_window_hypothesis"] = static_cast<double>(h);
    (*d)["first_window_estimator"] = starts[h].estimator;
    out.clear();
    for (int k = 0; k <= last; ++k) {
      const std::vector<double> p = *fg.Value(StepGraph::PositionKey(k));
      out.emplace_back(p[0], p[1], (*fg.Value(StepGraph::HeadingKey(k)))[0]);
    }
  }
  return out;
}

// fg-window-online's output of the nodes just updated: each one's estimate right after its update.
Status OnlinePoints(const StepGraph& graph, const FixedLagSmoother& smoother,
                    const std::vector<int>& nodes, std::vector<TrajectoryPoint>* points,
                    std::vector<bool>* have) {
  for (int j : nodes) {
    WG_ASSIGN_OR_RETURN(std::vector<double> pj, smoother.Estimate(StepGraph::PositionKey(j)));
    WG_ASSIGN_OR_RETURN(std::vector<double> hj, smoother.Estimate(StepGraph::HeadingKey(j)));
    (*points)[j] = MakePoint(graph.node_time(j), pj.data(), hj[0]);
    if (graph.has_floors()) {
      WG_ASSIGN_OR_RETURN(std::vector<double> zj, smoother.Estimate(StepGraph::HeightKey(j)));
      SetHeight(graph, zj[0], &(*points)[j]);
    }
    (*have)[j] = true;
  }
  return Status::Ok();
}

StatusOr<EstimateResult> RunWindowNodes(const Walk& walk, const StepGraphOptions& options_) {
  WG_ASSIGN_OR_RETURN(std::unique_ptr<StepGraph> graph, StepGraph::Build(walk, options_));
  const int n = graph->num_nodes();
  const bool online = options_.window_output == WindowOutput::kOnline;
  std::map<std::string, double> first_d;
  WG_ASSIGN_OR_RETURN(const std::vector<Eigen::Vector3d> first,
                      FirstWindowStart(walk, *graph, options_, &first_d));
  FixedLagSmoother smoother(WindowSmootherOptions(options_));

  std::vector<TrajectoryPoint> points(n);
  std::vector<bool> have(n, false);
  auto node_of = [](Key key) { return static_cast<int>(SymbolIndex(key)); };
  // (x, y, θ) covariances of the given nodes from the current window, in one banded solve.
  auto store_covariances = [&](const std::vector<int>& nodes) {
    if (!options_.covariance || nodes.empty()) return;
    std::vector<std::vector<Key>> groups;
    for (int k : nodes) groups.push_back({StepGraph::PositionKey(k), StepGraph::HeadingKey(k)});
    auto c = smoother.MarginalCovariances(groups);
    if (!c.ok()) return;  // rank-deficient window: these nodes go without covariance
    for (size_t i = 0; i < nodes.size(); ++i) {
      points[nodes[i]].covariance = PoseCovariance(0.5 * ((*c)[i] + (*c)[i].transpose()));
    }
  };
  smoother.set_before_marginalize([&](const std::vector<Key>& keys) {
    if (online) return;
    std::vector<int> nodes;
    for (Key key : keys) {
      if (SymbolLetter(key) == 'x') nodes.push_back(node_of(key));
    }
    store_covariances(nodes);
  });
  smoother.set_on_marginalize([&](Key key, double t, const std::vector<double>& v) {
    if (online) return;
    const int k = node_of(key);
    points[k].t_s = t;
    if (SymbolLetter(key) == 'x') {
      points[k].position_m.head<2>() = Eigen::Vector2d(v[0], v[1]);
      have[k] = true;
    } else if (SymbolLetter(key) == 'z') {
      SetHeight(*graph, v[0], &points[k]);
    } else {
      points[k].heading_rad = NormalizeAngle(v[0]);
    }
  });

  std::vector<double> latency;
  latency.reserve(n);
  int iterations = 0, solves = 0;
  size_t max_states = 0, max_factors = 0;  // the window's largest size (its memory)
  Eigen::Vector2d prev_p = graph->initial_nodes()[0].head<2>();
  double prev_theta = graph->initial_nodes()[0][2];
  // Nodes are fed one update each, or (window_update_s > 0) gathered into one update per
  // period; new nodes start from dead reckoning off the previous node's estimate.
  std::vector<GraphState> states;
  std::vector<GraphFactor> factors;
  std::vector<int> pending;
  double last_update_t = graph->node_time(0);
  for (int k = 0; k < n; ++k) {
    if (k == 0) states = graph->StaticStates();
    std::vector<GraphState> node = graph->NodeStates(k, prev_p, prev_theta);
    if (k < static_cast<int>(first.size())) {  // the first window's chosen start
      node[0].value = {first[k][0], first[k][1]};
      node[1].value = {first[k][2]};
    }
    prev_p = Eigen::Vector2d(node[0].value[0], node[0].value[1]);
    prev_theta = node[1].value[0];
    for (GraphState& st : node) states.push_back(std::move(st));
    for (GraphFactor& f : graph->FactorsAt(k)) factors.push_back(std::move(f));
    pending.push_back(k);
    if (k + 1 < n && graph->node_time(k) - last_update_t < options_.window_update_s) continue;
    last_update_t = graph->node_time(k);
    const auto start = std::chrono::steady_clock::now();
    WG_ASSIGN_OR_RETURN(FixedLagSmoother::UpdateResult u,
                        smoother.Update(std::move(states), std::move(factors)));
    states.clear();
    factors.clear();
    latency.push_back(
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
    iterations += u.ceres_iterations;
    solves += u.solved ? 1 : 0;
    max_states = std::max(max_states, smoother.NumStates());
    max_factors = std::max(max_factors, smoother.NumFactors());
    WG_ASSIGN_OR_RETURN(std::vector<double> p, smoother.Estimate(StepGraph::PositionKey(k)));
    WG_ASSIGN_OR_RETURN(std::vector<double> h, smoother.Estimate(StepGraph::HeadingKey(k)));
    prev_p = Eigen::Vector2d(p[0], p[1]);
    prev_theta = h[0];
    if (online) {
      WG_RETURN_IF_ERROR(OnlinePoints(*graph, smoother, pending, &points, &have));
      store_covariances(pending);
    }
    pending.clear();
  }
  if (!online) {
    // The nodes still in the window at the end: their final (smoothed) estimates.
    std::vector<int> nodes;
    for (Key key : smoother.WindowKeys()) {
      if (SymbolLetter(key) == 'x') nodes.push_back(node_of(key));
    }
    store_covariances(nodes);
    smoother.Flush();
  }

  EstimateResult result;
  for (int k = 0; k < n; ++k) {
    if (have[k]) result.trajectory.points.push_back(points[k]);
  }
  auto& d = result.diagnostics;
  d = {{"ceres_iterations", iterations},
       {"window_solves", solves},
       {"window_max_states", static_cast<double>(max_states)},
       {"window_max_factors", static_cast<double>(max_factors)},
       {"nodes", n}};
  d.insert(first_d.begin(), first_d.end());
  AddUpdateLatencyTimings(latency, &result.timings);
  AddWindowGraphDiagnostics(*graph, smoother, walk, options_, &d);
  return result;
}

}  // namespace

namespace internal {

Status RegisterStepGraphSmoothers(EstimatorRegistry* registry) {
  auto parse = [](const char* id, StepGraphOptions defaults) {
    return [id, defaults](const YAML::Node& config) {
      return StepGraphOptionsFromYaml(config, id, defaults);
    };
  };
  StepGraphOptions selfcal;
  selfcal.path_loss = PathLossMode::kGlobal;
  StepGraphOptions online;
  online.window_output = WindowOutput::kOnline;
  WG_RETURN_IF_ERROR(registry->Register(
      {"fg-batch",
       "factor graph, full batch: steps/odometry + RSS (dB) / ranges (bias, robust), Ceres "
       "sparse Cholesky",
       OptionsFactory<StepGraphBatch>(parse("fg-batch", StepGraphOptions())),
       /*estimates_unknown_anchors=*/true}));
  WG_RETURN_IF_ERROR(registry->Register(
      {"fg-batch-selfcal", "fg-batch with path-loss self-calibration (A, η estimated; weak prior)",
       OptionsFactory<StepGraphBatch>(parse("fg-batch-selfcal", selfcal)),
       /*estimates_unknown_anchors=*/true}));
  WG_RETURN_IF_ERROR(registry->Register(
      {"fg-window",
       "factor graph, fixed-lag smoother (10 s lag, marginalization prior): lagged estimates",
       OptionsFactory<StepGraphWindow>(parse("fg-window", StepGraphOptions()))}));
  return registry->Register({"fg-window-online",
                             "fg-window's online output: each node right after its own update",
                             OptionsFactory<StepGraphWindow>(parse("fg-window-online", online))});
}

}  // namespace internal
}  // namespace walkgraph
