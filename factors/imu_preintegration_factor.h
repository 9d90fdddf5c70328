// On-manifold IMU preintegration between two navigation states (Forster, Carlone, Dellaert,
// Scaramuzza, "On-Manifold Preintegration for Real-Time Visual-Inertial Odometry", IEEE T-RO
// 2017; equation numbers are that paper's).
//
// States x = (p, v, q, b_g, b_a) in the ENU frame, q = q_nb body → nav (NavQuaternionManifold),
// gravity g_n = (0, 0, −g). Over the IMU intervals k of (t_i, t_j] with readings ω̃_k, f̃_k
// (interval averages, strapdown.h kIntervalAverage) and the linearization-point biases b̄:
//   ΔR_{k+1} = ΔR_k·Exp((ω̃_k − b̄_g)δt),
//   Δv_{k+1} = Δv_k + ΔR_k (f̃_k − b̄_a) δt,
//   Δp_{k+1} = Δp_k + Δv_k δt + ½ ΔR_k (f̃_k − b̄_a) δt²                              (eq. 37–38)
// Noise (per-reading white σ_g, σ_a; δφ with ΔR̃ = ΔR·Exp(δφ)), ordering (δφ, δv, δp):
//   Σ ← A Σ Aᵀ + B σ_g² Bᵀ + C σ_a² Cᵀ,                                                (eq. 63)
//   A = [ΔR_{k,k+1}ᵀ 0 0; −ΔR_k[a]×δt I 0; −½ΔR_k[a]×δt² Iδt I],
//   B = [J_r(ωδt)δt; 0; 0],  C = [0; ΔR_k δt; ½ΔR_k δt²],
// a = f̃_k − b̄_a, ω = ω̃_k − b̄_g, J_r the right Jacobian of SO(3). With SetScaleNoise(s_g, s_a)
// each reading's σ² grows by (s·‖reading‖)²: σ_g,k² = σ_g² + s_g²‖ω̃_k‖², σ_a,k² = σ_a² +
// s_a²‖f̃_k‖² (our addition, not Forster's: a scale-factor-like error treated as white). Bias
// Jacobians, recursively (App. B, eq. 69–70 in their incremental form):
//   ∂Δp/∂b_a += ∂Δv/∂b_a δt − ½ΔR_k δt²,   ∂Δp/∂b_g += ∂Δv/∂b_g δt − ½ΔR_k[a]×∂ΔR/∂b_g δt²,
//   ∂Δv/∂b_a −= ΔR_k δt,                  ∂Δv/∂b_g −= ΔR_k[a]×∂ΔR/∂b_g δt,
//   ∂ΔR/∂b_g ← ΔR_{k,k+1}ᵀ ∂ΔR/∂b_g − J_r(ωδt) δt.
// Residual (eq. 45), with the first-order bias update δb = b_i − b̄ (eq. 44):
//   r_ΔR = Log( (ΔR·Exp(∂ΔR/∂b_g δb_g))ᵀ R_iᵀ R_j )
//   r_Δv = R_iᵀ (v_j − v_i − g_n Δt) − (Δv + ∂Δv/∂b_g δb_g + ∂Δv/∂b_a δb_a)
//   r_Δp = R_iᵀ (p_j − p_i − v_i Δt − ½ g_n Δt²) − (Δp + ∂Δp/∂b_g δb_g + ∂Δp/∂b_a δb_a)
//   cost = ‖S (r_ΔR, r_Δv, r_Δp)‖²,  S = Σ^{-1/2} (upper Cholesky factor of Σ⁻¹).
// The biases of state j do not enter (the bias random-walk factor links b_i and b_j). When the
// optimized b_i moves far from b̄, re-preintegrate with b̄ = b_i (the caller's choice).
// Parameter blocks: p_i(3), v_i(3), q_i(4), b_g,i(3), b_a,i(3), p_j(3), v_j(3), q_j(4).
// The hand-written parts are the bias Jacobians and the covariance recursion (checked against
// re-integration by numeric differences in ins_factors_test); the residual's Jacobians are
// automatic.
#ifndef WALKGRAPH_FACTORS_IMU_PREINTEGRATION_FACTOR_H_
#define WALKGRAPH_FACTORS_IMU_PREINTEGRATION_FACTOR_H_

#include <cmath>

#include <ceres/autodiff_cost_function.h>
#include <Eigen/Cholesky>
#include <Eigen/Core>
#include <Eigen/Geometry>

#include "factors/nav_quaternion_manifold.h"
#include "walkgraph/strapdown.h"

namespace walkgraph {

// Right Jacobian of SO(3): J_r(φ) = I − (1 − cos θ)/θ² [φ]× + (θ − sin θ)/θ³ [φ]×².
inline Eigen::Matrix3d SO3RightJacobian(const Eigen::Vector3d& phi) {
  const double theta = phi.norm();
  const Eigen::Matrix3d K = Skew(phi);
  if (theta < 1e-5) return Eigen::Matrix3d::Identity() - 0.5 * K + K * K / 6.0;
  const double t2 = theta * theta;
  return Eigen::Matrix3d::Identity() - (1.0 - std::cos(theta)) / t2 * K +
         (theta - std::sin(theta)) / (t2 * theta) * K * K;
}

class ImuPreintegration {
 public:
  using Matrix9d = Eigen::Matrix<double, 9, 9>;

  // Linearization-point biases and the readings' white-noise σ (per reading, each axis).
  ImuPreintegration(const Eigen::Vector3d& gyro_bias_radps, const Eigen::Vector3d& acc_bias_mps2,
                    double gyro_noise_radps, double acc_noise_mps2)
      : bg_(gyro_bias_radps),
        ba_(acc_bias_mps2),
        sigma_g2_(gyro_noise_radps * gyro_noise_radps),
        sigma_a2_(acc_noise_mps2 * acc_noise_mps2) {}

  // Scale-factor noise: each reading's σ² gains (s·‖reading‖)², s relative (e.g. 0.01 = 1 %),
  // for what the white noise leaves out and grows with the motion (scale factor, axis
  // misalignment, g-sensitivity, vibration at heel strike); treated as white, per reading.
  void SetScaleNoise(double gyro_scale, double acc_scale) {
    gyro_scale2_ = gyro_scale * gyro_scale;
    acc_scale2_ = acc_scale * acc_scale;
  }

  // One interval of length dt with its (average) rate and specific force, body frame.
  void Integrate(double dt, const Eigen::Vector3d& gyro_radps, const Eigen::Vector3d& acc_mps2) {
    const Eigen::Vector3d w = gyro_radps - bg_;
    const Eigen::Vector3d a = acc_mps2 - ba_;
    const Eigen::Matrix3d dR = dq_.toRotationMatrix();
    const Eigen::Matrix3d ax = Skew(a);
    const Eigen::Quaterniond step = QuaternionExp(w * dt);
    const Eigen::Matrix3d step_t = step.toRotationMatrix().transpose();
    const Eigen::Matrix3d jr = SO3RightJacobian(w * dt);
    // Covariance (eq. 63), order (δφ, δv, δp).
    Matrix9d A = Matrix9d::Identity();
    A.block<3, 3>(0, 0) = step_t;
    A.block<3, 3>(3, 0) = -dR * ax * dt;
    A.block<3, 3>(6, 0) = -0.5 * dR * ax * dt * dt;
    A.block<3, 3>(6, 3) = Eigen::Matrix3d::Identity() * dt;
    Eigen::Matrix<double, 9, 3> B = Eigen::Matrix<double, 9, 3>::Zero();
    Eigen::Matrix<double, 9, 3> C = Eigen::Matrix<double, 9, 3>::Zero();
    B.block<3, 3>(0, 0) = jr * dt;
    C.block<3, 3>(3, 0) = dR * dt;
    C.block<3, 3>(6, 0) = 0.5 * dR * dt * dt;
    const double sg2 = sigma_g2_ + gyro_scale2_ * gyro_radps.squaredNorm();
    const double sa2 = sigma_a2_ + acc_scale2_ * acc_mps2.squaredNorm();
    cov_ = A * cov_ * A.transpose() + sg2 * B * B.transpose() + sa2 * C * C.transpose();
    cov_ = 0.5 * (cov_ + cov_.transpose());
    // Bias Jacobians (App. B), before Δv and ΔR move on.
    dp_dba_ += dv_dba_ * dt - 0.5 * dR * dt * dt;
    dp_dbg_ += dv_dbg_ * dt - 0.5 * dR * ax * dR_dbg_ * dt * dt;
    dv_dba_ -= dR * dt;
    dv_dbg_ -= dR * ax * dR_dbg_ * dt;
    dR_dbg_ = step_t * dR_dbg_ - jr * dt;
    // Measurements (eq. 37–38).
    dp_ += dv_ * dt + 0.5 * dR * a * dt * dt;
    dv_ += dR * a * dt;
    dq_ = (dq_ * step).normalized();
    dt_ += dt;
  }

  // Adds q to the covariance of (δφ, δv, δp): what the readings do not tell, e.g. across a gap.
  void AddCovariance(const Matrix9d& q) {
    cov_ += q;
    cov_ = 0.5 * (cov_ + cov_.transpose());
  }

  double dt_s() const { return dt_; }
  const Eigen::Quaterniond& delta_q() const { return dq_; }
  const Eigen::Vector3d& delta_v() const { return dv_; }
  const Eigen::Vector3d& delta_p() const { return dp_; }
  const Eigen::Vector3d& gyro_bias() const { return bg_; }
  const Eigen::Vector3d& acc_bias() const { return ba_; }
  const Eigen::Matrix3d& dR_dbg() const { return dR_dbg_; }
  const Eigen::Matrix3d& dv_dbg() const { return dv_dbg_; }
  const Eigen::Matrix3d& dv_dba() const { return dv_dba_; }
  const Eigen::Matrix3d& dp_dbg() const { return dp_dbg_; }
  const Eigen::Matrix3d& dp_dba() const { return dp_dba_; }
  // Σ of (δφ, δv, δp).
  const Matrix9d& covariance() const { return cov_; }

  // State j predicted from state i with the first-order bias correction (eq. 44), e.g. to
  // initialise a new state: R_j = R_i ΔR(b), v_j = v_i + g Δt + R_i Δv(b),
  // p_j = p_i + v_i Δt + ½ g Δt² + R_i Δp(b).
  void Predict(const Eigen::Vector3d& p_i, const Eigen::Vector3d& v_i,
               const Eigen::Quaterniond& q_i, const Eigen::Vector3d& bg_i,
               const Eigen::Vector3d& ba_i, double gravity_mps2, Eigen::Vector3d* p_j,
               Eigen::Vector3d* v_j, Eigen::Quaterniond* q_j) const {
    const Eigen::Vector3d dbg = bg_i - bg_, dba = ba_i - ba_;
    const Eigen::Vector3d g(0.0, 0.0, -gravity_mps2);
    *q_j = (q_i * dq_ * QuaternionExp(dR_dbg_ * dbg)).normalized();
    *v_j = v_i + g * dt_ + q_i * (dv_ + dv_dbg_ * dbg + dv_dba_ * dba);
    *p_j = p_i + v_i * dt_ + 0.5 * g * dt_ * dt_ + q_i * (dp_ + dp_dbg_ * dbg + dp_dba_ * dba);
  }

 private:
  Eigen::Vector3d bg_, ba_;
  double sigma_g2_, sigma_a2_;
  double gyro_scale2_ = 0.0, acc_scale2_ = 0.0;
  double dt_ = 0.0;
  Eigen::Quaterniond dq_ = Eigen::Quaterniond::Identity();
  Eigen::Vector3d dv_ = Eigen::Vector3d::Zero(), dp_ = Eigen::Vector3d::Zero();
  Eigen::Matrix3d dR_dbg_ = Eigen::Matrix3d::Zero(), dv_dbg_ = Eigen::Matrix3d::Zero(),
                  dv_dba_ = Eigen::Matrix3d::Zero(), dp_dbg_ = Eigen::Matrix3d::Zero(),
                  dp_dba_ = Eigen::Matrix3d::Zero();
  Matrix9d cov_ = Matrix9d::Zero();
};

class ImuPreintegrationFactor {
 public:
  using Matrix9d = Eigen::Matrix<double, 9, 9>;

  // `regularization` is added to Σ's diagonal before inverting (a segment of one interval has
  // Δp and Δv perfectly correlated; 1e-12 is σ = 1 µm, 1 µm/s, 1 µrad).
  ImuPreintegrationFactor(const ImuPreintegration& pim, double gravity_mps2,
                          double regularization = 1e-12)
      : pim_(pim), gravity_(gravity_mps2) {
    const Matrix9d cov = pim.covariance() + regularization * Matrix9d::Identity();
    const Matrix9d info = cov.inverse();
    sqrt_info_ = Eigen::LLT<Matrix9d>(0.5 * (info + info.transpose())).matrixU();
  }

  template <typename T>
  bool operator()(const T* p_i, const T* v_i, const T* q_i, const T* bg_i, const T* ba_i,
                  const T* p_j, const T* v_j, const T* q_j, T* residual) const {
    using Vec3 = Eigen::Matrix<T, 3, 1>;
    Eigen::Map<const Vec3> pi(p_i), vi(v_i), bgi(bg_i), bai(ba_i), pj(p_j), vj(v_j);
    Eigen::Map<const Eigen::Quaternion<T>> qi(q_i), qj(q_j);
    const Vec3 dbg = bgi - pim_.gyro_bias().cast<T>();
    const Vec3 dba = bai - pim_.acc_bias().cast<T>();
    const Vec3 g(T(0.0), T(0.0), T(-gravity_));
    const T dt(pim_.dt_s());
    // eq. 44: first-order bias correction of the preintegrated measurements.
    const Vec3 dbg_rot = pim_.dR_dbg().cast<T>() * dbg;
    const Eigen::Quaternion<T> dq_corr = pim_.delta_q().cast<T>() * SO3Exp(dbg_rot);
    const Vec3 dv_corr =
        pim_.delta_v().cast<T>() + pim_.dv_dbg().cast<T>() * dbg + pim_.dv_dba().cast<T>() * dba;
    const Vec3 dp_corr =
        pim_.delta_p().cast<T>() + pim_.dp_dbg().cast<T>() * dbg + pim_.dp_dba().cast<T>() * dba;
    // eq. 45.
    const Eigen::Quaternion<T> qi_inv = qi.conjugate();
    Eigen::Matrix<T, 9, 1> r;
    r.template segment<3>(0) = SO3Log(Eigen::Quaternion<T>(dq_corr.conjugate() * qi_inv * qj));
    r.template segment<3>(3) = qi_inv * (vj - vi - g * dt) - dv_corr;
    r.template segment<3>(6) = qi_inv * (pj - pi - vi * dt - T(0.5) * g * dt * dt) - dp_corr;
    Eigen::Map<Eigen::Matrix<T, 9, 1>> out(residual);
    out = sqrt_info_.cast<T>() * r;
    return true;
  }

  static ceres::CostFunction* Create(const ImuPreintegration& pim, double gravity_mps2,
                                     double regularization = 1e-12) {
    return new ceres::AutoDiffCostFunction<ImuPreintegrationFactor, 9, 3, 3, 4, 3, 3, 3, 3, 4>(
        new ImuPreintegrationFactor(pim, gravity_mps2, regularization));
  }

 private:
  ImuPreintegration pim_;
  double gravity_;
  Matrix9d sqrt_info_;
};

}  // namespace walkgraph

#endif  // WALKGRAPH_FACTORS_IMU_PREINTEGRATION_FACTOR_H_
