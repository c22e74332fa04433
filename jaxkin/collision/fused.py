"""The exact clearance of placed robot primitives: robot-world and self pairs, and their pairs.

``clearance(spheres, capsules, world, self_pairs)`` gives, per configuration, the smallest
signed distance over every robot primitive against every obstacle and over every checked
self-collision primitive pair, and which pair attains it; ``min_clearance`` gives the distance
alone (no bookkeeping of the pair). The values equal the smallest entries of
``world.nearest_obstacles`` and ``pairs.self_distances`` (the same closed forms of
``distance``). ``world_and_self`` keeps the two apart: the world's smallest distance with its
(robot primitive, obstacle) pair and the self pairs' with theirs.

Layout (``collision.rows``): the configurations are the minor axis; one loop step per
obstacle (every robot primitive of a kind against it: a block ``(n, B)``) and per chunk of
self pairs, each block reduced by halving, with the integer code of the pair attaining the
minimum carried through the same minimums and decoded once per configuration. The program's
size depends on which kinds of primitives and obstacles are present, not on their counts.

World obstacles are taken unbatched (arrays ``(m, ...)``): for a world per configuration,
``vmap`` over it.
"""

from __future__ import annotations

import dataclasses
import functools
import math
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

from . import distance as sd
from .pairs import SelfPairs
from .primitives import Capsules, Spheres
from .rows import (
    CAPSULE_CHUNK,
    OBSTACLE_CHUNK,
    Placed,
    loop_pairs,
    loop_world,
    tree_argmin,
    tree_min,
)
from .world import BOX, CAPSULE, CYLINDER, HALFSPACE, SPHERE, World

__all__ = [
    "Clearance",
    "primitive_clearances",
    "WorldAndSelf",
    "clearance",
    "min_clearance",
    "min_clearance_rows",
    "world_and_self",
]


@jax.tree_util.register_dataclass
@dataclasses.dataclass(frozen=True)
class Clearance:
    """Per configuration (shapes ``batch``): the smallest signed ``distance`` over the robot's
    world and self pairs, and its pair: ``world`` (True: robot-world pair, False: self pair),
    the robot primitive ``robot_kind`` (``SPHERE`` or ``CAPSULE``, int8) and ``robot_index``
    (int32, within its kind), and the other member ``other_kind`` / ``other_index``: an
    obstacle (``SPHERE, CAPSULE, BOX, HALFSPACE, CYLINDER``) for a world pair, a robot
    primitive for a self pair. With nothing to check the distance is the dtype's largest
    finite value and the kinds and indices are -1."""

    distance: jax.Array
    world: jax.Array
    robot_kind: jax.Array
    robot_index: jax.Array
    other_kind: jax.Array
    other_index: jax.Array


@dataclasses.dataclass(frozen=True)
class WorldAndSelf:
    """Per configuration ``(B,)``: the smallest robot-world distance and its code
    (``primitive * n_obstacles + obstacle``, robot spheres first; obstacles by kind and
    index), the smallest self-pair distance and its code (the pair's index in ``ss``, then
    ``sc``, then ``cc``); a distance is the dtype's largest finite value and its code -1
    where there is nothing of its kind to check."""

    world: jax.Array
    world_code: jax.Array
    own: jax.Array
    own_code: jax.Array


def obstacle_kinds(world: World) -> list[tuple[int, int, tuple[jax.Array, ...]]]:
    """``(kind, first code, arrays (m, ...))`` of each non-empty obstacle kind, in kind
    order."""
    w, c, out, offset = world, world.cylinders, [], 0
    kinds: list[tuple[int, Any, tuple[jax.Array, ...]]] = [
        (SPHERE, w.spheres, (w.spheres.center, w.spheres.radius)),
        (CAPSULE, w.capsules, (w.capsules.a, w.capsules.b, w.capsules.radius)),
        (BOX, w.boxes, (w.boxes.center, w.boxes.rotation, w.boxes.half_extents)),
        (HALFSPACE, w.halfspaces, (w.halfspaces.normal, w.halfspaces.offset)),
        (CYLINDER, c, (c.center, c.axis, c.radius, c.half_length)),
    ]
    for kind, prims, arrays in kinds:
        if len(prims):
            out.append((kind, offset, arrays))
            offset += len(prims)
    return out


def _points(rows: jax.Array) -> jax.Array:
    """``(3, n, B)`` rows as points ``(n, B, 3)`` (the distances' layout; fused away)."""
    return jnp.stack([rows[0], rows[1], rows[2]], axis=-1)


def _sphere_distance(kind: int, c: jax.Array, r: jax.Array, obstacle: tuple) -> jax.Array:
    """Signed distances ``(n, B)`` of spheres (centres ``(n, B, 3)``) to one obstacle."""
    if kind == SPHERE:
        return sd.sphere_sphere(c, r, *obstacle)
    if kind == CAPSULE:
        return sd.sphere_capsule(c, r, *obstacle)
    if kind == BOX:
        return sd.sphere_box(c, r, *obstacle)
    if kind == CYLINDER:
        return sd.sphere_cylinder(c, r, *obstacle)
    return sd.sphere_halfspace(c, r, *obstacle)


def _capsule_distance(kind: int, a: jax.Array, b: jax.Array, r: jax.Array, obstacle: tuple):
    """Signed distances ``(n, B)`` of capsules (ends ``(n, B, 3)``) to one obstacle."""
    if kind == SPHERE:
        return sd.sphere_capsule(obstacle[0], obstacle[1], a, b, r)
    if kind == CAPSULE:
        return sd.capsule_capsule(a, b, r, *obstacle)
    if kind == BOX:
        return sd.capsule_box(a, b, r, *obstacle)
    if kind == CYLINDER:
        return sd.capsule_cylinder(a, b, r, *obstacle)
    return sd.capsule_halfspace(a, b, r, *obstacle)


def _sphere_rows(kind: int, spheres: tuple, obstacle: tuple) -> jax.Array:
    """``_sphere_distance`` of spheres in rows (centres ``(3, n, B)``, radii ``(n, 1)``)."""
    center, radius = spheres
    return _sphere_distance(kind, _points(center), radius, obstacle)


def _capsule_rows(kind: int, capsules: tuple, obstacle: tuple) -> jax.Array:
    """``_capsule_distance`` of capsules in rows (ends ``(3, n, B)``, radii ``(n, 1)``)."""
    a, b, radius = capsules
    return _capsule_distance(kind, _points(a), _points(b), radius, obstacle)


def _row(x: jax.Array, row: jax.Array) -> jax.Array:
    """Row ``row[b]`` of rows ``x`` ``(..., n, B)`` (or radii ``(n, 1)``) for each
    configuration ``b``: ``(..., 1, B)``."""
    if x.ndim == 2:
        return x[row, 0][None]
    return jnp.take_along_axis(x, row[None, None], axis=-2)


def _smaller(a: Any, b: Any) -> Any:
    """The elementwise smaller of two ``(value, code)`` pairs (a tie: the smaller code, a
    code of -1 (nothing) losing)."""
    later = (b[0] < a[0]) | ((b[0] == a[0]) & (b[1] >= 0) & ((b[1] < a[1]) | (a[1] < 0)))
    return jnp.where(later, b[0], a[0]), jnp.where(later, b[1], a[1])


def _running(codes: bool) -> Any:
    """The ``update`` of a self-pair loop: a running minimum over steps, with the pair's
    code."""

    def update(carry: Any, code: Any, block: jax.Array, rows_code: jax.Array) -> Any:
        if not codes:
            return jnp.minimum(carry, tree_min(block))
        value, row = tree_argmin(block, rows_code)
        return _smaller(carry, (value, row + code))

    return update


def world_and_self(
    placed: Placed, world: World, pairs: SelfPairs | None, codes: bool = True
) -> WorldAndSelf:
    """The smallest world and self distances of a placed chunk (module docstring); without
    ``codes`` the codes are -1."""
    size = placed.size
    dtype = placed.spheres.dtype
    big = jnp.finfo(dtype).max
    none = jnp.full((size,), -1, jnp.int32)
    kinds = obstacle_kinds(world.astype(dtype))
    n_obstacles = sum(len(arrays[0]) for _, _, arrays in kinds)
    ns = placed.spheres.shape[1]
    rows: list[tuple[int, int, int, tuple[jax.Array, ...], Any]] = []
    # (first code, count, obstacles per step, the rows' distances to an obstacle)
    if ns:
        spheres = (placed.spheres, placed.sphere_radius)
        rows.append((0, ns, OBSTACLE_CHUNK, spheres, _sphere_rows))
    if placed.capsule_a.shape[1]:
        capsules = (placed.capsule_a, placed.capsule_b, placed.capsule_radius)
        rows.append((ns, capsules[2].shape[0], CAPSULE_CHUNK, capsules, _capsule_rows))
    world_value, world_code = jnp.full((size,), big, dtype), none
    for first, count, chunk, prims, distance in rows:
        # per primitive the smallest distance over the obstacles (one output per step: the
        # obstacle's code carried along would have XLA store every obstacle's distances)
        carry = jnp.full((count, size), big, dtype)
        for kind, _, arrays in kinds:
            carry = loop_world(
                lambda obstacle, j, kind=kind, prims=prims, distance=distance: distance(  # type: ignore[misc]  # defaults
                    kind, prims, obstacle
                ),
                arrays,
                carry,
                jnp.minimum,
                chunk=chunk,
            )
        if not codes:
            world_value = jnp.minimum(world_value, tree_min(carry))
            continue
        value, prim = tree_argmin(carry, jnp.arange(count, dtype=jnp.int32)[:, None])
        # the obstacle: that primitive's distances again, one row per configuration
        chosen = tuple(_row(x, prim) for x in prims)
        nearest = (jnp.full((1, size), big, dtype), jnp.full((1, size), -1, jnp.int32))
        for kind, offset, arrays in kinds:

            def coded(obstacle, j, kind=kind, chosen=chosen, distance=distance, offset=offset):
                d = distance(kind, chosen, obstacle)
                return d, jnp.broadcast_to(offset + j, d.shape).astype(jnp.int32)

            nearest = loop_world(coded, arrays, nearest, _smaller, _smaller, chunk=chunk)
        code = jnp.where(nearest[1][0] < 0, -1, (first + prim) * n_obstacles + nearest[1][0])
        world_value, world_code = _smaller((world_value, world_code), (value, code))
    start = (jnp.full((size,), big, dtype), none) if codes else jnp.full((size,), big, dtype)
    own_value, own_code = _self(placed, pairs, start, _running(codes), codes)
    return WorldAndSelf(world_value, world_code, own_value, own_code)


def _world_test(distance: Any, kind: int, prims: tuple, obstacle: tuple, j: Any) -> jax.Array:
    """``distance(kind, prims, obstacle)``: one obstacle's test in ``loop_world``'s shape."""
    return distance(kind, prims, obstacle)


def primitive_clearances(
    placed: Placed, world: World, pairs: SelfPairs | None, skip_copies: bool = False
) -> tuple[jax.Array, jax.Array]:
    """Per robot primitive its smallest signed distance to the world, ``(S + C, B)``
    (spheres, then capsules; the dtype's largest finite value with no obstacle), and per
    checked link pair (``pairs.link_pairs``) its smallest self distance, ``(len(link_pairs),
    B)``: what conservative advancement bounds, one speed per link (``jaxkin.motion``).
    ``skip_copies``: the trailing copies of each kind's last obstacle are not tested again
    (``rows.loop_world``: the same values, not differentiable in reverse mode)."""
    size = placed.size
    dtype = placed.spheres.dtype
    big = jnp.finfo(dtype).max
    kinds = obstacle_kinds(world.astype(dtype))
    parts = []
    rows = [
        ((placed.spheres, placed.sphere_radius), _sphere_rows, OBSTACLE_CHUNK),
        ((placed.capsule_a, placed.capsule_b, placed.capsule_radius), _capsule_rows, CAPSULE_CHUNK),
    ]
    for prims, distance, chunk in rows:
        carry = jnp.full((prims[-1].shape[0], size), big, dtype)
        for kind, _, arrays in kinds:
            carry = loop_world(
                functools.partial(_world_test, distance, kind, prims),
                arrays,
                carry,
                jnp.minimum,
                chunk=chunk,
                skip_copies=skip_copies,
            )
        parts.append(carry)
    link_pairs = len(pairs.link_pairs) if pairs is not None else 0
    own = jnp.full((link_pairs, size), big, dtype)
    if pairs is not None and link_pairs:
        tests = _self_tests(placed)
        lists = ((pairs.ss, pairs.ss_pair), (pairs.sc, pairs.sc_pair), (pairs.cc, pairs.cc_pair))
        for test, ((first, second), of_pair) in zip(tests, lists, strict=True):
            own = loop_pairs(
                test, first, second, own, lambda c, tags, block: c.at[tags].min(block),
                tags=of_pair,
            )  # fmt: skip
    return jnp.concatenate(parts), own


def self_order(pairs: SelfPairs) -> tuple[list[np.ndarray], np.ndarray, np.ndarray, np.ndarray]:
    """The self pairs' codes: each pair's rank in the order of its link pair (then ``ss``,
    ``sc``, ``cc``), so that the smallest code among tied pairs names the first link pair;
    returns the ranks of the ``ss``, ``sc`` and ``cc`` pairs and, by rank, the pair's two
    primitives (numbered spheres first, then capsules: ``ns`` added to capsule indices by the
    caller) as ``(kind, index)`` codes ``index * 2 + (1 if capsule)`` and its link pair."""
    lists = [
        (pairs.ss, pairs.ss_pair, (0, 0)),
        (pairs.sc, pairs.sc_pair, (0, 1)),
        (pairs.cc, pairs.cc_pair, (1, 1)),
    ]
    rows = []  # (link pair, kind order, index, first, second)
    for order, ((first, second), of_pair, kinds) in enumerate(lists):
        for k, (i, j, link_pair) in enumerate(zip(first, second, of_pair, strict=True)):
            rows.append((link_pair, order, k, 2 * i + kinds[0], 2 * j + kinds[1]))
    ranked = sorted(range(len(rows)), key=lambda r: rows[r][:3])
    rank = np.empty(len(rows), np.int32)
    rank[ranked] = np.arange(len(rows), dtype=np.int32)
    sizes = np.cumsum([0] + [len(first) for (first, _), _, _ in lists])
    ranks = [rank[sizes[k] : sizes[k + 1]] for k in range(3)]
    by_rank = np.asarray([rows[r] for r in ranked], np.int32).reshape(-1, 5)
    return ranks, by_rank[:, 3], by_rank[:, 4], by_rank[:, 0]


def _self_tests(placed: Placed) -> tuple[Any, Any, Any]:
    """The signed distances ``(Q, B)`` of sphere-sphere, sphere-capsule and capsule-capsule
    self pairs ``(i, j)`` (index arrays ``(Q,)``) of a placed chunk."""
    s_c, s_r = placed.spheres, placed.sphere_radius
    c_a, c_b, c_r = placed.capsule_a, placed.capsule_b, placed.capsule_radius

    def ss(i: jax.Array, j: jax.Array) -> jax.Array:
        return sd.sphere_sphere(_points(s_c[:, i]), s_r[i], _points(s_c[:, j]), s_r[j])

    def sc(i: jax.Array, j: jax.Array) -> jax.Array:
        a, b = _points(c_a[:, j]), _points(c_b[:, j])
        return sd.sphere_capsule(_points(s_c[:, i]), s_r[i], a, b, c_r[j])

    def cc(i: jax.Array, j: jax.Array) -> jax.Array:
        a, b = _points(c_a[:, i]), _points(c_b[:, i])
        return sd.capsule_capsule(a, b, c_r[i], _points(c_a[:, j]), _points(c_b[:, j]), c_r[j])

    return ss, sc, cc


def _self(placed: Placed, pairs: SelfPairs | None, carry: Any, update: Any, codes: bool) -> Any:
    """The smallest self-pair distance (and code: ``self_order``) of a placed chunk."""
    if pairs is None or not pairs.link_pairs:
        return carry if codes else (carry, jnp.full(carry.shape, -1, jnp.int32))
    ranks = self_order(pairs)[0]
    tests = zip(_self_tests(placed), (pairs.ss, pairs.sc, pairs.cc), ranks, strict=True)
    for test, (first, second), rank in tests:
        carry = loop_pairs(
            test, first, second, carry, lambda c, tags, block: update(c, 0, block, tags[:, None]),
            tags=rank,
        )  # fmt: skip
    return carry if codes else (carry, jnp.full(carry.shape, -1, jnp.int32))


def as_placed(spheres: Spheres, capsules: Capsules) -> tuple[Placed, tuple[int, ...]]:
    """Placed primitives ``(*batch, n, 3)`` in the rows layout, and ``batch``."""
    batch = jnp.broadcast_shapes(spheres.radius.shape[:-1], capsules.radius.shape[:-1])
    size = math.prod(batch)
    dtype = jnp.result_type(spheres.radius, capsules.radius)

    def points(x: jax.Array, n: int) -> jax.Array:
        x = jnp.broadcast_to(x.astype(dtype), (*batch, n, 3))
        return jnp.transpose(x.reshape((size, n, 3)), (2, 1, 0))

    def radii(x: jax.Array, n: int) -> jax.Array:
        return jnp.broadcast_to(x.astype(dtype), (*batch, n)).reshape((size, n)).T

    ns, nc = spheres.radius.shape[-1], capsules.radius.shape[-1]
    placed = Placed(
        points(spheres.center, ns),
        radii(spheres.radius, ns),
        points(capsules.a, nc),
        points(capsules.b, nc),
        radii(capsules.radius, nc),
    )
    return placed, batch


def min_clearance(
    spheres: Spheres, capsules: Capsules, world: World, self_pairs: SelfPairs | None = None
) -> jax.Array:
    """The smallest signed distance per configuration over robot-world and self pairs.

    Args:
        spheres: the robot's spheres placed in the world, ``center (*batch, ns, 3)``,
            ``radius (*batch, ns)`` (``Body.place``).
        capsules: the robot's capsules placed in the world, ``a, b (*batch, nc, 3)``.
        world: the obstacles, unbatched (``vmap`` for a world per configuration).
        self_pairs: the self-collision primitive pairs (``SelfPairs.create``), or None.

    Returns:
        ``(*batch)``: the clearance, the dtype's largest finite value when nothing is checked.
    """
    placed, batch = as_placed(spheres, capsules)
    return min_clearance_rows(placed, world, self_pairs).reshape(batch)


def min_clearance_rows(placed: Placed, world: World, self_pairs: SelfPairs | None = None):
    """``min_clearance`` of primitives already in the rows layout (``rows.Placed``): returns
    ``(B,)``. For a pipeline whose forward kinematics writes each placed coordinate as a row
    of ``B`` configurations (``rows.place``), so no transpose is needed before the check."""
    parts = world_and_self(placed, world, self_pairs, codes=False)
    return jnp.minimum(parts.world, parts.own)


def clearance(
    spheres: Spheres, capsules: Capsules, world: World, self_pairs: SelfPairs | None = None
) -> Clearance:
    """The smallest signed distance per configuration and the pair attaining it.

    Arguments as ``min_clearance``; returns a ``Clearance`` with shapes ``batch``. Ties go
    to the first pair in the order: world pairs (robot spheres, then capsules; obstacles by
    kind and index), then self pairs.
    """
    placed, batch = as_placed(spheres, capsules)
    parts = world_and_self(placed, world, self_pairs)
    ns = spheres.radius.shape[-1]
    is_world = parts.world <= parts.own
    n_obstacles = max(1, sum(len(a[0]) for _, _, a in obstacle_kinds(world)))
    w_prim, w_obstacle = parts.world_code // n_obstacles, parts.world_code % n_obstacles
    first, second = self_primitives(self_pairs, ns, parts.own_code)
    prim = jnp.where(is_world, w_prim, first)
    nothing = jnp.where(is_world, parts.world_code, parts.own_code) < 0
    obstacle_kind, obstacle_index = obstacle_of(world, w_obstacle)

    def kind_of(p: jax.Array) -> jax.Array:
        return jnp.where(p < ns, SPHERE, CAPSULE)

    def index_of(p: jax.Array) -> jax.Array:
        return jnp.where(p < ns, p, p - ns)

    fields = (
        jnp.minimum(parts.world, parts.own),
        is_world & ~nothing,
        jnp.where(nothing, -1, kind_of(prim)).astype(jnp.int8),
        jnp.where(nothing, -1, index_of(prim)).astype(jnp.int32),
        jnp.where(nothing, -1, jnp.where(is_world, obstacle_kind, kind_of(second))).astype(
            jnp.int8
        ),
        jnp.where(nothing, -1, jnp.where(is_world, obstacle_index, index_of(second))).astype(
            jnp.int32
        ),
    )
    return Clearance(*(x.reshape(batch) for x in fields))


def self_primitives(
    pairs: SelfPairs | None, ns: int, code: jax.Array
) -> tuple[jax.Array, jax.Array]:
    """A self code (``self_order``) as the pair's two primitives, numbered spheres first then
    capsules (``ns`` spheres); ``(-1, -1)`` for -1."""
    if pairs is None or not pairs.num_primitive_pairs:
        none = jnp.full(code.shape, -1, jnp.int32)
        return none, none
    _, first, second, _ = self_order(pairs)

    def number(x: np.ndarray) -> jax.Array:
        return jnp.asarray(x // 2 + ns * (x % 2))  # a capsule after the spheres

    safe = jnp.clip(code, 0, len(first) - 1)
    return (
        jnp.where(code < 0, -1, number(first)[safe]),
        jnp.where(code < 0, -1, number(second)[safe]),
    )


def self_link_pair(pairs: SelfPairs | None, code: jax.Array) -> jax.Array:
    """A self code (``self_order``) as the index of its link pair in ``pairs.link_pairs``
    (-1 for -1)."""
    if pairs is None or not pairs.num_primitive_pairs:
        return jnp.full(code.shape, -1, jnp.int32)
    link_pair = jnp.asarray(self_order(pairs)[3])
    return jnp.where(code < 0, -1, link_pair[jnp.clip(code, 0, len(link_pair) - 1)])


def obstacle_of(world: World, code: jax.Array) -> tuple[jax.Array, jax.Array]:
    """An obstacle code (kinds in order, indices within) as ``(kind, index)``."""
    kind = jnp.full(code.shape, -1, jnp.int32)
    index = jnp.full(code.shape, -1, jnp.int32)
    for k, offset, arrays in obstacle_kinds(world):
        inside = (code >= offset) & (code < offset + arrays[0].shape[0])
        kind = jnp.where(inside, k, kind)
        index = jnp.where(inside, code - offset, index)
    return kind, index
