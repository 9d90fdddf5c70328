// Inline-SVG building blocks shared by the HTML pages (compare's report.html, study.html).
// Internal: not installed.
#ifndef WALKGRAPH_SRC_REPORT_SVG_H_
#define WALKGRAPH_SRC_REPORT_SVG_H_

#include <algorithm>
#include <cmath>
#include <iomanip>
#include <sstream>
#include <string>

namespace walkgraph::report {

inline const char* const kPalette[] = {"#1f77b4", "#d62728", "#2ca02c", "#ff7f0e", "#9467bd",
                                       "#8c564b", "#e377c2", "#17becf", "#bcbd22", "#7f7f7f"};

inline const char* Color(size_t i) { return kPalette[i % std::size(kPalette)]; }

inline std::string Escape(const std::string& s) {
  std::string o;
  for (char ch : s) {
    switch (ch) {
      case '<':
        o += "&lt;";
        break;
      case '>':
        o += "&gt;";
        break;
      case '&':
        o += "&amp;";
        break;
      case '"':
        o += "&quot;";
        break;
      default:
        o += ch;
    }
  }
  return o;
}

// Maps data coordinates to an SVG viewport with margins.
struct Axes {
  double x0, x1, y0, y1;  // data range
  double w = 640, h = 420, m = 48;
  bool equal_aspect = false;

  void Fix() {
    if (!(x1 > x0)) {
      x0 -= 1;
      x1 += 1;
    }
    if (!(y1 > y0)) {
      y0 -= 1;
      y1 += 1;
    }
    if (equal_aspect) {
      const double sx = (x1 - x0) / (w - 2 * m), sy = (y1 - y0) / (h - 2 * m);
      const double s = std::max(sx, sy);
      const double cx = 0.5 * (x0 + x1), cy = 0.5 * (y0 + y1);
      x0 = cx - s * (w - 2 * m) / 2;
      x1 = cx + s * (w - 2 * m) / 2;
      y0 = cy - s * (h - 2 * m) / 2;
      y1 = cy + s * (h - 2 * m) / 2;
    }
  }
  double X(double x) const { return m + (x - x0) / (x1 - x0) * (w - 2 * m); }
  double Y(double y) const { return h - m - (y - y0) / (y1 - y0) * (h - 2 * m); }
};

inline std::string Open(const Axes& a, const std::string& id, const std::string& title,
                        const std::string& xlabel, const std::string& ylabel) {
  std::ostringstream s;
  s << std::fixed << std::setprecision(1);
  s << "<svg id=\"" << id << "\" class=\"plot\" xmlns=\"http://www.w3.org/2000/svg\" width=\""
    << a.w << "\" height=\"" << a.h << "\" viewBox=\"0 0 " << a.w << ' ' << a.h << "\">\n";
  s << "<rect x=\"0\" y=\"0\" width=\"" << a.w << "\" height=\"" << a.h << "\" fill=\"white\"/>\n";
  s << "<rect x=\"" << a.m << "\" y=\"" << a.m << "\" width=\"" << a.w - 2 * a.m << "\" height=\""
    << a.h - 2 * a.m << "\" fill=\"none\" stroke=\"#444\"/>\n";
  s << "<text x=\"" << a.w / 2 << "\" y=\"20\" text-anchor=\"middle\" font-size=\"15\">"
    << Escape(title) << "</text>\n";
  s << "<text x=\"" << a.w / 2 << "\" y=\"" << a.h - 8
    << "\" text-anchor=\"middle\" font-size=\"12\">" << Escape(xlabel) << "</text>\n";
  s << "<text x=\"14\" y=\"" << a.h / 2 << "\" text-anchor=\"middle\" font-size=\"12\" "
    << "transform=\"rotate(-90 14 " << a.h / 2 << ")\">" << Escape(ylabel) << "</text>\n";
  // Enough decimals to tell the ticks (a quarter of the range) apart.
  auto decimals = [](double span) {
    const double step = span / 4.0;
    if (!(step > 0.0)) return 1;
    return std::clamp(static_cast<int>(std::ceil(-std::log10(step))) + 1, 0, 6);
  };
  const int dx = decimals(a.x1 - a.x0), dy = decimals(a.y1 - a.y0);
  for (int i = 0; i <= 4; ++i) {
    const double xv = a.x0 + (a.x1 - a.x0) * i / 4.0, yv = a.y0 + (a.y1 - a.y0) * i / 4.0;
    s << std::setprecision(1) << "<text x=\"" << a.X(xv) << "\" y=\"" << a.h - a.m + 14
      << "\" text-anchor=\"middle\" font-size=\"10\">" << std::setprecision(dx) << xv << "</text>";
    s << std::setprecision(1) << "<text x=\"" << a.m - 4 << "\" y=\"" << a.Y(yv) + 3
      << "\" text-anchor=\"end\" font-size=\"10\">" << std::setprecision(dy) << yv << "</text>\n";
  }
  s << std::setprecision(1);
  return s.str();
}

template <typename Get>
std::string Polyline(size_t n, Get get, const Axes& a, const std::string& color,
                     const std::string& cls, double width = 1.5, const std::string& dash = "") {
  std::ostringstream s;
  s << std::fixed << std::setprecision(1);
  s << "<polyline class=\"" << cls << "\" fill=\"none\" stroke=\"" << color << "\" stroke-width=\""
    << width << "\"";
  if (!dash.empty()) s << " stroke-dasharray=\"" << dash << "\"";
  s << " points=\"";
  const size_t stride = std::max<size_t>(1, n / 2000);  // keep the file small
  for (size_t i = 0; i < n; i += stride) {
    const auto [x, y] = get(i);
    s << a.X(x) << ',' << a.Y(y) << ' ';
  }
  if (n > 0 && (n - 1) % stride != 0) {
    const auto [x, y] = get(n - 1);
    s << a.X(x) << ',' << a.Y(y);
  }
  s << "\"/>\n";
  return s.str();
}

}  // namespace walkgraph::report

#endif  // WALKGRAPH_SRC_REPORT_SVG_H_
