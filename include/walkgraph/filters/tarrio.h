// Tarrío, Besada, Casar — RSS + inertial fusion with a linear Kalman filter (paper 000), and
// the paper's two baselines, over the shared front-end outputs (steps + RSS position fixes).
//
// State x = [x y]ᵀ. PDR velocity v̄ = v·[cos θ, sin θ]ᵀ is a control input (eq. 5), v = step
// length / step duration, updated at each detected step and held until the next one.
//   prediction at an RSS epoch, ΔT after the previous one:  x⁻ = x + ΔT·v̄   (eq. 8)
//                                                          P⁻ = P + Q       (eq. 9)
//   Q = I·(½·σ_a·ΔT²)² + I·(σ_v·ΔT)²,  σ_a = 0.1 m/s², σ_v = 0.1 m/s        (eq. 6)
//   update with the RSS fix z = x + r, R = σ_p²·I, σ_p = 2 m                (eq. 7, 10–12)
//   between RSS epochs the output follows the PDR: x_i = x_{i−1} + δT·v̄_i   (eq. 13)
// The filter starts at the first fix (Sec. IV: "the initial localization result is used as the
// starting point"), with P = R.
// Baselines (Sec. IV): "rss-only" holds the last fix; "rss-pdr-reset" runs eq. 13 between fixes
// and resets to each new fix; "pdr-only" runs eq. 13 from the start without any fix.
// Smoothing ("tarrio-kf-rts"): RTS over the RSS epochs (F = I); between epochs the output is
// the PDR path from the smoothed epoch state, with the mismatch at the next smoothed epoch
// spread linearly in time (the PDR shape between smoothed anchors).
#ifndef WALKGRAPH_FILTERS_TARRIO_H_
#define WALKGRAPH_FILTERS_TARRIO_H_

#include <optional>
#include <string>
#include <vector>

#include <yaml-cpp/yaml.h>
#include <Eigen/Core>

#include "walkgraph/estimator.h"
#include "walkgraph/measurements.h"

namespace walkgraph {

enum class TarrioMode { kKalman, kRssOnly, kRssPdrReset, kPdrOnly };

struct TarrioKfOptions {
  double sigma_a_mps2 = 0.1;  // eq. 6
  double sigma_v_mps = 0.1;   // eq. 6
  double sigma_p_m = 2.0;     // eq. 7
  // "last-velocity": eq. 8 as written (ΔT times the last PDR velocity). "pdr-displacement": the
  // PDR displacement integrated by eq. 13 since the last epoch (exact for curved paths).
  std::string prediction = "last-velocity";
  // Mahalanobis gate on the fix innovation: the χ²(2) quantile of this probability; 0 = off
  // (the paper does not gate).
  double gate_probability = 0.0;
  // RTS backward pass over the RSS epochs (estimator id "tarrio-kf-rts").
  bool smooth = false;

  static StatusOr<TarrioKfOptions> FromYaml(const YAML::Node& node, const std::string& context);
};

// Runs one of the four variants on front-end outputs. Steps and fixes must be sorted by time.
// `start` (pdr-only only): the start position; the first fix when absent.
StatusOr<EstimateResult> RunTarrio(const StepSequence& steps, const std::vector<PositionFix>& fixes,
                                   const TarrioKfOptions& options, TarrioMode mode,
                                   std::optional<Eigen::Vector2d> start = std::nullopt);

}  // namespace walkgraph

#endif  // WALKGRAPH_FILTERS_TARRIO_H_
