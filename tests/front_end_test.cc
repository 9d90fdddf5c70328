#include "walkgraph/filters/front_end.h"

#include "config/parsers.h"

#include <cmath>

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <Eigen/Dense>

namespace walkgraph {
namespace {

using ::testing::HasSubstr;

TEST(RadioFrontEndOptionsTest, OverlaysTheGivenDefaultsAndIsStrict) {
  RadioFrontEndOptions paper;
  paper.epochs.window_s = 2.0;
  paper.method = PositioningMethod::kNonlinearLs;
  paper.weighted = false;
  auto same = RadioFrontEndOptionsFromYaml(YAML::Node(), paper, "x");
  ASSERT_TRUE(same.ok());
  EXPECT_EQ(same->epochs.window_s, 2.0);
  EXPECT_EQ(same->method, PositioningMethod::kNonlinearLs);
  EXPECT_FALSE(same->weighted);
  auto o = RadioFrontEndOptionsFromYaml(
      YAML::Load("{window_s: 0.5, method: hyperbolic, weighted: true, max_iterations: 7}"), paper,
      "x");
  ASSERT_TRUE(o.ok());
  EXPECT_EQ(o->epochs.window_s, 0.5);
  EXPECT_EQ(o->method, PositioningMethod::kHyperbolic);
  EXPECT_TRUE(o->weighted);
  EXPECT_EQ(o->positioning.max_iterations, 7);
  auto bad = RadioFrontEndOptionsFromYaml(YAML::Load("{windoe_s: 1}"), paper, "tarrio-kf");
  ASSERT_FALSE(bad.ok());
  EXPECT_THAT(bad.status().message(), HasSubstr("tarrio-kf radio"));
  EXPECT_THAT(bad.status().message(), HasSubstr("windoe_s"));
  EXPECT_FALSE(RadioFrontEndOptionsFromYaml(YAML::Load("{method: lsq}"), paper, "x").ok());
  EXPECT_FALSE(RadioFrontEndOptionsFromYaml(YAML::Load("{window_s: 0}"), paper, "x").ok());
}

TEST(PdrOptionsFromYamlTest, PaperDefaultsUnderTheUsersKeys) {
  const std::map<std::string, std::string> paper = {
      {"detector", "energy"}, {"forward_axis", "pca"}, {"energy_threshold_m2ps4", "10"}};
  auto d = PdrOptionsFromYaml(YAML::Node(), paper, "gadeke-kf pdr");
  ASSERT_TRUE(d.ok());
  EXPECT_EQ(d->detector, StepDetector::kEnergy);
  EXPECT_EQ(d->forward_axis, ForwardAxisMethod::kPca);
  EXPECT_EQ(d->energy_threshold_m2ps4, 10.0);
  EXPECT_EQ(d->weinberg_k, PdrOptions().weinberg_k);  // untouched keys keep pdr.h's defaults
  auto u = PdrOptionsFromYaml(YAML::Load("{forward_axis: body-x, weinberg_k: 0.5}"), paper, "g");
  ASSERT_TRUE(u.ok());
  EXPECT_EQ(u->detector, StepDetector::kEnergy);
  EXPECT_EQ(u->forward_axis, ForwardAxisMethod::kBodyX);
  EXPECT_EQ(u->weinberg_k, 0.5);
  auto bad = PdrOptionsFromYaml(YAML::Load("{weinberg: 0.5}"), paper, "gadeke-kf pdr");
  ASSERT_FALSE(bad.ok());
  EXPECT_THAT(bad.status().message(), HasSubstr("gadeke-kf pdr"));
  EXPECT_THAT(bad.status().message(), HasSubstr("weinberg"));
  EXPECT_FALSE(PdrOptionsFromYaml(YAML::Load("[1, 2]"), paper, "g").ok());
}

TEST(WithoutKeysTest, DropsOnlyTheListedTopLevelKeys) {
  auto n = WithoutKeys(YAML::Load("{a: 1, pdr: {b: 2}, radio: {c: 3}}"), {"pdr", "radio"}, "x");
  ASSERT_TRUE(n.ok());
  EXPECT_EQ(n->size(), 1u);
  EXPECT_EQ((*n)["a"].as<int>(), 1);
  auto empty = WithoutKeys(YAML::Node(), {"pdr"}, "x");
  ASSERT_TRUE(empty.ok());
  EXPECT_EQ(empty->size(), 0u);
  EXPECT_FALSE(WithoutKeys(YAML::Load("3"), {"pdr"}, "x").ok());
}

// Four anchors at the corners of a 10 m square; range readings from a walker standing at
// `p`, with `noise` added to anchor i's range as noise[i].
Walk RangeWalk(const Eigen::Vector2d& p, const Eigen::Vector4d& noise) {
  Walk w;
  w.meta.radio.kind = RadioKind::kRange;
  w.meta.radio.range_sigma_m = 0.5;
  const Eigen::Vector2d corners[4] = {{0, 0}, {10, 0}, {10, 10}, {0, 10}};
  for (int i = 0; i < 4; ++i) w.anchors.push_back({i + 1, {corners[i].x(), corners[i].y(), 0}});
  for (int k = 0; k < 3; ++k) {
    for (int i = 0; i < 4; ++i) {
      w.ranges.push_back({k + 0.1 * i, i + 1, (p - corners[i]).norm() + noise[i]});
    }
  }
  return w;
}

TEST(PositionFixesFromFrontEndTest, UnweightedLsIsEquation5WithResidualCovariance) {
  const Eigen::Vector2d p(3.0, 4.0);
  RadioFrontEndOptions o;
  o.epochs.window_s = 1.0;
  o.method = PositioningMethod::kNonlinearLs;
  o.weighted = false;
  o.positioning.min_sigma_m = 0.01;
  auto exact = PositionFixesFromFrontEnd(RangeWalk(p, Eigen::Vector4d::Zero()), o, "x");
  ASSERT_TRUE(exact.ok()) << exact.status().message();
  ASSERT_EQ(exact->fixes.size(), 3u);
  EXPECT_EQ(exact->epochs, 3);
  EXPECT_EQ(exact->failed_epochs, 0);
  EXPECT_LT((exact->fixes[0].position_m - p).norm(), 1e-6);
  EXPECT_TRUE(exact->strongest.empty());  // a range walk has no RSS
  // With noisy ranges: the minimizer of Σ (d̂_i − ‖s_i − m‖)², found here by brute force on a
  // 1 mm grid, and Cov = s²(JᵀJ)⁻¹ with s² = Σ r_i²/(n − 2).
  const Eigen::Vector4d noise(0.4, -0.3, 0.5, 0.2);
  const Walk w = RangeWalk(p, noise);
  auto noisy = PositionFixesFromFrontEnd(w, o, "x");
  ASSERT_TRUE(noisy.ok());
  auto cost = [&](const Eigen::Vector2d& m) {
    double c = 0.0;
    for (int i = 0; i < 4; ++i) {
      const double r = w.ranges[i].range_m - (m - w.anchors[i].position_m.head<2>()).norm();
      c += r * r;
    }
    return c;
  };
  Eigen::Vector2d best = p;
  for (double x = 2.5; x <= 3.5; x += 1e-3) {
    for (double y = 3.5; y <= 4.5; y += 1e-3) {
      if (cost({x, y}) < cost(best)) best = {x, y};
    }
  }
  const PositionFix& f = noisy->fixes[0];
  EXPECT_LT((f.position_m - best).norm(), 2e-3);
  Eigen::Matrix2d jtj = Eigen::Matrix2d::Zero();
  for (int i = 0; i < 4; ++i) {
    const Eigen::Vector2d u = (f.position_m - w.anchors[i].position_m.head<2>()).normalized();
    jtj += u * u.transpose();
  }
  const Eigen::Matrix2d expected = cost(f.position_m) / 2.0 * jtj.inverse();
  EXPECT_LT((f.covariance - expected).norm(), 1e-6 * expected.norm());
  // The weighted fix (σ_i from range_sigma_m, all equal here) lands on the same point.
  o.weighted = true;
  auto weighted = PositionFixesFromFrontEnd(w, o, "x");
  ASSERT_TRUE(weighted.ok());
  EXPECT_LT((weighted->fixes[0].position_m - f.position_m).norm(), 1e-5);
}

TEST(PositionFixesFromFrontEndTest, StrongestReadingIsTheNearestAnchorAtTheFixTime) {
  Walk w;
  w.meta.radio.kind = RadioKind::kRss;
  w.meta.radio.path_loss = {-60.0, 2.5, 1.0, 5.0};
  const Eigen::Vector2d corners[4] = {{0, 0}, {10, 0}, {10, 10}, {0, 10}};
  for (int i = 0; i < 4; ++i) w.anchors.push_back({i + 1, {corners[i].x(), corners[i].y(), 0}});
  const PathLossModel model(w.meta.radio.path_loss, RssUnits::kDbm);
  const Eigen::Vector2d p(8.0, 1.0);  // nearest: anchor 2 at (10, 0)
  for (int i = 0; i < 4; ++i) {
    w.rss.push_back({0.2 + 0.1 * i, i + 1, model.ExpectedRss((p - corners[i]).norm())});
  }
  RadioFrontEndOptions o;
  o.epochs.window_s = 1.0;
  auto fixes = PositionFixesFromFrontEnd(w, o, "x");
  ASSERT_TRUE(fixes.ok()) << fixes.status().message();
  ASSERT_EQ(fixes->strongest.size(), 1u);
  const RangeMeasurement& s = fixes->strongest[0];
  EXPECT_EQ(s.anchor_id, 2);
  EXPECT_EQ(s.t_s, fixes->fixes[0].t_s);
  EXPECT_NEAR(s.rss, model.ExpectedRss(std::sqrt(5.0)), 1e-9);
  EXPECT_TRUE(s.from_rss);
  EXPECT_LT((fixes->fixes[0].position_m - p).norm(), 1e-6);  // exact RSS, exact fix
  // No epoch with three anchors: no fix, and the message says which estimator asked.
  w.rss.resize(2);
  auto none = PositionFixesFromFrontEnd(w, o, "tarrio-kf");
  ASSERT_FALSE(none.ok());
  EXPECT_THAT(none.status().message(), HasSubstr("tarrio-kf"));
}

TEST(CheckInputTest, MessagesNameTheEstimatorAndTheMissingFile) {
  Walk w;
  PdrOptions pdr;
  Status s = CheckStepInput(w, pdr, false, "tarrio-kf");
  EXPECT_THAT(s.message(), HasSubstr("tarrio-kf"));
  EXPECT_THAT(s.message(), HasSubstr("imu.csv"));
  w.odometry.push_back({1.0, 0.5, 0.0});
  EXPECT_TRUE(CheckStepInput(w, pdr, false, "x").ok());
  EXPECT_THAT(CheckStepInput(w, pdr, true, "x").message(), HasSubstr("initial_pose"));
  w.meta.initial_pose = InitialPose{};
  EXPECT_TRUE(CheckStepInput(w, pdr, true, "x").ok());
  Status r = CheckRadioInput(w, 3, "correa-ls");
  EXPECT_THAT(r.message(), HasSubstr("rss.csv or range.csv"));
  w.rss.push_back({0.0, 1, -70.0});
  w.anchors.push_back({1, Eigen::Vector3d::Zero()});
  EXPECT_THAT(CheckRadioInput(w, 3, "correa-ls").message(), HasSubstr("at least 3 anchors"));
  EXPECT_TRUE(CheckRadioInput(w, 1, "gadeke-kf").ok());
}

TEST(TrajectoryOfFixesTest, KeepsTimesPositionsAndCovariances) {
  PositionFix a, b;
  a.t_s = 1.0;
  a.position_m = {1, 2};
  a.covariance << 2, 0.5, 0.5, 3;
  b.t_s = 2.0;
  const Trajectory t = TrajectoryOfFixes({a, b});
  ASSERT_EQ(t.size(), 2u);
  EXPECT_EQ(t.points[0].position_m, Eigen::Vector3d(1, 2, 0));
  EXPECT_EQ(Eigen::Matrix2d(t.points[0].covariance->topLeftCorner(2, 2)), a.covariance);
  EXPECT_NEAR((*t.points[0].covariance)(2, 2), M_PI * M_PI, 1e-12);
}

}  // namespace
}  // namespace walkgraph
