// The YAML reader of StrideOptions (internal; defined in ins/strides.cc). A front end's reader sits
// beside it, below the estimators' parsers (config/parsers.h includes this header), so that the
// front end never reaches the filters' and smoothers' headers.
#ifndef WALKGRAPH_SRC_INS_STRIDES_YAML_H_
#define WALKGRAPH_SRC_INS_STRIDES_YAML_H_

#include <yaml-cpp/yaml.h>

#include "walkgraph/status.h"
#include "walkgraph/strides.h"

namespace walkgraph {

// Keys: sampling (interval-average|instantaneous), stance (a map, StanceOptions keys), and
// every other field by its name; a key the map does not name keeps its value in `base`.
StatusOr<StrideOptions> StrideOptionsFromYaml(const YAML::Node& node);

StatusOr<StrideOptions> StrideOptionsFromYaml(const YAML::Node& node, const StrideOptions& base);

}  // namespace walkgraph

#endif  // WALKGRAPH_SRC_INS_STRIDES_YAML_H_
