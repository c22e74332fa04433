"""Trajectory optimisation through the kinematics kernels: per-guess L-BFGS (or any optax method).

A trajectory is a Bezier curve ``c(s) = sum_i B_i(s) P_i`` with Bernstein polynomials ``B_i``
of degree ``K - 1`` and ``s = t / duration`` (``jaxkin.paths.bezier_path``). Its control points
live in one of two spaces (``controls``):

- ``"task"`` (robots whose targets are points): ``c`` is the tool's path; the joints come from
  the IK kernels along it (the branch held), with exact rates, so the cost sees an exact joint
  ``Jet``;
- ``"joint"`` (every robot; the default for robots whose targets are poses: URDF chains, the
  PUMA 560, the Stanford arm): ``c`` is the joint trajectory itself and the tool's path comes
  from the forward kinematics with rates. No IK runs inside the loop, so the path cannot leave
  the workspace or switch solution, and the joints are continuous by construction.

The end control points are ``start`` and ``goal`` (with ``rest_to_rest`` the second and
second-to-last too, so the path starts and ends at rest); the interior points are the
parameters, in units of the robot's size (task space and prismatic joints) or radians.
Pose ends of a joint-space problem are solved once by the IK (host side) on ``branch``.

Every guess is optimised on its own (``jax.vmap`` of one guess's update): every method is an
optax transformation of one guess's interior points (``init(params)``, ``update(grads, state,
params, value=..., value_fn=...)``). The default, ``LBFGS()`` (``jaxkin._lbfgs``), keeps each
guess's own L-BFGS memory (``LBFGSState``) and backtracking line search and evaluates one trial
point per running guess per loop iteration, so the guesses advance independently; ``Adam``
and other optax methods take one step per iteration. The loop runs compiled
(``lax.while_loop`` over a ``LoopState``) until every guess has stopped. Per guess (``Stop``):

- ``CONVERGED``: its gradient norm is below ``gtol * (1 + |f|)`` or its cost changed by less
  than ``ftol`` relatively in a step;
- ``MAX_STEPS``: ``steps`` were taken first;
- ``NO_DESCENT`` (L-BFGS): the line search found no point of sufficiently lower cost in
  ``linesearch_steps`` trials; the guess's memory is cleared and it goes on from the same
  point by steepest descent; a second failure in a row stops it there;
- ``DIVERGED``: a non-finite initial cost (or, for optax methods, a non-finite step), a final
  cost above ``BLOWN_UP`` (1000) times the initial one, or control points more than
  ``DIVERGED_SIZES`` (10) robot sizes outside the robot's workspace box (task space; the
  ends' box padded by the robot's size when it has none) or more than that many radians (or
  sizes, for prismatic joints) outside the joint limits or the ends' range (joint space).

``converged`` is true only for ``CONVERGED``: the stopping rule held at a finite cost that did
not blow up, with every control point near the workspace.

The cost is ``cost(TrajectorySample) -> (B,)``, built from the terms of ``jaxkin.costs``
(``compose``; default ``costs.DEFAULT_COST``). Costs and methods are described by value
(frozen dataclasses; a cost's weights, thresholds and obstacle positions are array data), so a
new start, goal, guess, weight or obstacle position reuses the compilation; only a new
*structure* compiles.
"""

from __future__ import annotations

import dataclasses
import enum
import functools
import math
from collections.abc import Sequence
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
import optax
from jax import Array
from jax.typing import ArrayLike

from . import _processes, _validate, paths, plan
from ._execute import as_robot, fk, ik, kernel, map_candidates
from ._lbfgs import LBFGS, LBFGSState
from .costs import DEFAULT_COST, CostTerm, TrajectorySample, bind
from .jet import Jet
from .robot import Robot
from .status import STATUS_DTYPE, Status

__all__ = [
    "DIVERGED_SIZES",
    "LBFGS",
    "Adam",
    "LBFGSState",
    "LoopState",
    "OptimizationResult",
    "Stop",
    "optimize",
]

PROGRESS_BLOCK = 50  # optimiser steps per compiled call when progress is reported
DIVERGED_SIZES = 10.0  # control points this many robot sizes (or radians) out have diverged
BLOWN_UP = 1000.0  # a final cost this many times the initial one has diverged


class Stop(enum.IntEnum):
    """Why a guess stopped (``OptimizationResult.stop``; module docstring)."""

    CONVERGED = 0
    MAX_STEPS = 1
    NO_DESCENT = 2
    DIVERGED = 3


# ------------------------------------------------------------------ methods
@dataclasses.dataclass(frozen=True)
class Adam:
    """Adam per guess with a step of ``learning_rate`` (in units of the robot's size)."""

    learning_rate: float = 1e-2

    def transformation(self) -> optax.GradientTransformationExtraArgs:
        return optax.with_extra_args_support(optax.adam(self.learning_rate))


def _transformation(method: Any) -> Any:
    """One guess's optax transformation: ``LBFGS`` itself (it takes ``value_fn``), ``Adam``'s,
    or any optax transformation given."""
    if isinstance(method, LBFGS):
        return method
    if isinstance(method, Adam):
        return method.transformation()
    return optax.with_extra_args_support(method)


# ------------------------------------------------------------------ the result
@jax.tree_util.register_dataclass
@dataclasses.dataclass(frozen=True)
class OptimizationResult:
    """Result of ``optimize``.

    Attributes:
        controls: all Bezier control points (ends included), shape ``(B, K, d)``: tool
            positions (``controls="task"``, ``d`` the target's size) or joints (``"joint"``,
            ``d = n_joints``).
        path: Jet of the optimised tool paths, shape ``(B, T, *robot.target.shape)``.
        cost: the final cost of each guess, shape ``(B,)``.
        history: the cost of each guess before every step and after the last, ``(steps + 1,
            B)`` (held constant once a guess has stopped).
        converged: each guess met a stopping rule at a finite cost that did not blow up, near
            the workspace (``stop == Stop.CONVERGED``), ``(B,)``.
        stop: why each guess stopped, ``int8`` codes of ``Stop``, ``(B,)``.
        iterations: steps taken by each guess, ``(B,)``.
        grad_norm: the final gradient norm (with respect to the interior points in units of the
            robot's size, or radians), ``(B,)``.
        best: the index of the best guess: the feasible one of least cost (or of least cost if
            none is feasible), an ``int32`` scalar.
        evaluation: ``plan.Evaluation`` of the optimised trajectories; its joint trajectories
            ``evaluation.q`` are continuous (revolute joints unwrapped).

    With several devices (one process or many, ``jax.distributed``) every array is global,
    split along the guess axis (``history`` along its second axis; replicated when B is not a
    multiple of ``jax.device_count()``), and ``best`` is the global index on every process.
    """

    controls: Array
    path: Jet
    cost: Array
    history: Array
    converged: Array
    stop: Array
    iterations: Array
    grad_norm: Array
    best: Array
    evaluation: plan.Evaluation


def _revolute(robot: Robot) -> np.ndarray:
    return np.array([kind == "R" for kind in robot.joint_types])


def _sample(robot, controls, basis, duration, dt, limits, branch) -> TrajectorySample:
    """Task-space controls: the tool's Bezier path and its IK (revolute joints unwrapped)."""
    path = paths.bezier_path(controls, basis, duration)
    res = ik(robot, path, branch)
    q = Jet(plan.unwrapped(res.q.p, _revolute(robot)), res.q.v, res.q.a)
    dt = jnp.asarray(dt, controls.dtype)
    return TrajectorySample(q, res.status, res.margin, dt, limits, path, robot)


def _joint_sample(robot, controls, basis, duration, dt, limits) -> TrajectorySample:
    """Joint-space controls: the joints' Bezier curve and its forward kinematics. The margin
    is ``+inf`` (no IK runs: the singularity and workspace terms see nothing)."""
    q = paths.bezier_path(controls, basis, duration)
    res = fk(robot, q)
    margin = jnp.full(res.status.shape, jnp.inf, controls.dtype)
    dt = jnp.asarray(dt, controls.dtype)
    return TrajectorySample(q, res.status, margin, dt, limits, res.x, robot)


@dataclasses.dataclass(frozen=True)
class _Static:
    """Everything that shapes the compiled loop (hashable)."""

    method: Any
    cost: Any  # the cost itself when it is not array data, else None
    cost_treedef: Any
    branch: Any
    rest_to_rest: bool
    steps: int
    joint: bool = False  # control points in joint space


@jax.tree_util.register_dataclass
@dataclasses.dataclass(frozen=True)
class _Data:
    """The loop's array data (a new start, goal, weight or obstacle position: no compilation).

    Attributes:
        robot: the robot (a geometry pytree).
        start, goal: the end control points, ``(d,)``.
        basis: the Bernstein basis and its derivatives at the samples (``paths.bezier_basis``).
        duration, dt: the motion time and the sample period.
        limits: ``plan.Limits``, the robot's own intersected with the caller's.
        cost: the cost's array leaves when it is data (``_Static.cost_treedef``), else empty.
        scale: the unit of the interior points (the robot's size; radians for revolute joints
            in joint space).
        gtol, ftol: the stopping rules' tolerances.
        box: ``(lo, hi, unit)`` the control points should stay near (``_box``).
    """

    robot: Robot
    start: Array
    goal: Array
    basis: Array
    duration: Array
    dt: Array
    limits: plan.Limits
    cost: list
    scale: Array
    gtol: Array
    ftol: Array
    box: tuple


def _controls(x: Array, data: _Data, static: _Static) -> Array:
    interior = x * data.scale
    return paths.bezier_controls(interior, data.start, data.goal, static.rest_to_rest)


def _trajectory(x: Array, data: _Data, static: _Static) -> TrajectorySample:
    controls = _controls(x, data, static)
    args = (data.robot, controls, data.basis, data.duration, data.dt, data.limits)
    if static.joint:
        return _joint_sample(*args)
    return _sample(*args, static.branch)


def _objective(x: Array, data: _Data, static: _Static) -> Array:
    """One guess's cost at interior points ``x`` ``(K', d)`` in units of the robot's size."""
    cost = static.cost
    if cost is None:
        cost = jax.tree.unflatten(static.cost_treedef, data.cost)
    return cost(_trajectory(x[None], data, static))[0]


# ------------------------------------------------------------------ the loop
@jax.tree_util.register_dataclass
@dataclasses.dataclass(frozen=True)
class LoopState:
    """The optimiser loop's state for B guesses (the ``lax.while_loop`` carry).

    Attributes:
        x: interior control points in units of the robot's size, ``(B, K', d)``.
        opt_state: each guess's state of the method (``LBFGSState`` or an optax state; leaves
            with a leading ``B`` axis).
        f: each guess's cost at ``x``, ``(B,)``.
        g: the gradient of ``f`` with respect to ``x``, ``(B, K', d)``.
        done: the guess has stopped, ``(B,)``.
        stop: why it stopped (``Stop``; ``MAX_STEPS`` while it runs), ``int8`` ``(B,)``.
        iterations: steps the guess took, ``int32`` ``(B,)``.
        evaluations: cost-and-gradient evaluations of the guess (line searches included),
            ``int32`` ``(B,)``.
        batched: evaluations of the whole batch the loop ran (per step the most any running
            guess's line search took), an ``int32`` scalar: the loop's cost.
        step: steps the loop ran, an ``int32`` scalar.
        history: ``f`` before every step and after the last, ``(steps + 1, B)``.
    """

    x: Array
    opt_state: Any
    f: Array
    g: Array
    done: Array
    stop: Array
    iterations: Array
    evaluations: Array
    batched: Array
    step: Array
    history: Array


@kernel(static=("static",))
def _start(x: Array, data: _Data, static: _Static) -> LoopState:
    """The loop's initial state for guesses ``x`` ``(B, K', d)``."""
    value_and_grad = jax.value_and_grad(_objective)
    f, g = jax.vmap(lambda xb: value_and_grad(xb, data, static))(x)
    batch = x.shape[0]
    tx = _transformation(static.method)
    if isinstance(tx, LBFGS):  # the first line search from the gradients at hand
        opt_state = jax.vmap(tx.init)(x, g)
    else:
        opt_state = jax.vmap(tx.init)(x)
    history = jnp.broadcast_to(f, (static.steps + 1, batch))
    done = ~jnp.isfinite(f) | (static.steps == 0)
    stop = jnp.where(jnp.isfinite(f), Stop.MAX_STEPS, Stop.DIVERGED).astype(jnp.int8)
    zeros = jnp.zeros(batch, jnp.int32)
    one = jnp.int32(1)
    return LoopState(x, opt_state, f, g, done, stop, zeros, zeros + 1, one, jnp.int32(0), history)


@kernel(static=("static",))
def _run(initial: LoopState, data: _Data, stop: Array, static: _Static) -> LoopState:
    """Loop iterations until every guess has stopped or loop iteration ``stop``; a guess
    stops after ``static.steps`` steps at the latest.

    Each iteration is one update of every running guess's method. An optax method's step is
    taken and evaluated; a non-finite result stops the guess (``DIVERGED``). ``LBFGS``
    evaluates its own trial point: the guess takes a step when the trial is accepted, and
    stops (``NO_DESCENT``) when its state says it gave up."""
    tx = _transformation(static.method)
    line_search = isinstance(static.method, LBFGS)  # it evaluates, accepts or refuses
    value_and_grad = jax.value_and_grad(_objective)
    gtol, ftol = data.gtol, data.ftol

    def one_step(x: Array, state: Any, f: Array, g: Array) -> tuple:
        """One guess's update: ``(x, state, f, g)`` after it, whether it took a step, gave up
        (no descent) or blew up (a step to a non-finite point)."""

        def value_fn(y: Array) -> Array:
            return _objective(y, data, static)

        updates, state = tx.update(g, state, x, value=f, grad=g, value_fn=value_fn)
        no = jnp.zeros((), bool)
        if line_search:  # the point it evaluated, exactly (params + updates rounds)
            return state.params, state, state.value, state.grad, state.accepted, state.gave_up, no
        x = optax.apply_updates(x, updates)
        f, g = value_and_grad(x, data, static)
        good = jnp.isfinite(f) & jnp.all(jnp.isfinite(g))
        return x, state, f, g, good, no, ~good

    def cond(loop: LoopState) -> Array:
        return (loop.step < stop) & ~jnp.all(loop.done)

    def body(loop: LoopState) -> LoopState:
        running = ~loop.done
        x_new, state_new, f_new, g_new, took, gave_up, blew = jax.vmap(one_step)(
            loop.x, loop.opt_state, loop.f, loop.g
        )
        took, gave_up, blew = running & took, running & gave_up, running & blew

        def choose(mask: Array, new: Array, old: Array) -> Array:
            mask = mask.reshape(mask.shape + (1,) * (jnp.ndim(new) - 1))
            return jnp.where(mask, new, old)

        x, f, g = jax.tree.map(
            functools.partial(choose, took), (x_new, f_new, g_new), (loop.x, loop.f, loop.g)
        )
        state = jax.tree.map(functools.partial(choose, running), state_new, loop.opt_state)
        grad_norm = jnp.sqrt(jnp.sum(g * g, axis=(-2, -1)))
        change = jnp.abs(loop.f - f) <= ftol * jnp.maximum(jnp.abs(loop.f), jnp.abs(f))
        met = took & ((grad_norm <= gtol * (1.0 + jnp.abs(f))) | change)
        iterations = loop.iterations + took.astype(jnp.int32)
        spent = running & (iterations >= static.steps)
        code = jnp.where(
            met,
            Stop.CONVERGED,
            jnp.where(gave_up, Stop.NO_DESCENT, jnp.where(blew, Stop.DIVERGED, Stop.MAX_STEPS)),
        ).astype(jnp.int8)
        ended = met | gave_up | blew | spent
        return LoopState(
            x=x,
            opt_state=state,
            f=f,
            g=g,
            done=loop.done | ended,
            stop=jnp.where(ended, code, loop.stop),
            iterations=iterations,
            evaluations=loop.evaluations + running.astype(jnp.int32),
            batched=loop.batched + jnp.any(running).astype(jnp.int32),
            step=loop.step + 1,
            history=_record(loop.history, iterations, f),
        )

    return jax.lax.while_loop(cond, body, initial)


def _record(history: Array, iterations: Array, f: Array) -> Array:
    """``history`` ``(steps + 1, B)`` with each guess's cost at its own step count."""
    index = jnp.minimum(iterations, history.shape[0] - 1)
    return history.at[index, jnp.arange(f.shape[0])].set(f)


@kernel(static=("static",))
def _outcome(loop: LoopState, f0: Array, data: _Data, static: _Static) -> tuple:
    """Controls, tool paths, history and stop codes of finished guesses; the divergence
    checks (blown-up cost, control points far outside the box) applied."""
    x, f, g = loop.x, loop.f, loop.g
    after = jnp.arange(static.steps + 1)[:, None] > loop.iterations
    history = jnp.where(after, f, loop.history)
    controls = _controls(x, data, static)
    if static.joint:
        sample = _trajectory(x, data, static)
        path, q, status = sample.path, sample.q, sample.status
    else:  # the tool paths alone: the planner's evaluation solves their IK
        path = paths.bezier_path(controls, data.basis, data.duration)
        q, status = None, None
    lo, hi, unit = data.box
    outside = (jax.nn.relu(lo - controls) + jax.nn.relu(controls - hi)) / unit
    far = jnp.any(outside > DIVERGED_SIZES, axis=(-2, -1))
    blown = ~(f <= BLOWN_UP * jnp.abs(f0)) & (f > 0)
    stop = jnp.where(far | blown | ~jnp.isfinite(f), jnp.int8(Stop.DIVERGED), loop.stop)
    grad_norm = jnp.sqrt(jnp.sum(g * g, axis=(-2, -1)))
    return controls, path, q, status, f, history.T, stop, grad_norm


@kernel
def _joint_evaluation(q: Jet, fk_status: Array, limits: plan.Limits, dt: Array, unit: Array) -> Any:
    """``plan.Evaluation`` of joint trajectories ``(N, T, n)`` (continuous by construction):
    a sample is ``OUT_OF_LIMITS`` where a limit is passed, else its FK status; the costs
    with each joint's ``unit`` (``plan.joint_units``), as the planner's."""
    solved = fk_status == Status.OK
    violated = plan.limit_excess(q, limits) > 0
    status = jnp.where(solved & violated, jnp.int8(Status.OUT_OF_LIMITS), fk_status)
    status = status.astype(STATUS_DTYPE)
    bad = status != Status.OK
    feasible = ~jnp.any(bad, axis=-1)
    first = jnp.where(feasible, -1, jnp.argmax(bad, axis=-1)).astype(jnp.int32)
    margin = jnp.full(feasible.shape, jnp.inf, q.p.dtype)
    return q, status, feasible, first, margin, plan.trajectory_costs(q, dt, limits, feasible, unit)


def _evaluation(robot, joint, path, q, status, limits, branch, dt) -> plan.Evaluation:
    """The optimised trajectories evaluated: the planner's own evaluation of the tool paths
    (task-space controls: the one call of ``plan.evaluate``), or the joint trajectories as
    they are (joint-space controls; no IK, so no margin: ``min_margin`` is ``+inf``)."""
    if not joint:
        return plan.evaluate(robot, path, limits=limits, branch=branch, dt=dt)
    q, status, feasible, first, margin, scores = _joint_evaluation(
        q, status, limits, jnp.asarray(dt, q.p.dtype), plan.joint_units(robot, q.p.dtype)
    )
    index = robot.branches.index(branch)
    evaluation = plan.Evaluation(
        q=q,
        status=status,
        feasible=feasible,
        first_failure=first,
        min_margin=margin,
        branch=jnp.full(feasible.shape, index, jnp.int8),
        costs=scores,
        branches=robot.branches,
    )
    return plan.with_context(evaluation, robot, limits, dt, "joint")  # plan.retime reads it


# ------------------------------------------------------------------ the ends
def _pose(x: Any, name: str) -> np.ndarray:
    """A pose given as a 4x4 homogeneous matrix or as ``(position (3,), quaternion (4,))``
    (``w, x, y, z``, any non-zero length), as a checked 4x4 matrix (host side)."""
    if isinstance(x, tuple | list) and len(x) == 2:
        position = np.asarray(x[0], dtype=float)
        quaternion = np.asarray(x[1], dtype=float)
        if position.shape != (3,) or quaternion.shape != (4,):
            raise ValueError(
                f"{name}: a pose as (position, quaternion) needs shapes (3,) and (4,), got "
                f"{position.shape} and {quaternion.shape}"
            )
        unit, _, ok = _validate.unit_quaternions(quaternion)
        if not (ok and np.all(np.isfinite(position))):
            raise ValueError(f"{name}: the position must be finite and the quaternion finite "
                             f"and non-zero, got {position} and {quaternion}")  # fmt: skip
        w, i, j, k = unit
        rotation = np.array(
            [
                [1 - 2 * (j * j + k * k), 2 * (i * j - k * w), 2 * (i * k + j * w)],
                [2 * (i * j + k * w), 1 - 2 * (i * i + k * k), 2 * (j * k - i * w)],
                [2 * (i * k - j * w), 2 * (j * k + i * w), 1 - 2 * (i * i + j * j)],
            ]
        )
        pose = np.eye(4)
        pose[:3, :3], pose[:3, 3] = rotation, position
        return pose
    pose = np.asarray(x, dtype=float)
    if pose.shape != (4, 4):
        raise ValueError(
            f"{name}: expected a pose, a 4x4 matrix or (position, quaternion), got shape "
            f"{pose.shape}"
        )
    rotation = pose[:3, :3]
    tol = 1e-6
    if not (
        np.all(np.isfinite(pose))
        and np.allclose(pose[3], [0, 0, 0, 1], atol=tol)
        and np.allclose(rotation.T @ rotation, np.eye(3), atol=tol)
        and np.linalg.det(rotation) > 0
    ):
        raise ValueError(
            f"{name}: a pose's rotation must be orthonormal with determinant 1 (to {tol}) and "
            f"its last row (0, 0, 0, 1), got\n{pose}"
        )
    return pose


def _target(robot: Robot, x: Any, name: str) -> np.ndarray:
    """A target of ``robot`` (a point, or a pose as ``_pose`` takes it), checked."""
    if robot.target.shape == (4, 4):
        return _pose(x, name)
    value = np.asarray(x, dtype=float)
    if value.shape != robot.target.shape:
        raise ValueError(
            f"{name}: expected a {robot.target.name} of shape {robot.target.shape} (task "
            f"space), got {value.shape}"
        )
    if not np.all(np.isfinite(value)):
        raise ValueError(f"{name} must be finite, got {value}")
    return value


def _ends(
    robot: Robot, start, goal, space: str, joint: bool, branch: Any, limits
) -> tuple[np.ndarray, np.ndarray]:
    """``start`` and goal as control points: joints (``joint``) or tool positions."""
    names = ("start", "goal")
    if space == "task":
        ends = [_target(robot, x, name) for name, x in zip(names, (start, goal), strict=True)]
    else:
        ends = [np.asarray(x, dtype=float) for x in (start, goal)]
        for name, value in zip(names, ends, strict=True):
            if value.shape != (robot.n_joints,):
                raise ValueError(
                    f"{name}: expected shape ({robot.n_joints},) (joint space), got {value.shape}"
                )
            if not np.all(np.isfinite(value)):
                raise ValueError(f"{name} must be finite, got {value}")
    if space == "joint" and not joint:  # tool positions of joint ends
        return np.asarray(fk(robot, ends[0]).x.p), np.asarray(fk(robot, ends[1]).x.p)
    if space == "task" and joint:  # joints of target ends
        for i, (name, target) in enumerate(zip(names, ends, strict=True)):
            res = ik(robot, target, branch)
            if int(res.status) != Status.OK:
                raise ValueError(
                    f"{name}: the target is not solved on branch {branch!r} "
                    f"({Status(int(res.status)).name}); give its joints with space='joint'"
                )
            ends[i] = np.asarray(res.q.p)
    if joint and space == "task":  # solved goal joints: the turn nearest the start's
        turns = np.round((ends[1] - ends[0]) / (2 * math.pi))
        moved = ends[1] - 2 * math.pi * np.where(_revolute(robot), turns, 0.0)
        inside = (moved >= np.asarray(limits.q_min)) & (moved <= np.asarray(limits.q_max))
        ends[1] = np.where(inside, moved, ends[1])
    return ends[0], ends[1]


def _box(robot: Robot, joint: bool, ends: Sequence[np.ndarray], limits: plan.Limits) -> tuple:
    """The box ``(lo, hi, unit)`` (each ``(d,)``) control points should stay near: the
    workspace box (task space; the ends' box padded by the robot's size when the robot has
    none) or the joint limits, the ends' range where a joint has none (joint space)."""
    size = float(robot.length_scale())
    if joint:
        low, high = np.minimum(*ends), np.maximum(*ends)
        q_min, q_max = np.asarray(limits.q_min), np.asarray(limits.q_max)
        lo = np.where(np.isfinite(q_min), np.minimum(q_min, low), low)
        hi = np.where(np.isfinite(q_max), np.maximum(q_max, high), high)
        unit = np.where(_revolute(robot), 1.0, size)
        return lo, hi, unit
    try:
        bounds, _ = robot.workspace_box()
        lo, hi = (np.array(b, dtype=float) for b in zip(*bounds, strict=True))
    except ValueError:
        lo, hi = np.minimum(*ends) - size, np.maximum(*ends) + size
    return (
        np.minimum(lo, np.minimum(*ends)),
        np.maximum(hi, np.maximum(*ends)),
        np.full(lo.shape, size),
    )


# ------------------------------------------------------------------ public API
def optimize(
    robot: Robot,
    start: Any,
    goal: Any,
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
    progress: _validate.Progress | None = None,
    controls: str | None = None,
) -> OptimizationResult:
    """Optimise B trajectories from ``start`` to ``goal`` at once, each guess on its own.

    Args:
        robot: any robot of the protocol.
        start, goal: the ends. ``space="task"``: targets of the robot, a point of shape
            ``robot.target.shape``, or a pose as a 4x4 matrix or ``(position, quaternion)``
            (``w, x, y, z``); ``space="joint"``: joint vectors ``(n_joints,)``.
        interior: initial interior control points, shape ``(B, K', d)`` or ``(K', d)`` with
            ``d`` the target's size (task-space controls) or ``n_joints`` (joint-space
            controls); at least one guess, every guess finite (a ``ValueError`` names the
            guesses that are not). Host data (the same on every process), or a global
            ``jax.Array`` split along the guesses: with several devices each runs its own
            guesses' loop.
        duration: motion time (positive, finite); ``n_samples`` samples are taken uniformly in
            [0, duration].
        optimizer: ``LBFGS()`` (default) or ``Adam(...)`` (described by value: no new
            compilation), or any optax transformation (a new object compiles anew: keep one).
        steps: the most steps a guess takes.
        cost: ``cost(TrajectorySample) -> (B,)``; default ``DEFAULT_COST``. A ``compose``-d
            cost's weights, thresholds and obstacles are data; a plain function is static.
        branch: the branch held along the path (None: the default); with joint-space controls,
            the branch the IK solves pose or point ends on.
        limits: ``plan.Limits``, intersected with the robot's own position, velocity and
            acceleration limits (``robot.joint_limits()``, which always apply), for the limit
            penalties (``costs.limit_penalty``, part of ``DEFAULT_COST``) and the evaluation.
        rest_to_rest: also fix the second and second-to-last control points.
        space: ``"task"`` or ``"joint"``: the meaning of ``start`` and ``goal``.
        gtol, ftol: stopping rules per guess: ``|grad| <= gtol (1 + |f|)`` or a relative cost
            change ``<= ftol`` in one step; None for ``max(1e-7, 1000 eps)`` and
            ``max(1e-10, 8 eps)`` (float64: 1e-7 and 1e-10, which reach the optimum of the
            benchmark problems to 1e-8 relative; float32: 1.2e-4 and 9.5e-7).
        progress: None, or a callback ``progress(done, total)`` told the steps of the
            furthest guess (of ``steps``) every ``PROGRESS_BLOCK`` loop iterations.
        controls: where the control points live, ``"task"`` or ``"joint"`` (module
            docstring); None: ``"task"`` for robots whose targets are points, else ``"joint"``.

    Returns:
        ``OptimizationResult``.

    Raises:
        ValueError: task-space controls for a robot whose targets are not points, shapes that
            do not match, non-finite or unsolvable ends, no guesses or non-finite ones, bad
            numeric options or a progress that is not callable (each named).
    """
    problem = _checked_problem(
        robot, start, goal, interior, duration, n_samples, optimizer, steps, cost, branch,
        limits, rest_to_rest, space, gtol, ftol, progress, controls,
    )  # fmt: skip
    data, static = _build(problem)
    # A guess's steps never depend on the others' (a stopped guess is held), so each device
    # runs its own guesses' loop to its own end.
    out = map_candidates(
        functools.partial(_optimise_guesses, data=data, static=static, progress=problem.progress),
        problem.interior,
        problem.interior.shape[0],
        name="interior",
    )
    return _result(problem, out)


@dataclasses.dataclass(frozen=True)
class _Problem:
    """``optimize``'s arguments, checked (host side).

    Attributes:
        robot, branch: the robot and the branch held (or solving the ends).
        joint: the control points are joints (else tool positions).
        ends: ``(start, goal)`` as control points, ``(d,)`` each.
        interior: the guesses' interior points ``(B, K', d)``, in the work dtype.
        duration, n_samples, steps, method, cost, rest_to_rest: as given (the method's
            default chosen, the cost bound to the robot: ``costs.bind``).
        limits: the robot's own limits intersected with the caller's.
        tolerances: ``(gtol, ftol)``, the stopping rules' (the defaults of the dtype chosen).
        progress: the progress callback, or None.
    """

    robot: Robot
    branch: Any
    joint: bool
    ends: tuple[np.ndarray, np.ndarray]
    interior: Array
    duration: float
    n_samples: int
    steps: int
    method: Any
    cost: Any
    rest_to_rest: bool
    limits: plan.Limits
    tolerances: tuple[float, float]
    progress: _validate.Progress | None


def _checked_problem(
    robot, start, goal, interior, duration, n_samples, optimizer, steps, cost, branch, limits,
    rest_to_rest, space, gtol, ftol, progress, controls,
) -> _Problem:  # fmt: skip
    """``optimize``'s boundary: every argument checked (a ``ValueError`` naming it), the ends
    made control points (their IK or FK solved), the defaults chosen."""
    robot = as_robot(robot)
    branch = robot.check_branch(branch)
    space = _validate.choice(space, "space", ("task", "joint"))
    if controls is None:
        controls = "task" if robot.target.is_point else "joint"
    controls = _validate.choice(controls, "controls", ("task", "joint"))
    if controls == "task" and not robot.target.is_point:
        raise ValueError(
            f"controls='task' needs a robot whose targets are points; {type(robot).__name__}'s "
            f"are {robot.target.name}s: use controls='joint' (the default for it)"
        )
    joint = controls == "joint"
    for name, value, low in (("n_samples", n_samples, 3), ("steps", steps, 0)):
        if isinstance(value, bool) or not isinstance(value, int | np.integer) or value < low:
            raise ValueError(f"{name} must be an int >= {low}, got {value!r}")
    duration = _validate.positive_number(duration, "duration")
    progress = _validate.progress(progress)
    interior = _checked_guesses(interior, robot, joint)
    epsilon = float(jnp.finfo(interior.dtype).eps)
    gtol = max(1e-7, 1000 * epsilon) if gtol is None else gtol
    ftol = max(1e-10, 8 * epsilon) if ftol is None else ftol
    gtol, ftol = (_validate.nonnegative_number(v, n) for n, v in (("gtol", gtol), ("ftol", ftol)))
    limits = plan.robot_limits(robot, limits)
    return _Problem(
        robot=robot,
        branch=branch,
        joint=joint,
        ends=_ends(robot, start, goal, space, joint, branch, limits),
        interior=interior,
        duration=duration,
        n_samples=int(n_samples),
        steps=int(steps),
        method=LBFGS() if optimizer is None else optimizer,
        cost=bind(cost, robot),  # obstacle terms get the robot's body here, on the host
        rest_to_rest=bool(rest_to_rest),
        limits=limits,
        tolerances=(gtol, ftol),
        progress=progress,
    )


def _checked_guesses(interior: ArrayLike, robot: Robot, joint: bool) -> Array:
    """The guesses as ``(B, K', d)``, at least one, every one finite (checked on every
    process when they are split over processes)."""
    dims = robot.n_joints if joint else robot.target.shape[0]
    interior = jnp.asarray(interior, float)
    if interior.ndim == 2:
        interior = interior[None]
    if interior.ndim != 3 or interior.shape[-1] != dims or interior.shape[1] < 1:
        what = "n_joints" if joint else "the target's size"
        controls = "joint" if joint else "task"
        raise ValueError(
            f"interior: expected shape (B, K', {dims}) ({what}, {controls}-space controls) with "
            f"K' >= 1, got {interior.shape}"
        )
    if interior.shape[0] == 0:
        raise ValueError(f"interior: no guesses (shape {interior.shape}); give at least one")
    bad = np.concatenate(
        [
            first + np.flatnonzero(~np.all(np.isfinite(rows), axis=(1, 2)))
            for first, rows in _processes.local_rows(interior)
        ]
    )
    if not _processes.fetchable(interior):  # split over processes: every process must raise
        bad = np.unique(_processes.allgather_rows(bad))
    if bad.size:
        raise ValueError(
            f"interior: initial guess(es) {bad.tolist()} hold NaN or inf (every guess must be "
            "finite: a NaN would come back as NaN controls)"
        )
    return interior


def _build(problem: _Problem) -> tuple[_Data, _Static]:
    """The compiled loop's array data and its static structure (a cost that is array data
    goes into the data: new weights or obstacles do not compile)."""
    dtype = problem.interior.dtype
    n_ctrl = problem.interior.shape[1] + 2 + (2 if problem.rest_to_rest else 0)
    leaves, treedef = jax.tree.flatten(problem.cost)
    is_data = all(isinstance(leaf, jax.Array | np.ndarray | float | int) for leaf in leaves)
    static = _Static(
        problem.method,
        None if is_data else problem.cost,
        treedef if is_data else None,
        problem.branch,
        problem.rest_to_rest,
        problem.steps,
        problem.joint,
    )
    robot, (start, goal) = problem.robot, problem.ends
    gtol, ftol = problem.tolerances
    box = _box(robot, problem.joint, problem.ends, problem.limits)
    size = robot.length_scale()
    scale = jnp.where(jnp.asarray(_revolute(robot)), 1.0, size) if problem.joint else size
    data = _Data(
        robot=robot,
        start=jnp.asarray(start, dtype),
        goal=jnp.asarray(goal, dtype),
        basis=jnp.asarray(paths.bezier_basis(n_ctrl, problem.n_samples), dtype),
        duration=jnp.asarray(problem.duration, dtype),
        dt=jnp.asarray(_period(problem), dtype),
        limits=problem.limits,
        cost=[jnp.asarray(leaf, dtype) for leaf in leaves] if is_data else [],
        scale=jnp.asarray(scale, dtype),
        gtol=jnp.asarray(gtol, dtype),
        ftol=jnp.asarray(ftol, dtype),
        box=tuple(jnp.asarray(b, dtype) for b in box),
    )
    return data, static


def _period(problem: _Problem) -> float:
    """The sample period ``duration / (n_samples - 1)``."""
    return problem.duration / (problem.n_samples - 1)


def _optimise_guesses(
    guesses: Array, data: _Data, static: _Static, progress: _validate.Progress | None
) -> tuple:
    """The guesses ``(b, K', d)`` of one device optimised: ``_outcome``'s arrays and the
    iterations, per-guess results leading. With progress reported the loop runs in blocks of
    ``PROGRESS_BLOCK`` iterations (the same values: a stopped guess is held)."""
    loop = _start(guesses / data.scale, data, static)
    f0 = loop.f
    steps = static.steps
    # loop iterations: one step each for optax methods, one evaluation each for LBFGS
    tries = 2 * static.method.linesearch_steps + 1 if isinstance(static.method, LBFGS) else 1
    limit = steps * tries + 1
    block = limit if progress is None else PROGRESS_BLOCK
    report = progress or _validate.no_progress
    report(0, steps)
    reached = 0
    while reached < limit:
        target = min(reached + block, limit)
        loop = _run(loop, data, jnp.int32(target), static)
        reached = int(loop.step)
        if block < limit:  # progress is reported: the furthest guess's steps
            report(int(jnp.max(loop.iterations)), steps)
        if reached < target:  # every guess has stopped
            break
    out = _outcome(loop, f0, data, static)
    return (*out, loop.iterations)


def _result(problem: _Problem, out: tuple) -> OptimizationResult:
    """The result of the optimised guesses: their evaluation (``_evaluation``) and the best."""
    ctrl, path, q, fk_status, f, history, stop, grad_norm, iterations = out
    evaluation = _evaluation(
        problem.robot,
        problem.joint,
        path,
        q,
        fk_status,
        problem.limits,
        problem.branch,
        _period(problem),
    )
    ranked = jnp.where(evaluation.feasible, f, jnp.inf)
    best = jnp.where(jnp.any(evaluation.feasible), jnp.argmin(ranked), jnp.argmin(f))
    return OptimizationResult(
        ctrl,
        path,
        f,
        history.T,
        stop == Stop.CONVERGED,
        stop,
        iterations,
        grad_norm,
        best.astype(jnp.int32),
        evaluation,
    )
