"""The ``Arm`` base class (the robot protocol for every analytic arm) and the host-side entry
points ``ik_all_branches``, ``ik_jet`` and ``fk``.

A concrete arm (``planar``, ``three_joint``, ``six_joint``) is a ``@geometry`` dataclass whose
fields are its lengths; it sets the protocol's class attributes ``target``, ``branches`` and
``joint_types`` and implements ``dh_table(dtype)`` and ``ik_branches(target)``: every branch's
joints ``(..., n_branches, n_joints)`` and statuses ``(..., n_branches)`` for finite targets in
units of the arm's size (the kernels in ``jaxkin.serial.arms.kernels`` do the scaling, the
input checks inside jit, the rates and the margin).
"""

from __future__ import annotations

import dataclasses
from typing import Any, ClassVar

import jax
import jax.numpy as jnp
import numpy as np
from jax import Array
from jax.typing import ArrayLike

from ... import _batching, _validate
from ..._execute import Kernel, solve_fk, solve_ik
from ...collision.body import Body
from ...collision.check import chain_self_pairs
from ...jet import Jet
from ...result import FKResult, IKResult
from ...robot import CompilePolicy, Robot
from ...status import Status
from ..dh import DHTable, transforms
from ..search import COMPILER_OPTIONS
from .kernels import ArmIKResult, fk_kernel, ik_all_jit, ik_branch_kernel

__all__ = ["Arm", "fk", "ik_all_branches", "ik_jet"]


class Arm(Robot, abstract=True):
    """Base class of the analytic arms: the robot protocol on top of the shared kernels.

    Subclasses set ``target``, ``branches`` and ``joint_types`` (class attributes) and
    implement ``dh_table`` and ``ik_branches`` (module docstring). Joints are named
    ``q1, q2, ...``. Every arm has a ``link_radius`` field (>= 0, default 0: the links as
    their centre lines), the radius of its collision body's capsules (``collision_body``).
    """

    joint_types: ClassVar[str]
    link_radius: Any  # every arm's field (a bare annotation here: no field of Arm's own)
    reachable: ClassVar = (Status.OK, Status.SINGULAR)
    # Every branch is solved anyway: the branch is picked by a traced index, one program,
    # compiled with the chain search's XLA options (a first call in about half the time).
    ik_policy: ClassVar = CompilePolicy(branch_as_data=True, compiler_options=COMPILER_OPTIONS)

    @property
    def joint_names(self) -> tuple[str, ...]:
        return tuple(f"q{i + 1}" for i in range(len(self.joint_types)))

    def _length_fields(self) -> tuple[Any, ...]:
        """The length fields as given, in field order (``link_radius`` is not one)."""
        fields = dataclasses.fields(self)  # type: ignore[arg-type]
        return tuple(getattr(self, f.name) for f in fields if f.name != "link_radius")

    def lengths(self, dtype) -> tuple[Array, ...]:
        """Every length field cast to ``dtype`` (in field order; ``link_radius`` is not one)."""
        return tuple(jnp.asarray(x).astype(dtype) for x in self._length_fields())

    def length_scale(self) -> Any:
        """The sum of the absolute values of the arm's lengths."""
        given = self._length_fields()
        if all(_validate.is_concrete(x) for x in given):
            # on the host: eager JAX operations would compile a program each per process
            dtype = jnp.result_type(float)
            return np.asarray(sum(np.abs(np.asarray(x, dtype)) for x in given), dtype)
        return sum(jnp.abs(x) for x in self.lengths(jnp.result_type(float)))

    def workspace_box(self) -> tuple[tuple[tuple[float, float], ...], float]:
        """A cube (square for planar arms) of half-side the arm's length scale around the base;
        voxel edge a 25th of it."""
        if not self.target.is_point:
            return super().workspace_box()
        reach = float(self.length_scale())
        return ((-reach, reach),) * self.target.shape[0], reach / 25.0

    def dh_table(self, dtype=None) -> DHTable:  # pragma: no cover - overridden
        """The arm's standard DH table (the 4x4 transform of its last frame is
        ``jaxkin.fk(serial.from_dh(arm.dh_table()), q).x.p``)."""
        raise NotImplementedError

    def ik_branches(self, target: Array) -> tuple[Array, Array]:  # pragma: no cover
        """``(q (..., n_branches, n_joints), status (..., n_branches))`` for finite targets."""
        raise NotImplementedError

    def link_segments(self, q: Array, x: Array) -> Array:
        """Base -> the origin of each DH frame in turn, ``(..., n, 2, d)``."""
        frames = transforms(self.dh_table(q.dtype), q, all_frames=True)[..., :3, 3]
        points = jnp.concatenate([jnp.zeros_like(frames[..., :1, :]), frames], axis=-2)
        points = points[
            ..., : 2 if self.target.shape == (2,) or self.target.name == "planar pose" else 3
        ]
        return jnp.stack([points[..., :-1, :], points[..., 1:, :]], axis=-2)

    def link_poses(self, q: Array) -> Array:
        """The base frame and every DH frame ``1 ... n`` at joints ``q``, ``(..., n + 1, 4,
        4)`` (links ``base, link1, ..., linkn``)."""
        frames = transforms(self.dh_table(q.dtype), q, all_frames=True)
        base = jnp.broadcast_to(jnp.eye(4, dtype=frames.dtype), frames[..., :1, :, :].shape)
        return jnp.concatenate([base, frames], axis=-3)

    def collision_body(self) -> Body:
        """One capsule of radius ``link_radius`` per link ``k`` (DH frame ``k``): for a
        revolute joint ``k`` the segment from frame ``k - 1``'s origin to frame ``k``'s, fixed
        in frame ``k`` at ``(-a_k, -d_k sin alpha_k, -d_k cos alpha_k)`` -> 0; for a prismatic
        joint ``k`` a rod from frame ``k``'s origin back along ``z_{k-1}`` as long as the arm
        (``length_scale``), through which the joint slides. An unbatched geometry only
        (traceable)."""
        if self.batch_shape():
            raise ValueError(f"{type(self).__name__}.collision_body: needs an unbatched geometry")
        if all(_validate.is_concrete(x) for x in jax.tree.leaves(self)):
            return _capsule_body_jit(self)  # one program, not an eager operation per line
        return self._capsule_body()

    def _capsule_body(self) -> Body:
        """``collision_body``'s capsules, traced."""
        table = self.dh_table()
        sa, ca = jnp.sin(table.alpha), jnp.cos(table.alpha)
        reach = self.length_scale()
        revolute = jnp.asarray([kind == "R" for kind in self.joint_types])
        depth = jnp.where(revolute, table.d, reach)
        a = jnp.stack([jnp.where(revolute, -table.a, 0.0), -depth * sa, -depth * ca], -1)
        n = len(self.joint_types)
        names = ("base", *(f"link{k + 1}" for k in range(n)))
        return Body.of_capsules(
            names, tuple(range(1, n + 1)), a, jnp.zeros_like(a), self.link_radius
        )

    def self_collision_pairs(self) -> tuple[tuple[int, int], ...]:
        """Links at least two apart along the arm whose capsules have length and are not in
        contact at ``q = 0`` (a spherical wrist's links meet at its centre: left out)."""
        return chain_self_pairs(self)

    def ik_kernel(self, target: Jet, branch: Any, options: Any, rates: bool) -> IKResult:
        index = jnp.asarray(self.branches.index(branch), jnp.int32)
        return self.ik_kernel_indexed(target, index, options, rates)

    def ik_kernel_indexed(
        self, target: Jet, index: Array, options: Any, rates: bool = True
    ) -> IKResult:
        return ik_branch_kernel(self, target, index, rates)  # the branch is data: one program

    def fk_kernel(self, q: Jet, options: Any, rates: bool) -> FKResult:
        return fk_kernel(self, q, rates)


def _check_arm(robot: Any) -> Arm:
    if not isinstance(robot, Arm):
        raise ValueError(f"robot: expected an analytic arm, got {type(robot).__name__}")
    return robot


def _check_target_shape(robot: Arm, shape: tuple[int, ...]) -> None:
    expected = robot.target.shape
    n = len(expected)
    if len(shape) < n or tuple(shape[-n:]) != expected:
        raise ValueError(
            f"target: {type(robot).__name__} expects shape "
            f"(..., {', '.join(map(str, expected))}), got {tuple(shape)}"
        )


def ik_all_branches(robot: Arm, target: ArrayLike) -> ArmIKResult:
    """Every branch of the analytic IK at once (``result.branch(name)`` picks one).

    Args:
        robot: an analytic arm (e.g. ``Anthropomorphic(l1, l2, l3)``).
        target: ``(..., *robot.target.shape)``: ``(x, y)`` for ``Planar2R``, ``(x, y, phi)``
            for ``Planar3R``, the wrist position ``(x, y, z)`` for the 3-joint arms and a 4x4
            homogeneous transform for ``Puma560`` and ``Stanford``.

    Returns:
        ``ArmIKResult``: ``q`` ``(..., n_branches, n_joints)``, ``valid`` and ``status``
        ``(..., n_branches)``, ``branches`` (the names, ``robot.branches``); dtype follows
        ``target``.

    Raises:
        ValueError: ``robot`` is not an analytic arm, or a target of the wrong trailing shape.
    """
    robot = _check_arm(robot)
    target = _validate.as_float(target)
    _check_target_shape(robot, target.shape)
    n = len(robot.target.shape)
    padding = _batching.shared_geometry(robot) and {"target": n}
    return ik_all_jit(robot, target, batch=target.shape[:-n], pad=padding)


def ik_jet(robot: Arm, target: Jet | ArrayLike, branch: str | None = None) -> IKResult:
    """One branch of the analytic IK with joint velocity and acceleration, and a margin
    (``jaxkin.ik`` of an arm).

    The rates come from ``jaxkin.lift`` (nested forward-mode jvp) of the position-level IK,
    compiled once; they are 0 where the branch's status is not ``OK``. A pose target's Jet holds
    4x4 matrices and their time derivatives.

    Args:
        robot: an analytic arm.
        target: Jet (or array, at rest) of shape ``(..., *robot.target.shape)``.
        branch: one of ``robot.branches`` (None: the first, ``robot.default_branch``).

    Returns:
        ``IKResult``: ``q`` (Jet ``(..., n_joints)``), ``status`` and ``margin`` (``(...)``:
        the Jacobian's isotropy in [0, 1] where solved, negative outside the workspace, -1 for
        invalid input; ``jaxkin.serial.arms.kernels``).
    """
    robot = _check_arm(robot)
    return solve_ik(robot, target, branch, robot.IKOptions())


def fk(robot: Arm, q: Jet | ArrayLike) -> FKResult:
    """Forward kinematics of an analytic arm in the form of its targets (``jaxkin.fk``).

    Args:
        robot: an analytic arm.
        q: joint coordinates ``(..., n_joints)``: a Jet (rates by ``jaxkin.lift``) or an
            array (at rest).

    Returns:
        ``FKResult``: ``x`` (Jet ``(..., *robot.target.shape)``: the point, the planar pose
        ``(x, y, phi)`` with phi in (-pi, pi], or the 4x4 pose) and ``status`` (``OK``, or
        ``INVALID_INPUT`` for NaN/inf in ``q``, where ``x`` is the pose at ``q = 0``). The
        4x4 transform of the last DH frame is
        ``jaxkin.fk(serial.from_dh(robot.dh_table()), q).x.p``.

    Raises:
        ValueError: ``robot`` is not an analytic arm or ``q``'s last axis is not ``n_joints``.
    """
    robot = _check_arm(robot)
    return solve_fk(robot, q, robot.FKOptions())


def _capsule_body_kernel(arm: Arm) -> Body:
    return arm._capsule_body()


_capsule_body_jit = Kernel(_capsule_body_kernel)
