"""SO(3) and SE(3) helpers: hat, vee, exp, log, inverse, adjoint (written once, used everywhere).

Conventions (Lynch & Park, "Modern Robotics", as in [Pineiro]): a rotation vector ``omega``
(..., 3) has angle ``t = |omega|``; ``hat(a) b = a x b``; a twist ``xi`` (..., 6) is ordered
``(omega, v)``; transforms are 4x4 ``[[R, p], [0, 1]]``; ``adjoint(T) = [[R, 0], [hat(p) R, R]]``
so that ``se3_hat(adjoint(T) xi) = T se3_hat(xi) T^-1``. Formulas::

    so3_exp(omega) = I + A hat(omega) + B hat(omega)^2                     (Rodrigues)
    se3_exp(omega, v) = [[so3_exp(omega), G v], [0, 1]],  G = I + B hat(omega) + C hat(omega)^2
    A = sin(t)/t,  B = (1 - cos t)/t^2,  C = (t - sin t)/t^3
    so3_log(R): t = atan2(|vee(R - R^T)| / 2, (tr R - 1) / 2) in [0, pi]
    se3_log(T): v = G^-1 p,  G^-1 = I - hat(omega)/2 + D hat(omega)^2,
                D = (1 - (t/2) cot(t/2)) / t^2

The ratios A, B, C, D are 0/0 at ``t = 0``: below ``t = 5 eps^(1/8)`` their Taylor series are
used, on a substituted safe angle (double-where), so values and gradients stay finite. Near
``t = pi`` the axis is read from the symmetric part ``(R + R^T)/2 - cos(t) I`` instead of
``R - R^T``. Everything is batched over leading axes, jit-able and follows the input dtype.
The ``*_soa`` helpers work on rotations as nested lists of batch arrays (for fused kernels).

Quaternions are ``(w, x, y, z)`` (Hamilton). ``quaternion_to_matrix`` is the quadratic map
``R = Q(s) / |s|^2`` (any non-zero length), with ``Q(s) = quaternion_bilinear(s, s)``;
``matrix_to_quaternion`` is Shepperd's method (of ``4 w^2 = 1 + tr R``, ``4 x^2 = 1 + 2 R_00
- tr R``, ... the largest is taken, the others read from off-diagonal sums and differences;
``w >= 0``); ``hemisphere_signs`` flips the signs of a sequence so that consecutive
quaternions lie in one hemisphere (``q`` and ``-q`` are one rotation). (Distances between
points, segments and boxes live in ``jaxkin.collision.distance``.)

The quaternion and sign functions, and ``vee``, take ``xp``: ``jax.numpy`` (the
default; traced by the caller's ``jit``) or ``numpy``, for path building on the host, which
stays in float64 whatever JAX's x64 setting. The formula is written once for both.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import jax.numpy as jnp
import numpy as np
from jax import Array
from jax.typing import ArrayLike

from ._execute import kernel
from ._numerics import computed_once, eps, safe_sqrt
from ._validate import as_float

__all__ = [
    "adjoint",
    "cross_soa",
    "from_rotation_translation",
    "hat",
    "hemisphere_signs",
    "matrix_to_quaternion",
    "quaternion_bilinear",
    "quaternion_product",
    "quaternion_rates_of_rotation",
    "quaternion_to_matrix",
    "rotation_rates_of_quaternion",
    "se3_exp",
    "se3_hat",
    "se3_inverse",
    "se3_log",
    "se3_vee",
    "so3_exp",
    "so3_log",
    "vee",
]


def _small_angle(dtype) -> float:
    """Angle below which the Taylor series of A, B, C, D are used (see module docstring)."""
    return 5.0 * eps(dtype) ** 0.125


@kernel
def hat(omega: ArrayLike) -> Array:
    """Skew-symmetric matrix of a 3-vector: ``(..., 3) -> (..., 3, 3)``, ``hat(a) b = a x b``."""
    omega = as_float(omega)
    x, y, z = omega[..., 0], omega[..., 1], omega[..., 2]
    zero = jnp.zeros_like(x)
    return jnp.stack(
        [
            jnp.stack([zero, -z, y], axis=-1),
            jnp.stack([z, zero, -x], axis=-1),
            jnp.stack([-y, x, zero], axis=-1),
        ],
        axis=-2,
    )


def vee(mat: XArray, *, xp: Any = jnp, skew: bool = False) -> XArray:
    """Inverse of ``hat``: ``(..., 3, 3) -> (..., 3)``.

    Reads the antisymmetric part ``(M - M^T) / 2``; with ``skew`` it reads ``(M_21, M_02,
    M_10)`` of a matrix skew-symmetric by construction (as ``R_dot R^T``) as it is.
    """
    mat = as_float(mat) if xp is jnp else np.asarray(mat, dtype=float)
    if skew:
        return xp.stack([mat[..., 2, 1], mat[..., 0, 2], mat[..., 1, 0]], -1)
    return 0.5 * xp.stack(
        [
            mat[..., 2, 1] - mat[..., 1, 2],
            mat[..., 0, 2] - mat[..., 2, 0],
            mat[..., 1, 0] - mat[..., 0, 1],
        ],
        axis=-1,
    )


@kernel
def se3_hat(xi: ArrayLike) -> Array:
    """4x4 matrix of a twist ``(omega, v)``: ``(..., 6) -> (..., 4, 4)``."""
    xi = as_float(xi)
    top = jnp.concatenate([hat(xi[..., :3]), xi[..., 3:, None]], axis=-1)
    bottom = jnp.zeros((*xi.shape[:-1], 1, 4), xi.dtype)
    return jnp.concatenate([top, bottom], axis=-2)


@kernel
def se3_vee(mat: ArrayLike) -> Array:
    """Inverse of ``se3_hat``: ``(..., 4, 4) -> (..., 6)`` ordered ``(omega, v)``."""
    mat = as_float(mat)
    return jnp.concatenate([vee(mat[..., :3, :3]), mat[..., :3, 3]], axis=-1)


def _exp_coefficients(theta_sq: Array) -> tuple[Array, Array, Array]:
    """``A = sin t / t``, ``B = (1 - cos t) / t^2``, ``C = (t - sin t) / t^3`` from ``t^2``."""
    small = theta_sq < _small_angle(theta_sq.dtype) ** 2
    # Double-where: the exact formulas see a safe angle where t is small.
    t_sq_safe = jnp.where(small, 1.0, theta_sq)
    t = jnp.sqrt(t_sq_safe)
    s, c = jnp.sin(t), jnp.cos(t)  # XLA's: _trig.sincos measured slower here (see so3_log)
    a_exact = s / t
    b_exact = (1.0 - c) / t_sq_safe
    c_exact = (t - s) / (t_sq_safe * t)
    t2 = theta_sq
    a_series = 1.0 - t2 / 6.0 * (1.0 - t2 / 20.0 * (1.0 - t2 / 42.0))
    b_series = 0.5 - t2 / 24.0 * (1.0 - t2 / 30.0 * (1.0 - t2 / 56.0))
    c_series = 1.0 / 6.0 - t2 / 120.0 * (1.0 - t2 / 42.0 * (1.0 - t2 / 72.0))
    return (
        jnp.where(small, a_series, a_exact),
        jnp.where(small, b_series, b_exact),
        jnp.where(small, c_series, c_exact),
    )


@kernel
def so3_exp(omega: ArrayLike) -> Array:
    """Rotation matrix of a rotation vector (Rodrigues): ``(..., 3) -> (..., 3, 3)``."""
    omega = as_float(omega)
    a, b, _ = _exp_coefficients(jnp.sum(omega * omega, axis=-1))
    k = hat(omega)
    eye = jnp.eye(3, dtype=omega.dtype)
    return eye + a[..., None, None] * k + b[..., None, None] * (k @ k)


@kernel
def se3_exp(xi: ArrayLike) -> Array:
    """Homogeneous transform of a twist ``(omega, v)``: ``(..., 6) -> (..., 4, 4)``.

    ``expm(se3_hat(xi))`` in closed form: ``R = I + A W + B W^2``, ``p = (I + B W + C W^2) v``
    with ``W = hat(omega)``.
    """
    xi = as_float(xi)
    omega, v = xi[..., :3], xi[..., 3:]
    a, b, c = _exp_coefficients(jnp.sum(omega * omega, axis=-1))
    k = hat(omega)
    k2 = k @ k
    eye = jnp.eye(3, dtype=xi.dtype)
    rot = eye + a[..., None, None] * k + b[..., None, None] * k2
    g = eye + b[..., None, None] * k + c[..., None, None] * k2
    p = jnp.einsum("...ij,...j->...i", g, v)
    return from_rotation_translation(rot, p)


@kernel
def from_rotation_translation(rot: ArrayLike, p: ArrayLike) -> Array:
    """Assemble ``[[R, p], [0, 1]]`` from ``R`` (..., 3, 3) and ``p`` (..., 3)."""
    rot, p = as_float(rot), as_float(p)
    batch = jnp.broadcast_shapes(rot.shape[:-2], p.shape[:-1])
    dtype = jnp.result_type(rot, p)
    rot = jnp.broadcast_to(rot, (*batch, 3, 3)).astype(dtype)
    p = jnp.broadcast_to(p, (*batch, 3)).astype(dtype)
    top = jnp.concatenate([rot, p[..., None]], axis=-1)
    bottom = jnp.broadcast_to(jnp.array([0.0, 0.0, 0.0, 1.0], dtype), (*batch, 1, 4))
    return jnp.concatenate([top, bottom], axis=-2)


# ----------------------------------------------------------------------------------------------
# Structure-of-arrays kernels, shared with the FK and IK kernels: a rotation is a 3 x 3 nested
# list of batch arrays (``None`` marks an entry known to be zero), a vector a list of three.
# All arithmetic is then elementwise, which XLA on CPU fuses into a few loops.

XArray = Any  # an array of the namespace ``xp`` of a function (NumPy or jax.numpy)
Rot = Sequence[Sequence[Array | None]]
FullRot = Sequence[Sequence[Array]]  # a rotation without structural zeros
Vec = Sequence[Array]


def unpack(transform: Array) -> tuple[FullRot, Vec]:
    """``(..., 4, 4)`` -> rotation and translation in the list representation."""
    rot = [[transform[..., r, c] for c in range(3)] for r in range(3)]
    return rot, [transform[..., r, 3] for r in range(3)]


def compose_soa(first: tuple[Rot, Vec], second: tuple[Rot, Vec]) -> tuple[Rot, Vec]:
    """``(R1, p1) (R2, p2) = (R1 R2, R1 p2 + p1)`` on the list representation."""
    rot1, p1 = first
    rot2, p2 = second
    rot: list[list[Array | None]] = []
    for r in range(3):
        row: list[Array | None] = []
        for c in range(3):
            pairs = ((rot1[r][k], rot2[k][c]) for k in range(3))
            terms = [a * b for a, b in pairs if a is not None and b is not None]
            row.append(sum(terms[1:], terms[0]) if terms else None)
        rot.append(row)
    p = [
        p1[r] + sum(a * b for a, b in zip(rot1[r], p2, strict=True) if a is not None)
        for r in range(3)
    ]
    return rot, p


def computed_once_soa(pose: tuple[Rot, Vec], batch: tuple[int, ...]) -> tuple[Rot, Vec]:
    """``pose`` stored once (``jaxkin._numerics.computed_once``), structural zeros kept.

    A chain of ``compose_soa`` calls is one expression per output entry; XLA's CPU fusion
    evaluates each entry's whole tree in its own loop, so shared partial products are
    recomputed. Storing a partial product cuts the trees.
    """
    rot, p = pose
    entries = [x for row in rot for x in row]
    given = [x for x in (*entries, *p) if x is not None]
    stored = iter(computed_once(jnp.stack([jnp.broadcast_to(x, batch) for x in given])))
    kept = [None if x is None else next(stored) for x in entries]
    return [kept[0:3], kept[3:6], kept[6:9]], [next(stored) for _ in p]


def rotate_soa(rot: Rot, x: Vec, transpose: bool = False) -> Vec:
    """``R x`` (or ``R^T x``) on the list representation."""
    out = []
    for r in range(3):
        terms = []
        for k in range(3):
            entry = rot[k][r] if transpose else rot[r][k]
            if entry is not None:
                terms.append(entry * x[k])
        out.append(sum(terms[1:], terms[0]))
    return out


def cross_soa(a: Vec, b: Vec) -> Vec:
    """``a x b`` of vectors given as three batch arrays (or scalars) each."""
    return [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]


def to_matrix_soa(pose: tuple[Rot, Vec], batch: tuple[int, ...], dtype) -> Array:
    """List representation -> ``(..., 4, 4)`` homogeneous matrices."""
    rot, p = pose
    zero = jnp.zeros(batch, dtype)
    rows = [
        jnp.stack(
            [jnp.broadcast_to(zero if x is None else x, batch) for x in (*rot[r], p[r])], axis=-1
        )
        for r in range(3)
    ]
    rows.append(jnp.broadcast_to(jnp.array([0.0, 0.0, 0.0, 1.0], dtype), (*batch, 4)))
    return jnp.stack(rows, axis=-2)


def so3_log_soa(rot: FullRot) -> tuple[Vec, Array, Array, Array]:
    """Rotation vector of ``R`` (module docstring), with ``t``, ``sin t``, ``cos t``.

    One transcendental call (``atan2``, an output): ``sin t`` and ``cos t`` are read
    algebraically from ``R``.
    """
    anti = [rot[2][1] - rot[1][2], rot[0][2] - rot[2][0], rot[1][0] - rot[0][1]]  # 2 sin t u
    s2 = safe_sqrt(anti[0] * anti[0] + anti[1] * anti[1] + anti[2] * anti[2])  # 2 sin t
    cos_t = jnp.clip(0.5 * (rot[0][0] + rot[1][1] + rot[2][2] - 1.0), -1.0, 1.0)
    sin_t = 0.5 * s2
    # XLA's atan2 here: theta feeds every output loop, and XLA would copy jaxkin._trig's
    # cheap-looking polynomial into each (measured slower in ik_newton).
    theta = jnp.arctan2(sin_t, cos_t)
    dtype = theta.dtype

    # Branch 1 (t <= pi/2): omega = t / (2 sin t) * anti, Taylor series near t = 0.
    t_sq = theta * theta
    small = theta < _small_angle(dtype)
    factor_exact = theta / jnp.where(small, 1.0, s2)
    factor_series = 0.5 + t_sq * (
        1.0 / 12.0 + t_sq * (7.0 / 720.0 + t_sq * (31.0 / 30240.0 + t_sq * 127.0 / 1209600.0))
    )
    factor = jnp.where(small, factor_series, factor_exact)

    # Branch 2 (t > pi/2): u u^T = ((R + R^T)/2 - cos t I) / (1 - cos t); take the column of
    # the largest diagonal entry (as argmax: first maximum), sign from anti.
    neg = cos_t < 0.0
    # One division each (XLA stores a shared quotient in a loop of its own).
    inv_one_minus_cos = 1.0 / jnp.where(neg, 1.0 - cos_t, 1.0)
    diag = [(rot[k][k] - cos_t) * inv_one_minus_cos for k in range(3)]

    def sym(i: int, j: int) -> Array:
        return diag[i] if i == j else 0.5 * (rot[i][j] + rot[j][i]) * inv_one_minus_cos

    pick0 = (diag[0] >= diag[1]) & (diag[0] >= diag[2])
    pick1 = ~pick0 & (diag[1] >= diag[2])

    def choose(values: list[Array]) -> Array:
        return jnp.where(pick0, values[0], jnp.where(pick1, values[1], values[2]))

    column = [choose([sym(i, 0), sym(i, 1), sym(i, 2)]) for i in range(3)]  # u * u_k
    inv_u_k = 1.0 / safe_sqrt(jnp.where(neg, choose(diag), 1.0))
    u = [column[i] * inv_u_k for i in range(3)]
    dot = u[0] * anti[0] + u[1] * anti[1] + u[2] * anti[2]
    scale = jnp.where(dot < 0.0, -theta, theta)
    omega = [jnp.where(neg, scale * u[i], factor * anti[i]) for i in range(3)]
    return omega, theta, sin_t, cos_t


def se3_log_soa(rot: FullRot, p: Vec) -> Vec:
    """Twist ``(omega, v)`` of ``(R, p)``: ``v = p - omega x p / 2 + D omega x (omega x p)``.

    ``D = (1 - (t/2) cot(t/2)) / t^2`` with ``cot(t/2) = sin t / (1 - cos t)`` (finite at
    ``t = pi``), Taylor series in ``t^2`` below the small-angle threshold.
    """
    omega, theta, sin_t, cos_t = so3_log_soa(rot)
    t_sq = theta * theta
    small = theta < _small_angle(theta.dtype)
    safe_t_sq = jnp.where(small, 1.0, t_sq)
    safe_one_minus_cos = jnp.where(small, 1.0, 1.0 - cos_t)
    d_exact = (1.0 - 0.5 * theta * sin_t / safe_one_minus_cos) / safe_t_sq
    d_series = 1.0 / 12.0 + t_sq * (1.0 / 720.0 + t_sq * (1.0 / 30240.0 + t_sq / 1209600.0))
    d = jnp.where(small, d_series, d_exact)
    wp = cross_soa(omega, p)
    wwp = cross_soa(omega, wp)
    return [*omega, *(p[i] - 0.5 * wp[i] + d * wwp[i] for i in range(3))]


@kernel
def so3_log(rot: ArrayLike) -> Array:
    """Rotation vector of a rotation matrix: ``(..., 3, 3) -> (..., 3)``, angle in [0, pi].

    Finite values and gradients at the identity and at half-turns (see module docstring).
    """
    rot = as_float(rot)
    omega, _, _, _ = so3_log_soa([[rot[..., r, c] for c in range(3)] for r in range(3)])
    return jnp.stack(omega, axis=-1)


@kernel
def se3_log(transform: ArrayLike) -> Array:
    """Twist ``(omega, v)`` of a homogeneous transform: ``(..., 4, 4) -> (..., 6)``.

    Inverse of ``se3_exp`` for rotation angles in [0, pi].
    """
    return jnp.stack(se3_log_soa(*unpack(as_float(transform))), axis=-1)


@kernel
def se3_inverse(transform: ArrayLike) -> Array:
    """Inverse of a homogeneous transform: ``[[R^T, -R^T p], [0, 1]]``, ``(..., 4, 4)``."""
    transform = as_float(transform)
    rot_t = jnp.swapaxes(transform[..., :3, :3], -1, -2)
    p = -jnp.einsum("...ij,...j->...i", rot_t, transform[..., :3, 3])
    return from_rotation_translation(rot_t, p)


@kernel
def adjoint(transform: ArrayLike) -> Array:
    """Adjoint of a transform on ``(omega, v)`` twists: ``(..., 4, 4) -> (..., 6, 6)``.

    ``[[R, 0], [hat(p) R, R]]``.
    """
    transform = as_float(transform)
    rot = transform[..., :3, :3]
    p_rot = hat(transform[..., :3, 3]) @ rot
    zero = jnp.zeros_like(rot)
    top = jnp.concatenate([rot, zero], axis=-1)
    bottom = jnp.concatenate([p_rot, rot], axis=-1)
    return jnp.concatenate([top, bottom], axis=-2)


# ----------------------------------------------------------------------------------------------
# Quaternions (w, x, y, z); ``xp`` is jax.numpy or numpy (module docstring).


def quaternion_bilinear(a: XArray, b: XArray, *, xp: Any = jnp) -> XArray:
    """The symmetric bilinear form with ``Q(s) = quaternion_bilinear(s, s)``: ``(..., 4)``
    twice -> ``(..., 3, 3)``; ``Q(s) / |s|^2`` is the rotation of ``s``, and being quadratic
    its derivatives along ``s(t)`` are exact (``rotation_rates_of_quaternion``)."""
    aw, ax, ay, az = xp.moveaxis(a, -1, 0)
    bw, bx, by, bz = xp.moveaxis(b, -1, 0)
    rows = [
        [aw * bw + ax * bx - ay * by - az * bz, ax * by + ay * bx - (aw * bz + az * bw),
         ax * bz + az * bx + (aw * by + ay * bw)],
        [ax * by + ay * bx + (aw * bz + az * bw), aw * bw - ax * bx + ay * by - az * bz,
         ay * bz + az * by - (aw * bx + ax * bw)],
        [ax * bz + az * bx - (aw * by + ay * bw), ay * bz + az * by + (aw * bx + ax * bw),
         aw * bw - ax * bx - ay * by + az * bz],
    ]  # fmt: skip
    return xp.stack([xp.stack(r, -1) for r in rows], -2)


def quaternion_to_matrix(quat: XArray, *, xp: Any = jnp) -> XArray:
    """Rotation matrix ``Q(s) / |s|^2`` of quaternions ``(..., 4)`` of any non-zero length:
    ``(..., 3, 3)``."""
    return rotation_rates_of_quaternion(quat, None, None, xp=xp)[0]


def rotation_rates_of_quaternion(
    s: XArray, ds: XArray | None, dds: XArray | None, *, xp: Any = jnp
) -> tuple[Array, Array | None, Array | None]:
    """``R``, ``R_dot``, ``R_ddot`` of ``R(s) = Q(s) / |s|^2`` along a quaternion curve ``s(t)``
    (``s`` any non-zero quaternion ``(..., 4)``, rates ``ds``, ``dds``; ``Q`` quadratic, so the
    rates are exact). With ``ds`` and ``dds`` None only ``R`` is computed."""
    norm2 = xp.sum(s * s, -1)[..., None, None]
    rot = quaternion_bilinear(s, s, xp=xp) / norm2
    if ds is None or dds is None:
        return rot, None, None
    d_norm2 = 2.0 * xp.sum(s * ds, -1)[..., None, None]
    dd_norm2 = 2.0 * xp.sum(ds * ds + s * dds, -1)[..., None, None]
    d_q = 2.0 * quaternion_bilinear(s, ds, xp=xp)
    dd_q = 2.0 * quaternion_bilinear(ds, ds, xp=xp) + 2.0 * quaternion_bilinear(s, dds, xp=xp)
    d_rot = (d_q - rot * d_norm2) / norm2
    dd_rot = (dd_q - 2.0 * d_rot * d_norm2 - rot * dd_norm2) / norm2
    return rot, d_rot, dd_rot


def quaternion_product(a: XArray, b: XArray, *, xp: Any = jnp) -> XArray:
    """Hamilton product of quaternions ``(..., 4)``."""
    aw, av, bw, bv = a[..., :1], a[..., 1:], b[..., :1], b[..., 1:]
    return xp.concatenate([aw * bw - xp.sum(av * bv, -1, keepdims=True),
                           aw * bv + bw * av + xp.cross(av, bv)], -1)  # fmt: skip


def matrix_to_quaternion(rot: XArray, *, xp: Any = jnp) -> XArray:
    """Unit quaternion ``(..., 4)`` of rotation matrices ``(..., 3, 3)`` by Shepperd's method,
    ``w >= 0`` (module docstring)."""
    trace = xp.trace(rot, axis1=-2, axis2=-1)[..., None]
    # Of 4 w^2 = 1 + tr, 4 x^2 = 1 + 2 R_00 - tr, ..., the largest is well conditioned.
    squares = 1.0 + xp.concatenate([trace, 2.0 * xp.diagonal(rot, 0, -2, -1) - trace], -1)
    big = xp.argmax(squares, -1)
    s = xp.sqrt(xp.maximum(xp.take_along_axis(squares, big[..., None], -1)[..., 0], 0.0))
    m = rot
    odd = xp.stack([m[..., 2, 1] - m[..., 1, 2], m[..., 0, 2] - m[..., 2, 0],
                    m[..., 1, 0] - m[..., 0, 1]], -1)  # fmt: skip
    even = xp.stack([m[..., 0, 1] + m[..., 1, 0], m[..., 0, 2] + m[..., 2, 0],
                     m[..., 1, 2] + m[..., 2, 1]], -1)  # fmt: skip
    half = 0.5 * s
    inv = xp.where(s > 0, 0.5 / xp.where(s > 0, s, 1.0), 0.0)
    cases = [
        xp.stack([half, odd[..., 0] * inv, odd[..., 1] * inv, odd[..., 2] * inv], -1),
        xp.stack([odd[..., 0] * inv, half, even[..., 0] * inv, even[..., 1] * inv], -1),
        xp.stack([odd[..., 1] * inv, even[..., 0] * inv, half, even[..., 2] * inv], -1),
        xp.stack([odd[..., 2] * inv, even[..., 1] * inv, even[..., 2] * inv, half], -1),
    ]
    quat = cases[3]
    for k in (2, 1, 0):
        quat = xp.where(big[..., None] == k, cases[k], quat)
    quat = xp.where(quat[..., :1] < 0, -quat, quat)
    return quat / xp.linalg.norm(quat, axis=-1, keepdims=True)


def quaternion_rates_of_rotation(
    rot: XArray, d_rot: XArray, dd_rot: XArray, *, xp: Any = jnp
) -> tuple[XArray, XArray, XArray]:
    """Unit quaternion of ``R`` (``matrix_to_quaternion``) and its rates along ``R(t)``.

    From the angular velocity ``[omega]_x = R_dot R^T`` and acceleration ``[alpha]_x = R_ddot
    R^T + R_dot R_dot^T``: ``q_dot = (0, omega) q / 2``, ``q_ddot = ((0, alpha) q + (0, omega)
    q_dot) / 2`` (Hamilton products). Each ``(..., 4)``.
    """
    quat = matrix_to_quaternion(rot, xp=xp)
    transpose = xp.swapaxes(rot, -1, -2)
    omega = vee(d_rot @ transpose, xp=xp, skew=True)
    alpha = vee(dd_rot @ transpose + d_rot @ xp.swapaxes(d_rot, -1, -2), xp=xp, skew=True)
    zero = xp.zeros_like(omega[..., :1])
    d_quat = 0.5 * quaternion_product(xp.concatenate([zero, omega], -1), quat, xp=xp)
    dd_quat = 0.5 * (
        quaternion_product(xp.concatenate([zero, alpha], -1), quat, xp=xp)
        + quaternion_product(xp.concatenate([zero, omega], -1), d_quat, xp=xp)
    )
    return quat, d_quat, dd_quat


def hemisphere_signs(quaternions: XArray, *, xp: Any = jnp) -> XArray:
    """Signs ``(..., T)`` (+-1) that put consecutive quaternions ``(..., T, 4)`` in one
    hemisphere (``q`` and ``-q`` are one rotation; a spline through them needs one sign); the
    first sample keeps its own."""
    q = quaternions
    flips = xp.where(xp.sum(q[..., 1:, :] * q[..., :-1, :], -1) < 0.0, -1.0, 1.0)
    return xp.concatenate([xp.ones_like(q[..., :1, 0]), xp.cumprod(flips, axis=-1)], -1)
