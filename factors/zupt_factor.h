// Zero-velocity update as a factor: the foot is still at a stance epoch (Foxlin 2005; 004's
// ZUPTs at foot stances).
//
//   r = v / σ_v,   v ∈ R³ the navigation-frame velocity of the state, σ_v per axis (m/s).
//
// Parameter block: v (3).
#ifndef WALKGRAPH_FACTORS_ZUPT_FACTOR_H_
#define WALKGRAPH_FACTORS_ZUPT_FACTOR_H_

#include <ceres/autodiff_cost_function.h>

namespace walkgraph {

class ZuptFactor {
 public:
  explicit ZuptFactor(double sigma_mps) : inv_sigma_(1.0 / sigma_mps) {}

  template <typename T>
  bool operator()(const T* v, T* residual) const {
    for (int i = 0; i < 3; ++i) residual[i] = v[i] * inv_sigma_;
    return true;
  }

  static ceres::CostFunction* Create(double sigma_mps) {
    return new ceres::AutoDiffCostFunction<ZuptFactor, 3, 3>(new ZuptFactor(sigma_mps));
  }

 private:
  double inv_sigma_;
};

}  // namespace walkgraph

#endif  // WALKGRAPH_FACTORS_ZUPT_FACTOR_H_
