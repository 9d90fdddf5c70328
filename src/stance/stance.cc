#include "walkgraph/stance.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <utility>

#include "config/reader.h"
#include "stance/stance_yaml.h"
#include "util/text.h"
#include "walkgraph/config.h"

namespace walkgraph {

namespace {

const std::vector<std::pair<std::string, StanceDetector>> kNames = {
    {"glrt", StanceDetector::kGlrt},
    {"mv", StanceDetector::kMv},
    {"mag", StanceDetector::kMag},
    {"are", StanceDetector::kAre},
    {"multi-condition", StanceDetector::kMultiCondition},
    {"adaptive", StanceDetector::kAdaptiveGlrt},
    {"gait", StanceDetector::kGaitGlrt}};

bool IsGlrt(StanceDetector d) {
  return d == StanceDetector::kGlrt || d == StanceDetector::kAdaptiveGlrt ||
         d == StanceDetector::kGaitGlrt;
}

// T_k of the OpenShoe detectors for the window starting at k (k = 0..n−W).
std::vector<double> WindowStatistic(const std::vector<ImuSample>& imu, const StanceOptions& o) {
  const size_t w = static_cast<size_t>(o.window);
  const double sa2 = o.sigma_acc_mps2 * o.sigma_acc_mps2;
  const double sg2 = o.sigma_gyro_radps * o.sigma_gyro_radps;
  std::vector<double> t(imu.size() - w + 1, 0.0);
  for (size_t k = 0; k + w <= imu.size(); ++k) {
    Eigen::Vector3d mean = Eigen::Vector3d::Zero();
    for (size_t i = k; i < k + w; ++i) mean += imu[i].acc_mps2;
    mean /= static_cast<double>(w);
    double sum = 0.0;
    for (size_t i = k; i < k + w; ++i) {
      const Eigen::Vector3d& a = imu[i].acc_mps2;
      const Eigen::Vector3d& g = imu[i].gyro_radps;
      switch (o.detector) {
        case StanceDetector::kGlrt:
        case StanceDetector::kAdaptiveGlrt:
        case StanceDetector::kGaitGlrt: {
          const Eigen::Vector3d up =
              mean.norm() > 0 ? Eigen::Vector3d(mean.normalized()) : Eigen::Vector3d::UnitZ();
          sum += (a - o.gravity_mps2 * up).squaredNorm() / sa2 + g.squaredNorm() / sg2;
          break;
        }
        case StanceDetector::kMv:
          sum += (a - mean).squaredNorm() / sa2;
          break;
        case StanceDetector::kMag: {
          const double d = a.norm() - o.gravity_mps2;
          sum += d * d / sa2;
          break;
        }
        case StanceDetector::kAre:
          sum += g.squaredNorm() / sg2;
          break;
        case StanceDetector::kMultiCondition:
          break;
      }
    }
    t[k] = sum / static_cast<double>(w);
  }
  return t;
}

// Centred local standard deviation of x over `window` samples (shrinking at the ends).
std::vector<double> LocalStd(const std::vector<double>& x, int window) {
  const long n = static_cast<long>(x.size()), h = window / 2;
  std::vector<double> out(x.size());
  for (long i = 0; i < n; ++i) {
    const long a = std::max(0L, i - h), b = std::min(n - 1, i + h);
    double m = 0.0;
    for (long j = a; j <= b; ++j) m += x[j];
    m /= static_cast<double>(b - a + 1);
    double v = 0.0;
    for (long j = a; j <= b; ++j) v += (x[j] - m) * (x[j] - m);
    out[i] = std::sqrt(v / static_cast<double>(b - a + 1));
  }
  return out;
}

// The ZARU still gyro threshold per sample (stance.h, still_adaptive): still_gyro_radps, raised
// to kStillGyroNoiseK times the gyro's white noise, at most kStillMaxFactor times
// still_gyro_radps. The noise of a window of `window` samples (windows every window/2) is the
// RMS over the axes of std(ω_k − ω_{k−1})/√2: white noise's σ, while a slow motion (a foot
// standing and swaying) adds little to it; the walk's is its quietest window's (causal: among
// the windows that end by the sample's centred window).
constexpr double kStillGyroNoiseK = 5.0, kStillMaxFactor = 4.0;
std::vector<double> StillGyroThresholds(const Walk& walk, int window, const StanceOptions& o) {
  const size_t n = walk.imu.size(), w = static_cast<size_t>(window);
  std::vector<double> out(n, o.still_gyro_radps);
  if (!o.still_adaptive || w < 2 || n < w + 1) return out;
  std::vector<std::pair<size_t, double>> noise;  // (last sample, σ) per window
  for (size_t s = 1; s + w <= n; s += std::max<size_t>(1, w / 2)) {
    Eigen::Vector3d mean = Eigen::Vector3d::Zero(), sq = Eigen::Vector3d::Zero();
    for (size_t j = s; j < s + w; ++j) {
      const Eigen::Vector3d d = walk.imu[j].gyro_radps - walk.imu[j - 1].gyro_radps;
      mean += d;
      sq += d.cwiseProduct(d);
    }
    const double k = static_cast<double>(w);
    mean /= k;
    const double var = (sq / k - mean.cwiseProduct(mean)).cwiseMax(0.0).mean() / 2.0;
    noise.push_back({s + w - 1, std::sqrt(var)});
  }
  double least = std::numeric_limits<double>::infinity();
  if (!o.adaptive_causal) {
    for (const auto& [end, sigma] : noise) least = std::min(least, sigma);
  }
  size_t next = 0;
  for (size_t i = 0; i < n; ++i) {
    for (; o.adaptive_causal && next < noise.size() && noise[next].first <= i + w / 2; ++next) {
      least = std::min(least, noise[next].second);
    }
    if (!std::isfinite(least)) continue;  // causal: no window yet
    out[i] = std::clamp(kStillGyroNoiseK * least, o.still_gyro_radps,
                        kStillMaxFactor * o.still_gyro_radps);
  }
  return out;
}

std::vector<bool> MedianFilter(const std::vector<bool>& x, int window) {
  const long n = static_cast<long>(x.size()), h = window / 2;
  std::vector<bool> out(x.size());
  for (long i = 0; i < n; ++i) {
    const long a = std::max(0L, i - h), b = std::min(n - 1, i + h);
    long ones = 0;
    for (long j = a; j <= b; ++j) ones += x[j] ? 1 : 0;
    out[i] = 2 * ones > (b - a + 1);
  }
  return out;
}

// Otsu's split of the histogram of `v` between its 0.5 % and 99.5 % order statistics: the
// class means (lower, upper). Reorders `v` (the histogram does not depend on the order).
std::pair<double, double> OtsuClassMeans(std::vector<double>* values, int bins) {
  std::vector<double>& v = *values;
  const size_t k_lo = v.size() / 200, k_hi = v.size() - 1 - v.size() / 200;
  std::nth_element(v.begin(), v.begin() + k_hi, v.end());
  const double hi = v[k_hi];
  std::nth_element(v.begin(), v.begin() + k_lo, v.begin() + k_hi);
  const double lo = v[k_lo];
  if (!(hi > lo)) return {lo, lo};
  std::vector<double> count(bins, 0.0);
  const double width = (hi - lo) / bins;
  for (double x : v) {
    const int b = static_cast<int>((x - lo) / width);
    count[std::clamp(b, 0, bins - 1)] += 1.0;
  }
  double total = 0.0, total_sum = 0.0;
  for (int b = 0; b < bins; ++b) {
    total += count[b];
    total_sum += count[b] * (lo + (b + 0.5) * width);
  }
  double w0 = 0.0, sum0 = 0.0, best = -1.0;
  std::pair<double, double> means{lo, hi};
  for (int b = 0; b + 1 < bins; ++b) {
    w0 += count[b];
    sum0 += count[b] * (lo + (b + 0.5) * width);
    const double w1 = total - w0;
    if (w0 <= 0.0 || w1 <= 0.0) continue;
    const double m0 = sum0 / w0, m1 = (total_sum - sum0) / w1;
    const double between = w0 * w1 * (m1 - m0) * (m1 - m0);
    if (between > best) {
      best = between;
      means = {m0, m1};
    }
  }
  return means;
}

// γ of the adaptive detector from the statistic of samples [a, b) (see stance.h), `fallback`
// when they are too few or not bimodal.
// `log_statistic`: log10 of the statistic, NaN where it is not finite or not positive.
double AdaptiveGamma(const std::vector<double>& log_statistic, size_t a, size_t b,
                     const StanceOptions& o, double fallback) {
  std::vector<double> v;
  v.reserve(b - a);
  for (size_t i = a; i < b; ++i) {
    if (!std::isnan(log_statistic[i])) v.push_back(log_statistic[i]);
  }
  if (static_cast<int>(v.size()) < std::max(o.adaptive_min_samples, 2)) return fallback;
  const auto [m0, m1] = OtsuClassMeans(&v, o.adaptive_bins);
  if (m1 - m0 < o.adaptive_min_separation) return fallback;
  return std::pow(10.0, m0 + o.adaptive_fraction * (m1 - m0));
}

// Index of the first IMU sample at or after t.
size_t ImuIndexAt(const Walk& walk, double t) {
  return static_cast<size_t>(
      std::lower_bound(walk.imu.begin(), walk.imu.end(), t,
                       [](const ImuSample& s, double x) { return s.t_s < x; }) -
      walk.imu.begin());
}

// Per-sample γ of the adaptive detector: one for the walk, or one per adaptive_step_s from the
// window of adaptive_window_s centred on the block (or, adaptive_causal, ending at it).
std::vector<double> AdaptiveThresholds(const Walk& walk, const std::vector<double>& statistic,
                                       const StanceOptions& o) {
  const size_t n = statistic.size();
  std::vector<double> log_statistic(n, std::numeric_limits<double>::quiet_NaN());
  for (size_t i = 0; i < n; ++i) {
    if (std::isfinite(statistic[i]) && statistic[i] > 0)
      log_statistic[i] = std::log10(statistic[i]);
  }
  // The causal detector never looks at the whole walk: its fallback is the last bimodal γ.
  double fallback = o.adaptive_causal ? o.glrt_threshold
                                      : AdaptiveGamma(log_statistic, 0, n, o, o.glrt_threshold);
  if (o.adaptive_window_s <= 0.0) return std::vector<double>(n, fallback);
  std::vector<double> gamma(n);
  // Blocks of adaptive_step_s from the walk's start (so a walk cut at t gets the same γ up to t).
  const double t0 = walk.imu.front().t_s;
  for (size_t i = 0; i < n;) {
    const double tc = walk.imu[i].t_s;
    const double g =
        o.adaptive_causal
            ? AdaptiveGamma(log_statistic, ImuIndexAt(walk, tc - o.adaptive_window_s), i, o,
                            fallback)
            : AdaptiveGamma(log_statistic, ImuIndexAt(walk, tc - 0.5 * o.adaptive_window_s),
                            ImuIndexAt(walk, tc + 0.5 * o.adaptive_window_s), o, fallback);
    if (o.adaptive_causal) fallback = g;
    const double t_next =
        t0 + o.adaptive_step_s * (std::floor((tc - t0) / o.adaptive_step_s) + 1.0);
    const size_t next = std::max(i + 1, ImuIndexAt(walk, t_next));
    for (size_t k = i; k < std::min(next, n); ++k) gamma[k] = g;
    i = next;
  }
  return gamma;
}

// ‖ω‖ averaged over bins of kGaitBinS from the walk's first sample (empty bins take the last
// value): the stride period's signal at one rate whatever the IMU's.
constexpr double kGaitBinS = 0.02;

std::vector<double> BinnedGyroNorm(const std::vector<ImuSample>& imu) {
  const double t0 = imu.front().t_s;
  const size_t bins = static_cast<size_t>((imu.back().t_s - t0) / kGaitBinS) + 1;
  std::vector<double> sum(bins, 0.0), count(bins, 0.0);
  for (const ImuSample& s : imu) {
    const size_t b = std::min(bins - 1, static_cast<size_t>((s.t_s - t0) / kGaitBinS));
    sum[b] += s.gyro_radps.norm();
    count[b] += 1.0;
  }
  double last = 0.0;
  for (size_t b = 0; b < bins; ++b) {
    if (count[b] > 0) last = sum[b] / count[b];
    sum[b] = last;
  }
  return sum;
}

// The stride period (s) of bins [a, b) of `x`: the lag of the largest normalized
// autocorrelation in [gait_period_min_s, gait_period_max_s] (and at most half the span), 0 when
// that peak is under gait_min_periodicity or the span is shorter than two shortest periods.
double StridePeriod(const std::vector<double>& x, size_t a, size_t b, const StanceOptions& o) {
  const size_t lo = static_cast<size_t>(std::ceil(o.gait_period_min_s / kGaitBinS));
  if (b <= a || lo < 2 || b - a < 2 * lo + 2) return 0.0;
  const size_t hi = std::min(static_cast<size_t>(o.gait_period_max_s / kGaitBinS), (b - a) / 2);
  const size_t n = b - a;
  double mean = 0.0;
  for (size_t i = a; i < b; ++i) mean += x[i];
  mean /= static_cast<double>(n);
  double c0 = 0.0;
  for (size_t i = a; i < b; ++i) c0 += (x[i] - mean) * (x[i] - mean);
  if (!(c0 > 0.0)) return 0.0;
  // Autocorrelation at lags lo − 1 … hi + 1; the period is its largest local peak inside
  // [lo, hi] (a maximum at an end of the range is a decay, not a rhythm).
  std::vector<double> c(hi + 2 - (lo - 1), 0.0);
  for (size_t lag = lo - 1; lag <= hi + 1; ++lag) {
    double sum = 0.0;
    for (size_t i = a; i + lag < b; ++i) sum += (x[i] - mean) * (x[i + lag] - mean);
    c[lag - (lo - 1)] = sum / c0;
  }
  double best = -1.0;
  size_t best_lag = 0;
  for (size_t k = 1; k + 1 < c.size(); ++k) {
    if (c[k] >= c[k - 1] && c[k] >= c[k + 1] && c[k] > best) {
      best = c[k];
      best_lag = k + lo - 1;
    }
  }
  return best >= o.gait_min_periodicity ? kGaitBinS * static_cast<double>(best_lag) : 0.0;
}

// Per IMU sample, the stride period of its block (0: no rhythm there); see stance.h. A walk
// whose time span is not finite or holds far more 20-ms bins than samples (long IMU gaps) gets
// no period: the bins would not fit in memory, and the rhythm is in its samples anyway.
std::vector<double> StridePeriods(const Walk& walk, const StanceOptions& o) {
  const size_t n = walk.imu.size();
  const double span_s = walk.imu.back().t_s - walk.imu.front().t_s;
  if (!std::isfinite(span_s) || !(span_s >= 0.0) ||
      span_s / kGaitBinS > 4.0 * static_cast<double>(n) + 1e4) {
    return std::vector<double>(n, 0.0);
  }
  const std::vector<double> x = BinnedGyroNorm(walk.imu);
  const size_t bins = x.size();
  const size_t window = std::min(bins, static_cast<size_t>(o.gait_window_s / kGaitBinS));
  const double t0 = walk.imu.front().t_s;
  std::vector<double> period(n, 0.0);
  for (size_t i = 0; i < n;) {
    const double tc = walk.imu[i].t_s;
    const size_t block = static_cast<size_t>((tc - t0) / o.gait_step_s);
    const size_t centre = static_cast<size_t>((block + 0.5) * o.gait_step_s / kGaitBinS);
    // Causal: the window ends where the block ends (a look-ahead of at most gait_step_s, as
    // the cycle minimum's own); else it is centred on the block. Clamped to the walk so that
    // its ends get a whole window.
    const size_t end_bin =
        o.adaptive_causal
            ? std::min(bins, static_cast<size_t>((block + 1) * o.gait_step_s / kGaitBinS))
            : std::min(bins, std::max(window, centre + window / 2));
    const size_t begin_bin = end_bin >= window ? end_bin - window : 0;
    const double p = StridePeriod(x, begin_bin, end_bin, o);
    const size_t next = ImuIndexAt(walk, t0 + (block + 1) * o.gait_step_s);
    for (size_t k = i; k < std::max(next, i + 1) && k < n; ++k) period[k] = p;
    i = std::max(next, i + 1);
  }
  return period;
}

// log10 of the statistic; the largest double where it is not finite or not positive.
std::vector<double> LogStatistic(const std::vector<double>& statistic) {
  std::vector<double> l(statistic.size());
  for (size_t i = 0; i < statistic.size(); ++i) {
    l[i] = std::isfinite(statistic[i]) && statistic[i] > 0 ? std::log10(statistic[i])
                                                           : std::numeric_limits<double>::max();
  }
  return l;
}

// Stance hypotheses (stance.h): in every stretch of more than gait_max_gap_s without stance,
// the least statistic of each gait_max_gap_s of it.
void AddStanceHypotheses(const Walk& walk, const std::vector<double>& l, const StanceOptions& o,
                         StanceMask* m) {
  const size_t n = l.size();
  const double imu_gap_s = ImuGapThresholdS(walk.imu);
  m->hypothesis.assign(n, false);
  for (size_t a = 0; a < n;) {
    if (m->stance[a]) {
      ++a;
      continue;
    }
    // [a, b) holds no stance and no IMU gap (the IMU says nothing across one: the stretches
    // either side are taken alone).
    size_t b = a + 1;
    while (b < n && !m->stance[b] && walk.imu[b].t_s - walk.imu[b - 1].t_s <= imu_gap_s) ++b;
    const double span = walk.imu[b - 1].t_s - walk.imu[a].t_s;
    // At most one hypothesis per sample (however sparse the samples are in time).
    const double wanted = std::isfinite(span) ? std::ceil(span / o.gait_max_gap_s) : 0.0;
    const size_t chunks = static_cast<size_t>(std::min(wanted, static_cast<double>(b - a)));
    for (size_t c = 0; chunks > 1 && c < chunks; ++c) {
      const size_t lo = a + (b - a) * c / chunks, hi = a + (b - a) * (c + 1) / chunks;
      if (hi <= lo) continue;
      const size_t k =
          static_cast<size_t>(std::min_element(l.begin() + lo, l.begin() + hi) - l.begin());
      m->stance[k] = m->cycle_minimum[k] = m->hypothesis[k] = true;
    }
    a = b;
  }
}

// Adds one stance per gait cycle (stance.h): marks each cycle minimum and its region, then the
// stance hypotheses.
void AddCycleStances(const Walk& walk, const std::vector<double>& statistic, const StanceOptions& o,
                     StanceMask* m) {
  const size_t n = statistic.size();
  const std::vector<double> period = StridePeriods(walk, o);
  const std::vector<double> l = LogStatistic(statistic);
  m->cycle_minimum.assign(n, false);
  for (size_t i = 0; i < n; ++i) {
    if (period[i] <= 0.0 || l[i] == std::numeric_limits<double>::max()) continue;
    const double half = o.gait_half_fraction * period[i];
    const size_t a = ImuIndexAt(walk, walk.imu[i].t_s - half);
    const size_t b = std::min(n, ImuIndexAt(walk, walk.imu[i].t_s + half) + 1);
    bool least = true;
    double most = l[i];
    for (size_t k = a; k < b && least; ++k) {
      // Ties go to the earliest sample, so that a flat minimum counts once.
      least = l[k] > l[i] || (l[k] == l[i] && k >= i);
      if (l[k] != std::numeric_limits<double>::max()) most = std::max(most, l[k]);
    }
    if (!least || most - l[i] < o.gait_min_depth_decades) continue;
    m->cycle_minimum[i] = true;
    const double limit = l[i] + o.gait_region_decades;
    for (size_t k = i; k < n && l[k] < limit; ++k) m->stance[k] = true;
    for (size_t k = i; k-- > 0 && l[k] < limit;) m->stance[k] = true;
    m->stance[i] = true;
  }
  AddStanceHypotheses(walk, l, o, m);
}

Status CheckImu(const Walk& walk, const StanceOptions& o) {
  if (walk.imu.size() < static_cast<size_t>(std::max(o.window, 2))) {
    return FailedPrecondition("stance: the walk needs at least W IMU samples");
  }
  return Status::Ok();
}

}  // namespace

const char* ToString(StanceDetector d) {
  for (const auto& [name, value] : kNames) {
    if (value == d) return name.c_str();
  }
  return "?";
}

StatusOr<StanceDetector> StanceDetectorFromString(const std::string& name) {
  for (const auto& [n, value] : kNames) {
    if (n == name) return value;
  }
  return InvalidArgument("stance: unknown detector " + internal::Quoted(name) +
                         " (glrt|mv|mag|are|multi-condition|adaptive|gait)");
}

double StanceOptions::threshold() const {
  switch (detector) {
    case StanceDetector::kGlrt:
      return glrt_threshold;
    case StanceDetector::kMv:
      return mv_threshold;
    case StanceDetector::kMag:
      return mag_threshold;
    case StanceDetector::kAre:
      return are_threshold;
    case StanceDetector::kMultiCondition:
      return mc_acc_std_max_mps2;
    case StanceDetector::kAdaptiveGlrt:
    case StanceDetector::kGaitGlrt:
      return adaptive_fraction;
  }
  return 0.0;
}

void StanceOptions::set_threshold(double value) {
  switch (detector) {
    case StanceDetector::kGlrt:
      glrt_threshold = value;
      break;
    case StanceDetector::kMv:
      mv_threshold = value;
      break;
    case StanceDetector::kMag:
      mag_threshold = value;
      break;
    case StanceDetector::kAre:
      are_threshold = value;
      break;
    case StanceDetector::kMultiCondition:
      mc_acc_std_max_mps2 = value;
      break;
    case StanceDetector::kAdaptiveGlrt:
    case StanceDetector::kGaitGlrt:
      adaptive_fraction = value;
      break;
  }
}

StatusOr<StanceOptions> StanceOptionsFromYaml(const YAML::Node& node) {
  return StanceOptionsFromYaml(node, StanceOptions());
}

StatusOr<StanceOptions> StanceOptionsFromYaml(const YAML::Node& node, const StanceOptions& base) {
  StanceOptions o = base;
  ConfigReader r(node, "stance");
  r.ReadEnum("detector", &o.detector, kNames,
             "stance detector (OpenShoe's GLRT, MV, MAG, ARE, multi-condition, or adaptive: the "
             "GLRT with a threshold from the walk's own statistic, or gait: adaptive plus one "
             "stance per gait cycle)");
  r.Read("window", &o.window, "samples per detector window W");
  r.Read("sigma_acc_mps2", &o.sigma_acc_mps2,
         "accelerometer noise sigma_a of the detector statistics");
  r.Read("sigma_gyro_radps", &o.sigma_gyro_radps, "gyro noise sigma_g of the detector statistics");
  r.Read("gravity_mps2", &o.gravity_mps2, "gravity magnitude");
  r.Read("glrt_threshold", &o.glrt_threshold, "GLRT detector threshold gamma");
  r.Read("mv_threshold", &o.mv_threshold, "MV (acceleration variance) detector threshold gamma");
  r.Read("mag_threshold", &o.mag_threshold,
         "MAG (acceleration magnitude) detector threshold gamma");
  r.Read("are_threshold", &o.are_threshold, "ARE (angular rate energy) detector threshold gamma");
  r.Read("mc_acc_min_mps2", &o.mc_acc_min_mps2,
         "multi-condition: least acceleration magnitude at stance");
  r.Read("mc_acc_max_mps2", &o.mc_acc_max_mps2,
         "multi-condition: largest acceleration magnitude at stance");
  r.Read("mc_acc_std_max_mps2", &o.mc_acc_std_max_mps2,
         "multi-condition: largest local acceleration std-dev (th_sigma)");
  r.Read("mc_std_window", &o.mc_std_window, "multi-condition: samples of the local std-dev window");
  r.Read("mc_gyro_max_radps", &o.mc_gyro_max_radps,
         "multi-condition: largest angular rate at stance");
  r.Read("mc_median_window", &o.mc_median_window,
         "multi-condition: samples of the median filter on the decision");
  r.Read("adaptive_fraction", &o.adaptive_fraction,
         "adaptive: log-threshold's place between the stance and swing class means (0..1)");
  r.Read("adaptive_window_s", &o.adaptive_window_s,
         "adaptive: window of the statistic's distribution, centred or (causal) trailing (0: the "
         "whole "
         "walk)");
  r.Read("adaptive_causal", &o.adaptive_causal,
         "adaptive: threshold from the adaptive_window_s before each sample only (causal)");
  r.Read("adaptive_step_s", &o.adaptive_step_s, "adaptive: threshold recomputed every step");
  r.Read("adaptive_bins", &o.adaptive_bins, "adaptive: histogram bins of Otsu's split");
  r.Read("adaptive_min_separation", &o.adaptive_min_separation,
         "adaptive: least decades between the class means, else glrt_threshold is used");
  r.Read("adaptive_min_samples", &o.adaptive_min_samples,
         "adaptive: least samples in the window, else glrt_threshold is used");
  r.Read("gait_window_s", &o.gait_window_s, "gait: window of the stride period's estimate");
  r.Read("gait_step_s", &o.gait_step_s, "gait: stride period estimated every step");
  r.Read("gait_period_min_s", &o.gait_period_min_s, "gait: shortest stride period");
  r.Read("gait_period_max_s", &o.gait_period_max_s, "gait: longest stride period");
  r.Read("gait_min_periodicity", &o.gait_min_periodicity,
         "gait: least autocorrelation of the gyro norm at the stride period, else no cycles");
  r.Read("gait_half_fraction", &o.gait_half_fraction,
         "gait: a cycle minimum is the least statistic within this fraction of a period");
  r.Read("gait_min_depth_decades", &o.gait_min_depth_decades,
         "gait: least decades between a cycle minimum and the swing around it");
  r.Read("gait_region_decades", &o.gait_region_decades,
         "gait: a cycle minimum's stance holds the samples within this of its log statistic");
  r.Read("gait_max_gap_s", &o.gait_max_gap_s,
         "gait: a longer stretch without stance gets a stance hypothesis per this span");
  r.Read("still_window_s", &o.still_window_s, "ZARU still detection: window span");
  r.Read("still_gyro_radps", &o.still_gyro_radps, "ZARU still detection: largest angular rate");
  r.Read("still_acc_std_mps2", &o.still_acc_std_mps2,
         "ZARU still detection: largest acceleration std-dev");
  r.Read("still_adaptive", &o.still_adaptive,
         "ZARU still detection: raise the angular-rate threshold to 5x the gyro's white noise "
         "(from the walk's quietest window), at most 4x still_gyro_radps");
  WG_RETURN_IF_ERROR(r.Finish());
  WG_RETURN_IF_ERROR(o.Validate());
  return o;
}

Status StanceOptions::Validate() const {
  const StanceOptions& o = *this;
  if (o.window < 1 || o.mc_std_window < 1 || o.mc_median_window < 1 || o.sigma_acc_mps2 <= 0 ||
      o.sigma_gyro_radps <= 0 || o.still_window_s < 0) {
    return InvalidArgument("stance: windows must be >= 1 and sigmas > 0");
  }
  if (!(o.adaptive_fraction >= 0.0 && o.adaptive_fraction <= 1.0) || o.adaptive_bins < 2 ||
      o.adaptive_window_s < 0 || !(o.adaptive_step_s > 0) || o.adaptive_min_separation < 0) {
    return InvalidArgument(
        "stance: adaptive_fraction must be in [0, 1], adaptive_bins >= 2, adaptive_step_s > 0, "
        "adaptive_window_s and adaptive_min_separation >= 0");
  }
  if (!(o.gait_window_s > 0) || !(o.gait_step_s > 0) || !(o.gait_period_min_s > 0) ||
      !(o.gait_period_max_s > o.gait_period_min_s) || !(o.gait_half_fraction > 0) ||
      !(o.gait_half_fraction <= 1.0) || o.gait_min_depth_decades < 0 || o.gait_region_decades < 0 ||
      !(o.gait_min_periodicity >= 0 && o.gait_min_periodicity <= 1)) {
    return InvalidArgument(
        "stance: gait_window_s, gait_step_s, gait_period_min_s, gait_max_gap_s > 0, "
        "gait_period_max_s > "
        "gait_period_min_s, gait_half_fraction in (0, 1], gait_min_periodicity in [0, 1], the "
        "gait decades >= 0");
  }
  if (o.adaptive_causal && !(o.adaptive_window_s > 0)) {
    return InvalidArgument(
        "stance: adaptive_causal needs adaptive_window_s > 0 (the trailing window)");
  }
  return Status::Ok();
}

StatusOr<StanceMask> DetectStance(const Walk& walk, const StanceOptions& o) {
  WG_RETURN_IF_ERROR(CheckImu(walk, o));
  WG_RETURN_IF_ERROR(o.Validate());
  const size_t n = walk.imu.size();
  StanceMask m;
  m.t_s.resize(n);
  for (size_t i = 0; i < n; ++i) m.t_s[i] = walk.imu[i].t_s;
  std::vector<double> acc_norm(n);
  for (size_t i = 0; i < n; ++i) acc_norm[i] = walk.imu[i].acc_mps2.norm();

  if (o.detector == StanceDetector::kMultiCondition) {
    m.statistic = LocalStd(acc_norm, o.mc_std_window);
    std::vector<bool> c(n);
    for (size_t i = 0; i < n; ++i) {
      const bool c1 = acc_norm[i] > o.mc_acc_min_mps2 && acc_norm[i] < o.mc_acc_max_mps2;
      const bool c2 = m.statistic[i] < o.mc_acc_std_max_mps2;
      const bool c3 = walk.imu[i].gyro_radps.norm() < o.mc_gyro_max_radps;
      c[i] = c1 && c2 && c3;
    }
    m.stance = MedianFilter(c, o.mc_median_window);
  } else {
    const std::vector<double> t = WindowStatistic(walk.imu, o);
    const size_t w = static_cast<size_t>(o.window);
    m.statistic.assign(n, std::numeric_limits<double>::infinity());
    for (size_t k = 0; k < t.size(); ++k) {
      for (size_t i = k; i < k + w; ++i) m.statistic[i] = std::min(m.statistic[i], t[k]);
    }
    const std::vector<double> gamma = o.detector == StanceDetector::kGlrt || !IsGlrt(o.detector)
                                          ? std::vector<double>(n, o.threshold())
                                          : AdaptiveThresholds(walk, m.statistic, o);
    m.stance.resize(n);
    for (size_t i = 0; i < n; ++i) m.stance[i] = m.statistic[i] < gamma[i];
    if (o.detector == StanceDetector::kGaitGlrt) AddCycleStances(walk, m.statistic, o, &m);
  }

  // ZARU: centred window of still_window_s.
  double dt = (walk.imu.back().t_s - walk.imu.front().t_s) / static_cast<double>(n - 1);
  const int still_w = std::max(1, static_cast<int>(std::lround(o.still_window_s / dt)));
  const std::vector<double> sd = LocalStd(acc_norm, still_w);
  const std::vector<double> still_gyro = StillGyroThresholds(walk, still_w, o);
  const long h = still_w / 2;
  m.still.resize(n);
  for (long i = 0; i < static_cast<long>(n); ++i) {
    const long a = std::max(0L, i - h), b = std::min(static_cast<long>(n) - 1, i + h);
    double max_w = 0.0;
    for (long j = a; j <= b; ++j) max_w = std::max(max_w, walk.imu[j].gyro_radps.norm());
    m.still[i] = max_w < still_gyro[i] && sd[i] < o.still_acc_std_mps2;
  }
  return m;
}

StatusOr<std::vector<bool>> StanceLabelsAtImu(const Walk& walk, double max_gap_s) {
  if (walk.stance_truth.empty()) return FailedPrecondition("stance: the walk has no stance labels");
  const auto& st = walk.stance_truth;
  std::vector<bool> out(walk.imu.size());
  for (size_t i = 0; i < walk.imu.size(); ++i) {
    const double t = walk.imu[i].t_s;
    auto it = std::lower_bound(st.begin(), st.end(), t,
                               [](const StanceSample& s, double v) { return s.t_s < v; });
    const StanceSample* best = nullptr;
    if (it != st.end()) best = &*it;
    if (it != st.begin() && (!best || t - std::prev(it)->t_s < best->t_s - t))
      best = &*std::prev(it);
    if (std::fabs(best->t_s - t) > max_gap_s) {
      return FailedPrecondition("stance: no label within " + internal::Num(max_gap_s) +
                                " s of IMU time " + internal::Num(t));
    }
    out[i] = best->stance;
  }
  return out;
}

double StanceScore::precision() const {
  const long d = true_positive + false_positive;
  return d == 0 ? 1.0 : static_cast<double>(true_positive) / static_cast<double>(d);
}

double StanceScore::recall() const {
  const long d = true_positive + false_negative;
  return d == 0 ? 1.0 : static_cast<double>(true_positive) / static_cast<double>(d);
}

StanceScore ScoreStance(const std::vector<bool>& detected, const std::vector<bool>& labels) {
  StanceScore s;
  const size_t n = std::min(detected.size(), labels.size());
  for (size_t i = 0; i < n; ++i) {
    if (detected[i] && labels[i]) ++s.true_positive;
    if (detected[i] && !labels[i]) ++s.false_positive;
    if (!detected[i] && labels[i]) ++s.false_negative;
    if (!detected[i] && !labels[i]) ++s.true_negative;
  }
  return s;
}

StatusOr<std::vector<StanceScore>> StanceThresholdSearch(const Walk& walk,
                                                         const StanceOptions& base,
                                                         std::vector<double> thresholds) {
  WG_ASSIGN_OR_RETURN(const std::vector<bool> labels, StanceLabelsAtImu(walk));
  if (thresholds.empty() && (base.detector == StanceDetector::kAdaptiveGlrt ||
                             base.detector == StanceDetector::kGaitGlrt)) {
    for (int i = 1; i <= 19; ++i) thresholds.push_back(0.05 * i);
  }
  if (thresholds.empty()) {
    WG_ASSIGN_OR_RETURN(const StanceMask m, DetectStance(walk, base));
    std::vector<double> v;
    for (double x : m.statistic) {
      if (std::isfinite(x) && x > 0) v.push_back(x);
    }
    if (v.empty()) return FailedPrecondition("stance: the statistic is zero everywhere");
    std::sort(v.begin(), v.end());
    const double lo = v[v.size() / 100], hi = v[v.size() * 99 / 100];
    const int count = 40;
    for (int i = 0; i < count; ++i) {
      thresholds.push_back(lo * std::pow(hi / lo, static_cast<double>(i) / (count - 1)));
    }
  }
  std::vector<StanceScore> out;
  for (double th : thresholds) {
    StanceOptions o = base;
    o.set_threshold(th);
    WG_ASSIGN_OR_RETURN(const StanceMask m, DetectStance(walk, o));
    StanceScore s = ScoreStance(m.stance, labels);
    s.threshold = th;
    out.push_back(s);
  }
  return out;
}

}  // namespace walkgraph
