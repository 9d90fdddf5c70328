// Running several estimators on the same walk and scoring them against its truth.
//
// The comparison differs only in the estimator: every estimator sees the same Walk. Results
// are written as results.json, errors.csv, trajectories/<id>.tum and a self-contained
// report.html (see WriteComparison).
#ifndef WALKGRAPH_COMPARE_H_
#define WALKGRAPH_COMPARE_H_

#include <map>
#include <optional>
#include <string>
#include <vector>

#include <yaml-cpp/yaml.h>

#include "walkgraph/estimator.h"
#include "walkgraph/metrics.h"
#include "walkgraph/status.h"
#include "walkgraph/walk.h"

namespace walkgraph {

struct CompareOptions {
  // Estimators to run, in order; empty = every registered estimator applicable to the walk.
  std::vector<std::string> estimator_ids;
  // Per-estimator configuration (YAML map of options), by id.
  std::map<std::string, YAML::Node> configs;
  Alignment alignment = Alignment::kNone;
};

struct EstimatorOutcome {
  std::string id;
  Status status;  // not OK: the estimator failed; stats are empty
  ErrorStats stats;
  double runtime_s = 0.0;
  EstimateResult result;
  ErrorSeries errors;
};

struct Comparison {
  std::string walk_name;
  int runs = 1;
  TruthKind truth_kind = TruthKind::kNone;
  std::vector<EstimatorOutcome> outcomes;
  std::optional<double> pcrb_rmse_m;
  // What the report draws under the trajectories.
  std::vector<Anchor> anchors;
  std::vector<TruthSample> truth;
};

// Runs the estimators on `walk`. Fails only when the request itself is invalid (unknown id, no
// truth); an estimator that fails is kept as an outcome with its Status.
StatusOr<Comparison> CompareOnWalk(const Walk& walk, const CompareOptions& options,
                                   const EstimatorRegistry& registry =
                                       EstimatorRegistry::Builtin());

// An aligned text table, one row per estimator; '*' marks the best value of each column.
std::string FormatComparisonTable(const Comparison& comparison);

// Writes results.json, errors.csv, trajectories/<id>.tum and report.html into `out_dir`.
// The folder appears complete or not at all (written under a temporary name, then renamed).
Status WriteComparison(const Comparison& comparison, const std::string& out_dir);

// The report page alone (self-contained HTML with inline SVG).
std::string RenderHtmlReport(const Comparison& comparison);

}  // namespace walkgraph

#endif  // WALKGRAPH_COMPARE_H_
