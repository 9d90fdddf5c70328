#include <filesystem>

#include "convert/text_table.h"
#include "walkgraph/convert.h"

namespace walkgraph {

namespace {

const std::vector<std::string> kPyshoeHeader = {"t_s",      "ax_mps2",  "ay_mps2",  "az_mps2",
                                                "gx_radps", "gy_radps", "gz_radps", "gt_x_m",
                                                "gt_y_m",   "gt_z_m",   "zv_vicon"};

}  // namespace

StatusOr<Walk> ConvertPyshoe(const std::string& csv_path) {
  WG_ASSIGN_OR_RETURN(internal::TextTable table,
                      internal::ReadTextTable(csv_path, kPyshoeHeader.size(), true));
  if (table.header != kPyshoeHeader) {
    std::string expected;
    for (const auto& h : kPyshoeHeader) expected += (expected.empty() ? "" : ",") + h;
    return InvalidArgument(csv_path + ":1: expected the header " + expected);
  }
  if (table.rows.empty()) return InvalidArgument(csv_path + ": no data rows");
  Walk walk;
  walk.meta.name = "pyshoe-" + std::filesystem::path(csv_path).stem().string();
  walk.meta.source =
      "Wagstaff, Peretroukhin, Kelly: Robust data-driven zero-velocity detection for foot-mounted "
      "inertial navigation (PyShoe, UofT VICON set), as processed in "
      "mtahakoroglu/gait-driven-inertial-navigation-dataset @b3b804e1 data/vicon/processed";
  walk.meta.licence = "MIT (repository)";
  walk.meta.imu_placement = ImuPlacement::kFoot;
  walk.meta.truth_kind = TruthKind::kContinuous;
  for (size_t i = 0; i < table.rows.size(); ++i) {
    const auto& r = table.rows[i];
    const std::string where = csv_path + ":" + std::to_string(table.line_numbers[i]);
    if (!walk.imu.empty() && !(r[0] > walk.imu.back().t_s)) {
      return InvalidArgument(where + ": time does not increase");
    }
    if (r[10] != 0.0 && r[10] != 1.0) return InvalidArgument(where + ": zv_vicon must be 0 or 1");
    ImuSample s;
    s.t_s = r[0];
    s.acc_mps2 = Eigen::Vector3d(r[1], r[2], r[3]);
    s.gyro_radps = Eigen::Vector3d(r[4], r[5], r[6]);
    walk.imu.push_back(s);
    TruthSample t;
    t.t_s = r[0];
    t.position_m = Eigen::Vector3d(r[7], r[8], r[9]);
    t.has_z = true;
    walk.truth.push_back(t);
    walk.stance_truth.push_back({r[0], r[10] == 1.0});
  }
  return walk;
}

}  // namespace walkgraph
