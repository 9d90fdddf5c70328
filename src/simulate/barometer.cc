#include <cmath>

#include "simulate/sim_models.h"
#include "walkgraph/barometric.h"

namespace walkgraph {
namespace sim {

BarometerResult SimulateBarometer(const std::function<double(double t_s)>& height_m,
                                  double t_begin_s, double t_end_s, const BarometerOptions& o,
                                  Rng rng) {
  BarometerResult r;
  Rng trend = rng.Fork(1), walk = rng.Fork(2), noise = rng.Fork(3);
  r.drift_rate_hpa_per_h = trend.Bernoulli(0.5) ? o.drift_hpa_per_h : -o.drift_hpa_per_h;
  double rw = 0.0, prev_t = t_begin_s;
  for (long k = static_cast<long>(std::ceil(t_begin_s * o.rate_hz - 1e-9));; ++k) {
    const double t = static_cast<double>(k) / o.rate_hz;
    if (t > t_end_s + 1e-9) break;
    rw += walk.Gaussian(0.0, o.drift_rw_hpa_per_sqrt_h * std::sqrt((t - prev_t) / 3600.0));
    prev_t = t;
    const double drift = r.drift_rate_hpa_per_h * (t - t_begin_s) / 3600.0 + rw;
    const double hpa =
        BarometricPressureHpa(height_m(t), o.ref_hpa) + drift + noise.Gaussian(0.0, o.noise_hpa);
    r.pressure.push_back({std::round(t * 1e6) / 1e6, std::round(hpa * 1e4) / 1e4});
    r.drift_hpa.push_back(drift);
  }
  return r;
}

}  // namespace sim
}  // namespace walkgraph
