// The standard atmosphere's pressure–height relation, shared by the barometric height factor
// (factors/barometric_height_factor.h) and the simulator's barometer.
#ifndef WALKGRAPH_BAROMETRIC_H_
#define WALKGRAPH_BAROMETRIC_H_

#include <cmath>

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

}  // namespace walkgraph

#endif  // WALKGRAPH_BAROMETRIC_H_
