#!/usr/bin/env python3
"""Where a dead-reckoned trajectory's error comes from: heading, scale or neither.

Usage: tools/error_decomposition.py ESTIMATE.csv TRUTH.csv
  ESTIMATE.csv: a compare output trajectory (t_s,x_m,y_m,...); TRUTH.csv: the walk's truth.csv.
The truth is interpolated at the estimate's times. Prints the 2-D RMSE after a best-fit SE(2)
(what `compare --align-se2` scores), after a best-fit Sim(2) (its scale: what a step-length or
accelerometer-scale error explains), after SE(2) with a constant yaw drift removed (the drift
that fits best on a grid of 0.05 mrad/s up to ±20 mrad/s: what a gyro-bias heading drift
explains), and with each half of the walk fitted alone.
"""
import csv
import math
import sys


def read(path):
    with open(path, newline="") as f:
        return [(float(r["t_s"]), float(r["x_m"]), float(r["y_m"])) for r in csv.DictReader(f)]


def interpolate(truth, t):
    if t <= truth[0][0]:
        return truth[0][1:]
    if t >= truth[-1][0]:
        return truth[-1][1:]
    lo, hi = 0, len(truth) - 1
    while hi - lo > 1:
        mid = (lo + hi) // 2
        if truth[mid][0] <= t:
            lo = mid
        else:
            hi = mid
    a, b = truth[lo], truth[hi]
    u = (t - a[0]) / (b[0] - a[0])
    return (a[1] + u * (b[1] - a[1]), a[2] + u * (b[2] - a[2]))


def fit(p, q, scale=False):
    """RMSE of p mapped onto q by the least-squares rotation + translation (+ scale); the scale."""
    n = len(p)
    mp = [sum(x[i] for x in p) / n for i in (0, 1)]
    mq = [sum(x[i] for x in q) / n for i in (0, 1)]
    c = s = vp = 0.0
    for (px, py), (qx, qy) in zip(p, q):
        a, b, u, v = px - mp[0], py - mp[1], qx - mq[0], qy - mq[1]
        c += a * u + b * v
        s += a * v - b * u
        vp += a * a + b * b
    th = math.atan2(s, c)
    k = math.hypot(c, s) / vp if scale else 1.0
    sq = 0.0
    for (px, py), (qx, qy) in zip(p, q):
        a, b = px - mp[0], py - mp[1]
        x = k * (math.cos(th) * a - math.sin(th) * b) + mq[0]
        y = k * (math.sin(th) * a + math.cos(th) * b) + mq[1]
        sq += (x - qx) ** 2 + (y - qy) ** 2
    return math.sqrt(sq / n), k


def without_drift(p, ts, w):
    """p with a yaw drift of w rad/s taken out of its increments."""
    out = [p[0]]
    for k in range(1, len(p)):
        dx, dy = p[k][0] - p[k - 1][0], p[k][1] - p[k - 1][1]
        a = -w * (ts[k] - ts[0])
        out.append((out[-1][0] + math.cos(a) * dx - math.sin(a) * dy,
                    out[-1][1] + math.sin(a) * dx + math.cos(a) * dy))
    return out


def main(argv):
    if len(argv) != 3:
        sys.stderr.write(__doc__)
        return 2
    est, truth = read(argv[1]), read(argv[2])
    if len(est) < 3 or len(truth) < 2:
        sys.stderr.write("error_decomposition: too few rows\n")
        return 1
    ts = [e[0] for e in est]
    p = [e[1:] for e in est]
    q = [interpolate(truth, t) for t in ts]
    se2, _ = fit(p, q)
    sim2, k = fit(p, q, scale=True)
    drift, w = min((fit(without_drift(p, ts, i * 5e-5), q)[0], i * 5e-5) for i in range(-400, 401))
    h = len(p) // 2
    walked = sum(math.dist(q[i - 1], q[i]) for i in range(1, len(q)))
    print(f"{ts[-1] - ts[0]:.1f} s, {walked:.2f} m walked; RMSE after SE(2) {se2:.4f} m; "
          f"after Sim(2) {sim2:.4f} m (scale {k:.4f}); after SE(2) without a yaw drift "
          f"{drift:.4f} m (drift {math.degrees(w) * 60:.2f} deg/min); halves fitted alone "
          f"{fit(p[:h], q[:h])[0]:.4f} / {fit(p[h:], q[h:])[0]:.4f} m")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
