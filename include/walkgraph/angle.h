// The one place where angles are wrapped.
//
// NormalizeAngle(a) = a - 2π·floor((a + π) / 2π) ∈ [-π, π). Templated so that the same
// function serves the filters (double) and the Ceres cost functions (ceres::Jet: floor is
// found by argument-dependent lookup).
#ifndef WALKGRAPH_ANGLE_H_
#define WALKGRAPH_ANGLE_H_

#include <cmath>

namespace walkgraph {

inline constexpr double kPi = 3.14159265358979323846;

template <typename T>
inline T NormalizeAngle(const T& angle_rad) {
  using std::floor;
  const T two_pi(2.0 * kPi);
  return angle_rad - two_pi * floor((angle_rad + T(kPi)) / two_pi);
}

inline constexpr double DegToRad(double deg) { return deg * kPi / 180.0; }
inline constexpr double RadToDeg(double rad) { return rad * 180.0 / kPi; }

}  // namespace walkgraph

#endif  // WALKGRAPH_ANGLE_H_
