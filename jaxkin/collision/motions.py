"""Batched motion validation: M straight joint-space edges checked in one compiled call.

Edge ``m`` from ``q_from[m]`` to ``q_to[m]`` has joint distance ``L_m = |q_to - q_from|``
(Euclidean, as a planner's real vector state space measures it) and is checked at the
``k_m + 1`` states ``q(t_j) = q_from + t_j (q_to - q_from)``, ``t_j = j / k_m``, ``j = 0 ...
k_m``, with ``k_m = max(1, ceil(L_m * resolution))``: consecutive states at most
``1 / resolution`` apart, both ends included. Every edge is given the same number ``S`` of
sample slots (a power of two at least ``max_m k_m + 1``, so that similar batches share a
compilation); slots past ``k_m`` repeat the end state. The states go through
``check_kernel`` at once, ``(M, S)`` configurations, and each edge reports whether all its
states are free and the first that is not.

An edge that needs more states than the slots a caller fixed (``k_m > S - 1``) is checked
at its own spacing as far as the slots reach, ``t_j = j / k_m`` for ``j < S``, and is not
valid even when those states are free: its rest was not checked. Its first failing state
is then the first unchecked one, ``j = S``, and ``last_valid`` the last checked state.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from jax import Array
from jax.typing import ArrayLike

from .. import _validate
from .._execute import Handle, Kernel, Policy, builds
from .._validate import positive_number
from .body import Body
from .check import (
    _as_q,
    _check_margin,
    _check_robot,
    _check_world,
    check_kernel,
    handle_setup,
    prepare,
    single,
)
from .pairs import SelfPairs
from .protocol import CollisionRobot
from .rows import COMPILER_OPTIONS
from .verdict import collides_kernel
from .world import World

__all__ = ["MotionResult", "motion_samples", "validate_motions", "validate_motions_kernel"]


@jax.tree_util.register_dataclass
@dataclasses.dataclass(frozen=True)
class MotionResult:
    """Per edge (shapes ``(M,)``).

    Attributes:
        valid: the edge was checked at the requested resolution and every state is free
            (and finite).
        first: index ``j`` of the first colliding state (``t = j / k``), ``-1`` for a valid
            edge; the slot count ``S`` for an edge whose checked states are free but that
            needed more states than ``S`` (the first state not checked).
        fraction: ``t`` of the first colliding (or unchecked) state in [0, 1]; 1 for a
            valid edge.
        last_valid: the last free state before ``first`` (``q_to`` for a valid edge,
            ``q_from`` when the start itself collides), ``(M, n)``.
        clearance: the smallest clearance over the edge's states.
        states: ``k``, the number of intervals the resolution cuts the edge into (more
            than ``S - 1`` for an edge not checked to its end).
    """

    valid: Array
    first: Array
    fraction: Array
    last_valid: Array
    clearance: Array
    states: Array


def motion_samples(q_from: ArrayLike, q_to: ArrayLike, resolution: float) -> int:
    """Host side: the sample slots ``S`` per edge (module docstring) for these edges."""
    step = np.asarray(q_to, float) - np.asarray(q_from, float)
    length = np.sqrt(np.sum(step * step, axis=-1)) if step.size else np.zeros(0)
    finite = length[np.isfinite(length)]
    k = int(np.max(np.ceil(finite * resolution))) if finite.size else 1
    return 1 << max(1, math.ceil(math.log2(max(k, 1) + 1)))


def _samples(samples: Any) -> int:
    """``samples`` as an int >= 2; ``ValueError`` naming it otherwise."""
    return _validate.count(samples, "samples", minimum=2)


def validate_motions_kernel(
    robot: CollisionRobot,
    body: Body,
    pairs: SelfPairs,
    q_from: Array,
    q_to: Array,
    world: World,
    resolution: ArrayLike,
    samples: int,
    margin: ArrayLike = 0.0,
    clearance: bool = True,
) -> MotionResult:
    """The pure kernel of ``validate_motions``: ``samples`` slots per edge (static);
    ``clearance`` (static) False checks the states with ``collides_kernel`` (the verdict
    alone) and reports a NaN clearance."""
    dtype = q_from.dtype
    step = q_to - q_from
    length = jnp.sqrt(jnp.sum(step * step, axis=-1))
    k = jnp.ceil(length * jnp.asarray(resolution, dtype))
    k = jnp.maximum(jnp.where(jnp.isfinite(k), k, 1.0), 1.0)
    j = jnp.arange(samples, dtype=dtype)
    t = jnp.minimum(j / k[..., None], 1.0)  # (M, S); slots past k repeat the end
    unchecked = k > samples - 1  # the slots end before the edge does
    states = q_from[..., None, :] + t[..., None] * step[..., None, :]
    if clearance:
        result = check_kernel(robot, body, pairs, states, world, margin)
        hit, smallest = result.collides, jnp.min(result.clearance, axis=-1)
    else:
        hit = collides_kernel(robot, body, pairs, states, world, margin).collides
        smallest = jnp.full(hit.shape[:-1], jnp.nan, dtype)
    free = ~jnp.any(hit, axis=-1)
    valid = free & ~unchecked
    first = jnp.where(free, jnp.where(unchecked, samples, -1), jnp.argmax(hit, axis=-1))
    hit_t = jnp.take_along_axis(t, jnp.clip(first, 0, samples - 1)[..., None], -1)[..., 0]
    fraction = jnp.where(valid, 1.0, jnp.where(free, jnp.minimum(samples / k, 1.0), hit_t))
    before = jnp.clip(first - 1, 0, samples - 1)
    last = jnp.take_along_axis(states, before[..., None, None], axis=-2)[..., 0, :]
    last_valid = jnp.where(valid[..., None], q_to, jnp.where((first == 0)[..., None], q_from, last))
    return MotionResult(
        valid,
        first.astype(jnp.int32),
        fraction.astype(dtype),
        last_valid,
        smallest,
        jnp.minimum(k, np.iinfo(np.int32).max).astype(jnp.int32),
    )


_validate_jit = Kernel(
    validate_motions_kernel,
    static=("samples", "clearance"),
    batched={"q_from": 1, "q_to": 1},
    policy=Policy(pad=True, compiler_options=COMPILER_OPTIONS),
)


def validate_motions(
    robot: CollisionRobot,
    q_from: ArrayLike,
    q_to: ArrayLike,
    world: World,
    resolution: float,
    margin: float = 0.0,
    self_collision: bool = True,
    samples: int | None = None,
    clearance: bool = True,
) -> MotionResult:
    """Validate M joint-space edges at once (module docstring).

    Args:
        robot: any robot of the collision protocol (``CollisionRobot``: every jaxkin robot).
        q_from, q_to: the edges' ends, ``(M, n_joints)`` (or any common leading axes).
        world: the obstacles.
        resolution: states per unit of joint distance (a number > 0; NumPy scalars too).
        margin, self_collision: as ``check``.
        samples: slots per edge (static); None computes them from the edges on the host (then
            ``q_from`` and ``q_to`` must be concrete).
        clearance: False checks the states with the verdict alone (``collision.collides``:
            faster, the same validity up to its rounding tolerance) and leaves
            ``MotionResult.clearance`` NaN.

    Returns:
        ``MotionResult`` with shapes ``(M,)`` (``last_valid`` ``(M, n)``).

    Raises:
        ValueError: as ``check``; ``q_from`` and ``q_to`` of different shapes, a resolution
            that is not a positive finite number, ``samples`` not an int ``>= 2``.
    """
    robot = _check_robot(robot)
    q_from, q_to = _as_q(robot, q_from, "q_from"), _as_q(robot, q_to, "q_to")
    if q_from.shape != q_to.shape:
        raise ValueError(f"q_from and q_to: shapes differ, {q_from.shape} and {q_to.shape}")
    resolution = positive_number(resolution, "resolution")
    world = _check_world(world).bucketed()  # a world within its buckets: no compilation
    margin = _check_margin(margin)
    dtype = jnp.result_type(q_from, q_to)
    q_from, q_to = q_from.astype(dtype), q_to.astype(dtype)
    samples = motion_samples(q_from, q_to, resolution) if samples is None else _samples(samples)
    body, pairs = prepare(robot, self_collision)
    return _validate_jit(
        robot,
        body,
        pairs,
        q_from,
        q_to,
        world,
        resolution,
        samples=samples,
        margin=margin,
        clearance=clearance,
        batch=q_from.shape[:-1],
        pad=single(q_from.shape[:-1]) and not world.batched(),
    )


@builds(validate_motions)
def _validate_motions_handle(
    robot: Any,
    world: World,
    resolution: float,
    samples: int,
    batch: Any = 1,
    margin: float = 0.0,
    self_collision: bool = True,
    clearance: bool = True,
    dtype: Any = None,
) -> Handle:
    """``compiled(collision.validate_motions, robot, world, resolution, samples, batch=1,
    margin=0.0, self_collision=True, clearance=True, dtype=None)``: ``handle(q_from, q_to)``
    for edges ``(*batch, n_joints)``, each checked at ``samples`` slots (an edge that needs
    more is reported not valid, as ``validate_motions`` with ``samples`` given); the
    ``MotionResult`` of ``validate_motions`` on the same edges (the other arguments as for
    ``check``'s handle; ``handle.rebound(world)`` for another world of the same layout)."""
    resolution = positive_number(resolution, "resolution")
    samples = _samples(samples)
    setup = handle_setup(robot, world, batch, margin, self_collision, dtype)

    def run(q_from: Array, q_to: Array, flat: Array) -> MotionResult:
        return validate_motions_kernel(
            setup.robot,
            setup.body,
            setup.pairs,
            q_from,
            q_to,
            setup.world(flat),
            resolution,
            samples,
            setup.margin,
            clearance,
        )

    example = setup.configurations()
    return Handle(
        run,
        (example, example),
        bound=(setup.packed,),
        rebind=setup.rebind,
        compiler_options=COMPILER_OPTIONS,
    )
