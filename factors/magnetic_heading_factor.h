// MagneticHeadingFactor: at a stance the foot is flat and still, so its magnetometer reading,
// rotated into the navigation frame, points along the local field's horizontal direction; with
// the field the same everywhere (indoors: up to local disturbances) that direction is one
// walk-wide angle ψ_f, a state of the graph. Residual, the angle from the field direction to the
// reading's:
//
//   f = (cos ψ_f, sin ψ_f),  u = [R(q) m]_xy,   r = atan2(f × u, f · u) / σ,
//
// m the magnetometer reading (µT, body frame) at the state, R(q) the state's body-to-navigation
// rotation (q in Eigen storage order x, y, z, w, as InsState). In (−π, π]: no wrap needed,
// smooth away from u = 0. This is 004's compass update at stance (Jiménez et al., Algorithm 1
// lines 10–11: z = α_N − α(R̂ m_b)) with the reference direction α_N estimated instead of given
// (the walk's frame is its own; the declination and the building's field are unknown). The
// caller learns σ from the walk and puts the factor under a robust loss (ins_graph.cc).
// Parameter blocks: q (4), ψ_f (1).
#ifndef WALKGRAPH_FACTORS_MAGNETIC_HEADING_FACTOR_H_
#define WALKGRAPH_FACTORS_MAGNETIC_HEADING_FACTOR_H_

#include <ceres/autodiff_cost_function.h>
#include <ceres/jet.h>
#include <Eigen/Core>
#include <Eigen/Geometry>

namespace walkgraph {

class MagneticHeadingFactor {
 public:
  MagneticHeadingFactor(const Eigen::Vector3d& mag, double sigma_rad)
      : mag_(mag), inv_sigma_(1.0 / sigma_rad) {}

  template <typename T>
  bool operator()(const T* q, const T* field_yaw, T* residual) const {
    using std::atan2;
    using std::cos;
    using std::sin;
    const Eigen::Quaternion<T> r(q[3], q[0], q[1], q[2]);
    // A unit quaternion on the manifold; normalized here so the factor also reads a raw block.
    const Eigen::Matrix<T, 3, 1> u = r.normalized() * mag_.cast<T>();
    const T fx = cos(field_yaw[0]), fy = sin(field_yaw[0]);
    residual[0] = atan2(fx * u.y() - fy * u.x(), fx * u.x() + fy * u.y()) * T(inv_sigma_);
    return true;
  }

  static ceres::CostFunction* Create(const Eigen::Vector3d& mag, double sigma_rad) {
    return new ceres::AutoDiffCostFunction<MagneticHeadingFactor, 1, 4, 1>(
        new MagneticHeadingFactor(mag, sigma_rad));
  }

 private:
  Eigen::Vector3d mag_;
  double inv_sigma_;
};

}  // namespace walkgraph

#endif  // WALKGRAPH_FACTORS_MAGNETIC_HEADING_FACTOR_H_
