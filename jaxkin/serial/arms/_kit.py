"""The analytic arms' kit: the planar two-link sub-problem, the ZYZ spherical wrist, polar
coordinates, angle wrapping, the status rule and a DH-table builder.

Shared conventions of the arm kernels (``jaxkin.serial.arms``): singular tests use
``tol = sqrt(eps(dtype)) * L``, ``L`` a length scale of the sub-problem (the sum of its link
lengths), so a target within ``tol`` outside the workspace is clamped onto its boundary
(``SINGULAR``, position error <= tol) rather than flagged unreachable; revolute outputs are
wrapped to ``[-pi, pi]``; an undetermined angle is set by ``guarded_atan2`` (double-where, finite
gradients). Nothing here knows an arm class.
"""

from __future__ import annotations

import dataclasses

import jax.numpy as jnp
import numpy as np
from jax import Array
from jax.typing import ArrayLike

from ..._numerics import safe_sqrt, singular_rtol
from ...status import STATUS_DTYPE, Status
from ..dh import DHTable

__all__ = [
    "HALF_PI",
    "PI",
    "TWO_PI",
    "TwoLinkSolution",
    "dh",
    "guarded_atan2",
    "polar",
    "status_from",
    "two_link",
    "wrap_angle",
    "zyz_wrist",
]

PI = float(np.pi)
TWO_PI = 2.0 * PI
HALF_PI = 0.5 * PI


def wrap_angle(x: Array) -> Array:
    """Wrap angles to ``[-pi, pi]`` (gradient 1 everywhere)."""
    return x - TWO_PI * jnp.round(x / TWO_PI)


def status_from(unreachable: Array, singular: Array) -> Array:
    """``UNREACHABLE`` before ``SINGULAR`` before ``OK``, as int8 codes."""
    return jnp.where(
        unreachable, Status.UNREACHABLE, jnp.where(singular, Status.SINGULAR, Status.OK)
    ).astype(STATUS_DTYPE)


def guarded_atan2(y: Array, x: Array, free: Array, fill: float | Array = 0.0) -> Array:
    """``atan2(y, x)``, or ``fill`` where ``free`` (the angle is undetermined: y = x = 0).

    Double-where: the arguments are replaced by ``(sin fill, cos fill)`` before ``atan2`` so
    the gradient stays finite at ``y = x = 0``.
    """
    fill = jnp.asarray(fill, y.dtype)
    return jnp.arctan2(jnp.where(free, jnp.sin(fill), y), jnp.where(free, jnp.cos(fill), x))


@dataclasses.dataclass(frozen=True)
class TwoLinkSolution:
    """Planar 2R sub-problem solution (see ``two_link``); every field has the broadcast shape."""

    q1: Array
    q2: Array
    c2: Array
    s2: Array
    unreachable: Array
    singular: Array


def two_link(x: Array, y: Array, l1: Array, l2: Array, elbow: ArrayLike) -> TwoLinkSolution:
    """Planar two-link inverse kinematics ([Pineiro], 2R; [Lopez-Villagomez, eqs. 11-14] corrected).

    Solves ``x = l1 cos q1 + l2 cos(q1 + q2)``, ``y = l1 sin q1 + l2 sin(q1 + q2)``::

        c2 = (x^2 + y^2 - l1^2 - l2^2) / (2 l1 l2),  s2 = elbow * sqrt(1 - c2^2)
        q2 = atan2(s2, c2)
        q1 = atan2(y, x) - atan2(l2 s2, l1 + l2 c2)
           = atan2(y k1 - x k2, x k1 + y k2),  k1 = l1 + l2 c2, k2 = l2 s2   (one atan2)

    ``elbow = -1`` puts the elbow to the left of the ray origin->target (``q2 <= 0``: "elbow
    up" when the target lies along +x), ``+1`` to the right. The reach test is on
    ``r = sqrt(x^2 + y^2)`` (docs/errata.md): unreachable when ``r > l1 + l2 + tol`` or
    ``r < |l1 - l2| - tol``; singular (both elbows coincide, ``c2 = +-1`` exactly) when ``r``
    is within ``tol = sqrt(eps) (l1 + l2)`` of either bound; at ``r <= tol`` (only reachable
    when ``l1 = l2``) ``q1`` is free and set to 0. Unreachable targets get the clamped, aligned
    configuration pointing at the target. All arrays broadcast together.
    """
    dtype = x.dtype
    tol = singular_rtol(dtype) * (l1 + l2)
    r2 = x * x + y * y
    r = safe_sqrt(r2)
    reach_out = l1 + l2
    reach_in = jnp.abs(l1 - l2)
    unreachable = (r > reach_out + tol) | (r < reach_in - tol)
    extended = jnp.abs(r - reach_out) <= tol
    folded = (jnp.abs(r - reach_in) <= tol) & ~extended
    coincident = r <= tol
    c2 = jnp.clip((r2 - l1 * l1 - l2 * l2) / (2.0 * l1 * l2), -1.0, 1.0)
    c2 = jnp.where(extended, 1.0, jnp.where(folded, -1.0, c2))
    elbow = jnp.asarray(elbow, dtype)
    s2_abs = safe_sqrt(1.0 - c2 * c2)
    s2 = elbow * s2_abs
    k1 = l1 + l2 * c2
    k2 = l2 * s2
    q1 = guarded_atan2(y * k1 - x * k2, x * k1 + y * k2, coincident)
    q2 = elbow * jnp.arctan2(s2_abs, c2)  # one atan2 for both elbows
    singular = (extended | folded | coincident) & ~unreachable
    shape = q1.shape
    c2 = jnp.broadcast_to(c2, shape)
    unreachable = jnp.broadcast_to(unreachable, shape)
    singular = jnp.broadcast_to(singular, shape)
    return TwoLinkSolution(q1, q2, c2, s2, unreachable, singular)


def zyz_wrist(rot: Array, sign: float, branch: ArrayLike) -> tuple[Array, Array, Array, Array]:
    """Spherical wrist: solve ``rot = Rz(t4) Ry(sign * t5) Rz(t6)`` for ``(t4, t5, t6)``.

    With ``beta = sign * t5``: ``rot[2, 2] = cos beta``, ``(rot[0, 2], rot[1, 2]) =
    sin beta (cos t4, sin t4)``, ``(rot[2, 0], rot[2, 1]) = sin beta (-cos t6, sin t6)``.
    ``branch = +1`` returns ``t5 >= 0`` and ``-1`` returns ``t5 <= 0`` (the "wrist flip"),
    with ``sin beta = sign * branch * sqrt(rot02^2 + rot12^2)``.

    Singular (``sqrt(rot02^2 + rot12^2) <= sqrt(eps)``: axes 4 and 6 aligned, only
    ``t4 +- t6`` is determined): ``t4 = 0``, ``t5 in {0, pi}`` and ``t6`` from
    ``Ry(-beta) rot = Rz(t6)``, i.e. ``t6 = atan2(rot10, cos(beta) rot00)``.

    Args:
        rot: ``(..., 3, 3)`` rotation matrices (assumed orthonormal).
        sign: the static ``+1`` / ``-1`` of the arm's DH wrist (Spong's ZYZ: +1; PUMA: -1).
        branch: ``+1`` / ``-1``, broadcastable against ``rot.shape[:-2]``.

    Returns:
        ``(t4, t5, t6, singular)`` with the broadcast batch shape.
    """
    r00, r02 = rot[..., 0, 0], rot[..., 0, 2]
    r10, r12 = rot[..., 1, 0], rot[..., 1, 2]
    r20, r21, r22 = rot[..., 2, 0], rot[..., 2, 1], rot[..., 2, 2]
    w = jnp.asarray(branch, rot.dtype) * sign  # sign of sin(beta)
    sin_abs = safe_sqrt(r02 * r02 + r12 * r12)
    singular = sin_abs <= singular_rtol(rot.dtype)
    sin_beta = jnp.where(singular, 0.0, w * sin_abs)
    beta = jnp.arctan2(sin_beta, r22)
    t4 = guarded_atan2(w * r12, w * r02, singular)
    cos_beta_sign = jnp.where(r22 >= 0.0, 1.0, -1.0)
    # One atan2 for both regimes; neither argument pair can vanish in its own regime
    # (regular: |(r21, r20)| = |sin beta| > tol; singular: |(r10, r00)| = 1), so the
    # gradient is finite without a further guard.
    t6 = jnp.arctan2(
        jnp.where(singular, r10, w * r21), jnp.where(singular, cos_beta_sign * r00, -w * r20)
    )
    return t4, sign * beta, t6, singular


def dh(dtype, a: list, alpha: list, d: list, theta: list, joint_types: str) -> DHTable:
    """A ``DHTable`` from lists mixing Python floats and scalar arrays (works on tracers)."""

    def col(values: list) -> Array:
        return jnp.stack([jnp.asarray(v, dtype) for v in values])

    return DHTable(col(a), col(alpha), col(d), col(theta), tuple(joint_types))


def polar(p: Array, height: Array, dtype) -> tuple[Array, Array]:
    """Front/back ``(q1, q2, rho)`` of a point seen from a shoulder at ``(0, 0, height)``.

    ``q1 = atan2(py, px)`` or ``+ pi``; ``q2 = atan2(s, +-r)`` (elevation, [Pineiro]'s Stanford
    ``theta2 = atan2(s, r)``, ``theta2' = pi - atan2(s, r)``); ``rho = sqrt(r^2 + s^2)``.
    Returns ``q`` ``(..., 2, 3)`` and the singular flag ``(..., 1)`` (on the base axis, or
    at the shoulder).
    """
    px, py, pz = p[..., 0], p[..., 1], p[..., 2]
    s = pz - height
    r = safe_sqrt(px * px + py * py)
    rho = safe_sqrt(r * r + s * s)
    tol = singular_rtol(dtype) * (jnp.abs(height) + rho)
    on_axis = r <= tol
    at_shoulder = rho <= tol
    q1_front = guarded_atan2(py, px, on_axis)
    q1 = jnp.stack([q1_front, wrap_angle(q1_front + PI)], axis=-1)
    q2 = guarded_atan2(s[..., None], jnp.stack([r, -r], axis=-1), at_shoulder[..., None])
    rho2 = jnp.broadcast_to(rho[..., None], q1.shape)
    q = jnp.stack([q1, q2, rho2], axis=-1)
    return q, (on_axis | at_shoulder)[..., None]
