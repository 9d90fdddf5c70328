// Posterior Cramér–Rao bound: per-walk Fisher information, the Tichavský recursion and the
// sparse full-walk smoothing bound (the math is at the top of walkgraph/pcrb.h).
#include "walkgraph/pcrb.h"

#include <algorithm>
#include <array>
#include <atomic>
#include <cmath>
#include <thread>

#include <Eigen/Cholesky>
#include <Eigen/SparseCholesky>

#include "config/reader.h"
#include "eval/pcrb_yaml.h"
#include "util/parallel_for.h"
#include "walkgraph/compare.h"
#include "walkgraph/config.h"
#include "walkgraph/parallel.h"

namespace walkgraph {

StatusOr<PcrbOptions> PcrbOptionsFromYaml(const YAML::Node& node, const std::string& context) {
  PcrbOptions o;
  ConfigReader r(node, context);
  r.Read("step_sigma_frac", &o.step_sigma_frac,
         "step length sigma, fraction of the length (plus step_sigma_m)");
  r.Read("step_sigma_m", &o.step_sigma_m, "step length sigma, constant part");
  r.Read("heading_sigma_rad", &o.heading_sigma_rad,
         "heading-increment sigma; lateral sigma = step length x this");
  r.Read("min_process_sigma_m", &o.min_process_sigma_m,
         "floor on the step length and lateral sigmas");
  r.Read("prior_sigma_m", &o.prior_sigma_m,
         "start position sigma; <= 0: the walk's initial_pose sigma_xy");
  r.Read("min_distance_m", &o.min_distance_m,
         "floor on the anchor distance in the radio information");
  WG_RETURN_IF_ERROR(r.Finish());
  WG_RETURN_IF_ERROR(o.Validate(context));
  return o;
}

Status PcrbOptions::Validate(const std::string& context) const {
  const PcrbOptions& o = *this;
  if (o.step_sigma_frac < 0.0 || o.step_sigma_m < 0.0 || o.heading_sigma_rad < 0.0) {
    return InvalidArgument(context + ": step_sigma_frac, step_sigma_m, heading_sigma_rad >= 0");
  }
  if (!(o.min_process_sigma_m > 0.0) || !(o.min_distance_m > 0.0)) {
    return InvalidArgument(context + ": min_process_sigma_m and min_distance_m must be > 0");
  }
  return Status::Ok();
}

namespace {

// Linear interpolation of the truth at time t (clamped to its span).
Eigen::Vector3d TruthAt(const std::vector<TruthSample>& truth, double t) {
  if (t <= truth.front().t_s) return truth.front().position_m;
  if (t >= truth.back().t_s) return truth.back().position_m;
  const auto it = std::lower_bound(truth.begin(), truth.end(), t,
                                   [](const TruthSample& s, double v) { return s.t_s < v; });
  const TruthSample& b = *it;
  const TruthSample& a = *(it - 1);
  const double w = (t - a.t_s) / (b.t_s - a.t_s);
  return (1.0 - w) * a.position_m + w * b.position_m;
}

// Fisher information of one reading about the horizontal position y (see pcrb.h):
// scale²·u uᵀ with u = (p − a)_xy / d, scale² already divided by d² for RSS.
Eigen::Matrix2d ReadingInformation(const Eigen::Vector3d& receiver, const Eigen::Vector3d& anchor,
                                   double per_unit_distance, bool rss, double min_distance_m) {
  const Eigen::Vector3d r = receiver - anchor;
  const double d = std::max(r.norm(), min_distance_m);
  const Eigen::Vector2d u = r.head<2>() / d;
  double s2 = per_unit_distance * per_unit_distance;
  if (rss) s2 /= d * d;  // ∂RSS/∂d = −10η/(d ln10)
  return s2 * u * u.transpose();
}

void AddReading(const PcrbInformation& nodes, double t, const Eigen::Matrix2d& M,
                PcrbInformation* info) {
  const std::vector<double>& ts = nodes.t_s;
  info->readings += 1.0;
  if (t <= ts.front()) {
    info->J0 += M;
    return;
  }
  const size_t hi = std::min<size_t>(
      static_cast<size_t>(std::lower_bound(ts.begin(), ts.end(), t) - ts.begin()), ts.size() - 1);
  const size_t k = hi - 1;
  const double a = std::clamp((t - ts[k]) / (ts[hi] - ts[k]), 0.0, 1.0);
  info->D11[k] += (1.0 - a) * (1.0 - a) * M;
  info->D12[k] += a * (1.0 - a) * M;
  info->D22[k] += a * a * M;
}

// Q⁻¹ = u uᵀ/σ_l² + u⊥ u⊥ᵀ/σ_c².
Eigen::Matrix2d ProcessInformation(const Eigen::Vector2d& u, double sigma_l, double sigma_c) {
  const Eigen::Vector2d n(-u.y(), u.x());
  return u * u.transpose() / (sigma_l * sigma_l) + n * n.transpose() / (sigma_c * sigma_c);
}

bool SameNodes(const PcrbInformation& a, const PcrbInformation& b) {
  if (a.t_s.size() != b.t_s.size()) return false;
  for (size_t k = 0; k < a.t_s.size(); ++k) {
    if (std::fabs(a.t_s[k] - b.t_s[k]) > 1e-9 * std::max(1.0, std::fabs(a.t_s[k]))) return false;
  }
  return true;
}

Status AddInto(const PcrbInformation& x, int run, PcrbInformation* sum) {
  if (!SameNodes(*sum, x)) {
    return FailedPrecondition("PCRB: run " + std::to_string(run) +
                              " has other node times than run 0 (" + std::to_string(x.t_s.size()) +
                              " vs " + std::to_string(sum->t_s.size()) +
                              " nodes): the Monte Carlo expectation needs one walker");
  }
  sum->J0 += x.J0;
  for (size_t k = 0; k < sum->D11.size(); ++k) {
    sum->D11[k] += x.D11[k];
    sum->D12[k] += x.D12[k];
    sum->D22[k] += x.D22[k];
  }
  sum->readings += x.readings;
  sum->runs += x.runs;
  return Status::Ok();
}

void DivideByRuns(PcrbInformation* sum) {
  const double inv = 1.0 / sum->runs;
  sum->J0 *= inv;
  for (size_t k = 0; k < sum->D11.size(); ++k) {
    sum->D11[k] *= inv;
    sum->D12[k] *= inv;
    sum->D22[k] *= inv;
  }
  sum->readings *= inv;
}

StatusOr<Eigen::Matrix2d> InverseSpd(const Eigen::Matrix2d& J, const char* what, size_t k) {
  const Eigen::Matrix2d S = 0.5 * (J + J.transpose());
  Eigen::LLT<Eigen::Matrix2d> llt(S);
  if (llt.info() != Eigen::Success) {
    return NumericalError(std::string("PCRB: ") + what +
                          " information not positive definite at node " + std::to_string(k));
  }
  Eigen::Matrix2d B = llt.solve(Eigen::Matrix2d::Identity());
  return Eigen::Matrix2d(0.5 * (B + B.transpose()));
}

// sqrt(mean over `score` of tr B(t)), tr B linear in t between nodes, clamped at the ends.
double RmseBound(const std::vector<double>& t, const std::vector<Eigen::Matrix2d>& B,
                 const std::vector<double>& score) {
  if (score.empty()) return 0.0;
  double sum = 0.0;
  for (double s : score) {
    double tr;
    if (s <= t.front()) {
      tr = B.front().trace();
    } else if (s >= t.back()) {
      tr = B.back().trace();
    } else {
      const size_t hi = static_cast<size_t>(std::lower_bound(t.begin(), t.end(), s) - t.begin());
      const double a = (s - t[hi - 1]) / (t[hi] - t[hi - 1]);
      tr = (1.0 - a) * B[hi - 1].trace() + a * B[hi].trace();
    }
    sum += tr;
  }
  return std::sqrt(sum / static_cast<double>(score.size()));
}

// Blocks (A⁻¹)_kk of the block-tridiagonal full-walk information A (2×2 blocks): sparse
// Cholesky A = L Lᵀ in the natural order (bandwidth 3, no fill outside the band), then the
// Takahashi recursion from Lᵀ Z = L⁻¹ restricted to the band:
//   Z_ij = −(1/L_jj) Σ_{m>j} L_mj Z_mi  (i > j),   Z_jj = (1/L_jj)(1/L_jj − Σ_{m>j} L_mj Z_mj).
StatusOr<std::vector<Eigen::Matrix2d>> SmoothingBlocks(const PcrbInformation& in) {
  const int n = static_cast<int>(in.t_s.size());
  const int N = 2 * n;
  std::vector<Eigen::Triplet<double>> trip;
  trip.reserve(static_cast<size_t>(12) * n);
  auto block = [&](int r, int c, const Eigen::Matrix2d& B) {
    for (int i = 0; i < 2; ++i) {
      for (int j = 0; j < 2; ++j) {
        if (B(i, j) != 0.0) trip.emplace_back(2 * r + i, 2 * c + j, B(i, j));
      }
    }
  };
  for (int k = 0; k < n; ++k) {
    Eigen::Matrix2d diag = Eigen::Matrix2d::Zero();
    if (k == 0) diag += in.J0;
    if (k < n - 1) diag += in.D11[k];
    if (k > 0) diag += in.D22[k - 1];
    // Keep the structural diagonal even where a block entry is zero.
    block(k, k, 0.5 * (diag + diag.transpose()));
    trip.emplace_back(2 * k, 2 * k, 0.0);
    trip.emplace_back(2 * k + 1, 2 * k + 1, 0.0);
    if (k < n - 1) {
      block(k + 1, k, in.D12[k].transpose());  // A_{k+1,k} = D21_k
      block(k, k + 1, in.D12[k]);
    }
  }
  Eigen::SparseMatrix<double> A(N, N);
  A.setFromTriplets(trip.begin(), trip.end());
  Eigen::SimplicialLLT<Eigen::SparseMatrix<double>, Eigen::Lower, Eigen::NaturalOrdering<int>> llt(
      A);
  if (llt.info() != Eigen::Success) {
    return NumericalError("PCRB: the full-walk information is not positive definite");
  }
  const Eigen::SparseMatrix<double> L = llt.matrixL();
  constexpr int kBand = 3;
  std::vector<std::array<double, kBand + 1>> Lb(N), Z(N);
  for (int j = 0; j < N; ++j) {
    Lb[j].fill(0.0);
    Z[j].fill(0.0);
    for (Eigen::SparseMatrix<double>::InnerIterator it(L, j); it; ++it) {
      const int o = static_cast<int>(it.row()) - j;
      if (o < 0) continue;
      if (o > kBand) return InternalError("PCRB: Cholesky factor wider than the block band");
      Lb[j][o] = it.value();
    }
    if (!(Lb[j][0] > 0.0)) return NumericalError("PCRB: zero pivot in the Cholesky factor");
  }
  auto z = [&](int i, int k) {  // Z(i, k) for |i − k| ≤ kBand, both already computed
    const int lo = std::min(i, k), hi = std::max(i, k);
    return Z[lo][hi - lo];
  };
  for (int j = N - 1; j >= 0; --j) {
    const double ljj = Lb[j][0];
    for (int o = kBand; o >= 1; --o) {
      const int i = j + o;
      if (i >= N) continue;
      double s = 0.0;
      for (int m = 1; m <= kBand && j + m < N; ++m) s += Lb[j][m] * z(i, j + m);
      Z[j][o] = -s / ljj;
    }
    double s = 0.0;
    for (int m = 1; m <= kBand && j + m < N; ++m) s += Lb[j][m] * Z[j][m];
    Z[j][0] = (1.0 / ljj - s) / ljj;
  }
  std::vector<Eigen::Matrix2d> out(n);
  for (int k = 0; k < n; ++k) {
    out[k] << Z[2 * k][0], Z[2 * k][1], Z[2 * k][1], Z[2 * k + 1][0];
  }
  return out;
}

}  // namespace

StatusOr<PcrbInformation> PcrbInformationFromSimulation(const Simulation& sim,
                                                        const PcrbOptions& o) {
  WG_RETURN_IF_ERROR(o.Validate());
  const Walk& w = sim.walk;
  if (w.meta.imu_placement == ImuPlacement::kFoot) {
    return FailedPrecondition(
        "PCRB not computed for foot-IMU walks: a ZUPT-aided foot INS drifts mainly through yaw "
        "from the gyro biases, which a per-stride planar state cannot carry (see pcrb.h)");
  }
  if (w.truth.size() < 2)
    return FailedPrecondition("PCRB: the walk needs at least 2 truth samples");
  double sigma0 = o.prior_sigma_m;
  if (!(sigma0 > 0.0)) {
    if (!w.meta.initial_pose) {
      return FailedPrecondition("PCRB: no prior_sigma_m and no initial_pose in the walk");
    }
    sigma0 = w.meta.initial_pose->sigma_xy_m;
  }
  const auto step_sigma = w.meta.extra.find("sim.step_sigma_m");
  const bool linear = sim.steps.empty() && w.has_odometry() && step_sigma != w.meta.extra.end();
  if (sim.steps.empty() && !linear) {
    return FailedPrecondition("PCRB: the simulation of '" + w.meta.name +
                              "' has no step events to place the states at");
  }

  PcrbInformation info;
  // The nodes span the truth (the walker is the same in every run; readings past the last
  // truth sample, within one IMU period, go to the last node).
  const double t0 = w.truth.front().t_s, t_end = w.truth.back().t_s;
  if (linear) {
    for (const TruthSample& s : w.truth) info.t_s.push_back(s.t_s);
  } else {
    info.t_s.push_back(t0);
    for (const sim::StepEvent& e : sim.steps) {
      if (e.t_s > info.t_s.back() + 1e-9 && e.t_s < t_end - 1e-9) info.t_s.push_back(e.t_s);
    }
    info.t_s.push_back(t_end);
  }
  const size_t n = info.t_s.size();
  if (n < 2) return FailedPrecondition("PCRB: the walk has fewer than 2 states");
  for (double t : info.t_s) info.position_m.push_back(TruthAt(w.truth, t).head<2>());
  info.J0 = Eigen::Matrix2d::Identity() / (sigma0 * sigma0);
  info.D11.assign(n - 1, Eigen::Matrix2d::Zero());
  info.D12.assign(n - 1, Eigen::Matrix2d::Zero());
  info.D22.assign(n - 1, Eigen::Matrix2d::Zero());
  for (const TruthSample& s : w.truth) info.score_t_s.push_back(s.t_s);

  // Process terms.
  const double floor = o.min_process_sigma_m;
  const double heading =
      w.meta.extra.count("sim.heading_rad") ? w.meta.extra.at("sim.heading_rad") : 0.0;
  for (size_t k = 0; k + 1 < n; ++k) {
    const Eigen::Vector2d delta = info.position_m[k + 1] - info.position_m[k];
    const double l = delta.norm();
    Eigen::Vector2d u = l > 1e-9 ? Eigen::Vector2d(delta / l)
                                 : Eigen::Vector2d(std::cos(heading), std::sin(heading));
    double sigma_l, sigma_c;
    if (linear) {
      sigma_l = std::max(step_sigma->second, floor);
      sigma_c = floor;  // the heading is known
    } else {
      sigma_l = std::max(o.step_sigma_frac * l + o.step_sigma_m, floor);
      sigma_c = std::max(l * o.heading_sigma_rad, floor);
    }
    const Eigen::Matrix2d Qi = ProcessInformation(u, sigma_l, sigma_c);
    info.D11[k] += Qi;
    info.D12[k] -= Qi;
    info.D22[k] += Qi;
  }

  // Readings.
  const bool per_anchor = sim.per_anchor.size() == w.anchors.size();
  for (const RssSample& r : w.rss) {
    const int i = w.AnchorIndex(r.anchor_id);
    if (i < 0)
      return InvalidArgument("PCRB: rss names unknown anchor " + std::to_string(r.anchor_id));
    const PathLossParams& pl = per_anchor ? sim.per_anchor[i] : w.meta.radio.path_loss;
    const double scale = 10.0 * pl.eta / (pl.sigma_db * std::log(10.0));
    AddReading(info, r.t_s,
               ReadingInformation(TruthAt(w.truth, r.t_s), w.anchors[i].position_m, scale, true,
                                  o.min_distance_m),
               &info);
  }
  const auto beta_it = w.meta.extra.find("sim.toa_beta");
  const double beta = beta_it != w.meta.extra.end() ? beta_it->second : 1.0;
  const double range_sigma = w.meta.radio.range_sigma_m;
  if (!w.ranges.empty() && !(range_sigma > 0.0)) {
    return InvalidArgument("PCRB: range readings need radio.range_sigma_m > 0");
  }
  for (const RangeSample& r : w.ranges) {
    const int i = w.AnchorIndex(r.anchor_id);
    if (i < 0) {
      return InvalidArgument("PCRB: range names unknown anchor " + std::to_string(r.anchor_id));
    }
    AddReading(info, r.t_s,
               ReadingInformation(TruthAt(w.truth, r.t_s), w.anchors[i].position_m,
                                  beta / range_sigma, false, o.min_distance_m),
               &info);
  }
  return info;
}

StatusOr<PcrbInformation> MeanPcrbInformation(const std::vector<PcrbInformation>& runs) {
  if (runs.empty()) return InvalidArgument("PCRB: no runs to average");
  PcrbInformation sum = runs.front();
  for (size_t r = 1; r < runs.size(); ++r) {
    WG_RETURN_IF_ERROR(AddInto(runs[r], static_cast<int>(r), &sum));
  }
  DivideByRuns(&sum);
  return sum;
}

StatusOr<PcrbBound> ComputePcrb(const PcrbInformation& in) {
  const size_t n = in.t_s.size();
  if (n < 2 || in.D11.size() != n - 1 || in.D12.size() != n - 1 || in.D22.size() != n - 1) {
    return InvalidArgument("PCRB: need n >= 2 nodes and n - 1 interval terms");
  }
  for (size_t k = 1; k < n; ++k) {
    if (!(in.t_s[k] > in.t_s[k - 1])) return InvalidArgument("PCRB: node times must increase");
  }
  PcrbBound out;
  out.t_s = in.t_s;
  out.runs = in.runs;
  out.readings = in.readings;
  // Filtering bound: J_{k+1} = D22 − D21 (J_k + D11)⁻¹ D12 (Tichavský et al. 1998).
  out.filter.resize(n);
  Eigen::Matrix2d J = in.J0;
  WG_ASSIGN_OR_RETURN(out.filter[0], InverseSpd(J, "prior", 0));
  for (size_t k = 0; k + 1 < n; ++k) {
    const Eigen::Matrix2d S = J + in.D11[k];
    Eigen::LLT<Eigen::Matrix2d> llt(0.5 * (S + S.transpose()));
    if (llt.info() != Eigen::Success) {
      return NumericalError("PCRB: J_k + D11 not positive definite at node " + std::to_string(k));
    }
    J = in.D22[k] - in.D12[k].transpose() * llt.solve(in.D12[k]);
    J = 0.5 * (J + J.transpose());
    WG_ASSIGN_OR_RETURN(out.filter[k + 1], InverseSpd(J, "filtering", k + 1));
  }
  WG_ASSIGN_OR_RETURN(out.smoother, SmoothingBlocks(in));
  out.filter_rmse_m = RmseBound(out.t_s, out.filter, in.score_t_s);
  out.smoother_rmse_m = RmseBound(out.t_s, out.smoother, in.score_t_s);
  return out;
}

PcrbAccumulator::PcrbAccumulator(int runs) : runs_(std::max(runs, 0)) {}

Status PcrbAccumulator::Add(int run, PcrbInformation information) {
  std::lock_guard<std::mutex> lock(mutex_);
  if (!error_.ok()) return error_;
  if (run < next_ || run >= runs_ || pending_.count(run) != 0) {
    return InvalidArgument("PCRB: run " + std::to_string(run) + " added twice or out of range");
  }
  pending_.emplace(run, std::move(information));
  for (auto it = pending_.find(next_); it != pending_.end(); it = pending_.find(next_)) {
    if (!sum_) {
      sum_ = std::move(it->second);
    } else {
      error_ = AddInto(it->second, next_, &*sum_);
      if (!error_.ok()) return error_;
    }
    pending_.erase(it);
    ++next_;
  }
  return Status::Ok();
}

StatusOr<PcrbInformation> PcrbAccumulator::Mean() const {
  std::lock_guard<std::mutex> lock(mutex_);
  if (!error_.ok()) return error_;
  if (!sum_ || next_ != runs_) {
    return FailedPrecondition("PCRB: " + std::to_string(next_) + " of " + std::to_string(runs_) +
                              " runs added");
  }
  PcrbInformation mean = *sum_;
  DivideByRuns(&mean);
  return mean;
}

StatusOr<PcrbBound> ScenarioPcrb(const std::string& scenario, const Config& config, int runs,
                                 uint64_t seed, int threads, const PcrbOptions& options) {
  const YAML::Node& overrides = config.node();
  if (runs < 1 || runs > kMaxMonteCarloRuns) {
    return InvalidArgument("PCRB: runs must be in [1, " + std::to_string(kMaxMonteCarloRuns) +
                           "], not " + std::to_string(runs));
  }
  WG_ASSIGN_OR_RETURN(threads, ResolveThreads(threads, runs));
  PcrbAccumulator sum(runs);
  auto run_one = [&](int i, const YAML::Node& node) -> Status {
    WG_ASSIGN_OR_RETURN(Simulation s,
                        SimulateScenarioDetailed(scenario, MonteCarloSeed(seed, i), node));
    WG_ASSIGN_OR_RETURN(PcrbInformation info, PcrbInformationFromSimulation(s, options));
    return sum.Add(i, std::move(info));
  };
  // Run 0 alone on the caller's node (its errors keep their YAML line numbers); the others on
  // private copies: reading a yaml-cpp node by key may modify it, so threads must not share one.
  WG_RETURN_IF_ERROR(run_one(0, overrides));
  std::mutex clone_mutex;
  WG_RETURN_IF_ERROR(internal::ParallelFor(1, runs, threads, [&](int i) {
    YAML::Node node;
    {
      std::lock_guard<std::mutex> lock(clone_mutex);
      if (overrides.IsDefined() && !overrides.IsNull()) node = YAML::Clone(overrides);
    }
    return run_one(i, node);
  }));
  WG_ASSIGN_OR_RETURN(PcrbInformation mean, sum.Mean());
  return ComputePcrb(mean);
}

}  // namespace walkgraph
