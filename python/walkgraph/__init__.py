"""walkgraph: factor-graph smoothing and the papers' Kalman filters for indoor pedestrian walks.

Walk streams are float64 numpy arrays, one row per sample:
  imu          (N, 7|10)  t_s, ax, ay, az [m/s^2], gx, gy, gz [rad/s][, mx, my, mz [uT]]
  rss          (N, 3)     t_s, anchor_id, rss
  ranges       (N, 3)     t_s, anchor_id, range_m
  odometry     (N, 3)     t_s, dist_m, dheading_rad
  truth        (N, 3|4)   t_s, x_m, y_m[, z_m]
  anchors      (N, 4|5)   id, x_m, y_m, z_m[, sigma_m]  (x_m, y_m NaN: position unknown;
                          sigma_m > 0: uncertain, a prior; five columns when an anchor has one)
  waypoints    (N, 4)     t_s, x_m, y_m, sigma_m
  stance_truth (N, 2)     t_s, stance (0/1)
Errors raise ValueError (bad input, with file:line), NotFoundError (a FileNotFoundError and a
LookupError: a missing walk, an unknown estimator, scenario or key), KeyboardInterrupt (Ctrl-C
during a run) or RuntimeError, carrying the library's message.
"""
from ._walkgraph import (  # noqa: F401
    Estimate,
    Factor,
    FactorGraph,
    FixedLagSmoother,
    NotFoundError,
    Walk,
    compare,
    errors,
    estimators,
    factors,
    key_to_string,
    pcrb,
    apply_radio_map,
    read_walk,
    run,
    survey,
    scenarios,
    simulate,
    step_graph,
    symbol,
    write_walk,
)

__all__ = [
    "Estimate", "Factor", "FactorGraph", "FixedLagSmoother", "NotFoundError", "Walk", "compare", "errors",
    "apply_radio_map", "estimators", "factors", "key_to_string", "pcrb", "read_walk", "run", "scenarios",
    "simulate", "step_graph", "survey", "symbol", "write_walk",
]
