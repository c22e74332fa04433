"""Where the chain IK search (``serial.search``) starts its runs.

Per element, the first runs start from the configuration of a fixed table (``TABLE_SIZE``
configurations uniform over the limits, in ``NEAR_GROUPS`` groups) whose tool pose is nearest
the target, then from the middle of the limits, then from the
nearest of each further group; later runs from fixed seeds spread uniformly over the limits.
Every table and seed comes from a fixed generator: the same starts every call. Nearness is
``|p - p_d|^2 + w^2 |R - R_d|_F^2`` in units of the chain's size (``w = ROTATION_WEIGHT``),
evaluated as one matrix product in float32 (it only ranks starts); ``w = 0`` for a chain whose
targets are points.
"""

from __future__ import annotations

import dataclasses
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from jax import Array

from . import _kinematics

__all__ = ["NEAR_GROUPS", "ROTATION_WEIGHT", "TABLE_SIZE", "Box", "first_starts", "seeds"]

# A table of TABLE_SIZE configurations uniform over the limits in NEAR_GROUPS groups;
# ROTATION_WEIGHT weighs |R - R_d|_F against |p - p_d| (units of the chain's size). Tuned on
# 1,000 UR5 / Panda poses: 12-19 updates per pose on average.
TABLE_SIZE = 1024
NEAR_GROUPS = 8
ROTATION_WEIGHT = 0.15


@jax.tree_util.register_dataclass
@dataclasses.dataclass(frozen=True)
class Box:
    """The joint box the search projects onto, per coordinate, each ``(n,)``.

    Attributes:
        lower, upper: position limits (``-inf``/``+inf`` for none), in units of the chain.
        revolute: True for a rotating coordinate (revolute or continuous).
        continuous: True for a continuous coordinate (wrapped to [-pi, pi)).
    """

    lower: Array
    upper: Array
    revolute: Array
    continuous: Array


def spread(box: Box, u: Array) -> Array:
    """Points ``u`` of the unit cube ``(..., n)`` as configurations: uniform over the limits
    (revolute joints without limits over [-pi, pi), prismatic ones at 0)."""
    finite = jnp.isfinite(box.lower) & jnp.isfinite(box.upper)
    inside = jnp.where(finite, box.lower, 0.0) + u * jnp.where(finite, box.upper - box.lower, 0.0)
    free = jnp.clip(jnp.where(box.revolute, (2.0 * u - 1.0) * np.pi, 0.0), box.lower, box.upper)
    return jnp.where(finite, inside, free)


def seeds(box: Box, runs: int, dtype: Any) -> Array:
    """``(runs, n)`` starts: the middle of the limits (0 for an unbounded joint), then uniform
    over the limits."""
    u = np.random.default_rng(0).uniform(size=(runs, box.lower.shape[-1]))
    u[0] = 0.5
    return spread(box, jnp.asarray(u, dtype))


def _near_starts(unit: Any, goal: Array, box: Box) -> Array:
    """``(..., NEAR_GROUPS, n)``: per goal pose, the configuration of each group of the table
    whose pose is nearest (module docstring), nearest first."""
    n = box.lower.shape[-1]
    u = np.random.default_rng(1).uniform(size=(TABLE_SIZE, n))
    table = spread(box, jnp.asarray(u, goal.dtype))
    rot, p = _kinematics.fk_rp(unit, table, looped=True)

    weight = 0.0 if unit.target_kind == "point" else ROTATION_WEIGHT  # a point: p only

    def features(rot, p):
        flat = rot.reshape(*rot.shape[:-2], 9)
        return jnp.concatenate([p, weight * flat], -1).astype(jnp.float32)

    ours = features(rot, p)
    theirs = features(goal[..., :3, :3], goal[..., :3, 3])
    # |a - b|^2 less |b|^2 (the same for every row of the table), grouped.
    d = jnp.sum(ours * ours, -1) - 2.0 * theirs @ ours.T
    d = d.reshape(*d.shape[:-1], NEAR_GROUPS, TABLE_SIZE // NEAR_GROUPS)
    inner = jnp.argmin(d, axis=-1)
    nearest = jnp.take_along_axis(d, inner[..., None], -1)[..., 0]
    order = jnp.argsort(nearest, axis=-1)
    index = jnp.take_along_axis(inner, order, -1) + order * (TABLE_SIZE // NEAR_GROUPS)
    return table[index]


def first_starts(unit: Any, goal: Array, box: Box, seeds: Array) -> Array:
    """``(..., NEAR_GROUPS + 1, n)`` starts of an element's first runs: the nearest table pose,
    the middle of the limits (``seeds[0]``), then the other groups' nearest."""
    near = _near_starts(unit, goal, box)
    first = near[..., 0, :]
    middle = jnp.broadcast_to(seeds[0], first.shape)
    starts = jnp.concatenate([first[..., None, :], middle[..., None, :], near[..., 1:, :]], -2)
    return jnp.where(jnp.isfinite(starts), starts, 0.0)
