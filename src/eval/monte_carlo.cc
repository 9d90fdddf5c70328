// Monte Carlo comparison: seeded walks on a thread pool, aggregated in run order.
#include <algorithm>
#include <atomic>
#include <cmath>
#include <mutex>
#include <thread>

#include "walkgraph/compare.h"

namespace walkgraph {

uint64_t MonteCarloSeed(uint64_t seed, int run) {
  // SplitMix64 (Steele, Lea, Flood 2014), as in Vigna's reference implementation.
  uint64_t z = seed + (static_cast<uint64_t>(run) + 1) * 0x9E3779B97F4A7C15ULL;
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ULL;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBULL;
  return z ^ (z >> 31);
}

namespace {

struct MeanStd {
  double mean = 0.0, std = 0.0;
};

MeanStd Spread(const std::vector<double>& v) {
  MeanStd r;
  if (v.empty()) return r;
  for (double x : v) r.mean += x;
  r.mean /= static_cast<double>(v.size());
  if (v.size() < 2) return r;
  double ss = 0.0;
  for (double x : v) ss += (x - r.mean) * (x - r.mean);
  r.std = std::sqrt(ss / static_cast<double>(v.size() - 1));
  return r;
}

}  // namespace

StatusOr<Comparison> AggregateRuns(const std::vector<Comparison>& runs) {
  if (runs.empty()) return InvalidArgument("Monte Carlo: no runs to aggregate");
  Comparison out;
  out.walk_name = runs.front().walk_name;
  out.runs = static_cast<int>(runs.size());
  out.truth_kind = runs.front().truth_kind;
  out.anchors = runs.front().anchors;
  out.truth = runs.front().truth;
  // Estimators in order of first appearance.
  std::vector<std::string> ids;
  for (const Comparison& c : runs) {
    for (const EstimatorOutcome& o : c.outcomes) {
      if (std::find(ids.begin(), ids.end(), o.id) == ids.end()) ids.push_back(o.id);
    }
  }
  using Field = double ErrorStats::*;
  const Field kMeanFields[] = {&ErrorStats::rmse_m, &ErrorStats::mean_m, &ErrorStats::max_m,
                               &ErrorStats::final_m, &ErrorStats::pct_distance};
  const Field kPooledFields[] = {&ErrorStats::median_m, &ErrorStats::p75_m, &ErrorStats::p90_m};
  const double kPooledQ[] = {50.0, 75.0, 90.0};
  for (const std::string& id : ids) {
    EstimatorOutcome agg;
    agg.id = id;
    std::vector<const EstimatorOutcome*> ok;
    Status first_failure;
    for (size_t r = 0; r < runs.size(); ++r) {
      const EstimatorOutcome* found = nullptr;
      for (const EstimatorOutcome& o : runs[r].outcomes) {
        if (o.id == id) found = &o;
      }
      if (found == nullptr) {
        ++agg.failed_runs;
        if (first_failure.ok()) {
          first_failure = FailedPrecondition("run " + std::to_string(r) + ": not applicable");
        }
        continue;
      }
      if (!found->status.ok()) {
        ++agg.failed_runs;
        if (first_failure.ok()) {
          first_failure = Status(found->status.code(),
                                 "run " + std::to_string(r) + ": " + found->status.message());
        }
        continue;
      }
      if (ok.empty()) agg.result = found->result;
      ok.push_back(found);
      for (size_t i = 0; i < found->errors.t_s.size(); ++i) {
        agg.errors.t_s.push_back(found->errors.t_s[i]);
        agg.errors.error_m.push_back(found->errors.error_m[i]);
        agg.error_run.push_back(static_cast<int>(r));
      }
      agg.errors.n_skipped += found->errors.n_skipped;
    }
    if (ok.empty()) {
      agg.status = first_failure;
      out.outcomes.push_back(std::move(agg));
      continue;
    }
    ErrorStats stds;
    std::vector<double> v(ok.size());
    for (Field f : kMeanFields) {
      for (size_t k = 0; k < ok.size(); ++k) v[k] = ok[k]->stats.*f;
      const MeanStd m = Spread(v);
      agg.stats.*f = m.mean;
      stds.*f = m.std;
    }
    for (size_t j = 0; j < std::size(kPooledFields); ++j) {
      for (size_t k = 0; k < ok.size(); ++k) v[k] = ok[k]->stats.*kPooledFields[j];
      stds.*kPooledFields[j] = Spread(v).std;
      agg.stats.*kPooledFields[j] = Percentile(agg.errors.error_m, kPooledQ[j]);
    }
    for (size_t k = 0; k < ok.size(); ++k) v[k] = ok[k]->runtime_s;
    const MeanStd t = Spread(v);
    agg.runtime_s = t.mean;
    agg.runtime_std_s = t.std;
    agg.stats.n_points = static_cast<int>(agg.errors.error_m.size());
    agg.stats_std = stds;
    out.outcomes.push_back(std::move(agg));
  }
  return out;
}

StatusOr<Comparison> CompareMonteCarlo(const WalkGenerator& generate, const CompareOptions& options,
                                       const MonteCarloOptions& mc,
                                       const EstimatorRegistry& registry) {
  if (mc.runs < 1) return InvalidArgument("Monte Carlo: runs must be >= 1");
  if (!generate) return InvalidArgument("Monte Carlo: no walk generator");
  int threads = mc.threads > 0
                    ? mc.threads
                    : static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  threads = std::min(threads, mc.runs);

  std::vector<std::optional<Comparison>> results(mc.runs);
  std::vector<Status> errors(mc.runs);
  std::atomic<int> next{0};
  std::atomic<bool> failed{false};
  std::mutex progress_mutex;
  int done = 0;
  auto worker = [&] {
    while (!failed.load()) {
      const int i = next.fetch_add(1);
      if (i >= mc.runs) return;
      const uint64_t seed = MonteCarloSeed(mc.seed, i);
      StatusOr<Walk> walk = generate(seed);
      if (!walk.ok()) {
        errors[i] = Status(walk.status().code(), "run " + std::to_string(i) + " (seed " +
                                                     std::to_string(seed) +
                                                     "): " + walk.status().message());
        failed.store(true);
        return;
      }
      StatusOr<Comparison> c = CompareOnWalk(*walk, options, registry);
      if (!c.ok()) {
        errors[i] =
            Status(c.status().code(), "run " + std::to_string(i) + " (seed " +
                                          std::to_string(seed) + "): " + c.status().message());
        failed.store(true);
        return;
      }
      // Only the first run's truth is drawn; the others need not keep theirs.
      if (i != 0) c->truth.clear();
      results[i] = std::move(c).value();
      if (mc.progress) {
        std::lock_guard<std::mutex> lock(progress_mutex);
        mc.progress(++done, mc.runs);
      }
    }
  };
  std::vector<std::thread> pool;
  pool.reserve(threads);
  for (int t = 0; t < threads; ++t) pool.emplace_back(worker);
  for (std::thread& t : pool) t.join();
  for (const Status& s : errors) {
    if (!s.ok()) return s;
  }
  std::vector<Comparison> runs;
  runs.reserve(mc.runs);
  for (auto& r : results) runs.push_back(std::move(*r));
  WG_ASSIGN_OR_RETURN(Comparison out, AggregateRuns(runs));
  out.seed = mc.seed;
  return out;
}

}  // namespace walkgraph
