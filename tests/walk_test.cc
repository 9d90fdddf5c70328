// The Walk type's own helpers (src/walk.cc).
#include "walkgraph/walk.h"

#include <gtest/gtest.h>

namespace walkgraph {
namespace {

Walk Imu(const std::vector<double>& t) {
  Walk w;
  for (double x : t) w.imu.push_back({x, Eigen::Vector3d(0, 0, 9.81), Eigen::Vector3d::Zero()});
  return w;
}

TEST(WalkImuGaps, HolesLongerThanTenMedianIntervalsAreGaps) {
  std::vector<double> t;
  for (int i = 0; i < 100; ++i) t.push_back(0.01 * i);        // 100 Hz, 0 .. 0.99 s
  for (int i = 0; i < 100; ++i) t.push_back(1.5 + 0.01 * i);  // a 0.51 s hole
  for (int i = 0; i < 100; ++i) t.push_back(2.5 + 0.01 * i);  // 2.49 → 2.50: no hole
  t.push_back(4.0);  // 3.49 → 4.0: a second hole
  const std::vector<ImuGap> gaps = Imu(t).ImuGaps();
  ASSERT_EQ(gaps.size(), 2u);
  EXPECT_DOUBLE_EQ(gaps[0].t_begin_s, 0.99);
  EXPECT_DOUBLE_EQ(gaps[0].t_end_s, 1.5);
  EXPECT_NEAR(gaps[0].duration_s(), 0.51, 1e-12);
  EXPECT_DOUBLE_EQ(gaps[1].t_end_s, 4.0);
  // Jitter within 10 median intervals is not a gap; nor is anything in a 2-sample stream.
  EXPECT_TRUE(Imu({0.0, 0.01, 0.03, 0.04, 0.12, 0.13}).ImuGaps().empty());
  EXPECT_TRUE(Imu({0.0, 100.0}).ImuGaps().empty());
}

}  // namespace
}  // namespace walkgraph
