// The walk's row rules (internal, src/io/): one definition of what a walk's rows must hold,
// shared by the readers (walk_reader.cc), which prefix "file:line: ", and ValidateWalk
// (walk_validation.cc), which prefixes the stream and index. The std::string checks return ""
// when the row is acceptable, else what was expected.
#ifndef WALKGRAPH_SRC_IO_WALK_RULES_H_
#define WALKGRAPH_SRC_IO_WALK_RULES_H_

#include <string>
#include <unordered_map>

#include "walkgraph/io.h"
#include "walkgraph/status.h"
#include "walkgraph/walk.h"

namespace walkgraph::internal {

// t_s in [0, 1e10] s (a larger value names the unit it looks like), after `prev_t` if given.
std::string CheckTimeStrictlyIncreasing(double t, const double* prev_t);
// Multi-anchor streams: timestamps never go backwards; per anchor they strictly increase.
std::string CheckRadioTime(double t, int anchor_id, double* last_t,
                           std::unordered_map<int, double>* last_by_anchor, bool first);
// An integer that fits an int.
bool IsIntegral(double v);
// A floor number: an integer level, 0 the ground floor, negative below.
std::string CheckFloor(double v);
// A barometer reading in hPa, after `previous` if given.
std::string CheckPressure(const PressureSample& s, const PressureSample* previous);
// The storey height of walk.yaml (metres between consecutive floors).
std::string CheckStoreyHeight(double h);
// The anchor's survey fields agree (sigma_m in [0, 1000] m, none on an unknown anchor) and its
// group is a plain word.
std::string CheckAnchorSurvey(const Anchor& a);
// A waypoint, after `previous` if given.
std::string CheckWaypoint(const Waypoint& w, const Waypoint* previous, const ValidationLimits& lim);
// The text fields of walk.yaml end up in JSON and HTML: they must be UTF-8.
Status CheckMetaText(const WalkMeta& m, const std::string& where);
// The streams a walk.yaml declares must be the ones present.
Status CheckDeclaredStreams(const Walk& walk, const std::string& yaml);

}  // namespace walkgraph::internal

#endif  // WALKGRAPH_SRC_IO_WALK_RULES_H_
