// The common estimator interface and the registry that finds estimators by a stable id.
//
// An estimator sees a Walk and its configuration, nothing global. Configuration is a YAML map
// whose keys are the estimator's Options fields; absent keys keep the paper's defaults, unknown
// keys are an error. The CLI and research code find estimators the same way:
//
//   auto est = walkgraph::EstimatorRegistry::Builtin().Create("fg-batch", config);
//   if (!est.ok()) { ... est.status().message() ... }
//   auto result = (*est)->Run(walk);
#ifndef WALKGRAPH_ESTIMATOR_H_
#define WALKGRAPH_ESTIMATOR_H_

#include <functional>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "walkgraph/config.h"
#include "walkgraph/estimate_result.h"
#include "walkgraph/progress.h"
#include "walkgraph/status.h"
#include "walkgraph/trajectory.h"
#include "walkgraph/walk.h"

namespace walkgraph {

class Estimator {
 public:
  virtual ~Estimator() = default;
  // Why this estimator cannot run on `walk` (missing sensors), or OK.
  virtual Status CheckApplicable(const Walk& walk) const = 0;
  // Runs on the whole walk. Never aborts: failure comes back as a Status.
  virtual StatusOr<EstimateResult> Run(const Walk& walk) const = 0;
};

// Progress inside a running estimator (ReportEstimatorProgress, ScopedEstimatorProgress):
// walkgraph/progress.h, included here.

using EstimatorFactory = std::function<StatusOr<std::unique_ptr<Estimator>>(const Config& config)>;

struct EstimatorInfo {
  std::string id;
  std::string description;  // one line: paper, equations, sensors
  EstimatorFactory factory;
  // Whether the estimator handles anchors of unknown position itself (fg-batch makes them
  // states). Otherwise Create wraps it: on a walk with such anchors it runs on
  // WithoutUnknownAnchors(walk) and its diagnostics count what was left out
  // (unknown_anchors_ignored, unknown_anchor_readings_ignored). The wrapper is not the
  // estimator's class: `factory` gives the estimator itself (e.g. for a dynamic_cast).
  bool estimates_unknown_anchors = false;
};

class EstimatorRegistry {
 public:
  // Every estimator shipped with the library.
  static const EstimatorRegistry& Builtin();

  // Adds `info`; an empty id, a missing factory or an id already registered is an error, which
  // the registry also keeps (status()).
  Status Register(EstimatorInfo info);
  // The first failed Register, or OK. While it is not OK, Create and OptionDefaults fail with
  // it: a registry that dropped an estimator does not pass for a complete one.
  const Status& status() const { return status_; }
  StatusOr<std::unique_ptr<Estimator>> Create(const std::string& id,
                                              const Config& config = {}) const;
  const EstimatorInfo* Find(const std::string& id) const;
  // The options `id` accepts (the keys of its YAML config) with their defaults.
  StatusOr<std::vector<OptionDefault>> OptionDefaults(const std::string& id) const;
  std::vector<std::string> Ids() const;  // in registration order

 private:
  std::vector<EstimatorInfo> entries_;
  Status status_ = Status::Ok();
};

}  // namespace walkgraph

#endif  // WALKGRAPH_ESTIMATOR_H_
