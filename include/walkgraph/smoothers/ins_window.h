// The foot-INS factor graph as a fixed-lag smoother (estimator ids "fg-ins-window", lagged
// output, and "fg-ins-window-online", online output).
//
// The graph is fg-ins-batch's (ins_graph.h: states at mid-stance, ImuPreintegrationFactor,
// bias random walks, ZUPT, ZARU, gauge and bias priors, RSS/range factors), fed state by state
// to FixedLagSmoother (fixed_lag_smoother.h) with a lag in seconds: the update of state i adds
// its five blocks (p, v, q on NavQuaternionManifold, b_g, b_a; keys 5i..5i+4) and
//   InsSegmentFactors(context, &states, i−1, 1)   (preintegration i−1 → i, bias random
//                                                   walks, ZARU, ZUPT on i),
//   InsRadioFactors(context, &states, i−1, 1)     (every reading of (t_{i−1}, t_i]),
// the i = 0 update the gauge, the bias priors and the readings at t_0. With window_update_s > 0
// the states of each window_update_s are gathered into one update. The smoother solves, then
// marginalizes every state older than t_newest − lag into a MarginalizationPrior on its Markov
// blanket (the next state's blocks and the static ones).
// Static states (no timestamp, never marginalized): the path loss (A, η), held constant as in
// the batch, and the per-anchor range bias (constant 0, or estimated with its prior when
// estimate_range_bias) — each added by the first update with a reading that needs it.
//
// New states start from the front end (the ZUPT-aided INS of strides.h) carried into the
// window's frame: with the previous state's current estimate (p̂, q̂) and the front end's
// (p̃, q̃) at both states, Δψ = yaw(q̂_{i−1}) − yaw(q̃_{i−1}) and
//   p_i = p̂_{i−1} + R_z(Δψ)(p̃_i − p̃_{i−1}),  v_i = R_z(Δψ) ṽ_i,  q_i = R_z(Δψ) ⊗ q̃_i,
//   b_i = b̂_{i−1}
// (state 0 from the front end, as in the batch); the front end drifts in position and yaw,
// which the radio corrects, so its raw values can be metres from the window's estimate.
// Preintegration point b̄ (preintegration_bias): "front-end" — the front end's bias estimates
// at state i−1, the batch's first round, so a window longer than the walk builds exactly the
// batch graph of max_relinearizations: 0; "estimate" — the window's estimate of b_{i−1} when
// state i arrives. Either way a preintegration is built once and corrected to first order when
// the biases move (Forster eq. 44); the window never re-preintegrates (the batch may).
//
// Linearization-point policy (the smoother's own, fixed_lag_smoother.h): every factor in the
// window is relinearized at each solve; the MarginalizationPrior's Jacobian stays at the
// estimate its states had when they were marginalized (first-estimate Jacobian), while its
// blanket states keep being relinearized by the remaining factors — the usual sliding-window
// approximation. Robust (Cauchy) radio factors enter the prior with their IRLS weight ρ′ at
// that estimate.
//
// Output (same rate and format as fg-ins-batch, InsStatesTrajectory):
//   lagged (fg-ins-window): each state's estimate when it leaves the window (the states still
//     in the window at the end: their final estimates), the segments between states closed as
//     in the batch; (x, y, yaw) covariance of each state from the window just before it is
//     marginalized (FixedLagSmoother::MarginalCovariances in before_marginalize).
//   online (fg-ins-window-online): each state's estimate right after the update that added it
//     (data up to its own time — plus the front end's look-ahead to the end of the stance
//     phase that places the state); between states, strapdown from the earlier state only
//     (no end correction: the next state is the future), with the earlier state's covariance.
// A covariance that cannot be computed (rank-deficient window) leaves those states without
// one; the run goes on (diagnostics states_without_covariance).
// Diagnostics (deterministic): num_states, num_radio_factors, window_solves, ceres_iterations,
// window_max_keys (the largest WindowKeys().size() after any update: 5 keys per state — the
// memory bound), window_max_states, states_without_covariance, covariance_ok. Wall-clock
// figures go to EstimateResult::timings: update_latency_{median,p99,max}_s, run_s,
// run_s_per_walk_minute.
#ifndef WALKGRAPH_SMOOTHERS_INS_WINDOW_H_
#define WALKGRAPH_SMOOTHERS_INS_WINDOW_H_

#include <string>

#include "walkgraph/estimator.h"
#include "walkgraph/smoothers/ins_graph.h"
#include "walkgraph/status.h"

namespace walkgraph {

struct InsWindowOptions {
  // The graph (every fg-ins-batch key; max_iterations is the batch's), with the causal stance
  // detector (StrideOptions::Causal: a window's output at t must not depend on the walk after t).
  // The stance magnetometer (use_stance_magnetometer, ins_graph.h) is off by default here: a
  // window cannot revise the headings it marginalized, and on short walks the field direction
  // ψ_f it learnt from the first stances bends them. Measured with it on (factors at stances
  // 3 m apart): over 8 laps, 10 runs, fg-ins-window 0.338 -> 0.256 m on jimenez-building
  // stairs, 0.320 -> 0.257 running, 0.379 -> 0.274 on prieto-laps running; but over 3 walking
  // laps of jimenez-building (seeds 300, 301) 0.263 -> 0.358 and 0.203 -> 0.220 m, the online
  // output 0.290 -> 0.408 and 0.306 -> 0.322 m. (With a factor at every stance it was worse on
  // 4 of 8 stair seeds.) fg-ins-batch, which solves ψ_f with the whole walk, keeps it on.
  InsGraphOptions graph = [] {
    InsGraphOptions g;
    g.front_end = g.front_end.Causal();
    g.use_stance_magnetometer = false;
    return g;
  }();
  double lag_s = 10.0;
  double window_update_s = 0.0;  // 0: one update per state; > 0: states gathered per period
  int window_max_iterations = 10;
  WindowOutput window_output = WindowOutput::kLagged;
  PreintegrationBias preintegration_bias = PreintegrationBias::kFrontEnd;  // (see the top)
  // FixedLagSmoother::Options: states leave in batches of this span; LM's starting radius
  // (the window is warm-started: nearly undamped). Measured on a 60-min prieto-laps walk
  // without covariances: 0 s / 1e4 (Ceres' default) 16.9 s, RMSE 0.621 m; 1 s / 1e8 9.7 s,
  // 0.614 m.
  double window_marginalize_batch_s = 1.0;
  double window_initial_trust_region_radius = 1e8;
  // Across an IMU gap (Walk::ImuGaps) the graph bridges with a walker's motion model that
  // leaves the heading free; until radio and motion pin it down again, a marginalization
  // prior taken after the gap would freeze a wrong heading into the window. So the window is
  // held open from the state before the gap (FixedLagSmoother::HoldFrom) until the newest
  // state's yaw σ is back to that of the last state before the gap (gap_release_yaw_sigma_rad
  // when that one is not known), for at most gap_hold_max_s after the gap (0: no hold).
  // Measured (jimenez-building, 3 laps, seed 5, a 10 s gap at 40 %): released at σ_before
  // after 54 s, RMSE 0.204 m; no hold 0.236 m; no gap 0.235 m. (Before the readings inside a
  // gap were interpolated across it, ins_graph.h: held 0.296 m, no hold 1.48 m.)
  double gap_hold_max_s = 60.0;
  double gap_release_yaw_sigma_rad = 0.05;
  // While held, each update's solve may take up to this many LM iterations
  // (FixedLagSmoother::Options::held_max_iterations): the states after a gap start from the
  // heading before it and a solve cut at window_max_iterations leaves them there (a gap that
  // holds a 90° turn, jimenez-building, 8 seeds at each of two gap positions: fg-ins-window
  // 8.5x / 7.2x its nominal RMSE with 10 iterations, 2.06x / 1.99x with 100).
  int gap_max_iterations = 100;

  // Every rule the YAML reader applies (and graph.Validate()); the window's Run refuses options
  // that break one. Messages are prefixed with `context`.
  Status Validate(const std::string& context = "fg-ins-window") const;
};

class InsGraphWindow : public Estimator {
 public:
  explicit InsGraphWindow(InsWindowOptions options) : options_(std::move(options)) {}
  Status CheckApplicable(const Walk& walk) const override;
  StatusOr<EstimateResult> Run(const Walk& walk) const override;

 private:
  InsWindowOptions options_;
};

}  // namespace walkgraph

#endif  // WALKGRAPH_SMOOTHERS_INS_WINDOW_H_
