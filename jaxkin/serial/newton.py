"""Textbook Newton-Raphson inverse kinematics of a chain [Pineiro, "Cinemática Inversa Numérica"].

``ik_newton``: given a desired pose ``T_sd`` and a start ``q^0``, [Pineiro]'s iteration::

    V_b = log(T(q^k)^-1 T_sd)            body twist to the target, rows (omega, v)
    body frame: V = V_b, J = J_b(q^k);   space frame: V = Ad(T(q^k)) V_b, J = J_s(q^k)
    q^{k+1} = q^k + J^+ V                until angle(R^T R_d) <= eps_omega, |p_d - p| <= eps_v

The stopping rule bounds the tool's own errors (rotation angle in rad, position distance in
length units) in either frame: ``|v|`` of the space twist is the velocity of the point at the
base origin, not of the tool (docs/errata.md). The step is the damped least-squares step of
``serial._step`` with ``mu = damping^2 + sqrt(eps) trace(J^T J)``, scaled (direction kept) so
that no revolute joint moves more than ``max_step``; with ``limits`` every iterate is clamped
into the box. Every element iterates on its own in one jitted ``lax.scan``; ``NOT_CONVERGED``
elements keep the last iterate, ``INVALID_INPUT`` (NaN/inf in the target or the start) the
start with non-finite entries replaced by 0; a target whose rotation block is not a rotation
(``max |R^T R - I| > sqrt(eps)`` or ``det R <= 0``, ``eps`` of the target's own dtype) is
``INVALID_INPUT`` too: ``OK`` only ever means the tolerances were met on a rigid target. A
target in a less precise dtype than the computation's (float32 targets, float64 joints) is
that pose to its own precision: its rotation block becomes the nearest rotation in the
computation's dtype (``serial._step.promoted_pose``).

This is the iteration as the textbook has it, from the caller's starts; ``jaxkin.ik`` of a
chain is the robot's IK search (``serial.search``: limits, restarts, rates, margins).
"""

from __future__ import annotations

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np
from jax import Array
from jax.typing import ArrayLike

from .. import _validate
from .._execute import Kernel, Policy
from .._numerics import all_finite
from ..result import SolverResult
from ..status import STATUS_DTYPE, Status
from . import _kinematics, _step
from .chain import Chain, positive

__all__ = ["FRAMES", "NewtonIKResult", "ik_newton"]

FRAMES = ("space", "body")


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


@jax.tree_util.register_dataclass
@dataclasses.dataclass(frozen=True)
class _NewtonState:
    """The ``lax.scan`` carry of ``ik_newton``.

    Attributes:
        q: the iterate, ``(..., n)``.
        iterations: updates applied per element, ``int32`` ``(...)``.
        all_done: every element had met the tolerances at the previous check (then the
            FK/Jacobian work is skipped), a scalar bool.
    """

    q: Array
    iterations: Array
    all_done: Array


def _twist_and_jacobian(chain: Chain, q: Array, target: Array, frame: str):
    """Twist to the target ``V`` (update frame, 6 arrays), the Jacobian's columns at ``q`` and
    the tool's position error ``|p_d - p|``; ``|omega|`` of either frame's twist is the
    rotation angle of ``R^T R_d``."""
    rot, p, jac = _kinematics.fk_and_jacobian(chain, q, frame)
    twist, p_bd = _step.body_twist(rot, p, target)
    if frame == "space":
        twist_arr = _kinematics.apply_adjoint(rot, p, jnp.stack(twist, axis=-1)[..., None])
        twist = [twist_arr[..., 0][..., k] for k in range(6)]
    columns = [[jac[..., k, i] for k in range(6)] for i in range(jac.shape[-1])]
    return twist, columns, _step.norm3(p_bd)


def _ik_impl(
    chain: Chain,
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
    # Double-where, step 1: replace invalid elements (NaN, inf, a target that is not a rigid
    # transform) before any arithmetic.
    valid = _step.rigid_target(target) & all_finite(q0)
    target = jnp.where(valid[..., None, None], target, jnp.eye(4, dtype=target.dtype))
    q0 = jnp.clip(jnp.where(jnp.isfinite(q0), q0, 0.0), lower, upper)
    # Revolute coordinates set the step limit; prismatic ones do not.
    revolute = np.array([kind != "prismatic" for kind in chain.joint_kinds])

    def errors(q):
        twist, columns, err_v = _twist_and_jacobian(chain, q, target, frame)
        err_w = _step.norm3(twist[:3])
        done = (err_w <= eps_omega) & (err_v <= eps_v)
        return twist, columns, jnp.stack([err_w, err_v], axis=-1), done | ~valid

    def do_step(state: _NewtonState) -> _NewtonState:
        twist, columns, _, done = errors(state.q)
        step = _step.damped_step_soa(columns, twist, damping)
        dq = _step.limited(jnp.stack(step, axis=-1), revolute, max_step)
        q = jnp.where(done[..., None], state.q, jnp.clip(state.q + dq, lower, upper))
        iterations = state.iterations + (~done).astype(state.iterations.dtype)
        return _NewtonState(q, iterations, jnp.all(done))

    def body(state: _NewtonState, _) -> tuple[_NewtonState, Array]:
        state = jax.lax.cond(
            state.all_done,
            lambda s: _NewtonState(s.q, s.iterations, jnp.array(True)),
            do_step,
            state,
        )
        return state, state.q

    init = _NewtonState(q0, jnp.zeros(batch, jnp.int32), jnp.array(False))
    final, steps = jax.lax.scan(body, init, None, length=max_iter)
    q, iterations = final.q, final.iterations
    history = jnp.concatenate([q0[None], steps], axis=0)
    _, _, err, done = errors(q)
    converged = done & valid
    status = jnp.where(
        ~valid, Status.INVALID_INPUT, jnp.where(converged, Status.OK, Status.NOT_CONVERGED)
    ).astype(STATUS_DTYPE)
    err = jnp.where(valid[..., None], err, 0.0)
    return NewtonIKResult(q, converged, iterations, err, history, status)


_ik_jit = Kernel(
    _ik_impl,
    static=("max_iter", "frame"),
    batched={"target": 2, "q0": 1},
    policy=Policy(pad=True),
    axes={"history": 1},
)


def ik_newton(
    chain: Chain,
    target: ArrayLike,
    q0: ArrayLike,
    eps_omega: float = 1e-3,
    eps_v: float = 1e-4,
    max_iter: int = 20,
    damping: float = 0.0,
    max_step: float | None = 1.0,
    limits: tuple[ArrayLike, ArrayLike] | None = None,
    frame: str = "space",
) -> NewtonIKResult:
    """Newton-Raphson IK [Pineiro], batched, each element converging on its own.

    Args:
        chain: a ``serial.Chain`` (``serial.from_dh``, ``from_screws``, ``from_urdf``).
        target: desired end-effector transforms ``T_sd``, shape ``(..., 4, 4)``.
        q0: seeds, shape ``(..., n)``; batch shapes of ``target`` and ``q0`` broadcast.
        eps_omega: tolerance on the tool's rotation angle to the target (radians), > 0.
        eps_v: tolerance on the tool's distance to the target (length units), > 0.
        max_iter: number of Newton steps (static; ``history`` has ``max_iter + 1`` rows).
        damping: ``lambda >= 0`` of damped least squares; 0 gives the pseudo-inverse step.
        max_step: largest change of a revolute joint in one step (radians), > 0; the step is
            scaled down, direction kept, when longer (module docstring). ``None``: no limit.
        limits: optional ``(lower, upper)`` arrays broadcastable to ``(n,)`` (``+-inf``
            allowed); iterates are clamped into the box. None: no limits (the chain's own are
            ``chain.lower``, ``chain.upper``).
        frame: ``'space'`` or ``'body'`` update (module docstring).

    Returns:
        ``NewtonIKResult`` (``q``, ``converged``, ``iterations``, ``error``, ``history``,
        ``status``); dtype the promotion of ``target``, ``q0`` and the chain.

    Raises:
        ValueError: not a ``Chain``, an unknown ``frame``, shapes that are not
            ``(..., 4, 4)`` / ``(..., n)`` or do not broadcast, non-positive tolerances,
            negative damping, ``max_iter < 0``, non-positive ``max_step``, or
            ``lower > upper``.
    """
    if not isinstance(chain, Chain):
        raise ValueError(f"chain: expected a serial.Chain, got {type(chain).__name__}")
    frame = _validate.choice(frame, "frame", FRAMES)
    max_iter = _validate.count(max_iter, "max_iter", minimum=0)
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
    positive(eps_omega, "eps_omega")
    positive(eps_v, "eps_v")
    positive(damping, "damping", allow_zero=True)
    if max_step is not None:
        positive(max_step, "max_step")
    dtype = jnp.result_type(target, q0, chain.dtype, float)
    if limits is None:
        lower = jnp.full((n,), -jnp.inf, dtype)
        upper = jnp.full((n,), jnp.inf, dtype)
    else:
        try:
            given_lower, given_upper = limits
        except (TypeError, ValueError):
            raise ValueError("limits: expected a pair (lower, upper) of (n,) arrays") from None
        try:
            lower = jnp.broadcast_to(jnp.asarray(given_lower, dtype), (n,))
            upper = jnp.broadcast_to(jnp.asarray(given_upper, dtype), (n,))
        except ValueError:
            raise ValueError(
                f"limits: lower and upper must broadcast to ({n},), got "
                f"{jnp.shape(limits[0])} and {jnp.shape(limits[1])}"
            ) from None
        if _validate.is_concrete(lower) and _validate.is_concrete(upper):
            lo, up = np.asarray(lower), np.asarray(upper)
            if np.any(np.isnan(lo)) or np.any(np.isnan(up)) or np.any(lo > up):
                raise ValueError(f"limits: need lower <= upper (no NaN), got {lo} and {up}")
    chain = _validate.cast_leaves(chain, dtype)
    return _ik_jit(
        chain,
        _step.promoted_pose(target, dtype),
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
