// The foot-INS graph's states and factor makers (ins_graph_internal.h), shared by fg-ins-batch
// and fg-ins-window.
#include "smoothers/ins_graph_internal.h"

#include <algorithm>
#include <cmath>
#include <set>
#include <utility>

#include <ceres/normal_prior.h>

#include "factors/anchor_state_factors.h"
#include "factors/bias_random_walk_factor.h"
#include "factors/difference_prior_factor.h"
#include "factors/gap_reach_factor.h"
#include "factors/imu_preintegration_factor.h"
#include "factors/ins_prior_factor.h"
#include "factors/magnetic_heading_change_factor.h"
#include "factors/magnetic_heading_factor.h"
#include "factors/position_prior_factor.h"
#include "factors/range_factor.h"
#include "factors/rss_factor.h"
#include "factors/stance_level_factor.h"
#include "factors/zaru_factor.h"
#include "factors/zupt_factor.h"
#include "smoothers/graph_internal.h"
#include "util/enum_define.h"
#include "util/median.h"
#include "walkgraph/angle.h"

namespace walkgraph {

WALKGRAPH_DEFINE_ENUM_NAMES(
    InsFactorKind, "InsFactor kind", {"imu", InsFactorKind::kImu},
    {"bias_rw_gyro", InsFactorKind::kBiasRwGyro}, {"bias_rw_acc", InsFactorKind::kBiasRwAcc},
    {"zupt", InsFactorKind::kZupt}, {"zaru", InsFactorKind::kZaru},
    {"prior", InsFactorKind::kPrior}, {"bias_prior_gyro", InsFactorKind::kBiasPriorGyro},
    {"bias_prior_acc", InsFactorKind::kBiasPriorAcc},
    {"path_loss_spread", InsFactorKind::kPathLossSpread},
    {"path_loss_prior", InsFactorKind::kPathLossPrior}, {"rss", InsFactorKind::kRss},
    {"range", InsFactorKind::kRange}, {"range_bias_prior", InsFactorKind::kRangeBiasPrior},
    {"anchor_prior", InsFactorKind::kAnchorPrior}, {"waypoint", InsFactorKind::kWaypoint},
    {"gap_reach", InsFactorKind::kGapReach},
    {"gap_magnetic_heading", InsFactorKind::kGapMagneticHeading},
    {"stance_magnetic_heading", InsFactorKind::kStanceMagneticHeading},
    {"stance_level", InsFactorKind::kStanceLevel})

namespace {

InsFactor MakeFactor(InsFactorKind kind, ceres::CostFunction* cost, std::vector<double*> blocks) {
  InsFactor f;
  f.kind = kind;
  f.cost.reset(cost);
  f.blocks = std::move(blocks);
  return f;
}

// The ZUPT sample nearest the middle of a stance phase: the foot is stillest there (the
// phase's edges hold the slow ends of the swing, where a ZUPT state would be biased).
size_t MidStance(const ZuptInsSolution& front, const StancePhase& ph) {
  const size_t mid = (ph.begin + ph.end) / 2;
  for (size_t d = 0; d <= (ph.end - ph.begin) / 2 + 1; ++d) {
    if (mid >= ph.begin + d && front.zupt[mid - d]) return mid - d;
    if (mid + d <= ph.end && front.zupt[mid + d]) return mid + d;
  }
  return mid;
}

bool UsesRss(const InsGraphContext& c) {
  return c.options.use_rss && c.walk->has_rss() && !c.walk->anchors.empty();
}
bool UsesRanges(const InsGraphContext& c) {
  return c.options.use_ranges && c.walk->has_ranges() && !c.walk->anchors.empty();
}
bool HasRadio(const InsGraphContext& c) { return UsesRss(c) || UsesRanges(c); }

}  // namespace

StatusOr<std::vector<InsState>> InitialInsStates(const Walk& walk, const ZuptInsSolution& front,
                                                 const InsGraphOptions& o) {
  WG_RETURN_IF_ERROR(o.Validate());
  const size_t n = walk.imu.size();
  if (n < 2 || front.states.size() != n) {
    return FailedPrecondition("fg-ins-batch: the front end's solution does not match the IMU");
  }
  std::set<size_t> idx = {0, n - 1};
  if (o.placement == InsStatePlacement::kStance) {
    for (const StancePhase& ph : front.phases) idx.insert(MidStance(front, ph));
  } else {
    for (size_t k = 0; k < n; k += static_cast<size_t>(o.every_n_samples)) idx.insert(k);
  }
  // No interval longer than max_state_interval_s (long standstills, walks without stance).
  std::vector<size_t> sorted(idx.begin(), idx.end());
  std::vector<size_t> all;
  for (size_t s = 0; s < sorted.size(); ++s) {
    all.push_back(sorted[s]);
    if (s + 1 == sorted.size()) break;
    const size_t a = sorted[s], b = sorted[s + 1];
    const double span = walk.imu[b].t_s - walk.imu[a].t_s;
    const int pieces = static_cast<int>(std::ceil(span / o.max_state_interval_s));
    for (int j = 1; j < pieces; ++j) {
      const size_t k =
          a + static_cast<size_t>(std::llround(static_cast<double>(b - a) * j / pieces));
      if (k > all.back() && k < b) all.push_back(k);
    }
  }
  std::vector<InsState> states;
  states.reserve(all.size());
  for (size_t k : all) {
    InsState s;
    s.t_s = walk.imu[k].t_s;
    s.imu_index = k;
    s.zupt = front.zupt[k];
    const NavState& x = front.states[k];
    for (int i = 0; i < 3; ++i) {
      s.p[i] = x.p_n[i];
      s.v[i] = x.v_n[i];
      s.bg[i] = front.gyro_bias_radps[k][i];
      s.ba[i] = front.acc_bias_mps2[k][i];
    }
    const Eigen::Quaterniond q = x.q_nb.normalized();
    s.q = {q.x(), q.y(), q.z(), q.w()};
    states.push_back(s);
  }
  return states;
}

namespace {

// The front end's scale noise at IMU sample k (0 without one).
double ScaleNoiseAt(const InsGraphContext& c, size_t k) {
  return c.scale_noise != nullptr && k < c.scale_noise->size() ? (*c.scale_noise)[k] : 0.0;
}

// The levelling factor of a ZUPT state (InsGraphOptions::use_stance_level): the mean reading
// over the middle half of the run of ZUPT samples around it (the run's ends hold the foot
// settling and lifting: on three simulated preset walks the whole run's spread was 0.061–0.108
// m/s² (10th–90th percentile), its middle half's 0.010–0.012, the accelerometer's noise 0.011),
// the run within max_state_interval_s / 2
// of the state (a long standstill has a state every max_state_interval_s: the runs of two
// states do not overlap) and not across an IMU gap.
InsFactor StanceLevel(const InsGraphContext& c, InsState* s) {
  const std::vector<ImuSample>& imu = c.walk->imu;
  const std::vector<bool>& zupt = *c.zupt;
  const size_t k = s->imu_index;
  const double half = 0.5 * c.options.max_state_interval_s;
  size_t lo = k, hi = k;
  while (lo > 0 && zupt[lo - 1] && imu[k].t_s - imu[lo - 1].t_s <= half &&
         imu[lo].t_s - imu[lo - 1].t_s <= c.imu_gap_s) {
    --lo;
  }
  while (hi + 1 < imu.size() && zupt[hi + 1] && imu[hi + 1].t_s - imu[k].t_s <= half &&
         imu[hi + 1].t_s - imu[hi].t_s <= c.imu_gap_s) {
    ++hi;
  }
  const size_t quarter = (hi - lo) / 4;
  lo = std::min(lo + quarter, k);
  hi = std::max(hi - quarter, k);
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (size_t j = lo; j <= hi; ++j) mean += imu[j].acc_mps2;
  const double m = static_cast<double>(hi - lo + 1);
  mean /= m;
  // σ² per axis: the white noise averages over the m readings; what the readings spread beyond
  // it is the foot moving (a real foot rolls as it stands: middle-half medians 0.14–0.15 m/s² on
  // the PyShoe walking trials, 0.43–0.70 on the running ones),
  // correlated over the stance, so it does not.
  double spread2 = 0.0;
  for (size_t j = lo; j <= hi; ++j) spread2 += (imu[j].acc_mps2 - mean).squaredNorm() / 3.0;
  spread2 /= m;
  const StrideOptions& fe = c.options.front_end;
  const double s_noise = ScaleNoiseAt(c, k);
  const double white2 =
      fe.acc_noise_mps2 * fe.acc_noise_mps2 + std::pow(s_noise * fe.gravity_mps2, 2);
  const double sigma = std::sqrt(white2 / m + std::max(0.0, spread2 - white2));
  InsFactor f = MakeFactor(InsFactorKind::kStanceLevel,
                           StanceLevelFactor::Create(mean, fe.gravity_mps2, sigma),
                           {s->q.data(), s->ba.data()});
  f.loss = internal::MakeLoss(c.options.zupt_loss, c.options.zupt_loss_scale);
  return f;
}

}  // namespace

std::vector<InsFactor> InsStateFactors(const InsGraphContext& c, InsState* s) {
  std::vector<InsFactor> out;
  if (s->zupt) {
    out.push_back(MakeFactor(InsFactorKind::kZupt, ZuptFactor::Create(c.options.zupt_sigma_mps),
                             {s->v.data()}));
    out.back().loss = internal::MakeLoss(c.options.zupt_loss, c.options.zupt_loss_scale);
    if (c.options.use_stance_level && c.zupt != nullptr && c.zupt->size() == c.walk->imu.size()) {
      out.push_back(StanceLevel(c, s));
    }
  }
  return out;
}

namespace {

// The last sample at or before IMU sample `index`, within 0.1 s of it, that has a magnetometer
// reading (at or before: the online output at a state uses no later reading).
std::optional<size_t> MagnetometerNear(const std::vector<ImuSample>& imu, size_t index) {
  for (size_t k = index + 1; k-- > 0 && imu[index].t_s - imu[k].t_s <= 0.1;) {
    if (imu[k].has_mag) return k;
  }
  return std::nullopt;
}

// What the walk before an IMU gap shows of spans as long as the gap's (InsGraphOptions::
// use_gap_reach, use_gap_magnetometer): on the front end's path over the kGapHistoryS before
// the gap, for spans starting every 0.5 s and crossing no earlier gap, the horizontal path
// length walked (spans of at least 0.1 m/s only: standing does not say how far the walker
// goes) and the change of the magnetic field's horizontal direction in the navigation frame.
// The bounded history keeps a walk with many gaps linear in its length (and follows the
// walker's recent pace).
struct GapHistory {
  std::vector<double> reach_m;
  std::vector<double> field_turn_rad;
};

double FieldDirection(const InsGraphContext& c, size_t k) {
  const Eigen::Vector3d m = (*c.path)[k].q_nb * c.walk->imu[k].mag_ut;
  return std::atan2(m.y(), m.x());
}

constexpr double kGapHistoryS = 300.0;

GapHistory LearnGapHistory(const InsGraphContext& c, size_t k_end, double span_s) {
  const std::vector<ImuSample>& imu = c.walk->imu;
  const std::vector<NavState>& path = *c.path;
  size_t k0 = k_end;  // the first sample of the history
  while (k0 > 0 && imu[k_end].t_s - imu[k0 - 1].t_s <= kGapHistoryS) --k0;
  const size_t n = k_end - k0 + 1;
  std::vector<double> arc(n, 0.0);  // cumulative horizontal path length from k0
  std::vector<int> gaps(n, 0);      // gaps among the intervals from k0
  for (size_t m = 1; m < n; ++m) {
    const size_t i = k0 + m;
    const bool gap = imu[i].t_s - imu[i - 1].t_s > c.imu_gap_s;
    gaps[m] = gaps[m - 1] + (gap ? 1 : 0);
    arc[m] = arc[m - 1] + (gap ? 0.0 : (path[i].p_n - path[i - 1].p_n).head<2>().norm());
  }
  GapHistory h;
  double next_t = -std::numeric_limits<double>::infinity();
  for (size_t i = k0, j = k0; i <= k_end; ++i) {
    if (imu[i].t_s < next_t) continue;
    next_t = imu[i].t_s + 0.5;
    j = std::max(j, i);
    while (j <= k_end && imu[j].t_s < imu[i].t_s + span_s) ++j;
    if (j > k_end) break;
    if (gaps[j - k0] != gaps[i - k0]) continue;
    const double reach = arc[j - k0] - arc[i - k0];
    if (reach >= 0.1 * span_s) h.reach_m.push_back(reach);
    const auto mi = MagnetometerNear(imu, i), mj = MagnetometerNear(imu, j);
    if (mi && mj) {
      h.field_turn_rad.push_back(NormalizeAngle(FieldDirection(c, *mj) - FieldDirection(c, *mi)));
    }
  }
  return h;
}

// The RMS of angles about their median (the learnt σ of both magnetic factors).
double AngleSpreadAboutMedian(const std::vector<double>& angles) {
  const double med = internal::Median(angles);
  double sum2 = 0.0;
  for (double x : angles) sum2 += std::pow(NormalizeAngle(x - med), 2);
  return std::sqrt(sum2 / static_cast<double>(angles.size()));
}

// The yaw tie and the reach bound across an IMU gap between a and b (see the options).
std::vector<InsFactor> GapFactors(const InsGraphContext& c, InsState* a, InsState* b) {
  const InsGraphOptions& o = c.options;
  const std::vector<ImuSample>& imu = c.walk->imu;
  std::vector<InsFactor> out;
  if (!(o.use_gap_reach || o.use_gap_magnetometer) || c.path == nullptr ||
      c.path->size() != imu.size()) {
    return out;
  }
  const GapHistory h = LearnGapHistory(c, a->imu_index, b->t_s - a->t_s);
  const size_t enough = static_cast<size_t>(o.gap_min_spans);
  if (o.use_gap_reach && h.reach_m.size() >= enough) {
    std::vector<double> r = h.reach_m;
    std::sort(r.begin(), r.end());
    const double reach = r[r.size() * 9 / 10], med = r[r.size() / 2];  // as internal::Median
    for (double& x : r) x = std::fabs(x - med);
    const double sigma = std::max(1.4826 * internal::Median(r), 0.05 * reach + 0.05);
    out.push_back(MakeFactor(InsFactorKind::kGapReach, GapReachFactor::Create(reach, sigma),
                             {a->p.data(), b->p.data()}));
  }
  const auto ma = MagnetometerNear(imu, a->imu_index), mb = MagnetometerNear(imu, b->imu_index);
  if (o.use_gap_magnetometer && ma && mb && h.field_turn_rad.size() >= enough) {
    const double sigma =
        std::max(AngleSpreadAboutMedian(h.field_turn_rad), o.gap_magnetic_min_sigma_rad);
    out.push_back(
        MakeFactor(InsFactorKind::kGapMagneticHeading,
                   MagneticHeadingChangeFactor::Create(imu[*ma].mag_ut, imu[*mb].mag_ut, sigma),
                   {a->q.data(), b->q.data()}));
    out.back().loss = internal::MakeLoss(LossKind::kCauchy, 1.0);
  }
  return out;
}

// Whether a field vector in the navigation frame has a horizontal direction to read: at least
// 5 % of its magnitude (a dip under ~87°; not a zero reading), where atan2 and its derivatives
// are well defined.
bool HasHorizontalDirection(const Eigen::Vector3d& f) {
  const double n = f.norm();
  return std::isfinite(n) && n > 0 && f.head<2>().norm() >= 0.05 * n;
}

// σ of the stance magnetic heading factor from the field turns of the pairs seen so far: their
// RMS about the median, ÷√2 (either end of a pair disturbed), at least min_sigma.
double StanceMagneticSigma(const std::vector<double>& turns, double min_sigma) {
  return std::max(AngleSpreadAboutMedian(turns) / std::sqrt(2.0), min_sigma);
}

}  // namespace

std::vector<double> StanceMagneticSigmas(const Walk& walk, const ZuptInsSolution& front,
                                         const InsGraphOptions& o) {
  const std::vector<ImuSample>& imu = walk.imu;
  std::vector<double> sigma(imu.size(), std::numeric_limits<double>::quiet_NaN());
  if (!o.use_stance_magnetometer || front.states.size() != imu.size()) return sigma;
  struct Seen {
    double t_s;
    Eigen::Vector2d p;
    double field_rad;
  };
  std::vector<Seen> seen;     // stances with a reading, in time order
  std::vector<double> turns;  // the field's turn of each pair so far
  double current = std::numeric_limits<double>::quiet_NaN();
  size_t learnt_from = 0;  // σ is relearnt each time the pairs double (n log n in all)
  std::optional<Eigen::Vector2d> last_used;  // where the last factor's stance was
  for (const StancePhase& ph : front.phases) {
    const size_t m = MidStance(front, ph);
    const std::optional<size_t> k = MagnetometerNear(imu, m);
    if (!k) continue;
    const Eigen::Vector3d f = front.states[*k].q_nb * imu[*k].mag_ut;
    if (!HasHorizontalDirection(f)) continue;
    const Seen now{imu[m].t_s, front.states[m].p_n.head<2>(), std::atan2(f.y(), f.x())};
    for (size_t j = seen.size();
         j-- > 0 && now.t_s - seen[j].t_s <= o.stance_magnetic_pair_max_s;) {
      if ((now.p - seen[j].p).norm() >= o.stance_magnetic_spacing_m) {
        turns.push_back(NormalizeAngle(now.field_rad - seen[j].field_rad));
        break;
      }
    }
    seen.push_back(now);
    const size_t enough = static_cast<size_t>(o.stance_magnetic_min_pairs);
    if (turns.size() >= std::max(enough, 2 * learnt_from)) {
      current = StanceMagneticSigma(turns, o.stance_magnetic_min_sigma_rad);
      learnt_from = turns.size();
    }
    if (!std::isfinite(current)) continue;
    if (last_used && (now.p - *last_used).norm() < o.stance_magnetic_spacing_m) continue;
    last_used = now.p;
    for (size_t i = ph.begin; i <= ph.end && i < sigma.size(); ++i) sigma[i] = current;
  }
  return sigma;
}

void AddStanceMagneticDiagnostics(const std::vector<double>& sigma, size_t factors,
                                  std::map<std::string, double>* diagnostics) {
  (*diagnostics)["num_stance_magnetic_factors"] = static_cast<double>(factors);
  for (size_t i = sigma.size(); i-- > 0;) {
    if (std::isfinite(sigma[i])) {
      (*diagnostics)["stance_magnetic_sigma_rad"] = sigma[i];
      break;
    }
  }
}

std::vector<InsFactor> InsStanceMagneticFactors(const InsGraphContext& c,
                                                std::vector<InsState>* states, size_t k, size_t n,
                                                InsSharedBlocks* blocks) {
  std::vector<InsFactor> out;
  const std::vector<double>* sigma = c.stance_magnetic_sigma;
  const std::vector<ImuSample>& imu = c.walk->imu;
  if (sigma == nullptr || sigma->size() != imu.size()) return out;
  auto has_sigma = [&](size_t i) { return std::isfinite((*sigma)[i]); };
  for (size_t j = (k == 0 ? 0 : k + 1); j <= k + n && j < states->size(); ++j) {
    InsState& s = (*states)[j];
    if (!s.zupt || !has_sigma(s.imu_index)) continue;
    // One factor per stance: a state after another inside the same stance (a standstill's
    // extra states) would count that spot's disturbance again.
    if (j > 0) {
      size_t i = (*states)[j - 1].imu_index;
      while (i < s.imu_index && has_sigma(i)) ++i;
      if ((*states)[j - 1].zupt && i == s.imu_index) continue;
    }
    const std::optional<size_t> m = MagnetometerNear(imu, s.imu_index);
    if (!m) continue;
    const Eigen::Vector3d f = s.attitude().normalized() * imu[*m].mag_ut;
    if (!HasHorizontalDirection(f)) continue;
    if (!blocks->field_yaw_set) {
      blocks->field_yaw_rad = std::atan2(f.y(), f.x());
      blocks->field_yaw_set = true;
    }
    out.push_back(MakeFactor(InsFactorKind::kStanceMagneticHeading,
                             MagneticHeadingFactor::Create(imu[*m].mag_ut, (*sigma)[s.imu_index]),
                             {s.q.data(), &blocks->field_yaw_rad}));
    out.back().loss = internal::MakeLoss(LossKind::kCauchy, 1.0);
  }
  return out;
}

StatusOr<std::vector<InsFactor>> InsBetweenFactors(const InsGraphContext& c, InsState* a,
                                                   InsState* b) {
  const std::vector<ImuSample>& imu = c.walk->imu;
  const InsGraphOptions& o = c.options;
  if (!(a->imu_index < b->imu_index) || b->imu_index >= imu.size()) {
    return InvalidArgument("fg-ins-batch: states must be in IMU order inside the walk");
  }
  const Eigen::Vector3d bg = a->gyro_bias(), ba = a->acc_bias();
  ImuPreintegration pim(bg, ba, o.front_end.gyro_noise_radps, o.front_end.acc_noise_mps2);
  const double scale_noise = ScaleNoiseAt(c, a->imu_index);
  pim.SetScaleNoise(scale_noise, scale_noise);
  bool spans_gap = false;
  for (size_t k = a->imu_index + 1; k <= b->imu_index; ++k) {
    const double dt = imu[k].t_s - imu[k - 1].t_s;
    if (dt > c.imu_gap_s) {
      // An IMU gap: nothing to integrate. The mean is rest (no rotation, the specific force
      // that cancels gravity at a's attitude); the uncertainty is a walker's: any rotation,
      // kImuGapSpeedMps of velocity and kImuGapSpeedMps × dt of position per axis.
      const Eigen::Vector3d up_body = (a->attitude() * pim.delta_q()).conjugate() *
                                      Eigen::Vector3d(0.0, 0.0, o.front_end.gravity_mps2);
      pim.Integrate(dt, bg, ba + up_body);
      ImuPreintegration::Matrix9d q = ImuPreintegration::Matrix9d::Zero();
      q.diagonal() << kPi * kPi, kPi * kPi, kPi * kPi,
          Eigen::Vector3d::Constant(kImuGapSpeedMps * kImuGapSpeedMps),
          Eigen::Vector3d::Constant(std::pow(kImuGapSpeedMps * dt, 2));
      pim.AddCovariance(q);
      spans_gap = true;
      continue;
    }
    if (o.front_end.sampling == ImuSampling::kIntervalAverage) {
      pim.Integrate(dt, imu[k].gyro_radps, imu[k].acc_mps2);
    } else {
      // Point samples: the trapezoid of strapdown.h in the frame of t_{k−1} (coning omitted).
      const Eigen::Vector3d w = 0.5 * (imu[k - 1].gyro_radps + imu[k].gyro_radps);
      const Eigen::Matrix3d e = QuaternionExp((w - bg) * dt).toRotationMatrix();
      const Eigen::Vector3d f =
          0.5 * ((imu[k - 1].acc_mps2 - ba) + e * (imu[k].acc_mps2 - ba)) + ba;
      pim.Integrate(dt, w, f);
    }
  }
  std::vector<InsFactor> out;
  out.push_back(MakeFactor(InsFactorKind::kImu,
                           ImuPreintegrationFactor::Create(pim, o.front_end.gravity_mps2),
                           {a->p.data(), a->v.data(), a->q.data(), a->bg.data(), a->ba.data(),
                            b->p.data(), b->v.data(), b->q.data()}));
  const double dt = b->t_s - a->t_s;
  out.push_back(MakeFactor(InsFactorKind::kBiasRwGyro,
                           BiasRandomWalkFactor::Create(o.front_end.gyro_bias_rw_radps_sqrts, dt),
                           {a->bg.data(), b->bg.data()}));
  out.push_back(MakeFactor(InsFactorKind::kBiasRwAcc,
                           BiasRandomWalkFactor::Create(o.front_end.acc_bias_rw_mps2_sqrts, dt),
                           {a->ba.data(), b->ba.data()}));
  if (spans_gap) {
    for (InsFactor& f : GapFactors(c, a, b)) out.push_back(std::move(f));
  }
  if (o.use_zaru && c.still != nullptr && c.still->size() == imu.size()) {
    Eigen::Vector3d sum = Eigen::Vector3d::Zero();
    int m = 0;
    for (size_t k = a->imu_index + 1; k <= b->imu_index; ++k) {
      if (!(*c.still)[k]) continue;
      sum += imu[k].gyro_radps;
      ++m;
    }
    if (m > 0) {
      out.push_back(MakeFactor(
          InsFactorKind::kZaru,
          ZaruFactor::Create(sum / m, o.zaru_sigma_radps / std::sqrt(static_cast<double>(m))),
          {b->bg.data()}));
    }
  }
  return out;
}

std::vector<InsFactor> InsGaugeFactors(const InsGraphContext& c, InsState* first) {
  const InsGraphOptions& o = c.options;
  std::vector<InsFactor> out;
  Eigen::Vector3d p0 = first->position(), sigma_p = Eigen::Vector3d::Constant(o.gauge_sigma_m);
  double yaw0 = QuaternionYaw(first->attitude()), sigma_yaw = o.gauge_sigma_yaw_rad;
  if (c.walk->meta.initial_pose) {
    const InitialPose& ip = *c.walk->meta.initial_pose;
    p0 = Eigen::Vector3d(ip.x_m, ip.y_m, 0.0);
    sigma_p = Eigen::Vector3d(ip.sigma_xy_m, ip.sigma_xy_m, o.initial_sigma_z_m);
    if (ip.heading_known) {
      yaw0 = ip.heading_rad;
      sigma_yaw = ip.sigma_heading_rad;
    } else {
      sigma_yaw = kUnknownHeadingSigmaRad;  // position-only start
    }
  }
  // Without a known start but with radio, the anchors fix the gauge.
  if (c.walk->meta.initial_pose || !HasRadio(c)) {
    out.push_back(MakeFactor(InsFactorKind::kPrior,
                             InsPriorFactor::Create(p0, sigma_p, yaw0, sigma_yaw),
                             {first->p.data(), first->q.data()}));
  }
  if (o.use_bias_prior) {
    out.push_back(MakeFactor(
        InsFactorKind::kBiasPriorGyro,
        BiasPriorFactor::Create(Eigen::Vector3d::Zero(), o.front_end.gyro_bias_sigma_radps),
        {first->bg.data()}));
    out.push_back(MakeFactor(
        InsFactorKind::kBiasPriorAcc,
        BiasPriorFactor::Create(Eigen::Vector3d::Zero(), o.front_end.acc_bias_sigma_mps2),
        {first->ba.data()}));
  }
  if (o.use_zaru && c.still != nullptr && c.still->size() == c.walk->imu.size() &&
      (*c.still)[first->imu_index]) {
    out.push_back(
        MakeFactor(InsFactorKind::kZaru,
                   ZaruFactor::Create(c.walk->imu[first->imu_index].gyro_radps, o.zaru_sigma_radps),
                   {first->bg.data()}));
  }
  return out;
}

StatusOr<std::vector<InsFactor>> InsSegmentFactors(const InsGraphContext& c,
                                                   std::vector<InsState>* states, size_t k,
                                                   size_t n) {
  if (k + n >= states->size()) return InvalidArgument("fg-ins-batch: segment beyond the states");
  std::vector<InsFactor> out;
  auto append = [&out](std::vector<InsFactor> more) {
    for (InsFactor& f : more) out.push_back(std::move(f));
  };
  if (k == 0) {
    append(InsGaugeFactors(c, &(*states)[0]));
    append(InsStateFactors(c, &(*states)[0]));
  }
  for (size_t j = k + 1; j <= k + n; ++j) {
    WG_ASSIGN_OR_RETURN(std::vector<InsFactor> between,
                        InsBetweenFactors(c, &(*states)[j - 1], &(*states)[j]));
    append(std::move(between));
    append(InsStateFactors(c, &(*states)[j]));
  }
  return out;
}

namespace {

// Where a reading at time t is received: the bracketing states of states[k..k+n] and α along
// the front end's path (see the top of ins_graph.h); b null: at a alone.
struct Where {
  InsState* a;
  InsState* b;
  double alpha;
};
Where ReceiverAt(const InsGraphContext& c, std::vector<InsState>* states, size_t k, size_t n,
                 double t) {
  const Walk& w = *c.walk;
  size_t j =
      static_cast<size_t>(std::upper_bound(states->begin() + static_cast<long>(k),
                                           states->begin() + static_cast<long>(k + n + 1), t,
                                           [](double x, const InsState& s) { return x < s.t_s; }) -
                          states->begin());
  if (j == 0) j = 1;
  if (j > k + n) return {&(*states)[k + n], nullptr, 0.0};
  InsState* a = &(*states)[j - 1];
  InsState* b = &(*states)[j];
  double alpha = (t - a->t_s) / (b->t_s - a->t_s);
  // Across an IMU gap the front end's path stands still: it says nothing of the progress there,
  // so a segment that spans a gap interpolates by time (the bridge's own assumption).
  bool spans_gap = false;
  for (size_t m = a->imu_index + 1; m <= b->imu_index && !spans_gap; ++m) {
    spans_gap = w.imu[m].t_s - w.imu[m - 1].t_s > c.imu_gap_s;
  }
  if (!spans_gap && c.path != nullptr && c.path->size() == w.imu.size()) {
    const Eigen::Vector3d pa = (*c.path)[a->imu_index].p_n, pb = (*c.path)[b->imu_index].p_n;
    const Eigen::Vector3d d = pb - pa;
    if (d.squaredNorm() > 1e-4) {
      // The IMU sample at or after t.
      size_t m = a->imu_index;
      while (m < b->imu_index && w.imu[m].t_s < t) ++m;
      alpha = ((*c.path)[m].p_n - pa).dot(d) / d.squaredNorm();
    }
  }
  alpha = std::clamp(alpha, 0.0, 1.0);
  if (alpha < 1e-3) return {a, nullptr, 0.0};
  if (alpha > 1.0 - 1e-3) return {b, nullptr, 0.0};
  return {a, b, alpha};
}

}  // namespace

PathLossMode ResolveInsPathLoss(const InsGraphOptions& o, const RadioDefaults& radio) {
  if (o.path_loss != PathLossMode::kAuto) return o.path_loss;
  return radio.calibrated ? PathLossMode::kFixed : PathLossMode::kGlobal;
}

namespace {

// The path-loss block an RSS reading of anchor `id` uses: the walk's, or (hierarchical) the
// anchor's own, created at the mean's value and tied to it on first use.
double* PathLossBlock(const InsGraphOptions& o, int id, InsSharedBlocks* blocks,
                      std::vector<InsFactor>* out) {
  if (!blocks->per_anchor_path_loss) return blocks->path_loss.data();
  auto [it, created] = blocks->anchor_path_loss.emplace(id, blocks->path_loss);
  if (blocks->anchor_path_loss_prior_added.insert(id).second) {
    out->push_back(MakeFactor(
        InsFactorKind::kPathLossSpread,
        DifferencePriorFactor<2>::Create(Eigen::Vector2d(o.A_spread_prior_db, o.eta_spread_prior)),
        {it->second.data(), blocks->path_loss.data()}));
  }
  (void)created;
  return it->second.data();
}

// The position block of a not-surveyed anchor (walk.h Anchor), created at its position in the
// walk (an unknown one: where fg-ins-batch's search placed it) on first use; an uncertain one's
// prior N(position, sigma_m²) per axis once per problem.
double* AnchorPositionBlock(const Anchor& a, InsSharedBlocks* blocks, std::vector<InsFactor>* out) {
  auto [it, created] = blocks->anchor_position.emplace(
      a.id, std::array<double, 2>{a.position_m.x(), a.position_m.y()});
  (void)created;
  if (a.position_known && a.sigma_m > 0.0 &&
      blocks->anchor_position_prior_added.insert(a.id).second) {
    out->push_back(MakeFactor(
        InsFactorKind::kAnchorPrior,
        new ceres::NormalPrior(Eigen::Matrix2d::Identity() / a.sigma_m, a.position_m.head<2>()),
        {it->second.data()}));
  }
  return it->second.data();
}

}  // namespace

StatusOr<std::vector<InsFactor>> InsRadioFactors(const InsGraphContext& c,
                                                 std::vector<InsState>* states, size_t k, size_t n,
                                                 InsSharedBlocks* blocks) {
  if (k + n >= states->size()) return InvalidArgument("fg-ins-batch: segment beyond the states");
  const Walk& w = *c.walk;
  const InsGraphOptions& o = c.options;
  std::vector<InsFactor> out;
  const double t_lo = (*states)[k].t_s, t_hi = (*states)[k + n].t_s;
  auto inside = [&](double t) { return (t > t_lo || (k == 0 && t == t_lo)) && t <= t_hi; };
  auto where = [&](double t) { return ReceiverAt(c, states, k, n, t); };
  const Eigen::Vector3d lower(0.0, 0.0, o.receiver_offset_z_m);
  if (UsesRss(c)) {
    const RadioDefaults& radio = w.meta.radio;
    if (!blocks->path_loss_set) {
      blocks->path_loss = {radio.path_loss.A_dbm, radio.path_loss.eta};
      blocks->path_loss_set = true;
    }
    const PathLossMode model = ResolveInsPathLoss(o, radio);
    blocks->estimate_path_loss = model != PathLossMode::kFixed;
    blocks->per_anchor_path_loss = model == PathLossMode::kHierarchical;
    if (blocks->estimate_path_loss && !blocks->path_loss_prior_added) {
      blocks->path_loss_prior_added = true;
      out.push_back(MakeFactor(
          InsFactorKind::kPathLossPrior,
          new ceres::NormalPrior(
              Eigen::Vector2d(1.0 / o.A_prior_sigma_db, 1.0 / o.eta_prior_sigma).asDiagonal(),
              Eigen::Vector2d(radio.path_loss.A_dbm, radio.path_loss.eta)),
          {blocks->path_loss.data()}));
    }
    for (const RssSample& r : w.rss) {
      if (!inside(r.t_s)) continue;
      const int ai = w.AnchorIndex(r.anchor_id);
      if (ai < 0) return InvalidArgument("fg-ins-batch: rss from an unknown anchor");
      RssFactor<3>::Reading reading;
      reading.rss = r.rss;
      reading.anchor_m = w.anchors[static_cast<size_t>(ai)].position_m - lower;
      reading.sigma_db = radio.path_loss.sigma_db;
      reading.sign = radio.units == RssUnits::kRfcode ? -1.0 : 1.0;
      reading.d0_m = radio.path_loss.d0_m;
      double* path_loss = PathLossBlock(o, r.anchor_id, blocks, &out);
      const Where at = where(r.t_s);
      const Anchor& anchor = w.anchors[static_cast<size_t>(ai)];
      InsFactor f;
      if (!anchor.surveyed()) {  // its position a state (AnchorRssFactor: x, y unused here)
        double* position = AnchorPositionBlock(anchor, blocks, &out);
        f = at.b == nullptr ? MakeFactor(InsFactorKind::kRss, AnchorRssFactor<3>::Create(reading),
                                         {at.a->p.data(), position, path_loss})
                            : MakeFactor(InsFactorKind::kRss,
                                         AnchorRssFactor<3>::CreateInterpolated(reading, at.alpha),
                                         {at.a->p.data(), at.b->p.data(), position, path_loss});
      } else if (at.b == nullptr) {
        f = MakeFactor(InsFactorKind::kRss, RssFactor<3>::Create(reading),
                       {at.a->p.data(), path_loss});
      } else {
        f = MakeFactor(InsFactorKind::kRss, RssFactor<3>::CreateInterpolated(reading, at.alpha),
                       {at.a->p.data(), at.b->p.data(), path_loss});
      }
      f.anchor_id = r.anchor_id;
      f.loss = internal::MakeLoss(o.rss_loss, o.rss_loss_scale);
      out.push_back(std::move(f));
    }
  }
  if (UsesRanges(c)) {
    for (const RangeSample& r : w.ranges) {
      if (!inside(r.t_s)) continue;
      const int ai = w.AnchorIndex(r.anchor_id);
      if (ai < 0) return InvalidArgument("fg-ins-batch: range from an unknown anchor");
      const Eigen::Vector3d anchor = w.anchors[static_cast<size_t>(ai)].position_m - lower;
      double* bias = &blocks->range_bias_m[r.anchor_id];
      if (o.estimate_range_bias && blocks->bias_prior_added.insert(r.anchor_id).second) {
        out.push_back(MakeFactor(
            InsFactorKind::kRangeBiasPrior,
            new ceres::NormalPrior(Eigen::MatrixXd::Constant(1, 1, 1.0 / o.range_bias_sigma_m),
                                   Eigen::VectorXd::Zero(1)),
            {bias}));
      }
      const double sigma = w.meta.radio.range_sigma_m;
      const Where at = where(r.t_s);
      const Anchor& record = w.anchors[static_cast<size_t>(ai)];
      InsFactor f;
      if (!record.surveyed()) {  // its position a state, the range scale held at 0
        double* position = AnchorPositionBlock(record, blocks, &out);
        double* scale = &blocks->zero_range_scale;
        f = at.b == nullptr
                ? MakeFactor(InsFactorKind::kRange,
                             AnchorRangeFactor<3>::Create(r.range_m, anchor.z(), sigma, 0.0),
                             {at.a->p.data(), position, bias, scale})
                : MakeFactor(InsFactorKind::kRange,
                             AnchorRangeFactor<3>::CreateInterpolated(r.range_m, anchor.z(), sigma,
                                                                      at.alpha, 0.0),
                             {at.a->p.data(), at.b->p.data(), position, bias, scale});
      } else if (at.b == nullptr) {
        f = MakeFactor(InsFactorKind::kRange, RangeFactor<3>::Create(r.range_m, anchor, sigma),
                       {at.a->p.data(), bias});
      } else {
        f = MakeFactor(InsFactorKind::kRange,
                       RangeFactor<3>::CreateInterpolated(r.range_m, anchor, sigma, at.alpha),
                       {at.a->p.data(), at.b->p.data(), bias});
      }
      f.loss = internal::MakeLoss(o.range_loss, o.range_loss_scale);
      out.push_back(std::move(f));
    }
  }
  for (const Waypoint& wp : w.waypoints) {  // known positions of the foot
    if (!inside(wp.t_s)) continue;
    const Where at = where(wp.t_s);
    out.push_back(at.b == nullptr
                      ? MakeFactor(InsFactorKind::kWaypoint,
                                   PositionPriorFactor<3>::Create(wp.position_m, wp.sigma_m),
                                   {at.a->p.data()})
                      : MakeFactor(InsFactorKind::kWaypoint,
                                   PositionPriorFactor<3>::CreateInterpolated(wp.position_m,
                                                                              wp.sigma_m, at.alpha),
                                   {at.a->p.data(), at.b->p.data()}));
  }
  return out;
}

void AddInsPathLossDiagnostics(const Walk& walk, const InsSharedBlocks& blocks,
                               std::map<std::string, double>* d) {
  if (!walk.has_rss() || !blocks.path_loss_set) return;
  (*d)["path_loss_estimated"] = blocks.estimate_path_loss ? 1.0 : 0.0;
  if (!blocks.estimate_path_loss) return;
  (*d)["path_loss_A"] = blocks.path_loss[0];
  (*d)["path_loss_eta"] = blocks.path_loss[1];
  for (const auto& [id, v] : blocks.anchor_path_loss) {
    (*d)["path_loss_A." + std::to_string(id)] = v[0];
    (*d)["path_loss_eta." + std::to_string(id)] = v[1];
  }
}

}  // namespace walkgraph
