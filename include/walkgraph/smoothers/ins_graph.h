// The foot-mounted INS factor graph (estimator id "fg-ins-batch") and its building blocks.
//
// States x_k = (p_k, v_k, q_k, b_g,k, b_a,k) at stance epochs (mid-stance: the ZUPT sample
// nearest the middle of every stance phase of the stride front end, strides.h — the phase's
// edges hold the slow ends of the swing, and a state there biased the strides by ≈2 cm each
// on jimenez-building) or every N IMU samples; the first IMU sample and the last one are
// always states, and no two states are more than max_state_interval_s apart. Factors
// (factors/):
//   ImuPreintegrationFactor  between consecutive states (Forster et al. 2017 eq. 45),
//   BiasRandomWalkFactor     b_j − b_i for the gyro and the accelerometer biases,
//   ZuptFactor               v_k = 0 at a state inside a stance (ZUPT sample of the front end),
//   StanceLevelFactor        R(q_k)ᵀ·g = f̄ − b_a,k over the ZUPT samples around a ZUPT state,
//   ZaruFactor               ω̄ − b_g,j = 0 with ω̄ the mean gyro over the still samples of
//                            (t_i, t_j] (σ = zaru_sigma/√m); ZARU and the preintegration use
//                            the same readings, a small double count the EKF makes as well,
//   InsPriorFactor           the gauge: position and yaw of the first state,
//   BiasPriorFactor          turn-on bias priors on the first state (data-sheet bias stability),
//   RssFactor<3>             each rss.csv reading, dB domain, path loss (A, η) of walk.yaml held
//                            constant, Cauchy loss (the integrator's factors/rss_factor.h),
//   RangeFactor<3>           each range.csv reading, σ = radio.range_sigma_m, Cauchy loss,
//                            per-anchor additive bias constant 0 or estimated (option),
//   PositionPriorFactor<3>   each waypoints.csv point on the foot's (x, y) at its time.
// Cost: Σ ‖r‖², one FactorGraph (graph.h; keys x(i), v(i), q(i), g(i), a(i) of state i) solved
// by SolveBatch with SPARSE_NORMAL_CHOLESKY (single-threaded, hence the same output for the
// same input), as fg-ins-window feeds the same states and factors to the FixedLagSmoother. Gauge:
// without radio, position (3) and yaw (1) are unobservable; the InsPriorFactor on the first state
// fixes them from walk.yaml initial_pose (its x, y, heading and σ; z = 0 with σ initial_sigma_z_m),
// or without one at the origin with yaw = the front end's initial yaw and σ = gauge_sigma_m /
// gauge_sigma_yaw_rad (then the output is in an arbitrary frame: score it with --align-se2).
// Initialization (option `initialization`): "window" (default), every state's lagged estimate
// from a fast fg-ins-window pass over the same graph (ins_window.h), itself started from the
// front end; "front-end", every state from the ZUPT-aided INS of the front end at its sample
// (p, v, q, biases). Relinearization: the preintegrations use the biases of their first state as b̄;
// after a solve, if some b_i moved from b̄ by more than relinearize_*, the preintegrations are
// rebuilt at the new estimate and the problem solved again (at most max_relinearizations).
// Output: a pose every 1/output_rate_hz and at every state. Between states i and j the IMU is
// integrated from state i with its biases (strapdown.h) and the end mismatch to state j is
// spread linearly in time: p(t) = p_fwd(t) + α·(p_j − p_fwd(t_j)), likewise the yaw,
// α = (t − t_i)/(t_j − t_i). Covariance of (x, y, yaw) per state from the banded chain solver
// (chain_covariance.h; ceres::Covariance if the graph is not chain-shaped) in the tangent space
// of NavQuaternionManifold (δ_z is the yaw), linearly interpolated between states; when the
// covariance cannot be computed (rank deficiency) the trajectory comes without it and
// diagnostics["covariance_ok"] = 0.
//
// Incremental use (the fixed-lag smoother): the graph is a chain, and every factor is made by
// one of the factor makers of src/smoothers/ins_graph_internal.h from the states, a segment
// k..k+n at a time, so a window adds, for new states k+1..k+n after state k, the factors of
// that segment and the radio readings of (t_k, t_{k+n}] (and t_0 when k == 0); InsKeyMap there
// is the one mapping of the states' and the walk-wide blocks to the graph's keys.
//
// Radio readings between states a and b are received at (1 − α)·p_a + α·p_b
// (receiver_position.h) with α the progress along the front end's path at the reading's time,
// α = clamp((p̃(t) − p̃_a)·(p̃_b − p̃_a)/‖p̃_b − p̃_a‖²), not the time fraction: between mid-stance
// states the foot stands still for half the time. Across an IMU gap the front end's path
// stands still, so there α is the time fraction (the bridge's own assumption: walking on at
// constant pace). A reading at α < 1e-3 (> 1 − 1e-3) is tied
// to state a (b) alone. Anchors are lowered by receiver_offset_z_m (distance from p + offset·ẑ
// to a = distance from p to a − offset·ẑ). Without initial_pose but with radio, the gauge comes
// from the anchors and the first state gets no position/yaw prior (the initial guess is then
// the front end's arbitrary frame, which Ceres must rotate into the anchors' one).
#ifndef WALKGRAPH_SMOOTHERS_INS_GRAPH_H_
#define WALKGRAPH_SMOOTHERS_INS_GRAPH_H_

#include <string>
#include <vector>

#include "walkgraph/estimator.h"
#include "walkgraph/graph.h"
#include "walkgraph/smoothers/graph_options.h"
#include "walkgraph/status.h"
#include "walkgraph/strides.h"
#include "walkgraph/walk.h"

namespace walkgraph {

enum class InsStatePlacement { kStance, kEveryN };

struct InsGraphOptions {
  // Stance detection, IMU noise model (also the preintegration's) and the initial solution.
  // The gyro white noise is 0.01 rad/s, not the front end's 0.0055 (the presets' true value):
  // it also stands for what the model leaves out (scale factor, g-sensitivity, heel-strike
  // vibration). Measured (issue 21, adaptive stance): PyShoe 11-22-03 0.045 → 0.036 m,
  // 11-48-35 0.054 → 0.051 m; jimenez-building / prieto-laps seeds 1–3 within ±2 %.
  StrideOptions front_end = [] {
    StrideOptions s;
    s.gyro_noise_radps = 0.01;
    return s;
  }();
  InsStatePlacement placement = InsStatePlacement::kStance;
  int every_n_samples = 20;
  double max_state_interval_s = 2.0;  // more states inside longer gaps (standstills)
  double zupt_sigma_mps = 0.01;       // OpenShoe's ZUPT σ
  // Robust loss of the ZUPT factors: a stance detected inside a swing (|v|/σ ~ 100 there)
  // then costs little instead of stopping the foot, while a planted foot (|v| below ~scale·σ)
  // keeps OpenShoe's quadratic ZUPT; the scale is in σ of the whitened residual (10σ = 0.1 m/s
  // at the default σ). Measured (jimenez-building 3 laps, 8 seeds, a detector made to
  // over-detect: adaptive_fraction 0.8): quadratic fg-ins-batch 0.94–1.17 m RMSE, fg-ins-window
  // 0.60–1.09 m; cauchy 10σ within 0.005 m of the right detector's (0.15–0.40 m), which it
  // leaves unchanged (8 seeds, prieto-laps, PyShoe trials ±0.001 m). Cauchy 3σ lost the ZUPTs
  // of real stances on a PyShoe trial (0.036 → 0.123 m). ZARU stays quadratic. With stance
  // placement every detected stance interval is one state with one ZUPT, so this is the stance
  // hypothesis per interval that the solve can turn down: a robust kernel such as Cauchy is a
  // weight (switch) variable per factor eliminated in closed form (Black and Rangarajan, IJCV
  // 1996; Agarwal et al., ICRA 2013, show it for switchable constraints).
  LossKind zupt_loss = LossKind::kCauchy;
  double zupt_loss_scale = 10.0;
  bool use_zaru = true;
  double zaru_sigma_radps = 0.0055;  // per reading (the gyro white noise); ÷√m for m readings
  // Levelling at every ZUPT state (factors/stance_level_factor.h): the mean accelerometer over
  // the middle half of the run of ZUPT samples around the state (within max_state_interval_s / 2)
  // is gravity; σ² per axis = w²/m + max(0, spread² − w²) for m readings of RMS spread about
  // their mean, w² = σ_a² + (s·g)² (σ_a = front_end.acc_noise_mps2, s the front end's scale
  // noise there); the ZUPT's loss. One ZUPT per stance state leaves the tilt to the swings'
  // preintegrations, which a ZUPT-aided EKF gets from its ZUPT at every stance sample; without
  // a standstill (no ZARU) the gyro bias about the foot's vertical then went unobserved:
  // simulated jimenez-building walks that start in motion, IMU alone, fg-ins-batch 0.137 /
  // 0.095 -> 0.045 / 0.067 m, fg-ins-window 2.86 / 0.95 -> 0.052 / 0.064 m (docs/results.md).
  bool use_stance_level = true;
  // Across an IMU gap the bridge allows any rotation and walking speed (the IMU says nothing
  // there). Two factors tie the states either side with what the walk itself shows, learnt on
  // the front end's path over the 300 s before the gap (causal, so the window's online output
  // uses them too) from spans as long as the gap, starting every 0.5 s; none with fewer than
  // gap_min_spans:
  // - use_gap_reach: the horizontal distance is at most the reach L, the 90th percentile of the
  //   path length walked in those spans (spans of at least 0.1 m/s), one-sided, σ = 1.4826 ·
  //   MAD of those lengths, at least 5 % of L + 0.05 m (factors/gap_reach_factor.h);
  // - use_gap_magnetometer (walks whose IMU has a magnetometer): the field's horizontal
  //   direction in the navigation frame is the same either side
  //   (factors/magnetic_heading_change_factor.h), σ = the RMS of that direction's change over
  //   those spans about their median (indoor disturbances are local, heavy-tailed), at least
  //   gap_magnetic_min_sigma_rad, under a Cauchy loss at 1σ.
  // Measured (jimenez-building, 3 laps, a 10-s gap at 40 % of the walk, on a straight leg; mean
  // RMSE over seeds 1-8 against the same walks without the gap, CLI): fg-ins-window-online
  // 1.76x -> 1.42x, fg-ins-window 1.26x -> 1.24x, fg-ins-batch 1.23x -> 1.22x. With the gap
  // in a turn (seeds 1-3) online 4.44x -> 4.24x: the reach bound is inactive there.
  // Robustness.FootInsGraphBridgesAnImuGap: its first 3 seeds online 2.48x -> 2.13x; its 8
  // seeds 1.69x.
  bool use_gap_reach = true;
  bool use_gap_magnetometer = true;
  double gap_magnetic_min_sigma_rad = 0.01;
  int gap_min_spans = 20;
  // use_stance_magnetometer (walks whose IMU has a magnetometer): at a stance state the
  // reading, rotated by the state's attitude, points along the field's horizontal direction,
  // one walk-wide angle ψ_f estimated with the states (factors/magnetic_heading_factor.h: 004's
  // compass at stance with the reference learnt, not given), so the yaw cannot drift over a long
  // walk. Indoor disturbances are local and the same at one place: readings closer than
  // stance_magnetic_spacing_m are taken as one, so a factor is added only at a stance at least
  // that far (on the front end's path) from the last one with a factor — taken as independent,
  // every stance's factor bent the headings along a disturbed leg (jimenez-building stairs,
  // 8 laps, seeds 1/2/5/8, fg-ins-batch RMSE with a factor at every stance 0.143/0.217/0.148/
  // 0.155 m, none 0.181 m on seed 2; at 3 m spacing 0.159/0.160/0.154/0.153). σ is learnt from
  // the walk, causally (the window's online output uses the factor too): on the front end's
  // path, the change of the field's direction between each stance and the last one at least
  // stance_magnetic_spacing_m away (within stance_magnetic_pair_max_s, so the front end's own
  // yaw drift stays small), its RMS about the median over the pairs before the state, ÷√2
  // (either end disturbed), at least stance_magnetic_min_sigma_rad, under a Cauchy loss at 1σ
  // (heavy-tailed disturbances); no factor before stance_magnetic_min_pairs such pairs.
  bool use_stance_magnetometer = true;
  double stance_magnetic_min_sigma_rad = 0.01;
  double stance_magnetic_spacing_m = 3.0;
  double stance_magnetic_pair_max_s = 20.0;
  int stance_magnetic_min_pairs = 20;
  bool use_bias_prior = true;       // N(0, front_end.*_bias_sigma²) on the first state
  double initial_sigma_z_m = 0.01;  // start height prior (z = 0)
  double gauge_sigma_m = 1e-3;      // without initial_pose: the arbitrary origin's σ
  double gauge_sigma_yaw_rad = 1e-3;
  double output_rate_hz = 20.0;
  bool compute_covariance = true;
  int max_iterations = 100;
  // Initial values of the batch: "front-end" (the ZUPT-aided INS at each state) or "window"
  // (the lagged states of a fast fg-ins-window pass, ins_window.h: lag init_lag_s, states
  // leaving in batches of init_marginalize_batch_s, no covariances). The front end's yaw and
  // position drift grows with the walk and the batch must undo it: from the front end LM took 31
  // iterations on a 16-min prieto-laps walk and 173 on 1 h; the window grows the solution
  // incrementally and hands the batch a start near its optimum.
  InsInitialization initialization = InsInitialization::kWindow;
  double init_lag_s = 10.0;
  double init_marginalize_batch_s = 1.0;
  // LM's starting trust-region radius (Ceres' default 1e4 damps a long chain's soft modes).
  double initial_trust_region_radius = 1e8;
  // Ceres' stopping rules (its defaults; the fixed-lag version uses the first two as well).
  double function_tolerance = 1e-6;
  double parameter_tolerance = 1e-8;
  double gradient_tolerance = 1e-10;
  int max_relinearizations = 2;
  double relinearize_gyro_bias_radps = 2e-3;
  double relinearize_acc_bias_mps2 = 0.02;
  // Radio: the walk's rss.csv (RssFactor<3>, dB domain, path loss = walk.yaml radio, held
  // constant) and range.csv (RangeFactor<3>, σ = radio.range_sigma_m), robust losses
  // (huber|cauchy|none, scale in σ of the whitened residual).
  bool use_rss = true;
  bool use_ranges = true;
  double receiver_offset_z_m = 0.0;  // receiver above the IMU (jimenez-building sim: 1 m)
  // Cauchy at 1σ: on prieto-laps (30 % NLOS, +6 dB / +3 m) 2-lap RMSE 0.38 m vs 0.62 m with
  // Huber at 2σ (mean of 4 seeds); jimenez-building unchanged (0.18 m). RSS at 2σ (issue 21,
  // 1-lap presets, seeds 1–3, adaptive stance): jimenez-building 0.210/0.212/0.176 →
  // 0.158/0.204/0.180 m (its shadowing is log-normal: Cauchy at 1σ throws away half the weight of
  // a 1σ reading), prieto-laps 0.317/0.231/0.251 → 0.337/0.259/0.263 m (its NLOS outliers
  // still get Cauchy's down-weighting); Huber at 2σ there 0.375/0.302/0.287 m. Kept at 1σ: on
  // jimenez-building, 3 laps, seeds 300–301 (the causal GLRT stance), 2σ gave fg-ins-batch
  // 0.164 vs 0.163 m, fg-ins-window 0.247 vs 0.233 m and its online output 0.324 vs 0.297 m.
  LossKind rss_loss = LossKind::kCauchy;
  double rss_loss_scale = 1.0;
  LossKind range_loss = LossKind::kCauchy;
  double range_loss_scale = 1.0;
  bool estimate_range_bias = false;  // per-anchor additive range bias, prior N(0, σ²)
  double range_bias_sigma_m = 1.0;
  // Path loss (A, η) of the RSS factors, as the step graph's (StepGraphOptions::path_loss):
  // fixed | global (one block, prior mean walk.yaml's values, σ A_prior_sigma_db,
  // eta_prior_sigma) | hierarchical (one block per anchor tied to a walk-wide mean by
  // σ A_spread_prior_db, eta_spread_prior; the mean has the weak prior) | auto (the default):
  // global unless the walk declares its radio calibrated (radio.calibrated), which holds
  // walk.yaml's values. Not hierarchical outright here, unlike the step graph: measured on
  // jimenez-building (1 lap), anchors spread ±4 dB / ±0.4 (seeds 1–3): global 0.515 m,
  // hierarchical 0.189 m; identical anchors, η declared ×0.5 (seed 1): global 0.152 m,
  // hierarchical 0.265 m — the foot INS is precise enough that per-anchor freedom costs more
  // than it gains unless the anchors do differ. So fg-ins-batch lets the data say: after the
  // global solve, the anchors' mean residuals are tested against one shared model (a χ² test,
  // internal::TestAnchorOffsets) and the graph is solved again per anchor when they disagree
  // at path_loss_anchor_test_z (the normal quantile of the test's level: 3.09, p = 0.001;
  // 0: never). Measured (seed 1): identical anchors T = 54 for 66 anchors (critical 105),
  // spread T = 9,949. fg-ins-window keeps global (it cannot solve its past again).
  PathLossMode path_loss = PathLossMode::kAuto;  // not kPerAnchor
  double A_prior_sigma_db = 10.0;
  double eta_prior_sigma = 1.0;
  double A_spread_prior_db = 4.0;
  double eta_spread_prior = 0.4;
  double path_loss_anchor_test_z = 3.09;

  // A user's own factors (graph.h UserFactorsFn), for fg-ins-batch and fg-ins-window alike:
  // pose k of the hook is state k, keys x(k) its position (x, y, z: 3-D), v(k) velocity,
  // q(k) attitude (x, y, z, w; NavQuaternionManifold), g(k) gyro bias, a(k) accelerometer bias.
  UserFactorsFn user_factors;

  // Every rule the YAML reader applies; the estimators' Run refuses options that break one.
  Status Validate() const;
};

// fg-ins-batch.
class InsGraphBatch : public Estimator {
 public:
  explicit InsGraphBatch(InsGraphOptions options) : options_(std::move(options)) {}
  Status CheckApplicable(const Walk& walk) const override;
  StatusOr<EstimateResult> Run(const Walk& walk) const override;

 private:
  InsGraphOptions options_;
};

}  // namespace walkgraph

#endif  // WALKGRAPH_SMOOTHERS_INS_GRAPH_H_
