// fg-batch / fg-window options: read from YAML (StepGraphOptionsFromYaml) and checked
// (StepGraphOptions::Validate).
#include "walkgraph/smoothers/step_graph.h"

#include <string>
#include <vector>

#include "config/parsers.h"
#include "smoothers/step_graph_run.h"
#include "util/text.h"

namespace walkgraph {

namespace internal {

std::vector<std::string> StartEstimatorIds(const std::string& list) {
  std::vector<std::string> ids;
  if (Trim(list).empty()) return ids;
  for (const std::string& id : Split(list, ',')) ids.push_back(Trim(id));
  return ids;
}

}  // namespace internal

namespace {

// start_estimators: estimator ids, none of the step graph's own.
Status CheckStartEstimators(const StepGraphOptions& o, const std::string& context) {
  for (const std::string& id : internal::StartEstimatorIds(o.start_estimators)) {
    if (id.empty() || id.rfind("fg-", 0) == 0) {
      return InvalidArgument(context +
                             ": start_estimators must list estimator ids (none of "
                             "the step graph's own, fg-*), comma-separated: '" +
                             o.start_estimators + "'");
    }
  }
  return Status::Ok();
}

Status CheckStepGraphOptions(const StepGraphOptions& o, const std::string& context);
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
  r.Read("window_gyro_bias_without_heading", &o->window_gyro_bias_without_heading,
         "fg-window: estimate the gyro bias even when no step carries a magnetometer heading");
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
  r.Read("window_anchor_max_sigma_m", &o->window_anchor_max_sigma_m,
         "fg-window, unknown anchors: largest position sigma at which the window places one");
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
  r.ReadEnum("linear_solver", &o->linear_solver, WindowLinearSolverNames(),
             "fg-batch: linear solver of its solves");
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
         "no start: dead reckoning aligned to every fix, turned n ways, each solved; a start "
         "without heading (no magnetometer): turned n ways about it (0: off)");
  r.Read("start_estimators", &o->start_estimators,
         "no start: comma-separated estimator ids whose trajectories are more start hypotheses");
  r.Read("noise_scale_rounds", &o->noise_scale_rounds,
         "fg-batch: rounds of noise scales from the residuals, each solved again (0: as given)");
  r.Read("estimate_step_scale", &o->estimate_step_scale,
         "one step-length scale for the walk, a state of the graph");
  r.Read("step_scale_prior_sigma", &o->step_scale_prior_sigma,
         "prior sigma of the step-length scale (1 + c)");
  r.Read("noise_scale_lower", &o->noise_scale_lower,
         "fg-batch: noise scales may also lower the steps' and heading increments' sigma");
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
  WG_RETURN_IF_ERROR(positive(o.step_scale_prior_sigma, "step_scale_prior_sigma"));
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
  WG_RETURN_IF_ERROR(positive(o.window_anchor_max_sigma_m, "window_anchor_max_sigma_m"));
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
  WG_RETURN_IF_ERROR(
      CheckEnumOption(WindowLinearSolverNames(), o.linear_solver, "linear_solver", context));
  if (o.path_loss != PathLossMode::kAuto && o.path_loss != PathLossMode::kFixed &&
      o.rss_residual != RssResidual::kDb) {
    return InvalidArgument(context + ": path-loss self-calibration needs rss_residual 'db'");
  }
  WG_RETURN_IF_ERROR(positive(o.init_lag_s, "init_lag_s"));
  if (o.noise_scale_rounds < 0 || o.noise_scale_rounds > 10) {
    return InvalidArgument(context + ": noise_scale_rounds must be in [0, 10]");
  }
  if (o.start_hypotheses < 0 || o.start_hypotheses > 360) {
    return InvalidArgument(context + ": start_hypotheses must be in [0, 360]");
  }
  WG_RETURN_IF_ERROR(CheckStartEstimators(o, context));
  if (o.window_update_s < 0 || o.init_update_s < 0 || o.window_marginalize_batch_s < 0) {
    return InvalidArgument(context +
                           ": window_update_s, init_update_s, window_marginalize_batch_s must "
                           "be >= 0");
  }
  return Status::Ok();
}

}  // namespace

}  // namespace walkgraph
