// Divergence: the rules of divergence.h on hand-made estimates, and compare's handling of a
// diverged estimator (not ranked, shown as diverged, Monte Carlo runs counted).
#include <cmath>
#include <limits>
#include <string>

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <yaml-cpp/yaml.h>

#include "walkgraph/compare.h"
#include "walkgraph/divergence.h"
#include "walkgraph/io.h"

namespace walkgraph {
namespace {

using ::testing::HasSubstr;

// A 100-s walk along x at 1 m/s, truth at 1 Hz, two anchors at the ends.
Walk Line() {
  Walk w;
  w.meta.name = "line";
  w.meta.truth_kind = TruthKind::kContinuous;
  w.anchors = {{1, Eigen::Vector3d(0, 0, 0)}, {2, Eigen::Vector3d(100, 0, 0)}};
  for (int i = 0; i <= 100; ++i) {
    w.truth.push_back({static_cast<double>(i), Eigen::Vector3d(i, 0, 0), false});
    w.odometry.push_back({i + 0.5, 1.0, 0.0});
  }
  return w;
}

// The truth offset by `dy` north, with position variance `var` (none when 0).
Trajectory Offset(const Walk& w, double dy, double var) {
  Trajectory t;
  for (const TruthSample& s : w.truth) {
    TrajectoryPoint p;
    p.t_s = s.t_s;
    p.position_m = s.position_m + Eigen::Vector3d(0, dy, 0);
    if (var > 0) p.covariance = Eigen::Matrix3d::Identity() * var;
    t.points.push_back(p);
  }
  return t;
}

std::optional<Divergence> Check(const Walk& w, const Trajectory& t) {
  auto e = ComputeErrors(w, t);
  EXPECT_TRUE(e.ok());
  return CheckDivergence(w, t, *e, 0.0);
}

TEST(CheckDivergence, AnHonestEstimateHolds) {
  const Walk w = Line();
  EXPECT_FALSE(Check(w, Offset(w, 0.5, 0.25)));    // NEES 1
  EXPECT_FALSE(Check(w, Offset(w, 40.0, 0.0)));    // 40 m off, but inside the margin (50 m)
  EXPECT_FALSE(Check(w, Offset(w, 20.0, 100.0)));  // wrong but honest: NEES 4
}

TEST(CheckDivergence, LeavingTheSceneNonFiniteAndNonPdCovariances) {
  const Walk w = Line();
  Trajectory t = Offset(w, 0.0, 1.0);
  t.points[30].position_m.y() = 2500.0;
  auto d = Check(w, t);
  ASSERT_TRUE(d);
  EXPECT_EQ(d->t_s, 30.0);
  EXPECT_THAT(d->reason, HasSubstr("2.5 km outside the scene"));
  EXPECT_THAT(ToString(*d), HasSubstr("diverged at 30 s: "));
  t = Offset(w, 0.0, 1.0);
  t.points[12].heading_rad = std::numeric_limits<double>::quiet_NaN();
  EXPECT_EQ(Check(w, t)->t_s, 12.0);
  t = Offset(w, 0.0, 1.0);
  (*t.points[20].covariance)(1, 1) = -1.0;
  d = Check(w, t);
  ASSERT_TRUE(d);
  EXPECT_EQ(d->t_s, 20.0);
  EXPECT_THAT(d->reason, HasSubstr("not positive semi-definite"));
  // A zero covariance (a point held constant to fix the gauge, as the step graph's first node
  // without a known start) is no divergence.
  t = Offset(w, 0.0, 1.0);
  *t.points[20].covariance = Eigen::Matrix3d::Zero();
  EXPECT_FALSE(Check(w, t));
  // Before the scored part (score_from) nothing counts.
  t = Offset(w, 0.0, 1.0);
  t.points[5].position_m.y() = 2500.0;
  auto e = ComputeErrors(w, t);
  EXPECT_FALSE(CheckDivergence(w, t, *e, 10.0));
}

TEST(CheckDivergence, AbsurdOverconfidenceOverAWindow) {
  const Walk w = Line();
  // 20 m off with σ = 1 cm: NEES 4e6 everywhere.
  auto d = Check(w, Offset(w, 20.0, 1e-4));
  ASSERT_TRUE(d);
  EXPECT_EQ(d->t_s, 0.0);
  EXPECT_THAT(d->reason, HasSubstr("median position NEES 4e+06 at a median error of 20 m"));
  // As overconfident but close (5 m, under nees_min_error_m): a tight filter, not a diverged one.
  EXPECT_FALSE(Check(w, Offset(w, 5.0, 1e-4)));
  // Overconfident from t = 40 s on only: the window starts there.
  Trajectory late = Offset(w, 0.5, 0.25);
  for (auto& p : late.points) {
    if (p.t_s >= 40) p = Offset(w, 20.0, 1e-4).points[static_cast<size_t>(p.t_s)];
  }
  d = Check(w, late);
  ASSERT_TRUE(d);
  EXPECT_EQ(d->t_s, 40.0);
  // One absurd point among honest ones does not make a window.
  Trajectory t = Offset(w, 0.5, 0.25);
  t.points[50].covariance = Eigen::Matrix3d::Identity() * 1e-8;
  EXPECT_FALSE(Check(w, t));
  DivergenceOptions off;
  off.enabled = false;
  auto e = ComputeErrors(w, Offset(w, 20.0, 1e-4));
  EXPECT_FALSE(CheckDivergence(w, Offset(w, 20.0, 1e-4), *e, 0.0, off));
  DivergenceOptions bad;
  bad.nees_limit = 1.0;
  EXPECT_FALSE(bad.Validate().ok());
}

// Test-only estimator: the truth offset by dy north with position variance var; diverges to
// 10 km when `runaway`.
class Fake : public Estimator {
 public:
  Fake(double dy, double var, bool runaway) : dy_(dy), var_(var), runaway_(runaway) {}
  Status CheckApplicable(const Walk&) const override { return Status::Ok(); }
  StatusOr<EstimateResult> Run(const Walk& walk) const override {
    EstimateResult r;
    r.trajectory = Offset(walk, dy_, var_);
    if (runaway_) {
      for (auto& p : r.trajectory.points) p.position_m.y() += p.t_s > 60 ? 1e4 : 0.0;
    }
    return r;
  }

 private:
  double dy_, var_;
  bool runaway_;
};

EstimatorRegistry FakeRegistry() {
  EstimatorRegistry r;
  const auto add = [&](const std::string& id, double dy, bool runaway) {
    EXPECT_TRUE(r.Register({id, "test",
                            [=](const Config&) -> StatusOr<std::unique_ptr<Estimator>> {
                              return std::unique_ptr<Estimator>(new Fake(dy, 1.0, runaway));
                            }})
                    .ok());
  };
  add("good", 0.5, false);
  add("runaway", 0.01, true);  // the smallest errors until it runs away: must not be "best"
  return r;
}

TEST(CompareOnWalk, ADivergedEstimatorIsShownAsDivergedAndNeverBest) {
  const EstimatorRegistry registry = FakeRegistry();
  CompareOptions o;
  o.estimator_ids = {"good", "runaway"};
  auto c = CompareOnWalk(Line(), o, registry);
  ASSERT_TRUE(c.ok()) << c.status().message();
  ASSERT_TRUE(c->outcomes[1].divergence);
  EXPECT_EQ(c->outcomes[1].divergence->t_s, 61.0);
  EXPECT_FALSE(c->outcomes[1].Ranked());
  EXPECT_TRUE(c->outcomes[0].Ranked());
  const std::string table = FormatComparisonTable(*c);
  EXPECT_THAT(table,
              ::testing::ContainsRegex("runaway +diverged at 61 s: 10 km outside the scene"));
  EXPECT_THAT(table, HasSubstr("0.500*"));  // the honest one is the best
  o.divergence.keep_in_figures = true;
  c = CompareOnWalk(Line(), o, registry);
  ASSERT_TRUE(c.ok());
  EXPECT_TRUE(c->outcomes[1].Ranked());
  EXPECT_THAT(FormatComparisonTable(*c), HasSubstr("(kept in the figures)"));
}

TEST(CompareMonteCarlo, DivergedRunsAreCountedAndLeftOut) {
  const EstimatorRegistry registry = FakeRegistry();
  CompareOptions o;
  o.estimator_ids = {"good", "runaway"};
  MonteCarloOptions mc;
  mc.runs = 3;
  auto c = CompareMonteCarlo([](uint64_t) -> StatusOr<Walk> { return Line(); }, o, mc, registry);
  ASSERT_TRUE(c.ok()) << c.status().message();
  const EstimatorOutcome& runaway = c->outcomes[1];
  EXPECT_EQ(runaway.diverged_runs, 3);
  EXPECT_FALSE(runaway.Ranked());
  EXPECT_THAT(runaway.divergence->reason, HasSubstr("run 0: "));
  EXPECT_EQ(c->outcomes[0].diverged_runs, 0);
}

}  // namespace
}  // namespace walkgraph
