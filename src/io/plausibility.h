// Physical plausibility of single readings (internal): one set of rules for the walk readers,
// ValidateWalk and the converters, and the converters' record of what they had to drop.
#ifndef WALKGRAPH_SRC_IO_PLAUSIBILITY_H_
#define WALKGRAPH_SRC_IO_PLAUSIBILITY_H_

#include <map>
#include <string>
#include <utility>
#include <vector>

#include "walkgraph/io.h"
#include "walkgraph/status.h"
#include "walkgraph/walk.h"

namespace walkgraph::internal {

// "" when the reading is plausible under `limits`, else what is wrong with it.
std::string CheckImu(const ImuSample& s, const ValidationLimits& limits);
std::string CheckRss(const RssSample& s, RssUnits units, const ValidationLimits& limits);
std::string CheckRange(const RangeSample& s, const ValidationLimits& limits);

// A Bluetooth LE RSSI in dBm ("" when plausible): below 0 dBm (a BLE transmitter sends at most
// +20 dBm and loses about 40 dB in its first metre; 0 is iOS's "unknown").
std::string CheckBleRss(double rss_dbm);

// A converter's check of one column over a whole file: a column where more than half of the
// lines fail a per-line rule holds something else (two columns swapped), which a reading at a
// time cannot tell from a few bad readings. Check() then refuses the file, naming the first
// failing line, the column and what was expected.
class ColumnCheck {
 public:
  // `column`: e.g. "field 4 (RSS)"; `expected`: e.g. "a negative RSSI in dBm".
  ColumnCheck(std::string column, std::string expected)
      : column_(std::move(column)), expected_(std::move(expected)) {}
  // One line: whether it passed the rule; `where` ("file:line: ") and `value` (as text) are
  // kept for the first failure.
  void Add(bool ok, const std::string& where, const std::string& value);
  // InvalidArgument when more than half of the lines failed; else OK.
  Status Check(const std::string& layout) const;

 private:
  std::string column_, expected_, first_where_, first_value_;
  long long lines_ = 0, failed_ = 0;
};

// Path-loss parameters within physical reason ("" when they are): A_dbm within the RSS limits
// (RFCode units: [0, 300]), eta in (0, 10], sigma_db in [0.001, 50] dB, d0_m in [0.01, 100] m.
// For walk.yaml's radio, converters' defaults and fit-path-loss's results alike.
std::string CheckPathLoss(const PathLossParams& p, RssUnits units, const ValidationLimits& limits);
// walk.yaml's radio: the path loss above and range_sigma_m in [0.001, 1000] m.
std::string CheckRadioDefaults(const RadioDefaults& r, const ValidationLimits& limits);
// walk.yaml's initial_pose: coordinates within limits.max_abs_coordinate_m, heading_rad within
// [-2π, 2π] (radians, not degrees), sigma_xy_m in [1e-6, 1e4] m, sigma_heading_rad in
// [1e-6, 2π] rad (the simulator's exactly known heading is 1e-6).
std::string CheckInitialPose(const InitialPose& p, const ValidationLimits& limits);

// Rules across a walk's streams ("" when they hold; streams named as files with `as_files`):
// the IMU's (and odometry's) time span overlaps the radio's; not every range is 0 m; RFCode
// readings are not all negative (dBm-like); with radio readings, the truth, waypoints and
// start lie within 100 km of the anchors (one frame); waypoints lie within the walk's time span
// (1 s tolerance).
std::string CheckStreamSpans(const Walk& walk, bool as_files);

// A converter meets a physically impossible reading in someone else's recording (a corrupted
// RSSI of +42 dBm, an accelerometer spike past its range): it drops the reading and goes on,
// counting it per stream; with `strict` it refuses the recording instead.
class DroppedReadings {
 public:
  explicit DroppedReadings(bool strict) : strict_(strict) {}
  // `problem` from the checks above ("" = keep the reading). Returns an error naming `where`
  // (the source's "file:line") when strict; else OK with *drop saying whether to drop it.
  Status Check(const std::string& stream, const std::string& where, const std::string& problem,
               bool* drop);
  // Writes meta.extra "convert.<stream>_invalid_dropped" for every stream that dropped
  // readings, and appends to `warnings` (when given) the first kMaxWarnings drops per stream as
  // "file:line: problem; dropped", then a count of the rest.
  void Report(WalkMeta* meta, std::vector<std::string>* warnings) const;

  static constexpr int kMaxWarnings = 5;

 private:
  bool strict_;
  std::map<std::string, int> counts_;
  std::map<std::string, std::vector<std::string>> first_;
};

}  // namespace walkgraph::internal

#endif  // WALKGRAPH_SRC_IO_PLAUSIBILITY_H_
