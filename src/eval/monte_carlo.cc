// Monte Carlo comparison: seeded walks on a thread pool, aggregated in run order.
#include <algorithm>
#include <climits>
#include <cmath>
#include <condition_variable>
#include <iomanip>
#include <map>
#include <mutex>
#include <optional>
#include <sstream>

#include <yaml-cpp/yaml.h>

#include "eval/monte_carlo_share.h"
#include "util/parallel_for.h"
#include "util/text.h"
#include "util/text_spill.h"
#include "walkgraph/compare.h"
#include "walkgraph/parallel.h"
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

// Monte Carlo run counts: at least one, at most kMaxMonteCarloRuns.
Status CheckRuns(int runs) {
  if (runs >= 1 && runs <= kMaxMonteCarloRuns) return Status::Ok();
  return InvalidArgument("Monte Carlo: runs must be in [1, " + std::to_string(kMaxMonteCarloRuns) +
                         "], not " + std::to_string(runs) +
                         " (10^6 runs take days; split a larger study into seeds)");
}

// Mean (as the plain sum over n, in run order) and sample std (Welford) of a stream.
struct RunningStat {
  long long n = 0;
  double sum = 0.0, mean = 0.0, m2 = 0.0;
  void Add(double x) {
    ++n;
    sum += x;
    const double d = x - mean;
    mean += d / static_cast<double>(n);
    m2 += d * (x - mean);
  }
  double Mean() const { return n > 0 ? sum / static_cast<double>(n) : 0.0; }
  double Std() const { return n > 1 ? std::sqrt(m2 / static_cast<double>(n - 1)) : 0.0; }
};

using Field = double ErrorStats::*;
// anees, mean_pct_distance, the floor figures: NaN (none) as soon as one run has none. The
// IPIN score is the mean of the runs' scores (each a third quartile of its own run).
const Field kMeanFields[] = {
    &ErrorStats::rmse_m,  &ErrorStats::mean_m,       &ErrorStats::max_m,
    &ErrorStats::final_m, &ErrorStats::pct_distance, &ErrorStats::mean_pct_distance,
    &ErrorStats::anees,   &ErrorStats::ipin_score_m, &ErrorStats::floor_hit_rate};
const Field kPooledFields[] = {&ErrorStats::median_m, &ErrorStats::p75_m, &ErrorStats::p90_m};
const double kPooledQ[] = {50.0, 75.0, 90.0};

struct EstimatorAggregate {
  EstimatorOutcome outcome;  // id, first successful result and errors, failed_runs
  Status first_failure;
  std::optional<Divergence> first_divergence;
  RunningStat means[std::size(kMeanFields)];
  RunningStat per_run_percentiles[std::size(kPooledFields)];
  RunningStat runtime;
  QuantileSketch pooled;
  long long successes = 0;
};

std::string ErrorRows(const EstimatorOutcome& o, int run) {
  std::ostringstream out;
  out << std::setprecision(10);
  for (size_t i = 0; i < o.errors.t_s.size(); ++i) {
    out << o.errors.t_s[i] << ',' << o.id << ',' << o.errors.error_m[i] << ',' << run << '\n';
  }
  return out.str();
}

}  // namespace

struct RunAggregator::State {
  Comparison out;
  int runs = 0;
  std::vector<EstimatorAggregate> estimators;  // in order of first appearance
  std::shared_ptr<internal::TextSpill> rows = std::make_shared<internal::TextSpill>();

  EstimatorAggregate& Find(const std::string& id) {
    for (EstimatorAggregate& e : estimators) {
      if (e.outcome.id == id) return e;
    }
    EstimatorAggregate e;
    e.outcome.id = id;
    // Runs before this one did not have the estimator: not applicable there.
    e.outcome.failed_runs = runs;
    if (runs > 0) e.first_failure = FailedPrecondition("run 0: not applicable");
    estimators.push_back(std::move(e));
    return estimators.back();
  }
};

RunAggregator::RunAggregator() : state_(std::make_unique<State>()) {}
RunAggregator::~RunAggregator() = default;
RunAggregator::RunAggregator(RunAggregator&&) noexcept = default;
RunAggregator& RunAggregator::operator=(RunAggregator&&) noexcept = default;

void RunAggregator::Add(Comparison run) {
  State& st = *state_;
  const int r = st.runs;
  if (r == 0) {
    st.out.walk_name = run.walk_name;
    st.out.truth_kind = run.truth_kind;
    st.out.score_from_s = run.score_from_s;
    st.out.anchors = std::move(run.anchors);
    st.out.truth = std::move(run.truth);
  }
  st.out.warning_count += run.warning_count;
  for (const std::string& w : run.warnings) {
    if (st.out.warnings.size() >= static_cast<size_t>(kMaxWarningMessages)) break;
    st.out.warnings.push_back("run " + std::to_string(r) + ": " + w);
  }
  std::vector<bool> seen(st.estimators.size(), false);
  for (EstimatorOutcome& o : run.outcomes) {
    EstimatorAggregate& e = st.Find(o.id);
    seen.resize(st.estimators.size(), false);
    seen[&e - st.estimators.data()] = true;
    if (!o.status.ok()) {
      ++e.outcome.failed_runs;
      if (e.first_failure.ok()) {
        e.first_failure =
            Status(o.status.code(), "run " + std::to_string(r) + ": " + o.status.message());
      }
      continue;
    }
    if (o.divergence) {
      ++e.outcome.diverged_runs;
      e.outcome.divergence_kept_in_figures = o.divergence_kept_in_figures;
      if (!e.first_divergence) {
        e.first_divergence = o.divergence;
        e.first_divergence->reason = "run " + std::to_string(r) + ": " + o.divergence->reason;
      }
      if (!o.divergence_kept_in_figures) continue;
    }
    for (size_t j = 0; j < std::size(kMeanFields); ++j) e.means[j].Add(o.stats.*kMeanFields[j]);
    for (size_t j = 0; j < std::size(kPooledFields); ++j) {
      e.per_run_percentiles[j].Add(o.stats.*kPooledFields[j]);
    }
    e.runtime.Add(o.runtime_s);
    e.outcome.run_rmse_m.push_back(o.stats.rmse_m);
    for (double v : o.errors.error_m) e.pooled.Add(v);
    st.rows->Append(ErrorRows(o, r));
    e.outcome.errors.n_skipped += o.errors.n_skipped;
    if (e.successes++ == 0) {
      const int skipped = e.outcome.errors.n_skipped;
      e.outcome.result = std::move(o.result);
      e.outcome.errors = std::move(o.errors);
      e.outcome.errors.n_skipped = skipped;
    }
  }
  for (size_t k = 0; k < st.estimators.size(); ++k) {
    if (seen[k]) continue;
    EstimatorAggregate& e = st.estimators[k];
    ++e.outcome.failed_runs;
    if (e.first_failure.ok()) {
      e.first_failure = FailedPrecondition("run " + std::to_string(r) + ": not applicable");
    }
  }
  ++st.runs;
}

StatusOr<Comparison> RunAggregator::Finish() {
  State& st = *state_;
  if (st.runs == 0) return InvalidArgument("Monte Carlo: no runs to aggregate");
  WG_RETURN_IF_ERROR(st.rows->status());
  Comparison out = std::move(st.out);
  out.runs = st.runs;
  out.errors_csv_rows = st.rows;
  for (EstimatorAggregate& e : st.estimators) {
    EstimatorOutcome agg = std::move(e.outcome);
    if (e.successes == 0) {
      // Every run failed or diverged: a divergence says more than a failure.
      if (e.first_divergence) {
        agg.divergence = e.first_divergence;
      } else {
        agg.status = e.first_failure;
      }
      out.outcomes.push_back(std::move(agg));
      continue;
    }
    // Flagged runs that count in the figures (keep_in_figures): the outcome says so.
    if (agg.divergence_kept_in_figures) agg.divergence = e.first_divergence;
    ErrorStats stds;
    for (size_t j = 0; j < std::size(kMeanFields); ++j) {
      agg.stats.*kMeanFields[j] = e.means[j].Mean();
      stds.*kMeanFields[j] = e.means[j].Std();
    }
    for (size_t j = 0; j < std::size(kPooledFields); ++j) {
      stds.*kPooledFields[j] = e.per_run_percentiles[j].Std();
      agg.stats.*kPooledFields[j] = e.pooled.Percentile(kPooledQ[j]);
    }
    agg.runtime_s = e.runtime.Mean();
    agg.runtime_std_s = e.runtime.Std();
    agg.stats.n_points = static_cast<int>(std::min<long long>(e.pooled.count(), INT32_MAX));
    agg.stats_std = stds;
    agg.pooled_errors = std::move(e.pooled);
    out.outcomes.push_back(std::move(agg));
  }
  return out;
}

StatusOr<Comparison> AggregateRuns(const std::vector<Comparison>& runs) {
  RunAggregator agg;
  for (const Comparison& c : runs) agg.Add(c);
  return agg.Finish();
}

namespace {

// The walk of run `run` (whose seed is `seed`).
using RunGenerator = std::function<StatusOr<Walk>(int run, uint64_t seed)>;
// Receives finished runs in run order (calls are serialized).
using RunSink = std::function<Status(int run, Comparison comparison)>;

// How many of `runs` runs fall to `share` (runs r with r % count == index).
int ShareRuns(int runs, const MonteCarloShare& share) {
  return share.index < runs ? (runs - 1 - share.index) / share.count + 1 : 0;
}

Status ValidateShare(const MonteCarloShare& share) {
  if (share.count < 1 || share.index < 0 || share.index >= share.count) {
    return InvalidArgument("Monte Carlo share " + std::to_string(share.index) + "/" +
                           std::to_string(share.count) + ": need 0 <= i < n");
  }
  return Status::Ok();
}

// The runs of `share`, compared on a pool of threads and handed to `sink` in run order.
Status RunShare(const RunGenerator& generate, const CompareOptions& options,
                const MonteCarloOptions& mc, const MonteCarloShare& share,
                const EstimatorRegistry& registry, const RunSink& sink) {
  const int count = ShareRuns(mc.runs, share);
  if (count == 0) return Status::Ok();
  WG_ASSIGN_OR_RETURN(const int threads, ResolveThreads(mc.threads, count));
  // Finished runs wait in `pending` until every earlier run of the share is handed on. A run
  // starts only within `window` runs of the next one to hand on, so at most that many wait (the
  // run being waited for never waits itself: it has already started).
  const int window = 2 * threads + 2;
  CompareOptions run_options = options;
  run_options.compact = false;     // the aggregator keeps one run's outcomes and drops the rest
  run_options.progress = nullptr;  // runs are counted by mc.progress
  std::mutex mutex;
  std::condition_variable drained;
  std::map<int, Comparison> pending;  // by position in the share
  int next_to_add = 0, done = 0;
  auto run_one = [&](int k) -> Status {
    {
      std::unique_lock<std::mutex> lock(mutex);
      drained.wait(lock, [&] { return k - next_to_add < window; });
    }
    const int i = share.index + k * share.count;
    const uint64_t seed = MonteCarloSeed(mc.seed, i);
    auto located = [&](const Status& s) {
      return Status(s.code(), "run " + std::to_string(i) + " (seed " + std::to_string(seed) +
                                  "): " + s.message());
    };
    StatusOr<Walk> walk = generate(i, seed);
    if (!walk.ok()) return located(walk.status());
    StatusOr<Comparison> c = CompareOnWalk(*walk, run_options, registry);
    if (!c.ok()) return located(c.status());
    if (i != 0) c->truth.clear();  // only the first run's truth is drawn
    std::lock_guard<std::mutex> lock(mutex);
    pending.emplace(k, std::move(c).value());
    for (auto it = pending.find(next_to_add); it != pending.end(); it = pending.find(next_to_add)) {
      Comparison ready = std::move(it->second);
      pending.erase(it);
      WG_RETURN_IF_ERROR(sink(share.index + next_to_add * share.count, std::move(ready)));
      ++next_to_add;
    }
    drained.notify_all();
    if (mc.progress) mc.progress(++done, count);
    return Status::Ok();
  };
  return internal::ParallelFor(0, count, threads, [&](int k) {
    Status r = run_one(k);
    if (!r.ok()) {
      // Let the runs waiting for this one go on (they stop at the failure).
      std::lock_guard<std::mutex> lock(mutex);
      next_to_add = count;
      drained.notify_all();
    }
    return r;
  });
}

StatusOr<Comparison> RunMonteCarlo(const RunGenerator& generate, const CompareOptions& options,
                                   const MonteCarloOptions& mc, const EstimatorRegistry& registry) {
  WG_RETURN_IF_ERROR(CheckRuns(mc.runs));
  RunAggregator aggregator;
  WG_RETURN_IF_ERROR(
      RunShare(generate, options, mc, MonteCarloShare(), registry, [&](int, Comparison c) {
        aggregator.Add(std::move(c));
        return Status::Ok();
      }));
  WG_ASSIGN_OR_RETURN(Comparison out, aggregator.Finish());
  out.seed = mc.seed;
  return out;
}

}  // namespace

StatusOr<Comparison> CompareMonteCarlo(const WalkGenerator& generate, const CompareOptions& options,
                                       const MonteCarloOptions& mc,
                                       const EstimatorRegistry& registry) {
  if (!generate) return InvalidArgument("Monte Carlo: no walk generator");
  return RunMonteCarlo([&](int, uint64_t seed) { return generate(seed); }, options, mc, registry);
}

namespace internal {

namespace {

Status CheckScenarioName(const std::string& scenario) {
  bool known = false;
  for (const ScenarioInfo& s : Scenarios()) known |= s.name == scenario;
  if (known) return Status::Ok();
  std::string names;
  for (const ScenarioInfo& s : Scenarios()) names += (names.empty() ? "" : ", ") + s.name;
  return NotFound("unknown scenario " + internal::Quoted(scenario) + "; known: " + names);
}

// The PCRB information of a share's runs, computed as each is simulated (from any thread) and
// held until the run is handed on. After a failure no more is computed.
class SharePcrbs {
 public:
  SharePcrbs(bool on, const PcrbOptions& options) : on_(on), options_(options) {}
  void Compute(int run, const Simulation& s) {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      if (!on_) return;
    }
    StatusOr<PcrbInformation> info = PcrbInformationFromSimulation(s, options_);
    std::lock_guard<std::mutex> lock(mutex_);
    if (info.ok()) {
      of_[run].information = std::move(info).value();
    } else {
      of_[run].status = info.status();
      on_ = false;
    }
  }
  RunPcrb Take(int run) {
    std::lock_guard<std::mutex> lock(mutex_);
    RunPcrb pcrb;
    auto it = of_.find(run);
    if (it != of_.end()) {
      pcrb = std::move(it->second);
      of_.erase(it);
    }
    return pcrb;
  }

 private:
  std::mutex mutex_;
  bool on_;
  const PcrbOptions& options_;
  std::map<int, RunPcrb> of_;  // by run
};

}  // namespace

Status RunScenarioShare(const std::string& scenario, const ScenarioCompareOptions& sc,
                        const CompareOptions& options, const MonteCarloOptions& mc,
                        const MonteCarloShare& share, const EstimatorRegistry& registry,
                        const ScenarioRunSink& sink) {
  WG_RETURN_IF_ERROR(CheckScenarioName(scenario));
  WG_RETURN_IF_ERROR(CheckRuns(mc.runs));
  WG_RETURN_IF_ERROR(ValidateShare(share));
  if (ShareRuns(mc.runs, share) == 0) return Status::Ok();
  const std::string prefix = sc.overrides_origin.empty() ? "" : sc.overrides_origin + ": ";
  auto located = [&prefix](const Status& s) { return Status(s.code(), prefix + s.message()); };
  // The share's first run is simulated first, alone, on the caller's node: override errors keep
  // their YAML line numbers (and, when the runs are shared, name the run). Later runs simulate
  // on private copies (a yaml-cpp lookup may modify the node, so threads must not share one).
  const int first_run = share.index;
  const uint64_t first_seed = MonteCarloSeed(mc.seed, first_run);
  StatusOr<Simulation> first = SimulateScenarioDetailed(scenario, first_seed, sc.overrides);
  if (!first.ok() && share.count == 1) return located(first.status());
  if (!first.ok()) {
    return Status(first.status().code(), "run " + std::to_string(first_run) + " (seed " +
                                             std::to_string(first_seed) +
                                             "): " + located(first.status()).message());
  }
  SharePcrbs pcrbs(sc.pcrb, sc.pcrb_options);
  pcrbs.Compute(first_run, *first);
  std::mutex mutex;  // guards first_walk and the cloning of the overrides
  std::optional<Walk> first_walk = std::move(first->walk);
  const YAML::Node overrides = sc.overrides.node();
  const RunGenerator generate = [&](int run, uint64_t seed) -> StatusOr<Walk> {
    YAML::Node node;
    {
      std::lock_guard<std::mutex> lock(mutex);
      if (run == first_run && first_walk) {
        Walk w = std::move(*first_walk);
        first_walk.reset();
        return w;
      }
      if (overrides.IsDefined() && !overrides.IsNull()) node = YAML::Clone(overrides);
    }
    StatusOr<Simulation> s = SimulateScenarioDetailed(scenario, seed, node);
    if (!s.ok()) return located(s.status());
    pcrbs.Compute(run, *s);
    return std::move(s->walk);
  };
  return RunShare(generate, options, mc, share, registry,
                  [&](int run, Comparison c) { return sink(run, std::move(c), pcrbs.Take(run)); });
}

ScenarioPcrbSum::ScenarioPcrbSum(const ScenarioCompareOptions& sc, int runs)
    : on_(sc.pcrb),
      prefix_(sc.overrides_origin.empty() ? "" : sc.overrides_origin + ": "),
      sum_(runs) {}

void ScenarioPcrbSum::Add(int run, RunPcrb pcrb) {
  if (!on_ || !status_.ok()) return;
  if (!pcrb.status.ok()) {
    status_ = pcrb.status;
    return;
  }
  // A run without information follows a failure that comes later in run order (its share
  // stopped computing the bound when a run that finished before it failed).
  if (!pcrb.information) skipped_ = true;
  if (skipped_) return;
  status_ = sum_.Add(run, std::move(*pcrb.information));
}

Status ScenarioPcrbSum::AttachTo(Comparison* c) const {
  if (!on_) return Status::Ok();
  if (!status_.ok()) {
    if (status_.code() != StatusCode::kFailedPrecondition) {
      return Status(status_.code(), prefix_ + status_.message());
    }
    c->pcrb_note = status_.message();
    return Status::Ok();
  }
  WG_ASSIGN_OR_RETURN(const PcrbInformation mean, sum_.Mean());
  WG_ASSIGN_OR_RETURN(const PcrbBound bound, ComputePcrb(mean));
  AttachPcrb(bound, c);
  return Status::Ok();
}

}  // namespace internal

StatusOr<Comparison> CompareScenario(const std::string& scenario, const ScenarioCompareOptions& sc,
                                     const CompareOptions& options, const MonteCarloOptions& mc,
                                     const EstimatorRegistry& registry) {
  RunAggregator aggregator;
  internal::ScenarioPcrbSum pcrb(sc, mc.runs);
  WG_RETURN_IF_ERROR(internal::RunScenarioShare(scenario, sc, options, mc, MonteCarloShare(),
                                                registry,
                                                [&](int run, Comparison c, internal::RunPcrb p) {
                                                  aggregator.Add(std::move(c));
                                                  pcrb.Add(run, std::move(p));
                                                  return Status::Ok();
                                                }));
  WG_ASSIGN_OR_RETURN(Comparison c, aggregator.Finish());
  c.seed = mc.seed;
  WG_RETURN_IF_ERROR(pcrb.AttachTo(&c));
  return c;
}

}  // namespace walkgraph
