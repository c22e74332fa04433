"""The robot protocol: what every robot offers, and ``jaxkin.ik`` / ``jaxkin.fk``.

Every robot geometry (``scara.Scara``, ``delta.Delta``, the serial arms, ``serial.DHTable``
and ``serial.PoEChain``) is a ``Robot``. The planner, the optimiser, workspace sweeps and the
command line are written against this interface alone and never ask which robot they have:

* ``robot.target``: what its inverse kinematics takes and its forward kinematics returns
  (``PLANAR_POINT`` ``(2,)``, ``POINT`` ``(3,)``, ``PLANAR_POSE`` ``(x, y, phi)``, ``POSE`` a
  4x4 homogeneous transform), with the coordinate names used in files;
* ``robot.branches`` and ``robot.default_branch``: the solution branches its IK can hold along
  a path (the SCARA's assembly modes ``+1``/``-1``, the Delta's ``"out"``/``"in"``, an arm's
  branch names);
* ``robot.joint_names`` (hence ``n_joints``), ``robot.joint_types`` (``"R"``/``"P"`` per joint)
  and ``robot.joint_limits()``;
* ``robot.reachable``: the statuses that count as reachable in a workspace sweep;
* ``robot.length_scale()``: a characteristic length (the robot's size),
  ``robot.workspace_box()``: the default box and voxel edge of a sweep, and
  ``robot.link_segments(q, x)``: the links as segments, for collision costs.

``ik(robot, target, branch=None)`` returns an ``IKResult`` (``q``: a ``Jet`` of joint
coordinates ``(..., n_joints)``, ``status``, ``margin``) for the default branch when ``branch``
is None; ``fk(robot, q)`` returns an ``FKResult`` whose ``x`` is a ``Jet`` in the form of the
targets, so ``fk(robot, ik(robot, t).q).x`` reproduces ``t``. Targets and joints may be plain
arrays (taken at rest: zero rates) or ``Jet``s. Both work inside ``jit`` and ``vmap``.

A new robot subclasses ``Robot`` (as a ``geometry`` dataclass whose fields are ``number``s),
sets the class attributes and implements ``_ik`` and ``_fk`` (and may override ``_ik_path``,
the planner's IK along sampled paths); the command line needs one registry entry
(``jaxkin.cli.robots``). The protocol is written down in ``docs/design.md``.
"""

from __future__ import annotations

import dataclasses
import functools
from collections.abc import Mapping
from typing import Any, ClassVar

import jax
import jax.numpy as jnp
import numpy as np
from jax import Array
from jax.typing import ArrayLike

from ._geometry import BOUND, LENGTH, REAL, Geometry, geometry, number
from .jet import Jet
from .result import FKResult, IKResult
from .status import Status

__all__ = [
    "LENGTH",
    "PLANAR_POINT",
    "PLANAR_POSE",
    "POINT",
    "POSE",
    "REAL",
    "JointLimits",
    "Robot",
    "Target",
    "as_robot",
    "fk",
    "geometry",
    "ik",
    "number",
]

Bounds = tuple[tuple[float, float], ...]


@dataclasses.dataclass(frozen=True)
class Target:
    """What a robot's inverse kinematics takes (and its forward kinematics returns).

    Attributes:
        name: ``"planar point"``, ``"point"``, ``"planar pose"`` or ``"pose"``.
        shape: trailing shape of one target: ``(2,)``, ``(3,)``, ``(3,)`` or ``(4, 4)``.
        coordinates: names of the coordinates in files (``x, y, z``; a pose is written as
            ``x, y, z, qw, qx, qy, qz``).
        is_point: True for points (a workspace sweep grids them; a path is a curve of them).
    """

    name: str
    shape: tuple[int, ...]
    coordinates: tuple[str, ...]
    is_point: bool


PLANAR_POINT = Target("planar point", (2,), ("x", "y"), True)
POINT = Target("point", (3,), ("x", "y", "z"), True)
PLANAR_POSE = Target("planar pose", (3,), ("x", "y", "phi"), False)
POSE = Target("pose", (4, 4), ("x", "y", "z", "qw", "qx", "qy", "qz"), False)


@geometry
class JointLimits(Geometry):
    """Closed joint ranges ``lower <= q <= upper``.

    Attributes:
        lower: lower bounds, shape ``(n,)`` (rad or length); ``-inf`` for none.
        upper: upper bounds, shape ``(n,)``; ``+inf`` for none.
    """

    lower: Array = number(BOUND, (-1,))
    upper: Array = number(BOUND, (-1,))

    def _validate(self) -> None:
        super()._validate()
        lower, upper = (np.asarray(x, dtype=float) for x in (self.lower, self.upper))
        if lower.shape != upper.shape:
            raise ValueError(
                f"JointLimits.upper must have the shape of lower {lower.shape}, got {upper.shape}"
            )
        bad = np.flatnonzero(lower > upper)
        if bad.size:
            raise ValueError(
                f"JointLimits: need lower <= upper, got lower {lower[bad]} > upper {upper[bad]} "
                f"at joints {bad.tolist()}"
            )

    @classmethod
    def named(
        cls, joint_names: tuple[str, ...], ranges: Mapping[str, tuple[float, float] | None]
    ) -> JointLimits:
        """Limits from ``{joint name: (low, high)}``; a joint left out (or None) is unbounded.

        Raises:
            ValueError: an unknown joint name or a malformed pair (the message names it).
        """
        unknown = sorted(set(ranges) - set(joint_names))
        if unknown:
            raise ValueError(f"limits: unknown joint(s) {unknown}, expected keys {joint_names}")
        lower, upper = [], []
        for name in joint_names:
            pair = ranges.get(name)
            if pair is None:
                pair = (-np.inf, np.inf)
            if isinstance(pair, str | bytes) or not hasattr(pair, "__len__") or len(pair) != 2:
                raise ValueError(f"limits[{name!r}] must be a (low, high) pair, got {pair!r}")
            for bound in pair:
                if isinstance(bound, bool) or not isinstance(bound, int | float | np.number):
                    raise ValueError(
                        f"limits[{name!r}] must be a (low, high) pair of numbers, got {pair!r}"
                    )
            low, high = float(pair[0]), float(pair[1])
            if np.isnan(low) or np.isnan(high) or low > high:
                raise ValueError(f"limits[{name!r}] must satisfy low <= high, got {pair!r}")
            lower.append(low)
            upper.append(high)
        return cls(np.asarray(lower), np.asarray(upper))

    @classmethod
    def unbounded(cls, n: int) -> JointLimits:
        """No limit on any of ``n`` joints."""
        return cls(np.full(n, -np.inf), np.full(n, np.inf))

    def contains(self, q: ArrayLike) -> Array:
        """True where every joint of ``q`` (shape ``(..., n)``) lies in its closed range."""
        q = jnp.asarray(q)
        inside = (q >= jnp.asarray(self.lower, q.dtype)) & (q <= jnp.asarray(self.upper, q.dtype))
        return jnp.all(inside, axis=-1)


class Robot(Geometry):
    """Base class of every robot geometry (see the module docstring for the protocol)."""

    target: ClassVar[Target]
    branches: ClassVar[tuple[Any, ...]]
    reachable: ClassVar[tuple[Status, ...]] = (Status.OK, Status.SINGULAR)

    @property
    def default_branch(self) -> Any:
        """The branch ``ik`` solves when none is given (the first of ``branches``)."""
        return self.branches[0]

    @property
    def joint_names(self) -> tuple[str, ...]:
        """One name per joint, in the order of ``q``'s last axis."""
        raise NotImplementedError

    @property
    def joint_types(self) -> str:
        """``"R"`` (revolute, rad) or ``"P"`` (prismatic, length) per joint."""
        raise NotImplementedError

    @property
    def n_joints(self) -> int:
        return len(self.joint_names)

    def joint_limits(self) -> JointLimits:
        """The robot's own position limits (``-inf``/``+inf`` where a joint has none)."""
        return JointLimits.unbounded(self.n_joints)

    def length_scale(self) -> Any:
        """A characteristic length of the robot (its size; traceable)."""
        raise NotImplementedError

    def workspace_box(self) -> tuple[Bounds, float]:
        """The default box ``((lo, hi), ...)`` (one pair per target coordinate) and voxel edge
        of a workspace sweep (host side)."""
        raise ValueError(
            f"{type(self).__name__} has no default workspace box: give bounds and a resolution"
        )

    def link_segments(self, q: Array, x: Array) -> Array:
        """The robot's links as segments ``(..., S, 2, d)`` (start and end points, in the
        coordinates of the target's position) at joints ``q`` ``(..., n)`` whose end point is
        ``x`` (the target, known to the caller), for collision costs. By default the end point
        alone, as one segment of zero length."""
        point = x[..., :3, 3] if self.target.shape == (4, 4) else x[..., : self.target.shape[0]]
        if self.target.name == "planar pose":
            point = x[..., :2]
        return jnp.stack([point, point], axis=-2)[..., None, :, :]

    def check_branch(self, branch: Any) -> Any:
        """``branch``, or the default branch for None; ``ValueError`` naming the choices."""
        if branch is None:
            return self.default_branch
        if isinstance(branch, bool) or branch not in self.branches:
            raise ValueError(
                f"branch must be one of {self.branches} for {type(self).__name__}, got {branch!r}"
            )
        return self.branches[self.branches.index(branch)]

    def _ik(self, target: Jet | ArrayLike, branch: Any, **options: Any) -> IKResult:
        raise NotImplementedError

    def _ik_indexed(self, target: Jet, index: Array) -> IKResult:
        """The IK on branch ``self.branches[index]``, ``index`` a traced ``int32`` scalar (the
        planner maps it over every branch). By default a ``lax.switch`` over the branches;
        a robot whose kernel takes the branch as data overrides it, so that its branches
        compile as one program."""
        solvers = [functools.partial(self._ik, branch=b) for b in self.branches]
        return jax.lax.switch(index, solvers, target)

    def _ik_path(self, path: Jet, index: Any) -> IKResult:
        """The IK of sampled paths ``(..., T, *target.shape)`` (consecutive samples along the
        axis before the target's) on branch ``self.branches[index]`` (``index`` an int, or a
        traced ``int32`` scalar), for the planner. By default every sample on its own
        (``_ik``, or ``_ik_indexed`` for a traced index); a robot whose IK is iterative
        overrides it to warm-start each sample from the previous one."""
        if isinstance(index, int):
            return self._ik(path, self.branches[index])
        return self._ik_indexed(path, index)

    def _fk(self, q: Jet | ArrayLike, **options: Any) -> FKResult:
        raise NotImplementedError


def as_robot(robot: Any, name: str = "robot") -> Robot:
    """``robot`` if it implements the robot protocol, else a ``ValueError`` naming it."""
    if not isinstance(robot, Robot):
        raise ValueError(
            f"{name} must be a jaxkin robot (scara.Scara, delta.Delta, a serial arm, "
            f"serial.DHTable or serial.PoEChain), got {type(robot).__name__}"
        )
    return robot


def ik(robot: Robot, target: Jet | ArrayLike, branch: Any = None, **options: Any) -> IKResult:
    """Inverse kinematics of any robot for one branch.

    Args:
        robot: any ``Robot``.
        target: ``Jet`` (or plain array, at rest) of shape ``(..., *robot.target.shape)``.
        branch: one of ``robot.branches``; None for ``robot.default_branch``.
        **options: passed to the robot's solver (e.g. ``method="autodiff"``).

    Returns:
        ``IKResult`` (or a subclass): ``q`` (Jet, ``(..., n_joints)``), ``status``, ``margin``.

    Raises:
        ValueError: not a robot, an unknown branch, or a target of the wrong shape.
    """
    robot = as_robot(robot)
    return robot._ik(target, robot.check_branch(branch), **options)


def fk(robot: Robot, q: Jet | ArrayLike, **options: Any) -> FKResult:
    """Forward kinematics of any robot.

    Args:
        robot: any ``Robot``.
        q: ``Jet`` (or plain array, at rest) of joint coordinates, shape ``(..., n_joints)``.
        **options: passed to the robot's solver (e.g. ``tol`` for the Delta's Newton FK).

    Returns:
        ``FKResult`` (or a subclass): ``x`` (Jet in the form of the robot's targets) and
        ``status``.

    Raises:
        ValueError: not a robot, or ``q`` of the wrong shape.
    """
    return as_robot(robot)._fk(q, **options)
