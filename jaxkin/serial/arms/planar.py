"""Planar 2R and 3R arms: forward kinematics by DH and closed-form inverse kinematics.

Both arms move in the base xy-plane; joint axes are parallel to z and the DH table is
``a = (l1, l2[, l3])``, ``alpha = d = theta = 0``. ``fk`` returns the 4x4 transform of the last
DH frame: rotation ``Rz(q1 + q2 [+ q3])``, translation ``(x, y, 0)``.

**Planar2R(l1, l2)**, target ``(..., 2)`` = ``(x, y)`` ([Pineiro], 2R; [UANL, ex. 2])::

    x = l1 cos q1 + l2 cos(q1 + q2),   y = l1 sin q1 + l2 sin(q1 + q2)
    cos q2 = (x^2 + y^2 - l1^2 - l2^2) / (2 l1 l2),  q2 = atan2(+-sqrt(1 - cos^2 q2), cos q2)
    q1 = atan2(y, x) - atan2(l2 sin q2, l1 + l2 cos q2)

Branches ``("elbow_up", "elbow_down")``: ``q2 <= 0`` (elbow to the left of the ray
base->target, i.e. above it for a target on +x) and ``q2 >= 0``. [Pineiro] writes the same
pair as ``theta1 = gamma +- alpha, theta2 = -+(pi - beta)``.

**Planar3R(l1, l2, l3)**, target ``(..., 3)`` = ``(x, y, phi)`` with ``phi`` the end
orientation ([UANL, ex. 3], Asada eqs. 4.1.1-4.1.3): the wrist
``(x - l3 cos phi, y - l3 sin phi)`` is solved as a 2R, then ``q3 = phi - q1 - q2`` wrapped to
``[-pi, pi]``. Same two branches.

Statuses (per branch, see ``jaxkin.serial.arms.kernels``): ``UNREACHABLE`` when the (wrist)
distance ``r`` lies outside ``[|l1 - l2|, l1 + l2]`` by more than ``tol = sqrt(eps)(l1 + l2)``;
``SINGULAR`` within ``tol`` of either bound (the two branches coincide) or at ``r <= tol``
(``l1 = l2``, target on the base joint: ``q1`` free, returned as 0); ``INVALID_INPUT`` for
NaN/inf.

Float32: ``docs/performance.md`` (measured round-trip accuracy of every arm).
"""

from __future__ import annotations

from typing import ClassVar

import jax.numpy as jnp
from jax import Array

from ..._geometry import LENGTH, NONNEGATIVE, Numeric, geometry, number
from ...robot import PLANAR_POINT, PLANAR_POSE
from ..dh import DHTable
from ._kit import dh, status_from, two_link, wrap_angle
from .base import Arm

__all__ = ["Planar2R", "Planar3R"]

_ELBOWS = (-1.0, 1.0)  # elbow_up (q2 <= 0), elbow_down (q2 >= 0)


@geometry
class Planar2R(Arm):
    """Planar two-link arm (revolute, revolute).

    Attributes:
        l1: length of link 1 (base joint to elbow), positive scalar.
        l2: length of link 2 (elbow to tip), positive scalar.
    """

    l1: Numeric = number(LENGTH)
    l2: Numeric = number(LENGTH)
    link_radius: Numeric = number(NONNEGATIVE, default=0.0)  # collision body (Arm)

    joint_types: ClassVar[str] = "RR"
    branches: ClassVar[tuple[str, ...]] = ("elbow_up", "elbow_down")
    target: ClassVar = PLANAR_POINT

    def dh_table(self, dtype=None) -> DHTable:
        dtype = dtype or jnp.result_type(float)
        l1, l2 = self.lengths(dtype)
        return dh(dtype, [l1, l2], [0.0, 0.0], [0.0, 0.0], [0.0, 0.0], "RR")

    def ik_branches(self, target: Array) -> tuple[Array, Array]:
        l1, l2 = self.lengths(target.dtype)
        x, y = target[..., 0:1], target[..., 1:2]  # (..., 1): broadcast over branches
        sol = two_link(x, y, l1, l2, jnp.asarray(_ELBOWS, target.dtype))
        q = jnp.stack([sol.q1, sol.q2], axis=-1)
        return q, status_from(sol.unreachable, sol.singular)


@geometry
class Planar3R(Arm):
    """Planar three-link arm with end orientation (revolute x 3).

    Attributes:
        l1: link 1 length, positive scalar.
        l2: link 2 length, positive scalar.
        l3: link 3 length (wrist joint to end point), positive scalar.
    """

    l1: Numeric = number(LENGTH)
    l2: Numeric = number(LENGTH)
    l3: Numeric = number(LENGTH)
    link_radius: Numeric = number(NONNEGATIVE, default=0.0)  # collision body (Arm)

    joint_types: ClassVar[str] = "RRR"
    branches: ClassVar[tuple[str, ...]] = ("elbow_up", "elbow_down")
    target: ClassVar = PLANAR_POSE

    def dh_table(self, dtype=None) -> DHTable:
        dtype = dtype or jnp.result_type(float)
        l1, l2, l3 = self.lengths(dtype)
        zeros = [0.0, 0.0, 0.0]
        return dh(dtype, [l1, l2, l3], zeros, zeros, zeros, "RRR")

    def ik_branches(self, target: Array) -> tuple[Array, Array]:
        l1, l2, l3 = self.lengths(target.dtype)
        phi = target[..., 2:3]
        wx = target[..., 0:1] - l3 * jnp.cos(phi)
        wy = target[..., 1:2] - l3 * jnp.sin(phi)
        sol = two_link(wx, wy, l1, l2, jnp.asarray(_ELBOWS, target.dtype))
        q3 = wrap_angle(phi - sol.q1 - sol.q2)
        q = jnp.stack([sol.q1, sol.q2, q3], axis=-1)
        return q, status_from(sol.unreachable, sol.singular)
