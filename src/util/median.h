// The median of a sample (the upper one for an even count; 0 for none), by nth_element.
#ifndef WALKGRAPH_UTIL_MEDIAN_H_
#define WALKGRAPH_UTIL_MEDIAN_H_

#include <algorithm>
#include <cstddef>
#include <vector>

namespace walkgraph::internal {

inline double Median(std::vector<double> v) {
  if (v.empty()) return 0.0;
  const auto mid = v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2);
  std::nth_element(v.begin(), mid, v.end());
  return *mid;
}

}  // namespace walkgraph::internal

#endif  // WALKGRAPH_UTIL_MEDIAN_H_
