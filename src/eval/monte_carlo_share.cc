// Monte Carlo runs shared among processes (compare.h): a share's runs as bytes, and the merger
// that aggregates them in run order.
#include "eval/monte_carlo_share.h"

#include <set>
#include <utility>

#include "eval/part_bytes.h"
#include "walkgraph/compare.h"

namespace walkgraph {

namespace {

using internal::PartReader;
using internal::PartWriter;

constexpr const char kRunMagic[] = "walkgraph-monte-carlo-run 1";
constexpr const char kWhat[] = "walkgraph Monte Carlo run";

void PutDoubles(PartWriter& w, const std::vector<double>& v) {
  w.Int(static_cast<long long>(v.size()));
  for (double x : v) w.Double(x);
}

std::vector<double> GetDoubles(PartReader& r) {
  std::vector<double> v(r.ok() ? r.Count() : 0);
  for (double& x : v) x = r.Double();
  return v;
}

void PutOptInt(PartWriter& w, const std::optional<int>& v) {
  w.Int(v ? 1 : 0);
  if (v) w.Int(*v);
}

std::optional<int> GetOptInt(PartReader& r) {
  if (r.Int(0, 1) == 0) return std::nullopt;
  return static_cast<int>(r.Int(INT32_MIN, INT32_MAX));
}

template <typename Matrix>
void PutMatrix(PartWriter& w, const Matrix& m) {
  for (int k = 0; k < m.size(); ++k) w.Double(m.data()[k]);
}

template <typename Matrix>
void GetMatrix(PartReader& r, Matrix* m) {
  for (int k = 0; k < m->size(); ++k) m->data()[k] = r.Double();
}

template <typename Matrix>
void PutMatrices(PartWriter& w, const std::vector<Matrix>& v) {
  w.Int(static_cast<long long>(v.size()));
  for (const Matrix& m : v) PutMatrix(w, m);
}

template <typename Matrix>
std::vector<Matrix> GetMatrices(PartReader& r) {
  std::vector<Matrix> v(r.ok() ? r.Count() : 0, Matrix::Zero());
  for (Matrix& m : v) GetMatrix(r, &m);
  return v;
}

void PutMap(PartWriter& w, const std::map<std::string, double>& m) {
  w.Int(static_cast<long long>(m.size()));
  for (const auto& [k, v] : m) {
    w.String(k);
    w.Double(v);
  }
}

std::map<std::string, double> GetMap(PartReader& r) {
  std::map<std::string, double> m;
  const long long n = r.Count();
  for (long long i = 0; r.ok() && i < n; ++i) {
    std::string k = r.String();
    m[std::move(k)] = r.Double();
  }
  return m;
}

void PutTrajectory(PartWriter& w, const Trajectory& t) {
  w.Int(static_cast<long long>(t.points.size()));
  for (const TrajectoryPoint& p : t.points) {
    w.Double(p.t_s);
    PutMatrix(w, p.position_m);
    w.Double(p.heading_rad);
    w.Int(p.covariance ? 1 : 0);
    if (p.covariance) PutMatrix(w, *p.covariance);
    PutOptInt(w, p.floor);
    w.Line();
  }
}

Trajectory GetTrajectory(PartReader& r) {
  Trajectory t;
  t.points.resize(r.ok() ? r.Count() : 0);
  for (TrajectoryPoint& p : t.points) {
    p.t_s = r.Double();
    GetMatrix(r, &p.position_m);
    p.heading_rad = r.Double();
    if (r.Int(0, 1) == 1) {
      p.covariance = Eigen::Matrix3d::Zero();
      GetMatrix(r, &*p.covariance);
    }
    p.floor = GetOptInt(r);
  }
  return t;
}

// An outcome; `whole`: with its whole result and error series (what the aggregation keeps of
// the first run that counts), otherwise the error series' times and errors alone.
void PutOutcome(PartWriter& w, const EstimatorOutcome& o, bool whole) {
  w.String(o.id);
  internal::PutStatus(w, o.status);
  internal::PutStats(w, o.stats);
  w.Double(o.runtime_s);
  w.Int(o.divergence ? 1 : 0);
  if (o.divergence) {
    w.Double(o.divergence->t_s);
    w.String(o.divergence->reason);
  }
  w.Int(o.divergence_kept_in_figures ? 1 : 0);
  w.Int(o.errors.n_skipped);
  PutDoubles(w, o.errors.t_s);
  PutDoubles(w, o.errors.error_m);
  w.Int(whole ? 1 : 0);
  w.Line();
  if (!whole) return;
  PutDoubles(w, o.errors.nees);
  PutDoubles(w, o.errors.distance_m);
  w.Int(static_cast<long long>(o.errors.floors_missed.size()));
  for (int f : o.errors.floors_missed) w.Int(f);
  w.Line();
  PutTrajectory(w, o.result.trajectory);
  PutDoubles(w, o.result.nis);
  PutMap(w, o.result.diagnostics);
  PutMap(w, o.result.timings);
  w.Line();
}

EstimatorOutcome GetOutcome(PartReader& r) {
  EstimatorOutcome o;
  o.id = r.String();
  o.status = internal::GetStatus(r);
  o.stats = internal::GetStats(r);
  o.runtime_s = r.Double();
  if (r.Int(0, 1) == 1) {
    o.divergence = Divergence();
    o.divergence->t_s = r.Double();
    o.divergence->reason = r.String();
  }
  o.divergence_kept_in_figures = r.Int(0, 1) == 1;
  o.errors.n_skipped = static_cast<int>(r.Int(0, INT32_MAX));
  o.errors.t_s = GetDoubles(r);
  o.errors.error_m = GetDoubles(r);
  if (r.Int(0, 1) == 0) return o;
  o.errors.nees = GetDoubles(r);
  o.errors.distance_m = GetDoubles(r);
  o.errors.floors_missed.resize(r.ok() ? r.Count() : 0);
  for (int& f : o.errors.floors_missed) f = static_cast<int>(r.Int(INT32_MIN, INT32_MAX));
  o.result.trajectory = GetTrajectory(r);
  o.result.nis = GetDoubles(r);
  o.result.diagnostics = GetMap(r);
  o.result.timings = GetMap(r);
  return o;
}

void PutPcrb(PartWriter& w, const internal::RunPcrb& p) {
  w.Int(p.information ? 1 : 0);
  internal::PutStatus(w, p.status);
  if (!p.information) return;
  const PcrbInformation& info = *p.information;
  PutDoubles(w, info.t_s);
  PutMatrices(w, info.position_m);
  PutMatrix(w, info.J0);
  PutMatrices(w, info.D11);
  PutMatrices(w, info.D12);
  PutMatrices(w, info.D22);
  PutDoubles(w, info.score_t_s);
  w.Double(info.readings);
  w.Int(info.runs);
  w.Line();
}

internal::RunPcrb GetPcrb(PartReader& r) {
  internal::RunPcrb p;
  const bool with_information = r.Int(0, 1) == 1;
  p.status = internal::GetStatus(r);
  if (!with_information) return p;
  PcrbInformation info;
  info.t_s = GetDoubles(r);
  info.position_m = GetMatrices<Eigen::Vector2d>(r);
  GetMatrix(r, &info.J0);
  info.D11 = GetMatrices<Eigen::Matrix2d>(r);
  info.D12 = GetMatrices<Eigen::Matrix2d>(r);
  info.D22 = GetMatrices<Eigen::Matrix2d>(r);
  info.score_t_s = GetDoubles(r);
  info.readings = r.Double();
  info.runs = static_cast<int>(r.Int(1, INT32_MAX));
  p.information = std::move(info);
  return p;
}

void PutWalkPart(PartWriter& w, const Comparison& c) {
  w.String(c.walk_name);
  w.Int(static_cast<int>(c.truth_kind));
  w.Double(c.score_from_s);
  w.Int(static_cast<long long>(c.anchors.size()));
  for (const Anchor& a : c.anchors) {
    w.Int(a.id);
    PutMatrix(w, a.position_m);
    PutOptInt(w, a.floor);
  }
  w.Int(static_cast<long long>(c.truth.size()));
  for (const TruthSample& t : c.truth) {
    w.Double(t.t_s);
    PutMatrix(w, t.position_m);
    w.Int(t.has_z ? 1 : 0);
    PutOptInt(w, t.floor);
  }
  w.Int(c.warning_count);
  w.Int(static_cast<long long>(c.warnings.size()));
  for (const std::string& message : c.warnings) w.String(message);
  w.Line();
}

void GetWalkPart(PartReader& r, Comparison* c) {
  c->walk_name = r.String();
  c->truth_kind = static_cast<TruthKind>(r.Int(0, static_cast<int>(TruthKind::kCheckpoints)));
  c->score_from_s = r.Double();
  c->anchors.resize(r.ok() ? r.Count() : 0);
  for (Anchor& a : c->anchors) {
    a.id = static_cast<int>(r.Int(INT32_MIN, INT32_MAX));
    GetMatrix(r, &a.position_m);
    a.floor = GetOptInt(r);
  }
  c->truth.resize(r.ok() ? r.Count() : 0);
  for (TruthSample& t : c->truth) {
    t.t_s = r.Double();
    GetMatrix(r, &t.position_m);
    t.has_z = r.Int(0, 1) == 1;
    t.floor = GetOptInt(r);
  }
  c->warning_count = static_cast<int>(r.Int(0, INT32_MAX));
  c->warnings.resize(r.ok() ? r.Count() : 0);
  for (std::string& message : c->warnings) message = r.String();
}

// Whether an outcome counts in the figures (RunAggregator keeps the first such run whole).
bool Counts(const EstimatorOutcome& o) {
  return o.status.ok() && (!o.divergence || o.divergence_kept_in_figures);
}

}  // namespace

Status CompareScenarioShare(const std::string& scenario, const ScenarioCompareOptions& sc,
                            const CompareOptions& options, const MonteCarloOptions& mc,
                            const MonteCarloShare& share,
                            const std::function<Status(int run, std::string bytes)>& sink,
                            const EstimatorRegistry& registry) {
  if (!sink) return InvalidArgument("Monte Carlo share: no sink for the runs");
  std::set<std::string> sent_whole;  // estimators whose first counting run went whole
  return internal::RunScenarioShare(scenario, sc, options, mc, share, registry,
                                    [&](int run, Comparison c, internal::RunPcrb pcrb) {
                                      PartWriter w;
                                      w.String(kRunMagic);
                                      w.Int(run);
                                      if (run != 0)
                                        c.anchors.clear();  // the aggregation draws run 0's
                                      PutWalkPart(w, c);
                                      w.Int(static_cast<long long>(c.outcomes.size()));
                                      w.Line();
                                      for (const EstimatorOutcome& o : c.outcomes) {
                                        PutOutcome(w, o,
                                                   Counts(o) && sent_whole.insert(o.id).second);
                                      }
                                      PutPcrb(w, pcrb);
                                      w.String("end");
                                      w.Line();
                                      return sink(run, w.str());
                                    });
}

struct ScenarioRunMerger::State {
  State(const ScenarioCompareOptions& sc, const MonteCarloOptions& mc)
      : runs(mc.runs), seed(mc.seed), pcrb(sc, mc.runs) {}
  int runs;
  uint64_t seed;
  int next = 0;  // the run Add expects
  RunAggregator aggregator;
  internal::ScenarioPcrbSum pcrb;
  Status error;  // the first failure; Add and Finish return it from then on
};

ScenarioRunMerger::ScenarioRunMerger(const ScenarioCompareOptions& scenario_options,
                                     const MonteCarloOptions& monte_carlo)
    : state_(std::make_unique<State>(scenario_options, monte_carlo)) {}
ScenarioRunMerger::~ScenarioRunMerger() = default;

Status ScenarioRunMerger::Add(const std::string& bytes, const std::string& origin) {
  State& st = *state_;
  if (!st.error.ok()) return st.error;
  PartReader r(bytes, origin, kWhat);
  Comparison c;
  if (r.String() != kRunMagic || !r.ok()) return st.error = r.Error();
  const int run = static_cast<int>(r.Int(0, INT32_MAX));
  GetWalkPart(r, &c);
  const long long outcomes = r.Count();
  for (long long k = 0; r.ok() && k < outcomes; ++k) c.outcomes.push_back(GetOutcome(r));
  internal::RunPcrb pcrb = GetPcrb(r);
  if (r.String() != "end" || !r.ok() || !r.AtEnd()) return st.error = r.Error();
  if (run != st.next || run >= st.runs) {
    return st.error = InvalidArgument(origin + ": run " + std::to_string(run) + " where run " +
                                      std::to_string(st.next) + " was due (of " +
                                      std::to_string(st.runs) + ")");
  }
  st.aggregator.Add(std::move(c));
  st.pcrb.Add(run, std::move(pcrb));
  ++st.next;
  return Status::Ok();
}

StatusOr<Comparison> ScenarioRunMerger::Finish() {
  State& st = *state_;
  if (!st.error.ok()) return st.error;
  if (st.next != st.runs) {
    return InvalidArgument("Monte Carlo: " + std::to_string(st.next) + " of " +
                           std::to_string(st.runs) + " runs merged");
  }
  WG_ASSIGN_OR_RETURN(Comparison out, st.aggregator.Finish());
  out.seed = st.seed;
  WG_RETURN_IF_ERROR(st.pcrb.AttachTo(&out));
  return out;
}

}  // namespace walkgraph
