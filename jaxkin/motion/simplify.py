"""A found path made short and smooth, every step re-checked inside the compiled program.

1. **Shortcuts** (vertex reduction): from waypoint ``i``, the straight edges to ``i + 2 ...
   i + 1 + SHORTCUTS`` are checked at once (``edges.edge_check`` with the slots of the longest)
   and the farthest good one replaces the waypoints it skips; then from there. The edge to
   ``i + 1`` is an edge of the found path, known good. A partial shortcut counts only when it
   is good to its end (all or nothing).
2. **Spline**: the natural cubic spline through the remaining waypoints, parameterised by the
   joint distance between them (chord length; ``space.distance``), is checked at
   ``spline_states`` states: in discrete mode at most ``1 / resolution`` apart in joint distance
   (each piece gets states in proportion to the length of its Bezier control polygon, which
   bounds its arc length), in certified mode piece by piece by ``swept.spline_certified``
   (enclosures of short stretches with the curvature bound of ``bound``; for a robot with a
   sampled bound, by clearance balls with the speed bound applied to the largest ``|dq/ds|``
   of any piece, the Bezier control points of ``dq/ds`` bounding it). A piece with a bad
   state (or not certified) gets the midpoint of its chord as a new
   waypoint (the spline is pulled towards the checked polygon) and the spline is checked
   again, ``SPLINE_ROUNDS`` times; a spline still not good is dropped (``smooth`` False) and
   the polygon is returned. A piece that may leave the joint limits (a Bezier control point
   outside them) is bad as well: the waypoints are within them, the spline can overshoot.

Both stages work on fixed buffers ``(P, n)`` with a count, one problem per ``vmap`` element.
"""

from __future__ import annotations

import dataclasses
from typing import Any, NamedTuple

import jax
import jax.numpy as jnp
from jax import Array

from .._splines import hermite
from .edges import ball_radius, covered_prefix, edge_check
from .space import JointSpace

__all__ = [
    "SHORTCUTS",
    "SPLINE_ROUNDS",
    "Checker",
    "Simplified",
    "simplify_kernel",
    "spline_pieces",
    "spline_slopes",
]

SHORTCUTS = 4  # candidate shortcuts checked together from a waypoint
SPLINE_ROUNDS = 3  # midpoint insertions before the spline is given up


@jax.tree_util.register_dataclass
@dataclasses.dataclass(frozen=True)
class Simplified:
    """Per problem: ``path (P, n)`` and ``count`` (the shortcut polygon, or the spline's
    knots when ``smooth``), ``knots_s (P,)`` the chord-length parameter of the knots,
    ``slopes (P, n)`` the spline's ``dq/ds`` at the knots, ``smooth`` (bool)."""

    path: Array
    count: Array
    knots_s: Array
    slopes: Array
    smooth: Array


def kept_order(keep: Array, size: int) -> Array:
    """The indices of the ``True`` entries of ``keep`` ``(K,)`` in order, in the first slots of
    ``size`` (the rest point past them, clipped to ``K - 1``): slot ``k`` holds the first index
    whose running count of kept entries reaches ``k + 1``, a binary search (no sort, which XLA
    cannot compile into one function with the loop around it)."""
    rank = jnp.cumsum(keep.astype(jnp.int32))
    slots = jnp.arange(1, size + 1, dtype=jnp.int32)
    return jnp.minimum(jnp.searchsorted(rank, slots, side="left"), keep.shape[0] - 1)


def _compact(path: Array, keep: Array) -> tuple[Array, Array]:
    """The waypoints with ``keep`` in order at the front (the rest repeat the last kept)."""
    p = path.shape[0]
    count = jnp.sum(keep).astype(jnp.int32)
    out = path[kept_order(keep, p)]
    last = out[jnp.maximum(count - 1, 0)]
    return jnp.where((jnp.arange(p) < count)[:, None], out, last), count


class Checker(NamedTuple):
    """What checks a path: ``evaluate(states (E, T, n))`` (``free`` in discrete mode,
    ``(dist, placed)`` in certified mode: ``collider.clearances``), the joint space, the speed
    rows (``bound.speed_rows``), the mode, the rounding tolerance, the resolution (discrete
    mode), the states per edge per round (``edges``), and in certified mode where the robot
    has a curvature bound ``straight(a, delta) -> (E,)`` and ``curved(knots, s, slopes,
    count) -> (P - 1,)``, which certify straight edges and a spline's pieces (``swept``;
    None: clearance balls)."""

    evaluate: Any
    space: JointSpace
    rows: Array
    mode: str
    tol: Array
    resolution: Array
    chunk: int
    straight: Any = None
    curved: Any = None


def shortcut(check: Checker, path: Array, count: Array, slots: int) -> tuple[Array, Array]:
    """Vertex reduction (module docstring) of one path ``(P, n)`` with ``count`` waypoints.
    ``slots``: intervals for the longest candidate edge (``SHORTCUTS + 1`` path edges)."""
    evaluate, space, rows, mode, tol, resolution, chunk, straight, _ = check
    p, n = path.shape
    m = SHORTCUTS

    def body(carry):
        i, keep = carry
        j = i + 2 + jnp.arange(m, dtype=jnp.int32)
        valid_j = j <= count - 1
        a = jnp.broadcast_to(path[i], (m, n))
        b = path[jnp.minimum(j, p - 1)]
        delta = space.step(a, b)
        if straight is not None and mode != "discrete":
            good = straight(a, delta)
        else:
            t_good = edge_check(
                evaluate, rows, a, delta, slots, chunk, mode, tol, resolution, space
            )
            good = t_good >= 1.0
        good = good & valid_j
        best = jnp.where(jnp.any(good), jnp.max(jnp.where(good, j, 0)), i + 1)
        skipped = (jnp.arange(p) > i) & (jnp.arange(p) < best)
        return best.astype(jnp.int32), keep & ~skipped

    def cond(carry):
        return carry[0] < count - 1

    keep = jnp.arange(p) < count
    _, keep = jax.lax.while_loop(cond, body, (jnp.int32(0), keep))
    return _compact(path, keep)


def spline_slopes(knots: Array, s: Array, count: Array) -> Array:
    """``dq/ds`` at the knots of the natural cubic spline through ``knots (P, n)`` at
    parameters ``s (P,)``, the first ``count`` of them (de Boor's slope system, ch. IV:
    ``h_i m_{i-1} + 2 (h_{i-1} + h_i) m_i + h_{i-1} m_{i+1} = 3 (h_i d_{i-1} + h_{i-1} d_i)``,
    natural ends ``2 m_0 + m_1 = 3 d_0``); rows past ``count`` solve ``m = 0``."""
    p = knots.shape[0]
    idx = jnp.arange(p)
    h = jnp.diff(s)  # (P - 1,)
    inside = idx[:-1] < count - 1
    h = jnp.where(inside, h, 1.0)
    d = jnp.diff(knots, axis=0) / h[:, None]
    d = jnp.where(inside[:, None], d, 0.0)
    h_prev = jnp.concatenate([h[:1], h])  # h_{i-1}
    h_next = jnp.concatenate([h, h[-1:]])  # h_i
    d_prev = jnp.concatenate([d[:1], d])
    d_next = jnp.concatenate([d, d[-1:]])
    lower = h_next
    diag = 2.0 * (h_prev + h_next)
    upper = h_prev
    rhs = 3.0 * (h_next[:, None] * d_prev + h_prev[:, None] * d_next)
    first, last = idx == 0, idx == count - 1
    lower = jnp.where(first, 0.0, jnp.where(last, 1.0, lower))
    diag = jnp.where(first | last, 2.0, diag)
    upper = jnp.where(first, 1.0, jnp.where(last, 0.0, upper))
    rhs = jnp.where(first[:, None], 3.0 * d[0], rhs)
    rhs = jnp.where(last[:, None], 3.0 * d_prev, rhs)
    past = idx >= count
    lower, upper = jnp.where(past, 0.0, lower), jnp.where(past | last, 0.0, upper)
    diag, rhs = jnp.where(past, 1.0, diag), jnp.where(past[:, None], 0.0, rhs)
    slopes = solve_tridiagonal(lower, diag, upper, rhs)
    # two knots: the straight line (the system above gives it too, kept exact)
    return jnp.where(count <= 2, jnp.broadcast_to(d[0], slopes.shape), slopes)


def solve_tridiagonal(lower: Array, diag: Array, upper: Array, rhs: Array) -> Array:
    """``x (P, n)`` with ``lower_i x_{i-1} + diag_i x_i + upper_i x_{i+1} = rhs_i`` (``lower``,
    ``diag``, ``upper`` ``(P,)``, shared by the ``n`` columns of ``rhs``; ``lower_0`` and
    ``upper_{P-1}`` unused): the Thomas algorithm, one forward and one backward ``lax.scan``.
    Without pivoting: the slope system is strictly diagonally dominant by rows."""

    def forward(prev: tuple[Array, Array], row: tuple[Array, ...]) -> tuple[Any, Any]:
        c_prev, d_prev = prev
        lo, di, up, r = row
        denom = di - lo * c_prev
        c, d = up / denom, (r - lo * d_prev) / denom
        return (c, d), (c, d)

    zero = jnp.zeros((), diag.dtype)
    init = (zero, jnp.zeros_like(rhs[0]))
    _, (c, d) = jax.lax.scan(forward, init, (lower, diag, upper, rhs))

    def backward(x_next: Array, row: tuple[Array, Array]) -> tuple[Array, Array]:
        c_i, d_i = row
        x = d_i - c_i * x_next
        return x, x

    _, x = jax.lax.scan(backward, jnp.zeros_like(rhs[0]), (c, d), reverse=True)
    return x


def spline_pieces(knots, s, slopes, count) -> tuple[Array, Array, tuple[Array, ...]]:
    """Per piece of the spline through the first ``count`` knots ``(P, n)`` at parameters
    ``s (P,)`` with slopes ``dq/ds``: whether it is one ``(P - 1,)``, its length ``h`` in
    ``s`` (1 past the last knot) and its Bezier control points ``(y0, c1, c2, y1)``, each
    ``(P - 1, n)``: ``c1 = y0 + h m0 / 3``, ``c2 = y1 - h m1 / 3``."""
    p = knots.shape[0]
    live = jnp.arange(p - 1) < count - 1
    h = jnp.where(live, jnp.diff(s), 1.0)
    y0, y1 = knots[:-1], knots[1:]
    c1 = y0 + slopes[:-1] * h[:, None] / 3.0
    c2 = y1 - slopes[1:] * h[:, None] / 3.0
    return live, h, (y0, c1, c2, y1)


def _spline_states(knots, s, slopes, count, states: int, space, resolution, mode):
    """States along the spline ``(T, n)``, their parameters ``(T,)`` and whether their
    spacing meets the resolution (discrete mode) (module docstring)."""
    p, n = knots.shape
    live, h, (y0, c1, c2, y1) = spline_pieces(knots, s, slopes, count)
    poly = space.norm(c1 - y0) + space.norm(c2 - c1) + space.norm(y1 - c2)
    poly = jnp.where(live, poly, 0.0)
    want = jnp.where(live, jnp.maximum(jnp.ceil(poly * resolution), 1.0), 0.0)
    if mode != "discrete":  # states in proportion to length (the balls decide)
        total_len = jnp.maximum(jnp.sum(poly), 1e-30)
        want = jnp.where(
            live, jnp.maximum(jnp.floor(poly / total_len * (states - count)), 1.0), 0.0
        )
    enough = jnp.sum(want) + 1 <= states
    want = jnp.where(
        enough,
        want,
        jnp.where(
            live,
            jnp.maximum(jnp.floor(want * (states - count) / jnp.maximum(jnp.sum(want), 1.0)), 1.0),
            0.0,
        ),
    )
    ends = jnp.cumsum(want)  # state index where each piece ends
    k = jnp.arange(states)
    piece = jnp.clip(jnp.searchsorted(ends, k, side="right"), 0, p - 2)
    begin = ends[piece] - want[piece]
    tau = jnp.clip((k - begin) / jnp.maximum(want[piece], 1.0), 0.0, 1.0)
    total = ends[jnp.maximum(count - 2, 0)]
    tau = jnp.where(k >= total, 1.0, tau)
    piece = jnp.where(k >= total, jnp.maximum(count - 2, 0), piece)
    q, _, _ = hermite(
        y0[piece], slopes[piece], y1[piece], slopes[piece + 1], h[piece][:, None], tau[:, None]
    )
    param = s[piece] + tau * h[piece]
    return q, param, piece, enough


def within_limits(space: JointSpace, knots, s, slopes, count) -> Array:
    """Per spline piece ``(P - 1,)``: its Bezier control points, and so the piece (their
    convex hull holds it), lie within the joint box ``[lower, upper]`` (continuous joints
    have none); pieces past the last knot are."""
    live, _, control = spline_pieces(knots, s, slopes, count)
    points = jnp.stack(control)
    inside = (points >= space.lower) & (points <= space.upper) | (space.continuous > 0)
    return jnp.all(inside, axis=(0, 2)) | ~live


def spline_check(check: Checker, knots, s, slopes, count, states):
    """Per spline piece ``(P - 1,)``: bad (a state of it collides or is not covered, or it
    may leave the joint limits: ``within_limits``)."""
    evaluate, space, rows, mode, tol, resolution, _, _, curved = check
    p, n = knots.shape
    outside = ~within_limits(space, knots, s, slopes, count)
    if curved is not None and mode != "discrete":
        return ~curved(knots, s, slopes, count) | outside
    q, param, piece, enough = _spline_states(
        knots, s, slopes, count, states, space, resolution, mode
    )
    result = jax.tree.map(lambda x: x[0], evaluate(q[None]))
    if mode == "discrete":
        bad_state = ~result
    else:
        live, h, (y0, _, _, y1) = spline_pieces(knots, s, slopes, count)
        # the Bezier control points of dq/ds bound it on each piece (convex hull)
        c = jnp.stack(
            [slopes[:-1], 3.0 * (y1 - y0) / h[:, None] - slopes[:-1] - slopes[1:], slopes[1:]]
        )
        vmax = jnp.where(live[:, None], jnp.max(jnp.abs(c), axis=0), 0.0)  # (P - 1, n)
        span = jnp.maximum(s[jnp.maximum(count - 1, 0)], 1e-30)
        t = param / span
        # a state's ball may reach into the pieces beside its own: the speed bound of the
        # three, the ball cut at their outer ends
        near = jnp.maximum(
            jnp.maximum(vmax, jnp.roll(vmax, 1, 0).at[0].set(0.0)),
            jnp.roll(vmax, -1, 0).at[-1].set(0.0),
        )
        speeds = jnp.abs(near[piece] * span) @ rows.T.astype(q.dtype)  # (T, R): per state
        # each state's ball with its own speeds (ball_radius broadcasts speeds over states)
        radius = ball_radius(result[0][:, None], result[1][:, None], speeds, tol)[:, 0]
        lo = s[jnp.maximum(piece - 1, 0)] / span
        hi = s[jnp.minimum(piece + 2, count - 1)] / span
        good_to = covered_prefix(
            t, jnp.minimum(radius, hi - t), left=jnp.minimum(radius, t - lo), free=radius > 0
        )
        bad_state = t > good_to
    bad = jnp.any((piece[None, :] == jnp.arange(p - 1)[:, None]) & bad_state[None, :], axis=1)
    return bad | ~enough | outside


def _insert_midpoints(path, count, bad, space):
    """Each bad piece ``k`` (between waypoints ``k`` and ``k + 1``) gets its chord's midpoint."""
    p, n = path.shape
    add = bad & (jnp.arange(p - 1) < count - 1)
    mids = path[:-1] + 0.5 * space.step(path[:-1], path[1:])
    # interleave: waypoint k, then its midpoint if added
    both = jnp.stack([path[:-1], mids], 1).reshape(2 * (p - 1), n)
    keep = jnp.stack([jnp.arange(p - 1) < count, add], 1).reshape(-1)
    both = jnp.concatenate([both, path[-1:]])
    keep = jnp.concatenate([keep, jnp.array([False])])
    # the last waypoint (count - 1) is kept by the first column
    fits = jnp.sum(keep) <= p
    new = both[kept_order(keep, p)]
    new_count = jnp.minimum(jnp.sum(keep), p).astype(jnp.int32)
    last = new[jnp.maximum(new_count - 1, 0)]
    new = jnp.where((jnp.arange(p) < new_count)[:, None], new, last)
    return jnp.where(fits, new, path), jnp.where(fits, new_count, count), fits


def chord_parameters(path: Array, count: Array, space: JointSpace) -> Array:
    """``s_k``: the joint distance along the waypoints (constant past ``count``, then
    increasing by 1 so that it stays strictly increasing)."""
    p = path.shape[0]
    step = space.distance(path[:-1], path[1:])
    live = jnp.arange(p - 1) < count - 1
    step = jnp.where(live, jnp.maximum(step, 1e-9), 1.0)
    return jnp.concatenate([jnp.zeros((1,), path.dtype), jnp.cumsum(step)])


def simplify_kernel(
    check: Checker, path: Array, count: Array, slots: int, states: int
) -> Simplified:
    """Shortcuts, then the spline (module docstring), for one path ``(P, n)``."""
    space = check.space
    path, count = shortcut(check, path, count, slots)
    path = space.unwrap(path)

    def round_(carry):
        knots, k, done, stuck, rounds = carry
        s = chord_parameters(knots, k, space)
        slopes = spline_slopes(knots, s, k)
        bad = spline_check(check, knots, s, slopes, k, states)
        ok = ~jnp.any(bad)
        new, new_k, fits = _insert_midpoints(knots, k, bad, space)
        keep = ok | ~fits
        knots2 = jnp.where(keep, knots, new)
        k2 = jnp.where(keep, k, new_k)
        return knots2, k2, ok, ~ok & ~fits, rounds + 1

    def more(carry):
        _, _, done, stuck, rounds = carry
        return ~done & ~stuck & (rounds <= SPLINE_ROUNDS)

    start = (path, count, jnp.bool_(False), jnp.bool_(False), jnp.int32(0))
    knots, k, done, _, _ = jax.lax.while_loop(more, round_, start)
    s = chord_parameters(knots, k, space)
    slopes = spline_slopes(knots, s, k)
    return Simplified(
        jnp.where(done, knots, path),
        jnp.where(done, k, count),
        jnp.where(done, s, chord_parameters(path, count, space)),
        jnp.where(done, slopes, 0.0),
        done,
    )
