// The step-level factor graph and its smoothers: fg-batch, fg-batch-selfcal, fg-window.
//
// Graph. Node k = 0..N at time t_k: position p_k ∈ R² and heading θ_k (AngleManifold). Node 0
// is the walk's start; node k ≥ 1 ends step k−1 of the shared StepSequence (StepsForWalk:
// PDR steps, foot-IMU strides or odometry increments). Factors:
//   StepFactor(p_{k−1}, p_k, θ_k)            step length along the step's heading
//   HeadingIncrementFactor(θ_{k−1}, θ_k [, b_g])  gyro heading change, optional constant gyro
//                                                 bias b_g (estimated, weak prior)
//   HeadingFactor(θ_k)                        per-step magnetometer heading (robust), optional
//   OdometryFactor(p_{k−1}, θ_{k−1}, p_k, θ_k)  instead of the two above for odometry walks
//   RssFactor / RssRangeFactor / ScaledRangeFactor  every radio reading, received at the position
//                                             interpolated between the two nodes around it
//   PositionPriorFactor(p_a [, p_b])          each waypoints.csv point, interpolated the same way
//   priors                                    initial pose (walk.yaml initial_pose), path loss,
//                                             range bias, gyro bias (ceres::NormalPrior)
// A step moves the walker only during the last max_step_duration_s before its node; a reading
// in the pause before that is received at the previous node (stops are not smeared).
// A walk without steps (radio only, e.g. the BLE tracks) gets a node per radio epoch of
// radio_epoch_s and PositionRandomWalkFactor(p_{k−1}, p_k) as its motion model; headings are
// not states there (held at 0; their output variance is π²/3).
// Path loss: a constant (A, η) block (the walk's radio model) — or, self-calibrating, one free
// block for the walk or one per anchor with a weak prior. Ranges: ρ = (1 + s)·d + b (002 eq. 6)
// with a bias block b per anchor and a scale block s for the walk (Plaza-style ranging radios
// read long, and longer with distance) — each free with a weak prior, or held at 0.
// Robust losses per factor type (none | huber | cauchy | soft-l1 | arctan | tukey, scale in σ).
//
// Anchors of unknown position (anchors.csv x_m, y_m empty) and uncertain ones (sigma_m > 0):
// their horizontal position is a state p(a), an uncertain one with the prior N(position,
// sigma_m²) per axis (AnchorRssFactor / AnchorRangeFactor instead of the fixed-anchor factors).
// fg-batch places the unknown ones without a guess: (1) the walk solved without them (and
// without the uncertain ones); (2) each unknown one placed on that path by a coarse grid search
// over its extent plus a margin (anchor_search.h: the robust range or RSS cost, the anchor's
// bias or transmit power at its median), or declared unobservable (too few readings, a path too
// narrow around it, or two places that explain its readings about as well) and left out with
// its readings; (3) one joint solve from (1)'s nodes, kept only where it moves the walk within
// (1)'s covariance (median shift NEES ≤ 13.82, χ²(2) at 99.9 %); beyond, the anchors that
// are not surveyed contradict those that are, and (1) is the answer, all of them left out
// ("inconsistent"; src/smoothers/unknown_anchors.h). Diagnostics: unknown_anchors (the anchors
// not surveyed: unknown or uncertain), unknown_anchors_estimated, unknown_anchors_unobservable
// (+ .few_readings / .narrow_geometry / .ambiguous / .inconsistent), unknown_anchors_shift_nees,
// unknown_anchor_readings_ignored, anchor_x_m.<id> / anchor_y_m.<id>, gauge (0 the known
// start's frame, 1 the anchors' of given position, 2 the walk's own: node 0 held); each
// anchor's estimate and covariance in EstimateResult::anchors. fg-window (both outputs) places
// them causally by delayed initialization (src/smoothers/step_graph_pending.h: the same search
// over the readings so far, the anchor joining the window once placed with σ ≤
// window_anchor_max_sigma_m); an uncertain one waits the same way and joins with its prior
// once the search places it where that prior allows (χ²(2) at 99.9 %); the other estimators run
// without the unknown anchors (the registry's wrapper, estimator.h) and use uncertain ones at
// their mean (the filters).
// Gauge: with a known start (initial_pose) its prior fixes position and heading softly; with
// no start but radio anchors the anchors fix the frame; with neither, node 0 is held constant
// (the only gauge freedom of a dead-reckoning graph is its start pose).
// Initialization: dead reckoning from the known start; without one, dead reckoning aligned by
// the best rotation + translation (Umeyama) to the radio position fixes of the first
// align_window_s seconds. fg-batch may restart from fg-window's estimates (`initialization`).
//
// fg-batch: every node and reading in one Ceres problem (SPARSE_NORMAL_CHOLESKY, SuiteSparse),
// marginal covariances of (x, y, θ) per node by ceres::Covariance (when that fails — rank
// deficiency — the trajectory comes back without covariances and diagnostics say so).
// fg-window: the same factors fed node by node to FixedLagSmoother (lag in seconds); the
// "lagged" output is each node's estimate when it leaves the window, the "online" output each
// node's estimate right after the update that added it (data up to its own time only).
#ifndef WALKGRAPH_SMOOTHERS_STEP_GRAPH_H_
#define WALKGRAPH_SMOOTHERS_STEP_GRAPH_H_

#include <limits>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "walkgraph/estimator.h"
#include "walkgraph/pdr.h"
#include "walkgraph/smoothers/fixed_lag_smoother.h"
#include "walkgraph/smoothers/graph_options.h"

namespace walkgraph {

struct StepGraphOptions {
  PdrOptions pdr;  // the shared front end (YAML child "pdr")

  // Motion model.
  double sigma_cross_m = 0.05;        // StepFactor lateral σ per step
  double step_sigma_scale = 1.0;      // × Step::sigma_length_m
  double dheading_sigma_scale = 1.0;  // × Step::sigma_dheading_rad
  double min_sigma_length_m = 0.01;   // floors
  double min_sigma_dheading_rad = 1e-3;
  double max_step_duration_s = 1.0;
  // Walks without steps (no odometry, no IMU): a node per radio epoch, random-walk motion.
  double radio_epoch_s = 0.5;
  double motion_sigma_mps = 1.0;  // PositionRandomWalkFactor σ_v
  // A step across an IMU gap (Walk::ImuGaps) is bridged: displacement N(0, (bridge_speed_mps ×
  // Δt)²) per axis and a free heading change (σ π), instead of integrating across the hole.
  double bridge_speed_mps = kImuGapSpeedMps;
  bool estimate_gyro_bias = true;  // constant vertical gyro bias in heading increments
  double gyro_bias_prior_sigma_radps = 0.02;
  // One step-length scale c for the walk (state c(0)): each step factor's length is (1 + c)·l,
  // l the front end's (e.g. Weinberg's K·(a_max − a_min)^¼, whose K varies from walker to
  // walker), with a prior N(0, step_scale_prior_sigma²). 0.2: Weinberg's K spans 0.40-0.55
  // across the papers' walkers (000 Sec. IV 0.45; the handheld-phone preset walks with 0.40).
  // Radio or waypoints make it observable; alone, the steps leave it at its prior. Diagnostic
  // step_length_scale (1 + c). Off by default: the radio's own biases (censored weak readings,
  // NLOS) then shrink the walk. fg-batch, 10 runs from seed 1: handheld-phone 0.680 -> 0.383 m
  // RMSE (its scale found at 0.89-0.90 for the true 0.889), but tarrio-circle 0.332 -> 0.459
  // (scale 0.94-0.96 where the steps are right), correa-corridor 0.315 -> 0.342 and
  // two-floor-building 0.643 -> 1.236 m.
  bool estimate_step_scale = false;
  double step_scale_prior_sigma = 0.2;
  // fg-window (and fg-batch's window initialization) on PDR steps without an absolute heading
  // (no step with a magnetometer heading): the gyro bias held at 0 unless this is set. Without
  // a heading reference a window cannot tell a bias from the few radio readings it holds
  // bending the path, and its marginalization prior keeps what it took (issue 41: IPIN trial
  // 01, magnetometer dropped, the window's bias went to +0.0125 rad/s against fg-batch's
  // −0.0037 and its p75 to 27.2 m; held: 13.3 m; hip presets without magnetometer, 5 seeds:
  // tarrio-circle 0.89x, two-floor-building 0.92x). Not foot strides: the
  // foot INS tracks its gyro bias at every stance, and the window's residual bias helps there
  // (jimenez-building-8tags held: 1.07x). fg-batch sees the whole walk and keeps estimating it.
  bool window_gyro_bias_without_heading = false;
  bool use_mag_heading = true;  // HeadingFactor per step when the steps carry it
  double mag_heading_sigma_rad = 0.35;
  LossKind mag_heading_loss = LossKind::kCauchy;
  double mag_heading_loss_scale = 1.0;
  // Odometry walks: OdometryFactor σ (the odometry-dr defaults).
  double odometry_sigma_dist_frac = 0.05;
  double odometry_sigma_dist_m = 0.001;
  double odometry_sigma_cross_m = 0.01;
  double odometry_sigma_dheading_rad = 0.01;

  // Floors (walks with pressure.csv): a height z_k per node, barometric height changes
  // between consecutive nodes (BarometricHeightFactor, σ² = 2·baro_sigma_m² + baro_drift_m2ps·Δt,
  // each node's pressure the mean of the readings within ±baro_window_s/2), the start height
  // at the start floor (initial_pose.floor; floor 0 when the walk does not give it) with σ
  // start_height_sigma_m, level walking steps and floor levels (level_sigma_m,
  // floor_sigma_m below); each node's floor is its height over walk.yaml storey_height_m,
  // rounded. The readings' receiver heights (and floors) are the height chain's causal
  // estimate (StepGraph::Impl::ChainHeights). A phone barometer's noise is ~0.02–0.03 hPa (≈ 0.2
  // m); indoor drift (weather, air conditioning) ~1 hPa per hour (≈ 2 mm/s, as a random walk 0.5 m
  // over 100 s). Datasheet and textbook figures, not fitted on a walk.
  bool floors = true;
  double baro_sigma_m = 0.25;
  double baro_drift_m2ps = 0.0025;
  double baro_window_s = 1.0;
  double start_height_sigma_m = 0.5;
  // Stairs: a step during which the barometric height changes faster than stair_rate_mps
  // (over stair_window_s around it) is a stair step, and moves the walker one tread,
  // stair_tread_m (σ stair_tread_sigma_m), horizontally instead of the PDR step length (a
  // walking step is ~0.7 m, a stair's tread ~0.28 m: Blondel's 2·rise + tread ≈ 0.63 m with
  // a 0.17 m rise). Climbing or descending stairs takes ~0.3 m/s of height (one 0.17 m rise
  // per ~0.6 s step); 0.1 m/s keeps the barometer's noise (0.25 m over 3 s) out. Lifts and
  // escalators give no steps. Only runs of such steps one way that change the height by
  // stair_min_rise_storeys × storey_height_m (a floor transition; half a storey also takes
  // a mezzanine) count: a phone lifted or lowered in the hand moves it ~0.5 m at that rate
  // (IPIN trials 01/05/21, flat: runs of ≤ 2.5 s at 0.1–0.18 m/s). stairs: false keeps the PDR
  // lengths (the staircases are still found: their steps get no level factor, below).
  bool stairs = true;
  double stair_rate_mps = 0.1;
  double stair_window_s = 3.0;
  double stair_tread_m = 0.28;
  double stair_tread_sigma_m = 0.1;
  double stair_min_rise_storeys = 0.5;
  // Flights joined by a landing: runs of stair steps one way, each starting within
  // stair_landing_s of the previous one's end, count as one staircase (a U-turn landing is
  // walked in ~3–6 s, and the 3-s window leaves a flight's first and last step out; its steps
  // keep their PDR lengths).
  double stair_landing_s = 10.0;
  // Level walking: a walking step (one of at most max_step_duration_s, not across an IMU gap)
  // that is not a stair step keeps the height, Δz ~ N(0, level_sigma_m²) beside the
  // barometric factor, so the barometer's drift (weather: ~1–2 hPa, ≈ 8–17 m, per hour)
  // leaves the height between staircases and the floor follows the stairs only. 0.05 m per
  // step: a 1:12 ramp (the steepest wheelchair ramp) rises 0.06 m per 0.7 m step. Ramps, lifts
  // and escalators change the height through the barometric factor alone (no walking steps
  // on a lift; a ramp's rise is mostly held back). 0 turns it off.
  double level_sigma_m = 0.05;
  // Floors are levels: a level walking step's node whose height (the chain's causal estimate)
  // lies within floor_snap_storeys × storey of a floor's level f × storey_height_m is held
  // there, σ floor_sigma_m per node, so the height errors of the staircases (the barometer's
  // noise and drift over each, ~0.2–0.4 m) do not add up from floor to floor. Landings and
  // mezzanines near half a storey are left alone. floor_sigma_m 0 turns it off.
  double floor_sigma_m = 0.5;
  double floor_snap_storeys = 0.25;

  // Radio.
  // db (RssFactor) | range (RssRangeFactor, 004 eq. 7).
  RssResidual rss_residual = RssResidual::kDb;
  // Cauchy at 0.5σ: with 20 % NLOS readings 15 dB low (tarrio-circle) the RMSE rises 1.16×
  // over clean data, against 1.88× for Huber at 2σ, and clean data lose nothing (0.332 vs
  // 0.343 m); measured, see docs/results.md.
  LossKind rss_loss = LossKind::kCauchy;
  double rss_loss_scale = 0.5;  // in σ (residuals are whitened)
  LossKind range_loss = LossKind::kCauchy;
  double range_loss_scale = 2.0;
  double receiver_height_m = 0.0;  // receiver z for the planar graph
  double range_sigma_m = 0.0;      // > 0: overrides walk.meta.radio.range_sigma_m
  // The path-loss model (RSS = A − 10η·log10(d/d0) + N(0, σ²)): the walk's radio defaults,
  // unless set here (> 0; A any finite value). With self-calibration it is the prior mean and
  // the starting value.
  double A_dbm = std::numeric_limits<double>::quiet_NaN();
  double eta = 0.0;
  double sigma_db = 0.0;
  // Self-calibration: auto | fixed | global | per-anchor | hierarchical.
  //   fixed: the walk's (A, η) (or the values above) held.
  //   global: one (A, η) block for the walk, prior mean the walk's values (σ A_prior_sigma_db,
  //     eta_prior_sigma).
  //   per-anchor: one block per anchor, each with that weak prior.
  //   hierarchical: one block per anchor, each tied to a walk-wide mean block m(0) by
  //     (A_a − A_m, η_a − η_m) ~ N(0, diag(A_spread_prior_db², eta_spread_prior²)); the mean
  //     has the weak prior. An anchor heard often gets its own model; one heard a few times
  //     shrinks to the mean (where the data cannot separate the anchors, it is the global
  //     model). tarrio-circle, anchors spread ±4 dB / ±0.4 (6 seeds, fg-batch mean RMSE):
  //     global 1.281 m, hierarchical 0.374 m; identical anchors 0.329 vs 0.363 m (the test
  //     StepGraphSelfCalibration.AnchorsThatDifferGetTheirOwnPathLoss).
  //   auto (the default): fixed when the walk declares its radio calibrated (walk.yaml
  //     radio.calibrated: true), else hierarchical — except where the walk cannot identify the
  //     path loss: on a radio-only walk (no steps, no odometry) nothing fixes the scale of the
  //     motion, and η trades against the distances (BLE straight_04, 10.5 m: estimated 10.5 m
  //     RMSE against 2.2 m held), so it is held there and diagnostics say so
  //     (path_loss_held_radio_only = 1).
  // diagnostics: path_loss_estimated = 1 when (A, η) were estimated; path_loss_A /
  // path_loss_eta the walk-wide estimate (global, or hierarchical's mean), path_loss_A.<id> /
  // path_loss_eta.<id> each anchor's (per-anchor, hierarchical).
  PathLossMode path_loss = PathLossMode::kAuto;
  double A_prior_sigma_db = 10.0;
  double eta_prior_sigma = 1.0;
  // hierarchical: how far one anchor's (A, η) may sit from the walk's mean (1σ). Spreads
  // between BLE beacons of one model are a few dB in A (transmit power, mounting) and a few
  // tenths in η (surroundings); chosen from that, not tuned on a walk.
  double A_spread_prior_db = 4.0;
  double eta_spread_prior = 0.4;
  CalibrationScope range_bias = CalibrationScope::kPerAnchor;  // none | global | per-anchor
  double range_bias_prior_sigma_m = 5.0;
  CalibrationScope range_scale = CalibrationScope::kGlobal;  // ρ = (1 + s)·d + b
  double range_scale_prior_sigma = 0.1;

  // Anchors of unknown position (fg-batch; walk.h Anchor, "Anchors of unknown position" at the
  // top of this file): the grid search over the path's extent plus anchor_search_margin_m at
  // anchor_search_step_m (refined to a tenth), and the verdict "unobservable" for an anchor
  // with fewer than anchor_min_readings readings, a path that spreads less than
  // anchor_min_spread_m (1σ) across its narrowest direction at its readings, or a second grid
  // minimum farther than anchor_distinct_radius_m within anchor_min_cost_gap of the best
  // (χ²(2) at 99 %: the two places are not told apart). Our choices, not tuned on a walk.
  double anchor_search_margin_m = 20.0;
  double anchor_search_step_m = 1.0;
  int anchor_min_readings = 10;
  double anchor_min_spread_m = 1.0;
  double anchor_distinct_radius_m = 5.0;
  double anchor_min_cost_gap = 9.21;
  // fg-window places an unknown anchor once its readings so far place it (the search above,
  // over the receivers where the window put them) with a position σ (the search region's
  // largest axis) of at most this; earlier, a place that the window cannot revise later (its
  // past receivers are marginalized) pulled the path: tarrio-circle, half the anchors unknown,
  // 12 seeds, fg-window 1.09× the surveyed RMSE placing at once, 1.01× with 3 m
  // (step_graph_pending.h; docs/results.md). Our choice, measured on the simulator only.
  double window_anchor_max_sigma_m = 3.0;

  // Initialization and solver. fg-batch starts from dead reckoning ("dead-reckoning"), from
  // the lagged estimates of a fast fixed-lag pass ("window": lag init_lag_s, one update per
  // init_update_s), or ("auto") from dead reckoning for odometry walks and the window for IMU
  // steps, whose gyro heading drift leaves dead reckoning in a wrong basin.
  double align_window_s = 30.0;
  // A known start heading checked against the radio (StepGraph::Impl::CheckStartHeading): left
  // out when the dead reckoning of the first align_window_s, aligned to the radio fixes there,
  // turns by more than max(start_check_rad, start_check_sigmas × σ_heading). Measured on
  // Plaza1 (fg-window RMSE by start heading error): 30° 0.281, 60° 0.296, 90° 0.331,
  // 120° 1.875, 180° 20.8 m (0.279 m right): the solver recovers up to ~90° by itself, so the
  // check leaves smaller errors to it and the prior.
  bool start_check = true;
  double start_check_rad = 1.0471975511965976;  // 60°
  double start_check_sigmas = 5.0;
  StepGraphInit initialization = StepGraphInit::kAuto;
  double init_lag_s = 20.0;
  // fg-batch on a walk with no start (no walk.yaml initial_pose) but radio: besides its own
  // initialization, the dead reckoning aligned by rotation + translation (Procrustes/Umeyama) to
  // every radio fix of the walk, turned by k·360°/start_hypotheses (k = 0..n−1) about its
  // centroid, each solved; the lowest final cost wins (diagnostics start_hypothesis: 0 its own
  // initialization, k + 1 the k-th turn; start_hypothesis_cost.k). 0: its own only. Our choice
  // (issue 41: a short first window of fixes leaves the start heading ambiguous). On a start of
  // known position but no heading, with steps of relative heading (no magnetometer): the dead
  // reckoning turned by k·360°/start_hypotheses about the start, for fg-batch (k = 0..n−1)
  // and fg-window's first window (k = 1..n−1 besides its own; StartHeadingTurns).
  int start_hypotheses = 4;
  // More start hypotheses on a walk with no start (issue 41: an unknown start costs little):
  // the trajectories of these estimators (comma-separated registry ids, each run with its
  // defaults; none of the step graph's own), where they can run. Each gives two: the dead
  // reckoning aligned by Procrustes to the estimator's positions at the node times within its
  // span, and its positions themselves (clamped to its span) with the aligned headings.
  // fg-batch solves them like the turns above; the least final cost wins (diagnostics
  // start_hypothesis_cost.<id> and .<id>/aligned; start_hypothesis_estimator: 1 + the
  // winner's place in this list, 0 not an estimator's). fg-window (and fg-batch's window
  // initialization) solves the nodes of its first align_window_s (when
  // that holds at least 3 radio readings: fewer cannot tell the hypotheses apart) as one batch
  // from its own initialization and from the causal estimators' hypotheses over that
  // span (an id ending in -rts gives its filter's, the id without it), and starts those nodes
  // at the least-cost solution (first_window_hypothesis, first_window_estimator,
  // first_window_cost.<name>). Not fg-window-online: that would give the online output of
  // those nodes the data up to the span's end, and the partial windows, started at the span's
  // solution, left it (IPIN 21 without a start: 7.71 m p75 causal, 52 m outside the scene
  // with the look-ahead). Empty: none. Our choice: the two filters that run on every step walk
  // with RSS (Gädeke's PDR + RSS KF with its RTS pass, Prieto's EKF), cheap against a solve.
  std::string start_estimators = "gadeke-kf-rts,prieto-ekf-wifi";
  // fg-batch's noise models from the walk's own residuals: after its solve, each noise group —
  // steps (step_sigma_scale and sigma_cross_m), heading increments (dheading_sigma_scale), the
  // magnetometer's headings (mag_heading_sigma_rad), RSS (sigma_db), ranges (range_sigma_m) —
  // whose residuals are larger than its σ says has its σ multiplied by the scale they show
  // (variance-component estimation, graph.h EstimateNoiseScales), and the walk is solved again
  // from there; up to this many rounds, fewer when no scale moves by more than 5 %. Odometry
  // keeps its σ. A group the data barely check keeps its σ (EstimateNoiseScales); each σ stays
  // within [0.1, 10] × its given value. Diagnostics noise_scale.<group> (the product over the
  // rounds) and noise_scale_rounds. 0: the σ as given (fg-window and its online output always
  // use them). Our choice; measured in docs/results.md ("Noise scales from the residuals").
  int noise_scale_rounds = 2;
  // Also lower the σ of steps and heading increments whose residuals are smaller than it says
  // (never the magnetometer's, RSS or ranges: their errors persist along a walk, so their
  // residuals look tighter than the independent information they carry). Off: on the simulated
  // presets it took tarrio-circle from 0.332 to 0.171 m RMSE but correa-classroom from 0.239 to
  // 0.321 and gadeke-outage from 0.670 to 0.817 (10 runs each): a few degrees of freedom of
  // redundancy do not tell white noise from a bias the model lacks.
  bool noise_scale_lower = false;
  double init_update_s = 5.0;
  int init_max_iterations = 10;  // LM iterations per update of that pass
  int max_iterations = 100;
  // fg-batch's LM start: Ceres' default 1e4 damps the soft modes of a long chain; measured on
  // Plaza1 1e4 12 iterations, 1e8 5, same RMSE (0.311 m).
  double initial_trust_region_radius = 1e8;
  double function_tolerance = 1e-6;  // Ceres' relative cost-change stop (fg-batch)
  double parameter_tolerance = 1e-8;
  // fg-batch's linear solver (fg-window's choices, below). eigen-sparse, Eigen's
  // SimplicialLDLT, against SuiteSparse's supernodal CHOLMOD: faster where anchors are states
  // (their rows are dense: IPIN 05 with WiFi 169 → 109 ms, 01 179 → 134 ms) and on long walks
  // (Plaza1 323 → 281 ms, hip-60min 1.93 → 1.72 s), the 1-min walks and IPIN BLE alone within
  // the VM's noise (−2 … +7 %); every fg-batch figure of the real-data tables the same to the
  // last digit shown, six presets × 5 seeds within 1e-10 m per error point.
  WindowLinearSolver linear_solver = WindowLinearSolver::kEigenSparse;
  int num_threads = 1;
  bool covariance = true;

  // fg-window.
  double lag_s = 10.0;
  // LM iterations per window update (to convergence). Fewer is faster but not safe: measured
  // with 2, Plaza1 2.87 → 2.64 s at the same RMSE and the presets within 0.3 %, but IPIN
  // trial 21 (real) 5.92 → 12.56 m mean landmark error (both at function tolerance 1e-6).
  int window_max_iterations = 10;
  // sparse: SPARSE_NORMAL_CHOLESKY on SuiteSparse; eigen-sparse: the same on Eigen's
  // SimplicialLDLT (less set-up per solve, which dominates on a window of ~100 blocks:
  // Plaza1 without covariances 2.62 → 2.28 s); dense: DENSE_NORMAL_CHOLESKY.
  WindowLinearSolver window_linear_solver = WindowLinearSolver::kEigenSparse;
  double window_update_s = 0.0;  // 0: one update per node; > 0: nodes gathered per period
  WindowOutput window_output = WindowOutput::kLagged;
  // States leave the window in batches of this span (FixedLagSmoother::Options): one
  // marginalization and one covariance solve per batch instead of per node; 0: per update.
  double window_marginalize_batch_s = 1.0;
  // LM's starting trust-region radius in each window solve (FixedLagSmoother::Options). The
  // window is warm-started, so it starts nearly undamped: measured on Plaza1, 1e4 (Ceres'
  // default) took 6.4 iterations per solve, 1e8 2.7, at the same RMSE (0.279 m).
  double window_initial_trust_region_radius = 1e8;
  // Ceres' relative cost-change stop in each window solve (fg-batch: function_tolerance), a
  // speed/accuracy choice measured against 1e-6: Plaza1 RMSE 0.279 m either way and 3.02 →
  // 2.60 G instructions on its first 400 s; fg-window RMSE on the presets +0.0 to +0.9 %,
  // BLE tracks +0.6 to +3 %, IPIN 01 / 05 / 21 mean +0.0 / +0.8 / −5 %. 1e-5 lies in between
  // (BLE +0.1 to +0.8 %, 2.80 G).
  double window_function_tolerance = 1e-4;

  // A user's own factors (graph.h UserFactorsFn): pose k of the hook is node k (keys
  // StepGraph::PositionKey(k), HeadingKey(k)); the static keys are listed at the top of graph.h.
  UserFactorsFn user_factors;

  // Every rule the YAML reader applies (ranges, names of losses and modes); StepGraph::Build,
  // hence every step-graph estimator's Run, refuses options that break one.
  Status Validate() const;
};

// Builds the graph of one walk, node by node (shared by the batch and the window smoother).
class StepGraph {
 public:
  static StatusOr<std::unique_ptr<StepGraph>> Build(const Walk& walk,
                                                    const StepGraphOptions& options);
  ~StepGraph();

  int num_nodes() const { return static_cast<int>(node_t_.size()); }
  double node_time(int k) const { return node_t_[k]; }
  // Node k's keys (graph.h): x(k) its position, h(k) its heading.
  static Key PositionKey(int k) { return Symbol('x', static_cast<uint64_t>(k)); }
  static Key HeadingKey(int k) { return Symbol('h', static_cast<uint64_t>(k)); }
  // z(k): node k's height (m above floor 0), a state when has_floors().
  static Key HeightKey(int k) { return Symbol('z', static_cast<uint64_t>(k)); }
  // p(a): the horizontal position (x, y) of anchor index a (walk.anchors), a static state when
  // the anchor is not surveyed (walk.h Anchor) and heard; see AnchorIsState.
  static Key AnchorKey(int anchor_index) {
    return Symbol('p', static_cast<uint64_t>(anchor_index));
  }
  bool AnchorIsState(int anchor_index) const;
  // Whether the graph estimates a height per node (StepGraphOptions::floors, pressure.csv).
  bool has_floors() const;
  // The floor of a height (walk.yaml storey_height_m).
  int FloorOfHeight(double z_m) const;
  // How many steps were taken for stair steps (StepGraphOptions::stairs).
  int stair_steps() const;
  // The start's floor when the walk does not give it (initial_pose.floor) and its anchors have
  // floors: the floor of the surveyed anchors heard strongest (StepGraph::Impl::RadioStartFloor);
  // else nullopt (the start is on the given floor, or on floor 0). Not for the online output
  // (WindowOutput::kOnline), which would need readings it has not seen yet: floor 0 there.
  std::optional<int> radio_start_floor() const;
  // What the step front end chose from the walk (pdr.h; defaults for odometry/radio-only).
  const StepFrontEndReport& front_end_report() const;

  // Static (untimed) states: path loss, range bias, gyro bias blocks.
  std::vector<GraphState> StaticStates() const;
  // Node k's two states (three with has_floors(): the height last), initialized from node k−1's (p,
  // θ) by its step (dead reckoning); node 0 from the start.
  std::vector<GraphState> NodeStates(int k, const Eigen::Vector2d& prev_p, double prev_theta) const;
  // The initial (p, θ) of every node (dead reckoning from the start).
  const std::vector<Eigen::Vector3d>& initial_nodes() const { return init_; }
  // Every factor whose newest node is k (priors on static states come with k = 0).
  std::vector<GraphFactor> FactorsAt(int k) const;
  // The whole graph into `fg` (fg-batch's graph before it solves): every state at its dead-
  // reckoning value and every factor, the user's included. A caller may add more and solve.
  Status AddTo(FactorGraph* fg) const;
  // fg-batch's start hypotheses (StepGraphOptions::start_hypotheses): the dead reckoning aligned
  // to every radio fix, turned by k·2π/n about its centroid; empty when the walk has a start,
  // no radio fix, or no steps.
  std::vector<std::vector<Eigen::Vector3d>> StartHypotheses(const Walk& walk, int n) const;
  // A start of known position whose heading nothing gives (no heading in walk.yaml's
  // initial_pose, and steps whose heading is relative: the gyro alone, no magnetometer): the
  // dead reckoning turned about the start by k·2π/n, k = 1..n−1 (k = 0 is the initialization
  // itself), each over the nodes with t <= until_s. Empty for any other walk, without radio, or
  // when the radio fixes already turned the dead reckoning (odometry walks: see start_check).
  std::vector<std::vector<Eigen::Vector3d>> StartHeadingTurns(
      int n, double until_s = std::numeric_limits<double>::infinity()) const;
  // Start hypotheses from a trajectory (StepGraphOptions::start_estimators), over the nodes
  // with t <= until_s: [0] the dead reckoning aligned by Procrustes to the trajectory's
  // positions at the node times within its span, [1] those positions (clamped to its span)
  // with [0]'s headings. Empty when the walk has a start, is radio-only, or fewer than 3 nodes
  // lie in the span.
  std::vector<std::vector<Eigen::Vector3d>> HypothesesFrom(
      const Trajectory& trajectory, double until_s = std::numeric_limits<double>::infinity()) const;
  // Whether node 0 must be held constant (no prior and no anchors: see the top of this file).
  bool fix_first_node() const { return fix_first_node_; }
  // path_loss "auto" held the path loss because the walk is radio-only (not identifiable).
  bool path_loss_held_radio_only() const { return path_loss_held_radio_only_; }
  // > 0: the known start's heading was contradicted by the radio by this much (radians) and
  // left out (StepGraphOptions::start_check).
  double start_heading_contradicted_rad() const { return start_heading_contradicted_; }
  // Whether a step carries an absolute (magnetometer) heading the graph uses (HeadingFactor).
  bool has_heading_reference() const;
  // Whether the walk's RSS readings enter the graph with a free (A, η) block.
  bool path_loss_estimated() const;
  // Whether there is one path-loss block per anchor (path_loss per-anchor or hierarchical,
  // auto's choice included).
  bool path_loss_per_anchor() const;

  // A radio reading of an anchor as the graph receives it: at (1 − alpha)·p(node_a) +
  // alpha·p(node_b) (node_b < 0: at node_a).
  struct AnchorReading {
    int anchor_index = 0;  // into walk.anchors
    bool range = false;    // a range (m), else RSS
    double value = 0.0;
    int node_a = 0, node_b = -1;
    double alpha = 0.0;
  };
  // The radio readings whose newest node is k (those of FactorsAt(k)).
  std::vector<AnchorReading> AnchorReadingsAt(int k) const;
  // The static states of anchor index a alone: p(a) when it is a state, and its path-loss,
  // range-bias and range-scale blocks where those are per anchor.
  std::vector<Key> AnchorOwnKeys(int anchor_index) const;

 private:
  StepGraph() = default;
  struct Impl;
  std::unique_ptr<Impl> impl_;
  std::vector<double> node_t_;
  std::vector<Eigen::Vector3d> init_;
  bool fix_first_node_ = false;
  bool path_loss_held_radio_only_ = false;
  double start_heading_contradicted_ = 0.0;
};

// The estimators (registered as fg-batch, fg-batch-selfcal, fg-window, fg-window-online).
class StepGraphBatch : public Estimator {
 public:
  explicit StepGraphBatch(StepGraphOptions options) : options_(std::move(options)) {}
  Status CheckApplicable(const Walk& walk) const override;
  StatusOr<EstimateResult> Run(const Walk& walk) const override;

 private:
  StepGraphOptions options_;
};

class StepGraphWindow : public Estimator {
 public:
  explicit StepGraphWindow(StepGraphOptions options) : options_(std::move(options)) {}
  Status CheckApplicable(const Walk& walk) const override;
  StatusOr<EstimateResult> Run(const Walk& walk) const override;

 private:
  StepGraphOptions options_;
};

}  // namespace walkgraph

#endif  // WALKGRAPH_SMOOTHERS_STEP_GRAPH_H_
