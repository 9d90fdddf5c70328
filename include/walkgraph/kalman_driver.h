// The one driver of the papers' filters (FilterPy's shape: a model's predict/update run by
// batch_filter, then rts_smoother). A paper's file holds its model: state, process model,
// measurement models, equations cited. The driver merges the sensor events by time, runs the
// model over them, records the epochs and each update's NIS or gating (kalman.h RecordOutcome),
// smooths with the one RTS (kalman.h RtsSmooth) and produces the trajectory.
//
// Two shapes:
// - RunKalmanFilter: a state-space filter with one epoch per event time (correa, gadeke):
//   Initialize at the first time, Predict from each time to the next, Update at every time;
//   RTS over every epoch when smoothing.
// - RunErrorStateFilter: an error-state filter at IMU rate (jimenez, prieto, zupt-ins):
//   Propagate from each sample to the next, Update at every sample (each correction injected
//   into the nominal state and the error reset); the driver decimates the output epochs and
//   outputs them filtered, or, when smoothing, records them in a ClonedErrorSmoother: the
//   filter carries a clone of its error at the last output epoch (stochastic cloning), the RTS
//   runs over those epochs (kalman.h: FilterEpoch::P_cross) and each smoothed error is
//   retracted into its epoch's nominal state. These models keep their own update bookkeeping
//   (NIS per measurement kind, gating counts: their diagnostics differ), through kalman.h's
//   KalmanUpdate.
//
// tarrio (RunTarrio) takes EventTimes only, and does not fit RunKalmanFilter: (1) its KF epochs
// are its fixes only, but it outputs a point at every event time (steps too), PDR-propagated
// from the last fix with P = P_fix + Q(t − t_fix); its prior at the next fix is built from the
// last fix in one step (eq. 9: P_fix + Q(ΔT), and eq. 6's Q(ΔT) grows with ΔT⁴ and ΔT², so it is
// not the sum of per-event predictions), and with prediction: last-velocity also the state
// (p_fix + ΔT·v); (2) its smoothed outputs between fixes are the smoothed fix plus the PDR since
// it with the mismatch at the next smoothed fix spread linearly (SmoothOutputs), not an RTS over
// every event time; (3) its two baselines (pdr-only, rss-only) run in the same event loop and
// are not Kalman filters. Its fix epochs do go through kalman.h's KalmanUpdate, RecordOutcome
// and RtsSmooth.
#ifndef WALKGRAPH_KALMAN_DRIVER_H_
#define WALKGRAPH_KALMAN_DRIVER_H_

#include <algorithm>
#include <functional>
#include <type_traits>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "walkgraph/estimate_result.h"
#include "walkgraph/kalman.h"
#include "walkgraph/progress.h"
#include "walkgraph/status.h"
#include "walkgraph/trajectory.h"

namespace walkgraph {

// Event times of a filter: t0 and every event of the streams (vectors of anything with a t_s)
// at or after t0, sorted, each time once.
template <typename... Streams>
std::vector<double> EventTimes(double t0, const Streams&... streams) {
  std::vector<double> times{t0};
  auto append = [&times, t0](const auto& events) {
    for (const auto& e : events) {
      if (e.t_s >= t0) times.push_back(e.t_s);
    }
  };
  (append(streams), ...);
  std::sort(times.begin(), times.end());
  times.erase(std::unique(times.begin(), times.end()), times.end());
  return times;
}

// The running filter as a model's Update sees it: the state and its measurement updates (Joseph
// form, gating, kalman.h), each recorded in the result (NIS of an accepted update, gated count)
// and the angle components wrapped after it.
class KalmanRun {
 public:
  KalmanRun(std::vector<int> angle_indices, EstimateResult* result)
      : angle_indices_(std::move(angle_indices)), result_(*result) {}

  Eigen::VectorXd x;
  Eigen::MatrixXd P;

  // ν = z − h(x) (angle components wrapped), Jacobian H, noise R; gate_probability ≤ 0: no gate.
  StatusOr<UpdateOutcome> Update(const Eigen::VectorXd& innovation, const Eigen::MatrixXd& H,
                                 const Eigen::MatrixXd& R, double gate_probability);

 private:
  const std::vector<int> angle_indices_;
  EstimateResult& result_;
};

// A filter model with one epoch per event time.
class KalmanModel {
 public:
  virtual ~KalmanModel() = default;
  // x and P at the first event time t.
  virtual Status Initialize(double t, Eigen::VectorXd* x, Eigen::MatrixXd* P) = 0;
  // The process model from t_prev to t: x ← f(x), P ← F P Fᵀ + Q, and F = ∂f/∂x (for the RTS).
  virtual Status Predict(double t_prev, double t, Eigen::VectorXd* x, Eigen::MatrixXd* P,
                         Eigen::MatrixXd* F) = 0;
  // The measurement updates due at epoch k (time t), each through run->Update.
  virtual Status Update(size_t k, double t, KalmanRun* run) = 0;
  // The trajectory point of epoch k from its (filtered or smoothed) state.
  virtual TrajectoryPoint Output(size_t k, const SmoothedState& state) const = 0;
};

struct KalmanRunOptions {
  bool smooth = false;             // RTS over the epochs (offline)
  std::vector<int> angle_indices;  // state components that are angles
};

// Runs `model` over `times` (increasing; the first is the start), appends one trajectory point
// per epoch (filtered, or smoothed with the RTS) to result->trajectory, NIS and gated updates to
// result->nis / result->diagnostics.
Status RunKalmanFilter(const std::vector<double>& times, KalmanModel* model,
                       const KalmanRunOptions& options, EstimateResult* result);

// The stochastic-cloning RTS of an error-state filter over its output epochs. At each output
// epoch the filter's error is 0 after the reset (the chart origin of the nominal state); the
// clone it carries since the previous output epoch holds that epoch's correction δx_{k|k+1}, its
// covariance P_{k|k+1} and the cross-covariance Cov(δx_{k+1}, δx_k); kalman.h's RtsSmooth gives
// C_k = Cov(δx_k, δx_{k+1}) P_{k+1}⁻¹ and
//   δx_{k|N} = δx_{k|k+1} + C_k δx_{k+1|N},   P_{k|N} = P_{k|k+1} + C_k (P_{k+1|N} − P_{k+1}) C_kᵀ.
//
// The clone of the error at output epoch j, as the filter carries it to the next output epoch k.
struct ErrorClone {
  Eigen::VectorXd delta;  // δ_j: the correction of epoch j's state in its chart
  Eigen::MatrixXd P_jj;   // its covariance P_{j|k}
  Eigen::MatrixXd P_cj;   // P_{kj|k}: Cov(current error, clone error)
};

template <typename Nominal>
class ClonedErrorSmoother {
 public:
  void Reserve(size_t n) {
    epochs_.reserve(n);
    nominal_.reserve(n);
  }
  size_t size() const { return epochs_.size(); }

  // Records an output epoch at t with the nominal state and its error covariance P; `clone`
  // (null at the first epoch) closes the previous epoch. The filter then restarts its clone.
  void Record(double t, const Nominal& nominal, const Eigen::MatrixXd& P, const ErrorClone* clone) {
    FilterEpoch e;
    e.t_s = t;
    e.x_prior = e.x_post = Eigen::VectorXd::Zero(P.rows());
    e.P_prior = e.P_post = P;  // P_post: until the next epoch's clone closes it
    if (clone != nullptr && !epochs_.empty()) {
      epochs_.back().x_post = clone->delta;
      epochs_.back().P_post = clone->P_jj;
      e.P_cross = clone->P_cj;
    }
    epochs_.push_back(std::move(e));
    nominal_.push_back(nominal);
  }

  // The backward pass; `output(nominal, smoothed)` retracts each epoch's smoothed error into its
  // nominal state and makes the trajectory point.
  template <typename Output>
  StatusOr<std::vector<TrajectoryPoint>> Smooth(Output output) const {
    WG_ASSIGN_OR_RETURN(const std::vector<SmoothedState> smoothed, RtsSmooth(epochs_));
    std::vector<TrajectoryPoint> points;
    points.reserve(smoothed.size());
    for (size_t k = 0; k < smoothed.size(); ++k) points.push_back(output(nominal_[k], smoothed[k]));
    return points;
  }

 private:
  std::vector<FilterEpoch> epochs_;
  std::vector<Nominal> nominal_;
};

// An error-state filter at IMU rate (RunErrorStateFilter): the model holds its nominal state,
// error covariance and measurement models; the driver calls, for k = 0, 1, …, size() − 1,
//   Propagate(k) (k ≥ 1), Update(k), IsOutputEpoch(k, scheduled) and, at an output epoch,
//   Output(k) (filtering) or the cloned smoother's record (smoothing).
class ErrorStateModel {
 public:
  virtual ~ErrorStateModel() = default;
  // The number of samples and the time of sample k.
  virtual size_t size() const = 0;
  virtual double Time(size_t k) const = 0;
  // Sample k−1 → k: the nominal state's mechanization, P ← F P Fᵀ + Q and, when cloning, the
  // clone's cross-covariance P_cj ← F P_cj.
  virtual Status Propagate(size_t k) = 0;
  // The measurement updates due at sample k (k = 0 too), the error estimate injected into the
  // nominal state and reset.
  virtual Status Update(size_t k) = 0;
  // Whether sample k is an output epoch; `scheduled` is the driver's decimation
  // (ErrorStateRunOptions). Called once per sample, after Update.
  virtual bool IsOutputEpoch(size_t k, bool scheduled) {
    (void)k;
    return scheduled;
  }
  // The filtered output of output epoch k (not called when smoothing).
  virtual void Output(size_t k, std::vector<TrajectoryPoint>* points) = 0;
};

// An error-state model that carries a clone of its error for the cloned RTS (smoothing).
template <typename Nominal>
class ClonedErrorStateModel : public ErrorStateModel {
 public:
  using nominal_type = Nominal;
  // At an output epoch: the nominal state, the covariance of its error and the clone of the
  // error at the previous output epoch (as carried to now).
  virtual const Nominal& nominal() const = 0;
  virtual Eigen::MatrixXd Covariance() const = 0;
  virtual const ErrorClone& Clone() = 0;
  // Restarts the clone from the current error (0 after the reset) at an output epoch.
  virtual void StartClone() = 0;
  // The trajectory point of an output epoch: its smoothed error retracted into its nominal state.
  virtual TrajectoryPoint SmoothedPoint(const Nominal& nominal,
                                        const SmoothedState& smoothed) const = 0;
};

struct ErrorStateRunOptions {
  bool smooth = false;  // cloned RTS over the output epochs (ClonedErrorStateModel only)
  // Output decimation: the first and the last sample and every output_every-th sample or, when
  // output_period_s > 0, the first sample at or after each multiple of output_period_s from the
  // first sample's time (1e-9 s tolerance), and the last.
  size_t output_every = 1;
  double output_period_s = 0.0;
};

namespace internal {
// The driver loops report their progress (progress.h ReportEstimatorProgress) every this many
// samples or events.
inline constexpr size_t kProgressEvery = 4096;

// The sample loop of RunErrorStateFilter: `at_output(k)` at each output epoch. A template over
// the model's own type, so that the calls of a `final` model are direct (and may be inlined):
// the loop runs once per IMU sample.
template <typename Model, typename AtOutput>
Status ErrorStateLoop(Model* model, const ErrorStateRunOptions& options, AtOutput&& at_output) {
  const size_t n = model->size();
  if (n == 0) return InvalidArgument("RunErrorStateFilter: no samples");
  const size_t every = std::max<size_t>(options.output_every, 1);
  const double period = options.output_period_s;
  double next_out = model->Time(0);
  for (size_t k = 0; k < n; ++k) {
    if (k % kProgressEvery == 0) ReportEstimatorProgress(static_cast<double>(k) / n);
    if (k > 0) WG_RETURN_IF_ERROR(model->Propagate(k));
    WG_RETURN_IF_ERROR(model->Update(k));
    bool scheduled = k + 1 == n;
    if (period > 0) {
      const double t = model->Time(k);
      scheduled = scheduled || t >= next_out - 1e-9;
      if (scheduled) {
        while (next_out <= t + 1e-9) next_out += period;
      }
    } else {
      scheduled = scheduled || k % every == 0;
    }
    if (model->IsOutputEpoch(k, scheduled)) at_output(k);
  }
  return Status::Ok();
}
// An upper bound of the number of output epochs (for reserving).
size_t OutputEpochBound(const ErrorStateModel& model, const ErrorStateRunOptions& options);

// Whether Model derives from a ClonedErrorStateModel (has the nominal_type it clones).
template <typename Model, typename = void>
struct IsClonedModel : std::false_type {};
template <typename Model>
struct IsClonedModel<Model, std::void_t<typename Model::nominal_type>>
    : std::is_base_of<ClonedErrorStateModel<typename Model::nominal_type>, Model> {};
}  // namespace internal

// Runs `model` (an ErrorStateModel, best its own `final` type) over its samples and appends the
// output epochs to `points`, filtered or, when options.smooth (a ClonedErrorStateModel only),
// smoothed with the cloned RTS over the output epochs; `output_epochs` (optional) receives
// their number.
template <typename Model>
Status RunErrorStateFilter(Model* model, const ErrorStateRunOptions& options,
                           std::vector<TrajectoryPoint>* points, size_t* output_epochs = nullptr) {
  static_assert(std::is_base_of_v<ErrorStateModel, Model>, "an ErrorStateModel");
  if (!options.smooth) {
    size_t count = 0;
    WG_RETURN_IF_ERROR(internal::ErrorStateLoop(model, options, [&](size_t k) {
      model->Output(k, points);
      ++count;
    }));
    if (output_epochs != nullptr) *output_epochs = count;
    return Status::Ok();
  }
  if constexpr (!internal::IsClonedModel<Model>::value) {
    return InvalidArgument("RunErrorStateFilter: smoothing needs a ClonedErrorStateModel");
  } else {
    using Nominal = typename Model::nominal_type;
    ClonedErrorSmoother<Nominal> rts;
    rts.Reserve(internal::OutputEpochBound(*model, options));
    WG_RETURN_IF_ERROR(internal::ErrorStateLoop(model, options, [&rts, model](size_t k) {
      rts.Record(model->Time(k), model->nominal(), model->Covariance(),
                 rts.size() > 0 ? &model->Clone() : nullptr);
      model->StartClone();
    }));
    if (output_epochs != nullptr) *output_epochs = rts.size();
    WG_ASSIGN_OR_RETURN(std::vector<TrajectoryPoint> smoothed,
                        rts.Smooth([model](const Nominal& nominal, const SmoothedState& s) {
                          return model->SmoothedPoint(nominal, s);
                        }));
    points->insert(points->end(), smoothed.begin(), smoothed.end());
    return Status::Ok();
  }
}

}  // namespace walkgraph

#endif  // WALKGRAPH_KALMAN_DRIVER_H_
