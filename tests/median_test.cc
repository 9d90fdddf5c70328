// util/median.h: the median of a sample.
#include "util/median.h"

#include <vector>

#include <gtest/gtest.h>

namespace walkgraph::internal {
namespace {

TEST(Median, OddCountIsTheMiddleValue) { EXPECT_EQ(Median({5.0, -1.0, 3.0}), 3.0); }

TEST(Median, EvenCountIsTheUpperOfTheTwoMiddleValues) {
  EXPECT_EQ(Median({4.0, 1.0, 3.0, 2.0}), 3.0);
}

TEST(Median, EmptyIsZeroAndOneValueIsItself) {
  EXPECT_EQ(Median({}), 0.0);
  EXPECT_EQ(Median({-7.5}), -7.5);
}

}  // namespace
}  // namespace walkgraph::internal
