"""Paths for the planner, built on the host from samples, poses or joint waypoints.

A ``Path`` is a ``Jet`` of samples ``(N, T, ...)`` taken every ``dt`` that carries ``dt`` and
its ``space``: ``"task"`` (targets of the robot: points, poses) or ``"joint"`` (joint
coordinates ``(N, T, n_joints)``). ``jaxkin.plan.evaluate`` reads both from it, so the sampling
period is given once, where the rates are made.

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

``path_from_joint_waypoints`` builds joint-space candidates: the cubic spline through joint
waypoints equally spaced in time, sampled every ``dt`` with its exact rates.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from jax import Array
from jax.typing import ArrayLike

from . import _splines, _validate, lie
from .jet import Jet

__all__ = [
    "SPACES",
    "Path",
    "bezier_basis",
    "bezier_controls",
    "bezier_path",
    "path_from_joint_waypoints",
    "path_from_poses",
    "path_from_samples",
    "pose_from_quaternions",
    "quaternions_from_pose",
    "straight_line_guess",
]


SPACES = ("task", "joint")


@jax.tree_util.register_dataclass
@dataclasses.dataclass(frozen=True)
class Path(Jet):
    """A ``Jet`` of sampled paths that knows its sampling period and space.

    Attributes:
        p, v, a: samples and their exact first and second time derivatives, shape
            ``(N, T, *coords)``: the robot's target shape in task space, ``(n_joints,)`` in
            joint space.
        dt: the time between consecutive samples (positive; static: a Python float).
        space: ``"task"`` (end-effector targets) or ``"joint"`` (joint coordinates).

    Indexing, ``map`` and ``astype`` keep ``dt`` and ``space``.
    """

    dt: float = dataclasses.field(metadata=dict(static=True))
    space: str = dataclasses.field(default="task", metadata=dict(static=True))

    def __post_init__(self) -> None:
        _validate.positive_number(self.dt, "dt")
        _validate.choice(self.space, "space", SPACES)

    @classmethod
    def from_jet(cls, jet: Jet, dt: float, space: str = "task") -> Path:
        """A ``Jet`` of samples ``dt`` apart (e.g. ``bezier_path``'s) as a ``Path``."""
        return cls(jet.p, jet.v, jet.a, dt=_validate.positive_number(dt, "dt"), space=space)

    def with_jet(self, jet: Jet) -> Path:
        """``jet`` with this path's ``dt`` and ``space``."""
        return Path(jet.p, jet.v, jet.a, dt=self.dt, space=self.space)

    def __getitem__(self, index: Any) -> Path:
        return self.with_jet(Jet.__getitem__(self, index))

    def astype(self, dtype: Any) -> Path:
        return self.with_jet(Jet.astype(self, dtype))

    def map(self, fn: Any) -> Path:
        return self.with_jet(Jet.map(self, fn))

    @property
    def jet(self) -> Jet:
        """The samples as a plain ``Jet``."""
        return Jet(self.p, self.v, self.a)


def _path(p: Any, v: Any, a: Any, dt: float, space: str) -> Path:
    jet = Jet.of(p, v, a)
    return Path(jet.p, jet.v, jet.a, dt=float(dt), space=space)


def path_from_samples(
    positions: ArrayLike, dt: float, end: str = "not-a-knot", space: str = "task"
) -> Path:
    """Path of samples taken at a fixed time step, rates from a cubic spline (host side).

    Each coordinate of each candidate is interpolated by a cubic spline through its samples
    (``"not-a-knot"`` ends reproduce any cubic exactly) and
    the spline's exact first and second derivatives at the samples are the velocity and
    acceleration: no finite differences.

    Args:
        positions: shape ``(N, T, d)`` (any leading dims), samples ``dt`` apart. A candidate
            with a NaN or inf sample gets NaN rates: its samples are ``INVALID_INPUT`` in
            ``evaluate``, and the other candidates are unaffected.
        dt: the time step (positive), carried by the returned ``Path``.
        end: the spline end condition, ``"not-a-knot"`` or ``"natural"``.
        space: ``"task"`` (the samples are the robot's targets) or ``"joint"`` (joint
            coordinates ``(N, T, n_joints)``).
    """
    positions = np.asarray(positions, dtype=float)
    _check_samples(positions, "positions", None, dt)
    _validate.choice(space, "space", SPACES)
    p, v, a = _splined(positions, dt, end)
    return _path(p, v, a, dt, space)


def path_from_joint_waypoints(
    waypoints: ArrayLike, dt: float, steps: int, end: str = "not-a-knot"
) -> Path:
    """Joint-space candidates through waypoints, sampled at a control period (host side).

    Waypoint ``k`` of each candidate is reached at time ``t_k = k steps dt``; each joint
    follows the cubic spline through the waypoints at those times (``end`` condition as in
    SciPy's ``CubicSpline``), sampled every ``dt``, with the spline's exact velocity and
    acceleration: on segment ``[t_k, t_k+1]`` the cubic Hermite interpolant of the waypoints
    and the spline's slopes there (``jaxkin._splines``).

    Args:
        waypoints: joint coordinates, shape ``(N, K, n)`` (any leading dims), ``K >= 2``.
        dt: the control period (positive).
        steps: samples per segment, a positive integer: ``T = (K - 1) steps + 1`` samples.
        end: the spline end condition, ``"not-a-knot"`` or ``"natural"``.

    Returns:
        A joint-space ``Path`` of shape ``(N, T, n)``. A candidate with a non-finite waypoint
        gets NaN samples (``INVALID_INPUT`` in ``evaluate``); the others are unaffected.
    """
    waypoints = np.asarray(waypoints, dtype=float)
    _check_samples(waypoints, "waypoints", None, dt)
    steps = _validate.count(steps, "steps")
    _validate.choice(end, "end", _splines.END_CONDITIONS)
    segment_time = int(steps) * float(dt)
    count = waypoints.shape[-2]
    knots = np.arange(count) * segment_time
    finite = np.all(np.isfinite(waypoints), axis=(-2, -1))[..., None, None]
    clean = np.where(finite, waypoints, 0.0)
    slopes, _ = _splines.derivatives(np.broadcast_to(knots, clean.shape[:-1]), clean, end=end)
    fractions = np.arange(steps) / steps
    tau = np.concatenate([np.tile(fractions, count - 1), [1.0]])[:, None]
    segment = np.concatenate([np.repeat(np.arange(count - 1), steps), [count - 2]])
    y0, y1 = clean[..., segment, :], clean[..., segment + 1, :]
    m0, m1 = slopes[..., segment, :], slopes[..., segment + 1, :]
    value, velocity, acceleration = _splines.hermite(y0, m0, y1, m1, segment_time, tau)
    value, velocity, acceleration = (
        np.where(finite, x, np.nan) for x in (value, velocity, acceleration)
    )
    return _path(value, velocity, acceleration, dt, "joint")


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
    _validate.positive_number(dt, "dt")


def path_from_poses(
    positions: ArrayLike, quaternions: ArrayLike, dt: float, end: str = "not-a-knot"
) -> Path:
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
        A task-space ``Path`` of shape ``(..., T, 4, 4)`` carrying ``dt``. A candidate with a
        non-finite sample gets NaN rates (``INVALID_INPUT`` in ``evaluate``); the others are
        unaffected.

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
    unit = _validate.quaternion_samples(quaternions, "quaternions")
    unit = unit * lie.hemisphere_signs(unit, xp=np)[..., None]
    p, v, a = _splined(np.concatenate([positions, unit], -1), dt, end)
    pose = pose_from_quaternions(p, v, a)
    return _path(pose.p, pose.v, pose.a, dt, "task")


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
    # device_put: as jnp.asarray, without compiling a program per shape
    return Jet.of(*(jax.device_put(x) for x in (value, velocity, acceleration)))


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
    n_ctrl, n_samples = _validate.count(n_ctrl, "n_ctrl"), _validate.count(n_samples, "n_samples")

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


def bezier_path(controls: Array, basis: Array, duration: ArrayLike) -> Jet:
    """Jet of the Bezier path, shape ``(..., T, d)``, from controls ``(..., K, d)``."""
    p = jnp.einsum("tk,...kc->...tc", basis[0], controls)
    v = jnp.einsum("tk,...kc->...tc", basis[1], controls) / duration
    a = jnp.einsum("tk,...kc->...tc", basis[2], controls) / duration**2
    return Jet(p, v, a)


def straight_line_guess(
    start: ArrayLike, goal: ArrayLike, n_interior: int, n_guesses: int = 1, noise=0.0, seed=0
) -> np.ndarray:
    """Interior control points on the segment start-goal, plus Gaussian noise: (B, K-2, d)."""
    n_interior = _validate.count(n_interior, "n_interior")
    n_guesses = _validate.count(n_guesses, "n_guesses")
    start, goal = np.asarray(start, float), np.asarray(goal, float)
    s = np.linspace(0.0, 1.0, n_interior + 2)[1:-1, None]
    line = start + s * (goal - start)
    rng = np.random.default_rng(seed)
    return line + noise * rng.normal(size=(n_guesses, n_interior, start.shape[-1]))
