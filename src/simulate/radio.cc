#include <algorithm>
#include <cmath>

#include "simulate/sim_models.h"

namespace walkgraph {
namespace sim {

double DetectionModel::At(double d_m) const {
  if (d50_m <= 0.0) return p_max;
  return p_max / (1.0 + std::exp((d_m - d50_m) / width_m));
}

namespace {

// Alternating LOS/NLOS intervals of one anchor over [t0, t1): a two-state Markov chain whose
// NLOS share is `fraction` and whose NLOS episodes last `mean_episode_s` on average.
std::vector<std::pair<double, double>> NlosEpisodes(const NlosOptions& o, double t0, double t1,
                                                    Rng rng) {
  std::vector<std::pair<double, double>> out;
  if (o.fraction <= 0.0) return out;
  if (o.fraction >= 1.0) return {{t0, t1}};
  const double mean_los = o.mean_episode_s * (1.0 - o.fraction) / o.fraction;
  bool nlos = rng.Bernoulli(o.fraction);
  double t = t0;
  while (t < t1) {
    const double d = rng.Exponential(nlos ? o.mean_episode_s : mean_los);
    if (nlos) out.emplace_back(t, std::min(t + d, t1));
    t += d;
    nlos = !nlos;
  }
  return out;
}

bool Inside(const std::vector<std::pair<double, double>>& windows, double t) {
  for (const auto& [a, b] : windows) {
    if (t >= a && t < b) return true;
  }
  return false;
}

double RoundTo(double v, double quantum) {
  if (quantum <= 0.0) return v;
  const double inv = std::round(1.0 / quantum);
  if (std::fabs(inv * quantum - 1.0) < 1e-12) return std::round(v * inv) / inv;
  return std::round(v / quantum) * quantum;
}

// Emission times of one anchor: random phase, fixed period, optional jitter; rounded to 1 µs
// (or up to the reader's polling grid).
std::vector<double> EmissionTimes(const RadioOptions& o, double t0, double t1, Rng* rng) {
  std::vector<double> times;
  const double phase = rng->Uniform(0.0, o.period_s);
  const double jitter = std::min(o.jitter_s, 0.45 * o.period_s);
  for (long k = 0;; ++k) {
    double t = t0 + phase + k * o.period_s;
    if (t >= t1) break;
    if (jitter > 0.0) t += rng->Uniform(-jitter, jitter);
    t = std::clamp(t, t0, t1);
    if (o.report_period_s > 0.0) {
      const double rate = 1.0 / o.report_period_s;
      t = std::ceil(t * rate - 1e-9) / rate;
    } else {
      t = std::round(t * 1e6) / 1e6;
    }
    if (!times.empty() && t <= times.back()) continue;
    times.push_back(t);
  }
  return times;
}

// Floor slabs (at f × storey) between two heights: |⌊z_a/storey⌋ − ⌊z_b/storey⌋|; 0 without
// a floor loss.
int SlabsBetween(double z_a, double z_b, const RadioOptions& o) {
  if (!(o.path_loss.floor_loss_db > 0.0)) return 0;
  const double fa = std::floor(z_a / o.storey_height_m), fb = std::floor(z_b / o.storey_height_m);
  return static_cast<int>(std::fabs(fa - fb));
}

template <typename Sample>
void SortByTime(std::vector<Sample>* v) {
  std::stable_sort(v->begin(), v->end(), [](const Sample& a, const Sample& b) {
    return a.t_s != b.t_s ? a.t_s < b.t_s : a.anchor_id < b.anchor_id;
  });
}

}  // namespace

RadioResult SimulateRss(const std::vector<Anchor>& anchors, const ReceiverTrack& rx, double t0,
                        double t1, const RadioOptions& o, Rng rng) {
  RadioResult r;
  const double sign = o.units == RssUnits::kDbm ? 1.0 : -1.0;
  for (const Anchor& anchor : anchors) {
    Rng base = rng.Fork(static_cast<uint64_t>(anchor.id));
    Rng params = base.Fork(0), noise = base.Fork(2);
    PathLossParams pl = o.path_loss;
    pl.A_dbm += params.Gaussian(0.0, o.A_spread_db);
    pl.eta = std::max(0.5, pl.eta + params.Gaussian(0.0, o.eta_spread));
    r.per_anchor.push_back(pl);
    const PathLossModel model(pl, o.units);
    const auto nlos = NlosEpisodes(o.nlos, t0, t1, base.Fork(1));
    for (double t : EmissionTimes(o, t0, t1, &noise)) {
      Emission e;
      e.t_s = t;
      e.anchor_id = anchor.id;
      const Eigen::Vector3d receiver = rx(t);
      e.distance_m = (receiver - anchor.position_m).norm();
      e.nlos = Inside(nlos, t);
      e.in_outage = Inside(o.outages_s, t);
      e.expected = model.ExpectedRss(e.distance_m) -
                   sign * pl.floor_loss_db * SlabsBetween(receiver.z(), anchor.position_m.z(), o);
      // Fixed draw order per emission keeps streams aligned whatever the outcome.
      const double shadow = noise.Gaussian(0.0, pl.sigma_db);
      const double extra = noise.Exponential(o.nlos.rss_bias_db);
      const double u = noise.Uniform();
      e.value = RoundTo(e.expected + shadow - (e.nlos ? sign * extra : 0.0), o.rss_quantum);
      const bool sensed =
          !o.use_sensitivity ||
          (o.units == RssUnits::kDbm ? e.value >= o.sensitivity : e.value <= o.sensitivity);
      e.detected = !e.in_outage && u < o.detection.At(e.distance_m) && sensed;
      if (e.detected) r.rss.push_back({t, anchor.id, e.value});
      r.emissions.push_back(e);
    }
  }
  SortByTime(&r.rss);
  return r;
}

RadioResult SimulateToa(const std::vector<Anchor>& anchors, const ReceiverTrack& rx, double t0,
                        double t1, const RadioOptions& o, Rng rng) {
  RadioResult r;
  for (const Anchor& anchor : anchors) {
    Rng base = rng.Fork(static_cast<uint64_t>(anchor.id));
    Rng noise = base.Fork(3);
    const auto nlos = NlosEpisodes(o.nlos, t0, t1, base.Fork(1));
    for (double t : EmissionTimes(o, t0, t1, &noise)) {
      Emission e;
      e.t_s = t;
      e.anchor_id = anchor.id;
      e.distance_m = (rx(t) - anchor.position_m).norm();
      e.nlos = Inside(nlos, t);
      e.in_outage = Inside(o.outages_s, t);
      e.expected = o.toa_alpha_m + o.toa_beta * e.distance_m;  // 002 eq. 6
      const double n = noise.Gaussian(0.0, o.toa_sigma_m);
      const double extra = noise.Exponential(o.nlos.range_bias_m);
      const double u = noise.Uniform();
      e.value = std::max(0.0, std::round((e.expected + n + (e.nlos ? extra : 0.0)) * 1e3) / 1e3);
      e.detected = !e.in_outage && u < o.detection.At(e.distance_m);
      if (e.detected) r.ranges.push_back({t, anchor.id, e.value});
      r.emissions.push_back(e);
    }
  }
  SortByTime(&r.ranges);
  return r;
}

std::vector<Anchor> GridAnchors(int n, double x0, double y0, double w, double h, double z) {
  int rows = 1;
  for (int r = 1; r * r <= n; ++r) {
    if (n % r == 0) rows = r;
  }
  const int cols = n / rows;
  std::vector<Anchor> out;
  for (int i = 0; i < rows; ++i) {
    for (int j = 0; j < cols; ++j) {
      Anchor a;
      a.id = static_cast<int>(out.size()) + 1;
      const double x = cols > 1 ? x0 + w * j / (cols - 1) : x0 + 0.5 * w;
      const double y = rows > 1 ? y0 + h * i / (rows - 1) : y0 + 0.5 * h;
      a.position_m = Eigen::Vector3d(x, y, z);
      out.push_back(a);
    }
  }
  return out;
}

std::vector<Anchor> SpreadSubset(const std::vector<Anchor>& all, int count) {
  std::vector<Anchor> out;
  if (all.empty() || count <= 0) return out;
  std::vector<double> dmin(all.size(), 1e300);
  size_t next = 0;
  while (static_cast<int>(out.size()) < std::min<int>(count, all.size())) {
    out.push_back(all[next]);
    for (size_t i = 0; i < all.size(); ++i) {
      dmin[i] = std::min(dmin[i], (all[i].position_m - all[next].position_m).norm());
    }
    next = std::max_element(dmin.begin(), dmin.end()) - dmin.begin();
  }
  std::sort(out.begin(), out.end(), [](const Anchor& a, const Anchor& b) { return a.id < b.id; });
  return out;
}

}  // namespace sim
}  // namespace walkgraph
