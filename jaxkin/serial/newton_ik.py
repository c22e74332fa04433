"""Newton-Raphson inverse kinematics of serial chains [Pineiro, "Cinemática Inversa Numérica"].

``ik_newton``: given a desired pose ``T_sd`` and a start ``q^0``, [Pineiro]'s iteration::

    V_b = log(T(q^k)^-1 T_sd)            body twist to the target, rows (omega, v)
    body frame: V = V_b, J = J_b(q^k);   space frame: V = Ad(T(q^k)) V_b, J = J_s(q^k)
    q^{k+1} = q^k + J^+ V                until angle(R^T R_d) <= eps_omega, |p_d - p| <= eps_v

The stopping rule bounds the tool's own errors (rotation angle in rad, position distance in
length units) in either frame: ``|v|`` of the space twist is the velocity of the point at the
base origin, not of the tool (docs/errata.md). The step solves ``(J^T J + mu I) dq = J^T V``
(``n <= 6``) or ``dq = J^T (J J^T + mu I)^-1 V`` with an unrolled Cholesky,
``mu = damping^2 + sqrt(eps) trace(J^T J)``, scaled (direction kept) so that no revolute joint
moves more than ``max_step``; with ``limits`` every iterate is clamped into the box. Every
element iterates on its own in one jitted ``lax.scan``; ``NOT_CONVERGED`` elements keep the
last iterate, ``INVALID_INPUT`` (NaN/inf) the start with non-finite entries replaced by 0.

``ik_chain`` is the robot protocol's IK of a chain (``jaxkin.ik``), in units of the chain's
size and in the body frame, with

* projected Levenberg-Marquardt: ``mu = LM_WEIGHT |V|^2`` (Yamashita and Fukushima; quadratic
  also near singular poses) and every iterate projected onto the joint limits (a revolute
  joint outside them first tries the 2 pi turn that lands inside; continuous joints wrap to
  [-pi, pi)): Kanzow, Yamashita and Fukushima (J. Comput. Appl. Math. 172, 2004) prove local
  quadratic convergence to a solution inside the box. Joints come back within the limits (but
  for ``OUT_OF_LIMITS``);
* restarts, one after the other per element, ``max_iter`` updates each: from the
  configuration of a fixed table (``TABLE_SIZE`` uniform over the limits) whose tool pose is
  nearest the target (or from ``q0``), then the middle of the limits, then the nearest of
  each further group of the table, then fixed seeds spread uniformly over the limits; the
  first run that meets the tolerances ends the element's search; after the last, one
  unbounded run from the best iterate tells ``OUT_OF_LIMITS`` (the pose is solved only
  outside the limits) from ``NOT_CONVERGED``. ``UNREACHABLE``: the target lies beyond
  ``chain.reach()``. A batch larger than ``QUEUE_SLOTS`` runs as a work queue: that many lanes
  iterate, and a lane whose target has ended takes the next one (the same updates, so the
  same results, as in step); from ``2 * CHAIN_MIN_PART`` targets, one queue per host thread
  (``jaxkin._batching``);
* ``OK`` only where ``angle(R^T R_d) <= orientation_tol`` and ``|p_d - p| <= position_tol``,
  evaluated at the returned joints;
* rates from the target's body twist, ``q_dot = J_b^+ V_b``, ``q_ddot = J_b^+ (V_b_dot -
  J_b_dot q_dot)`` (minimum-norm for a redundant chain, least squares for one with fewer than
  six joints), a Jacobian-based margin, and implicit derivatives (``dq = J_b^+ dV_b``).

``ik_chain_path`` warm-starts along sampled paths: the first sample as ``ik_chain``, every
further one from the previous solution (one run, then the unbounded run); a sample that fails
keeps its status, and the next one starts from the last solution.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from jax import Array
from jax.typing import ArrayLike

from .. import _batching, _validate, lie
from .._numerics import all_finite, computed_once, eps, isotropy, safe_sqrt, singular_rtol
from ..jet import Jet
from ..result import IKResult, SolverResult
from ..robot import solve_ik
from ..status import STATUS_DTYPE, Status
from . import chain as _chain
from . import dh as _dh
from . import poe as _poe
from ._chain_options import CHAIN_MIN_PART, QUEUE_SLOTS, ChainIKOptions

__all__ = [
    "ChainIKOptions",
    "NewtonIKResult",
    "chain_ik_kernel",
    "chain_ik_path_kernel",
    "ik_chain",
    "ik_chain_path",
    "ik_newton",
]


@jax.tree_util.register_dataclass
@dataclasses.dataclass(frozen=True)
class NewtonIKResult(SolverResult):
    """Result of ``ik_newton`` for a batch of targets.

    Attributes:
        q: final joint values, shape ``(..., n)``.
        converged: both tolerances met, shape ``(...)``.
        iterations: number of Newton updates applied (0 if the seed already met the
            tolerances), ``int32``, shape ``(...)`` ([Pineiro]'s table of 4 rows = 3 updates).
        error: the tool's ``(rotation angle, position distance)`` to the target at ``q``
            (rad, length units), ``(..., 2)``: what the tolerances bound.
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


def _computed(values: list[Array]) -> list[Array]:
    """``values`` stored once (``computed_once``): fused into every reader, they made the
    ``J J^T`` step ten times slower."""
    return list(computed_once(jnp.stack(jnp.broadcast_arrays(*values))))


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
    lower = iter(_computed([outer[i][j] for i in range(6) for j in range(i + 1)]))
    outer = [[next(lower) if j <= i else None for j in range(6)] for i in range(6)]
    y = _computed(_spd_solve(outer, twist))
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
    """Twist to the target ``V`` (update frame, 6 arrays), the Jacobian's columns at ``q`` and
    the tool's position error ``|p_d - p|``.

    ``V_b = log(T_sb^-1 T_sd)``: ``R_bd = R^T R_d``, ``p_bd = R^T (p_d - p)``; ``|omega|`` of
    either frame's twist is the rotation angle of ``R_bd``.
    """
    rot, p, jac = _poe._fk_and_jacobian(chain, q, frame)
    twist, p_bd = _body_twist(rot, p, target)
    if frame == "space":
        twist_arr = _poe._apply_adjoint(rot, p, jnp.stack(twist, axis=-1)[..., None])[..., 0]
        twist = [twist_arr[..., k] for k in range(6)]
    columns = [[jac[..., k, i] for k in range(6)] for i in range(jac.shape[-1])]
    return twist, columns, _norm3(p_bd)


def _body_twist(rot: Array, p: Array, target: Array) -> tuple[list[Array], list[Array]]:
    """``V_b = log(T^-1 T_d)`` (6 arrays) and ``p_bd = R^T (p_d - p)`` (3 arrays)."""
    rot_t = jnp.swapaxes(rot, -1, -2)
    rot_bd = rot_t @ target[..., :3, :3]
    p_bd = jnp.einsum("...ij,...j->...i", rot_t, target[..., :3, 3] - p)
    p_bd = [p_bd[..., r] for r in range(3)]
    twist = lie.se3_log_soa([[rot_bd[..., r, c] for c in range(3)] for r in range(3)], p_bd)
    return twist, p_bd


def _norm3(x: list[Array]) -> Array:
    return safe_sqrt(x[0] * x[0] + x[1] * x[1] + x[2] * x[2])


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

    def errors(q):
        twist, columns, err_v = _twist_and_jacobian(chain, q, target, frame)
        err_w = _norm3(twist[:3])
        done = (err_w <= eps_omega) & (err_v <= eps_v)
        return twist, columns, jnp.stack([err_w, err_v], axis=-1), done | ~valid

    def body(carry, _):
        # carry: iterate, per-element update count, and whether every element had already
        # converged at the previous check (then the FK/Jacobian work is skipped).
        q, iterations, all_done = carry

        def do_step(c):
            q_c, it_c = c
            twist, columns, _, done = errors(q_c)
            step = _newton_step_soa(columns, twist, damping)
            dq = _limited(jnp.stack(step, axis=-1), revolute, max_step)
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


def _limited(dq: Array, revolute: Array, max_step: Array) -> Array:
    """``dq`` scaled, direction kept, so that no revolute joint moves more than ``max_step``."""
    largest = jnp.max(jnp.where(revolute, jnp.abs(dq), 0.0), axis=-1, keepdims=True)
    too_long = largest > max_step  # never true for max_step = inf (no limit)
    return dq * jnp.where(too_long, max_step / jnp.where(too_long, largest, 1.0), 1.0)


_ik_jit = _batching.PaddedJit(
    jax.jit(_ik_impl, static_argnames=("max_iter", "frame")),
    {"target": 2, "q0": 1},
    axes={"history": 1},
)


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
        eps_omega: tolerance on the tool's rotation angle to the target (radians), > 0.
        eps_v: tolerance on the tool's distance to the target (length units), > 0.
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
    batch = _validate.batch_shape({"target": target.shape[:-2], "q0": q0.shape[:-1]})
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
        batch=batch,
    )


# ------------------------------------------------------------------ the robot protocol
_TWO_PI = 2.0 * np.pi


def _body_twists(target: Jet) -> tuple[Array, Array]:
    """The target's body twist ``V = vee(T^-1 T_dot)`` and its time derivative
    ``vee(T^-1 T_ddot - (T^-1 T_dot)^2)``, rows ``(omega, v)``, each ``(..., 6)``."""
    inverse = lie.se3_inverse(target.p)
    x = inverse @ target.v
    y = inverse @ target.a - x @ x
    twist, rate = lie.se3_vee(x), lie.se3_vee(y)
    return twist, rate


def _joint_chain(chain: Any) -> _chain.JointChain:
    """A ``JointChain`` as is; a ``PoEChain`` or ``DHTable`` as the same chain, no limits."""
    if isinstance(chain, _chain.JointChain):
        return chain
    poe = _poe.change_frame(_poe.as_poe(chain), "space")
    if _validate.is_concrete(poe.screws) and _validate.is_concrete(poe.home):
        return _chain.JointChain.from_poe(poe)
    # A traced chain (differentiated, or a user's jit argument): nothing to validate, and the
    # kernels read which joints are prismatic from the screws, not from ``kinds``.
    n = poe.n_joints
    out = object.__new__(_chain.JointChain)
    ones, inf = jnp.ones(n, poe.screws.dtype), jnp.full(n, jnp.inf, poe.screws.dtype)
    fields = dict(screws=poe.screws, home=poe.home, multiplier=ones, offset=0.0 * ones)
    fields |= dict(lower=-inf, upper=inf, velocity=inf, follows=tuple(range(n)))
    fields |= dict(names=tuple(f"q{i + 1}" for i in range(n)), kinds=("revolute",) * n)
    for name, value in (fields | dict(base_link="", tip_link="")).items():
        object.__setattr__(out, name, value)
    return out


def _in_units(chain: _chain.JointChain, scale: Array) -> tuple[_chain.JointChain, Array, Array]:
    """The chain in units of its size (lengths / ``scale``), the factors ``g`` of the
    coordinates (``q_unit = g q``) and the mask of prismatic coordinates (whose joints slide)."""
    dtype = chain.screws.dtype
    sliding = jnp.all(chain.screws[:, :3] == 0, axis=-1)
    onto = jnp.asarray(_chain.follow_matrix(chain), dtype)
    prismatic = onto.T @ sliding.astype(dtype) > 0
    f = jnp.where(sliding, 1.0 / scale, 1.0)  # theta_unit = f theta
    g = jnp.where(prismatic, 1.0 / scale, 1.0)
    unit = _chain.JointChain(
        chain.screws.at[:, 3:].multiply(jnp.where(sliding, 1.0, 1.0 / scale)[:, None]),
        chain.home.at[:3, 3].divide(scale),
        chain.multiplier * f / g[np.asarray(chain.follows)],
        chain.offset * f,
        chain.lower * g,
        chain.upper * g,
        chain.velocity,
        chain.follows,
        chain.names,
        chain.kinds,
        chain.base_link,
        chain.tip_link,
    )
    return unit, g, prismatic


def _turned(q: Array, lower: Array, upper: Array, revolute: Array, continuous: Array) -> Array:
    """``q`` with every revolute joint outside its limits turned by the multiple of 2 pi that
    brings it inside, where one does (the one nearest the range's middle: the only one when the
    range is shorter than 2 pi); continuous joints wrapped to [-pi, pi)."""
    middle = jnp.where(jnp.isfinite(lower) & jnp.isfinite(upper), 0.5 * (lower + upper), 0.0)
    turned = q - _TWO_PI * jnp.round((q - middle) / _TWO_PI)
    outside = (q < lower) | (q > upper)
    q = jnp.where(revolute & outside & (turned >= lower) & (turned <= upper), turned, q)
    return jnp.where(continuous, q - _TWO_PI * jnp.floor((q + np.pi) / _TWO_PI), q)


def _projected(q: Array, lower: Array, upper: Array, revolute: Array, continuous: Array) -> Array:
    """The projection onto the joint limits after the 2 pi turns of ``_turned``."""
    return jnp.clip(_turned(q, lower, upper, revolute, continuous), lower, upper)


def _residual(chain: _chain.JointChain, q: Array, target: Array):
    """Body twist to the target (6 arrays), Jacobian columns, rotation and position errors."""
    rot, p, jac = _chain.fk_and_jacobian(chain, q, "body")
    twist, p_bd = _body_twist(rot, p, target)
    columns = [[jac[..., k, i] for k in range(6)] for i in range(chain.n_joints)]
    return twist, columns, _norm3(twist[:3]), _norm3(p_bd)


def _update(
    chain, goal, starts, q, run, k, done, best_q, best, seeds, limits, tols, max_iter, runs
):
    """One projected Levenberg-Marquardt update of every lane (``_search``): returns the next
    ``(q, run, k, best_q, best)``, which lanes ``ended`` and, for those, their joints and
    status code. ``starts`` ``(..., S, n)``: the lane's first ``S`` runs' starts."""
    lower, upper, revolute, continuous = limits
    tol_rot, tol_pos = tols
    one = jnp.asarray(1.0, q.dtype)
    bounded = jnp.any(jnp.isfinite(lower) | jnp.isfinite(upper))
    last = runs - 1 + bounded.astype(jnp.int32)  # the unbounded run comes last, with limits

    def project(x):
        return _projected(x, lower, upper, revolute, continuous)

    twist, columns, err_rot, err_pos = _residual(chain, q, goal)
    free = run >= runs
    turned = _turned(q, lower, upper, revolute, continuous)
    within = jnp.all((turned >= lower) & (turned <= upper), axis=-1)
    hit = (err_rot <= tol_rot) & (err_pos <= tol_pos)
    score = err_rot + err_pos
    improve = ~done & ~free & (score < best)
    best_q = jnp.where(improve[..., None], q, best_q)
    best = jnp.where(improve, score, best)
    spent = k >= max_iter
    ended = ~done & (hit | (spent & (run >= last)))
    code = jnp.where(within, Status.OK, Status.OUT_OF_LIMITS)
    code = jnp.where(hit, code, Status.NOT_CONVERGED).astype(STATUS_DTYPE)
    # Levenberg-Marquardt damping mu = LM_WEIGHT |V|^2 (the floor 16 eps trace keeps it defined).
    error_sq = sum(t * t for t in twist)
    step = _newton_step_soa(columns, twist, safe_sqrt(LM_WEIGHT * error_sq), 16 * eps(q.dtype))
    moved = q + _limited(jnp.stack(step, axis=-1), revolute, one)
    # The unbounded run projects onto no limits: only its continuous joints wrap.
    lo = jnp.where(free[..., None], -jnp.inf, lower)
    hi = jnp.where(free[..., None], jnp.inf, upper)
    moved = _projected(moved, lo, hi, revolute, continuous)
    following = run + 1
    own = starts.shape[-2]
    mine = jnp.take_along_axis(starts, jnp.minimum(following, own - 1)[..., None, None], -2)
    shared = jnp.take(seeds, jnp.minimum(following, runs - 1), axis=0)
    restart = project(jnp.where((following < own)[..., None], mine[..., 0, :], shared))
    restart = jnp.where((following < runs)[..., None], restart, best_q)
    q_next = jnp.where(spent[..., None], restart, moved)
    q_end = jnp.where(hit[..., None], turned, best_q)
    run = jnp.where(spent & ~done, following, run)
    k = jnp.where(spent, 0, k + 1)
    return (q_next, run, k, best_q, best), ended, q_end, code


def _search(
    chain: _chain.JointChain,
    target: Array,
    starts: Array,
    seeds: Array,
    limits: tuple[Array, Array, Array, Array],
    tols: tuple[Array, Array],
    done: Array,
    status: Array,
    max_iter: int,
    runs: int,
    slots: int | None = None,
) -> tuple[Array, Array]:
    """Projected Levenberg-Marquardt with restarts (module docstring), in units of the chain.

    ``target`` ``(..., 4, 4)``; ``starts`` ``(..., S, n)`` each element's first ``S`` runs'
    starts, ``seeds`` ``(runs, n)`` the later runs' (rows below ``S`` unused); ``limits``
    ``(lower, upper, revolute, continuous)``; ``tols`` ``(rotation, position)``;
    ``done``/``status`` preset elements (invalid, unreachable). Every element iterates in step
    until the last has ended, or, with more elements than ``slots``, as a work queue of
    ``slots`` lanes (``_queued``). Returns ``(q, status)``: ``OK``, ``OUT_OF_LIMITS``,
    ``NOT_CONVERGED`` or the preset status.
    """
    lower, upper, revolute, continuous = limits

    def project(x):
        return _projected(x, lower, upper, revolute, continuous)

    def update(goal, own, q, run, k, done, best_q, best):
        return _update(
            chain, goal, own, q, run, k, done, best_q, best, seeds, limits, tols, max_iter, runs
        )

    per_element = (runs + 1) * (max_iter + 1) + 2
    batch = starts.shape[:-2]
    size = math.prod(batch)
    if slots is not None and size > slots:
        flat = (target.reshape(size, 4, 4), starts.reshape(size, *starts.shape[-2:]))
        q, status = _queued(
            update, project, *flat, done.ravel(), status.ravel(), slots, per_element
        )
        return q.reshape(*batch, -1), status.reshape(batch)

    def body(state):
        q, run, k, done, status, best_q, best, it = state
        (q_next, run, k, best_q, best), ended, q_end, code = update(
            target, starts, q, run, k, done, best_q, best
        )
        status = jnp.where(ended, code, status)
        q = jnp.where(done[..., None], q, jnp.where(ended[..., None], q_end, q_next))
        return q, run, k, done | ended, status, best_q, best, it + 1

    def cond(state):
        return (state[-1] < per_element) & jnp.any(~state[3])

    q0 = project(starts[..., 0, :])
    zeros = jnp.zeros(batch, jnp.int32)
    init = (q0, zeros, zeros, done, status, q0, jnp.full(batch, jnp.inf, starts.dtype), 0)
    q, _, _, _, status, *_ = jax.lax.while_loop(cond, body, init)
    return q, status


def _queued(update, project, target, starts, done, status, slots: int, per_element: int):
    """``_search`` as a work queue over flat ``(B, ...)`` elements: ``slots`` lanes iterate,
    and a lane whose element has ended takes the next one, so a batch costs its elements'
    total work rather than its hardest element's work times its size. Each element gets the
    same updates as in step (the same starts and seeds), so the same results."""
    size = starts.shape[0]
    dtype = starts.dtype

    def fresh(index):
        """Per-lane state for elements ``index`` (past the end: an idle lane)."""
        q = project(starts[jnp.minimum(index, size - 1), 0])
        zeros = jnp.zeros(index.shape, jnp.int32)
        return q, zeros, zeros, q, jnp.full(index.shape, jnp.inf, dtype)

    def body(state):
        slot, (q, run, k, best_q, best), out_q, out_status, following, it = state
        i = jnp.minimum(slot, size - 1)
        preset = done[i] | (slot >= size)  # invalid, unreachable, or idle
        kept, ended, q_end, code = update(target[i], starts[i], q, run, k, preset, best_q, best)
        # A preset element ends at once with its preset status and its start.
        finished = ended | (preset & (slot < size))
        q_out = jnp.where(ended[..., None], q_end, project(starts[i, 0]))
        code = jnp.where(ended, code, status[i])
        where = jnp.where(finished, slot, size)  # out of range: dropped
        out_q = out_q.at[where].set(q_out, mode="drop")
        out_status = out_status.at[where].set(code, mode="drop")
        # Finished lanes take the next elements in order.
        rank = jnp.cumsum(finished, dtype=jnp.int32) - 1
        slot = jnp.where(finished, following + rank, slot)
        following = following + jnp.sum(finished, dtype=jnp.int32)
        lanes = tuple(
            jnp.where(finished.reshape(finished.shape + (1,) * (a.ndim - 1)), b, a)
            for a, b in zip(kept, fresh(slot), strict=True)
        )
        return slot, lanes, out_q, out_status, following, it + 1

    limit = (-(-size // slots) + 1) * per_element

    def cond(state):
        return jnp.any(state[0] < size) & (state[-1] < limit)

    slot = jnp.arange(slots, dtype=jnp.int32)
    init = (slot, fresh(slot), project(starts[:, 0]), status, jnp.int32(slots), 0)
    _, _, q, status, _, _ = jax.lax.while_loop(cond, body, init)
    return q, status


# Levenberg-Marquardt damping ``mu = LM_WEIGHT |V|^2``: any positive weight keeps
# Yamashita-Fukushima's quadratic convergence; 1e-3 needed 3-5x fewer updates than 1 from far
# starts (1,000 UR5 / Panda poses within the limits).
LM_WEIGHT = 1e-3
# Nearest-pose starts (``_near_starts``): a table of TABLE_SIZE configurations uniform over the
# limits in NEAR_GROUPS groups; ROTATION_WEIGHT weighs |R - R_d|_F against |p - p_d| (units of
# the chain's size). Tuned on 1,000 UR5 / Panda poses: 12-19 updates per pose on average.
TABLE_SIZE = 1024
NEAR_GROUPS = 8
ROTATION_WEIGHT = 0.15


@dataclasses.dataclass(frozen=True)
class _Search:
    """The static shape of a search: updates per run, runs, and updates of a warm start."""

    max_iter: int
    runs: int
    warm_iter: int


def _prepare(
    chain: _chain.JointChain, target: Jet, tols: tuple[Array, Array], use_limits, runs: int
):
    """Units, limits, the preset statuses (invalid, unreachable), the tolerances in units of
    the chain and the ``runs`` seeds of a batch."""
    dtype = target.dtype
    flat = jnp.concatenate(
        [x.reshape(*x.shape[:-2], 16) for x in (target.p, target.v, target.a)], -1
    )
    finite = all_finite(flat)
    safe = Jet(
        jnp.where(finite[..., None, None], target.p, jnp.eye(4, dtype=dtype)),
        jnp.where(finite[..., None, None], target.v, 0.0),
        jnp.where(finite[..., None, None], target.a, 0.0),
    )
    scale = jnp.asarray(chain.length_scale(), dtype)
    unit, g, prismatic = _in_units(chain, scale)
    n = chain.n_joints
    if use_limits:
        lower, upper = unit.lower, unit.upper
    else:
        lower, upper = jnp.full(n, -jnp.inf, dtype), jnp.full(n, jnp.inf, dtype)
    continuous = jnp.asarray([k == "continuous" for k in chain.kinds])
    limits = (lower, upper, ~prismatic, continuous)
    goal = safe.p.at[..., :3, 3].divide(scale)
    centre, radius = unit.reach()
    distance = safe_sqrt(jnp.sum((goal[..., :3, 3] - centre) ** 2, axis=-1))
    unit_tols = (tols[0], tols[1] / scale)
    unreachable = finite & (distance > radius + unit_tols[1])
    status = jnp.where(finite, Status.NOT_CONVERGED, Status.INVALID_INPUT)
    status = jnp.where(unreachable, Status.UNREACHABLE, status).astype(STATUS_DTYPE)
    seeds = _seeds(limits, runs, dtype)
    return safe, goal, unit, g, scale, limits, status, ~finite | unreachable, unit_tols, seeds


def _seeds(limits: tuple[Array, ...], runs: int, dtype) -> Array:
    """``(runs, n)`` starts: the middle of the limits (0 for an unbounded joint), then uniform
    over the limits, from a fixed generator: the same starts every call."""
    u = np.random.default_rng(0).uniform(size=(runs, limits[0].shape[-1]))
    u[0] = 0.5
    return _spread(limits, jnp.asarray(u, dtype))


def _spread(limits: tuple[Array, ...], u: Array) -> Array:
    """Points ``u`` of the unit cube ``(..., n)`` as configurations: uniform over the limits
    (revolute joints without limits over [-pi, pi), prismatic ones at 0)."""
    lower, upper, revolute, _ = limits
    finite = jnp.isfinite(lower) & jnp.isfinite(upper)
    inside = jnp.where(finite, lower, 0.0) + u * jnp.where(finite, upper - lower, 0.0)
    free = jnp.clip(jnp.where(revolute, (2.0 * u - 1.0) * np.pi, 0.0), lower, upper)
    return jnp.where(finite, inside, free)


def _near_starts(unit: _chain.JointChain, goal: Array, limits: tuple[Array, ...]) -> Array:
    """``(..., NEAR_GROUPS, n)``: per goal pose, the configuration of each group of a fixed
    table whose pose is nearest, nearest first, by ``|p - p_d|^2 + w^2 |R - R_d|_F^2`` (units of
    the chain, ``w = ROTATION_WEIGHT``), evaluated as one matrix product in float32 (it only
    ranks starts)."""
    n = limits[0].shape[-1]
    u = np.random.default_rng(1).uniform(size=(TABLE_SIZE, n))
    table = _spread(limits, jnp.asarray(u, goal.dtype))
    rot, p = _chain.fk_rp(unit, table)

    def features(rot, p):
        flat = rot.reshape(*rot.shape[:-2], 9)
        return jnp.concatenate([p, ROTATION_WEIGHT * flat], -1).astype(jnp.float32)

    ours = features(rot, p)
    theirs = features(goal[..., :3, :3], goal[..., :3, 3])
    # |a - b|^2 less |b|^2 (the same for every row of the table), grouped.
    d = jnp.sum(ours * ours, -1) - 2.0 * theirs @ ours.T
    d = d.reshape(*d.shape[:-1], NEAR_GROUPS, TABLE_SIZE // NEAR_GROUPS)
    inner = jnp.argmin(d, axis=-1)
    nearest = jnp.take_along_axis(d, inner[..., None], -1)[..., 0]
    order = jnp.argsort(nearest, axis=-1)
    index = jnp.take_along_axis(inner, order, -1) + order * (TABLE_SIZE // NEAR_GROUPS)
    return table[index]


def _first_starts(unit, goal, limits, seeds, q0) -> Array:
    """``(..., NEAR_GROUPS + 1, n)`` starts of an element's first runs: the nearest table pose
    (or ``q0``), the middle of the limits, then the other groups' nearest."""
    near = _near_starts(unit, goal, limits)
    first = near[..., 0, :] if q0 is None else q0
    middle = jnp.broadcast_to(seeds[0], first.shape)
    starts = jnp.concatenate([first[..., None, :], middle[..., None, :], near[..., 1:, :]], -2)
    return jnp.where(jnp.isfinite(starts), starts, 0.0)


def _finish(
    unit: _chain.JointChain,
    g: Array,
    scale: Array,
    target: Jet,
    goal: Array,
    q_unit: Array,
    status: Array,
    rates: bool,
) -> IKResult:
    """Joint rates, margins and implicit derivatives at the solutions (module docstring)."""
    dtype = q_unit.dtype
    ok = status == Status.OK
    fixed = jax.lax.stop_gradient(q_unit)
    rot, p, jac = _chain.fk_and_jacobian(unit, fixed, "body")
    # Implicit derivatives: one Newton step at the solution, whose value is removed; the
    # goal of a failed element is its own pose (finite derivatives of the log at identity).
    reached = lie.from_rotation_translation(rot, p)
    twist, _ = _body_twist(rot, p, jnp.where(ok[..., None, None], goal, reached))
    floor = eps(dtype)
    dq = _newton_step(jac, jnp.stack(twist, axis=-1), 0.0, floor)
    q_unit = fixed + jnp.where(ok[..., None], dq - jax.lax.stop_gradient(dq), 0.0)
    _, _, jac = _chain.fk_and_jacobian(unit, q_unit, "body")
    rows = jnp.concatenate([jnp.ones(3, dtype), jnp.full(3, 1.0 / scale, dtype)])
    if rates:
        velocity, acceleration = _body_twists(target)
        q_dot = _newton_step(jac, velocity * rows, 0.0, floor)
        jac_rate = jax.jvp(
            lambda x: _chain.fk_and_jacobian(unit, x, "body")[2], (q_unit,), (q_dot,)
        )[1]
        drift = jnp.einsum("...ij,...j->...i", jac_rate, q_dot)
        q_ddot = _newton_step(jac, acceleration * rows - drift, 0.0, floor)
        okc = ok[..., None]
        q_jet = Jet(q_unit / g, jnp.where(okc, q_dot / g, 0.0), jnp.where(okc, q_ddot / g, 0.0))
    else:
        q_jet = Jet.constant(q_unit / g)
    goal_twist, p_bd = _body_twist(rot, p, goal)
    error = jnp.minimum(_norm3(goal_twist[:3]) + _norm3(p_bd), 1.0)
    solved = ok | (status == Status.OUT_OF_LIMITS)
    margin = jnp.where(solved, isotropy(jac), -error)
    margin = jnp.where(status == Status.INVALID_INPUT, -1.0, margin)
    return IKResult(q_jet, status, margin.astype(dtype))


def _ik_chain_core(
    chain: _chain.JointChain,
    target: Jet,
    q0: Array | None,
    tols: tuple[Array, Array],
    search: _Search,
    use_limits: bool,
    rates: bool,
) -> IKResult:
    prepared = _prepare(chain, target, tols, use_limits, search.runs)
    safe, goal, unit, g, scale, limits, status, done, tols, seeds = prepared
    starts = _first_starts(unit, goal, limits, seeds, None if q0 is None else q0 * g)
    q, status = _search(
        unit, goal, starts, seeds, limits, tols, done, status, search.max_iter, search.runs,
        QUEUE_SLOTS,
    )  # fmt: skip
    return _finish(unit, g, scale, safe, goal, q, status, rates)


def _ik_chain_parts() -> _batching.PartsJit:
    """The compiled ``_ik_chain_core``, large batches split across the host threads."""
    return _batching.PartsJit(
        _ik_chain_core,
        static_argnames=("search", "use_limits", "rates"),
        batched_argnames=("target", "q0"),
        min_part=CHAIN_MIN_PART,
    )


_ik_chain_jit = _ik_chain_parts()


def _ik_chain_path_core(
    chain: _chain.JointChain,
    path: Jet,
    tols: tuple[Array, Array],
    search: _Search,
    use_limits: bool,
) -> IKResult:
    prepared = _prepare(chain, path, tols, use_limits, search.runs)
    safe, goal, unit, g, scale, limits, status, done, tols, seeds = prepared
    q, code = _search(
        unit,
        goal[..., 0, :, :],
        _first_starts(unit, goal[..., 0, :, :], limits, seeds, None),
        seeds,
        limits,
        tols,
        done[..., 0],
        status[..., 0],
        search.max_iter,
        search.runs,
        QUEUE_SLOTS,
    )

    def step(previous, sample):
        goal_t, done_t, status_t = sample
        q_t, code_t = _search(
            unit, goal_t, previous[..., None, :], seeds[:1], limits, tols, done_t, status_t,
            search.warm_iter, 1,
        )  # fmt: skip
        solved = (code_t == Status.OK) | (code_t == Status.OUT_OF_LIMITS)
        return jnp.where(solved[..., None], q_t, previous), (q_t, code_t)

    rest = (
        jnp.moveaxis(x[..., 1:, *([slice(None)] * k)], x.ndim - 1 - k, 0)
        for x, k in ((goal, 2), (done, 0), (status, 0))
    )
    _, (q_rest, code_rest) = jax.lax.scan(step, q, tuple(rest))
    q = jnp.concatenate([q[..., None, :], jnp.moveaxis(q_rest, 0, -2)], axis=-2)
    code = jnp.concatenate([code[..., None], jnp.moveaxis(code_rest, 0, -1)], axis=-1)
    return _finish(unit, g, scale, safe, goal, q, code, True)


_ik_chain_path_jit = jax.jit(_ik_chain_path_core, static_argnames=("search", "use_limits"))


def _tolerances(chain: _chain.JointChain, dtype, options: ChainIKOptions) -> tuple[Array, Array]:
    """``(orientation_tol, position_tol)`` of ``options`` as ``dtype`` arrays (traceable), the
    defaults ``max(1e-10, 1000 eps)`` (rad) and that times ``chain.length_scale()``."""
    default = max(1e-10, 1e3 * eps(dtype))
    rot = default if options.orientation_tol is None else options.orientation_tol
    if options.position_tol is None:
        pos = default * chain.length_scale()
    else:
        pos = options.position_tol
    return jnp.asarray(rot, dtype), jnp.asarray(pos, dtype)


def chain_ik_kernel(chain: Any, target: Jet, options: ChainIKOptions, rates: bool) -> IKResult:
    """The robot protocol's IK kernel of every chain (``JointChain``, ``PoEChain``,
    ``DHTable``): ``_ik_chain_core`` from the nearest table pose; traceable."""
    chain = _validate.cast_leaves(_joint_chain(chain), target.dtype)
    tols = _tolerances(chain, target.dtype, options)
    search = _Search(options.max_iter, options.restarts, options.max_iter)
    return _ik_chain_core(chain, target, None, tols, search, options.use_limits, rates)


def chain_ik_path_kernel(chain: Any, path: Jet, options: ChainIKOptions) -> IKResult:
    """The planner's IK along sampled paths ``(..., T, 4, 4)`` of every chain: the first
    sample searched as ``chain_ik_kernel``, every further one warm-started (``ik_chain_path``)."""
    chain = _validate.cast_leaves(_joint_chain(chain), path.dtype)
    tols = _tolerances(chain, path.dtype, options)
    search = _Search(options.max_iter, options.restarts, options.warm_iter)
    return _ik_chain_path_core(chain, path, tols, search, options.use_limits)


def _options(chain: _chain.JointChain, dtype, position_tol, orientation_tol, counts) -> tuple:
    """Validated tolerances (as arrays: no recompilation for new values) and counts."""
    for name, value in counts.items():
        if isinstance(value, bool) or not isinstance(value, int) or value < 1:
            raise ValueError(f"{name} must be an int >= 1, got {value!r}")
    default = max(1e-10, 1e3 * eps(dtype))
    rot = default if orientation_tol is None else orientation_tol
    _positive(rot, "orientation_tol")
    if position_tol is None:
        pos = jnp.asarray(default * chain.length_scale(), dtype)
    else:
        _positive(position_tol, "position_tol")
        pos = jnp.asarray(position_tol, dtype)
    return jnp.asarray(rot, dtype), pos


def _check_target(target: Jet | ArrayLike, name: str) -> tuple[Jet, bool]:
    rates = isinstance(target, Jet)
    target = _validate.as_jet(target, name, coords=None)
    if target.p.ndim < 2 or target.shape[-2:] != (4, 4):
        raise ValueError(f"{name}: expected shape (..., 4, 4), got {target.shape}")
    return target, rates


def ik_chain(
    chain: _chain.JointChain | _poe.PoEChain | _dh.DHTable,
    target: Jet | ArrayLike,
    branch: str | None = None,
    q0: ArrayLike | None = None,
    restarts: int = 64,
    max_iter: int = 12,
    position_tol: float | None = None,
    orientation_tol: float | None = None,
    use_limits: bool = True,
) -> IKResult:
    """Inverse kinematics of a chain as the robot protocol has it (``jaxkin.ik``).

    Projected Levenberg-Marquardt in the body frame with restarts, per element (module
    docstring). Guarantees: ``OK`` means ``angle(R^T R_d) <= orientation_tol`` (rad) and
    ``|p_d - p| <= position_tol`` (length) at the returned joints, computed by the chain's
    forward kinematics; with ``use_limits`` the joints of every status but ``OUT_OF_LIMITS``
    lie within the chain's limits; continuous joints come back in [-pi, pi).

    Args:
        chain: a ``JointChain`` (e.g. from ``serial.from_urdf``), ``PoEChain`` or ``DHTable``.
        target: Jet (or array, at rest) of 4x4 transforms ``(..., 4, 4)``; a Jet's rates give
            the joint rates (``q_dot = J_b^+ V_b``, ``q_ddot = J_b^+ (V_b_dot - J_b_dot
            q_dot)``: minimum-norm for a redundant chain).
        branch: ``"newton"`` (the only branch) or None.
        q0: the first run's start ``(..., n)`` (broadcast against the targets); None for the
            nearest pose of a fixed table. Later runs start from the middle of the limits,
            other table poses near the target, then fixed seeds spread over the limits.
        restarts: runs per element at most (>= 1), before the unbounded run.
        max_iter: updates per run (>= 1).
        position_tol: length units; None for ``max(1e-10, 1000 eps) * chain.length_scale()``.
        orientation_tol: rad; None for ``max(1e-10, 1000 eps)``.
        use_limits: respect the chain's position limits (False: search without them).

    Returns:
        ``IKResult``: ``q`` (Jet ``(..., n)``), ``status`` (``OK``, ``OUT_OF_LIMITS``: solved
        only outside the limits, ``q`` that solution; ``NOT_CONVERGED``: ``q`` the best iterate
        within the limits; ``UNREACHABLE``: beyond ``chain.reach()``; ``INVALID_INPUT``),
        ``margin`` (the isotropy of the body Jacobian in units of the chain's size where
        solved; minus the remaining error, at most 1, where not; -1 for invalid input).

    Raises:
        ValueError: an unknown branch, a target or ``q0`` of the wrong shape, non-positive
            tolerances or counts below 1.
    """
    if branch not in (None, "newton"):
        raise ValueError(f"branch must be 'newton' (or None) for a chain, got {branch!r}")
    if not isinstance(chain, _chain.JointChain | _poe.PoEChain | _dh.DHTable):
        raise ValueError(
            f"chain: expected a JointChain, PoEChain or DHTable, got {type(chain).__name__}"
        )
    options = ChainIKOptions(
        restarts, max_iter, max_iter, position_tol, orientation_tol, bool(use_limits)
    )
    if q0 is None:
        return solve_ik(chain, target, "newton", options)
    joint_chain = _joint_chain(chain)
    target, rates = _check_target(target, "target")
    dtype = jnp.result_type(target.dtype, joint_chain.dtype)
    counts = dict(restarts=restarts, max_iter=max_iter)
    tols = _options(joint_chain, dtype, position_tol, orientation_tol, counts)
    n = joint_chain.n_joints
    batch = target.shape[:-2]
    if q0 is not None:
        q0 = jnp.asarray(q0, dtype)
        if q0.ndim == 0 or q0.shape[-1] != n:
            raise ValueError(f"q0: expected shape (..., {n}), got {tuple(q0.shape)}")
        batch = _validate.batch_shape({"target": batch, "q0": q0.shape[:-1]})
        q0 = jnp.broadcast_to(q0, (*batch, n))
    target = target.map(lambda x: jnp.broadcast_to(x.astype(dtype), (*batch, 4, 4)))
    search = _Search(max_iter, restarts, max_iter)
    chain = _validate.cast_leaves(joint_chain, dtype)
    return _ik_chain_jit(
        chain, target, q0, tols, search, bool(use_limits), rates, batch=tuple(batch)
    )


def ik_chain_path(
    chain: _chain.JointChain | _poe.PoEChain | _dh.DHTable,
    path: Jet | ArrayLike,
    restarts: int = 64,
    max_iter: int = 12,
    warm_iter: int = 20,
    position_tol: float | None = None,
    orientation_tol: float | None = None,
    use_limits: bool = True,
) -> IKResult:
    """``ik_chain`` along sampled paths, each sample warm-started from the previous one.

    Args:
        chain: as for ``ik_chain``.
        path: Jet (or array) of 4x4 transforms ``(..., T, 4, 4)``, T >= 1 consecutive samples.
        restarts, max_iter: the search of each path's first sample (``ik_chain``).
        warm_iter: updates of a later sample's run from the previous solution (then the
            unbounded run tells ``OUT_OF_LIMITS``); no restart elsewhere: a sample that fails
            keeps ``NOT_CONVERGED`` and the next one starts from the last solution.
        position_tol, orientation_tol, use_limits: as for ``ik_chain``.

    Returns:
        ``IKResult`` of shape ``(..., T)`` (rates from the path's Jet).
    """
    joint_chain = _joint_chain(chain)
    path, _ = _check_target(path, "path")
    if path.p.ndim < 3:
        raise ValueError(f"path: expected shape (..., T, 4, 4), got {path.shape}")
    dtype = jnp.result_type(path.dtype, joint_chain.dtype)
    counts = dict(restarts=restarts, max_iter=max_iter, warm_iter=warm_iter)
    tols = _options(joint_chain, dtype, position_tol, orientation_tol, counts)
    search = _Search(max_iter, restarts, warm_iter)
    return _ik_chain_path_jit(
        _validate.cast_leaves(joint_chain, dtype),
        path.astype(dtype),
        tols,
        search,
        bool(use_limits),
    )
