"""Standard Denavit-Hartenberg tables and their forward kinematics [Lopez-Villagomez, eqs. 2-6].

Joint ``i`` has four parameters: ``a_i`` (link length along ``x_i``), ``alpha_i`` (twist about
``x_i``), ``d_i`` (offset along ``z_{i-1}``) and ``theta_i`` (angle about ``z_{i-1}``). The
transform from frame ``i-1`` to frame ``i`` is the *standard* (distal) convention
[Lopez-Villagomez, eq. 2]::

    T_i = Rz(theta_i) Tz(d_i) Tx(a_i) Rx(alpha_i)
        = [[ct, -ca st, sa st, a ct], [st, ca ct, -sa ct, a st], [0, sa, ca, d], [0, 0, 0, 1]]

and the chain's transform is ``T = T_1 T_2 ... T_n`` (eq. 6; tests check both against sympy).
Joint variables add to the offsets: a revolute joint (``'R'``) uses ``theta_i + q_i``, a
prismatic one (``'P'``) ``d_i + q_i``. A ``DHTable`` is a robot of the protocol whose targets
are poses. Lengths in the caller's unit, angles in radians. FK has no failure cases: NaN or inf
in ``q`` reaches only the affected elements (``fk_chain`` flags them ``INVALID_INPUT``).

The kernel multiplies the link transforms entry by entry (a rotation is a nested list of
batch arrays, see ``lie``) with the joints' ``cos``/``sin`` materialised once.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, ClassVar

import jax
import jax.numpy as jnp
import numpy as np
from jax import Array
from jax.typing import ArrayLike

from .. import _batching, _validate, lie
from .._geometry import REAL, geometry, number, static
from .._numerics import computed_once
from .._trig import cos_alone, sin_alone
from ..jet import Jet
from ..robot import POSE, CompilePolicy, Robot, promoted
from ..status import Status
from ._chain_options import CHAIN_MIN_PART, ChainIKOptions

__all__ = ["JOINT_TYPES", "DHTable", "dh_transform", "fk_dh"]

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
class DHTable(Robot):
    """A serial chain given by its standard Denavit-Hartenberg table (one row per joint).

    A robot of the protocol whose targets are poses (``jaxkin.ik`` solves it by Newton with
    restarts, ``jaxkin.serial.newton_ik.ik_chain``). The constructor validates every field
    (a ``ValueError`` naming it); ``create`` is the same with keyword defaults.

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

    a: Array = number(REAL, (-1,))
    alpha: Array = number(REAL, (-1,))
    d: Array = number(REAL, (-1,))
    theta: Array = number(REAL, (-1,), default=None)
    joint_types: tuple[str, ...] = static(default=None)

    target: ClassVar = POSE
    branches: ClassVar = ("newton",)
    reachable: ClassVar = (Status.OK,)
    IKOptions: ClassVar = ChainIKOptions
    ik_policy: ClassVar = CompilePolicy(pad=False, threads=True, min_part=CHAIN_MIN_PART)

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
        return cls(a, alpha, d, theta, joint_types)

    @property
    def n_joints(self) -> int:
        return len(self.joint_types)

    @property
    def dtype(self):
        return jnp.asarray(self.a).dtype

    @property
    def joint_names(self) -> tuple[str, ...]:
        return tuple(f"q{i + 1}" for i in range(self.n_joints))

    def length_scale(self) -> Any:
        """``sum |a_i| + sum |d_i|`` (1 for a table of zero lengths)."""
        total = jnp.sum(jnp.abs(self.a)) + jnp.sum(jnp.abs(self.d))
        return jnp.where(total > 0, total, 1.0)

    def link_segments(self, q: Array, x: Array) -> Array:
        """Base -> the origin of each DH frame in turn, ``(..., n, 2, 3)``."""
        frames = _fk_dh_impl(_validate.cast_leaves(self, q.dtype), q, True)[..., :3, 3]
        points = jnp.concatenate([jnp.zeros_like(frames[..., :1, :]), frames], axis=-2)
        return jnp.stack([points[..., :-1, :], points[..., 1:, :]], axis=-2)

    def ik_kernel(self, target: Jet, branch: Any, options: Any, rates: bool) -> Any:
        from .newton_ik import chain_ik_kernel

        return chain_ik_kernel(self, target, options, rates)

    def fk_kernel(self, q: Jet, options: Any, rates: bool) -> Any:
        from .poe import _fk_chain_core

        return _fk_chain_core(_validate.cast_leaves(self, q.dtype), q, rates)

    def work_dtype(self, dtype: Any) -> Any:
        return promoted(dtype, self.a.dtype)


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


def _fk_dh_impl(table: DHTable, q: Array, all_frames: bool) -> Array:
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


# The table has no batch axes: only the joints are padded.
_fk_dh_jit = _batching.PaddedJit(jax.jit(_fk_dh_impl, static_argnames=("all_frames",)), {"q": 1})


def check_q(q: ArrayLike, n: int, dtype) -> Array:
    """``q`` as an array of shape ``(..., n)`` in its promotion with ``dtype`` (and float).

    Raises:
        ValueError: ``q``'s last axis is not ``n``.
    """
    if not isinstance(q, jax.Array):
        q = jnp.asarray(q)
    if q.ndim == 0 or q.shape[-1] != n:
        raise ValueError(
            f"q: expected shape (..., {n}) (last axis = the chain's {n} joints), "
            f"got {tuple(q.shape)}"
        )
    return _validate.cast_leaves(q, jnp.result_type(q, dtype, float))


def fk_dh(table: DHTable, q: ArrayLike, all_frames: bool = False) -> Array:
    """Forward kinematics of a DH chain: ``T = T_1(q_1) ... T_n(q_n)`` [Lopez-Villagomez, eq. 6].

    Args:
        table: the chain (``DHTable.create``).
        q: joint variables, shape ``(..., n)`` (radians for 'R', length units for 'P').
        all_frames: if True, return every intermediate frame ``T_1 ... T_i`` for
            ``i = 1..n`` (frame ``i`` of the DH convention, in base coordinates).

    Returns:
        ``(..., 4, 4)`` base-to-end-effector transforms, or ``(..., n, 4, 4)`` with
        ``all_frames``. The dtype is the promotion of ``q`` and the table.

    Raises:
        ValueError: ``table`` is not a ``DHTable`` or ``q``'s last axis is not ``n``.
    """
    if not isinstance(table, DHTable):
        raise ValueError(f"table: expected a DHTable, got {type(table).__name__}")
    q = check_q(q, table.n_joints, table.dtype)
    table = _validate.cast_leaves(table, q.dtype)
    return _fk_dh_jit(table, q, bool(all_frames), batch=q.shape[:-1])
