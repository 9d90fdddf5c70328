// DifferencePriorFactor: two N-vectors a and m that should be close — a per-anchor parameter
// tied to the walk-wide mean of its kind (a hierarchical prior, e.g. each anchor's path loss
// (A, η) around the walk's mean path loss):
//   r_i = (a_i − m_i) / σ_i,   ∂r/∂a = diag(1/σ),  ∂r/∂m = −diag(1/σ).
// Linear in both blocks; autodiff keeps the Jacobians and the residual in one place.
#ifndef WALKGRAPH_FACTORS_DIFFERENCE_PRIOR_FACTOR_H_
#define WALKGRAPH_FACTORS_DIFFERENCE_PRIOR_FACTOR_H_

#include <ceres/autodiff_cost_function.h>
#include <Eigen/Core>

namespace walkgraph {

template <int N>
class DifferencePriorFactor {
 public:
  explicit DifferencePriorFactor(const Eigen::Matrix<double, N, 1>& sigma)
      : inv_sigma_(sigma.cwiseInverse()) {}

  // Blocks: a (N), m (N).
  template <typename T>
  bool operator()(const T* a, const T* m, T* residual) const {
    for (int i = 0; i < N; ++i) residual[i] = (a[i] - m[i]) * T(inv_sigma_[i]);
    return true;
  }

  // sigma: every entry > 0 (the caller validates it).
  static ceres::CostFunction* Create(const Eigen::Matrix<double, N, 1>& sigma) {
    return new ceres::AutoDiffCostFunction<DifferencePriorFactor, N, N, N>(
        new DifferencePriorFactor(sigma));
  }

 private:
  Eigen::Matrix<double, N, 1> inv_sigma_;
};

}  // namespace walkgraph

#endif  // WALKGRAPH_FACTORS_DIFFERENCE_PRIOR_FACTOR_H_
