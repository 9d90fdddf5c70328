// InsGraphOptions: its rules (Validate) and its YAML reader.
#include "walkgraph/smoothers/ins_graph.h"

#include "config/parsers.h"

#include <cmath>
#include <string>
#include <utility>
#include <vector>

#include "walkgraph/config.h"

namespace walkgraph {

namespace {

// path_loss: every mode but per-anchor (InsGraphOptions::path_loss).
const EnumNames<PathLossMode>& InsPathLossNames() {
  static const EnumNames<PathLossMode> names = [] {
    EnumNames<PathLossMode> n;
    for (const auto& nv : PathLossModeNames()) {
      if (nv.second != PathLossMode::kPerAnchor) n.push_back(nv);
    }
    return n;
  }();
  return names;
}
const std::vector<std::pair<std::string, InsStatePlacement>> kPlacementNames = {
    {"stance", InsStatePlacement::kStance}, {"every-n", InsStatePlacement::kEveryN}};

}  // namespace

Status InsGraphOptions::Validate() const {
  const InsGraphOptions& o = *this;
  const std::string context = "fg-ins-batch";
  WG_RETURN_IF_ERROR(
      CheckEnumOption(InsInitializationNames(), o.initialization, "initialization", context));
  WG_RETURN_IF_ERROR(CheckEnumOption(LossKindNames(), o.rss_loss, "rss_loss", context));
  WG_RETURN_IF_ERROR(CheckEnumOption(LossKindNames(), o.range_loss, "range_loss", context));
  WG_RETURN_IF_ERROR(CheckEnumOption(LossKindNames(), o.zupt_loss, "zupt_loss", context));
  WG_RETURN_IF_ERROR(CheckEnumOption(InsPathLossNames(), o.path_loss, "path_loss", context));
  if (!(o.init_lag_s > 0) || !(o.init_marginalize_batch_s >= 0) ||
      !(o.initial_trust_region_radius > 0)) {
    return InvalidArgument(
        "fg-ins-batch: need init_lag_s > 0, init_marginalize_batch_s >= 0, "
        "initial_trust_region_radius > 0");
  }
  if (o.every_n_samples < 1 || !(o.zupt_sigma_mps > 0) || !(o.zaru_sigma_radps > 0) ||
      !(o.initial_sigma_z_m > 0) || !(o.gauge_sigma_m > 0) || !(o.gauge_sigma_yaw_rad > 0) ||
      !(o.output_rate_hz > 0) || o.max_iterations < 1 || o.max_relinearizations < 0 ||
      !(o.relinearize_gyro_bias_radps > 0) || !(o.relinearize_acc_bias_mps2 > 0) ||
      !(o.max_state_interval_s > 0) || !(o.front_end.acc_bias_sigma_mps2 > 0) ||
      !(o.front_end.gyro_bias_sigma_radps > 0) || !(o.front_end.acc_bias_rw_mps2_sqrts > 0) ||
      !(o.front_end.gyro_bias_rw_radps_sqrts > 0) || !(o.rss_loss_scale > 0) ||
      !(o.range_loss_scale > 0) || !(o.zupt_loss_scale > 0) || !(o.range_bias_sigma_m > 0) ||
      !(o.function_tolerance > 0) || !(o.parameter_tolerance > 0) || !(o.gradient_tolerance > 0)) {
    return InvalidArgument(
        "fg-ins-batch: need every_n_samples >= 1, max_iterations >= 1, max_relinearizations >= "
        "0, and every sigma, rate, interval and threshold > 0 (bias sigmas and random walks "
        "of front_end included, and Ceres tolerances)");
  }
  if (!(o.A_prior_sigma_db > 0) || !(o.eta_prior_sigma > 0) || !(o.A_spread_prior_db > 0) ||
      !(o.eta_spread_prior > 0) || !(o.path_loss_anchor_test_z >= 0)) {
    return InvalidArgument(
        "fg-ins-batch: A_prior_sigma_db, eta_prior_sigma, A_spread_prior_db and "
        "eta_spread_prior must be > 0, path_loss_anchor_test_z >= 0");
  }
  if (!(o.gap_magnetic_min_sigma_rad > 0) || o.gap_min_spans < 2) {
    return InvalidArgument(
        "fg-ins-batch: need gap_magnetic_min_sigma_rad > 0 and gap_min_spans >= 2");
  }
  if (!(o.stance_magnetic_min_sigma_rad > 0) || !(o.stance_magnetic_spacing_m >= 0) ||
      !(o.stance_magnetic_pair_max_s > 0) || !std::isfinite(o.stance_magnetic_spacing_m) ||
      !std::isfinite(o.stance_magnetic_pair_max_s) || o.stance_magnetic_min_pairs < 2) {
    return InvalidArgument(
        "fg-ins-batch: need stance_magnetic_min_sigma_rad > 0, a finite stance_magnetic_spacing_m "
        ">= 0, a finite stance_magnetic_pair_max_s > 0 and stance_magnetic_min_pairs >= 2");
  }
  return Status::Ok();
}

StatusOr<InsGraphOptions> InsGraphOptionsFromYaml(const YAML::Node& node) {
  return InsGraphOptionsFromYaml(node, InsGraphOptions());
}

StatusOr<InsGraphOptions> InsGraphOptionsFromYaml(const YAML::Node& node,
                                                  const InsGraphOptions& base) {
  InsGraphOptions o = base;
  ConfigReader r(node, "fg-ins-batch");
  const YAML::Node front = r.Child("front_end");
  r.ReadEnum("placement", &o.placement, kPlacementNames,
             "where the graph puts states: at each stance or every n IMU samples");
  r.Read("every_n_samples", &o.every_n_samples, "every-n placement: IMU samples between states");
  r.Read("max_state_interval_s", &o.max_state_interval_s,
         "extra states inside longer gaps (standstills)");
  r.Read("zupt_sigma_mps", &o.zupt_sigma_mps,
         "sigma of the zero-velocity update at stance states (OpenShoe's)");
  r.ReadEnum("zupt_loss", &o.zupt_loss, LossKindNames(),
             "robust loss of the ZUPT factors (a false stance then costs little)");
  r.Read("zupt_loss_scale", &o.zupt_loss_scale,
         "scale of the ZUPT loss, in sigma of the whitened residual");
  r.Read("use_zaru", &o.use_zaru, "zero angular-rate updates when the foot is still");
  r.Read("use_stance_level", &o.use_stance_level,
         "levelling factor (mean specific force = gravity) at every ZUPT state");
  r.Read("use_gap_reach", &o.use_gap_reach,
         "across an IMU gap, bound the distance by how far the walker went in as long before "
         "it");
  r.Read("use_gap_magnetometer", &o.use_gap_magnetometer,
         "across an IMU gap, tie the yaw either side by the magnetometer (sigma learnt from the "
         "walk)");
  r.Read("gap_magnetic_min_sigma_rad", &o.gap_magnetic_min_sigma_rad,
         "floor on the learnt sigma of the gap's magnetic yaw factor");
  r.Read("gap_min_spans", &o.gap_min_spans,
         "spans before a gap needed to learn its reach or magnetic sigma (fewer: no factor)");
  r.Read("use_stance_magnetometer", &o.use_stance_magnetometer,
         "at every stance state, tie the yaw to the walk's magnetic field direction (sigma "
         "learnt from the walk)");
  r.Read("stance_magnetic_min_sigma_rad", &o.stance_magnetic_min_sigma_rad,
         "floor on the learnt sigma of the stance magnetic heading factor");
  r.Read("stance_magnetic_spacing_m", &o.stance_magnetic_spacing_m,
         "disturbances this far apart are taken as independent: factors at stances this far "
         "from the last one, and the sigma learnt from pairs this far apart");
  r.Read("stance_magnetic_pair_max_s", &o.stance_magnetic_pair_max_s,
         "learning that sigma: and at most this long before it");
  r.Read("stance_magnetic_min_pairs", &o.stance_magnetic_min_pairs,
         "pairs needed before the first stance magnetic heading factor");
  r.Read("zaru_sigma_radps", &o.zaru_sigma_radps,
         "ZARU sigma per gyro reading (divided by sqrt of the readings)");
  r.Read("use_bias_prior", &o.use_bias_prior,
         "prior N(0, front_end bias sigma^2) on the first state's IMU biases");
  r.Read("initial_sigma_z_m", &o.initial_sigma_z_m, "sigma of the start height prior (z = 0)");
  r.Read("gauge_sigma_m", &o.gauge_sigma_m,
         "without initial_pose: sigma fixing the arbitrary origin");
  r.Read("gauge_sigma_yaw_rad", &o.gauge_sigma_yaw_rad,
         "without initial_pose: sigma fixing the arbitrary start yaw");
  r.Read("output_rate_hz", &o.output_rate_hz, "rate of the output trajectory");
  r.Read("compute_covariance", &o.compute_covariance,
         "compute the state covariances of the output");
  r.Read("max_iterations", &o.max_iterations, "fg-ins-batch: most Levenberg-Marquardt iterations");
  r.ReadEnum("initialization", &o.initialization, InsInitializationNames(),
             "batch start: the ZUPT-aided INS (front-end) or a fast window pass");
  r.Read("init_lag_s", &o.init_lag_s, "initialization window: lag of the fast fg-ins-window pass");
  r.Read("init_marginalize_batch_s", &o.init_marginalize_batch_s,
         "initialization window: states leave in batches of this span");
  r.Read("initial_trust_region_radius", &o.initial_trust_region_radius,
         "LM starting trust-region radius");
  r.Read("function_tolerance", &o.function_tolerance, "Ceres relative cost-change stop");
  r.Read("parameter_tolerance", &o.parameter_tolerance, "Ceres relative step-size stop");
  r.Read("gradient_tolerance", &o.gradient_tolerance, "Ceres gradient stop");
  r.Read("max_relinearizations", &o.max_relinearizations,
         "most re-preintegrations of the IMU after the biases moved");
  r.Read("relinearize_gyro_bias_radps", &o.relinearize_gyro_bias_radps,
         "re-preintegrate when a gyro bias moved more than this");
  r.Read("relinearize_acc_bias_mps2", &o.relinearize_acc_bias_mps2,
         "re-preintegrate when an accelerometer bias moved more than this");
  r.Read("use_rss", &o.use_rss, "add the walk's rss.csv as RSS factors (dB domain)");
  r.Read("use_ranges", &o.use_ranges, "add the walk's range.csv as range factors");
  r.Read("receiver_offset_z_m", &o.receiver_offset_z_m, "receiver height above the IMU");
  r.ReadEnum("rss_loss", &o.rss_loss, LossKindNames(), "robust loss of the RSS factors");
  r.Read("rss_loss_scale", &o.rss_loss_scale,
         "scale of the RSS loss, in sigma of the whitened residual");
  r.ReadEnum("range_loss", &o.range_loss, LossKindNames(), "robust loss of the range factors");
  r.Read("range_loss_scale", &o.range_loss_scale,
         "scale of the range loss, in sigma of the whitened residual");
  r.Read("estimate_range_bias", &o.estimate_range_bias,
         "estimate a per-anchor additive range bias");
  r.ReadEnum("path_loss", &o.path_loss, InsPathLossNames(),
             "path loss (A, eta) of the RSS factors: held, global, or per anchor");
  r.Read("A_prior_sigma_db", &o.A_prior_sigma_db,
         "prior sigma of estimated A around walk.yaml's value");
  r.Read("eta_prior_sigma", &o.eta_prior_sigma,
         "prior sigma of estimated eta around walk.yaml's value");
  r.Read("A_spread_prior_db", &o.A_spread_prior_db,
         "per anchor: sigma of one anchor's A around the walk-wide mean");
  r.Read("eta_spread_prior", &o.eta_spread_prior,
         "per anchor: sigma of one anchor's eta around the walk-wide mean");
  r.Read("path_loss_anchor_test_z", &o.path_loss_anchor_test_z,
         "auto: solve per anchor when the anchor test exceeds this z; 0 never");
  r.Read("range_bias_sigma_m", &o.range_bias_sigma_m, "prior sigma of the per-anchor range bias");
  WG_RETURN_IF_ERROR(r.Finish());
  if (front.IsDefined()) {
    WG_ASSIGN_OR_RETURN(o.front_end, StrideOptionsFromYaml(front, o.front_end));
  }
  WG_RETURN_IF_ERROR(o.Validate());
  return o;
}

}  // namespace walkgraph
