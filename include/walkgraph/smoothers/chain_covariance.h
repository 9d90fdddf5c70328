// Marginal covariances of a chain-structured least-squares problem, fast.
//
// A smoother over a walk has states in time order, each factor touching a few consecutive
// ones, plus a handful of "static" blocks (path loss, biases) that touch everything. In that
// order the information H = JᵀJ (Jacobian in the tangent spaces, robust losses applied as the
// solver applies them) is banded with an arrow:
//   H = [A  B; Bᵀ C],  A banded (half-bandwidth w), C the static blocks.
// With A = L Lᵀ (banded Cholesky) the entries of A⁻¹ inside the band follow from Takahashi's
// recursion  Σ_jj = 1/L_jj² − (1/L_jj) Σ_{k>j} L_kj Σ_kj,  Σ_ij = −(1/L_jj) Σ_{k>j} L_kj Σ_ik,
// in O(n·w²); the statics enter through the Schur complement S = C − Bᵀ A⁻¹ B:
//   Σ_cc = A⁻¹ + X S⁻¹ Xᵀ,  X = A⁻¹ B.
// ceres::Covariance computes the same blocks by sparse QR, one column at a time — 24 s for the
// 9,658 poses of Plaza1, against milliseconds here.
// Robust factors: a residual block within inlier_sigma (whitened norm) counts as plain Gaussian
// information; beyond it, with its loss's IRLS weight ρ′ — outliers the loss discounted carry
// no information, inliers keep theirs (ρ′ of an aggressive loss, e.g. Cauchy at 0.5σ, would
// also discount inliers and make the covariance pessimistic: position NEES 0.84 for 2).
#ifndef WALKGRAPH_SMOOTHERS_CHAIN_COVARIANCE_H_
#define WALKGRAPH_SMOOTHERS_CHAIN_COVARIANCE_H_

#include <vector>

#include <ceres/problem.h>
#include <Eigen/Core>

#include "walkgraph/status.h"

namespace walkgraph {

// `groups`: the chain's parameter blocks grouped per state, in time order (e.g. {p_k, θ_k});
// `statics`: the other variable blocks. Constant blocks are skipped. Returns each group's
// joint covariance in its blocks' tangent spaces (stacked in group order). Fails — never
// aborts — when H is not positive definite (an unobservable direction) or when the problem is
// not chain-structured (half-bandwidth above max_bandwidth). `wanted` (empty: all) selects the
// groups whose covariance is returned; the others come back empty (0 × 0).
// `static_covariances` (not null): each static block's marginal covariance, S⁻¹'s diagonal
// block, in the order of `statics` (a constant one 0 × 0).
inline constexpr double kChainInlierSigma = 3.0;
inline constexpr int kChainMaxBandwidth = 64;
StatusOr<std::vector<Eigen::MatrixXd>> ChainMarginalCovariances(
    ceres::Problem* problem, const std::vector<std::vector<double*>>& groups,
    const std::vector<double*>& statics, double inlier_sigma = kChainInlierSigma,
    int max_bandwidth = kChainMaxBandwidth, const std::vector<bool>& wanted = {},
    std::vector<Eigen::MatrixXd>* static_covariances = nullptr);

}  // namespace walkgraph

#endif  // WALKGRAPH_SMOOTHERS_CHAIN_COVARIANCE_H_
