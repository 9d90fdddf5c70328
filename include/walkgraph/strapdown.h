// Strapdown inertial mechanization on a flat, non-rotating Earth (ENU navigation frame).
//
// State: attitude q_nb (unit quaternion, body→nav: v_n = q_nb·v_b), velocity v_n, position p_n.
// IMU model: gyro ω_b (rad/s, body rate w.r.t. nav), accelerometer f_b = R_nbᵀ(a_n − g_n),
// the specific force, g_n = (0, 0, −g): an IMU at rest reads f_b = R_nbᵀ·(0, 0, +g).
// Earth rotation (15 °/h) and transport rate are neglected (MEMS noise dominates indoors).
//
// Two sample conventions (StrapdownOptions::sampling):
// kIntervalAverage (default; integrating IMUs' Δθ/Δv outputs, and the simulator's foot IMU):
// sample k holds ω_k = Log(q_{k−1}⁻¹ q_k)/dt and f_k = Δv_b/dt over (t_{k−1}, t_k], so
//   q_k = q_{k−1} ⊗ Exp(ω_k·dt),   v_k = v_{k−1} + (R_{k−1} f_k + g_n)·dt      (both exact)
// kInstantaneous (point samples):
//   φ = ½(ω_{k−1} + ω_k)·dt + (dt²/12)·(ω_{k−1} × ω_k)   (trapezoid + two-sample coning term)
//   q_k = q_{k−1} ⊗ Exp(φ),   v_k = v_{k−1} + (½(R_{k−1} f_{k−1} + R_k f_k) + g_n)·dt
// Both: p_k = p_{k−1} + ½(v_{k−1} + v_k)·dt (its error telescopes to 0 between still phases).
// Biases are removed from every sample first. Why not point samples everywhere: for a foot
// the trapezoid's attitude error (dt²/12)·θ̈ couples with the swing acceleration and drifts
// ≈1 m per minute at 100 Hz even without noise (measured, strapdown_test).
#ifndef WALKGRAPH_STRAPDOWN_H_
#define WALKGRAPH_STRAPDOWN_H_

#include <string>
#include <utility>
#include <vector>

#include <limits>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "walkgraph/enum_names.h"
#include "walkgraph/walk.h"

namespace walkgraph {

struct NavState {
  double t_s = 0.0;
  Eigen::Quaterniond q_nb = Eigen::Quaterniond::Identity();
  Eigen::Vector3d v_n = Eigen::Vector3d::Zero();
  Eigen::Vector3d p_n = Eigen::Vector3d::Zero();
};

enum class ImuSampling { kIntervalAverage, kInstantaneous };
// Its names in options ("interval-average", "instantaneous"): the one table readers use.
const EnumNames<ImuSampling>& ImuSamplingNames();
const char* ToString(ImuSampling s);
StatusOr<ImuSampling> ImuSamplingFromString(const std::string& name);

struct StrapdownOptions {
  double gravity_mps2 = 9.81;
  ImuSampling sampling = ImuSampling::kIntervalAverage;
  bool coning_correction = true;                            // kInstantaneous only
  Eigen::Vector3d acc_bias_mps2 = Eigen::Vector3d::Zero();  // subtracted from every sample
  Eigen::Vector3d gyro_bias_radps = Eigen::Vector3d::Zero();
  // A longer interval is an IMU gap (ImuGapThresholdS): not integrated; the step holds the
  // position and attitude and sets the velocity to 0 (a foot is most often at rest), and the
  // caller accounts for the time (process noise, a bridge).
  double max_dt_s = std::numeric_limits<double>::infinity();
};

// Exp map of so(3) as a unit quaternion: rotation by |φ| about φ/|φ| (series near 0).
Eigen::Quaterniond QuaternionExp(const Eigen::Vector3d& phi);
// Inverse of QuaternionExp (angle in [0, π]).
Eigen::Vector3d QuaternionLog(const Eigen::Quaterniond& q);
// [v]× with [v]×·w = v × w.
Eigen::Matrix3d Skew(const Eigen::Vector3d& v);

// Advances `state` from sample `prev` to sample `cur` (state.t_s must equal prev.t_s).
NavState StrapdownStep(const NavState& state, const ImuSample& prev, const ImuSample& cur,
                       const StrapdownOptions& options = {});

// Integrates samples[begin..] from `initial` (whose time is samples[begin].t_s); returns one
// state per sample from `begin` on.
std::vector<NavState> IntegrateStrapdown(const NavState& initial,
                                         const std::vector<ImuSample>& samples, size_t begin = 0,
                                         const StrapdownOptions& options = {});

}  // namespace walkgraph

#endif  // WALKGRAPH_STRAPDOWN_H_
