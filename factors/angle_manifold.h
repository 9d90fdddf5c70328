// A heading angle as a Ceres manifold: ambient and tangent size 1, wrapped to [−π, π).
//
//   Plus(θ, δ)  = NormalizeAngle(θ + δ),      ∂Plus/∂δ at δ = 0 = 1
//   Minus(φ, θ) = NormalizeAngle(φ − θ),      ∂Minus/∂φ at φ = θ = 1
// so every heading block stays wrapped and differences never jump by 2π (Ceres' own
// pose_graph_2d example uses the same construction).
#ifndef WALKGRAPH_FACTORS_ANGLE_MANIFOLD_H_
#define WALKGRAPH_FACTORS_ANGLE_MANIFOLD_H_

#include <ceres/manifold.h>

#include "walkgraph/angle.h"

namespace walkgraph {

class AngleManifold : public ceres::Manifold {
 public:
  int AmbientSize() const override { return 1; }
  int TangentSize() const override { return 1; }
  bool Plus(const double* x, const double* delta, double* x_plus_delta) const override {
    x_plus_delta[0] = NormalizeAngle(x[0] + delta[0]);
    return true;
  }
  bool PlusJacobian(const double* /*x*/, double* jacobian) const override {
    jacobian[0] = 1.0;
    return true;
  }
  bool Minus(const double* y, const double* x, double* y_minus_x) const override {
    y_minus_x[0] = NormalizeAngle(y[0] - x[0]);
    return true;
  }
  bool MinusJacobian(const double* /*x*/, double* jacobian) const override {
    jacobian[0] = 1.0;
    return true;
  }
};

}  // namespace walkgraph

#endif  // WALKGRAPH_FACTORS_ANGLE_MANIFOLD_H_
