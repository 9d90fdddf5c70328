// The planar rigid motion that best maps one point set onto another (internal): Eigen's Umeyama
// least squares without scale, for the step graph's start alignment, compare's SE(2) alignment
// and the radio map's frames.
#ifndef WALKGRAPH_SRC_UTIL_RIGID2D_H_
#define WALKGRAPH_SRC_UTIL_RIGID2D_H_

#include <cstddef>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace walkgraph::internal {

// dst ≈ R src + t.
struct Rigid2d {
  Eigen::Matrix2d R = Eigen::Matrix2d::Identity();
  Eigen::Vector2d t = Eigen::Vector2d::Zero();
  Eigen::Vector2d operator()(const Eigen::Vector2d& p) const { return R * p + t; }
};

// The fit of the first `count` pairs (src[i], dst[i]); count >= 2 and at most both sizes.
inline Rigid2d FitRigid2d(const std::vector<Eigen::Vector2d>& src,
                          const std::vector<Eigen::Vector2d>& dst, size_t count) {
  Eigen::Matrix2Xd S(2, count), D(2, count);
  for (size_t i = 0; i < count; ++i) {
    S.col(static_cast<Eigen::Index>(i)) = src[i];
    D.col(static_cast<Eigen::Index>(i)) = dst[i];
  }
  const Eigen::Matrix3d T = Eigen::umeyama(S, D, /*with_scaling=*/false);
  Rigid2d f;
  f.R = T.topLeftCorner<2, 2>();
  f.t = T.topRightCorner<2, 1>();
  return f;
}

}  // namespace walkgraph::internal

#endif  // WALKGRAPH_SRC_UTIL_RIGID2D_H_
