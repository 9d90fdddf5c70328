#include "config/reader.h"

#include <algorithm>
#include <cerrno>
#include <charconv>
#include <set>
#include <sstream>
#include <variant>
#include <vector>

#include <yaml-cpp/eventhandler.h>

#include "util/csv_reader.h"
#include "util/input_file.h"
#include "util/text.h"

namespace walkgraph {

Config::Config() : node_(std::make_shared<const YAML::Node>()) {}
Config::Config(const YAML::Node& node) : node_(std::make_shared<const YAML::Node>(node)) {}

StatusOr<Config> Config::Parse(const std::string& yaml_text, const std::string& origin) {
  WG_ASSIGN_OR_RETURN(YAML::Node node, LoadYamlText(yaml_text, origin));
  return Config(node);
}

StatusOr<Config> Config::Load(const std::string& path) {
  WG_ASSIGN_OR_RETURN(YAML::Node node, LoadYamlFile(path));
  return Config(node);
}

bool Config::empty() const { return !node_->IsDefined() || node_->IsNull(); }
std::string Config::ToYaml() const { return YAML::Dump(*node_); }
const YAML::Node& Config::node() const { return *node_; }

namespace {

std::string LineOf(const YAML::Node& node) {
  const YAML::Mark mark = node.Mark();
  return mark.line >= 0 ? " (line " + std::to_string(mark.line + 1) + ")" : "";
}

template <typename Int>
bool ParseInteger(const std::string& text, Int* value) {
  const char* begin = text.data() + (!text.empty() && text[0] == '+' ? 1 : 0);
  const char* end = text.data() + text.size();
  const auto [ptr, ec] = std::from_chars(begin, end, *value);
  return begin != end && ec == std::errc() && ptr == end;
}

}  // namespace

// Numbers are read as the walk format's CSV fields are: decimal only.
bool ParseScalar(const std::string& text, double* value) {
  return internal::ParseFiniteDouble(text, value);
}
bool ParseScalar(const std::string& text, int* value) { return ParseInteger(text, value); }
bool ParseScalar(const std::string& text, uint64_t* value) {
  return !text.empty() && text[0] != '-' && ParseInteger(text, value);
}
bool ParseScalar(const std::string& text, bool* value) {
  if (text == "true" || text == "True" || text == "TRUE") return *value = true, true;
  if (text == "false" || text == "False" || text == "FALSE") return *value = false, true;
  return false;
}
bool ParseScalar(const std::string& text, std::string* value) {
  *value = text;
  return true;
}

namespace {

// RecordOptionDefaults' sink (this thread's), and the key under which Child() hands a nested
// reader its prefix while recording.
thread_local std::vector<OptionDefault>* g_recording = nullptr;
constexpr char kRecordPathKey[] = "\x01walkgraph-record-path";

}  // namespace

StatusOr<std::vector<OptionDefault>> RecordOptionDefaults(const std::function<Status()>& fn) {
  std::vector<OptionDefault> recorded;
  std::vector<OptionDefault>* outer = g_recording;
  g_recording = &recorded;
  const Status s = fn();
  g_recording = outer;
  if (!s.ok()) return s;
  std::vector<OptionDefault> unique;
  std::set<std::string> seen;
  for (OptionDefault& d : recorded) {
    if (seen.insert(d.key).second) unique.push_back(std::move(d));
  }
  return unique;
}

ConfigReader::ConfigReader(YAML::Node node, std::string context)
    : node_(std::move(node)), context_(std::move(context)) {
  if (g_recording != nullptr && node_.IsMap() && node_[kRecordPathKey]) {
    record_path_ = node_[kRecordPathKey].Scalar();
    node_.remove(kRecordPathKey);
  }
  if (node_.IsDefined() && !node_.IsNull() && !node_.IsMap()) {
    first_error_ = InvalidArgument(context_ + LineOf(node_) + ": expected a map of options");
  }
}

ConfigReader ConfigReader::ForFile(YAML::Node node, std::string path, std::string what) {
  ConfigReader r(YAML::Node(), std::move(path));  // no map check yet: messages in file form
  r.node_ = std::move(node);
  r.file_what_ = std::move(what);
  if (r.node_.IsDefined() && !r.node_.IsNull() && !r.node_.IsMap()) {
    r.first_error_ = InvalidArgument(r.At(r.node_) + ": " + r.file_what_ + " must be a map");
  }
  return r;
}

std::string ConfigReader::At(int line) const {
  if (file_what_.empty())
    return context_ + (line > 0 ? " (line " + std::to_string(line) + ")" : "");
  return context_ + ":" + std::to_string(line);
}

std::string ConfigReader::At(const YAML::Node& node) const {
  const YAML::Mark mark = node.Mark();
  return At(mark.line >= 0 ? mark.line + 1 : 0);
}

namespace {

// What RecordOptionDefaults shows of a default (its variant has no uint64_t or list).
std::variant<double, int, bool, std::string> Recorded(double v) { return v; }
std::variant<double, int, bool, std::string> Recorded(int v) { return v; }
std::variant<double, int, bool, std::string> Recorded(bool v) { return v; }
std::variant<double, int, bool, std::string> Recorded(const std::string& v) { return v; }
std::variant<double, int, bool, std::string> Recorded(uint64_t v) { return std::to_string(v); }
std::variant<double, int, bool, std::string> Recorded(const std::vector<std::string>& v) {
  return internal::Join(v, ", ");
}

// A list of plain values, each as written.
bool ParseList(const YAML::Node& node, std::vector<std::string>* value) {
  if (!node.IsSequence()) return false;
  std::vector<std::string> items;
  for (const YAML::Node& item : node) {
    if (!item.IsScalar()) return false;
    items.push_back(item.Scalar());
  }
  *value = std::move(items);
  return true;
}

bool ParseNode(const YAML::Node& node, std::vector<std::string>* value) {
  return ParseList(node, value);
}
template <typename T>
bool ParseNode(const YAML::Node& node, T* value) {
  return node.IsScalar() && ParseScalar(node.Scalar(), value);
}

std::string Found(const YAML::Node& node) {
  if (node.IsScalar()) return internal::QuotedNumber(node.Scalar());
  return node.IsSequence() ? "a list" : "a map";
}

}  // namespace

template <typename T>
void ConfigReader::ReadScalar(const std::string& key, T* value, const char* type_name,
                              const char* doc) {
  if (known_.insert(key).second) known_in_order_.push_back(key);
  if (g_recording != nullptr) {
    g_recording->push_back({record_path_ + key, Recorded(*value), {}, doc == nullptr ? "" : doc});
  }
  if (!first_error_.ok() || !node_.IsMap()) return;
  const YAML::Node child = node_[key];
  if (!child.IsDefined() || child.IsNull()) return;
  if (ParseNode(child, value)) return;
  if (file_what_.empty()) {  // an estimator's option: the message as it always was
    first_error_ = InvalidArgument(
        context_ + LineOf(child) + ": option '" + key + "' must be a " + type_name + ", found " +
        (child.IsScalar() ? internal::QuotedNumber(child.Scalar()) : std::string("a list or map")));
    return;
  }
  first_error_ = InvalidArgument(At(child) + ": " + key + " must be a " + type_name + ", found " +
                                 Found(child));
}

void ConfigReader::Read(const std::string& key, double* value, const char* doc) {
  ReadScalar(key, value, "finite decimal number", doc);
}
void ConfigReader::Read(const std::string& key, int* value, const char* doc) {
  ReadScalar(key, value, "decimal integer in [-2147483648, 2147483647]", doc);
}
void ConfigReader::Read(const std::string& key, bool* value, const char* doc) {
  ReadScalar(key, value, "boolean (true/false)", doc);
}
void ConfigReader::Read(const std::string& key, std::string* value, const char* doc) {
  ReadScalar(key, value, "string", doc);
}
void ConfigReader::Read(const std::string& key, uint64_t* value, const char* doc) {
  ReadScalar(key, value, "decimal integer in [0, 18446744073709551615]", doc);
}
void ConfigReader::Read(const std::string& key, std::vector<std::string>* value, const char* doc) {
  ReadScalar(key, value, "list of plain values ([a, b, ...])", doc);
}

bool ConfigReader::Has(const std::string& key) const {
  if (!node_.IsMap()) return false;
  const YAML::Node& map = node_;  // const: a lookup must not add the key
  const YAML::Node child = map[key];
  return child.IsDefined() && !child.IsNull();
}

int ConfigReader::Line(const std::string& key, int index) const {
  const auto line = [](const YAML::Node& n) { return n.Mark().line >= 0 ? n.Mark().line + 1 : 0; };
  if (key.empty() || !Has(key)) return line(node_);
  const YAML::Node& map = node_;
  const YAML::Node child = map[key];
  if (index >= 0 && child.IsSequence() && static_cast<size_t>(index) < child.size()) {
    return line(child[index]);
  }
  return line(child);
}

Status ConfigReader::Error(const std::string& key, const std::string& message, int index) const {
  return InvalidArgument(At(Line(key, index)) + ": " + message);
}

Status ConfigReader::ErrorAt(const YAML::Node& node, const std::string& message) const {
  return InvalidArgument(At(node) + ": " + message);
}

void ConfigReader::Read(const std::string& key, std::string* value,
                        const std::vector<std::string>& allowed, const char* doc) {
  const bool had_error = !first_error_.ok();
  ReadScalar(key, value, "string", doc);
  if (g_recording != nullptr) g_recording->back().allowed = allowed;
  if (had_error || !first_error_.ok() || !node_.IsMap() || !node_[key]) return;
  if (std::find(allowed.begin(), allowed.end(), *value) != allowed.end()) return;
  std::string list;
  for (const std::string& a : allowed) list += (list.empty() ? "" : ", ") + a;
  first_error_ =
      InvalidArgument(context_ + LineOf(node_[key]) + ": option '" + key + "' must be one of " +
                      list + ", found " + internal::Quoted(*value));
}

std::string OptionUnit(const std::string& key) {
  static const std::pair<const char*, const char*> kSuffixes[] = {
      {"_s", "s"},         {"_m", "m"},         {"_mps", "m/s"},       {"_mps2", "m/s²"},
      {"_rad", "rad"},     {"_radps", "rad/s"}, {"_radps2", "rad/s²"}, {"_hz", "Hz"},
      {"_db", "dB"},       {"_dbm", "dBm"},     {"_deg", "°"},         {"_m2", "m²"},
      {"_m2ps4", "m²/s⁴"}, {"_m_s", "m·s"},     {"_hpa", "hPa"},       {"_ms", "ms"}};
  auto ends_with = [](const std::string& k, const std::string& suffix) {
    return k.size() > suffix.size() &&
           k.compare(k.size() - suffix.size(), suffix.size(), suffix) == 0;
  };
  auto unit_of = [&](const std::string& k) -> std::string {  // the longest suffix that fits
    std::string unit;
    size_t length = 0;
    for (const auto& [suffix, u] : kSuffixes) {
      const std::string sfx(suffix);
      if (sfx.size() > length && ends_with(k, sfx)) {
        unit = u;
        length = sfx.size();
      }
    }
    return unit;
  };
  const std::string leaf = key.substr(key.rfind('.') == std::string::npos ? 0 : key.rfind('.') + 1);
  if (ends_with(leaf, "_sqrts")) {
    const std::string base = unit_of(leaf.substr(0, leaf.size() - 6));
    return base.empty() ? "" : base + "/√s";
  }
  return unit_of(leaf);
}

YAML::Node ConfigReader::Child(const std::string& key) {
  if (known_.insert(key).second) known_in_order_.push_back(key);
  if (g_recording != nullptr && (!node_.IsMap() || !node_[key])) {
    YAML::Node child(YAML::NodeType::Map);  // tells the nested reader its prefix
    child[kRecordPathKey] = record_path_ + key + ".";
    return child;
  }
  if (!node_.IsMap()) return YAML::Node(YAML::NodeType::Undefined);
  return node_[key];
}

Status ConfigReader::Finish() const {
  if (!first_error_.ok()) return first_error_;
  if (!node_.IsMap()) return Status::Ok();
  for (const auto& kv : node_) {
    if (!kv.first.IsScalar()) {
      if (!file_what_.empty()) return InvalidArgument(At(kv.first) + ": keys must be plain words");
      return InvalidArgument(context_ + LineOf(kv.first) + ": option names must be plain words");
    }
    const std::string key = kv.first.Scalar();
    if (known_.count(key) == 0) {
      std::string list;
      for (const auto& k : known_) list += (list.empty() ? "" : ", ") + k;
      if (!file_what_.empty()) {  // a file's keys in the order they are read (and documented)
        list = internal::Join(known_in_order_, ", ");
        return InvalidArgument(At(kv.first) + ": unknown key " + internal::Quoted(key) + " in " +
                               file_what_ + "; known: " + list);
      }
      return InvalidArgument(context_ + LineOf(kv.first) + ": unknown option " +
                             internal::Quoted(key) + "; known options: " + list);
    }
  }
  return Status::Ok();
}

namespace {

// yaml-cpp keeps both entries of a repeated key and answers lookups with the first: a repeated
// key is an error, with the line of its second appearance.
// Aliases make a small file expand to an exponential number of nodes (the "billion laughs"):
// at most kMaxYamlNodes are visited.
constexpr long kMaxYamlNodes = 1000000;

Status CheckDuplicateKeys(const YAML::Node& node, const std::string& path, long* visited,
                          int depth = 0) {
  if (depth > 64) return InvalidArgument(path + LineOf(node) + ": nested deeper than 64 levels");
  if (++*visited > kMaxYamlNodes) {
    return InvalidArgument(path + ": expands to more than " + std::to_string(kMaxYamlNodes) +
                           " YAML nodes (aliases?); expected a small configuration");
  }
  if (node.IsMap()) {
    std::set<std::string> keys;
    for (const auto& kv : node) {
      if (kv.first.IsScalar() && !keys.insert(kv.first.Scalar()).second) {
        return InvalidArgument(path + ":" + std::to_string(kv.first.Mark().line + 1) +
                               ": duplicate key " + internal::Quoted(kv.first.Scalar()) +
                               "; each key may appear once");
      }
      WG_RETURN_IF_ERROR(CheckDuplicateKeys(kv.second, path, visited, depth + 1));
    }
  } else if (node.IsSequence()) {
    for (const auto& item : node) {
      WG_RETURN_IF_ERROR(CheckDuplicateKeys(item, path, visited, depth + 1));
    }
  }
  return Status::Ok();
}

// Records where each document starts.
class DocumentStarts : public YAML::EventHandler {
 public:
  std::vector<YAML::Mark> starts;
  void OnDocumentStart(const YAML::Mark& mark) override { starts.push_back(mark); }
  void OnDocumentEnd() override {}
  void OnNull(const YAML::Mark&, YAML::anchor_t) override {}
  void OnAlias(const YAML::Mark&, YAML::anchor_t) override {}
  void OnScalar(const YAML::Mark&, const std::string&, YAML::anchor_t,
                const std::string&) override {}
  void OnSequenceStart(const YAML::Mark&, const std::string&, YAML::anchor_t,
                       YAML::EmitterStyle::value) override {}
  void OnSequenceEnd() override {}
  void OnMapStart(const YAML::Mark&, const std::string&, YAML::anchor_t,
                  YAML::EmitterStyle::value) override {}
  void OnMapEnd() override {}
};

// One YAML document, no more. (yaml-cpp 0.7's LoadAll never returns on some invalid input, a
// lone ',' among them: its parser then reports document after document at the same place. The
// documents are counted here with at most two parser steps instead.)
Status CheckOneDocument(const std::string& text, const std::string& path) {
  std::istringstream in(text);
  YAML::Parser parser(in);
  DocumentStarts docs;
  for (int i = 0; i < 2 && parser.HandleNextDocument(docs); ++i) {
  }
  if (docs.starts.size() < 2) return Status::Ok();
  const YAML::Mark& second = docs.starts[1];
  if (second.pos <= docs.starts[0].pos) {
    return InvalidArgument(path + ":" + std::to_string(second.line + 1) +
                           ": not valid YAML here (the parser cannot go on)");
  }
  return InvalidArgument(path + ":" + std::to_string(second.line + 1) +
                         ": a second YAML document starts here; expected one document");
}

}  // namespace

StatusOr<YAML::Node> LoadYamlFile(const std::string& path) {
  WG_ASSIGN_OR_RETURN(const std::string text,
                      internal::ReadInputFile(path, internal::kMaxYamlBytes));
  return LoadYamlText(text, path);
}

StatusOr<YAML::Node> LoadYamlText(const std::string& text, const std::string& path) {
  YAML::Node root;
  try {
    WG_RETURN_IF_ERROR(CheckOneDocument(text, path));
    root = YAML::Load(text);
  } catch (const YAML::Exception& e) {
    return InvalidArgument(path + ":" + std::to_string(e.mark.line + 1) + ": " + e.msg);
  } catch (const std::exception& e) {
    return InvalidArgument(path + ": cannot read as YAML: " + e.what());
  }
  long visited = 0;
  WG_RETURN_IF_ERROR(CheckDuplicateKeys(root, path, &visited));
  return root;
}

}  // namespace walkgraph
