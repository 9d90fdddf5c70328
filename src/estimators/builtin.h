// Registration of the estimators shipped with walkgraph (internal). Each estimator unit defines
// one Register* function; registry.cc calls them in order. Add one line per new unit.
//
// A unit registers its ids through OptionsFactory: the factory parses the YAML config into the
// unit's Options and builds the estimator from them, so no unit repeats that wrapper. A failed
// registration (an empty or duplicate id) is returned, and Builtin() keeps it (registry.cc).
#ifndef WALKGRAPH_SRC_ESTIMATORS_BUILTIN_H_
#define WALKGRAPH_SRC_ESTIMATORS_BUILTIN_H_

#include <memory>
#include <utility>

#include <yaml-cpp/yaml.h>

#include "config/reader.h"
#include "walkgraph/estimator.h"

namespace walkgraph::internal {

// The factory of an estimator built from parsed options: `parse(config)` returns
// StatusOr<Options> (a parse error is the factory's error); the estimator is
// EstimatorT(args..., options).
template <typename EstimatorT, typename Parse, typename... Args>
EstimatorFactory OptionsFactory(Parse parse, Args... args) {
  return [parse, args...](const Config& config) -> StatusOr<std::unique_ptr<Estimator>> {
    auto options = parse(config.node());
    if (!options.ok()) return options.status();
    return std::unique_ptr<Estimator>(new EstimatorT(args..., std::move(*options)));
  };
}

// Each unit returns its first failed registration.
Status RegisterOdometryDeadReckoning(EstimatorRegistry* registry);  // estimators/odometry_dr.cc
Status RegisterZuptIns(EstimatorRegistry* registry);                // estimators/zupt_ins.cc
Status RegisterTarrio(EstimatorRegistry* registry);                 // filters/tarrio.cc
Status RegisterCorrea(EstimatorRegistry* registry);                 // filters/correa.cc
Status RegisterPrieto(EstimatorRegistry* registry);                 // filters/prieto.cc
Status RegisterGadeke(EstimatorRegistry* registry);                 // filters/gadeke.cc
Status RegisterJimenezIez(EstimatorRegistry* registry);             // filters/jimenez.cc
Status RegisterStepGraphSmoothers(EstimatorRegistry* registry);     // smoothers/step_graph_run.cc
Status RegisterInsGraphBatch(EstimatorRegistry* registry);          // smoothers/ins_graph.cc
Status RegisterInsGraphWindow(EstimatorRegistry* registry);         // smoothers/ins_window.cc

}  // namespace walkgraph::internal

#endif  // WALKGRAPH_SRC_ESTIMATORS_BUILTIN_H_
