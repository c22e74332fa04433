"""The Delta robot [Cardona]: the ``Delta`` class (geometry and robot protocol) and its
host-side entry points, on top of the kernels.

Layers, read bottom to top: ``_math`` (the frame, constants and shared pieces), ``jacobians``
(constraint Jacobians, rates, singularity measures), ``inverse`` (closed-form IK) and
``forward`` (Newton and closed-form FK), then this module. The kernels read a robot by its
fields alone; only this module knows the class. The frame is stated in ``jaxkin.delta._math``
and ``docs/conventions.md``.

Entry points check their input on the host (``ValueError`` naming the argument) and call the
compiled kernels: ``ik``, ``fk`` (Newton, optional warm start), ``fk_closed_form``,
``which_branch``, ``singularity`` and ``workspace``.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any, ClassVar

import jax
import jax.numpy as jnp
from jax import Array
from jax.typing import ArrayLike

from .. import _batching, _validate, lie
from .._execute import solve_fk, solve_ik
from .._geometry import BOUND, LENGTH, NONNEGATIVE, geometry, number
from ..collision.body import Body
from ..jet import Jet
from ..result import IKResult
from ..robot import POINT, CompilePolicy, JointLimits, Robot
from ..status import Status
from . import forward, inverse, jacobians
from ._math import BRANCHES, JOINT_NAMES, UX, UY, as_coords, float_dtype
from .options import DeltaFKOptions, DeltaIKOptions

__all__ = ["Delta", "fk", "fk_closed_form", "ik", "singularity", "which_branch"]


@geometry
class Delta(Robot):
    """Geometry of a Delta robot (frame in ``jaxkin.delta._math``); a validated frozen pytree.

    Attributes:
        r_base: radius of the fixed platform, centre to actuator axis (positive, length).
        r_platform: radius of the moving platform, centre to rod joint (positive, length).
        l_arm: length of the actuated arm, actuator axis to elbow (positive, length).
        l_rod: length of the parallelogram rods, elbow to platform joint (positive, length).
        theta_min: lower actuator limit (rad), ``-inf`` for none.
        theta_max: upper actuator limit (rad), ``+inf`` for none; ``theta_min < theta_max``.
        link_radius: radius of the collision body's capsules (``collision_body``), >= 0;
            default 0 (arms, rods and platform edges as their centre lines).

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
    link_radius: Any = number(NONNEGATIVE, default=0.0)

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
            u = jnp.asarray([UX[i], UY[i], 0.0], q.dtype)
            axis = self.r_base * u
            cos_t, sin_t = jnp.cos(q[..., i, None]), jnp.sin(q[..., i, None])
            elbow = axis + self.l_arm * (cos_t * u - sin_t * jnp.asarray([0.0, 0.0, 1.0], q.dtype))
            joint = x + self.r_platform * u
            axis = jnp.broadcast_to(axis, elbow.shape)
            segments += [jnp.stack([axis, elbow], -2), jnp.stack([elbow, joint], -2)]
        return jnp.stack(segments, -3)

    def collision_body(self) -> Body:
        """Capsules of radius ``link_radius``: ``arm_i`` A_i -> E_i, ``rod_i`` E_i -> D_i (the
        parallelogram's centre line, length ``l_rod``) and the ``platform``'s triangle of rod
        joints D_1 D_2 D_3; the ``base`` link carries none (traceable)."""
        names = ("base", "arm_1", "arm_2", "arm_3", "rod_1", "rod_2", "rod_3", "platform")
        zero = 0.0 * jnp.asarray(self.l_arm)
        ux, uy = jnp.asarray(UX), jnp.asarray(UY)
        corners = self.r_platform * jnp.stack([ux, uy, 0.0 * ux], -1)
        tips = [jnp.stack([jnp.asarray(length), zero, zero]) for length in (self.l_arm, self.l_rod)]
        a = jnp.concatenate([jnp.zeros((6, 3)) + zero, corners])
        b = jnp.concatenate([jnp.stack([tips[0]] * 3 + [tips[1]] * 3), jnp.roll(corners, -1, 0)])
        return Body.of_capsules(names, (1, 2, 3, 4, 5, 6, 7, 7, 7), a, b, self.link_radius)

    def link_poses(self, q: Array) -> Array:
        """Poses ``(..., 8, 4, 4)``: ``base`` (identity); ``arm_i`` at A_i with x along the arm
        (``cos theta_i u_i - sin theta_i e_z``) and y along the actuator axis ``w_i = e_z x
        u_i``; ``rod_i`` at E_i with x towards D_i; the ``platform`` translated to the closed
        form FK's lower solution (``fk_closed_form``)."""
        dtype = q.dtype
        x = forward._fk_closed_form_impl(self, q).x
        ez = jnp.asarray([0.0, 0.0, 1.0], dtype)
        eye = jnp.broadcast_to(jnp.eye(3, dtype=dtype), (*q.shape[:-1], 3, 3))
        poses = [lie.from_rotation_translation(eye, jnp.zeros_like(x))]
        arms, rods = [], []
        for i in range(3):
            u = jnp.asarray([UX[i], UY[i], 0.0], dtype)
            w = jnp.asarray([-UY[i], UX[i], 0.0], dtype)
            cos_t, sin_t = jnp.cos(q[..., i, None]), jnp.sin(q[..., i, None])
            along = cos_t * u - sin_t * ez
            axis = jnp.broadcast_to(self.r_base * u, along.shape)
            elbow = axis + self.l_arm * along
            arms.append(_frame(axis, along, w))
            rod = x + self.r_platform * u - elbow
            length = jnp.sqrt(jnp.maximum(jnp.sum(rod * rod, -1, keepdims=True), 1e-30))
            rods.append(_frame(elbow, rod / length, w))
        poses += arms + rods + [lie.from_rotation_translation(eye, x)]
        return jnp.stack(poses, -3)

    def placeable(self, q: Array) -> Array:
        """The rods reach the platform: the closed form FK finds an assembly (``OK``,
        ``OUT_OF_LIMITS`` or ``SINGULAR``; not ``UNREACHABLE`` or ``INVALID_INPUT``)."""
        status = forward._fk_closed_form_impl(self, q).status
        return (status != Status.UNREACHABLE) & (status != Status.INVALID_INPUT)

    def self_collision_pairs(self) -> tuple[tuple[int, int], ...]:
        """Arms against arms, rods against rods and other chains' arms, and the platform
        against the arms (a rod is adjacent to its arm and to the platform)."""
        arm, rod, platform = (1, 2, 3), (4, 5, 6), 7
        pairs = [(a, b) for a in arm for b in arm if a < b]
        pairs += [(a, b) for a in rod for b in rod if a < b]
        pairs += [(a, r) for a in arm for r in rod if r - a != 3]
        pairs += [(a, platform) for a in arm]
        return tuple(sorted(pairs))

    def ik_kernel(self, target: Jet, branch: Any, options: DeltaIKOptions, rates: bool) -> IKResult:
        return inverse.ik_kernel(self, target, branch, options, rates)

    def fk_kernel(self, q: Jet, options: DeltaFKOptions, rates: bool) -> forward.NewtonFKResult:
        return forward.fk_kernel(self, q, options, rates)


def check_robot(robot: Any) -> Delta:
    """``robot`` if it is a ``Delta``, else a ``ValueError`` naming the argument."""
    if not isinstance(robot, Delta):
        raise ValueError(f"robot must be a jaxkin.delta.Delta, got {type(robot).__name__}")
    return robot


def ik(
    robot: Delta, p: Jet | ArrayLike, branch: str | None = None, method: str = "analytic"
) -> IKResult:
    """Actuator angles (and rates) for platform positions (``jaxkin.ik`` of a ``Delta``).

    Args:
        robot: the geometry.
        p: platform centre, shape ``(..., 3)``: a ``Jet`` (position, velocity, acceleration) or
            a plain array (taken at rest).
        branch: ``"out"`` (elbow-out, elbows farther from the z axis) or ``"in"``; None for
            ``"out"``.
        method: ``"analytic"`` (constraint Jacobians) or ``"autodiff"`` (``jaxkin.lift``).

    Returns:
        ``IKResult`` with ``q`` (Jet of the actuator angles, ``(..., 3)``), ``status`` and
        ``margin`` (``(...)``).

    Raises:
        ValueError: unknown branch/method, last axis not 3, or ``robot`` not a ``Delta``.
    """
    robot = check_robot(robot)
    branch = _validate.choice(BRANCHES[0] if branch is None else branch, "branch", BRANCHES)
    return solve_ik(robot, p, branch, DeltaIKOptions(method), name="p")


def fk(
    robot: Delta,
    theta: Jet | ArrayLike,
    guess: ArrayLike | None = None,
    tol: float | None = None,
    max_iter: int = 30,
    method: str = "analytic",
) -> forward.NewtonFKResult:
    """Platform position (and rates) from actuator angles by batched Newton-Raphson.

    A large batch called outside ``jit`` runs as one part per host thread
    (``jaxkin.set_num_threads``; the same values, see ``jaxkin._batching``).

    Args:
        robot: the geometry.
        theta: actuator angles, shape ``(..., 3)``: a ``Jet`` or a plain array (at rest).
        guess: initial platform positions, broadcastable to ``(..., 3)`` (warm start, e.g. the
            previous trajectory sample); ``None`` for the default guess below the elbows
            (module docstring), which converges to the lower (hanging) assembly.
        tol: converged where ``max_i |r_i| <= tol * (l_arm + l_rod)``; ``None`` for
            ``max(1e-12, 8 eps(dtype))``: 1e-12 in float64, 9.5e-7 in float32 (1e-12 is below
            float32 resolution).
        max_iter: maximum number of Newton updates.
        method: ``"analytic"`` rates (constraint Jacobians) or ``"autodiff"`` (``jaxkin.lift``
            through ``lax.custom_root``).

    Returns:
        ``NewtonFKResult`` (``x`` Jet ``(..., 3)``, ``status``, ``converged``, ``iterations``,
        ``residual``, ``conditioning``).

    Raises:
        ValueError: bad shapes, ``tol <= 0``, ``max_iter < 1``, unknown method.
    """
    robot = check_robot(robot)
    options = DeltaFKOptions(tol, max_iter, method)
    if guess is None:
        return solve_fk(robot, theta, options, name="theta")
    if isinstance(theta, Jet):
        rates, joints = True, _validate.as_jet(theta, "theta", coords=3)
    else:
        rates, joints = False, Jet.positions(as_coords(theta, "theta"))
    dtype = float_dtype(joints.p)
    guess = jnp.asarray(guess, dtype)
    if guess.ndim == 0 or guess.shape[-1] != 3:
        raise ValueError(f"guess: expected shape (..., 3), got {tuple(guess.shape)}")
    shape = _validate.batch_shape({"theta": joints.shape[:-1], "guess": guess.shape[:-1]})
    joints = jax.tree.map(lambda x: jnp.broadcast_to(x, (*shape, 3)).astype(dtype), joints)
    batch = joints.shape[:-1]
    outside = _batching.zero_rates_outside(rates, batch)
    result = forward.fk_guess_jit(
        robot, joints, guess, options.tolerance(dtype), max_iter, method, rates, not outside,
        batch=batch, pad=_batching.shared_geometry(robot),
    )  # fmt: skip
    return dataclasses.replace(result, x=Jet.constant(result.x.p)) if outside else result


def fk_closed_form(robot: Delta, theta: ArrayLike) -> forward.ClosedFormFKResult:
    """Platform position by three-sphere intersection (both assemblies), shape ``(..., 3)``."""
    robot = check_robot(robot)
    theta = as_coords(theta, "theta")
    return forward.closed_form_jit(robot, theta)


def which_branch(robot: Delta, theta: ArrayLike, p: ArrayLike) -> Array:
    """Which assembly ``p`` is: ``LOWER`` (0, below the plane of the sphere centres) or
    ``UPPER`` (1), e.g. to report which branch Newton converged to; shape ``(...)``."""
    robot = check_robot(robot)
    theta = as_coords(theta, "theta")
    p = as_coords(p, "p")
    _validate.batch_shape({"theta": theta.shape[:-1], "p": p.shape[:-1]})
    dtype = float_dtype(theta, p)
    return forward.branch_jit(robot, theta.astype(dtype), p.astype(dtype))


def singularity(
    robot: Delta, p: ArrayLike, theta: ArrayLike | None = None, branch: str = "out"
) -> jacobians.SingularityResult:
    """Inverse- and direct-type singularity measures at ``(p, theta)``, shape ``(...)``.

    ``theta`` defaults to ``ik(robot, p, branch).q.p``. See ``jaxkin.delta.jacobians`` for the
    normalisation (both measures in [0, 1], 0 at the singularity).
    """
    robot = check_robot(robot)
    p = as_coords(p, "p")
    if theta is None:
        theta = ik(robot, p, branch=branch).q.p
    theta = as_coords(theta, "theta")
    shape = _validate.batch_shape({"p": p.shape[:-1], "theta": theta.shape[:-1]})
    dtype = float_dtype(p, theta)
    p = jnp.broadcast_to(p, (*shape, 3)).astype(dtype)
    theta = jnp.broadcast_to(theta, (*shape, 3)).astype(dtype)
    return jacobians.singularity_jit(robot, p, theta)


def _frame(origin: Array, x_axis: Array, towards: Array) -> Array:
    """The pose at ``origin`` whose x axis is the unit ``x_axis`` and whose y axis is the part
    of ``towards`` orthogonal to it (never parallel to it here: ``towards`` is an actuator
    axis, normal to the arm and, within the workspace, far from the rod)."""
    y = towards - jnp.sum(towards * x_axis, -1, keepdims=True) * x_axis
    y = y / jnp.sqrt(jnp.maximum(jnp.sum(y * y, -1, keepdims=True), 1e-30))
    rot = jnp.stack([x_axis, y, jnp.cross(x_axis, y)], -1)
    return lie.from_rotation_translation(rot, origin)
