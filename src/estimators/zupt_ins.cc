#include "walkgraph/zupt_ins.h"

#include <cmath>

#include "config/parsers.h"
#include "estimators/builtin.h"
#include "walkgraph/angle.h"
#include "walkgraph/config.h"

namespace walkgraph {

StatusOr<ZuptInsOptions> ZuptInsOptionsFromYaml(const YAML::Node& node) {
  ZuptInsOptions o;
  ConfigReader r(node, "zupt-ins");
  const YAML::Node front = r.Child("front_end");
  r.Read("output_rate_hz", &o.output_rate_hz,
         "trajectory output rate (plus a pose at every stride end)");
  r.Read("gauge_sigma_m", &o.gauge_sigma_m,
         "start position std-dev without initial_pose (arbitrary origin)");
  r.Read("gauge_sigma_yaw_rad", &o.gauge_sigma_yaw_rad, "start yaw std-dev without initial_pose");
  WG_RETURN_IF_ERROR(r.Finish());
  if (front.IsDefined()) {
    WG_ASSIGN_OR_RETURN(o.front_end, StrideOptionsFromYaml(front, o.front_end));
  }
  WG_RETURN_IF_ERROR(o.Validate());
  return o;
}

Status ZuptInsOptions::Validate() const {
  const ZuptInsOptions& o = *this;
  WG_RETURN_IF_ERROR(o.front_end.Validate());
  if (!(o.output_rate_hz > 0) || !(o.gauge_sigma_m > 0) || !(o.gauge_sigma_yaw_rad > 0)) {
    return InvalidArgument("zupt-ins: output_rate_hz and the gauge sigmas must be > 0");
  }
  return Status::Ok();
}

Status ZuptInsDeadReckoning::CheckApplicable(const Walk& walk) const {
  if (walk.meta.imu_placement != ImuPlacement::kFoot) {
    return FailedPrecondition("zupt-ins needs a foot-mounted IMU (imu_placement: foot)");
  }
  if (walk.imu.size() < 10) return FailedPrecondition("zupt-ins needs imu.csv");
  return Status::Ok();
}

StatusOr<EstimateResult> ZuptInsDeadReckoning::Run(const Walk& walk) const {
  WG_RETURN_IF_ERROR(options_.Validate());
  WG_RETURN_IF_ERROR(CheckApplicable(walk));
  WG_ASSIGN_OR_RETURN(ZuptInsSolution s, RunZuptIns(walk, options_.front_end));
  Eigen::Matrix3d P = Eigen::Vector3d(options_.gauge_sigma_m * options_.gauge_sigma_m,
                                      options_.gauge_sigma_m * options_.gauge_sigma_m,
                                      options_.gauge_sigma_yaw_rad * options_.gauge_sigma_yaw_rad)
                          .asDiagonal();
  if (walk.meta.initial_pose) {
    const InitialPose& p0 = *walk.meta.initial_pose;
    P = Eigen::Vector3d(p0.sigma_xy_m * p0.sigma_xy_m, p0.sigma_xy_m * p0.sigma_xy_m,
                        p0.sigma_heading_rad * p0.sigma_heading_rad)
            .asDiagonal();
  }
  // Absolute covariance at the last reset (the reference, then each stride end).
  Eigen::Matrix3d P_base = P;
  Eigen::Vector2d p_base = s.states[0].p_n.head<2>();
  size_t next_stride = 0;
  EstimateResult result;
  const double period = 1.0 / options_.output_rate_hz;
  double next_tick = walk.imu[0].t_s;
  const size_t n = walk.imu.size();
  for (size_t k = 0; k < n; ++k) {
    const NavState& x = s.states[k];
    const Eigen::Vector2d d = x.p_n.head<2>() - p_base;
    Eigen::Matrix3d F = Eigen::Matrix3d::Identity();
    F(0, 2) = -d.y();
    F(1, 2) = d.x();
    Eigen::Matrix3d Pk = F * P_base * F.transpose() + s.stride_covariance[k];
    Pk = 0.5 * (Pk + Pk.transpose());
    const bool stride_end = next_stride < s.stride_end.size() && s.stride_end[next_stride] == k;
    if (stride_end || k + 1 == n || x.t_s + 1e-9 >= next_tick) {
      TrajectoryPoint pt;
      pt.t_s = x.t_s;
      pt.position_m = x.p_n;
      const Eigen::Matrix3d r = x.q_nb.toRotationMatrix();
      pt.heading_rad = NormalizeAngle(std::atan2(r(1, 0), r(0, 0)));
      pt.covariance = Pk;
      result.trajectory.points.push_back(pt);
      while (next_tick <= x.t_s + 1e-9) next_tick += period;
    }
    if (k == s.reference_index || stride_end) {
      P_base = Pk;
      p_base = x.p_n.head<2>();
      if (stride_end) ++next_stride;
    }
  }
  AddFrontEndDiagnostics(s, &result.diagnostics);
  return result;
}

namespace internal {

Status RegisterZuptIns(EstimatorRegistry* registry) {
  return registry->Register(
      {"zupt-ins",
       "ZUPT/ZARU-aided strapdown INS, 15-state error-state EKF (step-wise dead reckoning, "
       "Nilsson et al. 2014; foot IMU)",
       OptionsFactory<ZuptInsDeadReckoning>(
           [](const YAML::Node& config) { return ZuptInsOptionsFromYaml(config); })});
}

}  // namespace internal
}  // namespace walkgraph
