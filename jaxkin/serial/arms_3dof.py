"""Three-joint positioning arms: anthropomorphic RRR (seed 001), cylindrical and spherical
(seed 004). Target = the wrist position ``(..., 3)``; ``fk`` is the DH forward kinematics
(``jaxkin.serial.fk_dh``) of the tables below, returning the 4x4 transform of DH frame 3.

**Anthropomorphic(l1, l2, l3)** (seed 001, Table 1 and eqs. 2-6)::

    joint  theta   d    a    alpha
      1    q1      l1   0    +90 deg
      2    q2      0    l2   0
      3    q3      0    l3   0

    p = (cos q1 A, sin q1 A, l1 + l2 sin q2 + l3 sin(q2 + q3)),  A = l2 cos q2 + l3 cos(q2 + q3)

Inverse (seed 001 eqs. 10-14, corrected per ERRATA: two-argument ``atan2`` and the second
shoulder branch ``q1 + pi``; the paper prints no ``q2``)::

    q1 = atan2(py, px)            (shoulder "front"),   q1 + pi  ("back")          eq. 10
    A = px cos q1 + py sin q1 = +-sqrt(px^2 + py^2),   B = pz - l1                 eqs. 12, 13
    (q2, q3) = planar two-link IK of (A, B) with links (l2, l3)                     eqs. 11, 14

i.e. ``cos q3 = (A^2 + B^2 - l2^2 - l3^2) / (2 l2 l3)``, ``q2 = atan2(B, A) - atan2(l3 sin q3,
l2 + l3 cos q3)``. (``jaxkin.fixedpoint`` evaluates the paper's own sequence, eq. 14's ``C``
and eq. 11, instead.) Four branches, in this order: ``front_up``, ``front_down``,
``back_up``, ``back_down``; "up" means the elbow lies above the line shoulder->wrist
(``q3 <= 0`` for the front shoulder, ``q3 >= 0`` for the back one).

On the base axis (``sqrt(px^2 + py^2) <= tol``) ``q1`` is free: front branches return
``q1 = 0``, back branches ``q1 = pi``; all four are ``SINGULAR`` and valid.

**Cylindrical(h)** (seed 004, "robot cilindrico"): a revolute base joint ``q1`` about z, a
radial prismatic joint ``q2`` and a vertical prismatic joint ``q3``;
``p = (q2 cos q1, q2 sin q1, h + q3)``. Seed 004's inverse: ``q1 = atan2(py, px)``,
``q2 = sqrt(px^2 + py^2)``, ``q3 = pz - h``. One branch (``"front"``, ``q2 >= 0``); on the
axis ``q1 = 0`` (``SINGULAR``). DH: ``theta = (-90 deg, 0, 0)``, ``d = (h, 0, 0)``,
``a = 0``, ``alpha = (-90, +90, 0) deg``, joint types ``RPP``.

**Spherical(h)** (seed 004, "robot esferico"): base rotation ``q1`` about z, elevation
``q2`` above the horizontal plane (positive up), radial prismatic ``q3``::

    p = (q3 cos q2 cos q1, q3 cos q2 sin q1, h + q3 sin q2)
    q1 = atan2(py, px) [+ pi],  q2 = atan2(pz - h, +-r) with r = sqrt(px^2 + py^2),
    q3 = sqrt(r^2 + (pz - h)^2)

Branches ``front`` / ``back``. ``SINGULAR`` on the axis (``q1`` = 0 / pi) and at the
shoulder (``q3 = 0``: ``q2`` free, returned as 0). DH: ``theta = (0, 90 deg, 0)``,
``d = (h, 0, 0)``, ``a = 0``, ``alpha = (90, 90, 0) deg``, ``RRP``.

The prismatic joints have no stroke limits here: every target of the cylindrical and
spherical arms is reachable. ``tol = sqrt(eps(dtype))`` times the sum of the arm's lengths
(plus the target distance for the prismatic arms).
"""

from __future__ import annotations

import dataclasses
from typing import ClassVar

import jax.numpy as jnp
from jax import Array

from .._numerics import safe_sqrt, singular_rtol
from . import _arms_common as common
from .dh import DHTable

__all__ = ["Anthropomorphic", "Cylindrical", "Spherical"]

_PI = common.PI
_HALF_PI = common.HALF_PI


@common.register_arm
@dataclasses.dataclass(frozen=True)
class Anthropomorphic(common.Arm):
    """The 3-DOF anthropomorphic RRR arm of seed 001 (DH table in the module docstring).

    Attributes:
        l1: shoulder height ``d_1`` (base to the shoulder joint), positive scalar.
        l2: upper-arm length ``a_2``, positive scalar.
        l3: forearm length ``a_3`` (elbow to wrist), positive scalar.
    """

    l1: Array
    l2: Array
    l3: Array

    N_JOINTS: ClassVar[int] = 3
    JOINT_TYPES: ClassVar[str] = "RRR"
    BRANCHES: ClassVar[tuple[str, ...]] = ("front_up", "front_down", "back_up", "back_down")
    TARGET_SHAPE: ClassVar[tuple[int, ...]] = (3,)

    def dh_table(self, dtype=None) -> DHTable:
        dtype = dtype or jnp.result_type(float)
        l1, l2, l3 = self.lengths(dtype)
        return common.dh(
            dtype, [0.0, l2, l3], [_HALF_PI, 0.0, 0.0], [l1, 0.0, 0.0], [0.0, 0.0, 0.0], "RRR"
        )

    def _ik_kernel(self, target: Array) -> tuple[Array, Array]:
        dtype = target.dtype
        l1, l2, l3 = self.lengths(dtype)
        px, py, pz = target[..., 0], target[..., 1], target[..., 2]
        r = safe_sqrt(px * px + py * py)
        on_axis = r <= singular_rtol(dtype) * (l1 + l2 + l3)
        q1_front = common.guarded_atan2(py, px, on_axis)  # eq. 10 (atan2, ERRATA)
        q1 = jnp.stack([q1_front, common.wrap_angle(q1_front + _PI)], axis=-1)  # (..., 2)
        a = jnp.stack([r, -r], axis=-1)  # eq. 12: A = px c1 + py s1 = +-r
        b = pz - l1  # eq. 13
        elbow = jnp.asarray([[-1.0, 1.0], [1.0, -1.0]], dtype)  # [shoulder, up/down]
        sol = common.two_link(a[..., :, None], b[..., None, None], l2, l3, elbow)
        q1 = jnp.broadcast_to(q1[..., :, None], sol.q1.shape)
        q = jnp.stack([q1, sol.q1, sol.q2], axis=-1)  # (..., 2, 2, 3)
        status = common.status_from(sol.unreachable, sol.singular | on_axis[..., None, None])
        batch = q.shape[:-3]
        return q.reshape(*batch, 4, 3), status.reshape(*batch, 4)


@common.register_arm
@dataclasses.dataclass(frozen=True)
class Cylindrical(common.Arm):
    """Cylindrical arm of seed 004 (revolute base, radial and vertical prismatic joints).

    Attributes:
        h: column height (base to the radial slide at ``q3 = 0``), scalar ``>= 0``.
    """

    h: Array = dataclasses.field(metadata=dict(kind="nonnegative"))

    N_JOINTS: ClassVar[int] = 3
    JOINT_TYPES: ClassVar[str] = "RPP"
    BRANCHES: ClassVar[tuple[str, ...]] = ("front",)
    TARGET_SHAPE: ClassVar[tuple[int, ...]] = (3,)

    def dh_table(self, dtype=None) -> DHTable:
        dtype = dtype or jnp.result_type(float)
        (h,) = self.lengths(dtype)
        zeros = [0.0, 0.0, 0.0]
        return common.dh(
            dtype, zeros, [-_HALF_PI, _HALF_PI, 0.0], [h, 0.0, 0.0], [-_HALF_PI, 0.0, 0.0], "RPP"
        )

    def _ik_kernel(self, target: Array) -> tuple[Array, Array]:
        dtype = target.dtype
        (h,) = self.lengths(dtype)
        px, py, pz = target[..., 0], target[..., 1], target[..., 2]
        r = safe_sqrt(px * px + py * py)
        on_axis = r <= singular_rtol(dtype) * (h + r + jnp.abs(pz))
        q1 = common.guarded_atan2(py, px, on_axis)
        q = jnp.stack([q1, r, pz - h], axis=-1)[..., None, :]
        status = common.status_from(jnp.zeros_like(on_axis), on_axis)[..., None]
        return q, status


@common.register_arm
@dataclasses.dataclass(frozen=True)
class Spherical(common.Arm):
    """Spherical (polar) arm of seed 004: base rotation, elevation, radial prismatic joint.

    Attributes:
        h: shoulder height (base to the elevation axis), scalar ``>= 0``.
    """

    h: Array = dataclasses.field(metadata=dict(kind="nonnegative"))

    N_JOINTS: ClassVar[int] = 3
    JOINT_TYPES: ClassVar[str] = "RRP"
    BRANCHES: ClassVar[tuple[str, ...]] = ("front", "back")
    TARGET_SHAPE: ClassVar[tuple[int, ...]] = (3,)

    def dh_table(self, dtype=None) -> DHTable:
        dtype = dtype or jnp.result_type(float)
        (h,) = self.lengths(dtype)
        zeros = [0.0, 0.0, 0.0]
        return common.dh(
            dtype, zeros, [_HALF_PI, _HALF_PI, 0.0], [h, 0.0, 0.0], [0.0, _HALF_PI, 0.0], "RRP"
        )

    def _ik_kernel(self, target: Array) -> tuple[Array, Array]:
        dtype = target.dtype
        (h,) = self.lengths(dtype)
        q, singular = _polar(target, h, dtype)
        return q, common.status_from(jnp.zeros_like(singular), singular)


def _polar(p: Array, height: Array, dtype) -> tuple[Array, Array]:
    """Front/back ``(q1, q2, rho)`` of a point seen from a shoulder at ``(0, 0, height)``.

    ``q1 = atan2(py, px)`` or ``+ pi``; ``q2 = atan2(s, +-r)`` (elevation, seed 003's Stanford
    ``theta2 = atan2(s, r)``, ``theta2' = pi - atan2(s, r)``); ``rho = sqrt(r^2 + s^2)``.
    Returns ``q`` ``(..., 2, 3)`` and the singular flag ``(..., 1)`` (on the base axis, or
    at the shoulder).
    """
    px, py, pz = p[..., 0], p[..., 1], p[..., 2]
    s = pz - height
    r = safe_sqrt(px * px + py * py)
    rho = safe_sqrt(r * r + s * s)
    tol = singular_rtol(dtype) * (jnp.abs(height) + rho)
    on_axis = r <= tol
    at_shoulder = rho <= tol
    q1_front = common.guarded_atan2(py, px, on_axis)
    q1 = jnp.stack([q1_front, common.wrap_angle(q1_front + _PI)], axis=-1)
    q2 = common.guarded_atan2(s[..., None], jnp.stack([r, -r], axis=-1), at_shoulder[..., None])
    rho2 = jnp.broadcast_to(rho[..., None], q1.shape)
    q = jnp.stack([q1, q2, rho2], axis=-1)
    return q, (on_axis | at_shoulder)[..., None]
