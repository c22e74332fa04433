"""Batched collision checks of a robot's configurations against a world and itself.

``check(robot, q, world)`` places the robot's body (``robot.collision_body()``, spheres and
capsules attached to links) at every configuration with the robot's own kernel
``robot.link_poses(q)`` and reduces, per configuration::

    clearance = min( min_{robot primitive p, obstacle o} d(p, o),
                     min_{(i, j) in robot.self_collision_pairs()} min_{p on i, p' on j} d(p, p') )

with ``d`` the exact signed distance (``collision.distance``: negative in penetration). A
configuration collides where ``clearance <= margin``. The pair that attains the clearance is
reported: a robot link and an obstacle (``kind``, ``index``), or two robot links.

The reduction is one fused pass over the placed primitives (``fused.clearance``: robot-world
and self pairs together, configurations minor), run chunk by chunk over large batches so that
memory stays bounded; a world with leading batch axes goes through the per-primitive queries
(``world.nearest_obstacles``, ``pairs.self_distances``), which give the same values.

Everything after the host-side set-up (the body and the pairs, read once per robot) is one
pure function of arrays, compiled once per shapes: moving, resizing or turning an obstacle, or
giving the body other radii, reuses the compilation. A configuration with NaN or inf gets
``status = INVALID_INPUT``, ``collides = True`` and a clearance of 0 (a finite placeholder)
without touching the other elements of the batch; so does one at which the robot does not
assemble (``Robot.placeable``: a Delta's rods that cannot reach the platform), with
``status = UNREACHABLE``.
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

from .._batching import map_chunks
from .._numerics import all_finite
from .._validate import finite_number, is_concrete
from ..status import Status
from . import fused
from .body import Body
from .pairs import SelfPairs, self_distances
from .world import SPHERE, World, nearest_obstacles

__all__ = [
    "ROBOT_WORLD",
    "SELF",
    "CheckResult",
    "chain_self_pairs",
    "check",
    "check_kernel",
    "prepare",
]

# ``CheckResult.pair_kind``: what attains the clearance (-1: nothing to hit).
ROBOT_WORLD, SELF = 0, 1

# Configurations per step of the chunked check: the rows of ~65 spheres of 1024
# configurations stay in L2 (benchmarks/README.md: 2-4x the rate of 8192-configuration chunks)
CHECK_CHUNK = 1024

_OK, _INVALID_INPUT, _COLLISION = Status.OK, Status.INVALID_INPUT, Status.COLLISION
_UNREACHABLE = Status.UNREACHABLE


@jax.tree_util.register_dataclass
@dataclasses.dataclass(frozen=True)
class CheckResult:
    """Per configuration (shapes ``(...)``, the batch of ``q``).

    Attributes:
        clearance: smallest signed distance, robot-world and self (the dtype's largest finite
            value when there is nothing to hit; 0 for invalid input).
        collides: ``clearance <= margin``, or invalid input.
        status: ``int8`` ``jaxkin.Status``: ``OK``, ``COLLISION``, ``INVALID_INPUT`` or
            ``UNREACHABLE`` (joints at which the robot does not assemble).
        pair_kind: ``int8``: ``ROBOT_WORLD`` (0), ``SELF`` (1), or -1 (nothing to hit).
        link: the robot link (index into ``body.links``) of the closest pair.
        other: for ``ROBOT_WORLD`` the obstacle's index within its kind, for ``SELF`` the
            other link; -1 otherwise.
        obstacle_kind: ``int8`` ``collision.SPHERE/CAPSULE/BOX/HALFSPACE`` for
            ``ROBOT_WORLD``, -1 otherwise.
    """

    clearance: Array
    collides: Array
    status: Array
    pair_kind: Array
    link: Array
    other: Array
    obstacle_kind: Array


def chain_self_pairs(
    robot: Any, apart: int = 2, candidates: Any = None
) -> tuple[tuple[int, int], ...]:
    """Self-collision pairs of a robot whose links form a chain in ``body.links`` order: links
    at least ``apart`` positions apart (or the given ``candidates``), both with geometry, not
    in contact at ``q = 0`` (links that share a joint's centre, as a spherical wrist's do,
    would always collide): their distance there more than 64 ulp of the robot's size
    (``length_scale``), so that links that touch are left out whatever the round-off."""
    body = robot.collision_body()
    geometric = sorted(set(body.sphere_link) | set(body.capsule_link))
    if candidates is None:
        candidates = [(i, j) for i in geometric for j in geometric if j - i >= apart]
    candidates = list(candidates)
    if not candidates:
        return ()
    pairs = SelfPairs.create(body, candidates)
    home = robot.link_poses(jnp.zeros(robot.n_joints, body.sphere_radius.dtype))
    spheres, capsules = body.place(home)
    distance = self_distances(spheres, capsules, pairs)
    if not is_concrete(distance):  # the pairs are static: chosen from values
        raise ValueError(
            f"robot: {type(robot).__name__}'s self-collision pairs leave out the links in "
            "contact at q = 0, so they need its geometry as values, not traced (pass "
            "self_collision=False to differentiate in its link_radius or lengths)"
        )
    distance = np.asarray(distance)
    touching = 64.0 * np.finfo(distance.dtype).eps * float(robot.length_scale())
    return tuple(p for p, d in zip(candidates, distance, strict=True) if d > touching)


def prepare(robot: Any, self_collision: bool = True) -> tuple[Body, SelfPairs]:
    """Host side, once per robot: its body and the primitive pairs of its self-collision
    link pairs (none when ``self_collision`` is False)."""
    cached = robot.__dict__.get("_collision_prepared", {})
    if self_collision in cached:
        return cached[self_collision]
    body = robot.collision_body()
    if not isinstance(body, Body):
        raise ValueError(
            f"robot: {type(robot).__name__}.collision_body() must return a collision.Body, "
            f"got {type(body).__name__}"
        )
    link_pairs = robot.self_collision_pairs() if self_collision else ()
    prepared = (body, SelfPairs.create(body, link_pairs))
    if not any(isinstance(leaf, jax.core.Tracer) for leaf in jax.tree.leaves(body)):
        # kept on the (frozen) robot: a URDF body's mesh covers are computed once
        object.__setattr__(robot, "_collision_prepared", {**cached, self_collision: prepared})
    return prepared


def _world_batched(world: World) -> bool:
    """True when the obstacles carry leading batch axes (the fused pass takes one world)."""
    return (
        world.spheres.radius.ndim > 1
        or world.capsules.radius.ndim > 1
        or world.boxes.half_extents.ndim > 2
        or world.halfspaces.offset.ndim > 1
    )


def check_kernel(
    robot: Any,
    body: Body,
    pairs: SelfPairs,
    q: Array,
    world: World,
    margin: ArrayLike = 0.0,
) -> CheckResult:
    """The pure kernel of ``check`` (traceable, any leading batch axes of ``q``).

    One pass per chunk of configurations (``_batching.map_chunks``: at most ``CHECK_CHUNK``
    configurations at a time, so memory stays bounded for any batch): forward kinematics,
    placement, then the fused robot-world and self clearance (``fused.clearance``). A world
    with leading batch axes goes through the per-primitive queries instead.
    """
    dtype = q.dtype
    batch = q.shape[:-1]
    body, world = body.astype(dtype), world.astype(dtype)
    if _world_batched(world) or math.prod(batch) == 0 or not (body.num_spheres + body.num_capsules):
        return _check_per_primitive(robot, body, pairs, q, world, margin)
    prim_link = jnp.asarray(np.asarray(body.sphere_link + body.capsule_link, dtype=np.int32))
    ns = body.num_spheres
    margin = jnp.asarray(margin, dtype)

    def one(q: Array) -> CheckResult:
        valid = all_finite(q)
        q_safe = jnp.where(valid[..., None], q, jnp.zeros((), dtype))
        placed = robot.placeable(q_safe)
        spheres, capsules = body.place(robot.link_poses(q_safe).astype(dtype))
        near = fused.clearance(spheres, capsules, world, pairs if pairs.link_pairs else None)
        nothing = near.distance >= jnp.finfo(dtype).max
        link = prim_link[near.robot_index + jnp.where(near.robot_kind == SPHERE, 0, ns)]
        second = prim_link[near.other_index + jnp.where(near.other_kind == SPHERE, 0, ns)]
        is_self = ~near.world
        pair_kind = jnp.where(nothing, -1, jnp.where(is_self, SELF, ROBOT_WORLD))
        # a self pair is reported as (smaller link, larger link), as its link pair is listed
        first = jnp.where(is_self, jnp.minimum(link, second), link)
        other = jnp.where(is_self, jnp.maximum(link, second), near.other_index)
        obstacle_kind = jnp.where(is_self | nothing, -1, near.other_kind)
        first, other = (jnp.where(nothing, -1, x) for x in (first, other))
        pair = (pair_kind, first, other, obstacle_kind)
        return _verdict(valid, placed, near.distance, *pair, margin)

    return map_chunks(one, q, batch, CHECK_CHUNK)


def _check_per_primitive(
    robot: Any,
    body: Body,
    pairs: SelfPairs,
    q: Array,
    world: World,
    margin: ArrayLike = 0.0,
) -> CheckResult:
    """``check_kernel`` through the per-primitive queries (``nearest_obstacles`` and
    ``self_distances``): for a world with leading batch axes, and the reference of the
    fused pass in the tests."""
    dtype = q.dtype
    valid = all_finite(q)
    q_safe = jnp.where(valid[..., None], q, 0.0)
    placed = robot.placeable(q_safe)
    body, world = body.astype(dtype), world.astype(dtype)
    spheres, capsules = body.place(robot.link_poses(q_safe).astype(dtype))
    near_s, near_c = nearest_obstacles(spheres, capsules, world)
    big = jnp.finfo(dtype).max
    batch = q.shape[:-1]

    # robot-world: the closest robot primitive and its obstacle
    prim_link = np.asarray(body.sphere_link + body.capsule_link, dtype=np.int32)
    if len(prim_link):
        d_world = jnp.concatenate([near_s.distance, near_c.distance], axis=-1)
        kinds = jnp.concatenate([near_s.kind, near_c.kind], axis=-1)
        index = jnp.concatenate([near_s.index, near_c.index], axis=-1)
        p = jnp.argmin(d_world, axis=-1)
        world_clear = jnp.take_along_axis(d_world, p[..., None], -1)[..., 0]
        world_kind = jnp.take_along_axis(kinds, p[..., None], -1)[..., 0]
        world_index = jnp.take_along_axis(index, p[..., None], -1)[..., 0]
        world_link = jnp.asarray(prim_link)[p]
    else:
        world_clear = jnp.full(batch, big, dtype)
        world_kind = jnp.full(batch, -1, jnp.int8)
        world_index = world_link = jnp.full(batch, -1, jnp.int32)

    # self: the closest checked link pair
    if pairs.link_pairs:
        d_self = self_distances(spheres, capsules, pairs)
        k = jnp.argmin(d_self, axis=-1)
        self_clear = jnp.take_along_axis(d_self, k[..., None], -1)[..., 0]
        link_pairs = np.asarray(pairs.link_pairs, dtype=np.int32)
        self_a, self_b = jnp.asarray(link_pairs[:, 0])[k], jnp.asarray(link_pairs[:, 1])[k]
    else:
        self_clear = jnp.full(batch, big, dtype)
        self_a = self_b = jnp.full(batch, -1, jnp.int32)

    is_self = self_clear < world_clear
    clearance = jnp.minimum(world_clear, self_clear)
    nothing = clearance >= big
    pair_kind = jnp.where(nothing, -1, jnp.where(is_self, SELF, ROBOT_WORLD)).astype(jnp.int8)
    link = jnp.where(nothing, -1, jnp.where(is_self, self_a, world_link)).astype(jnp.int32)
    other = jnp.where(nothing, -1, jnp.where(is_self, self_b, world_index)).astype(jnp.int32)
    obstacle_kind = jnp.where(is_self | nothing, -1, world_kind).astype(jnp.int8)

    margin = jnp.asarray(margin, dtype)
    return _verdict(valid, placed, clearance, pair_kind, link, other, obstacle_kind, margin)


def _verdict(
    valid: Array,
    placed: Array,
    distance: Array,
    pair_kind: Array,
    link: Array,
    other: Array,
    obstacle_kind: Array,
    margin: Array,
) -> CheckResult:
    """The ``CheckResult`` of the closest pair (``-1`` fields where there is none): a
    configuration that is not finite (``INVALID_INPUT``), or at which the robot does not
    assemble (``placed`` False: ``UNREACHABLE``), gets clearance 0, collides and no pair;
    the others collide at a clearance ``<= margin``."""
    known = valid & placed
    clearance = jnp.where(known, distance, jnp.zeros((), distance.dtype))
    collides = ~known | (clearance <= margin)
    status = jnp.where(collides, _COLLISION, _OK)
    status = jnp.where(~valid, _INVALID_INPUT, jnp.where(~placed, _UNREACHABLE, status))
    return CheckResult(
        clearance,
        collides,
        status.astype(jnp.int8),
        jnp.where(known, pair_kind, -1).astype(jnp.int8),
        jnp.where(known, link, -1).astype(jnp.int32),
        jnp.where(known, other, -1).astype(jnp.int32),
        jnp.where(known, obstacle_kind, -1).astype(jnp.int8),
    )


_check_jit = jax.jit(check_kernel)


def _check_robot(robot: Any) -> Any:
    """``robot`` if it has the collision protocol's ``n_joints``, ``collision_body``,
    ``link_poses`` and ``placeable`` (``prepare`` checks the body it returns)."""
    methods = ("collision_body", "link_poses", "placeable")
    if not (hasattr(robot, "n_joints") and all(callable(getattr(robot, m, None)) for m in methods)):
        raise ValueError(
            f"robot: expected a robot with n_joints, collision_body(), link_poses() and "
            f"placeable() (a jaxkin robot), got {type(robot).__name__}"
        )
    return robot


def _as_q(robot: Any, q: ArrayLike, name: str = "q") -> Array:
    if not isinstance(q, jax.Array):
        q = np.asarray(q)
    # complex q would lose its imaginary part, boolean q is no joint coordinate
    if not (jnp.issubdtype(q.dtype, jnp.floating) or jnp.issubdtype(q.dtype, jnp.integer)):
        raise ValueError(f"{name}: expected real joint coordinates, got dtype {q.dtype}")
    if not jnp.issubdtype(q.dtype, jnp.floating):
        q = q.astype(jnp.result_type(float))
    q = jnp.asarray(q)
    if q.ndim < 1 or q.shape[-1] != robot.n_joints:
        raise ValueError(
            f"{name}: expected shape (..., {robot.n_joints}) for {type(robot).__name__}, "
            f"got {q.shape}"
        )
    return q


def _check_world(world: Any) -> World:
    if not isinstance(world, World):
        raise ValueError(f"world: expected a collision.World, got {type(world).__name__}")
    return world


def _check_margin(margin: Any) -> Any:
    """A concrete ``margin`` as a finite real number (a float); a traced one unchanged (the
    caller's ``jit`` or ``vmap``)."""
    if not is_concrete(margin):
        return margin
    # a NaN or -inf margin would report every configuration free (clearance <= margin False)
    return finite_number(margin, "margin")


def check(
    robot: Any,
    q: ArrayLike,
    world: World,
    margin: float = 0.0,
    self_collision: bool = True,
) -> CheckResult:
    """Check configurations ``q`` ``(..., n_joints)`` of ``robot`` against ``world`` and
    itself (module docstring).

    Args:
        robot: any robot of the protocol with ``collision_body`` and ``link_poses``.
        q: joint coordinates, any leading batch axes (may be traced: ``check`` works under
            ``jit`` and ``vmap``).
        world: a ``collision.World`` (array data: moving obstacles does not recompile).
        margin: a configuration collides where its clearance is ``<= margin`` (length units;
            one finite number, or traced).
        self_collision: check the robot's ``self_collision_pairs()`` too.

    Returns:
        ``CheckResult`` with shapes ``(...)``.

    Raises:
        ValueError: ``q`` of the wrong trailing shape or not real, a world that is not a
            ``World``, a margin that is not one finite number, a robot without a collision
            body.
    """
    robot, body, pairs, q, world, margin = checked_arguments(
        robot, q, world, margin, self_collision
    )
    return _check_jit(robot, body, pairs, q, world, margin)


def checked_arguments(
    robot: Any, q: ArrayLike, world: Any, margin: Any, self_collision: bool
) -> tuple:
    """The boundary of the public checks: the robot checked, ``q`` as an array of its joint
    count, the world and a concrete margin checked, the robot's body and self pairs
    (``prepare``); ``ValueError`` naming the argument otherwise. Returns ``(robot, body,
    pairs, q, world, margin)``."""
    robot = _check_robot(robot)
    q = _as_q(robot, q)
    world = _check_world(world)
    margin = _check_margin(margin)
    body, pairs = prepare(robot, self_collision)
    return robot, body, pairs, q, world, margin
