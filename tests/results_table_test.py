"""tools/results_table.py: a results.json's metrics as a markdown table (mean ± std per run set)."""
import json
import os
import subprocess
import sys

TOOL = os.path.join(os.path.dirname(__file__), "..", "tools", "results_table.py")


def run(tmp_path, results, *cols):
    path = tmp_path / "results.json"
    path.write_text(json.dumps(results))
    return subprocess.run([sys.executable, TOOL, str(path), *cols], capture_output=True,
                          text=True, check=True).stdout.splitlines()


def test_monte_carlo_rows_show_mean_std_and_bad_runs(tmp_path):
    lines = run(tmp_path, {
        "runs": 10, "pcrb_rmse_m": 0.25, "pcrb_filter_rmse_m": None,
        "estimators": {
            "fg-batch": {"rmse_m": 0.5, "rmse_m_std": 0.0625, "floor_hit_rate": 1.0,
                         "floor_hit_rate_std": 0.0, "diverged_runs": 0, "failed_runs": 0},
            "tarrio-kf": {"rmse_m": 2.0, "rmse_m_std": 0.5, "floor_hit_rate": None,
                          "diverged_runs": 3, "failed_runs": 1}}}, "rmse_m", "floor_hit_rate")
    assert lines[0] == "| estimator | rmse_m | floor_hit_rate | runs diverged / failed |"
    assert lines[2] == "| `fg-batch` | 0.500 ± 0.062 | 1.000 ± 0.000 | 0 / 0 of 10 |"
    assert lines[3] == "| `tarrio-kf` | 2.000 ± 0.500 | - | 3 / 1 of 10 |"
    assert lines[4] == "| PCRB (smoother) | 0.250 |  | |"
    assert len(lines) == 5  # no filter PCRB row: it is null


def test_single_walk_has_no_std(tmp_path):
    lines = run(tmp_path, {"estimators": {"fg-batch": {"rmse_m": 1.25}}}, "rmse_m")
    assert lines[2] == "| `fg-batch` | 1.250 | 0 / 0 of 1 |"


def test_pivot_puts_walks_side_by_side(tmp_path):
    a, b = tmp_path / "a.json", tmp_path / "b.json"
    a.write_text(json.dumps({"runs": 4, "estimators": {
        "fg-batch": {"anees": 1.5, "anees_std": 0.25},
        "rss-only": {"anees": 1234.5, "anees_std": 450.0, "diverged_runs": 1}}}))
    b.write_text(json.dumps({"runs": 4, "estimators": {
        "gadeke-kf": {"anees": None, "failed_runs": 4},
        "fg-batch": {"anees": 2.0, "anees_std": 0.5}}}))
    out = subprocess.run([sys.executable, TOOL, "--pivot", "anees", "A=%s" % a, "B=%s" % b],
                         capture_output=True, text=True, check=True).stdout.splitlines()
    assert out[0] == "| estimator | `A` | `B` |"
    assert out[2] == "| `fg-batch` | 1.500 ± 0.250 | 2.000 ± 0.500 |"
    assert out[3] == "| `rss-only` | 1.23e+03 ± 450.000 (1 diverged) | — |"
    assert out[4] == "| `gadeke-kf` | — | fails |"
