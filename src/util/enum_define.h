// Defines an option enum's names table, ToString and FromString (enum_names.h) in a .cc file:
//   WALKGRAPH_DEFINE_ENUM_NAMES(LossKind, "loss", {"none", LossKind::kNone}, ...)
// defines LossKindNames(), ToString(LossKind) and LossKindFromString(name), whose error names
// `what` and the table's names. Use inside namespace walkgraph.
#ifndef WALKGRAPH_SRC_UTIL_ENUM_DEFINE_H_
#define WALKGRAPH_SRC_UTIL_ENUM_DEFINE_H_

#include <string>

#include "walkgraph/enum_names.h"

#define WALKGRAPH_DEFINE_ENUM_NAMES(Enum, what, ...)                  \
  const EnumNames<Enum>& Enum##Names() {                              \
    static const EnumNames<Enum> names = {__VA_ARGS__};               \
    return names;                                                     \
  }                                                                   \
  const char* ToString(Enum v) { return EnumName(Enum##Names(), v); } \
  StatusOr<Enum> Enum##FromString(const std::string& name) {          \
    return EnumFromName(Enum##Names(), name, what);                   \
  }

#endif  // WALKGRAPH_SRC_UTIL_ENUM_DEFINE_H_
