// Parameter studies: the manifest, read and validated (study.h).
#include "walkgraph/study.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <filesystem>
#include <set>

#include "config/reader.h"
#include "eval/pcrb_yaml.h"
#include "study/study_internal.h"
#include "util/input_file.h"
#include "util/text.h"
#include "walkgraph/config.h"
#include "walkgraph/simulate.h"

namespace walkgraph {

namespace fs = std::filesystem;
using internal::CellAt;
using internal::CellConfig;
using internal::CellOverrides;
using internal::FieldOf;

namespace {}  // namespace

namespace internal {

// The figure of `m` (ErrorStatFields), or null.
double ErrorStats::*FieldOf(const std::string& m) {
  for (const ErrorStatField& f : ErrorStatFields()) {
    if (m == f.name) return f.field;
  }
  return nullptr;
}

}  // namespace internal

namespace {

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

}  // namespace

namespace internal {

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

}  // namespace internal

namespace {

std::string CellName(const StudySweep& sweep, size_t value) {
  return "sweep '" + sweep.name + "', value " + sweep.values[value];
}

}  // namespace

namespace internal {

std::string CellAt(const StudyManifest& m, const StudySweep& sweep, size_t value) {
  return m.path + ":" + std::to_string(sweep.value_lines[value]) + ": " + CellName(sweep, value);
}

}  // namespace internal

namespace {

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

}  // namespace walkgraph
