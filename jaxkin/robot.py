"""The robot protocol: what every robot offers, and ``jaxkin.ik`` / ``jaxkin.fk``.

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

They are THE pipeline: the input work is done here once for every robot (robot and branch
checks, options, ``Jet`` conversion, the target's shape against ``robot.target``, the work
dtype, the batch shape broadcast with the geometry's own, zero rates at rest, written once) and
the robot's kernel runs in one compiled program per robot class, branch and rates, under the
robot's compile policy (``CompilePolicy``, applied through ``jaxkin._batching``: small batches
padded to a power of two, large ones split across host threads, a concrete geometry compiled in
as constants). One element (batch ``()`` or ``(1,)``, the single query of a planner between
batches) goes straight to the program compiled for its shape: no padding, no host copy. A
robot object asked the same single query (kind, branch, options, input shape and dtype) from a
JAX or NumPy array ``_batching.HOT_AFTER`` times gets its own *hot* program: the geometry and
options compiled in as constants, the outputs that do not depend on the input computed once,
and no input work in Python (looked up first, by the robot object and the options as given,
checked when it was built, and the input's type, shape and dtype), in a table of the
``_batching.HOT_PROGRAMS`` most recently built; its results and statuses are the batched path's.

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
from typing import Any, ClassVar

import jax
import jax.numpy as jnp
import numpy as np
from jax import Array
from jax.typing import ArrayLike

from . import _batching, _compile_cache, _validate
from ._geometry import BOUND, LENGTH, REAL, Geometry, geometry, number
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
    "as_robot",
    "fk",
    "geometry",
    "ik",
    "number",
    "options",
    "promoted",
    "solve_fk",
    "solve_ik",
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

    lower: Array = number(BOUND, (-1,))
    upper: Array = number(BOUND, (-1,))
    velocity: Array = number(BOUND, (-1,), default=math.inf)
    acceleration: Array = number(BOUND, (-1,), default=math.inf)

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


@dataclasses.dataclass(frozen=True)
class CompilePolicy:
    """How the pipeline compiles and runs a robot's kernel (applied through ``_batching``).

    Attributes:
        pad: concrete batches of at most ``_batching.PAD_MAX`` elements run padded to a power
            of two (``_batching.PaddedJit``): batch sizes share one compilation per size class.
        threads: large concrete batches are split across the host threads
            (``_batching.PartsJit``), for loop-bound (iterative) kernels.
        min_part: fewest elements per host-thread part (None: ``_batching.MIN_PART``).
        constant_geometry: a geometry whose every leaf is a concrete scalar is compiled into
            the kernel as constants (one compilation per robot; XLA folds its values).
        branch_as_data: the branch reaches the kernel as a traced index
            (``ik_kernel_indexed``), so every branch shares one compilation.
        bucket: for an iterative kernel that ends a NaN input at once (a chain's IK search):
            a concrete batch of two or more elements runs in blocks of exactly ``bucket``
            rows (a smaller batch padded with NaN rows spread among its own, a larger one as
            overlapping blocks on the host threads): one compilation for every batch size.
            None: not so.
        compiler_options: XLA options of this kernel's compilation alone, ``(name, value)``
            pairs (``jax.jit``'s ``compiler_options``), e.g. a cheaper code generation for a
            large loop-bound kernel.
    """

    pad: bool = True
    threads: bool = False
    min_part: int | None = None
    constant_geometry: bool = False
    branch_as_data: bool = False
    bucket: int | None = None
    compiler_options: tuple[tuple[str, Any], ...] = ()


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

    def link_frame_rows(self, q: Array) -> tuple[list, list[int], Array | None]:
        """The link poses at joints ``q`` ``(C, n)`` in the rows layout, for checks that place
        points elementwise: ``(frames, of_link, homes)`` with ``frames[k]`` the rotation
        entries ``R[i][j]`` and translation entries ``p[i]`` (nested lists of ``(C,)`` arrays
        or Python floats) of frame ``k`` (world <- frame), ``of_link[l]`` the frame carrying
        link ``l`` and ``homes`` ``(L, 4, 4)`` each link's pose in its frame (None: the
        identity). By default one frame per link, from ``link_poses``; a robot whose links
        share frames (a chain's joint prefixes) overrides it."""
        poses = self.link_poses(q)
        count = poses.shape[-3]
        frames = [
            (
                [[poses[..., k, i, j] for j in range(3)] for i in range(3)],
                [poses[..., k, i, 3] for i in range(3)],
            )
            for k in range(count)
        ]
        return frames, list(range(count)), None

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


def as_robot(robot: Any, name: str = "robot") -> Robot:
    """``robot`` if it implements the robot protocol, else a ``ValueError`` naming it."""
    if not isinstance(robot, Robot):
        raise ValueError(
            f"{name} must be a jaxkin robot (scara.Scara, delta.Delta, a serial arm, "
            f"serial.Chain), got {type(robot).__name__}"
        )
    return robot


def make_options(cls: type, given: Any, values: dict[str, Any], name: str = "options") -> Any:
    """An instance of the options class ``cls``: ``given`` (an instance, or None for the
    defaults) with the keyword ``values`` replaced; a ``ValueError`` names unknown keys or an
    instance of another class."""
    if given is None:
        if not values:
            default = _DEFAULTS.get(cls)
            if default is None:
                default = _DEFAULTS[cls] = cls()
            return default
        given = cls()
    elif type(given) is not cls:
        raise ValueError(f"{name} must be a {cls.__qualname__} (or None), got {given!r}")
    if values:
        fields = {f.name for f in dataclasses.fields(cls)}
        unknown = sorted(set(values) - fields)
        if unknown:
            raise ValueError(
                f"unknown option(s) {unknown} for {cls.__qualname__}; expected some of "
                f"{sorted(fields)}"
            )
        given = dataclasses.replace(given, **values)
    return given


_DEFAULTS: dict[type, Any] = {}


# ------------------------------------------------------------------------------ the pipeline


def _float_dtype(dtypes: tuple, canonical: bool) -> Any:
    """The floating dtype inputs of ``dtypes`` are computed in (canonical for the x64 flag;
    ``canonical``: the inputs are JAX arrays, whose dtypes already are)."""
    if canonical and len(dtypes) == 1 and dtypes[0] in _FLOATS:
        return dtypes[0]
    key = (dtypes, jax.config.jax_enable_x64)
    found = _FLOAT_DTYPES.get(key)
    if found is None:
        canonical_dtypes = (jax.dtypes.canonicalize_dtype(d) for d in dtypes)
        found = _FLOAT_DTYPES[key] = jnp.result_type(*canonical_dtypes, float)
    return found


_FLOATS = (np.dtype(np.float32), np.dtype(np.float64))
_FLOAT_DTYPES: dict[Any, Any] = {}


def promoted(dtype: Any, other: Any) -> Any:
    """``jnp.result_type(dtype, other)``, cached (a chain's ``work_dtype`` on every call)."""
    if dtype is other:
        return dtype
    found = _PROMOTED.get((dtype, other))
    if found is None:
        found = _PROMOTED[(dtype, other)] = jnp.result_type(dtype, other)
    return found


_PROMOTED: dict[Any, Any] = {}


class _Program:
    """One compiled kernel of one robot class, branch and rates (the options are an argument:
    their static fields are part of its compilation key, the dynamic ones data): its whole-batch
    call and its padded call (``_batching.PaddedJit``); the geometry compiled in as constants
    when the policy says so."""

    def __init__(self, impl: Callable[..., Any], policy: CompilePolicy, core: int) -> None:
        self.policy = policy
        if policy.threads:
            batched = ("p", "v", "a")
            self.dynamic = _batching.PartsJit(impl, (), batched, policy.min_part)
            self.static = (
                _batching.PartsJit(impl, ("robot",), batched, policy.min_part)
                if policy.constant_geometry
                else None
            )
        else:
            xla = dict(policy.compiler_options) or None
            self.dynamic = _compile_cache.stored_jit(impl, compiler_options=xla)
            self.static = (
                jax.jit(impl, static_argnames="robot", compiler_options=xla)
                if policy.constant_geometry
                else None
            )
        self.padded = _batching.PaddedJit(self.whole, {"p": core, "v": core, "a": core})

    def whole(
        self, robot: Any, p: Any, v: Any, a: Any, index: Any, options: Any, *, batch: tuple = ()
    ) -> Any:
        """The kernel on the whole batch (split across host threads when large)."""
        jitted = self.dynamic
        if self.static is not None:
            constant = _constant_geometry(robot)
            if constant is not None:
                robot, jitted = constant, self.static
        if not self.policy.threads:
            return jitted(robot, p, v, a, index, options)
        if math.prod(batch) < 2:  # nothing to split: the kernel as it is
            return jitted.whole(robot, p, v, a, index, options)
        return jitted(robot, p, v, a, index, options, batch=batch)

    whole.takes_batch = True


def _constant_geometry(robot: Any) -> Any:
    """``robot`` with Python-float leaves when every leaf is a concrete scalar, else None."""
    leaves, tree = jax.tree.flatten(robot)
    if not all(is_concrete(leaf) and np.ndim(leaf) == 0 for leaf in leaves):
        return None
    return jax.tree.unflatten(tree, [float(leaf) for leaf in leaves])


def _ik_impl(branch: Any, rates: bool, robot: Robot, p, v, a, index, options) -> IKResult:
    target = _as_target(robot, p, v, a, len(robot.target.shape))
    if index is not None:
        return robot.ik_kernel_indexed(target, index, options, rates)
    return robot.ik_kernel(target, branch, options, rates)


def _fk_impl(rates: bool, outside: bool, robot: Robot, p, v, a, index, options) -> FKResult:
    result = robot.fk_kernel(_as_target(robot, p, v, a, 1), options, rates)
    if rates:
        return result
    # At rest the zero rates are written once: here, or by the caller for a large batch.
    x = Jet(result.x.p, None, None) if outside else Jet.constant(result.x.p)
    return dataclasses.replace(result, x=x)


def _as_target(robot: Robot, p: Array, v: Any, a: Any, core: int) -> Jet:
    """The kernel's input Jet, broadcast against the geometry's batch (zero rates at rest)."""
    extra = robot.batch_shape()
    if extra:
        shape = (*jnp.broadcast_shapes(p.shape[: p.ndim - core], extra), *p.shape[p.ndim - core :])
        p, v, a = (None if x is None else jnp.broadcast_to(x, shape) for x in (p, v, a))
    if v is None:
        zeros = jnp.zeros_like(p)
        return Jet(p, zeros, zeros)
    return Jet(p, v, a)


_PROGRAMS: dict[tuple, _Program] = {}


def _program(kind: str, robot: Robot, key: tuple, policy: CompilePolicy) -> _Program:
    """The cached ``_Program`` of ``kind`` (``"ik"``/``"fk"``) for the robot's class and the
    static ``key`` (branch, options, rates, ...)."""
    full = (kind, type(robot), *key)
    program = _PROGRAMS.get(full)
    if program is None:
        impl = _ik_impl if kind == "ik" else _fk_impl
        core = len(robot.target.shape) if kind == "ik" else 1
        program = _PROGRAMS[full] = _Program(functools.partial(impl, *key), policy, core)
    return program


def _inputs(robot: Robot, x: Any, name: str, core: tuple[int, ...]):
    """``(p, v, a, rates, batch)``: the input's arrays in the work dtype (``v``, ``a`` None at
    rest) and its batch shape broadcast with the geometry's; ``ValueError`` naming ``name``."""
    rates = isinstance(x, Jet)
    if rates:
        arrays = [_array(y) for y in (x.p, x.v, x.a)]
        shapes = {tuple(y.shape) for y in arrays}
        if len(shapes) != 1:
            raise ValueError(f"{name}: p, v and a must have one shape, got {sorted(shapes)}")
    else:
        arrays = [_array(x)]
    shape = arrays[0].shape
    k = len(core)
    if len(shape) < k or tuple(shape[len(shape) - k :]) != core:
        want = ", ".join(str(d) for d in core)
        raise ValueError(
            f"{name}: {type(robot).__name__} expects shape (..., {want}), got {tuple(shape)}"
        )
    canonical = all(type(y) in _JAX_TYPES for y in arrays)
    dtype = robot.work_dtype(_float_dtype(tuple(y.dtype for y in arrays), canonical))
    arrays = [y if y.dtype is dtype or y.dtype == dtype else _cast(y, dtype) for y in arrays]
    batch = tuple(shape[: len(shape) - k])
    extra = robot.batch_shape()
    if extra:
        batch = _validate.batch_shape({name: batch, "robot": extra})
    p, v, a = arrays if rates else (arrays[0], None, None)
    return p, v, a, rates, batch


def _array(x: Any) -> Any:
    """``x`` as an array with a shape and a dtype (JAX and NumPy arrays and tracers as they
    are; anything else through NumPy)."""
    if type(x) in _ARRAY_TYPES:
        return x
    if isinstance(x, _ARRAYS):
        if isinstance(x, jax.Array) and not isinstance(x, jax.core.Tracer):
            _ARRAY_TYPES.add(type(x))
            _JAX_TYPES.add(type(x))
        return x
    if not hasattr(x, "shape") or not hasattr(x, "dtype"):
        try:
            arr = np.asarray(x)
        except (TypeError, ValueError):
            raise ValueError(f"expected an array of numbers, got {x!r}") from None
        if arr.dtype == object or arr.dtype.kind not in "biuf":
            raise ValueError(f"expected an array of real numbers, got {x!r}")
        return arr
    return x


_ARRAYS = (jax.Array, np.ndarray)
_ARRAY_TYPES = {np.ndarray}  # concrete array types seen: checked before the slower isinstance
_JAX_TYPES: set[type] = set()  # concrete JAX array types seen


def _cast(x: Any, dtype: Any) -> Any:
    """``x`` in ``dtype``: on the host for NumPy input (no dispatch), else one JAX cast."""
    if isinstance(x, np.ndarray):
        return x.astype(dtype)
    return jnp.asarray(x).astype(dtype)


def _run(program: _Program, robot: Robot, p, v, a, index, options, batch: tuple) -> Any:
    """Apply the compile policy: one element straight to the kernel compiled for its shape
    (the single-query fast path), small batches padded, large ones as the policy says; with
    ``bucket``, every concrete batch (one element included) in the blocks of ``_bucketed``."""
    size = math.prod(batch)
    if program.policy.bucket and not robot.batch_shape():
        return _bucketed(program, robot, p, v, a, index, options, batch)
    if size == 1 or not program.policy.pad or robot.batch_shape():
        return program.whole(robot, p, v, a, index, options, batch=batch)
    return program.padded(robot, p, v, a, index, options, batch=batch)


def _bucketed(program: _Program, robot: Robot, p, v, a, index, options, batch: tuple) -> Any:
    """``CompilePolicy.bucket``: the batch in blocks of ``bucket`` rows (a small batch's rows
    spread among NaN rows, gathered back; a large one as overlapping blocks, joined), each
    through the one program of that block size (tracers run as they are)."""
    if not all(is_concrete(x) for x in jax.tree.leaves((robot, p, v, a, options))):
        return program.whole(robot, p, v, a, index, options, batch=batch)
    size, block = math.prod(batch), program.policy.bucket
    core = p.ndim - len(batch)
    if size <= block:
        p, v, a = (
            None if x is None else _batching.spread_rows(x, batch, core, block, np.nan)
            for x in (p, v, a)
        )
        result = program.whole(robot, p, v, a, index, options, batch=(block,))
        # Gathered on the host: a program per batch shape would compile anew for each size.
        rows = _batching.spread_positions(size, block)
        return jax.tree.map(
            lambda x: jax.device_put(np.asarray(x)[rows].reshape((*batch, *x.shape[1:]))), result
        )
    rows = [
        None if x is None else np.broadcast_to(np.asarray(x), (*batch, *p.shape[len(batch) :]))
        for x in (p, v, a)
    ]
    rows = [None if x is None else x.reshape(size, *x.shape[len(batch) :]) for x in rows]
    count = -(-size // block)
    starts = [k * block for k in range(count - 1)] + [size - block]

    def run(start: int) -> Any:
        p, v, a = (None if x is None else x[start : start + block] for x in rows)
        return program.whole(robot, p, v, a, index, options, batch=(block,))

    parts = _batching.run_parts(run, starts)
    overlap = count * block - size

    def joined(*leaves: Any) -> Any:
        host = [np.asarray(x) for x in leaves]
        whole = np.concatenate([*host[:-1], host[-1][overlap:]], axis=0)
        return jax.device_put(whole.reshape((*batch, *whole.shape[1:])))

    return jax.tree.map(joined, *parts)


# ------------------------------------------------------------------ hot single queries


def _hot_query(robot: Any, kind: str, branch: Any, options: Any, x: Any) -> Any:
    """The compiled single query of ``robot`` for this input's type, shape and dtype, once the
    same robot object has asked it ``_batching.HOT_AFTER`` times (``_batching.HotQueries``);
    None for anything else (the pipeline then does its usual input work). ``options`` as the
    caller gave it: None (the defaults) or an instance; the robot and the options are checked
    when the program is built, so a later call that finds it skips every check."""
    kx = type(x)
    if kx in _JAX_TYPES:  # its abstract value holds the shape and dtype (its properties: 3x)
        aval = x.aval
        shape, dtype = aval.shape, aval.dtype
    elif kx is np.ndarray:
        shape, dtype = x.shape, x.dtype
    else:
        return None  # a Jet, a tracer, a list: the usual path
    try:
        key = (id(robot), kind, branch, options, kx, shape, dtype, _X64.value)
        entry = _HOT.programs.get(key)
    except TypeError:  # options or a branch that cannot be hashed: the usual path
        return None
    if entry is not None and entry[0] is robot:
        return entry[1]
    if not isinstance(robot, Robot):
        return None
    return _HOT.get(key, robot, lambda: _hot_build(robot, kind, branch, options, x))


class _ConfigX64:
    """``jax.config.jax_enable_x64`` as ``.value`` (where JAX's own flag object is private)."""

    @property
    def value(self) -> bool:
        return jax.config.jax_enable_x64


try:  # the flag read in 70 ns (jax.config's attribute: 240 ns), once per hot call
    from jax._src.config import enable_x64 as _X64
except ImportError:  # pragma: no cover - another JAX layout
    _X64 = _ConfigX64()


def _hot_build(robot: Robot, kind: str, branch: Any, options: Any, x: Any) -> Any:
    """The single query compiled with the geometry and options as constants, or None when
    the query is not one element of a concrete, unbatched robot, or is the IK of a chain
    (an iterative search, dominated by its own iterations) or of an analytic arm (all its
    branches in one program: a second compilation of a minute would cost more than it saves)."""
    core = robot.target.shape if kind == "ik" else (robot.n_joints,)
    if np.shape(x) not in (core, (1, *core)) or robot.batch_shape():
        return None
    if kind == "ik" and (robot.ik_policy.bucket or robot.ik_policy.branch_as_data):
        return None  # a search, or every branch solved at once: compiles for tens of seconds
    leaves, tree = jax.tree.flatten(robot)
    if not all(is_concrete(leaf) for leaf in leaves):
        return None
    try:  # the usual path says what is wrong
        if kind == "ik":
            branch = robot.default_branch if branch is None else robot.check_branch(branch)
        options = make_options(robot.IKOptions if kind == "ik" else robot.FKOptions, options, {})
    except ValueError:
        return None
    # a robot rebuilt with the same values (a new object per episode) shares the program
    values = tuple(
        (np.asarray(leaf).dtype.str, np.shape(leaf), np.asarray(leaf).tobytes()) for leaf in leaves
    )
    key = (tree, values, kind, branch, options, x.shape, x.dtype, jax.config.jax_enable_x64)
    if key in _HOT.by_value:
        return _HOT.by_value[key]
    if kind == "ik":
        program = _batching.hot_program(lambda y: _solve_ik(robot, y, branch, options), x)
    else:
        program = _batching.hot_program(lambda y: _solve_fk(robot, y, options), x)
    _batching.bounded_put(_HOT.by_value, key, program, _HOT.size)
    return program


_HOT = _batching.HotQueries()


def ik(
    robot: Robot,
    target: Jet | ArrayLike,
    branch: Any = None,
    options: Any = None,
    **option_values: Any,
) -> IKResult:
    """Inverse kinematics of any robot for one branch.

    Args:
        robot: any ``Robot``.
        target: ``Jet`` (or plain array, at rest) of shape ``(..., *robot.target.shape)``.
        branch: one of ``robot.branches``; None for ``robot.default_branch``.
        options: an instance of ``robot.IKOptions`` (None: its defaults).
        **option_values: fields of ``robot.IKOptions`` replaced (e.g. ``method="autodiff"``).

    Returns:
        ``IKResult`` (or a subclass): ``q`` (Jet, ``(..., n_joints)``), ``status``, ``margin``.
        Work is done in the target's floating dtype (``robot.work_dtype``).

    Raises:
        ValueError: not a robot, an unknown branch or option, or a target of the wrong shape
            or a batch shape that does not broadcast with the geometry's.
    """
    if not option_values:  # a hot single query answers before any input work
        hot = _hot_query(robot, "ik", branch, options, target)
        if hot is not None:
            return hot(target)
        robot = as_robot(robot)
        return _solve_ik(robot, target, branch, make_options(robot.IKOptions, options, {}))
    robot = as_robot(robot)
    return solve_ik(robot, target, branch, make_options(robot.IKOptions, options, option_values))


def solve_ik(robot: Robot, target: Any, branch: Any, options: Any, name: str = "target") -> Any:
    """``ik`` with ``options`` an ``IKOptions`` instance and the target named ``name`` in
    messages (a robot module's own function, e.g. ``scara.ik``, calls this)."""
    hot = _hot_query(robot, "ik", branch, options, target)
    if hot is not None:
        return hot(target)
    return _solve_ik(robot, target, branch, options, name)


def _solve_ik(robot: Robot, target: Any, branch: Any, options: Any, name: str = "target") -> Any:
    """``solve_ik`` without the hot single query."""
    branch = robot.default_branch if branch is None else robot.check_branch(branch)
    p, v, a, rates, batch = _inputs(robot, target, name, robot.target.shape)
    policy = robot.ik_policy
    if policy.branch_as_data:
        index = np.int32(robot.branches.index(branch))
        program = _program("ik", robot, (None, rates), policy)
    else:
        index = None
        program = _program("ik", robot, (branch, rates), policy)
    return _run(program, robot, p, v, a, index, options, batch)


def fk(robot: Robot, q: Jet | ArrayLike, options: Any = None, **option_values: Any) -> FKResult:
    """Forward kinematics of any robot.

    Args:
        robot: any ``Robot``.
        q: ``Jet`` (or plain array, at rest) of joint coordinates, shape ``(..., n_joints)``.
        options: an instance of ``robot.FKOptions`` (None: its defaults).
        **option_values: fields of ``robot.FKOptions`` replaced (e.g. ``tol`` for the Delta's
            Newton FK).

    Returns:
        ``FKResult`` (or a subclass): ``x`` (Jet in the form of the robot's targets) and
        ``status``.

    Raises:
        ValueError: not a robot, an unknown option, or ``q`` of the wrong shape.
    """
    if not option_values:  # a hot single query answers before any input work
        hot = _hot_query(robot, "fk", None, options, q)
        if hot is not None:
            return hot(q)
        robot = as_robot(robot)
        return _solve_fk(robot, q, make_options(robot.FKOptions, options, {}))
    robot = as_robot(robot)
    return solve_fk(robot, q, make_options(robot.FKOptions, options, option_values))


def solve_fk(robot: Robot, q: Any, options: Any, name: str = "q") -> Any:
    """``fk`` with ``options`` an ``FKOptions`` instance and ``q`` named ``name``."""
    hot = _hot_query(robot, "fk", None, options, q)
    if hot is not None:
        return hot(q)
    return _solve_fk(robot, q, options, name)


def _solve_fk(robot: Robot, q: Any, options: Any, name: str = "q") -> Any:
    """``solve_fk`` without the hot single query."""
    p, v, a, rates, batch = _inputs(robot, q, name, (robot.n_joints,))
    outside = _batching.zero_rates_outside(rates, batch)
    program = _program("fk", robot, (rates, outside), robot.fk_policy)
    result = _run(program, robot, p, v, a, None, options, batch)
    return dataclasses.replace(result, x=Jet.constant(result.x.p)) if outside else result
