#include "convert.h"

#include <chrono>
#include <cmath>
#include <csignal>
#include <future>
#include <thread>
#include <vector>

#include <yaml-cpp/yaml.h>

#include "walkgraph/output.h"

namespace walkgraph::python {

PyObject* NotFoundError() {
  static PyObject* type = [] {
    PyObject* bases = PyTuple_Pack(2, PyExc_FileNotFoundError, PyExc_LookupError);
    PyObject* t = PyErr_NewExceptionWithDoc(
        "walkgraph.NotFoundError",
        "A file, estimator, scenario or key that does not exist (a FileNotFoundError and a "
        "LookupError).",
        bases, nullptr);
    Py_XDECREF(bases);
    return t;
  }();
  return type;
}

void Raise(const Status& status) {
  PyObject* type = PyExc_RuntimeError;
  switch (status.code()) {
    case StatusCode::kInvalidArgument:
      type = PyExc_ValueError;
      break;
    case StatusCode::kNotFound:
      type = NotFoundError();
      break;
    case StatusCode::kCancelled:
      type = PyExc_KeyboardInterrupt;
      break;
    default:
      break;
  }
  PyErr_SetString(type, status.message().c_str());
  throw py::error_already_set();
}

Status RunInterruptible(const std::function<Status()>& fn) {
  std::packaged_task<Status()> task(fn);
  std::future<Status> done = task.get_future();
  std::thread worker;
  {
    py::gil_scoped_release release;
    worker = std::thread(std::move(task));
  }
  bool interrupted = false;
  while (true) {
    {
      py::gil_scoped_release release;
      if (done.wait_for(std::chrono::milliseconds(50)) == std::future_status::ready) break;
    }
    if (!interrupted && PyErr_CheckSignals() != 0) {  // KeyboardInterrupt is now pending
      interrupted = true;
      RequestCancel(SIGINT);
    }
  }
  {
    py::gil_scoped_release release;
    worker.join();
  }
  if (interrupted) {
    ClearCancelRequest();
    throw py::error_already_set();
  }
  return done.get();
}

namespace {

// ToYaml's walk: `path` holds the containers being converted (a cycle is a container met again
// on its own path), `depth` their count.
YAML::Node ToYamlAt(const py::handle& value, const std::string& context,
                    std::vector<PyObject*>* path) {
  if (value.is_none()) return YAML::Node(YAML::NodeType::Null);
  if (py::isinstance<py::bool_>(value)) return YAML::Node(value.cast<bool>());
  if (py::isinstance<py::int_>(value)) {
    try {
      return YAML::Node(value.cast<long long>());
    } catch (const py::cast_error&) {
      Raise(InvalidArgument(context + ": integer out of the 64-bit range"));
    }
  }
  if (py::isinstance<py::float_>(value)) {
    const double x = value.cast<double>();
    if (!std::isfinite(x)) Raise(InvalidArgument(context + ": numbers must be finite"));
    return YAML::Node(x);
  }
  if (py::isinstance<py::str>(value)) return YAML::Node(value.cast<std::string>());
  const bool map = py::isinstance<py::dict>(value);
  if (!map && !py::isinstance<py::list>(value) && !py::isinstance<py::tuple>(value)) {
    Raise(InvalidArgument(context + ": cannot use a " +
                          std::string(py::str(value.get_type().attr("__name__"))) +
                          " as an option value"));
  }
  if (std::find(path->begin(), path->end(), value.ptr()) != path->end()) {
    Raise(InvalidArgument(context + ": the value contains itself (a cycle); expected a tree of "
                                    "dicts and lists"));
  }
  if (path->size() >= kMaxYamlDepth) {
    Raise(InvalidArgument(context + ": nested deeper than " + std::to_string(kMaxYamlDepth) +
                          " levels; expected a shallow dict of options"));
  }
  path->push_back(value.ptr());
  YAML::Node out(map ? YAML::NodeType::Map : YAML::NodeType::Sequence);
  if (map) {
    // A snapshot of the items (PyDict_Items runs no Python code): the conversion cannot see a
    // dict change under it.
    const auto items = py::reinterpret_steal<py::list>(PyDict_Items(value.ptr()));
    if (!items) throw py::error_already_set();
    for (const auto& item : items) {
      const py::handle k = PyTuple_GET_ITEM(item.ptr(), 0), v = PyTuple_GET_ITEM(item.ptr(), 1);
      if (!py::isinstance<py::str>(k)) {
        Raise(InvalidArgument(context + ": option names must be strings"));
      }
      const std::string key = k.cast<std::string>();
      out[key] = ToYamlAt(v, context + "." + key, path);
    }
  } else {
    // A copy: a list that grows while it is read cannot make the loop endless.
    const py::tuple items = py::tuple(py::reinterpret_borrow<py::object>(value));
    for (const auto& v : items) out.push_back(ToYamlAt(v, context, path));
  }
  path->pop_back();
  return out;
}

}  // namespace

YAML::Node ToYaml(const py::handle& value, const std::string& context) {
  std::vector<PyObject*> path;
  return ToYamlAt(value, context, &path);
}

py::dict ToDict(const std::vector<OptionDefault>& defaults) {
  py::dict out;
  for (const OptionDefault& d : defaults) {
    py::dict at = out;
    std::string key = d.key;
    for (size_t dot; (dot = key.find('.')) != std::string::npos; key = key.substr(dot + 1)) {
      const std::string parent = key.substr(0, dot);
      if (!at.contains(parent)) at[parent.c_str()] = py::dict();
      at = at[parent.c_str()].cast<py::dict>();
    }
    std::visit(
        [&](const auto& v) {
          using T = std::decay_t<decltype(v)>;
          if constexpr (std::is_same_v<T, double>) {
            at[key.c_str()] = std::isnan(v) ? py::object(py::none()) : py::object(py::float_(v));
          } else {
            at[key.c_str()] = v;
          }
        },
        d.value);
  }
  return out;
}

py::array_t<double> Matrix(size_t rows, size_t cols,
                           const std::function<double(size_t, size_t)>& at) {
  py::array_t<double> a({rows, cols});
  auto m = a.mutable_unchecked<2>();
  for (size_t i = 0; i < rows; ++i) {
    for (size_t j = 0; j < cols; ++j) m(i, j) = at(i, j);
  }
  return a;
}

namespace {

// A ValueError unless `value` is an array (or nested list) of real numbers or booleans: numpy
// turns None in an object array into NaN and would take strings, so an object array is refused
// at its first element that is not a real number, by row and column.
void CheckNumeric(const py::handle& value, const std::string& stream) {
  py::array any;
  try {
    any = py::array::ensure(value);
  } catch (const py::error_already_set&) {
  }
  if (!any) Raise(InvalidArgument("walk." + stream + ": expected a numeric array"));
  const char kind = any.dtype().kind();
  if (kind == 'b' || kind == 'i' || kind == 'u' || kind == 'f') return;
  if (kind == 'O' && any.ndim() == 2) {
    const py::object real = py::module_::import("numbers").attr("Real");
    for (py::ssize_t i = 0; i < any.shape(0); ++i) {
      for (py::ssize_t j = 0; j < any.shape(1); ++j) {
        const py::object x = any[py::make_tuple(i, j)];
        if (!py::isinstance(x, real)) {
          Raise(InvalidArgument("walk." + stream + "[" + std::to_string(i) + "], column " +
                                std::to_string(j) + ": " +
                                std::string(py::str(py::repr(x)).cast<std::string>()) +
                                " is not a number; expected a numeric array"));
        }
      }
    }
    return;
  }
  Raise(InvalidArgument("walk." + stream + ": expected a numeric array, not one of dtype " +
                        std::string(py::str(any.dtype()))));
}

// Rows of a (N, k) array with k one of `widths`; a ValueError names the stream otherwise.
std::vector<std::vector<double>> Rows(const py::handle& value, const std::string& stream,
                                      std::vector<size_t> widths, const char* columns) {
  std::vector<std::vector<double>> rows;
  if (value.is_none()) return rows;
  CheckNumeric(value, stream);
  py::array_t<double, py::array::c_style | py::array::forcecast> a;
  try {
    a = py::array_t<double, py::array::c_style | py::array::forcecast>::ensure(value);
  } catch (const py::error_already_set&) {
  }
  if (!a) Raise(InvalidArgument("walk." + stream + ": expected a numeric array"));
  if (a.ndim() == 1 && a.shape(0) == 0) return rows;
  size_t k = a.ndim() == 2 ? static_cast<size_t>(a.shape(1)) : 0;
  bool ok = false;
  for (size_t w : widths) ok |= k == w;
  if (!ok) {
    Raise(InvalidArgument("walk." + stream + ": expected an (N, " + std::to_string(widths[0]) +
                          ") array of " + columns));
  }
  auto m = a.unchecked<2>();
  for (py::ssize_t i = 0; i < m.shape(0); ++i) {
    std::vector<double> row(k);
    for (size_t j = 0; j < k; ++j) row[j] = m(i, static_cast<py::ssize_t>(j));
    rows.push_back(std::move(row));
  }
  return rows;
}

int AnchorId(double v, const std::string& stream, size_t row) {
  if (!(v == std::floor(v)) || std::fabs(v) > 2e9) {
    Raise(InvalidArgument("walk." + stream + "[" + std::to_string(row) +
                          "]: anchor id must be an integer"));
  }
  return static_cast<int>(v);
}

}  // namespace

void SetWalkStream(Walk* w, const std::string& s, const py::handle& v) {
  if (s == "imu") {
    w->imu.clear();
    for (const auto& r : Rows(v, s, {7, 10}, "t_s, ax, ay, az, gx, gy, gz[, mx, my, mz]")) {
      ImuSample x;
      x.t_s = r[0];
      x.acc_mps2 = {r[1], r[2], r[3]};
      x.gyro_radps = {r[4], r[5], r[6]};
      x.has_mag = r.size() == 10;
      if (x.has_mag) x.mag_ut = {r[7], r[8], r[9]};
      w->imu.push_back(x);
    }
  } else if (s == "rss" || s == "ranges") {
    (s == "rss") ? w->rss.clear() : w->ranges.clear();
    const auto rows =
        Rows(v, s, {3}, s == "rss" ? "t_s, anchor_id, rss" : "t_s, anchor_id, range_m");
    for (size_t i = 0; i < rows.size(); ++i) {
      if (s == "rss") {
        w->rss.push_back({rows[i][0], AnchorId(rows[i][1], s, i), rows[i][2]});
      } else {
        w->ranges.push_back({rows[i][0], AnchorId(rows[i][1], s, i), rows[i][2]});
      }
    }
  } else if (s == "odometry") {
    w->odometry.clear();
    for (const auto& r : Rows(v, s, {3}, "t_s, dist_m, dheading_rad")) {
      w->odometry.push_back({r[0], r[1], r[2]});
    }
  } else if (s == "truth") {
    w->truth.clear();
    for (const auto& r : Rows(v, s, {3, 4}, "t_s, x_m, y_m[, z_m]")) {
      TruthSample x;
      x.t_s = r[0];
      x.position_m = {r[1], r[2], r.size() == 4 ? r[3] : 0.0};
      x.has_z = r.size() == 4;
      w->truth.push_back(x);
    }
  } else if (s == "anchors") {
    w->anchors.clear();
    const auto rows = Rows(v, s, {4, 5}, "id, x_m, y_m, z_m[, sigma_m]");
    for (size_t i = 0; i < rows.size(); ++i) {
      w->anchors.push_back({AnchorId(rows[i][0], s, i), {rows[i][1], rows[i][2], rows[i][3]}});
      // NaN x and y: an anchor of unknown position (anchors.csv's empty x_m, y_m).
      if (std::isnan(rows[i][1]) && std::isnan(rows[i][2]))
        w->anchors.back().position_known = false;
      if (rows[i].size() == 5) w->anchors.back().sigma_m = rows[i][4];  // 0: surveyed
    }
  } else if (s == "waypoints") {
    w->waypoints.clear();
    for (const auto& r : Rows(v, s, {4}, "t_s, x_m, y_m, sigma_m")) {
      w->waypoints.push_back({r[0], {r[1], r[2]}, r[3]});
    }
  } else if (s == "stance_truth") {
    w->stance_truth.clear();
    for (const auto& r : Rows(v, s, {2}, "t_s, stance"))
      w->stance_truth.push_back({r[0], r[1] != 0});
  }
}

py::object WalkStream(const Walk& w, const std::string& s) {
  if (s == "imu") {
    bool mag = false;
    for (const ImuSample& x : w.imu) mag |= x.has_mag;
    return Matrix(w.imu.size(), mag ? 10 : 7, [&](size_t i, size_t j) {
      const ImuSample& x = w.imu[i];
      if (j == 0) return x.t_s;
      if (j <= 3) return x.acc_mps2[j - 1];
      if (j <= 6) return x.gyro_radps[j - 4];
      return x.has_mag ? x.mag_ut[j - 7] : std::nan("");
    });
  }
  if (s == "rss") {
    return Matrix(w.rss.size(), 3, [&](size_t i, size_t j) {
      const RssSample& x = w.rss[i];
      return j == 0 ? x.t_s : j == 1 ? double(x.anchor_id) : x.rss;
    });
  }
  if (s == "ranges") {
    return Matrix(w.ranges.size(), 3, [&](size_t i, size_t j) {
      const RangeSample& x = w.ranges[i];
      return j == 0 ? x.t_s : j == 1 ? double(x.anchor_id) : x.range_m;
    });
  }
  if (s == "odometry") {
    return Matrix(w.odometry.size(), 3, [&](size_t i, size_t j) {
      const OdometrySample& x = w.odometry[i];
      return j == 0 ? x.t_s : j == 1 ? x.dist_m : x.dheading_rad;
    });
  }
  if (s == "truth") {
    bool z = false;
    for (const TruthSample& x : w.truth) z |= x.has_z;
    return Matrix(w.truth.size(), z ? 4 : 3, [&](size_t i, size_t j) {
      const TruthSample& x = w.truth[i];
      return j == 0 ? x.t_s : x.position_m[j - 1];
    });
  }
  if (s == "anchors") {  // sigma_m as a fifth column when some anchor has one (anchors.csv)
    bool sigma = false;
    for (const Anchor& a : w.anchors) sigma = sigma || a.sigma_m > 0.0;
    return Matrix(w.anchors.size(), sigma ? 5 : 4, [&](size_t i, size_t j) {
      const Anchor& x = w.anchors[i];
      return j == 0 ? double(x.id) : j == 4 ? x.sigma_m : x.position_m[j - 1];
    });
  }
  if (s == "waypoints") {
    return Matrix(w.waypoints.size(), 4, [&](size_t i, size_t j) {
      const Waypoint& x = w.waypoints[i];
      return j == 0 ? x.t_s : j == 3 ? x.sigma_m : x.position_m[j - 1];
    });
  }
  return Matrix(w.stance_truth.size(), 2, [&](size_t i, size_t j) {
    return j == 0 ? w.stance_truth[i].t_s : double(w.stance_truth[i].stance);
  });
}

}  // namespace walkgraph::python
