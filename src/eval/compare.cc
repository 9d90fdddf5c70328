#include "walkgraph/compare.h"

#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <iomanip>
#include <limits>
#include <mutex>
#include <sstream>
#include <string>

#include <yaml-cpp/yaml.h>
#include <nlohmann/json.hpp>

#include "util/text.h"
#include "util/text_spill.h"
#include "walkgraph/io.h"

namespace walkgraph {

namespace fs = std::filesystem;

namespace {

// A walk with truth but no start (walk.yaml initial_pose), no waypoints and fewer than two heard
// anchors of known position (surveyed or from a radio map) gives no estimator the truth's
// frame: its errors are scored without alignment all the same, and then hold an arbitrary shift
// (and, without a magnetometer, turn). Empty when something ties the walk to that frame.
std::string UntiedFrameWarning(const Walk& walk) {
  if (walk.truth.empty() || walk.meta.initial_pose || !walk.waypoints.empty()) return "";
  int heard = 0;
  for (const Anchor& a : walk.anchors) heard += a.position_known && walk.AnchorReadings(a.id) > 0;
  if (heard >= 2) return "";
  return "walk.yaml has no initial_pose, the walk no waypoints.csv and it hears " +
         std::to_string(heard) +
         " anchor(s) of known position (2 or more place it): nothing ties an estimate to the "
         "truth's frame, so these errors include an arbitrary offset; --align-se2 scores the "
         "shape";
}

// Removes the errors before t_s (they count as skipped).
void DropBefore(double t_s, ErrorSeries* e) {
  const bool with_nees = !e->nees.empty();
  const bool with_distance = !e->distance_m.empty();
  const bool with_floors = !e->floors_missed.empty();
  size_t kept = 0;
  for (size_t i = 0; i < e->t_s.size(); ++i) {
    if (e->t_s[i] < t_s) continue;
    e->t_s[kept] = e->t_s[i];
    e->error_m[kept] = e->error_m[i];
    if (with_nees) e->nees[kept] = e->nees[i];
    if (with_distance) e->distance_m[kept] = e->distance_m[i];
    if (with_floors) e->floors_missed[kept] = e->floors_missed[i];
    ++kept;
  }
  e->n_skipped += static_cast<int>(e->t_s.size() - kept);
  e->t_s.resize(kept);
  e->error_m.resize(kept);
  if (with_nees) e->nees.resize(kept);
  if (with_distance) e->distance_m.resize(kept);
  if (with_floors) e->floors_missed.resize(kept);
}

// Every k-th element (and the last) of a series of n, k chosen to keep at most `max`.
std::vector<size_t> ThinnedIndices(size_t n, size_t max) {
  std::vector<size_t> out;
  const size_t k = n <= max ? 1 : (n + max - 2) / (max - 1);
  for (size_t i = 0; i < n; i += k) out.push_back(i);
  if (!out.empty() && out.back() != n - 1) out.push_back(n - 1);
  return out;
}

template <typename T>
void Thin(const std::vector<size_t>& keep, std::vector<T>* v) {
  if (v->empty()) return;
  std::vector<T> out;
  out.reserve(keep.size());
  for (size_t i : keep) out.push_back((*v)[i]);
  *v = std::move(out);
}

// CompareOptions::compact: the outcome's full trajectory and error rows go to disk; thinned
// copies and a sketch of its errors stay.
void Compact(EstimatorOutcome* o, internal::TextSpill* rows) {
  rows->Append([&](std::ostream& out) {
    out << std::setprecision(10);
    for (size_t i = 0; i < o->errors.t_s.size(); ++i) {
      out << o->errors.t_s[i] << ',' << o->id << ',' << o->errors.error_m[i] << '\n';
    }
  });
  o->trajectory_tum = std::make_shared<internal::TextSpill>();
  o->trajectory_tum->Append(
      [&](std::ostream& out) { FormatTumTrajectory(o->result.trajectory, out); });
  o->trajectory_csv = std::make_shared<internal::TextSpill>();
  o->trajectory_csv->Append(
      [&](std::ostream& out) { FormatTrajectoryCsv(o->result.trajectory, out); });
  QuantileSketch sketch;
  for (double e : o->errors.error_m) sketch.Add(e);
  o->pooled_errors = std::move(sketch);
  const std::vector<size_t> keep = ThinnedIndices(o->errors.t_s.size(), kCompactPoints);
  Thin(keep, &o->errors.t_s);
  Thin(keep, &o->errors.error_m);
  Thin(keep, &o->errors.nees);
  Thin(keep, &o->errors.distance_m);
  Thin(keep, &o->errors.floors_missed);
  Thin(ThinnedIndices(o->result.trajectory.size(), kCompactPoints), &o->result.trajectory.points);
  o->result.nis.clear();
  o->result.nis.shrink_to_fit();
}

}  // namespace

StatusOr<Comparison> CompareOnWalk(const Walk& walk, const CompareOptions& options,
                                   const EstimatorRegistry& registry) {
  WG_RETURN_IF_ERROR(ValidateWalk(walk));
  if (walk.truth.empty()) {
    return FailedPrecondition("walk '" + walk.meta.name + "' has no truth to compare against");
  }
  WG_RETURN_IF_ERROR(options.divergence.Validate());
  if (!(std::isfinite(options.score_from_s) && options.score_from_s >= 0.0)) {
    return InvalidArgument("compare: score_from_s must be finite and >= 0");
  }
  const double score_from_t = walk.truth.front().t_s + options.score_from_s;
  if (options.score_from_s > 0.0 && !(walk.truth.back().t_s >= score_from_t)) {
    return InvalidArgument("compare: score_from_s " + internal::Num(options.score_from_s) +
                           " s leaves no truth of walk '" + walk.meta.name + "' to score (" +
                           internal::Num(walk.truth.back().t_s - walk.truth.front().t_s) +
                           " s of truth)");
  }
  for (const auto& [id, node] : options.configs) {
    if (registry.Find(id) == nullptr) {
      return InvalidArgument("compare: options for " + internal::Quoted(id) +
                             ", which is not an estimator id (see walkgraph list)");
    }
  }
  std::vector<std::string> ids = options.estimator_ids;
  const bool explicit_list = !ids.empty();
  for (const auto& [id, node] : options.configs) {
    if (explicit_list && std::find(ids.begin(), ids.end(), id) == ids.end()) {
      return InvalidArgument("compare: options for " + internal::Quoted(id) +
                             ", which is not among the estimators run; add it to the estimators "
                             "or drop its options");
    }
  }
  if (!explicit_list) ids = registry.Ids();
  Comparison c;
  c.walk_name = walk.meta.name;
  c.truth_kind = walk.meta.truth_kind;
  c.score_from_s = options.score_from_s;
  for (const Anchor& a : walk.anchors) {  // the ones with a place (the report draws them)
    if (a.position_known) c.anchors.push_back(a);
  }
  c.truth = walk.truth;
  c.warnings = PlausibilityWarnings(walk);
  if (options.alignment == Alignment::kNone) {
    c.untied_frame = UntiedFrameWarning(walk);
    if (!c.untied_frame.empty()) c.warnings.push_back(c.untied_frame);
  }
  c.warning_count = static_cast<int>(c.warnings.size());
  if (options.compact) {
    c.truth_tum = std::make_shared<internal::TextSpill>();
    c.truth_tum->Append([&](std::ostream& out) { FormatTruthTum(walk.truth, out); });
    WG_RETURN_IF_ERROR(c.truth_tum->status());
    if (c.truth_kind != TruthKind::kCheckpoints) {
      Thin(ThinnedIndices(c.truth.size(), kCompactPoints), &c.truth);
    }
    c.errors_csv_rows = std::make_shared<internal::TextSpill>();
  }
  const double distance = walk.TruthDistance();
  const int total = static_cast<int>(ids.size());
  int done = 0;
  if (options.progress) options.progress(0.0, total);
  for (const std::string& id : ids) {
    auto it = options.configs.find(id);
    const YAML::Node config = it != options.configs.end() ? it->second.node() : YAML::Node();
    // Monte Carlo runs share the configuration nodes, and a yaml-cpp lookup by key may modify
    // a node: estimators are created one at a time.
    static std::mutex create_mutex;
    std::unique_lock<std::mutex> lock(create_mutex);
    WG_ASSIGN_OR_RETURN(std::unique_ptr<Estimator> est, registry.Create(id, config));
    lock.unlock();
    const Status applicable = est->CheckApplicable(walk);
    if (!applicable.ok()) {
      if (explicit_list) return FailedPrecondition(id + ": " + applicable.message());
      if (options.progress) options.progress(++done, total);
      continue;
    }
    EstimatorOutcome o;
    o.id = id;
    const auto start = std::chrono::steady_clock::now();
    std::optional<ScopedEstimatorProgress> inside;
    if (options.progress) {
      inside.emplace([&](double fraction) { options.progress(done + fraction, total); });
    }
    StatusOr<EstimateResult> r = est->Run(walk);
    inside.reset();
    o.runtime_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    if (!r.ok()) {
      o.status = r.status();
    } else {
      o.result = std::move(r).value();
      StatusOr<ErrorSeries> e = ComputeErrors(walk, o.result.trajectory, options.alignment);
      if (!e.ok()) {
        o.status = e.status();
      } else {
        o.errors = std::move(e).value();
        if (options.score_from_s > 0.0) DropBefore(score_from_t, &o.errors);
        if (o.errors.error_m.empty()) {
          o.status = FailedPrecondition(id + ": the estimate ends before the scored truth (from " +
                                        internal::Num(score_from_t) + " s)");
        } else {
          o.stats = SummarizeErrors(o.errors, distance);
          o.divergence = CheckDivergence(walk, o.result.trajectory, o.errors, score_from_t,
                                         options.divergence);
          o.divergence_kept_in_figures = options.divergence.keep_in_figures;
          if (options.compact) Compact(&o, c.errors_csv_rows.get());
        }
      }
    }
    c.outcomes.push_back(std::move(o));
    if (options.progress) options.progress(++done, total);
  }
  if (c.outcomes.empty()) {
    return FailedPrecondition("no estimator is applicable to walk '" + walk.meta.name + "'");
  }
  if (c.errors_csv_rows) WG_RETURN_IF_ERROR(c.errors_csv_rows->status());
  return c;
}

void AttachPcrb(const PcrbBound& bound, Comparison* c) {
  c->pcrb_rmse_m = bound.smoother_rmse_m;
  c->pcrb_filter_rmse_m = bound.filter_rmse_m;
  c->pcrb_note.clear();
  c->pcrb_t_s = bound.t_s;
  c->pcrb_filter_m.clear();
  c->pcrb_smoother_m.clear();
  for (size_t k = 0; k < bound.t_s.size(); ++k) {
    c->pcrb_filter_m.push_back(std::sqrt(bound.filter[k].trace()));
    c->pcrb_smoother_m.push_back(std::sqrt(bound.smoother[k].trace()));
  }
}

std::optional<double> RmseOverPcrb(const Comparison& c, const EstimatorOutcome& o) {
  if (!c.pcrb_rmse_m || !(*c.pcrb_rmse_m > 0.0) || !o.Ranked()) return std::nullopt;
  return o.stats.rmse_m / *c.pcrb_rmse_m;
}

namespace {

struct Column {
  const char* name;  // in the table
  const char* key;   // in results.json
  double ErrorStats::*field;
  int precision;
  bool larger_is_better = false;
  bool floors = false;  // a multi-floor figure: in the table only when some estimator has it
};

const Column kColumns[] = {
    {"rmse_m", "rmse_m", &ErrorStats::rmse_m, 3},
    {"mean_m", "mean_m", &ErrorStats::mean_m, 3},
    {"median_m", "median_m", &ErrorStats::median_m, 3},
    {"p75_m", "p75_m", &ErrorStats::p75_m, 3},
    {"p90_m", "p90_m", &ErrorStats::p90_m, 3},
    {"max_m", "max_m", &ErrorStats::max_m, 3},
    {"final_m", "final_m", &ErrorStats::final_m, 3},
    {"pct_dist", "pct_distance", &ErrorStats::pct_distance, 2},
    {"mean_pct", "mean_pct_distance", &ErrorStats::mean_pct_distance, 2},
    {"ipin_m", "ipin_score_m", &ErrorStats::ipin_score_m, 3, false, true},
    {"floor_hit", "floor_hit_rate", &ErrorStats::floor_hit_rate, 3, true, true},
};

// The columns of a comparison's table: the floor figures only on a multi-floor walk.
std::vector<const Column*> TableColumns(const Comparison& c) {
  std::vector<const Column*> out;
  for (const Column& col : kColumns) {
    bool any = !col.floors;
    for (const EstimatorOutcome& o : c.outcomes) {
      any = any || (o.Ranked() && !std::isnan(o.stats.*(col.field)));
    }
    if (any) out.push_back(&col);
  }
  return out;
}

using internal::Fixed;

}  // namespace

// Below 30 runs a ratio under 1 is usually the runs' sampling noise, not an estimator below
// the bound: the table says so with the ratio's 95 % interval, from a Student t interval on
// the mean of the runs' RMSE (t₀.₉₇₅ by degrees of freedom 1…29, from the t table).
constexpr int kPcrbWarnRuns = 30;
constexpr double kStudentT975[kPcrbWarnRuns - 1] = {
    12.706, 4.303, 3.182, 2.776, 2.571, 2.447, 2.365, 2.306, 2.262, 2.228,
    2.201,  2.179, 2.160, 2.145, 2.131, 2.120, 2.110, 2.101, 2.093, 2.086,
    2.080,  2.074, 2.069, 2.064, 2.060, 2.056, 2.052, 2.048, 2.045};

void WarnAboutFewRunsBelowTheBound(const Comparison& c, std::ostream& out) {
  for (const EstimatorOutcome& o : c.outcomes) {
    const std::optional<double> ratio = RmseOverPcrb(c, o);
    const int n = static_cast<int>(o.run_rmse_m.size());
    if (!ratio || !(*ratio < 1.0) || std::max(n, c.runs) >= kPcrbWarnRuns) continue;
    out << "warning: " << o.id << " rmse/pcrb " << Fixed(*ratio, 2) << " < 1 from "
        << std::max(n, 1) << (std::max(n, 1) == 1 ? " run" : " runs");
    if (n >= 2 && o.stats_std) {
      const double half = kStudentT975[n - 2] * o.stats_std->rmse_m / std::sqrt(n);
      out << " (95 % interval " << Fixed((o.stats.rmse_m - half) / *c.pcrb_rmse_m, 2) << " to "
          << Fixed((o.stats.rmse_m + half) / *c.pcrb_rmse_m, 2) << ")";
    } else {
      out << " (one run: no interval)";
    }
    out << ": with fewer than " << kPcrbWarnRuns
        << " runs this is within sampling noise, not below the bound; use --runs " << kPcrbWarnRuns
        << " or more\n";
  }
}

double ScoredPointsPerRun(const Comparison& c, const EstimatorOutcome& o) {
  if (!o.Ranked()) return 0.0;
  const size_t runs = c.runs > 1 ? std::max<size_t>(o.run_rmse_m.size(), 1) : 1;
  return static_cast<double>(o.stats.n_points) / static_cast<double>(runs);
}

namespace {

double MostScoredPointsPerRun(const Comparison& c) {
  double most = 0.0;
  for (const EstimatorOutcome& o : c.outcomes) most = std::max(most, ScoredPointsPerRun(c, o));
  return most;
}

}  // namespace

bool ScoredOnEveryPoint(const Comparison& c, const EstimatorOutcome& o) {
  // Monte Carlo: per counted run, so that failed runs (shown apart) do not count as missed
  // points; with runs of different lengths, failing on a long one lowers the mean and marks the
  // estimator partial too. 1e-9 is round-off.
  return o.Ranked() && ScoredPointsPerRun(c, o) >= MostScoredPointsPerRun(c) * (1.0 - 1e-9);
}

std::string ScoredPointsLabel(const Comparison& c, const EstimatorOutcome& o) {
  const std::string n = std::to_string(o.stats.n_points);
  if (!o.Ranked() || ScoredOnEveryPoint(c, o)) return n;
  const double per_run = ScoredPointsPerRun(c, o);
  const double runs = per_run > 0.0 ? static_cast<double>(o.stats.n_points) / per_run : 1.0;
  return n + "/" + std::to_string(std::lround(MostScoredPointsPerRun(c) * runs));
}

namespace {

// The best value of each table column, and of the runtime last, among the ranked estimators
// scored on every point.
std::vector<double> TableBestValues(const Comparison& c, const std::vector<const Column*>& cols) {
  const size_t ncol = cols.size();
  std::vector<double> best(ncol + 1, std::numeric_limits<double>::infinity());
  for (size_t j = 0; j < ncol; ++j) {
    if (cols[j]->larger_is_better) best[j] = -std::numeric_limits<double>::infinity();
  }
  for (const EstimatorOutcome& o : c.outcomes) {
    if (!ScoredOnEveryPoint(c, o)) continue;  // not ranked, or over part of the walk
    best[ncol] = std::min(best[ncol], o.runtime_s);
    for (size_t j = 0; j < ncol; ++j) {
      const double v = o.stats.*(cols[j]->field);
      if (std::isnan(v)) continue;
      best[j] = cols[j]->larger_is_better ? std::max(best[j], v) : std::min(best[j], v);
    }
  }
  return best;
}

}  // namespace

std::string FormatComparisonTable(const Comparison& c) {
  const std::vector<const Column*> cols = TableColumns(c);
  const size_t ncol = cols.size();
  const bool with_pcrb = c.pcrb_rmse_m.has_value();
  std::vector<std::vector<std::string>> rows;
  std::vector<std::string> header = {"estimator"};
  for (const Column* col : cols) header.push_back(col->name);
  header.push_back("anees");  // not marked best: 2 is consistent, not the smallest
  header.push_back("runtime_s");
  header.push_back("n");
  if (with_pcrb) header.push_back("rmse/pcrb");
  // Best (smallest, or largest where larger is better) per column, then the runtime's.
  const std::vector<double> best = TableBestValues(c, cols);
  bool partial = false;
  for (const EstimatorOutcome& o : c.outcomes)
    partial = partial || (o.Ranked() && !ScoredOnEveryPoint(c, o));
  for (const EstimatorOutcome& o : c.outcomes) {
    std::vector<std::string> row = {o.id};
    if (!o.status.ok() || !o.Ranked()) {
      row.push_back(o.status.ok() ? ToString(*o.divergence) : "failed: " + o.status.message());
      rows.push_back(row);
      continue;
    }
    for (size_t j = 0; j < ncol; ++j) {
      const double v = o.stats.*(cols[j]->field);
      if (std::isnan(v)) {  // mean_pct on a walk whose truth never leaves the start
        row.push_back("- ");
        continue;
      }
      std::string cell = Fixed(v, cols[j]->precision);
      if (o.stats_std) cell += "+-" + Fixed((*o.stats_std).*(cols[j]->field), cols[j]->precision);
      row.push_back(cell + (v == best[j] && ScoredOnEveryPoint(c, o) ? "*" : " "));
    }
    if (std::isfinite(o.stats.anees)) {
      std::string cell = Fixed(o.stats.anees, 2);
      if (o.stats_std && std::isfinite(o.stats_std->anees)) {
        cell += "+-" + Fixed(o.stats_std->anees, 2);
      }
      row.push_back(cell + " ");
    } else {
      row.push_back("- ");
    }
    row.push_back(Fixed(o.runtime_s, 3) +
                  (o.runtime_s == best[ncol] && ScoredOnEveryPoint(c, o) ? "*" : " "));
    row.push_back(ScoredPointsLabel(c, o));
    if (with_pcrb) {
      const std::optional<double> ratio = RmseOverPcrb(c, o);
      row.push_back(ratio ? Fixed(*ratio, 2) + " " : "- ");
    }
    rows.push_back(row);
  }
  // The bound's rows: the RMSE column only (no estimator can reach below it).
  if (with_pcrb) {
    for (const auto& [name, value] :
         {std::pair<const char*, std::optional<double>>{"PCRB smoother", c.pcrb_rmse_m},
          {"PCRB filter", c.pcrb_filter_rmse_m}}) {
      if (!value) continue;
      std::vector<std::string> row(header.size(), "-");
      row[0] = name;
      row[1] = Fixed(*value, 3) + " ";
      row.back() = "1.00 ";
      rows.push_back(row);
    }
  }
  std::vector<size_t> width(header.size(), 0);
  for (size_t j = 0; j < header.size(); ++j) width[j] = header[j].size();
  for (const auto& row : rows) {
    if (row.size() != header.size()) continue;
    for (size_t j = 0; j < row.size(); ++j) width[j] = std::max(width[j], row[j].size());
  }
  std::ostringstream out;
  out << "walk: " << c.walk_name << "  (truth: " << ToString(c.truth_kind) << ", runs: " << c.runs;
  if (c.score_from_s > 0.0) out << ", scored from " << c.score_from_s << " s";
  out << ")\n";
  auto print_row = [&](const std::vector<std::string>& row) {
    for (size_t j = 0; j < row.size(); ++j) {
      if (j == 0) {
        out << std::left << std::setw(static_cast<int>(width[j])) << row[j];
      } else if (row.size() == header.size()) {
        out << "  " << std::right << std::setw(static_cast<int>(width[j])) << row[j];
      } else {
        out << "  " << row[j];
      }
    }
    out << "\n";
  };
  print_row(header);
  for (const auto& row : rows) print_row(row);
  if (with_pcrb) {
    out << "PCRB: posterior Cramer-Rao bound of the position RMSE (smoother: full-walk "
           "information; filter: Tichavsky recursion; rmse/pcrb against the smoother bound)\n";
    WarnAboutFewRunsBelowTheBound(c, out);
  } else if (!c.pcrb_note.empty()) {
    out << "PCRB: " << c.pcrb_note << "\n";
  }
  if (!c.untied_frame.empty()) out << "warning: " << c.untied_frame << "\n";
  for (const EstimatorOutcome& o : c.outcomes) {
    if (o.diverged_runs > 0 && o.Ranked()) {
      out << o.id << ": " << o.diverged_runs << " of " << c.runs << " runs diverged ("
          << (o.divergence_kept_in_figures ? "kept in" : "left out of") << " the figures)\n";
    } else if (o.divergence && o.Ranked()) {
      out << o.id << ": " << ToString(*o.divergence) << " (kept in the figures)\n";
    }
  }
  out << "* best in column";
  if (partial) {
    out << " among the estimators scored on every truth point; n = a/b: scored on a of b points "
           "(its estimate does not span the walk), not marked best";
  }
  out << "\n";
  return out.str();
}

namespace {

// The figures of one outcome as results.json holds them.
nlohmann::ordered_json FiguresJson(const Comparison& c, const EstimatorOutcome& o) {
  nlohmann::ordered_json e;
  for (const Column& col : kColumns) {
    if (std::isnan(o.stats.*(col.field))) continue;
    const std::string key = col.key;
    e[key] = o.stats.*(col.field);
    if (o.stats_std) e[key + "_std"] = (*o.stats_std).*(col.field);
  }
  if (std::isfinite(o.stats.anees)) {
    e["anees"] = o.stats.anees;
    if (o.stats_std && std::isfinite(o.stats_std->anees)) e["anees_std"] = o.stats_std->anees;
  }
  e["n_points"] = o.stats.n_points;
  e["scored_on_every_point"] = ScoredOnEveryPoint(c, o);
  const std::optional<double> ratio = RmseOverPcrb(c, o);
  e["rmse_over_pcrb"] = ratio ? nlohmann::ordered_json(*ratio) : nullptr;
  return e;
}

// One estimator's entry of results.json; its timings go to `timing` under Monte Carlo (they
// would make results.json depend on the machine and the thread count).
nlohmann::ordered_json OutcomeJson(const Comparison& c, const EstimatorOutcome& o,
                                   nlohmann::ordered_json* timing) {
  const bool monte_carlo = c.runs > 1;
  nlohmann::ordered_json e;
  if (!o.status.ok()) {
    e["error"] = o.status.message();
    if (monte_carlo) e["failed_runs"] = o.failed_runs;
    return e;
  }
  // A diverged estimate's figures stay for the record, inside "diverged", not beside the others.
  const nlohmann::ordered_json figures = o.stats.n_points > 0 ? FiguresJson(c, o) : nullptr;
  if (o.divergence) {
    e["diverged"] = {{"t_s", o.divergence->t_s}, {"reason", o.divergence->reason}};
    if (!o.Ranked()) e["diverged"]["figures"] = figures;
  }
  if (o.Ranked()) e.update(figures);
  if (monte_carlo) {
    e["runtime_s"] = nullptr;
    (*timing)["estimators"][o.id] = {{"runtime_s", o.runtime_s},
                                     {"runtime_s_std", o.runtime_std_s}};
    for (const auto& [k, v] : o.result.timings) (*timing)["estimators"][o.id][k] = v;
    e["failed_runs"] = o.failed_runs;
    e["diverged_runs"] = o.diverged_runs;
  } else {
    e["runtime_s"] = o.runtime_s;
    for (const auto& [k, v] : o.result.timings) e["timings"][k] = v;
  }
  for (const auto& [k, v] : o.result.diagnostics) e["diagnostics"][k] = v;
  return e;
}

// results.json (and, under Monte Carlo, timing.json's content in `timing`).
nlohmann::ordered_json ResultsJson(const Comparison& c, nlohmann::ordered_json* timing) {
  nlohmann::ordered_json j;
  j["walk"] = c.walk_name;
  j["runs"] = c.runs;
  if (c.seed) j["seed"] = *c.seed;
  if (c.score_from_s > 0.0) j["score_from_s"] = c.score_from_s;
  j["truth_kind"] = ToString(c.truth_kind);
  j["estimators"] = nlohmann::ordered_json::object();
  (*timing)["runs"] = c.runs;
  (*timing)["estimators"] = nlohmann::ordered_json::object();
  for (const EstimatorOutcome& o : c.outcomes) {
    j["estimators"][o.id] = OutcomeJson(c, o, timing);
  }
  j["pcrb_rmse_m"] = c.pcrb_rmse_m ? nlohmann::ordered_json(*c.pcrb_rmse_m) : nullptr;
  j["pcrb_filter_rmse_m"] =
      c.pcrb_filter_rmse_m ? nlohmann::ordered_json(*c.pcrb_filter_rmse_m) : nullptr;
  if (!c.pcrb_note.empty()) j["pcrb_note"] = c.pcrb_note;
  j["warnings"] = {{"count", c.warning_count}, {"messages", nlohmann::ordered_json(c.warnings)}};
  return j;
}

// truth.tum (the whole truth, also under CompareOptions::compact) and, when the truth is
// checkpoints, checkpoints.csv.
Status WriteTruthFiles(const Comparison& c, const fs::path& tmp) {
  if (c.truth.empty() && !c.truth_tum) return Status::Ok();
  Status s = WriteFileInOutput((tmp / "truth.tum").string(), [&](std::ostream& out) {
    if (c.truth_tum) return c.truth_tum->CopyTo(out).ok();
    FormatTruthTum(c.truth, out);
    return true;
  });
  if (!s.ok() || c.truth_kind != TruthKind::kCheckpoints) return s;
  return WriteFileInOutput((tmp / "checkpoints.csv").string(), [&](std::ostream& out) {
    out << "t_s,x_m,y_m\n";
    for (const TruthSample& t : c.truth) {
      out << internal::Num(t.t_s) << ',' << internal::Num(t.position_m.x()) << ','
          << internal::Num(t.position_m.y()) << '\n';
    }
    return true;
  });
}

// anchors_estimated/<id>.csv for each estimator that placed anchors (EstimateResult::anchors):
// id,x_m,y_m,var_x_m2,cov_xy_m2,var_y_m2,readings,observable; empty fields where there is no
// position or covariance.
Status WriteAnchorEstimates(const Comparison& c, const fs::path& tmp) {
  for (const EstimatorOutcome& o : c.outcomes) {
    if (!o.status.ok() || o.result.anchors.empty()) continue;
    std::error_code ec;
    fs::create_directories(tmp / "anchors_estimated", ec);
    if (ec) return IoError(tmp.string() + ": cannot create anchors_estimated/: " + ec.message());
    WG_RETURN_IF_ERROR(WriteFileInOutput(
        (tmp / "anchors_estimated" / (o.id + ".csv")).string(), [&](std::ostream& out) {
          out << "id,x_m,y_m,var_x_m2,cov_xy_m2,var_y_m2,readings,observable\n";
          for (const AnchorEstimate& a : o.result.anchors) {
            out << a.id << ',';
            if (a.observable) {
              out << internal::Num(a.position_m.x()) << ',' << internal::Num(a.position_m.y());
            } else {
              out << ',';
            }
            if (a.covariance) {
              const Eigen::Matrix2d& P = *a.covariance;
              out << ',' << internal::Num(P(0, 0)) << ',' << internal::Num(P(0, 1)) << ','
                  << internal::Num(P(1, 1));
            } else {
              out << ",,,";
            }
            out << ',' << a.readings << ',' << (a.observable ? 1 : 0) << '\n';
          }
          return true;
        }));
  }
  return Status::Ok();
}

Status WriteComparisonFiles(const Comparison& c, const fs::path& tmp) {
  std::error_code ec;
  if (!fs::create_directories(tmp / "trajectories", ec)) {
    return IoError(tmp.string() + ": cannot create trajectories/: " + ec.message());
  }
  const bool monte_carlo = c.runs > 1;
  nlohmann::ordered_json timing;
  const nlohmann::ordered_json j = ResultsJson(c, &timing);
  Status s = WriteFileInOutput((tmp / "results.json").string(), [&](std::ostream& out) {
    out << j.dump(2, ' ', false, nlohmann::ordered_json::error_handler_t::replace) << "\n";
    return true;
  });
  if (!s.ok()) return s;
  if (monte_carlo) {
    s = WriteFileInOutput((tmp / "timing.json").string(), [&](std::ostream& out) {
      out << timing.dump(2, ' ', false, nlohmann::ordered_json::error_handler_t::replace) << "\n";
      return true;
    });
    if (!s.ok()) return s;
  }
  s = WriteFileInOutput((tmp / "errors.csv").string(), [&](std::ostream& out) {
    out << "t_s,estimator,error_m" << (monte_carlo ? ",run\n" : "\n") << std::setprecision(10);
    if (c.errors_csv_rows) return c.errors_csv_rows->CopyTo(out).ok();
    for (const EstimatorOutcome& o : c.outcomes) {
      for (size_t i = 0; i < o.errors.t_s.size(); ++i) {
        out << o.errors.t_s[i] << ',' << o.id << ',' << o.errors.error_m[i]
            << (monte_carlo ? ",0\n" : "\n");
      }
    }
    return true;
  });
  if (!s.ok()) return s;
  for (const EstimatorOutcome& o : c.outcomes) {
    if (!o.status.ok() || (o.result.trajectory.empty() && !o.trajectory_tum)) continue;
    s = WriteFileInOutput((tmp / "trajectories" / (o.id + ".tum")).string(),
                          [&](std::ostream& out) {
                            if (o.trajectory_tum) return o.trajectory_tum->CopyTo(out).ok();
                            FormatTumTrajectory(o.result.trajectory, out);
                            return true;
                          });
    if (!s.ok()) return s;
    s = WriteFileInOutput((tmp / "trajectories" / (o.id + ".csv")).string(),
                          [&](std::ostream& out) {
                            if (o.trajectory_csv) return o.trajectory_csv->CopyTo(out).ok();
                            FormatTrajectoryCsv(o.result.trajectory, out);
                            return true;
                          });
    if (!s.ok()) return s;
  }
  s = WriteAnchorEstimates(c, tmp);
  if (!s.ok()) return s;
  s = WriteTruthFiles(c, tmp);
  if (!s.ok()) return s;
  const std::string html = RenderHtmlReport(c);
  s = WriteFileInOutput((tmp / "report.html").string(), [&](std::ostream& out) {
    out << html;
    return true;
  });
  return s;
}

}  // namespace

std::string ResultsJsonText(const Comparison& comparison) {
  nlohmann::ordered_json timing;
  return ResultsJson(comparison, &timing)
             .dump(2, ' ', false, nlohmann::ordered_json::error_handler_t::replace) +
         "\n";
}

Status WriteComparison(const Comparison& c, const std::string& out_dir,
                       const OutputOptions& options) {
  return WriteOutputFolder(out_dir, options,
                           [&](const std::string& tmp) { return WriteComparisonFiles(c, tmp); });
}

}  // namespace walkgraph
