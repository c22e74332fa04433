"""Straight joint-space edges checked in rounds: a few states of every edge per call.

An edge from ``a`` along the step ``delta`` (``space.step``; its length capped so that ``S``
intervals suffice) has the states ``a + t_j delta``, ``t_j = j / S``, ``j = 0 ... S``. State 0
is where the edge starts (a node of a tree or a waypoint, known free), the others are checked
in *rounds* of ``chunk`` states per edge, coarse to fine (``rake_order``: the end, the middle,
the quarters, ...: a round is spread over the whole edge), each round one batch of the
collision kernel for every edge at once (the states of a motion checked together, vectorised
[Thomason, Kingston & Kavraki 2024]). An edge is *settled* when its answer is known; the
search advances each edge by one round per iteration of its loop (edges of different lanes
settle in different iterations), ``edge_check`` runs rounds until every edge is settled.

- ``"discrete"`` (VAMP's and OMPL's motion check): the states are at most ``1 / resolution``
  apart in joint distance, and the edge is valid when every state is free (all or nothing). A
  short edge needs fewer states: the first ``needed`` of the rake order (``needed_states``),
  those of the first halving level fine enough for its length. A state that collides settles
  the edge. Two free states may hide a thin obstacle between them.
- ``"certified"`` (conservative advancement [Schwarzer, Saha & Latombe 2005]): a state's
  clearances make the ball ``|t - t_j| < r_j`` free, ``r_j = min_r (d_r - tol) / B_r`` over
  its distances ``d_r`` (each link with geometry to the world, each self link pair), each with
  its speed bound along ``delta`` (``B_r = rows_r . |delta|``, ``bound``; ``tol``: rounding, a
  few ``eps`` times the robot's size) (``ball_radius``). The edge is good up to its *certified
  prefix*, the last known state before the first gap between the balls: every point of it
  lies in some state's free ball, so nothing slipped through. A round's states go only to the
  gaps the known balls still leave (``gap_states``: the unknown states between two known ones
  whose balls do not overlap, coarsest first), so the coarse balls alone settle an edge they
  cover (far from obstacles) and the states gather where the balls are small. Near an
  obstacle the balls shrink until states ``1 / S`` apart no longer overlap: there the edge is
  first cut to ``1.8 S r_0`` of its length (``r_0`` the ball of its first state, from the
  clearances known there), so that the extension advances as far as ``S`` states can
  certify.

``good_fraction`` gives ``t_g``, the fraction of the requested step that is good (0 or 1 in
discrete mode), and the last good state.
"""

from __future__ import annotations

import dataclasses
import functools
from collections.abc import Callable
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from jax import Array

__all__ = [
    "MODES",
    "EdgeState",
    "absorb",
    "ball_radius",
    "covered_prefix",
    "edge_check",
    "gap_states",
    "good_fraction",
    "needed_states",
    "path_edges_good",
    "rake_order",
    "round_states",
    "settled",
    "start_edges",
    "states_at",
]

MODES = ("certified", "discrete")


def ball_radius(dist: Array, placed: Array, speeds: Array, tol: Array) -> Array:
    """Per state ``(..., T)`` the free radius along the step, in units of its parameter:
    ``min_r (d_r - tol) / B_r`` over the distances ``dist (..., T, R)`` (``collider.
    clearances``: each link with geometry to the world, then each self link pair) with their
    speed bounds ``speeds (..., R)`` (``bound.speeds``, broadcast over the states); 0 where a
    state is not free (``placed`` False or a distance ``<= 0``); 2 (the whole edge) where
    nothing moves."""
    b = speeds[..., None, :]
    free = placed & jnp.all(dist > 0, -1)
    ratio = jnp.where(b > 0, jnp.maximum(dist - tol, 0.0) / jnp.where(b > 0, b, 1.0), 2.0)
    radius = jnp.min(ratio, axis=-1, initial=2.0)
    return jnp.where(free, jnp.minimum(radius, 2.0), 0.0)


def _prefix_end(t: Array, radius: Array, left: Array | None, free: Array | None) -> Array:
    """The index of the last state of the certified prefix (``covered_prefix``), -1 for none."""
    left = radius if left is None else left
    free = radius > 0 if free is None else free
    reach = jax.lax.cummax(t + radius, axis=radius.ndim - 1)
    # state j + 1 joins the covered prefix when its ball overlaps what is covered before it
    joins = (t[1:] - left[..., 1:] < reach[..., :-1]) & free[..., 1:]
    broken = ~jnp.concatenate([free[..., :1], joins], -1)
    first = jnp.where(jnp.any(broken, -1), jnp.argmax(broken, -1), t.shape[0])
    return first - 1


def covered_prefix(
    t: Array, radius: Array, left: Array | None = None, free: Array | None = None
) -> Array:
    """The certified prefix (module docstring) of states at ``t (T,)`` (increasing, from 0)
    with free radii ``radius (..., T)`` (``ball_radius``; 0: not free); ``left``: radii to the
    left where they differ (a ball cut at a boundary), ``free`` where a radius may be 0."""
    end = _prefix_end(t, radius, left, free)
    return jnp.where(end >= 0, t[jnp.maximum(end, 0)], 0.0)


def rake_order(slots: int) -> np.ndarray:
    """The states ``0 ... slots`` coarse to fine: the ends, then the midpoints of ever finer
    halvings (every state once), so that the first states are spread over the whole edge."""
    return _rake(slots)[0]


@functools.lru_cache(maxsize=64)
def _rake(slots: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``rake_order``, and per halving level the interval its states leave at most (in
    units of ``1 / slots``) and how many states (after state 0) it has reached."""
    order, seen, step = [], set(), slots
    gaps, counts = [], []
    while True:
        for j in range(0, slots + 1, max(step, 1)):
            if j not in seen:
                seen.add(j)
                order.append(j)
        gaps.append(max(step, 1))
        counts.append(len(order) - 1)
        if step <= 1:
            break
        step //= 2
    order += [j for j in range(slots + 1) if j not in seen]
    gaps.append(1)
    counts.append(slots)
    return np.asarray(order), np.asarray(gaps), np.asarray(counts)


def needed_states(slots: int, intervals: Array) -> Array:
    """States after state 0 (in the rake order) that leave gaps of at most ``1 / intervals``
    of the edge: those of the first halving level whose gap is that fine (``(...)`` int32;
    at least 1, at most ``slots``)."""
    _, gaps, counts = _rake(slots)
    fine = jnp.asarray(gaps)[None, :] * jnp.maximum(intervals, 1)[..., None] <= slots
    level = jnp.argmax(fine, axis=-1)
    return jnp.asarray(counts, jnp.int32)[jnp.where(jnp.any(fine, -1), level, len(gaps) - 1)]


@functools.lru_cache(maxsize=64)
def _round_order(slots: int, chunk: int) -> np.ndarray:
    """The rake order without state 0, padded by repeating the end state to whole rounds of
    ``chunk``: ``(rounds, chunk)``."""
    order = _rake(slots)[0][1:]
    rounds = -(-len(order) // chunk)
    pad = np.full(rounds * chunk - len(order), slots)
    return np.concatenate([order, pad]).reshape(rounds, chunk)


@jax.tree_util.register_dataclass
@dataclasses.dataclass(frozen=True)
class EdgeState:
    """What is known of ``E`` edges (leading axis ``E``).

    Attributes:
        a, delta: the start and the (certified: shortened) step ``(E, n)``.
        scale: the fraction of the requested step ``delta`` is ``(E,)`` (1 in discrete mode).
        needed: states after state 0 the edge needs ``(E,)`` (all ``S`` in certified mode).
        round: rounds done ``(E,)``.
        known: which states ``0 ... S`` are known ``(E, S + 1)``.
        value: per state, 1 free / 0 colliding (discrete), the ball radius (certified).
        speeds: the speed bounds along ``delta`` ``(E, R)`` (certified; ``R = 0`` discrete).
        clear: per state its distances ``(E, S + 1, R)`` where known (certified).
    """

    a: Array
    delta: Array
    scale: Array
    needed: Array
    round: Array
    known: Array
    value: Array
    speeds: Array
    clear: Array


def start_edges(
    a: Array,
    delta: Array,
    a_clear: Array,
    rows: Array,
    slots: int,
    mode: str,
    tol: Array,
    resolution: Array,
    space: Any,
) -> EdgeState:
    """Edges from ``a`` along ``delta`` ``(E, n)``; ``a_clear (E, R)`` the distances at ``a``
    (certified: they give state 0's ball, and shorten the edge to what ``S`` states can
    certify; discrete: unused, ``R = 0``); ``rows (R, n)`` the speed rows (``bound``)."""
    e, n = a.shape
    dtype = a.dtype
    total = slots + 1
    known = jnp.zeros((e, total), bool).at[:, 0].set(True)
    zero_round = jnp.zeros((e,), jnp.int32)
    if mode == "discrete":
        intervals = jnp.ceil(space.norm(delta) * resolution).astype(jnp.int32)
        value = jnp.ones((e, total), dtype)
        return EdgeState(
            a,
            delta,
            jnp.ones((e,), dtype),
            needed_states(slots, intervals),
            zero_round,
            known,
            value,
            jnp.zeros((e, 0), dtype),
            jnp.zeros((e, total, 0), dtype),
        )
    speeds = jnp.abs(delta) @ rows.T.astype(dtype)  # (E, R)
    placed = jnp.ones((e, 1), bool)
    r0 = ball_radius(a_clear[:, None], placed, speeds, tol)[:, 0]
    # the balls of states 1 / slots apart overlap only if they are large enough: an edge
    # starting close to an obstacle is shortened to the length its states can certify
    scale = jnp.clip(1.8 * slots * r0, 1.0 / slots, 1.0)
    speeds = speeds * scale[:, None]
    value = jnp.zeros((e, total), dtype).at[:, 0].set(jnp.minimum(r0 / scale, 2.0))
    clear = jnp.zeros((e, total, a_clear.shape[-1]), dtype).at[:, 0].set(a_clear)
    return EdgeState(
        a,
        delta * scale[:, None],
        scale,
        jnp.full((e,), slots, jnp.int32),
        zero_round,
        known,
        value,
        speeds,
        clear,
    )


def round_states(edges: EdgeState, slots: int, chunk: int, mode: str) -> tuple[Array, Array]:
    """The states of each edge's next round ``(E, chunk, n)`` and their indices ``(E,
    chunk)``: discrete, the next ``chunk`` of the rake order (a settled edge repeats its last
    round: computed, not used); certified, the gaps' states (``gap_states``)."""
    if mode != "discrete":
        j = gap_states(edges, slots, chunk)[0]
        return states_at(edges, j, slots), j
    order = jnp.asarray(_round_order(slots, chunk), jnp.int32)
    rounds = order.shape[0]
    j = order[jnp.minimum(edges.round, rounds - 1)]  # (E, chunk)
    return states_at(edges, j, slots), j


def states_at(edges: EdgeState, j: Array, slots: int) -> Array:
    """The states ``j (E, k)`` of each edge ``(E, k, n)``: ``a + (j / slots) delta``."""
    t = j.astype(edges.a.dtype) / slots
    return edges.a[:, None, :] + t[..., None] * edges.delta[:, None, :]


def absorb(
    edges: EdgeState, j: Array, result: Any, mode: str, tol: Array, keep_clear: bool
) -> EdgeState:
    """``edges`` with the round's states ``j (E, chunk)`` known: ``result`` the evaluation
    (``free (E, chunk)`` in discrete mode, ``(dist (E, chunk, R), placed (E, chunk))`` in
    certified mode); ``keep_clear``: keep each state's distances (the search's nodes)."""
    e = j.shape[0]
    rows = jnp.broadcast_to(jnp.arange(e)[:, None], j.shape)
    if mode == "discrete":
        v = result.astype(edges.value.dtype)
        clear = edges.clear
    else:
        dist, placed = result
        v = ball_radius(dist, placed, edges.speeds, tol)
        clear = edges.clear.at[rows, j].set(dist) if keep_clear else edges.clear
    return dataclasses.replace(
        edges,
        round=edges.round + 1,
        known=edges.known.at[rows, j].set(True),
        value=edges.value.at[rows, j].set(v),
        clear=clear,
    )


def settled(edges: EdgeState, slots: int, chunk: int, mode: str) -> Array:
    """``(E,)``: the edge's answer is known (discrete: a state collides, or every needed
    state is free; certified: no state is wanted, ``gap_states``)."""
    if mode != "discrete":
        return ~gap_states(edges, slots, chunk)[1]
    checked = edges.round * chunk >= edges.needed
    return checked | jnp.any(edges.known & (edges.value <= 0), -1)


def _certified_end(edges: EdgeState, slots: int) -> Array:
    """The certified prefix's last state, over the known states alone (a state not known lies
    in a gap the balls already cover, or in the open gap that ends the prefix); -1 for none."""
    t = jnp.arange(slots + 1, dtype=edges.value.dtype) / slots
    radius = jnp.where(edges.known, edges.value, 0.0)
    # each known state joins when its ball overlaps those before it
    index = jnp.arange(slots + 1, dtype=jnp.int32)
    reach = jax.lax.cummax(jnp.where(edges.known, t + radius, -jnp.inf), axis=1)
    joins = (t[1:] - radius[..., 1:] < reach[..., :-1]) & (radius[..., 1:] > 0)
    broken = edges.known & ~jnp.concatenate([radius[..., :1] > 0, joins], -1)
    first = jnp.where(jnp.any(broken, -1), jnp.argmax(broken, -1), slots + 1)
    last_known = jax.lax.cummax(jnp.where(edges.known, index, -1), axis=1)
    return jnp.where(
        first > 0, jnp.take_along_axis(last_known, first[..., None] - 1, -1)[..., 0], -1
    )


def good_fraction(edges: EdgeState, slots: int, mode: str) -> tuple[Array, Array]:
    """``(t_g (E,), end (E,))`` of settled edges: the fraction of the requested step that is
    good (discrete: 1 when no known state collides, else 0; certified: the certified prefix
    times ``scale``, ``_certified_end``) and the index of its last state (-1 for none)."""
    if mode == "discrete":
        good = ~jnp.any(edges.known & (edges.value <= 0), -1)
        return good.astype(edges.a.dtype), jnp.where(good, slots, -1)
    end = _certified_end(edges, slots)
    t = jnp.maximum(end, 0).astype(edges.a.dtype) / slots
    return jnp.where(end >= 0, t * edges.scale, 0.0), end


@functools.lru_cache(maxsize=64)
def _rake_rank(slots: int) -> np.ndarray:
    """Each state's position in the rake order ``(slots + 1,)`` (0 for the start)."""
    rank = np.empty(slots + 1, np.int32)
    rank[rake_order(slots)] = np.arange(slots + 1, dtype=np.int32)
    return rank


def gap_states(edges: EdgeState, slots: int, chunk: int) -> tuple[Array, Array]:
    """Certified mode: the next ``chunk`` states of each edge where they can still change its
    certified prefix, and whether it has any ``(E,)``. A state is wanted when it is not known,
    lies before the first known state that is not free, and lies between two known states
    (or after the last) whose balls, with every ball before, do not yet overlap (an open gap
    of the covered prefix), or is the end state; the coarsest first (the rake order). Covered
    stretches cost no states: the states go where the balls are small (near obstacles), not to
    a finer halving of the whole edge. Returns the states' indices ``(E, chunk)`` (when fewer
    are wanted the rest repeat known states: evaluated, harmless) and ``wanted (E,)``."""
    total = slots + 1
    index = jnp.arange(total, dtype=jnp.int32)
    t = index.astype(edges.value.dtype) / slots
    radius = jnp.where(edges.known, edges.value, 0.0)
    last = jax.lax.cummax(jnp.where(edges.known, index, -1), axis=1)  # known at or before
    after = jax.lax.cummin(jnp.where(edges.known, index, total), axis=1, reverse=True)
    reach = jax.lax.cummax(jnp.where(edges.known, t + radius, -jnp.inf), axis=1)
    reach_before = jnp.take_along_axis(reach, jnp.maximum(last, 0), 1)
    after_c = jnp.minimum(after, slots)
    start_after = jnp.take_along_axis(t - radius, after_c, 1)
    # a gap is closed when the balls up to its left end overlap the ball at its right end
    # (after the last known state: when they reach the end of the edge)
    closed = jnp.where(after < total, reach_before > start_after, reach_before > 1.0)
    blocked = jnp.min(jnp.where(edges.known & (edges.value <= 0), index, total), axis=1)
    # the end state is always known (the certified prefix ends at a known state)
    wanted = ~edges.known & (~closed | (index == slots)) & (index < blocked[:, None])
    rank = jnp.asarray(_rake_rank(slots))
    score = jnp.where(wanted, total - rank, -1)
    _, j = jax.lax.top_k(score, chunk)
    return j.astype(jnp.int32), jnp.any(wanted, axis=1)


def edge_check(
    evaluate: Callable[[Array], Any],
    rows: Array,
    a: Array,
    delta: Array,
    slots: int,
    chunk: int,
    mode: str,
    tol: Array,
    resolution: Array,
    space: Any,
    a_clear: Array | None = None,
) -> Array:
    """``t_g (E,)`` of edges ``a + t delta`` (``a, delta (E, n)``), module docstring: rounds of
    ``chunk`` states per edge through ``evaluate(states (E, chunk, n))`` (``free (E, chunk)``
    in discrete mode, ``(dist, placed)`` in certified mode: ``collider.clearances``) until every
    edge is settled. ``a_clear``: the distances at ``a`` (certified); evaluated when None."""
    if mode != "discrete" and a_clear is None:
        a_clear = evaluate(a[:, None, :])[0][:, 0]
    if a_clear is None:
        a_clear = jnp.zeros((a.shape[0], 0), a.dtype)
    edges = start_edges(a, delta, a_clear, rows, slots, mode, tol, resolution, space)

    def body(edges: EdgeState) -> EdgeState:
        states, j = round_states(edges, slots, chunk, mode)
        return absorb(edges, j, evaluate(states), mode, tol, keep_clear=False)

    def cond(edges: EdgeState) -> Array:
        return ~jnp.all(settled(edges, slots, chunk, mode))

    edges = jax.lax.while_loop(cond, body, edges)
    return good_fraction(edges, slots, mode)[0]


def path_edges_good(
    edge_good: Callable[[Array, Array], Array],
    space: Any,
    path: Array,
    count: Array,
    per_round: int = 4,
) -> Array:
    """Per edge of one path ``(P, n)`` (its first ``count`` waypoints) ``(P - 1,)``: good to
    its end (``edge_good(a, delta)``: ``edge_check``'s ``t_g (E,)`` of ``E = per_round``
    edges; True past the last edge), ``per_round`` edges at once."""
    p = path.shape[0]
    groups = -(-(p - 1) // per_round)
    # the waypoints padded so that every group of edges reads whole rows
    padded = jnp.concatenate(
        [path, jnp.broadcast_to(path[-1:], (groups * per_round + 1 - p, path.shape[1]))]
    )

    def body(i: Array, good: Array) -> Array:
        k = i * per_round + jnp.arange(per_round, dtype=jnp.int32)
        live = k < count - 1
        a = padded[k]
        delta = jnp.where(live[:, None], space.step(a, padded[k + 1]), 0.0)
        t_good = edge_good(a, delta)
        return jax.lax.dynamic_update_slice(good, (t_good >= 1.0) | ~live, (i * per_round,))

    good = jnp.ones((groups * per_round,), bool)
    used = jnp.maximum(count - 1 + per_round - 1, 0) // per_round
    return jax.lax.fori_loop(0, used, body, good)[: p - 1]
