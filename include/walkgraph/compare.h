// Running several estimators on the same walk and scoring them against its truth.
//
// The comparison differs only in the estimator: every estimator sees the same Walk. Results
// are written as results.json, errors.csv, trajectories/<id>.tum and <id>.csv (with the
// covariances), truth.tum (and checkpoints.csv) and a self-contained report.html (see
// WriteComparison; reading them with evo: docs/outputs.md).
//
// Monte Carlo (CompareMonteCarlo): N walks drawn from a seeded generator, run i with
// seed_i = MonteCarloSeed(S, i), compared on a pool of threads. Per estimator the figures of
// the N runs are aggregated as runs finish, in run order (so the result does not depend on the
// thread count), in memory that does not grow with N:
//   rmse, mean, max, final, pct_distance, mean_pct_distance, anees, runtime: mean over the
//     runs, *_std = sample std (Welford's running update);
//   median, p75, p90: percentiles of the pooled errors of all runs, from a QuantileSketch
//     (metrics.h: within 0.01 % of the exact pooled percentile), *_std = sample std of the
//     per-run (exact) percentiles.
// Only the first successful run's trajectory and error series are kept; every run's errors go
// to errors.csv through a temporary file on disk.
//
// Simulated scenarios (CompareScenario) also get the posterior Cramér–Rao bound of the same
// runs (pcrb.h): pcrb_rmse_m (smoothing bound), pcrb_filter_rmse_m (filtering bound), and each
// estimator's rmse_over_pcrb = rmse_m / pcrb_rmse_m in results.json, the table and the report.
#ifndef WALKGRAPH_COMPARE_H_
#define WALKGRAPH_COMPARE_H_

#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "walkgraph/config.h"
#include "walkgraph/divergence.h"
#include "walkgraph/estimator.h"
#include "walkgraph/metrics.h"
#include "walkgraph/output.h"
#include "walkgraph/pcrb.h"
#include "walkgraph/status.h"
#include "walkgraph/walk.h"

namespace walkgraph {

struct CompareOptions {
  // Estimators to run, in order; empty = every registered estimator applicable to the walk.
  std::vector<std::string> estimator_ids;
  // Per-estimator configuration (YAML map of options), by id.
  std::map<std::string, Config> configs;
  Alignment alignment = Alignment::kNone;
  // Score only truth at t >= t_first_truth + score_from_s (0 = the whole walk): a filter's
  // start-up transient left out, as papers that report "the stationary state of the filter"
  // (000 Sec. IV) do. The dropped points are counted in ErrorSeries::n_skipped; final_m and
  // pct_distance are unchanged, mean_pct_distance still divides by the distance from the start.
  // Must be finite, >= 0 and leave at least one truth point.
  double score_from_s = 0.0;
  // Which estimates are reported as diverged (divergence.h).
  DivergenceOptions divergence;
  // Memory of a single-walk comparison (Monte Carlo runs always keep what they need, see the
  // top of this file). false: every outcome keeps its full trajectory and error series.
  // true (what the CLI uses): as each estimator finishes, its trajectory (TUM text) and error
  // rows go to anonymous temporary files that WriteComparison copies into the report folder, and
  // the outcome keeps copies thinned to at most kCompactPoints points for the report (the
  // figures are computed before, from every point), plus a QuantileSketch of all its errors;
  // the comparison's truth is thinned the same way. A 10-h walk then needs the walk and one
  // estimator's run in memory, not every estimator's output.
  bool compact = false;
  // A single walk's progress (CompareOnWalk; Monte Carlo reports runs through
  // MonteCarloOptions::progress and ignores it): called with (estimators done, estimators to
  // run) before the first and after each estimator, and, while one runs, with its fraction added
  // (e.g. 2.25: two done, a quarter of the third) as its driver loop reports it
  // (progress.h ReportEstimatorProgress). Calls come from the calling thread.
  std::function<void(double done, int total)> progress;
};

// Points kept per curve by CompareOptions::compact.
inline constexpr size_t kCompactPoints = 5000;

namespace internal {
class TextSpill;
}  // namespace internal

struct EstimatorOutcome {
  std::string id;
  Status status;  // not OK: the estimator failed; stats are empty
  ErrorStats stats;
  double runtime_s = 0.0;
  EstimateResult result;
  ErrorSeries errors;
  // Monte Carlo only (runs > 1): spread of the per-run figures (see the top of this file) and
  // the runs the estimator failed on (excluded from the figures); `result` and `errors` are the
  // first successful run's.
  std::optional<ErrorStats> stats_std;
  double runtime_std_s = 0.0;
  int failed_runs = 0;
  // The RMSE of each run that counts in the figures, in run order (the report's box plot over
  // runs; 8 bytes a run).
  std::vector<double> run_rmse_m;
  // Every error point behind `stats` (Monte Carlo: of every successful run; compact: of the
  // whole walk, while `errors` is thinned); empty otherwise (`errors` holds them all).
  std::optional<QuantileSketch> pooled_errors;
  // CompareOptions::compact: the full trajectory as TUM text and as CSV with its covariances
  // (io.h FormatTrajectoryCsv); `result.trajectory` is thinned.
  std::shared_ptr<internal::TextSpill> trajectory_tum;
  std::shared_ptr<internal::TextSpill> trajectory_csv;
  // Set when the estimate diverged (divergence.h); Monte Carlo: the first diverged run's, when
  // every run that ran diverged. Unless DivergenceOptions::keep_in_figures, the outcome is then
  // shown as diverged instead of its figures (which stay in results.json for the record), and is
  // never marked best.
  std::optional<Divergence> divergence;
  bool divergence_kept_in_figures = false;
  // Monte Carlo: the runs whose estimate diverged (left out of the figures unless kept).
  int diverged_runs = 0;

  // Whether the figures count: it ran, and it did not diverge (or divergence is kept in them).
  bool Ranked() const { return status.ok() && (!divergence || divergence_kept_in_figures); }
};

struct Comparison {
  std::string walk_name;
  int runs = 1;
  std::optional<uint64_t> seed;  // Monte Carlo base seed S
  TruthKind truth_kind = TruthKind::kNone;
  double score_from_s = 0.0;  // CompareOptions::score_from_s the figures were taken with
  std::vector<EstimatorOutcome> outcomes;
  // Posterior Cramér–Rao bound of the position RMSE (simulated scenarios; see pcrb.h):
  // smoothing bound (full-walk information) and filtering bound (Tichavský recursion).
  std::optional<double> pcrb_rmse_m;
  std::optional<double> pcrb_filter_rmse_m;
  std::string pcrb_note;  // why there is no bound, when it was asked for and not computed
  // sqrt(tr B) at the bound's nodes, for the error-vs-time plot.
  std::vector<double> pcrb_t_s, pcrb_filter_m, pcrb_smoother_m;
  // What the report draws under the trajectories. CompareOptions::compact thins a continuous
  // truth (checkpoints are kept) and keeps the whole of it as TUM text in truth_tum.
  std::vector<Anchor> anchors;
  std::vector<TruthSample> truth;
  std::shared_ptr<internal::TextSpill> truth_tum;
  // Monte Carlo, or CompareOptions::compact: errors.csv's rows ("t_s,estimator,error_m[,run]"),
  // kept in an anonymous temporary file (not in memory); WriteComparison copies them.
  std::shared_ptr<internal::TextSpill> errors_csv_rows;
  // What the walk holds that is unusual but accepted (io.h PlausibilityWarnings), in
  // results.json as "warnings": {"count": warning_count, "messages": warnings}. Monte Carlo:
  // each run's, prefixed "run i: ", the first kMaxWarningMessages kept; warning_count counts
  // every one.
  std::vector<std::string> warnings;
  int warning_count = 0;
  // Set (and among warnings) when nothing ties an estimate to the truth's frame: no start, no
  // waypoints, fewer than two heard anchors of known position, scored without --align-se2; the
  // table (FormatComparisonTable) prints it under the rows.
  std::string untied_frame;
};

// The warning messages a Monte Carlo comparison keeps (Comparison::warnings).
inline constexpr int kMaxWarningMessages = 20;

// Runs the estimators on `walk`. Fails only when the request itself is invalid (unknown id, no
// truth); an estimator that fails is kept as an outcome with its Status.
StatusOr<Comparison> CompareOnWalk(
    const Walk& walk, const CompareOptions& options,
    const EstimatorRegistry& registry = EstimatorRegistry::Builtin());

// Makes the walk of one Monte Carlo run from its seed. Called concurrently from several
// threads with different seeds: it must not share mutable state between calls.
using WalkGenerator = std::function<StatusOr<Walk>(uint64_t seed)>;

// The most Monte Carlo runs one comparison takes (runs beyond it are refused): at about a
// second a run, 10^6 runs are 12 days on one core; split a larger study into seeds.
inline constexpr int kMaxMonteCarloRuns = 1000000;

struct MonteCarloOptions {
  int runs = 1;       // in [1, kMaxMonteCarloRuns]
  uint64_t seed = 0;  // S
  int threads = 1;    // <= 0: std::thread::hardware_concurrency(); at most kMaxThreads
  // Called after each finished run with (runs done, runs); calls are serialized.
  std::function<void(int done, int total)> progress;
};

// seed_i: the SplitMix64 output for state S + (i + 1)·0x9E3779B97F4A7C15 (i = 0, 1, ...):
// distinct, well-mixed seeds from consecutive indices, the same on every platform.
uint64_t MonteCarloSeed(uint64_t seed, int run);

// Runs the comparison on options.runs generated walks and aggregates them (see the top of this
// file). Fails if a walk cannot be generated or a run's request is invalid (e.g. no applicable
// estimator); an estimator failing on some runs is counted in failed_runs.
StatusOr<Comparison> CompareMonteCarlo(
    const WalkGenerator& generate, const CompareOptions& options,
    const MonteCarloOptions& monte_carlo,
    const EstimatorRegistry& registry = EstimatorRegistry::Builtin());

// Simulated scenario `scenario` with simulator overrides, N Monte Carlo runs (as
// CompareMonteCarlo with SimulateScenario), plus its PCRB over the same runs when `pcrb` is set.
// A bound that is not defined for the scenario (FailedPrecondition, e.g. foot-IMU presets)
// leaves pcrb_rmse_m empty and says why in pcrb_note; other PCRB failures are errors.
struct ScenarioCompareOptions {
  Config overrides;              // SimulateScenario overrides, e.g. {laps: 2, eta: 3.0}
  std::string overrides_origin;  // prefixed to simulator errors (e.g. the YAML file's path)
  bool pcrb = true;
  PcrbOptions pcrb_options;
};
StatusOr<Comparison> CompareScenario(
    const std::string& scenario, const ScenarioCompareOptions& scenario_options,
    const CompareOptions& options, const MonteCarloOptions& monte_carlo,
    const EstimatorRegistry& registry = EstimatorRegistry::Builtin());

// Copies the bound's figures into `comparison` (pcrb_rmse_m, pcrb_filter_rmse_m, series).
void AttachPcrb(const PcrbBound& bound, Comparison* comparison);

// rmse_m / pcrb_rmse_m of an outcome, when both exist.
std::optional<double> RmseOverPcrb(const Comparison& comparison, const EstimatorOutcome& outcome);

// The aggregation step alone: `runs` are single-walk comparisons in run order.
StatusOr<Comparison> AggregateRuns(const std::vector<Comparison>& runs);

// The same, one run at a time (what CompareMonteCarlo uses): Add() the runs in run order, then
// Finish(). Memory does not grow with the number of runs.
class RunAggregator {
 public:
  RunAggregator();
  ~RunAggregator();
  RunAggregator(RunAggregator&&) noexcept;
  RunAggregator& operator=(RunAggregator&&) noexcept;
  void Add(Comparison run);
  StatusOr<Comparison> Finish();

 private:
  struct State;
  std::unique_ptr<State> state_;
};

// ------------------------------------------------------------------ Monte Carlo in shares
// A scenario's runs shared among processes (the MPI build of the CLI: `mpirun -np N walkgraph
// compare --scenario NAME --runs R`, docs/studies-on-clusters.md). Share i of n runs the runs r
// with r % n == i on its own threads (monte_carlo.threads) and hands each finished run, in run
// order, to a sink as bytes (exact: doubles by their bits; the encoding of the study's parts):
// what the aggregation takes from a run — per estimator its status, figures, runtime,
// divergence and error series (times and errors), with the whole result and error series only
// for the share's first run that counts for the estimator — plus its PCRB information and run
// 0's truth. A ScenarioRunMerger given the bytes of runs 0, 1, ..., runs − 1 in that order
// gives the Comparison CompareScenario gives with the same options, bit for bit (the same
// aggregation, in the same order), whatever n; it holds the aggregate and one run at a time.
struct MonteCarloShare {
  int index = 0;  // i: 0 <= i < n
  int count = 1;  // n
};

// Fails as CompareScenario does, the message naming the run (and on the first failure stops);
// a sink that fails stops the share with its Status.
Status CompareScenarioShare(const std::string& scenario,
                            const ScenarioCompareOptions& scenario_options,
                            const CompareOptions& options, const MonteCarloOptions& monte_carlo,
                            const MonteCarloShare& share,
                            const std::function<Status(int run, std::string bytes)>& sink,
                            const EstimatorRegistry& registry = EstimatorRegistry::Builtin());

class ScenarioRunMerger {
 public:
  // The options every share was given (runs, seed; the PCRB's).
  ScenarioRunMerger(const ScenarioCompareOptions& scenario_options,
                    const MonteCarloOptions& monte_carlo);
  ~ScenarioRunMerger();
  ScenarioRunMerger(const ScenarioRunMerger&) = delete;
  ScenarioRunMerger& operator=(const ScenarioRunMerger&) = delete;
  // The next run's bytes (run 0 first); `origin` names them in errors. After a failure every
  // call returns it.
  Status Add(const std::string& bytes, const std::string& origin);
  // Once every run is in: the comparison (as CompareScenario's, PCRB included).
  StatusOr<Comparison> Finish();

 private:
  struct State;
  std::unique_ptr<State> state_;
};

// Truth points per counted run that `o` was scored on (Monte Carlo: its pooled points over the
// runs in its figures); 0 when it is not ranked.
double ScoredPointsPerRun(const Comparison& comparison, const EstimatorOutcome& o);

// Whether `o` was scored on as many truth points as any ranked estimator of the comparison. An
// estimate is scored on the truth inside its own time span (metrics.h), so one that does not
// span the walk (a filter that starts at its first radio fix: 7 of 13 landmarks on IPIN trial
// 01 without a known start) has figures over less of the walk than the others'. The tables
// show it with its points ("7/13") and never mark it best; results.json says
// "scored_on_every_point". False when `o` is not ranked.
bool ScoredOnEveryPoint(const Comparison& comparison, const EstimatorOutcome& o);

// The points `o` was scored on, as the tables show them: "13", or "7/13" when another ranked
// estimator was scored on more (Monte Carlo: pooled over the runs in its figures).
std::string ScoredPointsLabel(const Comparison& comparison, const EstimatorOutcome& o);

// An aligned text table, one row per estimator; '*' marks the best value of each column among
// the ranked estimators scored on every point (ScoredOnEveryPoint).
std::string FormatComparisonTable(const Comparison& comparison);

// Writes results.json, errors.csv, trajectories/<id>.tum, trajectories/<id>.csv (io.h
// FormatTrajectoryCsv), truth.tum (io.h FormatTruthTum), checkpoints.csv ("t_s,x_m,y_m", when
// the truth is checkpoints) and report.html into `out_dir`.
// With runs > 1, results.json gains "seed", the "*_std" fields and "failed_runs"; its
// "runtime_s" is null (timings differ from run to run and would make results.json depend on
// the machine and the thread count) and the timings go to timing.json instead; errors.csv gains
// a "run" column.
// Written through the output writer (output.h): the folder carries walkgraph's marker, appears
// whole or not at all, and replaces only a folder walkgraph wrote (or any with options.force).
Status WriteComparison(const Comparison& comparison, const std::string& out_dir,
                       const OutputOptions& options = {});

// results.json's text alone (what WriteComparison writes there).
std::string ResultsJsonText(const Comparison& comparison);

// The report page alone (self-contained HTML with inline SVG).
std::string RenderHtmlReport(const Comparison& comparison);

}  // namespace walkgraph

#endif  // WALKGRAPH_COMPARE_H_
