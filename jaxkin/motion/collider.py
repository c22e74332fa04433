"""The one door from the motion planner to the collision layer.

Every question the planner asks about collisions goes through this module, so that a change
of the collision kernels is one edit here:

- ``COMPILER_OPTIONS``: the XLA options of the checks' programs (``collision.rows``), for every
  program of the planner that runs them.
- ``prepare(robot)``: host side, once per robot: the body and the self-collision pairs
  (``collision.prepare``).
- ``free(robot, body, pairs, q, world)``: per configuration ``q (..., n)``, is the robot clear
  of the world and itself (``collision.collides_kernel``, the verdict alone, each obstacle
  tested against the bounds of each frame's spheres first)?
- ``clearances(robot, body, pairs, q, world)``: per configuration the signed distance of each
  link to the world and of each checked self link pair (``collision.clearances_kernel``,
  grouped by ``link_groups``), for conservative advancement with one speed bound per link
  and per pair (``bound.speed_rows``).
- ``piece_touches(robot, body, pairs, qa, qb, grow, world)``: per piece of motion from
  ``qa`` to ``qb``, does the body's enclosure over it (``swept``) touch the world or itself?
- ``stack_worlds(worlds)``: one world per problem as one ``World`` with a leading problem axis
  (every kind padded to a common count, a multiple of ``collision.OBSTACLE_BUCKET``, without
  changing any distance).

All but ``prepare`` and ``stack_worlds`` are pure and traceable (any leading batch axes of
``q``; the world without batch axes: under ``vmap`` over problems it is one world per lane).
"""

from __future__ import annotations

import dataclasses
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from jax import Array

from .. import collision
from .._numerics import all_finite
from ..collision import World
from ..collision.rows import Placed, index_groups, place
from ..collision.verdict import verdict_rows

__all__ = [
    "COMPILER_OPTIONS",
    "clearances",
    "free",
    "link_groups",
    "piece_touches",
    "prepare",
    "stack_worlds",
]

# XLA options of every program that runs the checks (the CPU's older fusion emitters)
COMPILER_OPTIONS = collision.rows.COMPILER_OPTIONS


def prepare(robot: Any, self_collision: bool = True) -> tuple[Any, Any]:
    """The robot's body and self pairs (host side; cached on the robot)."""
    return collision.prepare(robot, self_collision)


def free(robot: Any, body: Any, pairs: Any, q: Array, world: World) -> Array:
    """``(...)`` True where ``q (..., n)`` touches neither the world nor the robot itself
    (each obstacle tested against the bounds of each frame's spheres first: a planner's
    states pass most obstacles of a scene far away; the same verdicts)."""
    verdict = collision.collides_kernel(robot, body, pairs, q, world, 0.0, frame_bounds=True)
    return ~verdict.collides


def piece_touches(
    robot: Any, body: Any, pairs: Any, qa: Array, qb: Array, grow: Array, world: World
) -> Array:
    """``(C,)`` True where the enclosure of the motion from ``qa (C, n)`` to ``qb (C, n)``
    touches the world or a checked self pair (clearance ``<= 0``, ``collision.verdict``'s
    rounding), or where either end is not finite or does not assemble. Each primitive's
    enclosure: a sphere ``(c, r)`` placed at both ends becomes the sphere about the middle of
    its chord, radius ``r + |c_b - c_a| / 2 + grow``; a capsule the capsule between its ends'
    middles, radius ``r`` plus its ends' larger half chord plus ``grow``; ``grow (C, ns +
    nc)`` (``swept``: how far the primitive strays from its chords, and the rounding)."""
    dtype = qa.dtype
    body, world = body.astype(dtype), world.astype(dtype)
    ok = all_finite(qa) & all_finite(qb)
    safe_a = jnp.where(ok[:, None], qa, jnp.zeros((), dtype))
    safe_b = jnp.where(ok[:, None], qb, jnp.zeros((), dtype))
    ok = ok & robot.placeable(safe_a) & robot.placeable(safe_b)
    at_a, at_b = place(robot, body, safe_a), place(robot, body, safe_b)
    ns = body.num_spheres

    def half_chord(x: Array, y: Array) -> Array:
        return 0.5 * jnp.sqrt(jnp.sum((y - x) ** 2, axis=0))  # (k, C)

    grow = grow.T  # (ns + nc, C)
    sphere_r = at_a.sphere_radius + half_chord(at_a.spheres, at_b.spheres) + grow[:ns]
    ends = jnp.maximum(
        half_chord(at_a.capsule_a, at_b.capsule_a), half_chord(at_a.capsule_b, at_b.capsule_b)
    )
    enclosure = Placed(
        0.5 * (at_a.spheres + at_b.spheres),
        sphere_r,
        0.5 * (at_a.capsule_a + at_b.capsule_a),
        0.5 * (at_a.capsule_b + at_b.capsule_b),
        at_a.capsule_radius + ends + grow[ns:],
    )
    self_pairs = pairs if pairs.link_pairs else None
    zero = jnp.zeros((), dtype)
    return verdict_rows(enclosure, world, self_pairs, zero, ~ok)


def link_groups(body: Any) -> np.ndarray:
    """Host side: the body's primitives (spheres, then capsules) grouped by link, ``(L, m)``
    indices, one row per link with geometry in order of first appearance (shorter rows
    repeat their last index): every primitive of a link moves with it, so a link's distance
    to the world is the smallest of its primitives' (one speed bound per link, ``bound``)."""
    return index_groups(tuple(body.sphere_link) + tuple(body.capsule_link))[1]


def clearances(robot: Any, body: Any, pairs: Any, q: Array, world: World) -> tuple[Array, Array]:
    """``(dist (..., L + Q), placed (...))`` per configuration ``q (..., n)``: each link's
    signed distance to the world (the smallest of its primitives', ``link_groups`` order;
    the dtype's largest value without obstacles), then each checked self link pair's
    (``pairs.link_pairs``), and whether ``q`` is finite and the robot assembles there (where
    it is not, the distances are placeholders): ``collision.clearances_kernel``, without
    testing a padded world's copies of an obstacle again (never differentiated here)."""
    prims, own, placed = collision.clearances_kernel(robot, body, pairs, q, world, skip_copies=True)
    groups = link_groups(body)
    per_link = jnp.min(prims[..., groups], axis=-1) if groups.size else prims[..., :0]
    return jnp.concatenate([per_link, own], axis=-1), placed


_KINDS = tuple(f.name for f in dataclasses.fields(World))


def _pad_kind(kind: str, items: Any, count: int, world: World, far: np.ndarray) -> dict:
    """The arrays of one obstacle kind of one world padded to ``count`` rows by obstacles that
    change no distance: copies of its last row (as ``World.bucketed``); for a kind it lacks, a
    point (no extent) at an interior point of another of its obstacles (anything touching it
    touches that obstacle, and its distance is never smaller), or at ``far`` in an empty
    world."""
    fields = {f: np.asarray(getattr(items, f)) for f in items.__dataclass_fields__}
    have = next(iter(fields.values())).shape[0]
    if have == count:
        return fields
    if have:
        return {
            f: np.concatenate([v, np.repeat(v[-1:], count - have, 0)]) for f, v in fields.items()
        }
    inside = far
    for other in ("boxes", "spheres", "cylinders", "capsules"):
        rows = getattr(world, other)
        if len(rows):
            inside = np.asarray(rows.center if other != "capsules" else rows.a)[0]
            break
    point = np.tile(inside, (count, 1))
    zero = np.zeros(count)
    if kind == "spheres":
        return {"center": point, "radius": zero}
    if kind == "capsules":
        return {"a": point, "b": point, "radius": zero}
    if kind == "boxes":
        rotation = np.tile(np.eye(3), (count, 1, 1))
        return {"center": point, "rotation": rotation, "half_extents": np.zeros((count, 3))}
    if kind == "cylinders":
        axis = np.tile([0.0, 0.0, 1.0], (count, 1))
        return {"center": point, "axis": axis, "radius": zero, "half_length": zero}
    raise ValueError("world: a half-space cannot be padded into a world that has none")


def stack_worlds(worlds: list[World], far: float = 100.0) -> World:
    """Host side: the worlds of ``B`` problems as one ``World`` whose arrays have a leading
    axis ``B``, each kind padded to the largest count rounded up to a multiple of
    ``collision.OBSTACLE_BUCKET`` (``_pad_kind``: worlds within the same buckets share a
    compiled program); ``far`` places the padding of an empty world."""
    if not worlds:
        raise ValueError("worlds: expected at least one collision.World")
    for i, w in enumerate(worlds):
        if not isinstance(w, World):
            raise ValueError(f"worlds[{i}]: expected a collision.World, got {type(w).__name__}")
        if w.batched():
            raise ValueError(f"worlds[{i}]: expected a world without batch axes")
    bucket = collision.OBSTACLE_BUCKET
    counts = {k: max(len(getattr(w, k)) for w in worlds) for k in _KINDS}
    counts = {k: -(-c // bucket) * bucket for k, c in counts.items()}
    if counts["halfspaces"] and any(not len(w.halfspaces) for w in worlds):
        # a half-space no obstacle contains: the far one below everything
        worlds = [
            w
            if len(w.halfspaces)
            else dataclasses.replace(
                w,
                halfspaces=collision.HalfSpaces.create(
                    np.array([[0.0, 0.0, 1.0]]), np.array([-far])
                ),
            )
            for w in worlds
        ]
    point = np.array([0.0, 0.0, -far])
    stacked = {}
    for kind in _KINDS:
        if not counts[kind]:  # an empty kind gets the leading axis too
            stacked[kind] = jax.tree.map(
                lambda x: jnp.broadcast_to(x, (len(worlds), *x.shape)), getattr(worlds[0], kind)
            )
            continue
        rows = [_pad_kind(kind, getattr(w, kind), counts[kind], w, point) for w in worlds]
        cls = type(getattr(worlds[0], kind))
        stacked[kind] = cls(**{f: jnp.asarray(np.stack([r[f] for r in rows])) for f in rows[0]})
    return World(**stacked)
