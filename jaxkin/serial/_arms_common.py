"""Shared pieces of the analytic arm solvers (``jaxkin.serial.arms``): the result type, the ``Arm``
base class (the robot protocol), the planar two-link sub-problem, the ZYZ spherical wrist and
the generic jitted drivers.

Conventions shared by every arm:

* ``ik`` returns *every* solution branch: ``q`` ``(..., n_branches, n_joints)``, ``valid`` and
  ``status`` ``(..., n_branches)``; the static ``branches`` tuple names them.
* ``status`` per branch: ``OK``; ``SINGULAR`` (the branch reproduces the target, but a joint is
  free or two branches coincide: the documented choice is returned); ``UNREACHABLE`` (``q``
  is the nearest aligned placeholder configuration); ``INVALID_INPUT`` (NaN/inf in the target,
  ``q`` = 0). ``valid = status in (OK, SINGULAR)``.
* Singular tests use ``tol = sqrt(eps(dtype)) * L``, ``L`` a length scale of the arm (the sum
  of its link lengths), so a target within ``tol`` outside the workspace is clamped onto its
  boundary (``SINGULAR``, position error <= tol) rather than flagged unreachable.
* Revolute outputs are wrapped to ``[-pi, pi]``.
"""

from __future__ import annotations

import dataclasses
from typing import Any, ClassVar

import jax
import jax.numpy as jnp
import numpy as np
from jax import Array
from jax.typing import ArrayLike

from .. import _batching, _validate
from .._numerics import safe_sqrt, singular_rtol
from ..jet import Jet
from ..result import SolverResult
from ..robot import CompilePolicy, Robot
from ..status import STATUS_DTYPE, Status
from .dh import DHTable, transforms

PI = float(np.pi)
TWO_PI = 2.0 * PI


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


class Arm(Robot, abstract=True):
    """Base class of the analytic arms: the robot protocol and the per-arm IK kernel.

    Subclasses are ``@geometry`` dataclasses whose fields are scalar lengths (``number``) and
    set ``N_JOINTS``, ``JOINT_TYPES``, ``BRANCHES``, ``TARGET_SHAPE`` and ``target``.
    """

    N_JOINTS: ClassVar[int]
    JOINT_TYPES: ClassVar[str]
    BRANCHES: ClassVar[tuple[str, ...]]
    TARGET_SHAPE: ClassVar[tuple[int, ...]]
    reachable: ClassVar = (Status.OK, Status.SINGULAR)
    # Every branch is solved anyway: the branch is picked by a traced index, one program.
    ik_policy: ClassVar = CompilePolicy(branch_as_data=True)

    def __init_subclass__(cls, **kwargs: Any) -> None:
        super().__init_subclass__(**kwargs)
        if "BRANCHES" in cls.__dict__:
            cls.branches = cls.BRANCHES

    @property
    def joint_names(self) -> tuple[str, ...]:
        return tuple(f"q{i + 1}" for i in range(self.N_JOINTS))

    @property
    def joint_types(self) -> str:
        return self.JOINT_TYPES

    def lengths(self, dtype) -> tuple[Array, ...]:
        """Every field cast to ``dtype`` (in field order)."""
        return tuple(
            jnp.asarray(getattr(self, f.name)).astype(dtype)
            for f in dataclasses.fields(self)  # type: ignore[arg-type]
        )

    def length_scale(self) -> Any:
        """The sum of the absolute values of the arm's lengths."""
        return sum(jnp.abs(x) for x in self.lengths(jnp.result_type(float)))

    def workspace_box(self) -> tuple[tuple[tuple[float, float], ...], float]:
        """A cube (square for planar arms) of half-side the arm's length scale around the base;
        voxel edge a 25th of it."""
        if not self.target.is_point:
            return super().workspace_box()
        reach = float(self.length_scale())
        return ((-reach, reach),) * self.target.shape[0], reach / 25.0

    def dh_table(self, dtype=None) -> DHTable:  # pragma: no cover - overridden
        raise NotImplementedError

    def _ik_kernel(self, target: Array) -> tuple[Array, Array]:  # pragma: no cover
        """``(q (..., n_branches, n_joints), status (..., n_branches))`` for finite targets."""
        raise NotImplementedError

    def _placeholder_target(self, dtype) -> Array:
        """A finite target substituted for non-finite input before any math."""
        if self.TARGET_SHAPE == (4, 4):
            return jnp.eye(4, dtype=dtype)
        return jnp.zeros(self.TARGET_SHAPE, dtype)

    def link_segments(self, q: Array, x: Array) -> Array:
        """Base -> the origin of each DH frame in turn, ``(..., n, 2, d)``."""
        frames = transforms(self.dh_table(q.dtype), q, all_frames=True)[..., :3, 3]
        points = jnp.concatenate([jnp.zeros_like(frames[..., :1, :]), frames], axis=-2)
        points = points[
            ..., : 2 if self.target.shape == (2,) or self.target.name == "planar pose" else 3
        ]
        return jnp.stack([points[..., :-1, :], points[..., 1:, :]], axis=-2)

    def ik_kernel(self, target: Jet, branch: Any, options: Any, rates: bool) -> Any:
        index = jnp.asarray(self.branches.index(branch), jnp.int32)
        return self.ik_kernel_indexed(target, index, options, rates)

    def ik_kernel_indexed(self, target: Jet, index: Any, options: Any, rates: bool = True) -> Any:
        from .arms import _ik_jet_core

        return _ik_jet_core(self, target, index, rates)  # the branch is data: one program

    def fk_kernel(self, q: Jet, options: Any, rates: bool) -> Any:
        from .arms import _fk_core

        return _fk_core(self, q, rates)


# --------------------------------------------------------------------------- small math


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


# --------------------------------------------------------------------------- rotations


def rot_z(c: Array, s: Array) -> Array:
    """Rotation about z from its cosine and sine: ``(...) -> (..., 3, 3)``."""
    zero, one = jnp.zeros_like(c), jnp.ones_like(c)
    return jnp.stack(
        [
            jnp.stack([c, -s, zero], axis=-1),
            jnp.stack([s, c, zero], axis=-1),
            jnp.stack([zero, zero, one], axis=-1),
        ],
        axis=-2,
    )


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


# --------------------------------------------------------------------------- drivers


# Beyond this many robot sizes from the base a target is reported unreachable (tested before
# any square; an arm's prismatic strokes are unbounded in the kernels, but not in practice).
FAR = 1e6


def _split_target(robot: Arm, target: Array) -> tuple[Array, Array | None]:
    """The length coordinates of a target, and its angular rest (None for a point)."""
    if robot.TARGET_SHAPE == (4, 4):
        return target[..., :3, 3], target
    if robot.target.name == "planar pose":
        return target[..., :2], target
    return target, None


def _join_target(robot: Arm, lengths: Array, target: Array | None) -> Array:
    if robot.TARGET_SHAPE == (4, 4):
        return target.at[..., :3, 3].set(lengths)
    if robot.target.name == "planar pose":
        return jnp.concatenate([lengths, target[..., 2:]], axis=-1)
    return lengths


def _ik_impl(robot: Arm, target: Array) -> ArmIKResult:
    """Every branch, in units of the arm's size (no overflow or underflow at any scale)."""
    dtype = target.dtype
    n_target = len(robot.TARGET_SHAPE)
    axes = tuple(range(-n_target, 0))
    lengths = jnp.stack([jnp.asarray(x, dtype) for x in robot.lengths(dtype)])
    valid_in = jnp.all(jnp.isfinite(target), axis=axes) & jnp.all(jnp.isfinite(lengths))
    scale = jnp.sum(jnp.where(jnp.isfinite(lengths), jnp.abs(lengths), 0.0))
    scale = jnp.where(scale > 0, scale, 1.0)
    # Double-where: non-finite targets are replaced before any arithmetic (their gradient
    # would otherwise reach the lengths through the division below).
    placeholder = robot._placeholder_target(dtype)
    shape_mask = (1,) * n_target
    target = jnp.where(valid_in.reshape(valid_in.shape + shape_mask), target, placeholder)
    point, rest = _split_target(robot, target)
    point = point / scale
    far = ~jnp.all(jnp.abs(point) <= FAR, axis=-1)
    target = _join_target(robot, point, rest)
    unit = jax.tree.map(lambda x: jnp.asarray(x, dtype) / scale, robot)
    safe_target = jnp.where(far.reshape(far.shape + shape_mask), placeholder, target)
    q, status = unit._ik_kernel(safe_target)
    status = jnp.broadcast_to(status, q.shape[:-1])
    status = jnp.where(far[..., None], Status.UNREACHABLE, status)
    status = jnp.where(valid_in[..., None], status, Status.INVALID_INPUT).astype(STATUS_DTYPE)
    prismatic = jnp.asarray([kind == "P" for kind in robot.JOINT_TYPES])
    q = q * jnp.where(prismatic, scale, 1.0)
    q = jnp.where(valid_in[..., None, None], q, 0.0)
    valid = (status == Status.OK) | (status == Status.SINGULAR)
    return ArmIKResult(q, valid, status, robot.BRANCHES)


_ik_jit = _batching.PaddedJit(jax.jit(_ik_impl), {})


def check_robot(robot: Any, kinds: tuple[type, ...]) -> None:
    if not isinstance(robot, kinds):
        names = ", ".join(k.__name__ for k in kinds)
        raise ValueError(f"robot: expected one of {names}, got {type(robot).__name__}")


def ik_arm(robot: Arm, target: ArrayLike) -> ArmIKResult:
    """Validate ``target``'s shape and run the jitted analytic IK of ``robot``."""
    target = _validate.as_float(target)
    shape = robot.TARGET_SHAPE
    n = len(shape)
    if target.ndim < n or tuple(target.shape[-n:]) != shape:
        raise ValueError(
            f"target: {type(robot).__name__} expects shape (..., {', '.join(map(str, shape))}), "
            f"got {tuple(target.shape)}"
        )
    padding = _batching.shared_geometry(robot) and {"target": n}
    return _ik_jit(robot, target, batch=target.shape[:-n], pad=padding)


def dh(dtype, a: list, alpha: list, d: list, theta: list, joint_types: str) -> DHTable:
    """A ``DHTable`` from lists mixing Python floats and scalar arrays (works on tracers)."""

    def col(values: list) -> Array:
        return jnp.stack([jnp.asarray(v, dtype) for v in values])

    return DHTable(col(a), col(alpha), col(d), col(theta), tuple(joint_types))


HALF_PI = 0.5 * PI
