// Range measurements as the range-based filters consume them (003, 004; 001's SCMT detector
// also reads the raw RSS). RSS readings become ranges through the shared PathLossModel:
//   d̂ = d0·10^(s·(A − RSS)/(10η))  (001 eq. 14, 004 eq. 5),  σ_r = σ·ln10·d̂/(10η)  (004 eq. 7);
// optionally divided by e^{σ_d²/2} (001 eq. 17). Measured ranges (range.csv) keep the walk's
// range_sigma_m. The residual used by the filters is r − ‖p − a‖ with p the 3-D position
// (z = tag height) and a the anchor.
#ifndef WALKGRAPH_FILTERS_RANGES_H_
#define WALKGRAPH_FILTERS_RANGES_H_

#include <vector>

#include <Eigen/Core>

#include "walkgraph/status.h"
#include "walkgraph/walk.h"

namespace walkgraph {

struct RangeMeasurement {
  double t_s = 0.0;
  int anchor_id = 0;
  Eigen::Vector3d anchor_m = Eigen::Vector3d::Zero();
  double range_m = 0.0;
  double sigma_m = 1.0;
  bool from_rss = false;
  double rss = 0.0;  // the reading, when from_rss
};

struct RangeConversionOptions {
  bool bias_corrected = false;  // divide ML ranges by e^{σ_d²/2} (001 eq. 17)
  double min_sigma_m = 0.1;     // floor on σ_r (eq. 7 vanishes at d → 0)
};

// Every RSS and range sample of `walk`, in time order. Unknown anchor ids are an error.
StatusOr<std::vector<RangeMeasurement>> RangeMeasurementsFromWalk(
    const Walk& walk, const RangeConversionOptions& options = {});

}  // namespace walkgraph

#endif  // WALKGRAPH_FILTERS_RANGES_H_
