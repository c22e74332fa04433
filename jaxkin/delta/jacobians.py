"""The Delta's rates and singularities [Cardona, sec. III]: constraint Jacobians per chain.

With ``d_i = D_i - E_i`` and ``E_i' = dE_i/dtheta_i = -l_arm (sin th u_i + cos th e_z)``,
differentiating ``|d_i|^2 = l_rod^2`` gives ``J_p p_dot = J_theta theta_dot`` with the platform
Jacobian ``J_p = [d_1; d_2; d_3]`` and the actuator Jacobian ``J_theta = diag(d_i . E_i')``;
for the accelerations (``E_i'' = -(E_i - A_i)``)::

    d_i . p_ddot - (d_i . E_i') theta_ddot_i = (d_i . E_i'') theta_dot_i^2 - |d_i_dot|^2,
    d_i_dot = p_dot - E_i' theta_dot_i.

Singularity measures, both in [0, 1] and 0 at the singularity: inverse-type
``min_i |d_i . E_i'| / (l_arm l_rod)`` (a rod perpendicular to its elbow's velocity: the
workspace boundary, where the IK branches meet) and direct-type
``|det [d_1; d_2; d_3]| / l_rod^3`` (coplanar rods: the FK assemblies meet). A measure ``m``
with ``m^2 <= sqrt(eps(dtype))`` is ``SINGULAR`` (the square is what the solvers compute
without cancellation; see ``docs/conventions.md``).
"""

from __future__ import annotations

import dataclasses

import jax
import jax.numpy as jnp
from jax import Array

from .. import newton
from .._numerics import all_finite, computed_once, singular_rtol
from ..jet import Jet
from ..lie import cross_soa
from ..result import SolverResult
from ..status import STATUS_DTYPE, Status
from ._math import (
    UX,
    UY,
    DeltaRobot,
    components,
    constant_geometry_kernel,
    cos_sin,
    dot3,
    home,
    in_own_units,
    params,
)

__all__ = [
    "SingularityResult",
    "constraint_jacobians",
    "fk_rates",
    "ik_rates",
    "singularity_jit",
    "singularity_kernel",
]


@jax.tree_util.register_dataclass
@dataclasses.dataclass(frozen=True)
class SingularityResult(SolverResult):
    """Singularity measures, each in [0, 1] with 0 at the singularity, shape ``(...)``.

    Attributes:
        inverse: ``min_i |d_i . E_i'| / (l_arm l_rod)`` (actuator Jacobian degenerate).
        direct: ``|det [d_1; d_2; d_3]| / l_rod^3`` (platform Jacobian degenerate).
        status: ``SINGULAR`` where either measure squared is <= sqrt(eps), ``INVALID_INPUT``,
            or ``OK``.
    """

    inverse: Array
    direct: Array
    status: Array


def constraint_jacobians(robot: DeltaRobot, p, cos_theta, sin_theta):
    """Per chain ``i``: ``d_i = D_i - E_i`` (row i of ``J_p``), ``d_i . E_i'`` (``J_theta``),
    ``d_i . E_i''`` and ``E_i'``, all as components (batch-shaped arrays, see ``jaxkin.newton``).

    ``p``: the platform position as three components; ``cos_theta``, ``sin_theta``: three each.
    With ``R_i = r_base - r_platform + l_arm cos th_i`` (the module docstring's frame)::

        d_i = p - R_i u_i + l_arm sin th_i e_z,
        E_i' = -l_arm (sin th_i u_i + cos th_i e_z),   E_i'' = -(E_i - A_i),
        d_i . E_i'  = -l_arm (sin th_i (d_i . u_i) + cos th_i d_iz),
        d_i . E_i'' = -l_arm (cos th_i (d_i . u_i) - sin th_i d_iz).

    Component form, not stacked ``(..., 3, 3)`` arrays: XLA on CPU runs small minor axes as
    slow strided loops.
    """
    r_base, r_platform, l_arm, _, _, _ = params(robot, p[0].dtype)
    d, jt, d_dd, d_elbow = [], [], [], []
    for i in range(3):
        c, s = cos_theta[i], sin_theta[i]
        reach = r_base - r_platform + l_arm * c
        d_i = (p[0] - reach * UX[i], p[1] - reach * UY[i], p[2] + l_arm * s)
        radial = d_i[0] * UX[i] + d_i[1] * UY[i]  # d_i . u_i
        d.append(d_i)
        jt.append(-l_arm * (s * radial + c * d_i[2]))
        d_dd.append(-l_arm * (c * radial - s * d_i[2]))
        d_elbow.append((-l_arm * s * UX[i], -l_arm * s * UY[i], -l_arm * c))
    return d, jt, d_dd, d_elbow


def ik_rates(robot: DeltaRobot, p: Jet, theta: Array, cosines, ok: Array) -> Jet:
    """``J_theta theta_dot = J_p p_dot`` row by row, and its time derivative for theta_ddot.

    ``cosines``: ``(cos theta, sin theta)``, each ``(..., 3)``; rates are 0 where not ``ok``.
    """
    d, jt, d_dd, d_elbow = constraint_jacobians(
        robot, components(p.p), components(cosines[0]), components(cosines[1])
    )
    p_dot, p_ddot = components(p.v), components(p.a)
    theta_dot, theta_ddot = [], []
    for i in range(3):
        inv_jt = 1.0 / jnp.where(ok, jt[i], 1.0)
        rate = dot3(d[i], p_dot) * inv_jt
        d_dot = [p_dot[k] - d_elbow[i][k] * rate for k in range(3)]
        rhs = dot3(d[i], p_ddot) + dot3(d_dot, d_dot) - d_dd[i] * rate * rate
        theta_dot.append(jnp.where(ok, rate, 0.0))
        theta_ddot.append(jnp.where(ok, rhs * inv_jt, 0.0))
    return Jet(theta, jnp.stack(theta_dot, -1), jnp.stack(theta_ddot, -1))


def fk_rates(robot: DeltaRobot, theta: Jet, p: Array, ok: Array, cosines) -> Jet:
    """``J_p p_dot = J_theta theta_dot`` and its time derivative, solved per sample.

    ``cosines``: ``cos_sin(theta.p)`` (components); rates are 0 where not ``ok``.
    """
    d, jt, d_dd, d_elbow = constraint_jacobians(robot, components(p), *cosines)
    theta_dot, theta_ddot = components(theta.v), components(theta.a)
    p_dot = newton.solve_components(d, tuple(jt[i] * theta_dot[i] for i in range(3)))
    # Read by the three p_ddot loops: stored once, not recomputed (a solve each) by each.
    p_dot = tuple(computed_once(jnp.stack(p_dot)))
    rhs = []
    for i in range(3):
        d_dot = [p_dot[k] - d_elbow[i][k] * theta_dot[i] for k in range(3)]
        rhs.append(
            jt[i] * theta_ddot[i] + d_dd[i] * theta_dot[i] * theta_dot[i] - dot3(d_dot, d_dot)
        )
    p_ddot = newton.solve_components(d, tuple(rhs))
    zero = [jnp.where(ok, v, 0.0) for v in (*p_dot, *p_ddot)]
    return Jet(p, jnp.stack(zero[:3], -1), jnp.stack(zero[3:], -1))


def singularity_kernel(robot: DeltaRobot, p: Array, theta: Array) -> SingularityResult:
    """Both singularity measures at platform positions ``p`` and angles ``theta``, ``(..., 3)``
    each (same batch shape and dtype); non-finite input gives ``INVALID_INPUT``."""
    robot, scale = in_own_units(robot)
    p = p * (1.0 / jnp.asarray(scale, p.dtype))
    valid = all_finite(p) & all_finite(theta)
    p = jnp.where(valid[..., None], p, home(robot, p.dtype))
    theta = jnp.where(valid[..., None], theta, 0.0)
    _, _, l_arm, l_rod, _, _ = params(robot, p.dtype)
    d, jt, _, _ = constraint_jacobians(robot, components(p), *cos_sin(theta))
    inverse = jnp.minimum(jnp.minimum(jnp.abs(jt[0]), jnp.abs(jt[1])), jnp.abs(jt[2]))
    inverse = inverse / (l_arm * l_rod)
    direct = jnp.abs(dot3(d[0], cross_soa(d[1], d[2]))) / (l_rod * l_rod * l_rod)
    rtol = singular_rtol(p.dtype)
    status = jnp.where(
        ~valid,
        Status.INVALID_INPUT,
        jnp.where(
            (inverse * inverse <= rtol) | (direct * direct <= rtol), Status.SINGULAR, Status.OK
        ),
    ).astype(STATUS_DTYPE)
    return SingularityResult(inverse, direct, status)


singularity_jit = constant_geometry_kernel(singularity_kernel)
