"""Velocity and acceleration of sampled trajectories by cubic splines (host-side NumPy).

Each coordinate of each trajectory is interpolated by a cubic spline ``s(t)`` through its
samples ``(t_i, y_i)`` (``t`` strictly increasing, spacing may vary); the rates at the samples
are ``s'(t_i)`` and ``s''(t_i)``. Slope form (de Boor, *A Practical Guide to Splines*, ch. IV,
as SciPy's ``CubicSpline``): with ``h_i = t_{i+1} - t_i`` and ``d_i = (y_{i+1} - y_i) / h_i``
the slopes ``m_i = s'(t_i)`` solve the tridiagonal system (C2 continuity)::

    h_i m_{i-1} + 2 (h_{i-1} + h_i) m_i + h_{i-1} m_{i+1} = 3 (h_i d_{i-1} + h_{i-1} d_i)

closed by ``"not-a-knot"`` (default: the first two and the last two pieces are one cubic,
first row ``h_1 m_0 + (h_0 + h_1) m_1 = ((h_0 + 2 (h_0 + h_1)) h_1 d_0 + h_0^2 d_1) / (h_0 +
h_1)``; exact for any cubic) or ``"natural"`` (``s'' = 0`` at both ends: ``2 m_0 + m_1 = 3 d_0``).
Then ``s''(t_i) = (6 d_i - 4 m_i - 2 m_{i+1}) / h_i`` (the last knot from its left piece).
``n = 1`` gives zero rates, ``n = 2`` the straight line, ``n = 3`` (not-a-knot) the parabola.
Every leading axis is a separate spline, solved by the Thomas algorithm vectorised over the
batch; ``by_group`` handles candidates of different lengths and skips non-finite samples.
``hermite`` evaluates the cubic on one interval from its end values and slopes (the joint paths
of ``jaxkin.timing`` and ``jaxkin.paths.path_from_joint_waypoints``).
"""

from __future__ import annotations

from typing import Any

import numpy as np

END_CONDITIONS = ("not-a-knot", "natural")


def _solve_tridiagonal(
    lower: np.ndarray, diag: np.ndarray, upper: np.ndarray, rhs: np.ndarray
) -> np.ndarray:
    """Thomas algorithm, batched: ``lower/diag/upper`` ``(B, n)``, ``rhs`` ``(B, n, K)``.

    Row i reads ``lower[i] x[i-1] + diag[i] x[i] + upper[i] x[i+1] = rhs[i]`` (``lower[0]`` and
    ``upper[n-1]`` are ignored).
    """
    n = diag.shape[-1]
    c = np.empty_like(diag)
    d = np.empty_like(rhs)
    c[:, 0] = upper[:, 0] / diag[:, 0]
    d[:, 0] = rhs[:, 0] / diag[:, 0, None]
    for i in range(1, n):
        denom = diag[:, i] - lower[:, i] * c[:, i - 1]
        c[:, i] = upper[:, i] / denom if i < n - 1 else 0.0
        d[:, i] = (rhs[:, i] - lower[:, i, None] * d[:, i - 1]) / denom[:, None]
    x = np.empty_like(rhs)
    x[:, n - 1] = d[:, n - 1]
    for i in range(n - 2, -1, -1):
        x[:, i] = d[:, i] - c[:, i, None] * x[:, i + 1]
    return x


def derivatives(
    t: np.ndarray, y: np.ndarray, end: str = "not-a-knot"
) -> tuple[np.ndarray, np.ndarray]:
    """First and second derivatives at the samples of the cubic spline through ``(t, y)``.

    Args:
        t: sample times, shape ``(..., n)``, strictly increasing along the last axis.
        y: sample values, shape ``(..., n)`` or ``(..., n, k)`` (``k`` coordinates splined
            independently with the same ``t``); leading axes broadcast against ``t``'s.
        end: ``"not-a-knot"`` (default) or ``"natural"`` (see the module docstring).

    Returns:
        ``(velocity, acceleration)``, each of ``y``'s (broadcast) shape and float dtype.

    Raises:
        ValueError: unknown ``end``, mismatched sample axes, non-finite values, or ``t`` not
            strictly increasing.
    """
    if end not in END_CONDITIONS:
        raise ValueError(f"end must be one of {END_CONDITIONS}, got {end!r}")
    t = np.asarray(t, dtype=float)
    y = np.asarray(y, dtype=float)
    if t.ndim == 0:
        raise ValueError("t must have a sample axis (shape (..., n))")
    squeeze = y.ndim == t.ndim
    if squeeze:
        y = y[..., None]
    if y.ndim != t.ndim + 1 or y.shape[-2] != t.shape[-1]:
        raise ValueError(
            f"y must have shape (..., n) or (..., n, k) with n = {t.shape[-1]}, got {y.shape}"
        )
    if not (np.all(np.isfinite(t)) and np.all(np.isfinite(y))):
        raise ValueError("t and y must be finite")
    batch = np.broadcast_shapes(t.shape[:-1], y.shape[:-2])
    n, k = t.shape[-1], y.shape[-1]
    t = np.broadcast_to(t, (*batch, n)).reshape(-1, n)
    y = np.broadcast_to(y, (*batch, n, k)).reshape(-1, n, k)
    velocity, acceleration = _derivatives_2d(t, y, end)
    shape = (*batch, n) if squeeze else (*batch, n, k)
    return velocity.reshape(shape), acceleration.reshape(shape)


def _derivatives_2d(t: np.ndarray, y: np.ndarray, end: str) -> tuple[np.ndarray, np.ndarray]:
    """``t`` ``(B, n)``, ``y`` ``(B, n, K)``: the core of ``derivatives``."""
    n = t.shape[-1]
    if n == 1:
        return np.zeros_like(y), np.zeros_like(y)
    h = np.diff(t, axis=-1)  # (B, n-1)
    if np.any(h <= 0):
        raise ValueError("t must be strictly increasing")
    slope = np.diff(y, axis=-2) / h[..., None]  # d_i, (B, n-1, K)
    if n == 2:
        return np.repeat(slope, 2, axis=-2), np.zeros_like(y)
    if n == 3 and end == "not-a-knot":
        # The parabola through three points: s'' constant = 2 (d_1 - d_0) / (t_2 - t_0).
        curvature = 2.0 * (slope[:, 1] - slope[:, 0]) / (t[:, 2] - t[:, 0])[:, None]
        m0 = slope[:, 0] - 0.5 * curvature * h[:, 0, None]
        velocity = m0[:, None] + curvature[:, None] * (t - t[:, :1])[..., None]
        return velocity, np.broadcast_to(curvature[:, None], y.shape).copy()

    lower = np.zeros_like(t)
    diag = np.zeros_like(t)
    upper = np.zeros_like(t)
    rhs = np.zeros_like(y)
    h_left, h_right = h[:, :-1], h[:, 1:]
    lower[:, 1:-1] = h_right
    diag[:, 1:-1] = 2.0 * (h_left + h_right)
    upper[:, 1:-1] = h_left
    rhs[:, 1:-1] = 3.0 * (h_right[..., None] * slope[:, :-1] + h_left[..., None] * slope[:, 1:])
    if end == "natural":
        diag[:, 0], upper[:, 0] = 2.0, 1.0
        rhs[:, 0] = 3.0 * slope[:, 0]
        lower[:, -1], diag[:, -1] = 1.0, 2.0
        rhs[:, -1] = 3.0 * slope[:, -1]
    else:
        h0, h1 = h[:, 0], h[:, 1]
        span = h0 + h1
        diag[:, 0], upper[:, 0] = h1, span
        rhs[:, 0] = (
            (h0 + 2.0 * span)[:, None] * h1[:, None] * slope[:, 0]
            + (h0 * h0)[:, None] * slope[:, 1]
        ) / span[:, None]
        ha, hb = h[:, -2], h[:, -1]  # h_{n-3}, h_{n-2}
        span = ha + hb
        lower[:, -1], diag[:, -1] = span, ha
        rhs[:, -1] = (
            (hb * hb)[:, None] * slope[:, -2]
            + (2.0 * span + hb)[:, None] * ha[:, None] * slope[:, -1]
        ) / span[:, None]
    velocity = _solve_tridiagonal(lower, diag, upper, rhs)
    acceleration = np.empty_like(y)
    hh = h[..., None]
    acceleration[:, :-1] = (6.0 * slope - 4.0 * velocity[:, :-1] - 2.0 * velocity[:, 1:]) / hh
    acceleration[:, -1] = (2.0 * velocity[:, -2] + 4.0 * velocity[:, -1] - 6.0 * slope[:, -1]) / hh[
        :, -1
    ]
    return velocity, acceleration


def by_group(
    t: np.ndarray,
    y: np.ndarray,
    group: np.ndarray | None = None,
    end: str = "not-a-knot",
    valid: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Spline rates for rows of several trajectories stored in one table.

    Rows with the same ``group`` label (e.g. a file's ``candidate`` column) form one
    trajectory, in row order; they may be interleaved with other groups. Rows where ``valid``
    is False (default: rows with a non-finite ``t`` or ``y``) are left out of the fit and get
    NaN rates. Groups with the same number of valid rows are solved in one batched call.

    Args:
        t: ``(N,)`` times.
        y: ``(N, k)`` values.
        group: ``(N,)`` integer labels, or ``None`` for a single trajectory.
        end: end condition (``derivatives``).
        valid: ``(N,)`` bool mask of rows to use.

    Returns:
        ``(velocity, acceleration)``, each ``(N, k)``.

    Raises:
        ValueError: the valid times of a group are not strictly increasing (the message names
            the group and the first offending row index, 0-based).
    """
    t = np.asarray(t, dtype=float)
    y = np.asarray(y, dtype=float)
    group = np.zeros(len(t), dtype=np.int64) if group is None else np.asarray(group)
    if valid is None:
        valid = np.isfinite(t) & np.all(np.isfinite(y), axis=-1)
    velocity = np.full_like(y, np.nan)
    acceleration = np.full_like(y, np.nan)
    rows_by_length: dict[int, list[np.ndarray]] = {}
    for label in np.unique(group[valid]):
        rows = np.flatnonzero(valid & (group == label))
        bad = np.flatnonzero(np.diff(t[rows]) <= 0)
        if bad.size:
            raise ValueError(
                f"candidate {label}: t must be strictly increasing, but row {rows[bad[0] + 1]} "
                f"has t = {t[rows[bad[0] + 1]]:g} after t = {t[rows[bad[0]]]:g}"
            )
        rows_by_length.setdefault(len(rows), []).append(rows)
    for groups in rows_by_length.values():
        index = np.stack(groups)  # (G, n)
        v, a = derivatives(t[index], y[index], end=end)
        velocity[index] = v
        acceleration[index] = a
    return velocity, acceleration


def hermite(y0: Any, m0: Any, y1: Any, m1: Any, h: Any, tau: Any) -> tuple:
    """Cubic Hermite interpolant on ``[s0, s0 + h]`` at ``s = s0 + tau h``: value, d/ds, d2/ds2.

    ``y``, ``m`` are the values and slopes at the ends; broadcasting shapes; NumPy or JAX
    arrays (plain arithmetic).
    """
    t2 = tau * tau
    t3 = t2 * tau
    value = (
        (2.0 * t3 - 3.0 * t2 + 1.0) * y0
        + (t3 - 2.0 * t2 + tau) * h * m0
        + (3.0 * t2 - 2.0 * t3) * y1
        + (t3 - t2) * h * m1
    )
    slope = (
        6.0 * (t2 - tau) * (y0 - y1) / h
        + (3.0 * t2 - 4.0 * tau + 1.0) * m0
        + (3.0 * t2 - 2.0 * tau) * m1
    )
    curvature = (12.0 * tau - 6.0) * (y0 - y1) / (h * h) + (
        (6.0 * tau - 4.0) * m0 + (6.0 * tau - 2.0) * m1
    ) / h
    return value, slope, curvature
