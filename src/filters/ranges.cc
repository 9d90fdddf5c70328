#include "walkgraph/filters/ranges.h"

#include <algorithm>
#include <string>

#include "walkgraph/path_loss.h"

namespace walkgraph {

StatusOr<std::vector<RangeMeasurement>> RangeMeasurementsFromWalk(
    const Walk& walk, const RangeConversionOptions& options) {
  std::vector<RangeMeasurement> out;
  const PathLossModel model(walk.meta.radio.path_loss, walk.meta.radio.units);
  for (const RssSample& s : walk.rss) {
    const int i = walk.AnchorIndex(s.anchor_id);
    if (i < 0)
      return InvalidArgument("rss sample names unknown anchor " + std::to_string(s.anchor_id));
    RangeMeasurement m;
    m.t_s = s.t_s;
    m.anchor_id = s.anchor_id;
    m.anchor_m = walk.anchors[i].position_m;
    m.range_m = options.bias_corrected ? model.BiasCorrectedRange(s.rss) : model.MlRange(s.rss);
    m.sigma_m = std::max(model.RangeSigma(m.range_m), options.min_sigma_m);  // 004 eq. 7
    m.from_rss = true;
    m.rss = s.rss;
    out.push_back(m);
  }
  for (const RangeSample& s : walk.ranges) {
    const int i = walk.AnchorIndex(s.anchor_id);
    if (i < 0) {
      return InvalidArgument("range sample names unknown anchor " + std::to_string(s.anchor_id));
    }
    RangeMeasurement m;
    m.t_s = s.t_s;
    m.anchor_id = s.anchor_id;
    m.anchor_m = walk.anchors[i].position_m;
    m.range_m = s.range_m;
    m.sigma_m = std::max(walk.meta.radio.range_sigma_m, options.min_sigma_m);
    out.push_back(m);
  }
  std::stable_sort(
      out.begin(), out.end(),
      [](const RangeMeasurement& a, const RangeMeasurement& b) { return a.t_s < b.t_s; });
  return out;
}

}  // namespace walkgraph
