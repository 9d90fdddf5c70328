// WGS84 latitude/longitude (height 0) <-> east/north metres in the tangent plane at an origin
// (internal; the IPIN converter's local frame and the IPIN submission writer).
#ifndef WALKGRAPH_SRC_UTIL_GEODESY_H_
#define WALKGRAPH_SRC_UTIL_GEODESY_H_

#include <Eigen/Core>

namespace walkgraph::internal {

class LocalTangentPlane {
 public:
  LocalTangentPlane(double lat0_deg, double lon0_deg);
  Eigen::Vector2d EastNorth(double lat_deg, double lon_deg) const;
  // The inverse of EastNorth: the latitude and longitude (degrees) of the point of the plane
  // (to < 1e-12° within a few km of the origin).
  Eigen::Vector2d LatLon(double east_m, double north_m) const;

 private:
  double lat0_deg_, lon0_deg_;
  Eigen::Vector3d origin_, east_, north_;
};

}  // namespace walkgraph::internal

#endif  // WALKGRAPH_SRC_UTIL_GEODESY_H_
