"""Motions certified piece by piece: enclosures of the body's motion, cut in two where they
touch (straight edges, ``edges_certified``; a cubic spline's pieces, ``spline_certified``;
any motion ``q(t)`` with a bound on its points' second derivative, ``pieces_certified``).

An edge ``q(t) = a + t delta``, ``t in [0, 1]``, is cut into ``k = min(ceil(d(a, b)
resolution), slots)`` pieces of equal length (``d`` the joint space's metric). Over a piece
``[t0, t1]`` of length ``h`` every point ``c`` of a primitive stays within::

    e = A h^2 / 8,   A = |delta|^T M |delta|   (bound.curvature_bound)

of its chord from ``c(t0)`` to ``c(t1)``: ``A`` bounds ``|c''(t)|`` along the edge, and a
curve whose second derivative is at most ``A`` strays at most ``A h^2 / 8`` from its chord
(the error of linear interpolation). So the sphere about the chord's middle with radius
``r + |c(t1) - c(t0)| / 2 + e`` holds the primitive over the whole piece (a capsule: the
capsule between its ends' middles, ``collider.piece_touches``), and where no enclosure
touches the world or another checked link, nothing touches anywhere on the piece. ``tol``
(the planner's rounding tolerance, in the robot's units) is added to every radius: the ends
are placed in the working dtype, and consecutive pieces share their end parameter exactly
(``t = i / (k 2^l)``, each piece an integer index ``i`` at level ``l``).

A piece whose enclosure touches is cut in two (its chord and its ``e`` shrink, ``e`` four
times), down to ``levels`` cuts; a piece that still touches at the last level leaves its edge
uncertified. Unlike clearance balls [Schwarzer, Saha & Latombe 2005], whose radius in ``t`` is
the clearance over the fastest point's speed, an enclosure grows with the chord each point
actually travels and is second order in ``h`` beyond it: an arm moving along an obstacle's
face, a millimetre from it, is certified by pieces of the resolution's length, where balls
need thousands of states. The bound needs a kinematic tree (``MotionBound.curvature``); a
robot with a sampled bound keeps the balls.

The pieces wait in a stack of fixed capacity (``E slots + (levels + 1) chunk``: each step
takes the top ``chunk`` pieces and puts back at most two per piece, one level deeper, so the
stack never holds more than the first pieces and ``chunk`` per level); one
``lax.while_loop`` step checks ``chunk`` pieces at once, until the stack is empty.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import jax
import jax.numpy as jnp
from jax import Array

from .._splines import hermite
from .bound import curvature_bound
from .simplify import spline_pieces

__all__ = [
    "LEVELS",
    "edges_certified",
    "pieces_certified",
    "spline_bend",
    "spline_certified",
]

# Cuts of a piece before its edge is left uncertified: a piece of 1/32 rad cut 10 times is
# 3e-5 rad long, a thousandth of a millimetre for a point a metre from its axis
LEVELS = 10
# Relative widening of the curvature bound (its rounding in the working dtype)
_WIDEN = 1e-5


def pieces_certified(
    touches: Callable[[Array, Array, Array], Array],
    at: Callable[[Array, Array], Array],
    bend: Array,
    first: Array,
    tol: Array,
    slots: int,
    chunk: int,
    levels: int = LEVELS,
) -> Array:
    """``(E,)`` True where motion ``e``, ``q = at(e, t)`` for ``t in [0, 1]`` (``e``, ``t``
    ``(C,)``), is certified free: its ``first (E,)`` pieces (at most ``slots``; 0 for a motion
    not to check, which is certified) cut in two where their enclosures touch, ``bend (E,
    P)`` bounding each primitive's ``|d2c/dt2|`` over the whole motion (module docstring).
    ``touches(qa (C, n), qb (C, n), grow (C, P))``: whether each piece's enclosure touches;
    ``chunk``: pieces checked per step."""
    e_count = first.shape[0]
    dtype = bend.dtype
    first = jnp.minimum(first, slots)  # the first pieces must tile [0, 1]
    bend = bend * (1 + _WIDEN)
    capacity = e_count * slots + (levels + 1) * chunk
    # the first pieces, every motion's in order, compacted to the stack's bottom
    edge = jnp.repeat(jnp.arange(e_count, dtype=jnp.int32), slots)
    index = jnp.tile(jnp.arange(slots, dtype=jnp.int32), e_count)
    live = index < first[edge]
    slot = jnp.where(live, jnp.cumsum(live) - 1, capacity)
    stack_edge = jnp.zeros(capacity, jnp.int32).at[slot].set(edge, mode="drop")
    stack_index = jnp.zeros(capacity, jnp.int32).at[slot].set(index, mode="drop")
    stack_level = jnp.zeros(capacity, jnp.int32)
    size = jnp.sum(live).astype(jnp.int32)
    bad = jnp.zeros(e_count, bool)

    def step(state: tuple) -> tuple:
        stack_edge, stack_index, stack_level, size, bad = state
        start = jnp.maximum(size - chunk, 0)
        at_ = start + jnp.arange(chunk, dtype=jnp.int32)
        e = stack_edge[at_]
        i = stack_index[at_]
        level = stack_level[at_]
        taken = (at_ < size) & ~bad[e]  # a motion already lost needs no more pieces
        pieces = (jnp.maximum(first[e], 1) << level).astype(dtype)  # k 2^l
        # both ends from integer indices: neighbouring pieces share their end exactly
        t0 = i.astype(dtype) / pieces
        t1 = (i + 1).astype(dtype) / pieces
        h = t1 - t0
        grow = bend[e] * (h * h / 8.0)[:, None] + tol
        hit = touches(at(e, t0), at(e, t1), grow) & taken
        deepest = level >= levels
        bad = bad.at[jnp.where(hit & deepest, e, e_count)].set(True, mode="drop")
        split = hit & ~deepest
        left = jnp.where(split, start + 2 * (jnp.cumsum(split) - 1), capacity)
        over = split & (left + 1 >= capacity)  # no room (never with the capacity above)
        bad = bad.at[jnp.where(over, e, e_count)].set(True, mode="drop")
        for offset in (0, 1):
            where = left + offset
            stack_edge = stack_edge.at[where].set(e, mode="drop")
            stack_index = stack_index.at[where].set(2 * i + offset, mode="drop")
            stack_level = stack_level.at[where].set(level + 1, mode="drop")
        size = jnp.minimum(start + 2 * jnp.sum(split).astype(jnp.int32), capacity)
        return stack_edge, stack_index, stack_level, size, bad

    def more(state: tuple) -> Array:
        return (state[3] > 0) & ~jnp.all(state[4])

    return ~jax.lax.while_loop(more, step, (stack_edge, stack_index, stack_level, size, bad))[4]


def edges_certified(
    touches: Callable[[Array, Array, Array], Array],
    curvature: Array,
    space: Any,
    a: Array,
    delta: Array,
    resolution: Array,
    tol: Array,
    slots: int,
    chunk: int,
    levels: int = LEVELS,
) -> Array:
    """``(E,)`` True where the straight edge ``a + t delta`` (``a, delta (E, n)``) is
    certified free (``pieces_certified``): first pieces at the ``resolution`` of the joint
    space's metric (at most ``slots``), ``|c''| <= |delta|^T M |delta|`` (``curvature``:
    ``MotionBound.curvature`` ``(P, n, n)``)."""
    first = jnp.clip(jnp.ceil(space.norm(delta) * resolution), 1, slots).astype(jnp.int32)
    bend = curvature_bound(curvature, delta)

    def at(e: Array, t: Array) -> Array:
        return a[e] + t[:, None] * delta[e]

    good = pieces_certified(touches, at, bend, first, tol, slots, chunk, levels)
    return good & jnp.all(jnp.isfinite(delta), axis=-1)


def spline_bend(
    speed: Array, curvature: Array, knots: Array, s: Array, slopes: Array, count: Array
) -> tuple[Array, tuple[Array, Array, Array]]:
    """Per piece of a cubic spline (``knots (P, n)`` at parameters ``s (P,)`` with ``slopes``
    ``dq/ds``, the first ``count`` knots): ``bend (P - 1, R)``, a bound of each primitive's
    ``|d2c/dtau2|`` along the piece ``q(tau) = hermite(...)``, ``tau in [0, 1]``::

        |c''| <= r . max |q''| + max |q'|^T M max |q'|

    (``r``: its ``speed`` row, ``MotionBound.prims`` ``(R, n)``, bounds ``|dc/dq_j|``; ``M``:
    ``curvature``; ``q''`` is linear in ``tau``, largest at an end, and ``q'`` quadratic,
    within its Bezier control points; zero past the last knot), and the three legs of each
    piece's control polygon ``(P - 1, n)`` each (together longer than the piece)."""
    live, h, (y0, c1, c2, y1) = spline_pieces(knots, s, slopes, count)
    m0, m1 = slopes[:-1], slopes[1:]
    # d/dtau = h d/ds: the Bezier control points of dq/dtau are 3 times the legs
    legs = (c1 - y0, c2 - c1, y1 - c2)
    velocity = 3.0 * jnp.maximum(jnp.maximum(jnp.abs(legs[0]), jnp.abs(legs[1])), jnp.abs(legs[2]))
    ends = [hermite(y0, m0, y1, m1, h[:, None], tau)[2] for tau in (0.0, 1.0)]
    accel = (h * h)[:, None] * jnp.maximum(jnp.abs(ends[0]), jnp.abs(ends[1]))
    bend = accel @ speed.T.astype(knots.dtype) + curvature_bound(curvature, velocity)
    return jnp.where(live[:, None], bend, 0.0), legs


def spline_certified(
    touches: Callable[[Array, Array, Array], Array],
    speed: Array,
    curvature: Array,
    space: Any,
    knots: Array,
    s: Array,
    slopes: Array,
    count: Array,
    resolution: Array,
    tol: Array,
    slots: int,
    chunk: int,
    levels: int = LEVELS,
) -> Array:
    """Per piece of a cubic spline ``(P - 1,)`` (``spline_bend``'s arguments), True where it
    is certified free (``pieces_certified`` with ``spline_bend``'s bound; pieces past the last
    knot are): first pieces at the ``resolution`` along its control polygon (at most
    ``slots``)."""
    live, h, (y0, _, _, y1) = spline_pieces(knots, s, slopes, count)
    m0, m1 = slopes[:-1], slopes[1:]
    bend, legs = spline_bend(speed, curvature, knots, s, slopes, count)
    polygon = sum(space.norm(leg) for leg in legs)
    first = jnp.where(live, jnp.clip(jnp.ceil(polygon * resolution), 1, slots), 0)

    def at(e: Array, t: Array) -> Array:
        return hermite(y0[e], m0[e], y1[e], m1[e], h[e][:, None], t[:, None])[0]

    good = pieces_certified(touches, at, bend, first.astype(jnp.int32), tol, slots, chunk, levels)
    finite = jnp.all(jnp.isfinite(knots[:-1]) & jnp.isfinite(knots[1:]), axis=-1)
    return good & (finite | ~live)
