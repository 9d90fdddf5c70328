// Divergence: an estimate that has left what can be believed is reported as diverged (when and
// why), never ranked as a number among the others.
//
// An estimate diverges at the first scored time where
//   - a position, heading or covariance is NaN or infinite;
//   - a reported position covariance is not positive semi-definite (a negative eigenvalue
//     beyond rounding; zero is allowed: a point held constant to fix the gauge has none);
//   - the position leaves the scene (the bounding box of the anchors, the truth and the initial
//     pose) by more than max(min_margin_m, margin_fraction × the box's diagonal): no estimator
//     of this walk has a reason to be there;
//   - the estimator is absurdly overconfident and far off: in a window of nees_window_s (at
//     least kMinNeesPoints scored points) more than half of the points have a position NEES
//     above nees_limit at an error above nees_min_error_m (a median test: one spike does not
//     make a window). A consistent estimator's NEES has mean 2 (χ²(2)); the default 1e4 is an
//     error of ~70 σ held for most of the window. The error floor keeps out
//     filters that are overconfident by design but close (001's SCMT EKF sets R = ε near a mote:
//     windowed NEES 1.2e4-2.3e4 at errors under 8 m on its own scenarios).
// Estimators without covariances are checked by the first three rules only. What the defaults
// flag on the bundled walks and the simulated presets (seeds 1, 2) is listed in
// docs/command-line.md; they are options, not tuned per walk.
#ifndef WALKGRAPH_DIVERGENCE_H_
#define WALKGRAPH_DIVERGENCE_H_

#include <optional>
#include <string>

#include "walkgraph/metrics.h"
#include "walkgraph/status.h"
#include "walkgraph/trajectory.h"
#include "walkgraph/walk.h"

namespace walkgraph {

struct DivergenceOptions {
  bool enabled = true;
  double min_margin_m = 50.0;
  double margin_fraction = 0.5;
  double nees_window_s = 30.0;
  double nees_limit = 1e4;
  double nees_min_error_m = 10.0;
  // false: a diverged estimator (or Monte Carlo run) is left out of the figures, the best-value
  // marks and the study aggregates; true: it is scored like the others and still flagged.
  bool keep_in_figures = false;

  Status Validate() const;
};

inline constexpr int kMinNeesPoints = 5;

struct Divergence {
  double t_s = 0.0;    // the first scored time where the estimate had diverged
  std::string reason;  // e.g. "2.7 km outside the scene", "mean NEES 3.1e+05 over 30 s"
};

// "diverged at 812.4 s: 2.7 km outside the scene (...)".
std::string ToString(const Divergence& divergence);

// Checks `trajectory` (scored from `from_t_s` on) and its `errors` against `walk`; nullopt when
// the estimate holds.
std::optional<Divergence> CheckDivergence(const Walk& walk, const Trajectory& trajectory,
                                          const ErrorSeries& errors, double from_t_s,
                                          const DivergenceOptions& options = {});

}  // namespace walkgraph

#endif  // WALKGRAPH_DIVERGENCE_H_
