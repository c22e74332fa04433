"""The analytic arms' kernels, written once for every arm: every branch's IK in units of the
arm's size, one branch with rates and a margin, and the FK in the form of the targets.

A kernel reads an arm through the robot protocol (``target``, ``branches``, ``joint_types``,
``length_scale()``) and three methods of ``jaxkin.serial.arms.base.Arm``: ``lengths(dtype)``,
``dh_table(dtype)`` and ``ik_branches(target)`` (the arm's own closed form); it never imports
an arm class.

Statuses per branch: ``OK``; ``SINGULAR`` (the target is reproduced but a joint is free or
branches coincide: the documented choice is returned); ``UNREACHABLE`` (``q`` is the clamped,
aligned placeholder); ``INVALID_INPUT`` (NaN/inf in the target: ``q = 0``). Rates are 0 where
not OK; everything is finite and so are gradients of status-masked losses (double-where).
The margin is the isotropy (``jaxkin._numerics.isotropy``) of the task Jacobian in units of the
arm's size: in [0, 1], 0 at a singularity; minus the distance to the target in units of that
size where unreachable; -1 for invalid input.
"""

from __future__ import annotations

import dataclasses
from typing import Any

import jax
import jax.numpy as jnp
from jax import Array

from ... import _validate
from ..._execute import Kernel, Policy
from ..._numerics import isotropy, safe_norm
from ...jet import Jet, lift
from ...result import FKResult, IKResult, SolverResult, forward_result
from ...robot import PLANAR_POINT, PLANAR_POSE, POINT, POSE
from ...status import STATUS_DTYPE, Status
from .. import _kinematics
from .. import dh as _dh

__all__ = [
    "FAR",
    "ArmIKResult",
    "fk_kernel",
    "ik_all_jit",
    "ik_all_kernel",
    "ik_branch_kernel",
]

ArmRobot = Any  # an arms.base.Arm: the class sits above its kernels, which read its fields


@jax.tree_util.register_dataclass
@dataclasses.dataclass(frozen=True)
class ArmIKResult(SolverResult):
    """Every analytic inverse-kinematics branch of an arm.

    Attributes:
        q: joint values, shape ``(..., n_branches, n_joints)`` (radians for revolute joints,
            wrapped to ``[-pi, pi]``; length units for prismatic ones).
        valid: ``(..., n_branches)``, True where ``fk(robot, q)`` reproduces the target
            (status ``OK`` or ``SINGULAR``).
        status: ``(..., n_branches)`` ``int8`` codes of ``jaxkin.Status``.
        branches: static tuple naming the branches (length ``n_branches``).
    """

    q: Array
    valid: Array
    status: Array
    branches: tuple[str, ...] = dataclasses.field(metadata=dict(static=True))

    def branch(self, name: str) -> ArmIKResult:
        """The single named branch: ``q`` ``(..., n_joints)``, ``valid``/``status`` ``(...)``."""
        i = self.branches.index(_validate.choice(name, "name", self.branches))
        return ArmIKResult(self.q[..., i, :], self.valid[..., i], self.status[..., i], (name,))


# Beyond this many robot sizes from the base a target is reported unreachable (tested before
# any square; an arm's prismatic strokes are unbounded in the kernels, but not in practice).
FAR = 1e6


def _placeholder_target(robot: ArmRobot, dtype) -> Array:
    """A finite target substituted for non-finite input before any math."""
    if robot.target.shape == (4, 4):
        return jnp.eye(4, dtype=dtype)
    return jnp.zeros(robot.target.shape, dtype)


def _split_target(robot: ArmRobot, target: Array) -> tuple[Array, Array | None]:
    """The length coordinates of a target, and its angular rest (None for a point)."""
    if robot.target.shape == (4, 4):
        return target[..., :3, 3], target
    if robot.target.name == "planar pose":
        return target[..., :2], target
    return target, None


def _join_target(robot: ArmRobot, lengths: Array, target: Array | None) -> Array:
    if target is None:  # a point
        return lengths
    if robot.target.shape == (4, 4):
        return target.at[..., :3, 3].set(lengths)
    if robot.target.name == "planar pose":
        return jnp.concatenate([lengths, target[..., 2:]], axis=-1)
    return lengths


def ik_all_kernel(robot: ArmRobot, target: Array) -> ArmIKResult:
    """Every branch, in units of the arm's size (no overflow or underflow at any scale)."""
    dtype = target.dtype
    n_target = len(robot.target.shape)
    axes = tuple(range(-n_target, 0))
    lengths = jnp.stack([jnp.asarray(x, dtype) for x in robot.lengths(dtype)])
    valid_in = jnp.all(jnp.isfinite(target), axis=axes) & jnp.all(jnp.isfinite(lengths))
    scale = jnp.sum(jnp.where(jnp.isfinite(lengths), jnp.abs(lengths), 0.0))
    scale = jnp.where(scale > 0, scale, 1.0)
    # Double-where: non-finite targets are replaced before any arithmetic (their gradient
    # would otherwise reach the lengths through the division below).
    placeholder = _placeholder_target(robot, dtype)
    shape_mask = (1,) * n_target
    target = jnp.where(valid_in.reshape(valid_in.shape + shape_mask), target, placeholder)
    point, rest = _split_target(robot, target)
    point = point / scale
    far = ~jnp.all(jnp.abs(point) <= FAR, axis=-1)
    target = _join_target(robot, point, rest)
    unit = jax.tree.map(lambda x: jnp.asarray(x, dtype) / scale, robot)
    safe_target = jnp.where(far.reshape(far.shape + shape_mask), placeholder, target)
    q, status = unit.ik_branches(safe_target)
    status = jnp.broadcast_to(status, q.shape[:-1])
    status = jnp.where(far[..., None], Status.UNREACHABLE, status)
    status = jnp.where(valid_in[..., None], status, Status.INVALID_INPUT).astype(STATUS_DTYPE)
    prismatic = jnp.asarray([kind == "P" for kind in robot.joint_types])
    q = q * jnp.where(prismatic, scale, 1.0)
    q = jnp.where(valid_in[..., None, None], q, 0.0)
    valid = (status == Status.OK) | (status == Status.SINGULAR)
    return ArmIKResult(q, valid, status, robot.branches)


ik_all_jit = Kernel(ik_all_kernel, policy=Policy(pad=True))


def _task(robot: ArmRobot, q: Array) -> Array:
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


def _position(x: Array, robot: ArmRobot) -> Array:
    """The position part of a target, ``(..., 2 or 3)``."""
    if robot.target is PLANAR_POSE:
        return x[..., :2]
    if robot.target is POSE:
        return x[..., :3, 3]
    return x


def _scaled_jacobian(robot: ArmRobot, q: Array, scale: Array) -> tuple[Array, Array]:
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
    prismatic = jnp.asarray([kind == "P" for kind in robot.joint_types])
    rows = rows * jnp.where(prismatic, scale[..., None], 1.0)[..., None, :]
    return rows, p


def _margin(robot: ArmRobot, q: Array, target: Array, status: Array) -> Array:
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


def ik_branch_kernel(robot: ArmRobot, target: Jet, index: Array, rates: bool) -> IKResult:
    """One branch, ``robot.branches[index]`` (``index`` an ``int32`` scalar, possibly traced),
    with joint rates by ``jaxkin.lift`` of ``ik_all_kernel`` where ``rates`` (else ``target``'s
    rates are not read and the result's are 0) and the margin (module docstring)."""

    def position(x):
        res = ik_all_kernel(robot, x)
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


def fk_kernel(robot: ArmRobot, q: Jet, rates: bool) -> FKResult:
    """The arm's FK in the form of its targets (rates by ``jaxkin.lift`` where ``rates``)."""
    return forward_result(lambda joints: _task(robot, joints), q, rates, len(robot.target.shape))
