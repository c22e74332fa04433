"""Product-of-exponentials (PoE) chains: forward kinematics and Jacobians [Pineiro].

A chain of ``n`` joints is given by its screw axes and its home configuration ``M`` (the
end-effector transform at ``q = 0``). Screw rows are ordered ``(omega, v)`` (``lie`` module
convention). For a revolute joint ``omega`` is the unit axis and ``v = -omega x r`` for a point
``r`` on the axis (plus ``h omega`` for a screw of pitch ``h``); for a prismatic joint
``omega = 0`` and ``v`` is the unit direction. Two frames ([Pineiro], "Introducción")::

    space:  T(q) = exp([S_1] q_1) ... exp([S_n] q_n) M          (S_i in the base frame {s})
    body:   T(q) = M exp([B_1] q_1) ... exp([B_n] q_n)          (B_i in the end frame {b})

with ``B_i = Ad(M^-1) S_i``. Jacobians (columns are twists, rows ``(omega, v)``)::

    space:  J_s[:, i] = Ad(exp([S_1] q_1) ... exp([S_{i-1}] q_{i-1})) S_i
    body:   J_b[:, i] = Ad(exp(-[B_n] q_n) ... exp(-[B_{i+1}] q_{i+1})) B_i
    J_b = Ad(T^-1) J_s,   J_s = Ad(T) J_b

so that ``V_s = J_s q_dot`` with ``[V_s] = T_dot T^-1`` and ``V_b = J_b q_dot`` with
``[V_b] = T^-1 T_dot``. Because every screw is a unit screw (checked by ``PoEChain.create``),
``exp([S] q)`` needs no norm or small-angle branch::

    R = I + sin(q) W + (1 - cos q) W^2,   p = (q I + (1 - cos q) W + (q - sin q) W^2) v,
    W = hat(omega)   (W = 0 for a prismatic joint: R = I, p = q v)

``poe_from_dh`` builds the space-frame chain equivalent to a ``DHTable`` (same ``q``, same
``T(q)``), so DH and PoE forward kinematics can be compared; every function here that takes a
chain also accepts a ``DHTable`` (converted on the fly).

FK has no failure cases; NaN/inf in ``q`` only reaches the affected batch elements. Float32
inputs give float32 outputs (~1e-6 absolute for metre-scale arms).
"""

from __future__ import annotations

from typing import Any, ClassVar

import jax
import jax.numpy as jnp
import numpy as np
from jax import Array
from jax.typing import ArrayLike

from .. import _batching, _validate, lie
from .._geometry import REAL, geometry, number, static
from .._trig import sincos
from ..jet import Jet
from ..result import FKResult, forward_result
from ..robot import POSE, CompilePolicy, Robot, fk, promoted
from ..status import Status
from . import dh as _dh
from ._chain_options import CHAIN_MIN_PART, ChainIKOptions

__all__ = [
    "FRAMES",
    "PoEChain",
    "fk_chain",
    "body_jacobian",
    "chain_fk",
    "change_frame",
    "fk_poe",
    "poe_from_dh",
    "space_jacobian",
]

FRAMES = ("space", "body")
_UNIT_TOL = 1e-6  # tolerance on |omega| = 1 (revolute) or |v| = 1 with omega = 0 (prismatic)


def check_screws_and_home(screws: ArrayLike, home: ArrayLike, owner: str) -> None:
    """Host-side: unit screws ``(n, 6)``, n >= 1, and a rigid ``home``; a ``ValueError`` naming
    ``owner.screws`` / ``owner.home`` otherwise."""
    values = np.asarray(screws, dtype=np.float64)
    if values.shape[0] < 1:
        raise ValueError(f"{owner}.screws: expected shape (n, 6) with n >= 1, got (0, 6)")
    w_norm = np.linalg.norm(values[:, :3], axis=1)
    v_norm = np.linalg.norm(values[:, 3:], axis=1)
    revolute = np.abs(w_norm - 1.0) <= _UNIT_TOL
    prismatic = (w_norm <= _UNIT_TOL) & (np.abs(v_norm - 1.0) <= _UNIT_TOL)
    bad = np.flatnonzero(~(revolute | prismatic))
    if bad.size:
        raise ValueError(
            f"{owner}.screws: rows {bad.tolist()} are not unit screws (need |omega| = 1 for "
            "a revolute joint, or omega = 0 and |v| = 1 for a prismatic joint); got "
            f"|omega| = {w_norm[bad]}, |v| = {v_norm[bad]}"
        )
    m = np.asarray(home, dtype=np.float64)
    rot = m[:3, :3]
    if (
        np.max(np.abs(m[3] - np.array([0.0, 0.0, 0.0, 1.0]))) > _UNIT_TOL
        or np.max(np.abs(rot.T @ rot - np.eye(3))) > _UNIT_TOL
        or np.linalg.det(rot) < 0.0
    ):
        raise ValueError(
            f"{owner}.home: expected a rigid transform [[R, p], [0, 0, 0, 1]] with R a "
            f"rotation (R^T R = I, det R = +1), got {m}"
        )


@geometry
class PoEChain(Robot):
    """A serial chain in product-of-exponentials form; a robot of the protocol (pose targets).

    The constructor validates every field (a ``ValueError`` naming it); ``create`` is the same.

    Attributes:
        screws: unit screw axes, one row per joint ordered ``(omega, v)``, shape ``(n, 6)``;
            expressed in the base frame when ``frame == 'space'`` (``S_i``), in the home
            end-effector frame when ``frame == 'body'`` (``B_i``). A row is a unit screw when
            ``|omega| = 1`` (revolute) or ``omega = 0`` and ``|v| = 1`` (prismatic), within 1e-6.
        home: end-effector transform at ``q = 0`` (``M``), a rigid ``(4, 4)`` transform.
        frame: static, ``'space'`` or ``'body'``.
    """

    screws: Array = number(REAL, (-1, 6))
    home: Array = number(REAL, (4, 4))
    frame: str = static(default="space")

    target: ClassVar = POSE
    branches: ClassVar = ("newton",)
    reachable: ClassVar = (Status.OK,)
    IKOptions: ClassVar = ChainIKOptions
    ik_policy: ClassVar = CompilePolicy(pad=False, threads=True, min_part=CHAIN_MIN_PART)

    def _validate(self) -> None:
        _validate.choice(self.frame, "PoEChain.frame", FRAMES)
        super()._validate()
        if not (_validate.is_concrete(self.screws) and _validate.is_concrete(self.home)):
            return
        check_screws_and_home(self.screws, self.home, "PoEChain")
        dtype = jnp.result_type(self.screws, self.home, float)
        object.__setattr__(self, "screws", jnp.asarray(self.screws, dtype))
        object.__setattr__(self, "home", jnp.asarray(self.home, dtype))

    @classmethod
    def create(cls, screws: ArrayLike, home: ArrayLike, frame: str = "space") -> PoEChain:
        """The same as the constructor."""
        return cls(screws, home, frame)

    @property
    def n_joints(self) -> int:
        return int(self.screws.shape[0])

    @property
    def dtype(self):
        return self.screws.dtype

    @property
    def joint_names(self) -> tuple[str, ...]:
        return tuple(f"q{i + 1}" for i in range(self.n_joints))

    @property
    def joint_types(self) -> str:
        """``"R"`` where a screw has a rotation part, ``"P"`` elsewhere (host side)."""
        rotating = np.any(np.asarray(self.screws)[:, :3] != 0, axis=-1)
        return "".join("R" if r else "P" for r in rotating)

    def length_scale(self) -> Any:
        """``|p_home|`` plus the distances of the joint axes from the origin (``|v_i|`` of the
        revolute screws); 1 when all are zero."""
        rotating = jnp.any(self.screws[:, :3] != 0, axis=-1)
        offsets = jnp.where(rotating, jnp.linalg.norm(self.screws[:, 3:], axis=-1), 0.0)
        total = jnp.linalg.norm(self.home[:3, 3]) + jnp.sum(offsets)
        return jnp.where(total > 0, total, 1.0)

    def ik_kernel(self, target: Jet, branch: Any, options: Any, rates: bool) -> Any:
        from .newton_ik import chain_ik_kernel

        return chain_ik_kernel(self, target, options, rates)

    def fk_kernel(self, q: Jet, options: Any, rates: bool) -> FKResult:
        return _fk_chain_core(_validate.cast_leaves(self, q.dtype), q, rates)

    def work_dtype(self, dtype: Any) -> Any:
        return promoted(dtype, self.screws.dtype)


# ----------------------------------------------------------------------------------------------
# Kernels on (R, p) pairs: R (..., 3, 3), p (..., 3). Small batched matrix products (XLA dot
# ops) materialise every intermediate pose; an elementwise structure-of-arrays version of the
# same products was many times slower on CPU for 6 joints (XLA fused the whole product tree
# into a few loops and recomputed shared sub-expressions per output).


def _mat_vec(rot: Array, x: Array) -> Array:
    return jnp.einsum("...ij,...j->...i", rot, x)


def _compose(a: tuple[Array, Array], b: tuple[Array, Array]) -> tuple[Array, Array]:
    rot_a, p_a = a
    rot_b, p_b = b
    return jnp.einsum("...ij,...jk->...ik", rot_a, rot_b), _mat_vec(rot_a, p_b) + p_a


def _joint_exps(chain: PoEChain, q: Array) -> list[tuple[Array, Array]]:
    """``exp([S_i] q_i)`` of every joint as ``(R, p)``, for unit screws (module docstring).

    ``W = hat(omega)``, ``W^2``, ``W v`` and ``W^2 v`` are unbatched; the batched work is one
    ``sin`` and one ``cos`` per joint and multiply-adds.
    """
    w = lie.hat(chain.screws[:, :3])  # (n, 3, 3)
    w2 = w @ w
    v = chain.screws[:, 3:]
    wv = jnp.einsum("nij,nj->ni", w, v)
    w2v = jnp.einsum("nij,nj->ni", w2, v)
    s_all, c_all = sincos(q)
    eye = jnp.eye(3, dtype=q.dtype)
    exps = []
    for i in range(chain.n_joints):
        qi, s, c = q[..., i, None], s_all[..., i, None], c_all[..., i, None]
        omc, qs = 1.0 - c, qi - s
        rot = eye + s[..., None] * w[i] + omc[..., None] * w2[i]
        exps.append((rot, qi * v[i] + omc * wv[i] + qs * w2v[i]))
    return exps


def _home(chain: PoEChain) -> tuple[Array, Array]:
    return chain.home[:3, :3], chain.home[:3, 3]


def _fk_rp(chain: PoEChain, q: Array) -> tuple[Array, Array]:
    """End-effector ``(R, p)`` of a PoE chain (either frame)."""
    exps = _joint_exps(chain, q)
    if chain.frame == "space":
        acc = exps[-1]
        for e in reversed(exps[:-1]):
            acc = _compose(e, acc)
        return _compose(acc, _home(chain))
    acc = _home(chain)
    for e in exps:
        acc = _compose(acc, e)
    return acc


def _fk_and_jacobian(chain: PoEChain, q: Array, which: str) -> tuple[Array, Array, Array]:
    """``(R, p, J)`` with ``J`` the ``which`` ('space' or 'body') Jacobian, (..., 6, n)."""
    n = chain.n_joints
    exps = _joint_exps(chain, q)
    batch = q.shape[:-1]
    screws = chain.screws
    if chain.frame == "space":
        # Prefix products P_{i-1} = E_1 ... E_{i-1}; column i = Ad(P_{i-1}) S_i.
        columns = [jnp.broadcast_to(screws[0], (*batch, 6))]
        prefix = exps[0]
        for i in range(1, n):
            columns.append(_apply_adjoint(prefix[0], prefix[1], screws[i][:, None])[..., 0])
            prefix = _compose(prefix, exps[i])
        rot, p = _compose(prefix, _home(chain))
        jac = jnp.stack(columns, axis=-1)
        if which == "body":
            jac = _apply_adjoint_inv(rot, p, jac)
        return rot, p, jac
    # Body frame: suffix products Q_{i+1} = E_{i+1} ... E_n; column i = Ad(Q_{i+1}^-1) B_i.
    columns = [jnp.broadcast_to(screws[n - 1], (*batch, 6))]
    suffix = exps[n - 1]
    for i in range(n - 2, -1, -1):
        columns.append(_apply_adjoint_inv(suffix[0], suffix[1], screws[i][:, None])[..., 0])
        suffix = _compose(exps[i], suffix)
    rot, p = _compose(_home(chain), suffix)
    jac = jnp.stack(columns[::-1], axis=-1)
    if which == "space":
        jac = _apply_adjoint(rot, p, jac)
    return rot, p, jac


def _apply_adjoint(rot: Array, p: Array, twists: Array) -> Array:
    """``Ad([R, p]) V`` for twists ``V`` (..., 6, k): ``(R w, p x R w + R v)``."""
    rw = jnp.einsum("...ij,...jk->...ik", rot, twists[..., :3, :])
    rv = jnp.einsum("...ij,...jk->...ik", rot, twists[..., 3:, :])
    cross = jnp.cross(p[..., :, None], rw, axis=-2)
    return jnp.concatenate([rw, cross + rv], axis=-2)


def _apply_adjoint_inv(rot: Array, p: Array, twists: Array) -> Array:
    """``Ad([R, p]^-1) V`` for twists ``V`` (..., 6, k): ``(R^T w, R^T (v - p x w))``."""
    w, v = twists[..., :3, :], twists[..., 3:, :]
    shifted = v - jnp.cross(p[..., :, None], w, axis=-2)
    rw = jnp.einsum("...ji,...jk->...ik", rot, w)
    rv = jnp.einsum("...ji,...jk->...ik", rot, shifted)
    return jnp.concatenate([rw, rv], axis=-2)


def _chain_fk_impl(chain: PoEChain, q: Array) -> Array:
    if not isinstance(chain, PoEChain):  # a JointChain: its own coupling of q to the screws
        from .chain import fk_rp

        return lie.from_rotation_translation(*fk_rp(chain, q))
    return lie.from_rotation_translation(*_fk_rp(chain, q))


def _jacobian_impl(chain: PoEChain, q: Array, which: str) -> Array:
    if not isinstance(chain, PoEChain):
        from .chain import fk_and_jacobian

        return fk_and_jacobian(chain, q, which)[2]
    return _fk_and_jacobian(chain, q, which)[2]


# A chain has no batch axes: only the joints are padded.
_chain_fk_jit = _batching.PaddedJit(jax.jit(_chain_fk_impl), {"q": 1})
# Large batches split across host threads (memory-bound: 36-42 outputs per element).
_jacobian_jit = _batching.PaddedJit(
    _batching.PartsJit(_jacobian_impl, static_argnames=("which",), batched_argnames=("q",)),
    {"q": 1},
)


# ----------------------------------------------------------------------------------------------
# Conversions.


def _poe_from_dh_impl(table: _dh.DHTable) -> PoEChain:
    zeros = jnp.zeros((table.n_joints,), table.dtype)
    frames = _dh._fk_dh_impl(table, zeros, all_frames=True)  # (n, 4, 4): frames 1..n
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
    return PoEChain(jnp.stack(rows), frames[-1], "space")


_poe_from_dh_jit = jax.jit(_poe_from_dh_impl)


def poe_from_dh(table: _dh.DHTable) -> PoEChain:
    """The space-frame PoE chain with the same ``T(q)`` as a DH table (same ``q``).

    Joint ``i`` moves about (revolute) or along (prismatic) the ``z`` axis of DH frame
    ``i - 1`` at ``q = 0``: ``S_i = (z, -z x o)`` or ``(0, z)`` with ``z``, ``o`` that frame's
    axis and origin in base coordinates; ``M = fk_dh(table, 0)``.
    """
    if not isinstance(table, _dh.DHTable):
        raise ValueError(f"table: expected a DHTable, got {type(table).__name__}")
    return _poe_from_dh_jit(table)


def _change_frame_impl(chain: PoEChain, frame: str) -> PoEChain:
    rot, p = chain.home[:3, :3], chain.home[:3, 3]
    twists = chain.screws.T  # (6, n)
    if frame == "body":
        new = _apply_adjoint_inv(rot, p, twists)
    else:
        new = _apply_adjoint(rot, p, twists)
    return PoEChain(new.T, chain.home, frame)


_change_frame_jit = jax.jit(_change_frame_impl, static_argnames=("frame",))


def change_frame(chain: PoEChain, frame: str) -> PoEChain:
    """The same chain with its screws in the other frame: ``B_i = Ad(M^-1) S_i`` and back."""
    frame = _validate.choice(frame, "frame", FRAMES)
    if not isinstance(chain, PoEChain):
        raise ValueError(f"chain: expected a PoEChain, got {type(chain).__name__}")
    if frame == chain.frame:
        return chain
    return _change_frame_jit(chain, frame)


def as_poe(chain: PoEChain | _dh.DHTable, name: str = "chain") -> PoEChain:
    """Accept a ``PoEChain`` or a ``DHTable`` (converted with ``poe_from_dh``)."""
    if isinstance(chain, PoEChain):
        return chain
    if isinstance(chain, _dh.DHTable):
        return _poe_from_dh_jit(chain)
    raise ValueError(f"{name}: expected a PoEChain or a DHTable, got {type(chain).__name__}")


def _prepare(chain: PoEChain | _dh.DHTable, q: ArrayLike) -> tuple[PoEChain, Array]:
    from .chain import JointChain

    if not isinstance(chain, JointChain):
        chain = as_poe(chain)
    q = _dh.check_q(q, chain.n_joints, chain.dtype)
    return _validate.cast_leaves(chain, q.dtype), q


# ----------------------------------------------------------------------------------------------
# Public API.


def chain_fk(chain: PoEChain | _dh.DHTable, q: ArrayLike) -> Array:
    """Forward kinematics of a ``PoEChain`` (or ``DHTable``, ``JointChain``):
    ``(..., n) -> (..., 4, 4)``."""
    if isinstance(chain, _dh.DHTable):
        return _dh.fk_dh(chain, q)
    chain, q = _prepare(chain, q)
    return _chain_fk_jit(chain, q, batch=q.shape[:-1])


def fk_poe(screws: ArrayLike, home: ArrayLike, q: ArrayLike, frame: str = "space") -> Array:
    """Product-of-exponentials forward kinematics [Pineiro].

    Args:
        screws: unit screw axes ``(n, 6)``, rows ``(omega, v)``, in the ``frame`` given.
        home: end-effector transform at ``q = 0``, ``(4, 4)``.
        q: joint values ``(..., n)``.
        frame: ``'space'`` (``T = exp(S_1 q_1)...exp(S_n q_n) M``) or ``'body'``
            (``T = M exp(B_1 q_1)...exp(B_n q_n)``).

    Returns:
        ``(..., 4, 4)`` transforms, dtype the promotion of the inputs.

    Raises:
        ValueError: malformed screws or home (see ``PoEChain.create``), bad ``frame`` or ``q``.
    """
    return chain_fk(PoEChain.create(screws, home, frame), q)


def space_jacobian(chain: PoEChain | _dh.DHTable, q: ArrayLike) -> Array:
    """Space Jacobian ``J_s`` (..., 6, n): ``V_s = J_s q_dot`` with ``[V_s] = T_dot T^-1``
    (``chain`` a ``PoEChain``, ``DHTable`` or ``JointChain``; columns per coordinate of ``q``)."""
    chain, q = _prepare(chain, q)
    return _jacobian_jit(chain, q, "space", batch=q.shape[:-1])


def body_jacobian(chain: PoEChain | _dh.DHTable, q: ArrayLike) -> Array:
    """Body Jacobian ``J_b`` (..., 6, n): ``V_b = J_b q_dot`` with ``[V_b] = T^-1 T_dot``
    (``chain`` as for ``space_jacobian``)."""
    chain, q = _prepare(chain, q)
    return _jacobian_jit(chain, q, "body", batch=q.shape[:-1])


def _fk_chain_core(chain: PoEChain | _dh.DHTable, q: Jet, rates: bool) -> FKResult:
    def pose(joints):
        if isinstance(chain, _dh.DHTable):
            return _dh._fk_dh_impl(chain, joints, False)
        return _chain_fk_impl(chain, joints)

    return forward_result(pose, q, rates, 2)


def fk_chain(chain: PoEChain | _dh.DHTable, q: Jet | ArrayLike) -> FKResult:
    """Forward kinematics of a chain as the robot protocol has it: ``jaxkin.fk(chain, q)``.

    Args:
        chain: a ``PoEChain``, ``DHTable`` or ``JointChain``.
        q: joint coordinates ``(..., n)``: a Jet (the pose's rates by ``jaxkin.lift``) or an
            array (at rest).

    Returns:
        ``FKResult``: ``x`` (Jet of 4x4 transforms ``(..., 4, 4)`` with their time
        derivatives) and ``status`` (``INVALID_INPUT`` for NaN/inf in ``q``: ``x`` is then the
        home pose, else ``OK``).
    """
    if not isinstance(chain, Robot) or chain.target is not POSE:
        raise ValueError(f"chain: expected a PoEChain or a DHTable, got {type(chain).__name__}")
    return fk(chain, q)
