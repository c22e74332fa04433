"""Task-space paths for the planner, built on the host from samples or poses.

``path_from_samples`` splines sampled points (``(..., T, d)``, a fixed time step) per
coordinate with a cubic spline and takes its exact first and second derivatives at the samples
as the rates: no finite differences. ``path_from_poses`` does the same for poses: positions
splined per coordinate, the orientation along the quaternion curve that splines the four
components (signs made continuous by the hemisphere rule), mapped to rotations by the
quadratic quaternion-to-matrix map ``R = Q(s) / |s|^2`` whose rates are exact
(``jaxkin.lie``). ``pose_from_quaternions`` and ``quaternions_from_pose`` convert poses with
their rates between ``(x, y, z, qw, qx, qy, qz)`` rows and ``(..., 4, 4)`` transforms.

Everything runs in NumPy float64 on the host, whatever JAX's x64 setting; the results are
``Jet``s for ``jaxkin.plan.evaluate``. A candidate with a NaN or inf sample gets NaN rates
(its samples are ``INVALID_INPUT`` in ``evaluate``); the other candidates are unaffected.

Bezier paths (trajectory optimisation): ``p(s) = sum_i B_i(s) P_i`` with Bernstein
polynomials ``B_i`` of degree ``K - 1`` and ``s = t / duration``; ``bezier_basis`` tabulates
the basis and its first two derivatives on the host, ``bezier_path`` evaluates a ``Jet`` (in
JAX, differentiable in the control points), ``bezier_controls`` adds the fixed end points and
``straight_line_guess`` makes initial interior points.
"""

from __future__ import annotations

import math

import jax.numpy as jnp
import numpy as np
from jax import Array
from jax.typing import ArrayLike

from . import _splines, lie
from .jet import Jet

__all__ = [
    "bezier_basis",
    "bezier_controls",
    "bezier_path",
    "path_from_poses",
    "path_from_samples",
    "pose_from_quaternions",
    "quaternions_from_pose",
    "straight_line_guess",
]


def path_from_samples(positions: ArrayLike, dt: float, end: str = "not-a-knot") -> Jet:
    """Jet of paths sampled at a fixed time step, rates from a cubic spline (host side).

    Each coordinate of each candidate is interpolated by a cubic spline through its samples
    (``"not-a-knot"`` ends reproduce any cubic exactly) and
    the spline's exact first and second derivatives at the samples are the velocity and
    acceleration: no finite differences.

    Args:
        positions: shape ``(N, T, d)`` (any leading dims), samples ``dt`` apart. A candidate
            with a NaN or inf sample gets NaN rates: its samples are ``INVALID_INPUT`` in
            ``evaluate``, and the other candidates are unaffected.
        dt: the time step (positive).
        end: the spline end condition, ``"not-a-knot"`` or ``"natural"``.
    """
    positions = np.asarray(positions, dtype=float)
    _check_samples(positions, "positions", None, dt)
    return Jet.of(*_splined(positions, dt, end))


def _splined(positions: np.ndarray, dt: float, end: str) -> tuple[np.ndarray, ...]:
    """``(value, velocity, acceleration)`` of per-candidate cubic splines through samples
    ``(..., T, d)``; a candidate with a non-finite sample gets NaN rates."""
    t = np.broadcast_to(np.arange(positions.shape[-2]) * float(dt), positions.shape[:-1])
    finite = np.all(np.isfinite(positions), axis=(-2, -1))[..., None, None]
    velocity, acceleration = _splines.derivatives(t, np.where(finite, positions, 0.0), end=end)
    velocity, acceleration = (np.where(finite, x, np.nan) for x in (velocity, acceleration))
    return positions, velocity, acceleration


def _check_samples(x: np.ndarray, name: str, width: int | None, dt: float) -> None:
    """Samples ``(..., T, width)`` (any width for None) with T >= 2, and a positive ``dt``."""
    if x.ndim < 2 or x.shape[-2] < 2 or (width is not None and x.shape[-1] != width):
        shape = f"(..., T, {'d' if width is None else width})"
        raise ValueError(f"{name}: expected shape {shape} with T >= 2, got {x.shape}")
    if not (dt > 0 and math.isfinite(dt)):
        raise ValueError(f"dt must be a positive finite number, got {dt!r}")


def path_from_poses(
    positions: ArrayLike, quaternions: ArrayLike, dt: float, end: str = "not-a-knot"
) -> Jet:
    """Jet of pose paths ``(..., T, 4, 4)`` sampled at a fixed time step (host side).

    The pose target of the 6-DOF arms and chains is a homogeneous transform ``T = [[R, p],
    [0, 1]]``; its rates are the time derivatives ``T_dot = [[R_dot, p_dot], [0, 0]]`` and
    ``T_ddot`` (angular velocity ``[omega]_x = R_dot R^T``). Positions are splined per
    coordinate as in ``path_from_samples``; the orientation follows the quaternion curve
    ``s(t)`` that splines the four components (after flipping signs so that consecutive
    samples lie in one hemisphere), and ``R(t) = Q(s(t)) / |s(t)|^2`` with ``Q`` the quadratic
    quaternion-to-matrix map, so ``R`` is a rotation at every time, equals the given sample at
    every sample, and its rates are the exact derivatives of that curve: no finite differences.

    Args:
        positions: ``(..., T, 3)``, samples ``dt`` apart.
        quaternions: ``(..., T, 4)`` as ``(w, x, y, z)``, any non-zero length (normalised here).
        dt: the time step (positive).
        end: the spline end condition, ``"not-a-knot"`` or ``"natural"``.

    Returns:
        A ``Jet`` of shape ``(..., T, 4, 4)``. A candidate with a non-finite sample gets NaN
        rates (``INVALID_INPUT`` in ``evaluate``); the others are unaffected.

    Raises:
        ValueError: shapes not ``(..., T, 3)`` and ``(..., T, 4)`` with the same leading axes
            and T >= 2, a zero quaternion, or a non-positive ``dt``.
    """
    positions = np.asarray(positions, dtype=float)
    quaternions = np.asarray(quaternions, dtype=float)
    _check_samples(positions, "positions", 3, dt)
    _check_samples(quaternions, "quaternions", 4, dt)
    if positions.shape[:-1] != quaternions.shape[:-1]:
        raise ValueError(
            f"positions {positions.shape} and quaternions {quaternions.shape} must have the same "
            "leading axes (..., T)"
        )
    length = np.linalg.norm(quaternions, axis=-1, keepdims=True)
    if np.any(length == 0.0):
        raise ValueError("quaternions: every quaternion must be non-zero")
    unit = quaternions / length
    unit = unit * lie.hemisphere_signs(unit, xp=np)[..., None]
    p, v, a = _splined(np.concatenate([positions, unit], -1), dt, end)
    return pose_from_quaternions(p, v, a)


def pose_from_quaternions(p: ArrayLike, v: ArrayLike, a: ArrayLike) -> Jet:
    """Pose Jet ``(..., 4, 4)`` from poses as ``(x, y, z, qw, qx, qy, qz)`` and their time
    derivatives, each ``(..., 7)`` (host side).

    The quaternion part ``s`` may have any non-zero length: ``R = Q(s) / |s|^2`` with ``Q`` the
    quadratic quaternion-to-matrix map, and ``R_dot``, ``R_ddot`` its exact derivatives along
    ``s(t)`` with rates ``s_dot``, ``s_ddot`` (``path_from_poses``).
    """
    p, v, a = (np.asarray(x, dtype=float) for x in (p, v, a))
    rot, d_rot, dd_rot = lie.rotation_rates_of_quaternion(p[..., 3:], v[..., 3:], a[..., 3:], xp=np)
    shape = (*p.shape[:-1], 4, 4)
    value, velocity, acceleration = np.zeros(shape), np.zeros(shape), np.zeros(shape)
    for out, r, x in ((value, rot, p), (velocity, d_rot, v), (acceleration, dd_rot, a)):
        out[..., :3, :3], out[..., :3, 3] = r, x[..., :3]
    value[..., 3, 3] = 1.0
    return Jet.of(value, velocity, acceleration)


def quaternions_from_pose(pose: Jet) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Poses ``(..., 4, 4)`` with their rates as ``(x, y, z, qw, qx, qy, qz)`` rows (host side).

    The unit quaternion of each rotation (Shepperd's method, ``qw >= 0``), and its rates from
    the angular velocity and acceleration (``jaxkin.lie.quaternion_rates_of_rotation``).
    Returns ``(p, v, a)``, each ``(..., 7)``.
    """
    r, d_r, dd_r = (np.asarray(x, dtype=float) for x in (pose.p, pose.v, pose.a))
    quat, d_quat, dd_quat = lie.quaternion_rates_of_rotation(
        r[..., :3, :3], d_r[..., :3, :3], dd_r[..., :3, :3], xp=np
    )
    p = np.concatenate([r[..., :3, 3], quat], -1)
    v = np.concatenate([d_r[..., :3, 3], d_quat], -1)
    a = np.concatenate([dd_r[..., :3, 3], dd_quat], -1)
    return p, v, a


def bezier_basis(n_ctrl: int, n_samples: int) -> np.ndarray:
    """Bernstein basis and its first two derivatives in ``s``: shape ``(3, n_samples, n_ctrl)``.

    ``B_i(s) = C(K-1, i) s^i (1 - s)^(K-1-i)`` at ``s = linspace(0, 1, n_samples)``; the
    derivatives use ``B'_{i,n} = n (B_{i-1,n-1} - B_{i,n-1})`` (host-side setup, float64).
    """

    def bernstein(degree: int, s: np.ndarray) -> np.ndarray:
        i = np.arange(degree + 1)
        coef = np.array([math.comb(degree, k) for k in i], float)
        return coef * s[:, None] ** i * (1.0 - s[:, None]) ** (degree - i)

    def derivative(values: np.ndarray, degree: int) -> np.ndarray:
        padded = np.pad(values, ((0, 0), (1, 1)))
        return degree * (padded[:, :-1] - padded[:, 1:])

    s = np.linspace(0.0, 1.0, n_samples)
    n = n_ctrl - 1
    b0 = bernstein(n, s)
    b1 = derivative(bernstein(n - 1, s), n) if n >= 1 else np.zeros_like(b0)
    b2 = derivative(derivative(bernstein(n - 2, s), n - 1), n) if n >= 2 else np.zeros_like(b0)
    return np.stack([b0, b1, b2])


def bezier_controls(interior: Array, start: Array, goal: Array, rest_to_rest: bool) -> Array:
    """Every control point ``(..., K, d)`` from the interior ones ``(..., K', d)``: ``start``
    first and ``goal`` last (each twice with ``rest_to_rest``: the path starts and ends at
    rest)."""
    batch = interior.shape[:-2]
    ends = [jnp.broadcast_to(x, (*batch, 1, x.shape[-1])) for x in (start, goal)]
    if rest_to_rest:
        ends = [jnp.concatenate([e, e], axis=-2) for e in ends]
    return jnp.concatenate([ends[0], interior, ends[1]], axis=-2)


def bezier_path(controls: Array, basis: Array, duration: float) -> Jet:
    """Jet of the Bezier path, shape ``(..., T, d)``, from controls ``(..., K, d)``."""
    p = jnp.einsum("tk,...kc->...tc", basis[0], controls)
    v = jnp.einsum("tk,...kc->...tc", basis[1], controls) / duration
    a = jnp.einsum("tk,...kc->...tc", basis[2], controls) / duration**2
    return Jet(p, v, a)


def straight_line_guess(
    start: ArrayLike, goal: ArrayLike, n_interior: int, n_guesses: int = 1, noise=0.0, seed=0
) -> np.ndarray:
    """Interior control points on the segment start-goal, plus Gaussian noise: (B, K-2, d)."""
    start, goal = np.asarray(start, float), np.asarray(goal, float)
    s = np.linspace(0.0, 1.0, n_interior + 2)[1:-1, None]
    line = start + s * (goal - start)
    rng = np.random.default_rng(seed)
    return line + noise * rng.normal(size=(n_guesses, n_interior, start.shape[-1]))
