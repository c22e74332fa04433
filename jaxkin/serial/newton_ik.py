"""Newton-Raphson inverse kinematics of serial chains [Pineiro, "Cinemática Inversa Numérica"].

Given a desired pose ``T_sd`` and a start ``q^0``, iterate [Pineiro]'s algorithm::

    V_b = log(T(q^k)^-1 T_sd)            body twist to the target, rows (omega, v)
    body frame: V = V_b, J = J_b(q^k);   space frame: V = Ad(T(q^k)) V_b, J = J_s(q^k)
    q^{k+1} = q^k + J^+ V                until |omega| <= eps_omega and |v| <= eps_v

The frames take different paths; [Pineiro]'s 2R table is the body-frame one (docs/errata.md).
The step solves ``(J^T J + mu I) dq = J^T V`` (``n <= 6``) or ``dq = J^T (J J^T + mu I)^-1 V``
with an unrolled Cholesky, ``mu = damping^2 + sqrt(eps) trace(J^T J)``: the pseudo-inverse
step with a soft cut-off of singular directions (``damping > 0``: damped least squares). A step
is scaled, direction kept, so no revolute joint moves more than ``max_step`` (default 1 rad):
long steps far from the solution or near singular poses otherwise make iterates wander off.
With ``limits`` every iterate is clamped into the box (projected Newton). ``ik_newton`` works in
the chain's own units, as [Pineiro] does (the least-squares step weighs rotation errors in rad
against translation errors in the length unit).

Every element iterates on its own inside one jitted ``lax.scan``; a converged element is
frozen, and the remaining steps are skipped once all have converged. Statuses: ``OK``,
``NOT_CONVERGED`` (``q`` the last iterate, finite), ``INVALID_INPUT`` (NaN/inf in ``target`` or
``q0``: ``q`` is the start with non-finite entries replaced by 0). Gradients flow through the
unrolled scan.

``ik_chain`` is the robot protocol's IK of a chain (``jaxkin.ik``): the body frame,
Levenberg-Marquardt damping ``mu = |V|`` (Yamashita and Fukushima: quadratic convergence also
near singular poses, where the fixed ``sqrt(eps)`` floor converges linearly), tolerances
relative to the chain's size, restarts from fixed starts when no ``q0`` is given, joint rates
from the target's body twist, and a Jacobian-based margin.
"""

from __future__ import annotations

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np
from jax import Array
from jax.typing import ArrayLike

from .. import _validate
from .._numerics import all_finite, eps, isotropy, safe_sqrt, singular_rtol
from ..jet import Jet
from ..result import IKResult, SolverResult
from ..status import STATUS_DTYPE, Status
from . import dh as _dh
from . import lie
from . import poe as _poe

__all__ = ["NewtonIKResult", "ik_chain", "ik_newton"]


@jax.tree_util.register_dataclass
@dataclasses.dataclass(frozen=True)
class NewtonIKResult(SolverResult):
    """Result of ``ik_newton`` for a batch of targets.

    Attributes:
        q: final joint values, shape ``(..., n)``.
        converged: both tolerances met, shape ``(...)``.
        iterations: number of Newton updates applied (0 if the seed already met the
            tolerances), ``int32``, shape ``(...)`` ([Pineiro]'s table of 4 rows = 3 updates).
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


def _newton_step_soa(
    columns: list[list[Array]], twist: list[Array], damping: Array, floor: float | None = None
):
    """``dq = (J^T J + mu I)^-1 J^T V`` (n <= 6) or ``J^T (J J^T + mu I)^-1 V`` (n > 6).

    ``columns``: the ``n`` columns of ``J``, each 6 arrays; ``twist``: 6 arrays;
    ``mu = damping^2 + floor * trace(J^T J)`` with ``floor`` ``sqrt(eps)`` by default.
    """
    n = len(columns)
    gram = [[_dot(columns[i], columns[j]) if j <= i else None for j in range(n)] for i in range(n)]
    trace = sum(gram[i][i] for i in range(1, n)) if n > 1 else 0.0
    trace = gram[0][0] + trace
    floor = singular_rtol(trace.dtype) if floor is None else floor
    mu = damping * damping + floor * trace
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


def _newton_step(jac: Array, twist: Array, damping, floor: float | None = None) -> Array:
    """Array front end of ``_newton_step_soa``: ``jac`` (..., 6, n), ``twist`` (..., 6)."""
    batch = jnp.broadcast_shapes(jac.shape[:-2], twist.shape[:-1])
    columns = [[jac[..., k, i] for k in range(6)] for i in range(jac.shape[-1])]
    twist_list = [twist[..., k] for k in range(6)]
    damping = jnp.asarray(damping, jac.dtype)
    dq = _newton_step_soa(columns, twist_list, damping, floor)
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
    keep_history: bool = True,
    adaptive: bool = False,
    normalize: bool = False,
) -> NewtonIKResult:
    batch = jnp.broadcast_shapes(target.shape[:-2], q0.shape[:-1])
    n = chain.n_joints
    target = jnp.broadcast_to(target, (*batch, 4, 4))
    q0 = jnp.broadcast_to(q0, (*batch, n))
    # Double-where, step 1: replace non-finite elements before any arithmetic.
    valid = all_finite(target.reshape(*batch, 16)) & all_finite(q0)
    target = jnp.where(valid[..., None, None], target, jnp.eye(4, dtype=target.dtype))
    q0 = jnp.clip(jnp.where(jnp.isfinite(q0), q0, 0.0), lower, upper)
    scale = jnp.asarray(chain.length_scale() if normalize else 1.0, target.dtype)
    prismatic = ~jnp.any(chain.screws[:, :3] != 0, axis=-1)
    to_unit = jnp.where(prismatic, 1.0 / scale, 1.0)
    if normalize:
        # Units of the chain's size: the twist's two halves keep their relative weight at any
        # scale (a least-squares step weighs rotation against translation errors) and nothing
        # over- or underflows; q's prismatic joints and the length error are scaled back.
        v_scale = jnp.where(prismatic, 1.0, 1.0 / scale)[:, None]
        chain = _poe.PoEChain(
            jnp.concatenate([chain.screws[:, :3], chain.screws[:, 3:] * v_scale], axis=-1),
            chain.home.at[:3, 3].divide(scale),
            chain.frame,
        )
        target = target.at[..., :3, 3].divide(scale)
        q0, lower, upper = q0 * to_unit, lower * to_unit, upper * to_unit
        eps_v = eps_v / scale
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
            if adaptive:
                # Levenberg-Marquardt damping after Yamashita and Fukushima: it grows with the
                # squared error far from a solution and vanishes at it (quadratic convergence,
                # also where J is nearly singular); the floor 16 eps trace keeps it defined.
                error_sq = sum(t * t for t in twist)
                mu, floor = jnp.sqrt(damping * damping + error_sq), 16 * eps(q_c.dtype)
            else:
                mu, floor = damping, None
            step = _newton_step_soa(columns, twist, mu, floor)
            dq = limited(jnp.stack(step, axis=-1))
            q_new = jnp.where(done[..., None], q_c, jnp.clip(q_c + dq, lower, upper))
            return q_new, it_c + (~done).astype(it_c.dtype), jnp.all(done)

        q, iterations, now_done = jax.lax.cond(
            all_done, lambda c: (*c, jnp.array(True)), do_step, (q, iterations)
        )
        return (q, iterations, now_done), (q if keep_history else None)

    init = (q0, jnp.zeros(batch, jnp.int32), jnp.array(False))
    (q, iterations, _), steps = jax.lax.scan(body, init, None, length=max_iter)
    history = jnp.concatenate([q0[None], steps], axis=0) if keep_history else q0[None]
    _, _, err, done = errors(q)
    history, q = history / to_unit, q / to_unit
    err = err * jnp.stack([jnp.ones_like(scale), scale])
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
    """Newton-Raphson IK [Pineiro], batched, each element converging on its own.

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


# ------------------------------------------------------------------ the robot protocol


def _restart_seeds(chain: _poe.PoEChain, restarts: int, dtype) -> Array:
    """``(restarts, n)`` starts: zeros, then revolute joints uniform in [-pi, pi] (prismatic
    joints at 0), from a fixed generator (the same starts every call)."""
    uniform = np.random.default_rng(0).uniform(-np.pi, np.pi, size=(restarts, chain.n_joints))
    uniform[0] = 0.0
    revolute = jnp.any(chain.screws[:, :3] != 0, axis=-1)  # traceable: the chain may be
    return jnp.where(revolute, jnp.asarray(uniform, dtype), 0.0)


def _skew_parts(m: Array) -> Array:
    """``vee`` of the (skew) rotation block of ``(..., 4, 4)``: ``(..., 3)``."""
    return jnp.stack([m[..., 2, 1], m[..., 0, 2], m[..., 1, 0]], axis=-1)


def _body_twists(target: Jet) -> tuple[Array, Array]:
    """The target's body twist ``V = vee(T^-1 T_dot)`` and its time derivative
    ``vee(T^-1 T_ddot - (T^-1 T_dot)^2)``, rows ``(omega, v)``, each ``(..., 6)``."""
    rot, p = target.p[..., :3, :3], target.p[..., :3, 3]
    rot_t = jnp.swapaxes(rot, -1, -2)
    inverse = jnp.concatenate(
        [
            jnp.concatenate([rot_t, -jnp.einsum("...ij,...j->...i", rot_t, p)[..., None]], -1),
            jnp.broadcast_to(jnp.eye(4, dtype=p.dtype)[3:], (*p.shape[:-1], 1, 4)),
        ],
        axis=-2,
    )
    x = inverse @ target.v
    y = inverse @ target.a - x @ x
    twist = jnp.concatenate([_skew_parts(x), x[..., :3, 3]], axis=-1)
    rate = jnp.concatenate([_skew_parts(y), y[..., :3, 3]], axis=-1)
    return twist, rate


def _ik_chain_core(
    chain: _poe.PoEChain, target: Jet, seeds: Array, tol: Array, max_iter: int, rates: bool
) -> IKResult:
    dtype = target.dtype
    # Double-where: a non-finite target (or rate) is replaced before any arithmetic.
    flat = jnp.concatenate(
        [x.reshape(*x.shape[:-2], 16) for x in (target.p, target.v, target.a)], -1
    )
    finite = all_finite(flat)[..., None, None]
    target = Jet(
        jnp.where(finite, target.p, jnp.eye(4, dtype=dtype)),
        jnp.where(finite, target.v, 0.0),
        jnp.where(finite, target.a, 0.0),
    )
    scale = jnp.asarray(chain.length_scale(), dtype)
    revolute = jnp.any(chain.screws[:, :3] != 0, axis=-1)
    n = chain.n_joints
    lower = jnp.full((n,), -jnp.inf, dtype)
    upper = jnp.full((n,), jnp.inf, dtype)
    sol = _ik_impl(
        chain,
        target.p[..., None, :, :],
        seeds,
        tol,
        tol * scale,
        jnp.asarray(0.0, dtype),
        jnp.asarray(1.0, dtype),
        lower,
        upper,
        max_iter,
        "body",
        keep_history=False,
        adaptive=True,
        normalize=True,
    )
    # Per target: the converged restart with the smallest error, else the smallest error.
    score = sol.error[..., 0] + sol.error[..., 1] / scale
    score = jnp.where(sol.converged, score, score + 1e30)
    best = jnp.argmin(score, axis=-1)

    def pick(x):
        index = best.reshape(best.shape + (1,) * (x.ndim - best.ndim))
        return jnp.squeeze(jnp.take_along_axis(x, index, axis=best.ndim), axis=best.ndim)

    q, status = pick(sol.q), pick(sol.status)
    status = jnp.where(finite[..., 0, 0], status, Status.INVALID_INPUT).astype(status.dtype)
    ok = status == Status.OK
    _, _, jac = _poe._fk_and_jacobian(chain, q, "body")
    # The body Jacobian in units of the chain's size (v rows / scale, prismatic columns *
    # scale): the least-squares solves below stay well conditioned at any scale.
    rows = jnp.concatenate([jnp.ones(3, dtype), jnp.full(3, 1.0 / scale, dtype)])
    columns = jnp.where(revolute, 1.0, scale)
    unit_jac = jac * rows[:, None] * columns
    if rates:
        twist, twist_rate = _body_twists(target)
        floor = eps(dtype)
        q_dot = _newton_step(unit_jac, twist * rows, 0.0, floor) * columns
        jac_rate = jax.jvp(lambda x: _poe._fk_and_jacobian(chain, x, "body")[2], (q,), (q_dot,))[1]
        drift = jnp.einsum("...ij,...j->...i", jac_rate, q_dot)
        q_ddot = _newton_step(unit_jac, (twist_rate - drift) * rows, 0.0, floor) * columns
        okc = ok[..., None]
        q_jet = Jet(q, jnp.where(okc, q_dot, 0.0), jnp.where(okc, q_ddot, 0.0))
    else:
        q_jet = Jet.constant(q)
    margin = isotropy(unit_jac)
    margin = jnp.where(
        status == Status.INVALID_INPUT,
        -1.0,
        jnp.where(ok, margin, -jnp.minimum(pick(score), 1.0)),
    )
    return IKResult(q_jet, status, margin.astype(dtype))


_ik_chain_jit = jax.jit(_ik_chain_core, static_argnames=("max_iter", "rates"))


def ik_chain(
    chain: _poe.PoEChain | _dh.DHTable,
    target: Jet | ArrayLike,
    branch: str | None = None,
    q0: ArrayLike | None = None,
    restarts: int = 8,
    tol: float | None = None,
    max_iter: int = 50,
) -> IKResult:
    """Inverse kinematics of a chain as the robot protocol has it (``jaxkin.ik``).

    Newton-Raphson in the body frame (``ik_newton``, 1 rad step limit), from ``q0`` or, without
    one, from ``restarts`` fixed seeds (zeros, then random revolute angles) run as one batch;
    per target the converged run with the smallest error is kept. Converged means a body
    twist to the target below ``tol`` (rad) and ``tol * chain.length_scale()`` (length). Joint
    rates of a target Jet (4x4 matrices and their time derivatives) come from the body twist:
    ``q_dot = J_b^+ V_b``, ``q_ddot = J_b^+ (V_b_dot - J_b_dot q_dot)`` (minimum-norm for a
    redundant chain).

    Args:
        chain: a ``PoEChain`` or a ``DHTable``.
        target: Jet (or array, at rest) of 4x4 transforms ``(..., 4, 4)``.
        branch: ``"newton"`` (the only branch) or None.
        q0: seeds ``(..., n)`` broadcast against the targets; None for the restarts.
        restarts: number of seeds without ``q0`` (>= 1).
        tol: None for ``max(1e-10, 1000 eps(dtype))``.
        max_iter: Newton updates at most.

    Returns:
        ``IKResult``: ``q`` (Jet ``(..., n)``), ``status`` (``OK``, ``NOT_CONVERGED``,
        ``INVALID_INPUT``), ``margin`` (the scaled body Jacobian's isotropy in [0, 1] where
        converged; minus the remaining error, at most 1, where not; -1 for invalid input).
    """
    if branch not in (None, "newton"):
        raise ValueError(f"branch must be 'newton' (or None) for a chain, got {branch!r}")
    poe_chain = _poe.as_poe(chain)
    n = poe_chain.n_joints
    rates = isinstance(target, Jet)
    target = _validate.as_jet(target, "target", coords=None)
    if target.p.ndim < 2 or target.shape[-2:] != (4, 4):
        raise ValueError(f"target: expected shape (..., 4, 4), got {target.shape}")
    for name, value, low in (("restarts", restarts, 1), ("max_iter", max_iter, 1)):
        if isinstance(value, bool) or not isinstance(value, int) or value < low:
            raise ValueError(f"{name} must be an int >= {low}, got {value!r}")
    dtype = jnp.result_type(target.dtype, poe_chain.dtype)
    if tol is None:
        tol = max(1e-10, 1e3 * eps(dtype))
    _positive(tol, "tol")
    if q0 is None:
        seeds = _restart_seeds(poe_chain, restarts, dtype)
    else:
        q0 = jnp.asarray(q0, dtype)
        if q0.ndim == 0 or q0.shape[-1] != n:
            raise ValueError(f"q0: expected shape (..., {n}), got {tuple(q0.shape)}")
        _validate.batch_shape({"target": target.shape[:-2], "q0": q0.shape[:-1]})
        seeds = q0[..., None, :]
    batch = tuple(jnp.broadcast_shapes(target.shape[:-2], seeds.shape[:-2]))
    target = target.map(lambda x: jnp.broadcast_to(x.astype(dtype), (*batch, 4, 4)))
    body = _poe.change_frame(_validate.cast_leaves(poe_chain, dtype), "body")
    return _ik_chain_jit(body, target, seeds, jnp.asarray(tol, dtype), max_iter, rates)
