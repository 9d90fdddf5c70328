// The YAML reader of StanceOptions (internal; defined in stance/stance.cc). A front end's reader
// sits beside it, below the estimators' parsers (config/parsers.h includes this header), so that
// the front end never reaches the filters' and smoothers' headers.
#ifndef WALKGRAPH_SRC_STANCE_STANCE_YAML_H_
#define WALKGRAPH_SRC_STANCE_STANCE_YAML_H_

#include <yaml-cpp/yaml.h>

#include "walkgraph/stance.h"
#include "walkgraph/status.h"

namespace walkgraph {

// Keys: detector (glrt|mv|mag|are|multi-condition|adaptive) and every numeric field by its name;
// a key the map does not name keeps its value in `base` (a front end's own defaults).
StatusOr<StanceOptions> StanceOptionsFromYaml(const YAML::Node& node);

StatusOr<StanceOptions> StanceOptionsFromYaml(const YAML::Node& node, const StanceOptions& base);

}  // namespace walkgraph

#endif  // WALKGRAPH_SRC_STANCE_STANCE_YAML_H_
