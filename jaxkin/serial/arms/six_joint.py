"""Six-joint arms with a spherical wrist: PUMA 560 (6R) and Stanford (2RP3R) [Pineiro].

Both are solved by decoupling: the wrist centre ``p_w = p - d6 z`` (``z`` the third column of
the target rotation) fixes the first three joints; the wrist joints are the Euler angles of
``R_36 = R_03^T R`` (``R_03`` in closed form from the first three DH rows).

``Puma560``: the standard DH parameters of Corke's ``mdl_puma560`` (metres, all overridable).
Shoulder ``q1 = atan2(d3 px + X py, X px - d3 py)`` with ``X = +-sqrt(r^2 - d3^2)``
(``front``/``back``; [Pineiro]'s second shoulder angle is corrected, docs/errata.md); elbow: a
planar two-link problem with links ``a2`` and ``sqrt(a3^2 + d4^2)`` (``up``/``down``); wrist
``R_36 = Rz(q4) Ry(-q5) Rz(q6)`` (``noflip``: ``q5 >= 0``; ``flip``). Eight branches, named
e.g. ``"front_up_noflip"``. ``UNREACHABLE`` when ``r < |d3|`` or the elbow is out of reach;
``SINGULAR`` at ``r = |d3|``, at the elbow's reach bounds and for ``q5`` in {0, pi}.

``Stanford``: [Pineiro]'s arm without shoulder offset: base rotation ``q1``, elevation ``q2``,
prismatic boom ``q3`` (beyond the fixed length ``a2``; [Pineiro] drops ``- a2``, corrected),
ZYZ wrist ``R_36 = Rz(q4) Ry(q5) Rz(q6)``. Four branches ``{front, back} x {noflip, flip}``;
every target is reachable; ``SINGULAR`` on the base axis, at the shoulder and at wrist
singularities.

Targets are ``(..., 4, 4)`` transforms (rotation block assumed orthonormal). Tolerances:
``sqrt(eps)`` times the sum of the lengths for positions, ``sqrt(eps)`` for ``sin q5``. The DH
tables are the arms' ``dh_table()``; overview: ``docs/robots.md``.
"""

from __future__ import annotations

from typing import ClassVar

import jax.numpy as jnp
from jax import Array

from ..._geometry import LENGTH, NONNEGATIVE, REAL, Numeric, geometry, number
from ..._numerics import computed_once, safe_sqrt, singular_rtol
from ..._trig import atan2, sincos
from ...robot import POSE
from ..dh import DHTable
from ._kit import HALF_PI, PI, dh, guarded_atan2, polar, status_from, two_link, zyz_wrist
from .base import Arm

__all__ = ["Puma560", "Stanford"]


def _branch_names(*levels: tuple[str, ...]) -> tuple[str, ...]:
    names = [""]
    for level in levels:
        names = [f"{n}_{x}" if n else x for n in names for x in level]
    return tuple(names)


def _mat3(rows: list[list[Array]]) -> Array:
    return jnp.stack([jnp.stack(row, axis=-1) for row in rows], axis=-2)


def _wrist(r03: Array, rot: Array, sign: float) -> tuple[Array, Array]:
    """Wrist joints for every position branch: ``r03 (..., k, 3, 3)``, ``rot (..., 3, 3)``.

    Returns the wrist angles ``(..., k, 2, 3)`` (wrist branch ``noflip``, ``flip``) and the
    wrist singular flag ``(..., k, 1)``.
    """
    r36 = jnp.einsum("...ji,...jk->...ik", r03, rot[..., None, :, :])
    branch = jnp.asarray([1.0, -1.0], rot.dtype)
    t4, t5, t6, singular = zyz_wrist(r36[..., None, :, :], sign, branch)
    return jnp.stack([t4, t5, t6], axis=-1), singular[..., :1]


def _join(q_pos: Array, q_wrist: Array) -> Array:
    """``(..., k, 3)`` arm joints and ``(..., k, 2, 3)`` wrist joints -> ``(..., k, 2, 6)``."""
    q_pos = jnp.broadcast_to(q_pos[..., None, :], q_wrist.shape)
    return jnp.concatenate([q_pos, q_wrist], axis=-1)


@geometry
class Puma560(Arm):
    """PUMA-type 6R arm with spherical wrist (standard DH of Corke's ``mdl_puma560``).

    Attributes (metres; defaults are the PUMA 560's):
        d1: shoulder height above the base frame, finite scalar (default 0).
        a2: upper-arm length, positive (0.4318).
        a3: elbow offset along the forearm's normal, finite (0.0203).
        d3: shoulder offset along joint 2's axis, finite (0.15005).
        d4: forearm length, elbow to wrist centre, finite (0.4318).
        d6: tool offset along the last joint axis, finite (0).
    """

    d1: Numeric = number(REAL, default=0.0)
    a2: Numeric = number(LENGTH, default=0.4318)
    a3: Numeric = number(REAL, default=0.0203)
    d3: Numeric = number(REAL, default=0.15005)
    d4: Numeric = number(REAL, default=0.4318)
    d6: Numeric = number(REAL, default=0.0)
    link_radius: Numeric = number(NONNEGATIVE, default=0.0)  # collision body (Arm)

    joint_types: ClassVar[str] = "RRRRRR"
    branches: ClassVar[tuple[str, ...]] = _branch_names(
        ("front", "back"), ("up", "down"), ("noflip", "flip")
    )
    target: ClassVar = POSE

    def dh_table(self, dtype=None) -> DHTable:
        dtype = dtype or jnp.result_type(float)
        d1, a2, a3, d3, d4, d6 = self.lengths(dtype)
        return dh(
            dtype,
            [0.0, a2, a3, 0.0, 0.0, 0.0],
            [HALF_PI, 0.0, -HALF_PI, HALF_PI, -HALF_PI, 0.0],
            [d1, 0.0, d3, d4, 0.0, d6],
            [0.0] * 6,
            self.joint_types,
        )

    def ik_branches(self, target: Array) -> tuple[Array, Array]:
        dtype = target.dtype
        d1, a2, a3, d3, d4, d6 = self.lengths(dtype)
        rot = target[..., :3, :3]
        p = target[..., :3, 3] - d6 * rot[..., :, 2]
        px, py, pz = p[..., 0], p[..., 1], p[..., 2]
        l3 = safe_sqrt(a3 * a3 + d4 * d4)
        tol = singular_rtol(dtype) * (jnp.abs(d1) + a2 + l3 + jnp.abs(d3))
        r2 = px * px + py * py
        r = safe_sqrt(r2)
        shoulder_unreachable = r < jnp.abs(d3) - tol
        shoulder_singular = jnp.abs(r - jnp.abs(d3)) <= tol
        x_abs = safe_sqrt(r2 - d3 * d3)
        x = jnp.stack([x_abs, -x_abs], axis=-1)  # (..., 2): front, back
        free = (r <= tol)[..., None]
        fill = jnp.asarray([0.0, PI], dtype)
        q1 = guarded_atan2(
            d3 * px[..., None] + x * py[..., None],
            x * px[..., None] - d3 * py[..., None],
            free,
            fill,
        )
        elbow = jnp.asarray([[-1.0, 1.0], [1.0, -1.0]], dtype)
        sol = two_link(x[..., :, None], (pz - d1)[..., None, None], a2, l3, elbow)
        # The two-link's second angle is q3 + psi, psi = atan2(d4, a3):
        # q3 = atan2(s2 a3 - c2 d4, c2 a3 + s2 d4).
        q3 = atan2(sol.s2 * a3 - sol.c2 * d4, sol.c2 * a3 + sol.s2 * d4)
        q1 = jnp.broadcast_to(q1[..., :, None], sol.q1.shape)
        q_pos = jnp.stack([q1, sol.q1, q3], axis=-1)  # (..., 2, 2, 3)
        batch = q_pos.shape[:-3]
        q_pos = q_pos.reshape(*batch, 4, 3)
        # R_03 = Rz(q1) Ry(-(q2 + q3)) (DH rows 1-3; checked by the round trips).
        # Stored once: every entry of R_03 (and so every wrist output loop) reads them
        q23 = q_pos[..., 1] + q_pos[..., 2]
        s1, c1, s23, c23 = computed_once(jnp.stack([*sincos(q_pos[..., 0]), *sincos(q23)]))
        zero = jnp.zeros_like(c1)
        r03 = _mat3([[c1 * c23, -s1, -c1 * s23], [s1 * c23, c1, -s1 * s23], [s23, zero, c23]])
        q_wrist, wrist_singular = _wrist(r03, rot, sign=-1.0)
        q = _join(q_pos, q_wrist)
        unreachable = sol.unreachable | shoulder_unreachable[..., None, None]
        singular = sol.singular | shoulder_singular[..., None, None]
        unreachable = jnp.broadcast_to(unreachable.reshape(*batch, 4, 1), (*batch, 4, 2))
        singular = singular.reshape(*batch, 4, 1) | wrist_singular
        status = status_from(unreachable, singular)
        return q.reshape(*batch, 8, 6), status.reshape(*batch, 8)


@geometry
class Stanford(Arm):
    """Stanford arm (2RP3R) of [Pineiro], without shoulder offset (DH in the module docstring).

    Attributes:
        d1: shoulder height, finite scalar.
        a2: fixed boom length at ``q3 = 0``, scalar ``>= 0``.
        d6: tool offset along the last joint axis, finite scalar (default 0).
    """

    d1: Numeric = number(REAL)
    a2: Numeric = number(NONNEGATIVE)
    d6: Numeric = number(REAL, default=0.0)
    link_radius: Numeric = number(NONNEGATIVE, default=0.0)  # collision body (Arm)

    joint_types: ClassVar[str] = "RRPRRR"
    branches: ClassVar[tuple[str, ...]] = _branch_names(("front", "back"), ("noflip", "flip"))
    target: ClassVar = POSE

    def dh_table(self, dtype=None) -> DHTable:
        dtype = dtype or jnp.result_type(float)
        d1, a2, d6 = self.lengths(dtype)
        return dh(
            dtype,
            [0.0] * 6,
            [HALF_PI, HALF_PI, 0.0, -HALF_PI, HALF_PI, 0.0],
            [d1, 0.0, a2, 0.0, 0.0, d6],
            [0.0, HALF_PI, 0.0, 0.0, 0.0, 0.0],
            self.joint_types,
        )

    def ik_branches(self, target: Array) -> tuple[Array, Array]:
        dtype = target.dtype
        d1, a2, d6 = self.lengths(dtype)
        rot = target[..., :3, :3]
        p = target[..., :3, 3] - d6 * rot[..., :, 2]
        spherical, pos_singular = polar(p, d1, dtype)  # (..., 2, 3): q1, q2, rho
        q_pos = spherical.at[..., 2].add(-a2)  # q3 = sqrt(r^2 + s^2) - a2 (docs/errata.md)
        # R_03 = Rz(q1) Ry(-(q2 + pi/2)) Rx(pi) (DH rows 1-3; checked by the round trips).
        s1, c1, s2, c2 = computed_once(
            jnp.stack([*sincos(q_pos[..., 0]), *sincos(q_pos[..., 1])])
        )  # stored once, as for the PUMA
        zero = jnp.zeros_like(c1)
        r03 = _mat3([[-c1 * s2, s1, c1 * c2], [-s1 * s2, -c1, s1 * c2], [c2, zero, s2]])
        q_wrist, wrist_singular = _wrist(r03, rot, sign=1.0)
        q = _join(q_pos, q_wrist)
        singular = pos_singular[..., None] | wrist_singular  # (..., 2, 1)
        status = status_from(jnp.zeros_like(singular), singular)
        status = jnp.broadcast_to(status, q.shape[:-1])
        batch = q.shape[:-3]
        return q.reshape(*batch, 4, 6), status.reshape(*batch, 4)
