// Progress inside a running estimator, for the progress report of a long single walk (its own
// small unit at the bottom, so that the Kalman driver and the graph solves report without the
// estimator interface).
#ifndef WALKGRAPH_PROGRESS_H_
#define WALKGRAPH_PROGRESS_H_

#include <functional>

namespace walkgraph {

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

}  // namespace walkgraph

#endif  // WALKGRAPH_PROGRESS_H_
