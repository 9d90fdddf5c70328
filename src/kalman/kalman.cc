#include "walkgraph/kalman.h"

#include <cmath>
#include <limits>

#include <Eigen/Cholesky>
#include <Eigen/LU>
#include <unsupported/Eigen/SpecialFunctions>

#include "walkgraph/angle.h"
#include "walkgraph/cancel.h"

namespace walkgraph {

// .eval(): P appears on both sides with a transpose (Eigen aliasing).
void Symmetrize(Eigen::MatrixXd* P) { *P = (0.5 * (*P + P->transpose())).eval(); }

double ChiSquareQuantile(double p, int dof) {
  if (!(p > 0.0 && p < 1.0) || dof < 1) return std::numeric_limits<double>::quiet_NaN();
  const double a = 0.5 * dof;
  auto cdf = [a](double x) { return Eigen::numext::igamma(a, 0.5 * x); };
  double lo = 0.0, hi = static_cast<double>(dof);
  while (cdf(hi) < p) {
    lo = hi;
    hi *= 2.0;
  }
  for (int i = 0; i < 200 && hi - lo > 1e-14 * hi; ++i) {
    const double mid = 0.5 * (lo + hi);
    (cdf(mid) < p ? lo : hi) = mid;
  }
  return 0.5 * (lo + hi);
}

StatusOr<UpdateOutcome> KalmanUpdate(const Eigen::VectorXd& innovation, const Eigen::MatrixXd& H,
                                     const Eigen::MatrixXd& R, double gate_probability,
                                     Eigen::VectorXd* x, Eigen::MatrixXd* P) {
  if (CancelRequested()) return Cancelled("filter: interrupted");  // see cancel.h
  const Eigen::Index n = x->size(), m = innovation.size();
  if (P->rows() != n || P->cols() != n || H.rows() != m || H.cols() != n || R.rows() != m ||
      R.cols() != m) {
    return InvalidArgument("KalmanUpdate: inconsistent matrix sizes");
  }
  Eigen::MatrixXd S = H * (*P) * H.transpose() + R;
  Symmetrize(&S);
  const Eigen::LLT<Eigen::MatrixXd> llt(S);
  if (llt.info() != Eigen::Success) {
    return NumericalError("KalmanUpdate: innovation covariance is not positive definite");
  }
  UpdateOutcome out;
  out.nis = innovation.dot(llt.solve(innovation));
  if (!std::isfinite(out.nis)) return NumericalError("KalmanUpdate: non-finite NIS");
  if (gate_probability > 0.0 && out.nis > ChiSquareQuantile(gate_probability, int(m))) {
    return out;
  }
  // K = P Hᵀ S⁻¹, computed as (S⁻¹ H P)ᵀ since S and P are symmetric.
  const Eigen::MatrixXd K = llt.solve(H * (*P)).transpose();
  *x += K * innovation;
  const Eigen::MatrixXd IKH = Eigen::MatrixXd::Identity(n, n) - K * H;
  *P = IKH * (*P) * IKH.transpose() + K * R * K.transpose();
  Symmetrize(P);
  out.accepted = true;
  return out;
}

void RecordOutcome(const UpdateOutcome& outcome, std::vector<double>* nis,
                   std::map<std::string, double>* diagnostics) {
  if (outcome.accepted) {
    nis->push_back(outcome.nis);
  } else {
    (*diagnostics)["gated_updates"] += 1;
  }
}

StatusOr<std::vector<SmoothedState>> RtsSmooth(const std::vector<FilterEpoch>& epochs,
                                               const std::vector<int>& angle_indices) {
  if (epochs.empty()) return InvalidArgument("RtsSmooth: no epochs");
  const Eigen::Index n = epochs.front().x_post.size();
  for (size_t k = 0; k < epochs.size(); ++k) {
    const FilterEpoch& e = epochs[k];
    if (e.x_prior.size() != n || e.x_post.size() != n || e.P_prior.rows() != n ||
        e.P_prior.cols() != n || e.P_post.rows() != n || e.P_post.cols() != n ||
        (k > 0 && e.P_cross.size() == 0 && (e.F.rows() != n || e.F.cols() != n)) ||
        (e.P_cross.size() != 0 && (e.P_cross.rows() != n || e.P_cross.cols() != n))) {
      return InvalidArgument("RtsSmooth: inconsistent state sizes at epoch " + std::to_string(k));
    }
  }
  for (int i : angle_indices) {
    if (i < 0 || i >= n) return InvalidArgument("RtsSmooth: angle index out of range");
  }
  auto wrap = [&angle_indices](Eigen::VectorXd d) {
    for (int i : angle_indices) d[i] = NormalizeAngle(d[i]);
    return d;
  };
  std::vector<SmoothedState> out(epochs.size());
  out.back() = {epochs.back().t_s, epochs.back().x_post, epochs.back().P_post};
  for (size_t k = epochs.size() - 1; k-- > 0;) {
    const FilterEpoch& cur = epochs[k];
    const FilterEpoch& next = epochs[k + 1];
    const Eigen::LDLT<Eigen::MatrixXd> prior(next.P_prior);
    if (prior.info() != Eigen::Success || !prior.isPositive()) {
      return NumericalError("RtsSmooth: prior covariance not positive at epoch " +
                            std::to_string(k + 1));
    }
    // C_k = P_{k|k} F_{k+1}ᵀ P_{k+1|k}⁻¹ = (P_{k+1|k}⁻¹ F_{k+1} P_{k|k})ᵀ; with cloning
    // F_{k+1} P_{k|k} is the cross-covariance the epoch holds.
    const Eigen::MatrixXd C = next.P_cross.size() != 0
                                  ? Eigen::MatrixXd(prior.solve(next.P_cross).transpose())
                                  : Eigen::MatrixXd(prior.solve(next.F * cur.P_post).transpose());
    SmoothedState& s = out[k];
    s.t_s = cur.t_s;
    s.x = cur.x_post + C * wrap(out[k + 1].x - next.x_prior);
    for (int i : angle_indices) s.x[i] = NormalizeAngle(s.x[i]);
    s.P = cur.P_post + C * (out[k + 1].P - next.P_prior) * C.transpose();
    Symmetrize(&s.P);
  }
  return out;
}

}  // namespace walkgraph
