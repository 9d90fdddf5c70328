// Accuracy metrics of a trajectory against a walk's truth.
//
// Horizontal (2D) position error. With continuous truth the error is taken at every truth
// sample; with checkpoints at each checkpoint. The estimate is linearly interpolated at the
// truth time. Truth outside the estimate's time span is skipped (counted in n_skipped).
// Consistency: when the trajectory carries covariances at the scored times, the position NEES
// eᵀP⁻¹e (e the 2D error, P the (x, y) block interpolated linearly at the truth time, rotated
// with the estimate under kSE2) is taken at the same points; its mean (ANEES) is 2 for a
// consistent estimator (χ²(2)), larger when it is overconfident, smaller when conservative.
// Relative error (003 Sec. 5, Fig. 6): the error at each point over the truth path length
// walked up to it, averaged over the walk; 003 reports 3.5-10 % for its hip PDR.
#ifndef WALKGRAPH_METRICS_H_
#define WALKGRAPH_METRICS_H_

#include <limits>
#include <vector>

#include "walkgraph/status.h"
#include "walkgraph/trajectory.h"
#include "walkgraph/walk.h"

namespace walkgraph {

struct ErrorSeries {
  std::vector<double> t_s;
  std::vector<double> error_m;
  // Position NEES at each point; empty when a trajectory point has no covariance or one is
  // not positive definite (then no NEES is reported).
  std::vector<double> nees;
  // Truth path length (2D) from the walk's first truth sample to each point.
  std::vector<double> distance_m;
  // Floors missed at each point, |estimated floor − truth floor| (IPIN's floorfail); empty when
  // the truth has no floors. An estimate without floors is on Walk::StartFloor() throughout.
  std::vector<int> floors_missed;
  int n_skipped = 0;
};

// IPIN's penalty per floor missed (technical annex 2023, "Evaluation criterion").
inline constexpr double kIpinFloorPenaltyM = 15.0;

// Points closer than this to the start (along the truth) are left out of the relative error:
// 003 averages over the whole run, but e/d is 0/0 at the start and huge over the first step.
// (003 does not say how it treats the start; 1 m drops the standstill and the first step.)
inline constexpr double kRelativeErrorMinDistanceM = 1.0;

struct ErrorStats {
  double rmse_m = 0.0;
  double mean_m = 0.0;
  double median_m = 0.0;
  double p75_m = 0.0;  // the EvAAL/IPIN score
  double p90_m = 0.0;
  double max_m = 0.0;
  double final_m = 0.0;       // error at the last scored truth point
  double pct_distance = 0.0;  // final error as % of the truth path length
  // 003's relative error: mean over the points of 100·error / distance walked to the point
  // (points within kRelativeErrorMinDistanceM of the start left out); NaN when no point is
  // farther or the series carries no distances.
  double mean_pct_distance = std::numeric_limits<double>::quiet_NaN();
  // Mean position NEES over the points (2 = consistent); NaN when the series has no NEES.
  double anees = std::numeric_limits<double>::quiet_NaN();
  // Multi-floor truth (NaN without floors): IPIN's score, the third quartile over the points
  // of horizontal error + kIpinFloorPenaltyM × floors missed; the fraction of points on the
  // right floor.
  double ipin_score_m = std::numeric_limits<double>::quiet_NaN();
  double floor_hit_rate = std::numeric_limits<double>::quiet_NaN();
  int n_points = 0;
};

// Every figure of ErrorStats but n_points, with its name (the key of results.json and of the
// studies' CSV and parts), in one order: the one list that writers and readers iterate.
struct ErrorStatField {
  const char* name;
  double ErrorStats::*field;
};
const std::vector<ErrorStatField>& ErrorStatFields();

enum class Alignment { kNone, kSE2 };

// Errors of `trajectory` at the truth of `walk`. kSE2 first fits the rotation and translation
// that best aligns the estimate to the truth (for dead-reckoning-only walks).
StatusOr<ErrorSeries> ComputeErrors(const Walk& walk, const Trajectory& trajectory,
                                    Alignment alignment = Alignment::kNone);

// Statistics of an error series; `distance_m` is the path length for pct_distance.
ErrorStats SummarizeErrors(const std::vector<double>& errors_m, double distance_m);
// The same, with anees from the series' NEES, mean_pct_distance from its distances and the
// floor figures from its floors_missed.
ErrorStats SummarizeErrors(const ErrorSeries& series, double distance_m);

// Linear-interpolation percentile (q in [0, 100]) of unsorted values; 0 for an empty vector.
double Percentile(std::vector<double> values, double q);

// Percentiles of a stream of non-negative values in bounded memory: a log-bucket histogram
// (DDSketch, Masson, Rim & Lee, VLDB 2019). Bucket i holds the values in (γ^(i-1), γ^i] with
// γ = (1 + α)/(1 − α); a bucket is represented by 2γ^i/(γ + 1), within α (relative) of every
// value in it. Percentile() ranks as Percentile() above (linear interpolation between the two
// neighbouring order statistics) on the represented values, so it is within α of the exact
// figure. Values <= kZero count as 0. Memory: one counter per bucket between the smallest and
// the largest value seen (at α = 1e-4, 11.5 k buckets per decade of range). The result does not
// depend on the order of Add() calls.
class QuantileSketch {
 public:
  static constexpr double kDefaultRelativeAccuracy = 1e-4;
  static constexpr double kZero = 1e-12;

  explicit QuantileSketch(double relative_accuracy = kDefaultRelativeAccuracy);
  void Add(double value);
  double Percentile(double q) const;  // q in [0, 100]; 0 when empty
  long long count() const { return count_; }
  double relative_accuracy() const { return alpha_; }

 private:
  double Value(long long rank) const;  // the rank-th smallest (0-based), as represented

  double alpha_, log_gamma_;
  long long count_ = 0, zeros_ = 0;
  int offset_ = 0;  // bucket index of counts_[0]
  std::vector<long long> counts_;
};

}  // namespace walkgraph

#endif  // WALKGRAPH_METRICS_H_
