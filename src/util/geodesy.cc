#include "util/geodesy.h"

#include <cmath>

namespace walkgraph::internal {

namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kA = 6378137.0, kF = 1.0 / 298.257223563, kE2 = kF * (2.0 - kF);

Eigen::Vector3d Ecef(double lat_deg, double lon_deg) {
  const double lat = lat_deg * kPi / 180.0, lon = lon_deg * kPi / 180.0;
  const double n = kA / std::sqrt(1.0 - kE2 * std::sin(lat) * std::sin(lat));
  return {n * std::cos(lat) * std::cos(lon), n * std::cos(lat) * std::sin(lon),
          n * (1.0 - kE2) * std::sin(lat)};
}

}  // namespace

LocalTangentPlane::LocalTangentPlane(double lat0_deg, double lon0_deg)
    : lat0_deg_(lat0_deg), lon0_deg_(lon0_deg) {
  const double lat = lat0_deg * kPi / 180.0, lon = lon0_deg * kPi / 180.0;
  origin_ = Ecef(lat0_deg, lon0_deg);
  east_ = Eigen::Vector3d(-std::sin(lon), std::cos(lon), 0.0);
  north_ = Eigen::Vector3d(-std::sin(lat) * std::cos(lon), -std::sin(lat) * std::sin(lon),
                           std::cos(lat));
}

Eigen::Vector2d LocalTangentPlane::EastNorth(double lat_deg, double lon_deg) const {
  const Eigen::Vector3d d = Ecef(lat_deg, lon_deg) - origin_;
  return {east_.dot(d), north_.dot(d)};
}

Eigen::Vector2d LocalTangentPlane::LatLon(double east_m, double north_m) const {
  // Fixed point on EastNorth: each pass corrects by the residual over a sphere's metres per
  // degree, which differ from the ellipsoid's by < 0.7 %, so the error shrinks 150× per pass.
  constexpr double kR = 6371000.0;
  double lat = lat0_deg_, lon = lon0_deg_;
  for (int i = 0; i < 8; ++i) {
    const Eigen::Vector2d en = EastNorth(lat, lon);
    lat += (north_m - en.y()) / kR * 180.0 / kPi;
    lon += (east_m - en.x()) / (kR * std::cos(lat * kPi / 180.0)) * 180.0 / kPi;
  }
  return {lat, lon};
}

}  // namespace walkgraph::internal
