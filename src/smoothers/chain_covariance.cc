#include "walkgraph/smoothers/chain_covariance.h"

#include <algorithm>
#include <cmath>
#include <string>

#include <ceres/cost_function.h>
#include <ceres/crs_matrix.h>
#include <ceres/loss_function.h>
#include <Eigen/Cholesky>
#include <Eigen/SparseCore>

namespace walkgraph {

namespace {

// Lower band of a symmetric positive-definite matrix: band(i, d) = M(i, i − d), d = 0..w.
class Band {
 public:
  Band(int n, int w) : n_(n), w_(w), v_(static_cast<size_t>(n) * (w + 1), 0.0) {}
  double& at(int i, int j) { return v_[static_cast<size_t>(i) * (w_ + 1) + (i - j)]; }
  double get(int i, int j) const {
    if (i < j) std::swap(i, j);
    if (i - j > w_) return 0.0;
    return v_[static_cast<size_t>(i) * (w_ + 1) + (i - j)];
  }
  int n() const { return n_; }
  int w() const { return w_; }

 private:
  int n_, w_;
  std::vector<double> v_;
};

// In-place banded Cholesky A = L Lᵀ; false if A is not positive definite.
bool BandCholesky(Band* a) {
  const int n = a->n(), w = a->w();
  for (int j = 0; j < n; ++j) {
    double d = a->at(j, j);
    for (int k = std::max(0, j - w); k < j; ++k) d -= a->at(j, k) * a->at(j, k);
    if (!(d > 0.0) || !std::isfinite(d)) return false;
    const double ljj = std::sqrt(d);
    a->at(j, j) = ljj;
    for (int i = j + 1; i <= std::min(n - 1, j + w); ++i) {
      double s = a->at(i, j);
      for (int k = std::max(0, i - w); k < j; ++k) s -= a->at(i, k) * a->at(j, k);
      a->at(i, j) = s / ljj;
    }
  }
  return true;
}

// Solves L Lᵀ x = b in place.
void BandSolve(const Band& l, Eigen::Ref<Eigen::VectorXd> x) {
  const int n = l.n(), w = l.w();
  for (int i = 0; i < n; ++i) {
    double s = x[i];
    for (int k = std::max(0, i - w); k < i; ++k) s -= l.get(i, k) * x[k];
    x[i] = s / l.get(i, i);
  }
  for (int i = n - 1; i >= 0; --i) {
    double s = x[i];
    for (int k = i + 1; k <= std::min(n - 1, i + w); ++k) s -= l.get(k, i) * x[k];
    x[i] = s / l.get(i, i);
  }
}

// Takahashi: the band of (L Lᵀ)⁻¹.
Band BandInverse(const Band& l) {
  const int n = l.n(), w = l.w();
  Band s(n, w);
  for (int j = n - 1; j >= 0; --j) {
    const double ljj = l.get(j, j);
    const int hi = std::min(n - 1, j + w);
    for (int i = hi; i > j; --i) {
      double acc = 0.0;
      for (int k = j + 1; k <= hi; ++k) acc += l.get(k, j) * s.get(i, k);
      s.at(i, j) = -acc / ljj;
    }
    double acc = 0.0;
    for (int k = j + 1; k <= hi; ++k) acc += l.get(k, j) * s.get(k, j);
    s.at(j, j) = 1.0 / (ljj * ljj) - acc / ljj;
  }
  return s;
}

}  // namespace

StatusOr<std::vector<Eigen::MatrixXd>> ChainMarginalCovariances(
    ceres::Problem* problem, const std::vector<std::vector<double*>>& groups,
    const std::vector<double*>& statics, double inlier_sigma, int max_bandwidth) {
  // Column layout: the chain's variable blocks in order, then the statics.
  std::vector<double*> blocks;
  std::vector<std::vector<std::pair<int, int>>> group_cols(groups.size());  // (offset, size)
  int n_chain = 0;
  for (size_t g = 0; g < groups.size(); ++g) {
    for (double* b : groups[g]) {
      if (problem->IsParameterBlockConstant(b)) continue;
      const int t = problem->ParameterBlockTangentSize(b);
      group_cols[g].emplace_back(n_chain, t);
      blocks.push_back(b);
      n_chain += t;
    }
  }
  int n_static = 0;
  for (double* b : statics) {
    if (problem->IsParameterBlockConstant(b)) continue;
    blocks.push_back(b);
    n_static += problem->ParameterBlockTangentSize(b);
  }
  const int n = n_chain + n_static;
  std::vector<Eigen::MatrixXd> out(groups.size());
  if (n_chain == 0) return out;

  ceres::Problem::EvaluateOptions eo;
  eo.parameter_blocks = blocks;
  problem->GetResidualBlocks(&eo.residual_blocks);
  eo.apply_loss_function = false;  // robust weights applied below, per residual block
  ceres::CRSMatrix crs;
  std::vector<double> residuals;
  if (!problem->Evaluate(eo, nullptr, &residuals, nullptr, &crs)) {
    return NumericalError("covariance: the problem could not be evaluated");
  }
  if (crs.num_cols != n) return InternalError("covariance: unexpected Jacobian width");
  // Row weights: a robust residual block counts fully while ‖r‖ ≤ inlier_sigma (whitened), and
  // with its loss's IRLS weight ρ′(‖r‖²) beyond — an outlier the loss discounted is not
  // information, an inlier is (ρ′ of an aggressive loss would discount inliers too and
  // overstate the covariance).
  std::vector<double> row_weight(residuals.size(), 1.0);
  int row = 0;
  for (ceres::ResidualBlockId id : eo.residual_blocks) {
    const int m = problem->GetCostFunctionForResidualBlock(id)->num_residuals();
    const ceres::LossFunction* loss = problem->GetLossFunctionForResidualBlock(id);
    double s2 = 0.0;
    for (int i = 0; i < m; ++i) s2 += residuals[row + i] * residuals[row + i];
    if (loss != nullptr && s2 > inlier_sigma * inlier_sigma) {
      double rho[3];
      loss->Evaluate(s2, rho);
      for (int i = 0; i < m; ++i) row_weight[row + i] = std::sqrt(std::max(rho[1], 0.0));
    }
    row += m;
  }
  for (int r = 0; r < crs.num_rows; ++r) {
    for (int k = crs.rows[r]; k < crs.rows[r + 1]; ++k) crs.values[k] *= row_weight[r];
  }
  Eigen::Map<const Eigen::SparseMatrix<double, Eigen::RowMajor>> J(
      crs.num_rows, crs.num_cols, static_cast<Eigen::Index>(crs.values.size()), crs.rows.data(),
      crs.cols.data(), crs.values.data());
  const Eigen::SparseMatrix<double> H = Eigen::SparseMatrix<double>(J.transpose() * J);

  int w = 0;
  for (int c = 0; c < n_chain; ++c) {
    for (Eigen::SparseMatrix<double>::InnerIterator it(H, c); it; ++it) {
      if (it.row() < n_chain) w = std::max(w, static_cast<int>(std::abs(it.row() - c)));
    }
  }
  for (const auto& cols : group_cols) {  // a group's own entries must lie inside the band
    if (!cols.empty())
      w = std::max(w, cols.back().first + cols.back().second - 1 - cols.front().first);
  }
  if (w > max_bandwidth) {
    return FailedPrecondition("covariance: not chain-structured (half-bandwidth " +
                              std::to_string(w) + ")");
  }
  Band a(n_chain, w);
  Eigen::MatrixXd B = Eigen::MatrixXd::Zero(n_chain, n_static);
  Eigen::MatrixXd C = Eigen::MatrixXd::Zero(n_static, n_static);
  for (int c = 0; c < n; ++c) {
    for (Eigen::SparseMatrix<double>::InnerIterator it(H, c); it; ++it) {
      const int r = static_cast<int>(it.row());
      if (r < n_chain && c < n_chain) {
        if (r >= c) a.at(r, c) = it.value();
      } else if (r < n_chain) {
        B(r, c - n_chain) = it.value();
      } else if (c >= n_chain) {
        C(r - n_chain, c - n_chain) = it.value();
      }
    }
  }
  if (!BandCholesky(&a)) {
    return NumericalError("covariance: information matrix not positive definite (unobservable)");
  }
  const Band sigma = BandInverse(a);
  Eigen::MatrixXd X(n_chain, n_static), Sinv;
  if (n_static > 0) {
    X = B;
    for (int c = 0; c < n_static; ++c) BandSolve(a, X.col(c));
    const Eigen::MatrixXd S = C - B.transpose() * X;
    Eigen::LLT<Eigen::MatrixXd> llt(0.5 * (S + S.transpose()));
    if (llt.info() != Eigen::Success) {
      return NumericalError("covariance: static blocks not observable");
    }
    Sinv = llt.solve(Eigen::MatrixXd::Identity(n_static, n_static));
  }
  for (size_t g = 0; g < groups.size(); ++g) {
    std::vector<int> idx;
    for (const auto& [off, size] : group_cols[g]) {
      for (int i = 0; i < size; ++i) idx.push_back(off + i);
    }
    const int m = static_cast<int>(idx.size());
    Eigen::MatrixXd c(m, m);
    for (int i = 0; i < m; ++i) {
      for (int j = 0; j < m; ++j) c(i, j) = sigma.get(idx[i], idx[j]);
    }
    if (n_static > 0) {
      Eigen::MatrixXd xg(m, n_static);
      for (int i = 0; i < m; ++i) xg.row(i) = X.row(idx[i]);
      c += xg * Sinv * xg.transpose();
    }
    out[g] = 0.5 * (c + c.transpose());
  }
  return out;
}

}  // namespace walkgraph
