// MarginalizationPrior: the Gaussian prior that marginalizing states out of a sliding window
// leaves on the states that remain (their Markov blanket).
//
// Linearizing the factors that touch the marginalized states m at x_lin gives the information
// H and gradient b over (m, r); the Schur complement keeps
//   H* = H_rr − H_rm H_mm⁻¹ H_mr,   b* = b_r − H_rm H_mm⁻¹ b_m,
// and with H* = J₀ᵀ J₀, r₀ = J₀⁻ᵀ b* (from H*'s eigendecomposition, null directions dropped)
// the prior is the linear residual
//   r(x) = r₀ + J₀ · (x ⊟ x_lin),
// where ⊟ is each block's ceres::Manifold::Minus (Euclidean difference for blocks without a
// manifold), so no block size is hard-coded. The Jacobian is held at J₀ in each block's tangent
// space (first-estimate Jacobian); the ambient Jacobian Ceres asks for is J₀ ·
// MinusJacobian(x), which Ceres maps back to the tangent space with PlusJacobian(x).
// src/smoothers/marginalization.cc computes (J₀, r₀); this class only evaluates the prior.
#ifndef WALKGRAPH_FACTORS_MARGINALIZATION_PRIOR_H_
#define WALKGRAPH_FACTORS_MARGINALIZATION_PRIOR_H_

#include <utility>
#include <vector>

#include <ceres/cost_function.h>
#include <ceres/manifold.h>
#include <Eigen/Core>

namespace walkgraph {

class MarginalizationPrior : public ceres::CostFunction {
 public:
  struct Block {
    std::vector<double> x_lin;                  // ambient linearization point
    const ceres::Manifold* manifold = nullptr;  // not owned; nullptr = Euclidean
    int tangent_size() const {
      return manifold ? manifold->TangentSize() : static_cast<int>(x_lin.size());
    }
  };

  // j0: rows = num residuals, cols = Σ tangent sizes (blocks in order); r0: rows.
  MarginalizationPrior(std::vector<Block> blocks, Eigen::MatrixXd j0, Eigen::VectorXd r0)
      : blocks_(std::move(blocks)), j0_(std::move(j0)), r0_(std::move(r0)) {
    set_num_residuals(static_cast<int>(r0_.size()));
    for (const Block& b : blocks_) {
      mutable_parameter_block_sizes()->push_back(static_cast<int>(b.x_lin.size()));
    }
  }

  bool Evaluate(double const* const* parameters, double* residuals,
                double** jacobians) const override {
    Eigen::Map<Eigen::VectorXd> r(residuals, num_residuals());
    r = r0_;
    int col = 0;
    for (size_t i = 0; i < blocks_.size(); ++i) {
      const Block& b = blocks_[i];
      const int amb = static_cast<int>(b.x_lin.size()), tan = b.tangent_size();
      Eigen::VectorXd delta(tan);
      if (b.manifold) {
        if (!b.manifold->Minus(parameters[i], b.x_lin.data(), delta.data())) return false;
      } else {
        for (int k = 0; k < amb; ++k) delta[k] = parameters[i][k] - b.x_lin[k];
      }
      r += j0_.middleCols(col, tan) * delta;
      if (jacobians != nullptr && jacobians[i] != nullptr) {
        Eigen::Map<Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>> J(
            jacobians[i], num_residuals(), amb);
        if (b.manifold) {
          Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> minus_j(tan, amb);
          if (!b.manifold->MinusJacobian(parameters[i], minus_j.data())) return false;
          J = j0_.middleCols(col, tan) * minus_j;
        } else {
          J = j0_.middleCols(col, tan);
        }
      }
      col += tan;
    }
    return true;
  }

  const std::vector<Block>& blocks() const { return blocks_; }
  const Eigen::MatrixXd& j0() const { return j0_; }
  const Eigen::VectorXd& r0() const { return r0_; }

 private:
  std::vector<Block> blocks_;
  Eigen::MatrixXd j0_;
  Eigen::VectorXd r0_;
};

}  // namespace walkgraph

#endif  // WALKGRAPH_FACTORS_MARGINALIZATION_PRIOR_H_
