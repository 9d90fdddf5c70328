// Helpers shared by the test files (not a unit of its own).
#ifndef WALKGRAPH_TESTS_TEST_UTIL_H_
#define WALKGRAPH_TESTS_TEST_UTIL_H_

#include <algorithm>
#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <yaml-cpp/yaml.h>

#include "walkgraph/compare.h"
#include "walkgraph/simulate.h"

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

// The simulated foot walk without any rest (jimenez-building, 40 s, no standstill at either end)
// with the IMU alone: magnetometer, radio and start removed.
inline StatusOr<Walk> FootWalkWithoutRest(uint64_t seed) {
  StatusOr<Walk> w = SimulateScenario(
      "jimenez-building", seed, YAML::Load("{duration_s: 40, start_still_s: 0, end_still_s: 0}"));
  if (!w.ok()) return w;
  for (ImuSample& s : w->imu) s.has_mag = false;
  w->rss.clear();
  w->anchors.clear();
  w->meta.initial_pose.reset();
  return w;
}

// Seeded Monte Carlo of estimators `ids` on a simulator preset with YAML `overrides`; every
// estimator must run on every walk (expectations), an empty Comparison when the study fails.
inline Comparison ScenarioMonteCarlo(const std::string& scenario, const std::string& overrides,
                                     const std::vector<std::string>& ids, int runs, uint64_t seed,
                                     double score_from_s = 0.0,
                                     const std::map<std::string, Config>& configs = {}) {
  CompareOptions co;
  co.estimator_ids = ids;
  co.score_from_s = score_from_s;
  co.configs = configs;
  MonteCarloOptions mc;
  mc.runs = runs;
  mc.seed = seed;
  auto c = CompareMonteCarlo(
      [&](uint64_t s) { return SimulateScenario(scenario, s, YAML::Load(overrides)); }, co, mc);
  EXPECT_TRUE(c.ok()) << c.status().message();
  if (!c.ok()) return {};
  for (const EstimatorOutcome& o : c->outcomes) {
    EXPECT_TRUE(o.status.ok()) << o.id << ": " << o.status.message();
    EXPECT_EQ(o.failed_runs, 0) << o.id;
  }
  return *c;
}

// The aggregate statistics of estimator `id` in `c` (a test failure when it is absent).
inline const ErrorStats& StatsOf(const Comparison& c, const std::string& id) {
  for (const EstimatorOutcome& o : c.outcomes) {
    if (o.id == id) return o.stats;
  }
  static const ErrorStats none;
  ADD_FAILURE() << "no outcome " << id;
  return none;
}

}  // namespace walkgraph::testing

#endif  // WALKGRAPH_TESTS_TEST_UTIL_H_
