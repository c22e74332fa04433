"""Trajectory optimisation through the IK kernels: per-guess L-BFGS (or any optax method).

A trajectory is a Bezier curve in task space (``jaxkin.paths.bezier_path``): ``p(s) = sum_i
B_i(s) P_i`` with Bernstein polynomials ``B_i`` of degree ``K - 1`` and ``s = t / duration``.
The end control points are ``start`` and ``goal`` (with ``rest_to_rest`` the second and
second-to-last too, so the path starts and ends at rest); the interior points are the
parameters. Rates are exact derivatives of the basis, so the IK kernels receive an exact
``Jet``.

Every guess is optimised on its own (``jax.vmap`` of one guess's update): each has its own
L-BFGS history and line search (the default, ``LBFGS()``, optax's ``lbfgs`` with a zoom line
search), or its own Adam moments. The loop runs compiled (``lax.while_loop`` over a
``LoopState``) until every guess has stopped: its gradient norm is below ``gtol * (1 + |f|)``
or its cost changed by less than ``ftol`` relatively in a step (``converged``), or ``steps``
were taken. The parameters are the interior points in units of the robot's size.

The cost is ``cost(TrajectorySample) -> (B,)``, built from the terms of ``jaxkin.costs``
(``compose``; default ``costs.DEFAULT_COST``). Costs and methods are described by value
(frozen dataclasses; a cost's weights, thresholds and obstacle positions are array data), so a
new start, goal, guess, weight or obstacle position reuses the compilation; only a new
*structure* compiles.
"""

from __future__ import annotations

import dataclasses
import functools
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
import optax
from jax import Array
from jax.typing import ArrayLike

from . import _batching, _processes, paths, plan
from ._progress import bar, is_active
from .costs import DEFAULT_COST, CostTerm, TrajectorySample
from .jet import Jet
from .robot import Robot, as_robot, fk, ik

__all__ = ["LBFGS", "Adam", "LoopState", "OptimizationResult", "optimize"]

PROGRESS_BLOCK = 50  # optimiser steps per compiled call when a progress bar is shown


# ------------------------------------------------------------------ methods
@dataclasses.dataclass(frozen=True)
class LBFGS:
    """L-BFGS per guess (``optax.lbfgs``: ``memory`` pairs, a zoom line search of at most
    ``linesearch_steps`` evaluations). The default method."""

    memory: int = 10
    linesearch_steps: int = 20

    def transformation(self) -> optax.GradientTransformationExtraArgs:
        # A quasi-Newton step starts its line search at 1 ("one"), not at the last step length.
        search = optax.scale_by_zoom_linesearch(
            max_linesearch_steps=self.linesearch_steps, initial_guess_strategy="one"
        )
        return optax.lbfgs(memory_size=self.memory, linesearch=search)


@dataclasses.dataclass(frozen=True)
class Adam:
    """Adam per guess with a step of ``learning_rate`` (in units of the robot's size)."""

    learning_rate: float = 1e-2

    def transformation(self) -> optax.GradientTransformationExtraArgs:
        return optax.with_extra_args_support(optax.adam(self.learning_rate))


# ------------------------------------------------------------------ the result
@jax.tree_util.register_dataclass
@dataclasses.dataclass(frozen=True)
class OptimizationResult:
    """Result of ``optimize``.

    Attributes:
        controls: all Bezier control points (ends included), shape ``(B, K, d)``.
        path: Jet of the optimised paths, shape ``(B, T, d)``.
        cost: the final cost of each guess, shape ``(B,)``.
        history: the cost of each guess before every step and after the last, ``(steps + 1,
            B)`` (held constant once a guess has stopped).
        converged: each guess met a stopping rule (gradient norm or cost change), ``(B,)``.
        iterations: steps taken by each guess, ``(B,)``.
        grad_norm: the final gradient norm (with respect to the interior points in units of the
            robot's size), ``(B,)``.
        best: the index of the best guess: the feasible one of least cost (or of least cost if
            none is feasible), an ``int32`` scalar.
        evaluation: ``plan.Evaluation`` of the optimised paths.

    With several devices (one process or many, ``jax.distributed``) every array is global,
    split along the guess axis (``history`` along its second axis; replicated when B is not a
    multiple of ``jax.device_count()``), and ``best`` is the global index on every process.
    """

    controls: Array
    path: Jet
    cost: Array
    history: Array
    converged: Array
    iterations: Array
    grad_norm: Array
    best: Array
    evaluation: plan.Evaluation


def _sample(robot, controls, basis, duration, dt, limits, branch) -> TrajectorySample:
    path = paths.bezier_path(controls, basis, duration)
    res = ik(robot, path, branch)
    dt = jnp.asarray(dt, controls.dtype)
    return TrajectorySample(res.q, res.status, res.margin, dt, limits, path, robot)


@dataclasses.dataclass(frozen=True)
class _Static:
    """Everything that shapes the compiled loop (hashable)."""

    method: Any
    cost: Any  # the cost itself when it is not array data, else None
    cost_treedef: Any
    branch: Any
    rest_to_rest: bool
    steps: int


def _objective(x: Array, data: dict, static: _Static) -> Array:
    """One guess's cost at interior points ``x`` ``(K', d)`` in units of the robot's size."""
    cost = static.cost
    if cost is None:
        cost = jax.tree.unflatten(static.cost_treedef, data["cost"])
    interior = (x * data["scale"])[None]
    controls = paths.bezier_controls(interior, data["start"], data["goal"], static.rest_to_rest)
    sample = _sample(
        data["robot"],
        controls,
        data["basis"],
        data["duration"],
        data["dt"],
        data["limits"],
        static.branch,
    )
    return cost(sample)[0]


def _transformation(method: Any) -> Any:
    if isinstance(method, LBFGS | Adam):
        return method.transformation()
    return optax.with_extra_args_support(method)


@jax.tree_util.register_dataclass
@dataclasses.dataclass(frozen=True)
class LoopState:
    """The optimiser loop's state for B guesses (the ``lax.while_loop`` carry).

    Attributes:
        x: interior control points in units of the robot's size, ``(B, K', d)``.
        opt_state: the optax state of each guess (leaves with a leading ``B`` axis).
        f: each guess's cost at ``x``, ``(B,)``.
        g: the gradient of ``f`` with respect to ``x``, ``(B, K', d)``.
        done: the guess has stopped (converged, or a non-finite step), ``(B,)``.
        converged: the guess met a stopping rule, ``(B,)``.
        iterations: steps the guess took, ``int32`` ``(B,)``.
        step: steps the loop ran, an ``int32`` scalar.
        history: ``f`` before every step and after the last, ``(steps + 1, B)``.
    """

    x: Array
    opt_state: Any
    f: Array
    g: Array
    done: Array
    converged: Array
    iterations: Array
    step: Array
    history: Array


@functools.partial(jax.jit, static_argnames="static")
def _start(x: Array, data: dict, static: _Static) -> LoopState:
    """The loop's initial state for guesses ``x`` ``(B, K', d)``."""
    value_and_grad = jax.value_and_grad(_objective)
    f, g = jax.vmap(lambda xb: value_and_grad(xb, data, static))(x)
    opt_state = jax.vmap(_transformation(static.method).init)(x)
    batch = x.shape[0]
    history = jnp.broadcast_to(f, (static.steps + 1, batch))
    done = ~jnp.isfinite(f)
    zeros = jnp.zeros(batch, jnp.int32)
    return LoopState(x, opt_state, f, g, done, jnp.zeros(batch, bool), zeros, jnp.int32(0), history)


@functools.partial(jax.jit, static_argnames="static")
def _run(initial: LoopState, data: dict, stop: Array, static: _Static) -> LoopState:
    """Steps until every guess has stopped, ``static.steps`` were taken, or step ``stop``."""
    tx = _transformation(static.method)
    value_and_grad = jax.value_and_grad(_objective)
    gtol, ftol = data["gtol"], data["ftol"]

    def one_step(x, state, f, g):
        def value_fn(y):
            return _objective(y, data, static)

        updates, state = tx.update(g, state, x, value=f, grad=g, value_fn=value_fn)
        x = optax.apply_updates(x, updates)
        if isinstance(static.method, LBFGS):
            # the line search evaluated the accepted point already: reuse, not re-trace
            f_new = optax.tree_utils.tree_get(state, "value")
            g_new = optax.tree_utils.tree_get(state, "grad")
        else:
            f_new, g_new = value_and_grad(x, data, static)
        return x, state, f_new, g_new

    def cond(loop: LoopState) -> Array:
        return (loop.step < jnp.minimum(stop, static.steps)) & ~jnp.all(loop.done)

    def body(loop: LoopState) -> LoopState:
        x, state, f, g = loop.x, loop.opt_state, loop.f, loop.g
        x_new, state_new, f_new, g_new = jax.vmap(one_step)(x, state, f, g)
        good = jnp.isfinite(f_new) & jnp.all(jnp.isfinite(g_new), axis=(-2, -1))
        take = ~loop.done & good

        def choose(new, old):
            mask = take.reshape(take.shape + (1,) * (jnp.ndim(new) - 1))
            return jnp.where(mask, new, old)

        x, state, f_next, g = jax.tree.map(
            choose, (x_new, state_new, f_new, g_new), (x, state, f, g)
        )
        grad_norm = jnp.sqrt(jnp.sum(g * g, axis=(-2, -1)))
        change = jnp.abs(f - f_next) <= ftol * jnp.maximum(jnp.abs(f), jnp.abs(f_next))
        met = take & ((grad_norm <= gtol * (1.0 + jnp.abs(f_next))) | change)
        return LoopState(
            x=x,
            opt_state=state,
            f=f_next,
            g=g,
            done=loop.done | met | ~good,
            converged=loop.converged | met,
            iterations=loop.iterations + take.astype(jnp.int32),
            step=loop.step + 1,
            history=loop.history.at[loop.step + 1].set(f_next),
        )

    return jax.lax.while_loop(cond, body, initial)


def optimize(
    robot: Robot,
    start: ArrayLike,
    goal: ArrayLike,
    interior: ArrayLike,
    duration: float = 1.0,
    n_samples: int = 100,
    optimizer: Any = None,
    steps: int = 500,
    cost: CostTerm = DEFAULT_COST,
    branch: Any = None,
    limits: plan.Limits | None = None,
    rest_to_rest: bool = False,
    space: str = "task",
    gtol: float | None = None,
    ftol: float | None = None,
    progress: bool | None = None,
) -> OptimizationResult:
    """Optimise B trajectories from ``start`` to ``goal`` at once, each guess on its own.

    Args:
        robot: any robot of the protocol whose targets are points (``robot.target``).
        start, goal: end points, shape ``robot.target.shape`` (``space="task"``), or joint
            vectors ``(n_joints,)`` (``space="joint"``: their forward kinematics).
        interior: initial interior control points, shape ``(B, K', d)`` or ``(K', d)``; every
            guess must be finite (a ``ValueError`` names the guesses that are not). Host data
            (the same on every process), or a global ``jax.Array`` split along the guesses:
            with several devices each runs its own guesses' loop.
        duration: motion time; ``n_samples`` samples are taken uniformly in [0, duration].
        optimizer: ``LBFGS()`` (default) or ``Adam(...)`` (described by value: no new
            compilation), or any optax transformation (a new object compiles anew: keep one).
        steps: the most steps a guess takes.
        cost: ``cost(TrajectorySample) -> (B,)``; default ``DEFAULT_COST``. A ``compose``-d
            cost's weights, thresholds and obstacles are data; a plain function is static.
        branch: the branch held along the path (None: the default).
        limits: ``plan.Limits`` for limit penalties and the final evaluation.
        rest_to_rest: also fix the second and second-to-last control points.
        space: ``"task"`` or ``"joint"`` (the meaning of ``start`` and ``goal``).
        gtol, ftol: stopping rules per guess: ``|grad| <= gtol (1 + |f|)`` or a relative cost
            change ``<= ftol`` in one step; None for ``max(1e-7, 1000 eps)`` and
            ``max(1e-10, 8 eps)`` (float64: 1e-7 and 1e-10, which reach the optimum of the
            benchmark problems to 1e-8 relative; float32: 1.2e-4 and 9.5e-7).
        progress: show a progress bar (default: only when stderr is a terminal).

    Returns:
        ``OptimizationResult``.

    Raises:
        ValueError: a robot whose targets are not points, shapes that do not match, non-finite
            start, goal or guesses, or bad numeric options (each named).
    """
    robot = as_robot(robot)
    if not robot.target.is_point:
        raise ValueError(
            f"optimize needs a robot whose targets are points; {type(robot).__name__}'s are "
            f"{robot.target.name}s"
        )
    branch = robot.check_branch(branch)
    dims = robot.target.shape[0]
    if space not in ("task", "joint"):
        raise ValueError(f"space must be 'task' or 'joint', got {space!r}")
    start = jnp.asarray(start, float)
    goal = jnp.asarray(goal, float)
    want = (robot.n_joints,) if space == "joint" else (dims,)
    for name, x in (("start", start), ("goal", goal)):
        if x.shape != want:
            raise ValueError(f"{name}: expected shape {want} ({space} space), got {x.shape}")
        if not bool(jnp.all(jnp.isfinite(x))):
            raise ValueError(f"{name} must be finite, got {np.asarray(x)}")
    if space == "joint":
        start, goal = (fk(robot, x).x.p for x in (start, goal))
    interior = jnp.asarray(interior, float)
    if interior.ndim == 2:
        interior = interior[None]
    if interior.ndim != 3 or interior.shape[-1] != dims or interior.shape[1] < 1:
        raise ValueError(
            f"interior: expected shape (B, K', {dims}) with K' >= 1, got {interior.shape}"
        )
    bad = np.concatenate(
        [
            start + np.flatnonzero(~np.all(np.isfinite(rows), axis=(1, 2)))
            for start, rows in _processes.local_rows(interior)
        ]
    )
    if not _processes.fetchable(interior):  # split over processes: every process must raise
        bad = np.unique(_processes.allgather_rows(bad))
    if bad.size:
        raise ValueError(
            f"interior: initial guess(es) {bad.tolist()} hold NaN or inf (every guess must be "
            "finite: a NaN would come back as NaN controls)"
        )
    for name, value, low in (("n_samples", n_samples, 3), ("steps", steps, 0)):
        if isinstance(value, bool) or not isinstance(value, int) or value < low:
            raise ValueError(f"{name} must be an int >= {low}, got {value!r}")
    epsilon = float(jnp.finfo(interior.dtype).eps)
    gtol = max(1e-7, 1000 * epsilon) if gtol is None else gtol
    ftol = max(1e-10, 8 * epsilon) if ftol is None else ftol
    for name, value in (("duration", duration), ("gtol", gtol), ("ftol", ftol)):
        if isinstance(value, bool) or not (isinstance(value, int | float) and value >= 0):
            raise ValueError(f"{name} must be a non-negative number, got {value!r}")
    if not duration > 0:
        raise ValueError(f"duration must be positive, got {duration!r}")
    method = LBFGS() if optimizer is None else optimizer
    n_ctrl = interior.shape[1] + 2 + (2 if rest_to_rest else 0)
    dtype = interior.dtype
    basis = jnp.asarray(paths.bezier_basis(n_ctrl, n_samples), dtype)
    dt = duration / (n_samples - 1)
    limits = plan.robot_limits(robot, limits)
    leaves, treedef = jax.tree.flatten(cost)
    is_data = all(isinstance(leaf, jax.Array | np.ndarray | float | int) for leaf in leaves)
    static = _Static(
        method,
        None if is_data else cost,
        treedef if is_data else None,
        branch,
        bool(rest_to_rest),
        steps,
    )
    scale = jnp.asarray(robot.length_scale(), dtype)
    data = dict(
        robot=robot,
        start=start.astype(dtype),
        goal=goal.astype(dtype),
        basis=basis,
        duration=jnp.asarray(duration, dtype),
        dt=jnp.asarray(dt, dtype),
        limits=limits,
        cost=[jnp.asarray(leaf, dtype) for leaf in leaves] if is_data else [],
        scale=scale,
        gtol=jnp.asarray(gtol, dtype),
        ftol=jnp.asarray(ftol, dtype),
    )

    def run(guesses: Array) -> tuple:
        """The guesses ``(b, K', d)`` of one device optimised, per-guess results leading."""
        loop = _start(guesses / scale, data, static)
        block = min(steps, PROGRESS_BLOCK) if is_active(progress) else steps
        with bar(steps, "optimize", enabled=progress) as meter:
            done_steps = 0
            while done_steps < steps:
                loop = _run(loop, data, jnp.int32(done_steps + block), static)
                reached = int(loop.step)
                meter.update(reached - done_steps)
                if reached < done_steps + block:  # every guess has stopped
                    break
                done_steps = reached
        x, f, g = loop.x, loop.f, loop.g
        history = jnp.where(jnp.arange(steps + 1)[:, None] > loop.step, f, loop.history)
        controls = paths.bezier_controls(x * scale, data["start"], data["goal"], rest_to_rest)
        path = paths.bezier_path(controls, basis, duration)
        grad_norm = jnp.sqrt(jnp.sum(g * g, axis=(-2, -1)))
        return controls, path, f, history.T, loop.converged, loop.iterations, grad_norm

    # A guess's steps never depend on the others' (a stopped guess is held), so each device
    # runs its own guesses' loop to its own end.
    controls, path, f, history, converged, iterations, grad_norm = _batching.map_candidates(
        run, interior, interior.shape[0], name="interior"
    )
    history = history.T
    evaluation = plan.evaluate(robot, path, limits=limits, branch=branch, dt=dt)
    ranked = jnp.where(evaluation.feasible, f, jnp.inf)
    best = jnp.where(jnp.any(evaluation.feasible), jnp.argmin(ranked), jnp.argmin(f))
    return OptimizationResult(
        controls,
        path,
        f,
        history,
        converged,
        iterations,
        grad_norm,
        best.astype(jnp.int32),
        evaluation,
    )
