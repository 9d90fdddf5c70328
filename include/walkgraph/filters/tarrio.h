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
//
// Estimators on a Walk (TarrioEstimator; ids rss-only, rss-pdr-reset, pdr-only, tarrio-kf,
// tarrio-kf-rts) gather the core's inputs from the shared front ends with 000's choices:
//   steps (StepsForWalk): vertical-acceleration peaks after a low-pass filter (Sec. IV),
//     Weinberg length l = K·(a_max − a_min)^{1/4} with K = 0.45 (eq. 3, Sec. IV), gyro heading
//     θ_i = θ_{i−1} + δT·ω_z (eq. 4) from the walk's initial_pose;
//   fixes: RSS averaged per anchor over ΔT = 2 s epochs (Sec. IV: "n values ... averaged"),
//     positioned by the weighted hyperbolic algorithm (eq. 2).
// Config: the TarrioKfOptions keys (except `smooth`, which the id chooses), `pdr:` and `radio:`
// child maps (filters/front_end.h; rss-only has no `pdr:`), and for pdr-only
// `start: first-fix | initial-pose`. The TarrioKfOptions keys shape the baselines' covariances.
#ifndef WALKGRAPH_FILTERS_TARRIO_H_
#define WALKGRAPH_FILTERS_TARRIO_H_

#include <optional>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "walkgraph/enum_names.h"
#include "walkgraph/estimator.h"
#include "walkgraph/filters/front_end.h"
#include "walkgraph/measurements.h"
#include "walkgraph/pdr.h"

namespace walkgraph {

enum class TarrioMode { kKalman, kRssOnly, kRssPdrReset, kPdrOnly };

// TarrioKfOptions::prediction: last-velocity | pdr-displacement.
enum class TarrioPrediction { kLastVelocity, kPdrDisplacement };
const EnumNames<TarrioPrediction>& TarrioPredictionNames();
const char* ToString(TarrioPrediction p);
StatusOr<TarrioPrediction> TarrioPredictionFromString(const std::string& name);
// TarrioEstimatorOptions::start: first-fix | initial-pose.
enum class TarrioStart { kFirstFix, kInitialPose };
const EnumNames<TarrioStart>& TarrioStartNames();
const char* ToString(TarrioStart s);
StatusOr<TarrioStart> TarrioStartFromString(const std::string& name);

struct TarrioKfOptions {
  double sigma_a_mps2 = 0.1;  // eq. 6
  double sigma_v_mps = 0.1;   // eq. 6
  double sigma_p_m = 2.0;     // eq. 7
  // "last-velocity": eq. 8 as written (ΔT times the last PDR velocity). "pdr-displacement": the
  // PDR displacement integrated by eq. 13 since the last epoch (exact for curved paths).
  TarrioPrediction prediction = TarrioPrediction::kLastVelocity;
  // Mahalanobis gate on the fix innovation: the χ²(2) quantile of this probability; 0 = off
  // (the paper does not gate).
  double gate_probability = 0.0;
  // RTS backward pass over the RSS epochs (estimator id "tarrio-kf-rts").
  bool smooth = false;

  // Every rule its YAML reader applies; RunTarrio refuses options that break one.
  Status Validate(const std::string& context = "tarrio-kf") const;
};

// Runs one of the four variants on front-end outputs. Steps and fixes must be sorted by time.
// `start` (pdr-only only): the start position; the first fix when absent.
StatusOr<EstimateResult> RunTarrio(const StepSequence& steps, const std::vector<PositionFix>& fixes,
                                   const TarrioKfOptions& options, TarrioMode mode,
                                   std::optional<Eigen::Vector2d> start = std::nullopt);

// Settling time of the filter at a constant epoch interval ΔT = `epoch_s`: the time after which
// a start-up error has decayed to `fraction` of itself, (ΔT·ln fraction / ln(1 − K∞)), with K∞
// the steady-state gain of eq. 9, 11, 12 (per axis: P⁻∞ = (q + √(q² + 4qr))/2, K∞ = P⁻∞/(P⁻∞ +
// r), q from eq. 6, r = σ_p²). 000 Sec. IV scores "the stationary state of the filter" without
// saying where it starts; fraction 0.05 (three time constants) is our reading. Fails for
// ΔT <= 0, fraction outside (0, 1) or Q = 0 (the gain then decays to 0: no stationary state).
StatusOr<double> TarrioSettlingTime(const TarrioKfOptions& options, double epoch_s,
                                    double fraction = 0.05);

struct TarrioEstimatorOptions {
  TarrioKfOptions filter;
  PdrOptions pdr;              // 000 Sec. III-B/IV: vertical peaks, Weinberg K = 0.45, gyro
  RadioFrontEndOptions radio;  // 000 Sec. IV: ΔT = 2 s epochs, hyperbolic positioning (eq. 2)
  // pdr-only: start at the first RSS fix (000 Sec. IV: "the initial localization result is used
  // as the starting point for the PDR system") or at the walk's initial_pose.
  TarrioStart start = TarrioStart::kFirstFix;

  // 000's front-end defaults.
  static TarrioEstimatorOptions PaperDefaults();
  // Every rule its YAML reader applies (filter and front ends); TarrioEstimator::Run refuses
  // options that break one.
  Status Validate(const std::string& id = "tarrio") const;
};

class TarrioEstimator : public Estimator {
 public:
  TarrioEstimator(std::string id, TarrioMode mode, TarrioEstimatorOptions options)
      : id_(std::move(id)), mode_(mode), options_(std::move(options)) {}
  Status CheckApplicable(const Walk& walk) const override;
  StatusOr<EstimateResult> Run(const Walk& walk) const override;

 private:
  bool UsesSteps() const { return mode_ != TarrioMode::kRssOnly; }
  bool UsesFixes() const {
    return mode_ != TarrioMode::kPdrOnly || options_.start == TarrioStart::kFirstFix;
  }

  std::string id_;
  TarrioMode mode_;
  TarrioEstimatorOptions options_;
};

}  // namespace walkgraph

#endif  // WALKGRAPH_FILTERS_TARRIO_H_
