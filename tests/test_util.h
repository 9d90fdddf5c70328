// Helpers shared by the test files (not a unit of its own).
#ifndef WALKGRAPH_TESTS_TEST_UTIL_H_
#define WALKGRAPH_TESTS_TEST_UTIL_H_

#include <algorithm>

namespace walkgraph::testing {

// Monte Carlo run count for accuracy tests: `runs` in the Release suite, which is where the
// accuracy targets are judged; a fifth of it (at least 3) in the sanitizer build, whose job is
// memory and UB errors on the same code paths, at 5-20x the run time.
inline int MonteCarloRuns(int runs) {
#ifdef WALKGRAPH_SANITIZED
  return std::max(3, runs / 5);
#else
  return runs;
#endif
}

// True in the sanitizer build (accuracy tolerances are judged only without it, where
// MonteCarloRuns gives the full count).
inline constexpr bool kSanitized =
#ifdef WALKGRAPH_SANITIZED
    true;
#else
    false;
#endif

}  // namespace walkgraph::testing

#endif  // WALKGRAPH_TESTS_TEST_UTIL_H_
