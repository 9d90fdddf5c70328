// An option enum's one table of names: each enum option has a (name, value) table, its YAML
// spelling, from which its ToString and <Enum>FromString are read (EnumName / EnumFromName
// below), its YAML reader takes its values and its error messages list them.
#ifndef WALKGRAPH_ENUM_NAMES_H_
#define WALKGRAPH_ENUM_NAMES_H_

#include <string>
#include <utility>
#include <vector>

#include "walkgraph/status.h"

namespace walkgraph {

template <typename E>
using EnumNames = std::vector<std::pair<std::string, E>>;

// The names of a table, comma-separated ("none, huber, cauchy").
template <typename E>
std::string EnumNameList(const EnumNames<E>& names) {
  std::string list;
  for (const auto& [name, value] : names) list += (list.empty() ? "" : ", ") + name;
  return list;
}

// `value`'s name; "?" for a value the table does not hold.
template <typename E>
const char* EnumName(const EnumNames<E>& names, E value) {
  for (const auto& [name, v] : names) {
    if (v == value) return name.c_str();
  }
  return "?";
}

// The value named `text`; an error naming `what` and the table's names otherwise.
template <typename E>
StatusOr<E> EnumFromName(const EnumNames<E>& names, const std::string& text,
                         const std::string& what) {
  for (const auto& [name, v] : names) {
    if (name == text) return v;
  }
  return InvalidArgument(what + " must be one of " + EnumNameList(names) + ", not '" + text + "'");
}

// Whether `value` is one of the table's (an enum option set from C++ by a cast may hold another).
template <typename E>
bool EnumHolds(const EnumNames<E>& names, E value) {
  for (const auto& nv : names) {
    if (nv.second == value) return true;
  }
  return false;
}

// OK, or an error "<context>: <key> must be one of <names>" for a value the table does not hold
// (Validate's check of an enum option set from C++).
template <typename E>
Status CheckEnumOption(const EnumNames<E>& names, E value, const std::string& key,
                       const std::string& context) {
  if (EnumHolds(names, value)) return Status::Ok();
  return InvalidArgument(context + ": " + key + " must be one of " + EnumNameList(names) +
                         ", not the value " + std::to_string(static_cast<long>(value)));
}

}  // namespace walkgraph

#endif  // WALKGRAPH_ENUM_NAMES_H_
