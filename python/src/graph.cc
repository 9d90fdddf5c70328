// The factor-graph core from Python: keys, built-in factors, FactorGraph (batch) and the
// FixedLagSmoother (sliding window), the same container walkgraph's own estimators use.
#include <cmath>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <ceres/loss_function.h>
#include <ceres/normal_prior.h>
#include <pybind11/eigen.h>
#include <pybind11/stl.h>

#include "config/parsers.h"
#include "convert.h"
#include "factors/position_prior_factor.h"
#include "factors/position_random_walk_factor.h"
#include "factors/range_factor.h"
#include "factors/rss_factor.h"
#include "smoothers/graph_internal.h"
#include "util/text.h"
#include "walkgraph/graph.h"
#include "walkgraph/io.h"
#include "walkgraph/smoothers/fixed_lag_smoother.h"
#include "walkgraph/smoothers/step_graph.h"

namespace walkgraph::python {

namespace {

Key SymbolOf(const std::string& letter, uint64_t index) {
  if (letter.size() != 1) Raise(InvalidArgument("symbol: the letter must be one character"));
  if (index > kMaxSymbolIndex) Raise(InvalidArgument("symbol: index beyond 2^56 - 1"));
  return Symbol(letter[0], index);
}

// A robust loss by the estimators' names (graph_options.h LossKindNames); None or "none": squared.
std::shared_ptr<const ceres::LossFunction> Loss(const std::optional<std::string>& loss,
                                                double scale) {
  if (!loss) return nullptr;
  if (!(scale > 0)) Raise(InvalidArgument("loss_scale must be > 0"));
  const StatusOr<LossKind> kind = LossKindFromString(*loss);
  if (!kind.ok()) {
    Raise(InvalidArgument("loss must be None or one of " + EnumNameList(LossKindNames()) +
                          ", not " + internal::Quoted(*loss)));
  }
  return internal::MakeLoss(*kind, scale);
}

void CheckSigma(double sigma, const char* what) {
  if (!(sigma > 0) || !std::isfinite(sigma)) {
    Raise(InvalidArgument(std::string(what) + " must be finite and > 0"));
  }
}

GraphState StateOf(Key key, std::vector<double> value, std::optional<double> t, bool constant) {
  GraphState s;
  s.key = key;
  s.t_s = t;
  s.value = std::move(value);
  s.constant = constant;
  return s;
}

py::dict SummaryDict(const SolveSummary& s) {
  py::dict d;
  d["iterations"] = s.iterations;
  d["initial_cost"] = s.initial_cost;
  d["final_cost"] = s.final_cost;
  d["termination"] = ToString(s.termination);
  d["time_s"] = s.time_s;
  d["num_residuals"] = s.num_residuals;
  d["num_parameters"] = s.num_parameters;
  return d;
}

void BindSmoother(py::module_& m) {
  py::class_<FixedLagSmoother>(m, "FixedLagSmoother",
                               "Sliding-window smoother: states older than lag_s are "
                               "marginalized into a prior.")
      .def(py::init([](double lag_s) {
             if (!(lag_s > 0) || !std::isfinite(lag_s)) {
               Raise(InvalidArgument("lag_s must be finite and > 0"));
             }
             FixedLagSmoother::Options o;
             o.lag_s = lag_s;
             return std::make_unique<FixedLagSmoother>(o);
           }),
           py::arg("lag_s") = 10.0)
      .def(
          "update",
          [](FixedLagSmoother& s, const py::list& states, const std::vector<GraphFactor>& factors) {
            std::vector<GraphState> new_states;
            for (const auto& item : states) {
              const py::tuple t = item.cast<py::tuple>();
              if (t.size() < 2 || t.size() > 3) {
                Raise(InvalidArgument("update: a state is (key, value) or (key, value, t)"));
              }
              const std::optional<double> time = t.size() == 3 && !t[2].is_none()
                                                     ? std::optional<double>(t[2].cast<double>())
                                                     : std::nullopt;
              new_states.push_back(
                  StateOf(t[0].cast<Key>(), t[1].cast<std::vector<double>>(), time, false));
            }
            std::optional<FixedLagSmoother::UpdateResult> r;
            Check(RunInterruptible([&]() -> Status {
              WG_ASSIGN_OR_RETURN(r, s.Update(std::move(new_states), factors));
              return Status::Ok();
            }));
            py::dict d;
            d["iterations"] = r->ceres_iterations;
            d["marginalized_states"] = r->marginalized_states;
            d["final_cost"] = r->final_cost;
            d["converged"] = r->converged;
            return d;
          },
          py::arg("states"), py::arg("factors"))
      .def("estimate",
           [](const FixedLagSmoother& s, Key key) {
             const std::vector<double> v = Value(s.Estimate(key));
             return Eigen::VectorXd(Eigen::Map<const Eigen::VectorXd>(v.data(), v.size()));
           })
      .def("covariance",
           [](FixedLagSmoother& s, Key key) { return Value(s.MarginalCovariance(key)); })
      .def("window_keys", &FixedLagSmoother::WindowKeys);
}

// walkgraph.factors: priors and motion factors.
void BindPriorFactors(py::module_& f) {
  f.def(
      "position_prior",
      [](Key key, const Eigen::Vector2d& xy, double sigma_m) {
        CheckSigma(sigma_m, "sigma_m");
        return GraphFactor{
            std::shared_ptr<ceres::CostFunction>(PositionPriorFactor<2>::Create(xy, sigma_m)),
            nullptr,
            {key}};
      },
      py::arg("key"), py::arg("xy"), py::arg("sigma_m"),
      "A known 2-D position (a waypoint) on one pose: r = (p - z) / sigma.");
  f.def(
      "waypoint_between",
      [](Key a, Key b, double alpha, const Eigen::Vector2d& xy, double sigma_m) {
        CheckSigma(sigma_m, "sigma_m");
        if (!(alpha >= 0 && alpha <= 1)) Raise(InvalidArgument("alpha must be in [0, 1]"));
        return GraphFactor{std::shared_ptr<ceres::CostFunction>(
                               PositionPriorFactor<2>::CreateInterpolated(xy, sigma_m, alpha)),
                           nullptr,
                           {a, b}};
      },
      py::arg("key_a"), py::arg("key_b"), py::arg("alpha"), py::arg("xy"), py::arg("sigma_m"),
      "A known position between two poses: r = ((1 - alpha) p_a + alpha p_b - z) / sigma.");
  f.def(
      "prior",
      [](Key key, const Eigen::VectorXd& mean, const Eigen::VectorXd& sigma) {
        if (mean.size() != sigma.size() || mean.size() == 0) {
          Raise(InvalidArgument("prior: mean and sigma must have the same, non-zero size"));
        }
        for (int i = 0; i < sigma.size(); ++i) CheckSigma(sigma[i], "sigma");
        const ceres::Matrix a = sigma.cwiseInverse().asDiagonal();
        return GraphFactor{std::make_shared<ceres::NormalPrior>(a, mean), nullptr, {key}};
      },
      py::arg("key"), py::arg("mean"), py::arg("sigma"),
      "A Gaussian prior with a diagonal covariance on any state.");
  f.def(
      "random_walk",
      [](Key a, Key b, double dt_s, double sigma_mps) {
        CheckSigma(dt_s, "dt_s");
        CheckSigma(sigma_mps, "sigma_mps");
        return GraphFactor{
            std::shared_ptr<ceres::CostFunction>(PositionRandomWalkFactor::Create(dt_s, sigma_mps)),
            nullptr,
            {a, b}};
      },
      py::arg("key_a"), py::arg("key_b"), py::arg("dt_s"), py::arg("sigma_mps"),
      "2-D position random walk: p_b - p_a ~ N(0, sigma^2 dt I).");
}

// walkgraph.factors: radio readings.
void BindRadioFactors(py::module_& f) {
  f.def(
      "range",
      [](Key key, Key bias_key, double range_m, const Eigen::Vector3d& anchor, double sigma_m,
         std::optional<std::string> loss, double loss_scale) {
        CheckSigma(sigma_m, "sigma_m");
        return GraphFactor{
            std::shared_ptr<ceres::CostFunction>(RangeFactor<2>::Create(range_m, anchor, sigma_m)),
            Loss(loss, loss_scale),
            {key, bias_key}};
      },
      py::arg("key"), py::arg("bias_key"), py::arg("range_m"), py::arg("anchor"),
      py::arg("sigma_m"), py::arg("loss") = py::none(), py::arg("loss_scale") = 1.0,
      "A range to an anchor (x, y, z) from a 2-D pose, with an additive bias state (size 1).");
  f.def(
      "rss",
      [](Key key, Key path_loss_key, double rss_dbm, const Eigen::Vector3d& anchor, double sigma_db,
         double d0_m, std::optional<std::string> loss, double loss_scale) {
        CheckSigma(sigma_db, "sigma_db");
        CheckSigma(d0_m, "d0_m");
        RssFactor<2>::Reading r;
        r.rss = rss_dbm;
        r.anchor_m = anchor;
        r.sigma_db = sigma_db;
        r.d0_m = d0_m;
        return GraphFactor{std::shared_ptr<ceres::CostFunction>(RssFactor<2>::Create(r)),
                           Loss(loss, loss_scale),
                           {key, path_loss_key}};
      },
      py::arg("key"), py::arg("path_loss_key"), py::arg("rss_dbm"), py::arg("anchor"),
      py::arg("sigma_db") = 5.0, py::arg("d0_m") = 1.0, py::arg("loss") = py::none(),
      py::arg("loss_scale") = 1.0,
      "An RSS reading (dBm) on a 2-D pose with a path-loss state (A_dbm, eta) (size 2).");
}

void BindFactorGraph(py::module_& m) {
  py::class_<FactorGraph>(m, "FactorGraph", "States by key, factors over them; batch solve.")
      .def(py::init<>())
      .def(
          "add_state",
          [](FactorGraph& g, Key key, std::vector<double> value, std::optional<double> t,
             bool constant) { Check(g.AddState(StateOf(key, std::move(value), t, constant))); },
          py::arg("key"), py::arg("value"), py::arg("t") = py::none(), py::arg("constant") = false,
          "A state (t=None: static, e.g. a calibration block).")
      .def(
          "add_factor", [](FactorGraph& g, const GraphFactor& f) { Check(g.AddFactor(f)); },
          py::arg("factor"))
      .def(
          "solve",
          [](FactorGraph& g, int max_iterations, double function_tolerance,
             double parameter_tolerance, double initial_trust_region_radius) {
            SolverOptions o;
            o.max_iterations = max_iterations;
            o.function_tolerance = function_tolerance;
            o.parameter_tolerance = parameter_tolerance;
            o.initial_trust_region_radius = initial_trust_region_radius;
            std::optional<SolveSummary> s;
            Check(RunInterruptible([&]() -> Status {
              WG_ASSIGN_OR_RETURN(s, SolveBatch(&g, o));
              return Status::Ok();
            }));
            return SummaryDict(*s);
          },
          py::arg("max_iterations") = 100, py::arg("function_tolerance") = 1e-6,
          py::arg("parameter_tolerance") = 1e-8, py::arg("initial_trust_region_radius") = 1e4,
          "Levenberg-Marquardt from the current values (Ceres' options; invalid ones raise).")
      .def("value",
           [](const FactorGraph& g, Key key) {
             const std::vector<double> v = Value(g.Value(key));
             return Eigen::VectorXd(Eigen::Map<const Eigen::VectorXd>(v.data(), v.size()));
           })
      .def(
          "covariance",
          [](FactorGraph& g, const std::vector<Key>& keys) {
            return Value(MarginalCovariances(&g, {keys})).front();
          },
          py::arg("keys"), "Joint marginal covariance of the keys (tangent spaces stacked).")
      .def(
          "set_value",
          [](FactorGraph& g, Key key, const std::vector<double>& v) { Check(g.SetValue(key, v)); },
          py::arg("key"), py::arg("value"))
      .def("__contains__", &FactorGraph::Contains)
      .def_property_readonly("num_states", &FactorGraph::num_states)
      .def_property_readonly("num_factors", &FactorGraph::num_factors);
}

void BindStepGraph(py::module_& m) {
  m.def(
      "step_graph",
      [](const Walk& walk, const py::object& config) {
        const YAML::Node yaml = ToYaml(config, "step_graph");
        const StepGraphOptions o = Value(StepGraphOptionsFromYaml(
            yaml.IsNull() ? YAML::Node() : yaml, "step_graph", StepGraphOptions()));
        Check(ValidateWalk(walk));
        auto graph = std::make_unique<FactorGraph>();
        std::vector<double> times;
        Check(RunInterruptible([&]() -> Status {
          WG_ASSIGN_OR_RETURN(std::unique_ptr<StepGraph> sg, StepGraph::Build(walk, o));
          for (int k = 0; k < sg->num_nodes(); ++k) times.push_back(sg->node_time(k));
          return sg->AddTo(graph.get());
        }));
        return py::make_tuple(py::cast(std::move(graph)), times);
      },
      py::arg("walk"), py::arg("config") = py::none(),
      "fg-batch's graph of a walk before it solves, and its pose times: pose k has keys "
      "symbol('x', k) (position) and symbol('h', k) (heading), at dead-reckoning values. Add "
      "factors and solve() it; fg-batch itself may first initialize from a window pass.");
}

}  // namespace

void BindGraph(py::module_& m) {
  m.def("symbol", &SymbolOf, py::arg("letter"), py::arg("index"),
        "A state key: a letter and an index (GTSAM's Symbol), e.g. symbol('x', 3).");
  m.def("key_to_string", &KeyToString, py::arg("key"));
  py::class_<GraphFactor>(m, "Factor", "A cost function over states by key (factors/).")
      .def_property_readonly("keys", [](const GraphFactor& f) { return f.keys; })
      .def_property_readonly("num_residuals",
                             [](const GraphFactor& f) { return f.cost->num_residuals(); });
  py::module_ f = m.def_submodule("factors", "Built-in factors (walkgraph's factors/).");
  BindPriorFactors(f);
  BindRadioFactors(f);
  BindFactorGraph(m);
  BindStepGraph(m);
  BindSmoother(m);
}

}  // namespace walkgraph::python
