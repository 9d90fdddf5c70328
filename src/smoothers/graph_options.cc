#include "walkgraph/smoothers/graph_options.h"

#include "util/enum_define.h"

namespace walkgraph {

WALKGRAPH_DEFINE_ENUM_NAMES(LossKind, "loss", {"none", LossKind::kNone},
                            {"huber", LossKind::kHuber}, {"cauchy", LossKind::kCauchy},
                            {"soft-l1", LossKind::kSoftL1}, {"arctan", LossKind::kArctan},
                            {"tukey", LossKind::kTukey})
WALKGRAPH_DEFINE_ENUM_NAMES(PathLossMode, "path_loss", {"auto", PathLossMode::kAuto},
                            {"fixed", PathLossMode::kFixed}, {"global", PathLossMode::kGlobal},
                            {"per-anchor", PathLossMode::kPerAnchor},
                            {"hierarchical", PathLossMode::kHierarchical})
WALKGRAPH_DEFINE_ENUM_NAMES(CalibrationScope, "calibration scope",
                            {"none", CalibrationScope::kNone},
                            {"global", CalibrationScope::kGlobal},
                            {"per-anchor", CalibrationScope::kPerAnchor})
WALKGRAPH_DEFINE_ENUM_NAMES(WindowOutput, "window_output", {"lagged", WindowOutput::kLagged},
                            {"online", WindowOutput::kOnline})
WALKGRAPH_DEFINE_ENUM_NAMES(RssResidual, "rss_residual", {"db", RssResidual::kDb},
                            {"range", RssResidual::kRange})
WALKGRAPH_DEFINE_ENUM_NAMES(StepGraphInit, "initialization",
                            {"dead-reckoning", StepGraphInit::kDeadReckoning},
                            {"window", StepGraphInit::kWindow}, {"auto", StepGraphInit::kAuto})
WALKGRAPH_DEFINE_ENUM_NAMES(WindowLinearSolver, "window_linear_solver",
                            {"dense", WindowLinearSolver::kDense},
                            {"sparse", WindowLinearSolver::kSparse},
                            {"eigen-sparse", WindowLinearSolver::kEigenSparse})
WALKGRAPH_DEFINE_ENUM_NAMES(InsInitialization, "initialization",
                            {"front-end", InsInitialization::kFrontEnd},
                            {"window", InsInitialization::kWindow})
WALKGRAPH_DEFINE_ENUM_NAMES(PreintegrationBias, "preintegration_bias",
                            {"front-end", PreintegrationBias::kFrontEnd},
                            {"estimate", PreintegrationBias::kEstimate})

#undef WALKGRAPH_ENUM_NAMES

}  // namespace walkgraph
