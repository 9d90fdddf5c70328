#include "walkgraph/filters/gadeke.h"

#include <algorithm>
#include <cmath>

#include "walkgraph/config.h"
#include "walkgraph/filters/kalman.h"

namespace walkgraph {

StatusOr<GadekeKfOptions> GadekeKfOptions::FromYaml(const YAML::Node& node,
                                                    const std::string& context) {
  GadekeKfOptions o;
  ConfigReader r(node, context);
  r.Read("velocity_factor", &o.velocity_factor);
  r.Read("processing_rate_hz", &o.processing_rate_hz);
  r.Read("pdr_input", &o.pdr_input);
  r.Read("pdr_sigma_frac", &o.pdr_sigma_frac);
  r.Read("q_position_m2ps", &o.q_position_m2ps);
  r.Read("q_velocity_m2ps3", &o.q_velocity_m2ps3);
  r.Read("init_sigma_m", &o.init_sigma_m);
  r.Read("init_sigma_v_mps", &o.init_sigma_v_mps);
  r.Read("tag_height_m", &o.tag_height_m);
  r.Read("bias_corrected_ranges", &o.bias_corrected_ranges);
  r.Read("gate_probability", &o.gate_probability);
  r.Read("outage_start_frac", &o.outage_start_frac);
  r.Read("outage_end_frac", &o.outage_end_frac);
  r.Read("smooth", &o.smooth);
  WG_RETURN_IF_ERROR(r.Finish());
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
  return o;
}

StatusOr<EstimateResult> RunGadekeKf(const StepSequence& steps,
                                     const std::vector<RangeMeasurement>& ranges,
                                     const GadekeStart& start, const GadekeKfOptions& o) {
  using Vec4 = Eigen::Matrix<double, 4, 1>;
  using Mat4 = Eigen::Matrix<double, 4, 4>;
  std::vector<double> times{start.t_s};
  for (const Step& s : steps.steps) {
    if (s.t_s > start.t_s) times.push_back(s.t_s);
  }
  for (const RangeMeasurement& m : ranges) {
    if (m.t_s > start.t_s) times.push_back(m.t_s);
  }
  std::sort(times.begin(), times.end());
  times.erase(std::unique(times.begin(), times.end()), times.end());

  EstimateResult result;
  std::vector<FilterEpoch> epochs;
  std::vector<double> headings;
  Eigen::VectorXd x = Vec4(start.position_m.x(), start.position_m.y(), 0.0, 0.0);
  Eigen::MatrixXd P =
      Vec4(start.sigma_m * start.sigma_m, start.sigma_m * start.sigma_m,
           o.init_sigma_v_mps * o.init_sigma_v_mps, o.init_sigma_v_mps * o.init_sigma_v_mps)
          .asDiagonal();
  size_t si = 0, ri = 0;
  while (si < steps.steps.size() && steps.steps[si].t_s <= start.t_s) ++si;
  while (ri < ranges.size() && ranges[ri].t_s < start.t_s) ++ri;
  double heading = 0.0;
  for (size_t k = 0; k < times.size(); ++k) {
    const double t = times[k];
    FilterEpoch e;
    e.t_s = t;
    if (k > 0) {
      const double dt = t - times[k - 1];
      Eigen::Vector2d u = Eigen::Vector2d::Zero();  // B·u_k: PDR displacement (eq. 6)
      for (; si < steps.steps.size() && steps.steps[si].t_s <= t; ++si) {
        const Step& s = steps.steps[si];
        if (o.pdr_input)
          u += s.length_m * Eigen::Vector2d(std::cos(s.heading_rad), std::sin(s.heading_rad));
        heading = s.heading_rad;
      }
      Mat4 A = Mat4::Identity();  // eq. 6 system matrix
      A(0, 2) = A(1, 3) = dt;
      A(2, 2) = A(3, 3) = std::pow(o.velocity_factor, dt * o.processing_rate_hz);
      Mat4 Q = Mat4::Zero();
      const double su = o.pdr_sigma_frac * u.norm();
      Q(0, 0) = Q(1, 1) = su * su + o.q_position_m2ps * dt;
      Q(2, 2) = Q(3, 3) = o.q_velocity_m2ps3 * dt;
      x = A * x;
      x.head<2>() += u;
      P = A * P * A.transpose() + Q;
      Symmetrize(&P);
      e.F = A;
    }
    e.x_prior = x;
    e.P_prior = P;
    for (; ri < ranges.size() && ranges[ri].t_s <= t; ++ri) {
      const RangeMeasurement& m = ranges[ri];
      const Eigen::Vector3d d(x[0] - m.anchor_m.x(), x[1] - m.anchor_m.y(),
                              o.tag_height_m - m.anchor_m.z());
      const double h = std::max(d.norm(), 1e-3);
      Eigen::MatrixXd H = Eigen::MatrixXd::Zero(1, 4);  // EKF range Jacobian
      H(0, 0) = d.x() / h;
      H(0, 1) = d.y() / h;
      const Eigen::VectorXd nu = Eigen::VectorXd::Constant(1, m.range_m - h);
      const Eigen::MatrixXd R = Eigen::MatrixXd::Constant(1, 1, m.sigma_m * m.sigma_m);
      WG_ASSIGN_OR_RETURN(UpdateOutcome out, KalmanUpdate(nu, H, R, o.gate_probability, &x, &P));
      if (out.accepted) {
        result.nis.push_back(out.nis);
      } else {
        result.diagnostics["gated_updates"] += 1;
      }
    }
    e.x_post = x;
    e.P_post = P;
    epochs.push_back(e);
    headings.push_back(heading);
  }

  std::vector<SmoothedState> states;
  if (o.smooth) {
    WG_ASSIGN_OR_RETURN(states, RtsSmooth(epochs));
  } else {
    for (const FilterEpoch& e : epochs) states.push_back({e.t_s, e.x_post, e.P_post});
  }
  for (size_t k = 0; k < states.size(); ++k) {
    TrajectoryPoint pt;
    pt.t_s = states[k].t_s;
    pt.position_m = Eigen::Vector3d(states[k].x[0], states[k].x[1], 0.0);
    pt.heading_rad = headings[k];
    Eigen::Matrix3d C = Eigen::Matrix3d::Zero();
    C.topLeftCorner<2, 2>() = states[k].P.topLeftCorner(2, 2);
    C(2, 2) = M_PI * M_PI;  // the filter does not estimate heading
    pt.covariance = C;
    result.trajectory.points.push_back(pt);
  }
  return result;
}

}  // namespace walkgraph
