#include "smoothers/anchor_search.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include <Eigen/Eigenvalues>

namespace walkgraph::internal {

const char* ToString(AnchorSearchResult::Verdict v) {
  switch (v) {
    case AnchorSearchResult::Verdict::kPlaced:
      return "placed";
    case AnchorSearchResult::Verdict::kFewReadings:
      return "few_readings";
    case AnchorSearchResult::Verdict::kNarrowGeometry:
      return "narrow_geometry";
    case AnchorSearchResult::Verdict::kAmbiguous:
      return "ambiguous";
  }
  return "?";
}

namespace {

// The readings of one search, laid out for CellCost's array arithmetic (Eigen vectorizes it:
// the logarithms of every reading of a cell at once).
struct Readings {
  Eigen::ArrayXd qx, qy, v;
  Readings(const std::vector<Eigen::Vector2d>& q, const std::vector<double>& values)
      : qx(q.size()), qy(q.size()), v(q.size()) {
    for (size_t i = 0; i < q.size(); ++i) {
      qx[static_cast<Eigen::Index>(i)] = q[i].x();
      qy[static_cast<Eigen::Index>(i)] = q[i].y();
      v[static_cast<Eigen::Index>(i)] = values[i];
    }
  }
};

// The cost C(a) of the top of anchor_search.h; `r` and `sorted` are reused between cells.
// log10(d/d0) as 0.5·ln(d²)/ln 10 − log10(d0), and the Cauchy ρ's log1p(x) as ln(1 + x): the
// vectorized logarithm (its error, ~1e-16 of a term, is far below any cost gap).
double CellCost(const Eigen::Vector2d& a, const Readings& q, const AnchorSearchOptions& o,
                Eigen::ArrayXd* r, std::vector<double>* sorted) {
  const Eigen::Index n = q.v.size();
  *r = (q.qx - a.x()).square() + (q.qy - a.y()).square() + (o.dz_m * o.dz_m + 1e-6);  // d²
  if (o.range) {
    *r = q.v - (1.0 + o.range_scale) * r->sqrt();
  } else {
    const double k = o.sign * 10.0 * o.eta;
    *r = q.v + (0.5 * k / std::log(10.0)) * r->log() - k * std::log10(o.d0_m);
  }
  // The level (bias b or transmit power A) that explains the readings best, robustly.
  double level = o.level_prior, cost = 0.0;
  if (o.level_prior_sigma > 0.0) {
    sorted->assign(r->data(), r->data() + n);
    std::nth_element(sorted->begin(), sorted->begin() + n / 2, sorted->end());
    level = (*sorted)[static_cast<size_t>(n / 2)];
    const double e = (level - o.level_prior) / o.level_prior_sigma;
    cost = e * e;
  }
  const double c2 = o.loss_scale * o.loss_scale;  // Cauchy: ρ(e²) = c²·log(1 + e²/c²)
  const double w = 1.0 / (o.sigma * o.sigma * c2);
  return cost + c2 * (1.0 + w * (*r - level).square()).log().sum();
}

// The grid's step: step_m, coarsened where the extent (m, both axes) would need more than
// kMaxGridCells cells or more than kMaxGridWork cell-reading evaluations (a path spread over
// kilometres, e.g. a diverged window, or a config's wide margin); our bounds: a few seconds
// and a few MB per search at most.
constexpr double kMaxGridCells = 262144.0, kMaxGridWork = 1e8;
double GridStep(const Eigen::Vector2d& extent, size_t readings, double step_m) {
  const double cells = std::min(kMaxGridCells, kMaxGridWork / static_cast<double>(readings));
  const double area = (extent.x() + step_m) * (extent.y() + step_m);
  // nx·ny ≤ area/step² + 2(w + h)/step + 4: the third bound keeps a long thin extent's edge
  // term under cells/2.
  return std::max({step_m, std::sqrt(area / cells), 4.0 * (extent.x() + extent.y()) / cells});
}

}  // namespace

AnchorSearchResult SearchAnchor(const std::vector<Eigen::Vector2d>& receivers,
                                const std::vector<double>& values, const AnchorSearchOptions& o) {
  AnchorSearchResult out;
  out.second_cost = std::numeric_limits<double>::infinity();
  const size_t n = receivers.size();
  if (static_cast<int>(n) < std::max(o.min_readings, 3) || values.size() != n) {
    out.verdict = AnchorSearchResult::Verdict::kFewReadings;
    return out;
  }
  const auto finite = [](const Eigen::Vector2d& q) { return q.allFinite(); };
  const auto finite_value = [](double v) { return std::isfinite(v); };
  if (!std::all_of(receivers.begin(), receivers.end(), finite) ||
      !std::all_of(values.begin(), values.end(), finite_value)) {  // a diverged path
    out.verdict = AnchorSearchResult::Verdict::kAmbiguous;
    return out;
  }
  Eigen::Vector2d mean = Eigen::Vector2d::Zero();
  for (const Eigen::Vector2d& q : receivers) mean += q;
  mean /= static_cast<double>(n);
  Eigen::Matrix2d cov = Eigen::Matrix2d::Zero();
  for (const Eigen::Vector2d& q : receivers) cov += (q - mean) * (q - mean).transpose();
  cov /= static_cast<double>(n);
  out.spread_m = std::sqrt(
      std::max(0.0, Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d>(cov).eigenvalues().minCoeff()));
  if (out.spread_m < o.min_spread_m) {
    out.verdict = AnchorSearchResult::Verdict::kNarrowGeometry;
    return out;
  }
  Eigen::Vector2d lo = receivers[0], hi = receivers[0];
  for (const Eigen::Vector2d& q : receivers) {
    lo = lo.cwiseMin(q);
    hi = hi.cwiseMax(q);
  }
  lo.array() -= o.margin_m;
  hi.array() += o.margin_m;
  const double step = GridStep(hi - lo, n, o.step_m);
  const int nx = static_cast<int>(std::ceil((hi.x() - lo.x()) / step)) + 1;
  const int ny = static_cast<int>(std::ceil((hi.y() - lo.y()) / step)) + 1;
  std::vector<double> cost(static_cast<size_t>(nx) * ny);
  const Readings readings(receivers, values);
  Eigen::ArrayXd r;
  std::vector<double> sorted;
  auto cell = [&](int i, int j) { return Eigen::Vector2d(lo.x() + i * step, lo.y() + j * step); };
  int best = 0;
  for (int j = 0; j < ny; ++j) {
    for (int i = 0; i < nx; ++i) {
      const size_t c = static_cast<size_t>(j) * nx + i;
      cost[c] = CellCost(cell(i, j), readings, o, &r, &sorted);
      if (cost[c] < cost[best]) best = static_cast<int>(c);
    }
  }
  const Eigen::Vector2d coarse = cell(best % nx, best / nx);
  // The region within min_cost_gap of the best: one piece around the best cell (4-connected),
  // not reaching the grid's edge; any other cell of it farther than distinct_radius_m is another
  // place (its least cost: second_cost).
  const double limit = cost[best] + o.min_cost_gap;
  std::vector<char> seen(cost.size(), 0);
  std::vector<int> stack = {best};
  seen[best] = 1;
  bool edge = false;
  while (!stack.empty()) {
    const int c = stack.back();
    stack.pop_back();
    const int i = c % nx, j = c / nx;
    edge = edge || i == 0 || j == 0 || i == nx - 1 || j == ny - 1;
    const int next[4][2] = {{i - 1, j}, {i + 1, j}, {i, j - 1}, {i, j + 1}};
    for (const auto& ij : next) {
      if (ij[0] < 0 || ij[1] < 0 || ij[0] >= nx || ij[1] >= ny) continue;
      const int k = ij[1] * nx + ij[0];
      if (seen[k] || !(cost[k] < limit)) continue;
      seen[k] = 1;
      stack.push_back(k);
    }
  }
  // The region's spread: a uniform density over the ellipse {Δ ≤ gap} of a Gaussian cost
  // Δ = eᵀΣ⁻¹e has covariance Σ·gap/4, so Σ = 4/gap · the region's second moment (+ a cell's).
  Eigen::Vector2d sum = Eigen::Vector2d::Zero();
  Eigen::Matrix2d sum2 = Eigen::Matrix2d::Zero();
  double cells = 0.0;
  for (size_t c = 0; c < cost.size(); ++c) {
    if (!seen[c]) continue;
    const Eigen::Vector2d p = cell(static_cast<int>(c) % nx, static_cast<int>(c) / nx);
    sum += p;
    sum2 += p * p.transpose();
    cells += 1.0;
  }
  const Eigen::Vector2d mean_region = sum / cells;
  const Eigen::Matrix2d spread = sum2 / cells - mean_region * mean_region.transpose();
  out.covariance = (o.min_cost_gap > 0.0 ? 4.0 / o.min_cost_gap : 0.0) * spread +
                   Eigen::Matrix2d::Identity() * (step * step / 12.0);
  for (size_t c = 0; c < cost.size(); ++c) {
    if (seen[c] || !(cost[c] < out.second_cost)) continue;
    const int i = static_cast<int>(c) % nx, j = static_cast<int>(c) / nx;
    if ((cell(i, j) - coarse).norm() > o.distinct_radius_m) out.second_cost = cost[c];
  }
  // Refine around the best cell.
  out.position_m = coarse;
  out.cost = cost[best];
  const double fine = step / 10.0;
  for (int dj = -10; dj <= 10; ++dj) {
    for (int di = -10; di <= 10; ++di) {
      const Eigen::Vector2d a = coarse + Eigen::Vector2d(di * fine, dj * fine);
      const double c = CellCost(a, readings, o, &r, &sorted);
      if (c < out.cost) {
        out.cost = c;
        out.position_m = a;
      }
    }
  }
  if (edge || out.second_cost - out.cost < o.min_cost_gap) {
    out.verdict = AnchorSearchResult::Verdict::kAmbiguous;
  }
  return out;
}

}  // namespace walkgraph::internal
