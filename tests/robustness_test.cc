// Every estimator on faulty data (issue 17): a 10 s IMU gap, a 50 % RSS outage and 20 % NLOS
// readings (+15 dB path loss) on tarrio-circle. Per fault and estimator, the mean RMSE over
// seeded walks against the same walks without the fault:
//   - every factor-graph estimator within 2× (the outage: see below);
//   - any run more than 10× its nominal RMSE is flagged diverged (divergence.h), never a number
//     (dead reckoning alone aside: see DeadReckoningOnly).
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>
#include <string>
#include <utility>
#include <vector>

#include <gtest/gtest.h>
#include <yaml-cpp/yaml.h>

#include "test_util.h"
#include "walkgraph/angle.h"
#include "walkgraph/compare.h"
#include "walkgraph/simulate.h"

namespace walkgraph {
namespace {

enum class Fault { kNone, kImuGap, kImuGapInTurn, kRssOutage, kNlos };

// The first time at or after `from` at which the truth's direction of travel turns by more than
// 45° within 2 s (directions over 1 s of truth), or `from` when it never does.
double FirstTurnAfter(const Walk& w, double from) {
  auto at = [&w](double t) {
    auto it = std::lower_bound(w.truth.begin(), w.truth.end(), t,
                               [](const TruthSample& s, double v) { return s.t_s < v; });
    return it == w.truth.end() ? w.truth.back().position_m : it->position_m;
  };
  auto direction = [&at](double t) {
    const Eigen::Vector3d d = at(t + 1.0) - at(t);
    return std::atan2(d.y(), d.x());
  };
  for (double t = from; t + 3.0 < w.truth.back().t_s; t += 0.1) {
    if (std::abs(NormalizeAngle(direction(t + 2.0) - direction(t))) > kPi / 4) return t + 1.0;
  }
  return from;
}

// The walk of `seed` with `fault`: IMU rows of [40 %, 40 % + 10 s) of the walk deleted (in a
// turn: the 10 s centred on the first turn after 40 % of the walk); RSS
// rows of its middle half deleted; 20 % of the readings NLOS (the simulator's own model).
Walk Faulty(uint64_t seed, Fault fault, const std::string& scenario = "tarrio-circle",
            const std::string& overrides = "{}") {
  YAML::Node o = YAML::Load(overrides);
  if (fault == Fault::kNlos) o["nlos_fraction"] = 0.2;
  auto w = SimulateScenario(scenario, seed, o);
  EXPECT_TRUE(w.ok());
  if (!w.ok()) return {};
  const double t0 = w->StartTime(), t1 = w->EndTime();
  if (fault == Fault::kImuGap || fault == Fault::kImuGapInTurn) {
    double a = t0 + 0.4 * (t1 - t0);
    if (fault == Fault::kImuGapInTurn) a = FirstTurnAfter(*w, a) - 5.0;
    const double b = a + 10.0;
    std::vector<ImuSample> kept;
    for (const ImuSample& s : w->imu) {
      if (s.t_s < a || s.t_s >= b) kept.push_back(s);
    }
    w->imu = kept;
  } else if (fault == Fault::kRssOutage) {
    const double a = t0 + 0.25 * (t1 - t0), b = t0 + 0.75 * (t1 - t0);
    std::vector<RssSample> kept;
    for (const RssSample& s : w->rss) {
      if (s.t_s < a || s.t_s >= b) kept.push_back(s);
    }
    w->rss = kept;
  }
  return *w;
}

const char* Name(Fault f) {
  return f == Fault::kImuGap ? "10 s IMU gap" : f == Fault::kRssOutage ? "50 % RSS outage" : "NLOS";
}

bool FactorGraph(const std::string& id) { return id.rfind("fg-", 0) == 0; }

// Dead reckoning alone loses the gap's 10 m of walking for good (nothing absolute brings it
// back): a worse estimate, honestly so (its covariance grows), not a diverged one. Measured
// pdr-only 0.72 → 10.6 m on one seed.
bool DeadReckoningOnly(const std::string& id) {
  return id == "pdr-only" || id == "odometry-dr" || id == "zupt-ins" || id == "jimenez-iez" ||
         id == "jimenez-iez-rts" || id.find("-imu") != std::string::npos;
}

TEST(Robustness, FactorGraphsHoldAndRunawaysAreFlagged) {
  const int runs = testing::kSanitized ? 1 : 6;  // accuracy is judged without sanitizers
  std::map<Fault, std::map<std::string, double>> mean_rmse;  // ranked runs only
  std::map<Fault, std::map<std::string, int>> ranked_runs;
  for (int i = 0; i < runs; ++i) {
    const uint64_t seed = MonteCarloSeed(1717, i);
    std::map<std::string, double> nominal;
    for (Fault f : {Fault::kNone, Fault::kImuGap, Fault::kRssOutage, Fault::kNlos}) {
      auto c = CompareOnWalk(Faulty(seed, f), CompareOptions());
      ASSERT_TRUE(c.ok()) << c.status().message();
      for (const EstimatorOutcome& o : c->outcomes) {
        if (!o.status.ok()) continue;
        if (f == Fault::kNone) nominal[o.id] = o.Ranked() ? o.stats.rmse_m : NAN;
        if (o.Ranked()) {
          mean_rmse[f][o.id] += o.stats.rmse_m;
          ++ranked_runs[f][o.id];
        }
        const double n = nominal.count(o.id) ? nominal[o.id] : NAN;
        if (f != Fault::kNone && o.Ranked() && std::isfinite(n) && !DeadReckoningOnly(o.id)) {
          EXPECT_LE(o.stats.rmse_m, 10.0 * n)
              << o.id << " with " << Name(f) << " (seed " << seed
              << "): over 10x its nominal RMSE and not flagged diverged";
        }
        if (FactorGraph(o.id)) EXPECT_TRUE(o.Ranked()) << o.id << " " << Name(f) << " diverged";
      }
    }
  }
  for (Fault f : {Fault::kImuGap, Fault::kRssOutage, Fault::kNlos}) {
    for (const auto& [id, sum] : mean_rmse[f]) {
      if (!FactorGraph(id)) continue;
      const double rmse = sum / ranked_runs[f][id];
      const double nominal = mean_rmse[Fault::kNone][id] / ranked_runs[Fault::kNone][id];
      std::printf("%-18s %-16s RMSE %.3f m, nominal %.3f m (%.2fx)\n", id.c_str(), Name(f), rmse,
                  nominal, rmse / nominal);
      if (testing::kSanitized) continue;
      EXPECT_LE(rmse, 2.0 * nominal) << id << " " << Name(f);
    }
  }
}

// The foot-INS graph across a 10 s IMU gap (jimenez-building, 3 laps): bridged, not integrated
// (measured on seed 1 with 8 laps: fg-ins-batch 0.21 → 0.24 m, fg-ins-window 0.36 → 0.52 m;
// before the bridge 8.3 and 7.8 m). The gap's 10 m are interpolated, so the ratio depends on
// the walk's length: 1 lap gave 2.3-5.2x. jimenez-iez-rss (IMU + RSS) integrates across the
// gap and must stay within 10x or be flagged. (Every estimator on jimenez-building, 1 lap,
// seeds 1-6 with the gap: none over 3x unflagged but zupt-ins, dead reckoning alone.)
// Mean RMSE over `runs` seeds of jimenez-building (3 laps) without and with `fault`, per
// factor-graph estimator of `ids`; every estimator that is not flagged stays within 10x.
std::map<std::string, std::pair<double, double>> FootGapRmse(Fault fault,
                                                             const std::vector<std::string>& ids,
                                                             int runs) {
  CompareOptions co;
  co.estimator_ids = ids;
  std::map<std::string, std::pair<double, double>> out;  // id → (nominal, with the fault)
  for (int i = 0; i < runs; ++i) {
    const uint64_t seed = MonteCarloSeed(1718, i);
    auto n = CompareOnWalk(Faulty(seed, Fault::kNone, "jimenez-building", "{laps: 3}"), co);
    auto g = CompareOnWalk(Faulty(seed, fault, "jimenez-building", "{laps: 3}"), co);
    EXPECT_TRUE(n.ok() && g.ok());
    if (!n.ok() || !g.ok()) return {};
    for (size_t k = 0; k < co.estimator_ids.size(); ++k) {
      const EstimatorOutcome &a = n->outcomes[k], &b = g->outcomes[k];
      EXPECT_TRUE(a.status.ok() && b.status.ok()) << a.id;
      EXPECT_TRUE(a.Ranked()) << a.id << " diverged on the clean walk";
      if (b.Ranked()) {
        EXPECT_LE(b.stats.rmse_m, 10.0 * a.stats.rmse_m) << b.id << ": runaway not flagged";
      }
      if (!FactorGraph(a.id)) continue;
      EXPECT_TRUE(b.Ranked()) << b.id;
      out[a.id].first += a.stats.rmse_m / runs;
      out[a.id].second += b.stats.rmse_m / runs;
    }
  }
  for (const auto& [id, r] : out) {
    std::printf("%-22s %s: RMSE %.3f m, nominal %.3f m (%.2fx)\n", id.c_str(),
                fault == Fault::kImuGapInTurn ? "10 s IMU gap in a turn" : Name(fault), r.second,
                r.first, r.second / r.first);
  }
  return out;
}

TEST(Robustness, FootInsGraphBridgesAnImuGap) {
  const int runs = testing::kSanitized ? 1 : 8;
  for (const auto& [id, r] : FootGapRmse(
           Fault::kImuGap,
           {"fg-ins-batch", "fg-ins-window", "fg-ins-window-online", "jimenez-iez-rss"}, runs)) {
    // The target is 2x, for the online output too. On these 8 seeds fg-ins-batch 1.07x,
    // fg-ins-window 1.26x, fg-ins-window-online 1.69x; on the first 3 alone (the test's count
    // until the gap's reach bound and magnetic yaw tie, InsGraphOptions::use_gap_reach /
    // use_gap_magnetometer) 0.99x, 1.20x and 2.13x (online 2.48x before those factors, 2.31x
    // before the held solves could iterate to InsWindowOptions::gap_max_iterations, 4.19x
    // before the readings of the gap were interpolated across it; fg-ins-window 1.70x before
    // that, 2.82x before it was held open across the gap: InsWindowOptions::gap_hold_max_s).
    if (!testing::kSanitized) EXPECT_LE(r.second, 2.0 * r.first) << id;
  }
}

// The foot-INS graphs under the other faults of issue 17's target (2x): the middle half of the
// RSS readings gone, and 20 % of them NLOS (+15 dB). Measured here: outage fg-ins-batch 1.15x,
// fg-ins-window 1.63x, online 1.55x; NLOS 1.31x, 1.23x, 1.21x (CLI, seeds 1-3: outage 1.26x,
// 1.51x, 1.34x; NLOS 1.29x, 1.80x, 1.63x). Accuracy only: the sanitizer build runs the same
// code in the gap tests above.
TEST(Robustness, FootInsGraphHoldsUnderRssOutageAndNlos) {
  if (testing::kSanitized) GTEST_SKIP() << "accuracy figures: Release only";
  for (Fault f : {Fault::kRssOutage, Fault::kNlos}) {
    for (const auto& [id, r] :
         FootGapRmse(f, {"fg-ins-batch", "fg-ins-window", "fg-ins-window-online"}, 3)) {
      EXPECT_LE(r.second, 2.0 * r.first) << id << " " << Name(f);
    }
  }
}

// A gap that holds one of the walk's 90° turns: the states after it start from the heading
// before it. With window_max_iterations (10) per held solve they stayed there: here
// fg-ins-window 13.3x and online 16.7x, unflagged (CLI, 8 seeds, the gap at 43 % / 46 % of
// the walk: 8.5x / 7.2x and 9.9x / 12.1x). With gap_max_iterations (100): 1.83x and 3.99x
// here (CLI: 2.06x / 1.99x and 3.9x / 3.7x); with the magnetic yaw tie across the gap 1.81x
// and 3.64x (the reach bound is inactive in a turn). fg-ins-batch 1.69x: the truth's corner inside
// the gap is scored against the line between the states around it (no estimator has a
// position inside an IMU gap).
TEST(Robustness, FootInsWindowTurnsAcrossAGapThatHoldsATurn) {
  const int runs = testing::kSanitized ? 1 : 3;
  for (const auto& [id, r] : FootGapRmse(
           Fault::kImuGapInTurn, {"fg-ins-batch", "fg-ins-window", "fg-ins-window-online"}, runs)) {
    const double bound = id == "fg-ins-window-online" ? 4.5 : 3.0;
    if (!testing::kSanitized) EXPECT_LE(r.second, bound * r.first) << id;
  }
}

}  // namespace
}  // namespace walkgraph
