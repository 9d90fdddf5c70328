// Trajectory formats (io.h): TUM and CSV trajectories, the truth as TUM, the IPIN competition
// submission, and the TUM reader.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <sstream>

#include "util/csv_reader.h"
#include "util/geodesy.h"
#include "util/input_file.h"
#include "util/text.h"
#include "walkgraph/io.h"
#include "walkgraph/output.h"

namespace walkgraph {

using internal::ExactNum;

void FormatTumTrajectory(const Trajectory& trajectory, std::ostream& o) {
  o << "# t x y z qx qy qz qw\n";
  for (const TrajectoryPoint& p : trajectory.points) {
    const double half = 0.5 * p.heading_rad;
    o << ExactNum(p.t_s) << ' ' << ExactNum(p.position_m.x()) << ' ' << ExactNum(p.position_m.y())
      << ' ' << ExactNum(p.position_m.z()) << " 0 0 " << ExactNum(std::sin(half)) << ' '
      << ExactNum(std::cos(half)) << '\n';
  }
}

void FormatTrajectoryCsv(const Trajectory& trajectory, std::ostream& o) {
  o << "t_s,x_m,y_m,yaw_rad,cov_xx,cov_xy,cov_yy,cov_xyaw,cov_yyaw,cov_yawyaw\n";
  for (const TrajectoryPoint& p : trajectory.points) {
    o << ExactNum(p.t_s) << ',' << ExactNum(p.position_m.x()) << ',' << ExactNum(p.position_m.y())
      << ',' << ExactNum(p.heading_rad);
    if (p.covariance) {
      const Eigen::Matrix3d& c = *p.covariance;
      o << ',' << ExactNum(c(0, 0)) << ',' << ExactNum(c(0, 1)) << ',' << ExactNum(c(1, 1)) << ','
        << ExactNum(c(0, 2)) << ',' << ExactNum(c(1, 2)) << ',' << ExactNum(c(2, 2)) << '\n';
    } else {
      o << ",,,,,,\n";
    }
  }
}

void FormatTruthTum(const std::vector<TruthSample>& truth, std::ostream& o) {
  o << "# t x y z qx qy qz qw (truth: position only, identity orientation)\n";
  for (const TruthSample& t : truth) {
    o << ExactNum(t.t_s) << ' ' << ExactNum(t.position_m.x()) << ' ' << ExactNum(t.position_m.y())
      << ' ' << ExactNum(t.position_m.z()) << " 0 0 0 1\n";
  }
}

Status WriteTumTrajectory(const Trajectory& trajectory, const std::string& path,
                          const OutputOptions& options) {
  return WriteOutputFile(path, options, [&](std::ostream& o) {
    FormatTumTrajectory(trajectory, o);
    return true;
  });
}

Status FormatIpinSubmission(const Walk& walk, const Trajectory& trajectory, std::ostream& o) {
  const auto lat = walk.meta.extra.find("ipin.origin_lat_deg");
  const auto lon = walk.meta.extra.find("ipin.origin_lon_deg");
  if (lat == walk.meta.extra.end() || lon == walk.meta.extra.end()) {
    return FailedPrecondition("IPIN submission: walk '" + walk.meta.name +
                              "' has no ipin.origin_lat_deg/_lon_deg (not from convert ipin)");
  }
  if (trajectory.empty()) return FailedPrecondition("IPIN submission: empty trajectory");
  const internal::LocalTangentPlane plane(lat->second, lon->second);
  const int start_floor = walk.StartFloor();
  double end = walk.EndTime();  // the last record, the barometer's included
  if (!walk.pressure.empty()) end = std::max(end, walk.pressure.back().t_s);
  char line[96];
  for (long k = 0; 0.5 * static_cast<double>(k) <= end; ++k) {
    const double t = 0.5 * static_cast<double>(k);
    if (t < trajectory.points.front().t_s) {
      o << "0,0,0\n";
      continue;
    }
    const Eigen::Vector3d p = trajectory.PositionAt(t);
    const Eigen::Vector2d ll = plane.LatLon(p.x(), p.y());
    std::snprintf(line, sizeof(line), "%.12f,%.12f,%d\n", ll.y(), ll.x(),
                  trajectory.FloorAt(t).value_or(start_floor));
    o << line;
  }
  return Status::Ok();
}

Status WriteIpinSubmission(const Walk& walk, const Trajectory& trajectory, const std::string& path,
                           const OutputOptions& options) {
  Status format = Status::Ok();
  WG_RETURN_IF_ERROR(WriteOutputFile(path, options, [&](std::ostream& o) {
    format = FormatIpinSubmission(walk, trajectory, o);
    return format.ok();
  }));
  return format;
}

StatusOr<Trajectory> ReadTumTrajectory(const std::string& path) {
  internal::LineReader in(path);
  WG_RETURN_IF_ERROR(in.Open());
  Trajectory traj;
  std::string line;
  while (true) {
    WG_ASSIGN_OR_RETURN(const bool more, in.Next(&line));
    if (!more) break;
    if (line.empty() || line[0] == '#') continue;
    std::istringstream ss(line);
    std::vector<double> v;
    std::string tok;
    while (ss >> tok && v.size() <= 8) {
      double x;
      if (!internal::ParseFiniteDouble(tok, &x)) {
        return InvalidArgument(in.Where() + internal::Quoted(tok) + " is not a number");
      }
      v.push_back(x);
    }
    if (v.size() != 8)
      return InvalidArgument(in.Where() + "expected 8 fields 't x y z qx qy qz qw'");
    TrajectoryPoint p;
    p.t_s = v[0];
    p.position_m = Eigen::Vector3d(v[1], v[2], v[3]);
    // yaw of the quaternion (x, y, z, w)
    p.heading_rad =
        std::atan2(2.0 * (v[7] * v[6] + v[4] * v[5]), 1.0 - 2.0 * (v[5] * v[5] + v[6] * v[6]));
    if (!traj.points.empty() && !(p.t_s > traj.points.back().t_s)) {
      return InvalidArgument(in.Where() + "timestamps must increase");
    }
    traj.points.push_back(p);
  }
  return traj;
}

}  // namespace walkgraph
