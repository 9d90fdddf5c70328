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

// ------------------------------------------------------------------ manifest checks
// The manifest is read by ConfigReader (ForFile: "MANIFEST:LINE: ..."): every key known, every
// value well typed. What a type cannot say is checked here, at the value's line.

int LineOf(const YAML::Node& n) { return n.Mark().line >= 0 ? n.Mark().line + 1 : 0; }

// A Monte Carlo run count: in [1, kMaxMonteCarloRuns].
Status CheckRuns(const ConfigReader& r, int runs) {
  if (runs < 1) return r.Error("runs", "runs must be >= 1");
  if (runs > kMaxMonteCarloRuns) {
    return r.Error("runs", "runs " + std::to_string(runs) + " over the cap of " +
                               std::to_string(kMaxMonteCarloRuns) +
                               " (10^6 runs take days; split a larger study into seeds)");
  }
  return Status::Ok();
}

Status CheckScoreFrom(const ConfigReader& r, double score_from_s) {
  if (std::isfinite(score_from_s) && score_from_s >= 0.0) return Status::Ok();
  return r.Error("score_from_s", "score_from_s must be a number >= 0");
}

Status CheckMetric(const ConfigReader& r, const std::string& m) {
  if (KnownMetric(m)) return Status::Ok();
  std::vector<std::string> all;
  for (const ErrorStatField& f : ErrorStatFields()) all.push_back(f.name);
  all.push_back("rmse_over_pcrb");
  return r.Error("metric", "unknown metric " + internal::Quoted(m) + "; known: " + Join(all));
}

// `estimators`: a non-empty list of registered ids, each once.
Status CheckEstimators(const ConfigReader& r, const std::vector<std::string>& ids,
                       const EstimatorRegistry& registry) {
  if (ids.empty()) {
    return r.Error("estimators", "estimators must be a non-empty list of estimator ids");
  }
  for (size_t i = 0; i < ids.size(); ++i) {
    const int at = static_cast<int>(i);
    if (registry.Find(ids[i]) == nullptr) {
      return r.Error(
          "estimators",
          "unknown estimator " + internal::Quoted(ids[i]) + "; known: " + Join(registry.Ids()), at);
    }
    if (std::find(ids.begin(), ids.begin() + at, ids[i]) != ids.begin() + at) {
      return r.Error("estimators", "estimator '" + ids[i] + "' listed twice", at);
    }
  }
  return Status::Ok();
}

// A scalar entry of a Child() map (an estimator id, an option key) as a string.
StatusOr<std::string> EntryText(const ConfigReader& r, const YAML::Node& n,
                                const std::string& what) {
  if (!n.IsScalar()) return r.ErrorAt(n, what + " must be a string");
  return n.Scalar();
}

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
Status ParseValues(const ConfigReader& r, const std::vector<std::string>& values,
                   const std::string& what, StudySweep* s) {
  if (values.empty())
    return r.Error("values", what + ": values must be a non-empty list of numbers");
  if (values.size() > kMaxSweepValues) {
    return r.Error("values", what + ": " + std::to_string(values.size()) +
                                 " values, over the cap of " + std::to_string(kMaxSweepValues) +
                                 " per sweep (a study that cannot finish); split the sweep");
  }
  for (size_t i = 0; i < values.size(); ++i) {
    const int at = static_cast<int>(i);
    double x = 0.0;
    if (!ParseScalar(values[i], &x)) {
      return r.Error(
          "values", "a swept value must be a number, got " + internal::QuotedNumber(values[i]), at);
    }
    if (!std::isfinite(x)) return r.Error("values", what + ": values must be finite numbers", at);
    if (std::find(s->x.begin(), s->x.end(), x) != s->x.end()) {
      return r.Error("values", what + ": value " + values[i] + " given twice", at);
    }
    s->values.push_back(values[i]);
    s->x.push_back(x);
    s->value_lines.push_back(r.Line("values", at));
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

// A sweep's keys as read (ReadSweepKeys), before the checks that need several of them.
struct SweepKeys {
  std::string walk;
  YAML::Node overrides, estimator_option;
  std::vector<std::string> values, estimators;
};

// Every key of a sweep, typed; the top level's settings where one is not given.
Status ReadSweepKeys(ConfigReader& r, const SweepDefaults& top, StudySweep* s, SweepKeys* k) {
  r.Read("name", &s->name);
  r.Read("title", &s->title);
  r.Read("label", &s->label);
  r.Read("scenario", &s->scenario);
  r.Read("walk", &k->walk);
  k->overrides = r.Child("overrides");
  r.Read("scenario_override", &s->scenario_override);
  k->estimator_option = r.Child("estimator_option");
  r.Read("values", &k->values);
  r.Read("estimators", &k->estimators);
  s->runs = top.runs;
  r.Read("runs", &s->runs);
  s->seed = top.seed;
  r.Read("seed", &s->seed);
  s->metric = top.metric;
  r.Read("metric", &s->metric);
  s->score_from_s = top.score_from_s;
  r.Read("score_from_s", &s->score_from_s);
  return r.Finish();
}

// A sweep's data: a simulated scenario (with its overrides) or a recorded walk.
Status CheckSweepData(const ConfigReader& r, const SweepKeys& k, const std::string& path,
                      const std::string& what, StudySweep* s) {
  if (r.Has("scenario") == r.Has("walk")) {
    return r.Error("", what + ": give exactly one of 'scenario' or 'walk'");
  }
  if (r.Has("scenario")) {
    std::vector<std::string> names;
    for (const ScenarioInfo& info : Scenarios()) names.push_back(info.name);
    if (std::find(names.begin(), names.end(), s->scenario) == names.end()) {
      return r.Error("scenario", "unknown scenario " + internal::Quoted(s->scenario) +
                                     "; known: " + Join(names));
    }
    if (r.Has("overrides")) {
      if (!k.overrides.IsMap()) {
        return r.Error("overrides", what + ": overrides must be a map of simulator options");
      }
      s->overrides = k.overrides;
    }
    return Status::Ok();
  }
  fs::path dir(k.walk);
  if (dir.is_relative()) dir = fs::path(path).parent_path() / dir;
  std::error_code ec;
  if (!fs::is_directory(dir, ec)) {
    return r.Error("walk", what + ": walk folder " + dir.string() + " does not exist");
  }
  s->walk_dir = dir.string();
  if (r.Has("overrides") || r.Has("scenario_override")) {
    return r.Error(r.Has("overrides") ? "overrides" : "scenario_override",
                   what + ": a recorded walk has no simulator overrides");
  }
  if (r.Has("runs") && s->runs != 1) return r.Error("runs", what + ": a recorded walk is one run");
  return Status::Ok();
}

// A sweep's estimators (the top level's where not given) and settings.
Status CheckSweepSettings(const ConfigReader& r, const SweepKeys& k, const std::string& what,
                          const SweepDefaults& top, const EstimatorRegistry& registry,
                          StudySweep* s) {
  if (r.Has("estimators")) {
    WG_RETURN_IF_ERROR(CheckEstimators(r, k.estimators, registry));
    s->estimators = k.estimators;
  } else if (!top.ids.empty()) {
    s->estimators = top.ids;
  } else {
    return r.Error("", what + ": no estimators (give 'estimators' here or at the top)");
  }
  WG_RETURN_IF_ERROR(CheckRuns(r, s->runs));
  if (!s->walk_dir.empty()) s->runs = 1;
  WG_RETURN_IF_ERROR(CheckMetric(r, s->metric));
  return CheckScoreFrom(r, s->score_from_s);
}

// estimator_option as {estimator id: option key}: the keys by estimator; the default label
// joins the distinct keys.
Status ParseOptionKeyMap(const ConfigReader& r, const YAML::Node& opt, const std::string& what,
                         StudySweep* s, std::string* default_label) {
  std::vector<std::string> keys;
  for (const auto& kv : opt) {
    WG_ASSIGN_OR_RETURN(std::string id, EntryText(r, kv.first, "estimator id"));
    if (std::find(s->estimators.begin(), s->estimators.end(), id) == s->estimators.end()) {
      return r.ErrorAt(kv.first, what + ": estimator '" + id + "' is not in the sweep's list (" +
                                     Join(s->estimators) + ")");
    }
    WG_ASSIGN_OR_RETURN(std::string key, EntryText(r, kv.second, "option key of " + id));
    s->option_keys[id] = key;
    if (std::find(keys.begin(), keys.end(), key) == keys.end()) keys.push_back(key);
  }
  for (const std::string& key : keys) {
    *default_label += (default_label->empty() ? "" : " / ") + key;
  }
  return Status::Ok();
}

// What a sweep varies: a simulator override or an estimator option (one key for every
// estimator, or one per estimator); the label defaults to it.
Status CheckSweptParameter(const ConfigReader& r, const SweepKeys& k, const std::string& what,
                           StudySweep* s) {
  if (r.Has("scenario_override") == r.Has("estimator_option")) {
    return r.Error("", what + ": give exactly one of 'scenario_override' or 'estimator_option'");
  }
  std::string default_label;
  if (r.Has("scenario_override")) {
    const YAML::Node& base = s->overrides.node();  // const: a lookup must not add the key
    if (base.IsDefined() && base[s->scenario_override]) {
      return r.Error("scenario_override",
                     what + ": '" + s->scenario_override + "' is both swept and in overrides");
    }
    default_label = s->scenario_override;
  } else if (k.estimator_option.IsScalar()) {
    const std::string key = k.estimator_option.Scalar();
    for (const std::string& id : s->estimators) s->option_keys[id] = key;
    default_label = key;
  } else if (k.estimator_option.IsMap() && k.estimator_option.size() > 0) {
    WG_RETURN_IF_ERROR(ParseOptionKeyMap(r, k.estimator_option, what, s, &default_label));
  } else {
    return r.Error("estimator_option",
                   what + ": estimator_option must be an option key or {estimator: key}");
  }
  if (s->label.empty()) s->label = default_label;
  return Status::Ok();
}

StatusOr<StudySweep> ParseSweep(const std::string& path, const YAML::Node& node,
                                const StudyManifest& m, const SweepDefaults& top,
                                const EstimatorRegistry& registry) {
  StudySweep s;
  s.line = LineOf(node);
  if (!node.IsMap()) {
    return InvalidArgument(path + ":" + std::to_string(s.line) + ": each sweep must be a map");
  }
  ConfigReader r = ConfigReader::ForFile(node, path, "a sweep");
  SweepKeys k;
  WG_RETURN_IF_ERROR(ReadSweepKeys(r, top, &s, &k));
  if (!r.Has("name")) return r.Error("", "a sweep needs a name");
  if (!ValidSweepName(s.name)) {
    return r.Error("name", "sweep name '" + s.name + "' may use letters, digits, . _ -");
  }
  const std::string what = "sweep '" + s.name + "'";
  WG_RETURN_IF_ERROR(CheckSweepData(r, k, path, what, &s));
  WG_RETURN_IF_ERROR(CheckSweepSettings(r, k, what, top, registry, &s));
  WG_RETURN_IF_ERROR(CheckSweptParameter(r, k, what, &s));
  WG_RETURN_IF_ERROR(ParseValues(r, k.values, what, &s));
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

// configs: {estimator id: options}, each id registered, each options a map (or nothing).
Status ParseConfigs(const ConfigReader& r, const YAML::Node& configs,
                    const EstimatorRegistry& registry, StudyManifest* m) {
  if (!configs.IsMap()) return r.Error("configs", "configs must be a map {estimator id: options}");
  for (const auto& kv : configs) {
    WG_ASSIGN_OR_RETURN(std::string id, EntryText(r, kv.first, "estimator id"));
    if (registry.Find(id) == nullptr) {
      return r.ErrorAt(kv.first, "configs: unknown estimator " + internal::Quoted(id) +
                                     "; known: " + Join(registry.Ids()));
    }
    if (!kv.second.IsMap() && !kv.second.IsNull()) {
      return r.ErrorAt(kv.second, "configs: the options of " + id + " must be a map");
    }
    m->configs[id] = kv.second;
  }
  return Status::Ok();
}

StatusOr<StudyManifest> ParseManifestRoot(const YAML::Node& root, const std::string& path,
                                          const EstimatorRegistry& registry) {
  if (!root.IsMap()) {
    return InvalidArgument(path + ":" + std::to_string(LineOf(root)) +
                           ": a study manifest must be a map (see study.h)");
  }
  ConfigReader r = ConfigReader::ForFile(root, path, "the manifest");
  StudyManifest m;
  m.path = path;
  SweepDefaults top{{}, 1, 1, "rmse_m", 0.0};
  r.Read("name", &m.name);
  r.Read("description", &m.description);
  r.Read("estimators", &top.ids);
  const YAML::Node configs = r.Child("configs");
  r.Read("metric", &top.metric);
  r.Read("runs", &top.runs);
  r.Read("seed", &top.seed);
  r.Read("score_from_s", &top.score_from_s);
  r.Read("pcrb", &m.pcrb);
  const YAML::Node pcrb_options = r.Child("pcrb_options");
  const YAML::Node sweeps = r.Child("sweeps");
  WG_RETURN_IF_ERROR(r.Finish());
  if (!r.Has("name")) return r.Error("", "the manifest needs a name");
  if (r.Has("estimators")) WG_RETURN_IF_ERROR(CheckEstimators(r, top.ids, registry));
  if (r.Has("configs")) WG_RETURN_IF_ERROR(ParseConfigs(r, configs, registry, &m));
  WG_RETURN_IF_ERROR(CheckMetric(r, top.metric));
  WG_RETURN_IF_ERROR(CheckRuns(r, top.runs));
  WG_RETURN_IF_ERROR(CheckScoreFrom(r, top.score_from_s));
  if (r.Has("pcrb_options")) {
    WG_ASSIGN_OR_RETURN(
        m.pcrb_options,
        PcrbOptionsFromYaml(
            pcrb_options, path + ":" + std::to_string(r.Line("pcrb_options")) + ": pcrb_options"));
  }
  if (!r.Has("sweeps") || !sweeps.IsSequence() || sweeps.size() == 0) {
    return r.Error("sweeps", "the manifest needs a non-empty list of sweeps");
  }
  std::set<std::string> names;
  for (const YAML::Node& node : sweeps) {
    WG_ASSIGN_OR_RETURN(StudySweep s, ParseSweep(path, node, m, top, registry));
    if (!names.insert(s.name).second) {
      return InvalidArgument(path + ":" + std::to_string(LineOf(node["name"])) + ": sweep name '" +
                             s.name + "' used twice");
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
