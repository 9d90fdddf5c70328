// Parameter studies: manifest validation, the cells, and their CSV / HTML output (study.h).
#include "walkgraph/study.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <limits>
#include <set>
#include <sstream>

#include "config/reader.h"
#include "eval/pcrb_yaml.h"
#include "report/estimator_style.h"
#include "report/svg.h"
#include "util/input_file.h"
#include "util/text.h"
#include "walkgraph/config.h"
#include "walkgraph/io.h"
#include "walkgraph/simulate.h"

namespace walkgraph {

namespace fs = std::filesystem;

namespace {

// The figure of `m` (ErrorStatFields), or null.
double ErrorStats::*FieldOf(const std::string& m) {
  for (const ErrorStatField& f : ErrorStatFields()) {
    if (m == f.name) return f.field;
  }
  return nullptr;
}

bool KnownMetric(const std::string& m) { return FieldOf(m) != nullptr || m == "rmse_over_pcrb"; }

std::string Join(const std::vector<std::string>& names) { return internal::Join(names, ", "); }

// ------------------------------------------------------------------ manifest parsing

class Parser {
 public:
  explicit Parser(std::string path) : path_(std::move(path)) {}

  int Line(const YAML::Node& n) const { return n.Mark().line >= 0 ? n.Mark().line + 1 : 0; }
  std::string At(const YAML::Node& n) const { return path_ + ":" + std::to_string(Line(n)); }
  Status Error(const YAML::Node& n, const std::string& message) const {
    return InvalidArgument(At(n) + ": " + message);
  }

  // Every key of `map` must be in `known`; keys must be plain scalars.
  Status CheckKeys(const YAML::Node& map, const std::vector<std::string>& known,
                   const std::string& what) const {
    for (const auto& kv : map) {
      if (!kv.first.IsScalar()) return Error(kv.first, what + ": keys must be plain words");
      const std::string key = kv.first.Scalar();
      if (std::find(known.begin(), known.end(), key) == known.end()) {
        return Error(kv.first, "unknown key " + internal::Quoted(key) + " in " + what +
                                   "; known: " + Join(known));
      }
    }
    return Status::Ok();
  }

  template <typename T>
  StatusOr<T> Scalar(const YAML::Node& n, const std::string& what, const char* type) const {
    if (!n.IsScalar()) return Error(n, what + " must be a " + type);
    T value{};
    if (!ParseScalar(n.Scalar(), &value)) {
      return Error(n, what + " must be a " + type + ", got " + internal::QuotedNumber(n.Scalar()));
    }
    return value;
  }

  StatusOr<std::string> String(const YAML::Node& n, const std::string& what) const {
    return Scalar<std::string>(n, what, "string");
  }

  StatusOr<int> PositiveInt(const YAML::Node& n, const std::string& what) const {
    WG_ASSIGN_OR_RETURN(int v, Scalar<int>(n, what, "positive integer"));
    if (v < 1) return Error(n, what + " must be >= 1");
    return v;
  }

  // A Monte Carlo run count: in [1, kMaxMonteCarloRuns].
  StatusOr<int> Runs(const YAML::Node& n) const {
    WG_ASSIGN_OR_RETURN(int v, PositiveInt(n, "runs"));
    if (v > kMaxMonteCarloRuns) {
      return Error(n, "runs " + std::to_string(v) + " over the cap of " +
                          std::to_string(kMaxMonteCarloRuns) +
                          " (10^6 runs take days; split a larger study into seeds)");
    }
    return v;
  }

  StatusOr<double> NonNegative(const YAML::Node& n, const std::string& what) const {
    WG_ASSIGN_OR_RETURN(double v, Scalar<double>(n, what, "number >= 0"));
    if (!(std::isfinite(v) && v >= 0.0)) return Error(n, what + " must be a number >= 0");
    return v;
  }

  StatusOr<uint64_t> Seed(const YAML::Node& n, const std::string& what) const {
    if (n.IsScalar() && !n.Scalar().empty() && n.Scalar()[0] == '-') {
      return Error(n, what + " must be a non-negative integer");
    }
    return Scalar<uint64_t>(n, what, "non-negative integer");
  }

  StatusOr<std::string> Metric(const YAML::Node& n) const {
    WG_ASSIGN_OR_RETURN(std::string m, String(n, "metric"));
    if (!KnownMetric(m)) {
      std::vector<std::string> all;
      for (const ErrorStatField& f : ErrorStatFields()) all.push_back(f.name);
      all.push_back("rmse_over_pcrb");
      return Error(n, "unknown metric " + internal::Quoted(m) + "; known: " + Join(all));
    }
    return m;
  }

  StatusOr<std::vector<std::string>> EstimatorList(const YAML::Node& n,
                                                   const EstimatorRegistry& registry) const {
    if (!n.IsSequence() || n.size() == 0) {
      return Error(n, "estimators must be a non-empty list of estimator ids");
    }
    std::vector<std::string> ids;
    for (const YAML::Node& item : n) {
      WG_ASSIGN_OR_RETURN(std::string id, String(item, "estimator id"));
      if (registry.Find(id) == nullptr) {
        return Error(
            item, "unknown estimator " + internal::Quoted(id) + "; known: " + Join(registry.Ids()));
      }
      if (std::find(ids.begin(), ids.end(), id) != ids.end()) {
        return Error(item, "estimator '" + id + "' listed twice");
      }
      ids.push_back(id);
    }
    return ids;
  }

  const std::string& path() const { return path_; }

 private:
  std::string path_;
};

// A new map with the entries of `n` (a map or nothing). The values are the manifest's own nodes,
// so option errors keep their manifest line; the new map is private to one cell.
YAML::Node MapCopy(const YAML::Node& n) {
  YAML::Node out(YAML::NodeType::Map);
  if (n.IsDefined() && n.IsMap()) {
    for (const auto& kv : n) out[kv.first.Scalar()] = kv.second;
  }
  return out;
}

// The simulator overrides of cell (sweep, value).
YAML::Node CellOverrides(const StudySweep& sweep, size_t value) {
  YAML::Node o = MapCopy(sweep.overrides.node());
  if (!sweep.scenario_override.empty()) o[sweep.scenario_override] = sweep.values[value];
  return o;
}

// The options of estimator `id` in cell (sweep, value).
YAML::Node CellConfig(const StudyManifest& m, const StudySweep& sweep, size_t value,
                      const std::string& id) {
  const auto base = m.configs.find(id);
  YAML::Node c = MapCopy(base != m.configs.end() ? base->second.node() : YAML::Node());
  const auto key = sweep.option_keys.find(id);
  if (key != sweep.option_keys.end()) c[key->second] = sweep.values[value];
  return c;
}

std::string CellName(const StudySweep& sweep, size_t value) {
  return "sweep '" + sweep.name + "', value " + sweep.values[value];
}

std::string CellAt(const StudyManifest& m, const StudySweep& sweep, size_t value) {
  return m.path + ":" + std::to_string(sweep.value_lines[value]) + ": " + CellName(sweep, value);
}

bool ValidSweepName(const std::string& s) {
  if (s.empty()) return false;
  for (char ch : s) {
    if (!(std::isalnum(static_cast<unsigned char>(ch)) || ch == '_' || ch == '-' || ch == '.')) {
      return false;
    }
  }
  return true;
}

// A sweep's values: a non-empty list of distinct finite numbers, at most kMaxSweepValues.
Status ParseValues(const Parser& p, const YAML::Node& node, const std::string& what,
                   StudySweep* s) {
  const YAML::Node values = node["values"];
  if (!values || !values.IsSequence() || values.size() == 0) {
    return p.Error(values ? values : node, what + ": values must be a non-empty list of numbers");
  }
  if (values.size() > kMaxSweepValues) {
    return p.Error(values, what + ": " + std::to_string(values.size()) +
                               " values, over the cap of " + std::to_string(kMaxSweepValues) +
                               " per sweep (a study that cannot finish); split the sweep");
  }
  for (const YAML::Node& v : values) {
    WG_ASSIGN_OR_RETURN(double x, p.Scalar<double>(v, "a swept value", "number"));
    if (!std::isfinite(x)) return p.Error(v, what + ": values must be finite numbers");
    if (std::find(s->x.begin(), s->x.end(), x) != s->x.end()) {
      return p.Error(v, what + ": value " + v.Scalar() + " given twice");
    }
    s->values.push_back(v.Scalar());
    s->x.push_back(x);
    s->value_lines.push_back(p.Line(v));
  }
  return Status::Ok();
}

// The manifest's top-level settings, each sweep's default.
struct SweepDefaults {
  std::vector<std::string> ids;
  int runs = 1;
  uint64_t seed = 0;
  std::string metric;
  double score_from_s = 0.0;
};

// A sweep's data: a simulated scenario (with its overrides) or a recorded walk.
Status ParseSweepData(const Parser& p, const YAML::Node& node, const std::string& what,
                      StudySweep* s) {
  if (!node["scenario"] == !node["walk"]) {
    return p.Error(node, what + ": give exactly one of 'scenario' or 'walk'");
  }
  if (node["scenario"]) {
    WG_ASSIGN_OR_RETURN(s->scenario, p.String(node["scenario"], "scenario"));
    std::vector<std::string> names;
    for (const ScenarioInfo& info : Scenarios()) names.push_back(info.name);
    if (std::find(names.begin(), names.end(), s->scenario) == names.end()) {
      return p.Error(node["scenario"], "unknown scenario " + internal::Quoted(s->scenario) +
                                           "; known: " + Join(names));
    }
    if (node["overrides"]) {
      if (!node["overrides"].IsMap()) {
        return p.Error(node["overrides"], what + ": overrides must be a map of simulator options");
      }
      s->overrides = node["overrides"];
    }
    return Status::Ok();
  }
  WG_ASSIGN_OR_RETURN(std::string walk, p.String(node["walk"], "walk"));
  fs::path dir(walk);
  if (dir.is_relative()) dir = fs::path(p.path()).parent_path() / dir;
  std::error_code ec;
  if (!fs::is_directory(dir, ec)) {
    return p.Error(node["walk"], what + ": walk folder " + dir.string() + " does not exist");
  }
  s->walk_dir = dir.string();
  if (node["overrides"] || node["scenario_override"]) {
    return p.Error(node["overrides"] ? node["overrides"] : node["scenario_override"],
                   what + ": a recorded walk has no simulator overrides");
  }
  if (node["runs"]) {
    WG_ASSIGN_OR_RETURN(int runs, p.Runs(node["runs"]));
    if (runs != 1) return p.Error(node["runs"], what + ": a recorded walk is one run");
  }
  return Status::Ok();
}

// A sweep's estimators, runs, seed, metric and score_from_s (the top level's where not given).
Status ParseSweepSettings(const Parser& p, const YAML::Node& node, const std::string& what,
                          const SweepDefaults& top, const EstimatorRegistry& registry,
                          StudySweep* s) {
  if (node["estimators"]) {
    WG_ASSIGN_OR_RETURN(s->estimators, p.EstimatorList(node["estimators"], registry));
  } else if (!top.ids.empty()) {
    s->estimators = top.ids;
  } else {
    return p.Error(node, what + ": no estimators (give 'estimators' here or at the top)");
  }
  s->runs = top.runs;
  if (node["runs"]) {
    WG_ASSIGN_OR_RETURN(s->runs, p.Runs(node["runs"]));
  }
  if (!s->walk_dir.empty()) s->runs = 1;
  s->seed = top.seed;
  if (node["seed"]) {
    WG_ASSIGN_OR_RETURN(s->seed, p.Seed(node["seed"], "seed"));
  }
  s->metric = top.metric;
  if (node["metric"]) {
    WG_ASSIGN_OR_RETURN(s->metric, p.Metric(node["metric"]));
  }
  s->score_from_s = top.score_from_s;
  if (node["score_from_s"]) {
    WG_ASSIGN_OR_RETURN(s->score_from_s, p.NonNegative(node["score_from_s"], "score_from_s"));
  }
  return Status::Ok();
}

// estimator_option as {estimator id: option key}: the keys by estimator; the default label
// joins the distinct keys.
Status ParseOptionKeyMap(const Parser& p, const YAML::Node& opt, const std::string& what,
                         StudySweep* s, std::string* default_label) {
  std::vector<std::string> keys;
  for (const auto& kv : opt) {
    WG_ASSIGN_OR_RETURN(std::string id, p.String(kv.first, "estimator id"));
    if (std::find(s->estimators.begin(), s->estimators.end(), id) == s->estimators.end()) {
      return p.Error(kv.first, what + ": estimator '" + id + "' is not in the sweep's list (" +
                                   Join(s->estimators) + ")");
    }
    WG_ASSIGN_OR_RETURN(std::string key, p.String(kv.second, "option key of " + id));
    s->option_keys[id] = key;
    if (std::find(keys.begin(), keys.end(), key) == keys.end()) keys.push_back(key);
  }
  for (const std::string& k : keys) *default_label += (default_label->empty() ? "" : " / ") + k;
  return Status::Ok();
}

// What a sweep varies: a simulator override or an estimator option (one key for every
// estimator, or one per estimator); the label defaults to it.
Status ParseSweptParameter(const Parser& p, const YAML::Node& node, const std::string& what,
                           StudySweep* s) {
  if (!node["scenario_override"] == !node["estimator_option"]) {
    return p.Error(node, what + ": give exactly one of 'scenario_override' or 'estimator_option'");
  }
  std::string default_label;
  if (node["scenario_override"]) {
    WG_ASSIGN_OR_RETURN(s->scenario_override,
                        p.String(node["scenario_override"], "scenario_override"));
    const YAML::Node& base = s->overrides.node();  // const: a lookup must not add the key
    if (base.IsDefined() && base[s->scenario_override]) {
      return p.Error(node["scenario_override"],
                     what + ": '" + s->scenario_override + "' is both swept and in overrides");
    }
    default_label = s->scenario_override;
  } else {
    const YAML::Node opt = node["estimator_option"];
    if (opt.IsScalar()) {
      WG_ASSIGN_OR_RETURN(std::string key, p.String(opt, "estimator_option"));
      for (const std::string& id : s->estimators) s->option_keys[id] = key;
      default_label = key;
    } else if (opt.IsMap() && opt.size() > 0) {
      WG_RETURN_IF_ERROR(ParseOptionKeyMap(p, opt, what, s, &default_label));
    } else {
      return p.Error(opt, what + ": estimator_option must be an option key or {estimator: key}");
    }
  }
  if (s->label.empty()) s->label = default_label;
  return Status::Ok();
}

StatusOr<StudySweep> ParseSweep(const Parser& p, const YAML::Node& node, const StudyManifest& m,
                                const SweepDefaults& top, const EstimatorRegistry& registry) {
  StudySweep s;
  s.line = p.Line(node);
  if (!node.IsMap()) return p.Error(node, "each sweep must be a map");
  WG_RETURN_IF_ERROR(p.CheckKeys(
      node,
      {"name", "title", "label", "scenario", "walk", "overrides", "scenario_override",
       "estimator_option", "values", "estimators", "runs", "seed", "metric", "score_from_s"},
      "a sweep"));
  if (!node["name"]) return p.Error(node, "a sweep needs a name");
  WG_ASSIGN_OR_RETURN(s.name, p.String(node["name"], "sweep name"));
  if (!ValidSweepName(s.name)) {
    return p.Error(node["name"], "sweep name '" + s.name + "' may use letters, digits, . _ -");
  }
  const std::string what = "sweep '" + s.name + "'";
  if (node["title"]) {
    WG_ASSIGN_OR_RETURN(s.title, p.String(node["title"], "title"));
  }
  if (node["label"]) {
    WG_ASSIGN_OR_RETURN(s.label, p.String(node["label"], "label"));
  }
  WG_RETURN_IF_ERROR(ParseSweepData(p, node, what, &s));
  WG_RETURN_IF_ERROR(ParseSweepSettings(p, node, what, top, registry, &s));
  WG_RETURN_IF_ERROR(ParseSweptParameter(p, node, what, &s));
  WG_RETURN_IF_ERROR(ParseValues(p, node, what, &s));
  // Every cell's estimator configuration must be accepted by its estimator.
  for (size_t i = 0; i < s.values.size(); ++i) {
    for (const std::string& id : s.estimators) {
      auto est = registry.Create(id, CellConfig(m, s, i, id));
      if (!est.ok()) {
        return InvalidArgument(CellAt(m, s, i) + ": estimator '" + id +
                               "': " + est.status().message());
      }
    }
  }
  return s;
}

}  // namespace

namespace {

StatusOr<StudyManifest> ParseManifestRoot(const YAML::Node& root, const std::string& path,
                                          const EstimatorRegistry& registry) {
  const Parser p(path);
  if (!root.IsMap()) return p.Error(root, "a study manifest must be a map (see study.h)");
  WG_RETURN_IF_ERROR(p.CheckKeys(root,
                                 {"name", "description", "estimators", "configs", "metric", "runs",
                                  "seed", "score_from_s", "pcrb", "pcrb_options", "sweeps"},
                                 "the manifest"));
  StudyManifest m;
  m.path = path;
  if (!root["name"]) return p.Error(root, "the manifest needs a name");
  WG_ASSIGN_OR_RETURN(m.name, p.String(root["name"], "name"));
  if (root["description"]) {
    WG_ASSIGN_OR_RETURN(m.description, p.String(root["description"], "description"));
  }
  std::vector<std::string> ids;
  if (root["estimators"]) {
    WG_ASSIGN_OR_RETURN(ids, p.EstimatorList(root["estimators"], registry));
  }
  if (root["configs"]) {
    const YAML::Node configs = root["configs"];
    if (!configs.IsMap()) return p.Error(configs, "configs must be a map {estimator id: options}");
    for (const auto& kv : configs) {
      WG_ASSIGN_OR_RETURN(std::string id, p.String(kv.first, "estimator id"));
      if (registry.Find(id) == nullptr) {
        return p.Error(kv.first, "configs: unknown estimator " + internal::Quoted(id) +
                                     "; known: " + Join(registry.Ids()));
      }
      if (!kv.second.IsMap() && !kv.second.IsNull()) {
        return p.Error(kv.second, "configs: the options of " + id + " must be a map");
      }
      m.configs[id] = kv.second;
    }
  }
  std::string metric = "rmse_m";
  if (root["metric"]) {
    WG_ASSIGN_OR_RETURN(metric, p.Metric(root["metric"]));
  }
  int runs = 1;
  if (root["runs"]) {
    WG_ASSIGN_OR_RETURN(runs, p.Runs(root["runs"]));
  }
  uint64_t seed = 1;
  if (root["seed"]) {
    WG_ASSIGN_OR_RETURN(seed, p.Seed(root["seed"], "seed"));
  }
  double score_from_s = 0.0;
  if (root["score_from_s"]) {
    WG_ASSIGN_OR_RETURN(score_from_s, p.NonNegative(root["score_from_s"], "score_from_s"));
  }
  if (root["pcrb"]) {
    WG_ASSIGN_OR_RETURN(m.pcrb, p.Scalar<bool>(root["pcrb"], "pcrb", "boolean (true/false)"));
  }
  if (root["pcrb_options"]) {
    WG_ASSIGN_OR_RETURN(
        m.pcrb_options,
        PcrbOptionsFromYaml(root["pcrb_options"], p.At(root["pcrb_options"]) + ": pcrb_options"));
  }
  const YAML::Node sweeps = root["sweeps"];
  if (!sweeps || !sweeps.IsSequence() || sweeps.size() == 0) {
    return p.Error(sweeps ? sweeps : root, "the manifest needs a non-empty list of sweeps");
  }
  std::set<std::string> names;
  for (const YAML::Node& node : sweeps) {
    WG_ASSIGN_OR_RETURN(StudySweep s,
                        ParseSweep(p, node, m, {ids, runs, seed, metric, score_from_s}, registry));
    if (!names.insert(s.name).second) {
      return p.Error(node["name"], "sweep name '" + s.name + "' used twice");
    }
    m.sweeps.push_back(std::move(s));
  }
  return m;
}

}  // namespace

StatusOr<StudyManifest> ParseStudyManifest(const std::string& text, const std::string& path,
                                           const EstimatorRegistry& registry) {
  WG_ASSIGN_OR_RETURN(const YAML::Node root, LoadYamlText(text, path));
  WG_ASSIGN_OR_RETURN(StudyManifest m, ParseManifestRoot(root, path, registry));
  m.text = text;
  return m;
}

StatusOr<StudyManifest> ReadStudyManifest(const std::string& path,
                                          const EstimatorRegistry& registry) {
  WG_ASSIGN_OR_RETURN(const std::string text,
                      internal::ReadInputFile(path, internal::kMaxYamlBytes));
  return ParseStudyManifest(text, path, registry);
}

// ------------------------------------------------------------------ running

namespace {

// (sweep, value) of every cell, in the study's order.
std::vector<std::pair<int, int>> CellIndex(const StudyManifest& m) {
  std::vector<std::pair<int, int>> cells;
  for (size_t k = 0; k < m.sweeps.size(); ++k) {
    for (size_t i = 0; i < m.sweeps[k].values.size(); ++i) {
      cells.emplace_back(static_cast<int>(k), static_cast<int>(i));
    }
  }
  return cells;
}

// Reads sweep k's walk into (*walks)[k] unless it is there already.
Status LoadSweepWalk(const StudyManifest& m, int k, std::vector<std::optional<Walk>>* walks) {
  const StudySweep& s = m.sweeps[k];
  if ((*walks)[k]) return Status::Ok();
  StatusOr<Walk> w = ReadWalk(s.walk_dir);
  if (!w.ok()) {
    return InvalidArgument(m.path + ":" + std::to_string(s.line) + ": sweep '" + s.name +
                           "': " + w.status().message());
  }
  (*walks)[k] = std::move(w).value();
  return Status::Ok();
}

// The validation pass over `cells`: every scenario cell simulates (run 0), every walk reads.
Status ValidateCells(const StudyManifest& m, const std::vector<std::pair<int, int>>& cells,
                     std::vector<std::optional<Walk>>* walks) {
  walks->assign(m.sweeps.size(), std::nullopt);
  for (const auto& [k, i] : cells) {
    const StudySweep& s = m.sweeps[k];
    if (!s.walk_dir.empty()) {
      WG_RETURN_IF_ERROR(LoadSweepWalk(m, k, walks));
      continue;
    }
    StatusOr<Walk> w = SimulateScenario(s.scenario, MonteCarloSeed(s.seed, 0), CellOverrides(s, i));
    if (!w.ok()) return InvalidArgument(CellAt(m, s, i) + ": " + w.status().message());
  }
  return Status::Ok();
}

StudyRow RowOf(EstimatorOutcome& o) {
  StudyRow r;
  r.estimator = o.id;
  // A diverged estimate is left out of the study's figures like a failed one, saying so.
  r.status = o.status.ok() && !o.Ranked() ? Status(StatusCode::kNumerical, ToString(*o.divergence))
                                          : o.status;
  r.stats = o.stats;
  r.stats_std = o.stats_std;
  r.failed_runs = o.failed_runs;
  r.diverged_runs = o.diverged_runs;
  r.runtime_s = o.runtime_s;
  r.runtime_std_s = o.runtime_std_s;
  return r;
}

// Runs cell (k, i); `walk` is the sweep's recorded walk (nullptr for a scenario).
StatusOr<StudyCell> RunCell(const StudyManifest& m, int k, int i, const Walk* walk,
                            const StudyOptions& options, const EstimatorRegistry& registry) {
  const StudySweep& s = m.sweeps[k];
  CompareOptions co;
  co.estimator_ids = s.estimators;
  co.score_from_s = s.score_from_s;
  for (const std::string& id : s.estimators) co.configs[id] = CellConfig(m, s, i, id);
  StatusOr<Comparison> c = FailedPrecondition("no comparison");
  if (walk != nullptr) {
    c = CompareOnWalk(*walk, co, registry);
  } else {
    ScenarioCompareOptions sc;
    sc.overrides = CellOverrides(s, i);
    sc.pcrb = m.pcrb;
    sc.pcrb_options = m.pcrb_options;
    MonteCarloOptions mc;
    mc.runs = s.runs;
    mc.seed = s.seed;
    mc.threads = options.threads;
    c = CompareScenario(s.scenario, sc, co, mc, registry);
  }
  if (!c.ok()) return Status(c.status().code(), CellAt(m, s, i) + ": " + c.status().message());
  StudyCell cell;
  cell.sweep = k;
  cell.value = i;
  cell.runs = c->runs;
  cell.seed = s.seed;
  cell.pcrb_rmse_m = c->pcrb_rmse_m;
  cell.pcrb_filter_rmse_m = c->pcrb_filter_rmse_m;
  cell.pcrb_note = c->pcrb_note;
  for (EstimatorOutcome& o : c->outcomes) cell.rows.push_back(RowOf(o));
  return cell;
}

// The cells a part runs: its fixed ones, or (claim_cell) the ones it claims as it goes.
class CellSource {
 public:
  CellSource(const StudyManifest& m, std::vector<int> fixed, const std::function<int()>& claim)
      : fixed_(std::move(fixed)), claim_(claim) {
    if (claim_) order_ = StudyCellOrder(m);
  }
  // The next cell (an index into the study's cells), or -1.
  int Next() {
    if (!claim_) return next_ < fixed_.size() ? fixed_[next_++] : -1;
    const int at = claim_();
    return at >= 0 && at < static_cast<int>(order_.size()) ? order_[at] : -1;
  }
  // For progress: the part's cells, or (claiming) every cell of the study.
  int total(int study_cells) const {
    return claim_ ? study_cells : static_cast<int>(fixed_.size());
  }

 private:
  std::vector<int> fixed_, order_;
  size_t next_ = 0;
  const std::function<int()>& claim_;
};

}  // namespace

StatusOr<StudyPart> RunStudyPart(const StudyManifest& m, const StudyShard& shard,
                                 const StudyOptions& options, const EstimatorRegistry& registry) {
  WG_RETURN_IF_ERROR(shard.Validate());
  const std::vector<std::pair<int, int>> all = CellIndex(m);
  std::vector<std::pair<int, int>> mine;
  const std::vector<int> fixed = StudyShardCells(m, shard);
  for (int c : fixed) mine.push_back(all[c]);
  std::vector<std::optional<Walk>> walks;
  Status valid = ValidateCells(m, mine, &walks);
  if (options.validated) {
    const Status agreed = options.validated(valid);
    if (valid.ok()) valid = agreed;
  }
  WG_RETURN_IF_ERROR(valid);
  StudyPart part;
  part.shard = shard;
  part.claimed = static_cast<bool>(options.claim_cell);
  part.manifest_path = m.path;
  part.manifest_text = m.text;
  CellSource source(m, fixed, options.claim_cell);
  int done = 0;
  for (int c = source.Next(); c >= 0; c = source.Next()) {
    const auto [k, i] = all[c];
    // A claimed cell may belong to a sweep whose walk another process validated.
    if (!m.sweeps[k].walk_dir.empty()) WG_RETURN_IF_ERROR(LoadSweepWalk(m, k, &walks));
    const Walk* walk = walks[k] ? &*walks[k] : nullptr;
    WG_ASSIGN_OR_RETURN(StudyCell cell, RunCell(m, k, i, walk, options, registry));
    part.cells.push_back(std::move(cell));
    if (options.progress) options.progress(++done, source.total(static_cast<int>(all.size())));
  }
  // In the study's order (claimed cells come in claim order).
  std::sort(part.cells.begin(), part.cells.end(), [](const StudyCell& a, const StudyCell& b) {
    return std::make_pair(a.sweep, a.value) < std::make_pair(b.sweep, b.value);
  });
  return part;
}

StatusOr<StudyResult> RunStudy(const StudyManifest& m, const StudyOptions& options,
                               const EstimatorRegistry& registry) {
  WG_ASSIGN_OR_RETURN(StudyPart part, RunStudyPart(m, StudyShard{}, options, registry));
  return MergeStudyParts(m, {std::move(part)});
}

// ------------------------------------------------------------------ output

namespace {

std::string Num(double v) { return internal::Num(v, 10); }

std::string CsvField(const std::string& s) {
  if (s.find_first_of(",\"\n\r") == std::string::npos) return s;
  std::string o = "\"";
  for (char ch : s) {
    if (ch == '"') o += '"';
    o += ch;
  }
  return o + "\"";
}

std::optional<double> RatioOf(const StudyCell& c, const StudyRow& r) {
  if (!r.status.ok() || !c.pcrb_rmse_m || !(*c.pcrb_rmse_m > 0.0)) return std::nullopt;
  return r.stats.rmse_m / *c.pcrb_rmse_m;
}

// v, or nothing when it is not finite (anees without covariances).
std::optional<double> Finite(double v) {
  if (!std::isfinite(v)) return std::nullopt;
  return v;
}

// The plotted figure (and its Monte Carlo spread) of a row.
std::optional<double> MetricOf(const StudyCell& c, const StudyRow& r, const std::string& metric) {
  if (!r.status.ok()) return std::nullopt;
  if (metric == "rmse_over_pcrb") return RatioOf(c, r);
  if (double ErrorStats::*f = FieldOf(metric)) return Finite(r.stats.*f);
  return std::nullopt;
}

std::optional<double> MetricStdOf(const StudyCell& c, const StudyRow& r,
                                  const std::string& metric) {
  if (!r.status.ok() || !r.stats_std || c.runs < 2) return std::nullopt;
  if (double ErrorStats::*f = FieldOf(metric)) return Finite((*r.stats_std).*f);
  return std::nullopt;
}

std::string Opt(const std::optional<double>& v) { return v ? Num(*v) : ""; }

// Cells of one sweep, in the order of their values.
std::vector<const StudyCell*> CellsOf(const StudyResult& r, int sweep) {
  std::vector<const StudyCell*> out;
  for (const StudyCell& c : r.cells) {
    if (c.sweep == sweep) out.push_back(&c);
  }
  return out;
}

}  // namespace

std::string StudyCsv(const StudyResult& r) {
  std::ostringstream out;
  out << "sweep,parameter,value,estimator,runs,seed,failed_runs,diverged_runs";
  for (const ErrorStatField& f : ErrorStatFields()) out << ',' << f.name << ',' << f.name << "_std";
  out << ",n_points,pcrb_rmse_m,pcrb_filter_rmse_m,rmse_over_pcrb,error\n";
  for (const StudyCell& c : r.cells) {
    const StudySweep& s = r.manifest.sweeps[c.sweep];
    for (const StudyRow& row : c.rows) {
      out << CsvField(s.name) << ',' << CsvField(s.label) << ',' << CsvField(s.values[c.value])
          << ',' << CsvField(row.estimator) << ',' << c.runs << ',' << c.seed << ','
          << row.failed_runs << ',' << row.diverged_runs;
      for (const ErrorStatField& f : ErrorStatFields()) {
        if (row.status.ok()) {
          out << ',' << Opt(Finite(row.stats.*f.field)) << ','
              << (row.stats_std && c.runs > 1 ? Opt(Finite((*row.stats_std).*f.field)) : "");
        } else {
          out << ",,";
        }
      }
      out << ',' << (row.status.ok() ? std::to_string(row.stats.n_points) : "") << ','
          << Opt(c.pcrb_rmse_m) << ',' << Opt(c.pcrb_filter_rmse_m) << ',' << Opt(RatioOf(c, row))
          << ',' << (row.status.ok() ? "" : CsvField(row.status.message())) << '\n';
    }
  }
  return out.str();
}

std::string StudyTimingCsv(const StudyResult& r) {
  std::ostringstream out;
  out << "sweep,value,estimator,runs,runtime_s,runtime_s_std\n";
  for (const StudyCell& c : r.cells) {
    const StudySweep& s = r.manifest.sweeps[c.sweep];
    for (const StudyRow& row : c.rows) {
      out << CsvField(s.name) << ',' << CsvField(s.values[c.value]) << ','
          << CsvField(row.estimator) << ',' << c.runs << ',' << Num(row.runtime_s) << ','
          << Num(row.runtime_std_s) << '\n';
    }
  }
  return out.str();
}

std::string FormatStudyTable(const StudyResult& r) {
  std::ostringstream out;
  for (size_t k = 0; k < r.manifest.sweeps.size(); ++k) {
    const StudySweep& s = r.manifest.sweeps[k];
    const auto cells = CellsOf(r, static_cast<int>(k));
    std::vector<std::vector<std::string>> rows;
    std::vector<std::string> header = {s.label};
    for (const std::string& id : s.estimators) header.push_back(id);
    const bool pcrb = std::any_of(cells.begin(), cells.end(),
                                  [](const StudyCell* c) { return c->pcrb_rmse_m.has_value(); });
    if (pcrb) header.push_back("pcrb_rmse_m");
    for (const StudyCell* c : cells) {
      std::vector<std::string> row = {s.values[c->value]};
      for (const std::string& id : s.estimators) {
        std::string cell = "-";
        for (const StudyRow& rr : c->rows) {
          if (rr.estimator != id) continue;
          const auto v = MetricOf(*c, rr, s.metric);
          const auto sd = MetricStdOf(*c, rr, s.metric);
          std::ostringstream f;
          f << std::fixed << std::setprecision(3);
          if (v) {
            f << *v;
            if (sd) f << "+-" << *sd;
          } else {
            f << "failed";
          }
          cell = f.str();
        }
        row.push_back(cell);
      }
      if (pcrb) {
        std::ostringstream f;
        f << std::fixed << std::setprecision(3);
        if (c->pcrb_rmse_m) f << *c->pcrb_rmse_m;
        row.push_back(c->pcrb_rmse_m ? f.str() : "-");
      }
      rows.push_back(row);
    }
    std::vector<size_t> width(header.size());
    for (size_t j = 0; j < header.size(); ++j) {
      width[j] = header[j].size();
      for (const auto& row : rows) width[j] = std::max(width[j], row[j].size());
    }
    out << "sweep " << s.name << " (" << s.metric << ", runs " << s.runs << ")"
        << (s.title.empty() ? "" : ": " + s.title) << "\n";
    for (const auto* row : {&header}) {
      for (size_t j = 0; j < row->size(); ++j) {
        out << (j ? "  " : "") << std::setw(static_cast<int>(width[j])) << (*row)[j];
      }
      out << "\n";
    }
    for (const auto& row : rows) {
      for (size_t j = 0; j < row.size(); ++j) {
        out << (j ? "  " : "") << std::setw(static_cast<int>(width[j])) << row[j];
      }
      out << "\n";
    }
    out << "\n";
  }
  return out.str();
}

namespace {

std::string SweepPlot(const StudyResult& r, int k) {
  using report::Axes;
  const StudySweep& s = r.manifest.sweeps[k];
  const auto cells = CellsOf(r, k);
  // Points in ascending x.
  std::vector<const StudyCell*> sorted = cells;
  std::sort(sorted.begin(), sorted.end(),
            [&](const StudyCell* a, const StudyCell* b) { return s.x[a->value] < s.x[b->value]; });
  Axes a{std::numeric_limits<double>::infinity(), -std::numeric_limits<double>::infinity(), 0.0,
         0.0};
  for (const StudyCell* c : sorted) {
    a.x0 = std::min(a.x0, s.x[c->value]);
    a.x1 = std::max(a.x1, s.x[c->value]);
    for (const StudyRow& row : c->rows) {
      const auto v = MetricOf(*c, row, s.metric);
      if (v) a.y1 = std::max(a.y1, *v + MetricStdOf(*c, row, s.metric).value_or(0.0));
    }
    if (s.metric == "rmse_m" && c->pcrb_rmse_m) a.y1 = std::max(a.y1, *c->pcrb_rmse_m);
  }
  if (s.metric == "rmse_over_pcrb") a.y1 = std::max(a.y1, 1.0);
  if (!std::isfinite(a.x0)) a.x0 = a.x1 = 0.0;
  const double pad = 0.05 * (a.x1 - a.x0);
  a.x0 -= pad;
  a.x1 += pad;
  a.y1 *= 1.1;
  // The legend column: a line sample and the longest label (about 6.5 px per character at 11 px).
  size_t longest = std::string("PCRB (smoother)").size();
  for (const std::string& id : s.estimators) longest = std::max(longest, id.size());
  a.legend_w = 44 + 6.5 * static_cast<double>(longest);
  a.w += a.legend_w;
  a.h = std::max(a.h, 2 * a.m + 16 + 15.0 * static_cast<double>(s.estimators.size() + 1));
  a.Fix();
  const std::vector<report::LineStyle> styles = report::AssignStyles(s.estimators);
  std::ostringstream out;
  out << std::fixed << std::setprecision(1);
  out << report::Open(a, "sweep-" + s.name, s.title.empty() ? s.name : s.title, s.label, s.metric);
  for (size_t e = 0; e < s.estimators.size(); ++e) {
    const std::string& id = s.estimators[e];
    std::vector<std::pair<double, double>> pts;
    for (const StudyCell* c : sorted) {
      for (const StudyRow& row : c->rows) {
        if (row.estimator != id) continue;
        const auto v = MetricOf(*c, row, s.metric);
        if (!v) continue;
        pts.emplace_back(s.x[c->value], *v);
        const auto sd = MetricStdOf(*c, row, s.metric);
        if (sd) {
          out << "<line class=\"std-bar\" x1=\"" << a.X(s.x[c->value]) << "\" x2=\""
              << a.X(s.x[c->value]) << "\" y1=\"" << a.Y(*v - *sd) << "\" y2=\"" << a.Y(*v + *sd)
              << "\" stroke=\"" << styles[e].color << "\"/>\n";
        }
        out << "<circle class=\"point\" cx=\"" << a.X(s.x[c->value]) << "\" cy=\"" << a.Y(*v)
            << "\" r=\"3.5\" fill=\"" << styles[e].color << "\"/>\n";
      }
    }
    out << report::Polyline(
        pts.size(), [&](size_t i) { return pts[i]; }, a, styles[e].color, "estimator-curve", 2.0,
        styles[e].dash);
    out << report::LegendEntry(a, e, id, styles[e].color, styles[e].dash);
  }
  std::vector<std::pair<double, double>> bound;
  for (const StudyCell* c : sorted) {
    if (s.metric == "rmse_m" && c->pcrb_rmse_m) bound.emplace_back(s.x[c->value], *c->pcrb_rmse_m);
    if (s.metric == "rmse_over_pcrb" && c->pcrb_rmse_m) bound.emplace_back(s.x[c->value], 1.0);
  }
  if (!bound.empty()) {
    out << report::Polyline(
        bound.size(), [&](size_t i) { return bound[i]; }, a, "#000", "pcrb-curve", 1.5, "6,3");
    out << report::LegendEntry(a, s.estimators.size(), "PCRB (smoother)", "#000", "6,3");
  }
  out << "</svg>\n";
  return out.str();
}

std::string SweepTable(const StudyResult& r, int k) {
  const StudySweep& s = r.manifest.sweeps[k];
  std::ostringstream out;
  out << std::fixed << std::setprecision(3);
  out << "<table class=\"sweep\"><tr><th>" << report::Escape(s.label) << "</th>";
  for (const std::string& id : s.estimators) out << "<th>" << report::Escape(id) << "</th>";
  out << "<th>PCRB [m]</th></tr>\n";
  for (const StudyCell* c : CellsOf(r, k)) {
    out << "<tr><td>" << report::Escape(s.values[c->value]) << "</td>";
    for (const std::string& id : s.estimators) {
      out << "<td>";
      for (const StudyRow& row : c->rows) {
        if (row.estimator != id) continue;
        const auto v = MetricOf(*c, row, s.metric);
        const auto sd = MetricStdOf(*c, row, s.metric);
        if (v) {
          out << *v;
          if (sd) out << " &plusmn; " << *sd;
        } else {
          out << "failed: " << report::Escape(row.status.message());
        }
      }
      out << "</td>";
    }
    out << "<td>";
    if (c->pcrb_rmse_m)
      out << *c->pcrb_rmse_m;
    else
      out << report::Escape(c->pcrb_note.empty() ? "-" : c->pcrb_note);
    out << "</td></tr>\n";
  }
  out << "</table>\n";
  return out.str();
}

}  // namespace

std::string RenderStudyHtml(const StudyResult& r) {
  const StudyManifest& m = r.manifest;
  std::ostringstream s;
  s << "<!DOCTYPE html>\n<html><head><meta charset=\"utf-8\"><title>walkgraph study: "
    << report::Escape(m.name) << "</title>\n<style>body{font-family:sans-serif;margin:16px}"
    << "table{border-collapse:collapse;margin:8px 0}td,th{border:1px solid #ccc;padding:3px 8px;"
    << "text-align:right}svg{margin:4px}</style></head><body>\n";
  s << "<h1>walkgraph study: " << report::Escape(m.name) << "</h1>\n";
  if (!m.description.empty()) s << "<p>" << report::Escape(m.description) << "</p>\n";
  s << "<p>manifest: " << report::Escape(m.path) << "</p>\n";
  for (size_t k = 0; k < m.sweeps.size(); ++k) {
    const StudySweep& sw = m.sweeps[k];
    s << "<h2 id=\"" << report::Escape(sw.name) << "\">" << report::Escape(sw.name)
      << (sw.title.empty() ? "" : ": " + report::Escape(sw.title)) << "</h2>\n";
    s << "<p>"
      << report::Escape(sw.scenario.empty() ? "walk " + sw.walk_dir : "scenario " + sw.scenario)
      << ", " << sw.runs << " run" << (sw.runs == 1 ? "" : "s") << " per value, seed " << sw.seed
      << "; " << report::Escape(sw.metric) << " against " << report::Escape(sw.label) << "</p>\n";
    s << "<div>" << SweepPlot(r, static_cast<int>(k)) << "</div>\n";
    s << SweepTable(r, static_cast<int>(k));
  }
  s << "</body></html>\n";
  return s.str();
}

Status WriteStudy(const StudyResult& r, const std::string& out_dir, const OutputOptions& options) {
  const std::string csv = StudyCsv(r), timing = StudyTimingCsv(r), html = RenderStudyHtml(r);
  return WriteOutputFolder(out_dir, options, [&](const std::string& tmp_dir) {
    const fs::path tmp(tmp_dir);
    for (const auto& file : {std::pair<const char*, const std::string*>{"study.csv", &csv},
                             {"timing.csv", &timing},
                             {"study.html", &html}}) {
      const std::string* text = file.second;  // (clang: lambdas cannot capture bindings)
      WG_RETURN_IF_ERROR(WriteFileInOutput((tmp / file.first).string(), [&](std::ostream& out) {
        out << *text;
        return true;
      }));
    }
    return Status::Ok();
  });
}

}  // namespace walkgraph
