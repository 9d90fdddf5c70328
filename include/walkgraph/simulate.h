// Seeded walk simulator: the papers' scenarios as walks with exact truth (the building blocks
// and their math are internal: src/simulate/sim_models.h; sim_truth.h holds the truth records).
//
//   auto walk = SimulateScenario("tarrio-circle", 7);                 // paper defaults
//   auto walk = SimulateScenario("jimenez-building", 7, *Config::Parse("{laps: 2, eta: 3.0}"));
//
// Same name + seed + overrides → identical walk (own Gaussian/uniform transforms over
// mt19937_64; one forked stream per component). Truth: the IMU position at every IMU sample
// (waist/hip: the walked path, planar but for stairs; foot: the foot, with z), plus stance
// labels for foot walks. meta.initial_pose = true start with σ_xy = 0.5 m, σ_ψ = 5°;
// meta.radio = the true path-loss model; meta.extra holds "sim.*" numbers (seed, step
// length/frequency, rates, …). Output resolution: acc 1e-6 m/s², gyro 1e-7 rad/s, mag 1e-4 µT,
// truth 1e-6 m, range 1 mm.
//
// Presets — paper numbers, and [choices where the paper is silent]:
// tarrio-circle (000 Sec. IV): 9 anchors on a 3×3 grid over 20×20 m (400 m²); circle r = 8 m
//   centred, 1 m/s constant from t = 0; waist IMU 50 Hz; σ_acc = 5.7575e-2 m/s²; gyro bias
//   10 °/h (all axes) [no gyro white noise: the paper lists none]; K = 0.45, l = 0.32 + 0.26v;
//   A = −60 dBm, η = 2.5, σ = 5 dB, sensitivity −95 dBm; ΔT = 2 s (sim.delta_t_s).
//   [4 laps ≈ 201 s; beacons every 0.5 s, i.e. n = 4 readings per anchor per ΔT; no mag.]
// correa-classroom (001 Sec. IV): 154.95 m² room [14.552 × 10.648 m]; 8 motes [corners and
//   wall midpoints]; 46.4 m rectangle [0.5 m from the walls] repeated > 20 min [24 laps at
//   0.9 m/s ≈ 20.7 min]; hip IMU: acc 100 Hz, gyro + mag 15 Hz (sample-and-hold in a 100 Hz
//   stream); beacons 1 Hz. [P_1m = −45 dBm, α = 2.3, σ_γ = 4 dB, sensitivity −101 dBm;
//   ADXL345/ITG-3200/HMC5883L-like noise 0.04 m/s², 0.0066 rad/s, 0.2 µT; gyro turn-on bias
//   σ 0.2 °/s; indoor magnetic disturbances 6 × 5 µT.]
// correa-corridor (001 Sec. IV): 11.2 × 47.6 m, 8 motes, A → B → A with stops at A and B
//   [A = (1, 2), B = (1, 45.6), 10 s still at A, 10 s stop + 180° turn at B; motes on both
//   walls, two next to A and B; radio/IMU as correa-classroom; 1 m/s].
// gadeke-outage (003): hip IMU processed at 10 Hz; anchors broadcast at 4 Hz; run 700 m
//   (table 1: institute mean; 400–1100 m via run_length_m) at 1.25 m/s (700 m / 560 s);
//   62 anchors; WSN outage from 0.3·t_run to 0.8·t_run. [60 × 30 m office floor, 160 m
//   corridor loop with a room detour; anchors on a jittered 11 × 6 grid; A = −45 dBm, η = 2.8,
//   σ = 5 dB, sensitivity −95 dBm, detection d50 = 25 m; Xsens-MTi noise; mag disturbances.]
// prieto-laps (002 Sec. IV-A): foot IMU 100 Hz (Xsens MTx); 4 APs, RSS and TOA about once per
//   second [1 s ± 0.1 s, one reading per AP and type]; 8 laps ≈ 915 m in ≈ 16 min [40 × 17.2 m
//   rectangle = 114.4 m per lap at 0.975 m/s]; NLOS [30 % of the time per AP, 15 s episodes,
//   +6 dB loss, +3 m mean TOA bias]. [RSS α = −40 dBm, β = 3.0, σ = 6 dB; TOA α = 0, β = 1,
//   σ = 1.5 m; APs 3 m outside the rectangle's corners; receiver at the foot.]
// jimenez-building (004): ≈2200 m² [55 × 40 m]; 71 tags at 2 m height [jittered 9 × 8 grid];
//   RSS at 10 Hz reader polling, tags emit at 1 Hz, RFCode units, RSS0 = 60, p = 2.3, σ = 6;
//   detection falls with range, few beyond 25 m [p(d) = 0.95/(1 + e^{(d − 15)/4}), readings
//   above 110 lost, 0.5-unit quantum = mean of two antennas]; closed path of 600 m with
//   8 repetitions (Fig. 8a) [76 m loop with a 180° dead-end turn]; foot IMU 100 Hz, ≈1 m/s;
//   Xsens MTi (Table I): bias stability acc 0.02 m/s², gyro 1 °/s [used as turn-on bias σ;
//   white noise 0.011 m/s², 0.0055 rad/s; bias random walk 1e-4 (m/s²)/√s, 1e-4 (rad/s)/√s;
//   reader at the waist: receiver 1 m above the foot].
// jimenez-building-8tags: the same with 8 of the 71 tags (farthest-point subset; Table III).
// two-floor-building [walkgraph's own; IMU and radio as tarrio-circle's]: two floors of a
//   [40 × 14 m] building, storey_height_m [3.5 m]; on each a corridor loop [(6, 2)–(38, 12),
//   84 m] and, at its west end, a dog-leg staircase: [storey / 0.175 m = 20 rises, 0.28-m
//   treads; the first flight 12 rises, so the landing (0.6 × 1.4-m U-turn) lies at 0.6 storey,
//   away from the half storey where a height's floor changes; walked at 0.45 m/s from rest
//   to rest, one step per tread, the waist bouncing like a level step of the same cadence].
//   Walk: `laps` [2] laps on floor 0, up, `laps` on floor 1, down, `laps` on floor 0 (≈ 9 min).
//   Truth: x, y, z (the ground under the walker), floor = its height over the storey,
//   rounded. Anchors [8 per floor, jittered 2 × 4 grid, 2.5 m above their floor, with the
//   floor column]; RSS [A = −60 dBm, η = 2.5, σ = 5 dB, −95 dBm, 1 s] at the waist [1 m above
//   the floor] with a floor loss [15 dB] per slab between anchor and receiver
//   (walk.yaml radio.floor_loss_db, the true value). Barometer (pressure.csv) at the waist:
//   the standard atmosphere of the estimators (BarometricPressureHpa, the inverse of
//   BarometricHeightM) from [1013.25 hPa] at floor 0, [10 Hz], white noise [0.03 hPa], and
//   drift: a weather trend [±2 hPa/h, sign drawn from the seed] plus a random walk
//   [0.3 hPa/√h] (src/simulate/sim_models.h SimulateBarometer). initial_pose.floor 0;
//   duration_s only cuts the walk.
// linear-gaussian: a linear-Gaussian problem in walk form, for KF+RTS == batch == fixed-lag
//   tests. Straight walk at known constant heading ψ0 (initial_pose σ_ψ = 1e-6 rad; every
//   dheading = 0): odometry x_{k+1} = x_k + d_k·(cos ψ0, sin ψ0), d_k = l_k + N(0, σ_d²),
//   linear in the position. Measurements: ranges to two anchors placed ON the walking line,
//   one behind the start and one beyond the end, with additive N(0, σ_r²) noise. For any
//   position on the line the range is affine in the along-track coordinate s
//   (r = s − s_a or s_a − s), and every estimate started on the line stays on it (odometry
//   and range Jacobians are along the line), so the 2-D problem restricted to the line is
//   exactly linear-Gaussian; lateral components only keep their prior. Truth and ranges at
//   step times. (A general 2-D position measurement is not expressible in the walk format.)
//
// Override keys (YAML map; unknown keys are errors). All presets:
//   speed_mps, duration_s (cut the walk; loops are extended to cover it), start_still_s,
//   end_still_s, imu_rate_hz, acc_noise_mps2, gyro_noise_radps, acc_bias_sigma_mps2,
//   gyro_bias_sigma_radps, gyro_bias_dph, acc_bias_rw, gyro_bias_rw, mag_noise_ut,
//   mag_disturbance_ut, mag_disturbance_count, weinberg_k, num_anchors, A_dbm, eta, sigma_db,
//   A_spread_db, eta_spread, sensitivity, use_sensitivity, beacon_period_s, detection_p_max,
//   detection_d50_m, detection_width_m, nlos_fraction, nlos_episode_s, nlos_rss_bias_db,
//   initial_sigma_xy_m, initial_sigma_heading_deg; loops: laps; prieto-laps: toa_sigma_m,
//   toa_alpha_m, toa_beta, nlos_range_bias_m; gadeke-outage: run_length_m, outage_start_frac,
//   outage_end_frac; foot presets: gait (walk | run: 3 m/s, stance_fraction 0.2, a higher
//   swing | stairs: every leg up 12 rises and down 12, a tread per step, at 0.45 m/s; the
//   gait's defaults first, then the other keys), stance_fraction, with gait stairs
//   stair_rise_m and stair_tread_m; two-floor-building: storey_height_m,
//   stair_rise_m, stair_tread_m, stair_speed_mps, floor_loss_db, anchor_mount_m, baro_rate_hz,
//   baro_ref_hpa, baro_noise_hpa, baro_drift_hpa_per_h, baro_drift_rw_hpa_per_sqrt_h.
//   linear-gaussian: duration_s, step_period_s, step_sigma_m, range_sigma_m, heading_deg,
//   range_every.
#ifndef WALKGRAPH_SIMULATE_H_
#define WALKGRAPH_SIMULATE_H_

#include <cstdint>
#include <string>
#include <vector>

#include "walkgraph/config.h"
#include "walkgraph/sim_truth.h"
#include "walkgraph/status.h"
#include "walkgraph/walk.h"

namespace walkgraph {

struct ScenarioInfo {
  std::string name;
  std::string description;
};

std::vector<ScenarioInfo> Scenarios();

// Deterministic for a given seed. `overrides` is an optional YAML map of scenario options
// (e.g. {eta: 3.0, num_anchors: 8, laps: 4, duration_s: 600, nlos_fraction: 0.2}).
StatusOr<Walk> SimulateScenario(const std::string& name, uint64_t seed,
                                const Config& overrides = {});

// The walk plus what the simulator knows beyond it (for statistics tests and studies).
struct Simulation {
  Walk walk;
  std::vector<sim::ImuTruth> imu_truth;      // noiseless readings and pose per IMU sample
  std::vector<sim::StepEvent> steps;         // waist/hip: true step events
  std::vector<sim::Emission> rss_emissions;  // every beacon, detected or not
  std::vector<sim::Emission> range_emissions;
  std::vector<PathLossParams> per_anchor;  // true per-anchor path loss (anchor order)
};
StatusOr<Simulation> SimulateScenarioDetailed(const std::string& name, uint64_t seed,
                                              const Config& overrides = {});

}  // namespace walkgraph

#endif  // WALKGRAPH_SIMULATE_H_
