"""SCARA robot: inverse kinematics on the RRR dyad [Noriega, sec. 3], forward kinematics.

Frame [Noriega, Fig. 5]: origin O on the floor, z up. A column of height ``l_oa`` carries the
shoulder A = (0, 0, l_oa); the arm AB (``l_ab``) turns about the vertical through A by
``theta1``, the forearm BC (``l_bc``) about the vertical through the elbow B; a prismatic joint
at the wrist C moves the end point D down by ``l3``: D = (x_C, y_C, l_oa - l3). Joints
``q = (theta1, theta2, l3)``; lengths in any one unit, angles in radians.

Inverse kinematics [Noriega, eqs. 11-15]: C = (x_D, y_D) with D's rates (eq. 13),
``l3 = l_oa - z_D`` (eq. 14); the plane problem is the dyad (``jaxkin.dyad``) with known joints
A and C, middle joint B, dyad lengths ``(l_ab, l_bc)``: ``theta1`` is the dyad's unwrapped
``phi = atan2(y_D, x_D) + branch * beta`` and ``theta2 = theta1 - theta_BC`` (eq. 15, the
*negative* of the usual relative elbow angle, not wrapped; ``relative_elbow_angle`` gives the
usual one). ``branch`` is the dyad's assembly mode: ``+1`` puts the elbow to the left of O->D
seen from +z, ``-1`` the mirror elbow. Forward kinematics:
``D = (l_ab cos theta1 + l_bc cos(theta1 - theta2), l_ab sin theta1 + l_bc sin(...), l_oa - l3)``.

Statuses (``jaxkin.Status``), from the dyad with its tolerance ``sqrt(eps) (l_ab + l_bc)``:
``INVALID_INPUT`` (NaN/inf in D), ``SINGULAR_COINCIDENT`` (D on the axis with equal links),
``UNREACHABLE`` (outside the annulus ``|l_ab - l_bc| <= r <= l_ab + l_bc``),
``SINGULAR_EXTENDED``/``SINGULAR_FOLDED`` (beta = 0 or pi), ``OUT_OF_LIMITS`` (solved, but a
joint limit is violated; every status above wins over it: whether a singular solution is
within the limits is ``robot.limits.contains(q.p)``), ``OK``. Where the status is neither
OK nor OUT_OF_LIMITS the rates are 0; positions are the dyad's finite placeholders. ``margin``
is the dyad's ``sin(beta)^2`` (< 0 outside the workspace, -1 for invalid input).

Conventions, the derivation and float32 accuracy: ``docs/conventions.md`` and
``docs/performance.md``.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, ClassVar

import jax.numpy as jnp
from jax import Array
from jax.typing import ArrayLike

from . import _validate, dyad, lie, planar
from ._execute import solve_fk, solve_ik
from ._geometry import LENGTH, NONNEGATIVE, Numeric, geometry, number
from ._numerics import all_finite, computed_once
from ._trig import cos_alone, sin_alone, sincos
from .collision.body import Body
from .jet import Jet, lift
from .result import FKResult, IKResult
from .robot import POINT, JointLimits, Robot, options
from .status import STATUS_DTYPE, Status

__all__ = [
    "BRANCHES",
    "METHODS",
    "JOINT_NAMES",
    "JointLimits",
    "Scara",
    "fk",
    "ik",
    "relative_elbow_angle",
]

BRANCHES = dyad.MODES
METHODS = dyad.METHODS
JOINT_NAMES = ("theta1", "theta2", "l3")


@options
class ScaraIKOptions:
    """Options of the SCARA's IK.

    Attributes:
        method: ``"analytic"`` (the dyad's closed forms) or ``"autodiff"`` (the position-level
            IK lifted by ``jaxkin.lift``); the same values.
    """

    method: str = "analytic"

    def __post_init__(self) -> None:
        _validate.choice(self.method, "method", METHODS)


@geometry
class Scara(Robot):
    """SCARA geometry [Noriega, Fig. 5]: a validated frozen pytree (vmappable, differentiable).

    Attributes:
        l_oa: column height, base O to shoulder A; positive, a scalar or an array broadcast
            against the batch (length unit).
        l_ab: arm length, shoulder A to elbow B; positive.
        l_bc: forearm length, elbow B to wrist C; positive.
        limits: ``JointLimits`` on ``(theta1, theta2, l3)`` (unwrapped theta1, eq. 15
            theta2), a mapping ``{"theta1": (low, high), ...}``, or None.
        link_radius: radius of the capsules of the collision body (``collision_body``),
            >= 0; default 0 (the links as their centre lines).
    """

    l_oa: Numeric = number(LENGTH, None)
    l_ab: Numeric = number(LENGTH, None)
    l_bc: Numeric = number(LENGTH, None)
    limits: JointLimits | None = None
    link_radius: Numeric = number(NONNEGATIVE, default=0.0)

    target: ClassVar = POINT
    branches: ClassVar = BRANCHES
    reachable: ClassVar = (Status.OK, Status.SINGULAR_EXTENDED, Status.SINGULAR_FOLDED)
    IKOptions: ClassVar = ScaraIKOptions

    def _validate(self) -> None:
        super()._validate()
        limits = self.limits
        if isinstance(limits, Mapping):
            limits = JointLimits.named(JOINT_NAMES, limits)
        elif limits is not None and not isinstance(limits, JointLimits):
            raise ValueError(
                "Scara.limits must be None, a JointLimits or a mapping, got "
                f"{type(limits).__name__}"
            )
        if limits is not None and jnp.shape(limits.lower)[-1:] != (3,):
            raise ValueError(
                f"Scara.limits: expected 3 joints (theta1, theta2, l3), got "
                f"{jnp.shape(limits.lower)}"
            )
        object.__setattr__(self, "limits", limits)

    @classmethod
    def create(
        cls,
        l_oa: ArrayLike,
        l_ab: ArrayLike,
        l_bc: ArrayLike,
        limits: JointLimits | Mapping[str, tuple[float, float]] | None = None,
    ) -> Scara:
        """The same as the constructor (kept for symmetry with the other geometries)."""
        return cls(l_oa, l_ab, l_bc, limits)  # type: ignore[arg-type]  # _validate: a mapping

    @classmethod
    def paper(cls) -> Scara:
        """The robot of [Noriega, sec. 4], in mm: ``l_oa = 150``, ``l_ab = 80``, ``l_bc = 50``."""
        return cls(150.0, 80.0, 50.0)

    @property
    def reach(self) -> tuple[Array, Array]:
        """Inner and outer radius of the reachable annulus: ``|l_ab - l_bc|``, ``l_ab + l_bc``."""
        return jnp.abs(self.l_ab - self.l_bc), self.l_ab + self.l_bc

    @property
    def joint_names(self) -> tuple[str, ...]:
        return JOINT_NAMES

    @property
    def joint_types(self) -> str:
        return "RRP"

    def joint_limits(self) -> JointLimits:
        return JointLimits.unbounded(3) if self.limits is None else self.limits

    def length_scale(self) -> Any:
        return self.l_ab + self.l_bc

    def workspace_box(self) -> tuple[tuple[tuple[float, float], ...], float]:
        """The square around the reach annulus, z from the floor to the arm plane (or the
        ``l3`` limits); voxel edge ``(l_ab + l_bc) / 50``."""
        reach = float(self.l_ab) + float(self.l_bc)
        l_oa = float(self.l_oa)
        lo, hi = 0.0, l_oa  # l3 between the arm plane and the floor
        if self.limits is not None:
            low, high = float(self.limits.lower[2]), float(self.limits.upper[2])
            lo = max(low, 0.0) if jnp.isfinite(low) else 0.0
            hi = high if jnp.isfinite(high) else l_oa
        return ((-reach, reach), (-reach, reach), (l_oa - hi, l_oa - lo)), reach / 50.0

    def link_segments(self, q: Array, x: Array) -> Array:
        """Column top A -> elbow B -> wrist C -> end point D as segments, ``(..., 3, 2, 3)``."""
        theta1, theta2, l3 = q[..., 0], q[..., 1], q[..., 2]
        l_oa = jnp.broadcast_to(jnp.asarray(self.l_oa, q.dtype), theta1.shape)
        zero = jnp.zeros_like(theta1)
        a = jnp.stack([zero, zero, l_oa], -1)
        b = a + self.l_ab * jnp.stack([jnp.cos(theta1), jnp.sin(theta1), zero], -1)
        c = b + self.l_bc * jnp.stack(
            [jnp.cos(theta1 - theta2), jnp.sin(theta1 - theta2), zero], -1
        )
        d = c - jnp.stack([zero, zero, l3], -1)
        return jnp.stack([jnp.stack([a, b], -2), jnp.stack([b, c], -2), jnp.stack([c, d], -2)], -3)

    def collision_body(self) -> Body:
        """Four capsules of radius ``link_radius`` (an unbatched geometry; traceable):
        ``column`` O -> A, ``arm`` A -> B, ``forearm`` B -> C and ``quill``, a rod of length
        ``l_oa`` standing on the end point D (it slides through the wrist C)."""
        if self.batch_shape():
            raise ValueError("Scara.collision_body: needs an unbatched geometry")
        zero = 0.0 * jnp.asarray(self.l_oa)
        ends = [
            (zero, zero, self.l_oa),
            (self.l_ab, zero, zero),
            (self.l_bc, zero, zero),
            (zero, zero, self.l_oa),
        ]
        b = jnp.stack([jnp.stack([jnp.asarray(x) for x in e]) for e in ends])
        names = ("column", "arm", "forearm", "quill")
        return Body.of_capsules(names, (0, 1, 2, 3), jnp.zeros_like(b), b, self.link_radius)

    def link_poses(self, q: Array) -> Array:
        """Poses ``(..., 4, 4, 4)`` of ``column`` (the base frame), ``arm`` (at A, turned by
        ``theta1``), ``forearm`` (at B, turned by ``theta1 - theta2``) and ``quill`` (at D,
        turned as the forearm)."""
        theta1, theta2, l3 = q[..., 0], q[..., 1], q[..., 2]
        zero, one = jnp.zeros_like(theta1), jnp.ones_like(theta1)
        l_oa = jnp.asarray(self.l_oa, q.dtype) * one

        def turn(angle):
            c, s = jnp.cos(angle), jnp.sin(angle)
            rows = [[c, -s, zero], [s, c, zero], [zero, zero, one]]
            return jnp.stack([jnp.stack(r, -1) for r in rows], -2)

        a = jnp.stack([zero, zero, l_oa], -1)
        b = a + self.l_ab * jnp.stack([jnp.cos(theta1), jnp.sin(theta1), zero], -1)
        c = b + self.l_bc * jnp.stack(
            [jnp.cos(theta1 - theta2), jnp.sin(theta1 - theta2), zero], -1
        )
        d = c - jnp.stack([zero, zero, l3], -1)
        eye = jnp.broadcast_to(jnp.eye(3, dtype=q.dtype), (*theta1.shape, 3, 3))
        rotations = [eye, turn(theta1), turn(theta1 - theta2), turn(theta1 - theta2)]
        origins = [jnp.zeros_like(a), a, b, d]
        return jnp.stack(
            [lie.from_rotation_translation(r, p) for r, p in zip(rotations, origins, strict=True)],
            -3,
        )

    def self_collision_pairs(self) -> tuple[tuple[int, int], ...]:
        """The quill against the column and the arm (the other pairs are adjacent, or stacked
        at different heights on a real SCARA)."""
        return ((0, 3), (1, 3))

    def ik_kernel(self, target: Jet, branch: Any, options: Any, rates: bool) -> IKResult:
        return _ik_impl(self, target, branch, options.method, rates)

    def fk_kernel(self, q: Jet, options: Any, rates: bool) -> FKResult:
        return _fk_impl(self, q, rates)


def relative_elbow_angle(theta2: Jet | ArrayLike) -> Jet | Array:
    """The usual relative elbow angle ([UANL]'s ``q2``) from eq. 15's ``theta2``.

    ``q2 = -theta2`` wrapped to (-pi, pi]; for a Jet the rates are ``-theta2_dot`` and
    ``-theta2_ddot``.
    """
    if isinstance(theta2, Jet):
        return Jet(_wrapped(-jnp.asarray(theta2.p)), -theta2.v, -theta2.a)
    return _wrapped(-jnp.asarray(theta2))


def _wrapped(angle: Array) -> Array:
    """``angle`` wrapped to (-pi, pi]."""
    return jnp.pi - jnp.mod(jnp.pi - angle, 2.0 * jnp.pi)


def _broadcast_geometry(robot: Scara, batch: tuple[int, ...]) -> tuple[Array, Array, Array]:
    return (
        jnp.broadcast_to(robot.l_oa, batch),
        jnp.broadcast_to(robot.l_ab, batch),
        jnp.broadcast_to(robot.l_bc, batch),
    )


def _ik_impl(robot: Scara, d: Jet, branch: int, method: str, rates: bool = True) -> IKResult:
    robot = robot.astype(d.dtype)  # inside jit: no per-call dispatch on the host
    lengths = (robot.l_oa, robot.l_ab, robot.l_bc)
    batch = jnp.broadcast_shapes(d.shape[:-1], *(jnp.shape(x) for x in lengths))
    d = d.map(lambda x: jnp.broadcast_to(x, (*batch, 3)))
    # Scalar lengths stay scalars (terms built from them alone are computed once, see dyad).
    if not all(jnp.ndim(x) == 0 for x in lengths):
        lengths = _broadcast_geometry(robot, batch)
    l_oa, l_ab, l_bc = lengths

    # Double-where, step 1: replace non-finite elements (including z, which the dyad never
    # sees) by a harmless reachable target before any arithmetic.
    valid = (
        all_finite(jnp.concatenate([d.p, d.v, d.a], axis=-1) if rates else d.p)
        & jnp.isfinite(l_oa)
        & jnp.isfinite(l_ab)
        & jnp.isfinite(l_bc)
    )
    vc = valid[..., None]
    d = Jet(
        jnp.where(vc, d.p, jnp.array([1.0, 0.0, 0.0], d.dtype)),
        jnp.where(vc, d.v, 0.0),
        jnp.where(vc, d.a, 0.0),
    )
    if jnp.ndim(l_ab) == 0:
        l_oa, l_ab, l_bc = (jnp.where(jnp.isfinite(x), x, 1.0) for x in (l_oa, l_ab, l_bc))
    else:
        l_oa, l_ab, l_bc = (jnp.where(valid, x, 1.0) for x in (l_oa, l_ab, l_bc))
    shoulder = jnp.zeros((*batch, 2), d.dtype)  # A projected on its plane: the origin, at rest

    if not rates:  # at rest, either method: positions only (zero rates), the analytic path's forms
        wrist_p = d.p[..., :2]
        sol = dyad.position(shoulder, wrist_p, l_ab, l_bc, mode=branch)
        inv_bc = jnp.asarray(1.0 / l_bc)[..., None]
        theta_bc, _ = planar.angle(Jet.constant((wrist_p - sol.c) * inv_bc))
        q = Jet.constant(jnp.stack([sol.phi, sol.phi - theta_bc.p, l_oa - d.p[..., 2]], -1))
        dyad_status, margin = sol.status, sol.margin
        ok = dyad_status == Status.OK
    elif method == "analytic":
        wrist = d[..., :2]  # eq. 13: C = (x_D, y_D) with the same rates
        solved = dyad.solve(Jet.constant(shoulder), wrist, l_ab, l_bc, mode=branch)
        ok = solved.status == Status.OK
        # The forearm in units of its length (the dyad works in units of the reach): the
        # angle's rate formulas multiply four lengths, which must not overflow at any scale.
        inv_bc = jnp.asarray(1.0 / l_bc)[..., None]
        forearm = Jet(
            (wrist.p - solved.c.p) * inv_bc,
            (wrist.v - solved.c.v) * inv_bc,
            (wrist.a - solved.c.a) * inv_bc,
        )
        theta_bc, _ = planar.angle(forearm)  # the angle of Fig. 2 (docs/errata.md)
        theta1 = solved.phi  # eqs. 9-10
        theta2 = Jet(  # eq. 15
            theta1.p - theta_bc.p,
            jnp.where(ok, theta1.v - theta_bc.v, 0.0),
            jnp.where(ok, theta1.a - theta_bc.a, 0.0),
        )
        l3 = Jet(l_oa - d.p[..., 2], -d.v[..., 2], -d.a[..., 2])  # eq. 14
        q = Jet.stack([theta1, theta2, l3])
        dyad_status, margin = solved.status, solved.margin
    else:

        def position(d_p: Array) -> tuple[Array, Array, Array]:
            """Position-level SCARA IK: q (..., 3), status, margin."""
            wrist_p = d_p[..., :2]
            sol = dyad.solve(shoulder, wrist_p, l_ab, l_bc, mode=branch)
            theta_bc, _ = planar.angle(
                Jet.constant((wrist_p - sol.c.p) / jnp.asarray(l_bc)[..., None])
            )
            q = jnp.stack([sol.phi.p, sol.phi.p - theta_bc.p, l_oa - d_p[..., 2]], axis=-1)
            return q, sol.status, sol.margin

        q, dyad_status, margin = lift(position)(d)
        margin = margin.p
        ok = dyad_status == Status.OK

    if rates:
        okc = ok[..., None]
        q = Jet(q.p, jnp.where(okc, q.v, 0.0), jnp.where(okc, q.a, 0.0))

    if robot.limits is not None:  # a singular status wins over the limits (module docstring)
        dyad_status = jnp.where(ok & ~robot.limits.contains(q.p), Status.OUT_OF_LIMITS, dyad_status)
    status = jnp.where(~valid, Status.INVALID_INPUT, dyad_status).astype(STATUS_DTYPE)
    margin = jnp.where(valid, margin, -1.0)
    return IKResult(q, status, margin)


def _check_robot(robot: Any) -> Scara:
    if not isinstance(robot, Scara):
        raise ValueError(f"robot must be a jaxkin.scara.Scara, got {type(robot).__name__}")
    return robot


def ik(
    robot: Scara, d: Jet | ArrayLike, branch: int | None = None, method: str = "analytic"
) -> IKResult:
    """SCARA inverse kinematics: joint position, velocity and acceleration [Noriega, eqs. 11-15].

    Args:
        robot: the geometry; lengths broadcast against the batch.
        d: Jet (or plain array, taken at rest) of the end point D, shape ``(..., 3)``.
        branch: assembly mode ``+1`` (elbow to the left of O->D, theta1 = atan2(y_D, x_D) +
            beta) or ``-1`` (the mirror elbow); None for ``+1``.
        method: ``"analytic"`` (the dyad's closed forms) or ``"autodiff"`` (the position-level
            IK lifted by ``jaxkin.lift``); the same values.

    Returns:
        ``IKResult`` with ``q`` (Jet ``(..., 3)``: theta1, theta2, l3), ``status`` and
        ``margin`` (the elbow B is ``robot.link_segments(q.p, d)[..., 0, 1, :]``). Work is
        done in ``d``'s floating dtype (the geometry is cast to it).

    Raises:
        ValueError: ``robot`` not a ``Scara``, ``d`` whose last axis is not 3, batch shapes
            that do not broadcast, or an unknown ``branch``/``method``.
    """
    branch = _validate.choice(BRANCHES[0] if branch is None else branch, "branch", BRANCHES)
    return solve_ik(_check_robot(robot), d, branch, ScaraIKOptions(method), name="d")


def _fk_position(q: Array, l_oa: Array, l_ab: Array, l_bc: Array) -> Array:
    theta1, theta2, l3 = q[..., 0], q[..., 1], q[..., 2]
    theta_bc = theta1 - theta2  # eq. 15
    (sin_1, cos_1), (sin_bc, cos_bc) = sincos(theta1), sincos(theta_bc)
    x = l_ab * cos_1 + l_bc * cos_bc
    y = l_ab * sin_1 + l_bc * sin_bc
    z = l_oa - l3  # eq. 14
    return jnp.stack([x, y, z], axis=-1)


def _fk_rates(q: Jet, l_oa: Array, l_ab: Array, l_bc: Array) -> Jet:
    """D with its velocity and acceleration: the two links' end rates (``planar``) added.

    Link AB turns at ``theta1``'s rates, link BC at ``theta_BC = theta1 - theta2``'s; ``z`` moves
    opposite to ``l3``. The four cos/sin are stored once (``computed_once``: the nine output
    rows would each evaluate them), as one polynomial per row (``cos_alone``/``sin_alone``).
    """
    theta1, theta2, l3 = (q.p[..., k] for k in range(3))
    (rate1, rate2, l3_dot), (acc1, acc2, l3_ddot) = (
        tuple(x[..., k] for k in range(3)) for x in (q.v, q.a)
    )
    theta_bc = theta1 - theta2  # eq. 15
    cos_1, sin_1, cos_bc, sin_bc = computed_once(
        jnp.stack([cos_alone(theta1), sin_alone(theta1), cos_alone(theta_bc), sin_alone(theta_bc)])
    )
    link_ab = planar.link_end_rates(l_ab, cos_1, sin_1, rate1, acc1)
    link_bc = planar.link_end_rates(l_bc, cos_bc, sin_bc, rate1 - rate2, acc1 - acc2)
    v_x, v_y, a_x, a_y = (u + w for u, w in zip(link_ab, link_bc, strict=True))
    p = jnp.stack([l_ab * cos_1 + l_bc * cos_bc, l_ab * sin_1 + l_bc * sin_bc, l_oa - l3], -1)
    return Jet(p, jnp.stack([v_x, v_y, -l3_dot], -1), jnp.stack([a_x, a_y, -l3_ddot], -1))


def _fk_impl(robot: Scara, q: Jet, rates: bool) -> FKResult:
    robot = robot.astype(q.dtype)
    batch = jnp.broadcast_shapes(
        q.shape[:-1], *(jnp.shape(x) for x in (robot.l_oa, robot.l_ab, robot.l_bc))
    )
    lengths = _broadcast_geometry(robot, batch)
    q = q.map(lambda x: jnp.broadcast_to(x, (*batch, 3)))
    valid = all_finite(jnp.concatenate([q.p, q.v, q.a], axis=-1) if rates else q.p)
    if rates:
        x = _fk_rates(q, *lengths)
        okc = valid[..., None]
        x = Jet(x.p, jnp.where(okc, x.v, 0.0), jnp.where(okc, x.a, 0.0))
    else:
        x = Jet.constant(_fk_position(q.p, *lengths))
    within = valid if robot.limits is None else valid & robot.limits.contains(q.p)
    status = jnp.where(
        ~valid, Status.INVALID_INPUT, jnp.where(within, Status.OK, Status.OUT_OF_LIMITS)
    ).astype(STATUS_DTYPE)
    return FKResult(x, status)


def fk(robot: Scara, q: Jet | ArrayLike) -> FKResult:
    """SCARA forward kinematics: the end point D from ``q = (theta1, theta2, l3)``.

    ``x_D = l_ab cos theta1 + l_bc cos(theta1 - theta2)``, ``y_D`` likewise with sin,
    ``z_D = l_oa - l3`` (theta2 of eq. 15; any wrapping of the angles works).

    Args:
        robot: the geometry.
        q: joint coordinates, shape ``(..., 3)``: a Jet (D's velocity and acceleration come
            from the links' rates) or a plain array (at rest).

    Returns:
        ``FKResult``: ``x`` (Jet of D, ``(..., 3)``; rates 0 where the input is not finite)
        and ``status`` (``INVALID_INPUT`` for NaN/inf in ``q``, ``OUT_OF_LIMITS`` outside
        ``robot.limits``, else ``OK``). Dtype follows ``q``.

    Raises:
        ValueError: ``robot`` not a ``Scara``, ``q`` whose last axis is not 3, or batch
            shapes that do not broadcast.
    """
    return solve_fk(_check_robot(robot), q, Scara.FKOptions())
