// Shared Kalman-filter machinery (one place, not copies): the papers' filters (filters/), the
// foot-INS front end (ins/) and the smoothers use it; it sits below them. The driver that runs a
// filter model over a walk is kalman_driver.h.
//
// Measurement update in Joseph form (stable for any gain, keeps P symmetric PD):
//   S = H P Hᵀ + R,  K = P Hᵀ S⁻¹,  x ← x + K ν,
//   P ← (I − K H) P (I − K H)ᵀ + K R Kᵀ,  then P ← (P + Pᵀ)/2.
// Normalized innovation squared NIS = νᵀ S⁻¹ ν ~ χ²(m) for a consistent filter. Innovation
// gating (Mahalanobis): the update is rejected when NIS > χ²_m⁻¹(p_gate), the p_gate quantile
// of the chi-square distribution with m = dim(ν) degrees of freedom (p_gate ≤ 0 disables it).
//
// Rauch–Tung–Striebel smoother over a filter's recorded priors and posteriors:
//   C_k = P_{k|k} F_{k+1}ᵀ P_{k+1|k}⁻¹,
//   x_{k|N} = x_{k|k} + C_k (x_{k+1|N} − x_{k+1|k}),
//   P_{k|N} = P_{k|k} + C_k (P_{k+1|N} − P_{k+1|k}) C_kᵀ,
// where F_{k+1} is the transition Jacobian from step k to k+1. Angle components (listed by
// index) are differenced through NormalizeAngle. With stochastic cloning (a filter that carries
// a clone of its state at the last epoch) the epoch supplies the cross-covariance
// P_{k+1,k} = Cov(x_{k+1|k+1}, x_{k|k+1}) instead, x_{k|k} and P_{k|k} being the clone's
// x_{k|k+1}, P_{k|k+1} and x_{k+1|k} its chart origin; then C_k = P_{k+1,k}ᵀ P_{k+1|k}⁻¹.
#ifndef WALKGRAPH_KALMAN_H_
#define WALKGRAPH_KALMAN_H_

#include <map>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "walkgraph/status.h"

namespace walkgraph {

// P ← (P + Pᵀ)/2.
void Symmetrize(Eigen::MatrixXd* P);

// Quantile x with F_χ²(x; dof) = p, for p in (0, 1) and dof ≥ 1: the root of the regularized
// lower incomplete gamma P(dof/2, x/2) = p (Eigen's igamma), found by bracketing and bisection to
// machine precision.
double ChiSquareQuantile(double p, int dof);

struct UpdateOutcome {
  bool accepted = false;  // false when gated out (x and P unchanged)
  double nis = 0.0;       // νᵀ S⁻¹ ν (computed also for gated updates)
};

// Joseph-form update of (x, P) with innovation ν = z − h(x), Jacobian H and noise R.
// gate_probability ≤ 0 disables gating. Angle components of ν must already be wrapped.
StatusOr<UpdateOutcome> KalmanUpdate(const Eigen::VectorXd& innovation, const Eigen::MatrixXd& H,
                                     const Eigen::MatrixXd& R, double gate_probability,
                                     Eigen::VectorXd* x, Eigen::MatrixXd* P);

// A filter's bookkeeping of one update: an accepted update's NIS goes to `nis`, a gated one
// counts in (*diagnostics)["gated_updates"].
void RecordOutcome(const UpdateOutcome& outcome, std::vector<double>* nis,
                   std::map<std::string, double>* diagnostics);

// One filter epoch as recorded for smoothing: the prior at this epoch, the transition Jacobian
// that produced it from the previous epoch's posterior, and the posterior (== prior when no
// measurement arrived). The first epoch's F is ignored.
struct FilterEpoch {
  double t_s = 0.0;
  Eigen::VectorXd x_prior, x_post;
  Eigen::MatrixXd P_prior, P_post;
  Eigen::MatrixXd F;
  // Stochastic cloning: Cov(this epoch's state, the previous epoch's clone), in place of
  // F · P_post of the previous epoch (empty: that product).
  Eigen::MatrixXd P_cross;
};

struct SmoothedState {
  double t_s = 0.0;
  Eigen::VectorXd x;
  Eigen::MatrixXd P;
};

// RTS backward pass over `epochs` (in time order). `angle_indices` lists state components that
// are angles. Fails on an empty input, inconsistent sizes or a singular prior covariance.
StatusOr<std::vector<SmoothedState>> RtsSmooth(const std::vector<FilterEpoch>& epochs,
                                               const std::vector<int>& angle_indices = {});

}  // namespace walkgraph

#endif  // WALKGRAPH_KALMAN_H_
