#include "walkgraph/filters/front_end.h"

#include <algorithm>
#include <cmath>

#include "config/parsers.h"
#include "walkgraph/config.h"

namespace walkgraph {

StatusOr<RadioFrontEndOptions> RadioFrontEndOptionsFromYaml(const YAML::Node& node,
                                                            const RadioFrontEndOptions& defaults,
                                                            const std::string& context) {
  RadioFrontEndOptions o = defaults;
  const std::string ctx = context + " radio";
  ConfigReader r(node, ctx);
  r.Read("window_s", &o.epochs.window_s, "readings within one window form an epoch");
  r.Read("bias_corrected", &o.epochs.bias_corrected,
         "RSS to range: ML (001 eq. 14) or bias-corrected (001 eq. 17)");
  r.Read("receiver_height_m", &o.epochs.receiver_height_m,
         "receiver height; ranges projected to the horizontal");
  r.Read("sensitivity", &o.epochs.sensitivity, "RSS readings below this are dropped (dBm only)");
  r.ReadEnum("method", &o.method,
             std::vector<std::pair<std::string, PositioningMethod>>{
                 {"hyperbolic", PositioningMethod::kHyperbolic},
                 {"nonlinear-ls", PositioningMethod::kNonlinearLs}},
             "position fix: hyperbolic (linearized) or nonlinear least squares (001 eq. 5)");
  r.Read("weighted", &o.weighted, "weight the ranges of a fix by 1/sigma^2 (else equal weights)");
  r.Read("collinear_ratio", &o.positioning.collinear_ratio,
         "no fix when anchors' smallest/largest principal std-dev is below this");
  r.Read("max_iterations", &o.positioning.max_iterations, "most Gauss-Newton iterations of a fix");
  r.Read("tolerance_m", &o.positioning.tolerance_m,
         "Gauss-Newton stop: position update below this");
  r.Read("min_sigma_m", &o.positioning.min_sigma_m, "floor on each range's sigma (weights)");
  WG_RETURN_IF_ERROR(r.Finish());
  WG_RETURN_IF_ERROR(o.Validate(context));
  return o;
}

Status RadioFrontEndOptions::Validate(const std::string& context) const {
  const RadioFrontEndOptions& o = *this;
  const std::string ctx = context + " radio";
  if (!(o.epochs.window_s > 0) || !(o.positioning.collinear_ratio >= 0) ||
      o.positioning.max_iterations < 1 || !(o.positioning.tolerance_m > 0) ||
      !(o.positioning.min_sigma_m > 0)) {
    return InvalidArgument(ctx +
                           ": need window_s > 0, collinear_ratio >= 0, max_iterations >= 1, "
                           "tolerance_m > 0, min_sigma_m > 0");
  }
  return Status::Ok();
}

StatusOr<PdrOptions> PdrOptionsFromYaml(const YAML::Node& node,
                                        const std::map<std::string, std::string>& paper_defaults,
                                        const std::string& context) {
  // The user's keys alone first: errors then point at the user's lines.
  StatusOr<PdrOptions> user = PdrOptionsFromYaml(node);
  if (!user.ok()) return InvalidArgument(context + ": " + user.status().message());
  YAML::Node merged(YAML::NodeType::Map);
  for (const auto& [key, value] : paper_defaults) merged[key] = value;
  if (node.IsMap()) {
    for (const auto& kv : node) merged[kv.first.Scalar()] = kv.second;
  }
  StatusOr<PdrOptions> o = PdrOptionsFromYaml(merged);
  if (!o.ok()) return InvalidArgument(context + ": " + o.status().message());
  return o;
}

StatusOr<YAML::Node> WithoutKeys(const YAML::Node& node, const std::vector<std::string>& keys,
                                 const std::string& context) {
  YAML::Node out(YAML::NodeType::Map);
  if (!node.IsDefined() || node.IsNull()) return out;
  if (!node.IsMap()) return InvalidArgument(context + ": expected a map of options");
  for (const auto& kv : node) {
    if (!kv.first.IsScalar())
      return InvalidArgument(context + ": option names must be plain words");
    bool drop = false;
    for (const std::string& k : keys) drop = drop || kv.first.Scalar() == k;
    if (!drop) out[kv.first] = kv.second;
  }
  return out;
}

Status RefuseKeysChosenById(const YAML::Node& own, const std::vector<std::string>& keys,
                            const std::string& ids, const std::string& id) {
  for (const std::string& key : keys) {
    if (own[key]) {
      return InvalidArgument(id + ": option '" + key + "' is chosen by the estimator id (" + ids +
                             "), not by the config");
    }
  }
  return Status::Ok();
}

Status CheckStepInput(const Walk& walk, const PdrOptions& pdr, bool need_absolute_heading,
                      const std::string& id) {
  if (!walk.has_odometry()) {
    if (!walk.has_imu()) {
      return FailedPrecondition(id +
                                " needs steps: odometry.csv or imu.csv from a waist/hip/handheld "
                                "IMU (the walk has neither)");
    }
    if (walk.meta.imu_placement == ImuPlacement::kFoot) {
      return FailedPrecondition(id +
                                " needs step-level PDR: a waist/hip/handheld IMU or odometry.csv "
                                "(the walk's IMU is foot-mounted)");
    }
    if (pdr.heading == HeadingMethod::kComplementary && !walk.imu.front().has_mag) {
      return FailedPrecondition(id +
                                " uses pdr heading 'complementary', which needs magnetometer "
                                "columns (mx, my, mz) in imu.csv");
    }
  }
  if (need_absolute_heading && !(walk.meta.initial_pose && walk.meta.initial_pose->heading_known)) {
    const bool mag_heading = !walk.has_odometry() &&
                             walk.meta.imu_placement != ImuPlacement::kFoot &&
                             ResolveHeadingMethod(walk, pdr) == HeadingMethod::kComplementary;
    if (!mag_heading) {
      return FailedPrecondition(id +
                                " needs a heading in the anchors' frame: initial_pose in "
                                "walk.yaml, or a magnetometer (mx, my, mz in imu.csv) with pdr "
                                "heading 'complementary' or 'auto'");
    }
  }
  return Status::Ok();
}

Status CheckRadioInput(const Walk& walk, int min_anchors, const std::string& id) {
  if (!walk.has_rss() && !walk.has_ranges()) {
    return FailedPrecondition(id + " needs radio readings: rss.csv or range.csv");
  }
  if (static_cast<int>(walk.anchors.size()) < min_anchors) {
    return FailedPrecondition(id + " needs at least " + std::to_string(min_anchors) +
                              " anchors in anchors.csv (the walk has " +
                              std::to_string(walk.anchors.size()) + ")");
  }
  return Status::Ok();
}

StatusOr<StepSequence> StepsFromFrontEnd(const Walk& walk, const PdrOptions& pdr,
                                         bool need_absolute_heading, const std::string& id) {
  StatusOr<StepSequence> steps = StepsForWalk(walk, pdr);
  if (!steps.ok()) return Status(steps.status().code(), id + ": " + steps.status().message());
  if (steps->steps.empty()) {
    return FailedPrecondition(id + ": the PDR front end detected no step in the walk");
  }
  if (need_absolute_heading && !steps->absolute_heading) {
    return FailedPrecondition(id +
                              ": the PDR heading is not absolute (no initial_pose, no "
                              "magnetometer heading)");
  }
  return steps;
}

StatusOr<FixesFromFrontEnd> PositionFixesFromFrontEnd(const Walk& walk,
                                                      const RadioFrontEndOptions& radio,
                                                      const std::string& id) {
  WG_RETURN_IF_ERROR(radio.Validate(id));
  StatusOr<std::vector<RangeEpoch>> epochs = BuildRangeEpochs(walk, radio.epochs);
  if (!epochs.ok()) return Status(epochs.status().code(), id + ": " + epochs.status().message());
  // The radio front end's rule for which stream it positions from.
  const bool rss =
      walk.meta.radio.kind == RadioKind::kRss || (walk.has_rss() && !walk.has_ranges());
  FixesFromFrontEnd out;
  out.epochs = static_cast<int>(epochs->size());
  for (RangeEpoch& e : *epochs) {
    FixResult r;
    if (radio.method == PositioningMethod::kHyperbolic) {
      r = HyperbolicFix(e.ranges, radio.positioning);  // 000 eq. 2
    } else if (radio.weighted) {
      r = NonlinearLsFix(e.ranges, radio.positioning);
    } else {
      // 001 eq. 5 as written: equal weights (σ_i = 1 m), covariance from the residuals.
      for (AnchorRange& a : e.ranges) a.sigma_m = 1.0;
      PositioningOptions unit = radio.positioning;
      unit.min_sigma_m = 1.0;
      r = NonlinearLsFix(e.ranges, unit);
      if (r.ok()) {
        double ss = 0.0;
        for (const AnchorRange& a : e.ranges) {
          const double res = a.range_m - (r.fix.position_m - a.anchor_m).norm();
          ss += res * res;
        }
        const double n = static_cast<double>(e.ranges.size());
        const double floor2 = radio.positioning.min_sigma_m * radio.positioning.min_sigma_m;
        r.fix.covariance *= std::max(n > 2 ? ss / (n - 2) : floor2, floor2);
      }
    }
    if (!r.ok()) {
      ++out.failed_epochs;
      continue;
    }
    r.fix.t_s = e.t_s;
    out.fixes.push_back(r.fix);
    if (rss) {
      const AnchorRange* nearest = &e.ranges.front();
      for (const AnchorRange& a : e.ranges) {
        if (a.range_m < nearest->range_m) nearest = &a;
      }
      RangeMeasurement m;
      m.t_s = e.t_s;
      m.anchor_id = nearest->anchor_id;
      m.anchor_m = walk.anchors[walk.AnchorIndex(nearest->anchor_id)].position_m;
      m.range_m = nearest->range_m;
      m.sigma_m = nearest->sigma_m;
      m.from_rss = true;
      m.rss = e.max_rss;
      out.strongest.push_back(m);
    }
  }
  if (out.fixes.empty()) {
    return FailedPrecondition(id + ": no radio epoch gave a position fix (" +
                              std::to_string(out.epochs) + " epochs)");
  }
  return out;
}

Trajectory TrajectoryOfFixes(const std::vector<PositionFix>& fixes) {
  Trajectory t;
  for (const PositionFix& f : fixes) {
    TrajectoryPoint p;
    p.t_s = f.t_s;
    p.position_m = Eigen::Vector3d(f.position_m.x(), f.position_m.y(), 0.0);
    Eigen::Matrix3d c = Eigen::Matrix3d::Zero();
    c.topLeftCorner<2, 2>() = f.covariance;
    c(2, 2) = M_PI * M_PI;
    p.covariance = c;
    t.points.push_back(p);
  }
  return t;
}

}  // namespace walkgraph
