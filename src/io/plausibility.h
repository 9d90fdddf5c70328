// Physical plausibility of single readings (internal): one set of rules for the walk readers,
// ValidateWalk and the converters, and the converters' record of what they had to drop.
#ifndef WALKGRAPH_SRC_IO_PLAUSIBILITY_H_
#define WALKGRAPH_SRC_IO_PLAUSIBILITY_H_

#include <map>
#include <string>
#include <vector>

#include "walkgraph/io.h"
#include "walkgraph/status.h"
#include "walkgraph/walk.h"

namespace walkgraph::internal {

// "" when the reading is plausible under `limits`, else what is wrong with it.
std::string CheckImu(const ImuSample& s, const ValidationLimits& limits);
std::string CheckRss(const RssSample& s, RssUnits units, const ValidationLimits& limits);
std::string CheckRange(const RangeSample& s, const ValidationLimits& limits);

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
