"""tools/study_table.py: one sweep of a study.csv as a markdown table."""
import os
import subprocess
import sys

TOOL = os.path.join(os.path.dirname(__file__), "..", "tools", "study_table.py")
HEADER = ("sweep,parameter,value,estimator,runs,seed,failed_runs,diverged_runs,final_m,final_m_std,"
          "error\n")
CSV = HEADER + (
    "s2,eta,1.5,a,10,1,0,0,0.5,0.25,\n"
    "s2,eta,1.5,b,10,1,0,2,1.25,0.5,\n"
    "s2,eta,2.0,a,10,1,0,0,0.75,,\n"
    "s2,eta,2.0,b,10,1,10,0,,,no fix\n"
    "s3,tags,5,a,10,1,0,0,9,1,\n")


def run(tmp_path, *args):
    path = tmp_path / "study.csv"
    path.write_text(CSV)
    return subprocess.run([sys.executable, TOOL, str(path), *args], capture_output=True, text=True)


def test_sweep_rows_values_and_paper_column(tmp_path):
    r = run(tmp_path, "s2", "final_m", "--column", "paper=1.86 1.32", "--label", "p")
    assert r.returncode == 0, r.stderr
    assert r.stdout.splitlines() == [
        "| p | paper | `a` | `b` |",
        "|---|---|---|---|",
        "| 1.5 | 1.86 | 0.500 ± 0.250 | 1.250 ± 0.500 (2 diverged) |",
        "| 2.0 | 1.32 | 0.750 | failed |",
    ]


def test_wrong_column_length_and_unknown_sweep_are_refused(tmp_path):
    r = run(tmp_path, "s2", "final_m", "--column", "paper=1 2 3")
    assert r.returncode != 0 and "3 values for 2" in r.stderr
    r = run(tmp_path, "nope", "final_m")
    assert r.returncode != 0 and "no sweep 'nope'" in r.stderr
