"""The damped least-squares step of a chain's IK, and the twist to a target pose.

Both IKs of a chain (``newton``: the textbook iteration; ``search``: the robot's IK) take the
step that solves, for the ``6 x n`` Jacobian ``J`` and the twist ``V`` to the target::

    n <= r:  (J^T J + mu I) dq = J^T V           n > r:  dq = J^T (J J^T + mu I)^-1 V

(``r`` rows: 6 for a pose target, 3 for a point target) with
``mu = damping^2 + floor trace(J^T J)`` (``floor`` ``sqrt(eps)`` unless given: a soft
cut-off of the singular values, so a rank-deficient ``J`` gives a finite step). The symmetric
positive definite system is solved by a Cholesky factorisation unrolled over its static size
(``spd_solve``): elementwise batch arithmetic, much faster on CPU than a batched LAPACK call for
sizes up to 6. Matrices and vectors are nested lists of batch arrays (structure of arrays).
The chain IK solves it on arrays by one loop of Gauss-Jordan elimination
(``spd_solve_looped``: a small compiled program, and no LAPACK call, whose first use in a
process imports scipy).

The twist to a target ``T_d`` from the pose ``T = [R, p]`` is ``V_b = log(T^-1 T_d)``
(``body_twist``): ``R_bd = R^T R_d``, ``p_bd = R^T (p_d - p)``; ``|omega|`` of the twist is the
rotation angle of ``R_bd`` and ``|p_bd| = |p_d - p|`` the tool's distance to the target.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import jax
import jax.numpy as jnp
from jax import Array
from jax.typing import ArrayLike

from .. import lie
from .._numerics import all_finite, computed_once, eps, safe_sqrt, singular_rtol

__all__ = [
    "body_twist",
    "damped_step",
    "damped_step_soa",
    "limited",
    "norm3",
    "promoted_pose",
    "rigid_target",
    "damped_step_looped",
    "spd_solve",
    "spd_solve_looped",
]


def spd_solve(a: Sequence[Sequence[Array]], b: list[Array]) -> list[Array]:
    """Solve ``a x = b`` for symmetric positive definite ``a`` (nested lists of batch arrays,
    row ``i`` at least ``i + 1`` long: the lower triangle is read) and ``b`` (m arrays), by an
    unrolled Cholesky factorisation."""
    m = len(b)
    tiny = float(jnp.finfo(jnp.result_type(b[0])).tiny) ** 0.5
    chol: dict[tuple[int, int], Array] = {}
    inv_diag: list[Array] = []
    for j in range(m):
        diag = a[j][j] - sum(chol[j, k] * chol[j, k] for k in range(j))
        inv = jax.lax.rsqrt(jnp.maximum(diag, tiny))
        inv_diag.append(inv)
        for i in range(j + 1, m):
            chol[i, j] = (a[i][j] - sum(chol[i, k] * chol[j, k] for k in range(j))) * inv
    y: list[Array] = []
    for i in range(m):
        y.append((b[i] - sum(chol[i, k] * y[k] for k in range(i))) * inv_diag[i])
    x: list[Array] = [b[0]] * m
    for i in range(m - 1, -1, -1):
        x[i] = (y[i] - sum(chol[k, i] * x[k] for k in range(i + 1, m))) * inv_diag[i]
    return x


def _computed(values: list[Array]) -> list[Array]:
    """``values`` stored once (``computed_once``): fused into every reader, they made the
    ``J J^T`` step ten times slower."""
    return list(computed_once(jnp.stack(jnp.broadcast_arrays(*values))))


def _dot(u: list[Array], v: list[Array]) -> Array:
    return sum((a * b for a, b in zip(u[1:], v[1:], strict=True)), u[0] * v[0])


def damped_step_soa(
    columns: list[list[Array]], twist: list[Array], damping: Array, floor: float | None = None
) -> list[Array]:
    """The step (module docstring) for ``columns``, the ``n`` columns of ``J`` (each ``r``
    arrays), and ``twist`` (``r`` arrays); ``floor`` ``sqrt(eps)`` by default."""
    n, r = len(columns), len(twist)
    gram = [[_dot(columns[i], columns[j]) for j in range(i + 1)] for i in range(n)]  # lower
    trace = gram[0][0] + (sum(gram[i][i] for i in range(1, n)) if n > 1 else 0.0)
    floor = singular_rtol(trace.dtype) if floor is None else floor
    mu = damping * damping + floor * trace
    if n <= r:
        for i in range(n):
            gram[i][i] = gram[i][i] + mu
        return spd_solve(gram, [_dot(col, twist) for col in columns])
    rows = [[col[k] for col in columns] for k in range(r)]  # rows of J
    outer = [[_dot(rows[i], rows[j]) for j in range(i + 1)] for i in range(r)]  # lower
    for i in range(r):
        outer[i][i] = outer[i][i] + mu
    lower = iter(_computed([outer[i][j] for i in range(r) for j in range(i + 1)]))
    outer = [[next(lower) for j in range(i + 1)] for i in range(r)]
    y = _computed(spd_solve(outer, twist))
    return [_dot(col, y) for col in columns]


def damped_step(jac: Array, twist: Array, damping, floor: float | None = None) -> Array:
    """Array front end of ``damped_step_soa``: ``jac`` (..., r, n), ``twist`` (..., r)."""
    batch = jnp.broadcast_shapes(jac.shape[:-2], twist.shape[:-1])
    r = jac.shape[-2]
    columns = [[jac[..., k, i] for k in range(r)] for i in range(jac.shape[-1])]
    twist_list = [twist[..., k] for k in range(r)]
    damping = jnp.asarray(damping, jac.dtype)
    dq = damped_step_soa(columns, twist_list, damping, floor)
    return jnp.stack([jnp.broadcast_to(x, batch) for x in dq], axis=-1)


def spd_solve_looped(a: Array, b: Array) -> Array:
    """Solve ``a x = b`` for symmetric positive definite ``a`` ``(..., k, k)`` and ``b``
    ``(..., k)`` by Gauss-Jordan elimination on ``[a | b]``, one loop over the ``k`` columns:
    the pivot row is divided by its pivot and subtracted from every other row, so the last
    column ends as ``x``. Without row exchanges: the pivots of a positive definite matrix are
    its Schur complements' diagonals, positive (a damped system's at least the damping); a
    pivot is clamped at ``sqrt(tiny)``, so a zero system gives ``x = 0``. One loop in the
    compiled program (a Cholesky factorisation and its two substitutions were three)."""
    k = b.shape[-1]
    tiny = float(jnp.finfo(b.dtype).tiny) ** 0.5
    rows = jnp.arange(k)
    augmented = jnp.concatenate([a, b[..., None]], -1)

    def eliminate(j, augmented):
        pivot = jnp.maximum(augmented[..., j, j], tiny)
        row = augmented[..., j, :] * (1.0 / pivot)[..., None]
        factor = jnp.where(rows == j, 0.0, augmented[..., :, j])
        augmented = augmented - factor[..., :, None] * row[..., None, :]
        return jnp.where((rows == j)[:, None], row[..., None, :], augmented)

    return jax.lax.fori_loop(0, k, eliminate, augmented)[..., k]


def damped_step_looped(
    jac: Array, twist: Array, damping: Array, floor: float | None = None, solve=spd_solve_looped
) -> Array:
    """The step of ``damped_step`` for ``jac`` ``(..., r, n)`` and ``twist`` ``(..., r)``, as
    array products and ``solve`` of the symmetric positive definite system
    (``spd_solve_looped``: a small compiled program, the chain IK)."""
    r, n = jac.shape[-2:]
    jac_t = jnp.swapaxes(jac, -1, -2)
    trace = jnp.sum(jac * jac, axis=(-2, -1))
    floor = singular_rtol(jac.dtype) if floor is None else floor
    mu = (damping * damping + floor * trace)[..., None, None]
    if n <= r:
        gram = jac_t @ jac + mu * jnp.eye(n, dtype=jac.dtype)
        return solve(gram, jnp.einsum("...ki,...k->...i", jac, twist))
    outer = jac @ jac_t + mu * jnp.eye(r, dtype=jac.dtype)
    return jnp.einsum("...ki,...k->...i", jac, solve(outer, twist))


def limited(dq: Array, revolute: ArrayLike, max_step: ArrayLike) -> Array:
    """``dq`` scaled, direction kept, so that no revolute joint moves more than ``max_step``."""
    largest = jnp.max(jnp.where(revolute, jnp.abs(dq), 0.0), axis=-1, keepdims=True)
    too_long = largest > max_step  # never true for max_step = inf (no limit)
    return dq * jnp.where(too_long, max_step / jnp.where(too_long, largest, 1.0), 1.0)


def body_twist(rot: Array, p: Array, target: Array) -> tuple[list[Array], list[Array]]:
    """``V_b = log(T^-1 T_d)`` (6 arrays) and ``p_bd = R^T (p_d - p)`` (3 arrays)."""
    rot_t = jnp.swapaxes(rot, -1, -2)
    rot_bd = rot_t @ target[..., :3, :3]
    p_bd = jnp.einsum("...ij,...j->...i", rot_t, target[..., :3, 3] - p)
    p_rows = [p_bd[..., r] for r in range(3)]
    twist = lie.se3_log_soa([[rot_bd[..., r, c] for c in range(3)] for r in range(3)], p_rows)
    return list(twist), p_rows


def rigid_target(target: Array) -> Array:
    """True where a target ``(..., 4, 4)`` is finite and its rotation block is a rotation:
    ``max |R^T R - I| <= sqrt(eps)`` and ``det R > 0`` (the twist to a non-rotation means
    nothing, and could meet a tolerance by chance); False for NaN or inf anywhere."""
    finite = all_finite(target.reshape(*target.shape[:-2], 16))
    rot = jnp.where(finite[..., None, None], target[..., :3, :3], jnp.eye(3, dtype=target.dtype))
    gram = jnp.swapaxes(rot, -1, -2) @ rot - jnp.eye(3, dtype=rot.dtype)
    orthonormal = jnp.max(jnp.abs(gram), axis=(-2, -1)) <= singular_rtol(rot.dtype)
    # det R = r_0 . (r_1 x r_2), elementwise: no LAPACK call (whose first use imports scipy).
    det = jnp.sum(rot[..., 0, :] * jnp.cross(rot[..., 1, :], rot[..., 2, :]), axis=-1)
    return finite & orthonormal & (det > 0)


def promoted_pose(target: Array, dtype: Any) -> Array:
    """Pose targets ``(..., 4, 4)`` in the work dtype ``dtype``. Given in a less precise
    floating dtype (float32 targets of a float64 chain), an element whose rotation block is a
    rotation to the precision of that dtype (``rigid_target`` in it) gets the nearest rotation
    in ``dtype``, the orthogonal polar factor of the block, by the iterations
    ``R <- R (3 I - R^T R) / 2`` [Bjorck and Bowie 1971] (quadratic: from
    ``|R^T R - I| <= sqrt(eps)`` of the given dtype to ``eps`` of ``dtype`` in the count
    computed here). The pose it stands for, to its own precision, so the IK's tolerances in
    ``dtype`` can be met; the translation is exact in ``dtype``. Any other element (not a
    rotation, NaN, inf) is only cast, and the IK's check in ``dtype`` refuses it. Otherwise a
    cast."""
    given = jnp.result_type(target)
    if not jnp.issubdtype(given, jnp.floating) or eps(given) <= eps(dtype):
        return target.astype(dtype)
    rigid = rigid_target(target)[..., None, None]
    pose = jnp.asarray(target).astype(dtype)
    eye = jnp.eye(3, dtype=dtype)
    rot = jnp.where(rigid, pose[..., :3, :3], eye)  # a harmless block where not used
    error = singular_rtol(given)
    while error > eps(dtype):
        rot = rot @ (1.5 * eye - 0.5 * jnp.swapaxes(rot, -1, -2) @ rot)
        error = error * error
    return pose.at[..., :3, :3].set(jnp.where(rigid, rot, pose[..., :3, :3]))


def norm3(x: list[Array]) -> Array:
    """``|x|`` of 3 arrays (finite gradient at 0)."""
    return safe_sqrt(x[0] * x[0] + x[1] * x[1] + x[2] * x[2])
