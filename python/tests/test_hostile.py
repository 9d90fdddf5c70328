"""Hostile input through the Python module (issue 42): every case runs in its own interpreter,
so an abort or a segfault fails the case instead of killing pytest, and must end in a Python
exception of the expected class whose message says what is wrong (stream, row, field, key).

Classes: A. Python values → YAML (cycles, depth, types); B. the factor graph (Ceres/Eigen
assertions guarded); C. the fixed-lag smoother; D. in-memory walks get the reader's rules
(run, compare, errors, step_graph, validate); E. compare's and write_walk's arguments."""
import os
import subprocess
import sys
import textwrap

import pytest

SRC = os.environ.get("WALKGRAPH_SOURCE_DIR",
                     os.path.join(os.path.dirname(__file__), "..", ".."))
VALID_SMALL = os.path.join(SRC, "tests", "data", "walks", "valid_small")

# Run in the child before each case: `w` is a valid walk (tests/data/walks/valid_small),
# `g` a solved two-pose graph with keys x(0), x(1), `s` a fixed-lag smoother with states at
# t = 0..20 s (lag 5 s), deep(n, kind) a value nested n levels deep (built without recursion).
PRELUDE = r"""
import math, os, pathlib, re, sys
import numpy as np
import walkgraph
w = walkgraph.read_walk(%(walk)r)
x = lambda k: walkgraph.symbol("x", k)
def graph():
    g = walkgraph.FactorGraph()
    g.add_state(x(0), [0.0, 0.0], t=0.0)
    g.add_state(x(1), [1.0, 0.0], t=1.0)
    g.add_factor(walkgraph.factors.position_prior(x(0), [0.0, 0.0], 0.1))
    g.add_factor(walkgraph.factors.random_walk(x(0), x(1), 1.0, 1.0))
    g.solve()
    return g
def smoother():
    s = walkgraph.FixedLagSmoother(lag_s=5.0)
    for k in range(21):
        fs = [walkgraph.factors.position_prior(x(k), [float(k), 0.0], 0.5)]
        if k:
            fs.append(walkgraph.factors.random_walk(x(k - 1), x(k), 1.0, 1.0))
        s.update([(x(k), [float(k), 0.0], float(k))], fs)
    return s
def deep(n, kind=dict):
    v = 1
    for _ in range(n):
        v = {"a": v} if kind is dict else [v]
    return v
def rows(stream):
    return np.array(getattr(w, stream), dtype=float)
"""

CHILD = r"""
%(prelude)s
try:
%(body)s
except %(exc)s as e:
    msg = str(e)
    if not re.search(%(pattern)r, msg):
        print("WRONG MESSAGE: " + repr(msg))
        sys.exit(4)
    print("REFUSED: " + msg)
    sys.exit(0)
except BaseException as e:
    print("WRONG EXCEPTION: %%s: %%s" %% (type(e).__name__, e))
    sys.exit(5)
print("ACCEPTED (expected %(exc)s)")
sys.exit(3)
"""

CASES = []


def case(name, body, exc, pattern):
    CASES.append(pytest.param(textwrap.dedent(body).strip(), exc, pattern, id=name))


# ------------------------------------------------------------- A. Python values → YAML
case("config-dict-contains-itself", """
    c = {}; c["x"] = c
    walkgraph.run("odometry-dr", w, c)""", "ValueError", r"contains itself")
case("config-list-contains-itself", """
    l = []; l.append(l)
    walkgraph.run("odometry-dr", w, {"x": l})""", "ValueError",
     r"odometry-dr\.x: .*contains itself")
case("config-dict-30000-deep", """
    walkgraph.run("odometry-dr", w, deep(30000))""", "ValueError", r"nested deeper than 64")
case("config-list-30000-deep", """
    walkgraph.run("odometry-dr", w, {"x": deep(30000, list)})""", "ValueError",
     r"nested deeper than 64")
case("compare-config-contains-itself", """
    c = {}; c["fg-batch"] = c
    walkgraph.compare(w, ["fg-batch"], config=c)""", "ValueError", r"contains itself")
case("compare-config-30000-deep", """
    walkgraph.compare(w, ["fg-batch"], config={"fg-batch": deep(30000)})""", "ValueError",
     r"config\.fg-batch.*nested deeper")
case("simulate-overrides-contain-themselves", """
    o = {"duration_s": 30}; o["self"] = o
    walkgraph.simulate("tarrio-circle", 1, o)""", "ValueError", r"overrides.*contains itself")
case("simulate-overrides-30000-deep", """
    walkgraph.simulate("tarrio-circle", 1, deep(30000))""", "ValueError", r"nested deeper")
case("pcrb-overrides-contain-themselves", """
    o = {}; o["o"] = [o]
    walkgraph.pcrb("tarrio-circle", 1, 0, o)""", "ValueError", r"contains itself")
case("step-graph-config-contains-itself", """
    c = {}; c["c"] = c
    walkgraph.step_graph(w, c)""", "ValueError", r"step_graph.*contains itself")
case("config-key-not-a-string", """
    walkgraph.run("odometry-dr", w, {1: 2})""", "ValueError", r"option names must be strings")
case("config-value-an-object", """
    walkgraph.run("odometry-dr", w, {"x": object()})""", "ValueError",
     r"cannot use a object as an option value")
case("config-value-nan", """
    walkgraph.run("odometry-dr", w, {"x": float("nan")})""", "ValueError", r"must be finite")
case("config-value-huge-int", """
    walkgraph.run("odometry-dr", w, {"x": 2 ** 70})""", "ValueError", r"64-bit range")
case("compare-config-not-a-dict", """
    walkgraph.compare(w, ["fg-batch"], config=[1, 2])""", "ValueError", r"config: expected a dict")
case("config-shallow-but-unknown-key", """
    walkgraph.run("fg-batch", w, {"a": deep(50)})""", "ValueError", r"unknown option 'a'")
case("config-value-a-set", """
    walkgraph.run("odometry-dr", w, {"x": {1, 2}})""", "ValueError", r"cannot use a set")

# ------------------------------------------------------------- B. the factor graph
case("covariance-same-key-twice", """
    graph().covariance([x(0), x(0)])""", "ValueError", r"x0 named twice")
case("covariance-key-twice-among-others", """
    graph().covariance([x(0), x(1), x(0)])""", "ValueError", r"x0 named twice")
case("covariance-unconstrained-state", """
    g = graph()
    g.add_state(x(7), [0.0, 0.0], t=7.0)
    print(g.covariance([x(7)]))""", "(ValueError, RuntimeError)",
     r"x7.*(unconstrained|no factor|rank-deficient|not computable)")
case("covariance-unknown-key", """
    graph().covariance([x(9)])""", "walkgraph.NotFoundError", r"x9 not in the graph")
case("add-state-nan-value", """
    walkgraph.FactorGraph().add_state(x(0), [float("nan"), 0.0], t=0.0)""", "ValueError",
     r"x0 has a non-finite value")
case("add-state-inf-time", """
    walkgraph.FactorGraph().add_state(x(0), [0.0, 0.0], t=float("inf"))""", "ValueError",
     r"x0 has a non-finite time")
case("add-state-twice", """
    g = graph(); g.add_state(x(0), [0.0, 0.0])""", "ValueError", r"x0 added twice")
case("add-state-empty-value", """
    walkgraph.FactorGraph().add_state(x(0), [])""", "ValueError", r"empty value")
case("set-value-nan", """
    graph().set_value(x(0), [0.0, float("nan")])""", "ValueError", r"non-finite value for x0")
case("set-value-wrong-size", """
    graph().set_value(x(0), [0.0])""", "ValueError", r"another size for x0")
case("factor-names-a-state-twice", """
    g = graph()
    g.add_factor(walkgraph.factors.random_walk(x(0), x(0), 1.0, 1.0))""", "ValueError",
     r"names x0 twice")
case("factor-of-another-size", """
    g = graph()
    g.add_factor(walkgraph.factors.prior(x(0), [0.0, 0.0, 0.0], [1.0, 1.0, 1.0]))""",
     "ValueError", r"has size 3 but x0 has 2")
case("factor-on-a-missing-state", """
    graph().add_factor(walkgraph.factors.position_prior(x(5), [0.0, 0.0], 1.0))""",
     "ValueError", r"x5, which is not in the graph")
case("solve-negative-iterations", """
    graph().solve(max_iterations=-1)""", "ValueError", r"max_iterations")
case("solve-nan-tolerance", """
    graph().solve(function_tolerance=float("nan"))""", "ValueError", r"tolerances >= 0")
case("symbol-two-letters", """
    walkgraph.symbol("xy", 1)""", "ValueError", r"one character")
case("symbol-index-too-large", """
    walkgraph.symbol("x", 2 ** 60)""", "ValueError", r"2\^56")
case("factor-unknown-loss", """
    walkgraph.factors.range(x(0), x(1), 1.0, [0.0, 0.0, 0.0], 0.3, loss="welsch")""",
     "ValueError", r"loss must be None or one of none, huber, cauchy, soft-l1, arctan, tukey, "
                   r"not 'welsch'")
case("factor-zero-loss-scale", """
    walkgraph.factors.range(x(0), x(1), 1.0, [0.0, 0.0, 0.0], 0.3, loss="huber",
                            loss_scale=0.0)""", "ValueError", r"loss_scale must be > 0")
case("waypoint-between-alpha-2", """
    walkgraph.factors.waypoint_between(x(0), x(1), 2.0, [0.0, 0.0], 1.0)""", "ValueError",
     r"alpha must be in \[0, 1\]")
case("prior-mean-sigma-mismatch", """
    walkgraph.factors.prior(x(0), [0.0, 0.0], [1.0])""", "ValueError", r"same, non-zero size")
case("rss-factor-zero-sigma", """
    walkgraph.factors.rss(x(0), x(1), -60.0, [0.0, 0.0, 0.0], sigma_db=0.0)""", "ValueError",
     r"sigma_db must be finite and > 0")
case("position-prior-inf-sigma", """
    walkgraph.factors.position_prior(x(0), [0.0, 0.0], float("inf"))""", "ValueError",
     r"sigma_m must be finite and > 0")

# ------------------------------------------------------------- C. the fixed-lag smoother
case("smoother-nan-lag", """
    walkgraph.FixedLagSmoother(lag_s=float("nan"))""", "ValueError", r"lag_s must be finite")
case("smoother-inf-lag", """
    walkgraph.FixedLagSmoother(lag_s=float("inf"))""", "ValueError", r"lag_s must be finite")
case("smoother-nan-time", """
    s = smoother()
    s.update([(x(50), [0.0, 0.0], float("nan"))], [])""", "ValueError",
     r"x50 has a non-finite time")
case("smoother-time-before-the-window", """
    s = smoother()
    s.update([(x(50), [0.0, 0.0], 1.0)],
             [walkgraph.factors.position_prior(x(50), [0.0, 0.0], 1.0)])""", "ValueError",
     r"x50 at t = 1.* goes back before the window")
case("smoother-nan-value", """
    s = smoother()
    s.update([(x(50), [float("nan"), 0.0], 21.0)], [])""", "ValueError",
     r"x50 has a non-finite value")
case("smoother-same-key-twice-in-one-update", """
    s = walkgraph.FixedLagSmoother(lag_s=5.0)
    s.update([(x(0), [0.0, 0.0], 0.0), (x(0), [1.0, 0.0], 1.0)], [])""", "ValueError",
     r"x0 added twice")
case("smoother-state-tuple-of-four", """
    walkgraph.FixedLagSmoother().update([(x(0), [0.0], 0.0, 1)], [])""", "ValueError",
     r"a state is \(key, value\) or \(key, value, t\)")
case("smoother-factor-on-missing-state", """
    s = walkgraph.FixedLagSmoother()
    s.update([], [walkgraph.factors.position_prior(x(3), [0.0, 0.0], 1.0)])""",
     "(ValueError, walkgraph.NotFoundError)", r"x3")

case("smoother-factor-names-a-state-twice", """
    s = walkgraph.FixedLagSmoother()
    s.update([(x(0), [0.0, 0.0], 0.0)], [walkgraph.factors.random_walk(x(0), x(0), 1.0, 1.0)])""",
     "ValueError", r"names state x0 twice")
case("smoother-factor-of-another-size", """
    s = walkgraph.FixedLagSmoother()
    s.update([(x(0), [0.0], 0.0)], [walkgraph.factors.position_prior(x(0), [0.0, 0.0], 1.0)])""",
     "ValueError", r"block size mismatch on state x0")
case("smoother-refused-update-changes-nothing", """
    s = walkgraph.FixedLagSmoother()
    try:
        s.update([(x(0), [0.0, 0.0], 0.0)],
                 [walkgraph.factors.position_prior(x(0), [0.0, 0.0], 1.0),
                  walkgraph.factors.random_walk(x(0), x(9), 1.0, 1.0)])
    except ValueError:
        pass
    assert s.window_keys() == [], s.window_keys()
    s.estimate(x(0))""", "walkgraph.NotFoundError", r"x0")
case("smoother-covariance-of-a-state-without-factors", """
    s = walkgraph.FixedLagSmoother()
    s.update([(x(0), [0.0, 0.0], 0.0)], [])
    s.covariance(x(0))""", "RuntimeError", r"covariance of \{x0\} is not defined")
case("covariance-static-state-without-factors", """
    g = graph()
    g.add_state(walkgraph.symbol("b", 0), [0.0])
    g.covariance([x(0), walkgraph.symbol("b", 0)])""", "RuntimeError",
     r"(not defined|not computable)")
case("solve-absurd-prior-fails-cleanly", """
    g = walkgraph.FactorGraph()
    g.add_state(x(0), [0.0, 0.0], t=0.0)
    g.add_factor(walkgraph.factors.position_prior(x(0), [1e308, 1e308], 1e-300))
    g.solve()""", "(RuntimeError, ValueError)", r"Ceres failed|sigma_m")

# ------------------------------------------------------------- D. in-memory walks
case("run-nan-rss", """
    r = rows("rss"); r[3, 2] = np.nan; w.rss = r
    walkgraph.run("odometry-dr", w)""", "ValueError", r"rss\[3\]: non-finite value in rss")
case("run-nan-rss-time", """
    r = rows("rss"); r[2, 0] = np.nan; w.rss = r
    walkgraph.run("odometry-dr", w)""", "ValueError", r"rss\[2\]: non-finite value in t_s")
case("compare-inf-truth", """
    t = rows("truth"); t[1, 1] = np.inf; w.truth = t
    walkgraph.compare(w, ["odometry-dr"])""", "ValueError",
     r"truth\[1\]: non-finite value in x_m")
case("errors-duplicate-truth-time", """
    e = walkgraph.run("odometry-dr", w)
    t = rows("truth"); t[2, 0] = t[1, 0]; w.truth = t
    walkgraph.errors(e, w)""", "ValueError", r"truth\[2\]: timestamp .* repeats")
case("step-graph-nan-odometry", """
    o = rows("odometry"); o[1, 2] = np.nan; w.odometry = o
    walkgraph.step_graph(w)""", "ValueError", r"odometry\[1\]: non-finite value in dheading_rad")
case("imu-object-array-of-none", """
    a = np.array(rows("imu"), dtype=object); a[2, 2] = None
    w.imu = a""", "ValueError", r"walk\.imu\[2\], column 2: None is not a number")
case("truth-list-with-none", """
    w.truth = [[0.0, 0.0, 0.0], [1.0, None, 0.0]]""", "ValueError",
     r"walk\.truth\[1\], column 1: None is not a number")
case("rss-object-array-with-a-string", """
    a = np.array(rows("rss"), dtype=object); a[0, 2] = "-60"
    w.rss = a""", "ValueError", r"walk\.rss\[0\], column 2: '-60' is not a number")
case("rss-string-array", """
    w.rss = np.array([["0", "1", "-60"]])""", "ValueError", r"walk\.rss: expected a numeric array")
case("imu-wrong-width", """
    w.imu = np.zeros((3, 5))""", "ValueError", r"walk\.imu: expected an \(N, 7\) array")
case("rss-fractional-anchor-id", """
    r = rows("rss"); r[0, 1] = 1.5; w.rss = r""", "ValueError",
     r"walk\.rss\[0\]: anchor id must be an integer")
case("run-imu-time-backwards", """
    a = rows("imu"); a[3, 0] = a[1, 0]; w.imu = a
    walkgraph.run("odometry-dr", w)""", "ValueError", r"imu\[3\]: timestamp .* goes backwards")
case("run-rss-unknown-anchor", """
    r = rows("rss"); r[0, 1] = 77; w.rss = r
    walkgraph.run("odometry-dr", w)""", "ValueError", r"rss\[0\]: unknown anchor_id")
case("run-rss-plus-42-dbm", """
    r = rows("rss"); r[1, 2] = 42.0; w.rss = r
    walkgraph.run("odometry-dr", w)""", "ValueError", r"rss\[1\]: rss 42 outside")
case("run-imu-acceleration-absurd", """
    a = rows("imu"); a[0, 1] = 1e6; w.imu = a
    walkgraph.run("odometry-dr", w)""", "ValueError", r"imu\[0\]: acceleration component over")
case("run-radio-eta-zero", """
    w.radio = {"eta": 0.0}
    walkgraph.run("odometry-dr", w)""", "ValueError", r"radio: eta 0 outside \(0, 10\]")
case("run-radio-eta-huge", """
    w.radio = {"eta": 1e6}
    walkgraph.run("odometry-dr", w)""", "ValueError", r"radio: eta 1e\+06 outside")
case("run-radio-a-dbm-absurd", """
    w.radio = {"A_dbm": -9.9e6}
    walkgraph.run("odometry-dr", w)""", "ValueError", r"radio: A_dbm -9\.9e\+06 outside")
case("run-radio-sigma-tiny", """
    w.radio = {"sigma_db": 1e-9}
    walkgraph.run("odometry-dr", w)""", "ValueError", r"radio: sigma_db .* outside")
case("radio-eta-a-string", """
    w.radio = {"eta": "2.5"}""", "ValueError", r"radio\.eta: expected a number, not a str")
case("radio-unknown-key", """
    w.radio = {"gain": 1.0}""", "ValueError", r"radio: unknown key 'gain'")
case("run-heading-in-degrees", """
    w.initial_pose = {"x_m": 0.0, "y_m": 0.0, "heading_rad": 90.0}
    walkgraph.run("odometry-dr", w)""", "ValueError", r"initial_pose: heading_rad 90 outside")
case("run-start-coordinate-huge", """
    w.initial_pose = {"x_m": 1e9, "y_m": 0.0}
    walkgraph.run("odometry-dr", w)""", "ValueError", r"initial_pose: x_m 1e\+09 outside")
case("run-start-sigma-tiny", """
    w.initial_pose = {"x_m": 0.0, "y_m": 0.0, "sigma_xy_m": 1e-9}
    walkgraph.run("odometry-dr", w)""", "ValueError", r"initial_pose: sigma_xy_m .* outside")
case("initial-pose-a-list", """
    w.initial_pose = [0.0, 0.0]""", "ValueError", r"initial_pose: expected a dict or None")
case("run-extra-nan", """
    w.extra = {"gain": float("nan")}
    walkgraph.run("odometry-dr", w)""", "ValueError", r"extra\.gain is not finite")
case("run-waypoint-long-after-the-walk", """
    p = rows("waypoints"); p[-1, 0] = 1e9; w.waypoints = p
    walkgraph.run("odometry-dr", w)""", "ValueError",
     r"waypoints\[1\]: t_s 1e\+09 outside the walk's time span")
case("run-imu-1000-s-away-from-radio", """
    a = rows("imu"); a[:, 0] += 1000.0; w.imu = a
    walkgraph.run("odometry-dr", w)""", "ValueError",
     r"imu spans .* and rss .* do not overlap in time")
case("validate-every-range-zero", """
    w2 = walkgraph.Walk(anchors=w.anchors, ranges=[[0.0, 1, 0.0], [0.5, 2, 0.0]],
                        radio={"kind": "range"}, truth=[[0.0, 0, 0], [0.5, 0.7, 0]])
    w2.validate()""", "ValueError", r"range: every range_m is 0")
case("validate-rfcode-units-with-dbm-readings", """
    w.radio = {"units": "rfcode", "A_dbm": 100.0}
    w.validate()""", "ValueError", r"every reading is negative \(dBm-like\)")
case("run-truth-in-another-frame", """
    t = rows("truth"); t[:, 1] += 4.8e6; w.truth = t
    walkgraph.run("odometry-dr", w)""", "ValueError",
     r"truth\[0\]: \(4\.8e\+06, 0\) is .* m from the anchors; expected it and the anchors in "
     r"one frame")
case("walk-unknown-field", """
    walkgraph.Walk(speed=1.0)""", "ValueError", r"Walk: unknown field 'speed'")
case("walk-truth-kind-bogus", """
    w.truth_kind = "sometimes\"""", "ValueError", r"truth_kind: 'sometimes' is not one of")

# ------------------------------------------------------------- E. compare's, write_walk's arguments
case("compare-empty-estimator-list", """
    walkgraph.compare(w, [])""", "ValueError", r"estimators is an empty list")
case("compare-estimators-a-string", """
    walkgraph.compare(w, "fg-batch")""", "ValueError", r"estimators must be a list")
case("compare-estimators-not-strings", """
    walkgraph.compare(w, [1, 2])""", "ValueError", r"list of estimator ids \(str\)")
case("compare-option-of-an-estimator-not-run", """
    walkgraph.compare(w, ["odometry-dr"], config={"fg-batch": {"covariance": False}})""",
     "ValueError", r"options for 'fg-batch', which is not among the estimators run")
case("compare-option-of-an-unknown-estimator", """
    walkgraph.compare(w, ["odometry-dr"], config={"nope": {}})""", "ValueError",
     r"'nope', which is not an estimator id")
case("compare-out-an-int", """
    walkgraph.compare(w, ["odometry-dr"], out=123)""", "ValueError",
     r"out: expected a path \(str or os\.PathLike\), not a int")
case("compare-out-bytes", """
    walkgraph.compare(w, ["odometry-dr"], out=b"dir")""", "ValueError",
     r"out: expected a path .* not a bytes")
case("compare-not-a-walk", """
    walkgraph.compare(123)""", "ValueError", r"expected a Walk or a scenario name")
case("compare-runs-on-a-walk", """
    walkgraph.compare(w, ["odometry-dr"], runs=2)""", "ValueError",
     r"runs > 1 needs a scenario name")
case("compare-scenario-zero-runs", """
    walkgraph.compare("tarrio-circle", ["odometry-dr"], runs=0)""", "ValueError", r"runs")
case("write-walk-path-an-int", """
    walkgraph.write_walk(w, 123)""", "ValueError", r"write_walk: expected a path")
case("write-walk-invalid-walk", """
    r = rows("rss"); r[0, 2] = np.nan; w.rss = r
    walkgraph.write_walk(w, "never-written")""", "ValueError", r"rss\[0\]: non-finite value")


def run_child(body, exc, pattern, cwd):
    code = CHILD % {
        "prelude": PRELUDE % {"walk": VALID_SMALL},
        "body": textwrap.indent(body, "    "),
        "exc": exc,
        "pattern": pattern,
    }
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join(
        os.path.abspath(p) for p in env.get("PYTHONPATH", "").split(os.pathsep) if p)
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          timeout=300, cwd=cwd, env=env)


@pytest.mark.parametrize("body,exc,pattern", CASES)
def test_hostile(body, exc, pattern, tmp_path):
    p = run_child(body, exc, pattern, str(tmp_path))
    assert p.returncode == 0, (
        "exit %d (negative: killed by a signal)\nstdout: %s\nstderr: %s" %
        (p.returncode, p.stdout[-2000:], p.stderr[-2000:]))
    assert "REFUSED: " in p.stdout
    # Nothing was written where the case ran (write_walk refused, compare had no out=).
    assert sorted(os.listdir(tmp_path)) == []


def test_out_accepts_a_path_like(tmp_path):
    # The positive control of compare-out-an-int: a pathlib.Path is a path.
    body = textwrap.dedent("""
        out = pathlib.Path("report")
        res = walkgraph.compare(w, ["odometry-dr"], out=out)
        assert (out / "results.json").exists()
        raise ValueError("written")""").strip()
    p = run_child(body, "ValueError", r"^written$", str(tmp_path))
    assert p.returncode == 0, p.stdout + p.stderr


def test_there_are_at_least_60_cases():
    assert len(CASES) >= 60
