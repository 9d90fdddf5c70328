// What the parts of the study share (src/study/): study_manifest.cc reads the manifest and
// names the cells, study.cc runs them, study_output.cc writes their CSV, table and HTML.
#ifndef WALKGRAPH_SRC_STUDY_STUDY_INTERNAL_H_
#define WALKGRAPH_SRC_STUDY_STUDY_INTERNAL_H_

#include <string>

#include <yaml-cpp/yaml.h>

#include "walkgraph/metrics.h"
#include "walkgraph/study.h"

namespace walkgraph::internal {

// The figure of metric `m` (ErrorStatFields), or null.
double ErrorStats::*FieldOf(const std::string& m);
// The simulator overrides of cell (sweep, value).
YAML::Node CellOverrides(const StudySweep& sweep, size_t value);
// The options of estimator `id` in cell (sweep, value).
YAML::Node CellConfig(const StudyManifest& m, const StudySweep& sweep, size_t value,
                      const std::string& id);
// "manifest:line: sweep 'name', value v": where cell (sweep, value) is, for messages.
std::string CellAt(const StudyManifest& m, const StudySweep& sweep, size_t value);

}  // namespace walkgraph::internal

#endif  // WALKGRAPH_SRC_STUDY_STUDY_INTERNAL_H_
