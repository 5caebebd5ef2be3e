"""The ``toppra`` package on the feed planner's own problem: an independent reference for
camsmooth.smoothing.feed's forward-backward pass (same gridpoints, spline and constraints; TOPP-RA
by toppra's seidel LP solver). Used by tests/test_feed.py and benchmarks/bench_feed.py."""

from __future__ import annotations

import logging

import numpy as np
import toppra
import toppra.algorithm
import toppra.constraint as tc

from camsmooth.errors import InfeasibleError
from camsmooth.smoothing.feed import RowPath

_log = logging.getLogger("toppra")


class _PathSpeedBound(tc.LinearConstraint):
    """Upper bound on s'^2 per gridpoint (toppra's canonical 'xbound'): the tip-feed constraint
    |p'(s)| s' <= F as s'^2 <= (F / |p'(s)|)^2, given directly at the gridpoints it was built for."""

    def __init__(self, xmax: np.ndarray, dof: int):
        super().__init__()
        self.xmax = np.asarray(xmax, float)
        self.dof = dof

    def compute_constraint_params(self, path, gridpoints, *args, **kwargs):  # noqa: ANN001, ANN201 (toppra API)
        if len(gridpoints) != len(self.xmax):
            raise ValueError("path-speed bound built for other gridpoints")
        return None, None, None, None, None, None, np.column_stack([np.zeros(len(self.xmax)), self.xmax])


def toppra_speed(rp: RowPath) -> np.ndarray:
    """s' (scaled parameter per s) at the gridpoints from TOPP-RA (module docstring), rest to rest.
    InfeasibleError if toppra finds no parameterisation."""
    vl, al = rp.vmax, rp.amax
    constraints = [tc.JointVelocityConstraint(np.column_stack([-vl, vl])),
                   tc.JointAccelerationConstraint(np.column_stack([-al, al]),
                                                  discretization_scheme=tc.DiscretizationType.Interpolation),
                   _PathSpeedBound(rp.x_feed, 5)]
    algo = toppra.algorithm.TOPPRA(constraints, toppra.SplineInterpolator(rp.s, rp.q), gridpoints=rp.s,
                                   solver_wrapper="seidel",
                                   parametrizer="ParametrizeConstAccel")
    level = _log.level
    _log.setLevel(logging.ERROR)  # toppra logs recoverable retries as warnings
    try:
        _, sd, _ = algo.compute_parameterization(0.0, 0.0)
    finally:
        _log.setLevel(level)
    if sd is None or not np.all(np.isfinite(sd)):
        raise InfeasibleError("feed planning: toppra found no time law for this row (the path is not controllable "
                              "under the axis limits)")
    return np.asarray(sd, float)
