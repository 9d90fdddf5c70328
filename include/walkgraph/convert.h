// Converters from other people's recordings to the walk format.
//
// Each converter is strict like the readers: a malformed source line is reported as
// "file:line: what was expected". Whatever a converter had to repair in the source (reordered
// or duplicate lines) is counted in WalkMeta::extra under "convert.*", never silently.
#ifndef WALKGRAPH_CONVERT_H_
#define WALKGRAPH_CONVERT_H_

#include <functional>
#include <string>
#include <vector>

#include "walkgraph/status.h"
#include "walkgraph/walk.h"

namespace walkgraph {

struct ConverterInfo {
  std::string format;       // "plaza", ...
  std::string description;  // what SRC... must be
  std::function<StatusOr<Walk>(const std::vector<std::string>& sources)> convert;
};

// Every converter shipped with the library.
const std::vector<ConverterInfo>& Converters();

// Runs the converter named `format` on `sources`.
StatusOr<Walk> Convert(const std::string& format, const std::vector<std::string>& sources);

// Plaza1/Plaza2 (Djugash et al., CMU 2009; as shipped in GTSAM's examples/Data): `dir` holds
// <P>_DR.txt (t, Δdistance, Δheading), <P>_TD.txt (t, sender, anchor, range), <P>_anchors.csv
// and optionally <P>_GT.csv (t_s, x_m, y_m, heading_rad). The start pose is taken from the first
// ground-truth sample (as GTSAM's Plaza example does).
StatusOr<Walk> ConvertPlaza(const std::string& dir);

// PyShoe VICON set (Wagstaff et al.; CSV with header t_s, ax/ay/az_mps2, gx/gy/gz_radps,
// gt_x/y/z_m, zv_vicon): a foot-mounted 200 Hz IMU → imu.csv, the Vicon foot position → truth
// (continuous, with z), zv_vicon → stance_truth. Time must increase; zv_vicon must be 0 or 1.
StatusOr<Walk> ConvertPyshoe(const std::string& csv_path);

}  // namespace walkgraph

#endif  // WALKGRAPH_CONVERT_H_
