"""Three-joint positioning arms: anthropomorphic RRR [Lopez-Villagomez], cylindrical and
spherical [UANL]. The target is the wrist position ``(..., 3)``; ``fk`` is the DH forward
kinematics of each arm's table (``dh_table``).

``Anthropomorphic(l1, l2, l3)`` [Lopez-Villagomez, Table 1, eqs. 2-6 and 10-14, with the
corrections of docs/errata.md]: ``q1 = atan2(py, px)`` (``front``) or ``+ pi`` (``back``);
``(q2, q3)`` the planar two-link IK of ``(+-sqrt(px^2 + py^2), pz - l1)`` with links
``(l2, l3)``. Four branches ``front_up, front_down, back_up, back_down`` ("up": the elbow above
the line shoulder->wrist). On the base axis ``q1`` is free (0 / pi) and all four are
``SINGULAR``.

``Cylindrical(h)`` [UANL]: revolute base ``q1``, radial prismatic ``q2``, vertical prismatic
``q3``: ``p = (q2 cos q1, q2 sin q1, h + q3)``; one branch ``front`` (``q2 >= 0``);
``SINGULAR`` on the axis.

``Spherical(h)`` [UANL]: base rotation ``q1``, elevation ``q2``, radial prismatic ``q3``:
``p = (q3 cos q2 cos q1, q3 cos q2 sin q1, h + q3 sin q2)``; branches ``front``/``back``;
``SINGULAR`` on the axis and at the shoulder (``q3 = 0``).

The prismatic joints have no stroke limits, so every target of the cylindrical and spherical
arms is reachable. Tolerances ``sqrt(eps(dtype))`` times the sum of the lengths (plus the
target distance for the prismatic arms). Each arm's DH table is its ``dh_table()``; overview:
``docs/robots.md``.
"""

from __future__ import annotations

from typing import ClassVar

import jax.numpy as jnp
from jax import Array

from ..._geometry import LENGTH, NONNEGATIVE, Numeric, geometry, number
from ..._numerics import safe_sqrt, singular_rtol
from ...robot import POINT
from ..dh import DHTable
from ._kit import HALF_PI, PI, dh, guarded_atan2, polar, status_from, two_link, wrap_angle
from .base import Arm

__all__ = ["Anthropomorphic", "Cylindrical", "Spherical"]


@geometry
class Anthropomorphic(Arm):
    """The 3-DOF anthropomorphic RRR arm of [Lopez-Villagomez] (DH table in the module docstring).

    Attributes:
        l1: shoulder height ``d_1`` (base to the shoulder joint), positive scalar.
        l2: upper-arm length ``a_2``, positive scalar.
        l3: forearm length ``a_3`` (elbow to wrist), positive scalar.
    """

    l1: Numeric = number(LENGTH)
    l2: Numeric = number(LENGTH)
    l3: Numeric = number(LENGTH)
    link_radius: Numeric = number(NONNEGATIVE, default=0.0)  # collision body (Arm)

    joint_types: ClassVar[str] = "RRR"
    branches: ClassVar[tuple[str, ...]] = ("front_up", "front_down", "back_up", "back_down")
    target: ClassVar = POINT

    def dh_table(self, dtype=None) -> DHTable:
        dtype = dtype or jnp.result_type(float)
        l1, l2, l3 = self.lengths(dtype)
        return dh(dtype, [0.0, l2, l3], [HALF_PI, 0.0, 0.0], [l1, 0.0, 0.0], [0.0, 0.0, 0.0], "RRR")

    def ik_branches(self, target: Array) -> tuple[Array, Array]:
        dtype = target.dtype
        l1, l2, l3 = self.lengths(dtype)
        px, py, pz = target[..., 0], target[..., 1], target[..., 2]
        r = safe_sqrt(px * px + py * py)
        on_axis = r <= singular_rtol(dtype) * (l1 + l2 + l3)
        q1_front = guarded_atan2(py, px, on_axis)  # eq. 10, two-argument atan2 (docs/errata.md)
        q1 = jnp.stack([q1_front, wrap_angle(q1_front + PI)], axis=-1)  # (..., 2)
        a = jnp.stack([r, -r], axis=-1)  # eq. 12: A = px c1 + py s1 = +-r
        b = pz - l1  # eq. 13
        elbow = jnp.asarray([[-1.0, 1.0], [1.0, -1.0]], dtype)  # [shoulder, up/down]
        sol = two_link(a[..., :, None], b[..., None, None], l2, l3, elbow)
        q1 = jnp.broadcast_to(q1[..., :, None], sol.q1.shape)
        q = jnp.stack([q1, sol.q1, sol.q2], axis=-1)  # (..., 2, 2, 3)
        status = status_from(sol.unreachable, sol.singular | on_axis[..., None, None])
        batch = q.shape[:-3]
        return q.reshape(*batch, 4, 3), status.reshape(*batch, 4)


@geometry
class Cylindrical(Arm):
    """Cylindrical arm of [UANL] (revolute base, radial and vertical prismatic joints).

    Attributes:
        h: column height (base to the radial slide at ``q3 = 0``), scalar ``>= 0``.
    """

    h: Numeric = number(NONNEGATIVE)
    link_radius: Numeric = number(NONNEGATIVE, default=0.0)  # collision body (Arm)

    joint_types: ClassVar[str] = "RPP"
    branches: ClassVar[tuple[str, ...]] = ("front",)
    target: ClassVar = POINT

    def dh_table(self, dtype=None) -> DHTable:
        dtype = dtype or jnp.result_type(float)
        (h,) = self.lengths(dtype)
        zeros = [0.0, 0.0, 0.0]
        return dh(
            dtype, zeros, [-HALF_PI, HALF_PI, 0.0], [h, 0.0, 0.0], [-HALF_PI, 0.0, 0.0], "RPP"
        )

    def ik_branches(self, target: Array) -> tuple[Array, Array]:
        dtype = target.dtype
        (h,) = self.lengths(dtype)
        px, py, pz = target[..., 0], target[..., 1], target[..., 2]
        r = safe_sqrt(px * px + py * py)
        on_axis = r <= singular_rtol(dtype) * (h + r + jnp.abs(pz))
        q1 = guarded_atan2(py, px, on_axis)
        q = jnp.stack([q1, r, pz - h], axis=-1)[..., None, :]
        status = status_from(jnp.zeros_like(on_axis), on_axis)[..., None]
        return q, status


@geometry
class Spherical(Arm):
    """Spherical (polar) arm of [UANL]: base rotation, elevation, radial prismatic joint.

    Attributes:
        h: shoulder height (base to the elevation axis), scalar ``>= 0``.
    """

    h: Numeric = number(NONNEGATIVE)
    link_radius: Numeric = number(NONNEGATIVE, default=0.0)  # collision body (Arm)

    joint_types: ClassVar[str] = "RRP"
    branches: ClassVar[tuple[str, ...]] = ("front", "back")
    target: ClassVar = POINT

    def dh_table(self, dtype=None) -> DHTable:
        dtype = dtype or jnp.result_type(float)
        (h,) = self.lengths(dtype)
        zeros = [0.0, 0.0, 0.0]
        return dh(dtype, zeros, [HALF_PI, HALF_PI, 0.0], [h, 0.0, 0.0], [0.0, HALF_PI, 0.0], "RRP")

    def ik_branches(self, target: Array) -> tuple[Array, Array]:
        dtype = target.dtype
        (h,) = self.lengths(dtype)
        q, singular = polar(target, h, dtype)
        return q, status_from(jnp.zeros_like(singular), singular)
