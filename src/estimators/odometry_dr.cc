#include <cmath>

#include <Eigen/Core>

#include "config/parsers.h"
#include "estimators/builtin.h"
#include "walkgraph/angle.h"
#include "walkgraph/config.h"
#include "walkgraph/dead_reckoning.h"

namespace walkgraph {

StatusOr<OdometryDeadReckoningOptions> OdometryDeadReckoningOptionsFromYaml(
    const YAML::Node& node) {
  OdometryDeadReckoningOptions o;
  ConfigReader r(node, "odometry-dr");
  r.Read("sigma_dist_frac", &o.sigma_dist_frac,
         "distance noise per increment, fraction of its length");
  r.Read("sigma_dist_m", &o.sigma_dist_m, "constant distance noise per increment");
  r.Read("sigma_dheading_rad", &o.sigma_dheading_rad, "heading-increment noise per increment");
  WG_RETURN_IF_ERROR(r.Finish());
  WG_RETURN_IF_ERROR(o.Validate());
  return o;
}

Status OdometryDeadReckoningOptions::Validate() const {
  const OdometryDeadReckoningOptions& o = *this;
  if (o.sigma_dist_frac < 0 || o.sigma_dist_m < 0 || o.sigma_dheading_rad < 0) {
    return InvalidArgument("odometry-dr: sigmas must be >= 0");
  }
  return Status::Ok();
}

Status OdometryDeadReckoning::CheckApplicable(const Walk& walk) const {
  if (!walk.has_odometry()) return FailedPrecondition("odometry-dr needs odometry.csv");
  if (!walk.meta.initial_pose || !walk.meta.initial_pose->heading_known) {
    return FailedPrecondition(
        "odometry-dr needs initial_pose in walk.yaml with a heading (a known start pose)");
  }
  return Status::Ok();
}

StatusOr<EstimateResult> OdometryDeadReckoning::Run(const Walk& walk) const {
  WG_RETURN_IF_ERROR(options_.Validate());
  WG_RETURN_IF_ERROR(CheckApplicable(walk));
  const InitialPose& p0 = *walk.meta.initial_pose;
  Eigen::Vector3d x(p0.x_m, p0.y_m, p0.heading_rad);
  Eigen::Matrix3d P = Eigen::Vector3d(p0.sigma_xy_m * p0.sigma_xy_m, p0.sigma_xy_m * p0.sigma_xy_m,
                                      p0.sigma_heading_rad * p0.sigma_heading_rad)
                          .asDiagonal();
  EstimateResult result;
  auto emit = [&](double t) {
    TrajectoryPoint pt;
    pt.t_s = t;
    pt.position_m = Eigen::Vector3d(x[0], x[1], 0.0);
    pt.heading_rad = x[2];
    pt.covariance = P;
    result.trajectory.points.push_back(pt);
  };
  // The known start pose, at the walk's start time when that precedes the first increment.
  const double t_start = walk.StartTime();
  if (t_start < walk.odometry.front().t_s) emit(t_start);
  for (const OdometrySample& s : walk.odometry) {
    const double c = std::cos(x[2]), sn = std::sin(x[2]);
    Eigen::Matrix3d F = Eigen::Matrix3d::Identity();
    F(0, 2) = -s.dist_m * sn;
    F(1, 2) = s.dist_m * c;
    Eigen::Matrix<double, 3, 2> G = Eigen::Matrix<double, 3, 2>::Zero();
    G(0, 0) = c;
    G(1, 0) = sn;
    G(2, 1) = 1.0;
    const double sd = options_.sigma_dist_frac * s.dist_m + options_.sigma_dist_m;
    const Eigen::Vector2d q(sd * sd, options_.sigma_dheading_rad * options_.sigma_dheading_rad);
    x[0] += s.dist_m * c;
    x[1] += s.dist_m * sn;
    x[2] = NormalizeAngle(x[2] + s.dheading_rad);
    P = F * P * F.transpose() + G * q.asDiagonal() * G.transpose();
    P = (0.5 * (P + P.transpose())).eval();
    emit(s.t_s);
  }
  return result;
}

namespace internal {

Status RegisterOdometryDeadReckoning(EstimatorRegistry* registry) {
  return registry->Register({"odometry-dr", "dead reckoning from odometry increments (no radio)",
                             OptionsFactory<OdometryDeadReckoning>([](const YAML::Node& config) {
                               return OdometryDeadReckoningOptionsFromYaml(config);
                             })});
}

}  // namespace internal
}  // namespace walkgraph
