"""Adds a waypoint (a known position at a known time, e.g. a surveyed mark the walker stepped
on) to a walk, runs fg-batch with and without it, and plots what moved to a PNG: the estimate
is pulled onto the waypoint and its position sigma there shrinks.

usage: python3 examples/waypoint.py [WALK_DIR] [OUT.png]
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
out_png = sys.argv[2] if len(sys.argv) > 2 else "waypoint.png"

walk = walkgraph.read_walk(walk_dir)
mark = walk.truth[len(walk.truth) // 2]  # the truth at mid-walk as the surveyed mark
with_mark = walk.copy()
with_mark.waypoints = np.array([[mark[0], mark[1], mark[2], 0.2]])  # t_s, x_m, y_m, sigma_m

fig, ax = plt.subplots(figsize=(7, 6))
ax.plot(walk.truth[:, 1], walk.truth[:, 2], "k-", lw=1, label="truth")
for label, w in (("without", walk), ("with waypoint", with_mark)):
    est = walkgraph.run("fg-batch", w)
    i = int(np.argmin(np.abs(est.t - mark[0])))
    err = np.linalg.norm(est.xy[i] - mark[1:3])
    sigma = np.sqrt(np.trace(est.cov[i, :2, :2]))
    print("%-14s error at the mark %.3f m, position sigma there %.3f m" % (label, err, sigma))
    ax.plot(est.xy[:, 0], est.xy[:, 1], lw=1, label="fg-batch %s (%.2f m at the mark)" %
            (label, err))
ax.plot(mark[1], mark[2], "r*", ms=14, label="waypoint (sigma 0.2 m)")
ax.set_aspect("equal")
ax.legend(fontsize=8)
ax.set_title("%s: a waypoint at t = %.0f s" % (walk.name, mark[0]))
fig.tight_layout()
fig.savefig(out_png, dpi=100)
print("wrote", out_png)
