"""Gradient-based trajectory optimisation through the IK kernels, with optax.

A trajectory is a Bezier curve in end-effector space: ``p(s) = sum_i B_i(s) P_i`` with
Bernstein polynomials ``B_i`` of degree ``K - 1`` and ``s = t / duration`` in [0, 1]. The end
control points ``P_0 = start`` and ``P_{K-1} = goal`` are fixed (the curve interpolates them);
the interior points are the parameters. With ``rest_to_rest=True`` ``P_1 = start`` and
``P_{K-2} = goal`` are fixed too, so the path starts and ends with zero velocity. The path's
velocity and acceleration are exact (derivatives of the basis, no finite differences), so
the IK kernels receive an exact ``Jet``.

The cost is user-composable: a callable ``cost(sample) -> (B,)`` where ``sample`` is a
``TrajectorySample`` (joint Jet, status, margin, dt, limits); ``compose`` sums weighted terms.
Terms provided: ``acceleration``, ``jerk``, ``singularity_barrier``, ``limit_penalty``,
``unreachable_penalty``. Gradients flow through the kernels' closed forms; at non-OK samples
the kernels return finite placeholders with finite gradients, and the margin-based penalties
pull the path back into the workspace.

Many initial guesses are optimised at once (a leading batch axis B); each one's cost is
independent, so one optax step on their sum updates each as if alone (for per-coordinate
optimisers such as SGD, Adam, RMSProp).
"""

from __future__ import annotations

import dataclasses
import functools
import math
from collections.abc import Callable
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
import optax
from jax import Array
from jax.typing import ArrayLike

from . import plan
from ._progress import bar, is_active
from .jet import Jet
from .robot import as_robot, ik

__all__ = [
    "DEFAULT_COST",
    "OptimizationResult",
    "TrajectorySample",
    "acceleration",
    "bezier_basis",
    "bezier_path",
    "compose",
    "jerk",
    "limit_penalty",
    "optimize",
    "singularity_barrier",
    "straight_line_guess",
    "unreachable_penalty",
]

PROGRESS_BLOCK = 50  # optimiser steps per compiled block when a progress bar is shown


@jax.tree_util.register_dataclass
@dataclasses.dataclass(frozen=True)
class TrajectorySample:
    """What a cost term sees: the IK of B candidate paths of T samples.

    Attributes:
        q: Jet of joint coordinates, shape ``(B, T, n)``.
        status: ``int8`` statuses, shape ``(B, T)``.
        margin: singularity margin, shape ``(B, T)``.
        dt: sample spacing (scalar).
        limits: ``plan.Limits``.
    """

    q: Jet
    status: Array
    margin: Array
    dt: Array
    limits: plan.Limits


CostTerm = Callable[[TrajectorySample], Array]


def acceleration(sample: TrajectorySample) -> Array:
    """``sum_t |q_ddot|^2 dt`` per candidate (``plan`` calls it integrated_acceleration)."""
    return jnp.sum(sample.q.a**2, axis=(-2, -1)) * sample.dt


def jerk(sample: TrajectorySample) -> Array:
    """``sum_t |jerk|^2 dt`` per candidate, jerk by forward differences of q_ddot."""
    return jnp.sum(plan.jerk(sample.q, sample.dt) ** 2, axis=(-2, -1)) * sample.dt


def singularity_barrier(threshold: float) -> CostTerm:
    """Quadratic barrier ``sum_t (max(0, threshold - margin) / threshold)^2``."""
    if not threshold > 0:
        raise ValueError(f"threshold must be positive, got {threshold!r}")

    def term(sample: TrajectorySample) -> Array:
        return jnp.sum((jax.nn.relu(threshold - sample.margin) / threshold) ** 2, axis=-1)

    return term


def limit_penalty(sample: TrajectorySample) -> Array:
    """``sum_t excess^2`` where ``excess`` is how far q, |q_dot|, |q_ddot| pass their limits."""
    return jnp.sum(plan.limit_excess(sample.q, sample.limits) ** 2, axis=-1)


def unreachable_penalty(sample: TrajectorySample) -> Array:
    """``sum_t max(0, -margin)^2``: the margin is negative outside the workspace."""
    return jnp.sum(jax.nn.relu(-sample.margin) ** 2, axis=-1)


def compose(*weighted_terms: tuple[float, CostTerm]) -> CostTerm:
    """Sum of ``weight * term(sample)`` over ``(weight, term)`` pairs."""

    def cost(sample: TrajectorySample) -> Array:
        return sum(w * term(sample) for w, term in weighted_terms)

    return cost


DEFAULT_COST = compose(
    (1.0, acceleration), (100.0, singularity_barrier(0.05)), (1e6, unreachable_penalty)
)
"""Smooth joint motion, kept away from singularities, and (dominant) inside the workspace.

The weights suit joint units of rad and mm and motions of about a second: near the workspace
boundary joint accelerations grow like ``1 / sin(beta)^3``, so the unreachable penalty must
dominate or the optimiser can settle with samples outside (where rates are 0 placeholders).
"""


# ------------------------------------------------------------------ the path
def bezier_basis(n_ctrl: int, n_samples: int) -> np.ndarray:
    """Bernstein basis and its first two derivatives in ``s``: shape ``(3, n_samples, n_ctrl)``.

    ``B_i(s) = C(K-1, i) s^i (1 - s)^(K-1-i)`` at ``s = linspace(0, 1, n_samples)``; the
    derivatives use ``B'_{i,n} = n (B_{i-1,n-1} - B_{i,n-1})`` (host-side setup, float64).
    """

    def bernstein(degree: int, s: np.ndarray) -> np.ndarray:
        i = np.arange(degree + 1)
        coef = np.array([math.comb(degree, k) for k in i], float)
        return coef * s[:, None] ** i * (1.0 - s[:, None]) ** (degree - i)

    def derivative(values: np.ndarray, degree: int) -> np.ndarray:
        # values: basis of degree - 1 (n_samples, degree); result (n_samples, degree + 1)
        padded = np.pad(values, ((0, 0), (1, 1)))
        return degree * (padded[:, :-1] - padded[:, 1:])

    s = np.linspace(0.0, 1.0, n_samples)
    n = n_ctrl - 1
    b0 = bernstein(n, s)
    b1 = derivative(bernstein(n - 1, s), n) if n >= 1 else np.zeros_like(b0)
    b2 = derivative(derivative(bernstein(n - 2, s), n - 1), n) if n >= 2 else np.zeros_like(b0)
    return np.stack([b0, b1, b2])


def _full_controls(interior: Array, start: Array, goal: Array, rest_to_rest: bool) -> Array:
    batch = interior.shape[:-2]
    ends = [jnp.broadcast_to(x, (*batch, 1, x.shape[-1])) for x in (start, goal)]
    if rest_to_rest:
        ends = [jnp.concatenate([e, e], axis=-2) for e in ends]
    return jnp.concatenate([ends[0], interior, ends[1]], axis=-2)


def bezier_path(controls: Array, basis: Array, duration: float) -> Jet:
    """Jet of the Bezier path, shape ``(..., T, 3)``, from controls ``(..., K, 3)``."""
    p = jnp.einsum("tk,...kc->...tc", basis[0], controls)
    v = jnp.einsum("tk,...kc->...tc", basis[1], controls) / duration
    a = jnp.einsum("tk,...kc->...tc", basis[2], controls) / duration**2
    return Jet(p, v, a)


@jax.tree_util.register_dataclass
@dataclasses.dataclass(frozen=True)
class OptimizationResult:
    """Result of ``optimize``.

    Attributes:
        controls: all Bezier control points (ends included), shape ``(B, K, 3)``.
        path: Jet of the optimised paths, shape ``(B, T, 3)``.
        history: cost of every candidate before each step and after the last, shape
            ``(steps + 1, B)``.
        evaluation: ``plan.Evaluation`` of the optimised paths.
    """

    controls: Array
    path: Jet
    history: Array
    evaluation: plan.Evaluation


def straight_line_guess(
    start: ArrayLike, goal: ArrayLike, n_interior: int, n_guesses: int = 1, noise=0.0, seed=0
) -> np.ndarray:
    """Interior control points on the segment start-goal, plus Gaussian noise: (B, K-2, d)."""
    start, goal = np.asarray(start, float), np.asarray(goal, float)
    s = np.linspace(0.0, 1.0, n_interior + 2)[1:-1, None]
    line = start + s * (goal - start)
    rng = np.random.default_rng(seed)
    return line + noise * rng.normal(size=(n_guesses, n_interior, start.shape[-1]))


def optimize(
    robot: Any,
    start: ArrayLike,
    goal: ArrayLike,
    interior: ArrayLike,
    duration: float = 1.0,
    n_samples: int = 100,
    optimizer: optax.GradientTransformation | None = None,
    steps: int = 200,
    cost: CostTerm = DEFAULT_COST,
    branch: Any = None,
    limits: plan.Limits | None = None,
    rest_to_rest: bool = False,
    progress: bool | None = None,
) -> OptimizationResult:
    """Optimise B trajectories from ``start`` to ``goal`` at once.

    Args:
        robot: any robot of the protocol whose targets are points (``robot.target``).
        start, goal: end-effector positions, shape ``robot.target.shape``: fixed.
        interior: initial interior control points, shape ``(B, K', d)`` or ``(K', d)``; every
            guess must be finite (a ``ValueError`` names the guesses that are not).
        duration: motion time; ``n_samples`` samples are taken uniformly in [0, duration].
        optimizer: any optax transformation (default ``optax.adam(1e-2 * scale)`` with
            ``scale = |goal - start|``).
        steps: optimiser steps, all inside one jitted ``lax.scan``.
        cost: ``cost(TrajectorySample) -> (B,)``; default ``DEFAULT_COST``.
        branch: the branch held along the path (one of ``robot.branches``; None for the
            default).
        limits: ``plan.Limits`` for limit penalties and the final evaluation.
        rest_to_rest: also fix the second and second-to-last control points.
        progress: show a progress bar (default: only when stderr is a terminal; False never,
            and then all steps run in a single compiled scan).

    Returns:
        ``OptimizationResult``.
    """
    robot = as_robot(robot)
    if not robot.target.is_point:
        raise ValueError(
            f"optimize needs a robot whose targets are points; {type(robot).__name__}'s are "
            f"{robot.target.name}s"
        )
    mode = robot.check_branch(branch)
    dims = robot.target.shape[0]
    start = jnp.asarray(start, float)
    goal = jnp.asarray(goal, float)
    for name, x in (("start", start), ("goal", goal)):
        if x.shape != (dims,):
            raise ValueError(f"{name}: expected shape ({dims},), got {x.shape}")
    interior = jnp.asarray(interior, float)
    if interior.ndim == 2:
        interior = interior[None]
    if interior.ndim != 3 or interior.shape[-1] != dims or interior.shape[1] < 1:
        raise ValueError(
            f"interior: expected shape (B, K', {dims}) with K' >= 1, got {interior.shape}"
        )
    for name, x in (("start", start), ("goal", goal)):
        if not bool(jnp.all(jnp.isfinite(x))):
            raise ValueError(f"{name} must be finite, got {np.asarray(x)}")
    bad = np.flatnonzero(~np.all(np.isfinite(np.asarray(interior)), axis=(1, 2)))
    if bad.size:
        raise ValueError(
            f"interior: initial guess(es) {bad.tolist()} hold NaN or inf (every guess must be "
            "finite: a NaN would come back as NaN controls)"
        )
    if not (duration > 0 and n_samples >= 3 and steps >= 0):
        raise ValueError("need duration > 0, n_samples >= 3 and steps >= 0")
    n_ctrl = interior.shape[1] + 2 + (2 if rest_to_rest else 0)
    basis = jnp.asarray(bezier_basis(n_ctrl, n_samples), interior.dtype)
    dt = duration / (n_samples - 1)
    limits = plan.robot_limits(robot, limits)
    if optimizer is None:
        optimizer = optax.adam(1e-2 * float(jnp.linalg.norm(goal - start)))
    # The steps run as jitted lax.scan blocks; between blocks a progress bar is updated
    # (drawn only on a terminal). Blocks of one size share one compilation.
    args = (robot, start, goal, basis, duration, dt, limits, optimizer, cost, mode, rest_to_rest)
    ctrl, opt_state = interior, optimizer.init(interior)
    histories = []
    block = min(steps, PROGRESS_BLOCK) if is_active(progress) else steps
    with bar(steps, "optimize", enabled=progress) as meter:
        done = 0
        while done < steps:
            n = min(block, steps - done)
            ctrl, opt_state, values = _run(ctrl, opt_state, *args, steps=n)
            histories.append(values)
            done += n
            meter.update(n)
    final = _final_cost(ctrl, *args)
    history = jnp.concatenate([*histories, final[None]], axis=0)
    controls = _full_controls(ctrl, start, goal, rest_to_rest)
    path = bezier_path(controls, basis, duration)
    evaluation = plan.evaluate(robot, path, limits=limits, branch=mode, dt=dt)
    return OptimizationResult(controls, path, history, evaluation)


def _sample(robot, controls, basis, duration, dt, limits, mode) -> TrajectorySample:
    res = ik(robot, bezier_path(controls, basis, duration), mode)
    return TrajectorySample(res.q, res.status, res.margin, jnp.asarray(dt, controls.dtype), limits)


def _per_candidate(params, robot, start, goal, basis, duration, dt, limits, cost, mode, rest):
    controls = _full_controls(params, start, goal, rest)
    return cost(_sample(robot, controls, basis, duration, dt, limits, mode))


_STATIC = ("optimizer", "cost", "mode", "rest_to_rest")


@functools.partial(jax.jit, static_argnames=(*_STATIC, "steps"))
def _run(
    params,
    opt_state,
    robot,
    start,
    goal,
    basis,
    duration,
    dt,
    limits,
    optimizer,
    cost,
    mode,
    rest_to_rest,
    steps,
):
    """``steps`` optimiser steps in one ``lax.scan``; returns the costs before each step."""

    def total(p):
        values = _per_candidate(
            p, robot, start, goal, basis, duration, dt, limits, cost, mode, rest_to_rest
        )
        return jnp.sum(values), values

    grad_fn = jax.value_and_grad(total, has_aux=True)

    def step(carry, _):
        p, state = carry
        (_, values), grads = grad_fn(p)
        updates, state = optimizer.update(grads, state, p)
        return (optax.apply_updates(p, updates), state), values

    (params, opt_state), history = jax.lax.scan(step, (params, opt_state), None, length=steps)
    return params, opt_state, history


@functools.partial(jax.jit, static_argnames=_STATIC)
def _final_cost(
    params, robot, start, goal, basis, duration, dt, limits, optimizer, cost, mode, rest_to_rest
):
    del optimizer
    return _per_candidate(
        params, robot, start, goal, basis, duration, dt, limits, cost, mode, rest_to_rest
    )
