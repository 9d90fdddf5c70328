#include "walkgraph/metrics.h"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <optional>

#include <Eigen/Cholesky>
#include <Eigen/Geometry>

#include "util/rigid2d.h"

namespace walkgraph {

double Percentile(std::vector<double> values, double q) {
  if (values.empty()) return 0.0;
  std::sort(values.begin(), values.end());
  const double pos = std::clamp(q, 0.0, 100.0) / 100.0 * static_cast<double>(values.size() - 1);
  const size_t lo = static_cast<size_t>(std::floor(pos));
  const size_t hi = std::min(lo + 1, values.size() - 1);
  const double w = pos - static_cast<double>(lo);
  return (1.0 - w) * values[lo] + w * values[hi];
}

QuantileSketch::QuantileSketch(double relative_accuracy)
    : alpha_(std::clamp(relative_accuracy, 1e-8, 0.5)),
      log_gamma_(std::log((1.0 + alpha_) / (1.0 - alpha_))) {}

void QuantileSketch::Add(double value) {
  ++count_;
  if (!(value > kZero)) {  // also NaN: errors are never NaN here, but the count stays right
    ++zeros_;
    return;
  }
  const int i = static_cast<int>(std::ceil(std::log(value) / log_gamma_));
  if (counts_.empty()) {
    offset_ = i;
    counts_.assign(1, 0);
  } else if (i < offset_) {
    counts_.insert(counts_.begin(), static_cast<size_t>(offset_ - i), 0);
    offset_ = i;
  } else if (i >= offset_ + static_cast<int>(counts_.size())) {
    counts_.resize(static_cast<size_t>(i - offset_ + 1), 0);
  }
  ++counts_[static_cast<size_t>(i - offset_)];
}

double QuantileSketch::Value(long long rank) const {
  if (rank < zeros_) return 0.0;
  long long seen = zeros_;
  for (size_t k = 0; k < counts_.size(); ++k) {
    seen += counts_[k];
    if (rank < seen) {
      const double gamma = std::exp(log_gamma_);
      return 2.0 * std::exp(log_gamma_ * (offset_ + static_cast<double>(k))) / (gamma + 1.0);
    }
  }
  return 0.0;
}

double QuantileSketch::Percentile(double q) const {
  if (count_ == 0) return 0.0;
  const double pos = std::clamp(q, 0.0, 100.0) / 100.0 * static_cast<double>(count_ - 1);
  const long long lo = static_cast<long long>(std::floor(pos));
  const long long hi = std::min(lo + 1, count_ - 1);
  const double w = pos - static_cast<double>(lo);
  return (1.0 - w) * Value(lo) + w * Value(hi);
}

namespace {

// eᵀP⁻¹e, or nullopt when P (symmetrized) is not positive definite.
std::optional<double> Nees(const Eigen::Vector2d& e, const Eigen::Matrix2d& P) {
  const Eigen::Matrix2d S = 0.5 * (P + P.transpose());
  const Eigen::LLT<Eigen::Matrix2d> llt(S);
  if (llt.info() != Eigen::Success || !S.allFinite()) return std::nullopt;
  return e.dot(llt.solve(e));
}

}  // namespace

StatusOr<ErrorSeries> ComputeErrors(const Walk& walk, const Trajectory& trajectory,
                                    Alignment alignment) {
  if (walk.truth.empty()) return FailedPrecondition("walk '" + walk.meta.name + "' has no truth");
  if (trajectory.empty()) return FailedPrecondition("empty trajectory");
  const double t0 = trajectory.points.front().t_s;
  const double t1 = trajectory.points.back().t_s;
  std::vector<double> t, walked;
  std::vector<Eigen::Vector2d> est, ref;
  int skipped = 0;
  const std::vector<double> distances = walk.TruthDistances();
  for (size_t i = 0; i < walk.truth.size(); ++i) {
    const TruthSample& s = walk.truth[i];
    if (s.t_s < t0 || s.t_s > t1) {
      ++skipped;
      continue;
    }
    t.push_back(s.t_s);
    walked.push_back(distances[i]);
    est.push_back(trajectory.PositionAt(s.t_s).head<2>());
    ref.push_back(s.position_m.head<2>());
  }
  if (t.empty()) return FailedPrecondition("no truth sample inside the trajectory's time span");
  std::vector<int> floors_missed;
  if (walk.has_truth_floors()) {
    const int start_floor = walk.StartFloor();
    for (size_t i = 0; i < walk.truth.size(); ++i) {
      const TruthSample& s = walk.truth[i];
      if (s.t_s < t0 || s.t_s > t1) continue;
      const int truth_floor = s.floor.value_or(start_floor);
      const int est_floor = trajectory.FloorAt(s.t_s).value_or(start_floor);
      floors_missed.push_back(std::abs(est_floor - truth_floor));
    }
  }
  Eigen::Matrix2d rotation = Eigen::Matrix2d::Identity();
  if (alignment == Alignment::kSE2 && t.size() >= 2) {
    const internal::Rigid2d f = internal::FitRigid2d(est, ref, est.size());
    rotation = f.R;
    for (Eigen::Vector2d& e : est) e = f(e);
  }
  ErrorSeries out;
  out.t_s = std::move(t);
  out.distance_m = std::move(walked);
  out.n_skipped = skipped;
  out.floors_missed = std::move(floors_missed);
  out.error_m.reserve(est.size());
  for (size_t i = 0; i < est.size(); ++i) out.error_m.push_back((est[i] - ref[i]).norm());
  if (trajectory.points.front().covariance) {
    out.nees.reserve(est.size());
    for (size_t i = 0; i < est.size(); ++i) {
      const std::optional<Eigen::Matrix2d> P = trajectory.PositionCovarianceAt(out.t_s[i]);
      const std::optional<double> nees =
          P ? Nees(est[i] - ref[i], rotation * *P * rotation.transpose()) : std::nullopt;
      if (!nees) {
        out.nees.clear();
        break;
      }
      out.nees.push_back(*nees);
    }
  }
  return out;
}

const std::vector<ErrorStatField>& ErrorStatFields() {
  using S = ErrorStats;
  static const std::vector<ErrorStatField> fields = {{"rmse_m", &S::rmse_m},
                                                     {"mean_m", &S::mean_m},
                                                     {"median_m", &S::median_m},
                                                     {"p75_m", &S::p75_m},
                                                     {"p90_m", &S::p90_m},
                                                     {"max_m", &S::max_m},
                                                     {"final_m", &S::final_m},
                                                     {"pct_distance", &S::pct_distance},
                                                     {"anees", &S::anees},
                                                     {"mean_pct_distance", &S::mean_pct_distance},
                                                     {"ipin_score_m", &S::ipin_score_m},
                                                     {"floor_hit_rate", &S::floor_hit_rate}};
  return fields;
}

ErrorStats SummarizeErrors(const std::vector<double>& e, double distance_m) {
  ErrorStats s;
  s.n_points = static_cast<int>(e.size());
  if (e.empty()) return s;
  double sum = 0.0, sum2 = 0.0;
  for (double v : e) {
    sum += v;
    sum2 += v * v;
    s.max_m = std::max(s.max_m, v);
  }
  const double n = static_cast<double>(e.size());
  s.mean_m = sum / n;
  s.rmse_m = std::sqrt(sum2 / n);
  s.median_m = Percentile(e, 50.0);
  s.p75_m = Percentile(e, 75.0);
  s.p90_m = Percentile(e, 90.0);
  s.final_m = e.back();
  s.pct_distance = distance_m > 0.0 ? 100.0 * s.final_m / distance_m : 0.0;
  return s;
}

ErrorStats SummarizeErrors(const ErrorSeries& series, double distance_m) {
  ErrorStats s = SummarizeErrors(series.error_m, distance_m);
  if (!series.nees.empty()) {
    double sum = 0.0;
    for (double v : series.nees) sum += v;
    s.anees = sum / static_cast<double>(series.nees.size());
  }
  if (series.distance_m.size() == series.error_m.size()) {
    double sum = 0.0;
    int n = 0;
    for (size_t i = 0; i < series.error_m.size(); ++i) {
      if (!(series.distance_m[i] >= kRelativeErrorMinDistanceM)) continue;
      sum += 100.0 * series.error_m[i] / series.distance_m[i];  // 003 Sec. 5
      ++n;
    }
    if (n > 0) s.mean_pct_distance = sum / n;
  }
  if (!series.floors_missed.empty() && series.floors_missed.size() == series.error_m.size()) {
    std::vector<double> score;
    int hits = 0;
    for (size_t i = 0; i < series.error_m.size(); ++i) {
      score.push_back(series.error_m[i] + kIpinFloorPenaltyM * series.floors_missed[i]);
      hits += series.floors_missed[i] == 0 ? 1 : 0;
    }
    s.ipin_score_m = Percentile(score, 75.0);
    s.floor_hit_rate = static_cast<double>(hits) / static_cast<double>(score.size());
  }
  return s;
}

}  // namespace walkgraph
