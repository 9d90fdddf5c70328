// StepFactor: one detected step between consecutive step poses.
//
// Node k holds the position p_k ∈ R² and the heading θ_k of the step that ends at node k
// (measurements.h: Step::heading_rad is the direction of the step's displacement). The step
// of length l moves the walker along that heading:
//   r = S^{-1/2} · R(θ_k)ᵀ (p_k − p_{k−1}) − S^{-1/2} · (l, 0)ᵀ,   S = diag(σ_l², σ_c²)
// i.e. the displacement expressed along-track / cross-track in the step's own frame; σ_l is
// the step-length σ (Weinberg model error), σ_c the lateral sway of one step (the heading's
// own uncertainty lives in θ_k and its HeadingIncrementFactor / HeadingFactor). Optionally with
// the walk's step-length scale c: the model length becomes (1 + c)·l.
#ifndef WALKGRAPH_FACTORS_STEP_FACTOR_H_
#define WALKGRAPH_FACTORS_STEP_FACTOR_H_

#include <cmath>

#include <ceres/autodiff_cost_function.h>

namespace walkgraph {

class StepFactor {
 public:
  StepFactor(double length_m, double sigma_length_m, double sigma_cross_m)
      : length_m_(length_m),
        inv_sigma_l_(1.0 / sigma_length_m),
        inv_sigma_c_(1.0 / sigma_cross_m) {}

  template <typename T>
  bool operator()(const T* p_prev, const T* p, const T* theta, T* residual) const {
    return Residual(p_prev, p, theta, T(length_m_), residual);
  }

  // With the walk's step-length scale c (one block for the walk): the step is (1 + c)·l long,
  // the front end's step-length model off by the factor 1 + c (e.g. a Weinberg K that does not
  // fit the walker).
  template <typename T>
  bool operator()(const T* p_prev, const T* p, const T* theta, const T* scale, T* residual) const {
    return Residual(p_prev, p, theta, (T(1.0) + scale[0]) * T(length_m_), residual);
  }

  // Blocks: p_{k−1} (2), p_k (2), θ_k (1).
  static ceres::CostFunction* Create(double length_m, double sigma_length_m, double sigma_cross_m) {
    return new ceres::AutoDiffCostFunction<StepFactor, 2, 2, 2, 1>(
        new StepFactor(length_m, sigma_length_m, sigma_cross_m));
  }
  // Blocks: p_{k−1} (2), p_k (2), θ_k (1), c (1).
  static ceres::CostFunction* CreateWithScale(double length_m, double sigma_length_m,
                                              double sigma_cross_m) {
    return new ceres::AutoDiffCostFunction<StepFactor, 2, 2, 2, 1, 1>(
        new StepFactor(length_m, sigma_length_m, sigma_cross_m));
  }

 private:
  // The residual of the top of this file for a model step length `length`.
  template <typename T>
  bool Residual(const T* p_prev, const T* p, const T* theta, const T& length, T* residual) const {
    using std::cos;
    using std::sin;
    const T dx = p[0] - p_prev[0], dy = p[1] - p_prev[1];
    const T c = cos(theta[0]), s = sin(theta[0]);
    residual[0] = (c * dx + s * dy - length) * T(inv_sigma_l_);
    residual[1] = (-s * dx + c * dy) * T(inv_sigma_c_);
    return true;
  }

  double length_m_, inv_sigma_l_, inv_sigma_c_;
};

}  // namespace walkgraph

#endif  // WALKGRAPH_FACTORS_STEP_FACTOR_H_
