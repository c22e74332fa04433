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
from jax.typing import ArrayLike

from .. import _validate, newton
from .._numerics import all_finite, computed_once, singular_rtol
from ..jet import Jet
from ..lie import cross_soa
from ..result import SolverResult
from ..status import STATUS_DTYPE, Status
from .geometry import (
    _UX,
    _UY,
    Delta,
    _components,
    _cos_sin,
    _dot3,
    _home,
    _params,
    as_coords,
    check_robot,
    compiled,
    float_dtype,
    in_own_units,
)

__all__ = ["SingularityResult", "singularity"]


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


def _constraint_jacobians(robot: Delta, p, cos_theta, sin_theta):
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
    r_base, r_platform, l_arm, _, _, _ = _params(robot, p[0].dtype)
    d, jt, d_dd, d_elbow = [], [], [], []
    for i in range(3):
        c, s = cos_theta[i], sin_theta[i]
        reach = r_base - r_platform + l_arm * c
        d_i = (p[0] - reach * _UX[i], p[1] - reach * _UY[i], p[2] + l_arm * s)
        radial = d_i[0] * _UX[i] + d_i[1] * _UY[i]  # d_i . u_i
        d.append(d_i)
        jt.append(-l_arm * (s * radial + c * d_i[2]))
        d_dd.append(-l_arm * (c * radial - s * d_i[2]))
        d_elbow.append((-l_arm * s * _UX[i], -l_arm * s * _UY[i], -l_arm * c))
    return d, jt, d_dd, d_elbow


def _ik_rates_analytic(robot, p: Jet, theta: Array, cos_sin, ok: Array) -> Jet:
    """``J_theta theta_dot = J_p p_dot`` row by row, and its time derivative for theta_ddot."""
    d, jt, d_dd, d_elbow = _constraint_jacobians(
        robot, _components(p.p), _components(cos_sin[0]), _components(cos_sin[1])
    )
    p_dot, p_ddot = _components(p.v), _components(p.a)
    theta_dot, theta_ddot = [], []
    for i in range(3):
        inv_jt = 1.0 / jnp.where(ok, jt[i], 1.0)
        rate = _dot3(d[i], p_dot) * inv_jt
        d_dot = [p_dot[k] - d_elbow[i][k] * rate for k in range(3)]
        rhs = _dot3(d[i], p_ddot) + _dot3(d_dot, d_dot) - d_dd[i] * rate * rate
        theta_dot.append(jnp.where(ok, rate, 0.0))
        theta_ddot.append(jnp.where(ok, rhs * inv_jt, 0.0))
    return Jet(theta, jnp.stack(theta_dot, -1), jnp.stack(theta_ddot, -1))


def _fk_rates_analytic(robot, theta: Jet, p: Array, ok: Array, cos_sin) -> Jet:
    """``J_p p_dot = J_theta theta_dot`` and its time derivative, solved per sample."""
    d, jt, d_dd, d_elbow = _constraint_jacobians(robot, _components(p), *cos_sin)
    theta_dot, theta_ddot = _components(theta.v), _components(theta.a)
    p_dot = newton.solve_components(d, tuple(jt[i] * theta_dot[i] for i in range(3)))
    # Read by the three p_ddot loops: stored once, not recomputed (a solve each) by each.
    p_dot = tuple(computed_once(jnp.stack(p_dot)))
    rhs = []
    for i in range(3):
        d_dot = [p_dot[k] - d_elbow[i][k] * theta_dot[i] for k in range(3)]
        rhs.append(
            jt[i] * theta_ddot[i] + d_dd[i] * theta_dot[i] * theta_dot[i] - _dot3(d_dot, d_dot)
        )
    p_ddot = newton.solve_components(d, tuple(rhs))
    zero = [jnp.where(ok, v, 0.0) for v in (*p_dot, *p_ddot)]
    return Jet(p, jnp.stack(zero[:3], -1), jnp.stack(zero[3:], -1))


def _singularity_impl(robot: Delta, p: Array, theta: Array) -> SingularityResult:
    robot, scale = in_own_units(robot)
    p = p * (1.0 / jnp.asarray(scale, p.dtype))
    valid = all_finite(p) & all_finite(theta)
    p = jnp.where(valid[..., None], p, _home(robot, p.dtype))
    theta = jnp.where(valid[..., None], theta, 0.0)
    _, _, l_arm, l_rod, _, _ = _params(robot, p.dtype)
    d, jt, _, _ = _constraint_jacobians(robot, _components(p), *_cos_sin(theta))
    inverse = jnp.minimum(jnp.minimum(jnp.abs(jt[0]), jnp.abs(jt[1])), jnp.abs(jt[2]))
    inverse = inverse / (l_arm * l_rod)
    direct = jnp.abs(_dot3(d[0], cross_soa(d[1], d[2]))) / (l_rod * l_rod * l_rod)
    rtol = singular_rtol(p.dtype)
    status = jnp.where(
        ~valid,
        Status.INVALID_INPUT,
        jnp.where(
            (inverse * inverse <= rtol) | (direct * direct <= rtol), Status.SINGULAR, Status.OK
        ),
    ).astype(STATUS_DTYPE)
    return SingularityResult(inverse, direct, status)


_singularity_jit = compiled(_singularity_impl)


def singularity(
    robot: Delta, p: ArrayLike, theta: ArrayLike | None = None, branch: str = "out"
) -> SingularityResult:
    """Inverse- and direct-type singularity measures at ``(p, theta)``, shape ``(...)``.

    ``theta`` defaults to ``ik(robot, p, branch).theta.p``. See the module docstring for the
    normalisation (both measures in [0, 1], 0 at the singularity).
    """
    robot = check_robot(robot)
    p = as_coords(p, "p")
    if theta is None:
        from .inverse import ik

        theta = ik(robot, p, branch=branch).q.p
    theta = as_coords(theta, "theta")
    shape = _validate.batch_shape({"p": p.shape[:-1], "theta": theta.shape[:-1]})
    dtype = float_dtype(p, theta)
    p = jnp.broadcast_to(p, (*shape, 3)).astype(dtype)
    theta = jnp.broadcast_to(theta, (*shape, 3)).astype(dtype)
    return _singularity_jit(robot, p, theta)
