"""The rows layout of a chunk of configurations, and the loops that reduce over it.

A chunk of ``B`` configurations is laid out with the configurations as the minor axis, so
every elementwise operation is one vectorised loop across configurations:

- link frames: rotations ``(F, 3, 3, B)`` and translations ``(F, 3, B)`` (world <- frame)
  from the robot's
  ``link_frame_rows(q)`` (a chain: its joint prefixes, computed in one loop over the joints;
  by default one frame per link from ``link_poses``), each link carried by a frame
  (``of_link``) at its pose in that frame (``homes``, folded into the body's points);
- placed points ``(3, k, B)``: ``x_i = sum_m R[f, i, m] c'_m + p[f, i]`` for a point ``c'``
  in frame ``f`` (one gather of the frames and one fused loop for every point);
- radii ``(k, 1)``: the body's, shared by the chunk;
- frame bounds (``place_bounded``): per frame that carries spheres, one sphere holding them
  all, placed with them, for loops that pass over the obstacles no bound comes near
  (``loop_world``'s ``visit``, ``fold``'s ``needed``).

Every reduction over the robot's primitives, the obstacles and the self pairs is a loop
inside the program (``lax.fori_loop`` or ``lax.while_loop``), one obstacle or one chunk of
``PAIR_CHUNK`` self pairs per step, so the compiled program does not grow with the number of
links, primitives, obstacles or pairs. A step's block ``(k, B)`` is reduced over ``k`` by
halving (``tree_min``: minimums of its two halves, slices that XLA fuses with the tests into
one vectorised loop writing only ``(B,)``); ``tree_argmin`` carries the row attaining it.
"""

from __future__ import annotations

import dataclasses
import functools
import math
from collections.abc import Callable
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from jax import Array

from .._numerics import computed_once
from .body import Body
from .protocol import CollisionRobot
from .world import OBSTACLE_BUCKET

__all__ = [
    "BOUND_GROWTH",
    "bounding_spheres",
    "CAPSULE_CHUNK",
    "COMPILER_OPTIONS",
    "FrameBounds",
    "OBSTACLE_CHUNK",
    "PAIR_CHUNK",
    "Placed",
    "distinct_rows",
    "fold",
    "frames_of",
    "in_frames",
    "index_groups",
    "loop_pairs",
    "loop_world",
    "place",
    "place_bounded",
    "place_points",
    "tree_argmin",
    "tree_min",
]

# Self pairs per step of a pair loop: a step's block (PAIR_CHUNK, B) of one configuration
# fits a cache line's worth of work per pair and a chunk of 512 configurations stays in L2
PAIR_CHUNK = 256
# XLA options of every program of the checks: the CPU's older fusion emitters generate the
# loop bodies' fusions (over obstacles and pairs) 2-5x faster than the newer ones
COMPILER_OPTIONS: tuple = (("xla_cpu_use_fusion_emitters", False),)
# Obstacles of one kind per step of a world loop, written out in the step (loop_world): for
# the spheres' tests (a world's kinds come padded to multiples of it: World.bucketed); a
# capsule's exact distances (a few hundred operations each) take one
OBSTACLE_CHUNK = OBSTACLE_BUCKET
CAPSULE_CHUNK = 1
# Relative growth of a bounding sphere's radius (FrameBounds, collision.culled's groups):
# covers its rounding in any dtype
BOUND_GROWTH = 1e-5


@jax.tree_util.register_dataclass
@dataclasses.dataclass(frozen=True)
class Placed:
    """A body placed at a chunk of configurations (rows layout).

    Attributes:
        spheres: centres ``(3, S, B)``.
        sphere_radius: ``(S, 1)``.
        capsule_a, capsule_b: end points ``(3, C, B)``.
        capsule_radius: ``(C, 1)``.
    """

    spheres: Array
    sphere_radius: Array
    capsule_a: Array
    capsule_b: Array
    capsule_radius: Array

    @property
    def size(self) -> int:
        """``B``, the configurations of the chunk."""
        return max(self.spheres.shape[-1], self.capsule_a.shape[-1])

    def scale(self) -> Array:
        """``(B,)``: the largest coordinate magnitude of the placed primitives."""
        points = (self.spheres, self.capsule_a, self.capsule_b)
        # by halving: a reduce over the leading axes is a scalar loop per configuration
        parts = [-tree_min(-jnp.abs(x.reshape((-1, x.shape[-1])))) for x in points if x.shape[1]]
        return functools.reduce(jnp.maximum, parts)


Frames = tuple[Array, Array]


def frames_of(robot: CollisionRobot, q: Array) -> tuple[Frames, tuple[int, ...], Array | None]:
    """``robot.link_frame_rows(q)`` for configurations ``q`` ``(B, n)``: the frames'
    rotations ``(F, 3, 3, B)`` and translations ``(F, 3, B)`` in the dtype of ``q``, the
    frame of each link, each link's pose in it (or None)."""
    (rot, pos), of_link, homes = robot.link_frame_rows(q)
    frames = (jnp.asarray(rot, q.dtype), jnp.asarray(pos, q.dtype))
    if homes is not None:
        homes = jnp.asarray(homes, q.dtype)
    return frames, tuple(int(f) for f in of_link), homes


def place_points(
    frames: Frames, of_link: tuple[int, ...], homes: Array | None, points: Array, links: Any
) -> Array:
    """``points (k, 3)`` on ``links`` (static, ``(k,)``) placed: ``(3, k, B)``."""
    rot, pos = frames
    links = np.asarray(links, dtype=np.int64)
    if not len(links):
        return jnp.zeros((3, 0, rot.shape[-1]), rot.dtype)
    points = in_frames(homes, points.astype(rot.dtype), links)
    which = np.asarray(of_link, dtype=np.int64)[links]
    r, p = rot[which], pos[which]  # (k, 3, 3, B), (k, 3, B)
    c = points[:, :, None]  # (k, 3, 1)
    rows = [
        r[:, i, 0] * c[:, 0] + r[:, i, 1] * c[:, 1] + r[:, i, 2] * c[:, 2] + p[:, i]
        for i in range(3)
    ]
    return jnp.stack(rows)


def in_frames(homes: Array | None, points: Array, links: Any) -> Array:
    """``points (k, 3)`` on ``links`` (static, ``(k,)``) in their carrying frames'
    coordinates (``homes``: each link's pose in its frame; None: the links are the frames)."""
    if homes is None:
        return points
    home = homes[np.asarray(links, dtype=np.int64)]
    return jnp.einsum("kij,kj->ki", home[:, :3, :3], points) + home[:, :3, 3]


def bounding_spheres(centers: Array, radius: Array) -> tuple[Array, Array]:
    """Per group of spheres ``(centers (G, K, 3), radius (G, K))``, in one rigid frame (a short
    group padded by repeating a member), one sphere holding them all: ``g (G, 3)`` the middle
    of their bounding box, ``R (G,) = (1 + BOUND_GROWTH) max_i (|c_i - g| + r_i)``."""
    lo = jnp.min(centers - radius[..., None], axis=1)
    hi = jnp.max(centers + radius[..., None], axis=1)
    middle = 0.5 * (lo + hi)
    reach = jnp.max(jnp.linalg.norm(centers - middle[:, None], axis=-1) + radius, axis=1)
    return middle, reach * (1.0 + BOUND_GROWTH)


def place(robot: CollisionRobot, body: Body, q: Array) -> Placed:
    """``body`` placed at configurations ``q`` ``(B, n)`` (rows layout)."""
    return _place(robot, body, q, False)[0]


@jax.tree_util.register_dataclass
@dataclasses.dataclass(frozen=True)
class FrameBounds:
    """Per frame that carries spheres (``robot.link_frame_rows``: the spheres of the links it
    moves rigidly), one sphere holding all of them, placed at a chunk of configurations
    (``place_bounded``).

    Attributes:
        center: ``(3, G, B)`` rows: ``g``, the middle of the bounding box of the frame's
            spheres in its own coordinates, placed.
        reach: ``(G, 1)``: ``R = (1 + BOUND_GROWTH) max_i (|c_i - g| + r_i)`` over the frame's
            spheres ``(c_i, r_i)`` (a rigid motion keeps it), so every sphere lies in the ball
            ``(g, R)``: ``|c_i - g| <= R - r_i``.
        scale: ``(B,)``: the largest coordinate magnitude of the bounds, ``max_k |g_k| + R``.
    """

    center: Array
    reach: Array
    scale: Array


def place_bounded(robot: CollisionRobot, body: Body, q: Array) -> tuple[Placed, FrameBounds]:
    """``place(robot, body, q)`` and the bounds of the spheres each frame carries
    (``FrameBounds``), from one forward kinematics; ``body`` has spheres."""
    placed, bounds = _place(robot, body, q, True)
    assert bounds is not None
    return placed, bounds


def index_groups(keys: Any) -> tuple[np.ndarray, np.ndarray]:
    """Host side: the distinct ``keys (k,)`` in order of first appearance ``(G,)``, and the
    indices holding each ``(G, m)`` int32 (shorter rows repeat their last index: no change to
    a min or max over a row)."""
    keys = np.asarray(keys, np.int64)
    order = np.asarray(list(dict.fromkeys(keys.tolist())), np.int64)
    groups = [np.flatnonzero(keys == k) for k in order]
    width = max((len(g) for g in groups), default=1)
    rows = [np.concatenate([g, np.repeat(g[-1:], width - len(g))]) for g in groups]
    return order, np.asarray(rows, np.int32).reshape(len(groups), width)


def _frame_bounds(
    centers: Array, radius: Array, frame: np.ndarray
) -> tuple[Array, Array, np.ndarray]:
    """``(g (G, 3), R (G,), frames (G,))`` of the spheres ``(centers (S, 3), radius (S,))``
    in the coordinates of their carrying frames ``frame (S,)`` (static): one bound per frame
    that carries some (``FrameBounds``)."""
    frames, members = index_groups(frame)
    return (*bounding_spheres(centers[members], radius[members]), frames)


def _place(
    robot: CollisionRobot, body: Body, q: Array, bounded: bool
) -> tuple[Placed, FrameBounds | None]:
    """``place``, and when ``bounded`` the bounds of each frame's spheres placed with them."""
    frames, of_link, homes = frames_of(robot, q)
    dtype = q.dtype
    centers, links = body.sphere_center.astype(dtype), np.asarray(body.sphere_link, np.int64)
    spheres = place_points(frames, of_link, homes, centers, links)
    frame_bounds = None
    if bounded:
        frame = np.asarray(of_link, np.int64)[links]
        radius = body.sphere_radius.astype(dtype)
        middle, reach, which = _frame_bounds(in_frames(homes, centers, links), radius, frame)
        identity = tuple(range(frames[0].shape[0]))
        # stored once: fused into each coarse test, the bounds would be placed again per test
        g = computed_once(place_points(frames, identity, None, middle, which))
        magnitude = jnp.maximum(jnp.maximum(jnp.abs(g[0]), jnp.abs(g[1])), jnp.abs(g[2]))
        frame_bounds = FrameBounds(g, reach[:, None], -tree_min(-(magnitude + reach[:, None])))
    ends = jnp.concatenate([body.capsule_a, body.capsule_b])
    placed = place_points(frames, of_link, homes, ends, body.capsule_link * 2)
    nc = body.num_capsules
    return (
        Placed(
            spheres,
            body.sphere_radius.astype(dtype)[:, None],
            placed[:, :nc],
            placed[:, nc:],
            body.capsule_radius.astype(dtype)[:, None],
        ),
        frame_bounds,
    )


# ------------------------------------------------------------------ reductions


def tree_min(x: Array, axis: int = 0) -> Array:
    """The minimum over ``axis`` by halving: ``min(x[:h], x[n-h:])`` with ``h = ceil(n /
    2)`` (the middle entry of an odd length taken twice), ``axis`` dropped. Elementwise
    minimums of slices fuse with their producer into one vectorised loop; XLA on CPU emits a
    ``reduce`` over a major axis as a scalar loop per output element."""
    while x.shape[axis] > 1:
        n = x.shape[axis]
        h = (n + 1) // 2
        a = jax.lax.slice_in_dim(x, 0, h, axis=axis)
        b = jax.lax.slice_in_dim(x, n - h, n, axis=axis)
        x = jnp.minimum(a, b)
    return jax.lax.squeeze(x, (axis,))


def tree_argmin(x: Array, code: Array) -> tuple[Array, Array]:
    """``(min, code of a row attaining it)`` over axis 0 by halving (``tree_min``); ``code``
    broadcasts against ``x``. Ties go to the smallest code."""
    code = jnp.broadcast_to(code, x.shape)
    while x.shape[0] > 1:
        n = x.shape[0]
        h = (n + 1) // 2
        a, b = x[:h], x[n - h :]
        ca, cb = code[:h], code[n - h :]
        later = (b < a) | ((b == a) & (cb < ca))
        x = jnp.where(later, b, a)
        code = jnp.where(later, cb, ca)
    return x[0], code[0]


# ------------------------------------------------------------------ loops


def distinct_rows(arrays: tuple[Array, ...]) -> Array:
    """``()`` int32: the obstacles of one kind (``arrays``: their fields, ``(m, ...)``) up to
    and including the first of the trailing run of copies of the last one (``World.bucketed``
    and ``motion.collider.stack_worlds`` pad a kind so): the rows a minimum or a verdict over
    them needs. A field that is NaN differs from itself, so such a row is never dropped."""
    m = arrays[0].shape[0]
    differs = functools.reduce(
        jnp.logical_or, [jnp.any((a != a[-1:]).reshape(m, -1), axis=1) for a in arrays]
    )
    return jnp.max(jnp.where(differs, jnp.arange(m, dtype=jnp.int32) + 2, 1)).clip(max=m)


def fold(
    count: int,
    step: Callable[[Array, Any], Any],
    init: Any,
    stop: Callable[[Any], Array] | None,
    used: Array | None = None,
    needed: Callable[[Array, Any], Array] | None = None,
) -> Any:
    """``step(k, carry)`` for ``k = 0 ... count - 1``: a ``fori_loop`` (differentiable in
    reverse mode), or a ``while_loop`` that ends early, once ``stop(carry)`` is true (a
    verdict settled for the whole chunk) or after the first ``used`` steps (``()``, a traced
    count; ``count`` at most), and that passes over the ``k`` for which ``needed(k, carry)``
    is False (an inner loop of that test alone: a conditional step would cost the runtime's
    own dispatch each time)."""
    if stop is None and used is None and needed is None:
        return jax.lax.fori_loop(0, count, step, init)
    last = count if used is None else jnp.minimum(used, count)

    def skip(k: Array, carry: Any) -> Array:
        if needed is None:
            return k
        return jax.lax.while_loop(lambda j: (j < last) & ~needed(j, carry), lambda j: j + 1, k)

    def cond(state: tuple[Array, Any]) -> Array:
        k, carry = state
        return (k < last) if stop is None else (k < last) & ~stop(carry)

    def body(state: tuple[Array, Any]) -> tuple[Array, Any]:
        k, carry = state
        carry = step(k, carry)
        return skip(k + 1, carry), carry

    return jax.lax.while_loop(cond, body, (skip(jnp.int32(0), init), init))[1]


def loop_world(
    test: Callable[[tuple[Array, ...], Array], Any],
    arrays: tuple[Array, ...],
    init: Any,
    update: Callable[[Any, Any], Any],
    combine: Callable[[Any, Any], Any] = jnp.minimum,
    stop: Callable[[Any], Array] | None = None,
    chunk: int = OBSTACLE_CHUNK,
    skip_copies: bool | None = None,
    visit: Callable[[tuple[Array, ...], Any], Array] | None = None,
) -> Any:
    """Fold over the ``m`` obstacles of one kind (``arrays``: their fields, ``(m, ...)``),
    ``chunk`` obstacles per step (``fold``): each step evaluates ``test(obstacle,
    j)`` (the obstacle's fields, its index ``j``) for each of its obstacles, joins the results
    with ``combine`` and folds them into the carry with ``update(carry, joined)``. The
    step's obstacles are written out one after the other (XLA fuses their tests and their
    minimum into one loop that writes only the result; a block of a whole group broadcast
    along an axis ran 2-7x slower on the CPU), so the program holds ``chunk`` copies of the
    test whatever ``m`` (``OBSTACLE_CHUNK`` for the cheap tests of spheres, fewer for a
    capsule's). The last step's group is padded by repeating the last obstacle: a repeated
    obstacle repeats a test, never changes a minimum (and a tie keeps the earlier).

    With ``skip_copies`` (by default when there is a ``stop``) the loop takes one obstacle
    per step and ends after the ``distinct_rows``, so a world padded to a larger bucket pays
    for the obstacles it has (measured no slower per obstacle than ``chunk`` per step, in
    either CPU runtime: ``docs/performance.md``); such a loop is a ``while_loop``, which
    reverse mode cannot differentiate. ``visit(obstacle, carry)``, when given, says whether
    an obstacle needs its tests (a coarse test: ``fold``'s ``needed``, a step's obstacles
    joined by ``or``); the others are passed over."""
    m = arrays[0].shape[0]
    if not m:
        return init
    skip = stop is not None if skip_copies is None else skip_copies
    # a loop that skips copies takes one obstacle per step: it stops right after the last
    # distinct one
    group = 1 if skip else min(m, chunk)
    steps = math.ceil(m / group)
    pad = steps * group - m
    used = distinct_rows(arrays) if skip else None

    def grouped(a: Array) -> Array:
        if pad:
            a = jnp.concatenate([a, jnp.broadcast_to(a[-1:], (pad, *a.shape[1:]))])
        return a.reshape((steps, group, *a.shape[1:]))

    groups = [grouped(a) for a in arrays]

    def fields_at(k: Array) -> list[Array]:
        return [jax.lax.dynamic_index_in_dim(a, k, keepdims=False) for a in groups]

    def step(k: Array, carry: Any) -> Any:
        fields = fields_at(k)
        joined = None
        for g in range(group):
            value = test(tuple(f[g] for f in fields), k * group + g)
            joined = value if joined is None else combine(joined, value)
        return update(carry, joined)

    needed = None
    if visit is not None:

        def needed(k: Array, carry: Any) -> Array:
            fields = fields_at(k)
            return functools.reduce(
                jnp.logical_or, [visit(tuple(f[g] for f in fields), carry) for g in range(group)]
            )

    return fold(steps, step, init, stop, used, needed)


def pair_chunks(*indices: Any) -> tuple[np.ndarray, ...]:
    """Per-pair index arrays (the pairs' first and second primitives, tags) as ``(chunks,
    PAIR_CHUNK)`` arrays, the last chunk padded by repeating the last pair (a repeated pair
    repeats a test, never changes a minimum)."""
    arrays = [np.asarray(x, np.int32) for x in indices]
    count = len(arrays[0])
    chunk = min(PAIR_CHUNK, count)
    chunks = math.ceil(count / chunk)
    pad = chunks * chunk - count
    return tuple(np.concatenate([x, np.repeat(x[-1:], pad)]).reshape(chunks, chunk) for x in arrays)


def loop_pairs(
    test: Callable[[Array, Array], Array],
    first: Any,
    second: Any,
    init: Any,
    update: Callable[[Any, Array, Array], Any],
    stop: Callable[[Any], Array] | None = None,
    tags: Any = None,
) -> Any:
    """Fold ``update(carry, tags, test(i, j))`` over the pairs ``(first[p], second[p])``
    (static index tuples), ``PAIR_CHUNK`` pairs per step (``i``, ``j``, ``tags``:
    ``(PAIR_CHUNK,)`` arrays of the step's pairs; ``tags`` the pairs' own, by default their
    indices); ``stop`` as ``fold``."""
    if not len(first):
        return init
    tags = np.arange(len(first)) if tags is None else tags
    firsts, seconds, tagged = (jnp.asarray(x) for x in pair_chunks(first, second, tags))

    def step(k: Array, carry: Any) -> Any:
        return update(carry, tagged[k], test(firsts[k], seconds[k]))

    return fold(firsts.shape[0], step, init, stop)
