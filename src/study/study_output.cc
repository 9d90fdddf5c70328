// Parameter studies: a result's CSV, table and HTML, and the output folder (study.h).
#include "walkgraph/study.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <iomanip>
#include <limits>
#include <sstream>

#include "report/estimator_style.h"
#include "report/svg.h"
#include "study/study_internal.h"
#include "util/text.h"
#include "walkgraph/io.h"

namespace walkgraph {

namespace fs = std::filesystem;
using internal::CellAt;
using internal::CellConfig;
using internal::CellOverrides;
using internal::FieldOf;

// ------------------------------------------------------------------ output

namespace {

std::string Num(double v) { return internal::Num(v, 10); }

std::string CsvField(const std::string& s) {
  if (s.find_first_of(",\"\n\r") == std::string::npos) return s;
  std::string o = "\"";
  for (char ch : s) {
    if (ch == '"') o += '"';
    o += ch;
  }
  return o + "\"";
}

std::optional<double> RatioOf(const StudyCell& c, const StudyRow& r) {
  if (!r.status.ok() || !c.pcrb_rmse_m || !(*c.pcrb_rmse_m > 0.0)) return std::nullopt;
  return r.stats.rmse_m / *c.pcrb_rmse_m;
}

// v, or nothing when it is not finite (anees without covariances).
std::optional<double> Finite(double v) {
  if (!std::isfinite(v)) return std::nullopt;
  return v;
}

// The plotted figure (and its Monte Carlo spread) of a row.
std::optional<double> MetricOf(const StudyCell& c, const StudyRow& r, const std::string& metric) {
  if (!r.status.ok()) return std::nullopt;
  if (metric == "rmse_over_pcrb") return RatioOf(c, r);
  if (double ErrorStats::*f = FieldOf(metric)) return Finite(r.stats.*f);
  return std::nullopt;
}

std::optional<double> MetricStdOf(const StudyCell& c, const StudyRow& r,
                                  const std::string& metric) {
  if (!r.status.ok() || !r.stats_std || c.runs < 2) return std::nullopt;
  if (double ErrorStats::*f = FieldOf(metric)) return Finite((*r.stats_std).*f);
  return std::nullopt;
}

std::string Opt(const std::optional<double>& v) { return v ? Num(*v) : ""; }

// Cells of one sweep, in the order of their values.
std::vector<const StudyCell*> CellsOf(const StudyResult& r, int sweep) {
  std::vector<const StudyCell*> out;
  for (const StudyCell& c : r.cells) {
    if (c.sweep == sweep) out.push_back(&c);
  }
  return out;
}

}  // namespace

std::string StudyCsv(const StudyResult& r) {
  std::ostringstream out;
  out << "sweep,parameter,value,estimator,runs,seed,failed_runs,diverged_runs";
  for (const ErrorStatField& f : ErrorStatFields()) out << ',' << f.name << ',' << f.name << "_std";
  out << ",n_points,pcrb_rmse_m,pcrb_filter_rmse_m,rmse_over_pcrb,error\n";
  for (const StudyCell& c : r.cells) {
    const StudySweep& s = r.manifest.sweeps[c.sweep];
    for (const StudyRow& row : c.rows) {
      out << CsvField(s.name) << ',' << CsvField(s.label) << ',' << CsvField(s.values[c.value])
          << ',' << CsvField(row.estimator) << ',' << c.runs << ',' << c.seed << ','
          << row.failed_runs << ',' << row.diverged_runs;
      for (const ErrorStatField& f : ErrorStatFields()) {
        if (row.status.ok()) {
          out << ',' << Opt(Finite(row.stats.*f.field)) << ','
              << (row.stats_std && c.runs > 1 ? Opt(Finite((*row.stats_std).*f.field)) : "");
        } else {
          out << ",,";
        }
      }
      out << ',' << (row.status.ok() ? std::to_string(row.stats.n_points) : "") << ','
          << Opt(c.pcrb_rmse_m) << ',' << Opt(c.pcrb_filter_rmse_m) << ',' << Opt(RatioOf(c, row))
          << ',' << (row.status.ok() ? "" : CsvField(row.status.message())) << '\n';
    }
  }
  return out.str();
}

std::string StudyTimingCsv(const StudyResult& r) {
  std::ostringstream out;
  out << "sweep,value,estimator,runs,runtime_s,runtime_s_std\n";
  for (const StudyCell& c : r.cells) {
    const StudySweep& s = r.manifest.sweeps[c.sweep];
    for (const StudyRow& row : c.rows) {
      out << CsvField(s.name) << ',' << CsvField(s.values[c.value]) << ','
          << CsvField(row.estimator) << ',' << c.runs << ',' << Num(row.runtime_s) << ','
          << Num(row.runtime_std_s) << '\n';
    }
  }
  return out.str();
}

std::string FormatStudyTable(const StudyResult& r) {
  std::ostringstream out;
  for (size_t k = 0; k < r.manifest.sweeps.size(); ++k) {
    const StudySweep& s = r.manifest.sweeps[k];
    const auto cells = CellsOf(r, static_cast<int>(k));
    std::vector<std::vector<std::string>> rows;
    std::vector<std::string> header = {s.label};
    for (const std::string& id : s.estimators) header.push_back(id);
    const bool pcrb = std::any_of(cells.begin(), cells.end(),
                                  [](const StudyCell* c) { return c->pcrb_rmse_m.has_value(); });
    if (pcrb) header.push_back("pcrb_rmse_m");
    for (const StudyCell* c : cells) {
      std::vector<std::string> row = {s.values[c->value]};
      for (const std::string& id : s.estimators) {
        std::string cell = "-";
        for (const StudyRow& rr : c->rows) {
          if (rr.estimator != id) continue;
          const auto v = MetricOf(*c, rr, s.metric);
          const auto sd = MetricStdOf(*c, rr, s.metric);
          std::ostringstream f;
          f << std::fixed << std::setprecision(3);
          if (v) {
            f << *v;
            if (sd) f << "+-" << *sd;
          } else {
            f << "failed";
          }
          cell = f.str();
        }
        row.push_back(cell);
      }
      if (pcrb) {
        std::ostringstream f;
        f << std::fixed << std::setprecision(3);
        if (c->pcrb_rmse_m) f << *c->pcrb_rmse_m;
        row.push_back(c->pcrb_rmse_m ? f.str() : "-");
      }
      rows.push_back(row);
    }
    std::vector<size_t> width(header.size());
    for (size_t j = 0; j < header.size(); ++j) {
      width[j] = header[j].size();
      for (const auto& row : rows) width[j] = std::max(width[j], row[j].size());
    }
    out << "sweep " << s.name << " (" << s.metric << ", runs " << s.runs << ")"
        << (s.title.empty() ? "" : ": " + s.title) << "\n";
    for (const auto* row : {&header}) {
      for (size_t j = 0; j < row->size(); ++j) {
        out << (j ? "  " : "") << std::setw(static_cast<int>(width[j])) << (*row)[j];
      }
      out << "\n";
    }
    for (const auto& row : rows) {
      for (size_t j = 0; j < row.size(); ++j) {
        out << (j ? "  " : "") << std::setw(static_cast<int>(width[j])) << row[j];
      }
      out << "\n";
    }
    out << "\n";
  }
  return out.str();
}

namespace {

std::string SweepPlot(const StudyResult& r, int k) {
  using report::Axes;
  const StudySweep& s = r.manifest.sweeps[k];
  const auto cells = CellsOf(r, k);
  // Points in ascending x.
  std::vector<const StudyCell*> sorted = cells;
  std::sort(sorted.begin(), sorted.end(),
            [&](const StudyCell* a, const StudyCell* b) { return s.x[a->value] < s.x[b->value]; });
  Axes a{std::numeric_limits<double>::infinity(), -std::numeric_limits<double>::infinity(), 0.0,
         0.0};
  for (const StudyCell* c : sorted) {
    a.x0 = std::min(a.x0, s.x[c->value]);
    a.x1 = std::max(a.x1, s.x[c->value]);
    for (const StudyRow& row : c->rows) {
      const auto v = MetricOf(*c, row, s.metric);
      if (v) a.y1 = std::max(a.y1, *v + MetricStdOf(*c, row, s.metric).value_or(0.0));
    }
    if (s.metric == "rmse_m" && c->pcrb_rmse_m) a.y1 = std::max(a.y1, *c->pcrb_rmse_m);
  }
  if (s.metric == "rmse_over_pcrb") a.y1 = std::max(a.y1, 1.0);
  if (!std::isfinite(a.x0)) a.x0 = a.x1 = 0.0;
  const double pad = 0.05 * (a.x1 - a.x0);
  a.x0 -= pad;
  a.x1 += pad;
  a.y1 *= 1.1;
  // The legend column: a line sample and the longest label (about 6.5 px per character at 11 px).
  size_t longest = std::string("PCRB (smoother)").size();
  for (const std::string& id : s.estimators) longest = std::max(longest, id.size());
  a.legend_w = 44 + 6.5 * static_cast<double>(longest);
  a.w += a.legend_w;
  a.h = std::max(a.h, 2 * a.m + 16 + 15.0 * static_cast<double>(s.estimators.size() + 1));
  a.Fix();
  const std::vector<report::LineStyle> styles = report::AssignStyles(s.estimators);
  std::ostringstream out;
  out << std::fixed << std::setprecision(1);
  out << report::Open(a, "sweep-" + s.name, s.title.empty() ? s.name : s.title, s.label, s.metric);
  for (size_t e = 0; e < s.estimators.size(); ++e) {
    const std::string& id = s.estimators[e];
    std::vector<std::pair<double, double>> pts;
    for (const StudyCell* c : sorted) {
      for (const StudyRow& row : c->rows) {
        if (row.estimator != id) continue;
        const auto v = MetricOf(*c, row, s.metric);
        if (!v) continue;
        pts.emplace_back(s.x[c->value], *v);
        const auto sd = MetricStdOf(*c, row, s.metric);
        if (sd) {
          out << "<line class=\"std-bar\" x1=\"" << a.X(s.x[c->value]) << "\" x2=\""
              << a.X(s.x[c->value]) << "\" y1=\"" << a.Y(*v - *sd) << "\" y2=\"" << a.Y(*v + *sd)
              << "\" stroke=\"" << styles[e].color << "\"/>\n";
        }
        out << "<circle class=\"point\" cx=\"" << a.X(s.x[c->value]) << "\" cy=\"" << a.Y(*v)
            << "\" r=\"3.5\" fill=\"" << styles[e].color << "\"/>\n";
      }
    }
    out << report::Polyline(
        pts.size(), [&](size_t i) { return pts[i]; }, a, styles[e].color, "estimator-curve", 2.0,
        styles[e].dash);
    out << report::LegendEntry(a, e, id, styles[e].color, styles[e].dash);
  }
  std::vector<std::pair<double, double>> bound;
  for (const StudyCell* c : sorted) {
    if (s.metric == "rmse_m" && c->pcrb_rmse_m) bound.emplace_back(s.x[c->value], *c->pcrb_rmse_m);
    if (s.metric == "rmse_over_pcrb" && c->pcrb_rmse_m) bound.emplace_back(s.x[c->value], 1.0);
  }
  if (!bound.empty()) {
    out << report::Polyline(
        bound.size(), [&](size_t i) { return bound[i]; }, a, "#000", "pcrb-curve", 1.5, "6,3");
    out << report::LegendEntry(a, s.estimators.size(), "PCRB (smoother)", "#000", "6,3");
  }
  out << "</svg>\n";
  return out.str();
}

std::string SweepTable(const StudyResult& r, int k) {
  const StudySweep& s = r.manifest.sweeps[k];
  std::ostringstream out;
  out << std::fixed << std::setprecision(3);
  out << "<table class=\"sweep\"><tr><th>" << report::Escape(s.label) << "</th>";
  for (const std::string& id : s.estimators) out << "<th>" << report::Escape(id) << "</th>";
  out << "<th>PCRB [m]</th></tr>\n";
  for (const StudyCell* c : CellsOf(r, k)) {
    out << "<tr><td>" << report::Escape(s.values[c->value]) << "</td>";
    for (const std::string& id : s.estimators) {
      out << "<td>";
      for (const StudyRow& row : c->rows) {
        if (row.estimator != id) continue;
        const auto v = MetricOf(*c, row, s.metric);
        const auto sd = MetricStdOf(*c, row, s.metric);
        if (v) {
          out << *v;
          if (sd) out << " &plusmn; " << *sd;
        } else {
          out << "failed: " << report::Escape(row.status.message());
        }
      }
      out << "</td>";
    }
    out << "<td>";
    if (c->pcrb_rmse_m)
      out << *c->pcrb_rmse_m;
    else
      out << report::Escape(c->pcrb_note.empty() ? "-" : c->pcrb_note);
    out << "</td></tr>\n";
  }
  out << "</table>\n";
  return out.str();
}

}  // namespace

std::string RenderStudyHtml(const StudyResult& r) {
  const StudyManifest& m = r.manifest;
  std::ostringstream s;
  s << "<!DOCTYPE html>\n<html><head><meta charset=\"utf-8\"><title>walkgraph study: "
    << report::Escape(m.name) << "</title>\n<style>body{font-family:sans-serif;margin:16px}"
    << "table{border-collapse:collapse;margin:8px 0}td,th{border:1px solid #ccc;padding:3px 8px;"
    << "text-align:right}svg{margin:4px}</style></head><body>\n";
  s << "<h1>walkgraph study: " << report::Escape(m.name) << "</h1>\n";
  if (!m.description.empty()) s << "<p>" << report::Escape(m.description) << "</p>\n";
  s << "<p>manifest: " << report::Escape(m.path) << "</p>\n";
  for (size_t k = 0; k < m.sweeps.size(); ++k) {
    const StudySweep& sw = m.sweeps[k];
    s << "<h2 id=\"" << report::Escape(sw.name) << "\">" << report::Escape(sw.name)
      << (sw.title.empty() ? "" : ": " + report::Escape(sw.title)) << "</h2>\n";
    s << "<p>"
      << report::Escape(sw.scenario.empty() ? "walk " + sw.walk_dir : "scenario " + sw.scenario)
      << ", " << sw.runs << " run" << (sw.runs == 1 ? "" : "s") << " per value, seed " << sw.seed
      << "; " << report::Escape(sw.metric) << " against " << report::Escape(sw.label) << "</p>\n";
    s << "<div>" << SweepPlot(r, static_cast<int>(k)) << "</div>\n";
    s << SweepTable(r, static_cast<int>(k));
  }
  s << "</body></html>\n";
  return s.str();
}

Status WriteStudy(const StudyResult& r, const std::string& out_dir, const OutputOptions& options) {
  const std::string csv = StudyCsv(r), timing = StudyTimingCsv(r), html = RenderStudyHtml(r);
  return WriteOutputFolder(out_dir, options, [&](const std::string& tmp_dir) {
    const fs::path tmp(tmp_dir);
    for (const auto& file : {std::pair<const char*, const std::string*>{"study.csv", &csv},
                             {"timing.csv", &timing},
                             {"study.html", &html}}) {
      const std::string* text = file.second;  // (clang: lambdas cannot capture bindings)
      WG_RETURN_IF_ERROR(WriteFileInOutput((tmp / file.first).string(), [&](std::ostream& out) {
        out << *text;
        return true;
      }));
    }
    return Status::Ok();
  });
}

}  // namespace walkgraph
