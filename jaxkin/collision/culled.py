"""The verdict of a body of many spheres through groups: bounds first, spheres where needed.

A body's spheres are taken in groups of at most ``GROUP`` (the coarse level's groups,
``Body.sphere_bound``, of at most ``body.GROUP_SIZE`` primitives; a larger one, from a body
saved before, cut into runs of ``GROUP`` in index order), a short group padded by repeating
its last sphere (a repeated test never changes a minimum). Each group's bounding sphere is
computed in the program from its spheres' centres ``c`` (radii ``r``) in their carrying frame:
``g`` the middle of their bounding box, ``R = (1 + 1e-5) max (|c - g| + r)``. A chunk of
configurations (the rows layout, ``collision.rows``; ``W`` of them, the chunk padded with
settled configurations to whole vectors of blocks) is cut into blocks of ``LANES``
configurations, configuration ``b`` being lane ``b // (W / LANES)`` of block ``b % (W /
LANES)``. Then:

1. **coarse**: the groups' bounds are placed (``(3, groups, W)``) and tested, every group
   against every obstacle and every self group pair, by the fine test itself with the radius
   ``R`` widened by what the fine test tolerates beyond contact (``sqrt(slack)`` for a
   squared test, ``tol`` for a linear one) and by ``4 tol`` for the rounding of the coarse
   test. Each test is a signed distance (or its square, compared with a squared bound) of
   the sphere's centre less its radius, and a distance is 1-Lipschitz: for a sphere
   ``(c, r)`` inside the bound ``(g, R)``, ``|c - g| <= R - r``, so ``d(g) - R <= d(c) - r``
   and a sphere the fine test flags lies in a bound the coarse test flags (two groups'
   bounds likewise for a self pair);
2. **fine**: each (obstacle, group, block) or (group pair, block) unit whose block holds a
   flagged configuration not yet known to collide is visited by a loop over the set bits of
   words of 32 units (an empty word one step): it places the group's spheres at the block's
   configurations from their frames and runs ``collision.verdict``'s tests (its formulas,
   tolerances and slack), a ``(GROUP, LANES)`` or ``(GROUP, GROUP, LANES)`` block reduced by
   halving.

The world goes first; the self pairs skip the configurations it flagged. The verdict is the
dense tests' except that ``X`` in the rounding tolerance (the robot's largest coordinate
magnitude) is the groups' bound ``max |g_k| + R``, never smaller: it may flag a configuration
within that tolerance of contact the dense tests leave free, never miss one. The program holds
one copy of each test whatever the numbers of spheres, groups, obstacles and pairs.

``collision.verdict`` takes this path for a body of spheres alone with at least
``CULL_SPHERES`` spheres or ``CULL_PAIRS`` self sphere pairs, when its self sphere pairs are
whole group pairs (``groups_of``; ``SelfPairs.create`` gives every sphere pair between the
checked links, so they are). Below that the dense blocks of ``collision.verdict`` are as fast
or faster (``docs/performance.md``, "The default body's throughput").
"""

from __future__ import annotations

import dataclasses
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from jax import Array

from .._numerics import computed_once
from .body import GROUP_SIZE, Body
from .pairs import SelfPairs
from .rows import bounding_spheres, frames_of, in_frames, tree_min

__all__ = ["CULL_PAIRS", "CULL_SPHERES", "GROUP", "LANES", "Groups", "groups_of", "verdict_rows"]

# Spheres per group (the coarse level's largest): a group pair's fine test is a (GROUP,
# GROUP, LANES) block
GROUP = GROUP_SIZE
# Configurations per block: a unit costs about the same for 4, 8 or 16 lanes (its overhead),
# while a block of more lanes more often holds a flagged configuration (4 and 8 measured
# fastest, 16 1.5x slower)
LANES = 8
# Spheres, or self sphere pairs, from which the groups pay: VAMP's 59-sphere Panda (550
# pairs) ran 1.14x faster through them at 1e4 configurations but 0.78x at 32 (an edge)
CULL_SPHERES = 128
CULL_PAIRS = 4096


@dataclasses.dataclass(frozen=True)
class Groups:
    """Static groups of a body's spheres: ``members (n, GROUP)`` sphere indices, ``link
    (n,)`` their link, and the self group pairs ``first``, ``second`` ``(P,)``."""

    members: np.ndarray
    link: np.ndarray
    first: np.ndarray
    second: np.ndarray


def groups_of(body: Body, pairs: SelfPairs | None) -> Groups | None:
    """The groups of ``body`` (module docstring), or None when the dense tests serve: a body
    with capsules, with fewer than ``CULL_SPHERES`` spheres and ``CULL_PAIRS`` self sphere
    pairs, or whose self sphere pairs are not whole group pairs."""
    ss = pairs.ss if pairs is not None and pairs.link_pairs else ((), ())
    if body.num_capsules or not body.num_spheres:
        return None
    if body.num_spheres < CULL_SPHERES and len(ss[0]) < CULL_PAIRS:
        return None
    link = np.asarray(body.sphere_link, np.int64)
    bound = np.asarray(body.sphere_bound, np.int64) if body.sphere_bound else link
    members: list[np.ndarray] = []
    of_group: list[int] = []
    group = np.empty(len(link), np.int64)
    for b in np.unique(bound):
        index = np.flatnonzero(bound == b)
        for start in range(0, len(index), GROUP):
            part = index[start : start + GROUP]
            group[part] = len(members)
            members.append(np.concatenate([part, np.repeat(part[-1:], GROUP - len(part))]))
            of_group.append(int(link[part[0]]))
    size = np.bincount(group, minlength=len(members))
    i, j = np.asarray(ss[0], np.int64), np.asarray(ss[1], np.int64)
    gi, gj = group[i], group[j]
    if np.any(gi == gj):
        return None
    keys = np.unique(np.stack([np.minimum(gi, gj), np.maximum(gi, gj)], axis=1), axis=0)
    distinct = len(np.unique(np.stack([np.minimum(i, j), np.maximum(i, j)], axis=1), axis=0))
    if distinct != np.sum(size[keys[:, 0]] * size[keys[:, 1]]):
        return None  # some group pair is not checked whole
    return Groups(np.asarray(members), np.asarray(of_group), keys[:, 0], keys[:, 1])


def _threshold(radius: Array) -> Array:
    """``R^2`` where ``R >= 0``, else -1 (as ``verdict``)."""
    return jnp.where(radius >= 0, radius * radius, -1.0)


def _visit(active: Array, work: Any, hit: Array) -> Array:
    """``hit = work(k, hit)`` for each active unit ``k`` (``active`` flat), in order: the
    units as words of 32 bits, a word's set bits visited lowest first (its lowest set bit
    ``x & -x``, its index ``31 - clz``), an empty word in one step."""
    n = active.shape[0]
    count = -(-n // 32)
    bits = jnp.pad(active, (0, count * 32 - n)).reshape(count, 32).astype(jnp.uint32)
    words = jnp.sum(bits << jnp.arange(32, dtype=jnp.uint32), axis=1, dtype=jnp.uint32)

    def word(w: Array, hit: Array) -> Array:
        def cond(state: tuple[Array, Array]) -> Array:
            return state[0] != 0

        def body(state: tuple[Array, Array]) -> tuple[Array, Array]:
            bits, hit = state
            j = 31 - jax.lax.clz(bits & (~bits + 1)).astype(jnp.int32)
            return bits & (bits - 1), work(w * 32 + j, hit)

        return jax.lax.while_loop(cond, body, (words[w], hit))[1]

    return jax.lax.fori_loop(0, count, word, hit)


def _blocks(flags: Array, hit: Array, lanes: int) -> Array:
    """``(..., W / lanes)``: whether a block holds a flagged configuration not yet hit
    (configuration ``b`` is lane ``b // blocks`` of block ``b % blocks``), by halving over
    the lanes, a major axis (``rows.tree_min``)."""
    fresh = flags & ~hit
    fresh = fresh.reshape((*fresh.shape[:-1], lanes, -1))
    while fresh.shape[-2] > 1:
        h = (fresh.shape[-2] + 1) // 2
        fresh = fresh[..., :h, :] | fresh[..., fresh.shape[-2] - h :, :]
    return fresh[..., 0, :]


def _by_block(x: Array, lanes: int) -> Array:
    """Rows ``(..., W)`` as ``(..., W / lanes, lanes)``: a block's configurations
    contiguous (``_blocks``' order)."""
    return jnp.swapaxes(x.reshape((*x.shape[:-1], lanes, -1)), -1, -2)


def verdict_rows(
    robot: Any,
    body: Body,
    groups: Groups,
    q: Array,
    world: Any,
    margin: Array,
    hit: Array,
    kinds: list,
    tolerance: float,
) -> Array:
    """The verdict ``(B,)`` of configurations ``q`` ``(B, n)``: ``hit`` or any test that flags
    a collision (``verdict``'s ``_sphere_kinds`` as ``kinds``, ``tolerance`` its ``TOLERANCE``;
    module docstring)."""
    dtype = q.dtype
    eps = jnp.finfo(dtype).eps
    size = q.shape[0]
    lanes = min(LANES, size)
    # whole vectors of blocks in the rows (blocks, lanes); a ragged row of 63 blocks ran 3x slower
    step = lanes * min(32, -(-size // lanes))
    width = -(-size // step) * step
    (rot, pos), of_link, homes = frames_of(robot, q)
    if width > size:  # the last block's configurations repeated, already settled
        rot = jnp.pad(rot, [(0, 0)] * 3 + [(0, width - size)], mode="edge")
        pos = jnp.pad(pos, [(0, 0)] * 2 + [(0, width - size)], mode="edge")
        hit = jnp.pad(hit, (0, width - size), constant_values=True)
    members, link = groups.members, groups.link
    n_groups = len(link)
    # the groups' spheres in their carrying frames, and their bounds
    local = in_frames(homes, body.sphere_center.astype(dtype), body.sphere_link)
    center = local[members]  # (n, GROUP, 3)
    radius = body.sphere_radius.astype(dtype)[members]  # (n, GROUP)
    middle, reach = bounding_spheres(center, radius)
    frame = np.asarray(of_link, np.int64)[link]  # (n,)
    r, p = rot[frame], pos[frame]  # (n, 3, 3, W), (n, 3, W)
    placed = [
        r[:, i, 0] * middle[:, 0, None]
        + r[:, i, 1] * middle[:, 1, None]
        + r[:, i, 2] * middle[:, 2, None]
        + p[:, i]
        for i in range(3)
    ]  # 3 x (n, W)
    # stored once: fused into each reader, every group pair's test would place both again
    placed = list(computed_once(jnp.stack(placed)))
    scale = -tree_min(-(jnp.maximum(jnp.maximum(*[jnp.abs(x) for x in placed[:2]]),
                                    jnp.abs(placed[2])) + reach[:, None]))  # fmt: skip
    r_max = jnp.max(body.sphere_radius.astype(dtype))
    margin_plus = jnp.maximum(margin, 0.0)
    frame_of = jnp.asarray(frame, jnp.int32)
    n_blocks = width // lanes
    rot_blocks, pos_blocks = _by_block(rot, lanes), _by_block(pos, lanes)

    def spheres_at(g: Array, block: Array) -> list[Array]:
        """Group ``g``'s spheres placed at block ``block``'s configurations: 3 x (GROUP,
        LANES)."""
        f, block, o = frame_of[g], block.astype(jnp.int32), jnp.int32(0)
        rf = jax.lax.dynamic_slice(rot_blocks, (f, o, o, block, o), (1, 3, 3, 1, lanes))[0, :, :, 0]
        pf = jax.lax.dynamic_slice(pos_blocks, (f, o, block, o), (1, 3, 1, lanes))[0, :, 0]
        c = jax.lax.dynamic_index_in_dim(center, g, keepdims=False)  # (GROUP, 3)
        return [
            rf[i, 0] * c[:, 0, None] + rf[i, 1] * c[:, 1, None] + rf[i, 2] * c[:, 2, None]
            + pf[i]
            for i in range(3)
        ]  # fmt: skip

    def lanes_of(x: Array, block: Array) -> Array:
        """Block ``block``'s lanes of rows ``x`` ``(blocks, lanes)`` (``_by_block``)."""
        return jax.lax.dynamic_index_in_dim(x, block, keepdims=False)

    def hit_block(hit: Array, block: Array, flagged: Array) -> Array:
        """``hit`` ``(blocks, lanes)`` with block ``block``'s ``flagged`` lanes set."""
        old = lanes_of(hit, block)
        return jax.lax.dynamic_update_index_in_dim(hit, old | flagged, block, 0)

    def visit(active: Array, work: Any, hit: Array) -> Array:
        """``_visit`` on ``hit`` in rows ``(W,)``, carried by block."""
        carried = _visit(active, work, _by_block(hit, lanes))
        return jnp.swapaxes(carried, 0, 1).reshape(-1)

    scale_blocks = _by_block(scale, lanes)

    # ---- the world: per kind, (obstacle, group, block) units
    for test, squared, arrays, scale_of in kinds:
        m = arrays[0].shape[0]
        obstacle_scale, obstacle_radius = jax.vmap(
            lambda o, scale_of=scale_of: tuple(jnp.asarray(v, dtype) for v in scale_of(o))
        )(arrays)  # (m,), (m,)

        def fine_bound(tol, radius, squared=squared):
            return tol * (2.0 * (r_max + radius + margin_plus) + tol) if squared else tol

        tol = tolerance * eps * (1.0 + jnp.maximum(scale[None], obstacle_scale[:, None]))
        bound = fine_bound(tol, obstacle_radius[:, None])  # (m, W)
        widen = (jnp.sqrt(bound) if squared else bound) + 4.0 * tol  # (m, W)

        def coarse(obstacle, widen, test=test):
            return test(placed, reach[:, None] + widen, margin, *obstacle) <= 0.0

        # one obstacle per step: all of them at once (a vmap) ran 1.12x slower in all
        active = jax.lax.map(
            lambda a, hit=hit: _blocks(coarse(a[:-1], a[-1]), hit, lanes), (*arrays, widen)
        ).reshape(-1)  # (m * n * n_blocks,)

        def work(k, hit, test=test, arrays=arrays, scale_of=scale_of, fine_bound=fine_bound):
            o, rest = k // (n_groups * n_blocks), k % (n_groups * n_blocks)
            g, block = rest // n_blocks, rest % n_blocks
            obstacle = [jax.lax.dynamic_index_in_dim(a, o, keepdims=False) for a in arrays]
            o_scale, o_radius = scale_of(obstacle)
            tol = tolerance * eps * (1.0 + jnp.maximum(lanes_of(scale_blocks, block), o_scale))
            x = spheres_at(g, block)
            r = jax.lax.dynamic_index_in_dim(radius, g, keepdims=False)[:, None]
            excess = test(x, r, margin, *obstacle) - fine_bound(tol, o_radius)
            return hit_block(hit, block, tree_min(excess) <= 0.0)

        if m:
            hit = visit(active, work, hit)

    # ---- the self pairs: (group pair, block) units
    if len(groups.first):
        first, second = groups.first, groups.second
        tol = tolerance * eps * (1.0 + scale)
        slack = tol * (2.0 * (2.0 * r_max + margin_plus) + tol)  # (W,)
        widen = jnp.sqrt(slack) + 4.0 * tol
        d2 = sum((placed[k][first] - placed[k][second]) ** 2 for k in range(3))
        limit = reach[first, None] + reach[second, None] + margin + widen
        flags = d2 <= _threshold(limit)  # (P, W)
        active = _blocks(flags, hit, lanes).reshape(-1)
        first_of, second_of = jnp.asarray(first, jnp.int32), jnp.asarray(second, jnp.int32)
        slack_blocks = _by_block(slack, lanes)

        def pair_work(k, hit):
            pair, block = k // n_blocks, k % n_blocks
            a, b = first_of[pair], second_of[pair]
            xa, xb = spheres_at(a, block), spheres_at(b, block)
            ra = jax.lax.dynamic_index_in_dim(radius, a, keepdims=False)
            rb = jax.lax.dynamic_index_in_dim(radius, b, keepdims=False)
            d2 = sum((xa[k][:, None] - xb[k][None]) ** 2 for k in range(3))  # (G, G, L)
            excess = d2 - _threshold(ra[:, None, None] + rb[None, :, None] + margin)
            flagged = tree_min(excess.reshape((-1, lanes))) <= lanes_of(slack_blocks, block)
            return hit_block(hit, block, flagged)

        hit = visit(active, pair_work, hit)
    return hit[:size]
