// Marginalizing states out of a set of factors: the function behind the fixed-lag smoother's
// MarginalizationPrior, testable on its own (GTSAM's CalculateMarginalFactors).
//
// Each factor touching a state to marginalize is linearized at the current estimate: residual
// r_f and Jacobians in the tangent space of each block (ambient Jacobian × PlusJacobian). A
// robust factor is linearized as iteratively-reweighted least squares does it at that point:
// r_f and J_f scaled by √ρ′(‖r_f‖²), the loss's first-order (ρ′) correction; ρ″ is dropped so
// the prior's information stays positive semi-definite. Then
//   H = Σ J_fᵀ J_f,  b = Σ J_fᵀ r_f  over (m, r);
//   H* = H_rr − H_rm H_mm⁺ H_mr,  b* = b_r − H_rm H_mm⁺ b_m   (H_mm⁺: pseudo-inverse)
//   H* = V Λ Vᵀ,  J₀ = Λ^{1/2} Vᵀ,  r₀ = Λ^{-1/2} Vᵀ b*  (eigenvalues ≤ tol·λ_max dropped)
// so that ½‖r₀ + J₀ δ‖² has gradient b* and Hessian H* at δ = 0.
#ifndef WALKGRAPH_SMOOTHERS_MARGINALIZATION_H_
#define WALKGRAPH_SMOOTHERS_MARGINALIZATION_H_

#include <cstdint>
#include <memory>
#include <set>
#include <vector>

#include <ceres/cost_function.h>
#include <ceres/loss_function.h>
#include <ceres/manifold.h>
#include <Eigen/Core>

#include "factors/marginalization_prior.h"
#include "walkgraph/graph.h"
#include "walkgraph/status.h"

namespace walkgraph {

// One parameter block as marginalization sees it.
struct BlockRef {
  Key key = 0;
  double* values = nullptr;  // current estimate (ambient)
  int ambient_size = 0;
  const ceres::Manifold* manifold = nullptr;  // nullptr = Euclidean
  // Held fixed by the solver (e.g. a known path loss): not a variable, so it gets no column in
  // H and the prior never constrains it; factors are linearized at its value.
  bool constant = false;
  int tangent_size() const { return manifold ? manifold->TangentSize() : ambient_size; }
};

// A factor to be marginalized: its cost function over `blocks` (in the cost function's order).
struct FactorRef {
  const ceres::CostFunction* cost = nullptr;
  const ceres::LossFunction* loss = nullptr;  // nullptr = squared loss
  std::vector<BlockRef> blocks;
};

struct MarginalPrior {
  std::vector<BlockRef> blocks;  // the remaining blocks the prior constrains (in J₀'s order)
  Eigen::MatrixXd j0;
  Eigen::VectorXd r0;
  bool empty() const { return blocks.empty() || r0.size() == 0; }
  // The cost function (x_lin = the blocks' current values).
  std::unique_ptr<MarginalizationPrior> MakeCostFunction() const;
};

// Marginalizes the blocks whose keys are in `marginalize` out of `factors` (every factor that
// touches them, and no other). Factors touching only marginalized blocks contribute to H_mm
// alone. An empty `marginalize` or a result that constrains nothing gives an empty prior.
// Fails if a factor cannot be evaluated.
StatusOr<MarginalPrior> Marginalize(const std::vector<FactorRef>& factors,
                                    const std::set<Key>& marginalize,
                                    double eigenvalue_tolerance = 1e-12);

}  // namespace walkgraph

#endif  // WALKGRAPH_SMOOTHERS_MARGINALIZATION_H_
