#include "walkgraph/filters/correa.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <sstream>

#include "config/parsers.h"
#include "estimators/builtin.h"
#include "walkgraph/angle.h"
#include "walkgraph/config.h"
#include "walkgraph/kalman.h"
#include "walkgraph/kalman_driver.h"

namespace walkgraph {

StatusOr<CorreaEkfOptions> CorreaEkfOptionsFromYaml(const YAML::Node& node,
                                                    const std::string& context) {
  CorreaEkfOptions o;
  ConfigReader r(node, context);
  r.Read("scmt", &o.scmt, "SCMT switch of 001 eq. 21 (correa-scmt-ekf)");
  r.Read("p_fa", &o.p_fa,
         "false-alarm probability that sets the power threshold P_Th (001 eq. 19)");
  r.Read("d_max_m", &o.d_max_m, "d_max of 001 eq. 19; 0: diagonal of the anchors' bounding box");
  r.Read("epsilon_m2", &o.epsilon_m2, "epsilon << 1 of 001 eq. 21");
  r.Read("sigma_p_m", &o.sigma_p_m, "sigma_p of the fix measurement (001 eq. 21)");
  r.Read("sigma_v_mps", &o.sigma_v_mps, "sigma of the PDR speed V^ measurement (001 eq. 21)");
  r.Read("sigma_theta_rad", &o.sigma_theta_rad,
         "sigma of the PDR heading theta^ measurement (001 eq. 21)");
  r.Read("step_length_m", &o.step_length_m,
         "l_step of 001 eq. 6; <= 0: the front end's step lengths");
  r.Read("q_position_m", &o.q_position_m, "process noise q_p of each position axis per epoch");
  r.Read("q_speed_mps", &o.q_speed_mps, "process noise q_V of the speed per epoch");
  r.Read("q_heading_rad", &o.q_heading_rad, "process noise q_theta of the heading per epoch");
  r.Read("gate_probability", &o.gate_probability,
         "chi-square(4) gate on the full innovation; 0 off");
  r.Read("smooth", &o.smooth, "RTS smoother after the filter (-rts ids)");
  WG_RETURN_IF_ERROR(r.Finish());
  WG_RETURN_IF_ERROR(o.Validate(context));
  return o;
}

Status CorreaEkfOptions::Validate(const std::string& context) const {
  const CorreaEkfOptions& o = *this;
  if (!(o.p_fa > 0 && o.p_fa < 1)) return InvalidArgument(context + ": p_fa must be in (0, 1)");
  if (o.d_max_m < 0 || !(o.epsilon_m2 > 0) || !(o.sigma_p_m > 0) || !(o.sigma_v_mps > 0) ||
      !(o.sigma_theta_rad > 0) || !(o.q_position_m > 0) || !(o.q_speed_mps > 0) ||
      !(o.q_heading_rad > 0)) {
    return InvalidArgument(context + ": sigmas, epsilon and q must be > 0, d_max_m >= 0");
  }
  if (o.gate_probability < 0 || o.gate_probability >= 1) {
    return InvalidArgument(context + ": gate_probability must be in [0, 1)");
  }
  return Status::Ok();
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

// The EKF of 001 on [x y V θ] (eq. 3–12, 21), one epoch per LS fix, as kalman_driver.h runs it.
class CorreaModel : public KalmanModel {
 public:
  CorreaModel(const CorreaInputs& in, const CorreaEkfOptions& o, double p_th)
      : in_(in), o_(o), p_th_(p_th), s_(in.model.sign()) {}

  int scmt_epochs() const { return scmt_epochs_; }

  // The first fix (or, near an anchor, the anchor) with the epoch's position noise.
  Status Initialize(double t, Eigen::VectorXd* x, Eigen::MatrixXd* P) override {
    const Epoch z = Gather(t, true);
    *x = Eigen::Vector4d(z.position.x(), z.position.y(), 0.0, 0.0);
    *P = Eigen::Vector4d(z.r_pos, z.r_pos, 1.0, M_PI * M_PI).asDiagonal();
    t_prev_ = t;
    return Status::Ok();
  }

  // eq. 3, 8 and the covariance of eq. 9.
  Status Predict(double t_prev, double t, Eigen::VectorXd* x, Eigen::MatrixXd* P,
                 Eigen::MatrixXd* F) override {
    t_prev_ = t_prev;
    const double T = t - t_prev;
    Eigen::Matrix4d M;
    *x = CorreaPredict(Eigen::Vector4d(*x), T, &M);
    const Eigen::Vector4d q(o_.q_position_m, o_.q_position_m, o_.q_speed_mps, o_.q_heading_rad);
    *P = M * (*P) * M.transpose() + Eigen::MatrixXd(q.cwiseAbs2().asDiagonal());  // eq. 9
    Symmetrize(P);
    *F = M;
    return Status::Ok();
  }

  // z = [x̂ ŷ V̂ θ̂] (eq. 4); without a step in the epoch V̂ = 0 and θ̂ is absent (eq. 10–12).
  Status Update(size_t k, double t, KalmanRun* run) override {
    if (k == 0) return Status::Ok();  // the first fix started the state
    const Epoch z = Gather(t, false);
    const double T = t - t_prev_;
    const bool has_heading = z.n_steps > 0;
    const int m = has_heading ? 4 : 3;
    const double v_hat =
        (o_.step_length_m > 0 ? z.n_steps * o_.step_length_m : z.length_sum) / T;  // eq. 6
    const Eigen::VectorXd& x = run->x;
    Eigen::VectorXd nu(m);
    nu[0] = z.position.x() - x[0];
    nu[1] = z.position.y() - x[1];
    nu[2] = v_hat - x[2];
    Eigen::VectorXd r_diag(m);
    r_diag[0] = r_diag[1] = z.r_pos;
    r_diag[2] = o_.sigma_v_mps * o_.sigma_v_mps;
    if (has_heading) {
      nu[3] = NormalizeAngle(z.heading - x[3]);
      r_diag[3] = o_.sigma_theta_rad * o_.sigma_theta_rad;
    }
    const Eigen::MatrixXd H = Eigen::MatrixXd::Identity(m, 4);
    return run->Update(nu, H, Eigen::MatrixXd(r_diag.asDiagonal()), o_.gate_probability).status();
  }

  // (x, y, θ) and its covariance.
  TrajectoryPoint Output(size_t, const SmoothedState& st) const override {
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
    return pt;
  }

 private:
  // One epoch's measurements: the steps and the strongest reading since the last fix.
  struct Epoch {
    int n_steps = 0;
    double length_sum = 0.0, heading = 0.0;
    Eigen::Vector2d position;  // the fix, or the strongest anchor near one (SCMT)
    double r_pos = 0.0;        // eq. 21
  };

  Epoch Gather(double t, bool first) {
    Epoch z;
    // Speed (eq. 6) and heading (eq. 7) measurements of the steps in (t_prev, t].
    const std::vector<Step>& steps = in_.steps.steps;
    for (; si_ < steps.size() && steps[si_].t_s <= t; ++si_) {
      if (first) continue;
      ++z.n_steps;
      z.length_sum += steps[si_].length_m;
      z.heading = steps[si_].heading_rad;
    }
    // Strongest reading of the epoch (SCMT detector).
    double p_max = -std::numeric_limits<double>::infinity();
    Eigen::Vector2d strongest = Eigen::Vector2d::Zero();
    for (; ri_ < in_.rss.size() && in_.rss[ri_].t_s <= t; ++ri_) {
      const RangeMeasurement& m = in_.rss[ri_];
      if (!m.from_rss || (!first && m.t_s <= t_prev_)) continue;
      if (s_ * m.rss > p_max) {
        p_max = s_ * m.rss;
        strongest = m.anchor_m.head<2>();
      }
    }
    const bool near_anchor = o_.scmt && p_max >= s_ * p_th_;
    z.position = near_anchor ? strongest : in_.fixes[fi_].position_m;
    z.r_pos = near_anchor ? o_.epsilon_m2 : o_.sigma_p_m * o_.sigma_p_m;  // eq. 21
    scmt_epochs_ += near_anchor;
    ++fi_;
    return z;
  }

  const CorreaInputs& in_;
  const CorreaEkfOptions& o_;
  const double p_th_, s_;
  size_t si_ = 0, ri_ = 0, fi_ = 0;
  double t_prev_ = 0.0;
  int scmt_epochs_ = 0;
};

}  // namespace

StatusOr<EstimateResult> RunCorreaEkf(const CorreaInputs& in, const CorreaEkfOptions& o) {
  WG_RETURN_IF_ERROR(o.Validate());
  if (in.fixes.empty()) return FailedPrecondition("correa: no LS position fixes");
  WG_ASSIGN_OR_RETURN(const double p_th, ScmtThreshold(in, o));
  EstimateResult result;
  result.diagnostics["p_th"] = o.scmt ? p_th : 0.0;
  std::vector<double> times;
  times.reserve(in.fixes.size());
  for (const PositionFix& fix : in.fixes) times.push_back(fix.t_s);
  CorreaModel model(in, o, p_th);
  KalmanRunOptions run;
  run.smooth = o.smooth;
  run.angle_indices = {3};
  WG_RETURN_IF_ERROR(RunKalmanFilter(times, &model, run, &result));
  result.diagnostics["scmt_epochs"] = model.scmt_epochs();
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

StatusOr<CorreaEstimatorOptions> CorreaEstimatorOptionsFromYaml(const YAML::Node& node,
                                                                CorreaVariant variant, bool smooth,
                                                                const std::string& id) {
  CorreaEstimatorOptions o = CorreaEstimatorOptions::PaperDefaults();
  WG_ASSIGN_OR_RETURN(const YAML::Node own, WithoutKeys(node, {"pdr", "radio"}, id));
  WG_RETURN_IF_ERROR(
      RefuseKeysChosenById(own, {"scmt", "smooth"}, "correa-ekf, correa-scmt-ekf, -rts", id));
  ConfigReader r(node, id);
  const YAML::Node radio = r.Child("radio");
  YAML::Node pdr;
  if (variant != CorreaVariant::kLs) {
    WG_ASSIGN_OR_RETURN(o.filter, CorreaEkfOptionsFromYaml(own, id));
    pdr = r.Child("pdr");
    for (const auto& kv : own) r.Child(kv.first.Scalar());
  }
  WG_RETURN_IF_ERROR(r.Finish());  // correa-ls: only radio
  o.filter.scmt = variant == CorreaVariant::kScmtEkf;
  o.filter.smooth = smooth;
  WG_ASSIGN_OR_RETURN(o.radio, RadioFrontEndOptionsFromYaml(radio, o.radio, id));
  std::map<std::string, std::string> pdr_defaults = {
      {"detector", "fir-magnitude"}, {"length_model", "constant"}, {"heading", "complementary"}};
  if (o.filter.step_length_m > 0) {
    std::ostringstream length;
    length.precision(17);
    length << o.filter.step_length_m;
    pdr_defaults["constant_length_m"] = length.str();
  }
  WG_ASSIGN_OR_RETURN(o.pdr, PdrOptionsFromYaml(pdr, pdr_defaults, id + " pdr"));
  WG_RETURN_IF_ERROR(o.Validate(id));
  return o;
}

Status CorreaEstimatorOptions::Validate(const std::string& id) const {
  WG_RETURN_IF_ERROR(filter.Validate(id));
  WG_RETURN_IF_ERROR(radio.Validate(id));
  return pdr.Validate();
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
  WG_RETURN_IF_ERROR(options_.Validate(id_));
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
  AddFrontEndDiagnostics(in.steps.report, &result->diagnostics);
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
      return CorreaEstimatorOptionsFromYaml(config, variant, smooth, id);
    };
    WG_RETURN_IF_ERROR(registry->Register(
        {id, e.description, OptionsFactory<CorreaEstimator>(parse, id, variant)}));
  }
  return Status::Ok();
}

}  // namespace internal
}  // namespace walkgraph
