// Reading an estimator's Options from YAML (internal: the config layer): every key must be known,
// every value well typed.
//
//   ConfigReader r(node, "tarrio-kf");
//   r.Read("sigma_p_m", &opts.sigma_p_m, "process noise of the position random walk (eq. 9)");
//   WG_RETURN_IF_ERROR(r.Finish());   // reports unknown keys and type errors with line numbers
#ifndef WALKGRAPH_SRC_CONFIG_READER_H_
#define WALKGRAPH_SRC_CONFIG_READER_H_

#include <cstdint>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include <yaml-cpp/yaml.h>

#include "walkgraph/config.h"
#include "walkgraph/status.h"

namespace walkgraph {

class ConfigReader {
 public:
  ConfigReader(YAML::Node node, std::string context);
  // A map of a file's own settings (the study manifest) rather than an estimator's options:
  // messages read "PATH:LINE: ..." and call its entries keys ("unknown key 'k' in WHAT;
  // known: ..."); `what` names the map ("the manifest", "a sweep").
  static ConfigReader ForFile(YAML::Node node, std::string path, std::string what);

  // Reads `key` into `value` if present; the first failure is kept and reported by Finish().
  // `doc`: what the option does, in one line, shown by `walkgraph list ID` (from this call, so
  // the list cannot drift from what the reader accepts).
  void Read(const std::string& key, double* value, const char* doc = nullptr);
  void Read(const std::string& key, int* value, const char* doc = nullptr);
  void Read(const std::string& key, bool* value, const char* doc = nullptr);
  void Read(const std::string& key, std::string* value, const char* doc = nullptr);
  void Read(const std::string& key, uint64_t* value, const char* doc = nullptr);  // e.g. a seed
  // A list of plain values, each as written ("[a, 1.5]" is {"a", "1.5"}; one value is not a
  // list); check or convert the items after Finish(), with Line/Error(key, message, index).
  void Read(const std::string& key, std::vector<std::string>* value, const char* doc = nullptr);
  // A string option with a fixed set of values: any other is an error naming them, and
  // `walkgraph list ID` shows them (from this same list).
  void Read(const std::string& key, std::string* value, const std::vector<std::string>& allowed,
            const char* doc = nullptr);
  // An enum option by name: `names` is the option's one table of (name, value), which its
  // error message and `walkgraph list ID` show.
  template <typename E>
  void ReadEnum(const std::string& key, E* value,
                const std::vector<std::pair<std::string, E>>& names, const char* doc = nullptr) {
    std::string text;
    std::vector<std::string> allowed;
    for (const auto& [name, v] : names) {
      allowed.push_back(name);
      if (v == *value) text = name;
    }
    Read(key, &text, allowed, doc);
    for (const auto& [name, v] : names) {
      if (name == text) *value = v;
    }
  }
  // A sub-map, for nested options; returns an undefined node when absent.
  YAML::Node Child(const std::string& key);

  // OK, or the first type error, or the first key that no Read() asked for.
  Status Finish() const;

  // For the checks beyond a value's type (a range, a known name), with the value's line:
  // True when `key` is given with a value (a null value is not given, as for Read).
  bool Has(const std::string& key) const;
  // The 1-based line of `key`'s value, or of item `index` of its list; the map's own line when
  // `key` is absent or `index` beyond the list (0 when the node has none).
  int Line(const std::string& key, int index = -1) const;
  // `message` at that line: "CONTEXT (line N): message", or "PATH:N: message" (ForFile). An
  // empty `key`: the map's own line.
  Status Error(const std::string& key, const std::string& message, int index = -1) const;
  // `message` at `node`'s line: for the entries of a Child() map whose keys are not fixed.
  Status ErrorAt(const YAML::Node& node, const std::string& message) const;

 private:
  template <typename T>
  void ReadScalar(const std::string& key, T* value, const char* type_name, const char* doc);
  // "CONTEXT (line N)" or "PATH:N" (ForFile) for messages at `node`.
  std::string At(const YAML::Node& node) const;
  std::string At(int line) const;

  YAML::Node node_;
  std::string context_;
  std::string file_what_;    // ForFile: what the map is; empty for an estimator's options
  std::string record_path_;  // under RecordOptionDefaults: this reader's prefix ("pdr.")
  std::set<std::string> known_;
  std::vector<std::string> known_in_order_;  // the same, in reading order
  Status first_error_;
};

// Loads a YAML file; errors name the file and line. The file must be a regular file of at most
// 16 MiB holding one YAML document without repeated keys.
StatusOr<YAML::Node> LoadYamlFile(const std::string& path);
// The same on text; `path` names it in messages.
StatusOr<YAML::Node> LoadYamlText(const std::string& text, const std::string& path);

}  // namespace walkgraph

#endif  // WALKGRAPH_SRC_CONFIG_READER_H_
