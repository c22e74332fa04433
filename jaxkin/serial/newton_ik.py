"""Newton-Raphson inverse kinematics of serial chains (seed 003, "Cinemática Inversa Numérica").

Given a desired end-effector pose ``T_sd`` and a seed ``q^0``, iterate (seed 003's algorithm)::

    T_sb = T(q^k)                                     forward kinematics (jaxkin.serial.poe)
    V_b  = log(T_sb^-1 T_sd)                          body twist to the target, (omega, v)
    body frame:   V = V_b,              J = J_b(q^k)
    space frame:  V = Ad(T_sb) V_b,     J = J_s(q^k)
    stop when |omega| <= eps_omega and |v| <= eps_v   (the twist V of the update frame)
    q^{k+1} = q^k + J^+ V                             (pseudo-inverse step)

The two frames take different paths; seed 003's 2R iteration table is the body-frame one
(ERRATA seed 003). ``frame`` defaults to the chain's own frame (``'space'`` for a chain built
from a ``DHTable``).

Step. ``J`` is ``6 x n``. The step solves the (damped) normal equations with an explicit
Cholesky factorisation unrolled over the ``m = min(n, 6)`` rows (no batched LAPACK call)::

    n <= 6:  (J^T J + mu I) dq = J^T V
    n > 6:   dq = J^T y,  (J J^T + mu I) y = V
    mu = damping^2 + sqrt(eps(dtype)) * trace(J^T J)

With ``damping = 0`` this is the pseudo-inverse step ``J^+ V`` with a soft cut-off: along a
singular direction of ``J`` with singular value ``s`` the step is ``s / (s^2 + mu)`` times the
twist component instead of ``1 / s``, equal to the pseudo-inverse to a relative
``mu / s^2``, i.e. to ~1e-7 for well-conditioned arms in float64 (tests compare against
``numpy.linalg.pinv``), while singular values below ``eps^(1/4) |J|`` (exactly or nearly
singular poses) are suppressed as ``pinv`` suppresses zero ones. The ``sqrt(eps)`` floor
(``jaxkin._numerics.singular_rtol``) is what makes the suppression reliable: with a smaller
floor the rounding error of the Gram matrix leaves an O(1) spurious step along the null
direction. Convergence is still quadratic down to ~1e-7 relative error, then at least
linear with ratio ~1e-7. ``damping > 0`` gives damped least squares (Levenberg-Marquardt
style, ``|dq|`` bounded by ``|V| / (2 damping)``), slower near the solution but robust near
singularities.

Step limit. Far from the solution, or where ``J`` is nearly singular on the way, a full
Newton step can be many radians long and the iterates then wander off (measured on the
PUMA 560 from seeds within +-0.3 rad of a solution: 0.5 % of 10,000 targets ended
``NOT_CONVERGED`` with joints at hundreds of radians). With ``max_step`` (default 1.0 rad) the
step is scaled, direction kept, so that no revolute joint moves more than ``max_step`` in one
iteration::

    dq <- dq * min(1, max_step / max_i |dq_i|)      (i over revolute joints, |omega_i| = 1)

Prismatic joints are left out of the maximum (their units are the chain's lengths). Near the
solution steps are far below 1 rad, so quadratic convergence is untouched; on the PUMA
benchmark every one of 10,000 targets converged, in 13 iterations or fewer (20 before), which
also makes the batch stop sooner. ``max_step=None`` gives the unlimited step of seed 003.

Joint limits. With ``limits=(lower, upper)`` the seed is clamped into the box and every
iterate is clamped after its step (projected Newton); an element whose target is only
reachable outside the box ends ``NOT_CONVERGED``.

Batching. ``target`` (..., 4, 4) and ``q0`` (..., n) broadcast. Every element iterates on its
own inside one jitted ``lax.scan`` over ``max_iter`` steps: once an element satisfies the
tolerances its ``q`` is frozen, so ``history`` (max_iter + 1, ..., n) repeats its last value
from then on. When every element of the batch has converged the remaining steps are skipped
(``lax.cond``; under an outer ``vmap`` both branches run, with the same result).

Statuses: ``OK`` (converged), ``NOT_CONVERGED`` (tolerances not met after ``max_iter`` steps:
unreachable targets, poor seeds, limits in the way; ``q`` is then the last iterate, finite),
``INVALID_INPUT`` (NaN/inf in this element's ``target`` or ``q0``: ``q`` is the seed with
non-finite entries replaced by 0 and no step is taken). Rotations in ``target`` are assumed
orthonormal (not checked per element).

Differentiation: gradients flow through the unrolled ``lax.scan`` (no implicit
differentiation). Float32 works but the default tolerances (1e-3 rad, 1e-4 length units) are
near float32's attainable accuracy for long arms; loosen them for float32 if needed.
"""

from __future__ import annotations

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np
from jax import Array
from jax.typing import ArrayLike

from .. import _validate
from .._numerics import all_finite, safe_sqrt, singular_rtol
from ..result import SolverResult
from ..status import STATUS_DTYPE, Status
from . import dh as _dh
from . import lie
from . import poe as _poe

__all__ = ["NewtonIKResult", "ik_newton"]


@jax.tree_util.register_dataclass
@dataclasses.dataclass(frozen=True)
class NewtonIKResult(SolverResult):
    """Result of ``ik_newton`` for a batch of targets.

    Attributes:
        q: final joint values, shape ``(..., n)``.
        converged: both tolerances met, shape ``(...)``.
        iterations: number of Newton updates applied (0 if the seed already met the
            tolerances), ``int32``, shape ``(...)``. Seed 003's table of 4 rows = 3 updates.
        error: ``(|omega|, |v|)`` of the twist ``V`` (update frame) at ``q``, ``(..., 2)``.
        history: the iterates ``q^0 ... q^max_iter``, ``(max_iter + 1, ..., n)``, held
            constant after convergence.
        status: ``int8`` codes (``OK``, ``NOT_CONVERGED``, ``INVALID_INPUT``), ``(...)``.
    """

    q: Array
    converged: Array
    iterations: Array
    error: Array
    history: Array
    status: Array


def _spd_solve(a: list[list[Array]], b: list[Array]) -> list[Array]:
    """Solve ``a x = b`` for symmetric positive definite ``a`` (m x m nested lists of batch
    arrays, lower triangle read) and ``b`` (m arrays).

    Cholesky factorisation and triangular solves unrolled over the static size ``m``: pure
    elementwise batch arithmetic, much faster on CPU than a batched LAPACK call for m <= 6.
    """
    m = len(b)
    tiny = float(jnp.finfo(jnp.result_type(b[0])).tiny) ** 0.5
    chol: dict[tuple[int, int], Array] = {}
    inv_diag: list[Array] = []
    for j in range(m):
        diag = a[j][j] - sum(chol[j, k] * chol[j, k] for k in range(j))
        inv = jax.lax.rsqrt(jnp.maximum(diag, tiny))
        inv_diag.append(inv)
        for i in range(j + 1, m):
            chol[i, j] = (a[i][j] - sum(chol[i, k] * chol[j, k] for k in range(j))) * inv
    y: list[Array] = []
    for i in range(m):
        y.append((b[i] - sum(chol[i, k] * y[k] for k in range(i))) * inv_diag[i])
    x: list[Array] = [b[0]] * m
    for i in range(m - 1, -1, -1):
        x[i] = (y[i] - sum(chol[k, i] * x[k] for k in range(i + 1, m))) * inv_diag[i]
    return x


def _dot(u: list[Array], v: list[Array]) -> Array:
    return sum((a * b for a, b in zip(u[1:], v[1:], strict=True)), u[0] * v[0])


def _newton_step_soa(columns: list[list[Array]], twist: list[Array], damping: Array):
    """``dq = (J^T J + mu I)^-1 J^T V`` (n <= 6) or ``J^T (J J^T + mu I)^-1 V`` (n > 6).

    ``columns``: the ``n`` columns of ``J``, each 6 arrays; ``twist``: 6 arrays.
    """
    n = len(columns)
    gram = [[_dot(columns[i], columns[j]) if j <= i else None for j in range(n)] for i in range(n)]
    trace = sum(gram[i][i] for i in range(1, n)) if n > 1 else 0.0
    trace = gram[0][0] + trace
    mu = damping * damping + singular_rtol(trace.dtype) * trace
    if n <= 6:
        for i in range(n):
            gram[i][i] = gram[i][i] + mu
        return _spd_solve(gram, [_dot(col, twist) for col in columns])
    rows = [[col[k] for col in columns] for k in range(6)]  # rows of J
    outer = [[_dot(rows[i], rows[j]) if j <= i else None for j in range(6)] for i in range(6)]
    for i in range(6):
        outer[i][i] = outer[i][i] + mu
    y = _spd_solve(outer, twist)
    return [_dot(col, y) for col in columns]


def _newton_step(jac: Array, twist: Array, damping) -> Array:
    """Array front end of ``_newton_step_soa``: ``jac`` (..., 6, n), ``twist`` (..., 6)."""
    batch = jnp.broadcast_shapes(jac.shape[:-2], twist.shape[:-1])
    columns = [[jac[..., k, i] for k in range(6)] for i in range(jac.shape[-1])]
    twist_list = [twist[..., k] for k in range(6)]
    damping = jnp.asarray(damping, jac.dtype)
    dq = _newton_step_soa(columns, twist_list, damping)
    return jnp.stack([jnp.broadcast_to(x, batch) for x in dq], axis=-1)


def _twist_and_jacobian(chain: _poe.PoEChain, q: Array, target: Array, frame: str):
    """Twist to the target ``V`` (update frame, 6 arrays) and the Jacobian's columns at ``q``.

    ``V_b = log(T_sb^-1 T_sd)``: ``R_bd = R^T R_d``, ``p_bd = R^T (p_d - p)``.
    """
    rot, p, jac = _poe._fk_and_jacobian(chain, q, frame)
    rot_t = jnp.swapaxes(rot, -1, -2)
    rot_bd = rot_t @ target[..., :3, :3]
    p_bd = jnp.einsum("...ij,...j->...i", rot_t, target[..., :3, 3] - p)
    twist = lie.se3_log_soa(
        [[rot_bd[..., r, c] for c in range(3)] for r in range(3)],
        [p_bd[..., r] for r in range(3)],
    )
    if frame == "space":
        twist_arr = _poe._apply_adjoint(rot, p, jnp.stack(twist, axis=-1)[..., None])[..., 0]
        twist = [twist_arr[..., k] for k in range(6)]
    columns = [[jac[..., k, i] for k in range(6)] for i in range(chain.n_joints)]
    return twist, columns


def _ik_impl(
    chain: _poe.PoEChain,
    target: Array,
    q0: Array,
    eps_omega: Array,
    eps_v: Array,
    damping: Array,
    max_step: Array,
    lower: Array,
    upper: Array,
    max_iter: int,
    frame: str,
) -> NewtonIKResult:
    batch = jnp.broadcast_shapes(target.shape[:-2], q0.shape[:-1])
    n = chain.n_joints
    target = jnp.broadcast_to(target, (*batch, 4, 4))
    q0 = jnp.broadcast_to(q0, (*batch, n))
    # Double-where, step 1: replace non-finite elements before any arithmetic.
    valid = all_finite(target.reshape(*batch, 16)) & all_finite(q0)
    target = jnp.where(valid[..., None, None], target, jnp.eye(4, dtype=target.dtype))
    q0 = jnp.clip(jnp.where(jnp.isfinite(q0), q0, 0.0), lower, upper)
    # Revolute joints (|omega| = 1) set the step limit; prismatic rows (omega = 0) do not.
    revolute = jnp.any(chain.screws[:, :3] != 0, axis=-1)

    def limited(dq):
        largest = jnp.max(jnp.where(revolute, jnp.abs(dq), 0.0), axis=-1, keepdims=True)
        too_long = largest > max_step  # never true for max_step = inf (no limit)
        return dq * jnp.where(too_long, max_step / jnp.where(too_long, largest, 1.0), 1.0)

    def errors(q):
        twist, columns = _twist_and_jacobian(chain, q, target, frame)
        err_w = safe_sqrt(twist[0] * twist[0] + twist[1] * twist[1] + twist[2] * twist[2])
        err_v = safe_sqrt(twist[3] * twist[3] + twist[4] * twist[4] + twist[5] * twist[5])
        done = (err_w <= eps_omega) & (err_v <= eps_v)
        return twist, columns, jnp.stack([err_w, err_v], axis=-1), done | ~valid

    def body(carry, _):
        # carry: iterate, per-element update count, and whether every element had already
        # converged at the previous check (then the FK/Jacobian work is skipped).
        q, iterations, all_done = carry

        def do_step(c):
            q_c, it_c = c
            twist, columns, _, done = errors(q_c)
            dq = limited(jnp.stack(_newton_step_soa(columns, twist, damping), axis=-1))
            q_new = jnp.where(done[..., None], q_c, jnp.clip(q_c + dq, lower, upper))
            return q_new, it_c + (~done).astype(it_c.dtype), jnp.all(done)

        q, iterations, now_done = jax.lax.cond(
            all_done, lambda c: (*c, jnp.array(True)), do_step, (q, iterations)
        )
        return (q, iterations, now_done), q

    init = (q0, jnp.zeros(batch, jnp.int32), jnp.array(False))
    (q, iterations, _), steps = jax.lax.scan(body, init, None, length=max_iter)
    history = jnp.concatenate([q0[None], steps], axis=0)
    _, _, err, done = errors(q)
    converged = done & valid
    status = jnp.where(
        ~valid, Status.INVALID_INPUT, jnp.where(converged, Status.OK, Status.NOT_CONVERGED)
    ).astype(STATUS_DTYPE)
    err = jnp.where(valid[..., None], err, 0.0)
    return NewtonIKResult(q, converged, iterations, err, history, status)


_ik_jit = jax.jit(_ik_impl, static_argnames=("max_iter", "frame"))


def _positive(x: ArrayLike, name: str, allow_zero: bool = False) -> None:
    if _validate.is_concrete(x):
        values = np.asarray(x, dtype=np.float64)
        bad = ~np.isfinite(values) | (values < 0.0 if allow_zero else values <= 0.0)
        if np.any(bad):
            kind = "non-negative" if allow_zero else "positive"
            raise ValueError(f"{name} must be {kind} and finite, got {values}")


def ik_newton(
    chain: _poe.PoEChain | _dh.DHTable,
    target: ArrayLike,
    q0: ArrayLike,
    eps_omega: float = 1e-3,
    eps_v: float = 1e-4,
    max_iter: int = 20,
    damping: float = 0.0,
    max_step: float | None = 1.0,
    limits: tuple[ArrayLike, ArrayLike] | None = None,
    frame: str | None = None,
) -> NewtonIKResult:
    """Newton-Raphson IK (seed 003), batched, each element converging on its own.

    Args:
        chain: a ``PoEChain`` or a ``DHTable`` (converted to its space-frame PoE chain).
        target: desired end-effector transforms ``T_sd``, shape ``(..., 4, 4)``.
        q0: seeds, shape ``(..., n)``; batch shapes of ``target`` and ``q0`` broadcast.
        eps_omega: tolerance on ``|omega|`` of the twist (radians), > 0.
        eps_v: tolerance on ``|v|`` of the twist (length units), > 0.
        max_iter: number of Newton steps (static; ``history`` has ``max_iter + 1`` rows).
        damping: ``lambda >= 0`` of damped least squares; 0 gives the pseudo-inverse step.
        max_step: largest change of a revolute joint in one step (radians), > 0; the step is
            scaled down, direction kept, when longer (module docstring). ``None``: no limit.
        limits: optional ``(lower, upper)`` arrays broadcastable to ``(n,)`` (``+-inf``
            allowed); iterates are clamped into the box.
        frame: ``'body'`` or ``'space'`` update (module docstring); default: the chain's
            frame (``'space'`` for a ``DHTable``).

    Returns:
        ``NewtonIKResult`` (``q``, ``converged``, ``iterations``, ``error``, ``history``,
        ``status``); dtype the promotion of ``target``, ``q0`` and the chain.

    Raises:
        ValueError: unknown chain type or ``frame``, shapes that are not ``(..., 4, 4)`` /
            ``(..., n)`` or do not broadcast, non-positive tolerances, negative damping,
            ``max_iter < 0``, non-positive ``max_step``, or ``lower > upper``.
    """
    chain = _poe.as_poe(chain)
    frame = chain.frame if frame is None else _validate.choice(frame, "frame", _poe.FRAMES)
    if isinstance(max_iter, bool) or not isinstance(max_iter, (int, np.integer)) or max_iter < 0:
        raise ValueError(f"max_iter must be a non-negative int, got {max_iter!r}")
    target = jnp.asarray(target)
    q0 = jnp.asarray(q0)
    n = chain.n_joints
    if target.ndim < 2 or target.shape[-2:] != (4, 4):
        raise ValueError(f"target: expected shape (..., 4, 4), got {tuple(target.shape)}")
    if q0.ndim == 0 or q0.shape[-1] != n:
        raise ValueError(
            f"q0: expected shape (..., {n}) (last axis = the chain's {n} joints), "
            f"got {tuple(q0.shape)}"
        )
    _validate.batch_shape({"target": target.shape[:-2], "q0": q0.shape[:-1]})
    _positive(eps_omega, "eps_omega")
    _positive(eps_v, "eps_v")
    _positive(damping, "damping", allow_zero=True)
    if max_step is not None:
        _positive(max_step, "max_step")
    dtype = jnp.result_type(target, q0, chain.dtype, float)
    if limits is None:
        lower = jnp.full((n,), -jnp.inf, dtype)
        upper = jnp.full((n,), jnp.inf, dtype)
    else:
        try:
            lower, upper = limits
        except (TypeError, ValueError):
            raise ValueError("limits: expected a pair (lower, upper) of (n,) arrays") from None
        try:
            lower = jnp.broadcast_to(jnp.asarray(lower, dtype), (n,))
            upper = jnp.broadcast_to(jnp.asarray(upper, dtype), (n,))
        except ValueError:
            raise ValueError(
                f"limits: lower and upper must broadcast to ({n},), got "
                f"{jnp.shape(limits[0])} and {jnp.shape(limits[1])}"
            ) from None
        if _validate.is_concrete(lower) and _validate.is_concrete(upper):
            lo, up = np.asarray(lower), np.asarray(upper)
            if np.any(np.isnan(lo)) or np.any(np.isnan(up)) or np.any(lo > up):
                raise ValueError(f"limits: need lower <= upper (no NaN), got {lo} and {up}")
    if frame != chain.frame:
        chain = _poe.change_frame(chain, frame)
    chain = _validate.cast_leaves(chain, dtype)
    return _ik_jit(
        chain,
        target.astype(dtype),
        q0.astype(dtype),
        jnp.asarray(eps_omega, dtype),
        jnp.asarray(eps_v, dtype),
        jnp.asarray(damping, dtype),
        jnp.asarray(jnp.inf if max_step is None else max_step, dtype),
        lower,
        upper,
        int(max_iter),
        frame,
    )
