#include "walkgraph/smoothers/marginalization.h"

#include <map>
#include <string>

#include <Eigen/Eigenvalues>

namespace walkgraph {

std::unique_ptr<MarginalizationPrior> MarginalPrior::MakeCostFunction() const {
  std::vector<MarginalizationPrior::Block> b;
  for (const BlockRef& r : blocks) {
    MarginalizationPrior::Block block;
    block.x_lin.assign(r.values, r.values + r.ambient_size);
    block.manifold = r.manifold;
    b.push_back(std::move(block));
  }
  return std::make_unique<MarginalizationPrior>(std::move(b), j0, r0);
}

namespace {

using RowMajor = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

// Symmetric pseudo-inverse (eigenvalues ≤ tol·λ_max treated as zero).
Eigen::MatrixXd PseudoInverse(const Eigen::MatrixXd& H, double tol) {
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es(H);
  const Eigen::VectorXd& l = es.eigenvalues();
  const double cut = tol * std::max(l.maxCoeff(), 0.0);
  Eigen::VectorXd inv = Eigen::VectorXd::Zero(l.size());
  for (int i = 0; i < l.size(); ++i) {
    if (l[i] > cut && l[i] > 0) inv[i] = 1.0 / l[i];
  }
  return es.eigenvectors() * inv.asDiagonal() * es.eigenvectors().transpose();
}

}  // namespace

StatusOr<MarginalPrior> Marginalize(const std::vector<FactorRef>& factors,
                                    const std::set<Key>& marginalize, double eigenvalue_tolerance) {
  MarginalPrior out;
  if (marginalize.empty() || factors.empty()) return out;

  // Column layout: marginalized blocks first, then the remaining ones, each in first-seen order.
  std::map<Key, int> offset;
  std::vector<BlockRef> order_m, order_r;
  for (const FactorRef& f : factors) {
    for (const BlockRef& b : f.blocks) {
      if (b.constant || offset.count(b.key)) continue;
      offset[b.key] = -1;
      (marginalize.count(b.key) ? order_m : order_r).push_back(b);
    }
  }
  int n_m = 0, n_r = 0;
  for (const BlockRef& b : order_m) offset[b.key] = n_m, n_m += b.tangent_size();
  for (const BlockRef& b : order_r) offset[b.key] = n_m + n_r, n_r += b.tangent_size();
  if (n_m == 0) return out;  // nothing of `marginalize` is touched by these factors
  const int n = n_m + n_r;

  Eigen::MatrixXd H = Eigen::MatrixXd::Zero(n, n);
  Eigen::VectorXd g = Eigen::VectorXd::Zero(n);
  for (const FactorRef& f : factors) {
    const int m = f.cost->num_residuals();
    const std::vector<int32_t>& sizes = f.cost->parameter_block_sizes();
    if (sizes.size() != f.blocks.size()) {
      return InvalidArgument("marginalize: factor has " + std::to_string(sizes.size()) +
                             " parameter blocks, " + std::to_string(f.blocks.size()) + " given");
    }
    std::vector<const double*> params;
    std::vector<RowMajor> jac;
    std::vector<double*> jac_ptr;
    for (size_t i = 0; i < f.blocks.size(); ++i) {
      if (sizes[i] != f.blocks[i].ambient_size) {
        return InvalidArgument("marginalize: block size mismatch for key " +
                               std::to_string(f.blocks[i].key));
      }
      params.push_back(f.blocks[i].values);
      jac.emplace_back(m, sizes[i]);
    }
    for (RowMajor& j : jac) jac_ptr.push_back(j.data());
    Eigen::VectorXd r(m);
    if (!f.cost->Evaluate(params.data(), r.data(), jac_ptr.data())) {
      return NumericalError("marginalize: a factor could not be evaluated at the estimate");
    }
    double w = 1.0;
    if (f.loss != nullptr) {
      double rho[3];
      f.loss->Evaluate(r.squaredNorm(), rho);
      w = std::sqrt(std::max(rho[1], 0.0));  // IRLS weight √ρ′ (see the header)
    }
    Eigen::MatrixXd J = Eigen::MatrixXd::Zero(m, n);
    for (size_t i = 0; i < f.blocks.size(); ++i) {
      const BlockRef& b = f.blocks[i];
      if (b.constant) continue;
      const int tan = b.tangent_size();
      if (b.manifold) {
        RowMajor plus(b.ambient_size, tan);
        if (!b.manifold->PlusJacobian(b.values, plus.data())) {
          return NumericalError("marginalize: PlusJacobian failed");
        }
        J.middleCols(offset[b.key], tan) += jac[i] * plus;
      } else {
        J.middleCols(offset[b.key], tan) += jac[i];
      }
    }
    J *= w;
    r *= w;
    H.noalias() += J.transpose() * J;
    g.noalias() += J.transpose() * r;
  }
  if (n_r == 0) return out;  // nothing remains to be constrained

  const Eigen::MatrixXd Hmm_inv = PseudoInverse(H.topLeftCorner(n_m, n_m), eigenvalue_tolerance);
  const Eigen::MatrixXd Hrm = H.bottomLeftCorner(n_r, n_m);
  Eigen::MatrixXd Hs = H.bottomRightCorner(n_r, n_r) - Hrm * Hmm_inv * Hrm.transpose();
  const Eigen::VectorXd bs = g.tail(n_r) - Hrm * Hmm_inv * g.head(n_m);
  Hs = 0.5 * (Hs + Hs.transpose());

  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es(Hs);
  const Eigen::VectorXd& l = es.eigenvalues();
  const double cut = eigenvalue_tolerance * std::max(l.maxCoeff(), 0.0);
  std::vector<int> keep;
  for (int i = 0; i < l.size(); ++i) {
    if (l[i] > cut && l[i] > 0) keep.push_back(i);
  }
  if (keep.empty()) return out;
  const int k = static_cast<int>(keep.size());
  out.j0.resize(k, n_r);
  out.r0.resize(k);
  for (int i = 0; i < k; ++i) {
    const Eigen::VectorXd v = es.eigenvectors().col(keep[i]);
    const double s = std::sqrt(l[keep[i]]);
    out.j0.row(i) = s * v.transpose();
    out.r0[i] = v.dot(bs) / s;
  }
  out.blocks = order_r;
  return out;
}

}  // namespace walkgraph
