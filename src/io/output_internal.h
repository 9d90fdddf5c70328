// Test hooks of the output writers (internal).
#ifndef WALKGRAPH_SRC_IO_OUTPUT_INTERNAL_H_
#define WALKGRAPH_SRC_IO_OUTPUT_INTERNAL_H_

#include <functional>
#include <string>

namespace walkgraph::internal {

// Called by the writers at each phase of a write, by name: "tmp-created", "filled",
// "before-exchange", "old-moved" (fallback path only), "exchanged", "done". Tests use it to
// cancel or kill the process at each instant. Not thread-safe; empty = no hook.
void SetOutputPhaseHookForTesting(std::function<void(const std::string& phase)> hook);

// The target name as it appears in its hidden siblings (temporary, backup, lock): the name
// itself, or, when the siblings' names would pass NAME_MAX (255 bytes), a prefix of it and a
// hash of the whole.
std::string OutputSiblingBase(const std::string& name);

// Name of this process's temporary (kind "tmp") or backup (kind "old") for the entry `name`.
std::string OutputSiblingName(const std::string& name, const char* kind);

}  // namespace walkgraph::internal

#endif  // WALKGRAPH_SRC_IO_OUTPUT_INTERNAL_H_
