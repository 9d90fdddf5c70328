"""Loads a walk (the bundled Plaza1 by default), runs fg-batch and a paper filter (Tarrio's KF,
000), and plots both trajectories over the truth and the CDF of their errors to a PNG.

usage: python3 examples/plaza1_fg_vs_filter.py [WALK_DIR] [OUT.png]
(with the module built: PYTHONPATH=build/python, or installed by cmake --install)
"""
import os
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

import walkgraph  # noqa: E402

here = os.path.dirname(os.path.abspath(__file__))
walk_dir = sys.argv[1] if len(sys.argv) > 1 else os.path.join(here, "..", "datasets", "plaza1")
out_png = sys.argv[2] if len(sys.argv) > 2 else "plaza1_fg_vs_filter.png"

walk = walkgraph.read_walk(walk_dir)
fig, (ax_xy, ax_cdf) = plt.subplots(1, 2, figsize=(12, 5))
ax_xy.plot(walk.truth[:, 1], walk.truth[:, 2], "k-", lw=1, label="truth")
ax_xy.plot(walk.anchors[:, 1], walk.anchors[:, 2], "k^", label="anchors")
for estimator in ("tarrio-kf", "fg-batch"):
    estimate = walkgraph.run(estimator, walk)
    err = walkgraph.errors(estimate, walk)
    stats = err["stats"]
    print("%-10s RMSE %.3f m, p75 %.3f m, max %.3f m" % (estimator, stats["rmse_m"],
                                                        stats["p75_m"], stats["max_m"]))
    ax_xy.plot(estimate.xy[:, 0], estimate.xy[:, 1], lw=1,
               label="%s (RMSE %.2f m)" % (estimator, stats["rmse_m"]))
    e = np.sort(np.asarray(err["error_m"]))
    ax_cdf.plot(e, np.arange(1, len(e) + 1) / len(e), label=estimator)
ax_xy.set_aspect("equal")
ax_xy.set_xlabel("x [m]")
ax_xy.set_ylabel("y [m]")
ax_xy.legend(fontsize=8)
ax_xy.set_title(walk.name)
ax_cdf.set_xlabel("horizontal error [m]")
ax_cdf.set_ylabel("fraction of truth points")
ax_cdf.grid(True)
ax_cdf.legend()
fig.tight_layout()
fig.savefig(out_png, dpi=100)
print("wrote", out_png)
