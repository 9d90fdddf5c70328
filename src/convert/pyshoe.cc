// PyShoe VICON converter (see ConvertPyshoe in walkgraph/convert.h for the columns).
//
// Frame: the truth's y is negated; the IMU is kept as recorded. Evidence (trial 11-22-03,
// zupt-ins with GLRT γ = 3e4, scored with --align-se2 = best rotation + translation):
//   IMU as recorded,                      truth (x, −y, z):    RMSE 0.041 m
//   IMU as recorded,                      truth as recorded:   RMSE 1.590 m (a mirror image)
//   IMU with acc y and gyro y negated,    truth as recorded:   RMSE 1.410 m
//   IMU with acc y, gyro x and z negated, truth as recorded:   RMSE 0.041 m
// The third variant (one axis flipped in both sensors) breaks the rigid-body relation of the
// pair (ḟ = −ω × f for a constant navigation-frame force becomes +ω × f), so the recorded pair
// is already a consistent right-handed body frame; the fourth is its exact mirror image, which
// physics alone cannot tell from a mirrored truth. The tie-break: the IMU's body frame is
// right-handed with z down (VectorNav VN-100 and MicroStrain, the units PyShoe's scripts name,
// both use x forward, y right, z down; here at rest az ≈ −9.4 m/s²: the specific force points
// up = −z), and PyShoe's own pipeline (utiasSTARS/pyshoe,
// ins_tools/EKF.py + INS.py) integrates in a z-down navigation frame, negates only z at the end
// and aligns to these Vicon x-y by a rotation alone (util.align_plots): the processed Vicon x-y
// are those of a z-down frame, while its z points up (the foot stands at z ≈ +0.12 m and rises
// in swing), so (x, y, z) is a left-handed triple. Signed (shoelace) areas agree after the
// flip: zupt-ins −15.6 m² vs truth (x, −y) −16.2 m² (11-22-03), +9.6 vs +10.6 m² (11-48-35).
// (x, −y, z) is a right-handed frame with z up (ENU up to an unknown yaw): score with
// --align-se2.
//
// Held truth. The Vicon position sometimes repeats exactly for several samples and then jumps
// (trial 11-22-03, 13.24–13.61 s: the foot is held 17.5 cm above the floor in mid-swing for
// 75 samples, then jumps 0.83 m): a tracking dropout, not a standstill (real standstills move
// by ~10 µm per sample). Every truth sample equal in x, y and z to the previous kept one is
// dropped (counted in meta.extra "convert.truth_held_dropped"). zv_vicon comes from the Vicon
// velocity over a 5-sample moving average (PyShoe's EKF.py vicon_zv, W = 5), so it reads 1 over
// such a hold (and within 2 samples of it): a label with a held truth sample within ±2 samples
// repeats the last label that has none (changed labels counted in "convert.stance_labels_held"),
// so the dropout stays swing and a repeat inside a stance stays stance.
#include <algorithm>
#include <filesystem>

#include "convert/text_table.h"
#include "io/plausibility.h"
#include "util/text.h"
#include "walkgraph/convert.h"

namespace walkgraph {

namespace {

const std::vector<std::string> kPyshoeHeader = {"t_s",      "ax_mps2",  "ay_mps2",  "az_mps2",
                                                "gx_radps", "gy_radps", "gz_radps", "gt_x_m",
                                                "gt_y_m",   "gt_z_m",   "zv_vicon"};

}  // namespace

StatusOr<Walk> ConvertPyshoe(const std::string& csv_path, const ConvertOptions& options,
                             std::vector<std::string>* warnings) {
  internal::DroppedReadings dropped(options.strict);
  WG_ASSIGN_OR_RETURN(internal::TextTable table,
                      internal::ReadTextTable(csv_path, kPyshoeHeader.size(), true));
  if (table.header != kPyshoeHeader) {
    std::string expected;
    for (const auto& h : kPyshoeHeader) expected += (expected.empty() ? "" : ",") + h;
    return InvalidArgument(csv_path + ":1: expected the header " + expected);
  }
  if (table.rows.empty()) return InvalidArgument(csv_path + ": no data rows");
  Walk walk;
  walk.meta.name =
      internal::ToValidUtf8("pyshoe-" + std::filesystem::path(csv_path).stem().string());
  walk.meta.source =
      "Wagstaff, Peretroukhin, Kelly: Robust data-driven zero-velocity detection for foot-mounted "
      "inertial navigation (PyShoe, UofT VICON set), as processed in "
      "mtahakoroglu/gait-driven-inertial-navigation-dataset @b3b804e1 data/vicon/processed";
  walk.meta.licence = "MIT (repository)";
  walk.meta.imu_placement = ImuPlacement::kFoot;
  walk.meta.truth_kind = TruthKind::kContinuous;
  std::vector<bool> held(table.rows.size(), false);
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
    bool drop = false;
    WG_RETURN_IF_ERROR(dropped.Check("imu", where + ": ", internal::CheckImu(s, {}), &drop));
    if (!drop) walk.imu.push_back(s);
    // Left-handed Vicon x-y (z up) → right-handed: negate y (see the top of this file).
    const Eigen::Vector3d p(r[7], -r[8], r[9]);
    held[i] = !walk.truth.empty() && p == walk.truth.back().position_m;
    if (held[i]) continue;
    TruthSample t;
    t.t_s = r[0];
    t.position_m = p;
    t.has_z = true;
    walk.truth.push_back(t);
  }
  constexpr long kLabelHalfWindow = 2;  // PyShoe's 5-sample moving average
  const long n = static_cast<long>(table.rows.size());
  long held_count = 0, labels_held = 0;
  bool last_fresh_label = table.rows[0][10] == 1.0;
  for (long i = 0; i < n; ++i) {
    held_count += held[i] ? 1 : 0;
    bool stale = false;
    for (long j = std::max(0L, i - kLabelHalfWindow); j <= std::min(n - 1, i + kLabelHalfWindow);
         ++j) {
      stale = stale || held[j];
    }
    bool stance = table.rows[i][10] == 1.0;
    if (stale) {
      if (stance != last_fresh_label) ++labels_held;
      stance = last_fresh_label;
    } else {
      last_fresh_label = stance;
    }
    walk.stance_truth.push_back({table.rows[i][0], stance});
  }
  walk.meta.extra["convert.truth_held_dropped"] = static_cast<double>(held_count);
  walk.meta.extra["convert.stance_labels_held"] = static_cast<double>(labels_held);
  dropped.Report(&walk.meta, warnings);
  return walk;
}

}  // namespace walkgraph
