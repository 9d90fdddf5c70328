// Posterior Cramér–Rao bound (PCRB) of the horizontal position on a simulated walk: the limit
// no estimator using the same model can beat, reported beside the estimators' errors.
//
// State: x_k ∈ R², the horizontal position at node k (times t_0 < t_1 < … < t_{n−1}).
// Prior x_0 ~ N(·, σ_0² I): J_0 = I/σ_0² (+ readings at t ≤ t_0).
// Process (additive, F = I): x_{k+1} = x_k + Δ_k + w_k, w_k ~ N(0, Q_k), with Δ_k the true
// displacement, u = Δ_k/|Δ_k|, l = |Δ_k|, u⊥ the left normal and
//   Q_k = σ_l² u uᵀ + σ_c² u⊥ u⊥ᵀ,
// each σ floored at min_process_sigma_m (a singular Q has no information form).
// Readings: a reading at t ∈ (t_k, t_{k+1}] sees the interpolated position
// y = (1−α) x_k + α x_{k+1}, α = (t − t_k)/(t_{k+1} − t_k) (after the last node: on it); its
// Fisher information about y is
//   RSS, log-distance (000 eq. 1, 004 eq. 4):  M = (10η/(σ ln10))² u uᵀ / d²
//   TOA z = α_toa + β d + n (002 eq. 6):       M = (β/σ_r)² u uᵀ
// with d the 3-D receiver–anchor distance at the truth (floored at min_distance_m) and
// u = (p − a)_xy / d the unit vector projected to the horizontal; η, σ the true per-anchor
// path loss of the simulator. Only readings that exist (detected, outside outages) count:
// anchors' sensitivity and detection enter through which readings exist.
//
// Tichavský, Muravchik, Nehorai (1998) terms of interval k (expectations over the Monte Carlo
// runs, i.e. over the true trajectory and the readings drawn with it):
//   D11_k = E[Q⁻¹ + Σ (1−α)² M],  D12_k = E[−Q⁻¹ + Σ α(1−α) M] = D21_kᵀ,
//   D22_k = E[Q⁻¹ + Σ α² M]
// Filtering bound (the recursion):   J_{k+1} = D22_k − D21_k (J_k + D11_k)⁻¹ D12_k,
//                                    E[(x̂_k − x_k)(·)ᵀ] ≥ J_k⁻¹.
// Smoothing bound: the full-walk Fisher information at the truth is block tridiagonal,
//   A_kk = [k = 0] J_0 + D11_k + D22_{k−1},  A_{k,k+1} = D12_k;
// its sparse Cholesky factor A = L Lᵀ (Eigen SimplicialLLT, natural ordering, bandwidth 3) and
// the Takahashi recursion give the blocks of A⁻¹ inside the band in O(n) — never a dense
// inverse. The two agree at the last node: (A⁻¹)_{n−1,n−1} = J_{n−1}⁻¹.
// RMSE bound: sqrt(mean over the walk's truth samples of tr B(t)), tr B linearly interpolated
// in time between nodes (B = J⁻¹ or A⁻¹ block), the same points the estimators are scored on.
//
// Models per scenario (which nodes and which σ):
//  * step-level presets (waist/hip IMU: tarrio-circle, correa-*, gadeke-outage): nodes at the
//    walk start, at every true step event of the simulator (Simulation::steps) and at the end.
//    σ_l = step_sigma_frac·l + step_sigma_m, σ_c = l·heading_sigma_rad: by default exactly the
//    per-step σ the PDR front end attaches to each Step and the step-level estimators weight
//    their step factors with (PdrOptions defaults sigma_length_frac = 0.1,
//    sigma_length_m = 0.02 m, sigma_dheading_rad = 0.02 rad), the heading error taken as
//    independent per step. It is the bound under the estimators' own step model: a PDR that is
//    better than it assumes can beat it, heading drift (gyro bias) is not in it.
//  * linear-gaussian: nodes at the truth (= odometry) times; σ_l = sim.step_sigma_m, the known
//    heading gives σ_c = 0 → min_process_sigma_m. Ranges are linear: the bound is the exact
//    KF/RTS covariance of that model.
//  * foot-IMU presets (prieto-laps, jimenez-*): not computed (FailedPrecondition). A ZUPT-aided
//    foot INS loses position mainly through yaw drift from the gyro biases, which a per-stride
//    planar state cannot carry; with the IMU white noise alone the stride-to-stride σ is ≈1 mm
//    and the bound a few centimetres, a figure that says nothing about the estimators. A bound
//    for them needs the INS error state (attitude, velocity, biases) at every sample.
// Prior: σ_0 = prior_sigma_m, by default 1 mm: the simulator gives every estimator the true
// start as initial_pose (with σ_xy = 0.5 m), so the start is known and a bound with a 0.5 m
// prior would not hold for an estimator that starts there (dead reckoning does). prior_sigma_m
// ≤ 0 uses initial_pose σ_xy: the Bayesian bound for a start drawn from that prior.
#ifndef WALKGRAPH_PCRB_H_
#define WALKGRAPH_PCRB_H_

#include <cstdint>
#include <map>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "walkgraph/config.h"
#include "walkgraph/pdr.h"
#include "walkgraph/simulate.h"
#include "walkgraph/status.h"

namespace walkgraph {

struct PcrbOptions {
  double step_sigma_frac = PdrOptions().sigma_length_frac;  // σ_l = frac·l + step_sigma_m
  double step_sigma_m = PdrOptions().sigma_length_m;
  double heading_sigma_rad = PdrOptions().sigma_dheading_rad;  // σ_c = l·σ_ψ
  double min_process_sigma_m = 1e-3;                           // floor of σ_l and σ_c
  double prior_sigma_m = 1e-3;  // σ_0 (known start); ≤ 0: the walk's initial_pose σ_xy
  double min_distance_m = 0.5;  // floor of d in the radio information

  // Every rule its YAML reader applies; the bound refuses options that break one.
  Status Validate(const std::string& context = "pcrb") const;
};

// The Fisher information of one walk (or its Monte Carlo mean), split into the Tichavský terms
// of each interval (see the top of this file).
struct PcrbInformation {
  std::vector<double> t_s;                  // node times, strictly increasing (n ≥ 2)
  std::vector<Eigen::Vector2d> position_m;  // true node positions
  Eigen::Matrix2d J0 = Eigen::Matrix2d::Zero();
  std::vector<Eigen::Matrix2d> D11, D12, D22;  // one per interval (n − 1)
  std::vector<double> score_t_s;               // truth sample times (where errors are scored)
  double readings = 0.0;                       // readings that contributed (mean over runs)
  int runs = 1;
};

// The information of one simulated walk at its truth. FailedPrecondition for foot-IMU walks
// and walks the simulator gives no step events for.
StatusOr<PcrbInformation> PcrbInformationFromSimulation(const Simulation& simulation,
                                                        const PcrbOptions& options = {});

// E[·] over runs: the element-wise mean, summed in the given order. The runs must share the
// node times (the simulator's walker does not depend on the seed).
StatusOr<PcrbInformation> MeanPcrbInformation(const std::vector<PcrbInformation>& runs);

// Sums the runs' information in run order whatever order they arrive in, so the mean does not
// depend on the thread count (thread-safe; a run waits until every earlier run is in, so about
// `threads` runs are held at a time).
class PcrbAccumulator {
 public:
  explicit PcrbAccumulator(int runs);
  Status Add(int run, PcrbInformation information);
  // The mean over all runs (each must have been added).
  StatusOr<PcrbInformation> Mean() const;

 private:
  mutable std::mutex mutex_;
  int runs_ = 0;
  std::map<int, PcrbInformation> pending_;  // added out of order, waiting for earlier runs
  std::optional<PcrbInformation> sum_;
  int next_ = 0;
  Status error_;
};

struct PcrbBound {
  std::vector<double> t_s;                // node times
  std::vector<Eigen::Matrix2d> filter;    // J_k⁻¹ (Tichavský recursion)
  std::vector<Eigen::Matrix2d> smoother;  // (A⁻¹)_kk (full-walk information)
  double filter_rmse_m = 0.0;             // sqrt(mean tr B(t)) over the score times
  double smoother_rmse_m = 0.0;
  int runs = 1;
  double readings = 0.0;
};

StatusOr<PcrbBound> ComputePcrb(const PcrbInformation& information);

// The bound of a scenario over `runs` Monte Carlo runs with seeds MonteCarloSeed(seed, i) —
// the walks CompareMonteCarlo sees for the same (runs, seed). Runs are simulated on `threads`
// threads (≤ 0: all cores) and averaged in run order: the result does not depend on threads.
StatusOr<PcrbBound> ScenarioPcrb(const std::string& scenario, const Config& overrides, int runs,
                                 uint64_t seed, int threads, const PcrbOptions& options = {});

}  // namespace walkgraph

#endif  // WALKGRAPH_PCRB_H_
