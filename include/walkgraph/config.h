// The configuration of an estimator (its options) or of a simulated scenario (its overrides):
// a YAML map, parsed, held as a value. Absent keys keep the defaults; each reader refuses keys
// it does not know, with the line.
//
//   auto config = walkgraph::Config::Parse("{lag_s: 5, path_loss: global}");
//   auto est = walkgraph::EstimatorRegistry::Builtin().Create("fg-window", *config);
//
// The library reads configurations with yaml-cpp, which stays out of its public headers: code
// that has yaml-cpp itself (the library, its tests, the Python module) converts a YAML::Node
// implicitly and reads Config::node(); other code needs neither.
#ifndef WALKGRAPH_CONFIG_H_
#define WALKGRAPH_CONFIG_H_

#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <variant>
#include <vector>

#include "walkgraph/status.h"

namespace YAML {
class Node;
}  // namespace YAML

namespace walkgraph {

class Config {
 public:
  Config();                        // no keys: every default
  Config(const YAML::Node& node);  // NOLINT(runtime/explicit): shares the node (no copy)
  // `yaml_text`: one YAML document holding a map (or nothing); `origin` names it in messages.
  static StatusOr<Config> Parse(const std::string& yaml_text, const std::string& origin = "config");
  // A YAML file (at most 16 MiB, one document, no repeated keys); errors name the file and line.
  static StatusOr<Config> Load(const std::string& path);

  bool empty() const;          // null or absent: no keys
  std::string ToYaml() const;  // the configuration as YAML text
  const YAML::Node& node() const;

 private:
  std::shared_ptr<const YAML::Node> node_;
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

}  // namespace walkgraph

#endif  // WALKGRAPH_CONFIG_H_
