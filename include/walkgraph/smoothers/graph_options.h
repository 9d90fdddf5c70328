// The enum options of the factor-graph estimators (step_graph.h, ins_graph.h, ins_window.h),
// each with its one table of YAML names (enum_names.h), ToString and <Enum>FromString.
#ifndef WALKGRAPH_SMOOTHERS_GRAPH_OPTIONS_H_
#define WALKGRAPH_SMOOTHERS_GRAPH_OPTIONS_H_

#include <string>

#include "walkgraph/enum_names.h"
#include "walkgraph/status.h"

namespace walkgraph {

// A factor type's robust loss (Ceres' losses on whitened residuals, scale in σ):
// none | huber | cauchy | soft-l1 | arctan | tukey.
enum class LossKind { kNone, kHuber, kCauchy, kSoftL1, kArctan, kTukey };
const EnumNames<LossKind>& LossKindNames();
const char* ToString(LossKind k);
StatusOr<LossKind> LossKindFromString(const std::string& name);

// Path-loss self-calibration (StepGraphOptions::path_loss, InsGraphOptions::path_loss):
// auto | fixed | global | per-anchor | hierarchical.
enum class PathLossMode { kAuto, kFixed, kGlobal, kPerAnchor, kHierarchical };
const EnumNames<PathLossMode>& PathLossModeNames();
const char* ToString(PathLossMode m);
StatusOr<PathLossMode> PathLossModeFromString(const std::string& name);

// How many blocks of a calibration parameter (range bias, range scale): none (held at 0) |
// global (one for the walk) | per-anchor.
enum class CalibrationScope { kNone, kGlobal, kPerAnchor };
const EnumNames<CalibrationScope>& CalibrationScopeNames();
const char* ToString(CalibrationScope s);
StatusOr<CalibrationScope> CalibrationScopeFromString(const std::string& name);

// A fixed-lag smoother's output: lagged (each pose when it leaves the window) | online (each
// pose right after the update that added it).
enum class WindowOutput { kLagged, kOnline };
const EnumNames<WindowOutput>& WindowOutputNames();
const char* ToString(WindowOutput o);
StatusOr<WindowOutput> WindowOutputFromString(const std::string& name);

// The step graph's RSS factor: db (RssFactor, in dB) | range (RssRangeFactor, 004 eq. 7).
enum class RssResidual { kDb, kRange };
const EnumNames<RssResidual>& RssResidualNames();
const char* ToString(RssResidual r);
StatusOr<RssResidual> RssResidualFromString(const std::string& name);

// fg-batch's start: dead-reckoning | window | auto (StepGraphOptions::initialization).
enum class StepGraphInit { kDeadReckoning, kWindow, kAuto };
const EnumNames<StepGraphInit>& StepGraphInitNames();
const char* ToString(StepGraphInit i);
StatusOr<StepGraphInit> StepGraphInitFromString(const std::string& name);

// fg-window's linear solver: dense | sparse | eigen-sparse (StepGraphOptions).
enum class WindowLinearSolver { kDense, kSparse, kEigenSparse };
const EnumNames<WindowLinearSolver>& WindowLinearSolverNames();
const char* ToString(WindowLinearSolver s);
StatusOr<WindowLinearSolver> WindowLinearSolverFromString(const std::string& name);

// fg-ins-batch's start: front-end | window (InsGraphOptions::initialization).
enum class InsInitialization { kFrontEnd, kWindow };
const EnumNames<InsInitialization>& InsInitializationNames();
const char* ToString(InsInitialization i);
StatusOr<InsInitialization> InsInitializationFromString(const std::string& name);

// fg-ins-window's preintegration bias: front-end | estimate (InsWindowOptions).
enum class PreintegrationBias { kFrontEnd, kEstimate };
const EnumNames<PreintegrationBias>& PreintegrationBiasNames();
const char* ToString(PreintegrationBias b);
StatusOr<PreintegrationBias> PreintegrationBiasFromString(const std::string& name);

}  // namespace walkgraph

#endif  // WALKGRAPH_SMOOTHERS_GRAPH_OPTIONS_H_
