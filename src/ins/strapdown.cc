#include "walkgraph/strapdown.h"

#include <cmath>

#include "util/enum_define.h"

namespace walkgraph {

WALKGRAPH_DEFINE_ENUM_NAMES(ImuSampling, "imu_sampling",
                            {"interval-average", ImuSampling::kIntervalAverage},
                            {"instantaneous", ImuSampling::kInstantaneous})

Eigen::Quaterniond QuaternionExp(const Eigen::Vector3d& phi) {
  const double a = phi.norm();
  double c, k;  // q = (cos(a/2), k·φ) with k = sin(a/2)/a
  if (a < 1e-6) {
    c = 1.0 - a * a / 8.0;
    k = 0.5 - a * a / 48.0;
  } else {
    c = std::cos(0.5 * a);
    k = std::sin(0.5 * a) / a;
  }
  Eigen::Quaterniond q(c, k * phi.x(), k * phi.y(), k * phi.z());
  q.normalize();
  return q;
}

Eigen::Vector3d QuaternionLog(const Eigen::Quaterniond& q_in) {
  Eigen::Quaterniond q = q_in.normalized();
  if (q.w() < 0.0) q.coeffs() = -q.coeffs();
  const double n = q.vec().norm();
  if (n < 1e-12) return 2.0 * q.vec();
  return 2.0 * std::atan2(n, q.w()) / n * q.vec();
}

Eigen::Matrix3d Skew(const Eigen::Vector3d& v) {
  Eigen::Matrix3d m;
  m << 0.0, -v.z(), v.y(), v.z(), 0.0, -v.x(), -v.y(), v.x(), 0.0;
  return m;
}

NavState StrapdownStep(const NavState& s, const ImuSample& prev, const ImuSample& cur,
                       const StrapdownOptions& o) {
  const double dt = cur.t_s - prev.t_s;
  if (dt > o.max_dt_s) {
    NavState held = s;
    held.t_s = cur.t_s;
    held.v_n.setZero();
    return held;
  }
  const Eigen::Vector3d w0 = prev.gyro_radps - o.gyro_bias_radps;
  const Eigen::Vector3d w1 = cur.gyro_radps - o.gyro_bias_radps;
  const Eigen::Vector3d f0 = prev.acc_mps2 - o.acc_bias_mps2;
  const Eigen::Vector3d f1 = cur.acc_mps2 - o.acc_bias_mps2;
  const Eigen::Vector3d g_n(0.0, 0.0, -o.gravity_mps2);
  NavState n;
  n.t_s = cur.t_s;
  Eigen::Vector3d a_n;
  if (o.sampling == ImuSampling::kIntervalAverage) {
    n.q_nb = (s.q_nb * QuaternionExp(w1 * dt)).normalized();
    a_n = s.q_nb * f1 + g_n;
  } else {
    Eigen::Vector3d phi = 0.5 * (w0 + w1) * dt;
    if (o.coning_correction) phi += (dt * dt / 12.0) * w0.cross(w1);
    n.q_nb = (s.q_nb * QuaternionExp(phi)).normalized();
    a_n = 0.5 * (s.q_nb * f0 + n.q_nb * f1) + g_n;
  }
  n.v_n = s.v_n + a_n * dt;
  n.p_n = s.p_n + 0.5 * (s.v_n + n.v_n) * dt;
  return n;
}

std::vector<NavState> IntegrateStrapdown(const NavState& initial,
                                         const std::vector<ImuSample>& samples, size_t begin,
                                         const StrapdownOptions& options) {
  std::vector<NavState> out;
  if (begin >= samples.size()) return out;
  out.reserve(samples.size() - begin);
  out.push_back(initial);
  for (size_t k = begin + 1; k < samples.size(); ++k) {
    out.push_back(StrapdownStep(out.back(), samples[k - 1], samples[k], options));
  }
  return out;
}

}  // namespace walkgraph
