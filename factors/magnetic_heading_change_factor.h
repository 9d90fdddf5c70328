// MagneticHeadingChangeFactor: the magnetic field's horizontal direction in the navigation
// frame is the same at two instants, so the magnetometer relates the yaw of two states that
// nothing else links (either side of an IMU gap, where the gyro says nothing):
//
//   u = [R(q_a) m_a]_xy,  v = [R(q_b) m_b]_xy,   r = atan2(u × v, u · v) / σ,
//
// m_a, m_b the magnetometer readings (µT, body frame) at the two states, R(q) the states'
// body-to-navigation rotations (q in Eigen storage order x, y, z, w, as InsState). The residual
// is the angle from u to v, in (−π, π]: no wrap needed, smooth away from u or v = 0. Indoor
// disturbances make the field's direction differ between places; σ says by how much (the
// caller learns it from the walk, ins_graph.cc). Parameter blocks: q_a (4), q_b (4).
#ifndef WALKGRAPH_FACTORS_MAGNETIC_HEADING_CHANGE_FACTOR_H_
#define WALKGRAPH_FACTORS_MAGNETIC_HEADING_CHANGE_FACTOR_H_

#include <ceres/autodiff_cost_function.h>
#include <ceres/jet.h>
#include <Eigen/Core>
#include <Eigen/Geometry>

namespace walkgraph {

class MagneticHeadingChangeFactor {
 public:
  MagneticHeadingChangeFactor(const Eigen::Vector3d& mag_a, const Eigen::Vector3d& mag_b,
                              double sigma_rad)
      : mag_a_(mag_a), mag_b_(mag_b), inv_sigma_(1.0 / sigma_rad) {}

  template <typename T>
  bool operator()(const T* q_a, const T* q_b, T* residual) const {
    using std::atan2;
    const Eigen::Quaternion<T> ra(q_a[3], q_a[0], q_a[1], q_a[2]);
    const Eigen::Quaternion<T> rb(q_b[3], q_b[0], q_b[1], q_b[2]);
    // Unit quaternions on the manifold; normalized here so the factor also reads a raw block.
    const Eigen::Matrix<T, 3, 1> u = ra.normalized() * mag_a_.cast<T>();
    const Eigen::Matrix<T, 3, 1> v = rb.normalized() * mag_b_.cast<T>();
    const T cross = u.x() * v.y() - u.y() * v.x();
    const T dot = u.x() * v.x() + u.y() * v.y();
    residual[0] = atan2(cross, dot) * T(inv_sigma_);
    return true;
  }

  static ceres::CostFunction* Create(const Eigen::Vector3d& mag_a, const Eigen::Vector3d& mag_b,
                                     double sigma_rad) {
    return new ceres::AutoDiffCostFunction<MagneticHeadingChangeFactor, 1, 4, 4>(
        new MagneticHeadingChangeFactor(mag_a, mag_b, sigma_rad));
  }

 private:
  Eigen::Vector3d mag_a_, mag_b_;
  double inv_sigma_;
};

}  // namespace walkgraph

#endif  // WALKGRAPH_FACTORS_MAGNETIC_HEADING_CHANGE_FACTOR_H_
