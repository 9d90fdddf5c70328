#include "walkgraph/smoothers/chain_covariance.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <string>

#include <unordered_map>

#include <ceres/cost_function.h>
#include <ceres/loss_function.h>
#include <ceres/manifold.h>
#include <Eigen/Cholesky>

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

namespace {

struct Column {
  int offset = 0;
  int size = 0;
};
// One variable block's rows of a residual block's tangent Jacobian (row-major, in `jac`).
struct Slab {
  Column column;
  size_t at = 0;  // into Jacobians::jac
};
struct Term {
  int rows = 0;
  size_t first = 0, count = 0;  // into Jacobians::slabs
};
struct Jacobians {
  std::vector<Term> terms;
  std::vector<Slab> slabs;
  std::vector<double> jac;
  int bandwidth = 0;  // half-bandwidth of the chain part
};

// Every residual block's weighted tangent Jacobian over the variable blocks in `column_of`.
Status CollectJacobians(ceres::Problem* problem,
                        const std::unordered_map<const double*, Column>& column_of, int n_chain,
                        double inlier_sigma, Jacobians* out) {
  // Each residual block's Jacobian in the tangent spaces of its variable blocks (the others are
  // held), evaluated directly: a Problem::Evaluate would set up a whole program per call.
  // Stored flat: per term its rows, then per variable block a (rows × tangent) row-major slab.
  std::vector<ceres::ResidualBlockId> ids;
  problem->GetResidualBlocks(&ids);
  std::vector<Term>& terms = out->terms;
  std::vector<Slab>& slabs = out->slabs;
  std::vector<double>& jac = out->jac;
  terms.reserve(ids.size());
  int& w = out->bandwidth;
  std::vector<double*> params;
  std::vector<double> ambient, plus, r;
  std::vector<double*> jac_ptrs;
  std::vector<size_t> ambient_at;
  for (ceres::ResidualBlockId id : ids) {
    const ceres::CostFunction* cost = problem->GetCostFunctionForResidualBlock(id);
    problem->GetParameterBlocksForResidualBlock(id, &params);
    const int m = cost->num_residuals();
    size_t total = 0;
    ambient_at.assign(params.size(), SIZE_MAX);
    for (size_t i = 0; i < params.size(); ++i) {
      if (!column_of.count(params[i])) continue;
      ambient_at[i] = total;
      total += static_cast<size_t>(m) * cost->parameter_block_sizes()[i];
    }
    if (total == 0) continue;
    ambient.assign(total, 0.0);
    jac_ptrs.assign(params.size(), nullptr);
    for (size_t i = 0; i < params.size(); ++i) {
      if (ambient_at[i] != SIZE_MAX) jac_ptrs[i] = ambient.data() + ambient_at[i];
    }
    r.assign(m, 0.0);
    if (!cost->Evaluate(params.data(), r.data(), jac_ptrs.data())) {
      return NumericalError("covariance: a residual block could not be evaluated");
    }
    // Row weight: a robust residual block counts fully while ‖r‖ ≤ inlier_sigma (whitened),
    // and with its loss's IRLS weight ρ′(‖r‖²) beyond — an outlier the loss discounted is not
    // information, an inlier is (ρ′ of an aggressive loss would discount inliers too and
    // overstate the covariance).
    double s2 = 0.0;
    for (double v : r) s2 += v * v;
    if (!std::isfinite(s2)) return NumericalError("covariance: non-finite residual");
    double weight = 1.0;
    const ceres::LossFunction* loss = problem->GetLossFunctionForResidualBlock(id);
    if (loss != nullptr && s2 > inlier_sigma * inlier_sigma) {
      double rho[3];
      loss->Evaluate(s2, rho);
      weight = std::sqrt(std::max(rho[1], 0.0));
    }
    Term term;
    term.rows = m;
    term.first = slabs.size();
    int lo = n_chain, hi = -1;
    for (size_t i = 0; i < params.size(); ++i) {
      if (jac_ptrs[i] == nullptr) continue;
      const Column col = column_of.at(params[i]);
      const int amb = cost->parameter_block_sizes()[i];
      const double* ja = jac_ptrs[i];
      Slab slab{col, jac.size()};
      jac.resize(jac.size() + static_cast<size_t>(m) * col.size);
      double* jt = jac.data() + slab.at;
      const ceres::Manifold* manifold = problem->GetManifold(params[i]);
      if (manifold != nullptr) {  // J_tangent = J_ambient · ∂Plus/∂δ (ambient × tangent)
        plus.assign(static_cast<size_t>(amb) * col.size, 0.0);
        if (!manifold->PlusJacobian(params[i], plus.data())) {
          return NumericalError("covariance: a manifold's PlusJacobian failed");
        }
        for (int row = 0; row < m; ++row) {
          for (int c = 0; c < col.size; ++c) {
            double v = 0.0;
            for (int a = 0; a < amb; ++a) v += ja[row * amb + a] * plus[a * col.size + c];
            jt[row * col.size + c] = weight * v;
          }
        }
      } else {
        for (int e = 0; e < m * amb; ++e) jt[e] = weight * ja[e];
      }
      for (int e = 0; e < m * col.size; ++e) {
        if (!std::isfinite(jt[e])) return NumericalError("covariance: non-finite Jacobian");
      }
      if (col.offset < n_chain) {
        lo = std::min(lo, col.offset);
        hi = std::max(hi, col.offset + col.size - 1);
      }
      slabs.push_back(slab);
    }
    term.count = slabs.size() - term.first;
    if (hi >= lo) w = std::max(w, hi - lo);
    terms.push_back(term);
  }
  return Status::Ok();
}

// H = JᵀJ = [A B; Bᵀ C]: A's lower band into `a`, B and C in full.
void AssembleInformation(const Jacobians& J, int n_chain, Band* a_band, Eigen::MatrixXd* B_out,
                         Eigen::MatrixXd* C_out) {
  Band& a = *a_band;
  Eigen::MatrixXd& B = *B_out;
  Eigen::MatrixXd& C = *C_out;
  const std::vector<Slab>& slabs = J.slabs;
  const std::vector<double>& jac = J.jac;
  for (const Term& term : J.terms) {
    for (size_t i = term.first; i < term.first + term.count; ++i) {
      const Slab& si = slabs[i];
      const double* ji = jac.data() + si.at;
      for (size_t k = term.first; k < term.first + term.count; ++k) {
        const Slab& sk = slabs[k];
        const double* jk = jac.data() + sk.at;
        for (int p = 0; p < si.column.size; ++p) {
          const int row = si.column.offset + p;
          for (int q = 0; q < sk.column.size; ++q) {
            const int col = sk.column.offset + q;
            const bool chain_row = row < n_chain, chain_col = col < n_chain;
            if (chain_row && chain_col && row < col) continue;  // the upper half mirrors
            if (!chain_row && chain_col) continue;              // Bᵀ mirrors B
            double h = 0.0;
            for (int e = 0; e < term.rows; ++e) {
              h += ji[e * si.column.size + p] * jk[e * sk.column.size + q];
            }
            if (chain_row && chain_col) {
              a.at(row, col) += h;
            } else if (chain_row) {
              B(row, col - n_chain) += h;
            } else {
              C(row - n_chain, col - n_chain) += h;
            }
          }
        }
      }
    }
  }
}

}  // namespace

StatusOr<std::vector<Eigen::MatrixXd>> ChainMarginalCovariances(
    ceres::Problem* problem, const std::vector<std::vector<double*>>& groups,
    const std::vector<double*>& statics, double inlier_sigma, int max_bandwidth,
    const std::vector<bool>& wanted, std::vector<Eigen::MatrixXd>* static_covariances) {
  if (!wanted.empty() && wanted.size() != groups.size()) {
    return InvalidArgument("covariance: 'wanted' must have one entry per group");
  }
  // Column layout: the chain's variable blocks in order, then the statics.
  std::unordered_map<const double*, Column> column_of;
  std::vector<std::vector<std::pair<int, int>>> group_cols(groups.size());  // (offset, size)
  int n_chain = 0;
  for (size_t g = 0; g < groups.size(); ++g) {
    for (double* b : groups[g]) {
      if (problem->IsParameterBlockConstant(b)) continue;
      const int t = problem->ParameterBlockTangentSize(b);
      group_cols[g].emplace_back(n_chain, t);
      column_of[b] = {n_chain, t};
      n_chain += t;
    }
  }
  int n = n_chain;
  for (double* b : statics) {
    if (problem->IsParameterBlockConstant(b)) continue;
    const int t = problem->ParameterBlockTangentSize(b);
    column_of[b] = {n, t};
    n += t;
  }
  const int n_static = n - n_chain;
  std::vector<Eigen::MatrixXd> out(groups.size());
  if (n_chain == 0) return out;

  Jacobians J;
  WG_RETURN_IF_ERROR(CollectJacobians(problem, column_of, n_chain, inlier_sigma, &J));
  int w = J.bandwidth;
  for (const auto& cols : group_cols) {  // a group's own entries must lie inside the band
    if (!cols.empty())
      w = std::max(w, cols.back().first + cols.back().second - 1 - cols.front().first);
  }
  if (w > max_bandwidth) {
    return FailedPrecondition("covariance: not chain-structured (half-bandwidth " +
                              std::to_string(w) + ")");
  }
  // H = JᵀJ = [A B; Bᵀ C], assembled slab by slab: A's lower band, B, and C in full.
  Band a(n_chain, w);
  Eigen::MatrixXd B = Eigen::MatrixXd::Zero(n_chain, n_static);
  Eigen::MatrixXd C = Eigen::MatrixXd::Zero(n_static, n_static);
  AssembleInformation(J, n_chain, &a, &B, &C);
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
  if (static_covariances != nullptr) {
    static_covariances->clear();
    for (double* b : statics) {
      if (problem->IsParameterBlockConstant(b)) {
        static_covariances->emplace_back(0, 0);
        continue;
      }
      const Column& c = column_of.at(b);
      const Eigen::MatrixXd block =
          Sinv.block(c.offset - n_chain, c.offset - n_chain, c.size, c.size);
      static_covariances->push_back(0.5 * (block + block.transpose()));
    }
  }
  for (size_t g = 0; g < groups.size(); ++g) {
    if (!wanted.empty() && !wanted[g]) continue;
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
