"""Kernels of the chain robot: product-of-exponentials forward kinematics and Jacobians [Pineiro].

A chain holds the unit screws ``S_i`` of its ``m`` moving joints in the base frame (rows
``(omega, v)``: for a revolute joint ``omega`` is the unit axis and ``v = -omega x r`` for a
point ``r`` on it; for a prismatic joint ``omega = 0`` and ``v`` the unit direction) and the
home pose ``M`` of the tip at ``theta = 0``::

    T(theta) = exp([S_1] theta_1) ... exp([S_m] theta_m) M,     theta_i = c_i q_{k(i)} + b_i

Because every screw is a unit screw, ``exp([S] theta)`` needs no norm or small-angle branch::

    R = I + sin(theta) W + (1 - cos theta) W^2,
    p = (theta I + (1 - cos theta) W + (theta - sin theta) W^2) v,      W = hat(omega)

The space Jacobian's columns are ``J_s[:, i] = Ad(exp([S_1] theta_1) ... exp([S_{i-1}]
theta_{i-1})) S_i`` and the body Jacobian is ``J_b = Ad(T^-1) J_s`` (columns are twists, rows
``(omega, v)``: ``V_s = J_s theta_dot`` with ``[V_s] = T_dot T^-1``, ``V_b = J_b theta_dot``
with ``[V_b] = T^-1 T_dot``). With respect to the coordinates ``q`` the columns of the joints
that follow one coordinate are summed::

    J(q)[:, j] = sum_{i : k(i) = j} c_i J_theta(theta)[:, i]

Every function here is pure and traceable; it reads the chain's numeric fields (``screws``,
``home``, ``multiplier``, ``offset``) and its static ``follows``, and never its labels. FK has no
failure cases: NaN or inf in ``q`` reaches only the affected batch elements.
"""

from __future__ import annotations

from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from jax import Array

from .. import lie
from .._trig import sincos

__all__ = [
    "angles",
    "apply_adjoint",
    "apply_adjoint_inv",
    "couple",
    "fk_and_jacobian",
    "fk_rp",
    "follow_matrix",
    "joint_prefix_poses",
    "joint_prefix_frames",
    "pose",
    "screws_fk_and_jacobian",
    "screws_fk_rp",
]


# ------------------------------------------------------------------------- coordinates


def angles(chain: Any, q: Array) -> Array:
    """``theta_i = c_i q_{k(i)} + b_i``: ``(..., n) -> (..., m)``."""
    if chain.follows != tuple(range(len(chain.joint_kinds))):
        q = q[..., np.asarray(chain.follows)]
    return q * chain.multiplier + chain.offset


def follow_matrix(chain: Any) -> np.ndarray:
    """``(m, n)``: 1 where path joint ``i`` follows coordinate ``k(i)``, else 0."""
    m, n = len(chain.follows), len(chain.joint_kinds)
    onto = np.zeros((m, n))
    onto[np.arange(m), np.asarray(chain.follows)] = 1.0
    return onto


def couple(chain: Any, jac: Array) -> Array:
    """Jacobian columns of the path joints ``(..., 6, m)`` -> of the coordinates ``(..., 6, n)``
    (module docstring)."""
    if chain.follows == tuple(range(len(chain.joint_kinds))):
        return jac * chain.multiplier
    onto = jnp.asarray(follow_matrix(chain), jac.dtype)
    return jnp.einsum("...im,mn->...in", jac * chain.multiplier, onto)


# ------------------------------------------------------------------------- the chain


def fk_rp(chain: Any, q: Array, looped: bool = False) -> tuple[Array, Array]:
    """Tip ``(R (..., 3, 3), p (..., 3))`` at coordinates ``q`` ``(..., n)`` (``looped``: a
    loop over the joints, ``_over_joints``)."""
    return screws_fk_rp(chain.screws, chain.home, angles(chain, q), looped)


def pose(chain: Any, q: Array, looped: bool = False) -> Array:
    """Tip pose ``(..., 4, 4)`` at coordinates ``q`` ``(..., n)`` (``looped``: as ``fk_rp``)."""
    return lie.from_rotation_translation(*fk_rp(chain, q, looped))


def fk_and_jacobian(
    chain: Any, q: Array, which: str, looped: bool = False
) -> tuple[Array, Array, Array]:
    """``(R, p, J)`` with ``J`` the ``which`` (``"space"``/``"body"``) Jacobian with respect to
    the coordinates ``q``, ``(..., 6, n)`` (``looped``: a loop over the joints,
    ``_over_joints``)."""
    rot, p, jac = screws_fk_and_jacobian(chain.screws, chain.home, angles(chain, q), which, looped)
    return rot, p, couple(chain, jac)


# ------------------------------------------------------------------------- screws and angles
# Small batched matrix products (XLA dot ops) materialise every intermediate pose; an
# elementwise structure-of-arrays version of the same products was many times slower on CPU
# for 6 joints (XLA fused the whole product tree into a few loops and recomputed shared
# sub-expressions per output).


def _mat_vec(rot: Array, x: Array) -> Array:
    return jnp.einsum("...ij,...j->...i", rot, x)


def _compose(a: tuple[Array, Array], b: tuple[Array, Array]) -> tuple[Array, Array]:
    rot_a, p_a = a
    rot_b, p_b = b
    return jnp.einsum("...ij,...jk->...ik", rot_a, rot_b), _mat_vec(rot_a, p_b) + p_a


def _screw_terms(screws: Array) -> tuple[Array, ...]:
    """Per unit screw of ``screws`` ``(m, 6)``: ``W = hat(omega)``, ``W^2``, ``v``, ``W v``
    and ``W^2 v`` (``(m, 3, 3)`` twice, ``(m, 3)`` three times), the unbatched factors of
    ``_joint_exp``, computed once for every joint (outside the loop over the joints)."""
    w = lie.hat(screws[:, :3])
    w2 = w @ w
    v = screws[:, 3:]
    return w, w2, v, _mat_vec(w, v), _mat_vec(w2, v)


def _joint_exp(terms: tuple[Array, ...], theta: Array) -> tuple[Array, Array]:
    """``exp([S] theta)`` of one unit screw at angles ``theta`` ``(...)`` as ``(R, p)``
    (module docstring), from its ``_screw_terms`` (unbatched): the batched work is one
    ``sin``, one ``cos`` and multiply-adds."""
    w, w2, v, wv, w2v = terms
    s, c = sincos(theta)
    q, s, c = theta[..., None], s[..., None], c[..., None]
    omc = 1.0 - c
    rot = jnp.eye(3, dtype=theta.dtype) + s[..., None] * w + omc[..., None] * w2
    return rot, q * v + omc * wv + (q - s) * w2v


def joint_prefix_poses(chain: Any, q: Array) -> Array:
    """``exp([S_1] theta_1) ... exp([S_k] theta_k)`` for ``k = 0 ... m`` (the identity first):
    the motion of every link that the first ``k`` path joints carry, ``(..., m + 1, 4, 4)``
    (a link's pose is this times its pose at ``theta = 0``, in the base frame)."""
    theta = angles(chain, q)
    eye = jnp.broadcast_to(jnp.eye(3, dtype=theta.dtype), (*theta.shape[:-1], 3, 3))
    acc = (eye, jnp.zeros((*theta.shape[:-1], 3), theta.dtype))
    poses = [lie.from_rotation_translation(*acc)]
    terms = _screw_terms(chain.screws)
    for i in range(theta.shape[-1]):
        e = _joint_exp(tuple(t[i] for t in terms), theta[..., i])
        acc = _compose(acc, e)
        poses.append(lie.from_rotation_translation(*acc))
    return jnp.stack(poses, axis=-3)


def _home(home: Array) -> tuple[Array, Array]:
    return home[:3, :3], home[:3, 3]


def _identity(theta: Array) -> tuple[Array, Array]:
    batch = theta.shape[:-1]
    eye = jnp.broadcast_to(jnp.eye(3, dtype=theta.dtype), (*batch, 3, 3))
    return eye, jnp.zeros((*batch, 3), theta.dtype)


def _over_joints(body, carry, screws: Array, theta: Array, looped: bool):
    """``body(carry, (S_i, terms_i, theta_i)) -> (carry, out_i)`` over the joints in order
    (``terms_i`` the screw's ``_screw_terms``): a
    ``lax.scan`` (one copy of the body in the compiled program: the chain IK's search, whose
    program holds several FK and Jacobian evaluations; and a single configuration's FK, whose
    program XLA then counts as cheap and runs on the calling thread) or unrolled (``looped``
    False: a batch's FK). The same operations in the same order either way."""
    joints = (screws, _screw_terms(screws), jnp.moveaxis(theta, -1, 0))
    return jax.lax.scan(body, carry, joints, unroll=1 if looped else True)


def screws_fk_rp(
    screws: Array, home: Array, theta: Array, looped: bool = False
) -> tuple[Array, Array]:
    """Tip ``(R, p)`` of base-frame screws ``(m, 6)`` and ``home`` at joint angles ``theta``
    ``(..., m)``: ``E_1 (E_2 (... (E_m M)))``, one joint at a time (``looped``: as
    ``_over_joints``)."""

    def body(acc, joint):
        _, terms, theta_i = joint
        return _compose(acc, _joint_exp(terms, theta_i)), None

    acc, _ = _over_joints(body, _identity(theta), screws, theta, looped)
    return _compose(acc, _home(home))


def screws_fk_and_jacobian(
    screws: Array, home: Array, theta: Array, which: str, looped: bool = False
) -> tuple[Array, Array, Array]:
    """``(R, p, J)`` of base-frame screws at ``theta`` ``(..., m)``, ``J`` the ``which``
    (``"space"``/``"body"``) Jacobian with respect to ``theta``, ``(..., 6, m)``
    (``looped``: as ``_over_joints``)."""

    # Prefix products P_{i-1} = E_1 ... E_{i-1}; column i = Ad(P_{i-1}) S_i.
    def body(prefix, joint):
        screw, terms, theta_i = joint
        column = apply_adjoint(prefix[0], prefix[1], screw[:, None])[..., 0]
        return _compose(prefix, _joint_exp(terms, theta_i)), column

    prefix, columns = _over_joints(body, _identity(theta), screws, theta, looped)
    rot, p = _compose(prefix, _home(home))
    jac = jnp.moveaxis(columns, 0, -1)
    if which == "body":
        jac = apply_adjoint_inv(rot, p, jac)
    return rot, p, jac


def apply_adjoint(rot: Array, p: Array, twists: Array) -> Array:
    """``Ad([R, p]) V`` for twists ``V`` (..., 6, k): ``(R w, p x R w + R v)``."""
    rw = jnp.einsum("...ij,...jk->...ik", rot, twists[..., :3, :])
    rv = jnp.einsum("...ij,...jk->...ik", rot, twists[..., 3:, :])
    cross = jnp.cross(p[..., :, None], rw, axis=-2)
    return jnp.concatenate([rw, cross + rv], axis=-2)


def apply_adjoint_inv(rot: Array, p: Array, twists: Array) -> Array:
    """``Ad([R, p]^-1) V`` for twists ``V`` (..., 6, k): ``(R^T w, R^T (v - p x w))``."""
    w, v = twists[..., :3, :], twists[..., 3:, :]
    shifted = v - jnp.cross(p[..., :, None], w, axis=-2)
    rw = jnp.einsum("...ji,...jk->...ik", rot, w)
    rv = jnp.einsum("...ji,...jk->...ik", rot, shifted)
    return jnp.concatenate([rw, rv], axis=-2)


# ------------------------------------------------------------------ rows layout


def joint_prefix_frames(chain: Any, q: Array) -> tuple[Array, Array]:
    """``joint_prefix_poses`` in the rows layout of the collision checks: for ``k = 0 ...
    m`` the rotation ``(m + 1, 3, 3, B)`` and translation ``(m + 1, 3, B)`` of
    ``exp([S_1] theta_1) ... exp([S_k] theta_k)`` at configurations ``q`` ``(B, n)``
    (configurations minor). Same closed form as ``_joint_exp`` (module docstring), the
    products written out entry by entry, one joint per step of a ``lax.scan``: the program
    holds one joint's work whatever the chain's length."""
    theta = angles(chain, q).T  # (m, B)
    # every joint's sine and cosine at once: inside a step's fused loop each output entry
    # would evaluate them again
    sines, cosines = sincos(theta)
    w, w2, v, wv, w2v = _screw_terms(chain.screws.astype(q.dtype))
    size = q.shape[0]
    eye = jnp.broadcast_to(jnp.eye(3, dtype=q.dtype)[:, :, None], (3, 3, size))
    zero = jnp.zeros((3, size), q.dtype)

    def step(acc: tuple[Array, Array], joint: tuple[Array, ...]) -> tuple[Any, Any]:
        w, w2, v, wv, w2v, t, s, c = joint
        omc = 1.0 - c
        rot = jnp.eye(3, dtype=t.dtype)[:, :, None] + s * w[:, :, None] + omc * w2[:, :, None]
        pos = t * v[:, None] + omc * wv[:, None] + (t - s) * w2v[:, None]
        a_rot, a_pos = acc
        new = (
            sum(a_rot[:, n, None] * rot[None, n] for n in range(3)),
            sum(a_rot[:, n] * pos[None, n] for n in range(3)) + a_pos,
        )
        return new, new

    _, (rots, poss) = jax.lax.scan(step, (eye, zero), (w, w2, v, wv, w2v, theta, sines, cosines))
    return jnp.concatenate([eye[None], rots]), jnp.concatenate([zero[None], poss])
