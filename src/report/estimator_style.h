// How the report tells estimators apart (internal): a family per id, and per estimator a colour
// and a dash pattern. Families share a hue band and differ in lightness, hue offset and dash:
//   factor graph (fg-*) blue · Tarrío 2011 (tarrio-*) orange · Correa 2017 (correa-*) green ·
//   Prieto 2012 (prieto-*) purple · Gädeke 2012 (gadeke-*) teal · Jiménez 2012 (jimenez-*) red ·
//   baselines (everything else: pdr-only, rss-only, rss-pdr-reset, odometry-dr, zupt-ins, and
//   estimators a user registers) brown-grey.
// Shade k of a family: lightness kLightness[k % 6], hue shifted by 10° per further cycle of six,
// dash kDashes[k % 4]. Colours are distinct for any number of estimators: a colour already
// taken is darkened by 1 % lightness steps until it is free.
#ifndef WALKGRAPH_SRC_REPORT_ESTIMATOR_STYLE_H_
#define WALKGRAPH_SRC_REPORT_ESTIMATOR_STYLE_H_

#include <string>
#include <vector>

namespace walkgraph::report {

struct EstimatorFamily {
  const char* key;    // stable, for CSS and the DOM ("fg", "tarrio", ..., "baseline")
  const char* label;  // shown in the table
  double hue_deg, saturation;
};

// The families in display order.
const std::vector<EstimatorFamily>& EstimatorFamilies();

// Index into EstimatorFamilies() of an estimator id.
size_t FamilyOf(const std::string& id);

struct LineStyle {
  size_t family = 0;
  std::string color;  // "#rrggbb"
  std::string dash;   // SVG stroke-dasharray; empty = solid
};

// Styles for `ids` (in order): the k-th id of a family gets its family's shade k.
std::vector<LineStyle> AssignStyles(const std::vector<std::string>& ids);

// "#rrggbb" of an HSL colour (hue in degrees, saturation and lightness in [0, 1]).
std::string HslToHex(double hue_deg, double saturation, double lightness);

}  // namespace walkgraph::report

#endif  // WALKGRAPH_SRC_REPORT_ESTIMATOR_STYLE_H_
