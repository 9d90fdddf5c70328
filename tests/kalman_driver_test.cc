#include "walkgraph/kalman_driver.h"

#include <algorithm>
#include <cmath>
#include <random>
#include <vector>

#include <gtest/gtest.h>

#include <Eigen/Dense>

namespace walkgraph {
namespace {

struct Event {
  double t_s;
};

TEST(EventTimesTest, MergesStreamsFromStartSortedOnce) {
  const std::vector<Event> a{{0.5}, {1.0}, {2.0}, {3.0}};
  const std::vector<Event> b{{1.0}, {2.5}, {0.9}};
  const std::vector<double> times = EventTimes(0.9, a, b);
  EXPECT_EQ(times, (std::vector<double>{0.9, 1.0, 2.0, 2.5, 3.0}));
  EXPECT_EQ(EventTimes(5.0, a), std::vector<double>{5.0});
}

// Constant-velocity model [x v] with position measurements, for the driver.
class ConstantVelocity : public KalmanModel {
 public:
  ConstantVelocity(std::vector<double> z, double q, double r, double gate)
      : z_(std::move(z)), q_(q), r_(r), gate_(gate) {}
  Status Initialize(double, Eigen::VectorXd* x, Eigen::MatrixXd* P) override {
    *x = Eigen::Vector2d(0.0, 0.0);
    *P = Eigen::Vector2d(4.0, 1.0).asDiagonal();
    return Status::Ok();
  }
  Status Predict(double t_prev, double t, Eigen::VectorXd* x, Eigen::MatrixXd* P,
                 Eigen::MatrixXd* F) override {
    *F = Eigen::Matrix2d::Identity();
    (*F)(0, 1) = t - t_prev;
    *x = *F * *x;
    *P = *F * *P * F->transpose() + Q(t - t_prev);
    return Status::Ok();
  }
  Status Update(size_t k, double, KalmanRun* run) override {
    Eigen::MatrixXd H(1, 2);
    H << 1.0, 0.0;
    const Eigen::VectorXd nu = Eigen::VectorXd::Constant(1, z_[k] - run->x[0]);
    return run->Update(nu, H, Eigen::MatrixXd::Constant(1, 1, r_), gate_).status();
  }
  TrajectoryPoint Output(size_t, const SmoothedState& s) const override {
    TrajectoryPoint p;
    p.t_s = s.t_s;
    p.position_m = Eigen::Vector3d(s.x[0], s.x[1], 0.0);
    return p;
  }
  Eigen::Matrix2d Q(double dt) const { return q_ * dt * Eigen::Matrix2d::Identity(); }

 private:
  std::vector<double> z_;
  double q_, r_, gate_;
};

// The smoothed trajectory is the batch least-squares solution of the same problem (prior,
// process and measurement residuals), the filtered one ends at it; every update's NIS is kept.
TEST(RunKalmanFilterTest, SmoothedEqualsBatchLeastSquares) {
  std::mt19937_64 rng(7);
  std::normal_distribution<double> n01(0.0, 1.0);
  const int N = 25;
  std::vector<double> times, z;
  for (int k = 0; k < N; ++k) {
    times.push_back(0.3 * k + 0.05 * (k % 4));
    z.push_back(0.7 * times.back() + n01(rng));
  }
  const double q = 0.2, r = 0.5;
  ConstantVelocity model(z, q, r, 0.0);
  EstimateResult filtered, smoothed;
  ASSERT_TRUE(RunKalmanFilter(times, &model, {}, &filtered).ok());
  ConstantVelocity model2(z, q, r, 0.0);
  KalmanRunOptions smooth;
  smooth.smooth = true;
  ASSERT_TRUE(RunKalmanFilter(times, &model2, smooth, &smoothed).ok());
  ASSERT_EQ(smoothed.trajectory.size(), size_t(N));
  EXPECT_EQ(filtered.nis.size(), size_t(N));

  const int n = 2;
  Eigen::MatrixXd Lam = Eigen::MatrixXd::Zero(N * n, N * n);
  Eigen::VectorXd eta = Eigen::VectorXd::Zero(N * n);
  Lam.block(0, 0, n, n) += Eigen::Vector2d(1 / 4.0, 1 / 1.0).asDiagonal();
  for (int k = 0; k < N; ++k) {
    Lam(k * n, k * n) += 1.0 / r;
    eta[k * n] += z[k] / r;
    if (k == 0) continue;
    Eigen::Matrix2d F = Eigen::Matrix2d::Identity();
    F(0, 1) = times[k] - times[k - 1];
    Eigen::MatrixXd J(n, 2 * n);
    J << -F, Eigen::Matrix2d::Identity();
    const Eigen::MatrixXd W = model.Q(times[k] - times[k - 1]).inverse();
    const Eigen::MatrixXd JtWJ = J.transpose() * W * J;
    for (int a = 0; a < 2; ++a) {
      for (int b = 0; b < 2; ++b) {
        Lam.block((k - 1 + a) * n, (k - 1 + b) * n, n, n) += JtWJ.block(a * n, b * n, n, n);
      }
    }
  }
  const Eigen::VectorXd batch = Lam.ldlt().solve(eta);
  for (int k = 0; k < N; ++k) {
    EXPECT_NEAR(smoothed.trajectory.points[k].position_m.x(), batch[k * n], 1e-9) << k;
    EXPECT_NEAR(smoothed.trajectory.points[k].position_m.y(), batch[k * n + 1], 1e-9) << k;
    EXPECT_EQ(smoothed.trajectory.points[k].t_s, times[k]);
  }
  EXPECT_NEAR(filtered.trajectory.points.back().position_m.x(), batch[(N - 1) * n], 1e-9);
  EXPECT_GT(std::fabs(filtered.trajectory.points[0].position_m.x() - batch[0]), 1e-3);
}

TEST(RunKalmanFilterTest, GatedUpdatesAreCountedNotKept) {
  std::vector<double> times{0.0, 1.0, 2.0, 3.0}, z{0.0, 0.1, 50.0, 0.2};
  ConstantVelocity model(z, 0.01, 0.1, 0.99);
  EstimateResult result;
  ASSERT_TRUE(RunKalmanFilter(times, &model, {}, &result).ok());
  EXPECT_EQ(result.nis.size(), 3u);
  EXPECT_EQ(result.diagnostics["gated_updates"], 1.0);
  EXPECT_FALSE(RunKalmanFilter({}, &model, {}, &result).ok());
}

// Measurements of a scalar random walk x_k = x_{k−1} + w_k (variance q) with noise variance r.
std::vector<double> RandomWalkMeasurements(int n, double q, double r) {
  std::mt19937_64 rng(3);
  std::normal_distribution<double> n01(0.0, 1.0);
  std::vector<double> z(n);
  double truth = 0.0;
  for (int k = 0; k < n; ++k) {
    if (k > 0) truth += std::sqrt(q) * n01(rng);
    z[k] = truth + std::sqrt(r) * n01(rng);
  }
  return z;
}

// The full-rate KF of that random walk (x_0 = 0, P_0 = p0), one epoch per measurement at t = k.
std::vector<FilterEpoch> RandomWalkKalman(const std::vector<double>& z, double q, double r,
                                          double p0) {
  std::vector<FilterEpoch> full;
  Eigen::VectorXd x = Eigen::VectorXd::Zero(1);
  Eigen::MatrixXd P = Eigen::MatrixXd::Constant(1, 1, p0);
  const Eigen::MatrixXd H = Eigen::MatrixXd::Ones(1, 1), R = Eigen::MatrixXd::Constant(1, 1, r);
  for (size_t k = 0; k < z.size(); ++k) {
    FilterEpoch e;
    e.t_s = static_cast<double>(k);
    if (k > 0) {
      P(0, 0) += q;
      e.F = Eigen::MatrixXd::Ones(1, 1);
    }
    e.x_prior = x;
    e.P_prior = P;
    EXPECT_TRUE(KalmanUpdate(Eigen::VectorXd::Constant(1, z[k] - x[0]), H, R, 0, &x, &P).ok());
    e.x_post = x;
    e.P_post = P;
    full.push_back(e);
  }
  return full;
}

// A scalar random walk x_k = x_{k−1} + w_k (variance q), measured at every sample (variance r),
// filtered in error-state form (nominal + error, reset after each update) with a clone at every
// third sample: the cloned smoother's output epochs equal the full-rate RTS at those samples.
TEST(ClonedErrorSmootherTest, EqualsFullRateRtsAtTheOutputEpochs) {
  const int N = 31, every = 3;
  const double q = 0.3, r = 0.8, p0 = 2.0;
  const std::vector<double> z = RandomWalkMeasurements(N, q, r);
  const std::vector<FilterEpoch> full = RandomWalkKalman(z, q, r, p0);
  auto reference = RtsSmooth(full);
  ASSERT_TRUE(reference.ok());
  const Eigen::MatrixXd R = Eigen::MatrixXd::Constant(1, 1, r);

  // Error state [δ_now, δ_clone] about the nominal y.
  ClonedErrorSmoother<double> smoother;
  double y = 0.0;
  Eigen::VectorXd dx = Eigen::VectorXd::Zero(2);
  Eigen::MatrixXd Pa = Eigen::MatrixXd::Constant(2, 2, p0);
  Eigen::MatrixXd Ha(1, 2);
  Ha << 1.0, 0.0;
  for (int k = 0; k < N; ++k) {
    if (k > 0) Pa(0, 0) += q;
    ASSERT_TRUE(
        KalmanUpdate(Eigen::VectorXd::Constant(1, z[k] - y - dx[0]), Ha, R, 0, &dx, &Pa).ok());
    y += dx[0];  // inject and reset
    dx[0] = 0.0;
    if (k % every != 0) continue;
    const ErrorClone clone{dx.tail(1), Pa.bottomRightCorner(1, 1), Pa.topRightCorner(1, 1)};
    smoother.Record(k, y, Pa.topLeftCorner(1, 1), k > 0 ? &clone : nullptr);
    dx[1] = 0.0;  // new clone of the current error
    Pa.row(1) = Pa.row(0);
    Pa.col(1) = Pa.col(0);
  }
  auto points = smoother.Smooth([](double nominal, const SmoothedState& s) {
    TrajectoryPoint p;
    p.t_s = s.t_s;
    p.position_m.x() = nominal + s.x[0];
    p.covariance = Eigen::Matrix3d::Identity() * s.P(0, 0);
    return p;
  });
  ASSERT_TRUE(points.ok()) << points.status().message();
  ASSERT_EQ(points->size(), size_t((N - 1) / every + 1));
  for (const TrajectoryPoint& p : *points) {
    const int k = static_cast<int>(p.t_s);
    EXPECT_NEAR(p.position_m.x(), (*reference)[k].x[0], 1e-9) << k;
    EXPECT_NEAR((*p.covariance)(0, 0), (*reference)[k].P(0, 0), 1e-9) << k;
  }
}

// The random walk in error-state form for RunErrorStateFilter: nominal y, error [δ_now] or, with
// the clone, [δ_now, δ_clone]; each update injected into y and the error reset.
class RandomWalkModel final : public ClonedErrorStateModel<double> {
 public:
  RandomWalkModel(std::vector<double> t, std::vector<double> z, double q, double r, double p0,
                  bool clone)
      : t_(std::move(t)), z_(std::move(z)), q_(q), R_(Eigen::MatrixXd::Constant(1, 1, r)) {
    const int n = clone ? 2 : 1;
    dx_ = Eigen::VectorXd::Zero(n);
    P_ = Eigen::MatrixXd::Constant(n, n, p0);
    H_ = Eigen::MatrixXd::Zero(1, n);
    H_(0, 0) = 1.0;
  }
  size_t size() const override { return t_.size(); }
  double Time(size_t k) const override { return t_[k]; }
  Status Propagate(size_t) override {
    P_(0, 0) += q_;  // F = 1: the clone's cross-covariance is unchanged
    return Status::Ok();
  }
  Status Update(size_t k) override {
    const Eigen::VectorXd nu = Eigen::VectorXd::Constant(1, z_[k] - y_ - dx_[0]);
    WG_RETURN_IF_ERROR(KalmanUpdate(nu, H_, R_, 0, &dx_, &P_).status());
    y_ += dx_[0];
    dx_[0] = 0.0;
    return Status::Ok();
  }
  void Output(size_t k, std::vector<TrajectoryPoint>* points) override {
    points->push_back(Point(t_[k], y_, P_(0, 0)));
  }
  const double& nominal() const override { return y_; }
  Eigen::MatrixXd Covariance() const override { return P_.topLeftCorner(1, 1); }
  const ErrorClone& Clone() override {
    clone_ = {dx_.tail(1), P_.bottomRightCorner(1, 1), P_.topRightCorner(1, 1)};
    return clone_;
  }
  void StartClone() override {
    dx_[1] = 0.0;
    P_.row(1) = P_.row(0);
    P_.col(1) = P_.col(0);
  }
  TrajectoryPoint SmoothedPoint(const double& y, const SmoothedState& s) const override {
    return Point(s.t_s, y + s.x[0], s.P(0, 0));
  }

 private:
  static TrajectoryPoint Point(double t, double x, double var) {
    TrajectoryPoint p;
    p.t_s = t;
    p.position_m.x() = x;
    p.covariance = Eigen::Matrix3d::Identity() * var;
    return p;
  }
  const std::vector<double> t_, z_;
  const double q_;
  const Eigen::MatrixXd R_;
  Eigen::VectorXd dx_;
  Eigen::MatrixXd P_, H_;
  double y_ = 0.0;
  ErrorClone clone_;
};

// Every third sample and the last are the output epochs; filtered they are the full-rate KF's
// estimates there, smoothed (cloned RTS) the full-rate RTS's.
TEST(RunErrorStateFilterTest, DecimatedFilterAndClonedRtsEqualFullRateKalmanAndRts) {
  const int N = 32;
  const double q = 0.3, r = 0.8, p0 = 2.0;
  const std::vector<double> z = RandomWalkMeasurements(N, q, r);
  const std::vector<FilterEpoch> full = RandomWalkKalman(z, q, r, p0);
  auto reference = RtsSmooth(full);
  ASSERT_TRUE(reference.ok());
  std::vector<double> t(N);
  for (int k = 0; k < N; ++k) t[k] = k;
  const std::vector<size_t> expected{0, 3, 6, 9, 12, 15, 18, 21, 24, 27, 30, 31};
  for (bool smooth : {false, true}) {
    RandomWalkModel model(t, z, q, r, p0, smooth);
    ErrorStateRunOptions options;
    options.smooth = smooth;
    options.output_every = 3;
    std::vector<TrajectoryPoint> points;
    size_t epochs = 0;
    ASSERT_TRUE(RunErrorStateFilter(&model, options, &points, &epochs).ok());
    ASSERT_EQ(points.size(), expected.size());
    EXPECT_EQ(epochs, expected.size());
    for (size_t i = 0; i < expected.size(); ++i) {
      const size_t k = expected[i];
      EXPECT_EQ(points[i].t_s, t[k]);
      const double x = smooth ? (*reference)[k].x[0] : full[k].x_post[0];
      const double var = smooth ? (*reference)[k].P(0, 0) : full[k].P_post(0, 0);
      EXPECT_NEAR(points[i].position_m.x(), x, 1e-9) << k << (smooth ? " smoothed" : "");
      EXPECT_NEAR((*points[i].covariance)(0, 0), var, 1e-9) << k << (smooth ? " smoothed" : "");
    }
  }
}

// With output_period_s the output epochs are the first sample at or after each multiple of the
// period from the start (irregular times), and the last.
TEST(RunErrorStateFilterTest, PeriodDecimationTakesFirstSampleOfEachPeriodAndTheLast) {
  const int N = 40;
  std::vector<double> t(N);
  for (int k = 0; k < N; ++k) t[k] = 10.0 + 0.13 * k + 0.04 * (k % 3);
  const double period = 0.5;
  std::vector<double> expected;
  for (int m = 0; 10.0 + m * period <= t.back(); ++m) {
    const double due = 10.0 + m * period - 1e-9;
    const double first = *std::find_if(t.begin(), t.end(), [due](double tk) { return tk >= due; });
    if (expected.empty() || expected.back() != first) expected.push_back(first);
  }
  if (expected.back() != t.back()) expected.push_back(t.back());
  RandomWalkModel model(t, RandomWalkMeasurements(N, 0.3, 0.8), 0.3, 0.8, 2.0, false);
  ErrorStateRunOptions options;
  options.output_period_s = period;
  std::vector<TrajectoryPoint> points;
  ASSERT_TRUE(RunErrorStateFilter(&model, options, &points).ok());
  std::vector<double> times;
  for (const TrajectoryPoint& p : points) times.push_back(p.t_s);
  EXPECT_EQ(times, expected);
  EXPECT_LT(times.size(), size_t(N));
  options.smooth = true;  // smoothing needs the clone
  EXPECT_FALSE(RunErrorStateFilter(static_cast<ErrorStateModel*>(&model), options, &points).ok());
}

}  // namespace
}  // namespace walkgraph
