// BarometricHeightFactor: the height change between two nodes measured by a barometer,
//   r = ((z_j − z_i) − Δh) / σ,
// Δh from the pressures at the two nodes by the hypsometric formula (BarometricHeightM,
// walkgraph/barometric.h), σ the barometer's noise on a difference of two node readings plus its
// drift (weather, air conditioning) over the time between them: σ² = 2σ_z² + q·Δt.
#ifndef WALKGRAPH_FACTORS_BAROMETRIC_HEIGHT_FACTOR_H_
#define WALKGRAPH_FACTORS_BAROMETRIC_HEIGHT_FACTOR_H_

#include <cmath>

#include <ceres/autodiff_cost_function.h>

#include "walkgraph/barometric.h"

namespace walkgraph {

class BarometricHeightFactor {
 public:
  BarometricHeightFactor(double dh_m, double sigma_m) : dh_m_(dh_m), inv_sigma_(1.0 / sigma_m) {}

  template <typename T>
  bool operator()(const T* z_i, const T* z_j, T* residual) const {
    residual[0] = ((z_j[0] - z_i[0]) - T(dh_m_)) * T(inv_sigma_);
    return true;
  }

  // Blocks: z_i (1), z_j (1). sigma_m > 0.
  static ceres::CostFunction* Create(double dh_m, double sigma_m) {
    return new ceres::AutoDiffCostFunction<BarometricHeightFactor, 1, 1, 1>(
        new BarometricHeightFactor(dh_m, sigma_m));
  }

 private:
  double dh_m_, inv_sigma_;
};

}  // namespace walkgraph

#endif  // WALKGRAPH_FACTORS_BAROMETRIC_HEIGHT_FACTOR_H_
