// The _walkgraph extension: walks, estimators, comparisons, simulation, metrics (this file) and
// the factor-graph core (graph.cc). Every library failure becomes a Python exception carrying
// the Status message; long calls run off the GIL and stop on Ctrl-C.
#include <cmath>
#include <initializer_list>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <pybind11/stl.h>
#include <yaml-cpp/yaml.h>

#include "convert.h"
#include "walkgraph/compare.h"
#include "walkgraph/estimator.h"
#include "walkgraph/io.h"
#include "walkgraph/metrics.h"
#include "walkgraph/pcrb.h"
#include "walkgraph/simulate.h"
#include "walkgraph/survey.h"

namespace walkgraph::python {

void BindGraph(py::module_& m);  // graph.cc

namespace {

template <typename E>
E FromName(const py::handle& value, std::initializer_list<E> all, const std::string& what) {
  const std::string name = py::str(value);
  std::string names;
  for (E e : all) {
    if (name == ToString(e)) return e;
    names += (names.empty() ? "" : ", ") + std::string(ToString(e));
  }
  Raise(InvalidArgument(what + ": '" + name + "' is not one of " + names));
}

constexpr std::initializer_list<ImuPlacement> kPlacements = {
    ImuPlacement::kNone, ImuPlacement::kFoot, ImuPlacement::kWaist, ImuPlacement::kHip,
    ImuPlacement::kHandheld};
constexpr std::initializer_list<TruthKind> kTruthKinds = {TruthKind::kNone, TruthKind::kContinuous,
                                                          TruthKind::kCheckpoints};
constexpr std::initializer_list<RadioKind> kRadioKinds = {RadioKind::kNone, RadioKind::kRss,
                                                          RadioKind::kRange};
constexpr std::initializer_list<RssUnits> kUnits = {RssUnits::kDbm, RssUnits::kRfcode};

const char* const kStreams[] = {"imu",   "rss",     "ranges",    "odometry",
                                "truth", "anchors", "waypoints", "stance_truth"};

py::dict RadioDict(const RadioDefaults& r) {
  py::dict d;
  d["kind"] = ToString(r.kind);
  d["units"] = ToString(r.units);
  d["A_dbm"] = r.path_loss.A_dbm;
  d["eta"] = r.path_loss.eta;
  d["d0_m"] = r.path_loss.d0_m;
  d["sigma_db"] = r.path_loss.sigma_db;
  d["range_sigma_m"] = r.range_sigma_m;
  d["calibrated"] = r.calibrated;
  return d;
}

// A real number (int or float, not bool) from Python, else a ValueError naming `what`.
double Number(const py::handle& v, const std::string& what) {
  const py::object real = py::module_::import("numbers").attr("Real");
  if (py::isinstance<py::bool_>(v) || !py::isinstance(v, real)) {
    Raise(InvalidArgument(what + ": expected a number, not a " +
                          std::string(py::str(v.get_type().attr("__name__")))));
  }
  return v.cast<double>();
}

void SetRadio(Walk* w, const py::dict& d) {
  RadioDefaults r = w->meta.radio;
  for (const auto& [k, v] : d) {
    const std::string key = py::str(k);
    if (key == "kind") {
      r.kind = FromName(v, kRadioKinds, "radio.kind");
    } else if (key == "units") {
      r.units = FromName(v, kUnits, "radio.units");
    } else if (key == "calibrated") {
      r.calibrated = v.cast<bool>();
    } else if (key == "A_dbm" || key == "eta" || key == "d0_m" || key == "sigma_db" ||
               key == "range_sigma_m") {
      const double x = Number(v, "radio." + key);
      double* field = key == "A_dbm"      ? &r.path_loss.A_dbm
                      : key == "eta"      ? &r.path_loss.eta
                      : key == "d0_m"     ? &r.path_loss.d0_m
                      : key == "sigma_db" ? &r.path_loss.sigma_db
                                          : &r.range_sigma_m;
      *field = x;
    } else {
      Raise(InvalidArgument("radio: unknown key '" + key +
                            "' (kind, units, A_dbm, eta, d0_m, sigma_db, range_sigma_m, "
                            "calibrated)"));
    }
  }
  w->meta.radio = r;
}

py::object PoseDict(const std::optional<InitialPose>& p) {
  if (!p) return py::none();
  py::dict d;
  d["x_m"] = p->x_m;
  d["y_m"] = p->y_m;
  d["sigma_xy_m"] = p->sigma_xy_m;
  if (p->heading_known) {
    d["heading_rad"] = p->heading_rad;
    d["sigma_heading_rad"] = p->sigma_heading_rad;
  }
  return std::move(d);
}

void SetPose(Walk* w, const py::object& v) {
  if (v.is_none()) {
    w->meta.initial_pose.reset();
    return;
  }
  InitialPose p;
  p.heading_known = false;
  p.sigma_heading_rad = kUnknownHeadingSigmaRad;
  if (!py::isinstance<py::dict>(v)) {
    Raise(InvalidArgument("initial_pose: expected a dict or None"));
  }
  for (const auto& [k, x] : v.cast<py::dict>()) {
    const std::string key = py::str(k);
    const double value = Number(x, "initial_pose." + key);
    if (key == "x_m") {
      p.x_m = value;
    } else if (key == "y_m") {
      p.y_m = value;
    } else if (key == "sigma_xy_m") {
      p.sigma_xy_m = value;
    } else if (key == "heading_rad") {
      p.heading_rad = value;
      p.heading_known = true;
      if (p.sigma_heading_rad == kUnknownHeadingSigmaRad) p.sigma_heading_rad = 0.1;
    } else if (key == "sigma_heading_rad") {
      p.sigma_heading_rad = value;
    } else {
      Raise(InvalidArgument("initial_pose: unknown key '" + key +
                            "' (x_m, y_m, sigma_xy_m, heading_rad, sigma_heading_rad)"));
    }
  }
  w->meta.initial_pose = p;
}

// The estimate of one run: arrays for Python, the C++ trajectory for errors().
struct Estimate {
  std::string estimator;
  EstimateResult result;
};

py::dict StatsDict(const ErrorStats& s) {
  py::dict d;
  for (const ErrorStatField& f : ErrorStatFields()) d[f.name] = s.*f.field;
  d["n_points"] = s.n_points;
  return d;
}

std::map<std::string, Config> ConfigsById(const py::object& config) {
  std::map<std::string, Config> out;
  if (config.is_none()) return out;
  if (!py::isinstance<py::dict>(config)) {
    Raise(InvalidArgument("config: expected a dict {estimator id: {option: value}}"));
  }
  for (const auto& [k, v] : config.cast<py::dict>()) {
    const std::string id = py::str(k);
    out[id] = ToYaml(v, "config." + id);
  }
  return out;
}

// compare()'s estimators: None (every applicable one) or a non-empty list of ids.
std::vector<std::string> EstimatorIds(const py::object& estimators) {
  if (estimators.is_none()) return {};
  if (py::isinstance<py::str>(estimators) || !py::isinstance<py::sequence>(estimators)) {
    Raise(
        InvalidArgument("compare: estimators must be a list of estimator ids (or None for "
                        "every applicable one)"));
  }
  std::vector<std::string> ids;
  for (const auto& id : estimators.cast<py::sequence>()) {
    if (!py::isinstance<py::str>(id)) {
      Raise(InvalidArgument("compare: estimators must be a list of estimator ids (str)"));
    }
    ids.push_back(id.cast<std::string>());
  }
  if (ids.empty()) {
    Raise(
        InvalidArgument("compare: estimators is an empty list; expected at least one estimator "
                        "id (or None for every applicable one)"));
  }
  return ids;
}

// An output path: a str or an os.PathLike naming one (e.g. pathlib.Path); bytes and other
// types are a ValueError (str(123) would make a folder "123").
std::string OutputPath(const py::object& out, const std::string& what) {
  const py::object pathlike = py::module_::import("os").attr("PathLike");
  if (py::isinstance<py::str>(out) || py::isinstance(out, pathlike)) {
    const py::object path = py::module_::import("os").attr("fspath")(out);
    if (py::isinstance<py::str>(path)) return path.cast<std::string>();
  }
  Raise(InvalidArgument(what + ": expected a path (str or os.PathLike), not a " +
                        std::string(py::str(out.get_type().attr("__name__")))));
}

py::object Json(const std::string& text) { return py::module_::import("json").attr("loads")(text); }

void BindWalk(py::module_& m) {
  py::class_<Walk> walk(m, "Walk", "A recorded or simulated walk (see docs/walk-format.md).");
  walk.def(py::init([](const py::kwargs& kw) {
             Walk w;
             for (const auto& [k, v] : kw) {
               const std::string key = py::str(k);
               py::object self = py::cast(&w, py::return_value_policy::reference);
               if (!py::hasattr(self, key.c_str())) {
                 Raise(InvalidArgument("Walk: unknown field '" + key + "'"));
               }
               self.attr(key.c_str()) = v;
             }
             if (kw.contains("truth") && !kw.contains("truth_kind") && !w.truth.empty()) {
               w.meta.truth_kind = TruthKind::kContinuous;
             }
             return w;
           }),
           "Walk(imu=..., rss=..., anchors=..., name=..., ...): any field below, by keyword.");
  for (const char* s : kStreams) {
    const std::string name = s;
    walk.def_property(
        s, [name](const Walk& w) { return WalkStream(w, name); },
        [name](Walk& w, const py::object& v) { SetWalkStream(&w, name, v); });
  }
  walk.def_property(
      "name", [](const Walk& w) { return w.meta.name; },
      [](Walk& w, const std::string& v) { w.meta.name = v; });
  walk.def_property(
      "source", [](const Walk& w) { return w.meta.source; },
      [](Walk& w, const std::string& v) { w.meta.source = v; });
  walk.def_property(
      "licence", [](const Walk& w) { return w.meta.licence; },
      [](Walk& w, const std::string& v) { w.meta.licence = v; });
  walk.def_property(
      "imu_placement", [](const Walk& w) { return ToString(w.meta.imu_placement); },
      [](Walk& w, const py::object& v) {
        w.meta.imu_placement = FromName(v, kPlacements, "imu_placement");
      });
  walk.def_property(
      "truth_kind", [](const Walk& w) { return ToString(w.meta.truth_kind); },
      [](Walk& w, const py::object& v) {
        w.meta.truth_kind = FromName(v, kTruthKinds, "truth_kind");
      });
  walk.def_property(
      "radio", [](const Walk& w) { return RadioDict(w.meta.radio); },
      [](Walk& w, const py::dict& d) { SetRadio(&w, d); });
  walk.def_property(
      "initial_pose", [](const Walk& w) { return PoseDict(w.meta.initial_pose); },
      [](Walk& w, const py::object& v) { SetPose(&w, v); });
  walk.def_property(
      "extra", [](const Walk& w) { return w.meta.extra; },
      [](Walk& w, const std::map<std::string, double>& v) { w.meta.extra = v; });
  walk.def(
      "validate", [](const Walk& w) { Check(ValidateWalk(w)); },
      "Raises ValueError naming the stream, row and rule when the walk is not valid.");
  walk.def("copy", [](const Walk& w) { return Walk(w); });
  walk.def("__repr__", [](const Walk& w) {
    return "<walkgraph.Walk '" + w.meta.name + "': " + std::to_string(w.imu.size()) + " IMU, " +
           std::to_string(w.rss.size()) + " RSS, " + std::to_string(w.ranges.size()) + " ranges, " +
           std::to_string(w.odometry.size()) + " odometry, " + std::to_string(w.truth.size()) +
           " truth>";
  });
}

void BindEstimate(py::module_& m) {
  py::class_<Estimate>(m, "Estimate", "What an estimator returned.")
      .def_readonly("estimator", &Estimate::estimator)
      .def_property_readonly("t",
                             [](const Estimate& e) {
                               const auto& p = e.result.trajectory.points;
                               return Matrix(p.size(), 1,
                                             [&](size_t i, size_t) { return p[i].t_s; })
                                   .attr("reshape")(p.size());
                             })
      .def_property_readonly("xy",
                             [](const Estimate& e) {
                               const auto& p = e.result.trajectory.points;
                               return Matrix(p.size(), 2, [&](size_t i, size_t j) {
                                 return p[i].position_m[static_cast<int>(j)];
                               });
                             })
      .def_property_readonly("yaw",
                             [](const Estimate& e) {
                               const auto& p = e.result.trajectory.points;
                               return Matrix(p.size(), 1,
                                             [&](size_t i, size_t) { return p[i].heading_rad; })
                                   .attr("reshape")(p.size());
                             })
      .def_property_readonly(
          "cov",
          [](const Estimate& e) {
            const auto& p = e.result.trajectory.points;
            py::array_t<double> a({p.size(), size_t{3}, size_t{3}});
            auto c = a.mutable_unchecked<3>();
            for (size_t i = 0; i < p.size(); ++i) {
              for (int r = 0; r < 3; ++r) {
                for (int k = 0; k < 3; ++k) {
                  c(i, r, k) = p[i].covariance ? (*p[i].covariance)(r, k) : std::nan("");
                }
              }
            }
            return a;
          },
          "(N, 3, 3) covariance of (x, y, yaw); NaN where the estimator gives none.")
      .def_property_readonly("diagnostics", [](const Estimate& e) { return e.result.diagnostics; })
      .def_property_readonly("timings", [](const Estimate& e) { return e.result.timings; })
      .def("__len__", [](const Estimate& e) { return e.result.trajectory.size(); });
}

void BindCompare(py::module_& m) {
  m.def(
      "compare",
      [](const py::object& walk_or_scenario, const py::object& estimators, int runs, uint64_t seed,
         const py::object& config, const py::object& out, bool align_se2) {
        CompareOptions o;
        o.alignment = align_se2 ? Alignment::kSE2 : Alignment::kNone;
        o.estimator_ids = EstimatorIds(estimators);
        o.configs = ConfigsById(config);
        const std::optional<std::string> dir =
            out.is_none() ? std::nullopt : std::optional<std::string>(OutputPath(out, "out"));
        std::optional<Comparison> c;
        if (py::isinstance<py::str>(walk_or_scenario)) {
          const std::string scenario = walk_or_scenario.cast<std::string>();
          MonteCarloOptions mc;
          mc.runs = runs;
          mc.seed = seed;
          Check(RunInterruptible([&]() -> Status {
            WG_ASSIGN_OR_RETURN(c, CompareScenario(scenario, ScenarioCompareOptions(), o, mc));
            return Status::Ok();
          }));
        } else {
          if (!py::isinstance<Walk>(walk_or_scenario)) {
            Raise(InvalidArgument("compare: expected a Walk or a scenario name (str)"));
          }
          const Walk& walk = walk_or_scenario.cast<const Walk&>();
          if (runs != 1) Check(InvalidArgument("compare: runs > 1 needs a scenario name"));
          Check(RunInterruptible([&]() -> Status {
            WG_ASSIGN_OR_RETURN(c, CompareOnWalk(walk, o));
            return Status::Ok();
          }));
        }
        if (dir) Check(RunInterruptible([&] { return WriteComparison(*c, *dir); }));
        return Json(ResultsJsonText(*c));
      },
      py::arg("walk_or_scenario"), py::arg("estimators") = py::none(), py::arg("runs") = 1,
      py::arg("seed") = 0, py::arg("config") = py::none(), py::arg("out") = py::none(),
      py::arg("align_se2") = false,
      "Runs estimators side by side; returns results.json's content as a dict. out= also "
      "writes the report folder. align_se2: score each estimate after the rotation and "
      "translation that best fit it to the truth (the CLI's --align-se2).");
}

// read_walk, write_walk.
void BindWalkIo(py::module_& m) {
  m.def(
      "read_walk",
      [](const std::string& path) {
        StatusOr<Walk> w = InvalidArgument("");
        Check(RunInterruptible([&] {
          w = ReadWalk(path);
          return Status::Ok();
        }));
        return Value(std::move(w));
      },
      py::arg("path"), "Reads a walk directory; errors name file:line.");
  m.def(
      "write_walk",
      [](const Walk& w, const py::object& path_object, bool force) {
        const std::string path = OutputPath(path_object, "write_walk");
        OutputOptions o;
        o.force = force;
        Check(RunInterruptible([&] { return WriteWalk(w, path, o); }));
      },
      py::arg("walk"), py::arg("path"), py::arg("force") = false,
      "Writes a walk directory (whole or not at all; replaces only a folder walkgraph wrote, "
      "or any with force=True).");
}

// estimators, run.
void BindEstimators(py::module_& m) {
  m.def("estimators", [] {
    py::list out;
    const EstimatorRegistry& reg = EstimatorRegistry::Builtin();
    for (const std::string& id : reg.Ids()) {
      py::dict d;
      d["id"] = id;
      d["description"] = reg.Find(id)->description;
      d["options"] = ToDict(Value(reg.OptionDefaults(id)));
      out.append(d);
    }
    return out;
  });
  m.def(
      "run",
      [](const std::string& id, const Walk& walk, const py::object& config) {
        const YAML::Node yaml = ToYaml(config, id);
        std::unique_ptr<Estimator> est =
            Value(EstimatorRegistry::Builtin().Create(id, yaml.IsNull() ? YAML::Node() : yaml));
        Check(ValidateWalk(walk));
        Check(est->CheckApplicable(walk));
        Estimate e{id, {}};
        Check(RunInterruptible([&]() -> Status {
          WG_ASSIGN_OR_RETURN(e.result, est->Run(walk));
          return Status::Ok();
        }));
        return e;
      },
      py::arg("estimator"), py::arg("walk"), py::arg("config") = py::none(),
      "Runs one estimator; config is a dict of its options (unknown keys are errors).");
}

// A stack of 2x2 matrices as an (n, 2, 2) array.
py::array_t<double> Stack2x2(const std::vector<Eigen::Matrix2d>& v) {
  py::array_t<double> a({v.size(), size_t{2}, size_t{2}});
  auto c = a.mutable_unchecked<3>();
  for (size_t i = 0; i < v.size(); ++i) {
    for (int r = 0; r < 2; ++r) {
      for (int k = 0; k < 2; ++k) c(i, r, k) = v[i](r, k);
    }
  }
  return a;
}

// survey, apply_radio_map (survey.h).
void BindSurvey(py::module_& m) {
  m.def(
      "survey",
      [](const std::vector<Walk>& walks, double checkpoint_sigma_m, double checkpoint_spacing_s,
         bool pool_disagreement) {
        SurveyOptions o;
        o.pool_disagreement = pool_disagreement;
        o.checkpoint_sigma_m = checkpoint_sigma_m;
        o.checkpoint_spacing_s = checkpoint_spacing_s;
        for (const Walk& w : walks) Check(ValidateWalk(w));
        std::optional<RadioMap> map;
        Check(RunInterruptible([&]() -> Status {
          WG_ASSIGN_OR_RETURN(map, SurveyRadioMap(walks, o));
          return Status::Ok();
        }));
        py::dict d;
        d["anchors"] = Matrix(map->anchors.size(), 5, [&](size_t i, size_t j) {
          const Anchor& a = map->anchors[i];
          return j == 0 ? double(a.id) : j == 4 ? a.sigma_m : a.position_m[j - 1];
        });
        std::vector<int> ids, used, readings;
        std::vector<double> disagreement;
        std::vector<Eigen::Matrix2d> covariance;
        for (const SurveyedAnchor& a : map->details) {
          ids.push_back(a.id);
          used.push_back(a.walks);
          readings.push_back(a.readings);
          disagreement.push_back(a.disagreement);
          covariance.push_back(a.covariance);
        }
        d["placed_ids"] = ids;
        d["covariance"] = Stack2x2(covariance);
        d["walks"] = used;
        d["readings"] = readings;
        d["disagreement"] = disagreement;
        d["unobservable"] = map->unobservable;
        d["variance_factor"] = map->variance_factor;
        return d;
      },
      py::arg("walks"), py::arg("checkpoint_sigma_m") = 0.5, py::arg("checkpoint_spacing_s") = 1.0,
      py::arg("pool_disagreement") = true,
      "A radio map from walks with truth (walkgraph survey): a dict with 'anchors' (an (N, 5) "
      "array id, x_m, y_m, z_m, sigma_m, as walk.anchors takes it) and, per placed anchor, "
      "'placed_ids', 'covariance' (n, 2, 2), 'walks', 'readings', 'disagreement'; "
      "'unobservable' and 'variance_factor' (the median disagreement, survey.h).");
  m.def(
      "apply_radio_map",
      [](Walk& walk, const py::handle& anchors) {
        Walk map;
        SetWalkStream(&map, "anchors", anchors);
        const int changed = Value(ApplyRadioMap(map.anchors, &walk));
        Check(ValidateWalk(walk));
        return changed;
      },
      py::arg("walk"), py::arg("anchors"),
      "Gives the walk's unsurveyed anchors that the map (survey()['anchors']) places its position "
      "and sigma as a prior; returns how many changed.");
}

// simulate, scenarios, pcrb.
void BindSimulation(py::module_& m) {
  m.def(
      "simulate",
      [](const std::string& scenario, uint64_t seed, const py::object& overrides) {
        const YAML::Node yaml = ToYaml(overrides, "overrides");
        std::optional<Walk> w;
        Check(RunInterruptible([&]() -> Status {
          WG_ASSIGN_OR_RETURN(
              w, SimulateScenario(scenario, seed, yaml.IsNull() ? YAML::Node() : yaml));
          return Status::Ok();
        }));
        return std::move(*w);
      },
      py::arg("scenario"), py::arg("seed") = 0, py::arg("overrides") = py::none());
  m.def("scenarios", [] {
    std::map<std::string, std::string> out;
    for (const ScenarioInfo& s : Scenarios()) out[s.name] = s.description;
    return out;
  });
  m.def(
      "pcrb",
      [](const std::string& scenario, int runs, uint64_t seed, const py::object& overrides) {
        const YAML::Node yaml = ToYaml(overrides, "overrides");
        std::optional<PcrbBound> b;
        Check(RunInterruptible([&]() -> Status {
          WG_ASSIGN_OR_RETURN(
              b, ScenarioPcrb(scenario, yaml.IsNull() ? YAML::Node() : yaml, runs, seed, 1));
          return Status::Ok();
        }));
        py::dict d;
        d["t"] = b->t_s;
        d["filter_rmse_m"] = b->filter_rmse_m;
        d["smoother_rmse_m"] = b->smoother_rmse_m;
        d["filter"] = Stack2x2(b->filter);
        d["smoother"] = Stack2x2(b->smoother);
        return d;
      },
      py::arg("scenario"), py::arg("runs") = 1, py::arg("seed") = 0,
      py::arg("overrides") = py::none(),
      "Posterior Cramér–Rao bound of a simulated scenario (pcrb.h).");
}

// errors.
void BindErrors(py::module_& m) {
  m.def(
      "errors",
      [](const Estimate& e, const Walk& walk, bool align_se2) {
        Check(ValidateWalk(walk));
        const ErrorSeries s = Value(ComputeErrors(walk, e.result.trajectory,
                                                  align_se2 ? Alignment::kSE2 : Alignment::kNone));
        py::dict d;
        d["t"] = s.t_s;
        d["error_m"] = s.error_m;
        d["nees"] = s.nees;
        d["distance_m"] = s.distance_m;
        d["n_skipped"] = s.n_skipped;
        d["stats"] = StatsDict(SummarizeErrors(s, walk.TruthDistance()));
        return d;
      },
      py::arg("estimate"), py::arg("walk"), py::arg("align_se2") = false,
      "Horizontal errors at the truth and their statistics (the metrics compare uses).");
}

}  // namespace

PYBIND11_MODULE(_walkgraph, m) {
  m.doc() = "walkgraph: factor-graph smoothing and the papers' Kalman filters for indoor walks";
  m.attr("NotFoundError") = py::handle(NotFoundError());
  BindWalk(m);
  BindEstimate(m);
  BindWalkIo(m);
  BindEstimators(m);
  BindCompare(m);
  BindSimulation(m);
  BindSurvey(m);
  BindErrors(m);
  BindGraph(m);
}

}  // namespace walkgraph::python
