#include "walkgraph/pdr.h"

#include <algorithm>
#include <cmath>
#include <numeric>

#include <Eigen/Eigenvalues>

#include "config/reader.h"
#include "ins/strides_yaml.h"
#include "pdr/pdr_yaml.h"
#include "util/enum_define.h"
#include "walkgraph/angle.h"
#include "walkgraph/config.h"

namespace walkgraph {

WALKGRAPH_DEFINE_ENUM_NAMES(EnergyLockoutKeep, "energy_lockout_keep",
                            {"first", EnergyLockoutKeep::kFirst},
                            {"strongest", EnergyLockoutKeep::kStrongest})

namespace {

const std::vector<std::pair<std::string, StepDetector>> kDetectorNames = {
    {"vertical-peak", StepDetector::kVerticalPeak},
    {"fir-magnitude", StepDetector::kFirMagnitude},
    {"energy", StepDetector::kEnergy}};
const std::vector<std::pair<std::string, StepLengthModel>> kLengthNames = {
    {"weinberg", StepLengthModel::kWeinberg},
    {"constant", StepLengthModel::kConstant},
    {"linear", StepLengthModel::kLinearFrequency}};
const std::vector<std::pair<std::string, HeadingMethod>> kHeadingNames = {
    {"gyro", HeadingMethod::kGyro},
    {"complementary", HeadingMethod::kComplementary},
    {"auto", HeadingMethod::kAuto}};
const std::vector<std::pair<std::string, ForwardAxisMethod>> kForwardNames = {
    {"body-x", ForwardAxisMethod::kBodyX},
    {"body-y", ForwardAxisMethod::kBodyY},
    {"pca", ForwardAxisMethod::kPca},
    {"auto", ForwardAxisMethod::kAuto}};
const std::vector<std::pair<std::string, StepThresholdMethod>> kThresholdNames = {
    {"fixed", StepThresholdMethod::kFixed}, {"auto", StepThresholdMethod::kAuto}};

// Yaw of a body-to-ENU rotation: the ENU angle of the body x axis projected on the horizontal.
double Yaw(const Eigen::Matrix3d& r) { return std::atan2(r(1, 0), r(0, 0)); }

// Local maxima of x above `threshold`, at least `min_gap` samples apart (the larger kept).
std::vector<size_t> PeaksWithGap(const std::vector<double>& x, double threshold, size_t min_gap) {
  std::vector<size_t> peaks;
  for (size_t i = 1; i + 1 < x.size(); ++i) {
    if (!(x[i] > threshold && x[i] > x[i - 1] && x[i] >= x[i + 1])) continue;
    if (!peaks.empty() && i - peaks.back() < min_gap) {
      if (x[i] > x[peaks.back()]) peaks.back() = i;
      continue;
    }
    peaks.push_back(i);
  }
  return peaks;
}

// Signals every detector and the heading share.
struct ImuSignals {
  double rate_hz = 0.0;
  std::vector<Eigen::Quaterniond> attitude;
  std::vector<double> vertical_lp;  // low-pass a_z^n − g
  std::vector<double> yaw_rate;     // ω_z^n = (R ω)_z
};

StatusOr<ImuSignals> ComputeSignals(const Walk& walk, const PdrOptions& o) {
  ImuSignals s;
  s.rate_hz = 1.0 / MedianImuIntervalS(walk.imu);
  WG_ASSIGN_OR_RETURN(s.attitude, EstimateAttitude(walk.imu, o));
  std::vector<double> vertical(walk.imu.size());
  s.yaw_rate.resize(walk.imu.size());
  for (size_t i = 0; i < walk.imu.size(); ++i) {
    const Eigen::Matrix3d r = s.attitude[i].toRotationMatrix();
    vertical[i] = (r * walk.imu[i].acc_mps2).z() - o.gravity_mps2;
    s.yaw_rate[i] = (r * walk.imu[i].gyro_radps).z();  // 000 eq. 4: ω projected on the vertical
  }
  // A long filter (transition ≈ 3.3·rate/order) so that step frequencies pass undamped.
  const int order =
      std::max(20, 2 * static_cast<int>(std::lround(2.0 * s.rate_hz / o.vertical_cutoff_hz)));
  s.vertical_lp =
      FilterZeroDelay(vertical, DesignLowPassFir(order, o.vertical_cutoff_hz, s.rate_hz));
  return s;
}

std::vector<StepEvent> EventsFromPeaks(const Walk& walk, const ImuSignals& s,
                                       const std::vector<size_t>& peaks, double min_swing) {
  std::vector<StepEvent> events;
  size_t prev = 0;
  for (size_t p : peaks) {
    StepEvent e;
    e.imu_index = p;
    e.t_s = walk.imu[p].t_s;
    const auto begin = s.vertical_lp.begin() + static_cast<long>(events.empty() ? 0 : prev);
    const auto end = s.vertical_lp.begin() + static_cast<long>(p) + 1;
    e.a_max_mps2 = *std::max_element(begin, end);
    e.a_min_mps2 = *std::min_element(begin, end);
    if (e.a_max_mps2 - e.a_min_mps2 < min_swing) continue;
    e.duration_s = events.empty() ? 0.0 : e.t_s - events.back().t_s;
    events.push_back(e);
    prev = p;
  }
  return events;
}

// The q-quantile of x (nearest rank; x not empty), x reordered.
double Quantile(std::vector<double>* x, double q) {
  const size_t k = std::min(x->size() - 1, static_cast<size_t>(q * static_cast<double>(x->size())));
  std::nth_element(x->begin(), x->begin() + static_cast<long>(k), x->end());
  return (*x)[k];
}

// The standstill class of the windows' σ: Otsu's split of log σ (the threshold that maximises
// the between-class variance of a two-class walk: still and walking), the median σ of the
// quieter class.
double StillSigma(std::vector<double> sd) {
  std::sort(sd.begin(), sd.end());
  std::vector<double> l;
  for (double v : sd) l.push_back(std::log(std::max(v, 1e-6)));
  const double total = std::accumulate(l.begin(), l.end(), 0.0);
  const double n = static_cast<double>(l.size());
  double best = -1.0, below = 0.0;
  size_t split = l.size();  // quieter class: [0, split)
  for (size_t k = 1; k < l.size(); ++k) {
    below += l[k - 1];
    const double w0 = static_cast<double>(k) / n, w1 = 1.0 - w0;
    const double m0 = below / static_cast<double>(k);
    const double m1 = (total - below) / (n - static_cast<double>(k));
    const double between = w0 * w1 * (m0 - m1) * (m0 - m1);
    if (between > best) best = between, split = k;
  }
  return sd[split / 2];
}

// Vertical-peak thresholds of StepThresholdMethod::kAuto (pdr.h): a fraction of the walk's
// typical step (the median peak and swing of the steps the fixed thresholds find), when the
// walk has standstills in a hand, whose shake could pass for steps.
void AutoThresholds(const Walk& walk, const ImuSignals& s, const PdrOptions& o, size_t gap,
                    double* peak, double* swing, StepFrontEndReport* report) {
  *peak = o.vertical_peak_mps2;
  *swing = o.vertical_min_swing_mps2;
  if (o.step_thresholds == StepThresholdMethod::kFixed) return;
  const size_t win = std::max<size_t>(2, static_cast<size_t>(std::lround(s.rate_hz)));
  std::vector<double> sd;
  for (size_t a = 0; a + win <= s.vertical_lp.size(); a += win) {
    double m = 0.0, m2 = 0.0;
    for (size_t i = a; i < a + win; ++i) m += s.vertical_lp[i];
    m /= static_cast<double>(win);
    for (size_t i = a; i < a + win; ++i) m2 += (s.vertical_lp[i] - m) * (s.vertical_lp[i] - m);
    sd.push_back(std::sqrt(m2 / static_cast<double>(win - 1)));
  }
  const std::vector<StepEvent> fixed =
      EventsFromPeaks(walk, s, PeaksWithGap(s.vertical_lp, *peak, gap), *swing);
  if (sd.empty() || fixed.size() < 4) return;
  std::vector<double> peaks, swings;
  for (const StepEvent& e : fixed) {
    peaks.push_back(e.a_max_mps2);
    swings.push_back(e.a_max_mps2 - e.a_min_mps2);
  }
  const double still = StillSigma(sd);
  const double step_peak = Quantile(&peaks, 0.5), step_swing = Quantile(&swings, 0.5);
  report->standstill_sigma_mps2 = still;
  report->step_peak_mps2 = step_peak;
  // No standstill (quiet windows as lively as steps), or a sensor at rest: the fixed values.
  if (still > o.auto_still_ratio * step_peak || o.auto_noise_sigmas * still < *peak) return;
  *peak = std::max(*peak, o.auto_step_fraction * step_peak);
  *swing = std::max(*swing, o.auto_step_fraction * step_swing);
}

StatusOr<std::vector<StepEvent>> DetectWithSignals(const Walk& walk, const ImuSignals& s,
                                                   const PdrOptions& o,
                                                   StepFrontEndReport* report) {
  const size_t gap = static_cast<size_t>(std::lround(o.min_step_interval_s * s.rate_hz));
  switch (o.detector) {
    case StepDetector::kVerticalPeak: {
      // 000 Sec. III-B: local maxima of the smoothed vertical acceleration.
      double peak = 0.0, swing = 0.0;
      AutoThresholds(walk, s, o, gap, &peak, &swing, report);
      report->vertical_peak_mps2 = peak;
      report->vertical_min_swing_mps2 = swing;
      return EventsFromPeaks(walk, s, PeaksWithGap(s.vertical_lp, peak, gap), swing);
    }
    case StepDetector::kFirMagnitude: {
      // 001 eq. 6: FIR (order 20, 3 Hz) on ‖a‖, local maxima above a threshold.
      std::vector<double> mag(walk.imu.size());
      for (size_t i = 0; i < mag.size(); ++i) mag[i] = walk.imu[i].acc_mps2.norm() - o.gravity_mps2;
      const std::vector<double> f =
          FilterZeroDelay(mag, DesignLowPassFir(o.fir_order, o.fir_cutoff_hz, s.rate_hz));
      return EventsFromPeaks(walk, s, PeaksWithGap(f, o.fir_peak_mps2, gap), 0.0);
    }
    case StepDetector::kEnergy: {
      // 003 eq. 1: E = ‖a^n − g‖² above 10 (m/s²)², maxima within 300 ms of a step rejected.
      std::vector<double> energy(walk.imu.size());
      for (size_t i = 0; i < energy.size(); ++i) {
        Eigen::Vector3d a = s.attitude[i] * walk.imu[i].acc_mps2;
        a.z() -= o.gravity_mps2;
        energy[i] = a.squaredNorm();
      }
      std::vector<size_t> peaks;
      double window_start_s = 0.0;  // the lockout runs from the step's first maximum
      for (size_t i = 1; i + 1 < energy.size(); ++i) {
        if (!(energy[i] > o.energy_threshold_m2ps4 && energy[i] > energy[i - 1] &&
              energy[i] >= energy[i + 1])) {
          continue;
        }
        // "Within 300 ms" inclusive: a maximum exactly 300 ms on (3 samples at 10 Hz) is
        // rejected; 1 ns of slack since sample times carry rounding (0.1 + 0.2 > 0.3).
        if (!peaks.empty() && walk.imu[i].t_s - window_start_s <= o.energy_lockout_s + 1e-9) {
          if (o.energy_lockout_keep == EnergyLockoutKeep::kStrongest &&
              energy[i] > energy[peaks.back()]) {
            peaks.back() = i;  // the step moves to the larger maximum; its window does not
          }
          continue;
        }
        peaks.push_back(i);
        window_start_s = walk.imu[i].t_s;
      }
      return EventsFromPeaks(walk, s, peaks, 0.0);
    }
  }
  return InternalError("pdr: unknown detector");
}

Status CheckImu(const Walk& walk) {
  if (walk.imu.empty()) return FailedPrecondition("pdr: the walk needs an IMU (imu.csv)");
  if (walk.imu.size() < 10) {
    return FailedPrecondition("pdr: the walk has " + std::to_string(walk.imu.size()) +
                              " IMU samples; expected at least 10");
  }
  for (size_t i = 1; i < walk.imu.size(); ++i) {
    if (!(walk.imu[i].t_s > walk.imu[i - 1].t_s)) {
      return InvalidArgument("pdr: IMU time does not increase at sample " + std::to_string(i));
    }
  }
  return Status::Ok();
}

// The principal axis of the horizontal acceleration in the levelled body frame (003 eq. 3-5)
// over the IMU index ranges `segments` ([a, b] each), its sign making the forward acceleration
// lead the vertical one by less than half a step (Kourogi & Kurata): the correlations of
// forward now with vertical later (lead) and the reverse (lag) over lags up to half of step_s,
// within each segment.
double PcaAngleOverSegments(const Walk& walk, const ImuSignals& s,
                            const std::vector<std::pair<size_t, size_t>>& segments, double step_s) {
  std::vector<std::vector<Eigen::Vector2d>> h;
  for (const auto& [begin, end] : segments) {
    h.emplace_back();
    for (size_t i = begin; i <= end; ++i) {
      const Eigen::Matrix3d r = s.attitude[i].toRotationMatrix();
      Eigen::Vector3d a = r * walk.imu[i].acc_mps2;  // a^n: g and a_z^n drop with the z part
      const double yaw = Yaw(r);
      const Eigen::Vector2d an(a.x(), a.y());
      h.back().push_back(Eigen::Rotation2Dd(-yaw) * an);  // levelled body frame
    }
  }
  Eigen::Vector2d mean = Eigen::Vector2d::Zero();
  size_t count = 0;
  for (const auto& seg : h) {
    for (const auto& v : seg) mean += v;
    count += seg.size();
  }
  mean /= static_cast<double>(count);
  Eigen::Matrix2d c = Eigen::Matrix2d::Zero();
  for (const auto& seg : h) {
    for (const auto& v : seg) c += (v - mean) * (v - mean).transpose();
  }
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> eig(c);
  const Eigen::Vector2d axis = eig.eigenvectors().col(1);
  const int max_lag = std::max(1, static_cast<int>(0.5 * step_s * s.rate_hz));
  double lead = 0.0, lag = 0.0;
  for (int k = 1; k <= max_lag; ++k) {
    for (size_t g = 0; g < h.size(); ++g) {
      const size_t begin = segments[g].first;
      for (size_t i = 0; i + static_cast<size_t>(k) < h[g].size(); ++i) {
        const double f_i = (h[g][i] - mean).dot(axis);
        const double f_k = (h[g][i + k] - mean).dot(axis);
        lead += f_i * s.vertical_lp[begin + i + k];  // forward now, vertical later
        lag += f_k * s.vertical_lp[begin + i];
      }
    }
  }
  const Eigen::Vector2d fwd = lead >= lag ? axis : Eigen::Vector2d(-axis);
  return std::atan2(fwd.y(), fwd.x());
}

// Forward axis angle φ in the levelled body frame by PCA of the horizontal acceleration
// (003 eq. 3–5) over the first pca_window_s of walking.
double PcaForwardAngle(const Walk& walk, const ImuSignals& s, const std::vector<StepEvent>& ev,
                       const PdrOptions& o) {
  if (ev.size() < 4) return 0.0;
  const size_t begin = ev.front().imu_index;
  size_t end = begin;
  while (end + 1 < walk.imu.size() && walk.imu[end].t_s - walk.imu[begin].t_s < o.pca_window_s) {
    ++end;
  }
  const double step_s = (ev.back().t_s - ev.front().t_s) / static_cast<double>(ev.size() - 1);
  return PcaAngleOverSegments(walk, s, {{begin, end}}, step_s);
}

// ForwardAxisMethod::kAuto (our choice, after Kourogi & Kurata's sign rule of the PCA above):
// the forward acceleration of a walker oscillates at the step frequency and leads the vertical
// one, while the lateral sway runs at half of it (one period per stride) and so correlates with
// the vertical with alternating sign from step to step. Per step s (the samples between two
// consecutive steps at most 1.5 s apart: walking, not pauses) the vector
//   d_s = Σ_{k=1..L} Σ_i [h_i·v_{i+k} − h_{i+k}·v_i]
// (h the levelled horizontal acceleration less its walk mean, v the filtered vertical one, L half
// a median step) points forward; the forward axis is the mean direction of the unit vectors
// u_s = d_s/|d_s| (one vote per step, so that a few jolts of the hand do not outweigh the
// walk), accepted when the steps agree by Rayleigh's test, z = n·R² ≥ auto_forward_min_z with
// R = |Σ u_s| / n (random directions give z ≈ 1), and snapped to the nearest body axis within
// forward_axis_snap_rad. Otherwise: body y for a walk.yaml handheld device (a phone in portrait),
// else body x.
double AutoForwardAngle(const Walk& walk, const ImuSignals& s, const std::vector<StepEvent>& ev,
                        const PdrOptions& o, StepFrontEndReport* report) {
  constexpr double kMaxStepS = 1.5;  // a step takes 0.4-1 s; longer is a pause
  const double fallback = walk.meta.imu_placement == ImuPlacement::kHandheld ? kPi / 2.0 : 0.0;
  std::vector<std::pair<size_t, size_t>> segments;
  std::vector<double> durations;
  for (size_t k = 1; k < ev.size(); ++k) {
    if (!(ev[k].duration_s > 0 && ev[k].duration_s <= kMaxStepS)) continue;
    segments.emplace_back(ev[k - 1].imu_index, ev[k].imu_index);
    durations.push_back(ev[k].duration_s);
  }
  if (segments.size() < 4) return fallback;
  auto levelled = [&](size_t i) {
    const Eigen::Matrix3d r = s.attitude[i].toRotationMatrix();
    const Eigen::Vector3d a = r * walk.imu[i].acc_mps2;
    return Eigen::Vector2d(Eigen::Rotation2Dd(-Yaw(r)) * Eigen::Vector2d(a.x(), a.y()));
  };
  Eigen::Vector2d mean = Eigen::Vector2d::Zero();
  size_t count = 0;
  for (const auto& [a, b] : segments) {
    for (size_t i = a; i <= b; ++i, ++count) mean += levelled(i);
  }
  mean /= static_cast<double>(count);
  const size_t lags =
      static_cast<size_t>(std::max(1.0, std::floor(0.5 * Quantile(&durations, 0.5) * s.rate_hz)));
  Eigen::Vector2d sum = Eigen::Vector2d::Zero();
  for (const auto& [a, b] : segments) {
    std::vector<Eigen::Vector2d> h;
    for (size_t i = a; i <= b; ++i) h.push_back(levelled(i) - mean);
    Eigen::Vector2d d = Eigen::Vector2d::Zero();
    for (size_t k = 1; k <= lags; ++k) {
      for (size_t i = 0; i + k < h.size(); ++i) {
        d += h[i] * s.vertical_lp[a + i + k] - h[i + k] * s.vertical_lp[a + i];
      }
    }
    if (d.norm() > 0) sum += d.normalized();  // one vote per step: a jolt of the hand is one
  }
  const double consistency = sum.norm() / static_cast<double>(segments.size());
  report->forward_axis_consistency = consistency;
  const double z = static_cast<double>(segments.size()) * consistency * consistency;
  if (!(z >= o.auto_forward_min_z)) return fallback;
  const double angle = std::atan2(sum.y(), sum.x());
  report->forward_axis_data_rad = angle;
  for (const double axis : {0.0, kPi / 2.0, kPi, -kPi / 2.0}) {
    if (std::fabs(NormalizeAngle(angle - axis)) <= o.forward_axis_snap_rad) {
      return NormalizeAngle(axis);
    }
  }
  return angle;
}

// Heading of the body x axis from the tilt-compensated magnetometer (ENU, from east).
double MagHeading(const ImuSample& m, const Eigen::Quaterniond& q, double declination) {
  const Eigen::Matrix3d r = q.toRotationMatrix();
  const Eigen::Vector3d mn = r * m.mag_ut;
  const Eigen::Vector2d ml = Eigen::Rotation2Dd(-Yaw(r)) * Eigen::Vector2d(mn.x(), mn.y());
  // Levelled-frame field of a body at yaw ψ: (B sin ψ, B cos ψ) for a field pointing north (+y).
  return NormalizeAngle(std::atan2(ml.x(), ml.y()) - declination);
}

}  // namespace

StatusOr<PdrOptions> PdrOptionsFromYaml(const YAML::Node& node) {
  PdrOptions o;
  ConfigReader r(node, "pdr");
  r.ReadEnum("detector", &o.detector, kDetectorNames,
             "step detector: vertical peaks, FIR magnitude (001 eq. 6), or energy (003 eq. 1)");
  r.ReadEnum("length_model", &o.length_model, kLengthNames,
             "step length model: Weinberg (000), constant, or linear in step frequency");
  r.ReadEnum("heading", &o.heading, kHeadingNames,
             "step heading: integrated gyro, gyro blended with magnetometer (001 eq. 7), or auto "
             "(the blend when the walk has a magnetometer and no start heading)");
  r.ReadEnum("forward_axis", &o.forward_axis, kForwardNames,
             "walking direction: body x, body y, PCA of horizontal acceleration (003), or auto "
             "(the direction whose acceleration leads the vertical, step after step)");
  r.Read("auto_forward_min_z", &o.auto_forward_min_z,
         "auto forward axis: least Rayleigh z of the steps' agreement on the forward direction");
  r.Read("forward_axis_snap_rad", &o.forward_axis_snap_rad,
         "auto forward axis: a direction within this of a body axis is that axis");
  r.ReadEnum(
      "step_thresholds", &o.step_thresholds, kThresholdNames,
      "vertical-peak thresholds: fixed, or auto (raised to half the walk's typical step when "
      "it stands still in a shaking hand)");
  r.Read("auto_still_ratio", &o.auto_still_ratio,
         "auto thresholds: the walk has standstills if their sigma is below this x the median "
         "step peak");
  r.Read("auto_noise_sigmas", &o.auto_noise_sigmas,
         "auto thresholds: raised only if this x the standstill sigma reaches the fixed peak (a "
         "hand, not a sensor at rest)");
  r.Read("auto_step_fraction", &o.auto_step_fraction,
         "auto thresholds: least peak and swing as this fraction of the walk's median step");
  r.Read("vertical_cutoff_hz", &o.vertical_cutoff_hz,
         "vertical-peak: low-pass cut-off of vertical acceleration");
  r.Read("vertical_peak_mps2", &o.vertical_peak_mps2,
         "vertical-peak: least peak of the filtered vertical acceleration");
  r.Read("vertical_min_swing_mps2", &o.vertical_min_swing_mps2,
         "vertical-peak: least a_max - a_min of a step");
  r.Read("fir_order", &o.fir_order, "fir-magnitude: FIR low-pass order (001 eq. 6)");
  r.Read("fir_cutoff_hz", &o.fir_cutoff_hz, "fir-magnitude: FIR cut-off (001 eq. 6)");
  r.Read("fir_peak_mps2", &o.fir_peak_mps2, "fir-magnitude: least peak of filtered |a| - g");
  r.Read("energy_threshold_m2ps4", &o.energy_threshold_m2ps4,
         "energy: acceleration energy threshold (003 eq. 1)");
  r.Read("energy_lockout_s", &o.energy_lockout_s,
         "energy: maxima this long after a step are not steps (003 eq. 1)");
  r.ReadEnum("energy_lockout_keep", &o.energy_lockout_keep, EnergyLockoutKeepNames(),
             "energy: which maximum of a lockout span is the step");
  r.Read("min_step_interval_s", &o.min_step_interval_s,
         "vertical-peak, fir-magnitude: shortest time between steps");
  r.Read("weinberg_k", &o.weinberg_k, "Weinberg K of l = K (a_max - a_min)^(1/4) (000 Sec. IV)");
  r.Read("constant_length_m", &o.constant_length_m, "constant model: step length");
  r.Read("linear_c0_m", &o.linear_c0_m, "linear model: c0 of l = c0 + c1 f_step");
  r.Read("linear_c1_m_s", &o.linear_c1_m_s, "linear model: c1 of l = c0 + c1 f_step");
  r.Read("sigma_length_frac", &o.sigma_length_frac,
         "step length sigma, fraction of the length (plus sigma_length_m)");
  r.Read("sigma_length_m", &o.sigma_length_m, "step length sigma, constant part");
  r.Read("complementary_w", &o.complementary_w,
         "complementary heading: magnetometer weight W per step (001 eq. 7)");
  r.Read("mag_declination_rad", &o.mag_declination_rad,
         "magnetic declination added to magnetometer headings");
  r.Read("pca_window_s", &o.pca_window_s, "pca: walking time used for the PCA (003 eq. 3-5)");
  r.Read("sigma_dheading_rad", &o.sigma_dheading_rad, "sigma of each step's heading increment");
  r.Read("sigma_heading0_rad", &o.sigma_heading0_rad,
         "sigma of the initial heading when initial_pose does not give it");
  r.Read("attitude_gain", &o.attitude_gain, "Mahony attitude filter proportional gain");
  r.Read("attitude_acc_gate_mps2", &o.attitude_acc_gate_mps2,
         "attitude filter uses the accelerometer only if | |a| - g | below this");
  r.Read("gravity_mps2", &o.gravity_mps2, "gravity magnitude");
  const YAML::Node stride = r.Child("stride");
  WG_RETURN_IF_ERROR(r.Finish());
  if (stride.IsDefined()) {
    WG_ASSIGN_OR_RETURN(o.stride, StrideOptionsFromYaml(stride));
  }
  WG_RETURN_IF_ERROR(o.Validate());
  return o;
}

Status PdrOptions::Validate() const {
  const PdrOptions& o = *this;
  if (o.fir_order < 2 || o.fir_cutoff_hz <= 0 || o.vertical_cutoff_hz <= 0 ||
      o.complementary_w < 0 || o.complementary_w > 1 || o.weinberg_k <= 0 ||
      o.min_step_interval_s < 0 || o.energy_lockout_s < 0 || o.gravity_mps2 <= 0) {
    return InvalidArgument(
        "pdr: need fir_order >= 2, cut-offs > 0, 0 <= complementary_w <= 1, weinberg_k > 0, "
        "intervals >= 0, gravity_mps2 > 0");
  }
  if (!(o.forward_axis_snap_rad >= 0 && o.forward_axis_snap_rad <= kPi / 4) ||
      !(o.auto_forward_min_z >= 0) || !(o.auto_still_ratio >= 0) || !(o.auto_noise_sigmas >= 0) ||
      !(o.auto_step_fraction >= 0 && o.auto_step_fraction < 1)) {
    return InvalidArgument(
        "pdr: need 0 <= forward_axis_snap_rad <= pi/4, auto_forward_min_z >= 0, "
        "auto_still_ratio >= 0, auto_noise_sigmas >= 0, 0 <= auto_step_fraction < 1");
  }
  return CheckEnumOption(EnergyLockoutKeepNames(), o.energy_lockout_keep, "energy_lockout_keep",
                         "pdr");
}

std::vector<double> DesignLowPassFir(int order, double cutoff_hz, double rate_hz) {
  const int n = std::max(order, 0) + 1;
  const double fc = std::min(cutoff_hz / rate_hz, 0.5);
  const double mid = 0.5 * order;
  std::vector<double> taps(n);
  for (int i = 0; i < n; ++i) {
    const double x = i - mid;
    const double sinc = std::fabs(x) < 1e-12 ? 2.0 * fc : std::sin(2.0 * kPi * fc * x) / (kPi * x);
    const double window = order == 0 ? 1.0 : 0.54 - 0.46 * std::cos(2.0 * kPi * i / order);
    taps[i] = sinc * window;
  }
  const double sum = std::accumulate(taps.begin(), taps.end(), 0.0);
  for (double& t : taps) t /= sum;
  return taps;
}

std::vector<double> FilterZeroDelay(const std::vector<double>& x, const std::vector<double>& taps) {
  std::vector<double> y(x.size(), 0.0);
  if (x.empty()) return y;
  const long half = static_cast<long>(taps.size() / 2);
  const long n = static_cast<long>(x.size());
  for (long i = 0; i < n; ++i) {
    double acc = 0.0;
    for (long k = 0; k < static_cast<long>(taps.size()); ++k) {
      const long j = std::clamp(i + half - k, 0L, n - 1);
      acc += taps[k] * x[j];
    }
    y[i] = acc;
  }
  return y;
}

StatusOr<std::vector<Eigen::Quaterniond>> EstimateAttitude(const std::vector<ImuSample>& imu,
                                                           const PdrOptions& o) {
  if (imu.empty()) return FailedPrecondition("attitude: no IMU samples");
  // Initial tilt from the mean specific force of the first 0.5 s (it points up at rest).
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  size_t n = 0;
  for (const ImuSample& s : imu) {
    if (s.t_s - imu.front().t_s > 0.5 && n > 0) break;
    mean += s.acc_mps2;
    ++n;
  }
  if (mean.norm() < 1e-6) return FailedPrecondition("attitude: zero specific force at start");
  std::vector<Eigen::Quaterniond> q(imu.size());
  q[0] = Eigen::Quaterniond::FromTwoVectors(mean.normalized(), Eigen::Vector3d::UnitZ());
  // Across an IMU gap (Walk::ImuGaps) the attitude is held, not integrated over the hole.
  const double gap_s = ImuGapThresholdS(imu);
  for (size_t i = 1; i < imu.size(); ++i) {
    double dt = imu[i].t_s - imu[i - 1].t_s;
    if (dt > gap_s) dt = 0.0;
    Eigen::Vector3d w = 0.5 * (imu[i].gyro_radps + imu[i - 1].gyro_radps);
    const Eigen::Vector3d& a = imu[i].acc_mps2;
    if (std::fabs(a.norm() - o.gravity_mps2) < o.attitude_acc_gate_mps2) {
      const Eigen::Vector3d up_body = q[i - 1].conjugate() * Eigen::Vector3d::UnitZ();
      w += o.attitude_gain * a.normalized().cross(up_body);  // Mahony tilt correction
    }
    const double angle = w.norm() * dt;
    const Eigen::Quaterniond dq = angle > 1e-15
                                      ? Eigen::Quaterniond(Eigen::AngleAxisd(angle, w.normalized()))
                                      : Eigen::Quaterniond::Identity();
    q[i] = (q[i - 1] * dq).normalized();
  }
  return q;
}

StatusOr<std::vector<StepEvent>> DetectSteps(const Walk& walk, const PdrOptions& options) {
  WG_RETURN_IF_ERROR(options.Validate());
  WG_RETURN_IF_ERROR(CheckImu(walk));
  WG_ASSIGN_OR_RETURN(const ImuSignals s, ComputeSignals(walk, options));
  StepFrontEndReport report;
  return DetectWithSignals(walk, s, options, &report);
}

StatusOr<StepSequence> ComputeSteps(const Walk& walk, const PdrOptions& o) {
  WG_RETURN_IF_ERROR(o.Validate());
  WG_RETURN_IF_ERROR(CheckImu(walk));
  WG_ASSIGN_OR_RETURN(const ImuSignals s, ComputeSignals(walk, o));
  StepSequence out;
  WG_ASSIGN_OR_RETURN(const std::vector<StepEvent> events,
                      DetectWithSignals(walk, s, o, &out.report));

  // Integrated yaw ψ_i (000 eq. 4) at every sample.
  // Held across IMU gaps (Walk::ImuGaps): the step graph bridges them.
  std::vector<double> psi(walk.imu.size(), 0.0);
  const double gap_s = ImuGapThresholdS(walk.imu);
  for (size_t i = 1; i < psi.size(); ++i) {
    double dt = walk.imu[i].t_s - walk.imu[i - 1].t_s;
    if (dt > gap_s) dt = 0.0;
    psi[i] = psi[i - 1] + dt * 0.5 * (s.yaw_rate[i] + s.yaw_rate[i - 1]);
  }
  const bool have_mag = walk.imu.front().has_mag;
  const bool use_mag = ResolveHeadingMethod(walk, o) == HeadingMethod::kComplementary;
  if (use_mag && !have_mag) {
    return FailedPrecondition("pdr: heading 'complementary' needs magnetometer samples");
  }
  // Forward axis relative to body x (ENU yaw, counter-clockwise): body y is +90°.
  const double phi =
      o.forward_axis == ForwardAxisMethod::kAuto ? AutoForwardAngle(walk, s, events, o, &out.report)
      : o.forward_axis == ForwardAxisMethod::kPca   ? PcaForwardAngle(walk, s, events, o)
      : o.forward_axis == ForwardAxisMethod::kBodyY ? kPi / 2.0
                                                    : 0.0;
  out.report.forward_axis_rad = phi;
  auto mag_walk_heading = [&](size_t from, size_t to) {
    // Circular mean of the magnetometer heading over [from, to] (body x, then forward axis).
    double c = 0.0, sn = 0.0;
    for (size_t i = from; i <= to; ++i) {
      const double h = MagHeading(walk.imu[i], s.attitude[i], o.mag_declination_rad);
      c += std::cos(h);
      sn += std::sin(h);
    }
    return NormalizeAngle(std::atan2(sn, c) + phi);
  };

  double theta = 0.0, var = o.sigma_heading0_rad * o.sigma_heading0_rad;
  if (walk.meta.initial_pose && walk.meta.initial_pose->heading_known) {
    theta = walk.meta.initial_pose->heading_rad;
    var = walk.meta.initial_pose->sigma_heading_rad * walk.meta.initial_pose->sigma_heading_rad;
    out.absolute_heading = true;
    out.report.heading_source = HeadingSource::kInitialPose;
  } else if (use_mag && !events.empty()) {
    theta = mag_walk_heading(0, events.front().imu_index);
    out.absolute_heading = true;
    out.report.heading_source = HeadingSource::kMagnetometer;
  }
  // θ is the walking direction at the walk's start (the first IMU sample).
  const double sigma_mag = std::max(o.sigma_heading0_rad, 1e-3);
  size_t prev = 0;
  for (const StepEvent& e : events) {
    Step st;
    st.t_s = e.t_s;
    st.duration_s = e.duration_s;
    st.a_max_mps2 = e.a_max_mps2;
    st.a_min_mps2 = e.a_min_mps2;
    switch (o.length_model) {
      case StepLengthModel::kWeinberg:  // 000 eq. 3, 003 eq. 2
        st.length_m = o.weinberg_k * std::pow(std::max(e.a_max_mps2 - e.a_min_mps2, 0.0), 0.25);
        break;
      case StepLengthModel::kConstant:  // 001: constant per-user step length
        st.length_m = o.constant_length_m;
        break;
      case StepLengthModel::kLinearFrequency: {
        const double f = e.duration_s > 0 ? 1.0 / e.duration_s : 0.0;
        st.length_m = f > 0 ? o.linear_c0_m + o.linear_c1_m_s * f : o.constant_length_m;
        break;
      }
    }
    st.sigma_length_m = o.sigma_length_frac * st.length_m + o.sigma_length_m;
    if (have_mag) {
      st.has_mag_heading = true;
      st.mag_heading_rad = mag_walk_heading(prev, e.imu_index);
    }
    const double dpsi = psi[e.imu_index] - psi[prev];
    st.dheading_rad = NormalizeAngle(dpsi);
    st.sigma_dheading_rad = o.sigma_dheading_rad;
    theta += dpsi;
    var += o.sigma_dheading_rad * o.sigma_dheading_rad;
    if (use_mag) {
      // 001 eq. 7: θ = (1 − W)(θ + ω̄T) + W·θ_mag, blended on the circle.
      const double m = mag_walk_heading(e.imu_index, e.imu_index);
      theta += o.complementary_w * NormalizeAngle(m - theta);
      const double w = o.complementary_w;
      var = (1 - w) * (1 - w) * var + w * w * sigma_mag * sigma_mag;
    }
    theta = NormalizeAngle(theta);
    st.heading_rad = theta;
    st.sigma_heading_rad = std::sqrt(var);
    out.steps.push_back(st);
    prev = e.imu_index;
  }
  return out;
}

HeadingMethod ResolveHeadingMethod(const Walk& walk, const PdrOptions& o) {
  if (o.heading != HeadingMethod::kAuto) return o.heading;
  const bool start_heading = walk.meta.initial_pose && walk.meta.initial_pose->heading_known;
  const bool mag = !walk.imu.empty() && walk.imu.front().has_mag;
  return mag && !start_heading ? HeadingMethod::kComplementary : HeadingMethod::kGyro;
}

void AddFrontEndDiagnostics(const StepFrontEndReport& r, std::map<std::string, double>* d) {
  (*d)["pdr_heading_source"] = static_cast<double>(r.heading_source);
  auto put = [d](const char* key, double v, double scale) {
    if (std::isfinite(v)) (*d)[key] = v * scale;
  };
  const double deg = 180.0 / kPi;
  put("pdr_forward_axis_deg", r.forward_axis_rad, deg);
  put("pdr_forward_axis_data_deg", r.forward_axis_data_rad, deg);
  put("pdr_forward_axis_consistency", r.forward_axis_consistency, 1.0);
  put("pdr_standstill_sigma_mps2", r.standstill_sigma_mps2, 1.0);
  put("pdr_step_peak_mps2", r.step_peak_mps2, 1.0);
  put("pdr_vertical_peak_mps2", r.vertical_peak_mps2, 1.0);
  put("pdr_vertical_min_swing_mps2", r.vertical_min_swing_mps2, 1.0);
}

StepSequence StepsFromOdometry(const Walk& walk) {
  StepSequence out;
  double theta = 0.0;
  double var = 0.0;
  if (walk.meta.initial_pose && walk.meta.initial_pose->heading_known) {
    theta = walk.meta.initial_pose->heading_rad;
    var = walk.meta.initial_pose->sigma_heading_rad * walk.meta.initial_pose->sigma_heading_rad;
    out.absolute_heading = true;
    out.report.heading_source = HeadingSource::kInitialPose;
  }
  // Same noise model as the odometry-dr estimator's defaults.
  constexpr double kSigmaDistFrac = 0.05, kSigmaDistM = 0.001, kSigmaDheading = 0.01;
  double prev_turn = 0.0;
  for (size_t i = 0; i < walk.odometry.size(); ++i) {
    const OdometrySample& o = walk.odometry[i];
    Step st;
    st.t_s = o.t_s;
    st.duration_s = i == 0 ? 0.0 : o.t_s - walk.odometry[i - 1].t_s;
    st.length_m = o.dist_m;
    st.sigma_length_m = kSigmaDistFrac * std::fabs(o.dist_m) + kSigmaDistM;
    st.dheading_rad = NormalizeAngle(prev_turn);
    st.sigma_dheading_rad = kSigmaDheading;
    theta = NormalizeAngle(theta + prev_turn);
    if (i > 0) var += kSigmaDheading * kSigmaDheading;
    st.heading_rad = theta;
    st.sigma_heading_rad = std::sqrt(var);
    out.steps.push_back(st);
    prev_turn = o.dheading_rad;
  }
  return out;
}

StatusOr<StepSequence> StepsForWalk(const Walk& walk, const PdrOptions& options) {
  if (walk.has_odometry()) return StepsFromOdometry(walk);
  if (!walk.has_imu()) {
    return FailedPrecondition("walk '" + walk.meta.name + "' has neither odometry nor an IMU");
  }
  if (walk.meta.imu_placement == ImuPlacement::kFoot) return ComputeStrides(walk, options.stride);
  return ComputeSteps(walk, options);
}

}  // namespace walkgraph
