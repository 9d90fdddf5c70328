// Rotations for the foot-INS graph: unit quaternions q_nb (body → navigation, Eigen storage
// order x, y, z, w) perturbed in the navigation frame by a full-angle rotation vector δ ∈ R³:
//
//   q ⊞ δ = Exp(δ) ⊗ q,        y ⊟ x = Log(y ⊗ x⁻¹),
//   Exp(δ) = (cos(|δ|/2), sin(|δ|/2)·δ/|δ|),   Log the inverse (angle in [0, π]).
//
// Why not ceres::EigenQuaternionManifold: that one perturbs by (cos|δ|, sin|δ|·δ/|δ|), i.e. by
// the HALF angle, so its tangent-space covariances are a quarter of the rotation-vector ones.
// Here the tangent is exactly the navigation-frame attitude error δθ of the error-state EKF
// (strides.h, R = Exp(δθ)·R̂): covariances from ceres::Covariance read as rad², and δ_z is the
// yaw error. Plus/Minus Jacobians come from ceres::AutoDiffManifold (no hand-written Jacobian).
//
// Also here, templated for ceres::Jet: SO3Exp, SO3Log and QuaternionYaw (the ENU angle of the
// body x axis on the horizontal, atan2(R₁₀, R₀₀)).
#ifndef WALKGRAPH_FACTORS_NAV_QUATERNION_MANIFOLD_H_
#define WALKGRAPH_FACTORS_NAV_QUATERNION_MANIFOLD_H_

#include <cmath>

#include <ceres/autodiff_manifold.h>
#include <ceres/manifold.h>
#include <Eigen/Core>
#include <Eigen/Geometry>

namespace walkgraph {

template <typename T>
Eigen::Quaternion<T> SO3Exp(const Eigen::Matrix<T, 3, 1>& phi) {
  using std::cos;
  using std::sin;
  using std::sqrt;
  const T theta_sq = phi.squaredNorm();
  T w, k;  // q = (w, k·φ)
  if (theta_sq < T(1e-12)) {
    // Series of cos(θ/2) and sin(θ/2)/θ: exact to O(θ⁴), derivatives right at φ = 0.
    w = T(1.0) - theta_sq / T(8.0);
    k = T(0.5) - theta_sq / T(48.0);
  } else {
    const T theta = sqrt(theta_sq);
    w = cos(theta / T(2.0));
    k = sin(theta / T(2.0)) / theta;
  }
  return Eigen::Quaternion<T>(w, k * phi.x(), k * phi.y(), k * phi.z());
}

template <typename T>
Eigen::Matrix<T, 3, 1> SO3Log(const Eigen::Quaternion<T>& q_in) {
  using std::atan2;
  using std::sqrt;
  Eigen::Quaternion<T> q = q_in;
  if (q.w() < T(0.0)) q.coeffs() = -q.coeffs();  // the same rotation, angle in [0, π]
  const T n_sq = q.vec().squaredNorm();
  if (n_sq < T(1e-12)) {
    // 2·atan2(n, w)/n → 2/w (1 − n²/(3w²)) as n → 0.
    return (T(2.0) / q.w() * (T(1.0) - n_sq / (T(3.0) * q.w() * q.w()))) * q.vec();
  }
  const T n = sqrt(n_sq);
  return (T(2.0) * atan2(n, q.w()) / n) * q.vec();
}

template <typename T>
T QuaternionYaw(const Eigen::Quaternion<T>& q) {
  using std::atan2;
  // R₀₀ and R₁₀ scaled by ‖q‖²: the same angle for any scale of q.
  const T r00 = q.w() * q.w() + q.x() * q.x() - q.y() * q.y() - q.z() * q.z();
  const T r10 = T(2.0) * (q.x() * q.y() + q.w() * q.z());
  return atan2(r10, r00);
}

// The Plus/Minus functor of NavQuaternionManifold (storage x, y, z, w).
struct NavQuaternionPlus {
  template <typename T>
  bool Plus(const T* x, const T* delta, T* x_plus_delta) const {
    Eigen::Map<const Eigen::Quaternion<T>> q(x);
    const Eigen::Matrix<T, 3, 1> d(delta[0], delta[1], delta[2]);
    Eigen::Map<Eigen::Quaternion<T>> out(x_plus_delta);
    out = SO3Exp(d) * q;
    return true;
  }
  template <typename T>
  bool Minus(const T* y, const T* x, T* y_minus_x) const {
    Eigen::Map<const Eigen::Quaternion<T>> qy(y), qx(x);
    Eigen::Map<Eigen::Matrix<T, 3, 1>> out(y_minus_x);
    out = SO3Log(Eigen::Quaternion<T>(qy * qx.conjugate()));
    return true;
  }
};

using NavQuaternionManifold = ceres::AutoDiffManifold<NavQuaternionPlus, 4, 3>;

}  // namespace walkgraph

#endif  // WALKGRAPH_FACTORS_NAV_QUATERNION_MANIFOLD_H_
