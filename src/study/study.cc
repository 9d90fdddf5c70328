// Parameter studies: running the cells, whole or in parts (study.h).
#include "walkgraph/study.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "eval/pcrb_yaml.h"
#include "study/study_internal.h"
#include "walkgraph/config.h"
#include "walkgraph/io.h"
#include "walkgraph/simulate.h"

namespace walkgraph {

namespace fs = std::filesystem;
using internal::CellAt;
using internal::CellConfig;
using internal::CellOverrides;
using internal::FieldOf;

// ------------------------------------------------------------------ running

namespace {

// (sweep, value) of every cell, in the study's order.
std::vector<std::pair<int, int>> CellIndex(const StudyManifest& m) {
  std::vector<std::pair<int, int>> cells;
  for (size_t k = 0; k < m.sweeps.size(); ++k) {
    for (size_t i = 0; i < m.sweeps[k].values.size(); ++i) {
      cells.emplace_back(static_cast<int>(k), static_cast<int>(i));
    }
  }
  return cells;
}

// Reads sweep k's walk into (*walks)[k] unless it is there already.
Status LoadSweepWalk(const StudyManifest& m, int k, std::vector<std::optional<Walk>>* walks) {
  const StudySweep& s = m.sweeps[k];
  if ((*walks)[k]) return Status::Ok();
  StatusOr<Walk> w = ReadWalk(s.walk_dir);
  if (!w.ok()) {
    return InvalidArgument(m.path + ":" + std::to_string(s.line) + ": sweep '" + s.name +
                           "': " + w.status().message());
  }
  (*walks)[k] = std::move(w).value();
  return Status::Ok();
}

// The validation pass over `cells`: every scenario cell simulates (run 0), every walk reads.
Status ValidateCells(const StudyManifest& m, const std::vector<std::pair<int, int>>& cells,
                     std::vector<std::optional<Walk>>* walks) {
  walks->assign(m.sweeps.size(), std::nullopt);
  for (const auto& [k, i] : cells) {
    const StudySweep& s = m.sweeps[k];
    if (!s.walk_dir.empty()) {
      WG_RETURN_IF_ERROR(LoadSweepWalk(m, k, walks));
      continue;
    }
    StatusOr<Walk> w = SimulateScenario(s.scenario, MonteCarloSeed(s.seed, 0), CellOverrides(s, i));
    if (!w.ok()) return InvalidArgument(CellAt(m, s, i) + ": " + w.status().message());
  }
  return Status::Ok();
}

StudyRow RowOf(EstimatorOutcome& o) {
  StudyRow r;
  r.estimator = o.id;
  // A diverged estimate is left out of the study's figures like a failed one, saying so.
  r.status = o.status.ok() && !o.Ranked() ? Status(StatusCode::kNumerical, ToString(*o.divergence))
                                          : o.status;
  r.stats = o.stats;
  r.stats_std = o.stats_std;
  r.failed_runs = o.failed_runs;
  r.diverged_runs = o.diverged_runs;
  r.runtime_s = o.runtime_s;
  r.runtime_std_s = o.runtime_std_s;
  return r;
}

// Runs cell (k, i); `walk` is the sweep's recorded walk (nullptr for a scenario).
StatusOr<StudyCell> RunCell(const StudyManifest& m, int k, int i, const Walk* walk,
                            const StudyOptions& options, const EstimatorRegistry& registry) {
  const StudySweep& s = m.sweeps[k];
  CompareOptions co;
  co.estimator_ids = s.estimators;
  co.score_from_s = s.score_from_s;
  for (const std::string& id : s.estimators) co.configs[id] = CellConfig(m, s, i, id);
  StatusOr<Comparison> c = FailedPrecondition("no comparison");
  if (walk != nullptr) {
    c = CompareOnWalk(*walk, co, registry);
  } else {
    ScenarioCompareOptions sc;
    sc.overrides = CellOverrides(s, i);
    sc.pcrb = m.pcrb;
    sc.pcrb_options = m.pcrb_options;
    MonteCarloOptions mc;
    mc.runs = s.runs;
    mc.seed = s.seed;
    mc.threads = options.threads;
    c = CompareScenario(s.scenario, sc, co, mc, registry);
  }
  if (!c.ok()) return Status(c.status().code(), CellAt(m, s, i) + ": " + c.status().message());
  StudyCell cell;
  cell.sweep = k;
  cell.value = i;
  cell.runs = c->runs;
  cell.seed = s.seed;
  cell.pcrb_rmse_m = c->pcrb_rmse_m;
  cell.pcrb_filter_rmse_m = c->pcrb_filter_rmse_m;
  cell.pcrb_note = c->pcrb_note;
  for (EstimatorOutcome& o : c->outcomes) cell.rows.push_back(RowOf(o));
  return cell;
}

// The cells a part runs: its fixed ones, or (claim_cell) the ones it claims as it goes.
class CellSource {
 public:
  CellSource(const StudyManifest& m, std::vector<int> fixed, const std::function<int()>& claim)
      : fixed_(std::move(fixed)), claim_(claim) {
    if (claim_) order_ = StudyCellOrder(m);
  }
  // The next cell (an index into the study's cells), or -1.
  int Next() {
    if (!claim_) return next_ < fixed_.size() ? fixed_[next_++] : -1;
    const int at = claim_();
    return at >= 0 && at < static_cast<int>(order_.size()) ? order_[at] : -1;
  }
  // For progress: the part's cells, or (claiming) every cell of the study.
  int total(int study_cells) const {
    return claim_ ? study_cells : static_cast<int>(fixed_.size());
  }

 private:
  std::vector<int> fixed_, order_;
  size_t next_ = 0;
  const std::function<int()>& claim_;
};

}  // namespace

StatusOr<StudyPart> RunStudyPart(const StudyManifest& m, const StudyShard& shard,
                                 const StudyOptions& options, const EstimatorRegistry& registry) {
  WG_RETURN_IF_ERROR(shard.Validate());
  const std::vector<std::pair<int, int>> all = CellIndex(m);
  std::vector<std::pair<int, int>> mine;
  const std::vector<int> fixed = StudyShardCells(m, shard);
  for (int c : fixed) mine.push_back(all[c]);
  std::vector<std::optional<Walk>> walks;
  Status valid = ValidateCells(m, mine, &walks);
  if (options.validated) {
    const Status agreed = options.validated(valid);
    if (valid.ok()) valid = agreed;
  }
  WG_RETURN_IF_ERROR(valid);
  StudyPart part;
  part.shard = shard;
  part.claimed = static_cast<bool>(options.claim_cell);
  part.manifest_path = m.path;
  part.manifest_text = m.text;
  CellSource source(m, fixed, options.claim_cell);
  int done = 0;
  for (int c = source.Next(); c >= 0; c = source.Next()) {
    const auto [k, i] = all[c];
    // A claimed cell may belong to a sweep whose walk another process validated.
    if (!m.sweeps[k].walk_dir.empty()) WG_RETURN_IF_ERROR(LoadSweepWalk(m, k, &walks));
    const Walk* walk = walks[k] ? &*walks[k] : nullptr;
    WG_ASSIGN_OR_RETURN(StudyCell cell, RunCell(m, k, i, walk, options, registry));
    part.cells.push_back(std::move(cell));
    if (options.progress) options.progress(++done, source.total(static_cast<int>(all.size())));
  }
  // In the study's order (claimed cells come in claim order).
  std::sort(part.cells.begin(), part.cells.end(), [](const StudyCell& a, const StudyCell& b) {
    return std::make_pair(a.sweep, a.value) < std::make_pair(b.sweep, b.value);
  });
  return part;
}

StatusOr<StudyResult> RunStudy(const StudyManifest& m, const StudyOptions& options,
                               const EstimatorRegistry& registry) {
  WG_ASSIGN_OR_RETURN(StudyPart part, RunStudyPart(m, StudyShard{}, options, registry));
  return MergeStudyParts(m, {std::move(part)});
}

}  // namespace walkgraph
