"""The Delta's inverse kinematics in closed form [Cardona, eqs. 1-7], with rates.

Per chain, with ``Q_i = p - (r_base - r_platform) u_i``, its radial and tangential coordinates
``a = Q_i . u_i``, ``b = Q_i . (e_z x u_i)`` and ``z``, the constraint is
``2 T L cos th + 2 z L sin th = K`` (eq. 5) with ``T = -a``, ``L = l_arm`` and
``K = l_rod^2 - b^2 - T^2 - L^2 - z^2``; with ``t = tan(th / 2)`` it is
``e1 t^2 + e2 t + e3 = 0`` (eq. 6) with ``e1 = K + 2 T L``, ``e2 = -4 z L``,
``e3 = K - 2 T L`` and discriminant ``D = e2^2 - 4 e1 e3``. The roots are taken in the stable
form ``t = 2 e3 / (-e2 -/+ sqrt(D))`` (eq. 7 divides by ``e1``, which changes sign inside the
workspace): the elbow-out root (``branch="out"``, the default: elbows farther from the z axis)
is ``t = -2 e3 / (e2 + sign(e2) sqrt(D))``, the elbow-in one
``t = -(e2 + sign(e2) sqrt(D)) / (2 e1)``; ``theta = 2 atan2(num, den)`` with ``den >= 0``.
Which printed root is which branch is in ``docs/errata.md``.

Statuses: ``INVALID_INPUT`` (non-finite p), ``UNREACHABLE`` (some chain has
``D / (4 l_arm l_rod)^2 < -sqrt(eps)``), ``SINGULAR`` (``|D| / (4 l_arm l_rod)^2 <= sqrt(eps)``:
the workspace boundary; position valid, rates 0), ``OUT_OF_LIMITS``, ``OK``. ``margin`` is the
smallest signed inverse-type measure ``sign(D) sqrt(|D|) / (4 l_arm l_rod)`` over the chains:
the inverse-type singularity measure at a solution, negative outside the workspace.
Unreachable targets get the angle of the nearest (tangent) configuration.
"""

from __future__ import annotations

import jax.numpy as jnp
from jax import Array
from jax.typing import ArrayLike

from .._numerics import safe_sqrt, singular_rtol
from ..jet import Jet, lift
from ..result import IKResult
from ..status import STATUS_DTYPE, Status
from ._math import (
    DeltaRobot,
    any3,
    far_away,
    home,
    in_own_units,
    params,
    radial,
    rates_ok,
    sanitise,
)
from .jacobians import ik_rates
from .options import DeltaIKOptions

__all__ = ["ik_kernel"]


def _ik_position(robot: DeltaRobot, p: Array, branch: str) -> tuple[Array, Array, Array, Array]:
    """Actuator angles, their cosines and sines, and the signed inverse measure, ``(..., 3)``."""
    dtype = p.dtype
    r_base, r_platform, l_arm, l_rod, _, _ = params(robot, dtype)
    ux, uy = radial(dtype)
    x, y, z = p[..., 0:1], p[..., 1:2], p[..., 2:3]  # broadcast against the chain axis
    a = x * ux + y * uy - (r_base - r_platform)  # radial coordinate of Q_i from A_i
    b = -x * uy + y * ux  # tangential coordinate
    t_coef = -a  # the paper's T
    # Eq. 5: 2 T L cos(theta) + 2 z L sin(theta) = K.
    k = l_rod * l_rod - b * b - t_coef * t_coef - l_arm * l_arm - z * z
    e1 = k + 2.0 * t_coef * l_arm  # eq. 6 (its "e - 3" read as e3, docs/errata.md)
    e2 = -4.0 * z * l_arm
    e3 = k - 2.0 * t_coef * l_arm
    disc = e2 * e2 - 4.0 * e1 * e3
    sqrt_disc = safe_sqrt(disc)
    sign_e2 = jnp.where(e2 >= 0, 1.0, -1.0).astype(dtype)
    big = jnp.abs(e2) + sqrt_disc  # |e2 + sign(e2) sqrt(D)|, never a cancellation
    if branch == "out":
        # t_out = -2 e3 / (e2 + sign(e2) sqrt(D)) (stable form of eq. 7, see module docstring).
        num, den = -2.0 * e3 * sign_e2, big
    else:
        # t_in = -(e2 + sign(e2) sqrt(D)) / (2 e1).
        sign_e1 = jnp.where(e1 >= 0, 1.0, -1.0).astype(dtype)
        num, den = -sign_e2 * big * sign_e1, 2.0 * jnp.abs(e1)
    degenerate = (num == 0) & (den == 0)  # z = 0 and D = 0 and e3 = 0: any angle; take 0
    den = jnp.where(degenerate, 1.0, den)
    # XLA's atan2, not jaxkin._trig.atan2: inside the planner the polynomial measured slower.
    theta = 2.0 * jnp.arctan2(num, den)
    # cos and sin of theta = 2 atan2(num, den), algebraically (no further transcendentals).
    norm_sq = num * num + den * den
    cos_theta = (den * den - num * num) / norm_sq
    sin_theta = 2.0 * num * den / norm_sq
    # Signed inverse measure sign(D) sqrt(|D|) / (4 L l_rod). With rho the distance from A_i to
    # the in-plane projection Q_i' and alpha the angle at A_i of the triangle (A_i, E_i, Q_i'),
    # sqrt(D) = 4 L rho sin(alpha) and |d_i . E_i'| = L rho sin(alpha) (law of sines), so at a
    # solution this is exactly the inverse-type measure |d_i . E_i'| / (l_arm l_rod).
    signed = jnp.where(disc >= 0, sqrt_disc, -safe_sqrt(-disc)) / (4.0 * l_arm * l_rod)
    return theta, cos_theta, sin_theta, signed


def _ik_status(robot: DeltaRobot, theta: Array, signed: Array, valid: Array) -> Array:
    _, _, _, _, lo, hi = params(robot, theta.dtype)
    rtol = singular_rtol(theta.dtype)
    margin = jnp.minimum(jnp.minimum(signed[..., 0], signed[..., 1]), signed[..., 2])
    margin_sq = jnp.sign(margin) * margin * margin  # D / (4 l_arm l_rod)^2, signed
    out_of_limits = any3((theta < lo) | (theta > hi))
    return jnp.where(
        ~valid,
        Status.INVALID_INPUT,
        jnp.where(
            margin_sq < -rtol,
            Status.UNREACHABLE,
            jnp.where(
                margin_sq <= rtol,
                Status.SINGULAR,
                jnp.where(out_of_limits, Status.OUT_OF_LIMITS, Status.OK),
            ),
        ),
    ).astype(STATUS_DTYPE)


def _ik_impl(robot: DeltaRobot, p: Jet, branch: str, method: str, rates: bool) -> IKResult:
    """Actuator angles (rates where ``rates``; else ``p.v``, ``p.a`` are None and the result's
    rates are 0) for platform positions ``p`` ``(..., 3)`` on ``branch`` ("out" or "in").
    """
    # Non-finite input is replaced first (double-where), then the kernel works in units of
    # the robot's size.
    p, valid = sanitise(p, jnp.zeros((3,), p.p.dtype), rates)
    robot, scale = in_own_units(robot)
    inv_scale = 1.0 / jnp.asarray(scale, p.p.dtype)
    p = Jet(*(None if x is None else x * inv_scale for x in (p.p, p.v, p.a)))
    rest = home(robot, p.p.dtype)
    p = Jet(jnp.where(valid[..., None], p.p, rest), p.v, p.a)
    far = far_away(p.p)  # certainly unreachable: solved at the home pose instead, then flagged
    fills: tuple[ArrayLike, ...] = (home(robot, p.p.dtype), 0.0, 0.0)
    p = Jet(
        *(
            None if x is None else jnp.where(far[..., None], fill, x)
            for x, fill in zip((p.p, p.v, p.a), fills, strict=True)
        )
    )

    def checked(status):
        return jnp.where(far & valid, jnp.int8(Status.UNREACHABLE), status)

    if method == "analytic" or not rates:
        theta, cos_theta, sin_theta, signed = _ik_position(robot, p.p, branch)
        status = checked(_ik_status(robot, theta, signed, valid))
        if rates:
            ok = rates_ok(status)
            theta_jet = ik_rates(robot, p, theta, (cos_theta, sin_theta), ok)
        else:
            theta_jet = Jet.constant(theta)
    else:

        def position(x):
            theta, _, _, signed = _ik_position(robot, x, branch)
            return theta, signed

        theta_j, signed_j = lift(position)(p)
        status = checked(_ik_status(robot, theta_j.p, signed_j.p, valid))
        okc = rates_ok(status)[..., None]
        theta_jet = Jet(theta_j.p, jnp.where(okc, theta_j.v, 0.0), jnp.where(okc, theta_j.a, 0.0))
        signed = signed_j.p
    margin = jnp.clip(jnp.min(signed, axis=-1), -1.0, 1.0)
    margin = jnp.where(valid & ~far, margin, -1.0)
    return IKResult(theta_jet, status, margin)


def ik_kernel(
    robot: DeltaRobot, p: Jet, branch: str, options: DeltaIKOptions, rates: bool
) -> IKResult:
    """The robot protocol's IK kernel (``Delta.ik_kernel``): at rest no rate is read."""
    return _ik_impl(robot, p if rates else Jet.positions(p.p), branch, options.method, rates)
