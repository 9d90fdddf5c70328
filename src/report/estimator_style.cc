#include "report/estimator_style.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <set>

namespace walkgraph::report {

namespace {

constexpr double kLightness[] = {0.38, 0.55, 0.27, 0.47, 0.64, 0.33};
const char* const kDashes[] = {"", "7,3", "2,2", "9,3,2,3"};

bool StartsWith(const std::string& s, const char* prefix) { return s.rfind(prefix, 0) == 0; }

}  // namespace

const std::vector<EstimatorFamily>& EstimatorFamilies() {
  static const std::vector<EstimatorFamily> families = {
      {"fg", "factor graph (walkgraph)", 215, 0.75},
      {"tarrio", "Tarr&iacute;o et al. 2011 (000)", 28, 0.90},
      {"correa", "Correa et al. 2017 (001)", 125, 0.60},
      {"prieto", "Prieto et al. 2012 (002)", 280, 0.55},
      {"gadeke", "G&auml;deke et al. 2012 (003)", 180, 0.70},
      {"jimenez", "Jim&eacute;nez et al. 2012 (004)", 355, 0.75},
      {"baseline", "baselines and other references", 35, 0.22},
  };
  return families;
}

size_t FamilyOf(const std::string& id) {
  const auto& families = EstimatorFamilies();
  for (size_t f = 0; f + 1 < families.size(); ++f) {
    if (StartsWith(id, families[f].key) && id.size() > std::string(families[f].key).size() &&
        id[std::string(families[f].key).size()] == '-') {
      return f;
    }
  }
  return families.size() - 1;
}

std::string HslToHex(double hue_deg, double saturation, double lightness) {
  const double h = std::fmod(std::fmod(hue_deg, 360.0) + 360.0, 360.0) / 60.0;
  const double c = (1.0 - std::abs(2.0 * lightness - 1.0)) * saturation;
  const double x = c * (1.0 - std::abs(std::fmod(h, 2.0) - 1.0));
  double r = 0, g = 0, b = 0;
  switch (static_cast<int>(h)) {
    case 0:
      r = c, g = x;
      break;
    case 1:
      r = x, g = c;
      break;
    case 2:
      g = c, b = x;
      break;
    case 3:
      g = x, b = c;
      break;
    case 4:
      r = x, b = c;
      break;
    default:
      r = c, b = x;
      break;
  }
  const double m = lightness - c / 2.0;
  auto byte = [&](double v) {
    return static_cast<int>(std::lround(std::clamp(v + m, 0.0, 1.0) * 255.0));
  };
  char out[8];
  std::snprintf(out, sizeof out, "#%02x%02x%02x", byte(r), byte(g), byte(b));
  return out;
}

std::vector<LineStyle> AssignStyles(const std::vector<std::string>& ids) {
  const auto& families = EstimatorFamilies();
  std::vector<int> count(families.size(), 0);
  std::set<std::string> taken;
  std::vector<LineStyle> out;
  for (const std::string& id : ids) {
    LineStyle s;
    s.family = FamilyOf(id);
    const int k = count[s.family]++;
    const EstimatorFamily& f = families[s.family];
    const int cycle = k / static_cast<int>(std::size(kLightness));
    const double hue = f.hue_deg + 10.0 * ((cycle + 1) / 2) * (cycle % 2 == 1 ? 1 : -1);
    double lightness = kLightness[k % std::size(kLightness)];
    s.color = HslToHex(hue, f.saturation, lightness);
    double shifted_hue = hue;
    for (int step = 0; taken.count(s.color) != 0 && step < 1000; ++step) {
      lightness -= 0.01;
      if (lightness < 0.15) {  // every lightness taken at this hue: move the hue a little
        lightness = 0.75;
        shifted_hue += 7.0;
      }
      s.color = HslToHex(shifted_hue, f.saturation, lightness);
    }
    taken.insert(s.color);
    s.dash = kDashes[k % std::size(kDashes)];
    out.push_back(std::move(s));
  }
  return out;
}

}  // namespace walkgraph::report
