#include "walkgraph/filters/tarrio.h"

#include <algorithm>
#include <cmath>

#include "config/parsers.h"
#include "estimators/builtin.h"
#include "util/enum_define.h"
#include "walkgraph/config.h"
#include "walkgraph/kalman.h"
#include "walkgraph/kalman_driver.h"

namespace walkgraph {

WALKGRAPH_DEFINE_ENUM_NAMES(TarrioPrediction, "prediction",
                            {"last-velocity", TarrioPrediction::kLastVelocity},
                            {"pdr-displacement", TarrioPrediction::kPdrDisplacement})
WALKGRAPH_DEFINE_ENUM_NAMES(TarrioStart, "start", {"first-fix", TarrioStart::kFirstFix},
                            {"initial-pose", TarrioStart::kInitialPose})

StatusOr<TarrioKfOptions> TarrioKfOptionsFromYaml(const YAML::Node& node,
                                                  const std::string& context) {
  TarrioKfOptions o;
  ConfigReader r(node, context);
  r.Read("sigma_a_mps2", &o.sigma_a_mps2,
         "acceleration noise sigma_a of the process noise Q (000 eq. 6)");
  r.Read("sigma_v_mps", &o.sigma_v_mps,
         "PDR velocity noise sigma_v of the process noise Q (000 eq. 6)");
  r.Read("sigma_p_m", &o.sigma_p_m,
         "std-dev of each axis of an RSS position fix, R = sigma_p^2 I (000 eq. 7)");
  r.ReadEnum("prediction", &o.prediction, TarrioPredictionNames(),
             "eq. 8 as written (last PDR velocity) or the PDR displacement since the last epoch");
  r.Read("gate_probability", &o.gate_probability,
         "chi-square(2) gate on the fix innovation at this probability; 0: no gate (as the paper)");
  r.Read("smooth", &o.smooth,
         "RTS backward pass over the RSS epochs (chosen by the id: tarrio-kf-rts)");
  WG_RETURN_IF_ERROR(r.Finish());
  WG_RETURN_IF_ERROR(o.Validate(context));
  return o;
}

Status TarrioKfOptions::Validate(const std::string& context) const {
  if (sigma_a_mps2 < 0 || sigma_v_mps < 0 || !(sigma_p_m > 0)) {
    return InvalidArgument(context + ": sigma_a_mps2, sigma_v_mps must be >= 0, sigma_p_m > 0");
  }
  WG_RETURN_IF_ERROR(CheckEnumOption(TarrioPredictionNames(), prediction, "prediction", context));
  if (gate_probability < 0 || gate_probability >= 1) {
    return InvalidArgument(context + ": gate_probability must be in [0, 1)");
  }
  return Status::Ok();
}

namespace {

// Q of eq. 6 for an interval dt.
Eigen::Matrix2d ProcessNoise(const TarrioKfOptions& o, double dt) {
  const double a = 0.5 * o.sigma_a_mps2 * dt * dt, v = o.sigma_v_mps * dt;
  return Eigen::Matrix2d::Identity() * (a * a + v * v);
}

struct Output {
  double t_s;
  Eigen::Vector2d p;
  Eigen::Matrix2d P;
  double heading;
  double sigma_heading;
  int epoch;  // index of the last RSS epoch at or before t (−1 before the first)
  Eigen::Vector2d pdr_since_epoch;  // eq. 13 displacement since that epoch
};

}  // namespace

StatusOr<double> TarrioSettlingTime(const TarrioKfOptions& options, double epoch_s,
                                    double fraction) {
  if (!(epoch_s > 0.0) || !(fraction > 0.0 && fraction < 1.0)) {
    return InvalidArgument("tarrio settling time: epoch_s must be > 0 and fraction in (0, 1)");
  }
  const double q = ProcessNoise(options, epoch_s)(0, 0);   // eq. 6
  const double r = options.sigma_p_m * options.sigma_p_m;  // eq. 7
  if (!(q > 0.0)) {
    return InvalidArgument("tarrio settling time: Q = 0 (sigma_a and sigma_v are 0)");
  }
  const double p_prior = 0.5 * (q + std::sqrt(q * q + 4.0 * q * r));  // fixed point of eq. 9, 11
  const double gain = p_prior / (p_prior + r);                        // eq. 12
  return epoch_s * std::log(fraction) / std::log1p(-gain);
}

namespace {

Status CheckTarrioInputs(const StepSequence& steps, const std::vector<PositionFix>& fixes,
                         TarrioMode mode, const std::optional<Eigen::Vector2d>& start) {
  if (fixes.empty() && !(mode == TarrioMode::kPdrOnly && start)) {
    return FailedPrecondition("tarrio: no RSS position fix (needed to start)");
  }
  if (mode != TarrioMode::kRssOnly && steps.steps.empty()) {
    return FailedPrecondition("tarrio: no steps from the PDR front end");
  }
  for (size_t i = 1; i < fixes.size(); ++i) {
    if (fixes[i].t_s <= fixes[i - 1].t_s) return InvalidArgument("tarrio: fixes not increasing");
  }
  for (size_t i = 1; i < steps.steps.size(); ++i) {
    if (steps.steps[i].t_s < steps.steps[i - 1].t_s) {
      return InvalidArgument("tarrio: steps not sorted");
    }
  }
  return Status::Ok();
}

// The KF epoch of a fix at t (eq. 8–12): prior from the last epoch, Joseph-form update.
StatusOr<FilterEpoch> KalmanFixEpoch(const PositionFix& f, double t, double t_epoch,
                                     const Eigen::Vector2d& p_epoch, const Eigen::Matrix2d& P_epoch,
                                     const Eigen::Vector2d& p, const Eigen::Vector2d& v,
                                     const TarrioKfOptions& options, const Eigen::Matrix2d& R,
                                     EstimateResult* result) {
  const double dT = t - t_epoch;
  FilterEpoch e;
  e.t_s = t;
  e.F = Eigen::Matrix2d::Identity();
  e.x_prior = options.prediction == TarrioPrediction::kLastVelocity
                  ? Eigen::Vector2d(p_epoch + dT * v)
                  : p;                              // eq. 8
  e.P_prior = P_epoch + ProcessNoise(options, dT);  // eq. 9, eq. 6
  Eigen::VectorXd x = e.x_prior;
  Eigen::MatrixXd Pk = e.P_prior;
  WG_ASSIGN_OR_RETURN(UpdateOutcome u,  // eq. 10–12 (Joseph form)
                      KalmanUpdate(f.position_m - x, Eigen::Matrix2d::Identity(), R,
                                   options.gate_probability, &x, &Pk));
  RecordOutcome(u, &result->nis, &result->diagnostics);
  e.x_post = x;
  e.P_post = Pk;
  return e;
}

// RTS over the fix epochs; an output between two epochs is the smoothed epoch plus its PDR since
// then, with the mismatch at the next smoothed epoch spread linearly over the interval.
Status SmoothOutputs(const std::vector<FilterEpoch>& epochs,
                     const std::vector<Eigen::Vector2d>& interval_pdr,
                     std::vector<Output>* outputs) {
  WG_ASSIGN_OR_RETURN(std::vector<SmoothedState> sm, RtsSmooth(epochs));
  for (Output& o : *outputs) {
    const int k = o.epoch;
    const double tk = sm[k].t_s;
    o.p = sm[k].x + o.pdr_since_epoch;
    o.P = sm[k].P;
    if (size_t(k + 1) < sm.size() && o.t_s > tk) {
      const double alpha = (o.t_s - tk) / (sm[k + 1].t_s - tk);
      o.p += alpha * (sm[k + 1].x - sm[k].x - interval_pdr[k + 1]);
      o.P = (1 - alpha) * sm[k].P + alpha * sm[k + 1].P;
    }
  }
  return Status::Ok();
}

void AppendTrajectory(const std::vector<Output>& outputs, Trajectory* trajectory) {
  for (const Output& o : outputs) {
    TrajectoryPoint pt;
    pt.t_s = o.t_s;
    pt.position_m = Eigen::Vector3d(o.p.x(), o.p.y(), 0.0);
    pt.heading_rad = o.heading;
    Eigen::Matrix3d C = Eigen::Matrix3d::Zero();
    C.topLeftCorner<2, 2>() = o.P;
    C(2, 2) = o.sigma_heading * o.sigma_heading;
    pt.covariance = C;
    trajectory->points.push_back(pt);
  }
}

}  // namespace

StatusOr<EstimateResult> RunTarrio(const StepSequence& steps, const std::vector<PositionFix>& fixes,
                                   const TarrioKfOptions& options, TarrioMode mode,
                                   std::optional<Eigen::Vector2d> start) {
  WG_RETURN_IF_ERROR(options.Validate());
  WG_RETURN_IF_ERROR(CheckTarrioInputs(steps, fixes, mode, start));
  const bool uses_fixes = mode != TarrioMode::kPdrOnly;
  const Eigen::Matrix2d R = Eigen::Matrix2d::Identity() * options.sigma_p_m * options.sigma_p_m;
  if (mode == TarrioMode::kPdrOnly && !start) start = fixes.front().position_m;
  const double t0 =
      mode == TarrioMode::kPdrOnly && (fixes.empty() || steps.steps.front().t_s < fixes.front().t_s)
          ? steps.steps.front().t_s
          : fixes.front().t_s;
  const std::vector<double> times = EventTimes(t0, fixes, steps.steps);  // kalman_driver.h

  EstimateResult result;
  std::vector<FilterEpoch> epochs;
  std::vector<Output> outputs;
  std::vector<Eigen::Vector2d> interval_pdr;    // eq. 13 displacement over each epoch interval
  Eigen::Vector2d v = Eigen::Vector2d::Zero();  // current PDR velocity (eq. 5)
  double heading = 0.0, sigma_heading = M_PI;
  Eigen::Vector2d p = Eigen::Vector2d::Zero(), p_epoch = p, pdr_since_epoch = p;
  Eigen::Matrix2d P = R, P_epoch = R;
  double t_prev = t0, t_epoch = t0;
  size_t si = 0, fi = 0;
  // Steps before the start only set the initial velocity.
  auto take_step = [&](const Step& s) {
    if (s.duration_s > 0) {
      v = s.length_m / s.duration_s *
          Eigen::Vector2d(std::cos(s.heading_rad), std::sin(s.heading_rad));
    }
    heading = s.heading_rad;
    sigma_heading = s.sigma_heading_rad;
  };
  while (si < steps.steps.size() && steps.steps[si].t_s < t0) take_step(steps.steps[si++]);
  bool started = false;
  int epoch = -1;
  for (double t : times) {
    const double dt = t - t_prev;
    // eq. 13: PDR propagation with the velocity held since the last step.
    if (started) {
      p += dt * v;
      pdr_since_epoch += dt * v;
      if (mode != TarrioMode::kRssOnly) P = P_epoch + ProcessNoise(options, t - t_epoch);
    }
    t_prev = t;
    while (si < steps.steps.size() && steps.steps[si].t_s <= t) take_step(steps.steps[si++]);
    if (uses_fixes && fi < fixes.size() && fixes[fi].t_s == t) {
      const PositionFix& f = fixes[fi++];
      if (!started) {
        p = f.position_m;
        P = mode == TarrioMode::kKalman ? R : f.covariance;
        started = true;
      } else if (mode == TarrioMode::kKalman) {
        WG_ASSIGN_OR_RETURN(FilterEpoch e, KalmanFixEpoch(f, t, t_epoch, p_epoch, P_epoch, p, v,
                                                          options, R, &result));
        p = e.x_post;
        P = e.P_post;
        epochs.push_back(std::move(e));
      } else {
        p = f.position_m;  // both baselines: reset to the new fix
        P = f.covariance;
      }
      if (mode == TarrioMode::kKalman && epochs.empty()) {
        FilterEpoch e;
        e.t_s = t;
        e.x_prior = e.x_post = p;
        e.P_prior = e.P_post = P;
        epochs.push_back(e);
      }
      interval_pdr.push_back(pdr_since_epoch);
      p_epoch = p;
      P_epoch = P;
      t_epoch = t;
      pdr_since_epoch.setZero();
      ++epoch;
    } else if (!started && !uses_fixes) {
      p = *start;
      P = R;
      P_epoch = P;
      t_epoch = t;
      started = true;
    }
    if (!started) continue;
    const Eigen::Vector2d shown = mode == TarrioMode::kRssOnly ? p_epoch : p;
    outputs.push_back({t, shown, P, heading, sigma_heading, epoch, pdr_since_epoch});
  }

  if (options.smooth && mode == TarrioMode::kKalman) {
    WG_RETURN_IF_ERROR(SmoothOutputs(epochs, interval_pdr, &outputs));
  }
  AppendTrajectory(outputs, &result.trajectory);
  return result;
}

// ------------------------------------------------------------------ estimators on a Walk

TarrioEstimatorOptions TarrioEstimatorOptions::PaperDefaults() {
  TarrioEstimatorOptions o;
  o.pdr.detector = StepDetector::kVerticalPeak;     // 000 Sec. IV: low-pass, local maxima/minima
  o.pdr.length_model = StepLengthModel::kWeinberg;  // eq. 3
  o.pdr.weinberg_k = 0.45;                          // Sec. IV
  // eq. 4 (gyro) from a known start heading; a walk without one but with a magnetometer gets
  // its absolute heading from 001 eq. 7's blend (heading 'auto', our choice: 000 starts from a
  // known pose, and a gyro heading alone has no anchor-frame direction).
  o.pdr.heading = HeadingMethod::kAuto;
  o.radio.epochs.window_s = 2.0;                    // ΔT = 2 s (Sec. IV)
  o.radio.method = PositioningMethod::kHyperbolic;  // eq. 2
  return o;
}

StatusOr<TarrioEstimatorOptions> TarrioEstimatorOptionsFromYaml(const YAML::Node& node,
                                                                TarrioMode mode, bool smooth,
                                                                const std::string& id) {
  TarrioEstimatorOptions o = TarrioEstimatorOptions::PaperDefaults();
  WG_ASSIGN_OR_RETURN(const YAML::Node own, WithoutKeys(node, {"pdr", "radio", "start"}, id));
  WG_RETURN_IF_ERROR(RefuseKeysChosenById(own, {"smooth"}, "tarrio-kf or tarrio-kf-rts", id));
  WG_ASSIGN_OR_RETURN(o.filter, TarrioKfOptionsFromYaml(own, id));
  o.filter.smooth = smooth;
  // The rest: pdr, radio and (pdr-only) start.
  ConfigReader r(node, id);
  if (mode == TarrioMode::kPdrOnly) {
    r.ReadEnum("start", &o.start, TarrioStartNames(),
               "pdr-only: start at the first RSS fix (000 Sec. IV) or at walk.yaml initial_pose");
  }
  const YAML::Node radio = r.Child("radio");
  const YAML::Node pdr = mode == TarrioMode::kRssOnly ? YAML::Node() : r.Child("pdr");
  // The filter's keys were checked above; mark them known for Finish().
  for (const auto& kv : own) r.Child(kv.first.Scalar());
  WG_RETURN_IF_ERROR(r.Finish());
  WG_ASSIGN_OR_RETURN(o.radio, RadioFrontEndOptionsFromYaml(radio, o.radio, id));
  WG_ASSIGN_OR_RETURN(o.pdr, PdrOptionsFromYaml(pdr,
                                                {{"detector", "vertical-peak"},
                                                 {"length_model", "weinberg"},
                                                 {"weinberg_k", "0.45"},
                                                 {"heading", "auto"}},
                                                id + " pdr"));
  WG_RETURN_IF_ERROR(o.Validate(id));
  return o;
}

Status TarrioEstimatorOptions::Validate(const std::string& id) const {
  WG_RETURN_IF_ERROR(filter.Validate(id));
  WG_RETURN_IF_ERROR(CheckEnumOption(TarrioStartNames(), start, "start", id));
  return pdr.Validate();
}

Status TarrioEstimator::CheckApplicable(const Walk& walk) const {
  if (UsesSteps()) WG_RETURN_IF_ERROR(CheckStepInput(walk, options_.pdr, true, id_));
  if (UsesFixes()) WG_RETURN_IF_ERROR(CheckRadioInput(walk, 3, id_));
  if (mode_ == TarrioMode::kPdrOnly && !UsesFixes() && !walk.meta.initial_pose) {
    return FailedPrecondition(id_ + " with start 'initial-pose' needs initial_pose in walk.yaml");
  }
  return Status::Ok();
}

StatusOr<EstimateResult> TarrioEstimator::Run(const Walk& walk) const {
  WG_RETURN_IF_ERROR(options_.Validate(id_));
  WG_RETURN_IF_ERROR(CheckApplicable(walk));
  StepSequence steps;
  if (UsesSteps()) {
    WG_ASSIGN_OR_RETURN(steps, StepsFromFrontEnd(walk, options_.pdr, true, id_));
  }
  FixesFromFrontEnd fixes;
  // pdr-only from the first fix on a walk whose radio never gives one (IPIN trials 05/21/52:
  // never three beacons in an epoch) starts at walk.yaml's initial_pose when it has one
  // (diagnostic start_from_initial_pose = 1; our choice, so that the walk needs no config).
  bool start_from_pose = mode_ == TarrioMode::kPdrOnly && !UsesFixes();
  if (UsesFixes()) {
    StatusOr<FixesFromFrontEnd> f = PositionFixesFromFrontEnd(walk, options_.radio, id_);
    if (f.ok()) {
      fixes = std::move(*f);
    } else if (mode_ == TarrioMode::kPdrOnly && walk.meta.initial_pose) {
      start_from_pose = true;
    } else {
      return f.status();
    }
  }
  std::optional<Eigen::Vector2d> start;
  if (start_from_pose) {
    start = Eigen::Vector2d(walk.meta.initial_pose->x_m, walk.meta.initial_pose->y_m);
  }
  StatusOr<EstimateResult> result = RunTarrio(steps, fixes.fixes, options_.filter, mode_, start);
  if (!result.ok()) return Status(result.status().code(), id_ + ": " + result.status().message());
  result->diagnostics["steps"] = static_cast<double>(steps.steps.size());
  if (UsesSteps()) AddFrontEndDiagnostics(steps.report, &result->diagnostics);
  if (start_from_pose && UsesFixes()) result->diagnostics["start_from_initial_pose"] = 1.0;
  result->diagnostics["radio_epochs"] = fixes.epochs;
  result->diagnostics["radio_epochs_without_fix"] = fixes.failed_epochs;
  return result;
}

namespace internal {

Status RegisterTarrio(EstimatorRegistry* registry) {
  struct Entry {
    const char* id;
    const char* description;
    TarrioMode mode;
    bool smooth;
  };
  const Entry entries[] = {
      {"pdr-only", "000 eq. 13: PDR from the first RSS fix, no radio afterwards (steps)",
       TarrioMode::kPdrOnly, false},
      {"rss-only", "000 Sec. IV baseline: hold the last hyperbolic RSS fix (eq. 2, 2 s epochs)",
       TarrioMode::kRssOnly, false},
      {"rss-pdr-reset",
       "000 Sec. IV baseline: PDR between RSS fixes, reset at each fix (steps+RSS)",
       TarrioMode::kRssPdrReset, false},
      {"tarrio-kf", "000 eq. 5-13: KF on [x y], PDR velocity as control input, RSS fixes",
       TarrioMode::kKalman, false},
      {"tarrio-kf-rts", "000 eq. 5-13 + RTS smoother over the RSS epochs (offline)",
       TarrioMode::kKalman, true},
  };
  for (const Entry& e : entries) {
    const std::string id = e.id;
    const TarrioMode mode = e.mode;
    const bool smooth = e.smooth;
    auto parse = [id, mode, smooth](const YAML::Node& config) {
      return TarrioEstimatorOptionsFromYaml(config, mode, smooth, id);
    };
    WG_RETURN_IF_ERROR(
        registry->Register({id, e.description, OptionsFactory<TarrioEstimator>(parse, id, mode)}));
  }
  return Status::Ok();
}

}  // namespace internal
}  // namespace walkgraph
