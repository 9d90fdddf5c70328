// The registry entries of the papers' filters (000, 001, 003): every id is registered, builds
// from an empty config, rejects unknown keys, says which sensor a walk lacks, and runs on a
// short simulated walk with covariances and (for the filters) NIS.
#include <algorithm>
#include <string>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <yaml-cpp/yaml.h>

#include "walkgraph/estimator.h"
#include "walkgraph/simulate.h"

namespace walkgraph {
namespace {

using ::testing::HasSubstr;

const std::vector<std::string>& PaperIds() {
  static const std::vector<std::string> ids = {
      "pdr-only",  "rss-only",     "rss-pdr-reset",   "tarrio-kf",      "tarrio-kf-rts",
      "correa-ls", "correa-ekf",   "correa-scmt-ekf", "correa-ekf-rts", "correa-scmt-ekf-rts",
      "gadeke-kf", "gadeke-kf-rts"};
  return ids;
}

bool UsesSteps(const std::string& id) { return id != "rss-only" && id != "correa-ls"; }
bool UsesMagnetometer(const std::string& id) {
  return id.rfind("correa-", 0) == 0 ? id != "correa-ls" : id.rfind("gadeke-", 0) == 0;
}
bool IsFilter(const std::string& id) {
  return id.find("-kf") != std::string::npos || id.find("-ekf") != std::string::npos;
}

// 40 s of the classroom: hip IMU with magnetometer, RSS from 8 motes, initial_pose.
const Walk& ShortWalk() {
  static const Walk walk = [] {
    auto w = SimulateScenario("correa-classroom", 3, YAML::Load("{duration_s: 40}"));
    EXPECT_TRUE(w.ok()) << w.status().message();
    return *w;
  }();
  return walk;
}

TEST(PaperEstimatorsTest, EveryIdIsRegisteredAndBuildsFromAnEmptyConfig) {
  const EstimatorRegistry& r = EstimatorRegistry::Builtin();
  const std::vector<std::string> all = r.Ids();
  for (const std::string& id : PaperIds()) {
    EXPECT_NE(r.Find(id), nullptr) << id;
    EXPECT_EQ(std::count(all.begin(), all.end(), id), 1) << id;
    EXPECT_TRUE(r.Create(id, YAML::Node()).ok()) << id;
    auto e = r.Create(id, YAML::Load("{}"));
    EXPECT_TRUE(e.ok()) << id << ": " << e.status().message();
  }
}

TEST(PaperEstimatorsTest, UnknownConfigKeysAreRejectedAtEveryLevel) {
  const EstimatorRegistry& r = EstimatorRegistry::Builtin();
  for (const std::string& id : PaperIds()) {
    auto top = r.Create(id, YAML::Load("{no_such_option: 1}"));
    ASSERT_FALSE(top.ok()) << id;
    EXPECT_THAT(top.status().message(), HasSubstr("no_such_option")) << id;
    auto radio = r.Create(id, YAML::Load("{radio: {no_such_radio_option: 1}}"));
    ASSERT_FALSE(radio.ok()) << id;
    EXPECT_THAT(radio.status().message(), HasSubstr("no_such_radio_option")) << id;
    // The PDR child exists exactly where the estimator uses steps.
    auto pdr = r.Create(id, YAML::Load("{pdr: {no_such_pdr_option: 1}}"));
    ASSERT_FALSE(pdr.ok()) << id;
    EXPECT_THAT(pdr.status().message(), HasSubstr(UsesSteps(id) ? "no_such_pdr_option" : "'pdr'"))
        << id;
    if (UsesSteps(id)) {
      EXPECT_TRUE(r.Create(id, YAML::Load("{pdr: {weinberg_k: 0.5}}")).ok()) << id;
    }
  }
  // Smoothing and SCMT are chosen by the id, not the config.
  EXPECT_FALSE(r.Create("tarrio-kf", YAML::Load("{smooth: true}")).ok());
  EXPECT_FALSE(r.Create("correa-ekf", YAML::Load("{scmt: true}")).ok());
  EXPECT_FALSE(r.Create("gadeke-kf", YAML::Load("{smooth: true}")).ok());
  EXPECT_FALSE(r.Create("pdr-only", YAML::Load("{start: somewhere}")).ok());
  EXPECT_FALSE(r.Create("tarrio-kf", YAML::Load("{start: first-fix}")).ok());
  EXPECT_FALSE(r.Create("tarrio-kf", YAML::Load("{radio: {method: triangulation}}")).ok());
  EXPECT_FALSE(r.Create("correa-ekf", YAML::Load("{pdr: {detector: magic}}")).ok());
}

TEST(PaperEstimatorsTest, CheckApplicableNamesTheMissingSensor) {
  const EstimatorRegistry& r = EstimatorRegistry::Builtin();
  Walk no_imu = ShortWalk();
  no_imu.imu.clear();
  Walk no_radio = ShortWalk();
  no_radio.rss.clear();
  Walk no_mag = ShortWalk();
  for (ImuSample& s : no_mag.imu) s.has_mag = false;
  Walk no_start = ShortWalk();
  no_start.meta.initial_pose.reset();
  Walk no_start_no_mag = no_mag;
  no_start_no_mag.meta.initial_pose.reset();
  Walk foot = ShortWalk();
  foot.meta.imu_placement = ImuPlacement::kFoot;
  for (const std::string& id : PaperIds()) {
    auto e = r.Create(id);
    ASSERT_TRUE(e.ok()) << id;
    const Status full = (*e)->CheckApplicable(ShortWalk());
    EXPECT_TRUE(full.ok()) << id << ": " << full.message();
    const Status imu = (*e)->CheckApplicable(no_imu);
    const Status radio = (*e)->CheckApplicable(no_radio);
    if (UsesSteps(id)) {
      ASSERT_FALSE(imu.ok()) << id;
      EXPECT_THAT(imu.message(), HasSubstr("imu.csv")) << id;
      EXPECT_THAT(imu.message(), HasSubstr(id)) << id;
      const Status f = (*e)->CheckApplicable(foot);
      ASSERT_FALSE(f.ok()) << id;
      EXPECT_THAT(f.message(), HasSubstr("foot")) << id;
    } else {
      EXPECT_TRUE(imu.ok()) << id << ": " << imu.message();
    }
    if (id == "pdr-only") {
      // Its default start is the first RSS fix.
      ASSERT_FALSE(radio.ok());
      EXPECT_THAT(radio.message(), HasSubstr("rss.csv"));
    } else {
      ASSERT_FALSE(radio.ok()) << id;
      EXPECT_THAT(radio.message(), HasSubstr("rss.csv")) << id;
      EXPECT_THAT(radio.message(), HasSubstr(id)) << id;
    }
    const Status mag = (*e)->CheckApplicable(no_mag);
    if (UsesMagnetometer(id)) {
      ASSERT_FALSE(mag.ok()) << id;
      EXPECT_THAT(mag.message(), HasSubstr("magnetometer")) << id;
    } else {
      EXPECT_TRUE(mag.ok()) << id << ": " << mag.message();
    }
    // Without a start heading the magnetometer gives it (pdr heading 'auto': Tarrio's gyro
    // heading too, issue 41); without a magnetometer either, a gyro-only heading cannot start.
    const Status start = (*e)->CheckApplicable(no_start);
    EXPECT_TRUE(start.ok()) << id << ": " << start.message();
    const Status neither = (*e)->CheckApplicable(no_start_no_mag);
    if (UsesSteps(id) && !UsesMagnetometer(id)) {
      ASSERT_FALSE(neither.ok()) << id;
      EXPECT_THAT(neither.message(), HasSubstr("initial_pose")) << id;
    }
    // Run refuses what CheckApplicable refuses.
    EXPECT_FALSE((*e)->Run(no_radio).ok()) << id;
  }
  // pdr-only from the known start needs no radio, but the start.
  auto pdr = r.Create("pdr-only", YAML::Load("{start: initial-pose}"));
  ASSERT_TRUE(pdr.ok());
  EXPECT_TRUE((*pdr)->CheckApplicable(no_radio).ok());
  Walk neither = no_radio;
  neither.meta.initial_pose.reset();
  EXPECT_THAT((*pdr)->CheckApplicable(neither).message(), HasSubstr("initial_pose"));
  // SCMT compares RSS with P_Th: a range-only walk will not do.
  Walk ranges = ShortWalk();
  for (const RssSample& s : ranges.rss) ranges.ranges.push_back({s.t_s, s.anchor_id, 3.0});
  ranges.rss.clear();
  ranges.meta.radio.kind = RadioKind::kRange;
  auto scmt = r.Create("correa-scmt-ekf");
  ASSERT_TRUE(scmt.ok());
  EXPECT_THAT((*scmt)->CheckApplicable(ranges).message(), HasSubstr("RSS"));
  auto ekf = r.Create("correa-ekf");
  ASSERT_TRUE(ekf.ok());
  EXPECT_TRUE((*ekf)->CheckApplicable(ranges).ok());
}

TEST(PaperEstimatorsTest, RunGivesCovariancesAndNisWhereThereAreInnovations) {
  const EstimatorRegistry& r = EstimatorRegistry::Builtin();
  const Walk& w = ShortWalk();
  for (const std::string& id : PaperIds()) {
    // 003's energy threshold, 10 (m/s²)², is above the simulated hip's step energy at 0.9 m/s
    // (vertical amplitude (l/K)⁴/2 ≈ 1.2 m/s²), and the simulated hip has no forward sway for
    // the PCA (it would find the lateral axis): see gadeke_test.cc.
    const YAML::Node config =
        id.rfind("gadeke-", 0) == 0
            ? YAML::Load("{pdr: {energy_threshold_m2ps4: 0.5, forward_axis: body-x}}")
            : YAML::Node();
    auto e = r.Create(id, config);
    ASSERT_TRUE(e.ok()) << id;
    auto result = (*e)->Run(w);
    ASSERT_TRUE(result.ok()) << id << ": " << result.status().message();
    const Trajectory& t = result->trajectory;
    ASSERT_GE(t.size(), 15u) << id;  // 40 s: 20 fixes at 2 s (000), 40 at 1 s (001)
    for (size_t i = 0; i < t.size(); ++i) {
      if (i > 0) ASSERT_GT(t.points[i].t_s, t.points[i - 1].t_s) << id;
      ASSERT_TRUE(t.points[i].covariance.has_value()) << id;
      const Eigen::Matrix3d& c = *t.points[i].covariance;
      ASSERT_LT((c - c.transpose()).norm(), 1e-9 * (1.0 + c.norm())) << id;
      ASSERT_GT(Eigen::Matrix2d(c.topLeftCorner(2, 2)).determinant(), 0.0) << id;
    }
    // The filters record one NIS per accepted update, ~χ²-sized; the baselines and the LS
    // fixes have no innovations.
    if (IsFilter(id)) {
      ASSERT_GT(result->nis.size(), 10u) << id;
      for (double v : result->nis) ASSERT_GE(v, 0.0) << id;
    } else {
      EXPECT_TRUE(result->nis.empty()) << id;
    }
    // Inside the 14.6 × 10.6 m classroom, give or take the radio error.
    for (const TrajectoryPoint& p : t.points) {
      ASSERT_GT(p.position_m.x(), -10.0) << id;
      ASSERT_LT(p.position_m.x(), 25.0) << id;
    }
  }
}

}  // namespace
}  // namespace walkgraph
