// Placing an anchor of unknown position from a path (internal; fg-batch's initialization of
// its anchor states, step_graph.h).
//
// Given the receiver's positions q_i at an anchor's readings (the path of a solve without the
// anchor), a coarse grid over the path's extent plus a margin, each cell a its cost
//   range:  C(a) = Σ ρ(ρ_i − (1 + s)·d_i − b̂) + (b̂/σ_b)²,   b̂ = median_i(ρ_i − (1 + s)·d_i)
//           (002 eq. 6; b̂ the anchor's bias, its prior N(0, σ_b²); held at 0 when σ_b = 0)
//   RSS:    C(a) = Σ ρ(RSS_i − (Â − sign·10·η·log10(d_i/d0))) + ((Â − A)/σ_A)²,
//           Â = median_i(RSS_i + sign·10·η·log10(d_i/d0))   (000 eq. 1; η held at the walk's
//           value; Â the anchor's transmit level with its prior N(A, σ_A²), held at A when
//           σ_A = 0: a calibrated radio)
// with d_i = ‖(q_i, z_r) − (a, z_a)‖, ρ(e) = c²·log(1 + e²/c²) the Cauchy loss of the residual
// in σ — the best cell, refined on a grid of a tenth of the step around it. The step is
// step_m, coarser where the extent would need more than 262144 cells or 10^8 cell-reading
// evaluations (a path spread over kilometres: a diverged estimate); a receiver or reading that
// is not finite gives no place (ambiguous). The median levels
// make the search robust to an unknown bias or transmit power without a good guess; their
// prior keeps an RSS anchor from sliding outward with a rising Â (distance and level trade).
// Verdict "unobservable" (left out of the graph) when the anchor has fewer than min_readings
// readings, when the receiver positions spread less than min_spread_m across their narrowest
// direction (a straight pass leaves the side of the path open), or when the region of the grid
// within min_cost_gap of the best cost is not one piece around it — it has a part farther
// than distinct_radius_m not connected to the best cell (another place, e.g. the mirror image
// across the path, explains the readings about as well) or reaches the grid's edge (the anchor
// may lie anywhere outward).
#ifndef WALKGRAPH_SRC_SMOOTHERS_ANCHOR_SEARCH_H_
#define WALKGRAPH_SRC_SMOOTHERS_ANCHOR_SEARCH_H_

#include <string>
#include <vector>

#include <Eigen/Core>

namespace walkgraph::internal {

// χ²(2) at 99.9 %: a 2-D shift beyond it, in its covariance, is a contradiction, not noise
// (unknown_anchors.h: the joint solve against the first; step_graph_pending.h: an uncertain
// anchor's search place against its prior).
inline constexpr double kChiSquare2At999 = 13.82;

struct AnchorSearchOptions {
  bool range = true;                         // ranges (else RSS)
  double sigma = 1.0;                        // σ of a reading (m or dB)
  double loss_scale = 2.0;                   // Cauchy scale in σ
  double dz_m = 0.0;                         // receiver height − anchor height
  double range_scale = 0.0;                  // s (the walk's estimate)
  double eta = 2.5, sign = 1.0, d0_m = 1.0;  // RSS path loss (η held)
  double level_prior = 0.0;                  // b's prior mean (0) or A's (the walk's A)
  double level_prior_sigma = 0.0;            // σ_b or σ_A; 0: the level held at level_prior
  double margin_m = 20.0;
  double step_m = 1.0;
  int min_readings = 10;
  double min_spread_m = 1.0;
  double distinct_radius_m = 5.0;
  double min_cost_gap = 9.21;  // χ²(2) at 99 %
};

struct AnchorSearchResult {
  enum class Verdict { kPlaced, kFewReadings, kNarrowGeometry, kAmbiguous };
  Verdict verdict = Verdict::kPlaced;
  Eigen::Vector2d position_m = Eigen::Vector2d::Zero();
  double cost = 0.0;
  double second_cost = 0.0;  // the least cost of the grid's other places (infinity: none)
  double spread_m = 0.0;     // the receiver positions' narrowest spread (1σ)
  // The position's covariance from the region within min_cost_gap of the best (a cost of
  // whitened residuals, near its minimum Δ = eᵀΣ⁻¹e: the region is Σ's χ²(2) ellipse), plus a
  // grid cell's own spread (m²); zero unless the search reached the grid.
  Eigen::Matrix2d covariance = Eigen::Matrix2d::Zero();
  bool placed() const { return verdict == Verdict::kPlaced; }
};

const char* ToString(AnchorSearchResult::Verdict v);

// receivers[i], values[i]: where reading i was received and its range (m) or RSS.
AnchorSearchResult SearchAnchor(const std::vector<Eigen::Vector2d>& receivers,
                                const std::vector<double>& values,
                                const AnchorSearchOptions& options);

}  // namespace walkgraph::internal

#endif  // WALKGRAPH_SRC_SMOOTHERS_ANCHOR_SEARCH_H_
