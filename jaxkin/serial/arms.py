"""Analytic inverse kinematics of the textbook arms, every branch at once, and their FK.

=========================  ====================  ==============  ========  ========
arm                        module                target          branches  joints
=========================  ====================  ==============  ========  ========
``Planar2R(l1, l2)``       ``arms_planar``       ``(x, y)``      2         RR
``Planar3R(l1, l2, l3)``   ``arms_planar``       ``(x, y, phi)`` 2         RRR
``Anthropomorphic``        ``arms_3dof``         point           4         RRR
``Cylindrical(h)``         ``arms_3dof``         point           1         RPP
``Spherical(h)``           ``arms_3dof``         point           2         RRP
``Puma560(...)``           ``arms_6dof``         4x4 pose        8         6R
``Stanford(d1, a2)``       ``arms_6dof``         4x4 pose        4         RRPRRR
=========================  ====================  ==============  ========  ========

``ik(robot, target)``: every branch, ``ArmIKResult`` with ``q`` ``(..., n_branches, n_joints)``,
``valid`` and ``status`` ``(..., n_branches)``; ``branch="front_up"`` (or
``result.branch("front_up")``) selects one. ``ik_jet(robot, target, branch)`` (what
``jaxkin.ik`` calls): one branch with joint rates (``jaxkin.lift`` of the position IK; a pose
target is a Jet of 4x4 matrices) and a margin. ``fk(robot, q)``: an ``FKResult`` whose ``x`` is
in the form of the targets (``jaxkin.fk(serial.from_dh(robot.dh_table()), q).x.p`` gives the
4x4 transform).

Statuses per branch: ``OK``; ``SINGULAR`` (the target is reproduced but a joint is free or
branches coincide: the documented choice is returned); ``UNREACHABLE`` (``q`` is the clamped,
aligned placeholder); ``INVALID_INPUT`` (NaN/inf in the target: ``q = 0``). Rates are 0 where
not OK; everything is finite and so are gradients of status-masked losses (double-where).
The margin is the isotropy (``jaxkin._numerics.isotropy``) of the task Jacobian in
units of the arm's size: in [0, 1], 0 at a singularity; minus the distance to the target in
units of that size where unreachable; -1 for invalid input. Accuracy in float64 and float32:
``docs/performance.md``; formulas: ``docs/robots.md``.
"""

from __future__ import annotations

import jax.numpy as jnp
from jax import Array
from jax.typing import ArrayLike

from .._numerics import isotropy, safe_norm
from ..jet import Jet, lift
from ..result import FKResult, IKResult, forward_result
from ..robot import PLANAR_POINT, PLANAR_POSE, POINT, POSE, solve_fk, solve_ik
from ..status import Status
from . import _kinematics
from . import dh as _dh
from ._arms_common import Arm, ArmIKResult, _ik_impl, check_robot, ik_arm
from .arms_3dof import Anthropomorphic, Cylindrical, Spherical
from .arms_6dof import Puma560, Stanford
from .arms_planar import Planar2R, Planar3R

__all__ = [
    "ARMS",
    "Anthropomorphic",
    "ArmIKResult",
    "Cylindrical",
    "Planar2R",
    "Planar3R",
    "Puma560",
    "Spherical",
    "Stanford",
    "fk",
    "ik",
    "ik_jet",
]

ARMS: tuple[type[Arm], ...] = (
    Planar2R,
    Planar3R,
    Anthropomorphic,
    Cylindrical,
    Spherical,
    Puma560,
    Stanford,
)


def _task(robot: Arm, q: Array) -> Array:
    """The forward kinematics in the form of the arm's targets, ``(..., *target.shape)``."""
    frame = _dh.transforms(robot.dh_table(q.dtype), q)
    if robot.target is PLANAR_POINT:
        return frame[..., :2, 3]
    if robot.target is PLANAR_POSE:
        phi = jnp.arctan2(frame[..., 1, 0], frame[..., 0, 0])
        return jnp.concatenate([frame[..., :2, 3], phi[..., None]], axis=-1)
    if robot.target is POINT:
        return frame[..., :3, 3]
    return frame


def _position(x: Array, robot: Arm) -> Array:
    """The position part of a target, ``(..., 2 or 3)``."""
    if robot.target is PLANAR_POSE:
        return x[..., :2]
    if robot.target is POSE:
        return x[..., :3, 3]
    return x


def _scaled_jacobian(robot: Arm, q: Array, scale: Array) -> tuple[Array, Array]:
    """The task Jacobian in units of the arm's size, ``(..., m, n)``, and the end point.

    From the space Jacobian of the arm's PoE chain (one pass): the end point's velocity is
    ``v_s + omega_s x p``; a pose takes the body twist ``(R^T omega_s, R^T p_dot)``, a planar
    pose ``(x_dot, y_dot, omega_z)``. Length rows are divided, prismatic columns multiplied,
    by ``scale``.
    """
    screws, home = _dh.screws(robot.dh_table(q.dtype))
    rot, p, jac = _kinematics.screws_fk_and_jacobian(screws, home, q, "space")
    omega, v = jac[..., :3, :], jac[..., 3:, :]
    p_dot = v + jnp.cross(omega, p[..., :, None], axis=-2)
    inv = 1.0 / scale[..., None, None]
    if robot.target is POSE:
        rot_t = jnp.swapaxes(rot, -1, -2)
        rows = jnp.concatenate([rot_t @ omega, (rot_t @ p_dot) * inv], axis=-2)
    elif robot.target is PLANAR_POSE:
        rows = jnp.concatenate([p_dot[..., :2, :] * inv, omega[..., 2:, :]], axis=-2)
    else:
        rows = p_dot[..., : robot.target.shape[0], :] * inv
    prismatic = jnp.asarray([kind == "P" for kind in robot.JOINT_TYPES])
    rows = rows * jnp.where(prismatic, scale[..., None], 1.0)[..., None, :]
    return rows, p


def _margin(robot: Arm, q: Array, target: Array, status: Array) -> Array:
    """``isotropy`` of the scaled task Jacobian where solved (0 at a singularity); where the
    target is unreachable minus the distance from the placeholder's end point to the target in
    units of the arm's size (at most 1); -1 for invalid input."""
    dtype = q.dtype
    scale = jnp.broadcast_to(jnp.asarray(robot.length_scale(), dtype), status.shape)
    scale = jnp.where(scale > 0, scale, 1.0)
    jac, end = _scaled_jacobian(robot, q, scale)
    ratio = isotropy(jac)
    dims = _position(target, robot).shape[-1]
    error = safe_norm(end[..., :dims] - _position(target, robot)) / scale
    return jnp.where(
        status == Status.INVALID_INPUT,
        -1.0,
        jnp.where(status == Status.UNREACHABLE, -jnp.minimum(error, 1.0), ratio),
    ).astype(dtype)


def ik(robot: Arm, target: ArrayLike, branch: str | None = None) -> ArmIKResult:
    """The analytic IK of ``robot``: every branch at once, or the one named by ``branch``.

    Args:
        robot: one of ``ARMS`` (e.g. ``Anthropomorphic(l1, l2, l3)``).
        target: ``(..., *robot.TARGET_SHAPE)``: ``(x, y)`` for ``Planar2R``, ``(x, y, phi)``
            for ``Planar3R``, the wrist position ``(x, y, z)`` for the 3-joint arms and a 4x4
            homogeneous transform for ``Puma560`` and ``Stanford``.
        branch: None for every branch (``q`` ``(..., n_branches, n_joints)``), or a branch
            name (``q`` ``(..., n_joints)``).

    Returns:
        ``ArmIKResult`` (``q``, ``valid``, ``status``, ``branches``); dtype follows ``target``.

    Raises:
        ValueError: unknown robot type or branch, or a target of the wrong trailing shape.
    """
    check_robot(robot, ARMS)
    result = ik_arm(robot, target)
    return result if branch is None else result.branch(branch)


def _ik_jet_core(robot: Arm, target: Jet, index: Array, rates: bool) -> IKResult:
    def position(x):
        res = _ik_impl(robot, x)
        return res.q, res.status

    # Every branch is solved anyway; the branch is picked by a traced index (one compilation
    # serves every branch).
    if rates:
        q_all, status_all = lift(position)(target)
    else:
        q_all, status_all = position(target.p)
        q_all = Jet.constant(q_all)
    q = q_all.map(lambda x: jnp.take(x, index, axis=-2))
    status = jnp.take(status_all, index, axis=-1)
    ok = (status == Status.OK)[..., None]
    q = Jet(q.p, jnp.where(ok, q.v, 0.0), jnp.where(ok, q.a, 0.0))
    return IKResult(q, status, _margin(robot, q.p, target.p, status))


def ik_jet(robot: Arm, target: Jet | ArrayLike, branch: str | None = None) -> IKResult:
    """One branch of the analytic IK with joint velocity and acceleration, and a margin
    (``jaxkin.ik`` of an arm).

    The rates come from ``jaxkin.lift`` (nested forward-mode jvp) of the position-level IK,
    compiled once; they are 0 where the branch's status is not ``OK``. A pose target's Jet holds
    4x4 matrices and their time derivatives.

    Args:
        robot: one of ``ARMS``.
        target: Jet (or array, at rest) of shape ``(..., *robot.target.shape)``.
        branch: one of the robot's branch names (None: the first, ``robot.default_branch``).

    Returns:
        ``IKResult``: ``q`` (Jet ``(..., n_joints)``), ``status`` and ``margin`` (``(...)``;
        see ``_margin``: the Jacobian's isotropy in [0, 1] where solved, negative outside
        the workspace, -1 for invalid input).
    """
    check_robot(robot, ARMS)
    return solve_ik(robot, target, branch, robot.IKOptions())


def _fk_core(robot: Arm, q: Jet, rates: bool) -> FKResult:
    return forward_result(lambda joints: _task(robot, joints), q, rates, len(robot.TARGET_SHAPE))


def fk(robot: Arm, q: Jet | ArrayLike) -> FKResult:
    """Forward kinematics of an analytic arm in the form of its targets (``jaxkin.fk``).

    Args:
        robot: one of ``ARMS``.
        q: joint coordinates ``(..., n_joints)``: a Jet (rates by ``jaxkin.lift``) or an
            array (at rest).

    Returns:
        ``FKResult``: ``x`` (Jet ``(..., *robot.TARGET_SHAPE)``: the point, the planar pose
        ``(x, y, phi)`` with phi in (-pi, pi], or the 4x4 pose) and ``status`` (``OK``, or
        ``INVALID_INPUT`` for NaN/inf in ``q``, where ``x`` is the pose at ``q = 0``). The
        4x4 transform of the last DH frame is ``jaxkin.fk(serial.from_dh(robot.dh_table()),
        q).x.p``.

    Raises:
        ValueError: ``robot`` is not one of ``ARMS`` or ``q``'s last axis is not ``n_joints``.
    """
    check_robot(robot, ARMS)
    return solve_fk(robot, q, robot.FKOptions())
