// Reading an estimator's Options from YAML (internal: the config layer): every key must be known,
// every value well typed.
//
//   ConfigReader r(node, "tarrio-kf");
//   r.Read("sigma_p_m", &opts.sigma_p_m, "process noise of the position random walk (eq. 9)");
//   WG_RETURN_IF_ERROR(r.Finish());   // reports unknown keys and type errors with line numbers
#ifndef WALKGRAPH_SRC_CONFIG_READER_H_
#define WALKGRAPH_SRC_CONFIG_READER_H_

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

  // Reads `key` into `value` if present; the first failure is kept and reported by Finish().
  // `doc`: what the option does, in one line, shown by `walkgraph list ID` (from this call, so
  // the list cannot drift from what the reader accepts).
  void Read(const std::string& key, double* value, const char* doc = nullptr);
  void Read(const std::string& key, int* value, const char* doc = nullptr);
  void Read(const std::string& key, bool* value, const char* doc = nullptr);
  void Read(const std::string& key, std::string* value, const char* doc = nullptr);
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

 private:
  template <typename T>
  void ReadScalar(const std::string& key, T* value, const char* type_name, const char* doc);

  YAML::Node node_;
  std::string context_;
  std::string record_path_;  // under RecordOptionDefaults: this reader's prefix ("pdr.")
  std::set<std::string> known_;
  Status first_error_;
};

// Loads a YAML file; errors name the file and line. The file must be a regular file of at most
// 16 MiB holding one YAML document without repeated keys.
StatusOr<YAML::Node> LoadYamlFile(const std::string& path);
// The same on text; `path` names it in messages.
StatusOr<YAML::Node> LoadYamlText(const std::string& text, const std::string& path);

}  // namespace walkgraph

#endif  // WALKGRAPH_SRC_CONFIG_READER_H_
