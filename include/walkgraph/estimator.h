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
#include "walkgraph/status.h"
#include "walkgraph/trajectory.h"
#include "walkgraph/walk.h"

namespace walkgraph {

struct EstimateResult {
  Trajectory trajectory;
  // Normalized innovation squared of each accepted measurement update (filters), for
  // consistency checks; empty where the estimator has no innovations.
  std::vector<double> nis;
  // Named figures an estimator wants to report (e.g. "ceres_iterations", "gated_updates"):
  // deterministic for a given walk and configuration.
  std::map<std::string, double> diagnostics;
  // Wall-clock figures in seconds (e.g. "update_latency_p99_s"): machine-dependent, so compare
  // keeps them out of a Monte Carlo results.json (they go to timing.json).
  std::map<std::string, double> timings;
};

class Estimator {
 public:
  virtual ~Estimator() = default;
  // Why this estimator cannot run on `walk` (missing sensors), or OK.
  virtual Status CheckApplicable(const Walk& walk) const = 0;
  // Runs on the whole walk. Never aborts: failure comes back as a Status.
  virtual StatusOr<EstimateResult> Run(const Walk& walk) const = 0;
};

// Progress inside a running estimator, for the progress report of a long single walk: a driver
// loop (the filters' sample loops) calls ReportEstimatorProgress(fraction of its work done, in
// [0, 1]) now and then; the call reaches the callback a ScopedEstimatorProgress installed on the
// calling thread (CompareOnWalk installs one around each estimator's Run when
// CompareOptions::progress is set), and is a thread-local load when none is installed. The
// fraction passed on never goes back: a report below an earlier one repeats the earlier, so a
// loop that cannot tell its fraction (the solver's iterations) reports 0 as a sign of life.
void ReportEstimatorProgress(double fraction);
class ScopedEstimatorProgress {
 public:
  explicit ScopedEstimatorProgress(std::function<void(double fraction)> callback);
  ~ScopedEstimatorProgress();
  ScopedEstimatorProgress(const ScopedEstimatorProgress&) = delete;
  ScopedEstimatorProgress& operator=(const ScopedEstimatorProgress&) = delete;

 private:
  friend void ReportEstimatorProgress(double fraction);
  std::function<void(double)> callback_;
  double reached_ = 0.0;
  ScopedEstimatorProgress* previous_;
};

using EstimatorFactory = std::function<StatusOr<std::unique_ptr<Estimator>>(const Config& config)>;

struct EstimatorInfo {
  std::string id;
  std::string description;  // one line: paper, equations, sensors
  EstimatorFactory factory;
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
