"""Fixed-point (bit-width) accuracy study of the anthropomorphic arm's inverse kinematics.

[Lopez-Villagomez] evaluates its IK "in fixed point": inputs and every intermediate value are
truncated to ``n`` fractional bits (``n = 1 .. 40``) and the RMS errors of the joint angles and
of the followed path are plotted against ``n``; it concludes that 10 bits suffice. This module
emulates that arithmetic in floating point with ``Q_n(x) = floor(x 2^n) / 2^n``
(``rounding="floor"``, the paper's truncation) or ``round(x 2^n) / 2^n`` (``"nearest"``),
applied to the inputs and after every elementary operation of [Lopez-Villagomez, eqs. 10-14]
(with the corrections of ``docs/errata.md``: two-argument ``atan2``, the second shoulder
branch, the missing ``theta2``)::

    theta1 = Q(atan2(py, px)) [+ pi];  A = Q(px c1) + Q(py s1);  B = pz - l1   eqs. 10, 12, 13
    C = Q((Q(l3^2) - Q(l2^2) - Q(A^2) - Q(B^2)) / (-2 l2));  rho = Q(sqrt(Q(A^2) + Q(B^2)))
    theta2 = Q(Q(atan2(B, A)) +- Q(acos(clip(Q(C / rho), -1, 1))))                 eq. 14
    theta3 = Q(atan2(Q(B c2) - Q(A s2), Q(A c2) + Q(B s2) - l2))                     eq. 11

Transcendental results are assumed correctly rounded then truncated (a table or CORDIC of
``n`` bits); sums of quantised values are exact. Branch order and names are those of
``jaxkin.serial.Anthropomorphic``. The ``acos`` argument saturates and a division by a value
quantised to 0 returns 0, so every width gives finite angles. Float64 is required for a
faithful emulation (40 fractional bits are exact for ``|x| < 2^12``); with ``bits=None`` no
quantisation is applied and the result equals ``jaxkin.serial.ik_all_branches``. Gradients through
``quantize`` are zero almost everywhere.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable

import jax
import jax.numpy as jnp
import numpy as np
from jax import Array
from jax.typing import ArrayLike

from . import _validate
from ._execute import Kernel, Policy
from ._numerics import safe_div, safe_sqrt
from .serial.arms import Anthropomorphic, fk

__all__ = [
    "ROUNDINGS",
    "AccuracyStudy",
    "accuracy_study",
    "anthropomorphic_ik",
    "quantize",
    "smallest_width",
]

ROUNDINGS = ("floor", "nearest")
_MAX_BITS = 40
_PI = float(np.pi)


def _quantizer(bits: Array | None, rounding: str) -> Callable[[Array], Array]:
    if bits is None:
        return lambda x: x
    # Exact powers of two through ldexp (jnp.exp2 is not exact for integer arguments).
    n = bits.astype(jnp.int32)
    op = jnp.floor if rounding == "floor" else jnp.round

    def qz(x: Array) -> Array:
        # Intermediates carry the batch axes first and branch axes after them.
        k = n.reshape(n.shape + (1,) * (x.ndim - n.ndim))
        return jnp.ldexp(op(jnp.ldexp(x, k)), -k)

    return qz


def _check_bits(bits: ArrayLike) -> Array:
    arr = jnp.asarray(bits)
    if not (jnp.issubdtype(arr.dtype, jnp.integer) or jnp.issubdtype(arr.dtype, jnp.floating)):
        raise ValueError(f"bits: expected integers in [1, {_MAX_BITS}], got dtype {arr.dtype}")
    if _validate.is_concrete(bits):
        values = np.asarray(arr)
        if (
            not np.all(np.isfinite(values))
            or np.any(values != np.round(values))
            or np.any(values < 1)
            or np.any(values > _MAX_BITS)
        ):
            raise ValueError(f"bits: expected integers in [1, {_MAX_BITS}], got {values}")
    return arr


def quantize(x: ArrayLike, bits: ArrayLike, rounding: str = "floor") -> Array:
    """Quantise ``x`` to ``bits`` fractional bits: ``floor(x 2^bits) / 2^bits`` (or round).

    Args:
        x: values, any shape (floating).
        bits: integer bit widths in ``[1, 40]``, broadcastable against ``x``.
        rounding: ``"floor"`` (truncation toward -inf, [Lopez-Villagomez]) or ``"nearest"``.

    Returns:
        The quantised values, broadcast shape, dtype of ``x``.
    """
    rounding = _validate.choice(rounding, "rounding", ROUNDINGS)
    x = _validate.as_float(x)
    bits = _check_bits(bits).astype(jnp.int32)
    x, bits = jnp.broadcast_arrays(x, bits)
    return _quantizer(bits, rounding)(x)


def _paper_ik(lengths: Array, p: Array, qz: Callable[[Array], Array]) -> Array:
    """[Lopez-Villagomez, eqs. 10-14], every intermediate through ``qz``: ``(..., 4, 3)``."""
    batch = p.shape[:-1]
    l1, l2, l3 = (qz(jnp.broadcast_to(lengths[i], batch)) for i in range(3))
    px, py, pz = qz(p[..., 0]), qz(p[..., 1]), qz(p[..., 2])
    pi_q = qz(jnp.full(batch, _PI, p.dtype))
    theta1 = qz(jnp.arctan2(py, px))  # eq. 10, two-argument (corrected, docs/errata.md)
    back = theta1 + pi_q
    back = jnp.where(back > pi_q, back - 2.0 * pi_q, back)
    theta1 = jnp.stack([theta1, back], axis=-1)  # (..., 2) shoulders
    c1, s1 = qz(jnp.cos(theta1)), qz(jnp.sin(theta1))
    ex = lambda x: x[..., None]  # noqa: E731 - broadcast over the shoulder axis
    a = qz(ex(px) * c1) + qz(ex(py) * s1)  # eq. 12
    b = ex(pz - l1)  # eq. 13
    a2, b2 = qz(a * a), qz(b * b)
    c = qz(safe_div(ex(qz(l3 * l3) - qz(l2 * l2)) - a2 - b2, ex(-2.0 * l2)))  # eq. 14
    rho = qz(safe_sqrt(a2 + b2))
    ratio = jnp.clip(qz(safe_div(c, rho)), -1.0, 1.0)
    gamma = qz(jnp.arctan2(b, a))
    delta = qz(jnp.arccos(ratio))
    up = jnp.asarray([1.0, -1.0], p.dtype)  # +acos is "up" for the front shoulder
    theta2 = ex(gamma) + jnp.stack([up, -up], axis=0) * ex(delta)  # (..., 2, 2)
    theta2 = qz(theta2 - 2.0 * _PI * jnp.round(theta2 / (2.0 * _PI)))
    c2, s2 = qz(jnp.cos(theta2)), qz(jnp.sin(theta2))
    a_, b_ = ex(a), ex(b)
    theta3 = qz(
        jnp.arctan2(qz(b_ * c2) - qz(a_ * s2), qz(a_ * c2) + qz(b_ * s2) - l2[..., None, None])
    )  # eq. 11, two-argument
    theta1 = jnp.broadcast_to(ex(theta1), theta2.shape)
    q = jnp.stack([theta1, theta2, theta3], axis=-1)
    return q.reshape(*q.shape[:-3], 4, 3)


def _ik_impl(lengths: Array, p: Array, bits: Array | None, rounding: str) -> Array:
    return _paper_ik(lengths, p, _quantizer(bits, rounding))


_ik_jit = Kernel(
    _ik_impl, static=("rounding",), batched={"p": 1, "bits": 0}, policy=Policy(pad=True)
)


def _robot_lengths(robot: Anthropomorphic, dtype) -> Array:
    if not isinstance(robot, Anthropomorphic):
        raise ValueError(f"robot: expected jaxkin.serial.Anthropomorphic, got {type(robot)}")
    return jnp.stack([jnp.asarray(x, dtype) for x in (robot.l1, robot.l2, robot.l3)])


def anthropomorphic_ik(
    robot: Anthropomorphic,
    target: ArrayLike,
    bits: ArrayLike | None = None,
    rounding: str = "floor",
) -> Array:
    """The anthropomorphic arm's IK in emulated fixed point (module docstring).

    Args:
        robot: ``jaxkin.serial.Anthropomorphic(l1, l2, l3)``.
        target: wrist positions ``(..., 3)``.
        bits: fractional bits, integers in ``[1, 40]`` broadcastable against the target's
            batch shape ``(...)`` (e.g. ``bits[:, None]`` with targets ``(n, 3)`` sweeps every
            width over every target); ``None`` for no quantisation.
        rounding: ``"floor"`` (default, truncation toward -inf) or ``"nearest"``.

    Returns:
        ``q`` ``(..., 4, 3)``: the four branches in ``Anthropomorphic.branches`` order. No
        reachability status: out-of-reach targets give the saturated (aligned) solution.

    Raises:
        ValueError: wrong robot type, target shape, bit widths or rounding.
    """
    rounding = _validate.choice(rounding, "rounding", ROUNDINGS)
    target = _validate.as_float(target)
    if target.ndim == 0 or target.shape[-1] != 3:
        raise ValueError(f"target: expected shape (..., 3), got {tuple(target.shape)}")
    lengths = _robot_lengths(robot, target.dtype)
    if bits is None:
        return _ik_jit(lengths, target, None, rounding, batch=target.shape[:-1])
    bits = _check_bits(bits).astype(jnp.int32)
    batch = _validate.batch_shape({"target": target.shape[:-1], "bits": bits.shape})
    target = jnp.broadcast_to(target, (*batch, 3))
    return _ik_jit(lengths, target, jnp.broadcast_to(bits, batch), rounding, batch=batch)


@jax.tree_util.register_dataclass
@dataclasses.dataclass(frozen=True)
class AccuracyStudy:
    """Errors of the fixed-point IK along a path, per bit width.

    Attributes:
        bits: bit widths, ``(k,)``.
        q: quantised joint angles of the chosen branch, ``(k, n, 3)``.
        q_ref: unquantised (float) joint angles, ``(n, 3)``.
        joint_rms: RMS joint-angle error per joint, radians, ``(k, 3)``.
        joint_rms_all: RMS over the three joints, radians, ``(k,)``.
        cartesian_rms: RMS distance between ``fk(q)`` (exact) and the path, ``(k,)``.
        cartesian_max: largest such distance, ``(k,)``.
    """

    bits: Array
    q: Array
    q_ref: Array
    joint_rms: Array
    joint_rms_all: Array
    cartesian_rms: Array
    cartesian_max: Array


def accuracy_study(
    robot: Anthropomorphic,
    path: ArrayLike,
    bits: ArrayLike,
    branch: str = "front_up",
    rounding: str = "floor",
) -> AccuracyStudy:
    """[Lopez-Villagomez]'s experiment: RMS joint and Cartesian errors of the IK per width.

    The reference is the unquantised solution of the same branch; joint errors are wrapped to
    ``[-pi, pi]``; the Cartesian error is the distance between the exact forward kinematics
    (``jaxkin.serial.fk``, float) of the quantised angles and the path point, i.e. where the
    real robot goes when commanded the fixed-point angles.

    Args:
        robot: the arm.
        path: wrist positions ``(n, 3)``, all reachable.
        bits: bit widths ``(k,)``, integers in ``[1, 40]``.
        branch: one of ``Anthropomorphic.branches``.
        rounding: ``"floor"`` or ``"nearest"``.
    """
    branch_index = Anthropomorphic.branches.index(
        _validate.choice(branch, "branch", Anthropomorphic.branches)
    )
    path = jnp.asarray(path)
    if path.ndim != 2 or path.shape[-1] != 3:
        raise ValueError(f"path: expected shape (n, 3), got {tuple(path.shape)}")
    bits = jnp.asarray(bits)
    if bits.ndim != 1:
        raise ValueError(f"bits: expected shape (k,), got {tuple(bits.shape)}")
    q = anthropomorphic_ik(robot, path, bits[:, None], rounding)[..., branch_index, :]
    q_ref = anthropomorphic_ik(robot, path)[..., branch_index, :]
    dq = q - q_ref
    dq = dq - 2.0 * _PI * jnp.round(dq / (2.0 * _PI))
    joint_rms = jnp.sqrt(jnp.mean(dq * dq, axis=1))
    reached = fk(robot, q).x.p
    dist = jnp.linalg.norm(reached - path, axis=-1)
    return AccuracyStudy(
        bits=bits,
        q=q,
        q_ref=q_ref,
        joint_rms=joint_rms,
        joint_rms_all=jnp.sqrt(jnp.mean(joint_rms * joint_rms, axis=-1)),
        cartesian_rms=jnp.sqrt(jnp.mean(dist * dist, axis=-1)),
        cartesian_max=jnp.max(dist, axis=-1),
    )


def smallest_width(bits: ArrayLike, errors: ArrayLike, tolerance: float) -> int | None:
    """Host-side: the smallest width from which on every listed width has ``error <= tol``.

    ``bits`` ``(k,)`` ascending; returns ``None`` if even the widest width fails.
    """
    bits = np.asarray(bits)
    ok = np.asarray(errors) <= tolerance
    if bits.ndim != 1 or bits.shape != ok.shape:
        raise ValueError(
            f"bits and errors: expected equal 1-D shapes, got {bits.shape}, {ok.shape}"
        )
    if not ok[-1]:
        return None
    failing = np.nonzero(~ok)[0]
    first = 0 if failing.size == 0 else failing[-1] + 1
    return int(bits[first])
