// Pre-processed measurements shared by every estimator: the front ends (pdr.h, stance.h,
// radio.h) produce them once, and the papers' filters and the factor graphs consume the same
// values, so a comparison differs only in the estimator.
//
// Headings are ENU angles: from x (east) counter-clockwise, radians, wrapped by NormalizeAngle.
#ifndef WALKGRAPH_MEASUREMENTS_H_
#define WALKGRAPH_MEASUREMENTS_H_

#include <limits>
#include <vector>

#include <Eigen/Core>

namespace walkgraph {

// One detected step (or one odometry increment).
struct Step {
  double t_s = 0.0;         // time the step ends
  double duration_s = 0.0;  // time since the previous step (0 for the first)
  double length_m = 0.0;
  double heading_rad = 0.0;   // absolute direction of the displacement
  double dheading_rad = 0.0;  // heading change since the previous step (gyro-integrated)
  double sigma_length_m = 0.1;
  double sigma_heading_rad = 0.2;    // of heading_rad (absolute: magnetometer-aided or integrated)
  double sigma_dheading_rad = 0.02;  // of dheading_rad
  double a_max_mps2 = 0.0;           // detector features (Weinberg): 0 when not from an IMU
  double a_min_mps2 = 0.0;
  // The tilt-compensated magnetometer's walking direction over this step alone (circular mean
  // of its samples), an independent absolute heading for smoothers; false without a
  // magnetometer. Indoors it carries magnetic disturbances: use it with a robust loss.
  bool has_mag_heading = false;
  double mag_heading_rad = 0.0;
};

// Where a step sequence's absolute heading comes from.
enum class HeadingSource { kRelative, kInitialPose, kMagnetometer };

// What the step front end chose from the walk itself (pdr.h: the `auto` options), for the
// estimators' diagnostics. NaN where not applicable (odometry, foot strides, fixed options).
struct StepFrontEndReport {
  HeadingSource heading_source = HeadingSource::kRelative;
  double forward_axis_rad =
      std::numeric_limits<double>::quiet_NaN();  // walking direction in the levelled body frame,
                                                 // from body x
  double forward_axis_data_rad = std::numeric_limits<double>::quiet_NaN();     // before snapping
  double forward_axis_consistency = std::numeric_limits<double>::quiet_NaN();  // Rayleigh R
  double standstill_sigma_mps2 = std::numeric_limits<double>::quiet_NaN();
  double step_peak_mps2 = std::numeric_limits<double>::quiet_NaN();      // median step peak
  double vertical_peak_mps2 = std::numeric_limits<double>::quiet_NaN();  // thresholds used
  double vertical_min_swing_mps2 = std::numeric_limits<double>::quiet_NaN();
};

struct StepSequence {
  std::vector<Step> steps;
  // True when heading_rad is absolute (magnetometer/compass or a known start); false when it
  // is only integrated from an arbitrary start.
  bool absolute_heading = false;
  StepFrontEndReport report;
};

// Zero-velocity (stance) decision per IMU sample of a foot-mounted walk.
struct StanceMask {
  std::vector<double> t_s;
  std::vector<double> statistic;  // detector statistic (GLRT T_k, variance, ...)
  std::vector<bool> stance;       // statistic below threshold (after any filtering)
  std::vector<bool> still;        // ZARU: the whole body still (no rotation); may be empty
  // The gait detector's cycle minima and, among them, its stance hypotheses (stance.h); empty
  // for the other detectors.
  std::vector<bool> cycle_minimum;
  std::vector<bool> hypothesis;
};

// A position fix from radio positioning (LS/WLS on ranges, hyperbolic RSS, ...).
struct PositionFix {
  double t_s = 0.0;
  Eigen::Vector2d position_m = Eigen::Vector2d::Zero();
  Eigen::Matrix2d covariance = Eigen::Matrix2d::Identity();
  int num_anchors = 0;
};

}  // namespace walkgraph

#endif  // WALKGRAPH_MEASUREMENTS_H_
