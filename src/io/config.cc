#include "walkgraph/config.h"

#include <fstream>

namespace walkgraph {

namespace {

std::string LineOf(const YAML::Node& node) {
  const YAML::Mark mark = node.Mark();
  return mark.line >= 0 ? " (line " + std::to_string(mark.line + 1) + ")" : "";
}

}  // namespace

ConfigReader::ConfigReader(YAML::Node node, std::string context)
    : node_(std::move(node)), context_(std::move(context)) {
  if (node_.IsDefined() && !node_.IsNull() && !node_.IsMap()) {
    first_error_ = InvalidArgument(context_ + LineOf(node_) + ": expected a map of options");
  }
}

template <typename T>
void ConfigReader::ReadScalar(const std::string& key, T* value, const char* type_name) {
  known_.insert(key);
  if (!first_error_.ok() || !node_.IsMap()) return;
  const YAML::Node child = node_[key];
  if (!child.IsDefined() || child.IsNull()) return;
  try {
    if (!child.IsScalar()) throw YAML::Exception(child.Mark(), "not a scalar");
    *value = child.as<T>();
  } catch (const YAML::Exception&) {
    first_error_ = InvalidArgument(context_ + LineOf(child) + ": option '" + key +
                                   "' must be a " + type_name);
  }
}

void ConfigReader::Read(const std::string& key, double* value) { ReadScalar(key, value, "number"); }
void ConfigReader::Read(const std::string& key, int* value) { ReadScalar(key, value, "integer"); }
void ConfigReader::Read(const std::string& key, bool* value) {
  ReadScalar(key, value, "boolean (true/false)");
}
void ConfigReader::Read(const std::string& key, std::string* value) {
  ReadScalar(key, value, "string");
}

YAML::Node ConfigReader::Child(const std::string& key) {
  known_.insert(key);
  if (!node_.IsMap()) return YAML::Node(YAML::NodeType::Undefined);
  return node_[key];
}

Status ConfigReader::Finish() const {
  if (!first_error_.ok()) return first_error_;
  if (!node_.IsMap()) return Status::Ok();
  for (const auto& kv : node_) {
    if (!kv.first.IsScalar()) {
      return InvalidArgument(context_ + LineOf(kv.first) + ": option names must be plain words");
    }
    const std::string key = kv.first.Scalar();
    if (known_.count(key) == 0) {
      std::string list;
      for (const auto& k : known_) list += (list.empty() ? "" : ", ") + k;
      return InvalidArgument(context_ + LineOf(kv.first) + ": unknown option '" + key +
                             "'; known options: " + list);
    }
  }
  return Status::Ok();
}

StatusOr<YAML::Node> LoadYamlFile(const std::string& path) {
  std::ifstream in(path);
  if (!in) return NotFound(path + ": cannot open file");
  try {
    return YAML::Load(in);
  } catch (const YAML::Exception& e) {
    return InvalidArgument(path + ":" + std::to_string(e.mark.line + 1) + ": " + e.msg);
  }
}

}  // namespace walkgraph
