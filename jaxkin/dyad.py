"""The planar RRR dyad (Assur group) [Noriega, sec. 2]: position, velocity, acceleration.

Known: points A and B (Jets) and the link lengths ``l_ac`` and ``l_bc``. Unknown: the middle
joint C and the angle ``phi`` of link AC with the +X axis. With ``theta`` the angle of A->B and
``l = |AB|`` [Noriega, eqs. 1, 4-6, 9-10]::

    A = l_ac^2 + l^2 - l_bc^2,   B = 2 l_ac l,   u = A / B = cos(beta)
    phi = theta + mode * beta,   C = A_point + l_ac (cos phi, sin phi)

``cos phi`` and ``sin phi`` are built algebraically from ``(dx, dy) / l``, ``u`` and
``sin(beta) = sqrt(1 - u^2)``: the only transcendental call is one ``atan2`` for the output
``phi``. Rates: ``method="analytic"`` (eqs. 2-10, with the corrections of ``docs/errata.md``)
or ``"autodiff"`` (``jaxkin.lift``); they agree to 1e-10 in float64 (tested).

Angles: ``theta`` in (-pi, pi] (Fig. 2), ``beta`` in [0, pi], ``phi`` the paper's *unwrapped*
sum (mode +1: (-pi, 2 pi), mode -1: (-2 pi, pi]); ``mode = +1`` puts C to the left of A->B.

Statuses, with the length tolerance ``tol = sqrt(eps(dtype)) * (l_ac + l_bc)``:
``INVALID_INPUT`` (NaN/inf in A, B or the lengths), ``SINGULAR_COINCIDENT`` (``l <= tol`` with
``|l_ac - l_bc| <= tol``: C undefined), ``UNREACHABLE`` (``|A/B| > 1`` beyond tol),
``SINGULAR_EXTENDED`` (beta = 0), ``SINGULAR_FOLDED`` (beta = pi), ``OK``. Where not OK the
rates are 0; at a singularity the position is valid; where the dyad cannot be assembled C is
the nearest aligned configuration. ``margin = 1 - (A/B)^2 = sin(beta)^2`` (0 at singularities,
negative where unreachable, -1 for invalid input): a continuous barrier for planners. Float32
accuracy: ``docs/performance.md``.
"""

from __future__ import annotations

import dataclasses
import functools
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
from jax import Array
from jax.typing import ArrayLike

from . import _validate
from ._execute import Kernel, Policy
from ._numerics import all_last, computed_once, rsqrt, singular_rtol
from ._trig import atan2
from .jet import Jet, lift
from .planar import angle_rates, length_rates, link_end_rates
from .result import SolverResult
from .status import STATUS_DTYPE, Status

__all__ = [
    "DyadPosition",
    "DyadResult",
    "METHODS",
    "MODES",
    "position",
    "solve",
]

MODES = (1, -1)
METHODS = ("analytic", "autodiff")


@jax.tree_util.register_dataclass
@dataclasses.dataclass(frozen=True)
class DyadResult(SolverResult):
    """Solution of a batch of RRR dyads.

    Attributes:
        c: Jet of point C, shape ``(..., 2)``.
        phi: Jet of the angle of AC with +X (unwrapped, see module docstring), shape ``(...)``.
        status: ``int8`` codes of ``jaxkin.Status``, shape ``(...)``.
        margin: ``1 - (A/B)^2``, shape ``(...)``: distance from singularity (see module doc).
    """

    c: Jet
    phi: Jet
    status: Array
    margin: Array


@jax.tree_util.register_dataclass
@dataclasses.dataclass(frozen=True)
class DyadPosition(SolverResult):
    """Position-level solution of a batch of RRR dyads (``dyad.position``).

    Attributes:
        c: point C, shape ``(..., 2)``.
        phi: angle of AC with +X (unwrapped, see module docstring), shape ``(...)``.
        status: ``int8`` codes of ``jaxkin.Status``, shape ``(...)``.
        margin: ``1 - (A/B)^2``, shape ``(...)`` (see ``DyadResult``).
    """

    c: Array
    phi: Array
    status: Array
    margin: Array


class _Position(NamedTuple):
    """Position-level quantities shared by the analytic and autodiff paths (batch shape)."""

    c_x: Array
    c_y: Array
    phi: Array  # unwrapped angle of AC
    cos_phi: Array
    sin_phi: Array
    u: Array  # cos(beta) = A/B, clamped to [-1, 1]
    sin_beta: Array
    inv_l: Array  # 1 / |AB|, 0 where A = B (reused by the rates)
    status: Array
    margin: Array


@jax.custom_jvp
def _reciprocal(x: Array) -> Array:
    """``1 / x`` whose derivative rule, ``-(1/x)^2 dx``, reuses the reciprocal (no division)."""
    return 1.0 / x


@_reciprocal.defjvp
def _reciprocal_jvp(primals, tangents):
    (x,), (x_dot,) = primals, tangents
    inv = _reciprocal(x)
    return inv, -(inv * inv) * x_dot


@jax.custom_jvp
def _sqrt(x: Array) -> Array:
    return jnp.sqrt(x)


@_sqrt.defjvp
def _sqrt_jvp(primals, tangents):
    (x,), (x_dot,) = primals, tangents
    # d sqrt(x) = dx / (2 sqrt(x)): one division after the square root, where ``rsqrt`` (as
    # in _numerics.safe_sqrt's rule) costs a second square root on CPU.
    root = _sqrt(x)
    return root, 0.5 * _reciprocal(root) * x_dot


def _safe_sqrt(x: Array) -> Array:
    """``sqrt(max(x, 0))`` with a zero derivative at and below 0 (double-where)."""
    positive = x > 0
    return jnp.where(positive, _sqrt(jnp.where(positive, x, 1.0)), 0.0)


@functools.partial(jax.custom_jvp, nondiff_argnums=(0,))
def _rotated_atan2(mode: int, sin_phi, cos_phi, cos_theta, sin_theta, u, sin_beta) -> Array:
    """``atan2(sin_phi, cos_phi)`` for the unit vector ``(cos_phi, sin_phi)`` that is
    ``(cos_theta, sin_theta)`` turned by ``mode * beta``, ``(u, sin_beta) = (cos, sin)(beta)``.

    Its derivative rule is that of ``phi = theta + mode * beta`` with each angle given by a
    unit vector: ``theta' = cos_theta sin_theta' - sin_theta cos_theta'`` (``cos^2 + sin^2 =
    1``, no division, unlike atan2's generic rule), likewise ``beta'``; the tangents of
    ``cos_phi`` and ``sin_phi`` (products of the others) are not read. Nested jvp
    differentiates the rule again. This keeps the autodiff path's loops short.
    """
    return atan2(sin_phi, cos_phi)


@_rotated_atan2.defjvp
def _rotated_atan2_jvp(mode, primals, tangents):
    sin_phi, cos_phi, cos_theta, sin_theta, u, sin_beta = primals
    _, _, cos_theta_dot, sin_theta_dot, u_dot, sin_beta_dot = tangents
    theta_dot = cos_theta * sin_theta_dot - sin_theta * cos_theta_dot
    beta_dot = u * sin_beta_dot - sin_beta * u_dot
    phi = _rotated_atan2(mode, *primals)
    return phi, theta_dot + mode * beta_dot


@jax.custom_jvp
def _turning_unit(phi: Array, cos_phi: Array, sin_phi: Array) -> tuple[Array, Array]:
    """``(cos_phi, sin_phi)``, given as ``cos phi`` and ``sin phi``, differentiated along phi.

    The derivative rule of the unit vector of angle ``phi``, ``d (cos, sin) = (-sin, cos)
    d phi``, reads phi's tangent only (those of ``cos_phi`` and ``sin_phi``, functions of phi,
    are not needed); nested jvp gives ``-(cos, sin) phi'^2 + (-sin, cos) phi''``.
    """
    return cos_phi, sin_phi


@_turning_unit.defjvp
def _turning_unit_jvp(primals, tangents):
    phi, cos_phi, sin_phi = primals
    phi_dot = tangents[0]
    cos_out, sin_out = _turning_unit(phi, cos_phi, sin_phi)
    return (cos_out, sin_out), (-sin_out * phi_dot, cos_out * phi_dot)


def _position(dx, dy, l_ac, l_bc, valid, mode: int, store_cos_sin: bool = False) -> _Position:
    """Position of C relative to A from the vector ``A->B = (dx, dy)``, in units of the reach
    (``l_ac + l_bc = 1``, see ``_sanitized``); ``valid`` marks elements whose raw input was
    finite.

    ``store_cos_sin``: compute cos/sin of phi once for all readers (``computed_once``), for
    ``solve``'s paths (under the autodiff path's jvp only their values are stored: the rule of
    ``_rotated_atan2`` reads no tangent of them).
    """
    r2 = dx * dx + dy * dy
    # One rsqrt for both |AB| and its reciprocal (double-where at A = B); fewer divisions
    # also keep the autodiff path's nested jvp cheap.
    inv_l = jnp.where(r2 > 0, rsqrt(jnp.where(r2 > 0, r2, 1.0)), 0.0)
    l = r2 * inv_l
    cos_theta = jnp.where(l > 0, dx * inv_l, 1.0)
    sin_theta = dy * inv_l

    reach_out = l_ac + l_bc
    reach_in = jnp.abs(l_ac - l_bc)
    tol = singular_rtol(l.dtype) * reach_out
    coincident = (l <= tol) & (reach_in <= tol)
    unreachable = (l > reach_out + tol) | (l < reach_in - tol)
    on_inner = jnp.abs(l - reach_in) <= tol
    extended = (jnp.abs(l - reach_out) <= tol) | (on_inner & (l_ac > l_bc))
    folded = on_inner & (l_bc > l_ac)

    # Eqs. 1, 4, 5: u = cos(beta) = A / B.
    # l = 0 cannot assemble unless coincident: u_raw = 2 there makes the margin negative.
    u_raw = jnp.where(l > 0, (l_ac * l_ac + r2 - l_bc * l_bc) * inv_l * (0.5 / l_ac), 2.0)
    # lax.clamp, not jnp.clip: clip's derivative rule (max/min) divides twice per element at
    # every order of a nested jvp; clamp's is a select. Same values.
    one = jnp.ones((), u_raw.dtype)
    u_in = jax.lax.clamp(-one, u_raw, one)
    u = jnp.where(extended, 1.0, jnp.where(folded, -1.0, u_in))
    sin_beta = _safe_sqrt(1.0 - u * u)

    # cos/sin of phi = theta + mode * beta, without evaluating theta or beta.
    cos_phi = cos_theta * u - mode * sin_theta * sin_beta
    sin_phi = sin_theta * u + mode * cos_theta * sin_beta
    if store_cos_sin:  # every output of C, phi and the rates reads them
        cos_phi, sin_phi = computed_once(jnp.stack([cos_phi, sin_phi]))

    # atan2 wraps to (-pi, pi]; restore the paper's unwrapped theta + mode * beta.
    phi_wrapped = _rotated_atan2(mode, sin_phi, cos_phi, cos_theta, sin_theta, u, sin_beta)
    if mode == 1:
        theta_on_side = (dy > 0) | ((dy == 0) & (dx < 0))  # theta > 0 (theta = pi for y = 0)
    else:
        theta_on_side = dy < 0  # theta < 0
    wrapped = theta_on_side & (mode * phi_wrapped < 0)
    phi = jnp.where(wrapped, phi_wrapped + mode * 2.0 * jnp.pi, phi_wrapped)

    # Nested where, most basic condition outermost (jnp.select lowers to a slow reduction).
    status = jnp.full(l.shape, Status.OK, STATUS_DTYPE)
    for condition, code in (
        (folded, Status.SINGULAR_FOLDED),
        (extended, Status.SINGULAR_EXTENDED),
        (unreachable, Status.UNREACHABLE),
        (coincident, Status.SINGULAR_COINCIDENT),
        (~valid, Status.INVALID_INPUT),
    ):
        status = jnp.where(condition, jnp.int8(code), status)
    singular = extended | folded | coincident
    margin = jnp.where(singular, 0.0, jnp.clip(1.0 - u_raw * u_raw, -1.0, 1.0))
    margin = jnp.where(valid, margin, -1.0)
    return _Position(
        l_ac * cos_phi,
        l_ac * sin_phi,
        phi,
        cos_phi,
        sin_phi,
        u,
        sin_beta,
        inv_l,
        status,
        margin,
    )


def _analytic_rates(a_rates, rel, l_ac, l_bc, pos: _Position, mode: int):
    """Rates of phi and of C relative to A by the paper's closed forms (eqs. 2-10).

    ``rel``: the vector A->B and its rates ``(x, y, x_dot, y_dot, x_ddot, y_ddot)`` in units of
    the reach. Returns ``(phi_dot, phi_ddot, c_dot_x, c_dot_y, c_ddot_x, c_ddot_y)`` (C's rates
    relative to A's, in units of the reach), 0 where not OK.
    """
    ok = pos.status == Status.OK
    inv_l = pos.inv_l
    x, y, x_dot, y_dot, x_ddot, y_ddot = rel
    # Fig. 2 (corrected, docs/errata.md)
    theta_dot, theta_ddot = angle_rates(x, y, x_dot, y_dot, x_ddot, y_ddot, inv_r2=inv_l * inv_l)
    l, l_dot, l_ddot = length_rates(x, y, x_dot, y_dot, x_ddot, y_ddot, inv_l=inv_l)  # Fig. 3
    # Eq. 4 (A_ddot corrected, docs/errata.md) and eq. 5. B and sin(beta) are replaced
    # by 1 where the status is not OK so no division below can make an inf (double-where).
    a_term = l_ac * l_ac + l * l - l_bc * l_bc
    a_dot = 2.0 * l * l_dot
    a_ddot = 2.0 * (l_dot * l_dot + l * l_ddot)
    inv_b = jnp.where(ok, inv_l * (0.5 / l_ac), 1.0)
    b_term = 2.0 * l_ac * l
    b_dot = 2.0 * l_ac * l_dot
    b_ddot = 2.0 * l_ac * l_ddot
    # The quotient rule inside eqs. 2 and 3: u_dot and u_ddot with u = A/B.
    quotient_num = a_dot * b_term - a_term * b_dot
    u_dot = quotient_num * inv_b * inv_b
    u_ddot = ((a_ddot * b_term - a_term * b_ddot) - 2.0 * quotient_num * b_dot * inv_b) * (
        inv_b * inv_b
    )
    inv_sin_beta = 1.0 / jnp.where(ok, pos.sin_beta, 1.0)
    beta_dot = -u_dot * inv_sin_beta  # eq. 2
    beta_ddot = -(pos.u * u_dot * u_dot * inv_sin_beta * inv_sin_beta + u_ddot) * inv_sin_beta
    phi_dot = jnp.where(ok, theta_dot + mode * beta_dot, 0.0)  # eq. 9 / 10
    phi_ddot = jnp.where(ok, theta_ddot + mode * beta_ddot, 0.0)  # eq. 3 above, then 9 / 10
    # Outputs read by C's four rate outputs: each stored once (in its output buffer, no
    # scratch) instead of recomputed by each reader.
    phi_dot, phi_ddot = computed_once(phi_dot), computed_once(phi_ddot)

    # Eqs. 7-8: C's rates are A's (added by the caller) plus those of the turning link AC;
    # 0 where not OK since phi's rates are (no second test of the status in their loops).
    link = link_end_rates(l_ac, pos.cos_phi, pos.sin_phi, phi_dot, phi_ddot)
    return (phi_dot, phi_ddot, *link)


def _sanitized(a: list[Array], b: list[Array], l_ac: Array, l_bc: Array):
    """Components of A and B (``(x, y)`` of each array in ``a``/``b``), lengths and ``valid``.

    ``a`` and ``b``: ``[p]`` or ``[p, v, a]``, arrays ``(..., 2)``. Casting here rather than in
    the public functions keeps the per-call host overhead small.
    """
    dtype = jnp.result_type(*a, *b, l_ac, l_bc)
    l_ac, l_bc = jnp.asarray(l_ac, dtype), jnp.asarray(l_bc, dtype)
    batch = jnp.broadcast_shapes(a[0].shape[:-1], b[0].shape[:-1], l_ac.shape, l_bc.shape)
    a = [jnp.broadcast_to(x.astype(dtype), (*batch, 2)) for x in a]
    b = [jnp.broadcast_to(x.astype(dtype), (*batch, 2)) for x in b]
    columns = [*a, *b]
    # Scalar lengths stay scalars: every term built from them alone is computed once, not
    # per element (divisions by l_ac included).
    lengths_are_scalars = l_ac.ndim == 0 and l_bc.ndim == 0
    if lengths_are_scalars:
        lengths_finite = jnp.isfinite(l_ac) & jnp.isfinite(l_bc)
    else:
        l_ac = jnp.broadcast_to(l_ac, batch)
        l_bc = jnp.broadcast_to(l_bc, batch)
        columns.append(jnp.stack([l_ac, l_bc], axis=-1))

    # Double-where, step 1: replace non-finite elements, and those beyond twice the reach
    # (where a square could overflow; the dyad cannot assemble there), by a harmless dyad
    # (A = 0, B = (1, 0), unit links) before any math, so neither values nor gradients can
    # become NaN. A batch's mask is a reduction on purpose: XLA keeps it as one loop that the
    # others read, whereas an elementwise mask would be recomputed in each of the kernel's
    # loops (one element's is elementwise: ``all_last``).
    finite_columns = jnp.isfinite(jnp.concatenate(columns, axis=-1))
    reach = l_ac + l_bc  # the comparison below is False for NaN and for an overflowed difference
    near = (
        jnp.abs(b[0] - a[0]) <= 2.0 * reach[..., None]
        if not lengths_are_scalars
        else (jnp.abs(b[0] - a[0]) <= 2.0 * reach)
    )
    valid = all_last(jnp.concatenate([finite_columns, near], axis=-1))
    finite = all_last(finite_columns)  # read by the status output only
    if lengths_are_scalars:
        valid = valid & lengths_finite
        finite = finite & lengths_finite
    a_comps = tuple(jnp.where(valid, arr[..., k], 0.0) for arr in a for k in (0, 1))
    # The vector A->B and its rates from the raw inputs, replaced as a whole: a sanitised A
    # read by both this and C's outputs would be stored by XLA (measured).
    placeholder = (1.0, 0.0, 0.0, 0.0, 0.0, 0.0)
    diffs = tuple(
        jnp.where(valid, bk[..., k] - ak[..., k], placeholder[2 * i + k])
        for i, (ak, bk) in enumerate(zip(a, b, strict=True))
        for k in (0, 1)
    )
    length_valid = lengths_finite if lengths_are_scalars else valid
    l_ac = jnp.where(length_valid, l_ac, 1.0)
    l_bc = jnp.where(length_valid, l_bc, 1.0)
    # Units of the reach: the kernel sees the vector A->B (and its rates) with lengths that
    # sum to 1, whatever the scale of the input, so no square, cube or product of rates over-
    # or underflows; C is scaled back and added to A.
    scale = l_ac + l_bc
    inv_scale = 1.0 / scale
    rel = tuple(d * inv_scale for d in diffs)
    return a_comps, rel, l_ac * inv_scale, l_bc * inv_scale, valid, scale, finite & ~valid


def _far_status(status: Array, far: Array) -> Array:
    """Elements solved as placeholders because they lie beyond twice the reach: UNREACHABLE."""
    return jnp.where(far, jnp.int8(Status.UNREACHABLE), status)


def _position_impl(a: Array, b: Array, l_ac: Array, l_bc: Array, mode: int) -> DyadPosition:
    a_comps, rel, l_ac, l_bc, valid, scale, far = _sanitized([a], [b], l_ac, l_bc)
    dx, dy = rel
    pos = _position(dx, dy, l_ac, l_bc, valid, mode)
    c = jnp.stack([a_comps[0] + pos.c_x * scale, a_comps[1] + pos.c_y * scale], axis=-1)
    return DyadPosition(c, pos.phi, _far_status(pos.status, far), pos.margin)


_DYAD_CORES = {"a": 1, "b": 1, "l_ac": 0, "l_bc": 0}
_position_jit = Kernel(
    _position_impl, static=("mode",), batched=_DYAD_CORES, policy=Policy(pad=True)
)


def _solve_impl(a: Jet, b: Jet, l_ac: Array, l_bc: Array, mode: int, method: str):
    *parts, far = _sanitized([a.p, a.v, a.a], [b.p, b.v, b.a], l_ac, l_bc)
    a_comps, rel, l_ac, l_bc, valid, scale = parts

    if method == "analytic":
        pos = _position(rel[0], rel[1], l_ac, l_bc, valid, mode, store_cos_sin=True)
        phi_dot, phi_ddot, *c_rates = _analytic_rates(a_comps[2:], rel, l_ac, l_bc, pos, mode)
        c_x, c_y, c_v_x, c_v_y, c_a_x, c_a_y = (
            a_k + c_k * scale
            for a_k, c_k in zip(a_comps, (pos.c_x, pos.c_y, *c_rates), strict=True)
        )
        c = Jet(
            jnp.stack([c_x, c_y], axis=-1),
            jnp.stack([c_v_x, c_v_y], axis=-1),
            jnp.stack([c_a_x, c_a_y], axis=-1),
        )
        status = _far_status(pos.status, far)
        return DyadResult(c, Jet(pos.phi, phi_dot, phi_ddot), status, pos.margin)

    # Forward-mode autodiff (two lifts, composed): phi's rates through the position kernel,
    # then C = A + l_ac (cos phi, sin phi) along phi's Jet. Routed through phi so that C's
    # four rate loops read phi's stored rates (as the analytic path does) instead of each
    # re-deriving the kernel's second-order tangents (docs/performance.md).
    def position(dx, dy):
        pos = _position(dx, dy, l_ac, l_bc, valid, mode, store_cos_sin=True)
        return pos.phi, pos.cos_phi, pos.sin_phi, pos.status, pos.margin

    phi, cos_phi, sin_phi, status, margin = lift(position)(Jet(*rel[0::2]), Jet(*rel[1::2]))
    ok = status == Status.OK
    phi = Jet(
        phi.p,
        computed_once(jnp.where(ok, phi.v, 0.0)),
        computed_once(jnp.where(ok, phi.a, 0.0)),
    )
    unit_x, unit_y = lift(lambda angle: _turning_unit(angle, cos_phi.p, sin_phi.p))(phi)
    c = Jet.stack(
        [
            Jet(
                a_comps[k] + l_ac * unit.p * scale,
                a_comps[k + 2] + l_ac * unit.v * scale,
                a_comps[k + 4] + l_ac * unit.a * scale,
            )
            for k, unit in ((0, unit_x), (1, unit_y))
        ]
    )
    return DyadResult(c, phi, _far_status(status, far), margin.p)


_solve_jit = Kernel(
    _solve_impl, static=("mode", "method"), batched=_DYAD_CORES, policy=Policy(pad=True)
)


def _checked_lengths(a_batch: tuple[int, ...], b_batch: tuple[int, ...], l_ac, l_bc):
    """The lengths, checked, and the batch shape (every batch shape must broadcast)."""
    # Lengths may be per-element batch data: NaN/inf there becomes INVALID_INPUT, not an error.
    l_ac = _validate.positive_length(l_ac, "l_ac", allow_nonfinite=True)
    l_bc = _validate.positive_length(l_bc, "l_bc", allow_nonfinite=True)
    batch = _validate.batch_shape(
        {"a": a_batch, "b": b_batch, "l_ac": np.shape(l_ac), "l_bc": np.shape(l_bc)}
    )
    return l_ac, l_bc, batch


def position(
    a: ArrayLike, b: ArrayLike, l_ac: ArrayLike, l_bc: ArrayLike, mode: int = 1
) -> DyadPosition:
    """Position only of a batch of RRR dyads: C, phi, status and margin (no rates).

    The position part of ``solve`` (same kernel, same values, statuses and margin), for
    callers that need no velocities or accelerations, e.g. feasibility sweeps and linkage
    simulation: no rate arrays are built or written, so it runs several times faster than
    ``solve`` (``docs/performance.md``).

    Args:
        a: the known joint A, shape ``(..., 2)``.
        b: the known joint B, shape ``(..., 2)``.
        l_ac, l_bc: link lengths, scalars or arrays broadcastable to the batch shape.
        mode: assembly mode, ``+1`` (eq. 9) or ``-1`` (eq. 10).

    Returns:
        A ``DyadPosition`` (``c`` ``(..., 2)``, ``phi``, ``status``, ``margin``).

    Raises:
        ValueError: as ``solve``.
    """
    mode = _validate.choice(mode, "mode", MODES)
    a = _validate.point(a, "a", coords=2)
    b = _validate.point(b, "b", coords=2)
    l_ac, l_bc, batch = _checked_lengths(a.shape[:-1], b.shape[:-1], l_ac, l_bc)
    return _position_jit(a, b, l_ac, l_bc, mode, batch=batch)


def solve(
    a: Jet | ArrayLike,
    b: Jet | ArrayLike,
    l_ac: ArrayLike,
    l_bc: ArrayLike,
    mode: int = 1,
    method: str = "analytic",
) -> DyadResult:
    """Solve a batch of RRR dyads: position, velocity and acceleration of C and phi.

    Args:
        a: Jet (or plain array, taken at rest) of the known joint A, shape ``(..., 2)``.
        b: Jet (or plain array) of the known joint B, shape ``(..., 2)``.
        l_ac: length of link AC; scalar or array broadcastable to the batch shape.
        l_bc: length of link BC; scalar or array broadcastable to the batch shape.
        mode: assembly mode, ``+1`` for phi = theta + beta (eq. 9), ``-1`` for
            phi = theta - beta (eq. 10).
        method: ``"analytic"`` (the paper's closed forms, eqs. 2-10, errata corrected) or
            ``"autodiff"`` (forward-mode differentiation of the position solution through
            ``jaxkin.lift``: phi's rates through the position kernel, then C's through
            ``C = A + l_ac (cos phi, sin phi)``). Both give the same values.

    Returns:
        A ``DyadResult`` with ``c``, ``phi``, ``status`` and ``margin``; batch shape is the
        broadcast of the inputs' batch shapes. Output dtype follows the inputs.

    Non-finite lengths are data, not errors: a NaN or inf length (a scalar, or one entry of a
    per-element array) marks the elements it applies to ``INVALID_INPUT`` (every element for
    a scalar), with finite placeholders.

    Raises:
        ValueError: a zero or negative length (when concrete), shapes whose last axis is not
            2, batch shapes that do not broadcast, or an unknown ``mode``/``method``.
    """
    mode = _validate.choice(mode, "mode", MODES)
    method = _validate.choice(method, "method", METHODS)
    a = _validate.as_jet(a, "a", coords=2)
    b = _validate.as_jet(b, "b", coords=2)
    l_ac, l_bc, batch = _checked_lengths(a.shape[:-1], b.shape[:-1], l_ac, l_bc)
    return _solve_jit(a, b, l_ac, l_bc, mode, method, batch=batch)
