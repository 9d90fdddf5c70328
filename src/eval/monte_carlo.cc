// Monte Carlo comparison: seeded walks on a thread pool, aggregated in run order.
#include <algorithm>
#include <atomic>
#include <cmath>
#include <map>
#include <mutex>
#include <optional>
#include <thread>

#include "walkgraph/compare.h"
#include "walkgraph/simulate.h"

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
  out.score_from_s = runs.front().score_from_s;
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
  // anees, mean_pct_distance: NaN (none) as soon as one run has none.
  const Field kMeanFields[] = {&ErrorStats::rmse_m,       &ErrorStats::mean_m,
                               &ErrorStats::max_m,        &ErrorStats::final_m,
                               &ErrorStats::pct_distance, &ErrorStats::mean_pct_distance,
                               &ErrorStats::anees};
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

StatusOr<Comparison> CompareScenario(const std::string& scenario, const ScenarioCompareOptions& sc,
                                     const CompareOptions& options, const MonteCarloOptions& mc,
                                     const EstimatorRegistry& registry) {
  bool known = false;
  for (const ScenarioInfo& s : Scenarios()) known |= s.name == scenario;
  if (!known) {
    std::string names;
    for (const ScenarioInfo& s : Scenarios()) names += (names.empty() ? "" : ", ") + s.name;
    return NotFound("unknown scenario '" + scenario + "'; known: " + names);
  }
  if (mc.runs < 1) return InvalidArgument("Monte Carlo: runs must be >= 1");
  const std::string prefix = sc.overrides_origin.empty() ? "" : sc.overrides_origin + ": ";
  auto located = [&prefix](const Status& s) { return Status(s.code(), prefix + s.message()); };
  // Run 0 is simulated first, alone, on the caller's node: override errors keep their YAML line
  // numbers. Later runs simulate on private copies (a yaml-cpp lookup may modify the node, so
  // threads must not share one).
  std::map<uint64_t, int> run_of_seed;
  for (int i = 0; i < mc.runs; ++i) run_of_seed[MonteCarloSeed(mc.seed, i)] = i;
  StatusOr<Simulation> first =
      SimulateScenarioDetailed(scenario, MonteCarloSeed(mc.seed, 0), sc.overrides);
  if (!first.ok()) return located(first.status());
  PcrbAccumulator pcrb_sum(mc.runs);
  std::mutex mutex;  // guards the fields below
  Status pcrb_status;
  bool pcrb_on = sc.pcrb;
  std::optional<Walk> first_walk;
  auto add_pcrb = [&](int run, const Simulation& s) {
    {
      std::lock_guard<std::mutex> lock(mutex);
      if (!pcrb_on) return;
    }
    StatusOr<PcrbInformation> info = PcrbInformationFromSimulation(s, sc.pcrb_options);
    Status st = info.ok() ? pcrb_sum.Add(run, std::move(info).value()) : info.status();
    if (!st.ok()) {
      std::lock_guard<std::mutex> lock(mutex);
      if (pcrb_status.ok()) pcrb_status = st;
      pcrb_on = false;
    }
  };
  add_pcrb(0, *first);
  first_walk = std::move(first->walk);
  const YAML::Node overrides = sc.overrides;
  const WalkGenerator generate = [&](uint64_t seed) -> StatusOr<Walk> {
    const int run = run_of_seed.at(seed);
    YAML::Node node;
    {
      std::lock_guard<std::mutex> lock(mutex);
      if (run == 0 && first_walk) {
        Walk w = std::move(*first_walk);
        first_walk.reset();
        return w;
      }
      if (overrides.IsDefined() && !overrides.IsNull()) node = YAML::Clone(overrides);
    }
    StatusOr<Simulation> s = SimulateScenarioDetailed(scenario, seed, node);
    if (!s.ok()) return located(s.status());
    add_pcrb(run, *s);
    return std::move(s->walk);
  };
  WG_ASSIGN_OR_RETURN(Comparison c, CompareMonteCarlo(generate, options, mc, registry));
  if (!sc.pcrb) return c;
  if (!pcrb_status.ok()) {
    if (pcrb_status.code() != StatusCode::kFailedPrecondition) return located(pcrb_status);
    c.pcrb_note = pcrb_status.message();
    return c;
  }
  WG_ASSIGN_OR_RETURN(PcrbInformation mean, pcrb_sum.Mean());
  WG_ASSIGN_OR_RETURN(PcrbBound bound, ComputePcrb(mean));
  AttachPcrb(bound, &c);
  return c;
}

}  // namespace walkgraph
