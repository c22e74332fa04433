"""The fused clearance of placed robot primitives: robot-world and self pairs in one pass.

``clearance(spheres, capsules, world, self_pairs)`` gives, per configuration, the smallest
signed distance over every robot primitive against every obstacle and over every checked
self-collision primitive pair, and which pair attains it; ``min_clearance`` gives the distance
alone (no bookkeeping of the pair: the cheapest verdict, ``min_clearance(...) > 0`` is
collision-free). The values equal the smallest entries of ``world.nearest_obstacles`` and
``pairs.self_distances`` (the same closed forms of ``distance``).

Layout (why it is fast on a CPU): the configurations are the minor axis. Each robot primitive
coordinate is a ``(n, B)`` array (structure of arrays), each obstacle enters as scalars, and
the reduction over obstacles is a running elementwise minimum written out obstacle by obstacle
(up to ``UNROLL`` of a kind; a ``fori_loop`` beyond), so XLA fuses each obstacle's distance
and its minimum into one vectorised loop over the batch, with no ``(B, n, m)`` temporary and
no multi-axis reduction. Self pairs are grouped by their first primitive: each group is a
contiguous ``(k, B)`` block against that primitive's row. The rows left at the end are
reduced by halving (elementwise minimums of two halves). The pair is tracked by an integer
code carried through the same minimums, decoded once per configuration.

World obstacles are taken unbatched (arrays ``(m, ...)``): for a world per configuration,
``vmap`` over it.
"""

from __future__ import annotations

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np

from . import distance as sd
from .pairs import SelfPairs
from .primitives import Capsules, Spheres
from .world import BOX, CAPSULE, HALFSPACE, SPHERE, World

__all__ = ["Clearance", "clearance", "min_clearance", "min_clearance_rows"]

# Obstacles of one kind written out one by one up to this count (compile size grows with
# it); larger kinds (point clouds) run in a fori_loop, one obstacle per step.
UNROLL = 48


@jax.tree_util.register_dataclass
@dataclasses.dataclass(frozen=True)
class Clearance:
    """Per configuration (shapes ``batch``): the smallest signed ``distance`` over the robot's
    world and self pairs, and its pair: ``world`` (True: robot-world pair, False: self pair),
    the robot primitive ``robot_kind`` (``SPHERE`` or ``CAPSULE``, int8) and ``robot_index``
    (int32, within its kind), and the other member ``other_kind`` / ``other_index``: an
    obstacle (``SPHERE, CAPSULE, BOX, HALFSPACE``) for a world pair, a robot primitive for a
    self pair. With nothing to check the distance is the dtype's largest finite value and
    the kinds and indices are -1."""

    distance: jax.Array
    world: jax.Array
    robot_kind: jax.Array
    robot_index: jax.Array
    other_kind: jax.Array
    other_index: jax.Array


def _soa(x: jax.Array, batch: tuple[int, ...], n: int) -> list[jax.Array]:
    """``(*batch, n, 3)`` -> three ``(n, B)`` coordinate arrays (configurations minor)."""
    flat = x.reshape((-1, n, 3))
    # the barrier materialises the transposed rows once; fused into every obstacle's loop,
    # the transpose would be a strided, unvectorised read per obstacle
    return list(_materialised([flat[..., i].T for i in range(3)]))


def _materialised(tree):
    """``tree`` computed into buffers of its own: XLA on CPU fuses a transpose into each of
    its consumers as a strided, unvectorised read (and drops optimisation barriers), but a
    conditional's results are materialised. The predicate is true unless the data hold a
    NaN, and both branches are the identity."""
    leaf = jax.tree.leaves(tree)[0]
    pred = jnp.ravel(leaf)[0] == jnp.ravel(leaf)[0] if leaf.size else jnp.bool_(True)
    return jax.lax.cond(pred, lambda t: t, lambda t: jax.tree.map(lambda x: x + 0, t), tree)


def _rows(x: jax.Array, batch: tuple[int, ...], n: int) -> jax.Array:
    return _materialised(jnp.broadcast_to(x, (*batch, n)).reshape((-1, n)).T)


def _take(x: jax.Array, idx: np.ndarray) -> jax.Array:
    """Rows ``idx`` of ``x`` (static): a slice when they are contiguous, else a gather."""
    if len(idx) and np.all(np.diff(idx) == 1):
        return x[int(idx[0]) : int(idx[-1]) + 1]
    return x[idx]


class _Best:
    """A running minimum ``value`` with the integer ``code`` of its argument (or no code)."""

    def __init__(self, codes: bool):
        self.codes = codes
        self.value = None
        self.code = None

    def add(self, value: jax.Array, code) -> None:
        """Take ``value`` (same shape or broadcast) with ``code`` (an int or an int32 array)."""
        code = jnp.asarray(code, jnp.int32) if self.codes else None
        if self.value is None:
            self.value = value
            self.code = jnp.broadcast_to(code, value.shape) if self.codes else None
            return
        if self.codes:
            self.code = jnp.where(value < self.value, code, self.code)
        self.value = jnp.minimum(self.value, value)


def _halve(value: jax.Array, code: jax.Array | None) -> tuple[jax.Array, jax.Array | None]:
    """The minimum over axis 0 of ``(k, B)`` rows, and the code of the row attaining it."""
    if code is None:
        return jnp.min(value, axis=0), None
    row = jnp.argmin(value, axis=0)[None]
    pick = lambda x: jnp.take_along_axis(x, row, axis=0)[0]  # noqa: E731
    return pick(value), pick(code)


def _obstacles(world: World) -> list[tuple[int, int, tuple[jax.Array, ...]]]:
    """``(kind, first code, arrays (m, ...))`` of each non-empty kind, in kind order."""
    w, out, offset = world, [], 0
    for kind, prims, arrays in [
        (SPHERE, w.spheres, (w.spheres.center, w.spheres.radius)),
        (CAPSULE, w.capsules, (w.capsules.a, w.capsules.b, w.capsules.radius)),
        (BOX, w.boxes, (w.boxes.center, w.boxes.rotation, w.boxes.half_extents)),
        (HALFSPACE, w.halfspaces, (w.halfspaces.normal, w.halfspaces.offset)),
    ]:
        if len(prims):
            out.append((kind, offset, arrays))
            offset += len(prims)
    return out


def _world_distance(robot_kind: int, robot: tuple, kind: int, obstacle: tuple) -> jax.Array:
    """Signed distances ``(n, B)`` of robot primitives (SoA) to one obstacle (its arrays
    without the obstacle axis)."""
    if robot_kind == SPHERE:
        (x, y, z), r = robot
        c = jnp.stack([x, y, z], axis=-1)
        if kind == SPHERE:
            return sd.sphere_sphere(c, r, *obstacle)
        if kind == CAPSULE:
            return sd.sphere_capsule(c, r, *obstacle)
        if kind == BOX:
            return sd.sphere_box(c, r, *obstacle)
        return sd.sphere_halfspace(c, r, *obstacle)
    (ax, ay, az), (bx, by, bz), r = robot
    a, b = jnp.stack([ax, ay, az], axis=-1), jnp.stack([bx, by, bz], axis=-1)
    if kind == SPHERE:
        return sd.sphere_capsule(obstacle[0], obstacle[1], a, b, r)
    if kind == CAPSULE:
        return sd.capsule_capsule(a, b, r, *obstacle)
    if kind == BOX:
        return sd.capsule_box(a, b, r, *obstacle)
    return sd.capsule_halfspace(a, b, r, *obstacle)


def _world_rows(robot_kind: int, robot: tuple, world: World, codes: bool) -> _Best:
    """Per robot primitive row ``(n, B)``: the smallest distance over the world and the
    obstacle's code."""
    best = _Best(codes)
    for kind, offset, arrays in _obstacles(world):
        m = arrays[0].shape[0]
        if m <= UNROLL:
            for j in range(m):
                obstacle = tuple(x[j] for x in arrays)
                best.add(_world_distance(robot_kind, robot, kind, obstacle), offset + j)
            continue
        best.add(_world_distance(robot_kind, robot, kind, tuple(x[0] for x in arrays)), offset)

        def step(j, carry, kind=kind, arrays=arrays, offset=offset):
            value, code = carry
            obstacle = tuple(jax.lax.dynamic_index_in_dim(x, j, keepdims=False) for x in arrays)
            d = _world_distance(robot_kind, robot, kind, obstacle)
            if codes:
                code = jnp.where(d < value, offset + j, code)
            return jnp.minimum(value, d), code

        carry = (best.value, best.code if codes else jnp.zeros((), jnp.int32))
        best.value, code = jax.lax.fori_loop(1, m, step, carry)
        best.code = code if codes else None
    return best


def _self_groups(pairs: SelfPairs) -> list[tuple[str, int, np.ndarray]]:
    """Self pairs grouped by kind and first primitive: ``(kind, i, js)`` with ``kind`` one of
    ``ss, sc, cc`` (static)."""
    out = []
    for kind, (first, second) in (("ss", pairs.ss), ("sc", pairs.sc), ("cc", pairs.cc)):
        first, second = np.asarray(first, int), np.asarray(second, int)
        for i in np.unique(first):
            out.append((kind, int(i), np.sort(second[first == i])))
    return out


def _as_rows(spheres: Spheres, capsules: Capsules) -> tuple[Spheres, Capsules]:
    """Placed primitives ``(*batch, n, 3)`` in the rows layout: centres and end points
    ``(3, n, B)``, radii ``(n, B)`` (configurations minor)."""
    batch = spheres.radius.shape[:-1]
    dtype = jnp.result_type(spheres.radius, capsules.radius)
    ns, nc = len(spheres), len(capsules)

    def points(x, n):
        return jnp.stack(_soa(x.astype(dtype), batch, n)) if n else jnp.zeros((3, 0, 1), dtype)

    def radii(x, n):
        return _rows(x.astype(dtype), batch, n) if n else jnp.zeros((0, 1), dtype)

    return (
        Spheres(points(spheres.center, ns), radii(spheres.radius, ns)),
        Capsules(points(capsules.a, nc), points(capsules.b, nc), radii(capsules.radius, nc)),
    )


def _fused(spheres: Spheres, capsules: Capsules, world: World, pairs: SelfPairs | None, codes):
    """The kernel on the rows layout (``_as_rows``)."""
    dtype = jnp.result_type(spheres.radius, capsules.radius)
    ns, nc = spheres.radius.shape[0], capsules.radius.shape[0]
    if not ns and not nc:
        raise ValueError("spheres, capsules: the robot has no primitive")
    size = max(x.shape[-1] for x in (spheres.radius, capsules.radius) if x.ndim == 2 and x.size)
    big = jnp.finfo(dtype).max
    s_c = [spheres.center[i] for i in range(3)] if ns else None
    s_r = spheres.radius if ns else None
    c_a = [capsules.a[i] for i in range(3)] if nc else None
    c_b = [capsules.b[i] for i in range(3)] if nc else None
    c_r = capsules.radius if nc else None
    world = world.astype(dtype)
    n_obstacles = sum(
        len(p) for p in (world.spheres, world.capsules, world.boxes, world.halfspaces)
    )
    prims = ns + nc
    total = _Best(codes)
    # robot-world: code = primitive * n_obstacles + obstacle (spheres first, then capsules)
    for robot_kind, n, robot, first in (
        (SPHERE, ns, (s_c, s_r), 0),
        (CAPSULE, nc, (c_a, c_b, c_r), ns),
    ):
        if not n or not n_obstacles:
            continue
        rows = _world_rows(robot_kind, robot, world, codes)
        code = None
        if codes:
            row = jnp.arange(first, first + n, dtype=jnp.int32)[:, None] * n_obstacles
            code = row + rows.code
        value, code = _halve(rows.value, code)
        total.add(value, code)
    world_value, world_code = total.value, total.code
    # self: code = primitive i * prims + primitive j
    own = _Best(codes)
    for kind, i, js in _self_groups(pairs) if pairs is not None else []:
        if kind == "ss":
            d = sd.sphere_sphere(
                jnp.stack([x[i] for x in s_c], -1),
                s_r[i],
                jnp.stack([_take(x, js) for x in s_c], -1),
                _take(s_r, js),
            )
            ci, cj = i, js
        elif kind == "sc":
            d = sd.sphere_capsule(
                jnp.stack([x[i] for x in s_c], -1),
                s_r[i],
                jnp.stack([_take(x, js) for x in c_a], -1),
                jnp.stack([_take(x, js) for x in c_b], -1),
                _take(c_r, js),
            )
            ci, cj = i, ns + js
        else:
            d = sd.capsule_capsule(
                jnp.stack([x[i] for x in c_a], -1),
                jnp.stack([x[i] for x in c_b], -1),
                c_r[i],
                jnp.stack([_take(x, js) for x in c_a], -1),
                jnp.stack([_take(x, js) for x in c_b], -1),
                _take(c_r, js),
            )
            ci, cj = ns + i, ns + js
        code = None
        if codes:
            code = jnp.asarray((ci * prims + cj).astype(np.int32))[:, None]
            code = jnp.broadcast_to(code, d.shape)
        own.add(*_halve(d, code))
    return world_value, world_code, own.value, own.code, big, size, ns, prims, n_obstacles


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
    batch = spheres.radius.shape[:-1]
    world_value, _, self_value, _, big, _, _, _, _ = _fused(
        *_as_rows(spheres, capsules), world, self_pairs, codes=False
    )
    parts = [v for v in (world_value, self_value) if v is not None]
    if not parts:
        return jnp.full(batch, big)
    out = parts[0] if len(parts) == 1 else jnp.minimum(*parts)
    return out.reshape(batch)


def min_clearance_rows(
    spheres: Spheres, capsules: Capsules, world: World, self_pairs: SelfPairs | None = None
) -> jax.Array:
    """``min_clearance`` for primitives already in the rows layout: centres and end points
    ``(3, n, B)``, radii ``(n, B)``, configurations minor; returns ``(B,)``.

    For a fused pipeline whose forward kinematics writes each placed coordinate as a row of
    ``B`` configurations, so no transpose is needed between placement and the check.
    """
    world_value, _, self_value, _, big, size, _, _, _ = _fused(
        spheres, capsules, world, self_pairs, codes=False
    )
    parts = [v for v in (world_value, self_value) if v is not None]
    if not parts:
        return jnp.full((size,), big)
    return parts[0] if len(parts) == 1 else jnp.minimum(*parts)


def clearance(
    spheres: Spheres, capsules: Capsules, world: World, self_pairs: SelfPairs | None = None
) -> Clearance:
    """The smallest signed distance per configuration and the pair attaining it.

    Arguments as ``min_clearance``; returns a ``Clearance`` with shapes ``batch``. Ties go
    to the first pair in the order: world pairs (robot spheres, then capsules; obstacles by
    kind and index), then self pairs.
    """
    batch = spheres.radius.shape[:-1]
    world_value, world_code, self_value, self_code, big, size, ns, prims, n_obstacles = _fused(
        *_as_rows(spheres, capsules), world, self_pairs, codes=True
    )
    dtype = jnp.result_type(spheres.radius, capsules.radius)
    none = jnp.full((size,), -1, jnp.int32)
    if world_value is None and self_value is None:
        return Clearance(
            jnp.full(batch, big, dtype),
            jnp.zeros(batch, bool),
            none.astype(jnp.int8).reshape(batch),
            none.reshape(batch),
            none.astype(jnp.int8).reshape(batch),
            none.reshape(batch),
        )
    w_value = jnp.full((size,), big, dtype) if world_value is None else world_value
    s_value = jnp.full((size,), big, dtype) if self_value is None else self_value
    is_world = (w_value <= s_value) & (world_value is not None)
    if self_value is None:
        is_world = jnp.ones((size,), bool)
    distance = jnp.minimum(w_value, s_value)
    # decode: world code = primitive * n_obstacles + obstacle; self code = i * prims + j
    wc = jnp.zeros((size,), jnp.int32) if world_code is None else world_code
    sc = jnp.zeros((size,), jnp.int32) if self_code is None else self_code
    w_prim, w_obst = wc // max(n_obstacles, 1), wc % max(n_obstacles, 1)
    s_first, s_second = sc // prims, sc % prims
    prim = jnp.where(is_world, w_prim, s_first)
    robot_kind = jnp.where(prim < ns, SPHERE, CAPSULE).astype(jnp.int8)
    robot_index = jnp.where(prim < ns, prim, prim - ns)
    obstacle_kind, obstacle_index = _obstacle_of(world, w_obst)
    other_kind = jnp.where(
        is_world, obstacle_kind, jnp.where(s_second < ns, SPHERE, CAPSULE)
    ).astype(jnp.int8)
    other_index = jnp.where(
        is_world, obstacle_index, jnp.where(s_second < ns, s_second, s_second - ns)
    )
    return Clearance(
        distance.reshape(batch),
        is_world.reshape(batch),
        robot_kind.reshape(batch),
        robot_index.astype(jnp.int32).reshape(batch),
        other_kind.reshape(batch),
        other_index.astype(jnp.int32).reshape(batch),
    )


def _obstacle_of(world: World, code: jax.Array) -> tuple[jax.Array, jax.Array]:
    """An obstacle code (kinds in order, indices within) as ``(kind, index)``."""
    kind = jnp.full(code.shape, -1, jnp.int32)
    index = jnp.full(code.shape, -1, jnp.int32)
    for k, offset, arrays in _obstacles(world):
        inside = (code >= offset) & (code < offset + arrays[0].shape[0])
        kind = jnp.where(inside, k, kind)
        index = jnp.where(inside, code - offset, index)
    return kind, index
