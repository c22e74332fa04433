"""Goals given as poses or points: collision-free joint configurations found in batch.

For every branch of the robot (``robot.branches``: an analytic arm's up to eight, the SCARA's
two assembly modes, the Delta's two, a chain's one search) ``jaxkin.ik`` solves every target at
once; a solution counts when its status is one the robot calls reachable
(``robot.reachable``), it lies within the joint limits and it is free of the world and of the
robot itself (``collider.free``). The free solutions nearest the start (``space.distance``)
become the goal configurations, at most ``keep`` per target; a target with none is
``UNREACHABLE_GOAL``.
"""

from __future__ import annotations

from typing import Any

import jax.numpy as jnp
import numpy as np

from .. import robot as _robot
from .space import JointSpace

__all__ = ["ik_goals"]


def ik_goals(
    robot: Any,
    targets: np.ndarray,
    starts: np.ndarray,
    space: JointSpace,
    free_fn: Any,
    keep: int,
) -> tuple[np.ndarray, np.ndarray]:
    """Host side: goal configurations ``(B, keep, n)`` and their count ``(B,)`` for targets
    ``(B, *target)`` (module docstring); ``free_fn(q (B, K, n)) -> (B, K)`` bool."""
    b = starts.shape[0]
    solutions, ok = [], []
    limits = robot.joint_limits()
    for branch in robot.branches:
        res = _robot.ik(robot, targets, branch=branch)
        q = np.asarray(res.q.p, float).reshape(b, -1)
        status = np.asarray(res.status).reshape(b)
        good = np.isin(status, [int(s) for s in robot.reachable])
        good &= np.asarray(limits.contains(q), bool) & np.all(np.isfinite(q), -1)
        solutions.append(np.where(np.isfinite(q), q, 0.0))
        ok.append(good)
    q = np.stack(solutions, 1)  # (B, K, n)
    good = np.stack(ok, 1)
    good &= np.asarray(free_fn(q), bool)
    dist = np.asarray(space.distance(jnp.asarray(starts[:, None]), jnp.asarray(q)))
    dist = np.where(good, dist, np.inf)
    order = np.argsort(dist, axis=1, kind="stable")[:, :keep]
    chosen = np.take_along_axis(q, order[..., None], 1)
    count = np.minimum(np.sum(good, 1), keep)
    if chosen.shape[1] < keep:
        pad = np.repeat(chosen[:, -1:], keep - chosen.shape[1], 1)
        chosen = np.concatenate([chosen, pad], 1)
    return chosen, count.astype(np.int32)
