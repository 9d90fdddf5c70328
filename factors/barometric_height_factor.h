// BarometricHeightFactor: the height change between two nodes measured by a barometer,
//   r = ((z_j − z_i) − Δh) / σ,
// Δh from the pressures at the two nodes by the hypsometric formula (BarometricHeightM), σ the
// barometer's noise on a difference of two node readings plus its drift (weather, air
// conditioning) over the time between them: σ² = 2σ_z² + q·Δt.
#ifndef WALKGRAPH_FACTORS_BAROMETRIC_HEIGHT_FACTOR_H_
#define WALKGRAPH_FACTORS_BAROMETRIC_HEIGHT_FACTOR_H_

#include <cmath>

#include <ceres/autodiff_cost_function.h>

namespace walkgraph {

// Height (m) of pressure `hpa` above the level of pressure `ref_hpa`, by the standard
// atmosphere's hypsometric formula h = 44330.8·(1 − (p/p_ref)^0.190263) (ICAO standard
// atmosphere, troposphere; ≈ 8.4 m per hPa near 1000 hPa).
inline double BarometricHeightM(double hpa, double ref_hpa) {
  return 44330.8 * (1.0 - std::pow(hpa / ref_hpa, 0.190263));
}

// Its inverse: the pressure height_m above the level of pressure `ref_hpa`,
// p = p_ref·(1 − h/44330.8)^(1/0.190263) (the simulator's barometer).
inline double BarometricPressureHpa(double height_m, double ref_hpa) {
  return ref_hpa * std::pow(1.0 - height_m / 44330.8, 1.0 / 0.190263);
}

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
