// A scenario's Monte Carlo runs, one share of them (internal): what CompareScenario (every run)
// and CompareScenarioShare / ScenarioRunMerger (compare.h: the runs shared among processes)
// have in common, so that both aggregate the same figures in the same order.
#ifndef WALKGRAPH_SRC_EVAL_MONTE_CARLO_SHARE_H_
#define WALKGRAPH_SRC_EVAL_MONTE_CARLO_SHARE_H_

#include <functional>
#include <optional>
#include <string>

#include "walkgraph/compare.h"
#include "walkgraph/pcrb.h"

namespace walkgraph::internal {

// One run's PCRB information, or why it has none. Neither (status OK, no information): not
// computed, because the bound is off or an earlier-finishing run of the same share failed it.
struct RunPcrb {
  std::optional<PcrbInformation> information;
  Status status;
};

// Receives a share's finished runs in run order (calls are serialized).
using ScenarioRunSink = std::function<Status(int run, Comparison comparison, RunPcrb pcrb)>;

// The runs r of the scenario with r % share.count == share.index, on monte_carlo.threads
// threads, each handed to `sink` in run order with its PCRB information (when
// scenario_options.pcrb). The share's first run is simulated first, alone, on the caller's
// overrides node (its errors keep their YAML line numbers).
Status RunScenarioShare(const std::string& scenario, const ScenarioCompareOptions& scenario_options,
                        const CompareOptions& options, const MonteCarloOptions& monte_carlo,
                        const MonteCarloShare& share, const EstimatorRegistry& registry,
                        const ScenarioRunSink& sink);

// The bound over a scenario's runs, given in run order (CompareScenario and ScenarioRunMerger).
class ScenarioPcrbSum {
 public:
  ScenarioPcrbSum(const ScenarioCompareOptions& scenario_options, int runs);
  void Add(int run, RunPcrb pcrb);
  // Attaches the bound (or the note on why there is none) to `comparison`; a failure other
  // than "not defined for the scenario" (FailedPrecondition) is an error.
  Status AttachTo(Comparison* comparison) const;

 private:
  bool on_;
  std::string prefix_;  // ScenarioCompareOptions::overrides_origin + ": ", or nothing
  PcrbAccumulator sum_;
  Status status_;         // the first failure, in run order
  bool skipped_ = false;  // a run came without information: nothing more is added
};

}  // namespace walkgraph::internal

#endif  // WALKGRAPH_SRC_EVAL_MONTE_CARLO_SHARE_H_
