#include "walkgraph/kalman_driver.h"

#include <algorithm>

#include "walkgraph/angle.h"

namespace walkgraph {

StatusOr<UpdateOutcome> KalmanRun::Update(const Eigen::VectorXd& innovation,
                                          const Eigen::MatrixXd& H, const Eigen::MatrixXd& R,
                                          double gate_probability) {
  WG_ASSIGN_OR_RETURN(const UpdateOutcome out,
                      KalmanUpdate(innovation, H, R, gate_probability, &x, &P));
  for (int i : angle_indices_) x[i] = NormalizeAngle(x[i]);
  RecordOutcome(out, &result_.nis, &result_.diagnostics);
  return out;
}

Status RunKalmanFilter(const std::vector<double>& times, KalmanModel* model,
                       const KalmanRunOptions& options, EstimateResult* result) {
  if (times.empty()) return InvalidArgument("RunKalmanFilter: no event times");
  KalmanRun run(options.angle_indices, result);
  std::vector<FilterEpoch> epochs;
  epochs.reserve(times.size());
  for (size_t k = 0; k < times.size(); ++k) {
    if (k % internal::kProgressEvery == 0) {
      ReportEstimatorProgress(static_cast<double>(k) / times.size());
    }
    FilterEpoch e;
    e.t_s = times[k];
    if (k == 0) {
      WG_RETURN_IF_ERROR(model->Initialize(times[0], &run.x, &run.P));
    } else {
      WG_RETURN_IF_ERROR(model->Predict(times[k - 1], times[k], &run.x, &run.P, &e.F));
    }
    e.x_prior = run.x;
    e.P_prior = run.P;
    WG_RETURN_IF_ERROR(model->Update(k, times[k], &run));
    e.x_post = run.x;
    e.P_post = run.P;
    epochs.push_back(std::move(e));
  }
  std::vector<SmoothedState> states;
  if (options.smooth) {
    WG_ASSIGN_OR_RETURN(states, RtsSmooth(epochs, options.angle_indices));
  } else {
    states.reserve(epochs.size());
    for (FilterEpoch& e : epochs)
      states.push_back({e.t_s, std::move(e.x_post), std::move(e.P_post)});
  }
  for (size_t k = 0; k < states.size(); ++k) {
    result->trajectory.points.push_back(model->Output(k, states[k]));
  }
  return Status::Ok();
}

namespace internal {

size_t OutputEpochBound(const ErrorStateModel& model, const ErrorStateRunOptions& options) {
  const size_t n = model.size();
  if (n == 0) return 0;
  if (options.output_period_s > 0) {
    const double span = model.Time(n - 1) - model.Time(0);
    return std::min(n, static_cast<size_t>(span / options.output_period_s) + 2);
  }
  return (n - 1) / std::max<size_t>(options.output_every, 1) + 2;
}

}  // namespace internal

}  // namespace walkgraph
