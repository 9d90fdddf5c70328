// The self-contained report page (report.html): the results table as HTML, the plotted series
// as one JSON block, and a small hand-written script (report_script.h) that draws the plots as
// inline SVG, sorts the table, toggles and highlights estimators and zooms the trajectories.
// No library and no network: the file opens offline, stays small and is the same bytes for the
// same comparison (only the runtime column differs from run to run).
//
// What is plotted is decimated, not every point: a curve keeps every k-th point and its last,
// k = ceil(n / kMaxCurvePoints); the error CDF is drawn from 101 percentiles; covariance
// ellipses are drawn at every k-th pose with a covariance, at most kMaxEllipses. The figures in
// the table are computed from every point.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <sstream>

#include <Eigen/Eigenvalues>

#include "report/estimator_style.h"
#include "report/report_script.h"
#include "report/report_table.h"
#include "report/svg.h"
#include "walkgraph/compare.h"

namespace walkgraph {

namespace {

using report::Escape;
using report::LineStyle;

constexpr size_t kMaxCurvePoints = 500;
constexpr size_t kMaxTruthPoints = 1500;
constexpr size_t kMaxEllipses = 30;

// A number for the JSON block: `decimals` after the point, "null" when not finite.
std::string Num(double v, int decimals) {
  if (!std::isfinite(v)) return "null";
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.*f", decimals, v);
  std::string s = buf;
  if (s.find('.') != std::string::npos) {  // 1.500 -> 1.5, 2.000 -> 2
    s.erase(s.find_last_not_of('0') + 1);
    if (s.back() == '.') s.pop_back();
  }
  return s == "-0" ? "0" : s;
}

// A JSON string; '<' escaped so that the text cannot close the <script> element it sits in.
std::string JsonString(const std::string& v) {
  std::string o = "\"";
  for (char ch : v) {
    if (ch == '"' || ch == '\\') {
      o += '\\';
      o += ch;
    } else if (ch == '<') {
      o += "\\u003c";
    } else if (static_cast<unsigned char>(ch) < 0x20) {
      o += ' ';
    } else {
      o += ch;
    }
  }
  return o + "\"";
}

// Three significant digits (NEES spans decades).
std::string Sig(double v) {
  if (!std::isfinite(v)) return "null";
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.3g", v);
  return buf;
}

// Indices 0, k, 2k, ... and n - 1, k = ceil(n / max).
std::vector<size_t> Decimated(size_t n, size_t max) {
  std::vector<size_t> out;
  const size_t k = std::max<size_t>(1, (n + max - 1) / max);
  for (size_t i = 0; i < n; i += k) out.push_back(i);
  if (n > 0 && out.back() != n - 1) out.push_back(n - 1);
  return out;
}

// The error percentile p (0..100) of an outcome: from the sketch of every error when there is
// one (Monte Carlo, compact), else from its series.
class ErrorQuantiles {
 public:
  explicit ErrorQuantiles(const EstimatorOutcome& o) : o_(o) {
    if (!o.pooled_errors) {
      sorted_ = o.errors.error_m;
      std::sort(sorted_.begin(), sorted_.end());
    }
  }
  double operator()(double p) const {
    if (o_.pooled_errors) return o_.pooled_errors->Percentile(p);
    if (sorted_.empty()) return std::nan("");
    const double r = p / 100.0 * static_cast<double>(sorted_.size() - 1);
    const size_t i = static_cast<size_t>(std::floor(r));
    const size_t j = std::min(i + 1, sorted_.size() - 1);
    return sorted_[i] + (r - static_cast<double>(i)) * (sorted_[j] - sorted_[i]);
  }

 private:
  const EstimatorOutcome& o_;
  std::vector<double> sorted_;
};

// 2σ ellipses [x, y, rx, ry, angle_deg] at every k-th pose with a position covariance.
std::string EllipsesJson(const Trajectory& traj) {
  std::vector<size_t> with_cov;
  for (size_t i = 0; i < traj.points.size(); ++i) {
    if (traj.points[i].covariance) with_cov.push_back(i);
  }
  std::ostringstream s;
  const char* sep = "";
  for (size_t k : Decimated(with_cov.size(), kMaxEllipses)) {
    const TrajectoryPoint& p = traj.points[with_cov[k]];
    const Eigen::Matrix2d cov = p.covariance->topLeftCorner<2, 2>();
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> eig(cov);
    if (eig.info() != Eigen::Success || !(eig.eigenvalues()(0) >= 0.0)) continue;
    const Eigen::Vector2d major = eig.eigenvectors().col(1);
    s << sep << Num(p.position_m.x(), 2) << ',' << Num(p.position_m.y(), 2) << ','
      << Num(2.0 * std::sqrt(eig.eigenvalues()(1)), 3) << ','
      << Num(2.0 * std::sqrt(eig.eigenvalues()(0)), 3) << ','
      << Num(std::atan2(major.y(), major.x()) * 180.0 / M_PI, 1);
    sep = ",";
  }
  return s.str();
}

// Error points [t, distance, error, x, y] (the estimate's position at t, for the APE map) and
// NEES points [t, nees].
void SeriesJson(const EstimatorOutcome& o, std::ostringstream& s) {
  const ErrorSeries& e = o.errors;
  const Trajectory& traj = o.result.trajectory;
  s << ",\"er\":[";
  const char* sep = "";
  for (size_t i : Decimated(e.t_s.size(), kMaxCurvePoints)) {
    const double d = i < e.distance_m.size() ? e.distance_m[i] : std::nan("");
    const Eigen::Vector3d p = traj.empty() ? Eigen::Vector3d::Zero() : traj.PositionAt(e.t_s[i]);
    s << sep << Num(e.t_s[i], 2) << ',' << Num(d, 2) << ',' << Num(e.error_m[i], 3) << ','
      << Num(p.x(), 2) << ',' << Num(p.y(), 2);
    sep = ",";
  }
  s << "],\"ne\":[";
  sep = "";
  if (e.nees.size() == e.t_s.size()) {
    for (size_t i : Decimated(e.nees.size(), kMaxCurvePoints)) {
      s << sep << Num(e.t_s[i], 2) << ',' << Sig(e.nees[i]);
      sep = ",";
    }
  }
  s << "]";
}

std::string EstimatorJson(const EstimatorOutcome& o, const LineStyle& style) {
  std::ostringstream s;
  s << "{\"id\":" << JsonString(o.id) << ",\"f\":" << style.family << ",\"c\":\"" << style.color
    << "\",\"d\":\"" << style.dash << "\",\"tr\":[";
  const auto& pts = o.result.trajectory.points;
  const char* sep = "";
  for (size_t i : Decimated(pts.size(), kMaxCurvePoints)) {
    s << sep << Num(pts[i].position_m.x(), 2) << ',' << Num(pts[i].position_m.y(), 2);
    sep = ",";
  }
  s << "]";
  SeriesJson(o, s);
  const ErrorQuantiles q(o);
  s << ",\"q\":[";
  for (int p = 0; p <= 100; ++p) s << (p ? "," : "") << Num(q(p), 3);
  s << "],\"el\":[" << EllipsesJson(o.result.trajectory) << "]";
  s << ",\"rmse\":" << Num(o.stats.rmse_m, 3);
  if (!o.run_rmse_m.empty()) {
    s << ",\"runs\":[";
    for (size_t i = 0; i < o.run_rmse_m.size(); ++i) {
      s << (i ? "," : "") << Num(o.run_rmse_m[i], 3);
    }
    s << "]";
  }
  s << "}";
  return s.str();
}

std::string DataJson(const Comparison& c, const std::vector<LineStyle>& styles) {
  std::ostringstream s;
  s << "{\"walk\":" << JsonString(c.walk_name) << ",\"runs\":" << c.runs
    << ",\"checkpoints\":" << (c.truth_kind == TruthKind::kCheckpoints ? "true" : "false")
    << ",\"families\":[";
  const auto& families = report::EstimatorFamilies();
  for (size_t f = 0; f < families.size(); ++f) {
    s << (f ? "," : "") << JsonString(families[f].label);
  }
  s << "],\"truth\":[";
  const size_t max_truth =
      c.truth_kind == TruthKind::kCheckpoints ? c.truth.size() + 1 : kMaxTruthPoints;
  const char* sep = "";
  for (size_t i : Decimated(c.truth.size(), max_truth)) {
    s << sep << Num(c.truth[i].position_m.x(), 2) << ',' << Num(c.truth[i].position_m.y(), 2);
    sep = ",";
  }
  s << "],\"anchors\":[";
  const char* anchor_sep = "";
  for (const Anchor& a : c.anchors) {
    if (!a.position_known) continue;  // nowhere to draw it
    s << anchor_sep << "[" << a.id << ',' << Num(a.position_m.x(), 2) << ','
      << Num(a.position_m.y(), 2) << "]";
    anchor_sep = ",";
  }
  s << "],\"pcrb\":";
  if (!c.pcrb_t_s.empty() && c.pcrb_smoother_m.size() == c.pcrb_t_s.size()) {
    s << "{\"rmse\":" << (c.pcrb_rmse_m ? Num(*c.pcrb_rmse_m, 3) : "null") << ",\"ts\":[";
    sep = "";
    for (size_t i : Decimated(c.pcrb_t_s.size(), kMaxCurvePoints)) {
      s << sep << Num(c.pcrb_t_s[i], 2) << ',' << Num(c.pcrb_smoother_m[i], 3) << ','
        << (i < c.pcrb_filter_m.size() ? Num(c.pcrb_filter_m[i], 3) : "null");
      sep = ",";
    }
    s << "]}";
  } else {
    s << "null";
  }
  s << ",\"est\":[";
  sep = "";
  for (size_t k = 0; k < c.outcomes.size(); ++k) {
    if (!c.outcomes[k].Ranked()) continue;
    s << sep << "\n" << EstimatorJson(c.outcomes[k], styles[k]);
    sep = ",";
  }
  s << "]}";
  return s.str();
}

// What the walk holds that is unusual but accepted, and an estimate's frame that nothing ties
// to the truth's (Comparison::warnings), under the table; empty when there is none.
std::string WarningsHtml(const Comparison& c) {
  if (c.warnings.empty()) return "";
  std::ostringstream s;
  s << "<div id=\"warnings\" class=\"warn\"><b>Warnings</b> (" << c.warning_count << ")<ul>\n";
  for (const std::string& w : c.warnings) s << "<li>" << Escape(w) << "</li>\n";
  const int more = c.warning_count - static_cast<int>(c.warnings.size());
  if (more > 0) s << "<li>and " << more << " more (counted in results.json)</li>\n";
  s << "</ul></div>\n";
  return s.str();
}

}  // namespace

std::string RenderHtmlReport(const Comparison& c) {
  std::vector<std::string> ids;
  for (const EstimatorOutcome& o : c.outcomes) ids.push_back(o.id);
  const std::vector<LineStyle> styles = report::AssignStyles(ids);
  std::ostringstream s;
  s << "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">\n<title>walkgraph: "
    << Escape(c.walk_name) << "</title>\n<style>" << report::kReportCss
    << "</style></head>\n<body>\n";
  s << "<h1>walkgraph comparison: " << Escape(c.walk_name) << "</h1>\n";
  s << report::ResultsTableHtml(c, styles);
  s << WarningsHtml(c);
  s << report::kReportBody;
  // The series as JSON ("<" is escaped in its strings, the rest are numbers).
  s << "<script type=\"application/json\" id=\"wg-data\">" << DataJson(c, styles)
    << "</script>\n<script>" << report::kReportJs << "</script>\n</body></html>\n";
  return s.str();
}

}  // namespace walkgraph
