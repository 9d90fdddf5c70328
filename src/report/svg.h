// Inline-SVG building blocks shared by the HTML pages (compare's report.html, study.html).
// Internal: not installed.
#ifndef WALKGRAPH_SRC_REPORT_SVG_H_
#define WALKGRAPH_SRC_REPORT_SVG_H_

#include <algorithm>
#include <cmath>
#include <iomanip>
#include <sstream>
#include <string>
#include <vector>

namespace walkgraph::report {

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

// Round tick values covering [lo, hi]: multiples of a step of 1, 2 or 5 × 10^k chosen so that
// about `target` ticks fall in the range (Heckbert's "nice numbers", Graphics Gems 1990).
struct Ticks {
  std::vector<double> values;
  int decimals = 0;  // enough to print the step exactly
};
inline Ticks NiceTicks(double lo, double hi, int target = 5) {
  Ticks t;
  const double span = hi - lo;
  if (!(span > 0.0) || !std::isfinite(span)) {
    t.values.push_back(lo);
    return t;
  }
  const double raw = span / target;
  const double mag = std::pow(10.0, std::floor(std::log10(raw)));
  const double f = raw / mag;
  const double step = (f < 1.5 ? 1.0 : f < 3.0 ? 2.0 : f < 7.0 ? 5.0 : 10.0) * mag;
  const double first = std::ceil(lo / step - 1e-9), last = std::floor(hi / step + 1e-9);
  for (double k = first; k <= last; k += 1.0) t.values.push_back(k == 0.0 ? 0.0 : k * step);
  t.decimals = std::clamp(static_cast<int>(-std::floor(std::log10(step) + 1e-9)), 0, 9);
  return t;
}

// Maps data coordinates to an SVG viewport: margin m around the plot area, and a legend column
// of legend_w px right of it (outside the data).
struct Axes {
  double x0, x1, y0, y1;  // data range
  double w = 640, h = 420, m = 48;
  double legend_w = 0;
  bool equal_aspect = false;

  double PlotW() const { return w - 2 * m - legend_w; }
  double PlotH() const { return h - 2 * m; }
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
      const double sx = (x1 - x0) / PlotW(), sy = (y1 - y0) / PlotH();
      const double s = std::max(sx, sy);
      const double cx = 0.5 * (x0 + x1), cy = 0.5 * (y0 + y1);
      x0 = cx - s * PlotW() / 2;
      x1 = cx + s * PlotW() / 2;
      y0 = cy - s * PlotH() / 2;
      y1 = cy + s * PlotH() / 2;
    }
  }
  double X(double x) const { return m + (x - x0) / (x1 - x0) * PlotW(); }
  double Y(double y) const { return h - m - (y - y0) / (y1 - y0) * PlotH(); }
};

// The frame, title, axis labels and round ticks of a plot.
inline std::string Open(const Axes& a, const std::string& id, const std::string& title,
                        const std::string& xlabel, const std::string& ylabel) {
  std::ostringstream s;
  s << std::fixed << std::setprecision(1);
  s << "<svg id=\"" << id << "\" class=\"plot\" xmlns=\"http://www.w3.org/2000/svg\" width=\""
    << a.w << "\" height=\"" << a.h << "\" viewBox=\"0 0 " << a.w << ' ' << a.h << "\">\n";
  s << "<rect x=\"0\" y=\"0\" width=\"" << a.w << "\" height=\"" << a.h << "\" fill=\"white\"/>\n";
  s << "<rect class=\"plot-area\" x=\"" << a.m << "\" y=\"" << a.m << "\" width=\"" << a.PlotW()
    << "\" height=\"" << a.PlotH() << "\" fill=\"none\" stroke=\"#444\"/>\n";
  const double cx = a.m + a.PlotW() / 2;
  s << "<text x=\"" << cx << "\" y=\"20\" text-anchor=\"middle\" font-size=\"15\">" << Escape(title)
    << "</text>\n";
  s << "<text x=\"" << cx << "\" y=\"" << a.h - 8 << "\" text-anchor=\"middle\" font-size=\"12\">"
    << Escape(xlabel) << "</text>\n";
  s << "<text x=\"14\" y=\"" << a.h / 2 << "\" text-anchor=\"middle\" font-size=\"12\" "
    << "transform=\"rotate(-90 14 " << a.h / 2 << ")\">" << Escape(ylabel) << "</text>\n";
  const Ticks tx = NiceTicks(a.x0, a.x1), ty = NiceTicks(a.y0, a.y1);
  for (double xv : tx.values) {
    s << std::setprecision(1) << "<text x=\"" << a.X(xv) << "\" y=\"" << a.h - a.m + 14
      << "\" text-anchor=\"middle\" font-size=\"10\">" << std::setprecision(tx.decimals) << xv
      << "</text>";
  }
  for (double yv : ty.values) {
    s << std::setprecision(1) << "<text x=\"" << a.m - 4 << "\" y=\"" << a.Y(yv) + 3
      << "\" text-anchor=\"end\" font-size=\"10\">" << std::setprecision(ty.decimals) << yv
      << "</text>\n";
  }
  s << std::setprecision(1);
  return s.str();
}

// One legend entry in the legend column (entry i from the top): a line sample and the label.
inline std::string LegendEntry(const Axes& a, size_t i, const std::string& label,
                               const std::string& color, const std::string& dash) {
  std::ostringstream s;
  s << std::fixed << std::setprecision(1);
  const double x = a.w - a.m - a.legend_w + 10, y = a.m + 8 + 15.0 * i;
  s << "<g class=\"legend\"><line x1=\"" << x << "\" x2=\"" << x + 22 << "\" y1=\"" << y
    << "\" y2=\"" << y << "\" stroke=\"" << color << "\" stroke-width=\"2\"";
  if (!dash.empty()) s << " stroke-dasharray=\"" << dash << "\"";
  s << "/><text x=\"" << x + 28 << "\" y=\"" << y + 4 << "\" font-size=\"11\">" << Escape(label)
    << "</text></g>\n";
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
