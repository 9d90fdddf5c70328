// What an estimator returns: timestamped planar poses with their covariances.
#ifndef WALKGRAPH_TRAJECTORY_H_
#define WALKGRAPH_TRAJECTORY_H_

#include <optional>
#include <vector>

#include <Eigen/Core>

namespace walkgraph {

struct TrajectoryPoint {
  double t_s = 0.0;
  Eigen::Vector3d position_m = Eigen::Vector3d::Zero();  // z = 0 for planar estimators
  double heading_rad = 0.0;
  // Covariance of (x, y, heading); absent when the estimator has none (e.g. a raw fix).
  std::optional<Eigen::Matrix3d> covariance;
  // The floor the estimator puts the walker on (multi-floor estimators; see Walk::StartFloor
  // for how an estimate without one is scored).
  std::optional<int> floor;
};

struct Trajectory {
  std::vector<TrajectoryPoint> points;  // strictly increasing t_s

  bool empty() const { return points.empty(); }
  size_t size() const { return points.size(); }
  // Position at time t, linearly interpolated; clamped to the ends outside the span.
  // Requires a non-empty trajectory.
  Eigen::Vector3d PositionAt(double t_s) const;
  // The (x, y) block of the covariance at time t, interpolated and clamped like PositionAt;
  // nullopt when a bracketing point has no covariance. Requires a non-empty trajectory.
  std::optional<Eigen::Matrix2d> PositionCovarianceAt(double t_s) const;
  // The floor of the point nearest in time to t (floors do not interpolate); nullopt when that
  // point has none. Requires a non-empty trajectory.
  std::optional<int> FloorAt(double t_s) const;

 private:
  struct Bracket {
    size_t a, b;  // the points around t (equal at and beyond the ends)
    double w;     // weight of b
  };
  Bracket BracketAt(double t_s) const;
};

}  // namespace walkgraph

#endif  // WALKGRAPH_TRAJECTORY_H_
