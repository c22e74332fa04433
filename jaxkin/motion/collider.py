"""The one door from the motion planner to the collision layer.

Every question the planner asks about collisions goes through this module, so that a change
of the collision kernels is one edit here:

- ``prepare(robot)``: host side, once per robot: the body and the self-collision pairs
  (``collision.prepare``).
- ``free(robot, body, pairs, q, world)``: per configuration ``q (..., n)``, is the robot clear
  of the world and itself (``collision.collides_kernel``, the verdict alone)?
- ``clearance(robot, body, pairs, q, world)``: per configuration, the smallest signed
  distance robot-world and self (``collision.check_kernel``; 0 where the configuration is not
  finite or the robot does not assemble), for conservative advancement.
- ``clearances(robot, body, pairs, q, world)``: per configuration the signed distance of each
  body primitive to its nearest obstacle and of each checked self link pair
  (``collision.nearest_obstacles``, ``collision.self_distances``), for conservative
  advancement with one speed bound per link and per pair (``bound``).
- ``stack_worlds(worlds)``: one world per problem as one ``World`` with a leading problem axis
  (every kind padded to the largest count without changing any distance).

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
from ..collision import World

__all__ = ["clearance", "free", "prepare", "stack_worlds"]


def prepare(robot: Any, self_collision: bool = True) -> tuple[Any, Any]:
    """The robot's body and self pairs (host side; cached on the robot)."""
    return collision.prepare(robot, self_collision)


def free(robot: Any, body: Any, pairs: Any, q: Array, world: World) -> Array:
    """``(...)`` True where ``q (..., n)`` touches neither the world nor the robot itself."""
    return ~collision.collides_kernel(robot, body, pairs, q, world, 0.0).collides


def clearance(robot: Any, body: Any, pairs: Any, q: Array, world: World) -> tuple[Array, Array]:
    """``(clearance, free)`` per configuration ``q (..., n)``: the smallest signed distance
    (robot-world and self) and whether it is positive (and ``q`` finite and placeable)."""
    result = collision.check_kernel(robot, body, pairs, q, world, 0.0)
    return result.clearance, ~result.collides


def clearances(
    robot: Any, body: Any, pairs: Any, q: Array, world: World
) -> tuple[Array, Array, Array]:
    """``(primitives (..., ns + nc), self_pairs (..., len(pairs.link_pairs)), placed (...))``:
    each primitive's signed distance to the world (spheres then capsules; the dtype's largest
    value without obstacles), each link pair's smallest signed distance, and whether ``q`` is
    finite and the robot assembles there (where it is not, the distances are placeholders)."""
    dtype = q.dtype
    valid = jnp.all(jnp.isfinite(q), -1)
    q_safe = jnp.where(valid[..., None], q, jnp.zeros((), dtype))
    placed = valid & robot.placeable(q_safe)
    body, world = body.astype(dtype), world.astype(dtype)
    spheres, capsules = body.place(robot.link_poses(q_safe).astype(dtype))
    near_s, near_c = collision.nearest_obstacles(spheres, capsules, world)
    prims = jnp.concatenate([near_s.distance, near_c.distance], -1)
    if pairs.link_pairs:
        own = collision.self_distances(spheres, capsules, pairs)
    else:
        own = jnp.zeros(q.shape[:-1] + (0,), dtype)
    return prims, own, placed


_KINDS = ("spheres", "capsules", "boxes", "halfspaces")


def _pad_kind(kind: str, items: Any, count: int, world: World, far: np.ndarray) -> dict:
    """The arrays of one obstacle kind of one world padded to ``count`` rows by obstacles that
    change no distance: copies of its first row; for a kind it lacks, a point (radius 0) at an
    interior point of another of its obstacles (anything touching it touches that obstacle,
    and its distance is never smaller), or at ``far`` in an empty world."""
    fields = {f: np.asarray(getattr(items, f)) for f in items.__dataclass_fields__}
    have = next(iter(fields.values())).shape[0]
    if have == count:
        return fields
    if have:
        return {
            f: np.concatenate([v, np.repeat(v[:1], count - have, 0)]) for f, v in fields.items()
        }
    inside = far
    for other in ("boxes", "spheres", "capsules"):
        rows = getattr(world, other)
        if len(rows):
            inside = np.asarray(rows.center if other != "capsules" else rows.a)[0]
            break
    if kind == "spheres":
        return {"center": np.tile(inside, (count, 1)), "radius": np.zeros(count)}
    if kind == "capsules":
        return {
            "a": np.tile(inside, (count, 1)),
            "b": np.tile(inside, (count, 1)),
            "radius": np.zeros(count),
        }
    if kind == "boxes":
        return {
            "center": np.tile(inside, (count, 1)),
            "rotation": np.tile(np.eye(3), (count, 1, 1)),
            "half_extents": np.zeros((count, 3)),
        }
    raise ValueError("world: a half-space cannot be padded into a world that has none")


def stack_worlds(worlds: list[World], far: float = 100.0) -> World:
    """Host side: the worlds of ``B`` problems as one ``World`` whose arrays have a leading
    axis ``B`` (``_pad_kind``); ``far`` places the padding of an empty world."""
    if not worlds:
        raise ValueError("worlds: expected at least one collision.World")
    for i, w in enumerate(worlds):
        if not isinstance(w, World):
            raise ValueError(f"worlds[{i}]: expected a collision.World, got {type(w).__name__}")
    counts = {k: max(len(getattr(w, k)) for w in worlds) for k in _KINDS}
    if counts["halfspaces"] and any(not len(w.halfspaces) for w in worlds):
        # a half-space no obstacle contains: the far one below everything
        worlds = [
            w
            if len(w.halfspaces)
            else dataclasses.replace(
                w, halfspaces=collision.HalfSpaces.create([[0.0, 0.0, 1.0]], [-far])
            )
            for w in worlds
        ]
    point = np.array([0.0, 0.0, -far])
    stacked = {}
    for kind in _KINDS:
        if not counts[kind]:
            stacked[kind] = getattr(worlds[0], kind)
            continue
        rows = [_pad_kind(kind, getattr(w, kind), counts[kind], w, point) for w in worlds]
        cls = type(getattr(worlds[0], kind))
        stacked[kind] = cls(**{f: jnp.asarray(np.stack([r[f] for r in rows])) for f in rows[0]})
    empty = [k for k in _KINDS if not counts[k]]
    for k in empty:  # an empty kind gets the leading axis too
        stacked[k] = jax.tree.map(
            lambda x: jnp.broadcast_to(x, (len(worlds), *x.shape)), stacked[k]
        )
    return World(**stacked)
