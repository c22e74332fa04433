"""The robot protocol: what every robot offers to ``jaxkin.ik`` / ``jaxkin.fk`` and the planners.

Every robot geometry (``scara.Scara``, ``delta.Delta``, the serial arms, the chain robot
``serial.Chain``) is a ``Robot``. The planner, the optimiser, workspace sweeps and the
command line are written against this interface alone and never ask which robot they have:

* ``robot.target``: what its inverse kinematics takes and its forward kinematics returns
  (``PLANAR_POINT`` ``(2,)``, ``POINT`` ``(3,)``, ``PLANAR_POSE`` ``(x, y, phi)``, ``POSE`` a
  4x4 homogeneous transform), with the coordinate names used in files;
* ``robot.branches`` and ``robot.default_branch``: the solution branches its IK can hold along
  a path (the SCARA's assembly modes ``+1``/``-1``, the Delta's ``"out"``/``"in"``, an arm's
  branch names);
* ``robot.joint_names`` (hence ``n_joints``), ``robot.joint_types`` (``"R"``/``"P"`` per joint)
  and ``robot.joint_limits()`` (position, velocity and acceleration bounds);
* ``robot.reachable``: the statuses that count as reachable in a workspace sweep;
* ``robot.length_scale()``: a characteristic length (the robot's size),
  ``robot.workspace_box()``: the default box and voxel edge of a sweep, and
  ``robot.link_segments(q, x)``: the links as segments;
* ``robot.collision_body()`` (a ``collision.Body``), ``robot.link_poses(q)`` (every link's
  pose, a pure kernel) and ``robot.self_collision_pairs()``: the body that
  ``collision.check`` places and checks.

``ik(robot, target, branch=None, options=None)`` returns an ``IKResult`` (``q``: a ``Jet`` of
joint coordinates ``(..., n_joints)``, ``status``, ``margin``) for the default branch when
``branch`` is None; ``fk(robot, q, options=None)`` returns an ``FKResult`` whose ``x`` is a
``Jet`` in the form of the targets, so ``fk(robot, ik(robot, t).q).x`` reproduces ``t``.
Targets and joints may be plain arrays (taken at rest: zero rates) or ``Jet``s. Both work inside
``jit`` and ``vmap``.

``jaxkin.ik`` and ``jaxkin.fk`` (re-exported here) are the execution layer's
(``jaxkin._execute.pipeline``): the input work done once for every robot, the robot's kernel
compiled once per robot class, branch and rates under the robot's compile policy
(``ik_policy``/``fk_policy``, a ``CompilePolicy``).

A new robot subclasses ``Robot`` (as a ``geometry`` dataclass whose fields are ``number``s),
sets the class attributes and implements the pure kernels ``ik_kernel`` and ``fk_kernel``
(declared abstract: a class lacking one fails when it is defined); it may declare
``IKOptions``/``FKOptions`` (``options`` dataclasses), a compile policy, and override
``ik_kernel_indexed`` and ``ik_path_kernel`` (the planner's IK along sampled paths). The
command line needs one registry entry (``jaxkin.cli.robots``). The protocol and a complete
example are in ``docs/design.md``.
"""

from __future__ import annotations

import abc
import dataclasses
import functools
import math
from collections.abc import Callable, Mapping
from typing import Any, ClassVar, TypeVar, dataclass_transform, overload

import jax
import jax.numpy as jnp
import numpy as np
from jax import Array
from jax.typing import ArrayLike

from . import _validate
from ._execute import Policy, fk, ik
from ._geometry import BOUND, LENGTH, REAL, Geometry, Numeric, geometry, number
from ._validate import is_concrete
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
    "CompilePolicy",
    "JointLimits",
    "NoOptions",
    "Robot",
    "Target",
    "fk",
    "geometry",
    "ik",
    "number",
    "options",
    "promoted",
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

    def position(self, x: Any) -> np.ndarray:
        """Host side: the tool's position in 3-D, ``(..., 3)``, of targets ``x`` ``(...,
        *shape)`` (a pose's translation; a planar target's ``x, y`` at ``z = 0``)."""
        x = np.asarray(x)
        if self.shape == (4, 4):
            return x[..., :3, 3]
        if self.shape == (3,) and self.is_point:
            return x
        return np.concatenate([x[..., :2], np.zeros_like(x[..., :1])], axis=-1)


PLANAR_POINT = Target("planar point", (2,), ("x", "y"), True)
POINT = Target("point", (3,), ("x", "y", "z"), True)
PLANAR_POSE = Target("planar pose", (3,), ("x", "y", "phi"), False)
POSE = Target("pose", (4, 4), ("x", "y", "z", "qw", "qx", "qy", "qz"), False)


@geometry
class JointLimits(Geometry):
    """A robot's own joint limits: closed ranges ``lower <= q <= upper`` and bounds on the
    joint rates ``|q_dot| <= velocity``, ``|q_ddot| <= acceleration`` (what the planner applies
    by default).

    Attributes:
        lower: lower bounds, shape ``(n,)`` (rad or length); ``-inf`` for none.
        upper: upper bounds, shape ``(n,)``; ``+inf`` for none.
        velocity: speed bounds, shape ``(n,)`` or a scalar for every joint (rad/s or length/s,
            ``>= 0``); ``+inf`` (the default) for none.
        acceleration: acceleration bounds, likewise (rad/s^2 or length/s^2); default none.
    """

    lower: Numeric = number(BOUND, (-1,))
    upper: Numeric = number(BOUND, (-1,))
    velocity: Numeric = number(BOUND, (-1,), default=math.inf)
    acceleration: Numeric = number(BOUND, (-1,), default=math.inf)

    def _validate(self) -> None:
        for name in ("velocity", "acceleration"):  # a scalar bound is every joint's
            value = getattr(self, name)
            if not is_concrete(value) or isinstance(value, bool | np.bool_) or np.ndim(value):
                continue
            if np.asarray(value).dtype.kind in "fiu":
                object.__setattr__(self, name, np.full(np.shape(self.lower), float(value)))
        super()._validate()
        lower, upper = (np.asarray(x, dtype=float) for x in (self.lower, self.upper))
        if lower.shape != upper.shape:
            raise ValueError(
                f"JointLimits.upper must have the shape of lower {lower.shape}, got {upper.shape}"
            )
        for name in ("velocity", "acceleration"):
            bound = np.asarray(getattr(self, name), dtype=float)
            try:
                bound = np.broadcast_to(bound, lower.shape)
            except ValueError:
                raise ValueError(
                    f"JointLimits.{name} must be a scalar or of shape {lower.shape}, got "
                    f"{bound.shape}"
                ) from None
            if np.any(bound < 0):
                raise ValueError(f"JointLimits.{name} must be >= 0, got {bound}")
            object.__setattr__(self, name, jax.device_put(bound))  # no program to compile
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
        n = _validate.count(n, "n")
        return cls(np.full(n, -np.inf), np.full(n, np.inf))

    def contains(self, q: ArrayLike) -> Array:
        """True where every joint of ``q`` (shape ``(..., n)``) lies in its closed range."""
        q = jnp.asarray(q)
        inside = (q >= jnp.asarray(self.lower, q.dtype)) & (q <= jnp.asarray(self.upper, q.dtype))
        return jnp.all(inside, axis=-1)


# ------------------------------------------------------------------------------- options


_Options = TypeVar("_Options", bound=type)


@overload
def options(cls: _Options, *, dynamic: tuple[str, ...] = ()) -> _Options: ...


@overload
def options(
    cls: None = None, *, dynamic: tuple[str, ...] = ()
) -> Callable[[_Options], _Options]: ...


@dataclass_transform(frozen_default=True)
def options(cls: type | None = None, *, dynamic: tuple[str, ...] = ()) -> Any:
    """Class decorator of a robot's ``IKOptions`` / ``FKOptions``: a frozen, hashable
    dataclass with defaults. Fields named in ``dynamic`` (tolerances) reach the kernel as traced
    values, so a new value compiles nothing new; the others (counts, methods) are static.
    ``__post_init__`` may validate the values (a ``ValueError`` naming the option)."""

    def wrap(cls: type) -> type:
        cls = dataclasses.dataclass(frozen=True)(cls)
        names = tuple(f.name for f in dataclasses.fields(cls))
        unknown = sorted(set(dynamic) - set(names))
        if unknown:
            raise TypeError(f"{cls.__name__}: dynamic names unknown fields {unknown}")
        meta = tuple(n for n in names if n not in dynamic)
        jax.tree_util.register_dataclass(cls, data_fields=list(dynamic), meta_fields=list(meta))
        return cls

    return wrap if cls is None else wrap(cls)


@options
class NoOptions:
    """The options of a kernel that takes none."""


# How the execution layer compiles and runs a robot's kernel (``_execute.Policy``).
CompilePolicy = Policy


KERNELS = ("ik_kernel", "fk_kernel")


class Robot(Geometry, metaclass=abc.ABCMeta):
    """Base class of every robot geometry (see the module docstring for the protocol).

    A concrete subclass implements ``ik_kernel`` and ``fk_kernel``; one lacking either fails
    with a ``TypeError`` when its class is defined, unless it declares itself abstract
    (``class Arm(Robot, abstract=True)``).
    """

    target: ClassVar[Target]
    branches: ClassVar[tuple[Any, ...]]
    reachable: ClassVar[tuple[Status, ...]] = (Status.OK, Status.SINGULAR)
    IKOptions: ClassVar[type] = NoOptions
    FKOptions: ClassVar[type] = NoOptions
    ik_policy: ClassVar[CompilePolicy] = CompilePolicy()
    fk_policy: ClassVar[CompilePolicy] = CompilePolicy()

    def __init_subclass__(cls, abstract: bool = False, **kwargs: Any) -> None:
        super().__init_subclass__(**kwargs)
        if abstract:
            return
        missing = [
            name
            for name in KERNELS
            if getattr(getattr(cls, name, None), "__isabstractmethod__", False)
        ]
        if missing:
            raise TypeError(
                f"{cls.__name__} must implement {', '.join(missing)} (the robot protocol's "
                f"kernels), or be declared abstract: class {cls.__name__}(..., abstract=True)"
            )

    # ------------------------------------------------------------------ kernels
    @abc.abstractmethod
    def ik_kernel(self, target: Jet, branch: Any, options: Any, rates: bool) -> IKResult:
        """Inverse kinematics on ``branch`` (one of ``branches``): pure and traceable.

        Args:
            target: Jet of the robot's work dtype, shape ``(..., *self.target.shape)`` (its
                leading axes broadcast against the geometry's own batch axes).
            branch: one of ``self.branches`` (static).
            options: an instance of ``self.IKOptions``.
            rates: False when the target is at rest: its rates are zero and the kernel may
                skip them (the result's rates must then be zero).
        """

    @abc.abstractmethod
    def fk_kernel(self, q: Jet, options: Any, rates: bool) -> FKResult:
        """Forward kinematics: pure and traceable; ``q`` a Jet ``(..., n_joints)`` of the work
        dtype. At rest (``rates`` False) the pipeline writes the zero rates of ``x`` itself:
        the kernel's are ignored."""

    def ik_kernel_indexed(
        self, target: Jet, index: Array, options: Any, rates: bool = True
    ) -> IKResult:
        """The IK on branch ``self.branches[index]``, ``index`` a traced ``int32`` scalar (the
        planner maps it over every branch). By default a ``lax.switch`` over the branches; a
        robot whose kernel takes the branch as data overrides it, so that its branches compile
        as one program."""
        solvers = [
            functools.partial(self.ik_kernel, branch=b, options=options, rates=rates)
            for b in self.branches
        ]
        return jax.lax.switch(index, solvers, target)

    def ik_path_kernel(self, path: Jet, index: Any, options: Any, seed: Any = None) -> IKResult:
        """The IK of sampled paths ``(..., T, *target.shape)`` (consecutive samples along the
        axis before the target's) on branch ``self.branches[index]`` (``index`` an int, or a
        traced ``int32`` scalar), for the planner. By default every sample on its own; a robot
        whose IK is iterative overrides it to warm-start each sample from the previous one,
        and the first from ``seed`` ``(..., n_joints)`` when given (the joints of the last
        solved sample before the path: a long path solved in windows), which the default
        ignores."""
        if isinstance(index, int):
            return self.ik_kernel(path, self.branches[index], options, True)
        return self.ik_kernel_indexed(path, index, options, True)

    # ------------------------------------------------------------------ description
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
        """The robot's own position, velocity and acceleration limits (``inf`` where a joint
        has none); the planner applies them by default."""
        return JointLimits.unbounded(self.n_joints)

    def length_scale(self) -> Any:
        """A characteristic length of the robot (its size; traceable)."""
        raise NotImplementedError

    def work_dtype(self, dtype: Any) -> Any:
        """The dtype the kernels work in for inputs of floating ``dtype`` (by default
        ``dtype`` itself; a chain promotes it with its own arrays' dtype: ``promoted``)."""
        return dtype

    def work_target(self, x: Any, dtype: Any) -> Any:
        """Targets ``x`` ``(..., *target.shape)`` in the work dtype ``dtype`` (``x``'s own is
        another): a cast by default; a chain's poses given in a less precise dtype also get
        the nearest rotation in ``dtype`` (``serial._step.promoted_pose``). Traceable."""
        return x.astype(dtype)

    def batch_shape(self) -> tuple[int, ...]:
        """The batch axes of the geometry's own values (broadcast against the inputs' batch);
        ``()`` for a geometry shared by the whole batch. By default read from the fields'
        declared shapes (``number(kind, shape)``: a field of shape None is all batch)."""
        cached = self.__dict__.get("_batch_shape")
        if cached is None:
            cached = _geometry_batch(self)
            object.__setattr__(self, "_batch_shape", cached)
        return cached

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

    def collision_body(self) -> Any:
        """The robot's body for collision checks: a ``collision.Body`` (spheres and capsules
        attached to the links that ``link_poses`` places; host side). A robot without one
        raises a ``ValueError``."""
        raise ValueError(f"{type(self).__name__} has no collision body (collision_body)")

    def link_poses(self, q: Array) -> Array:
        """Every link's pose ``(..., L, 4, 4)`` (world <- link, in the order of
        ``collision_body().links``) at joints ``q`` ``(..., n)``: a pure, traceable kernel."""
        raise ValueError(f"{type(self).__name__} has no link poses (link_poses)")

    def placeable(self, q: Array) -> Array:
        """Whether ``link_poses`` places the body as the robot assembles at finite joints
        ``q`` ``(..., n)``: ``(...,)`` bool (a pure, traceable kernel). True by default; a
        closed chain overrides it for joints at which it cannot assemble (a Delta's actuator
        angles that its rods cannot join to the platform), where its poses are a
        placeholder."""
        return jnp.ones(q.shape[:-1], bool)

    def link_frame_rows(self, q: Array) -> tuple[tuple[Array, Array], tuple[int, ...], Any]:
        """The link poses at joints ``q`` ``(B, n)`` in the rows layout of the collision
        checks (configurations minor): ``(frames, of_link, homes)`` with ``frames`` the
        rotations ``(F, 3, 3, B)`` and translations ``(F, 3, B)`` of ``F`` frames (world <-
        frame), ``of_link[l]`` the frame carrying link ``l`` and ``homes`` ``(L, 4, 4)`` each
        link's pose in its frame (None: the identity). By default one frame per link, from
        ``link_poses``; a robot whose links share frames (a chain's joint prefixes) overrides
        it."""
        poses = self.link_poses(q)
        frames = (jnp.moveaxis(poses[..., :3, :3], 0, -1), jnp.moveaxis(poses[..., :3, 3], 0, -1))
        return frames, tuple(range(poses.shape[-3])), None

    def self_collision_pairs(self) -> tuple[tuple[int, int], ...]:
        """The link index pairs ``(i, j)``, ``i < j``, checked for self-collision (host side;
        by default none)."""
        return ()

    def check_branch(self, branch: Any) -> Any:
        """``branch``, or the default branch for None; ``ValueError`` naming the choices."""
        if branch is None:
            return self.default_branch
        if isinstance(branch, bool) or branch not in self.branches:
            raise ValueError(
                f"branch must be one of {self.branches} for {type(self).__name__}, got {branch!r}"
            )
        return self.branches[self.branches.index(branch)]


def _geometry_batch(geometry: Any) -> tuple[int, ...]:
    """Broadcast batch axes of the ``number`` fields (and nested geometries) of ``geometry``."""
    shapes = []
    for field in dataclasses.fields(geometry):
        value = getattr(geometry, field.name)
        if isinstance(value, Geometry) and dataclasses.is_dataclass(value):
            shapes.append(_geometry_batch(value))
        elif "kind" in field.metadata:
            shape, core = tuple(np.shape(value)), field.metadata["shape"]
            shapes.append(shape if core is None else shape[: max(0, len(shape) - len(core))])
    return tuple(np.broadcast_shapes(*shapes)) if shapes else ()


def promoted(dtype: Any, other: Any) -> Any:
    """``jnp.result_type(dtype, other)``, cached (a chain's ``work_dtype`` on every call)."""
    if dtype is other:
        return dtype
    found = _PROMOTED.get((dtype, other))
    if found is None:
        found = _PROMOTED[(dtype, other)] = jnp.result_type(dtype, other)
    return found


_PROMOTED: dict[Any, Any] = {}
