// The YAML reader of PdrOptions (internal; defined in pdr/pdr.cc). A front end's reader sits
// beside it, below the estimators' parsers (config/parsers.h includes this header), so that the
// front end never reaches the filters' and smoothers' headers.
#ifndef WALKGRAPH_SRC_PDR_PDR_YAML_H_
#define WALKGRAPH_SRC_PDR_PDR_YAML_H_

#include <yaml-cpp/yaml.h>

#include "walkgraph/pdr.h"
#include "walkgraph/status.h"

namespace walkgraph {

// Keys: detector (vertical-peak|fir-magnitude|energy), length_model
// (weinberg|constant|linear), heading (gyro|complementary), forward_axis (body-x|body-y|pca), and
// every numeric field by its name; stride (a map of StrideOptions keys).
StatusOr<PdrOptions> PdrOptionsFromYaml(const YAML::Node& node);

}  // namespace walkgraph

#endif  // WALKGRAPH_SRC_PDR_PDR_YAML_H_
