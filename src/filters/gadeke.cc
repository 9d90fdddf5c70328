#include "walkgraph/filters/gadeke.h"

#include <algorithm>
#include <cmath>

#include "config/parsers.h"
#include "estimators/builtin.h"
#include "walkgraph/config.h"
#include "walkgraph/kalman.h"
#include "walkgraph/kalman_driver.h"

namespace walkgraph {

StatusOr<GadekeKfOptions> GadekeKfOptionsFromYaml(const YAML::Node& node,
                                                  const std::string& context) {
  GadekeKfOptions o;
  ConfigReader r(node, context);
  r.Read("velocity_factor", &o.velocity_factor, "velocity decay per processing epoch (003 eq. 6)");
  r.Read("processing_rate_hz", &o.processing_rate_hz, "filter epochs per second (003 Sec. 4.2)");
  r.Read("pdr_input", &o.pdr_input, "PDR displacement as control input (003 eq. 6)");
  r.Read("pdr_sigma_frac", &o.pdr_sigma_frac,
         "sigma of the PDR input, fraction of its distance (003 Sec. 5)");
  r.Read("q_position_m2ps", &o.q_position_m2ps,
         "position random-walk noise density in Q (003 eq. 6)");
  r.Read("q_velocity_m2ps3", &o.q_velocity_m2ps3,
         "velocity random-walk noise density in Q (003 eq. 6)");
  r.Read("init_sigma_m", &o.init_sigma_m,
         "start sigma at the anchors' centroid without initial_pose");
  r.Read("init_sigma_v_mps", &o.init_sigma_v_mps, "sigma of the start velocity");
  r.Read("tag_height_m", &o.tag_height_m, "tag height; ranges projected to the horizontal");
  r.Read("bias_corrected_ranges", &o.bias_corrected_ranges,
         "RSS to range: ML or bias-corrected (001 eq. 17)");
  r.Read("gate_probability", &o.gate_probability, "chi-square(1) gate on each range; 0 off");
  r.Read("outage_start_frac", &o.outage_start_frac,
         "simulated radio outage start, fraction of the walk; < 0 none");
  r.Read("outage_end_frac", &o.outage_end_frac, "simulated radio outage end, fraction of the walk");
  r.Read("smooth", &o.smooth, "RTS smoother after the filter (gadeke-kf-rts)");
  WG_RETURN_IF_ERROR(r.Finish());
  WG_RETURN_IF_ERROR(o.Validate(context));
  return o;
}

Status GadekeKfOptions::Validate(const std::string& context) const {
  const GadekeKfOptions& o = *this;
  if (!(o.velocity_factor > 0 && o.velocity_factor <= 1)) {
    return InvalidArgument(context + ": velocity_factor must be in (0, 1]");
  }
  if (!(o.processing_rate_hz > 0) || o.pdr_sigma_frac < 0 || o.q_position_m2ps < 0 ||
      !(o.q_velocity_m2ps3 > 0) || !(o.init_sigma_m > 0) || !(o.init_sigma_v_mps > 0)) {
    return InvalidArgument(context + ": rates, sigmas and noise densities must be positive");
  }
  if (o.gate_probability < 0 || o.gate_probability >= 1) {
    return InvalidArgument(context + ": gate_probability must be in [0, 1)");
  }
  if (o.outage_start_frac >= 0 && !(o.outage_end_frac > o.outage_start_frac)) {
    return InvalidArgument(context + ": outage_end_frac must exceed outage_start_frac");
  }
  return Status::Ok();
}

namespace {

// The KF of 003 on [p v] (eq. 6) with the PDR displacement as control input and the range EKF
// update, one epoch per step or reading, as kalman_driver.h runs it.
class GadekeModel : public KalmanModel {
 public:
  GadekeModel(const StepSequence& steps, const std::vector<RangeMeasurement>& ranges,
              const GadekeStart& start, const GadekeKfOptions& o)
      : steps_(steps.steps), ranges_(ranges), start_(start), o_(o) {
    while (si_ < steps_.size() && steps_[si_].t_s <= start.t_s) ++si_;
    while (ri_ < ranges_.size() && ranges_[ri_].t_s < start.t_s) ++ri_;
  }

  Status Initialize(double, Eigen::VectorXd* x, Eigen::MatrixXd* P) override {
    const double s2 = start_.sigma_m * start_.sigma_m,
                 v2 = o_.init_sigma_v_mps * o_.init_sigma_v_mps;
    *x = Eigen::Vector4d(start_.position_m.x(), start_.position_m.y(), 0.0, 0.0);
    *P = Eigen::Vector4d(s2, s2, v2, v2).asDiagonal();
    return Status::Ok();
  }

  Status Predict(double t_prev, double t, Eigen::VectorXd* x, Eigen::MatrixXd* P,
                 Eigen::MatrixXd* F) override {
    const double dt = t - t_prev;
    Eigen::Vector2d u = Eigen::Vector2d::Zero();  // B·u_k: PDR displacement (eq. 6)
    for (; si_ < steps_.size() && steps_[si_].t_s <= t; ++si_) {
      const Step& s = steps_[si_];
      if (o_.pdr_input)
        u += s.length_m * Eigen::Vector2d(std::cos(s.heading_rad), std::sin(s.heading_rad));
      heading_ = s.heading_rad;
    }
    Eigen::Matrix4d A = Eigen::Matrix4d::Identity();  // eq. 6 system matrix
    A(0, 2) = A(1, 3) = dt;
    A(2, 2) = A(3, 3) = std::pow(o_.velocity_factor, dt * o_.processing_rate_hz);
    Eigen::Matrix4d Q = Eigen::Matrix4d::Zero();
    const double su = o_.pdr_sigma_frac * u.norm();
    Q(0, 0) = Q(1, 1) = su * su + o_.q_position_m2ps * dt;
    Q(2, 2) = Q(3, 3) = o_.q_velocity_m2ps3 * dt;
    *x = A * (*x);
    x->head<2>() += u;
    *P = A * (*P) * A.transpose() + Q;
    Symmetrize(P);
    *F = A;
    return Status::Ok();
  }

  // The range readings up to t (EKF range Jacobian).
  Status Update(size_t, double t, KalmanRun* run) override {
    headings_.push_back(heading_);
    for (; ri_ < ranges_.size() && ranges_[ri_].t_s <= t; ++ri_) {
      const RangeMeasurement& m = ranges_[ri_];
      const Eigen::VectorXd& x = run->x;
      const Eigen::Vector3d d(x[0] - m.anchor_m.x(), x[1] - m.anchor_m.y(),
                              o_.tag_height_m - m.anchor_m.z());
      const double h = std::max(d.norm(), 1e-3);
      Eigen::MatrixXd H = Eigen::MatrixXd::Zero(1, 4);
      H(0, 0) = d.x() / h;
      H(0, 1) = d.y() / h;
      const Eigen::VectorXd nu = Eigen::VectorXd::Constant(1, m.range_m - h);
      const Eigen::MatrixXd R = Eigen::MatrixXd::Constant(1, 1, m.sigma_m * m.sigma_m);
      WG_RETURN_IF_ERROR(run->Update(nu, H, R, o_.gate_probability).status());
    }
    return Status::Ok();
  }

  // Position and its covariance; the heading is the PDR's (the filter does not estimate it).
  TrajectoryPoint Output(size_t k, const SmoothedState& st) const override {
    TrajectoryPoint pt;
    pt.t_s = st.t_s;
    pt.position_m = Eigen::Vector3d(st.x[0], st.x[1], 0.0);
    pt.heading_rad = headings_[k];
    Eigen::Matrix3d C = Eigen::Matrix3d::Zero();
    C.topLeftCorner<2, 2>() = st.P.topLeftCorner(2, 2);
    C(2, 2) = M_PI * M_PI;
    pt.covariance = C;
    return pt;
  }

 private:
  const std::vector<Step>& steps_;
  const std::vector<RangeMeasurement>& ranges_;
  const GadekeStart start_;
  const GadekeKfOptions& o_;
  size_t si_ = 0, ri_ = 0;
  double heading_ = 0.0;
  std::vector<double> headings_;  // the PDR heading at each epoch
};

}  // namespace

StatusOr<EstimateResult> RunGadekeKf(const StepSequence& steps,
                                     const std::vector<RangeMeasurement>& ranges,
                                     const GadekeStart& start, const GadekeKfOptions& o) {
  WG_RETURN_IF_ERROR(o.Validate());
  EstimateResult result;
  GadekeModel model(steps, ranges, start, o);
  KalmanRunOptions run;
  run.smooth = o.smooth;
  WG_RETURN_IF_ERROR(
      RunKalmanFilter(EventTimes(start.t_s, steps.steps, ranges), &model, run, &result));
  return result;
}

// ------------------------------------------------------------------ estimators on a Walk

GadekeEstimatorOptions GadekeEstimatorOptions::PaperDefaults() {
  GadekeEstimatorOptions o;
  o.pdr.detector = StepDetector::kEnergy;           // eq. 1
  o.pdr.energy_threshold_m2ps4 = 10.0;              // Sec. 3.1.2
  o.pdr.energy_lockout_s = 0.3;                     // Sec. 3.1.2
  o.pdr.length_model = StepLengthModel::kWeinberg;  // eq. 2
  o.pdr.forward_axis = ForwardAxisMethod::kPca;     // eq. 3-5
  o.pdr.heading = HeadingMethod::kComplementary;    // Xsens attitude with magnetometer
  o.ranges.bias_corrected = o.filter.bias_corrected_ranges;
  return o;
}

StatusOr<GadekeEstimatorOptions> GadekeEstimatorOptionsFromYaml(const YAML::Node& node, bool smooth,
                                                                const std::string& id) {
  GadekeEstimatorOptions o = GadekeEstimatorOptions::PaperDefaults();
  WG_ASSIGN_OR_RETURN(const YAML::Node own, WithoutKeys(node, {"pdr", "radio"}, id));
  WG_RETURN_IF_ERROR(RefuseKeysChosenById(own, {"smooth"}, "gadeke-kf or gadeke-kf-rts", id));
  WG_ASSIGN_OR_RETURN(o.filter, GadekeKfOptionsFromYaml(own, id));
  o.filter.smooth = smooth;
  ConfigReader r(node, id);
  const YAML::Node pdr = r.Child("pdr");
  const YAML::Node radio = r.Child("radio");
  for (const auto& kv : own) r.Child(kv.first.Scalar());
  WG_RETURN_IF_ERROR(r.Finish());
  ConfigReader rr(radio, id + " radio");
  rr.Read("min_sigma_m", &o.ranges.min_sigma_m, "floor on each range's sigma");
  WG_RETURN_IF_ERROR(rr.Finish());
  o.ranges.bias_corrected = o.filter.bias_corrected_ranges;
  WG_ASSIGN_OR_RETURN(o.pdr, PdrOptionsFromYaml(pdr,
                                                {{"detector", "energy"},
                                                 {"energy_threshold_m2ps4", "10"},
                                                 {"energy_lockout_s", "0.3"},
                                                 {"length_model", "weinberg"},
                                                 {"forward_axis", "pca"},
                                                 {"heading", "complementary"}},
                                                id + " pdr"));
  WG_RETURN_IF_ERROR(o.Validate(id));
  return o;
}

Status GadekeEstimatorOptions::Validate(const std::string& id) const {
  WG_RETURN_IF_ERROR(filter.Validate(id));
  if (!(ranges.min_sigma_m > 0)) return InvalidArgument(id + " radio: min_sigma_m must be > 0");
  return pdr.Validate();
}

Status GadekeEstimator::CheckApplicable(const Walk& walk) const {
  WG_RETURN_IF_ERROR(CheckStepInput(walk, options_.pdr, true, id_));
  WG_RETURN_IF_ERROR(CheckRadioInput(walk, 1, id_));
  return Status::Ok();
}

StatusOr<EstimateResult> GadekeEstimator::Run(const Walk& walk) const {
  WG_RETURN_IF_ERROR(options_.Validate(id_));
  WG_RETURN_IF_ERROR(CheckApplicable(walk));
  WG_ASSIGN_OR_RETURN(const StepSequence steps, StepsFromFrontEnd(walk, options_.pdr, true, id_));
  StatusOr<std::vector<RangeMeasurement>> all = RangeMeasurementsFromWalk(walk, options_.ranges);
  if (!all.ok()) return Status(all.status().code(), id_ + ": " + all.status().message());
  const GadekeKfOptions& f = options_.filter;
  const double t0 = walk.StartTime(), span = walk.EndTime() - t0;
  std::vector<RangeMeasurement> ranges;
  int dropped = 0;
  for (const RangeMeasurement& m : *all) {
    // Sec. 5.2: the simulated WSN outage [t0 + a·T, t0 + b·T].
    if (f.outage_start_frac >= 0 && m.t_s >= t0 + f.outage_start_frac * span &&
        m.t_s <= t0 + f.outage_end_frac * span) {
      ++dropped;
      continue;
    }
    ranges.push_back(m);
  }
  GadekeStart start;
  start.t_s = t0;
  if (walk.meta.initial_pose) {
    start.position_m = Eigen::Vector2d(walk.meta.initial_pose->x_m, walk.meta.initial_pose->y_m);
    start.sigma_m = walk.meta.initial_pose->sigma_xy_m;
  } else {
    Eigen::Vector2d c = Eigen::Vector2d::Zero();
    for (const Anchor& a : walk.anchors) c += a.position_m.head<2>();
    start.position_m = c / static_cast<double>(walk.anchors.size());
    start.sigma_m = f.init_sigma_m;
  }
  StatusOr<EstimateResult> result = RunGadekeKf(steps, ranges, start, f);
  if (!result.ok()) return Status(result.status().code(), id_ + ": " + result.status().message());
  result->diagnostics["steps"] = static_cast<double>(steps.steps.size());
  AddFrontEndDiagnostics(steps.report, &result->diagnostics);
  result->diagnostics["ranges"] = static_cast<double>(ranges.size());
  result->diagnostics["ranges_dropped_outage"] = dropped;
  return result;
}

namespace internal {

Status RegisterGadeke(EstimatorRegistry* registry) {
  for (const bool smooth : {false, true}) {
    const std::string id = smooth ? "gadeke-kf-rts" : "gadeke-kf";
    auto parse = [id, smooth](const YAML::Node& config) {
      return GadekeEstimatorOptionsFromYaml(config, smooth, id);
    };
    WG_RETURN_IF_ERROR(registry->Register(
        {id,
         smooth ? "003 KF + RTS smoother over every step/reading epoch (offline)"
                : "003 Sec. 3.2: KF on [p v], PDR displacement as control input, RSS range EKF",
         OptionsFactory<GadekeEstimator>(parse, id)}));
  }
  return Status::Ok();
}

}  // namespace internal
}  // namespace walkgraph
