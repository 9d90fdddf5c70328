// Radio front end: ranges from RSS, positioning from ranges, path-loss fitting, SCMT threshold.
//
// Weighted hyperbolic positioning (000 eq. 2, Tarrío et al. 2011): with anchor 1 moved to the
// origin, subtracting the first circle equation from the others gives the linear system
//   H x = b̃,  H_i = 2(p_i − p_1)ᵀ,  b̃_i = ‖p_i − p_1‖² − d̃_i² + d̃_1²,   i = 2..N,
//   x̂ = (Hᵀ S⁻¹ H)⁻¹ Hᵀ S⁻¹ b̃.
// S is the covariance of b̃ to first order, S = 4(d̃_1²σ_1² 11ᵀ + diag(d̃_i²σ_i²)); with the
// log-normal range error σ_i = σ_d·d̃_i this is 4σ_d² times the paper's S (d̃_1⁴ + d̃_i⁴ on the
// diagonal, d̃_1⁴ elsewhere), so x̂ is the paper's and Cov(x̂) = (Hᵀ S⁻¹ H)⁻¹.
// Nonlinear LS (001 eq. 5): min_m Σ_i w_i (d̂_i − ‖s_i − m‖)², w_i = 1/σ_i², by Gauss–Newton
// from the hyperbolic solution; Cov(m̂) = (Jᵀ W J)⁻¹ at the optimum.
// Geometry: fewer than 3 distinct anchors, or anchors (nearly) on a line (smallest/largest
// principal spread below collinear_ratio), give a "no fix" status, never NaN.
//
// Path-loss fit: RSS_j = A − s·10η·log10(d_j/d0) + e_j by linear least squares in (A, η), with
// σ = sqrt(Σe²/(n − 2)) (000 eq. 1 / 001 eq. 13 model; s as in path_loss.h).
// SCMT threshold (001 eq. 18–19): for d uniform on (1, d_max],
//   P_FA(P_Th) = 1/(d_max − 1) ∫_1^{d_max} Q((P_Th − μ(x))/σ) dx,  μ(x) = A − 10η·log10 x,
// P_D likewise on [d_min, 1]; P_Th solves P_FA(P_Th) = target by bisection.
#ifndef WALKGRAPH_RADIO_H_
#define WALKGRAPH_RADIO_H_

#include <string>
#include <vector>

#include <Eigen/Core>

#include "walkgraph/measurements.h"
#include "walkgraph/path_loss.h"
#include "walkgraph/status.h"
#include "walkgraph/walk.h"

namespace walkgraph {

// One horizontal range to an anchor, as the positioning solvers consume it (the time-stamped
// 3-D measurement stream the filters fuse is RangeMeasurement in filters/ranges.h).
struct AnchorRange {
  int anchor_id = 0;
  Eigen::Vector2d anchor_m = Eigen::Vector2d::Zero();
  double range_m = 0.0;  // horizontal range
  double sigma_m = 1.0;
};

// Readings grouped into one positioning epoch.
struct RangeEpoch {
  double t_s = 0.0;  // mean reading time of the group
  std::vector<AnchorRange> ranges;
  double max_rss = 0.0;  // strongest averaged RSS (SCMT's P_max); 0 for range walks
};

enum class FixStatus { kOk, kTooFewAnchors, kCollinear, kIllConditioned, kNoConvergence };
const char* ToString(FixStatus s);

struct FixResult {
  FixStatus status = FixStatus::kTooFewAnchors;
  std::string reason;  // empty when ok
  PositionFix fix;
  bool ok() const { return status == FixStatus::kOk; }
};

struct PositioningOptions {
  double collinear_ratio = 0.05;  // smallest/largest principal std-dev of the anchors
  int max_iterations = 20;        // Gauss–Newton
  double tolerance_m = 1e-6;
  double min_sigma_m = 0.05;  // floor on per-range σ (weights)
};

// 000 eq. 2.
FixResult HyperbolicFix(const std::vector<AnchorRange>& ranges,
                        const PositioningOptions& options = {});
// 001 eq. 5 (Gauss–Newton started at the hyperbolic fix, or at the anchors' centroid).
FixResult NonlinearLsFix(const std::vector<AnchorRange>& ranges,
                         const PositioningOptions& options = {});

struct EpochOptions {
  double window_s = 1.0;           // readings within one window form an epoch
  bool bias_corrected = false;     // RSS → range: ML (001 eq. 14) or bias-corrected (eq. 17)
  double receiver_height_m = 0.0;  // ranges projected to the horizontal with anchor z − this
  // RSS per anchor is averaged in dB within the epoch before conversion (000 Sec. IV);
  // readings below the sensitivity are dropped (dBm only; ignored when +inf/−inf).
  double sensitivity = -1e9;
};

// Groups a walk's RSS (converted with its PathLossModel) or range stream into epochs of
// consecutive windows [t0 + kΔ, t0 + (k+1)Δ). Range σ: RangeSigma(d̂) (004 eq. 7) for RSS,
// meta.radio.range_sigma_m for ranges. Epochs with no reading are skipped.
StatusOr<std::vector<RangeEpoch>> BuildRangeEpochs(const Walk& walk, const EpochOptions& options);

enum class PositioningMethod { kHyperbolic, kNonlinearLs };
// One FixResult per epoch (fix.t_s = epoch time), so "no fix" epochs stay visible.
StatusOr<std::vector<FixResult>> PositionWalk(const Walk& walk, const EpochOptions& epochs,
                                              PositioningMethod method,
                                              const PositioningOptions& options = {});

struct PathLossObservation {
  int anchor_id = 0;
  double distance_m = 0.0;
  double rss = 0.0;
  int floors_crossed = 0;  // floors between anchor and receiver (multi-floor walks)
};

struct PathLossFit {
  int anchor_id = -1;  // −1 for the global fit
  PathLossParams params;
  int num_observations = 0;
};

// Global fit over all observations (d0 as given, distances clamped at ≥ 0.1 m). When the
// observations cross different numbers of floors, the floor loss L is fitted with A and η
// (RSS = A − s·10·η·log10(d/d0) − s·L·floors_crossed, least squares), else L = 0.
StatusOr<PathLossFit> FitPathLoss(const std::vector<PathLossObservation>& obs, RssUnits units,
                                  double d0_m = 1.0);
// One fit per anchor (anchors with fewer than min_observations readings are skipped).
StatusOr<std::vector<PathLossFit>> FitPathLossPerAnchor(const std::vector<PathLossObservation>& obs,
                                                        RssUnits units, double d0_m = 1.0,
                                                        int min_observations = 10);

}  // namespace walkgraph

#endif  // WALKGRAPH_RADIO_H_
