// The YAML reader of PcrbOptions (internal; defined in eval/pcrb.cc), beside the bound it
// configures rather than among the estimators' parsers (config/parsers.h).
#ifndef WALKGRAPH_SRC_EVAL_PCRB_YAML_H_
#define WALKGRAPH_SRC_EVAL_PCRB_YAML_H_

#include <string>

#include <yaml-cpp/yaml.h>

#include "walkgraph/pcrb.h"
#include "walkgraph/status.h"

namespace walkgraph {

// Keys: the field names. Unknown keys are errors.
StatusOr<PcrbOptions> PcrbOptionsFromYaml(const YAML::Node& node, const std::string& context);

}  // namespace walkgraph

#endif  // WALKGRAPH_SRC_EVAL_PCRB_YAML_H_
