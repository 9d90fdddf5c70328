// How the papers' estimators gather their inputs from a Walk through the shared front ends
// (pdr.h, radio.h, filters/ranges.h), and how their configuration names those front ends.
//
// Every paper estimator's YAML config is the filter's own options plus two child maps:
//   pdr:    PdrOptions keys (pdr.h), laid over the paper's front-end defaults
//   radio:  the RSS/range epoch and positioning options below, laid over the paper's defaults
// so that the front end is configurable per estimator while a comparison of two estimators
// with the same front end differs only in the estimator.
//
// Position fixes: BuildRangeEpochs groups the readings into windows of window_s (000: ΔT = 2 s,
// 001: 1 s), averaging RSS per anchor in dB; each epoch is positioned by the hyperbolic WLS of
// 000 eq. 2 or the nonlinear LS of 001 eq. 5. Epochs without a fix (fewer than three anchors,
// collinear anchors, no convergence) are left out and counted.
#ifndef WALKGRAPH_FILTERS_FRONT_END_H_
#define WALKGRAPH_FILTERS_FRONT_END_H_

#include <map>
#include <string>
#include <vector>

#include "walkgraph/filters/ranges.h"
#include "walkgraph/measurements.h"
#include "walkgraph/pdr.h"
#include "walkgraph/radio.h"
#include "walkgraph/status.h"
#include "walkgraph/trajectory.h"
#include "walkgraph/walk.h"

namespace walkgraph {

// The `radio:` child map. Keys: window_s, bias_corrected, receiver_height_m, sensitivity,
// method (hyperbolic|nonlinear-ls), weighted, collinear_ratio, max_iterations, tolerance_m,
// min_sigma_m.
struct RadioFrontEndOptions {
  EpochOptions epochs;
  PositioningMethod method = PositioningMethod::kHyperbolic;
  // nonlinear-ls only: weights w_i = 1/σ_i² (radio.h), or none (001 eq. 5 as written: every
  // range weighs the same; then Cov(m̂) = s²·(JᵀJ)⁻¹, s² = max(Σ residual²/(n − 2), floor²),
  // floor = min_sigma_m).
  bool weighted = true;
  PositioningOptions positioning;

  // Every rule its YAML reader applies; messages are prefixed "<context> radio".
  Status Validate(const std::string& context = "estimator") const;
};

// Applicability checks, with messages naming the estimator and the missing input.
// Steps: odometry.csv, or imu.csv from a waist/hip/handheld IMU; with `need_absolute_heading`,
// also a heading in the anchors' frame: initial_pose in walk.yaml, or a magnetometer with
// pdr heading 'complementary'.
Status CheckStepInput(const Walk& walk, const PdrOptions& pdr, bool need_absolute_heading,
                      const std::string& id);
// Radio: rss.csv or range.csv, and at least `min_anchors` anchors in anchors.csv.
Status CheckRadioInput(const Walk& walk, int min_anchors, const std::string& id);

// Steps from StepsForWalk; fails (naming `id`) if there are none or, with
// `need_absolute_heading`, if their heading is not absolute.
StatusOr<StepSequence> StepsFromFrontEnd(const Walk& walk, const PdrOptions& pdr,
                                         bool need_absolute_heading, const std::string& id);

struct FixesFromFrontEnd {
  std::vector<PositionFix> fixes;  // in time order, only epochs with a fix
  // For RSS walks, per fix: the epoch's strongest reading at the fix time — rss = the epoch's
  // max_rss (RSS averaged in dB per anchor) at the anchor of the shortest range (the strongest
  // one when the anchors share a height). Empty for range walks.
  std::vector<RangeMeasurement> strongest;
  int epochs = 0;         // radio epochs built
  int failed_epochs = 0;  // epochs without a fix
};
// PositionWalk with the radio options; fails (naming `id`) if no epoch gives a fix.
StatusOr<FixesFromFrontEnd> PositionFixesFromFrontEnd(const Walk& walk,
                                                      const RadioFrontEndOptions& radio,
                                                      const std::string& id);

// Trajectory of the fixes themselves (covariance = the fix's, heading unknown: σ = π).
Trajectory TrajectoryOfFixes(const std::vector<PositionFix>& fixes);

}  // namespace walkgraph

#endif  // WALKGRAPH_FILTERS_FRONT_END_H_
