// The truth records of a simulated walk (simulate.h's Simulation): per IMU sample, per step
// event and per radio emission. Frames as in the simulator: ENU navigation frame n, IMU body
// frame b (x forward, y left, z up when level), rotations body→nav.
#ifndef WALKGRAPH_SIM_TRUTH_H_
#define WALKGRAPH_SIM_TRUTH_H_

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace walkgraph {
namespace sim {

struct StepEvent {
  double t_s = 0.0;       // integer crossing of the step phase
  double length_m = 0.0;  // path length walked since the previous step event
  double duration_s = 0.0;
};

// Truth of one IMU sample: what the sensor would read without errors, plus its pose.
struct ImuTruth {
  double t_s = 0.0;
  Eigen::Vector3d position_n = Eigen::Vector3d::Zero();
  Eigen::Vector3d velocity_n = Eigen::Vector3d::Zero();
  Eigen::Quaterniond q_nb = Eigen::Quaterniond::Identity();
  Eigen::Vector3d specific_force_b = Eigen::Vector3d::Zero();
  Eigen::Vector3d angular_rate_b = Eigen::Vector3d::Zero();
  bool stance = false;  // foot: flat on the ground and still
};

// Every emission, detected or not (the statistics tests and reports use it).
struct Emission {
  double t_s = 0.0;
  int anchor_id = 0;
  double distance_m = 0.0;
  bool nlos = false;
  bool in_outage = false;
  bool detected = false;  // survived outage, detection draw and sensitivity
  double value = 0.0;     // RSS or range (also when lost to sensitivity)
  double expected = 0.0;  // model mean (per-anchor A/η) or α + β·d
};

}  // namespace sim
}  // namespace walkgraph

#endif  // WALKGRAPH_SIM_TRUTH_H_
