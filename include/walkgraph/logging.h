// Logging set-up for programs that use walkgraph. The library logs only diagnostics (verbose
// levels); it never prints results or exits.
#ifndef WALKGRAPH_LOGGING_H_
#define WALKGRAPH_LOGGING_H_

namespace walkgraph {

// Initializes the logging backend once (safe to call more than once). `verbosity` > 0 turns on
// the library's verbose diagnostics on stderr.
void InitLogging(const char* program_name, int verbosity = 0);

}  // namespace walkgraph

#endif  // WALKGRAPH_LOGGING_H_
