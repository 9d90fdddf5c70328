// Registration functions of the estimators shipped with walkgraph (internal). Each estimator
// unit defines one; registry.cc calls them in order. Add one line in each file per new unit.
#ifndef WALKGRAPH_SRC_ESTIMATORS_BUILTIN_H_
#define WALKGRAPH_SRC_ESTIMATORS_BUILTIN_H_

#include "walkgraph/estimator.h"

namespace walkgraph::internal {

void RegisterOdometryDeadReckoning(EstimatorRegistry* registry);
void RegisterPrieto(EstimatorRegistry* registry);
void RegisterZuptIns(EstimatorRegistry* registry);
void RegisterInsGraphBatch(EstimatorRegistry* registry);
void RegisterInsGraphWindow(EstimatorRegistry* registry);  // smoothers/ins_window.cc
void RegisterJimenezIez(EstimatorRegistry* registry);
void RegisterTarrio(EstimatorRegistry* registry);  // filters/tarrio.cc
void RegisterCorrea(EstimatorRegistry* registry);  // filters/correa.cc
void RegisterGadeke(EstimatorRegistry* registry);  // filters/gadeke.cc
void RegisterStepGraphSmoothers(EstimatorRegistry* registry);

}  // namespace walkgraph::internal

#endif  // WALKGRAPH_SRC_ESTIMATORS_BUILTIN_H_
