// util/geodesy.h: WGS84 latitude/longitude <-> east/north metres in a local tangent plane.
#include "util/geodesy.h"

#include <cmath>

#include <gtest/gtest.h>

namespace walkgraph::internal {
namespace {

TEST(LocalTangentPlane, OriginIsZeroAndAxesPointEastAndNorth) {
  const LocalTangentPlane plane(40.3132, -3.4834);
  const Eigen::Vector2d o = plane.EastNorth(40.3132, -3.4834);
  EXPECT_NEAR(o.norm(), 0.0, 1e-9);
  const Eigen::Vector2d north = plane.EastNorth(40.3142, -3.4834);  // 0.001° north
  EXPECT_NEAR(north.x(), 0.0, 1e-3);
  EXPECT_NEAR(north.y(), 111.03, 0.05);  // WGS84 metres per 0.001° of latitude at 40°
  const Eigen::Vector2d east = plane.EastNorth(40.3132, -3.4824);  // 0.001° east
  EXPECT_NEAR(east.x(), 85.0, 0.2);                                // 111.32 m · cos(40.3°)
  EXPECT_NEAR(east.y(), 0.0, 0.01);
}

TEST(LocalTangentPlane, LatLonInvertsEastNorth) {
  const LocalTangentPlane plane(-33.9, 151.2);
  for (const Eigen::Vector2d en :
       {Eigen::Vector2d(120.0, -45.0), Eigen::Vector2d(-2500.0, 1800.0)}) {
    const Eigen::Vector2d ll = plane.LatLon(en.x(), en.y());
    const Eigen::Vector2d back = plane.EastNorth(ll.x(), ll.y());
    EXPECT_NEAR(back.x(), en.x(), 1e-6);
    EXPECT_NEAR(back.y(), en.y(), 1e-6);
  }
}

}  // namespace
}  // namespace walkgraph::internal
