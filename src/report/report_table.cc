#include "report/report_table.h"

#include <cmath>
#include <functional>
#include <limits>
#include <sstream>

#include "report/svg.h"
#include "util/text.h"

namespace walkgraph::report {

namespace {

// A column: its value (NaN = none), its Monte Carlo spread, and what "best" means.
enum class Best { kSmallest, kLargest, kClosestToTwo, kNone };
struct Column {
  const char* header;
  const char* title;  // the header's tooltip
  std::function<double(const Comparison&, const EstimatorOutcome&)> value;
  double ErrorStats::*spread;  // nullptr: none
  int precision;
  Best best;
  bool points = false;  // the n column: ScoredPointsLabel's "a/b" text
};

std::vector<Column> Columns(const Comparison& c) {
  auto stat = [](double ErrorStats::*f) {
    return [f](const Comparison&, const EstimatorOutcome& o) { return o.stats.*f; };
  };
  std::vector<Column> cols = {
      {"RMSE [m]", "root mean square horizontal error", stat(&ErrorStats::rmse_m),
       &ErrorStats::rmse_m, 3, Best::kSmallest},
      {"mean [m]", "mean error", stat(&ErrorStats::mean_m), &ErrorStats::mean_m, 3,
       Best::kSmallest},
      {"median [m]", "median error", stat(&ErrorStats::median_m), &ErrorStats::median_m, 3,
       Best::kSmallest},
      {"p75 [m]", "75th percentile (the EvAAL/IPIN score)", stat(&ErrorStats::p75_m),
       &ErrorStats::p75_m, 3, Best::kSmallest},
      {"p90 [m]", "90th percentile", stat(&ErrorStats::p90_m), &ErrorStats::p90_m, 3,
       Best::kSmallest},
      {"max [m]", "largest error", stat(&ErrorStats::max_m), &ErrorStats::max_m, 3,
       Best::kSmallest},
      {"final [m]", "error at the last scored truth point", stat(&ErrorStats::final_m),
       &ErrorStats::final_m, 3, Best::kSmallest},
      {"% dist", "final error as % of the distance walked", stat(&ErrorStats::pct_distance),
       &ErrorStats::pct_distance, 2, Best::kSmallest},
      {"mean % dist", "mean of error / distance walked so far",
       stat(&ErrorStats::mean_pct_distance), &ErrorStats::mean_pct_distance, 2, Best::kSmallest},
      {"ANEES", "mean position NEES; 2 = consistent (best: closest to 2 in ratio)",
       stat(&ErrorStats::anees), &ErrorStats::anees, 2, Best::kClosestToTwo},
      {"runtime [s]", "wall-clock time of the run (machine-dependent)",
       [](const Comparison&, const EstimatorOutcome& o) { return o.runtime_s; }, nullptr, 3,
       Best::kSmallest},
      {"n", "scored points",
       [](const Comparison&, const EstimatorOutcome& o) { return double(o.stats.n_points); },
       nullptr, 0, Best::kNone, true},
  };
  bool floors = false;  // a multi-floor walk: IPIN's score and the floor hit rate
  for (const EstimatorOutcome& o : c.outcomes) floors = floors || !std::isnan(o.stats.ipin_score_m);
  if (floors) {
    cols.insert(cols.begin() + 4,
                {"IPIN [m]", "IPIN score: 3rd quartile of error + 15 m per floor missed",
                 stat(&ErrorStats::ipin_score_m), &ErrorStats::ipin_score_m, 3, Best::kSmallest});
    cols.insert(cols.begin() + 5, {"floor hit", "fraction of points on the right floor",
                                   stat(&ErrorStats::floor_hit_rate), &ErrorStats::floor_hit_rate,
                                   3, Best::kLargest});
  }
  if (c.pcrb_rmse_m) {
    cols.push_back({"RMSE / PCRB", "RMSE over the smoother's posterior Cramér-Rao bound",
                    [](const Comparison& cc, const EstimatorOutcome& o) {
                      const std::optional<double> r = RmseOverPcrb(cc, o);
                      return r ? *r : std::nan("");
                    },
                    nullptr, 2, Best::kSmallest});
  }
  return cols;
}

double Badness(Best best, double v) {
  if (best == Best::kLargest) return -v;
  // ANEES: a factor k too confident is as bad as a factor k too cautious, so the distance to 2
  // is taken on a log scale; 0 (a covariance that says nothing) is never the best.
  if (best == Best::kClosestToTwo) {
    return v > 0.0 ? std::abs(std::log(v / 2.0)) : std::numeric_limits<double>::infinity();
  }
  return v;
}

using internal::Fixed;

// The best (smallest badness) value of each column among the ranked outcomes.
std::vector<double> BestValues(const Comparison& c, const std::vector<Column>& cols) {
  std::vector<double> best(cols.size(), std::numeric_limits<double>::infinity());
  for (const EstimatorOutcome& o : c.outcomes) {
    if (!ScoredOnEveryPoint(c, o)) continue;  // not ranked, or over part of the walk
    for (size_t j = 0; j < cols.size(); ++j) {
      const double v = cols[j].value(c, o);
      if (std::isfinite(v)) best[j] = std::min(best[j], Badness(cols[j].best, v));
    }
  }
  return best;
}

std::string Row(const Comparison& c, size_t k, const LineStyle& style,
                const std::vector<Column>& cols, const std::vector<double>& best) {
  const EstimatorOutcome& o = c.outcomes[k];
  std::ostringstream s;
  s << "<tr class=\"est\" data-id=\"" << Escape(o.id) << "\" data-f=\"" << style.family
    << "\" data-k=\"" << k << "\"><td class=\"name\"><input type=\"checkbox\" class=\"tog\" "
    << "checked title=\"show in the plots\"><span class=\"sw\" style=\"background:" << style.color
    << "\"></span>" << Escape(o.id) << "</td>";
  for (size_t j = 0; j < cols.size(); ++j) {
    const double v = cols[j].value(c, o);
    if (!std::isfinite(v)) {
      s << "<td data-v=\"\"></td>";
      continue;
    }
    const bool is_best = cols[j].best != Best::kNone && Badness(cols[j].best, v) == best[j] &&
                         ScoredOnEveryPoint(c, o);
    s << "<td data-v=\"" << Fixed(v, cols[j].precision + 3) << "\""
      << (is_best ? " class=\"best\" title=\"best in column\"" : "") << ">"
      << (cols[j].points ? ScoredPointsLabel(c, o) : Fixed(v, cols[j].precision));
    if (o.stats_std && cols[j].spread != nullptr && std::isfinite((*o.stats_std).*cols[j].spread)) {
      s << " &plusmn; " << Fixed((*o.stats_std).*cols[j].spread, cols[j].precision);
    }
    s << "</td>";
  }
  s << "</tr>\n";
  return s.str();
}

std::string Summary(const Comparison& c, const std::vector<double>& best) {
  std::ostringstream s;
  int ranked = 0, unranked = 0;
  const EstimatorOutcome* top = nullptr;
  for (const EstimatorOutcome& o : c.outcomes) {
    if (!o.Ranked()) {
      ++unranked;
      continue;
    }
    ++ranked;
    if (top == nullptr && ScoredOnEveryPoint(c, o) && o.stats.rmse_m == best[0]) top = &o;
  }
  s << "<p class=\"summary\">truth: " << ToString(c.truth_kind) << " &middot; runs: " << c.runs;
  if (c.seed) s << " &middot; seed: " << *c.seed;
  if (c.score_from_s > 0.0) s << " &middot; scored from " << c.score_from_s << " s";
  s << " &middot; " << ranked << " estimators ranked";
  if (unranked > 0) s << ", " << unranked << " diverged or failed (below the table, not ranked)";
  if (top != nullptr) {
    s << ".<br>Lowest RMSE: <b>" << Escape(top->id) << "</b> (" << Fixed(top->stats.rmse_m, 3)
      << " m).";
  }
  s << "</p>\n<p class=\"hint\">Click a column header to sort (within families while grouped); "
       "hover or click a row to highlight its lines in every plot; untick to hide it. "
       "<label><input type=\"checkbox\" id=\"group\" checked> group by family</label> "
       "<button id=\"all-on\">show all</button> <button id=\"all-off\">hide all</button></p>\n";
  return s.str();
}

std::string Unranked(const Comparison& c, const std::vector<LineStyle>& styles) {
  std::ostringstream s;
  bool any = false;
  for (size_t k = 0; k < c.outcomes.size(); ++k) {
    const EstimatorOutcome& o = c.outcomes[k];
    if (o.Ranked()) continue;
    if (!any) {
      s << "<h2>Diverged or failed: not ranked, not plotted</h2>\n<table id=\"unranked\">"
        << "<tr><th>estimator</th><th>family</th><th>why</th></tr>\n";
      any = true;
    }
    s << "<tr data-id=\"" << Escape(o.id) << "\"><td>" << Escape(o.id) << "</td><td>"
      << EstimatorFamilies()[styles[k].family].label << "</td><td class=\"why\">"
      << Escape(o.status.ok() ? ToString(*o.divergence) : "failed: " + o.status.message())
      << "</td></tr>\n";
  }
  if (any) s << "</table>\n";
  return s.str();
}

}  // namespace

std::string ResultsTableHtml(const Comparison& c, const std::vector<LineStyle>& styles) {
  const std::vector<Column> cols = Columns(c);
  const std::vector<double> best = BestValues(c, cols);
  std::ostringstream s;
  s << Summary(c, best);
  s << "<table id=\"results\"><thead><tr><th data-col=\"0\" title=\"estimator id\">estimator</th>";
  for (size_t j = 0; j < cols.size(); ++j) {
    s << "<th data-col=\"" << j + 1 << "\" title=\"" << cols[j].title << "\">" << cols[j].header
      << "</th>";
  }
  s << "</tr></thead>\n<tbody>\n";
  const auto& families = EstimatorFamilies();
  for (size_t f = 0; f < families.size(); ++f) {
    bool header = false;
    for (size_t k = 0; k < c.outcomes.size(); ++k) {
      if (styles[k].family != f || !c.outcomes[k].Ranked()) continue;
      if (!header) {
        s << "<tr class=\"fam\" data-f=\"" << f << "\"><th colspan=\"" << cols.size() + 1 << "\">"
          << families[f].label << "</th></tr>\n";
        header = true;
      }
      s << Row(c, k, styles[k], cols, best);
    }
  }
  s << "</tbody>\n";
  if (c.pcrb_rmse_m) {
    s << "<tfoot>";
    const std::pair<const char*, std::optional<double>> rows[] = {
        {"PCRB smoother", c.pcrb_rmse_m}, {"PCRB filter", c.pcrb_filter_rmse_m}};
    for (const auto& [name, value] : rows) {
      if (!value) continue;
      s << "<tr class=\"pcrb\"><td>" << name << "</td><td>" << Fixed(*value, 3)
        << "</td><td colspan=\"" << cols.size() - 1 << "\"></td></tr>";
    }
    s << "</tfoot>";
  }
  s << "</table>\n<p class=\"note\">&#9733; best in column among the ranked estimators scored on "
       "every truth point (ANEES: closest to 2, the consistent value, in ratio: 1 and 4 are as far "
       "from it).";
  bool partial = false;
  for (const EstimatorOutcome& o : c.outcomes)
    partial = partial || (o.Ranked() && !ScoredOnEveryPoint(c, o));
  if (partial) {
    s << " n = a/b: scored on a of the b truth points the others are scored on (its estimate does "
         "not span the walk, e.g. a filter that starts at its first radio fix), never marked best.";
  }
  if (c.pcrb_rmse_m) {
    s << " PCRB: posterior Cram&eacute;r&ndash;Rao bound of the position RMSE over the same runs "
         "(smoother: full-walk Fisher information; filter: Tichavsk&yacute; recursion); RMSE / "
         "PCRB is against the smoother bound.";
  } else if (!c.pcrb_note.empty()) {
    s << " PCRB: " << Escape(c.pcrb_note);
  }
  s << "</p>\n" << Unranked(c, styles);
  return s.str();
}

}  // namespace walkgraph::report
