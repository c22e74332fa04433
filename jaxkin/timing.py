"""Time-optimal retiming of N joint paths under velocity and acceleration limits (batched TOPP).

Given a geometric joint path ``q(s)`` (``s`` the path parameter, ``q'`` and ``q''`` its
derivatives with respect to ``s``), find the fastest timing ``s(t)`` that keeps every joint
within ``|q_dot_j| <= v_max_j`` and ``|q_ddot_j| <= a_max_j``. With ``x = s_dot^2`` and
``u = s_ddot``, the joint rates are linear in ``(u, x)`` [Pham & Pham 2018]::

    q_dot  = q'(s) s_dot                 ->  x <= min_j (v_max_j / |q'_j(s)|)^2
    q_ddot = q'(s) u + q''(s) x          ->  -a_max_j <= q'_j u + q''_j x <= a_max_j

On a grid ``s_0 < ... < s_M-1`` with constant ``u_i`` on each interval, ``x_{i+1} = x_i +
2 (s_{i+1} - s_i) u_i``. TOPP-RA [Pham & Pham 2018] runs two passes:

1. **backward**: the controllable sets ``K_i = [lo_i, hi_i]`` of path speeds squared from which
   the end speed can be reached, from ``K_M-1 = {x_end}`` down to ``K_0``; each step
   is a two-variable LP in ``(u, x)`` (maximise and minimise ``x``);
2. **forward**: from ``x_0 = x_start`` take the largest ``u_i`` that keeps ``x_{i+1}`` in
   ``K_{i+1}`` (greedy).

Every constraint of a stage is a *slab* ``lo <= p u + r x <= hi`` with ``p >= 0`` (a joint's
acceleration limit; the next controllable set is the slab ``K_lo <= 2 delta u + x <= K_hi``).
The LPs are solved exactly in closed form by eliminating ``u`` (Fourier-Motzkin): two slabs
``j, k`` leave ``D x <= p_k hi_j - p_j lo_k`` and ``-D x <= p_j hi_k - p_k lo_j`` with ``D =
p_k r_j - p_j r_k``, and the projection of the stage's polygon on the ``x`` axis is the
interval those half-lines (and the velocity bound ``0 <= x <= x_max``) leave. The pairs among
the joints' slabs do not depend on the passes and are computed for every stage at once; only
the pairs with the controllable-set slab run inside the ``lax.scan``. Candidates are batched
with ``vmap``, so N paths are timed in one compiled call.

The acceleration limits hold at both ends of each interval with that interval's ``u``
(``scheme="interpolation"``, toppra's default [Pham & Pham 2018]) or at its start
only (``"collocation"``). The retimed trajectory is ``s(t)`` with constant ``u_i`` per interval
(interval durations ``2 delta_i / (sqrt(x_i) + sqrt(x_{i+1}))``), and between grid points the
path is the cubic Hermite interpolant of ``q`` and ``q'`` at the interval's ends (exact for a
path built by ``path_from_waypoints``). Limits are enforced on the grid; between grid points
accelerations, and speeds with ``speed_bound="grid"``, hold up to the grid's resolution
(``docs/timing.md`` gives measured excesses), while ``speed_bound="interval"`` bounds each
grid point's speed by the peak ``|q'_j|`` of the intervals beside it, so that the speeds hold
everywhere.

Statuses per candidate: ``OK``; ``INVALID_INPUT`` (NaN or inf in the path or the limits);
``UNTIMEABLE`` (no timing within the limits on this grid: a joint that must move has a zero
velocity or acceleration limit, or no acceleration limit (``inf``: its speed could change
within one grid interval, and with no speed limit either it would move in no time), the start
or end speed is not reachable, or the speed falls to zero at two neighbouring grid points, a
grid too coarse for a sharp bend).
Failed candidates get finite placeholders: zero times, speeds and duration.
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

from . import _splines, _validate
from ._execute import kernel
from .jet import Jet
from .result import SolverResult
from .status import STATUS_DTYPE, Status

__all__ = [
    "JointPath",
    "RetimedTrajectory",
    "Timing",
    "best",
    "path_from_waypoints",
    "retime",
    "sample",
]

SCHEMES = ("interpolation", "collocation")
SPEED_BOUNDS = ("grid", "interval")


@jax.tree_util.register_dataclass
@dataclasses.dataclass(frozen=True)
class JointPath:
    """A geometric joint path sampled on a grid of its parameter ``s`` (no time yet).

    Attributes:
        s: grid of the path parameter, shape ``(..., M)``, strictly increasing, ``M >= 2``.
        q: joint positions on the grid, shape ``(..., M, n)``.
        dq: ``dq/ds`` on the grid, shape ``(..., M, n)``.
        ddq: ``d2q/ds2`` on the grid, shape ``(..., M, n)``.
    """

    s: Array
    q: Array
    dq: Array
    ddq: Array

    @property
    def batch_shape(self) -> tuple[int, ...]:
        return tuple(self.q.shape[:-2])


@jax.tree_util.register_dataclass
@dataclasses.dataclass(frozen=True)
class Timing(SolverResult):
    """The time-optimal timing of a batch of paths (``retime``).

    Attributes:
        duration: minimum duration, shape ``(...)`` (time unit of the limits; 0 where failed).
        status: ``int8`` codes of ``jaxkin.Status``, shape ``(...)``: ``OK``,
            ``INVALID_INPUT`` or ``UNTIMEABLE``.
        t: time at each grid point, shape ``(..., M)``, ``t[..., 0] = 0``.
        speed: path speed ``s_dot`` at each grid point, shape ``(..., M)``.
        acceleration: path acceleration ``s_ddot``, constant on each interval, shape
            ``(..., M - 1)``.
    """

    duration: Array
    status: Array
    t: Array
    speed: Array
    acceleration: Array


@jax.tree_util.register_dataclass
@dataclasses.dataclass(frozen=True)
class RetimedTrajectory:
    """A retimed batch sampled at a fixed control period (``sample``).

    Every candidate has the same number ``T`` of samples; sample ``k`` is at time
    ``k * period``. Candidate ``c`` is valid for its first ``count[c]`` samples (``valid``
    says the same per sample); the samples past its end hold its last position at rest, and a
    failed candidate holds its first position at rest with ``count = 0``.

    Attributes:
        t: sample times, shape ``(T,)``.
        q: Jet of joint positions, velocities and accelerations, shape ``(..., T, n)``.
        valid: True for the samples within the candidate's duration, shape ``(..., T)``.
        count: number of valid samples, shape ``(...)``, ``int32``.
    """

    t: Array
    q: Jet
    valid: Array
    count: Array


# --------------------------------------------------------------------------------------------
# Paths


# The cubic Hermite interpolant of the paths, shared with ``jaxkin.paths`` (NumPy or JAX).
_hermite = _splines.hermite


def _spline_slopes(knots: Array, end: str) -> Array:
    """Slopes at the knots of the cubic spline through ``knots`` ``(..., K, n)`` at ``s = k``.

    The tridiagonal system of ``jaxkin._splines`` with unit knot spacing: ``m_{i-1} + 4 m_i +
    m_{i+1} = 3 (y_{i+1} - y_{i-1})``, closed by ``m_0 + 2 m_1 = (5 d_0 + d_1) / 2`` (and its
    mirror) for not-a-knot, ``2 m_0 + m_1 = 3 d_0`` for natural ends (``d_i = y_{i+1} - y_i``).
    """
    count = knots.shape[-2]
    d = jnp.diff(knots, axis=-2)
    if count == 2:  # the straight line
        return jnp.concatenate([d, d], -2)
    if count == 3 and end == "not-a-knot":  # the parabola
        first, second = d[..., :1, :], d[..., 1:, :]
        bend = 0.5 * (second - first)
        return jnp.concatenate([first - bend, first + bend, second + bend], -2)
    one = jnp.ones(count, knots.dtype)
    lower, diag, upper = one.at[0].set(0.0), 4.0 * one, one.at[-1].set(0.0)
    if end == "natural":
        diag = diag.at[0].set(2.0).at[-1].set(2.0)
        first, last = 3.0 * d[..., :1, :], 3.0 * d[..., -1:, :]
    else:
        diag = diag.at[0].set(1.0).at[-1].set(1.0)
        upper, lower = upper.at[0].set(2.0), lower.at[-1].set(2.0)
        first = 0.5 * (5.0 * d[..., :1, :] + d[..., 1:2, :])
        last = 0.5 * (d[..., -2:-1, :] + 5.0 * d[..., -1:, :])
    rhs = jnp.concatenate([first, 3.0 * (d[..., :-1, :] + d[..., 1:, :]), last], -2)
    batch = knots.shape[:-2]
    lower, diag, upper = (jnp.broadcast_to(x, (*batch, count)) for x in (lower, diag, upper))
    return jax.lax.linalg.tridiagonal_solve(lower, diag, upper, rhs)


@kernel(static=("subdivisions", "end"))
def _spline_path(knots: Array, subdivisions: int, end: str) -> JointPath:
    """The spline through ``knots`` (``(..., K, n)`` at ``s = 0..K-1``), sampled
    ``subdivisions`` times per segment."""
    count = knots.shape[-2]
    slopes = _spline_slopes(knots, end)
    fractions = jnp.arange(subdivisions, dtype=knots.dtype) / subdivisions
    tau = jnp.concatenate([jnp.tile(fractions, count - 1), jnp.ones((1,), knots.dtype)])
    segment = np.concatenate([np.repeat(np.arange(count - 1), subdivisions), [count - 2]])
    y0, y1 = knots[..., segment, :], knots[..., segment + 1, :]
    m0, m1 = slopes[..., segment, :], slopes[..., segment + 1, :]
    q, dq, ddq = _hermite(y0, m0, y1, m1, 1.0, tau[:, None])
    s = jnp.broadcast_to(segment.astype(knots.dtype) + tau, q.shape[:-1])
    return JointPath(s, q, dq, ddq)


def path_from_waypoints(
    waypoints: ArrayLike, subdivisions: int = 1, end: str = "not-a-knot"
) -> JointPath:
    """The cubic spline through joint waypoints, as a ``JointPath`` to retime.

    Waypoint ``k`` sits at ``s = k`` (``k = 0..K-1``); each joint is an interpolating cubic
    spline in ``s`` (``end`` condition as in SciPy's ``CubicSpline`` and ``jaxkin._splines``:
    ``"not-a-knot"`` or ``"natural"``), sampled ``subdivisions`` times per segment, so the grid
    has ``M = (K - 1) * subdivisions + 1`` points. A finer grid enforces the limits more
    densely (and costs proportionally more). One compiled call; jit-able.

    Args:
        waypoints: shape ``(..., K, n)``, ``K >= 2``.
        subdivisions: grid points per spline segment, a positive integer.
        end: the spline's end condition.

    Raises:
        ValueError: a bad shape, a non-finite waypoint (checked when concrete), or a bad
            ``subdivisions`` or ``end``.
    """
    subdivisions = _validate.count(subdivisions, "subdivisions")
    _validate.choice(end, "end", _splines.END_CONDITIONS)
    arr = waypoints if isinstance(waypoints, jax.Array) else jnp.asarray(waypoints)
    if arr.ndim < 2 or arr.shape[-2] < 2 or arr.shape[-1] < 1:
        raise ValueError(
            f"waypoints: expected shape (..., K, n) with K >= 2 waypoints, got {arr.shape}"
        )
    if not jnp.issubdtype(arr.dtype, jnp.inexact):
        arr = arr.astype(jnp.result_type(float))
    if _validate.is_concrete(arr) and not np.all(np.isfinite(np.asarray(arr))):
        raise ValueError("waypoints must be finite")
    return _spline_path(arr, subdivisions, end)


# --------------------------------------------------------------------------------------------
# The two passes for one candidate


@jax.tree_util.register_dataclass
@dataclasses.dataclass(frozen=True)
class _Slabs:
    """Constraints ``lo <= p u + r x <= hi`` of every stage, ``p >= 0``; shape ``(M - 1, m)``."""

    p: Array
    r: Array
    lo: Array
    hi: Array


def _slabs(p: Array, r: Array, bound: Array) -> _Slabs:
    """Joint acceleration slabs ``-bound <= p u + r x <= bound`` with ``p`` made non-negative."""
    sign = jnp.where(p < 0, -1.0, 1.0).astype(p.dtype)
    bound = jnp.broadcast_to(bound, p.shape)
    return _Slabs(sign * p, sign * r, -bound, bound)


def _pair_bounds(a: _Slabs, b: _Slabs) -> tuple[Array, Array]:
    """Half-lines ``alpha x <= beta`` left by eliminating ``u`` from slabs ``a`` and ``b``
    (broadcast against each other): two per pair, stacked on a new last axis."""
    d = b.p * a.r - a.p * b.r
    alpha = jnp.stack(jnp.broadcast_arrays(d, -d), -1)
    beta = jnp.stack(jnp.broadcast_arrays(b.p * a.hi - a.p * b.lo, a.p * b.hi - b.p * a.lo), -1)
    return alpha, beta


def _upper_bound(slabs: _Slabs) -> Array:
    """The largest ``x`` that the slabs of each stage leave (``(..., m)`` -> ``(...)``), when
    ``lo <= 0 <= hi``: the smallest ``beta / alpha > 0`` over ordered pairs ``(j, k)``, whose
    first half-line of ``_pair_bounds`` covers both half-lines of every unordered pair."""
    pj, rj, hj = slabs.p[..., :, None], slabs.r[..., :, None], slabs.hi[..., :, None]
    pk, rk, lk = slabs.p[..., None, :], slabs.r[..., None, :], slabs.lo[..., None, :]
    alpha = pk * rj - pj * rk
    beta = pk * hj - pj * lk
    positive = alpha > 0
    ratio = beta / jnp.where(positive, alpha, 1.0)
    return jnp.min(jnp.where(positive, ratio, jnp.inf), axis=(-2, -1), initial=jnp.inf)


def _interval(alpha: Array, beta: Array, axes: tuple[int, ...]) -> tuple[Array, Array, Array]:
    """The interval ``[lo, hi]`` of ``x`` with every ``alpha x <= beta`` (over ``axes``), and
    whether a half-line with ``alpha = 0`` excludes every ``x``."""
    safe = jnp.where(alpha == 0, 1.0, alpha)
    ratio = beta / safe
    hi = jnp.min(jnp.where(alpha > 0, ratio, jnp.inf), axis=axes, initial=jnp.inf)
    lo = jnp.max(jnp.where(alpha < 0, ratio, -jnp.inf), axis=axes, initial=-jnp.inf)
    empty = jnp.any((alpha == 0) & (beta < 0), axis=axes)
    return lo, hi, empty


@jax.tree_util.register_dataclass
@dataclasses.dataclass(frozen=True)
class _Controllable:
    """Backward-pass carry: the controllable set ``[lo, hi]`` of the next stage, and whether
    a stage so far was empty."""

    lo: Array
    hi: Array
    empty: Array


def _peak_slope(q: Array, dq: Array, s: Array) -> Array:
    """``max |dq/ds|`` of each joint over each interval of the Hermite path, ``(M - 1, n)``.

    ``dq/ds`` is a quadratic in ``tau``: its extreme is at an end or at the vertex
    ``tau* = -B / (2 A)`` when that lies inside.
    """
    h = (s[1:] - s[:-1])[:, None]
    y0, y1, m0, m1 = q[:-1], q[1:], dq[:-1], dq[1:]
    chord = 6.0 * (y0 - y1) / h
    a = chord + 3.0 * m0 + 3.0 * m1
    b = -chord - 4.0 * m0 - 2.0 * m1
    vertex = jnp.clip(-b / (2.0 * jnp.where(a == 0, 1.0, a)), 0.0, 1.0)
    vertex = jnp.where(a == 0, 0.0, vertex)
    _, inside, _ = _hermite(y0, m0, y1, m1, h, vertex)
    return jnp.maximum(jnp.maximum(jnp.abs(m0), jnp.abs(m1)), jnp.abs(inside))


def _time_one(
    s: Array,
    q: Array,
    dq: Array,
    ddq: Array,
    v_max: Array,
    a_max: Array,
    x_start: Array,
    x_end: Array,
    scheme: str,
    speed_bound: str,
) -> tuple[Array, Array, Array, Array, Array]:
    """TOPP-RA for one path: ``s (M,)``, ``q, dq, ddq (M, n)``, limits ``(n,)``, speeds
    squared.

    Returns ``(duration, status, t (M,), speed (M,), acceleration (M - 1,))``.
    """
    dtype = dq.dtype
    eps = jnp.finfo(dtype).eps
    # A finite stand-in for "no bound": products of it with path derivatives stay finite.
    big = float(jnp.finfo(dtype).max) ** 0.25
    finite = (
        jnp.all(jnp.isfinite(s))
        & jnp.all(jnp.isfinite(q))
        & jnp.all(jnp.isfinite(dq))
        & jnp.all(jnp.isfinite(ddq))
        & ~jnp.any(jnp.isnan(v_max))
        & ~jnp.any(jnp.isnan(a_max))
    )
    # A joint that moves with no acceleration limit could change its speed within one grid
    # interval (and, with no speed limit either, move in no time): no time-optimal timing.
    moves = jnp.any((q != q[:1]) | (dq != 0), axis=0)
    unbounded = jnp.any(moves & jnp.isinf(a_max))
    s = jnp.where(finite, s, jnp.arange(s.shape[0], dtype=dtype))
    q = jnp.where(finite, q, 0.0)
    dq = jnp.where(finite, dq, 0.0)
    ddq = jnp.where(finite, ddq, 0.0)
    v_max = jnp.minimum(jnp.where(finite, v_max, 1.0), big)
    a_max = jnp.minimum(jnp.where(finite, a_max, 1.0), big)
    delta = jnp.diff(s)  # (M-1,)

    # Velocity bound per grid point: x <= (v_max / |q'|)^2; joints that do not move are free.
    # With speed_bound="interval", |q'| is the peak over the adjacent intervals: x is linear
    # in s on an interval, so the speed limits then hold all along it.
    slope = dq
    if speed_bound == "interval":
        peak = _peak_slope(q, dq, s)
        slope = jnp.concatenate([peak[:1], jnp.maximum(peak[:-1], peak[1:]), peak[-1:]])
    speed_sq = slope * slope
    moving = speed_sq > 0
    ratio = jnp.where(moving, v_max * v_max / jnp.where(moving, speed_sq, 1.0), big)
    x_max = jnp.minimum(jnp.min(ratio, axis=-1), big)  # (M,)

    slabs = _slabs(dq[:-1], ddq[:-1], a_max)
    if scheme == "interpolation":
        # The same u at the interval's end, where x_{i+1} = x + 2 delta u.
        ahead = _slabs(dq[1:] + 2.0 * delta[:, None] * ddq[1:], ddq[1:], a_max)
        slabs = jax.tree.map(lambda a, b: jnp.concatenate([a, b], -1), slabs, ahead)
    # Every joint slab holds at x = u = 0, so the stage's own set is [0, fixed_hi].
    fixed_hi = jnp.minimum(_upper_bound(slabs), x_max[:-1])

    def next_set_slab(lo: Array, hi: Array, d: Array) -> _Slabs:
        one = jnp.ones((1,), dtype)
        return _Slabs(2.0 * d * one, one, lo * one, hi * one)

    def backward(carry: _Controllable, stage: tuple) -> tuple[_Controllable, tuple]:
        joint, d, hi_fixed = stage
        alpha, beta = _pair_bounds(joint, next_set_slab(carry.lo, carry.hi, d))
        lo, hi, empty = _interval(alpha, beta, (-2, -1))
        lo = jnp.maximum(lo, 0.0)
        hi = jnp.minimum(hi, hi_fixed)
        tol = 64.0 * eps * (jnp.abs(lo) + jnp.abs(hi))
        empty = empty | (lo > hi + tol) | carry.empty
        lo = jnp.minimum(lo, hi)  # an empty set collapses to a point: finite values onward
        return _Controllable(lo, hi, empty), (lo, hi)

    x_end = jnp.minimum(x_end, big)
    end_ok = x_end <= x_max[-1] * (1.0 + 64.0 * eps)
    start = _Controllable(x_end, x_end, ~end_ok)
    last, (lo, hi) = jax.lax.scan(backward, start, (slabs, delta, fixed_hi), reverse=True)
    lo = jnp.concatenate([lo, x_end[None]])
    hi = jnp.concatenate([hi, x_end[None]])
    x_start = jnp.minimum(x_start, big)
    start_ok = (x_start >= lo[0] * (1.0 - 64.0 * eps)) & (x_start <= hi[0] * (1.0 + 64.0 * eps))
    x0 = jnp.clip(x_start, lo[0], hi[0])

    def forward(x: Array, stage: tuple) -> tuple[Array, Array]:
        joint, d, lo_next, hi_next = stage
        # A slab's room is known to its terms' round-off only: at a joint whose dq/ds is
        # round-off (p ~ 0) and whose r x is at its bound, room / p would be 0 / 0, and its
        # sign (the sign of p's round-off) would decide between no bound and u <= 0.
        slack = 64.0 * eps * (jnp.abs(joint.hi) + jnp.abs(joint.r * x))
        room = joint.hi - joint.r * x + slack
        bound = jnp.where(joint.p > 0, room / jnp.where(joint.p > 0, joint.p, 1.0), big)
        u = jnp.minimum(jnp.min(bound), (hi_next - x) / (2.0 * d))
        x_next = jnp.clip(x + 2.0 * d * u, lo_next, hi_next)
        return x_next, x_next

    _, xs = jax.lax.scan(forward, x0, (slabs, delta, lo[1:], hi[1:]))
    x = jnp.concatenate([x0[None], xs])
    speed = jnp.sqrt(x)
    total = speed[:-1] + speed[1:]
    # Two neighbouring speeds that are zero to round-off (relative to the path's top speed):
    # the motion stops on that interval, and its duration would be round-off's.
    still = x <= 64.0 * eps * jnp.max(x)
    stalled = jnp.any(still[:-1] & still[1:]) | jnp.any(total <= 0)
    steps = 2.0 * delta / jnp.where(total > 0, total, 1.0)
    t = jnp.concatenate([jnp.zeros((1,), dtype), jnp.cumsum(steps)])
    ok = finite & ~last.empty & start_ok & ~stalled & ~unbounded & jnp.isfinite(t[-1])
    status = jnp.where(
        finite, jnp.where(ok, Status.OK, Status.UNTIMEABLE), Status.INVALID_INPUT
    ).astype(STATUS_DTYPE)
    t = jnp.where(ok, t, 0.0)
    speed = jnp.where(ok, speed, 0.0)
    acceleration = jnp.where(ok, (x[1:] - x[:-1]) / (2.0 * delta), 0.0)
    return t[-1], status, t, speed, acceleration


@kernel(static=("scheme", "speed_bound"))
def _retime(
    path: JointPath,
    v_max: Array,
    a_max: Array,
    x_start: Array,
    x_end: Array,
    scheme: str,
    speed_bound: str,
) -> Timing:
    batch = path.batch_shape
    flat = int(np.prod(batch, dtype=int))
    m, n = path.q.shape[-2:]

    def rows(x: Array, tail: tuple[int, ...]) -> Array:
        return jnp.broadcast_to(x, (*batch, *tail)).reshape(flat, *tail)

    kernel = jax.vmap(functools.partial(_time_one, scheme=scheme, speed_bound=speed_bound))
    duration, status, t, speed, acceleration = kernel(
        rows(path.s, (m,)),
        rows(path.q, (m, n)),
        rows(path.dq, (m, n)),
        rows(path.ddq, (m, n)),
        rows(v_max, (n,)),
        rows(a_max, (n,)),
        rows(x_start, ()),
        rows(x_end, ()),
    )
    return Timing(
        duration.reshape(batch),
        status.reshape(batch),
        t.reshape(*batch, m),
        speed.reshape(*batch, m),
        acceleration.reshape(*batch, m - 1),
    )


def _limit(x: ArrayLike, name: str, n: int, dtype: Any) -> Array:
    """A per-joint limit ``(..., n)``: non-negative (``inf`` = unbounded), checked on the host."""
    if _validate.is_concrete(x):
        raw = np.asarray(x, dtype=float)
        if raw.ndim == 0 or raw.shape[-1] != n:
            raise ValueError(f"{name}: expected shape (..., {n}) (one per joint), got {raw.shape}")
        if not np.all(raw >= 0):
            raise ValueError(f"{name} must be non-negative (inf for no limit), got {raw}")
    arr = _validate.as_array(x, dtype)
    if arr.ndim == 0 or arr.shape[-1] != n:
        raise ValueError(f"{name}: expected shape (..., {n}) (one per joint), got {arr.shape}")
    return arr


def _speed(x: ArrayLike, name: str, dtype: Any) -> Array:
    if _validate.is_concrete(x) and not np.all(np.asarray(x, dtype=float) >= 0):
        raise ValueError(f"{name} must be a non-negative path speed, got {x!r}")
    return _validate.as_array(x, dtype)


def retime(
    path: JointPath,
    v_max: ArrayLike,
    a_max: ArrayLike,
    *,
    start_speed: ArrayLike = 0.0,
    end_speed: ArrayLike = 0.0,
    scheme: str = "interpolation",
    speed_bound: str = "grid",
) -> Timing:
    """The minimum-duration timing of every path of a batch under joint limits (TOPP-RA).

    One compiled call for the whole batch; a new batch of the same shapes reuses it.

    Args:
        path: the geometric paths (``path_from_waypoints``, or sampled by the caller), batch
            shape ``(...)``, grid ``M``, ``n`` joints.
        v_max: speed limit per joint, shape ``(n,)`` or per candidate ``(..., n)``; ``inf``
            for none; 0 pins the joint (a path that moves it is ``UNTIMEABLE``).
        a_max: acceleration limit per joint, same shapes; a path that moves a joint (its
            ``q`` or ``dq`` not all equal to its start's and zero, exactly) whose limit is
            ``inf`` is ``UNTIMEABLE``: its speed could change within one grid interval, at
            an acceleration set by nothing but the grid (and with no speed limit either, in
            no time at all).
        start_speed, end_speed: path speeds ``s_dot`` at the ends, default 0 (at rest);
            scalars or shape ``(...)``.
        scheme: ``"interpolation"`` (acceleration limits at both ends of every interval,
            toppra's default) or ``"collocation"`` (at its start only; faster).
        speed_bound: ``"grid"`` (speed limits at the grid points, as toppra) or
            ``"interval"`` (with each joint's peak ``|dq/ds|`` over the intervals next to a
            grid point: the sampled speeds then stay within the limits everywhere, for a
            slightly longer duration).

    Returns:
        ``Timing``: durations, statuses, grid times, path speeds and accelerations.

    Raises:
        ValueError: mismatched shapes, a negative limit or speed, a grid that is not
            increasing, a bad ``scheme``.
    """
    if not isinstance(path, JointPath):
        raise ValueError(
            "path must be a JointPath (jaxkin.timing.path_from_waypoints builds one from "
            f"waypoints), got {type(path).__name__}"
        )
    _validate.choice(scheme, "scheme", SCHEMES)
    _validate.choice(speed_bound, "speed_bound", SPEED_BOUNDS)
    q = _validate.as_array(path.q)
    if q.ndim < 2 or q.shape[-2] < 2:
        raise ValueError(f"path.q: expected shape (..., M, n) with M >= 2, got {q.shape}")
    inexact = jnp.issubdtype(q.dtype, jnp.inexact)
    dtype = jax.dtypes.canonicalize_dtype(q.dtype) if inexact else jnp.result_type(float)
    m, n = q.shape[-2:]
    for name in ("dq", "ddq"):
        if jnp.shape(getattr(path, name)) != q.shape:
            raise ValueError(
                f"path.{name}: expected the shape of path.q {q.shape}, "
                f"got {jnp.shape(getattr(path, name))}"
            )
    s = _validate.as_array(path.s, dtype)
    if s.ndim < 1 or s.shape[-1] != m:
        raise ValueError(f"path.s: expected shape (..., {m}), got {s.shape}")
    if _validate.is_concrete(path.s):
        steps = np.diff(np.asarray(path.s, dtype=float), axis=-1)
        if not np.all(steps[np.isfinite(steps)] > 0):
            raise ValueError("path.s must be strictly increasing along its last axis")
    v = _limit(v_max, "v_max", n, dtype)
    a = _limit(a_max, "a_max", n, dtype)
    x_start = _speed(start_speed, "start_speed", dtype) ** 2
    x_end = _speed(end_speed, "end_speed", dtype) ** 2
    batch = _validate.batch_shape(
        {
            "path": tuple(q.shape[:-2]),
            "path.s": tuple(s.shape[:-1]),
            "v_max": tuple(v.shape[:-1]),
            "a_max": tuple(a.shape[:-1]),
            "start_speed": tuple(x_start.shape),
            "end_speed": tuple(x_end.shape),
        }
    )
    # (on the host where concrete: no eager program compiled per process)
    full = JointPath(
        _validate.broadcast(s, (*batch, m)),
        _validate.broadcast(_validate.as_array(path.q, dtype), (*batch, m, n)),
        _validate.broadcast(_validate.as_array(path.dq, dtype), (*batch, m, n)),
        _validate.broadcast(_validate.as_array(path.ddq, dtype), (*batch, m, n)),
    )
    # Broadcast here, so that shared and per-candidate limits use one compiled program.
    v, a = (_validate.broadcast(x, (*batch, n)) for x in (v, a))
    x_start, x_end = (_validate.broadcast(x, batch) for x in (x_start, x_end))
    return _retime(full, v, a, x_start, x_end, scheme, speed_bound)


# --------------------------------------------------------------------------------------------
# Sampling the retimed trajectory


def _sample_one(
    s: Array,
    q: Array,
    dq: Array,
    t_grid: Array,
    speed: Array,
    acceleration: Array,
    ok: Array,
    times: Array,
) -> tuple[Jet, Array]:
    """One candidate at ``times (T,)``: Jet ``(T, n)`` and the valid mask ``(T,)``."""
    m = s.shape[0]
    duration = t_grid[-1]
    i = jnp.clip(jnp.searchsorted(t_grid, times, side="right") - 1, 0, m - 2)
    tau = jnp.clip(times - t_grid[i], 0.0, t_grid[i + 1] - t_grid[i])
    u = acceleration[i]
    s_dot = speed[i] + u * tau
    h = s[i + 1] - s[i]
    offset = jnp.clip(speed[i] * tau + 0.5 * u * tau * tau, 0.0, h)
    value, slope, curvature = _hermite(
        q[i], dq[i], q[i + 1], dq[i + 1], h[:, None], (offset / h)[:, None]
    )
    velocity = slope * s_dot[:, None]
    accel = curvature * (s_dot * s_dot)[:, None] + slope * u[:, None]
    valid = ok & (times <= duration)
    hold = jnp.where(ok, q[-1], q[0])
    keep = valid[:, None]
    jet = Jet(
        jnp.where(keep, value, hold),
        jnp.where(keep, velocity, 0.0),
        jnp.where(keep, accel, 0.0),
    )
    return jet, valid


@kernel
def _sample(path: JointPath, timing: Timing, times: Array) -> RetimedTrajectory:
    batch = timing.duration.shape
    flat = int(np.prod(batch, dtype=int))
    m, n = path.q.shape[-2:]

    def rows(x: Array, tail: tuple[int, ...]) -> Array:
        return jnp.broadcast_to(x, (*batch, *tail)).reshape(flat, *tail)

    jet, valid = jax.vmap(_sample_one, in_axes=(0, 0, 0, 0, 0, 0, 0, None))(
        rows(path.s, (m,)),
        rows(path.q, (m, n)),
        rows(path.dq, (m, n)),
        rows(timing.t, (m,)),
        rows(timing.speed, (m,)),
        rows(timing.acceleration, (m - 1,)),
        rows(timing.ok, ()),
        times,
    )
    count = jnp.sum(valid, axis=-1, dtype=jnp.int32)
    size = times.shape[0]
    return RetimedTrajectory(
        times,
        jet.map(lambda x: x.reshape(*batch, size, n)),
        valid.reshape(*batch, size),
        count.reshape(batch),
    )


def sample(
    path: JointPath, timing: Timing, period: float, num: int | None = None
) -> RetimedTrajectory:
    """The retimed trajectories sampled every ``period`` from ``t = 0``, padded to one length.

    Sample ``k`` is at ``t = k * period``; between grid points ``s(t)`` has the interval's
    constant path acceleration and the joints follow the path's cubic Hermite interpolant, so
    ``q_dot = q'(s) s_dot`` and ``q_ddot = q''(s) s_dot^2 + q'(s) s_ddot`` exactly.

    Args:
        path: the paths given to ``retime``.
        timing: ``retime``'s result for them.
        period: the control period (time unit of the limits), positive.
        num: samples per candidate (a static size: a new value compiles again). ``None``
            (host side) takes enough for the longest successful candidate,
            ``floor(max duration / period) + 1``.

    Returns:
        ``RetimedTrajectory`` with ``T = num`` samples per candidate.
    """
    if not isinstance(timing, Timing):
        raise ValueError(f"timing must be a Timing from retime, got {type(timing).__name__}")
    real = isinstance(period, int | float | np.integer | np.floating) and not isinstance(
        period, bool
    )
    if not (real and math.isfinite(period) and period > 0):
        raise ValueError(f"period must be a positive number, got {period!r}")
    if num is None:
        durations = np.asarray(timing.duration)
        longest = float(np.max(durations, initial=0.0))
        num = int(math.floor(longest / period * (1.0 + 1e-12))) + 1
    num = _validate.count(num, "num")
    q = _validate.as_array(path.q)
    if q.shape[-2] != timing.t.shape[-1]:
        raise ValueError(
            f"path and timing disagree: path has {q.shape[-2]} grid points, timing "
            f"{timing.t.shape[-1]}"
        )
    dtype = timing.t.dtype
    times = np.arange(num, dtype=dtype) * np.asarray(period, dtype)  # on the host
    return _sample(path, timing, times)


def best(timing: Timing, k: int) -> tuple[np.ndarray, np.ndarray]:
    """The ``k`` fastest timed candidates (host side), over a flat batch ``(N,)``.

    Returns:
        ``(indices, durations)``: indices of the candidates with status ``OK`` sorted by
        increasing duration (ties by index), and their durations, NumPy; fewer than ``k`` when
        fewer candidates could be timed.
    """
    k = _validate.count(k, "k")
    duration = np.asarray(timing.duration)
    if duration.ndim != 1:
        raise ValueError(f"timing: expected a flat batch (N,), got shape {duration.shape}")
    ok = np.flatnonzero(np.asarray(timing.ok))
    order = ok[np.argsort(duration[ok], kind="stable")][:k]
    return order, duration[order]
