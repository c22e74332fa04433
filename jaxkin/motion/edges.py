"""Straight joint-space edges checked inside the planner: the states of an edge together.

An edge from ``a`` along the step ``delta`` (``space.step``; the planner caps its length by
its range, so ``S`` intervals always suffice) has the states ``a + t_j delta``, ``t_j = j / S``.
They are checked in chunks of ``CHUNK``, coarse to fine (``rake_order``: the ends, the
middle, the quarters, ...: the first chunk is spread over the whole edge), each chunk one batch
of the collision kernel for every lane's edge at once (the states of a motion checked
together, vectorised [Thomason, Kingston & Kavraki 2024]), until every edge is settled.

- ``"discrete"`` (VAMP's and OMPL's motion check): the states are at most ``1 / resolution``
  apart (``S >= range * resolution``) and the edge is valid when every state is free (all or
  nothing); a coarse state that collides settles it. Two free states may hide a thin obstacle
  between them.
- ``"certified"`` (conservative advancement [Schwarzer, Saha & Latombe 2005]): each state's
  clearances make the ball ``|t - t_j| < r_j`` free, ``r_j = min_p (d_p - tol) / B_p`` over
  every primitive's distance to the world and every self pair's distance, each with its own
  bound along ``delta`` (``bound.part_speeds``; ``tol``: rounding, a few ``eps`` times the
  robot's size). The edge is good up to its *certified prefix*, the last state before the first gap
  between the balls: every point of it lies in some state's free ball, so nothing slipped
  through. The coarse balls alone settle an edge they cover (far from obstacles). Near an
  obstacle the balls shrink until states ``1 / S`` apart no longer overlap: there the edge is
  first cut to ``1.8 S r_0`` of its length (``r_0`` the ball of its first state, checked alone
  first), so that the extension advances as far as ``S`` states can certify.

``edge_check`` returns ``t_g``, the fraction of the edge that is good (0 or 1 in discrete
mode).
"""

from __future__ import annotations

from collections.abc import Callable

import jax
import jax.numpy as jnp
import numpy as np
from jax import Array

from .bound import MotionBound, part_speeds

__all__ = ["CHUNK", "MODES", "ball_radius", "covered_prefix", "edge_check", "rake_order"]

MODES = ("certified", "discrete")
CHUNK = 11  # states per call of the collision kernel within an edge


def ball_radius(
    parts: tuple[Array, Array, Array], speeds: tuple[Array, Array], tol: Array
) -> Array:
    """Per state ``(..., T)`` the free radius along the step, in units of its parameter:
    ``min(min_p (d_p - tol) / B_p, min_k (d_k - tol) / B_k)`` over the primitives' world
    clearances and the self pairs' (``collider.clearances``), each with its own speed bound
    ``B`` (``bound.part_speeds``, ``(..., P)`` broadcast over the states); 0 where a state is
    not free; 2 (the whole edge) where nothing moves."""
    prims, pairs, placed = parts
    b_prims, b_pairs = (b[..., None, :] for b in speeds)
    free = placed & jnp.all(prims > 0, -1) & jnp.all(pairs > 0, -1)

    def smallest(d, b):
        ratio = jnp.where(b > 0, jnp.maximum(d - tol, 0.0) / jnp.where(b > 0, b, 1.0), 2.0)
        return jnp.min(ratio, axis=-1, initial=2.0)

    radius = jnp.minimum(smallest(prims, b_prims), smallest(pairs, b_pairs))
    return jnp.where(free, jnp.minimum(radius, 2.0), 0.0)


def covered_prefix(
    t: Array, radius: Array, left: Array | None = None, free: Array | None = None
) -> Array:
    """The certified prefix (module docstring) of states at ``t (T,)`` (increasing, from 0)
    with free radii ``radius (..., T)`` (``ball_radius``; 0: not free); ``left``: radii to the
    left where they differ (a ball cut at a boundary), ``free`` where a radius may be 0."""
    left = radius if left is None else left
    free = radius > 0 if free is None else free
    reach = jax.lax.cummax(t + radius, axis=radius.ndim - 1)
    # state j + 1 joins the covered prefix when its ball overlaps what is covered before it
    joins = (t[1:] - left[..., 1:] < reach[..., :-1]) & free[..., 1:]
    broken = ~jnp.concatenate([free[..., :1], joins], -1)
    first = jnp.where(jnp.any(broken, -1), jnp.argmax(broken, -1), t.shape[0])
    return jnp.where(first > 0, t[jnp.maximum(first - 1, 0)], 0.0)


def rake_order(slots: int) -> np.ndarray:
    """The states ``0 ... slots`` coarse to fine: the ends, then the midpoints of ever finer
    halvings (every state once), so that the first chunk is spread over the whole edge."""
    order, seen, step = [], set(), slots
    while True:
        for j in range(0, slots + 1, max(step, 1)):
            if j not in seen:
                seen.add(j)
                order.append(j)
        if step <= 1:
            break
        step //= 2
    order += [j for j in range(slots + 1) if j not in seen]
    return np.asarray(order)


def edge_check(
    evaluate: Callable[[Array], tuple[Array, Array, Array]],
    bound: MotionBound,
    a: Array,
    delta: Array,
    slots: int,
    mode: str,
    tol: Array,
) -> Array:
    """``t_g (W,)`` of edges ``a + t delta`` (``a, delta (W, n)``), module docstring.

    The ``slots + 1`` states go through ``evaluate`` in chunks of ``CHUNK`` in the rake order
    (``rake_order``), one call site in a loop that ends when every edge is settled: in
    discrete mode, a colliding state settles an edge; in certified mode, a covered edge.
    ``evaluate(states (W, CHUNK, n))`` returns ``collider.clearances``' triple in certified
    mode, ``(None, None, free)`` in discrete mode.
    """
    dtype = a.dtype
    w = a.shape[0]
    total = slots + 1
    chunk = min(CHUNK, total)
    chunks = -(-total // chunk)
    order = rake_order(slots)
    order = np.concatenate([order, np.zeros(chunks * chunk - total, int)])  # pad: state 0
    order_j = jnp.asarray(order.reshape(chunks, chunk), jnp.int32)
    t_all = jnp.arange(total, dtype=dtype) / slots
    speeds = part_speeds(bound, delta) if mode != "discrete" else None
    scale = jnp.ones((w,), dtype)
    if mode != "discrete":
        # the balls of states 1 / slots apart overlap only if they are large enough: an edge
        # starting close to an obstacle is shortened to the length its states can certify
        # (its first state's ball, of radius r0, is checked first)
        r0 = ball_radius(evaluate(a[:, None, :]), speeds, tol)[:, 0]
        scale = jnp.clip(1.8 * slots * r0, 1.0 / slots, 1.0)
        delta = delta * scale[:, None]
        speeds = tuple(x * scale[:, None] for x in speeds)

    def settled(known, value):
        if mode == "discrete":
            return jnp.any(known & (value <= 0), -1) | jnp.all(known, -1)
        return (covered_prefix(t_all, jnp.where(known, value, 0.0)) >= 1.0) | jnp.all(known, -1)

    def body(carry):
        c, known, value = carry
        j = order_j[c]  # (chunk,)
        states = a[:, None, :] + t_all[j][:, None] * delta[:, None, :]
        parts = evaluate(states)
        if mode == "discrete":
            v = jnp.where(parts[2], 1.0, 0.0).astype(dtype)
        else:
            v = ball_radius(parts, speeds, tol)
        hit = jnp.arange(total)[None, :] == j[:, None]  # (chunk, total) one-hot
        new_val = jnp.max(jnp.where(hit[None], v[:, :, None], -jnp.inf), axis=1)
        cover = jnp.any(hit, 0)[None, :]
        return c + 1, known | cover, jnp.where(cover, new_val, value)

    def cond(carry):
        c, known, value = carry
        return (c < chunks) & ~jnp.all(settled(known, value))

    init = (jnp.int32(0), jnp.zeros((w, total), bool), jnp.zeros((w, total), dtype))
    _, known, value = jax.lax.while_loop(cond, body, init)
    if mode == "discrete":
        free = known & (value > 0)
        return jnp.all(free | (jnp.arange(total) == 0), -1).astype(dtype)
    return scale * covered_prefix(t_all, jnp.where(known, value, 0.0))
