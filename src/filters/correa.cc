#include "walkgraph/filters/correa.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <sstream>

#include "estimators/builtin.h"
#include "walkgraph/angle.h"
#include "walkgraph/config.h"
#include "walkgraph/filters/kalman.h"

namespace walkgraph {

StatusOr<CorreaEkfOptions> CorreaEkfOptions::FromYaml(const YAML::Node& node,
                                                      const std::string& context) {
  CorreaEkfOptions o;
  ConfigReader r(node, context);
  r.Read("scmt", &o.scmt);
  r.Read("p_fa", &o.p_fa);
  r.Read("d_max_m", &o.d_max_m);
  r.Read("epsilon_m2", &o.epsilon_m2);
  r.Read("sigma_p_m", &o.sigma_p_m);
  r.Read("sigma_v_mps", &o.sigma_v_mps);
  r.Read("sigma_theta_rad", &o.sigma_theta_rad);
  r.Read("step_length_m", &o.step_length_m);
  r.Read("q_position_m", &o.q_position_m);
  r.Read("q_speed_mps", &o.q_speed_mps);
  r.Read("q_heading_rad", &o.q_heading_rad);
  r.Read("gate_probability", &o.gate_probability);
  r.Read("smooth", &o.smooth);
  WG_RETURN_IF_ERROR(r.Finish());
  if (!(o.p_fa > 0 && o.p_fa < 1)) return InvalidArgument(context + ": p_fa must be in (0, 1)");
  if (o.d_max_m < 0 || !(o.epsilon_m2 > 0) || !(o.sigma_p_m > 0) || !(o.sigma_v_mps > 0) ||
      !(o.sigma_theta_rad > 0) || !(o.q_position_m > 0) || !(o.q_speed_mps > 0) ||
      !(o.q_heading_rad > 0)) {
    return InvalidArgument(context + ": sigmas, epsilon and q must be > 0, d_max_m >= 0");
  }
  if (o.gate_probability < 0 || o.gate_probability >= 1) {
    return InvalidArgument(context + ": gate_probability must be in [0, 1)");
  }
  return o;
}

double CorreaFalseAlarmProbability(const PathLossModel& model, double p_th, double d_max_m) {
  // eq. 19, uniform d on (1, d_max]; composite Simpson's rule in x.
  const int n = 2000;
  const double a = 1.0, b = d_max_m, h = (b - a) / n;
  const double s = model.sign(), sigma = model.params().sigma_db;
  auto f = [&](double x) {
    const double z = s * (p_th - model.ExpectedRss(x)) / sigma;
    return 0.5 * std::erfc(z / std::sqrt(2.0));
  };
  double sum = f(a) + f(b);
  for (int i = 1; i < n; ++i) sum += (i % 2 ? 4.0 : 2.0) * f(a + i * h);
  return sum * h / 3.0 / (b - a);
}

StatusOr<double> CorreaPowerThreshold(const PathLossModel& model, double p_fa, double d_max_m) {
  if (!(d_max_m > 1.0)) return InvalidArgument("correa: d_max must exceed 1 m (eq. 19)");
  if (!(model.params().sigma_db > 0)) return InvalidArgument("correa: sigma_db must be > 0");
  // s·P_Th between the far-end mean − 10σ and the 1 m mean + 10σ brackets every p_fa.
  const double s = model.sign(), sigma = model.params().sigma_db;
  double lo = s * model.ExpectedRss(d_max_m) - 10 * sigma,
         hi = s * model.ExpectedRss(1.0) + 10 * sigma;
  for (int i = 0; i < 200; ++i) {
    const double mid = 0.5 * (lo + hi);
    (CorreaFalseAlarmProbability(model, s * mid, d_max_m) > p_fa ? lo : hi) = mid;
  }
  return s * 0.5 * (lo + hi);
}

Eigen::Vector4d CorreaPredict(const Eigen::Vector4d& x, double T, Eigen::Matrix4d* M) {
  const double c = std::cos(x[3]), sn = std::sin(x[3]);
  if (M != nullptr) {
    *M = Eigen::Matrix4d::Identity();  // Jacobian of F(θ)x (eq. 9)
    (*M)(0, 2) = T * c;
    (*M)(1, 2) = T * sn;
    (*M)(0, 3) = -T * x[2] * sn;
    (*M)(1, 3) = T * x[2] * c;
  }
  return Eigen::Vector4d(x[0] + T * c * x[2], x[1] + T * sn * x[2], x[2], x[3]);  // eq. 3, 8
}

namespace {

// P_Th of the SCMT detector (eq. 18–19) with d_max from the options or the anchors' extent;
// +∞ (never near an anchor) without SCMT.
StatusOr<double> ScmtThreshold(const CorreaInputs& in, const CorreaEkfOptions& o) {
  if (!o.scmt) return std::numeric_limits<double>::infinity();
  double d_max = o.d_max_m;
  if (d_max <= 0) {
    if (in.anchor_xy.size() < 2) return FailedPrecondition("correa: d_max needs 2 anchors");
    Eigen::Vector2d mn = in.anchor_xy.front(), mx = mn;
    for (const Eigen::Vector2d& a : in.anchor_xy) {
      mn = mn.cwiseMin(a);
      mx = mx.cwiseMax(a);
    }
    d_max = (mx - mn).norm();
  }
  return CorreaPowerThreshold(in.model, o.p_fa, d_max);
}

// (x, y, θ) and its covariance of each state (filtered or smoothed).
void AppendTrajectory(const std::vector<SmoothedState>& states, Trajectory* trajectory) {
  for (const SmoothedState& st : states) {
    TrajectoryPoint pt;
    pt.t_s = st.t_s;
    pt.position_m = Eigen::Vector3d(st.x[0], st.x[1], 0.0);
    pt.heading_rad = st.x[3];
    Eigen::Matrix3d C;
    const int idx[3] = {0, 1, 3};
    for (int i = 0; i < 3; ++i) {
      for (int j = 0; j < 3; ++j) C(i, j) = st.P(idx[i], idx[j]);
    }
    pt.covariance = C;
    trajectory->points.push_back(pt);
  }
}

}  // namespace

StatusOr<EstimateResult> RunCorreaEkf(const CorreaInputs& in, const CorreaEkfOptions& o) {
  using Vec4 = Eigen::Matrix<double, 4, 1>;
  using Mat4 = Eigen::Matrix<double, 4, 4>;
  if (in.fixes.empty()) return FailedPrecondition("correa: no LS position fixes");
  WG_ASSIGN_OR_RETURN(const double p_th, ScmtThreshold(in, o));
  const double s = in.model.sign();
  EstimateResult result;
  result.diagnostics["p_th"] = o.scmt ? p_th : 0.0;
  std::vector<FilterEpoch> epochs;
  const std::vector<Step>& steps = in.steps.steps;
  size_t si = 0, ri = 0;
  Eigen::VectorXd x;
  Eigen::MatrixXd P;
  double t_prev = 0.0;
  int scmt_epochs = 0;
  for (size_t k = 0; k < in.fixes.size(); ++k) {
    const PositionFix& fix = in.fixes[k];
    const double t = fix.t_s;
    // Speed (eq. 6) and heading (eq. 7) measurements of the steps in (t_prev, t].
    int n_steps = 0;
    double length_sum = 0.0, heading = 0.0;
    for (; si < steps.size() && steps[si].t_s <= t; ++si) {
      if (k == 0) continue;
      ++n_steps;
      length_sum += steps[si].length_m;
      heading = steps[si].heading_rad;
    }
    // Strongest reading of the epoch (SCMT detector).
    double p_max = -std::numeric_limits<double>::infinity();
    Eigen::Vector2d strongest = Eigen::Vector2d::Zero();
    for (; ri < in.rss.size() && in.rss[ri].t_s <= t; ++ri) {
      const RangeMeasurement& m = in.rss[ri];
      if (!m.from_rss || (k > 0 && m.t_s <= t_prev)) continue;
      if (s * m.rss > p_max) {
        p_max = s * m.rss;
        strongest = m.anchor_m.head<2>();
      }
    }
    const bool near_anchor = o.scmt && p_max >= s * p_th;
    const Eigen::Vector2d z_pos = near_anchor ? strongest : fix.position_m;
    const double r_pos = near_anchor ? o.epsilon_m2 : o.sigma_p_m * o.sigma_p_m;  // eq. 21
    scmt_epochs += near_anchor;
    FilterEpoch e;
    e.t_s = t;
    if (k == 0) {
      x = Vec4(z_pos.x(), z_pos.y(), 0.0, 0.0);
      P = Vec4(r_pos, r_pos, 1.0, M_PI * M_PI).asDiagonal();
      e.x_prior = e.x_post = x;
      e.P_prior = e.P_post = P;
      epochs.push_back(e);
      t_prev = t;
      continue;
    }
    const double T = t - t_prev;
    Mat4 M;
    x = CorreaPredict(Vec4(x), T, &M);
    const Vec4 q(o.q_position_m, o.q_position_m, o.q_speed_mps, o.q_heading_rad);
    P = M * P * M.transpose() + Eigen::MatrixXd(q.cwiseAbs2().asDiagonal());  // eq. 9
    Symmetrize(&P);
    e.F = M;
    e.x_prior = x;
    e.P_prior = P;
    // z = [x̂ ŷ V̂ θ̂] (eq. 4); without a step in the epoch V̂ = 0 and θ̂ is absent.
    const bool has_heading = n_steps > 0;
    const int m = has_heading ? 4 : 3;
    const double v_hat =
        (o.step_length_m > 0 ? n_steps * o.step_length_m : length_sum) / T;  // eq. 6
    Eigen::VectorXd nu(m);
    nu[0] = z_pos.x() - x[0];
    nu[1] = z_pos.y() - x[1];
    nu[2] = v_hat - x[2];
    Eigen::VectorXd r_diag(m);
    r_diag[0] = r_diag[1] = r_pos;
    r_diag[2] = o.sigma_v_mps * o.sigma_v_mps;
    if (has_heading) {
      nu[3] = NormalizeAngle(heading - x[3]);
      r_diag[3] = o.sigma_theta_rad * o.sigma_theta_rad;
    }
    const Eigen::MatrixXd H = Eigen::MatrixXd::Identity(m, 4);
    WG_ASSIGN_OR_RETURN(
        UpdateOutcome out,  // eq. 10–12
        KalmanUpdate(nu, H, Eigen::MatrixXd(r_diag.asDiagonal()), o.gate_probability, &x, &P));
    x[3] = NormalizeAngle(x[3]);
    RecordOutcome(out, &result.nis, &result.diagnostics);
    e.x_post = x;
    e.P_post = P;
    epochs.push_back(e);
    t_prev = t;
  }
  result.diagnostics["scmt_epochs"] = scmt_epochs;

  std::vector<SmoothedState> states;
  if (o.smooth) {
    WG_ASSIGN_OR_RETURN(states, RtsSmooth(epochs, {3}));
  } else {
    for (const FilterEpoch& e : epochs) states.push_back({e.t_s, e.x_post, e.P_post});
  }
  AppendTrajectory(states, &result.trajectory);
  return result;
}

// ------------------------------------------------------------------ estimators on a Walk

CorreaEstimatorOptions CorreaEstimatorOptions::PaperDefaults() {
  CorreaEstimatorOptions o;
  o.pdr.detector = StepDetector::kFirMagnitude;      // eq. 6: FIR order 20, 3 Hz, maxima
  o.pdr.length_model = StepLengthModel::kConstant;   // eq. 6: constant l_step per user
  o.pdr.constant_length_m = o.filter.step_length_m;  // (the filter's l_step is used for V̂)
  o.pdr.heading = HeadingMethod::kComplementary;     // eq. 7
  o.radio.epochs.window_s = 1.0;                     // motes beacon at 1 Hz (Sec. IV)
  o.radio.epochs.bias_corrected = false;             // ML range (eq. 14)
  o.radio.method = PositioningMethod::kNonlinearLs;  // eq. 5
  o.radio.weighted = false;                          // eq. 5: unweighted squared range errors
  // Gauss–Newton to 1 mm in up to 100 iterations: near an anchor the cost is not smooth and
  // the front end's defaults (1e-6 m, 20) leave ~40 % of the classroom epochs without a fix.
  o.radio.positioning.tolerance_m = 1e-3;
  o.radio.positioning.max_iterations = 100;
  return o;
}

StatusOr<CorreaEstimatorOptions> CorreaEstimatorOptions::FromYaml(const YAML::Node& node,
                                                                  CorreaVariant variant,
                                                                  bool smooth,
                                                                  const std::string& id) {
  CorreaEstimatorOptions o = PaperDefaults();
  WG_ASSIGN_OR_RETURN(const YAML::Node own, WithoutKeys(node, {"pdr", "radio"}, id));
  for (const char* key : {"scmt", "smooth"}) {
    if (own[key]) {
      return InvalidArgument(id + ": option '" + key +
                             "' is chosen by the estimator id (correa-ekf, correa-scmt-ekf, "
                             "-rts), not by the config");
    }
  }
  ConfigReader r(node, id);
  const YAML::Node radio = r.Child("radio");
  YAML::Node pdr;
  if (variant != CorreaVariant::kLs) {
    WG_ASSIGN_OR_RETURN(o.filter, CorreaEkfOptions::FromYaml(own, id));
    pdr = r.Child("pdr");
    for (const auto& kv : own) r.Child(kv.first.Scalar());
  }
  WG_RETURN_IF_ERROR(r.Finish());  // correa-ls: only radio
  o.filter.scmt = variant == CorreaVariant::kScmtEkf;
  o.filter.smooth = smooth;
  WG_ASSIGN_OR_RETURN(o.radio, RadioFrontEndOptions::FromYaml(radio, o.radio, id));
  std::map<std::string, std::string> pdr_defaults = {
      {"detector", "fir-magnitude"}, {"length_model", "constant"}, {"heading", "complementary"}};
  if (o.filter.step_length_m > 0) {
    std::ostringstream length;
    length.precision(17);
    length << o.filter.step_length_m;
    pdr_defaults["constant_length_m"] = length.str();
  }
  WG_ASSIGN_OR_RETURN(o.pdr, PdrOptionsFromYaml(pdr, pdr_defaults, id + " pdr"));
  return o;
}

Status CorreaEstimator::CheckApplicable(const Walk& walk) const {
  if (variant_ != CorreaVariant::kLs) {
    WG_RETURN_IF_ERROR(CheckStepInput(walk, options_.pdr, true, id_));
  }
  WG_RETURN_IF_ERROR(CheckRadioInput(walk, 3, id_));
  if (variant_ == CorreaVariant::kScmtEkf) {
    if (!walk.has_rss()) {
      return FailedPrecondition(id_ +
                                " needs RSS readings (rss.csv): SCMT compares the strongest "
                                "RSS of each epoch with P_Th (001 eq. 21)");
    }
    if (walk.meta.radio.units != RssUnits::kDbm) {
      return FailedPrecondition(id_ + " needs RSS in dBm (P_Th of 001 eq. 19)");
    }
  }
  return Status::Ok();
}

StatusOr<EstimateResult> CorreaEstimator::Run(const Walk& walk) const {
  WG_RETURN_IF_ERROR(CheckApplicable(walk));
  WG_ASSIGN_OR_RETURN(FixesFromFrontEnd fixes,
                      PositionFixesFromFrontEnd(walk, options_.radio, id_));
  if (variant_ == CorreaVariant::kLs) {
    EstimateResult result;
    result.trajectory = TrajectoryOfFixes(fixes.fixes);
    result.diagnostics["radio_epochs"] = fixes.epochs;
    result.diagnostics["radio_epochs_without_fix"] = fixes.failed_epochs;
    return result;
  }
  CorreaInputs in;
  in.fixes = std::move(fixes.fixes);
  WG_ASSIGN_OR_RETURN(in.steps, StepsFromFrontEnd(walk, options_.pdr, true, id_));
  // P_max = max R over the epoch's readings (Sec. III): one reading per fix, at the fix time.
  if (variant_ == CorreaVariant::kScmtEkf) in.rss = std::move(fixes.strongest);
  in.model = PathLossModel(walk.meta.radio.path_loss, walk.meta.radio.units);
  for (const Anchor& a : walk.anchors) in.anchor_xy.push_back(a.position_m.head<2>());
  CorreaEkfOptions filter = options_.filter;
  // Odometry increments are not detected steps of one constant length: V̂ (eq. 6) then sums
  // their measured lengths.
  if (walk.has_odometry()) filter.step_length_m = 0.0;
  StatusOr<EstimateResult> result = RunCorreaEkf(in, filter);
  if (!result.ok()) return Status(result.status().code(), id_ + ": " + result.status().message());
  result->diagnostics["steps"] = static_cast<double>(in.steps.steps.size());
  result->diagnostics["radio_epochs"] = fixes.epochs;
  result->diagnostics["radio_epochs_without_fix"] = fixes.failed_epochs;
  return result;
}

namespace internal {

Status RegisterCorrea(EstimatorRegistry* registry) {
  struct Entry {
    const char* id;
    const char* description;
    CorreaVariant variant;
    bool smooth;
  };
  const Entry entries[] = {
      {"correa-ls", "001 eq. 5: nonlinear LS position of each 1 s RSS epoch (radio only)",
       CorreaVariant::kLs, false},
      {"correa-ekf", "001 eq. 1-12: EKF on [x y V theta], LS fix + step speed + compl. heading",
       CorreaVariant::kEkf, false},
      {"correa-scmt-ekf", "001 eq. 1-12, 18-21: EKF with R_pos = eps near an anchor (SCMT)",
       CorreaVariant::kScmtEkf, false},
      {"correa-ekf-rts", "001 EKF + RTS smoother over the 1 s epochs (offline)",
       CorreaVariant::kEkf, true},
      {"correa-scmt-ekf-rts", "001 SCMT-EKF + RTS smoother over the 1 s epochs (offline)",
       CorreaVariant::kScmtEkf, true},
  };
  for (const Entry& e : entries) {
    const std::string id = e.id;
    const CorreaVariant variant = e.variant;
    const bool smooth = e.smooth;
    auto parse = [id, variant, smooth](const YAML::Node& config) {
      return CorreaEstimatorOptions::FromYaml(config, variant, smooth, id);
    };
    WG_RETURN_IF_ERROR(registry->Register(
        {id, e.description, OptionsFactory<CorreaEstimator>(parse, id, variant)}));
  }
  return Status::Ok();
}

}  // namespace internal
}  // namespace walkgraph
