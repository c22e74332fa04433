"""Standard Denavit-Hartenberg tables and their forward kinematics [Lopez-Villagomez, eqs. 2-6].

Joint ``i`` has four parameters: ``a_i`` (link length along ``x_i``), ``alpha_i`` (twist about
``x_i``), ``d_i`` (offset along ``z_{i-1}``) and ``theta_i`` (angle about ``z_{i-1}``). The
transform from frame ``i-1`` to frame ``i`` is the *standard* (distal) convention
[Lopez-Villagomez, eq. 2]::

    T_i = Rz(theta_i) Tz(d_i) Tx(a_i) Rx(alpha_i)
        = [[ct, -ca st, sa st, a ct], [st, ca ct, -sa ct, a st], [0, sa, ca, d], [0, 0, 0, 1]]

and the chain's transform is ``T = T_1 T_2 ... T_n`` (eq. 6; tests check both against sympy).
Joint variables add to the offsets: a revolute joint (``'R'``) uses ``theta_i + q_i``, a
prismatic one (``'P'``) ``d_i + q_i``. Lengths in the caller's unit, angles in radians.

A ``DHTable`` is data, not a robot: ``from_dh(table)`` builds the ``serial.Chain`` with the
same ``q`` and the same ``T(q)`` (joint ``i`` moves about, or along, the ``z`` axis of DH frame
``i - 1`` at ``q = 0``: ``S_i = (z, -z x o)`` or ``(0, z)`` with ``z``, ``o`` that frame's
axis and origin in base coordinates; ``M = T(0)``), whose forward kinematics is
``jaxkin.fk(chain, q)``. ``transforms`` is the DH kernel itself (the analytic arms' forward
kinematics): it multiplies the link transforms entry by entry (a rotation is a nested list of
batch arrays, see ``lie``) with the joints' ``cos``/``sin`` materialised once. NaN or inf in
``q`` reaches only the affected elements.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from jax import Array
from jax.typing import ArrayLike

from .. import _validate, lie
from .._execute import Kernel
from .._geometry import REAL, Geometry, Numeric, geometry, number, static
from .._numerics import computed_once
from .._trig import cos_alone, sin_alone
from .chain import Chain

__all__ = ["JOINT_TYPES", "DHTable", "dh_transform", "from_dh", "screws", "transforms"]

JOINT_TYPES = ("R", "P")


def _common_floats(obj: Any, names: tuple[str, ...]) -> None:
    """Cast the named array fields of a geometry to their common floating dtype."""
    arrays = [getattr(obj, n) for n in names]
    if not all(_validate.is_concrete(x) for x in arrays):
        return
    dtype = jnp.result_type(*arrays, float)
    for name, arr in zip(names, arrays, strict=True):
        object.__setattr__(obj, name, jnp.asarray(arr, dtype))


@geometry
class DHTable(Geometry):
    """A standard Denavit-Hartenberg table (one row per joint): the data ``from_dh`` reads.

    The constructor validates every field (a ``ValueError`` naming it); ``create`` is the same
    with keyword defaults.

    Attributes:
        a: link lengths ``a_i``, shape ``(n,)``.
        alpha: link twists ``alpha_i`` in radians, shape ``(n,)``.
        d: link offsets ``d_i`` (for a prismatic joint, the offset at ``q_i = 0``), ``(n,)``.
        theta: joint angles ``theta_i`` at ``q = 0`` (for a revolute joint, the angle offset),
            radians, shape ``(n,)``; None for zeros.
        joint_types: static tuple of ``'R'`` (revolute: ``q_i`` adds to ``theta_i``) or
            ``'P'`` (prismatic: ``q_i`` adds to ``d_i``), length ``n``; a string such as
            ``"RRP"`` is accepted; None for all revolute.
    """

    a: Numeric = number(REAL, (-1,))
    alpha: Numeric = number(REAL, (-1,))
    d: Numeric = number(REAL, (-1,))
    theta: Numeric = number(REAL, (-1,), default=None)
    joint_types: tuple[str, ...] = static(default=None)

    def _validate(self) -> None:
        if self.theta is None and _validate.is_concrete(self.a):
            object.__setattr__(self, "theta", np.zeros(np.shape(self.a)))
        super()._validate()
        n = int(jnp.shape(self.a)[0])
        if n < 1:
            raise ValueError("DHTable.a: a DH table needs at least one joint, got 0 rows")
        for name in ("alpha", "d", "theta"):
            size = int(jnp.shape(getattr(self, name))[0])
            if size != n:
                raise ValueError(
                    f"DHTable.{name}: expected {n} entries (the length of a), got {size}"
                )
        kinds = self.joint_types
        kinds = ("R",) * n if kinds is None else tuple(kinds)
        if len(kinds) != n or any(k not in JOINT_TYPES for k in kinds):
            raise ValueError(
                f"DHTable.joint_types: expected {n} entries, each 'R' or 'P', "
                f"got {self.joint_types!r}"
            )
        object.__setattr__(self, "joint_types", kinds)
        _common_floats(self, ("a", "alpha", "d", "theta"))

    @classmethod
    def create(
        cls,
        a: ArrayLike,
        alpha: ArrayLike,
        d: ArrayLike,
        theta: ArrayLike | None = None,
        joint_types: str | Sequence[str] | None = None,
    ) -> DHTable:
        """The constructor with keyword defaults (``theta`` zeros, every joint revolute)."""
        return cls(a, alpha, d, theta, joint_types)  # type: ignore[arg-type]  # _validate: a tuple

    @property
    def n_joints(self) -> int:
        return len(self.joint_types)

    @property
    def dtype(self):
        return jnp.asarray(self.a).dtype


def dh_transform(a: ArrayLike, alpha: ArrayLike, d: ArrayLike, theta: ArrayLike) -> Array:
    """Standard DH link transform ``Rz(theta) Tz(d) Tx(a) Rx(alpha)`` [Lopez-Villagomez, eq. 2].

    Args:
        a, alpha, d, theta: arrays broadcastable to one batch shape ``(...)``.

    Returns:
        ``(..., 4, 4)`` homogeneous transforms, dtype of the broadcast inputs.
    """
    arrays = [jnp.asarray(x) for x in (a, alpha, d, theta)]
    dtype = jnp.result_type(*arrays, float)
    a, alpha, d, theta = jnp.broadcast_arrays(*(x.astype(dtype) for x in arrays))
    ct, st = jnp.cos(theta), jnp.sin(theta)
    ca, sa = jnp.cos(alpha), jnp.sin(alpha)
    zero, one = jnp.zeros_like(a), jnp.ones_like(a)
    rows = [
        [ct, -ca * st, sa * st, a * ct],
        [st, ca * ct, -sa * ct, a * st],
        [zero, sa, ca, d],
        [zero, zero, zero, one],
    ]
    return jnp.stack([jnp.stack(row, axis=-1) for row in rows], axis=-2)


def _link(ct: Array, st: Array, ca: Array, sa: Array, a: Array, d: Array):
    """[Lopez-Villagomez, eq. 2] as nested lists (``lie``; structural zero ``None``)."""
    rot = [[ct, -ca * st, sa * st], [st, ca * ct, -sa * ct], [None, sa, ca]]
    return rot, [a * ct, a * st, d]


def _joint_parameters(table: DHTable, q: Array) -> tuple[Array, Array, Array, Array]:
    """Per-joint ``(a, alpha, d, theta)`` with ``q`` added, each ``(..., n)``."""
    revolute = np.array([kind == "R" for kind in table.joint_types])
    theta = table.theta + jnp.where(revolute, q, 0.0)
    d = table.d + jnp.where(revolute, 0.0, q)
    a = jnp.broadcast_to(table.a, q.shape)
    alpha = jnp.broadcast_to(table.alpha, q.shape)
    return a, alpha, d, theta


def transforms(table: DHTable, q: Array, all_frames: bool = False) -> Array:
    """The DH kernel: ``T = T_1(q_1) ... T_n(q_n)`` [Lopez-Villagomez, eq. 6] at ``q``
    ``(..., n)`` in the table's dtype, ``(..., 4, 4)``; with ``all_frames`` every frame
    ``T_1 ... T_i`` (frame ``i`` of the DH convention, base coordinates), ``(..., n, 4, 4)``.
    Pure and traceable (no validation)."""
    _, _, d, theta = _joint_parameters(table, q)
    # Materialise sin/cos once (one stacked array, see computed_once): XLA's CPU fusion would
    # recompute them in every output loop. Joint-major (n, ...): each joint's row is contiguous
    # for its readers. Each stored row is its own loop, so sin_alone/cos_alone (one polynomial
    # each) rather than sincos; rotation entries need absolute accuracy only.
    joint_major = jnp.moveaxis(theta, -1, 0)
    sin_cos = computed_once(jnp.stack([sin_alone(joint_major), cos_alone(joint_major)]))
    # Unbatched per-joint constants, materialised too (else fused and recomputed per element).
    ca, sa, a = jax.lax.optimization_barrier((jnp.cos(table.alpha), jnp.sin(table.alpha), table.a))
    batch, dtype = q.shape[:-1], q.dtype
    pose = None
    frames = []
    for i in range(table.n_joints):
        link = _link(sin_cos[1, i], sin_cos[0, i], ca[i], sa[i], a[i], d[..., i])
        pose = link if pose is None else lie.compose_soa(pose, link)
        # Stored every 3 joints (for a 6R arm: the shoulder's T_3): fastest of the spacings
        # measured (docs/performance.md).
        if i % 3 == 2 and i < table.n_joints - 1:
            pose = lie.computed_once_soa(pose, batch)
        if all_frames or i == table.n_joints - 1:
            frames.append(lie.to_matrix_soa(pose, batch, dtype))
    if all_frames:
        return jnp.stack(frames, axis=-3)
    return frames[-1]


def screws(table: DHTable) -> tuple[Array, Array]:
    """The base-frame screws ``(n, 6)`` and home pose ``(4, 4)`` of the chain with the same
    ``T(q)`` (module docstring); pure and traceable."""
    zeros = jnp.zeros((table.n_joints,), table.dtype)
    frames = transforms(table, zeros, all_frames=True)  # (n, 4, 4): frames 1..n
    base = jnp.eye(4, dtype=table.dtype)[None]
    before = jnp.concatenate([base, frames[:-1]], axis=0)  # frame i-1 for joint i
    z_axis = before[:, :3, 2]
    origin = before[:, :3, 3]
    rows = []
    for i, kind in enumerate(table.joint_types):
        if kind == "R":
            rows.append(jnp.concatenate([z_axis[i], -jnp.cross(z_axis[i], origin[i])]))
        else:
            rows.append(jnp.concatenate([jnp.zeros_like(z_axis[i]), z_axis[i]]))
    return jnp.stack(rows), frames[-1]


_screws_jit = Kernel(screws)


def from_dh(
    table: DHTable,
    joint_names: Sequence[str] | None = None,
    lower: ArrayLike | None = None,
    upper: ArrayLike | None = None,
    velocity: ArrayLike | None = None,
    base_link: str = "",
    tip_link: str = "",
    target: str = "pose",
) -> Chain:
    """The ``serial.Chain`` of a DH table: the same ``q`` (radians for ``'R'``, length for
    ``'P'``) and the same ``T(q)`` (module docstring).

    Args:
        table: the table (``DHTable.create(a=..., alpha=..., d=...)``, or an analytic arm's
            ``dh_table()``).
        joint_names, lower, upper, velocity, base_link, tip_link, target: as ``Chain.create``
            (default names ``q1 ... qn``, no limits).

    Raises:
        ValueError: ``table`` is not a ``DHTable``, or a malformed name or limit.
    """
    if not isinstance(table, DHTable):
        raise ValueError(f"table: expected a serial.DHTable, got {type(table).__name__}")
    rows, home = _screws_jit(table)
    return Chain.create(
        np.asarray(rows),
        np.asarray(home),
        joint_names=joint_names,
        lower=lower,
        upper=upper,
        velocity=velocity,
        base_link=base_link,
        tip_link=tip_link,
        target=target,
    )
