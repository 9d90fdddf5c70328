// What fg-batch (step_graph_run.cc) and fg-window (step_graph_window.cc) share: the walk check,
// the diagnostics, output points and the start hypotheses of StepGraphOptions::start_estimators.
#ifndef WALKGRAPH_SRC_SMOOTHERS_STEP_GRAPH_RUN_H_
#define WALKGRAPH_SRC_SMOOTHERS_STEP_GRAPH_RUN_H_

#include <functional>
#include <map>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "smoothers/anchor_search.h"
#include "walkgraph/estimator.h"
#include "walkgraph/graph.h"
#include "walkgraph/smoothers/step_graph.h"
#include "walkgraph/status.h"
#include "walkgraph/trajectory.h"
#include "walkgraph/walk.h"

namespace walkgraph {
namespace internal {

// StepGraphOptions::start_estimators as ids: split at commas, blanks trimmed; blank: none.
std::vector<std::string> StartEstimatorIds(const std::string& list);

// The step graph runs on odometry or an IMU (steps), or on radio to >= 3 anchors.
Status CheckStepWalk(const Walk& walk);

// The static states' values (gyro bias, anchors, range calibration, path loss) as diagnostics;
// `value_of`: a state's solved value.
void AddStaticDiagnostics(const StepGraph& graph,
                          const std::function<std::vector<double>(Key)>& value_of, const Walk& walk,
                          const StepGraphOptions& o, std::map<std::string, double>* d);
// The graph's own diagnostics (path loss, start heading, stairs, the step front end).
void AddGraphDiagnostics(const StepGraph& graph, const Walk& walk,
                         std::map<std::string, double>* d);

// A node's height and the floor it is on.
void SetHeight(const StepGraph& graph, double z_m, TrajectoryPoint* point);
// An output point at (p, θ), θ wrapped.
TrajectoryPoint MakePoint(double t, const double* p, double theta);
// (x, y, θ) covariance from a node's tangent-space marginal (3×3, 2×2 or less: see the .cc).
Eigen::Matrix3d PoseCovariance(const Eigen::MatrixXd& c);
// The output points the graph's motion model puts at the start of each step after a stop.
void InsertStops(const Walk& walk, double max_step_duration_s, Trajectory* trajectory);

// The grid search's options for a range anchor and for an RSS one (anchor_search.h), from the
// graph's options and the estimates so far (diagnostics `fd`: range_scale, range_bias_m,
// path_loss_A, path_loss_eta where the graph estimates them).
struct SearchSetup {
  AnchorSearchOptions range, rss;
};
SearchSetup SearchOptions(const Walk& walk, const StepGraphOptions& o,
                          const std::map<std::string, double>& fd);

// fg-batch's solver options (the window's first-window solve uses them too).
SolverOptions BatchSolverOptions(const StepGraphOptions& o);

// The solver options' linear solver (and sparse library) for a choice of StepGraphOptions.
void SetLinearSolver(WindowLinearSolver choice, SolverOptions* so);

// A start hypothesis: its name in the diagnostics (start_hypothesis_cost.<name>), every node's
// initial (p, θ) (or the first nodes'), and 1 + its estimator's place in start_estimators (0:
// not an estimator's).
struct NamedStart {
  std::string name;
  std::vector<Eigen::Vector3d> nodes;
  int estimator = 0;
};

// The start hypotheses of StepGraphOptions::start_estimators (StepGraph::HypothesesFrom) over
// the nodes with t <= until_s; causal: the filters only (an id ending in "-rts" gives its
// filter's, the id without it). An estimator that cannot run on the walk, or fails, gives none;
// an id the registry does not know is an error.
StatusOr<std::vector<NamedStart>> EstimatorStarts(const Walk& walk, const StepGraph& graph,
                                                  const StepGraphOptions& o, bool causal,
                                                  double until_s);

// fg-window and fg-window-online: one output point per graph node (lagged or online).
StatusOr<EstimateResult> RunWindowNodes(const Walk& walk, const StepGraphOptions& options);

}  // namespace internal
}  // namespace walkgraph

#endif  // WALKGRAPH_SRC_SMOOTHERS_STEP_GRAPH_RUN_H_
