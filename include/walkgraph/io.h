// Reading, validating and writing walks (format version 1, documented in README.md).
//
// A walk is a directory: walk.yaml, anchors.csv and the optional streams imu.csv, rss.csv,
// range.csv, odometry.csv, truth.csv, stance_truth.csv. Readers are strict: every problem is
// reported as "file:line: what was expected". Writers are atomic: each file is written under a
// temporary name and the folder appears whole or not at all (output.h).
#ifndef WALKGRAPH_IO_H_
#define WALKGRAPH_IO_H_

#include <functional>
#include <ostream>
#include <string>

#include "walkgraph/output.h"
#include "walkgraph/status.h"
#include "walkgraph/trajectory.h"
#include "walkgraph/walk.h"

namespace walkgraph {

// Physical plausibility limits applied by the readers.
struct ValidationLimits {
  double max_abs_acc_mps2 = 300.0;
  double max_abs_gyro_radps = 50.0;
  double min_rss_dbm = -150.0;
  double max_rss_dbm = 30.0;
  double max_range_m = 1.0e5;
  // Every coordinate (anchors, truth, waypoints, initial_pose): a building-scale walk in a local
  // frame stays within a few km of its origin, but walks may also come in projected coordinates,
  // and UTM northings reach 10^7 m (the southern hemisphere's false northing; eastings 1.7e5 to
  // 8.3e5 m; Gauss-Krüger eastings with their zone prefix stay under 10^7 m too). So 10^7 m is
  // the largest legal coordinate: beyond it no metric projection of the Earth places a building
  // (Web Mercator's ±2e7 m is not metric: its scale is 1/cos(latitude)). A frame mismatch within
  // that range (latitude and longitude swapped, another origin) is caught by the frame rule
  // instead: the truth, waypoints and start within 100 km of the anchors (CheckStreamSpans).
  double max_abs_coordinate_m = 1.0e7;
};

// Reads and validates the walk in `dir`.
StatusOr<Walk> ReadWalk(const std::string& dir, const ValidationLimits& limits = {});

// Checks the cross-file rules on an in-memory walk (anchor ids known and unique, timestamps
// ordered, values plausible). ReadWalk applies it; writers apply it before writing.
Status ValidateWalk(const Walk& walk, const ValidationLimits& limits = {});

// What a walk holds that is within reason but unusual enough to say (a real recording may need
// it, so it is not an error): one line per finding, naming the walk's file (imu.csv, rss.csv,
// walk.yaml) and, where one reading is meant, its line. The CLI prints them when it reads a walk;
// CompareOnWalk keeps them in Comparison::warnings, which results.json counts ("warnings").
// They are: holes in the IMU stream (Walk::ImuGaps; bridged, not integrated across); readings a
// converter dropped as physically impossible (meta.extra convert.<stream>_invalid_dropped); a
// path-loss exponent outside [1.5, 6] (indoor exponents; up to 10 is accepted); RSS readings above
// 0 dBm; an IMU stream that covers less than half of the radio's time span (and leaves over
// 10 s of it uncovered).
std::vector<std::string> PlausibilityWarnings(const Walk& walk);

// An anchors.csv file on its own (walk-format.md), e.g. a radio map (`walkgraph survey`):
// the rules of a walk's anchors.csv, and at least one anchor.
StatusOr<std::vector<Anchor>> ReadAnchorsFile(const std::string& path,
                                              const ValidationLimits& limits = {});
// `anchors` as anchors.csv: sigma_m and group only when some anchor needs them, floor when every
// anchor has one; an unknown position's x_m and y_m empty.
void FormatAnchorsCsv(const std::vector<Anchor>& anchors, std::ostream& out);

// Writes `walk` as the walk folder `dir`, through the output writer (output.h): the folder
// carries walkgraph's marker, appears whole or not at all, and replaces only a folder walkgraph
// wrote (or any folder with options.force). Validates the walk first.
Status WriteWalk(const Walk& walk, const std::string& dir, const OutputOptions& options = {});

// TUM trajectory format ("t x y z qx qy qz qw", heading as yaw about z), as read by evo.
void FormatTumTrajectory(const Trajectory& trajectory, std::ostream& out);
// The same trajectory as CSV with its covariance, one row per point:
//   t_s,x_m,y_m,yaw_rad,cov_xx,cov_xy,cov_yy,cov_xyaw,cov_yyaw,cov_yawyaw
// (covariance of (x, y, yaw); the six fields are empty where a point has no covariance).
void FormatTrajectoryCsv(const Trajectory& trajectory, std::ostream& out);
// A walk's truth as a TUM trajectory (identity orientation: truth carries no heading), for
// evo: evo_ape tum truth.tum fg-batch.tum.
void FormatTruthTum(const std::vector<TruthSample>& truth, std::ostream& out);
// Writes the file `path` (a new path or a regular file; see WriteOutputFile).
Status WriteTumTrajectory(const Trajectory& trajectory, const std::string& path,
                          const OutputOptions& options = {});
StatusOr<Trajectory> ReadTumTrajectory(const std::string& path);

// IPIN Track 3's submission format (technical annex 2023, "Description of the Output"): one
// line "longitude,latitude,floor" (WGS84 degrees, 12 decimals; integer floor) every 0.5 s
// from app time 0 to the walk's last record (Walk::EndTime or pressure.csv's last), no header. The
// local frame goes back to WGS84 through the origin `convert ipin` keeps (meta.extra
// ipin.origin_lat_deg / ipin.origin_lon_deg; refused without it). Position: the estimate
// interpolated at each time, held at its last point after it ends, "0,0,0" before it begins (the
// annex's "cannot estimate"); floor: the estimate's (Trajectory::FloorAt), else the walk's start
// floor.
Status FormatIpinSubmission(const Walk& walk, const Trajectory& trajectory, std::ostream& out);
Status WriteIpinSubmission(const Walk& walk, const Trajectory& trajectory, const std::string& path,
                           const OutputOptions& options = {});

}  // namespace walkgraph

#endif  // WALKGRAPH_IO_H_
