#include "walkgraph/smoothers/ins_graph.h"

#include "config/parsers.h"
#include "walkgraph/smoothers/chain_covariance.h"
#include "walkgraph/smoothers/ins_window.h"

#include <algorithm>
#include <cmath>
#include <set>
#include <utility>

#include <ceres/covariance.h>
#include <ceres/normal_prior.h>
#include <ceres/solver.h>

#include "estimators/builtin.h"
#include "factors/bias_random_walk_factor.h"
#include "factors/difference_prior_factor.h"
#include "factors/gap_reach_factor.h"
#include "factors/imu_preintegration_factor.h"
#include "factors/ins_prior_factor.h"
#include "factors/magnetic_heading_change_factor.h"
#include "factors/magnetic_heading_factor.h"
#include "factors/nav_quaternion_manifold.h"
#include "factors/position_prior_factor.h"
#include "factors/range_factor.h"
#include "factors/rss_factor.h"
#include "factors/zaru_factor.h"
#include "factors/zupt_factor.h"
#include "smoothers/graph_internal.h"
#include "smoothers/ins_graph_internal.h"
#include "util/enum_define.h"
#include "util/median.h"
#include "walkgraph/angle.h"
#include "walkgraph/config.h"
#include "walkgraph/kalman.h"

namespace walkgraph {

WALKGRAPH_DEFINE_ENUM_NAMES(
    InsFactorKind, "InsFactor kind", {"imu", InsFactorKind::kImu},
    {"bias_rw_gyro", InsFactorKind::kBiasRwGyro}, {"bias_rw_acc", InsFactorKind::kBiasRwAcc},
    {"zupt", InsFactorKind::kZupt}, {"zaru", InsFactorKind::kZaru},
    {"prior", InsFactorKind::kPrior}, {"bias_prior_gyro", InsFactorKind::kBiasPriorGyro},
    {"bias_prior_acc", InsFactorKind::kBiasPriorAcc},
    {"path_loss_spread", InsFactorKind::kPathLossSpread},
    {"path_loss_prior", InsFactorKind::kPathLossPrior}, {"rss", InsFactorKind::kRss},
    {"range", InsFactorKind::kRange}, {"range_bias_prior", InsFactorKind::kRangeBiasPrior},
    {"waypoint", InsFactorKind::kWaypoint}, {"gap_reach", InsFactorKind::kGapReach},
    {"gap_magnetic_heading", InsFactorKind::kGapMagneticHeading},
    {"stance_magnetic_heading", InsFactorKind::kStanceMagneticHeading})

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

namespace {

InsFactor MakeFactor(InsFactorKind kind, ceres::CostFunction* cost, std::vector<double*> blocks) {
  InsFactor f;
  f.kind = kind;
  f.cost.reset(cost);
  f.blocks = std::move(blocks);
  return f;
}

NavState ToNavState(const InsState& s) {
  NavState n;
  n.t_s = s.t_s;
  n.p_n = s.position();
  n.v_n = s.velocity();
  n.q_nb = s.attitude().normalized();
  return n;
}

double Yaw(const Eigen::Quaterniond& q) { return QuaternionYaw(q); }

// The ZUPT sample nearest the middle of a stance phase: the foot is stillest there (the
// phase's edges hold the slow ends of the swing, where a ZUPT state would be biased).
size_t MidStance(const ZuptInsSolution& front, const StancePhase& ph) {
  const size_t mid = (ph.begin + ph.end) / 2;
  for (size_t d = 0; d <= (ph.end - ph.begin) / 2 + 1; ++d) {
    if (mid >= ph.begin + d && front.zupt[mid - d]) return mid - d;
    if (mid + d <= ph.end && front.zupt[mid + d]) return mid + d;
  }
  return mid;
}

bool UsesRss(const InsGraphContext& c) {
  return c.options.use_rss && c.walk->has_rss() && !c.walk->anchors.empty();
}
bool UsesRanges(const InsGraphContext& c) {
  return c.options.use_ranges && c.walk->has_ranges() && !c.walk->anchors.empty();
}
bool HasRadio(const InsGraphContext& c) { return UsesRss(c) || UsesRanges(c); }

}  // namespace

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

StatusOr<std::vector<InsState>> InitialInsStates(const Walk& walk, const ZuptInsSolution& front,
                                                 const InsGraphOptions& o) {
  WG_RETURN_IF_ERROR(o.Validate());
  const size_t n = walk.imu.size();
  if (n < 2 || front.states.size() != n) {
    return FailedPrecondition("fg-ins-batch: the front end's solution does not match the IMU");
  }
  std::set<size_t> idx = {0, n - 1};
  if (o.placement == InsStatePlacement::kStance) {
    for (const StancePhase& ph : front.phases) idx.insert(MidStance(front, ph));
  } else {
    for (size_t k = 0; k < n; k += static_cast<size_t>(o.every_n_samples)) idx.insert(k);
  }
  // No interval longer than max_state_interval_s (long standstills, walks without stance).
  std::vector<size_t> sorted(idx.begin(), idx.end());
  std::vector<size_t> all;
  for (size_t s = 0; s < sorted.size(); ++s) {
    all.push_back(sorted[s]);
    if (s + 1 == sorted.size()) break;
    const size_t a = sorted[s], b = sorted[s + 1];
    const double span = walk.imu[b].t_s - walk.imu[a].t_s;
    const int pieces = static_cast<int>(std::ceil(span / o.max_state_interval_s));
    for (int j = 1; j < pieces; ++j) {
      const size_t k =
          a + static_cast<size_t>(std::llround(static_cast<double>(b - a) * j / pieces));
      if (k > all.back() && k < b) all.push_back(k);
    }
  }
  std::vector<InsState> states;
  states.reserve(all.size());
  for (size_t k : all) {
    InsState s;
    s.t_s = walk.imu[k].t_s;
    s.imu_index = k;
    s.zupt = front.zupt[k];
    const NavState& x = front.states[k];
    for (int i = 0; i < 3; ++i) {
      s.p[i] = x.p_n[i];
      s.v[i] = x.v_n[i];
      s.bg[i] = front.gyro_bias_radps[k][i];
      s.ba[i] = front.acc_bias_mps2[k][i];
    }
    const Eigen::Quaterniond q = x.q_nb.normalized();
    s.q = {q.x(), q.y(), q.z(), q.w()};
    states.push_back(s);
  }
  return states;
}

std::vector<InsFactor> InsStateFactors(const InsGraphContext& c, InsState* s) {
  std::vector<InsFactor> out;
  if (s->zupt) {
    out.push_back(MakeFactor(InsFactorKind::kZupt, ZuptFactor::Create(c.options.zupt_sigma_mps),
                             {s->v.data()}));
    out.back().loss = internal::MakeLoss(c.options.zupt_loss, c.options.zupt_loss_scale);
  }
  return out;
}

namespace {

// The last sample at or before IMU sample `index`, within 0.1 s of it, that has a magnetometer
// reading (at or before: the online output at a state uses no later reading).
std::optional<size_t> MagnetometerNear(const std::vector<ImuSample>& imu, size_t index) {
  for (size_t k = index + 1; k-- > 0 && imu[index].t_s - imu[k].t_s <= 0.1;) {
    if (imu[k].has_mag) return k;
  }
  return std::nullopt;
}

// What the walk before an IMU gap shows of spans as long as the gap's (InsGraphOptions::
// use_gap_reach, use_gap_magnetometer): on the front end's path over the kGapHistoryS before
// the gap, for spans starting every 0.5 s and crossing no earlier gap, the horizontal path
// length walked (spans of at least 0.1 m/s only: standing does not say how far the walker
// goes) and the change of the magnetic field's horizontal direction in the navigation frame.
// The bounded history keeps a walk with many gaps linear in its length (and follows the
// walker's recent pace).
struct GapHistory {
  std::vector<double> reach_m;
  std::vector<double> field_turn_rad;
};

double FieldDirection(const InsGraphContext& c, size_t k) {
  const Eigen::Vector3d m = (*c.path)[k].q_nb * c.walk->imu[k].mag_ut;
  return std::atan2(m.y(), m.x());
}

constexpr double kGapHistoryS = 300.0;

GapHistory LearnGapHistory(const InsGraphContext& c, size_t k_end, double span_s) {
  const std::vector<ImuSample>& imu = c.walk->imu;
  const std::vector<NavState>& path = *c.path;
  size_t k0 = k_end;  // the first sample of the history
  while (k0 > 0 && imu[k_end].t_s - imu[k0 - 1].t_s <= kGapHistoryS) --k0;
  const size_t n = k_end - k0 + 1;
  std::vector<double> arc(n, 0.0);  // cumulative horizontal path length from k0
  std::vector<int> gaps(n, 0);      // gaps among the intervals from k0
  for (size_t m = 1; m < n; ++m) {
    const size_t i = k0 + m;
    const bool gap = imu[i].t_s - imu[i - 1].t_s > c.imu_gap_s;
    gaps[m] = gaps[m - 1] + (gap ? 1 : 0);
    arc[m] = arc[m - 1] + (gap ? 0.0 : (path[i].p_n - path[i - 1].p_n).head<2>().norm());
  }
  GapHistory h;
  double next_t = -std::numeric_limits<double>::infinity();
  for (size_t i = k0, j = k0; i <= k_end; ++i) {
    if (imu[i].t_s < next_t) continue;
    next_t = imu[i].t_s + 0.5;
    j = std::max(j, i);
    while (j <= k_end && imu[j].t_s < imu[i].t_s + span_s) ++j;
    if (j > k_end) break;
    if (gaps[j - k0] != gaps[i - k0]) continue;
    const double reach = arc[j - k0] - arc[i - k0];
    if (reach >= 0.1 * span_s) h.reach_m.push_back(reach);
    const auto mi = MagnetometerNear(imu, i), mj = MagnetometerNear(imu, j);
    if (mi && mj) {
      h.field_turn_rad.push_back(NormalizeAngle(FieldDirection(c, *mj) - FieldDirection(c, *mi)));
    }
  }
  return h;
}

// The RMS of angles about their median (the learnt σ of both magnetic factors).
double AngleSpreadAboutMedian(const std::vector<double>& angles) {
  const double med = internal::Median(angles);
  double sum2 = 0.0;
  for (double x : angles) sum2 += std::pow(NormalizeAngle(x - med), 2);
  return std::sqrt(sum2 / static_cast<double>(angles.size()));
}

// The yaw tie and the reach bound across an IMU gap between a and b (see the options).
std::vector<InsFactor> GapFactors(const InsGraphContext& c, InsState* a, InsState* b) {
  const InsGraphOptions& o = c.options;
  const std::vector<ImuSample>& imu = c.walk->imu;
  std::vector<InsFactor> out;
  if (!(o.use_gap_reach || o.use_gap_magnetometer) || c.path == nullptr ||
      c.path->size() != imu.size()) {
    return out;
  }
  const GapHistory h = LearnGapHistory(c, a->imu_index, b->t_s - a->t_s);
  const size_t enough = static_cast<size_t>(o.gap_min_spans);
  if (o.use_gap_reach && h.reach_m.size() >= enough) {
    std::vector<double> r = h.reach_m;
    std::sort(r.begin(), r.end());
    const double reach = r[r.size() * 9 / 10], med = r[r.size() / 2];  // as internal::Median
    for (double& x : r) x = std::fabs(x - med);
    const double sigma = std::max(1.4826 * internal::Median(r), 0.05 * reach + 0.05);
    out.push_back(MakeFactor(InsFactorKind::kGapReach, GapReachFactor::Create(reach, sigma),
                             {a->p.data(), b->p.data()}));
  }
  const auto ma = MagnetometerNear(imu, a->imu_index), mb = MagnetometerNear(imu, b->imu_index);
  if (o.use_gap_magnetometer && ma && mb && h.field_turn_rad.size() >= enough) {
    const double sigma =
        std::max(AngleSpreadAboutMedian(h.field_turn_rad), o.gap_magnetic_min_sigma_rad);
    out.push_back(
        MakeFactor(InsFactorKind::kGapMagneticHeading,
                   MagneticHeadingChangeFactor::Create(imu[*ma].mag_ut, imu[*mb].mag_ut, sigma),
                   {a->q.data(), b->q.data()}));
    out.back().loss = internal::MakeLoss(LossKind::kCauchy, 1.0);
  }
  return out;
}

// Whether a field vector in the navigation frame has a horizontal direction to read: at least
// 5 % of its magnitude (a dip under ~87°; not a zero reading), where atan2 and its derivatives
// are well defined.
bool HasHorizontalDirection(const Eigen::Vector3d& f) {
  const double n = f.norm();
  return std::isfinite(n) && n > 0 && f.head<2>().norm() >= 0.05 * n;
}

// σ of the stance magnetic heading factor from the field turns of the pairs seen so far: their
// RMS about the median, ÷√2 (either end of a pair disturbed), at least min_sigma.
double StanceMagneticSigma(const std::vector<double>& turns, double min_sigma) {
  return std::max(AngleSpreadAboutMedian(turns) / std::sqrt(2.0), min_sigma);
}

}  // namespace

std::vector<double> StanceMagneticSigmas(const Walk& walk, const ZuptInsSolution& front,
                                         const InsGraphOptions& o) {
  const std::vector<ImuSample>& imu = walk.imu;
  std::vector<double> sigma(imu.size(), std::numeric_limits<double>::quiet_NaN());
  if (!o.use_stance_magnetometer || front.states.size() != imu.size()) return sigma;
  struct Seen {
    double t_s;
    Eigen::Vector2d p;
    double field_rad;
  };
  std::vector<Seen> seen;     // stances with a reading, in time order
  std::vector<double> turns;  // the field's turn of each pair so far
  double current = std::numeric_limits<double>::quiet_NaN();
  size_t learnt_from = 0;  // σ is relearnt each time the pairs double (n log n in all)
  std::optional<Eigen::Vector2d> last_used;  // where the last factor's stance was
  for (const StancePhase& ph : front.phases) {
    const size_t m = MidStance(front, ph);
    const std::optional<size_t> k = MagnetometerNear(imu, m);
    if (!k) continue;
    const Eigen::Vector3d f = front.states[*k].q_nb * imu[*k].mag_ut;
    if (!HasHorizontalDirection(f)) continue;
    const Seen now{imu[m].t_s, front.states[m].p_n.head<2>(), std::atan2(f.y(), f.x())};
    for (size_t j = seen.size();
         j-- > 0 && now.t_s - seen[j].t_s <= o.stance_magnetic_pair_max_s;) {
      if ((now.p - seen[j].p).norm() >= o.stance_magnetic_spacing_m) {
        turns.push_back(NormalizeAngle(now.field_rad - seen[j].field_rad));
        break;
      }
    }
    seen.push_back(now);
    const size_t enough = static_cast<size_t>(o.stance_magnetic_min_pairs);
    if (turns.size() >= std::max(enough, 2 * learnt_from)) {
      current = StanceMagneticSigma(turns, o.stance_magnetic_min_sigma_rad);
      learnt_from = turns.size();
    }
    if (!std::isfinite(current)) continue;
    if (last_used && (now.p - *last_used).norm() < o.stance_magnetic_spacing_m) continue;
    last_used = now.p;
    for (size_t i = ph.begin; i <= ph.end && i < sigma.size(); ++i) sigma[i] = current;
  }
  return sigma;
}

void AddStanceMagneticDiagnostics(const std::vector<double>& sigma, size_t factors,
                                  std::map<std::string, double>* diagnostics) {
  (*diagnostics)["num_stance_magnetic_factors"] = static_cast<double>(factors);
  for (size_t i = sigma.size(); i-- > 0;) {
    if (std::isfinite(sigma[i])) {
      (*diagnostics)["stance_magnetic_sigma_rad"] = sigma[i];
      break;
    }
  }
}

std::vector<InsFactor> InsStanceMagneticFactors(const InsGraphContext& c,
                                                std::vector<InsState>* states, size_t k, size_t n,
                                                InsSharedBlocks* blocks) {
  std::vector<InsFactor> out;
  const std::vector<double>* sigma = c.stance_magnetic_sigma;
  const std::vector<ImuSample>& imu = c.walk->imu;
  if (sigma == nullptr || sigma->size() != imu.size()) return out;
  auto has_sigma = [&](size_t i) { return std::isfinite((*sigma)[i]); };
  for (size_t j = (k == 0 ? 0 : k + 1); j <= k + n && j < states->size(); ++j) {
    InsState& s = (*states)[j];
    if (!s.zupt || !has_sigma(s.imu_index)) continue;
    // One factor per stance: a state after another inside the same stance (a standstill's
    // extra states) would count that spot's disturbance again.
    if (j > 0) {
      size_t i = (*states)[j - 1].imu_index;
      while (i < s.imu_index && has_sigma(i)) ++i;
      if ((*states)[j - 1].zupt && i == s.imu_index) continue;
    }
    const std::optional<size_t> m = MagnetometerNear(imu, s.imu_index);
    if (!m) continue;
    const Eigen::Vector3d f = s.attitude().normalized() * imu[*m].mag_ut;
    if (!HasHorizontalDirection(f)) continue;
    if (!blocks->field_yaw_set) {
      blocks->field_yaw_rad = std::atan2(f.y(), f.x());
      blocks->field_yaw_set = true;
    }
    out.push_back(MakeFactor(InsFactorKind::kStanceMagneticHeading,
                             MagneticHeadingFactor::Create(imu[*m].mag_ut, (*sigma)[s.imu_index]),
                             {s.q.data(), &blocks->field_yaw_rad}));
    out.back().loss = internal::MakeLoss(LossKind::kCauchy, 1.0);
  }
  return out;
}

StatusOr<std::vector<InsFactor>> InsBetweenFactors(const InsGraphContext& c, InsState* a,
                                                   InsState* b) {
  const std::vector<ImuSample>& imu = c.walk->imu;
  const InsGraphOptions& o = c.options;
  if (!(a->imu_index < b->imu_index) || b->imu_index >= imu.size()) {
    return InvalidArgument("fg-ins-batch: states must be in IMU order inside the walk");
  }
  const Eigen::Vector3d bg = a->gyro_bias(), ba = a->acc_bias();
  ImuPreintegration pim(bg, ba, o.front_end.gyro_noise_radps, o.front_end.acc_noise_mps2);
  const double scale_noise = c.scale_noise != nullptr && a->imu_index < c.scale_noise->size()
                                 ? (*c.scale_noise)[a->imu_index]
                                 : 0.0;
  pim.SetScaleNoise(scale_noise, scale_noise);
  bool spans_gap = false;
  for (size_t k = a->imu_index + 1; k <= b->imu_index; ++k) {
    const double dt = imu[k].t_s - imu[k - 1].t_s;
    if (dt > c.imu_gap_s) {
      // An IMU gap: nothing to integrate. The mean is rest (no rotation, the specific force
      // that cancels gravity at a's attitude); the uncertainty is a walker's: any rotation,
      // kImuGapSpeedMps of velocity and kImuGapSpeedMps × dt of position per axis.
      const Eigen::Vector3d up_body = (a->attitude() * pim.delta_q()).conjugate() *
                                      Eigen::Vector3d(0.0, 0.0, o.front_end.gravity_mps2);
      pim.Integrate(dt, bg, ba + up_body);
      ImuPreintegration::Matrix9d q = ImuPreintegration::Matrix9d::Zero();
      q.diagonal() << kPi * kPi, kPi * kPi, kPi * kPi,
          Eigen::Vector3d::Constant(kImuGapSpeedMps * kImuGapSpeedMps),
          Eigen::Vector3d::Constant(std::pow(kImuGapSpeedMps * dt, 2));
      pim.AddCovariance(q);
      spans_gap = true;
      continue;
    }
    if (o.front_end.sampling == ImuSampling::kIntervalAverage) {
      pim.Integrate(dt, imu[k].gyro_radps, imu[k].acc_mps2);
    } else {
      // Point samples: the trapezoid of strapdown.h in the frame of t_{k−1} (coning omitted).
      const Eigen::Vector3d w = 0.5 * (imu[k - 1].gyro_radps + imu[k].gyro_radps);
      const Eigen::Matrix3d e = QuaternionExp((w - bg) * dt).toRotationMatrix();
      const Eigen::Vector3d f =
          0.5 * ((imu[k - 1].acc_mps2 - ba) + e * (imu[k].acc_mps2 - ba)) + ba;
      pim.Integrate(dt, w, f);
    }
  }
  std::vector<InsFactor> out;
  out.push_back(MakeFactor(InsFactorKind::kImu,
                           ImuPreintegrationFactor::Create(pim, o.front_end.gravity_mps2),
                           {a->p.data(), a->v.data(), a->q.data(), a->bg.data(), a->ba.data(),
                            b->p.data(), b->v.data(), b->q.data()}));
  const double dt = b->t_s - a->t_s;
  out.push_back(MakeFactor(InsFactorKind::kBiasRwGyro,
                           BiasRandomWalkFactor::Create(o.front_end.gyro_bias_rw_radps_sqrts, dt),
                           {a->bg.data(), b->bg.data()}));
  out.push_back(MakeFactor(InsFactorKind::kBiasRwAcc,
                           BiasRandomWalkFactor::Create(o.front_end.acc_bias_rw_mps2_sqrts, dt),
                           {a->ba.data(), b->ba.data()}));
  if (spans_gap) {
    for (InsFactor& f : GapFactors(c, a, b)) out.push_back(std::move(f));
  }
  if (o.use_zaru && c.still != nullptr && c.still->size() == imu.size()) {
    Eigen::Vector3d sum = Eigen::Vector3d::Zero();
    int m = 0;
    for (size_t k = a->imu_index + 1; k <= b->imu_index; ++k) {
      if (!(*c.still)[k]) continue;
      sum += imu[k].gyro_radps;
      ++m;
    }
    if (m > 0) {
      out.push_back(MakeFactor(
          InsFactorKind::kZaru,
          ZaruFactor::Create(sum / m, o.zaru_sigma_radps / std::sqrt(static_cast<double>(m))),
          {b->bg.data()}));
    }
  }
  return out;
}

std::vector<InsFactor> InsGaugeFactors(const InsGraphContext& c, InsState* first) {
  const InsGraphOptions& o = c.options;
  std::vector<InsFactor> out;
  Eigen::Vector3d p0 = first->position(), sigma_p = Eigen::Vector3d::Constant(o.gauge_sigma_m);
  double yaw0 = Yaw(first->attitude()), sigma_yaw = o.gauge_sigma_yaw_rad;
  if (c.walk->meta.initial_pose) {
    const InitialPose& ip = *c.walk->meta.initial_pose;
    p0 = Eigen::Vector3d(ip.x_m, ip.y_m, 0.0);
    sigma_p = Eigen::Vector3d(ip.sigma_xy_m, ip.sigma_xy_m, o.initial_sigma_z_m);
    if (ip.heading_known) {
      yaw0 = ip.heading_rad;
      sigma_yaw = ip.sigma_heading_rad;
    } else {
      sigma_yaw = kUnknownHeadingSigmaRad;  // position-only start
    }
  }
  // Without a known start but with radio, the anchors fix the gauge.
  if (c.walk->meta.initial_pose || !HasRadio(c)) {
    out.push_back(MakeFactor(InsFactorKind::kPrior,
                             InsPriorFactor::Create(p0, sigma_p, yaw0, sigma_yaw),
                             {first->p.data(), first->q.data()}));
  }
  if (o.use_bias_prior) {
    out.push_back(MakeFactor(
        InsFactorKind::kBiasPriorGyro,
        BiasPriorFactor::Create(Eigen::Vector3d::Zero(), o.front_end.gyro_bias_sigma_radps),
        {first->bg.data()}));
    out.push_back(MakeFactor(
        InsFactorKind::kBiasPriorAcc,
        BiasPriorFactor::Create(Eigen::Vector3d::Zero(), o.front_end.acc_bias_sigma_mps2),
        {first->ba.data()}));
  }
  if (o.use_zaru && c.still != nullptr && c.still->size() == c.walk->imu.size() &&
      (*c.still)[first->imu_index]) {
    out.push_back(
        MakeFactor(InsFactorKind::kZaru,
                   ZaruFactor::Create(c.walk->imu[first->imu_index].gyro_radps, o.zaru_sigma_radps),
                   {first->bg.data()}));
  }
  return out;
}

StatusOr<std::vector<InsFactor>> InsSegmentFactors(const InsGraphContext& c,
                                                   std::vector<InsState>* states, size_t k,
                                                   size_t n) {
  if (k + n >= states->size()) return InvalidArgument("fg-ins-batch: segment beyond the states");
  std::vector<InsFactor> out;
  auto append = [&out](std::vector<InsFactor> more) {
    for (InsFactor& f : more) out.push_back(std::move(f));
  };
  if (k == 0) {
    append(InsGaugeFactors(c, &(*states)[0]));
    append(InsStateFactors(c, &(*states)[0]));
  }
  for (size_t j = k + 1; j <= k + n; ++j) {
    WG_ASSIGN_OR_RETURN(std::vector<InsFactor> between,
                        InsBetweenFactors(c, &(*states)[j - 1], &(*states)[j]));
    append(std::move(between));
    append(InsStateFactors(c, &(*states)[j]));
  }
  return out;
}

namespace {

// Where a reading at time t is received: the bracketing states of states[k..k+n] and α along
// the front end's path (see the top of ins_graph.h); b null: at a alone.
struct Where {
  InsState* a;
  InsState* b;
  double alpha;
};
Where ReceiverAt(const InsGraphContext& c, std::vector<InsState>* states, size_t k, size_t n,
                 double t) {
  const Walk& w = *c.walk;
  size_t j =
      static_cast<size_t>(std::upper_bound(states->begin() + static_cast<long>(k),
                                           states->begin() + static_cast<long>(k + n + 1), t,
                                           [](double x, const InsState& s) { return x < s.t_s; }) -
                          states->begin());
  if (j == 0) j = 1;
  if (j > k + n) return {&(*states)[k + n], nullptr, 0.0};
  InsState* a = &(*states)[j - 1];
  InsState* b = &(*states)[j];
  double alpha = (t - a->t_s) / (b->t_s - a->t_s);
  // Across an IMU gap the front end's path stands still: it says nothing of the progress there,
  // so a segment that spans a gap interpolates by time (the bridge's own assumption).
  bool spans_gap = false;
  for (size_t m = a->imu_index + 1; m <= b->imu_index && !spans_gap; ++m) {
    spans_gap = w.imu[m].t_s - w.imu[m - 1].t_s > c.imu_gap_s;
  }
  if (!spans_gap && c.path != nullptr && c.path->size() == w.imu.size()) {
    const Eigen::Vector3d pa = (*c.path)[a->imu_index].p_n, pb = (*c.path)[b->imu_index].p_n;
    const Eigen::Vector3d d = pb - pa;
    if (d.squaredNorm() > 1e-4) {
      // The IMU sample at or after t.
      size_t m = a->imu_index;
      while (m < b->imu_index && w.imu[m].t_s < t) ++m;
      alpha = ((*c.path)[m].p_n - pa).dot(d) / d.squaredNorm();
    }
  }
  alpha = std::clamp(alpha, 0.0, 1.0);
  if (alpha < 1e-3) return {a, nullptr, 0.0};
  if (alpha > 1.0 - 1e-3) return {b, nullptr, 0.0};
  return {a, b, alpha};
}

}  // namespace

PathLossMode ResolveInsPathLoss(const InsGraphOptions& o, const RadioDefaults& radio) {
  if (o.path_loss != PathLossMode::kAuto) return o.path_loss;
  return radio.calibrated ? PathLossMode::kFixed : PathLossMode::kGlobal;
}

namespace {

// The path-loss block an RSS reading of anchor `id` uses: the walk's, or (hierarchical) the
// anchor's own, created at the mean's value and tied to it on first use.
double* PathLossBlock(const InsGraphOptions& o, int id, InsSharedBlocks* blocks,
                      std::vector<InsFactor>* out) {
  if (!blocks->per_anchor_path_loss) return blocks->path_loss.data();
  auto [it, created] = blocks->anchor_path_loss.emplace(id, blocks->path_loss);
  if (blocks->anchor_path_loss_prior_added.insert(id).second) {
    out->push_back(MakeFactor(
        InsFactorKind::kPathLossSpread,
        DifferencePriorFactor<2>::Create(Eigen::Vector2d(o.A_spread_prior_db, o.eta_spread_prior)),
        {it->second.data(), blocks->path_loss.data()}));
  }
  (void)created;
  return it->second.data();
}

}  // namespace

StatusOr<std::vector<InsFactor>> InsRadioFactors(const InsGraphContext& c,
                                                 std::vector<InsState>* states, size_t k, size_t n,
                                                 InsSharedBlocks* blocks) {
  if (k + n >= states->size()) return InvalidArgument("fg-ins-batch: segment beyond the states");
  const Walk& w = *c.walk;
  const InsGraphOptions& o = c.options;
  std::vector<InsFactor> out;
  const double t_lo = (*states)[k].t_s, t_hi = (*states)[k + n].t_s;
  auto inside = [&](double t) { return (t > t_lo || (k == 0 && t == t_lo)) && t <= t_hi; };
  auto where = [&](double t) { return ReceiverAt(c, states, k, n, t); };
  const Eigen::Vector3d lower(0.0, 0.0, o.receiver_offset_z_m);
  if (UsesRss(c)) {
    const RadioDefaults& radio = w.meta.radio;
    if (!blocks->path_loss_set) {
      blocks->path_loss = {radio.path_loss.A_dbm, radio.path_loss.eta};
      blocks->path_loss_set = true;
    }
    const PathLossMode model = ResolveInsPathLoss(o, radio);
    blocks->estimate_path_loss = model != PathLossMode::kFixed;
    blocks->per_anchor_path_loss = model == PathLossMode::kHierarchical;
    if (blocks->estimate_path_loss && !blocks->path_loss_prior_added) {
      blocks->path_loss_prior_added = true;
      out.push_back(MakeFactor(
          InsFactorKind::kPathLossPrior,
          new ceres::NormalPrior(
              Eigen::Vector2d(1.0 / o.A_prior_sigma_db, 1.0 / o.eta_prior_sigma).asDiagonal(),
              Eigen::Vector2d(radio.path_loss.A_dbm, radio.path_loss.eta)),
          {blocks->path_loss.data()}));
    }
    for (const RssSample& r : w.rss) {
      if (!inside(r.t_s)) continue;
      const int ai = w.AnchorIndex(r.anchor_id);
      if (ai < 0) return InvalidArgument("fg-ins-batch: rss from an unknown anchor");
      RssFactor<3>::Reading reading;
      reading.rss = r.rss;
      reading.anchor_m = w.anchors[static_cast<size_t>(ai)].position_m - lower;
      reading.sigma_db = radio.path_loss.sigma_db;
      reading.sign = radio.units == RssUnits::kRfcode ? -1.0 : 1.0;
      reading.d0_m = radio.path_loss.d0_m;
      double* path_loss = PathLossBlock(o, r.anchor_id, blocks, &out);
      const Where at = where(r.t_s);
      InsFactor f;
      if (at.b == nullptr) {
        f = MakeFactor(InsFactorKind::kRss, RssFactor<3>::Create(reading),
                       {at.a->p.data(), path_loss});
      } else {
        f = MakeFactor(InsFactorKind::kRss, RssFactor<3>::CreateInterpolated(reading, at.alpha),
                       {at.a->p.data(), at.b->p.data(), path_loss});
      }
      f.anchor_id = r.anchor_id;
      f.loss = internal::MakeLoss(o.rss_loss, o.rss_loss_scale);
      out.push_back(std::move(f));
    }
  }
  if (UsesRanges(c)) {
    for (const RangeSample& r : w.ranges) {
      if (!inside(r.t_s)) continue;
      const int ai = w.AnchorIndex(r.anchor_id);
      if (ai < 0) return InvalidArgument("fg-ins-batch: range from an unknown anchor");
      const Eigen::Vector3d anchor = w.anchors[static_cast<size_t>(ai)].position_m - lower;
      double* bias = &blocks->range_bias_m[r.anchor_id];
      if (o.estimate_range_bias && blocks->bias_prior_added.insert(r.anchor_id).second) {
        out.push_back(MakeFactor(
            InsFactorKind::kRangeBiasPrior,
            new ceres::NormalPrior(Eigen::MatrixXd::Constant(1, 1, 1.0 / o.range_bias_sigma_m),
                                   Eigen::VectorXd::Zero(1)),
            {bias}));
      }
      const double sigma = w.meta.radio.range_sigma_m;
      const Where at = where(r.t_s);
      InsFactor f;
      if (at.b == nullptr) {
        f = MakeFactor(InsFactorKind::kRange, RangeFactor<3>::Create(r.range_m, anchor, sigma),
                       {at.a->p.data(), bias});
      } else {
        f = MakeFactor(InsFactorKind::kRange,
                       RangeFactor<3>::CreateInterpolated(r.range_m, anchor, sigma, at.alpha),
                       {at.a->p.data(), at.b->p.data(), bias});
      }
      f.loss = internal::MakeLoss(o.range_loss, o.range_loss_scale);
      out.push_back(std::move(f));
    }
  }
  for (const Waypoint& wp : w.waypoints) {  // known positions of the foot
    if (!inside(wp.t_s)) continue;
    const Where at = where(wp.t_s);
    out.push_back(at.b == nullptr
                      ? MakeFactor(InsFactorKind::kWaypoint,
                                   PositionPriorFactor<3>::Create(wp.position_m, wp.sigma_m),
                                   {at.a->p.data()})
                      : MakeFactor(InsFactorKind::kWaypoint,
                                   PositionPriorFactor<3>::CreateInterpolated(wp.position_m,
                                                                              wp.sigma_m, at.alpha),
                                   {at.a->p.data(), at.b->p.data()}));
  }
  return out;
}

void AddInsPathLossDiagnostics(const Walk& walk, const InsSharedBlocks& blocks,
                               std::map<std::string, double>* d) {
  if (!walk.has_rss() || !blocks.path_loss_set) return;
  (*d)["path_loss_estimated"] = blocks.estimate_path_loss ? 1.0 : 0.0;
  if (!blocks.estimate_path_loss) return;
  (*d)["path_loss_A"] = blocks.path_loss[0];
  (*d)["path_loss_eta"] = blocks.path_loss[1];
  for (const auto& [id, v] : blocks.anchor_path_loss) {
    (*d)["path_loss_A." + std::to_string(id)] = v[0];
    (*d)["path_loss_eta." + std::to_string(id)] = v[1];
  }
}

namespace {
constexpr char kInsBlockLetters[kInsBlocksPerState + 1] = "xvqga";
}  // namespace

Key InsKey(size_t state, InsBlock block) {
  return Symbol(kInsBlockLetters[static_cast<int>(block)], state);
}

std::optional<InsBlock> InsBlockOfLetter(char letter) {
  for (int b = 0; b < kInsBlocksPerState; ++b) {
    if (letter == kInsBlockLetters[b]) return static_cast<InsBlock>(b);
  }
  return std::nullopt;
}

int InsBlockSize(InsBlock block) { return block == InsBlock::kQ ? 4 : 3; }

double* InsBlockData(InsState* s, InsBlock block) {
  switch (block) {
    case InsBlock::kP:
      return s->p.data();
    case InsBlock::kV:
      return s->v.data();
    case InsBlock::kQ:
      return s->q.data();
    case InsBlock::kBg:
      return s->bg.data();
    case InsBlock::kBa:
      break;
  }
  return s->ba.data();
}

std::vector<GraphState> InsStateBlocks(size_t i, const InsState& values,
                                       const std::shared_ptr<const ceres::Manifold>& q_manifold) {
  InsState copy = values;
  std::vector<GraphState> out;
  for (int b = 0; b < kInsBlocksPerState; ++b) {
    const InsBlock block = static_cast<InsBlock>(b);
    GraphState st;
    st.key = InsKey(i, block);
    st.t_s = values.t_s;
    const double* data = InsBlockData(&copy, block);
    st.value.assign(data, data + InsBlockSize(block));
    if (block == InsBlock::kQ) st.manifold = q_manifold;
    out.push_back(std::move(st));
  }
  return out;
}

Key InsStateKey(size_t state, char letter) { return Symbol(letter, state); }

double* InsBlockOfKey(std::vector<InsState>* states, Key key) {
  const uint64_t i = SymbolIndex(key);
  const std::optional<InsBlock> block = InsBlockOfLetter(SymbolLetter(key));
  if (i >= states->size() || !block) return nullptr;
  return InsBlockData(&(*states)[i], *block);
}

void InsKeyMap::RegisterState(size_t i, InsState* state) {
  for (int b = 0; b < kInsBlocksPerState; ++b) {
    const InsBlock block = static_cast<InsBlock>(b);
    double* data = InsBlockData(state, block);
    if (mapped_.emplace(data, Mapped{InsKey(i, block), data, InsBlockSize(block)}).second) {
      order_.push_back(data);
    }
  }
}

StatusOr<GraphState> InsKeyMap::SharedState(const double* block) {
  GraphState st;
  InsSharedBlocks& sh = *shared_;
  auto anchor_key = [&](char letter, int id) -> StatusOr<Key> {
    const int ai = walk_.AnchorIndex(id);
    if (ai < 0) return InternalError("foot-INS graph: a walk-wide block of an unknown anchor");
    return Symbol(letter, static_cast<uint64_t>(ai));
  };
  if (block == sh.path_loss.data()) {
    st.key = Symbol(sh.per_anchor_path_loss ? 'm' : 'l', 0);
    st.value.assign(sh.path_loss.begin(), sh.path_loss.end());
    st.constant = !sh.estimate_path_loss;
    return st;
  }
  if (block == &sh.field_yaw_rad) {
    st.key = Symbol('f', 0);
    st.value = {sh.field_yaw_rad};
    return st;
  }
  for (auto& [id, bias] : sh.range_bias_m) {
    if (&bias != block) continue;
    WG_ASSIGN_OR_RETURN(st.key, anchor_key('b', id));
    st.value = {bias};
    st.constant = !options_.estimate_range_bias;
    return st;
  }
  for (auto& [id, pl] : sh.anchor_path_loss) {
    if (pl.data() != block) continue;
    WG_ASSIGN_OR_RETURN(st.key, anchor_key('l', id));
    st.value.assign(pl.begin(), pl.end());
    return st;
  }
  return InternalError("foot-INS graph: a factor on a block that is no state's");
}

StatusOr<GraphFactor> InsKeyMap::ToGraphFactor(InsFactor* f, std::vector<GraphState>* new_states) {
  GraphFactor out;
  for (double* block : f->blocks) {
    auto it = mapped_.find(block);
    if (it == mapped_.end()) {
      WG_ASSIGN_OR_RETURN(GraphState st, SharedState(block));
      it = mapped_.emplace(block, Mapped{st.key, block, static_cast<int>(st.value.size())}).first;
      order_.push_back(block);
      new_states->push_back(std::move(st));
    }
    out.keys.push_back(it->second.key);
  }
  out.cost = std::shared_ptr<ceres::CostFunction>(f->cost.release());
  out.loss = std::shared_ptr<const ceres::LossFunction>(f->loss.release());
  return out;
}

Status InsKeyMap::CopyValues(const std::function<StatusOr<std::vector<double>>(Key)>& value) const {
  for (const double* block : order_) {
    const Mapped& m = mapped_.at(block);
    WG_ASSIGN_OR_RETURN(std::vector<double> v, value(m.key));
    if (v.size() != static_cast<size_t>(m.size)) {
      return InternalError("foot-INS graph: " + KeyToString(m.key) + " has another size");
    }
    std::copy(v.begin(), v.end(), m.block);
  }
  return Status::Ok();
}

StatusOr<std::vector<std::vector<GraphFactor>>> InsUserFactors(const InsGraphContext& c,
                                                               std::vector<InsState>* states) {
  std::vector<double> times;
  for (const InsState& s : *states) times.push_back(s.t_s);
  WG_ASSIGN_OR_RETURN(std::vector<GraphFactor> factors,
                      internal::CallUserFactors(c.options.user_factors, *c.walk, times));
  std::vector<std::vector<GraphFactor>> out(states->size());
  for (size_t i = 0; i < factors.size(); ++i) {
    const std::string where = "user factor " + std::to_string(i) + ": ";
    const std::vector<int32_t>& sizes = factors[i].cost->parameter_block_sizes();
    uint64_t newest = 0;
    for (size_t b = 0; b < factors[i].keys.size(); ++b) {
      const Key key = factors[i].keys[b];
      if (InsBlockOfKey(states, key) == nullptr) {
        return InvalidArgument(where + "key " + KeyToString(key) + " names no state block");
      }
      const int size = SymbolLetter(key) == 'q' ? 4 : 3;
      if (sizes[b] != size) {
        return InvalidArgument(where + "block " + KeyToString(key) + " has size " +
                               std::to_string(size) + ", the cost function expects " +
                               std::to_string(sizes[b]));
      }
      newest = std::max(newest, SymbolIndex(key));
    }
    out[newest].push_back(std::move(factors[i]));
  }
  return out;
}

Trajectory InsStatesTrajectory(const Walk& walk, const std::vector<InsState>& states,
                               const std::vector<std::optional<Eigen::Matrix3d>>& cov,
                               const InsGraphOptions& o, bool close_segments) {
  Trajectory out;
  if (states.empty()) return out;
  const std::vector<ImuSample>& imu = walk.imu;
  StrapdownOptions sd;
  sd.gravity_mps2 = o.front_end.gravity_mps2;
  sd.sampling = o.front_end.sampling;
  sd.max_dt_s = ImuGapThresholdS(imu);  // held across IMU gaps: the output interpolates there
  const double period = 1.0 / o.output_rate_hz;
  double next_tick = imu[states.front().imu_index].t_s;
  auto emit = [&](double t, const Eigen::Vector3d& p, double yaw,
                  const std::optional<Eigen::Matrix3d>& c) {
    TrajectoryPoint pt;
    pt.t_s = t;
    pt.position_m = p;
    pt.heading_rad = NormalizeAngle(yaw);
    pt.covariance = c;
    out.points.push_back(pt);
  };
  emit(states[0].t_s, states[0].position(), Yaw(states[0].attitude()), cov[0]);
  next_tick += period;
  for (size_t s = 0; s + 1 < states.size(); ++s) {
    const InsState& a = states[s];
    const InsState& b = states[s + 1];
    sd.gyro_bias_radps = a.gyro_bias();
    sd.acc_bias_mps2 = a.acc_bias();
    std::vector<NavState> fwd;
    NavState x = ToNavState(a);
    for (size_t k = a.imu_index + 1; k <= b.imu_index; ++k) {
      x = StrapdownStep(x, imu[k - 1], imu[k], sd);
      if (k < b.imu_index && imu[k].t_s + 1e-9 >= next_tick) {
        fwd.push_back(x);
        while (next_tick <= imu[k].t_s + 1e-9) next_tick += period;
      }
    }
    const double w = close_segments ? 1.0 : 0.0;
    const Eigen::Vector3d dp = w * (b.position() - x.p_n);
    const double dyaw = w * NormalizeAngle(Yaw(b.attitude()) - Yaw(x.q_nb));
    const double span = b.t_s - a.t_s;
    for (const NavState& f : fwd) {
      const double alpha = (f.t_s - a.t_s) / span;
      std::optional<Eigen::Matrix3d> c;
      if (!close_segments) {
        c = cov[s];
      } else if (cov[s] && cov[s + 1]) {
        c = Eigen::Matrix3d((1.0 - alpha) * *cov[s] + alpha * *cov[s + 1]);
      }
      emit(f.t_s, f.p_n + alpha * dp, Yaw(f.q_nb) + alpha * dyaw, c);
    }
    emit(b.t_s, b.position(), Yaw(b.attitude()), cov[s + 1]);
    while (next_tick <= b.t_s + 1e-9) next_tick += period;
  }
  return out;
}

Status InsGraphBatch::CheckApplicable(const Walk& walk) const {
  if (walk.meta.imu_placement != ImuPlacement::kFoot) {
    return FailedPrecondition("fg-ins-batch needs a foot-mounted IMU (imu_placement: foot)");
  }
  if (walk.imu.size() < 10) return FailedPrecondition("fg-ins-batch needs imu.csv");
  return Status::Ok();
}

namespace {

// One build of the batch graph: the states (valued as they are now) with the walk's factors in
// the order the factor makers give them (segment, radio, stance magnetic, then the user's), the
// walk-wide blocks as static states in the order first named; and each RSS factor's anchor id
// and index in the graph (for TestInsAnchors).
struct InsBatchGraph {
  std::unique_ptr<FactorGraph> graph;
  std::unique_ptr<InsKeyMap> keys;
  size_t num_radio = 0, num_magnetic = 0;
  std::vector<std::pair<int, size_t>> rss;
};

StatusOr<InsBatchGraph> BuildInsBatch(const InsGraphContext& context, std::vector<InsState>* states,
                                      InsSharedBlocks* radio,
                                      const std::vector<std::vector<GraphFactor>>& user) {
  InsBatchGraph out;
  const size_t last = states->size() - 1;
  WG_ASSIGN_OR_RETURN(std::vector<InsFactor> factors, InsSegmentFactors(context, states, 0, last));
  radio->bias_prior_added.clear();  // a new graph: priors again, bias values kept
  radio->path_loss_prior_added = false;
  radio->anchor_path_loss_prior_added.clear();
  WG_ASSIGN_OR_RETURN(std::vector<InsFactor> radio_factors,
                      InsRadioFactors(context, states, 0, last, radio));
  std::vector<InsFactor> magnetic = InsStanceMagneticFactors(context, states, 0, last, radio);
  out.num_radio = radio_factors.size();
  out.num_magnetic = magnetic.size();
  for (InsFactor& f : radio_factors) factors.push_back(std::move(f));
  for (InsFactor& f : magnetic) factors.push_back(std::move(f));

  out.keys = std::make_unique<InsKeyMap>(*context.walk, context.options, radio);
  for (size_t i = 0; i < states->size(); ++i) out.keys->RegisterState(i, &(*states)[i]);
  std::vector<GraphState> shared;
  std::vector<GraphFactor> graph_factors;
  for (InsFactor& f : factors) {
    if (f.kind == InsFactorKind::kRss) out.rss.emplace_back(f.anchor_id, graph_factors.size());
    WG_ASSIGN_OR_RETURN(GraphFactor g, out.keys->ToGraphFactor(&f, &shared));
    graph_factors.push_back(std::move(g));
  }
  out.graph = std::make_unique<FactorGraph>();
  const auto manifold = std::make_shared<NavQuaternionManifold>();
  for (size_t i = 0; i < states->size(); ++i) {
    for (GraphState& st : InsStateBlocks(i, (*states)[i], manifold)) {
      WG_RETURN_IF_ERROR(out.graph->AddState(std::move(st)));
    }
  }
  for (GraphState& st : shared) WG_RETURN_IF_ERROR(out.graph->AddState(std::move(st)));
  for (GraphFactor& f : graph_factors) WG_RETURN_IF_ERROR(out.graph->AddFactor(std::move(f)));
  for (const auto& at : user) {
    for (const GraphFactor& f : at) WG_RETURN_IF_ERROR(out.graph->AddFactor(f));
  }
  return out;
}

// One batch solve of the foot-INS graph, relinearized while the biases move
// (max_relinearizations): each round builds the graph again at the new biases (the
// preintegrations are made at their first state's), and its figures.
struct InsBatchSolve {
  InsBatchGraph built;
  int iterations = 0, relinearizations = 0;
  double initial_cost = 0.0, final_cost = 0.0;
  bool converged = false;
};

// The largest change of a gyro and of an accelerometer bias from `before`.
std::pair<double, double> BiasChange(const std::vector<InsState>& before,
                                     const std::vector<InsState>& after) {
  double dg = 0.0, da = 0.0;
  for (size_t i = 0; i < after.size(); ++i) {
    for (int k = 0; k < 3; ++k) {
      dg = std::max(dg, std::fabs(after[i].bg[k] - before[i].bg[k]));
      da = std::max(da, std::fabs(after[i].ba[k] - before[i].ba[k]));
    }
  }
  return {dg, da};
}

StatusOr<InsBatchSolve> SolveInsBatch(const InsGraphContext& context, std::vector<InsState>* states,
                                      InsSharedBlocks* radio,
                                      const std::vector<std::vector<GraphFactor>>& user,
                                      const SolverOptions& solver) {
  const InsGraphOptions& o = context.options;
  InsBatchSolve out;
  for (int round = 0; round <= o.max_relinearizations; ++round) {
    WG_ASSIGN_OR_RETURN(out.built, BuildInsBatch(context, states, radio, user));
    const std::vector<InsState> linearization = *states;
    FactorGraph* graph = out.built.graph.get();
    StatusOr<SolveSummary> summary = SolveBatch(graph, solver);
    if (!summary.ok()) {
      return Status(summary.status().code(), "fg-ins-batch: " + summary.status().message());
    }
    WG_RETURN_IF_ERROR(out.built.keys->CopyValues([graph](Key k) { return graph->Value(k); }));
    if (round == 0) out.initial_cost = summary->initial_cost;
    out.final_cost = summary->final_cost;
    out.iterations += summary->iterations;
    out.converged = summary->termination == Termination::kConverged;
    const auto [dg, da] = BiasChange(linearization, *states);
    if (dg <= o.relinearize_gyro_bias_radps && da <= o.relinearize_acc_bias_mps2) break;
    if (round < o.max_relinearizations) ++out.relinearizations;
  }
  return out;
}

// (x, y, yaw) covariance of every state (graph.h MarginalCovariances: the banded chain solve)
// in the tangent space of NavQuaternionManifold, δθ_z the yaw. False (and `out` untouched) when
// it cannot be computed (rank deficiency).
bool InsPoseCovariances(FactorGraph* graph, size_t num_states,
                        std::vector<std::optional<Eigen::Matrix3d>>* out) {
  std::vector<std::vector<Key>> groups;
  groups.reserve(num_states);
  for (size_t i = 0; i < num_states; ++i) {
    groups.push_back({InsKey(i, InsBlock::kP), InsKey(i, InsBlock::kQ)});
  }
  StatusOr<std::vector<Eigen::MatrixXd>> cov = MarginalCovariances(graph, groups);
  if (!cov.ok()) return false;
  std::vector<std::optional<Eigen::Matrix3d>> pose(num_states);
  for (size_t i = 0; i < num_states; ++i) {
    const Eigen::MatrixXd& c = (*cov)[i];
    if (c.rows() != 6) return false;  // p or q held constant: no pose covariance
    const int index[3] = {0, 1, 5};   // x, y of p; δθ_z of q (the yaw)
    Eigen::MatrixXd c3(3, 3);
    for (int r = 0; r < 3; ++r) {
      for (int k = 0; k < 3; ++k) c3(r, k) = c(index[r], index[k]);
    }
    Symmetrize(&c3);
    pose[i] = Eigen::Matrix3d(c3);
  }
  *out = std::move(pose);
  return true;
}

// auto's choice after a global solve (InsGraphOptions::path_loss): do the anchors' mean
// residuals disagree with the one path loss?
std::optional<internal::AnchorOffsetTest> TestInsAnchors(const InsGraphOptions& o,
                                                         const InsSharedBlocks& radio,
                                                         const InsBatchGraph& built) {
  if (o.path_loss != PathLossMode::kAuto || !radio.estimate_path_loss ||
      radio.per_anchor_path_loss || !(o.path_loss_anchor_test_z > 0) || built.rss.empty()) {
    return std::nullopt;
  }
  std::vector<std::pair<int, double>> residuals;
  for (const auto& [anchor, index] : built.rss) {
    StatusOr<Eigen::VectorXd> r = built.graph->FactorResiduals(index);
    if (r.ok()) residuals.emplace_back(anchor, (*r)[0]);
  }
  return internal::TestAnchorOffsets(residuals, o.path_loss_anchor_test_z);
}

}  // namespace

StatusOr<EstimateResult> InsGraphBatch::Run(const Walk& walk) const {
  WG_RETURN_IF_ERROR(CheckApplicable(walk));
  const InsGraphOptions& o = options_;
  WG_ASSIGN_OR_RETURN(ZuptInsSolution front, RunZuptIns(walk, o.front_end));
  WG_ASSIGN_OR_RETURN(std::vector<InsState> states, InitialInsStates(walk, front, o));
  if (o.initialization == InsInitialization::kWindow) {
    InsWindowOptions wo;
    wo.graph = o;
    wo.graph.compute_covariance = false;
    wo.lag_s = o.init_lag_s;
    wo.window_marginalize_batch_s = o.init_marginalize_batch_s;
    wo.window_initial_trust_region_radius = o.initial_trust_region_radius;
    WG_ASSIGN_OR_RETURN(std::vector<InsState> lagged, InsWindowLaggedStates(walk, wo));
    if (lagged.size() != states.size()) {
      return InternalError("fg-ins-batch: window initialization returned a different state count");
    }
    states = std::move(lagged);
  }
  InsGraphContext context;
  context.walk = &walk;
  context.imu_gap_s = ImuGapThresholdS(walk.imu);
  context.still = &front.stance.still;
  context.scale_noise = &front.scale_noise;
  context.path = &front.states;
  context.options = o;
  const std::vector<double> magnetic_sigma = StanceMagneticSigmas(walk, front, o);
  context.stance_magnetic_sigma = &magnetic_sigma;
  WG_ASSIGN_OR_RETURN(const std::vector<std::vector<GraphFactor>> user,
                      InsUserFactors(context, &states));

  SolverOptions so;  // single-threaded SPARSE_NORMAL_CHOLESKY: the same output for the same input
  so.max_iterations = o.max_iterations;
  so.function_tolerance = o.function_tolerance;
  so.parameter_tolerance = o.parameter_tolerance;
  so.gradient_tolerance = o.gradient_tolerance;
  so.initial_trust_region_radius = o.initial_trust_region_radius;
  WG_RETURN_IF_ERROR(so.Validate());

  InsSharedBlocks radio;
  WG_ASSIGN_OR_RETURN(InsBatchSolve solve, SolveInsBatch(context, &states, &radio, user, so));
  const std::optional<internal::AnchorOffsetTest> test = TestInsAnchors(o, radio, solve.built);
  if (test && test->disagree) {  // per anchor, from the global solution
    context.options.path_loss = PathLossMode::kHierarchical;
    const int iterations = solve.iterations;
    WG_ASSIGN_OR_RETURN(solve, SolveInsBatch(context, &states, &radio, user, so));
    solve.iterations += iterations;
  }

  EstimateResult result;
  std::vector<std::optional<Eigen::Matrix3d>> state_cov(states.size());
  bool cov_ok = false;
  if (o.compute_covariance) {
    cov_ok = InsPoseCovariances(solve.built.graph.get(), states.size(), &state_cov);
  }
  result.trajectory = InsStatesTrajectory(walk, states, state_cov, o, /*close_segments=*/true);
  auto& d = result.diagnostics;
  d["num_states"] = static_cast<double>(states.size());
  AddFrontEndDiagnostics(front, &d);
  d["num_radio_factors"] = static_cast<double>(solve.built.num_radio);
  AddStanceMagneticDiagnostics(magnetic_sigma, solve.built.num_magnetic, &d);
  AddInsPathLossDiagnostics(walk, radio, &d);
  if (test) {
    d["path_loss_anchor_chi2"] = test->statistic;
    d["path_loss_anchor_chi2_critical"] = test->critical;
    d["path_loss_per_anchor"] = test->disagree ? 1.0 : 0.0;
  }
  d["ceres_iterations"] = solve.iterations;
  d["ceres_initial_cost"] = solve.initial_cost;
  d["ceres_final_cost"] = solve.final_cost;
  d["ceres_converged"] = solve.converged ? 1.0 : 0.0;
  d["relinearizations"] = solve.relinearizations;
  d["covariance_ok"] = cov_ok ? 1.0 : 0.0;
  return result;
}

namespace internal {

Status RegisterInsGraphBatch(EstimatorRegistry* registry) {
  return registry->Register(
      {"fg-ins-batch",
       "foot-INS factor graph: Forster preintegration between stance states, ZUPT, ZARU, bias "
       "random walks; one Ceres problem (foot IMU)",
       OptionsFactory<InsGraphBatch>(
           [](const YAML::Node& config) { return InsGraphOptionsFromYaml(config); })});
}

}  // namespace internal
}  // namespace walkgraph
