// Reading an estimator's Options from YAML: every key must be known, every value well typed.
//
//   ConfigReader r(node, "tarrio-kf");
//   r.Read("sigma_p_m", &opts.sigma_p_m, "process noise of the position random walk (eq. 9)");
//   WG_RETURN_IF_ERROR(r.Finish());   // reports unknown keys and type errors with line numbers
#ifndef WALKGRAPH_CONFIG_H_
#define WALKGRAPH_CONFIG_H_

#include <cstdint>
#include <functional>
#include <set>
#include <string>
#include <variant>
#include <vector>

#include <yaml-cpp/yaml.h>

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

// An option and the value it holds before the YAML is applied: its default.
struct OptionDefault {
  std::string key;  // nested options as "parent.key"
  std::variant<double, int, bool, std::string> value;
  std::vector<std::string> allowed;  // a string option's values (empty: any string)
  std::string doc;                   // one line: what it does (empty when its Read gave none)
};
// An option's unit from its key: walkgraph's options carry their SI unit as the key's suffix
// (_s, _m, _mps, _mps2, _rad, _radps, _radps2, _hz, _db, _dbm, _deg, …, and "_X_sqrts" for
// X/√s); empty when the key names none (a count, a factor, a σ multiple).
std::string OptionUnit(const std::string& key);
// Runs `fn` (e.g. creating an estimator from an empty config) while every ConfigReader of this
// thread records the keys it is asked for with the values they hold: the options `fn` reads and
// their defaults, in reading order (each key once). Fails with `fn`'s Status.
StatusOr<std::vector<OptionDefault>> RecordOptionDefaults(const std::function<Status()>& fn);

// How every option and manifest value is read from its YAML text: numbers decimal and finite
// ("0x5", ".nan", ".inf", "1e999" are refused; integers within their type's range), booleans
// true/false. False when the text is not one.
bool ParseScalar(const std::string& text, double* value);
bool ParseScalar(const std::string& text, int* value);
bool ParseScalar(const std::string& text, uint64_t* value);
bool ParseScalar(const std::string& text, bool* value);
bool ParseScalar(const std::string& text, std::string* value);

// Loads a YAML file; errors name the file and line. The file must be a regular file of at most
// 16 MiB holding one YAML document without repeated keys.
StatusOr<YAML::Node> LoadYamlFile(const std::string& path);
// The same on text; `path` names it in messages.
StatusOr<YAML::Node> LoadYamlText(const std::string& text, const std::string& path);

}  // namespace walkgraph

#endif  // WALKGRAPH_CONFIG_H_
