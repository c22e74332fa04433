"""The Delta robot's geometry [Cardona]: frame, dimensions, limits and shared kernel pieces.

Frame (the paper's figures are not available; the convention is stated in
``docs/conventions.md``): origin at the centre of the fixed platform, z up, the moving platform
below it (z < 0). Chain i (i = 1, 2, 3) has its actuator axis at ``A_i = r_base u_i`` with
``u_i = (cos phi_i, sin phi_i, 0)``, ``phi_i = -90 + 120 (i - 1)`` degrees (chain 1 in the YZ
plane on the -y side, counter-clockwise seen from +z). ``theta_i = 0`` with the arm horizontal
and radially outward, positive *downward*: the elbow is
``E_i = A_i + l_arm (cos theta_i u_i - sin theta_i e_z)``. The platform does not rotate; its
joint i is at ``D_i = p + r_platform u_i`` and the parallelogram keeps ``|D_i - E_i| = l_rod``.
The sphere centres ``C_i = E_i - r_platform u_i`` are the points ``p`` keeps at ``l_rod``.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable
from typing import Any, ClassVar

import jax
import jax.numpy as jnp
from jax import Array
from jax.typing import ArrayLike

from .. import _batching, _validate
from .._geometry import BOUND, LENGTH, concrete_scalars, geometry, number
from .._numerics import computed_once, safe_sqrt
from .._trig import cos_alone, sin_alone
from ..jet import Jet
from ..robot import POINT, CompilePolicy, JointLimits, Robot, options
from ..status import Status

__all__ = ["BRANCHES", "METHODS", "Delta"]

BRANCHES = ("out", "in")
METHODS = ("analytic", "autodiff")
JOINT_NAMES = ("theta1", "theta2", "theta3")
FIELDS = ("r_base", "r_platform", "l_arm", "l_rod", "theta_min", "theta_max")

# Radial unit vectors u_i = (cos phi_i, sin phi_i), phi_i = -90, 30, 150 degrees.
_SQRT3_2 = math.sqrt(3.0) / 2.0

_UX = (0.0, _SQRT3_2, -_SQRT3_2)

_UY = (-1.0, 0.5, 0.5)


def _any3(x: Array) -> Array:
    """``any`` over a last axis of size 3, written elementwise: XLA on CPU runs reductions over
    a tiny minor axis as separate slow loops, elementwise ORs fuse with their producers."""
    return x[..., 0] | x[..., 1] | x[..., 2]


def _finite3(x: Array) -> Array:
    return ~_any3(~jnp.isfinite(x))


def _radial(dtype) -> tuple[Array, Array]:
    return jnp.asarray(_UX, dtype), jnp.asarray(_UY, dtype)


@options
class DeltaIKOptions:
    """Options of the Delta's IK: ``method`` ``"analytic"`` (constraint Jacobians) or
    ``"autodiff"`` (``jaxkin.lift``)."""

    method: str = "analytic"

    def __post_init__(self) -> None:
        _validate.choice(self.method, "method", METHODS)


@options
class DeltaFKOptions:
    """Options of the Delta's Newton FK (``jaxkin.delta.fk``).

    Attributes:
        tol: converged where ``max_i |r_i| <= tol * (l_arm + l_rod)``; None for
            ``max(1e-12, 8 eps(dtype))``.
        max_iter: maximum number of Newton updates (>= 1).
        method: ``"analytic"`` rates or ``"autodiff"``.
    """

    tol: float | None = None
    max_iter: int = 30
    method: str = "analytic"

    def __post_init__(self) -> None:
        tol = self.tol
        if tol is not None and not (
            isinstance(tol, int | float)
            and not isinstance(tol, bool)
            and math.isfinite(tol)
            and tol > 0
        ):
            raise ValueError(f"tol must be a positive finite float or None, got {tol!r}")
        if tol is not None:
            object.__setattr__(self, "tol", float(tol))
        max_iter = self.max_iter
        if isinstance(max_iter, bool) or not isinstance(max_iter, int) or max_iter < 1:
            raise ValueError(f"max_iter must be a positive int, got {max_iter!r}")
        _validate.choice(self.method, "method", METHODS)


@geometry
class Delta(Robot):
    """Geometry of a Delta robot (frame in the module docstring); a validated frozen pytree.

    Attributes:
        r_base: radius of the fixed platform, centre to actuator axis (positive, length).
        r_platform: radius of the moving platform, centre to rod joint (positive, length).
        l_arm: length of the actuated arm, actuator axis to elbow (positive, length).
        l_rod: length of the parallelogram rods, elbow to platform joint (positive, length).
        theta_min: lower actuator limit (rad), ``-inf`` for none.
        theta_max: upper actuator limit (rad), ``+inf`` for none; ``theta_min < theta_max``.

    Every field is a scalar pytree leaf (differentiable, e.g. for calibration; vmappable over
    a batch of robots). A ``Delta`` of Python numbers is compiled into the kernels as
    constants (one compilation per geometry); a traced one is passed as data.
    """

    r_base: Any = number(LENGTH)
    r_platform: Any = number(LENGTH)
    l_arm: Any = number(LENGTH)
    l_rod: Any = number(LENGTH)
    theta_min: Any = number(BOUND, default=-math.inf)
    theta_max: Any = number(BOUND, default=math.inf)

    target: ClassVar = POINT
    branches: ClassVar = BRANCHES
    reachable: ClassVar = (Status.OK, Status.SINGULAR)
    IKOptions: ClassVar = DeltaIKOptions
    FKOptions: ClassVar = DeltaFKOptions
    # Concrete geometry compiled in as constants; the Newton FK loop runs on one core per
    # program, so large batches are split across host threads.
    ik_policy: ClassVar = CompilePolicy(constant_geometry=True)
    fk_policy: ClassVar = CompilePolicy(constant_geometry=True, threads=True)

    def _validate(self) -> None:
        super()._validate()
        if not float(self.theta_min) < float(self.theta_max):
            raise ValueError(
                f"Delta.theta_min must be < theta_max, got {self.theta_min} and {self.theta_max}"
            )

    @classmethod
    def paper(cls) -> Delta:
        """The robot of [Cardona, sec. V], in cm: ``(7, 2.5, 15.5, 30)``."""
        return cls(7.0, 2.5, 15.5, 30.0)

    def with_limits(self, theta_min: float, theta_max: float) -> Delta:
        """The same robot with actuator limits (rad)."""
        return self.replace(theta_min=theta_min, theta_max=theta_max)

    @property
    def joint_names(self) -> tuple[str, ...]:
        return JOINT_NAMES

    @property
    def joint_types(self) -> str:
        return "RRR"

    def joint_limits(self) -> JointLimits:
        return JointLimits(jnp.full(3, self.theta_min, float), jnp.full(3, self.theta_max, float))

    def length_scale(self) -> Any:
        return self.l_arm + self.l_rod

    def workspace_box(self) -> tuple[tuple[tuple[float, float], ...], float]:
        """``x, y`` in ``[-R, R]`` with ``R = r_base - r_platform + l_arm + l_rod`` (the largest
        horizontal reach), ``z`` in ``[-0.9 R, 0.9 R]``, voxel edge ``R / 50``: for the paper's
        robot the 101 x 101 x 91 grid of 1 cm [Cardona, sec. V]."""
        reach = float(self.r_base) - float(self.r_platform) + float(self.l_arm)
        reach += float(self.l_rod)
        return ((-reach, reach), (-reach, reach), (-0.9 * reach, 0.9 * reach)), reach / 50.0

    def link_segments(self, q: Array, x: Array) -> Array:
        """Per chain the arm ``A_i -> E_i`` and the rod's centre line ``E_i -> D_i``, at
        actuator angles ``q`` with the platform at ``x``: ``(..., 6, 2, 3)``."""
        segments = []
        for i in range(3):
            u = jnp.asarray([_UX[i], _UY[i], 0.0], q.dtype)
            axis = self.r_base * u
            cos_t, sin_t = jnp.cos(q[..., i, None]), jnp.sin(q[..., i, None])
            elbow = axis + self.l_arm * (cos_t * u - sin_t * jnp.asarray([0.0, 0.0, 1.0], q.dtype))
            joint = x + self.r_platform * u
            axis = jnp.broadcast_to(axis, elbow.shape)
            segments += [jnp.stack([axis, elbow], -2), jnp.stack([elbow, joint], -2)]
        return jnp.stack(segments, -3)

    def ik_kernel(self, target: Jet, branch: Any, options: Any, rates: bool) -> Any:
        from .inverse import ik_kernel

        return ik_kernel(self, target, branch, options, rates)

    def fk_kernel(self, q: Jet, options: Any, rates: bool) -> Any:
        from .forward import fk_kernel

        return fk_kernel(self, q, options, rates)


def _params(robot: Delta, dtype) -> tuple[Array, ...]:
    return tuple(
        jnp.asarray(getattr(robot, f), dtype)
        for f in ("r_base", "r_platform", "l_arm", "l_rod", "theta_min", "theta_max")
    )


def _cos_sin(theta: Array) -> tuple[tuple[Array, ...], tuple[Array, ...]]:
    """``(cos theta_i, sin theta_i)`` of the three actuators as components, computed once.

    Stored once (``computed_once``): XLA would otherwise evaluate them in every loop that reads
    them. A stored stack computes each row on its own, so the rows use ``cos_alone`` and
    ``sin_alone`` (one polynomial each, absolute accuracy, which is what a centre needs).
    """
    angles = [theta[..., i] for i in range(3)]
    rows = computed_once(jnp.stack([cos_alone(t) for t in angles] + [sin_alone(t) for t in angles]))
    return tuple(rows[:3]), tuple(rows[3:])


def _centre_components(robot: Delta, theta: Array, cos_sin=None) -> tuple[tuple[Array, ...], ...]:
    """The sphere centres ``C_i = E_i - r_platform u_i`` as components ``C[i][k]`` (chain i,
    coordinate k), batch-shaped: ``p`` lies at distance ``l_rod`` from each.

    ``cos_sin``: ``_cos_sin(theta)`` when the caller has it already.
    """
    r_base, r_platform, l_arm, _, _, _ = _params(robot, theta.dtype)
    cos_theta, sin_theta = _cos_sin(theta) if cos_sin is None else cos_sin
    out = []
    for i in range(3):
        radial = r_base - r_platform + l_arm * cos_theta[i]
        out.append((radial * _UX[i], radial * _UY[i], -l_arm * sin_theta[i]))
    return tuple(out)


def _components(x: Array) -> tuple[Array, Array, Array]:
    return x[..., 0], x[..., 1], x[..., 2]


def _dot3(u, v) -> Array:
    return u[0] * v[0] + u[1] * v[1] + u[2] * v[2]


def _sanitise(x: Jet, fill: Array, rates: bool = True) -> tuple[Jet, Array]:
    """Double-where, step 1: replace non-finite elements by ``fill`` (position) and 0 (rates).

    Without rates, ``x.v`` and ``x.a`` are ``None`` (positions only, nothing else allocated).
    """
    valid = _finite3(x.p)
    if rates:
        valid = valid & _finite3(x.v) & _finite3(x.a)
    vc = valid[..., None]
    p = jnp.where(vc, x.p, fill)
    if not rates:
        return Jet(p, None, None), valid
    return Jet(p, jnp.where(vc, x.v, 0.0), jnp.where(vc, x.a, 0.0)), valid


def _home(robot: Delta, dtype) -> Array:
    r_base, r_platform, l_arm, l_rod, _, _ = _params(robot, dtype)
    reach = r_base - r_platform + l_arm
    z = -safe_sqrt(l_rod * l_rod - reach * reach)
    return jnp.stack([0.0 * z, 0.0 * z, jnp.where(z < 0, z, -l_rod)])


def in_own_units(robot: Delta) -> tuple[Delta, Any]:
    """The robot with its lengths divided by ``l_arm + l_rod``, and that scale.

    The kernels work in these units, so no square or product of rates over- or underflows
    whatever the scale of the robot and its targets; lengths are scaled back on output.
    """
    scale = robot.l_arm + robot.l_rod
    lengths = [robot.r_base, robot.r_platform, robot.l_arm, robot.l_rod]
    fields = [x / scale for x in lengths] + [robot.theta_min, robot.theta_max]
    return jax.tree.unflatten(jax.tree.structure(robot), fields), scale


# Beyond this many robot sizes from the base a point is unreachable: tested before any square.
FAR = 1e6


def far_away(p: Array) -> Array:
    """True where a point (in the robot's own units, ``(..., 3)``) is beyond ``FAR``."""
    return ~(
        (jnp.abs(p[..., 0]) <= FAR) & (jnp.abs(p[..., 1]) <= FAR) & (jnp.abs(p[..., 2]) <= FAR)
    )


def _rates_ok(status: Array) -> Array:
    # Rates are defined where the position is solved and the relevant Jacobian is regular.
    return (status == Status.OK) | (status == Status.OUT_OF_LIMITS)


def frozen(robot: Delta) -> Delta | None:
    """The robot with Python-float fields when every field is a concrete scalar, else None."""
    values = concrete_scalars(robot, FIELDS)
    if values is None:
        return None
    return jax.tree.unflatten(jax.tree.structure(robot), list(values))


def compiled(
    fn: Callable[..., Any],
    static_argnames: tuple[str, ...] = (),
    batched_argnames: tuple[str, ...] = (),
) -> Callable[..., Any]:
    """``jax.jit(fn)`` that compiles a concrete geometry in as constants.

    A geometry of Python numbers is a static argument (one compilation per robot, cached), so
    XLA folds it into the kernel; a traced or batched geometry (gradients with respect to the
    design, ``vmap`` over robots) takes the dynamic path.

    With ``batched_argnames``, large batches are split across host threads
    (``jaxkin._batching``) and the call takes the batch shape as the keyword ``batch``.
    """
    if batched_argnames:
        dynamic = _batching.PartsJit(fn, static_argnames, batched_argnames)
        static = _batching.PartsJit(fn, ("robot", *static_argnames), batched_argnames)
    else:
        dynamic = jax.jit(fn, static_argnames=static_argnames)
        static = jax.jit(fn, static_argnames=("robot", *static_argnames))

    @functools.wraps(fn)
    def call(robot: Delta, *args: Any, **kwargs: Any) -> Any:
        concrete = frozen(robot)
        if concrete is None:
            return dynamic(robot, *args, **kwargs)
        return static(concrete, *args, **kwargs)

    call.takes_batch = bool(batched_argnames)
    return call


def check_robot(robot: Any) -> Delta:
    if not isinstance(robot, Delta):
        raise ValueError(f"robot must be a jaxkin.delta.Delta, got {type(robot).__name__}")
    return robot


def float_dtype(*xs: Any) -> Any:
    return jnp.result_type(*xs, float)


def as_coords(x: ArrayLike, name: str) -> Array:
    x = _validate.as_float(x)
    if x.ndim == 0 or x.shape[-1] != 3:
        raise ValueError(f"{name}: expected shape (..., 3), got {tuple(x.shape)}")
    return x
