// Parameter studies: walks or simulated scenarios × estimators × parameter sweeps, from one
// manifest, to one CSV and one HTML page with a plot per sweep.
//
//   walkgraph study MANIFEST.yaml --out DIR     → DIR/study.csv, DIR/study.html, DIR/timing.csv
//
// Manifest (YAML; every key is checked, errors are "MANIFEST:LINE: what was expected"):
//   name: jimenez-tables            # required
//   description: "..."              # optional, shown on the page
//   estimators: [id, ...]           # required: registered estimator ids
//   configs: {id: {option: value}}  # optional base options per estimator
//   metric: rmse_m                  # plotted metric (default rmse_m): rmse_m mean_m median_m
//                                   #   p75_m p90_m max_m final_m pct_distance anees
//                                   #   mean_pct_distance
//                                   #   rmse_over_pcrb
//   score_from_s: 0                 # score truth from this many s on (compare --score-from)
//   runs: 10                        # Monte Carlo runs per cell (default 1; scenarios only)
//   seed: 1                         # base seed S (default 1)
//   pcrb: true                      # compute the PCRB per scenario cell (default true)
//   pcrb_options: {...}             # PcrbOptions (pcrb.h)
//   sweeps:                         # required, one plot each
//     - name: table3                # required, unique, letters digits . _ -
//       title: "..."                # optional plot title
//       label: "number of tags"     # optional x-axis label (default: the swept key)
//       scenario: jimenez-building  # exactly one of scenario / walk (path relative to the
//       walk: ../plaza1             #   manifest's folder; a walk cell is one run)
//       overrides: {laps: 2}        # base simulator overrides (scenario only)
//       scenario_override: num_anchors        # exactly one of: a simulator override key, or
//       estimator_option: path_loss_exponent  #   an estimator option key (every estimator of
//                                             #   the sweep) or {id: key, ...} (those only)
//       values: [5, 8, 16, 32, 71]  # required numbers, as the swept value
//       estimators: [id]            # optional: replaces the top-level list for this sweep
//       runs: 5 / seed: 2 / metric: final_m / score_from_s: 40   # optional per-sweep settings
//
// Each (sweep, value) is a cell: a comparison (CompareScenario / CompareOnWalk) of the sweep's
// estimators, with run i of every cell of a sweep using seed MonteCarloSeed(S, i) — common
// random numbers, so the curves differ only by the swept value. Cells run one after another;
// each cell's Monte Carlo runs on `threads` threads, and the results do not depend on them.
// Before anything runs, every cell's estimator configurations are created and every cell's
// scenario is simulated once (run 0), so a bad value fails at once with its manifest line.
//
// study.csv: one row per cell × estimator:
//   sweep,parameter,value,estimator,runs,seed,failed_runs,diverged_runs, then for each metric m of
//   rmse_m mean_m median_m p75_m p90_m max_m final_m pct_distance anees mean_pct_distance:
//   m,m_std (std empty for a single run; anees empty without covariances), then
//   n_points,pcrb_rmse_m,pcrb_filter_rmse_m,rmse_over_pcrb,error
//   (empty cells where a figure does not exist; error = why the estimator failed on every run).
//   Run times, which differ between machines, are in timing.csv instead.
// study.html: self-contained (inline SVG, no scripts): per sweep, the metric against the swept
// value, one line per estimator (± std bars for Monte Carlo cells), the PCRB (smoother) as a
// dashed line when the metric is rmse_m, and the numbers in a table.
#ifndef WALKGRAPH_STUDY_H_
#define WALKGRAPH_STUDY_H_

#include <cstdint>
#include <functional>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "walkgraph/compare.h"
#include "walkgraph/config.h"
#include "walkgraph/estimator.h"
#include "walkgraph/output.h"
#include "walkgraph/pcrb.h"
#include "walkgraph/status.h"

namespace walkgraph {

// The most values one sweep takes (a manifest with more is refused).
inline constexpr size_t kMaxSweepValues = 10000;

struct StudySweep {
  std::string name, title, label;
  int line = 0;  // 1-based manifest line of the sweep
  // The data: a scenario (with base overrides) or a walk directory.
  std::string scenario;
  Config overrides;
  std::string walk_dir;
  // What varies: a simulator override key, or per estimator an option key.
  std::string scenario_override;
  std::map<std::string, std::string> option_keys;  // estimator id → option key
  std::vector<std::string> values;                 // as written in the manifest
  std::vector<double> x;                           // the same, as numbers
  std::vector<int> value_lines;
  std::vector<std::string> estimators;
  std::string metric = "rmse_m";
  int runs = 1;
  uint64_t seed = 1;
  double score_from_s = 0.0;  // CompareOptions::score_from_s of the sweep's cells
};

struct StudyManifest {
  std::string path;  // as given (messages name it)
  std::string text;  // the manifest's text (carried by study parts, see below)
  std::string name, description;
  std::map<std::string, Config> configs;  // base options per estimator id
  bool pcrb = true;
  PcrbOptions pcrb_options;
  std::vector<StudySweep> sweeps;
};

// Reads and validates a manifest: structure, keys, types, estimator ids (against `registry`),
// scenario names, walk folders, and every cell's estimator configuration.
StatusOr<StudyManifest> ReadStudyManifest(
    const std::string& path, const EstimatorRegistry& registry = EstimatorRegistry::Builtin());
// The same on manifest text; `path` names it in messages and anchors relative walk paths.
StatusOr<StudyManifest> ParseStudyManifest(
    const std::string& text, const std::string& path,
    const EstimatorRegistry& registry = EstimatorRegistry::Builtin());

// One estimator's figures in one cell.
struct StudyRow {
  std::string estimator;
  Status status;
  ErrorStats stats;
  std::optional<ErrorStats> stats_std;
  int failed_runs = 0;
  int diverged_runs = 0;  // left out of the figures (DivergenceOptions::keep_in_figures)
  double runtime_s = 0.0, runtime_std_s = 0.0;
};

struct StudyCell {
  int sweep = 0;  // index into manifest.sweeps
  int value = 0;  // index into that sweep's values
  int runs = 1;
  uint64_t seed = 1;
  std::vector<StudyRow> rows;
  std::optional<double> pcrb_rmse_m, pcrb_filter_rmse_m;
  std::string pcrb_note;
};

struct StudyResult {
  StudyManifest manifest;
  std::vector<StudyCell> cells;  // sweep by sweep, value by value
};

struct StudyOptions {
  int threads = 1;  // per cell's Monte Carlo; <= 0: all cores
  // Called after each finished cell with (cells done, cells); calls are serialized.
  std::function<void(int done, int total)> progress;
  // Called once, after the validation pass over the part's cells and before any cell runs, with
  // that pass's result; a failure it returns stops the part (e.g. when another process of the
  // same study failed: the MPI glue agrees on it here so that every rank stops at once).
  std::function<Status(const Status& validation)> validated;
  // Cells shared out as they are asked for (the MPI glue's counter, shared by the ranks): when
  // set, the part validates its fixed cells (StudyShardCells) but then runs the cells it claims
  // — each call returns the next unclaimed position in StudyCellOrder, counted over every
  // process of the study; a position past the last cell means none is left. Each cell is still
  // computed whole by one process, so the merged outputs are those of a one-process run.
  std::function<int()> claim_cell;
};

StatusOr<StudyResult> RunStudy(const StudyManifest& manifest, const StudyOptions& options = {},
                               const EstimatorRegistry& registry = EstimatorRegistry::Builtin());

std::string StudyCsv(const StudyResult& result);
std::string StudyTimingCsv(const StudyResult& result);
std::string RenderStudyHtml(const StudyResult& result);
// A short aligned text summary (the plotted metric per sweep × value × estimator).
std::string FormatStudyTable(const StudyResult& result);

// ------------------------------------------------------------------ studies in parts
// A study runs whole (RunStudy) or in parts, one per process of a cluster job: part i of n
// (StudyShard) runs only the cells assigned to it, and MergeStudyParts puts the parts' cells
// together into the StudyResult the whole run gives — the same bytes of study.csv, since every
// cell is computed by exactly one part with the same code (RunStudy is part 0 of 1, merged).
// Cells are assigned by their cost (runs × estimators): largest first, each to the part with the
// least cost so far (ties: the earlier cell, the lower part), a deterministic function of the
// manifest and n. `walkgraph study --shard i/n` writes such a part to a folder and `walkgraph
// study merge` combines them. The MPI build of the CLI instead lets its ranks claim cells from a
// shared counter as they finish (StudyOptions::claim_cell: the cost model cannot know which cells
// are slow) and gathers the parts' bytes (SerializeStudyPart) on rank 0
// (docs/studies-on-clusters.md).
struct StudyShard {
  int index = 0;  // i: 0 <= i < count
  int count = 1;  // n
  Status Validate() const;
};
// "i/n", e.g. "3/16".
StatusOr<StudyShard> ParseStudyShard(const std::string& text);

// The cells of part `shard`, as indices into the study's cells (sweep by sweep, value by value).
std::vector<int> StudyShardCells(const StudyManifest& manifest, const StudyShard& shard);
// Every cell, largest cost first (ties: manifest order): the order in which the fixed split
// deals them out and in which claimed cells (StudyOptions::claim_cell) are handed out.
std::vector<int> StudyCellOrder(const StudyManifest& manifest);

struct StudyPart {
  StudyShard shard;
  std::string manifest_path, manifest_text;  // the manifest the part ran (StudyManifest path/text)
  std::vector<StudyCell> cells;              // the part's cells, in the study's order
  // The cells were claimed from a pool shared by the processes (StudyOptions::claim_cell), not
  // dealt by the fixed split: merged, every cell must come from exactly one part.
  bool claimed = false;
};

// Validates and runs the cells of part `shard` (as RunStudy does for all of them).
StatusOr<StudyPart> RunStudyPart(const StudyManifest& manifest, const StudyShard& shard,
                                 const StudyOptions& options = {},
                                 const EstimatorRegistry& registry = EstimatorRegistry::Builtin());

// A part as bytes (exact: doubles by their bits) and back; `origin` names the bytes in errors.
std::string SerializeStudyPart(const StudyPart& part);
StatusOr<StudyPart> ParseStudyPart(const std::string& bytes, const std::string& origin);

// The whole study from parts 0..n-1 of one manifest (each exactly once, in any order; all of
// the fixed split, or all claimed).
StatusOr<StudyResult> MergeStudyParts(const StudyManifest& manifest,
                                      const std::vector<StudyPart>& parts);

// The part file inside a part folder.
inline constexpr const char kStudyPartFile[] = "study.part";
// Writes `part` as out_dir/study.part through the output writer.
Status WriteStudyPart(const StudyPart& part, const std::string& out_dir,
                      const OutputOptions& options = {});
// Reads part folders (or study.part files), parses the manifest they carry (its walks must be
// where they were) and merges them.
StatusOr<StudyResult> MergeStudyPartFiles(
    const std::vector<std::string>& paths,
    const EstimatorRegistry& registry = EstimatorRegistry::Builtin());

// Writes study.csv, study.html and timing.csv into `out_dir` through the output writer
// (output.h: marker, whole or not at all, never over a folder walkgraph did not write).
Status WriteStudy(const StudyResult& result, const std::string& out_dir,
                  const OutputOptions& options = {});

}  // namespace walkgraph

#endif  // WALKGRAPH_STUDY_H_
