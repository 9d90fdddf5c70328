// Zero-velocity (stance) and still (ZARU) detection for a foot-mounted IMU.
//
// OpenShoe detectors (Skog et al. 2010), over windows Ω_k of W samples, ȳ_a the window mean:
//   GLRT (SHOE)  T_k = (1/W) Σ_{Ω_k} [ ‖y_a − g·ȳ_a/‖ȳ_a‖‖²/σ_a² + ‖y_ω‖²/σ_g² ]
//   MV           T_k = (1/(σ_a² W)) Σ_{Ω_k} ‖y_a − ȳ_a‖²
//   MAG          T_k = (1/(σ_a² W)) Σ_{Ω_k} (‖y_a‖ − g)²
//   ARE          T_k = (1/(σ_g² W)) Σ_{Ω_k} ‖y_ω‖²
// As in OpenShoe, every sample of a window with T_k < γ is stance; the per-sample statistic is
// the smallest T_k over the windows holding the sample, so stance ⇔ statistic < γ.
//
// Jiménez's multi-condition detector (Jiménez et al. 2009, used by 002 Sec. III-C and 004):
//   C1: a_min < ‖a‖ < a_max,  C2: σ_‖a‖ (local std over s samples) < th_σ,
//   C3: ‖ω‖ < ω_max;  stance = median filter (m samples) of C1 ∧ C2 ∧ C3.
// Its statistic is the local std σ_‖a‖ (th_σ is the threshold the search varies).
//
// Adaptive GLRT ("adaptive", the foot front end's default, strides.h): the GLRT statistic of
// a walk is bimodal — stance samples cluster decades below swing samples — but where the
// clusters sit depends on the IMU's noise, its mounting, the gait and the floor (the best fixed
// γ of the two shared PyShoe trials differs by two decades), so γ comes from the walk itself:
//   L = log10 T (finite, > 0) over the walk, or over a centred window of adaptive_window_s
//   (recomputed every adaptive_step_s) so that γ follows changes of gait speed;
//   Otsu's split of L's histogram (adaptive_bins bins between its 0.5th and 99.5th percentile)
//   gives the class means m_stance < m_swing;  log10 γ = m_stance + α·(m_swing − m_stance),
//   α = adaptive_fraction (0.5 is Otsu's midpoint; lower is more conservative for ZUPTs).
//   Not bimodal (m_swing − m_stance < adaptive_min_separation decades, e.g. a standstill or a
//   window of pure swing, or fewer than adaptive_min_samples samples): a window takes the whole
//   walk's γ, and a walk that is not bimodal glrt_threshold. adaptive_causal: the window
//   trails the sample instead (only past samples), for estimators that must be causal.
// Where it fails: a walk that is (nearly) all stance or all swing inside the window has no
// valley (hence the fallback); shuffling, crawling or a foot that never stops (running on
// some gaits) gives a stance mode that is not still, and the split then marks the quietest
// part of the swing; zero-velocity labels that call the whole ground contact (heel strike to
// toe off) stance cannot be matched by a detector meant for ZUPTs (see docs/estimators.md).
//
// Gait-cycle GLRT ("gait", the foot front end's default): the adaptive detector's stance, plus
// one stance per gait cycle that it missed. The adaptive split separates the walk's quietest
// mode from the rest; when running, the foot's stance is short (5–50 ms of Vicon zero velocity
// on the shared PyShoe running trials, against 0.46 s walking) and its GLRT statistic stays
// 10^4.5–10^6.5, decades above a standstill's 10^2, so the split marks the standstills and almost
// no running stance. A foot is still once per stride whatever the gait, so:
//   P = the stride period, the lag in [gait_period_min_s, gait_period_max_s] of the largest
//       local peak of the autocorrelation of ‖ω‖ (resampled to 20 ms bins) over gait_window_s
//       around each block of gait_step_s (ending with it when adaptive_causal); a block whose
//       peak is under
//       gait_min_periodicity (standing, no rhythm) adds nothing;
//   a cycle minimum is a sample whose L = log10 T is the least within ±gait_half_fraction·P and
//       at least gait_min_depth_decades below the largest L there (the swing around it);
//   its stance: the contiguous samples with L < L_min + gait_region_decades.
// Each cycle minimum is flagged (StanceMask::cycle_minimum) so that the stride front end keeps
// its run however short. Measured on the five shared PyShoe trials (issue 40,
// StanceTest.EveryDetectorOnEveryPyshoeGait): the front end's stance phases touch (±0.05 s) every
// Vicon stance event, and every phase touches one (recall and precision 1.000 on each trial;
// the adaptive split alone: recall 0.07–0.11 on the three running ones), at most 0.94–1.26 s
// apart. The decision looks ahead by gait_half_fraction·P (≤ 1 s) and the period's window by
// up to gait_step_s even in the causal mode: a detection delay of at most 2 s at the defaults,
// like any detector window's (StanceTest.GaitCausalLooksAheadBounded).
// The detector does not bet on finding them: a stretch of more than gait_max_gap_s without
// stance (nor an IMU gap) (a stride is at most ≈1.3 s at walking pace; a standstill is stance) gets
// a stance hypothesis at the least statistic of each gait_max_gap_s of it (StanceMask::hypothesis):
// the front end's filter gates them (χ² test of the ZUPT, 99.9 %), the foot-INS graph's robust
// ZUPT may turn them down, and the estimators count them in diagnostics (stance_hypotheses).
// Where it fails: a gait whose stance is not the quietest part of its cycle by a decade
// (shuffling with the foot never planted) adds nothing beyond the adaptive split, and an
// arrhythmic walk (turning on the spot, single steps) has no period.
//
// ZARU "still" (004): the whole foot at rest — over a centred window of still_window_s,
// max ‖ω‖ < still_gyro_radps (raised to the gyro's own noise, still_adaptive) and the std of
// ‖a‖ < still_acc_std_mps2.
#ifndef WALKGRAPH_STANCE_H_
#define WALKGRAPH_STANCE_H_

#include <string>
#include <vector>

#include "walkgraph/measurements.h"
#include "walkgraph/status.h"
#include "walkgraph/walk.h"

namespace walkgraph {

enum class StanceDetector { kGlrt, kMv, kMag, kAre, kMultiCondition, kAdaptiveGlrt, kGaitGlrt };
const char* ToString(StanceDetector d);
StatusOr<StanceDetector> StanceDetectorFromString(const std::string& name);

struct StanceOptions {
  StanceDetector detector = StanceDetector::kGlrt;
  int window = 5;                // W (OpenShoe default 3; PyShoe uses 5 at 200 Hz)
  double sigma_acc_mps2 = 0.01;  // OpenShoe σ_a
  double sigma_gyro_radps = 0.1 * 3.14159265358979323846 / 180.0;  // OpenShoe σ_g = 0.1 °/s
  double gravity_mps2 = 9.81;
  // γ per detector (OpenShoe's GLRT default 3e5 for these σ; the others set to typical values,
  // tune them with StanceThresholdSearch).
  double glrt_threshold = 3e5;
  double mv_threshold = 5e3;
  double mag_threshold = 5e3;
  double are_threshold = 5e3;
  // Multi-condition (Jiménez et al. 2009 values).
  double mc_acc_min_mps2 = 9.0;
  double mc_acc_max_mps2 = 11.0;
  double mc_acc_std_max_mps2 = 3.0;
  int mc_std_window = 15;
  double mc_gyro_max_radps = 50.0 * 3.14159265358979323846 / 180.0;
  int mc_median_window = 11;
  // Adaptive GLRT (see the top of this file).
  double adaptive_fraction = 0.3;
  double adaptive_window_s = 0.0;  // 0: the whole walk
  // Causal: γ of a sample from the adaptive_window_s before it only (which must then be > 0),
  // for filters and fixed-lag smoothers whose output at t may not depend on later samples.
  // Until that window holds a bimodal statistic, glrt_threshold; after, the last bimodal γ.
  bool adaptive_causal = false;
  double adaptive_step_s = 1.0;
  int adaptive_bins = 100;
  double adaptive_min_separation = 1.0;  // decades
  int adaptive_min_samples = 200;
  // Gait-cycle GLRT (see the top of this file; the adaptive options apply to its base split).
  double gait_window_s = 8.0;
  double gait_step_s = 1.0;
  double gait_period_min_s = 0.4;
  double gait_period_max_s = 2.5;
  double gait_min_periodicity = 0.2;
  double gait_half_fraction = 0.4;
  double gait_min_depth_decades = 1.0;
  double gait_region_decades = 0.3;
  double gait_max_gap_s = 1.5;
  // ZARU still detection.
  double still_window_s = 1.0;
  double still_gyro_radps = 0.05;
  double still_acc_std_mps2 = 0.1;
  // still_gyro_radps is a floor: it is raised to 5× the gyro's white noise — the per-axis std of
  // the rate's first differences over √2, in the walk's quietest still_window_s window (causal:
  // the quietest so far), which a slow motion hardly changes — at most 4× still_gyro_radps.
  // A noisier gyro than the presets' kept ‖ω‖ at rest above 0.05 rad/s, so no sample was still,
  // no ZARU tied the gyro bias, and the foot-INS graph lost its heading: simulated
  // jimenez-building with a gyro noise of 0.02 rad/s per reading (the presets' 0.0055), IMU
  // alone, fg-ins-batch diverged / 1.96 m on seeds 1 / 2.
  bool still_adaptive = true;

  // The threshold of the selected detector (γ, th_σ for the multi-condition detector, α =
  // adaptive_fraction for the adaptive one).
  double threshold() const;
  void set_threshold(double value);

  // Every rule its YAML reader applies; DetectStance refuses options that break one.
  Status Validate() const;
};

// Statistic, stance decision and still decision for every IMU sample of the walk.
StatusOr<StanceMask> DetectStance(const Walk& walk, const StanceOptions& options);

// The walk's stance labels at each IMU sample (nearest label in time, at most max_gap_s away).
StatusOr<std::vector<bool>> StanceLabelsAtImu(const Walk& walk, double max_gap_s = 0.05);

struct StanceScore {
  double threshold = 0.0;
  long true_positive = 0, false_positive = 0, false_negative = 0, true_negative = 0;
  double precision() const;  // of "stance" decisions (1 when nothing was declared)
  double recall() const;     // of labelled stance samples
};
StanceScore ScoreStance(const std::vector<bool>& detected, const std::vector<bool>& labels);

// Precision/recall per threshold against the walk's stance labels. With no thresholds given,
// 40 values log-spaced between the 1st and 99th percentile of the detector's statistic (for the
// adaptive and gait detectors: α = 0.05, 0.10, …, 0.95).
StatusOr<std::vector<StanceScore>> StanceThresholdSearch(const Walk& walk,
                                                         const StanceOptions& base,
                                                         std::vector<double> thresholds = {});

}  // namespace walkgraph

#endif  // WALKGRAPH_STANCE_H_
