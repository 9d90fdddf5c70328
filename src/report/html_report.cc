// The self-contained HTML report: inline SVG plots, no scripts, no network.
#include <algorithm>
#include <cmath>
#include <iomanip>
#include <limits>
#include <sstream>

#include "report/svg.h"
#include "walkgraph/compare.h"

namespace walkgraph {

namespace {

using report::Axes;
using report::Color;
using report::Escape;
using report::Open;
using report::Polyline;

std::string Legend(const Comparison& c, const Axes& a, bool with_truth) {
  std::ostringstream s;
  double y = a.m + 14;
  if (with_truth) {
    s << "<text x=\"" << a.w - a.m - 4 << "\" y=\"" << y
      << "\" text-anchor=\"end\" font-size=\"11\" fill=\"#000\">truth</text>\n";
    y += 13;
  }
  for (size_t i = 0; i < c.outcomes.size(); ++i) {
    if (!c.outcomes[i].Ranked()) continue;
    s << "<text class=\"legend\" x=\"" << a.w - a.m - 4 << "\" y=\"" << y
      << "\" text-anchor=\"end\" font-size=\"11\" fill=\"" << Color(i) << "\">"
      << Escape(c.outcomes[i].id) << "</text>\n";
    y += 13;
  }
  return s.str();
}

std::string TrajectoryPlot(const Comparison& c) {
  Axes a{std::numeric_limits<double>::infinity(), -std::numeric_limits<double>::infinity(),
         std::numeric_limits<double>::infinity(), -std::numeric_limits<double>::infinity()};
  a.equal_aspect = true;
  auto grow = [&](double x, double y) {
    a.x0 = std::min(a.x0, x);
    a.x1 = std::max(a.x1, x);
    a.y0 = std::min(a.y0, y);
    a.y1 = std::max(a.y1, y);
  };
  for (const TruthSample& t : c.truth) grow(t.position_m.x(), t.position_m.y());
  for (const Anchor& an : c.anchors) grow(an.position_m.x(), an.position_m.y());
  if (!std::isfinite(a.x0)) {
    a.x0 = a.y0 = 0;
    a.x1 = a.y1 = 1;
  }
  const double pad = 0.05 * std::max(a.x1 - a.x0, a.y1 - a.y0) + 0.5;
  a.x0 -= pad;
  a.x1 += pad;
  a.y0 -= pad;
  a.y1 += pad;
  a.Fix();
  std::ostringstream s;
  s << Open(a, "trajectories", "Trajectories", "x east [m]", "y north [m]");
  s << "<clipPath id=\"clip-traj\"><rect x=\"" << a.m << "\" y=\"" << a.m << "\" width=\""
    << a.w - 2 * a.m << "\" height=\"" << a.h - 2 * a.m
    << "\"/></clipPath><g clip-path=\"url(#clip-traj)\">\n";
  if (c.truth_kind == TruthKind::kCheckpoints) {
    for (const TruthSample& t : c.truth) {
      s << "<circle class=\"truth\" cx=\"" << a.X(t.position_m.x()) << "\" cy=\""
        << a.Y(t.position_m.y()) << "\" r=\"3\" fill=\"#000\"/>\n";
    }
  } else {
    s << Polyline(
        c.truth.size(),
        [&](size_t i) { return std::pair(c.truth[i].position_m.x(), c.truth[i].position_m.y()); },
        a, "#000", "truth", 2.5);
  }
  for (size_t k = 0; k < c.outcomes.size(); ++k) {
    const EstimatorOutcome& o = c.outcomes[k];
    if (!o.Ranked()) continue;
    const auto& pts = o.result.trajectory.points;
    s << Polyline(
        pts.size(),
        [&](size_t i) { return std::pair(pts[i].position_m.x(), pts[i].position_m.y()); }, a,
        Color(k), "estimate");
  }
  for (const Anchor& an : c.anchors) {
    const double x = a.X(an.position_m.x()), y = a.Y(an.position_m.y());
    s << "<polygon class=\"anchor\" points=\"" << x << ',' << y - 6 << ' ' << x - 5 << ',' << y + 4
      << ' ' << x + 5 << ',' << y + 4 << "\" fill=\"#f0c000\" stroke=\"#000\"/>"
      << "<text x=\"" << x + 6 << "\" y=\"" << y - 4 << "\" font-size=\"9\">" << an.id
      << "</text>\n";
  }
  s << "</g>" << Legend(c, a, true) << "</svg>\n";
  return s.str();
}

std::string ErrorTimePlot(const Comparison& c) {
  Axes a{std::numeric_limits<double>::infinity(), -std::numeric_limits<double>::infinity(), 0.0,
         0.0};
  for (const EstimatorOutcome& o : c.outcomes) {
    if (!o.Ranked() || o.errors.t_s.empty()) continue;
    a.x0 = std::min(a.x0, o.errors.t_s.front());
    a.x1 = std::max(a.x1, o.errors.t_s.back());
    a.y1 = std::max(a.y1, o.stats.p90_m * 1.5);
  }
  for (const std::vector<double>* bound : {&c.pcrb_smoother_m, &c.pcrb_filter_m}) {
    for (double v : *bound) a.y1 = std::max(a.y1, 1.05 * v);
  }
  if (!std::isfinite(a.x0)) {
    a.x0 = 0;
    a.x1 = 1;
  }
  a.Fix();
  std::ostringstream s;
  s << Open(a, "error-time", "Horizontal error vs time", "t [s]", "error [m]");
  s << "<clipPath id=\"clip-et\"><rect x=\"" << a.m << "\" y=\"" << a.m << "\" width=\""
    << a.w - 2 * a.m << "\" height=\"" << a.h - 2 * a.m
    << "\"/></clipPath><g clip-path=\"url(#clip-et)\">\n";
  for (size_t k = 0; k < c.outcomes.size(); ++k) {
    const EstimatorOutcome& o = c.outcomes[k];
    if (!o.Ranked()) continue;
    // Monte Carlo: the first successful run's errors.
    const size_t n = o.errors.t_s.size();
    s << Polyline(
        n, [&](size_t i) { return std::pair(o.errors.t_s[i], o.errors.error_m[i]); }, a, Color(k),
        "error-curve");
  }
  // The PCRB: sqrt(tr B(t)), a bound on the RMS error at t over the Monte Carlo runs.
  const std::vector<double>* bounds[] = {&c.pcrb_smoother_m, &c.pcrb_filter_m};
  const char* const dashes[] = {"6,3", "2,3"};
  for (int b = 0; b < 2; ++b) {
    const std::vector<double>& v = *bounds[b];
    if (v.size() != c.pcrb_t_s.size() || v.empty()) continue;
    s << Polyline(
        v.size(), [&](size_t i) { return std::pair(c.pcrb_t_s[i], v[i]); }, a, "#000", "pcrb-curve",
        1.2, dashes[b]);
  }
  s << "</g>" << Legend(c, a, false);
  if (!c.pcrb_t_s.empty()) {
    s << "<text class=\"legend\" x=\"" << a.m + 6 << "\" y=\"" << a.m + 14
      << "\" font-size=\"11\">PCRB: - - smoother, &#183;&#183;&#183; filter</text>\n";
  }
  s << "</svg>\n";
  return s.str();
}

std::string CdfPlot(const Comparison& c) {
  Axes a{0.0, 0.0, 0.0, 1.0};
  for (const EstimatorOutcome& o : c.outcomes) {
    if (o.Ranked()) a.x1 = std::max(a.x1, o.stats.p90_m * 1.5);
  }
  a.Fix();
  std::ostringstream s;
  s << Open(a, "error-cdf", "Error CDF", "error [m]", "fraction of points");
  s << "<clipPath id=\"clip-cdf\"><rect x=\"" << a.m << "\" y=\"" << a.m << "\" width=\""
    << a.w - 2 * a.m << "\" height=\"" << a.h - 2 * a.m
    << "\"/></clipPath><g clip-path=\"url(#clip-cdf)\">\n";
  for (size_t k = 0; k < c.outcomes.size(); ++k) {
    const EstimatorOutcome& o = c.outcomes[k];
    if (!o.Ranked() || o.errors.error_m.empty()) continue;
    if (o.pooled_errors) {  // Monte Carlo: every run's errors, from the sketch
      constexpr int kPoints = 400;
      s << Polyline(
          kPoints + 1,
          [&](size_t i) {
            const double f = static_cast<double>(i) / kPoints;
            return std::pair(o.pooled_errors->Percentile(100.0 * f), f);
          },
          a, Color(k), "cdf-curve");
      continue;
    }
    std::vector<double> e = o.errors.error_m;
    std::sort(e.begin(), e.end());
    const double n = static_cast<double>(e.size());
    s << Polyline(
        e.size(), [&](size_t i) { return std::pair(e[i], (i + 1) / n); }, a, Color(k), "cdf-curve");
  }
  s << "</g>" << Legend(c, a, false) << "</svg>\n";
  return s.str();
}

std::string Table(const Comparison& c) {
  const bool with_pcrb = c.pcrb_rmse_m.has_value();
  const int ncols = with_pcrb ? 13 : 12;
  std::ostringstream s;
  s << std::fixed << std::setprecision(3);
  s << "<table id=\"results\"><tr><th>estimator</th><th>RMSE [m]</th><th>mean</th><th>median</th>"
       "<th>p75</th><th>p90</th><th>max</th><th>final</th><th>% dist</th><th>mean % dist</th>"
       "<th>ANEES</th>"
       "<th>runtime [s]</th><th>n</th>";
  if (with_pcrb) s << "<th>RMSE / PCRB</th>";
  s << "</tr>\n";
  for (size_t k = 0; k < c.outcomes.size(); ++k) {
    const EstimatorOutcome& o = c.outcomes[k];
    s << "<tr><td style=\"color:" << Color(k) << "\">" << Escape(o.id) << "</td>";
    if (!o.Ranked()) {
      s << "<td colspan=\"" << ncols << "\">"
        << Escape(o.status.ok() ? ToString(*o.divergence) : "failed: " + o.status.message())
        << "</td></tr>\n";
      continue;
    }
    const ErrorStats& e = o.stats;
    const double ErrorStats::*fields[] = {
        &ErrorStats::rmse_m,  &ErrorStats::mean_m,       &ErrorStats::median_m,
        &ErrorStats::p75_m,   &ErrorStats::p90_m,        &ErrorStats::max_m,
        &ErrorStats::final_m, &ErrorStats::pct_distance, &ErrorStats::mean_pct_distance};
    for (const auto f : fields) {
      if (std::isnan(e.*f)) {  // mean % dist on a walk whose truth never leaves the start
        s << "<td></td>";
        continue;
      }
      s << "<td>" << e.*f;
      if (o.stats_std) s << " &plusmn; " << (*o.stats_std).*f;  // Monte Carlo spread
      s << "</td>";
    }
    s << "<td>";  // position NEES mean (2 = consistent); empty without covariances
    if (std::isfinite(e.anees)) {
      s << std::setprecision(2) << e.anees;
      if (o.stats_std && std::isfinite(o.stats_std->anees)) {
        s << " &plusmn; " << o.stats_std->anees;
      }
      s << std::setprecision(3);
    }
    s << "</td>";
    s << "<td>" << o.runtime_s << "</td>";
    s << "<td>" << e.n_points << "</td>";
    if (with_pcrb) {
      const std::optional<double> ratio = RmseOverPcrb(c, o);
      s << "<td>";
      if (ratio) s << std::setprecision(2) << *ratio << std::setprecision(3);
      s << "</td>";
    }
    s << "</tr>\n";
  }
  if (with_pcrb) {
    const std::pair<const char*, std::optional<double>> rows[] = {
        {"PCRB smoother", c.pcrb_rmse_m}, {"PCRB filter", c.pcrb_filter_rmse_m}};
    for (const auto& [name, value] : rows) {
      if (!value) continue;
      s << "<tr class=\"pcrb\"><td>" << name << "</td><td>" << *value << "</td>";
      for (int j = 1; j < ncols; ++j) s << "<td>-</td>";
      s << "</tr>\n";
    }
  }
  s << "</table>\n";
  if (with_pcrb) {
    s << "<p>PCRB: posterior Cram&eacute;r&ndash;Rao bound of the position RMSE over the same "
         "runs (smoother: full-walk Fisher information; filter: Tichavsk&yacute; recursion). "
         "RMSE / PCRB is against the smoother bound.</p>\n";
  } else if (!c.pcrb_note.empty()) {
    s << "<p>PCRB: " << Escape(c.pcrb_note) << "</p>\n";
  }
  return s.str();
}

}  // namespace

std::string RenderHtmlReport(const Comparison& c) {
  std::ostringstream s;
  s << "<!DOCTYPE html>\n<html><head><meta charset=\"utf-8\"><title>walkgraph: "
    << Escape(c.walk_name) << "</title>\n<style>body{font-family:sans-serif;margin:16px}"
    << "table{border-collapse:collapse}td,th{border:1px solid #ccc;padding:3px 8px;"
    << "text-align:right}td:first-child{text-align:left}svg{margin:4px}</style></head><body>\n";
  s << "<h1>walkgraph comparison: " << Escape(c.walk_name) << "</h1>\n";
  s << "<p>truth: " << ToString(c.truth_kind) << ", runs: " << c.runs << "</p>\n";
  s << Table(c);
  s << "<div>" << TrajectoryPlot(c) << ErrorTimePlot(c) << CdfPlot(c) << "</div>\n";
  s << "</body></html>\n";
  return s.str();
}

}  // namespace walkgraph
