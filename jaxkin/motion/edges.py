"""Straight joint-space edges checked inside the planner: the states of an edge together.

An edge from ``a`` along the step ``delta`` (``space.step``; the planner caps its length by
its range, so ``S`` intervals always suffice) has the states ``a + t_j delta``, ``t_j = j / S``.
They are checked in two stages, each one batch of the collision kernel for every lane's edge
at once (the states of a motion checked together, vectorised [Thomason, Kingston & Kavraki
2024]): first the coarse states ``t = k / C`` (``C = S / RAKE``: every ``RAKE``-th state,
spread over the whole edge), then, only for the edges the coarse states do not settle, the
others. The caller skips the second batch when no edge needs it.

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
  through. The coarse balls alone settle an edge they cover (far from obstacles).

``edge_check`` returns ``t_g``, the fraction of the edge that is good (0 or 1 in discrete
mode).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from jax import Array

from .bound import MotionBound, part_speeds

__all__ = ["MODES", "RAKE", "ball_radius", "covered_prefix", "edge_check"]

MODES = ("certified", "discrete")
RAKE = 4  # the coarse stage checks every RAKE-th state


def ball_radius(parts: tuple[Array, Array, Array], speeds: tuple[Array, Array], tol: Array) -> Array:
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


def covered_prefix(t: Array, radius: Array) -> Array:
    """The certified prefix (module docstring) of states at ``t (T,)`` (increasing, from 0)
    with free radii ``radius (..., T)`` (``ball_radius``; 0: not free)."""
    free = radius > 0
    reach = jax.lax.cummax(t + radius, axis=radius.ndim - 1)
    # state j + 1 joins the covered prefix when its ball overlaps what is covered before it
    joins = (t[1:] - radius[..., 1:] < reach[..., :-1]) & free[..., 1:]
    broken = ~jnp.concatenate([free[..., :1], joins], -1)
    first = jnp.where(jnp.any(broken, -1), jnp.argmax(broken, -1), t.shape[0])
    return jnp.where(first > 0, t[jnp.maximum(first - 1, 0)], 0.0)


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

    ``evaluate(states (W, T, n))`` returns ``collider.clearances``' triple in certified mode,
    ``(None, None, free (W, T))`` in discrete mode.
    """
    dtype = a.dtype
    coarse_j = np.arange(0, slots + 1, RAKE)
    fine_j = np.setdiff1d(np.arange(slots + 1), coarse_j)
    t_all = jnp.arange(slots + 1, dtype=dtype) / slots
    t_coarse, t_fine = t_all[coarse_j], t_all[fine_j]

    def states(t):
        return a[:, None, :] + t[:, None] * delta[:, None, :]

    if mode == "discrete":
        ok_c = jnp.all(evaluate(states(t_coarse))[2][:, 1:], -1)

        def fine(_):
            return jnp.all(evaluate(states(t_fine))[2], -1)

        ok = jax.lax.cond(jnp.any(ok_c), fine, lambda _: ok_c, None)
        return (ok_c & ok).astype(dtype)
    speeds = part_speeds(bound, delta)
    r_c = ball_radius(evaluate(states(t_coarse)), speeds, tol)
    t_c = covered_prefix(t_coarse, r_c)
    need = t_c < 1.0
    order = np.argsort(np.concatenate([coarse_j, fine_j]), kind="stable")

    def fine(_):
        r_f = ball_radius(evaluate(states(t_fine)), speeds, tol)
        return covered_prefix(t_all, jnp.concatenate([r_c, r_f], -1)[:, order])

    t_f = jax.lax.cond(jnp.any(need), fine, lambda _: t_c, None)
    return jnp.where(need, jnp.maximum(t_f, t_c), t_c)
