#include <cmath>

#include "walkgraph/angle.h"
#include "simulate/sim_models.h"

namespace walkgraph {
namespace sim {

namespace {

uint64_t SplitMix64(uint64_t x) {
  x += 0x9e3779b97f4a7c15ULL;
  x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ULL;
  x = (x ^ (x >> 27)) * 0x94d049bb133111ebULL;
  return x ^ (x >> 31);
}

}  // namespace

Rng::Rng(uint64_t seed) : seed_(seed), engine_(SplitMix64(seed)) {}

double Rng::Uniform() {
  // 53 random bits → [0, 1), independent of the standard library's distributions.
  return static_cast<double>(engine_() >> 11) * (1.0 / 9007199254740992.0);
}

double Rng::Gaussian() {
  const double u1 = 1.0 - Uniform();  // (0, 1]
  const double u2 = Uniform();
  return std::sqrt(-2.0 * std::log(u1)) * std::cos(2.0 * kPi * u2);
}

double Rng::Exponential(double mean) { return -mean * std::log(1.0 - Uniform()); }

Rng Rng::Fork(uint64_t stream) const {
  return Rng(SplitMix64(seed_ ^ SplitMix64(stream + 0x632be59bd9b4e019ULL)));
}

}  // namespace sim
}  // namespace walkgraph
