"""Analytic inverse kinematics of the textbook arms, every branch at once, and their FK.

Arms (geometry pytrees: frozen dataclasses whose scalar lengths are array leaves, validated
on the host when concrete; see each module's docstring for the DH table and formulas):

=====================  ===========================  ============  ==========  ========
arm                    module                       target        branches    joints
=====================  ===========================  ============  ==========  ========
``Planar2R(l1, l2)``   ``arms_planar``              ``(..., 2)``  2           RR
``Planar3R(l1..l3)``   ``arms_planar``              ``(..., 3)``  2           RRR
``Anthropomorphic``    ``arms_3dof`` (seed 001)     ``(..., 3)``  4           RRR
``Cylindrical(h)``     ``arms_3dof`` (seed 004)     ``(..., 3)``  1           RPP
``Spherical(h)``       ``arms_3dof`` (seed 004)     ``(..., 3)``  2           RRP
``Puma560(...)``       ``arms_6dof`` (seed 003)     ``(..., 4, 4)``  8        6R
``Stanford(d1, a2)``   ``arms_6dof`` (seed 003)     ``(..., 4, 4)``  4        RRPRRR
=====================  ===========================  ============  ==========  ========

``fk(robot, q)``: ``q`` ``(..., n_joints)`` -> ``(..., 4, 4)``, the DH forward kinematics
(``jaxkin.serial.fk_dh`` of ``robot.dh_table()``; planar arms: targets are read from the
translation ``(x, y)`` and, for the 3R, the angle ``q1 + q2 + q3``).

``ik(robot, target)`` -> ``ArmIKResult`` with ``q`` ``(..., n_branches, n_joints)``,
``valid`` and ``status`` ``(..., n_branches)`` and the static branch names ``branches``;
``result.branch("front_up")`` selects one. Per-branch statuses: ``OK``; ``SINGULAR`` (valid:
the target is reproduced, but a joint is free or branches coincide, the documented choice is
returned); ``UNREACHABLE`` (placeholder ``q``: the clamped, aligned configuration);
``INVALID_INPUT`` (NaN/inf in the target: ``q = 0``). ``valid = status in (OK, SINGULAR)``.
Everything is batched over leading axes, jitted once per arm type and batch shape, and safe
under ``jax.grad`` (double-where at every free angle and square root): a valid-masked loss
over a batch containing unreachable, singular and NaN targets has finite gradients.

Float64: ``fk(ik(T))`` reproduces random reachable targets to ~1e-15 (tests assert 1e-10) and
the generating joint vector is among the branches to ~1e-15 (tests assert 1e-8).

Float32 (measured on 400 random poses per arm with every elbow/wrist ``|sin| > 0.1``, links
of 0.2-1 m): every branch valid, targets reproduced to <= 9e-7 (absolute, metres or radians),
generating joints recovered to <= 3e-6 rad. The singular band is ``sqrt(eps) = 3.5e-4``
relative in float32: targets that close to a workspace boundary or a wrist singularity are
clamped onto it (``SINGULAR``), which moves the elbow or wrist angle by up to
``~sqrt(2 * 3.5e-4) = 0.03`` rad while keeping the position error within ``tol``. Joint
angles near singular sets are ill-conditioned in any precision: there the contract is the
round trip, not the angles.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
from jax import Array
from jax.typing import ArrayLike

from .. import _validate
from ..jet import Jet, lift
from ..status import Status
from ._arms_common import Arm, ArmIKResult, check_robot, fk_arm, ik_arm
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


def fk(robot: Arm, q: ArrayLike) -> Array:
    """Forward kinematics of an analytic arm: ``q`` ``(..., n_joints)`` -> ``(..., 4, 4)``.

    Raises:
        ValueError: ``robot`` is not one of ``ARMS`` or ``q``'s last axis is not ``n_joints``.
    """
    check_robot(robot, ARMS)
    return fk_arm(robot, q)


def ik(robot: Arm, target: ArrayLike) -> ArmIKResult:
    """Every analytic IK branch of ``robot`` for a batch of targets.

    Args:
        robot: one of ``ARMS`` (e.g. ``Anthropomorphic(l1, l2, l3)``).
        target: ``(..., *robot.TARGET_SHAPE)``: ``(x, y)`` for ``Planar2R``, ``(x, y, phi)``
            for ``Planar3R``, the wrist position ``(x, y, z)`` for the 3-joint arms and a 4x4
            homogeneous transform for ``Puma560`` and ``Stanford``.

    Returns:
        ``ArmIKResult`` (``q``, ``valid``, ``status``, ``branches``); dtype follows ``target``.

    Raises:
        ValueError: unknown robot type or a target of the wrong trailing shape.
    """
    check_robot(robot, ARMS)
    return ik_arm(robot, target)


def _ik_jet_core(robot: Arm, target: Jet, branch: str) -> tuple[Jet, Array]:
    def position(x):
        res = ik_arm(robot, x).branch(branch)
        return res.q, res.status

    q, status = lift(position)(target)
    ok = (status == Status.OK)[..., None]
    return Jet(q.p, jnp.where(ok, q.v, 0.0), jnp.where(ok, q.a, 0.0)), status


_ik_jet_jit = jax.jit(_ik_jet_core, static_argnames="branch")


def ik_jet(robot: Arm, target: Jet | ArrayLike, branch: str) -> tuple[Jet, Array]:
    """One branch of the analytic IK with joint velocity and acceleration.

    The rates come from ``jaxkin.lift`` (nested forward-mode jvp) of the position-level IK,
    compiled once; they are 0 where the branch's status is not ``OK``.

    Args:
        robot: an arm whose target is a point or vector (not the 4x4 targets of the 6R arms).
        target: Jet (or array, at rest) of shape ``(..., *robot.TARGET_SHAPE)``.
        branch: one of the robot's branch names (e.g. ``"front_up"``).

    Returns:
        ``(q, status)``: Jet ``(..., n_joints)`` and ``int8`` statuses ``(...)``.
    """
    check_robot(robot, ARMS)
    if len(robot.TARGET_SHAPE) != 1:
        raise ValueError(f"ik_jet needs a vector target, {type(robot).__name__} takes 4x4 poses")
    target = _validate.as_jet(target, "target", coords=robot.TARGET_SHAPE[0])
    return _ik_jet_jit(robot, target, branch=branch)
