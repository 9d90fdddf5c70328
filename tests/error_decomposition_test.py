"""tools/error_decomposition.py: a scaled and a drifting copy of a known path are explained."""
import math
import os
import re
import subprocess
import sys

TOOL = os.path.join(os.path.dirname(__file__), "..", "tools", "error_decomposition.py")


def write(path, rows):
    path.write_text("t_s,x_m,y_m\n" + "".join(f"{t},{x},{y}\n" for t, x, y in rows))


def truth_rows():  # a 60 s walk: a square of 10 m sides at 1 m/s, 10 Hz
    rows = []
    for i in range(601):
        s = i / 10.0
        side, u = int(s // 10) % 4, s % 10
        x, y = [(u, 0), (10, u), (10 - u, 10), (0, 10 - u)][side]
        rows.append((s, x, y))
    return rows


def numbers(out):
    return [float(v) for v in re.findall(r"-?\d+\.\d+", out)]


def run(tmp_path, est):
    write(tmp_path / "truth.csv", truth_rows())
    write(tmp_path / "est.csv", est)
    r = subprocess.run([sys.executable, TOOL, str(tmp_path / "est.csv"), str(tmp_path / "truth.csv")],
                       capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    return numbers(r.stdout)


def test_a_scale_error_is_explained_by_sim2(tmp_path):
    c, s = math.cos(0.3), math.sin(0.3)
    est = [(t, 0.95 * (c * x - s * y) + 3.0, 0.95 * (s * x + c * y) - 1.0) for t, x, y in truth_rows()]
    _, walked, se2, sim2, scale, drift_rmse, drift, _, _ = run(tmp_path, est)
    assert abs(walked - 60.0) < 0.01
    assert se2 > 0.1
    assert sim2 < 1e-6
    assert abs(scale - 1 / 0.95) < 1e-4  # printed to 4 decimals


def test_a_yaw_drift_is_explained_by_the_drift_fit(tmp_path):
    w = math.radians(10.0) / 60.0  # 10 deg/min
    rows, est = truth_rows(), []
    x = y = 0.0
    for i, (t, tx, ty) in enumerate(rows):
        if i:
            dx, dy = tx - rows[i - 1][1], ty - rows[i - 1][2]
            a = w * (t - rows[0][0])
            x, y = x + math.cos(a) * dx - math.sin(a) * dy, y + math.sin(a) * dx + math.cos(a) * dy
        est.append((t, x, y))
    _, _, se2, sim2, scale, drift_rmse, drift, _, _ = run(tmp_path, est)
    assert se2 > 0.1
    assert drift_rmse < 0.1 * se2
    assert abs(drift - 10.0) < 0.2


def test_too_few_rows_fail(tmp_path):
    write(tmp_path / "truth.csv", truth_rows())
    write(tmp_path / "est.csv", [(0, 0, 0)])
    r = subprocess.run([sys.executable, TOOL, str(tmp_path / "est.csv"), str(tmp_path / "truth.csv")],
                       capture_output=True, text=True)
    assert r.returncode == 1 and "too few rows" in r.stderr
