// Conversions between walkgraph's C++ types and Python: Status → exceptions, dicts ↔ YAML
// configs, walk streams ↔ numpy arrays, and running library calls off the GIL with Ctrl-C.
#ifndef WALKGRAPH_PYTHON_CONVERT_H_
#define WALKGRAPH_PYTHON_CONVERT_H_

#include <functional>
#include <string>
#include <utility>

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <yaml-cpp/yaml.h>

#include "walkgraph/config.h"
#include "walkgraph/status.h"
#include "walkgraph/walk.h"

namespace walkgraph::python {

namespace py = pybind11;

// Raises the Python exception for a failed Status (its message unchanged): InvalidArgument →
// ValueError, NotFound → walkgraph.NotFoundError (a FileNotFoundError and a LookupError: a
// missing walk, an unknown estimator or key), Cancelled → KeyboardInterrupt, others
// RuntimeError.
PyObject* NotFoundError();
[[noreturn]] void Raise(const Status& status);
inline void Check(const Status& status) {
  if (!status.ok()) Raise(status);
}
template <typename T>
T Value(StatusOr<T> s) {
  if (!s.ok()) Raise(s.status());
  return std::move(*s);
}

// Runs `fn` on a worker thread with the GIL released; the calling thread polls for signals,
// and on Ctrl-C asks the library to stop (RequestCancel), waits for it and raises
// KeyboardInterrupt.
Status RunInterruptible(const std::function<Status()>& fn);

// A Python dict (or None) as a YAML map, for estimator and simulator options: bool, int, float,
// str, None, lists and nested dicts. Anything else is a ValueError naming `context`, and so are
// a value that contains itself and nesting deeper than kMaxYamlDepth (never a stack overflow).
inline constexpr size_t kMaxYamlDepth = 64;
YAML::Node ToYaml(const py::handle& value, const std::string& context);
// Option defaults as nested dicts (NaN, "the walk's value", as None).
py::dict ToDict(const std::vector<OptionDefault>& defaults);

// Walk streams as (N, k) float64 arrays and back (see walkgraph/__init__.py for the columns).
py::array_t<double> Matrix(size_t rows, size_t cols,
                           const std::function<double(size_t, size_t)>& at);
void SetWalkStream(Walk* walk, const std::string& stream, const py::handle& array);
py::object WalkStream(const Walk& walk, const std::string& stream);

}  // namespace walkgraph::python

#endif  // WALKGRAPH_PYTHON_CONVERT_H_
