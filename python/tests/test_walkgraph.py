"""The Python module against the library and the CLI: every function, error mapping, numpy
round trips, and fg-batch through Python equal to the CLI's `smooth` to 1e-9 m."""
import math
import os
import subprocess
import sys
import tempfile

import numpy as np
import pytest

import walkgraph

SRC = os.environ.get("WALKGRAPH_SOURCE_DIR",
                     os.path.join(os.path.dirname(__file__), "..", ".."))
PLAZA1 = os.path.join(SRC, "datasets", "plaza1")
VALID_SMALL = os.path.join(SRC, "tests", "data", "walks", "valid_small")
CLI = os.environ.get("WALKGRAPH_CLI")


@pytest.fixture(scope="module")
def plaza1():
    return walkgraph.read_walk(PLAZA1)


def test_read_walk_exposes_streams_as_arrays(plaza1):
    assert plaza1.name == "Plaza1"
    assert plaza1.ranges.shape[1] == 3 and plaza1.ranges.shape[0] > 1000
    assert plaza1.anchors.shape == (4, 4)
    assert plaza1.odometry.shape[1] == 3
    assert plaza1.truth.shape[1] in (3, 4)
    assert plaza1.imu.shape == (0, 7)
    assert plaza1.radio["kind"] == "range"
    assert plaza1.imu_placement == "none"
    assert plaza1.initial_pose is not None and "x_m" in plaza1.initial_pose


def test_walk_built_in_python_equals_the_one_read(tmp_path):
    disk = walkgraph.read_walk(VALID_SMALL)
    built = walkgraph.Walk(
        name=disk.name, source=disk.source, licence=disk.licence,
        imu_placement=disk.imu_placement, radio=disk.radio, initial_pose=disk.initial_pose,
        imu=disk.imu, rss=disk.rss, odometry=disk.odometry, truth=disk.truth,
        anchors=disk.anchors, waypoints=disk.waypoints, truth_kind=disk.truth_kind)
    built.validate()
    for stream in ("imu", "rss", "ranges", "odometry", "truth", "anchors", "waypoints"):
        np.testing.assert_array_equal(getattr(built, stream), getattr(disk, stream))
    assert built.radio == disk.radio and built.initial_pose == disk.initial_pose
    # Written from Python and read back: the same numbers, bit for bit.
    out = tmp_path / "again"
    walkgraph.write_walk(built, str(out))
    back = walkgraph.read_walk(str(out))
    for stream in ("imu", "rss", "odometry", "truth", "anchors", "waypoints"):
        np.testing.assert_array_equal(getattr(back, stream), getattr(disk, stream))


def test_bad_input_raises_with_file_and_line(tmp_path):
    bad = tmp_path / "bad"
    walkgraph.write_walk(walkgraph.read_walk(VALID_SMALL), str(bad))
    with open(bad / "rss.csv", "a") as f:
        f.write("9,1,abc\n")
    with pytest.raises(ValueError, match=r"rss\.csv:\d+:.*'abc'"):
        walkgraph.read_walk(str(bad))
    with pytest.raises(FileNotFoundError):
        walkgraph.read_walk(str(tmp_path / "nowhere"))
    with pytest.raises(RuntimeError):  # a directory where a file should be: not ValueError
        walkgraph.write_walk(walkgraph.read_walk(VALID_SMALL), "/proc/walkgraph-test")
    w = walkgraph.read_walk(VALID_SMALL)
    w.waypoints = np.array([[0.5, 1.0, 2.0, 0.0]])
    with pytest.raises(ValueError, match=r"waypoints\[0\].*sigma_m"):
        w.validate()
    with pytest.raises(ValueError, match=r"walk\.rss: expected an \(N, 3\) array"):
        w.rss = np.zeros((2, 5))
    with pytest.raises(ValueError, match="anchor id must be an integer"):
        w.rss = np.array([[0.0, 1.5, -60.0]])
    with pytest.raises(ValueError, match="'wrist' is not one of"):
        w.imu_placement = "wrist"
    with pytest.raises(ValueError, match="unknown field"):
        walkgraph.Walk(colour="red")


def test_write_walk_refuses_a_folder_it_did_not_write(tmp_path):
    mine = tmp_path / "mine"
    mine.mkdir()
    (mine / "notes.txt").write_text("keep me")
    with pytest.raises(Exception):
        walkgraph.write_walk(walkgraph.read_walk(VALID_SMALL), str(mine))
    assert (mine / "notes.txt").read_text() == "keep me"


def test_estimators_list_ids_descriptions_and_defaults():
    est = {e["id"]: e for e in walkgraph.estimators()}
    assert "fg-batch" in est and "tarrio-kf" in est
    assert est["fg-batch"]["description"]
    opts = est["fg-batch"]["options"]
    assert opts["lag_s"] == 10.0 and opts["path_loss"] == "auto"
    assert isinstance(opts["pdr"], dict) and "weinberg_k" in opts["pdr"]
    assert opts["A_dbm"] is None  # unset: the walk's value


def test_run_gives_arrays_and_validates_config(plaza1):
    e = walkgraph.run("odometry-dr", plaza1)
    n = len(e)
    assert n > 100
    assert e.t.shape == (n,) and e.xy.shape == (n, 2) and e.yaw.shape == (n,)
    assert e.cov.shape == (n, 3, 3)
    assert isinstance(e.diagnostics, dict)
    with pytest.raises(ValueError, match="unknown option 'no_such_key'"):
        walkgraph.run("fg-batch", plaza1, {"no_such_key": 1})
    with pytest.raises(walkgraph.NotFoundError, match="unknown estimator 'nope'"):
        walkgraph.run("nope", plaza1)
    with pytest.raises(LookupError):
        walkgraph.run("nope", plaza1)


def test_fg_batch_equals_the_cli_smooth(plaza1, tmp_path):
    if not CLI:
        pytest.skip("WALKGRAPH_CLI not set")
    e = walkgraph.run("fg-batch", plaza1)
    out = tmp_path / "fg-batch.tum"
    subprocess.run([CLI, "smooth", PLAZA1, "--estimator", "fg-batch", "--out", str(out)],
                   check=True, capture_output=True)
    rows = np.loadtxt(out, comments="#")
    assert rows.shape[0] == len(e)
    np.testing.assert_allclose(rows[:, 0], e.t, rtol=0, atol=1e-9)
    assert np.max(np.abs(rows[:, 1:3] - e.xy)) <= 1e-9


def test_errors_and_compare(plaza1, tmp_path):
    e = walkgraph.run("fg-batch", plaza1)
    err = walkgraph.errors(e, plaza1)
    assert len(err["error_m"]) == len(err["t"]) > 100
    assert 0 < err["stats"]["rmse_m"] < 2.0
    res = walkgraph.compare(plaza1, estimators=["odometry-dr", "fg-batch"],
                            out=str(tmp_path / "report"))
    assert set(res["estimators"]) == {"odometry-dr", "fg-batch"}
    assert abs(res["estimators"]["fg-batch"]["rmse_m"] - err["stats"]["rmse_m"]) < 1e-9
    assert (tmp_path / "report" / "results.json").exists()
    assert (tmp_path / "report" / "report.html").exists()


def test_compare_counts_the_walks_warnings():
    w = walkgraph.read_walk(VALID_SMALL)
    assert walkgraph.compare(w)["warnings"] == {"count": 0, "messages": []}
    w.extra = {"convert.rss_invalid_dropped": 4.0}
    radio = w.radio
    radio["eta"] = 7.5
    w.radio = radio
    res = walkgraph.compare(w)
    assert res["warnings"]["count"] == 2
    assert "the converter dropped 4 rss reading(s)" in res["warnings"]["messages"][0]
    assert "radio: eta 7.5 outside [1.5, 6]" in res["warnings"]["messages"][1]


def test_compare_scores_after_alignment_and_warns_of_an_untied_frame():
    w = walkgraph.read_walk(VALID_SMALL)
    w.initial_pose = None
    w.waypoints = np.zeros((0, 4))
    w.rss = w.rss[w.rss[:, 1] == 1]  # one heard anchor: nothing ties the walk to the truth's frame
    plain = walkgraph.compare(w, ["fg-batch"])
    assert plain["warnings"]["count"] == 1
    assert "nothing ties an estimate to the truth's frame" in plain["warnings"]["messages"][0]
    aligned = walkgraph.compare(w, ["fg-batch"], align_se2=True)
    assert aligned["warnings"]["count"] == 0
    e = walkgraph.run("fg-batch", w)
    err = walkgraph.errors(e, w, align_se2=True)
    assert abs(aligned["estimators"]["fg-batch"]["rmse_m"] - err["stats"]["rmse_m"]) < 1e-9


def test_simulate_pcrb_and_monte_carlo_compare():
    w = walkgraph.simulate("tarrio-circle", 3, {"duration_s": 30})
    assert w.imu.shape[0] > 1000 and w.truth.shape[0] > 10
    again = walkgraph.simulate("tarrio-circle", 3, {"duration_s": 30})
    np.testing.assert_array_equal(w.imu, again.imu)  # same seed, same walk
    assert "tarrio-circle" in walkgraph.scenarios()
    b = walkgraph.pcrb("tarrio-circle", runs=1, seed=3, overrides={"duration_s": 30})
    assert b["smoother_rmse_m"] > 0 and b["filter"].shape[1:] == (2, 2)
    res = walkgraph.compare("tarrio-circle", estimators=["fg-batch"], runs=2, seed=1,
                            config={"fg-batch": {"covariance": False}})
    assert res["runs"] == 2 and "fg-batch" in res["estimators"]
    with pytest.raises(ValueError):
        walkgraph.simulate("tarrio-circle", 1, {"no_such_override": 1})
    with pytest.raises(walkgraph.NotFoundError, match="unknown scenario"):
        walkgraph.simulate("no-such-scenario", 1)


def test_survey_places_unknown_anchors_and_the_map_applies():
    walks = []
    for seed in (1, 2):
        w = walkgraph.simulate("tarrio-circle", seed, {"laps": 1})
        a = w.anchors.copy()
        a[::2, 1:3] = np.nan  # every other anchor of unknown position
        w.anchors = a
        walks.append(w)
    m = walkgraph.survey(walks)
    truth = walkgraph.simulate("tarrio-circle", 1, {"laps": 1}).anchors
    assert m["anchors"].shape == (truth.shape[0], 5)
    placed = np.isin(m["anchors"][:, 0], m["placed_ids"])
    assert placed.sum() >= 4 and m["covariance"].shape == (placed.sum(), 2, 2)
    err = np.linalg.norm(m["anchors"][placed, 1:3] - truth[placed, 1:3], axis=1)
    assert err.mean() < 3.0  # the C++ test's figure (tests/survey_test.cc)
    assert np.all(m["anchors"][placed, 4] > 0) and np.all(m["anchors"][~placed, 4] == 0)
    # The second walk's receiver 8 dB loud: the walks disagree, and every anchor's covariance is
    # at least the median disagreement times its own (survey.h, variance_factor).
    loud = [walks[0], walkgraph.simulate("tarrio-circle", 2, {"laps": 1})]
    loud[1].anchors = walks[1].anchors
    rss = loud[1].rss.copy()
    rss[:, 2] += 8.0
    loud[1].rss = rss
    pooled, own = walkgraph.survey(loud), walkgraph.survey(loud, pool_disagreement=False)
    both = np.asarray(pooled["walks"]) == 2
    d, d_own = np.asarray(pooled["disagreement"]), np.asarray(own["disagreement"])
    assert own["variance_factor"] == 1.0 and both.any()
    assert pooled["variance_factor"] == max(1.0, np.sort(d[both])[both.sum() // 2])  # upper median
    assert pooled["variance_factor"] > 1.0
    scale = np.maximum(np.maximum(1.0, d_own), pooled["variance_factor"]) / np.maximum(1.0, d_own)
    np.testing.assert_allclose(pooled["covariance"], scale[:, None, None] * own["covariance"],
                               rtol=1e-12)
    third = walkgraph.simulate("tarrio-circle", 3, {"laps": 1})
    a = third.anchors.copy()
    a[::2, 1:3] = np.nan
    third.anchors = a
    assert walkgraph.apply_radio_map(third, m["anchors"]) == placed.sum()
    assert third.anchors.shape[1] == 5 and not np.isnan(third.anchors[:, 1]).any()
    with pytest.raises(ValueError, match="checkpoint_sigma_m"):
        walkgraph.survey(walks, checkpoint_sigma_m=0)
    with pytest.raises(ValueError, match="no truth"):
        walkgraph.survey([walkgraph.Walk(anchors=truth)])


def test_graph_core_batch_and_fixed_lag():
    # A point walking east at 1 m/s past three anchors, as examples/ and the C++ docs do.
    anchors = [np.array([0.0, 5.0, 0.0]), np.array([10.0, -5.0, 0.0]),
               np.array([20.0, 5.0, 0.0])]
    x = lambda k: walkgraph.symbol("x", k)
    b = lambda a: walkgraph.symbol("b", a)
    g = walkgraph.FactorGraph()
    smoother = walkgraph.FixedLagSmoother(lag_s=5.0)
    for a in range(3):
        g.add_state(b(a), [0.0], constant=True)
    smoother.update([(b(a), [0.0]) for a in range(3)],
                    [walkgraph.factors.prior(b(a), [0.0], [1e-3]) for a in range(3)])
    for k in range(21):
        g.add_state(x(k), [k + 0.3, -0.2], t=float(k))
        fs = []
        if k > 0:
            fs.append(walkgraph.factors.random_walk(x(k - 1), x(k), 1.0, 1.0))
        for a in range(3):
            r = float(np.linalg.norm(np.array([k, 0.0, 0.0]) - anchors[a]))
            fs.append(walkgraph.factors.range(x(k), b(a), r, anchors[a], 0.3, loss="cauchy"))
        for f in fs:
            g.add_factor(f)
        smoother.update([(x(k), [k + 0.3, -0.2], float(k))], fs)
    s = g.solve()
    assert s["termination"] in ("converged", "no-convergence")
    assert np.allclose(g.value(x(10)), [10.0, 0.0], atol=0.01)
    cov = g.covariance([x(10)])
    assert cov.shape == (2, 2) and cov[0, 0] > 0
    # The window ends where the batch does (the newest state sees the same data).
    assert np.allclose(smoother.estimate(x(20)), g.value(x(20)), atol=1e-3)
    assert walkgraph.symbol("x", 0) not in smoother.window_keys()
    # A waypoint pulls the batch onto it and shrinks its covariance.
    g.add_factor(walkgraph.factors.position_prior(x(10), [10.5, 0.5], 0.05))
    g.solve()
    assert np.linalg.norm(g.value(x(10)) - [10.5, 0.5]) < 0.1
    assert g.covariance([x(10)])[0, 0] < cov[0, 0]
    with pytest.raises(ValueError):
        g.add_factor(walkgraph.factors.position_prior(x(99), [0.0, 0.0], 1.0))
    with pytest.raises(ValueError):
        walkgraph.factors.position_prior(x(1), [0.0, 0.0], -1.0)
    assert walkgraph.key_to_string(x(12)) == "x12"


def test_every_estimator_loss_name_is_a_factor_loss():
    # One range factor 10 sigma off (s = 100) under each of the estimators' six loss names (the
    # same table as their YAML options): its cost is Ceres' 0.5 rho(s) with scale 1 (the range
    # factor's distance is smoothed by ~1e-8 relative).
    x, b = walkgraph.symbol("x", 0), walkgraph.symbol("b", 0)
    expected = {None: 50.0, "none": 50.0, "huber": 0.5 * (2 * 10 - 1),
                "cauchy": 0.5 * math.log(101.0), "soft-l1": math.sqrt(101.0) - 1.0,
                "arctan": 0.5 * math.atan2(100.0, 1.0), "tukey": 0.5 / 3.0}
    for loss, cost in expected.items():
        g = walkgraph.FactorGraph()
        g.add_state(b, [0.0], constant=True)
        g.add_state(x, [0.0, 0.0])
        g.add_factor(walkgraph.factors.position_prior(x, [0.0, 0.0], 1.0))
        g.add_factor(walkgraph.factors.range(x, b, 0.0, [10.0, 0.0, 0.0], 1.0, loss=loss))
        assert g.solve()["initial_cost"] == pytest.approx(cost, rel=1e-6), loss


def test_ctrl_c_stops_a_long_run_and_the_library_goes_on():
    # A child process runs a long fixed-lag smoothing and gets SIGINT after 1 s: it must raise
    # KeyboardInterrupt within a few seconds, then run again normally.
    code = r"""
import os, signal, threading, time, walkgraph
w = walkgraph.simulate("tarrio-circle", 1, {"duration_s": 3000})
threading.Timer(1.0, lambda: os.kill(os.getpid(), signal.SIGINT)).start()
t0 = time.time()
try:
    walkgraph.run("fg-window", w)
    print("finished without interruption")
except KeyboardInterrupt:
    print("interrupted after %.1f s" % (time.time() - t0))
e = walkgraph.run("odometry-dr", walkgraph.read_walk(os.environ["PLAZA1"]))
print("then ran", len(e))
"""
    env = dict(os.environ, PLAZA1=PLAZA1)
    p = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True,
                       timeout=300)
    assert p.returncode == 0, p.stderr
    assert "interrupted after" in p.stdout, p.stdout
    secs = float(p.stdout.split("interrupted after ")[1].split(" s")[0])
    print(p.stdout)
    assert secs < 5.0, p.stdout
    assert "then ran" in p.stdout


def test_step_graph_from_a_walk_takes_a_waypoint(plaza1):
    # fg-batch's own graph of Plaza1 (odometry walks start from dead reckoning, as fg-batch
    # does): solved as is it gives fg-batch's positions; with a waypoint it moves onto it.
    g, times = walkgraph.step_graph(plaza1)
    assert len(times) > 1000 and walkgraph.symbol("x", len(times) - 1) in g
    g.solve(initial_trust_region_radius=1e8)  # fg-batch's solver options
    e = walkgraph.run("fg-batch", plaza1, {"covariance": False})
    k = len(times) // 2
    assert np.linalg.norm(g.value(walkgraph.symbol("x", k)) - e.xy[k]) < 1e-6
    target = e.xy[k] + np.array([1.0, 0.0])
    g.add_factor(walkgraph.factors.position_prior(walkgraph.symbol("x", k), target, 0.05))
    g.solve()
    assert np.linalg.norm(g.value(walkgraph.symbol("x", k)) - target) < 0.1
    with pytest.raises(ValueError, match="unknown option"):
        walkgraph.step_graph(plaza1, {"no_such_key": 1})
