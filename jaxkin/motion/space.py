"""The joint space a motion is planned in: the sampling box, continuous joints, the metric.

A robot's joint coordinates mix angles (rad) and lengths (the robot's unit). Distances are
measured in units of the robot's own size: with ``L = robot.length_scale()`` and ``w_j = 1``
for a revolute joint, ``1 / L`` for a prismatic one::

    d(a, b) = sqrt( sum_j (w_j delta_j)^2 ),   delta_j = b_j - a_j, wrapped to [-pi, pi)
                                                for a continuous joint

so a planner's range and resolution (states per unit of ``d``) mean the same on a SCARA in
millimetres and on an arm in metres. A continuous joint (revolute, no position limits) is
taken the short way round: ``delta_j`` is wrapped, the states of an edge are ``a + t delta``,
and the path returned is unwrapped (consecutive waypoints differ by the wrapped step, so a
continuous joint may end a full turn away from the goal's coordinate, at the same angle).
Other joints are sampled within their limits; a prismatic joint without limits has no box to
sample and is refused on the host (``joint_space``).
"""

from __future__ import annotations

import dataclasses
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from jax import Array

from .._validate import on_device

__all__ = ["JointSpace", "hashed_uniform", "joint_space"]


def _lowbias32(x: Array) -> Array:
    """Wellons' lowbias32 integer hash of ``uint32`` values (two multiply-xorshift rounds,
    full avalanche; a bijection)."""
    x = x ^ (x >> 16)
    x = x * jnp.uint32(0x7FEB352D)
    x = x ^ (x >> 15)
    x = x * jnp.uint32(0x846CA68B)
    return x ^ (x >> 16)


def hashed_uniform(stream: Array, index: Array, dtype: Any) -> Array:
    """Uniform numbers in ``[0, 1)`` ``index.shape``: Wellons' lowbias32 hash of ``index``
    spaced by the golden-ratio increment and offset by the hash of ``stream``, its top 24
    bits as the fraction. Counter-based: one draw per index, no state, no loop
    (``jax.random``'s threefry is a loop on the CPU). The stream is hashed first, so nearby
    streams are not the same draws shifted by a few indices."""
    offset = _lowbias32(jnp.asarray(stream).astype(jnp.uint32))
    x = _lowbias32(index.astype(jnp.uint32) * jnp.uint32(0x9E3779B9) + offset)
    return (x >> 8).astype(dtype) * jnp.asarray(2.0**-24, dtype)


@jax.tree_util.register_dataclass
@dataclasses.dataclass(frozen=True)
class JointSpace:
    """The sampling box and metric of a robot's joints (arrays ``(n,)``).

    Attributes:
        lower, upper: the box sampled (the limits; ``[-pi, pi)`` for a continuous joint).
        weight: ``w_j`` of the metric (1 for revolute joints, ``1 / length_scale`` for
            prismatic ones).
        continuous: 1.0 for a continuous joint (wrapped), 0.0 otherwise.
        wraps: static, the robot has a continuous joint (without one nothing is wrapped).

    ``joint_space`` gives float64 NumPy arrays (host side), ``astype`` JAX arrays of a dtype.
    """

    lower: Array | np.ndarray
    upper: Array | np.ndarray
    weight: Array | np.ndarray
    continuous: Array | np.ndarray
    wraps: bool = dataclasses.field(metadata=dict(static=True), default=True)

    def astype(self, dtype: Any) -> JointSpace:
        return jax.tree.map(lambda x: on_device(x, dtype), self)

    def wrap(self, delta: Array, axis: int = -1) -> Array:
        """``delta`` with its continuous entries wrapped to ``[-pi, pi)``; ``axis``: the one
        of the joints (``-1``: ``(..., n)``; ``-2``: coordinate-major ``(..., n, N)``)."""
        if not self.wraps:
            return delta
        turn = 2.0 * jnp.pi
        wrapped = delta - turn * jnp.floor((delta + jnp.pi) / turn)
        continuous = self.continuous.reshape((-1,) + (1,) * (-1 - axis))
        return jnp.where(continuous > 0, wrapped, delta)

    def step(self, a: Array, b: Array) -> Array:
        """The joint step from ``a`` to ``b`` (continuous joints the short way round)."""
        return self.wrap(b - a)

    def norm(self, delta: Array) -> Array:
        """``d`` of a step ``delta (..., n)``, ``(...)``."""
        x = delta * self.weight
        return jnp.sqrt(jnp.sum(x * x, axis=-1))

    def distance(self, a: Array, b: Array) -> Array:
        return self.norm(self.step(a, b))

    def canonical(self, q: Array) -> Array:
        """``q`` with continuous joints wrapped into ``[-pi, pi)`` (tree nodes are stored so)."""
        return jnp.where(self.continuous > 0, self.wrap(q), q)

    def sample_hashed(self, stream: Array, counter: Array, count: int) -> Array:
        """``count`` configurations in the box ``(count, n)``, the ``counter``-th draw of
        ``stream`` (``hashed_uniform``: a few integer operations, no loop)."""
        n = self.lower.shape[0]
        index = counter.astype(jnp.uint32) * jnp.uint32(count * n) + jnp.arange(
            count * n, dtype=jnp.uint32
        )
        lower, upper = jnp.asarray(self.lower), jnp.asarray(self.upper)
        u = hashed_uniform(stream, index, lower.dtype).reshape(count, n)
        return lower + u * (upper - lower)

    def unwrap(self, path: Array) -> Array:
        """A path ``(..., K, n)`` of wrapped waypoints as a continuous one: each waypoint the
        previous one plus the wrapped step (the first kept)."""
        steps = self.step(path[..., :-1, :], path[..., 1:, :])
        return jnp.concatenate(
            [path[..., :1, :], path[..., :1, :] + jnp.cumsum(steps, axis=-2)], axis=-2
        )


def joint_space(robot: Any) -> JointSpace:
    """Host side: the ``JointSpace`` of a robot of the protocol (``joint_limits``,
    ``joint_types``, ``length_scale``), float64 NumPy arrays.

    Raises:
        ValueError: a prismatic joint without finite limits (no box to sample).
    """
    limits = robot.joint_limits()
    lower = np.asarray(limits.lower, float).reshape(-1)
    upper = np.asarray(limits.upper, float).reshape(-1)
    types = robot.joint_types
    prismatic = np.array([t == "P" for t in types])
    unbounded = ~(np.isfinite(lower) & np.isfinite(upper))
    bad = np.flatnonzero(unbounded & prismatic)
    if bad.size:
        name = robot.joint_names[bad[0]]
        raise ValueError(
            f"robot: the prismatic joint {name!r} of {type(robot).__name__} has no finite "
            "limits, so the planner has no box to sample (give the robot limits)"
        )
    continuous = unbounded & ~prismatic
    lower = np.where(continuous, -np.pi, lower)
    upper = np.where(continuous, np.pi, upper)
    scale = float(np.asarray(robot.length_scale()))
    weight = np.where(prismatic, 1.0 / scale, 1.0)
    return JointSpace(lower, upper, weight, continuous.astype(float), bool(np.any(continuous)))
