"""The collision verdict alone: per configuration, does the robot touch the world or itself?

``collides(robot, q, world)`` answers what a sampling-based planner asks, ``check(...).collides``,
without the clearance's value or its pair, and so without a square root or a double ``where``
per pair. With ``R = r + r' + margin`` for two spheres (centres ``c``, ``c'``)::

    |c - c'| - r - r' <= margin   <=>   |c - c'|^2 <= R^2        (R >= 0; never when R < 0)

a sphere against a box (``u`` the centre in the box frame, ``e_i = |u_i| - h_i``,
``s = min(R, 0)``, ``R = r + margin``)::

    d <= margin   <=>   sum_i max(e_i - s, 0)^2 <= max(R, 0)^2

(outside the box ``d`` is the distance to it, inside ``max_i e_i - r``: for ``R >= 0`` the
left side is the squared distance, for ``R < 0`` it is zero exactly when every ``e_i <= R``;
the squared tolerance below then allows ``e_i`` up to ``R + sqrt(slack)``), a sphere against a
capsule through the squared point-segment distance, against a half-space the plane's linear
form; a robot capsule goes through the exact signed distances of ``collision.distance``.

Layout: forward kinematics and placement write each placed coordinate as a row of the chunk's
configurations (the robot's ``link_frame_rows``: for a chain its joint prefixes, rotation
entries as ``(B,)`` rows, each sphere's centre moved into its carrying frame, no per-link
4x4 pose; by default one frame per link from ``link_poses``), in the dtype of ``q``. The
robot's spheres are then tested in blocks: against each kind of obstacle, the block ``(m,
spheres, C)`` of every sphere and obstacle (the obstacles' entries broadcast along a leading
axis); the sphere-sphere self pairs as dense blocks ``(firsts, seconds, C)`` (``_ss_blocks``:
the Panda's 700 pairs are two). Each block is reduced to ``(C,)`` by halving (``_tree_min``:
minimums of its two halves, slices that XLA fuses with the tests into one vectorised loop
that writes only the result). Capsules take the exact distances of ``collision.distance``,
an obstacle kind with more than ``fused.UNROLL`` entries (a point cloud) a loop over them.
A large concrete batch runs as one part per host thread (``_batching.PartsJit``).

Rounding: the verdict is conservative by a tolerance ``tol = 16 eps (1 + X)`` (``eps`` of the
dtype, ``X`` the largest coordinate magnitude of the configuration's placed primitives and the
world): every configuration whose exact clearance is ``<= margin`` is flagged. A flagged one
has a linear test (half-space, capsule) ``<= margin + tol``, or a squared one ``d^2 <= R^2 +
tol (2 R_max + tol)`` (``R`` above taken as ``R + tol`` for the largest ``R_max``), so its
clearance is at most ``margin + tol (2 R_max + tol) / (2 R)``. Both paths round their placed
coordinates differently, so configurations that close to contact can only be flagged, never
missed.

Culling (``collision.cull``, ``cull=True``, off by default: the blocks above are faster on
the CPU): the spheres' world pass goes through bounding spheres of groups of at most five
spheres of a link first; only the (group, configuration) candidates they flag get the exact
sphere tests (the same tests on the same placed rows, so the same verdict), a chunk with more
candidates than the capacity the full pass.

NaN or inf in a configuration gives ``collides = True`` and ``INVALID_INPUT`` for that
element alone (``UNREACHABLE`` where the robot does not assemble, ``Robot.placeable``).
Moving or resizing an obstacle reuses the compilation (array data).
"""

from __future__ import annotations

import dataclasses
import functools
import math
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from jax import Array
from jax.typing import ArrayLike

from .._batching import PartsJit, map_chunks
from .._numerics import all_finite, computed_once
from ..status import Status
from . import distance as sd
from .body import Body
from .check import _world_batched, check_kernel, checked_arguments
from .cull import bounding_spheres, cull_world, sphere_groups
from .fused import UNROLL, _materialised, _self_groups, _take
from .pairs import SelfPairs
from .world import World

__all__ = ["VERDICT_CHUNK", "Verdict", "collides", "collides_kernel"]

# Configurations per step: the placed rows and the temporaries of ~65 spheres stay in L2
VERDICT_CHUNK = 512


@jax.tree_util.register_dataclass
@dataclasses.dataclass(frozen=True)
class Verdict:
    """Per configuration (shapes ``(...)``, the batch of ``q``).

    Attributes:
        collides: the configuration touches the world or itself (clearance ``<= margin``,
            module docstring for rounding), or is not finite.
        status: ``int8`` ``jaxkin.Status``: ``OK``, ``COLLISION``, ``INVALID_INPUT`` or
            ``UNREACHABLE`` (joints at which the robot does not assemble).
    """

    collides: Array
    status: Array


def _frames(robot: Any, q: Array) -> tuple[Array, list[int], Array | None]:
    """Per link, a frame that carries it, in rows: ``F (12 P, C)`` (the ``P`` frames'
    rotation entries ``R[i][j]`` at row ``12 k + 3 i + j``, translations at ``12 k + 9 + i``),
    stored once (each placement loop reads it), the frame of each link and each link's pose
    in its frame ``(L, 4, 4)`` (None: the identity), from ``robot.link_frame_rows``."""
    size = q.shape[0]
    frames, of_link, homes = robot.link_frame_rows(q)
    rows = []
    for rot, pos in frames:
        for x in [rot[i][j] for i in range(3) for j in range(3)] + list(pos):
            rows.append(jnp.broadcast_to(jnp.asarray(x, q.dtype), (size,)))
    if homes is not None:
        homes = jnp.asarray(homes, q.dtype)
    return computed_once(jnp.stack(rows)), list(of_link), homes


def _place(frames: Array, of_link: list[int], homes: Array | None, points: Array, links) -> Array:
    """``points (k, 3)`` on ``links`` placed: rows ``(3, k, C)``, ``x_i = sum_m R_im c'_m +
    p_i`` with ``c'`` the point in its link's frame (``homes``), run by run of one link."""
    links = np.asarray(links, dtype=np.int64)
    if homes is not None:
        home = homes[links]
        points = jnp.einsum("kij,kj->ki", home[:, :3, :3], points) + home[:, :3, 3]
    cuts = np.flatnonzero(np.diff(links)) + 1
    out: list[list[Array]] = [[], [], []]
    for start, stop in zip([0, *cuts], [*cuts, len(links)], strict=True):
        base = 12 * of_link[int(links[start])]
        c = points[start:stop]
        for i in range(3):
            row = frames[base + 9 + i][None, :]
            for m in range(3):
                row = row + frames[base + 3 * i + m][None, :] * c[:, m, None]
            out[i].append(row)
    return jnp.stack([jnp.concatenate(rows) for rows in out])


def _place_rows(
    robot: Any, body: Body, q: Array, extra: tuple[Array, tuple[int, ...]] | None = None
) -> tuple[Array | None, Array | None, Array | None]:
    """The body placed at configurations ``q`` ``(C, n)``: sphere centres ``(3, ns, C)``,
    capsule end points ``(3, 2, nc, C)`` and the ``extra`` points ``(k, 3)`` on links
    ``(k,)`` ``(3, k, C)`` (None where there are none), stored once."""
    frames, of_link, homes = _frames(robot, q)
    spheres = capsules = points = None
    if body.num_spheres:
        spheres = _place(frames, of_link, homes, body.sphere_center, body.sphere_link)
    if body.num_capsules:
        both = jnp.concatenate([body.capsule_a, body.capsule_b])
        placed = _place(frames, of_link, homes, both, body.capsule_link * 2)
        nc = body.num_capsules
        capsules = jnp.stack([placed[:, :nc], placed[:, nc:]], axis=1)
    if extra is not None:
        points = _place(frames, of_link, homes, *extra)
    return _materialised((spheres, capsules, points))


class _Excess:
    """Running minimums per configuration: squared excess ``d^2 - R^2`` (collision where
    ``<= slack``) and linear excess ``d - margin`` (collision where ``<= tol``), each kept as
    rows ``(k, C)`` of one shape (the world pass over the robot's rows) and as ``(C,)``."""

    def __init__(self):
        self.parts: dict[tuple[str, tuple[int, ...]], Array] = {}

    def _add(self, tag: str, x: Array) -> None:
        if x.ndim == 2 and (tag, x.shape) not in self.parts:
            if any(key[0] == tag and len(key[1]) == 2 for key in self.parts):
                x = jnp.min(x, axis=0)  # a self group: reduced at once
        key = (tag, x.shape)
        old = self.parts.get(key)
        self.parts[key] = x if old is None else jnp.minimum(old, x)

    def add_sq(self, x: Array) -> None:
        self._add("sq", x)

    def add_lin(self, x: Array) -> None:
        self._add("lin", x)

    def reduced(self, tag: str) -> Array | None:
        """The minimum ``(C,)`` of one kind, or None."""
        out = None
        for (t, _), x in self.parts.items():
            if t != tag:
                continue
            x = jnp.min(x, axis=0) if x.ndim == 2 else x
            out = x if out is None else jnp.minimum(out, x)
        return out

    def hits(self, slack: Array, tol: Array, hit: Array) -> Array:
        """``hit`` or a squared excess ``<= slack`` or a linear one ``<= tol``, ``(C,)``."""
        sq, lin = self.reduced("sq"), self.reduced("lin")
        hit = hit if sq is None else hit | (sq <= slack)
        return hit if lin is None else hit | (lin <= tol)


def _threshold(radius: Array) -> Array:
    """``R^2`` where ``R >= 0``, else -1 (no squared distance reaches it)."""
    return jnp.where(radius >= 0, radius * radius, -1.0)


def _sphere_test(x: list[Array], r: Array, margin: Array, c, ro) -> Array:
    """Squared excess of spheres (rows ``x``, radii ``r``) over a sphere obstacle. The
    obstacle's entries (``c[i]``, ``ro``) are scalars or arrays broadcasting against ``x``."""
    d2 = (x[0] - c[0]) ** 2 + (x[1] - c[1]) ** 2 + (x[2] - c[2]) ** 2
    return d2 - _threshold(r + ro + margin)


def _capsule_test(x: list[Array], r: Array, margin: Array, a, b, ro) -> Array:
    """Squared excess over a capsule obstacle: the squared point-segment distance."""
    d = [b[i] - a[i] for i in range(3)]
    dd = d[0] * d[0] + d[1] * d[1] + d[2] * d[2]
    inv = jnp.where(dd > 0, 1.0 / jnp.where(dd > 0, dd, 1.0), 0.0)
    rel = [x[i] - a[i] for i in range(3)]
    t = jnp.clip((rel[0] * d[0] + rel[1] * d[1] + rel[2] * d[2]) * inv, 0.0, 1.0)
    d2 = (rel[0] - t * d[0]) ** 2 + (rel[1] - t * d[1]) ** 2 + (rel[2] - t * d[2]) ** 2
    return d2 - _threshold(r + ro + margin)


def _box_test(x: list[Array], r: Array, margin: Array, c, rot, h) -> Array:
    """Squared excess over a box (module docstring); ``rot[i, k]`` the rotation's entries."""
    # u_k = x . R_k - c . R_k: the rows are read directly, each e_k is used once
    big = r + margin
    shift = jnp.minimum(big, 0.0)
    out = None
    for k in range(3):
        ck = c[0] * rot[0, k] + c[1] * rot[1, k] + c[2] * rot[2, k]
        u = x[0] * rot[0, k] + x[1] * rot[1, k] + x[2] * rot[2, k] - ck
        term = jnp.maximum(jnp.abs(u) - h[k] - shift, 0.0) ** 2
        out = term if out is None else out + term
    return out - jnp.where(big >= 0, big * big, 0.0)


def _halfspace_test(x: list[Array], r: Array, margin: Array, n, o) -> Array:
    """Linear excess over a half-space ``n . x <= o``."""
    return x[0] * n[0] + x[1] * n[1] + x[2] * n[2] - o - r - margin


def _world_kinds(world: World) -> list[tuple[Any, bool, tuple[Array, ...]]]:
    """``(test, squared, arrays (m, ...))`` per non-empty obstacle kind."""
    w = world
    kinds = [
        (_sphere_test, True, (w.spheres.center, w.spheres.radius)),
        (_capsule_test, True, (w.capsules.a, w.capsules.b, w.capsules.radius)),
        (_box_test, True, (w.boxes.center, w.boxes.rotation, w.boxes.half_extents)),
        (_halfspace_test, False, (w.halfspaces.normal, w.halfspaces.offset)),
    ]
    return [kind for kind in kinds if kind[2][0].shape[0]]


def _sphere_rows_world(x: list[Array], r: Array, kinds: list, margin: Array, acc: _Excess) -> None:
    """Robot spheres (rows ``(k, C)``, radii ``(k, 1)``) against the obstacles of ``kinds``
    (``_world_kinds``)."""

    def add(out, squared):
        (acc.add_sq if squared else acc.add_lin)(out)

    for test, squared, arrays in kinds:
        m = arrays[0].shape[0]
        if m <= UNROLL:
            for j in range(m):
                add(test(x, r, margin, *(a[j] for a in arrays)), squared)
            continue
        first = test(x, r, margin, *(a[0] for a in arrays))

        def step(j, best, test=test, arrays=arrays):
            obstacle = (jax.lax.dynamic_index_in_dim(a, j, keepdims=False) for a in arrays)
            return jnp.minimum(best, test(x, r, margin, *obstacle))

        add(jax.lax.fori_loop(1, m, step, first), squared)


def _tree_min(x: Array, axis: int = 0) -> Array:
    """The minimum over ``axis`` by halving: ``min(x[:h], x[n-h:])`` with ``h = ceil(n / 2)``
    (the middle entry of an odd length taken twice), ``axis`` dropped. Elementwise minimums
    of slices fuse with their producer into one vectorised loop; XLA on CPU emits a
    ``reduce`` over a major axis as a scalar loop per output element."""
    while x.shape[axis] > 1:
        n = x.shape[axis]
        h = (n + 1) // 2
        a = jax.lax.slice_in_dim(x, 0, h, axis=axis)
        b = jax.lax.slice_in_dim(x, n - h, n, axis=axis)
        x = jnp.minimum(a, b)
    return jax.lax.squeeze(x, (axis,))


def _sphere_block_world(x: list[Array], r: Array, kinds: list, margin: Array, acc: _Excess) -> None:
    """Robot spheres (rows ``(k, C)``, radii ``(k,)``) against the obstacles of ``kinds``:
    per kind one ``(m, k, C)`` block (obstacle entries broadcast along a leading axis)
    reduced by ``_tree_min`` to ``(C,)``; point clouds as in ``_sphere_rows_world``."""
    clouds = [k for k in kinds if k[2][0].shape[0] > UNROLL]
    for test, squared, arrays in kinds:
        if arrays[0].shape[0] > UNROLL:
            continue
        # entries with the obstacle axis first and two axes to broadcast: (..., m, 1, 1)
        lead = [jnp.moveaxis(a, 0, -1)[..., None, None] for a in arrays]
        out = _tree_min(_tree_min(test(x, r[:, None], margin, *lead), 1), 0)
        (acc.add_sq if squared else acc.add_lin)(out)
    if clouds:
        _sphere_rows_world(x, r[:, None], clouds, margin, acc)


def _ss_blocks(pairs: SelfPairs) -> list[tuple[np.ndarray, np.ndarray]]:
    """Sphere-sphere self pairs as dense blocks ``(firsts, seconds)``, every pair of
    ``firsts x seconds`` a self pair and every self pair in one block: the first spheres
    with the same partners (static; the Panda's 700 pairs are two blocks, 15 x 40 and
    5 x 20)."""
    first, second = (np.asarray(a, int) for a in pairs.ss)
    partners: dict[tuple[int, ...], list[int]] = {}
    for i in np.unique(first):
        partners.setdefault(tuple(np.sort(second[first == i]).tolist()), []).append(int(i))
    return [(np.asarray(firsts), np.asarray(seconds)) for seconds, firsts in partners.items()]


def _capsule_rows_world(
    a: Array, b: Array, r: Array, world: World, margin: Array, acc: _Excess
) -> None:
    """Robot capsules (``a, b (k, C, 3)``, radii ``(k, 1)``) against every obstacle: the
    exact signed distances (``collision.distance``)."""
    w = world
    for center, radius in zip(w.spheres.center, w.spheres.radius, strict=True):
        acc.add_lin(sd.sphere_capsule(center, radius, a, b, r) - margin)
    for oa, ob, radius in zip(w.capsules.a, w.capsules.b, w.capsules.radius, strict=True):
        acc.add_lin(sd.capsule_capsule(a, b, r, oa, ob, radius) - margin)
    for c, rot, h in zip(w.boxes.center, w.boxes.rotation, w.boxes.half_extents, strict=True):
        acc.add_lin(sd.capsule_box(a, b, r, c, rot, h) - margin)
    for n, o in zip(w.halfspaces.normal, w.halfspaces.offset, strict=True):
        acc.add_lin(sd.capsule_halfspace(a, b, r, n, o) - margin)


def _excess(
    spheres: Array | None,
    s_radius: Array,
    capsules: Array | None,
    c_radius: Array,
    world: World,
    pairs: SelfPairs | None,
    margin: Array,
    sphere_kinds: list,
) -> _Excess:
    """The running minimums over the world and self pairs (rows layout, ``(k, C)``): the
    spheres against the obstacle kinds ``sphere_kinds`` (``_world_kinds``; the others are
    culled), the capsules against every obstacle, every self pair."""
    acc = _Excess()
    if spheres is not None:
        x = [spheres[i] for i in range(3)]
        _sphere_block_world(x, s_radius, sphere_kinds, margin, acc)
    if capsules is not None:
        a = jnp.moveaxis(capsules[:, 0], 0, -1)  # (nc, C, 3)
        b = jnp.moveaxis(capsules[:, 1], 0, -1)
        n_obstacles = sum(
            len(p) for p in (world.spheres, world.capsules, world.boxes, world.halfspaces)
        )
        if n_obstacles:
            _capsule_rows_world(a, b, c_radius[:, None], world, margin, acc)
    # sphere-sphere pairs in dense blocks; sphere-capsule and capsule-capsule groups below
    groups = [g for g in _self_groups(pairs) if g[0] != "ss"] if pairs is not None else []
    if pairs is not None:
        for firsts, seconds in _ss_blocks(pairs):
            xi = [_take(spheres[k], firsts)[:, None] for k in range(3)]
            xj = [_take(spheres[k], seconds)[None] for k in range(3)]
            d2 = sum((xi[k] - xj[k]) ** 2 for k in range(3))
            big = _take(s_radius, firsts)[:, None] + _take(s_radius, seconds)[None] + margin
            acc.add_sq(_tree_min(_tree_min(d2 - _threshold(big)[..., None], 1), 0))
    for kind, i, js in groups:
        if kind == "sc":
            c = jnp.stack([spheres[k, i] for k in range(3)], -1)  # (C, 3)
            acc.add_lin(
                sd.sphere_capsule(c, s_radius[i], a[js], b[js], c_radius[js][:, None]) - margin
            )
        else:
            acc.add_lin(
                sd.capsule_capsule(a[i], b[i], c_radius[i], a[js], b[js], c_radius[js][:, None])
                - margin
            )
    return acc


def _scale(spheres: Array | None, capsules: Array | None, world: World) -> Array:
    """``X`` of the module docstring per configuration ``(C,)``."""
    parts = []
    if spheres is not None:
        parts.append(jnp.max(jnp.abs(spheres), axis=(0, 1)))
    if capsules is not None:
        parts.append(jnp.max(jnp.abs(capsules), axis=(0, 1, 2)))
    out = parts[0] if len(parts) == 1 else jnp.maximum(*parts)
    leaves = [
        world.spheres.center,
        world.capsules.a,
        world.capsules.b,
        world.boxes.center,
        world.halfspaces.offset,
    ]
    for leaf in leaves:
        if leaf.size:
            out = jnp.maximum(out, jnp.max(jnp.abs(leaf)))
    return out


def collides_kernel(
    robot: Any,
    body: Body,
    pairs: SelfPairs,
    q: Array,
    world: World,
    margin: ArrayLike = 0.0,
    cull: bool = False,
) -> Verdict:
    """The pure kernel of ``collides`` (traceable, any leading batch axes of ``q``), chunk by
    chunk (``VERDICT_CHUNK`` configurations). A world with leading batch axes goes through
    ``check_kernel``. ``cull`` (static): the robot's spheres through their bounding spheres
    first (``collision.cull``, the same verdict; slower on the CPU than the blocks of every
    pair, the default)."""
    dtype = q.dtype
    batch = q.shape[:-1]
    body, world = body.astype(dtype), world.astype(dtype)
    if _world_batched(world) or math.prod(batch) == 0 or not (body.num_spheres + body.num_capsules):
        exact = check_kernel(robot, body, pairs, q, world, margin)
        return Verdict(exact.collides, exact.status)
    margin = jnp.asarray(margin, dtype)
    eps = jnp.finfo(dtype).eps
    self_pairs = pairs if pairs.link_pairs else None
    kinds = _world_kinds(world)
    # the spheres' world pass culled for the obstacle kinds written out (not point clouds)
    culled = [k for k in kinds if k[2][0].shape[0] <= UNROLL] if cull and body.num_spheres else []
    rest = [k for k in kinds if not any(k is c for c in culled)]
    if culled:
        groups = sphere_groups(body.sphere_link)
        g_center, g_radius = bounding_spheres(groups, body.sphere_center, body.sphere_radius)
    extra = (g_center, groups.link) if culled else None

    def one(q: Array) -> Verdict:
        q = q.reshape((-1, q.shape[-1]))
        valid = all_finite(q)
        q_safe = jnp.where(valid[..., None], q, jnp.zeros((), dtype))
        placed = robot.placeable(q_safe)
        spheres, capsules, centers = _place_rows(robot, body, q_safe, extra)
        tol = 16.0 * eps * (1.0 + _scale(spheres, capsules, world))
        # the tolerance enters each R as R + tol: for the squared tests that is a slack of
        # at most tol (2 R_max + tol) on d^2 - R^2
        r_max = jnp.zeros((), dtype)
        if body.num_spheres:
            r_robot = jnp.max(body.sphere_radius)
            r_world = [jnp.max(r) for r in (world.spheres.radius, world.capsules.radius) if r.size]
            r_other = functools.reduce(jnp.maximum, r_world, r_robot)
            r_max = r_robot + r_other + jnp.maximum(margin, 0.0)
        slack = tol * (2.0 * r_max + tol)
        acc = _excess(
            spheres,
            body.sphere_radius,
            capsules,
            body.capsule_radius,
            world,
            self_pairs,
            margin,
            rest,
        )
        hit = acc.hits(slack, tol, ~(valid & placed))
        if culled:
            reach = g_radius[:, None] + (jnp.sqrt(slack) + 2.0 * tol)[None, :]

            def full() -> Array:
                part = _Excess()
                x = [spheres[i] for i in range(3)]
                _sphere_rows_world(x, body.sphere_radius[:, None], culled, margin, part)
                return part.hits(slack, tol, jnp.zeros((q.shape[0],), bool))

            args = (groups, spheres, body.sphere_radius, centers, reach, margin, slack, tol)
            hit = hit | cull_world(culled, *args, full)
        status = jnp.where(hit, Status.COLLISION, Status.OK)
        status = jnp.where(~placed, Status.UNREACHABLE, status)
        status = jnp.where(~valid, Status.INVALID_INPUT, status).astype(jnp.int8)
        return Verdict(hit, status)

    flat = q.reshape((-1, q.shape[-1]))
    out = map_chunks(one, flat, flat.shape[:-1], VERDICT_CHUNK)
    return jax.tree.map(lambda x: x.reshape(batch), out)


_collides_jit = jax.jit(collides_kernel, static_argnames=("cull",))
# Fewest configurations per host-thread part (docs/performance.md)
VERDICT_MIN_PART = 2048
_collides_parts = PartsJit(
    collides_kernel, static_argnames=("cull",), batched_argnames=("q",), min_part=VERDICT_MIN_PART
)


def collides(
    robot: Any,
    q: ArrayLike,
    world: World,
    margin: float = 0.0,
    self_collision: bool = True,
) -> Verdict:
    """Per configuration ``q`` ``(..., n_joints)``: does ``robot`` touch ``world`` or itself
    (module docstring)? The verdict of ``check(robot, q, world, margin).collides`` without
    the clearance or its pair: the arguments and errors of ``check``; a ``Verdict`` with
    shapes ``(...)``. A concrete batch of at least ``2 VERDICT_MIN_PART`` configurations
    runs as one part per host thread (``jaxkin.set_num_threads``)."""
    robot, body, pairs, q, world, margin = checked_arguments(
        robot, q, world, margin, self_collision
    )
    if _world_batched(world):
        return _collides_jit(robot, body, pairs, q, world, margin)
    return _collides_parts(robot, body, pairs, q, world, margin, batch=q.shape[:-1])
