"""Planner backend: evaluate N candidate trajectories of any robot in one call, and rank them.

A planner hands ``evaluate`` a ``Jet`` of end-effector paths of shape ``(N, T, *target)`` (N
candidates, T samples at a fixed time step ``dt``; ``target`` the robot's target shape, e.g.
``(3,)`` for a point, ``(4, 4)`` for a pose) and gets back, per candidate, the joint
trajectories, feasibility, the first failing sample, the smallest singularity margin and
costs. The robot is anything implementing the robot protocol (``jaxkin.robot``).

Costs, per candidate (joint units: rad for revolute joints, the length unit for prismatic ones;
sums run over joints and samples, ``dt`` is the sample spacing)::

    path_length             sum_t |q[t+1] - q[t]|                  (Euclidean norm over joints)
    peak_speed              max_t max_j |q_dot|
    integrated_speed        sum_t |q_dot|^2 dt
    peak_acceleration       max_t max_j |q_ddot|
    integrated_acceleration sum_t |q_ddot|^2 dt
    peak_jerk               max_t max_j |jerk|,   jerk[t] = (q_ddot[t+1] - q_ddot[t]) / dt
    integrated_jerk         sum_t |jerk|^2 dt
    limit_violation         sum_t sum_j of how far q, |q_dot|, |q_ddot| exceed their limits
    total                   integrated_acceleration where feasible, +inf otherwise

``total`` ranks candidates in ``best`` and ``branch="best"``: the smoothest feasible joint
motion wins. Jerk is the only finite difference (of the exact accelerations). Feasible means
every sample's status is ``OK``: solved, regular, continuous and within every position, speed
and acceleration limit. The limits are the robot's own (``robot.joint_limits()``) intersected
with the user's ``Limits``. A candidate keeps one branch from start to end: a path that would
need a switch passes through a singularity, which the kernel reports.

Continuity: revolute joints are unwrapped along each candidate (``unwrapped``: each sample the
``2 pi`` representative nearest the previous one), a candidate that leaves a joint's range is
moved by the whole turns (nearest zero) that bring it inside, if any (``within_turns``), and
then the limits are checked. A sample whose step from the previous one its rates do not
explain (``unexplained_steps``: the solution switched) is ``DISCONTINUOUS``, which wins over
``OUT_OF_LIMITS`` at the same sample. A candidate whose target rates are all zero (a path at
rest) has no rates to explain its steps: it is only unwrapped.

Scale: huge N is processed in chunks of about ``jaxkin._batching.plan_chunk_samples()`` samples,
so memory stays bounded besides the returned arrays; the chunks run on the host threads. With
several JAX devices, in one process or in many joined by ``jax.distributed`` (every process
then calls ``evaluate`` with the same arguments), the candidates are split into one block per
device, each process evaluates its own devices' blocks, and the results are global arrays
split along the candidate axis (``jaxkin._batching.map_candidates``; ``docs/scaling.md``).
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

from . import _batching, _processes, _validate, collision
from ._numerics import computed_once, safe_norm
from .jet import Jet
from .result import SolverResult
from .robot import Robot, as_robot
from .status import STATUS_DTYPE, Status

__all__ = [
    "Costs",
    "Evaluation",
    "Limits",
    "STEP_RTOL",
    "best",
    "evaluate",
    "jerk",
    "limit_excess",
    "trajectory_costs",
    "unexplained_steps",
    "unwrapped",
    "within_turns",
]


@jax.tree_util.register_dataclass
@dataclasses.dataclass(frozen=True)
class Limits:
    """Joint limits for the planner; ``inf`` where a joint is unbounded.

    Attributes:
        q_min, q_max: position range per joint, shape ``(n,)``.
        v_max: speed bound ``|q_dot| <= v_max`` per joint, shape ``(n,)``.
        a_max: acceleration bound ``|q_ddot| <= a_max`` per joint, shape ``(n,)``.
    """

    q_min: Array
    q_max: Array
    v_max: Array
    a_max: Array

    @classmethod
    def create(
        cls,
        n_joints: int,
        q_min: ArrayLike | None = None,
        q_max: ArrayLike | None = None,
        v_max: ArrayLike | None = None,
        a_max: ArrayLike | None = None,
    ) -> Limits:
        """Validated constructor; ``None`` leaves that kind of limit off.

        Raises:
            ValueError: a bound that does not broadcast to ``(n_joints,)``, is NaN, a negative
                speed or acceleration bound, or ``q_min > q_max``.
        """

        def bound(x, name, fill):
            arr = np.full(n_joints, fill) if x is None else np.asarray(x, dtype=float)
            try:
                arr = np.broadcast_to(arr, (n_joints,)).astype(float)
            except ValueError:
                raise ValueError(
                    f"{name} must broadcast to shape ({n_joints},), got {arr.shape}"
                ) from None
            if np.any(np.isnan(arr)):
                raise ValueError(f"{name} must not be NaN, got {arr}")
            return arr

        q_lo = bound(q_min, "q_min", -np.inf)
        q_hi = bound(q_max, "q_max", np.inf)
        v = bound(v_max, "v_max", np.inf)
        a = bound(a_max, "a_max", np.inf)
        if np.any(q_lo > q_hi):
            raise ValueError(f"q_min must be <= q_max, got {q_lo} and {q_hi}")
        for name, arr in (("v_max", v), ("a_max", a)):
            if np.any(arr < 0):
                raise ValueError(f"{name} must be >= 0, got {arr}")
        return cls(*(jnp.asarray(x) for x in (q_lo, q_hi, v, a)))

    def tightened(self, q_min: ArrayLike, q_max: ArrayLike) -> Limits:
        """These limits intersected with a position range (e.g. the robot's own)."""
        return dataclasses.replace(
            self, q_min=jnp.maximum(self.q_min, q_min), q_max=jnp.minimum(self.q_max, q_max)
        )


@jax.tree_util.register_dataclass
@dataclasses.dataclass(frozen=True)
class Costs:
    """Per-candidate costs, each of shape ``(N,)`` (definitions in the module docstring)."""

    path_length: Array
    peak_speed: Array
    integrated_speed: Array
    peak_acceleration: Array
    integrated_acceleration: Array
    peak_jerk: Array
    integrated_jerk: Array
    limit_violation: Array
    total: Array


@jax.tree_util.register_dataclass
@dataclasses.dataclass(frozen=True)
class Evaluation(SolverResult):
    """Evaluation of N candidate trajectories of T samples each.

    Attributes:
        q: Jet of joint coordinates, shape ``(N, T, n)``.
        status: per-sample ``int8`` status, shape ``(N, T)``.
        feasible: every sample OK, shape ``(N,)``.
        first_failure: index of the first non-OK sample, -1 when feasible, shape ``(N,)``.
        min_margin: smallest singularity margin along the candidate, shape ``(N,)``.
        branch: index into ``branches`` of the assembly mode/branch used, shape ``(N,)``.
        costs: ``Costs``, each ``(N,)``.
        branches: the robot's branch labels (static), e.g. ``(1, -1)`` for a SCARA.
        min_clearance: with a ``world``, the smallest clearance along the candidate
            (``collision.check``: signed distance, robot-world and self), ``(N,)``; else None.
    """

    q: Jet
    status: Array
    feasible: Array
    first_failure: Array
    min_margin: Array
    branch: Array
    costs: Costs
    branches: tuple = dataclasses.field(metadata=dict(static=True), default=())
    min_clearance: Array | None = None


def robot_limits(robot: Robot, limits: Limits | None) -> Limits:
    """The limits the planner applies: the robot's own (``robot.joint_limits()``: position,
    velocity, acceleration) intersected with the user's ``limits`` (None: none), so the tighter
    bound of each kind wins; ``limits`` is checked against the robot's joints."""
    n = robot.n_joints
    if limits is None:
        limits = Limits.create(n)
    elif not isinstance(limits, Limits) or tuple(jnp.shape(limits.q_min)) != (n,):
        raise ValueError(
            f"limits must be a Limits for {n} joints (Limits.create({n}, ...)), got {limits!r}"
        )
    own = robot.joint_limits()
    return dataclasses.replace(
        limits.tightened(own.lower, own.upper),
        v_max=jnp.minimum(limits.v_max, own.velocity),
        a_max=jnp.minimum(limits.a_max, own.acceleration),
    )


# ------------------------------------------------------------------ continuity
# A step is unexplained when it misses the rates' prediction by half their reach.
STEP_RTOL = 0.5


def unwrapped(q: Array, revolute: Any) -> Array:
    """Joint positions ``(..., T, n)`` made continuous along ``T``: every sample of a revolute
    joint (``revolute``: ``(n,)`` bools) moved by a multiple of ``2 pi`` to the representative
    nearest the previous (unwrapped) sample; the first sample keeps its own. That is
    ``q[t] - 2 pi K[t]`` with ``K[t] = sum_{s <= t} round((q[s] - q[s-1]) / (2 pi))``: only
    whole turns are subtracted, so the values are exact and the rates unchanged."""
    turn = 2.0 * math.pi
    turns = jnp.round((q[..., 1:, :] - q[..., :-1, :]) / turn)
    turns = jnp.where(jnp.asarray(revolute) & jnp.isfinite(turns), turns, 0.0)
    k = jnp.cumsum(turns, axis=-2)
    return q - turn * jnp.concatenate([jnp.zeros_like(k[..., :1, :]), k], axis=-2)


def within_turns(q: Array, revolute: Any, solved: Array, lower: Array, upper: Array) -> Array:
    """Continuous joints ``(..., T, n)`` shifted, per candidate and revolute joint, by the
    whole number of turns nearest zero that puts their range (over the ``solved`` samples,
    ``(..., T)``) within ``[lower, upper]``; unshifted when the range already fits or when no
    whole turn makes it fit. The fitting shifts are ``[lower - min q, upper - max q]``."""
    turn = 2.0 * math.pi
    big = jnp.asarray(jnp.finfo(q.dtype).max, q.dtype)
    inside = solved[..., None]
    low = jnp.min(jnp.where(inside, q, big), axis=-2)
    high = jnp.max(jnp.where(inside, q, -big), axis=-2)
    first, last = lower - low, upper - high  # the shifts that fit
    turns = jnp.where(
        first > 0, jnp.ceil(first / turn), jnp.where(last < 0, jnp.floor(last / turn), 0.0)
    )
    fits = (turns * turn >= first) & (turns * turn <= last) & jnp.isfinite(turns)
    turns = jnp.where(fits & jnp.asarray(revolute) & jnp.any(inside, axis=-2), turns, 0.0)
    return q + turn * turns[..., None, :]


def unexplained_steps(q: Jet, dt: Any, unit: Any) -> Array:
    """True where a step ``q[t+1] - q[t]`` of joints ``(..., T, n)`` is not explained by their
    rates, shape ``(..., T - 1)``.

    The rates at both ends predict the step by the corrected trapezoid rule (exact for a
    quartic motion)::

        predicted = dt (v[t] + v[t+1]) / 2 + dt^2 (a[t] - a[t+1]) / 12

    and the step is unexplained when, for some joint,
    ``|step - predicted| > STEP_RTOL * reach + sqrt(eps) * (|q[t]| + |q[t+1]| + unit)`` with
    ``reach = dt (|v[t]| + |v[t+1]|) / 2 + dt^2 (|a[t]| + |a[t+1]|) / 12`` (how far the rates
    can carry the joint in one step), ``eps`` the dtype's, and ``unit`` ``(n,)`` the size of a
    joint (1 rad, or the robot's length) so that an iterative solution's round-off is no jump.
    A smooth motion misses the prediction by ``O(dt^5)`` (a fraction ``(w dt)^4 / 720`` of the
    reach for a sinusoid of frequency ``w``), far below ``STEP_RTOL``.
    """
    p, v, a = q.p, q.v, q.a
    step = p[..., 1:, :] - p[..., :-1, :]
    predicted = (
        dt * (v[..., 1:, :] + v[..., :-1, :]) / 2 + dt * dt * (a[..., :-1, :] - a[..., 1:, :]) / 12
    )
    reach = dt * (jnp.abs(v[..., 1:, :]) + jnp.abs(v[..., :-1, :])) / 2
    reach = reach + dt * dt * (jnp.abs(a[..., 1:, :]) + jnp.abs(a[..., :-1, :])) / 12
    floor = math.sqrt(float(jnp.finfo(p.dtype).eps))
    floor = floor * (jnp.abs(p[..., 1:, :]) + jnp.abs(p[..., :-1, :]) + unit)
    bad = jnp.abs(step - predicted) > STEP_RTOL * reach + floor
    return jnp.any(bad, axis=-1)


# ------------------------------------------------------------------ costs (reused by jaxkin.costs)
def limit_excess(q: Jet, limits: Limits) -> Array:
    """How far each sample exceeds its limits, summed over joints: shape ``q.shape[:-1]``."""
    dtype = q.p.dtype
    excess = (
        jax.nn.relu(q.p - limits.q_max.astype(dtype))
        + jax.nn.relu(limits.q_min.astype(dtype) - q.p)
        + jax.nn.relu(jnp.abs(q.v) - limits.v_max.astype(dtype))
        + jax.nn.relu(jnp.abs(q.a) - limits.a_max.astype(dtype))
    )
    return jnp.sum(excess, axis=-1)


def jerk(q: Jet, dt: float) -> Array:
    """Jerk by a forward difference of the exact accelerations, shape ``(..., T - 1, n)``."""
    return (q.a[..., 1:, :] - q.a[..., :-1, :]) / dt


def trajectory_costs(q: Jet, dt: float, limits: Limits, feasible: Array) -> Costs:
    """All per-candidate costs of joint trajectories ``q`` of shape ``(..., T, n)``."""
    step = q.p[..., 1:, :] - q.p[..., :-1, :]
    path_length = jnp.sum(safe_norm(step), axis=-1)  # safe: zero steps keep finite gradients
    j = jerk(q, dt)

    def peak(x):
        return jnp.max(jnp.abs(x), axis=(-2, -1))

    def integral(x):
        return jnp.sum(x * x, axis=(-2, -1)) * dt

    integrated_acceleration = integral(q.a)
    return Costs(
        path_length=path_length,
        peak_speed=peak(q.v),
        integrated_speed=integral(q.v),
        peak_acceleration=peak(q.a),
        integrated_acceleration=integrated_acceleration,
        peak_jerk=peak(j),
        integrated_jerk=integral(j),
        limit_violation=jnp.sum(limit_excess(q, limits), axis=-1),
        total=jnp.where(feasible, integrated_acceleration, jnp.inf),
    )


# ------------------------------------------------------------------ the kernel
def _evaluate_branch(
    robot, path: Jet, limits: Limits, dt, branch_index: Any, collide: Any = None
) -> Evaluation:
    """Every candidate on one branch; ``branch_index`` an int, or a traced one (``"best"``)."""
    branches = robot.branches
    # Along each candidate: an iterative IK warm-starts every sample from the previous one.
    path = path.astype(robot.work_dtype(path.dtype))
    res = robot.ik_path_kernel(path, branch_index, robot.IKOptions())
    q, status, margin = res.q, res.status, res.margin
    revolute = np.array([kind == "R" for kind in robot.joint_types])
    solved = status == Status.OK
    dtype = q.p.dtype
    lower, upper = limits.q_min.astype(dtype), limits.q_max.astype(dtype)
    q = Jet(within_turns(unwrapped(q.p, revolute), revolute, solved, lower, upper), q.v, q.a)
    # Stored once: about ten cost and status reductions read q; without the barrier XLA fuses
    # IK work into each of them.
    q = Jet(*computed_once(jnp.stack([q.p, q.v, q.a])))
    # A path at rest (every target rate zero, e.g. plain positions) has no rates to explain
    # its steps: it is only unwrapped.
    moving = jnp.any((path.v != 0) | (path.a != 0), axis=tuple(range(1, path.p.ndim)))
    unit = jnp.where(jnp.asarray(revolute), 1.0, robot.length_scale()).astype(q.p.dtype)
    jumped = unexplained_steps(q, dt, unit) & solved[..., :-1] & moving[:, None]
    jumped = jnp.concatenate([jnp.zeros_like(jumped[..., :1]), jumped], axis=-1)
    violated = limit_excess(q, limits) > 0
    status = jnp.where(solved & jumped, jnp.int8(Status.DISCONTINUOUS), status)
    status = jnp.where(
        (status == Status.OK) & violated, jnp.int8(Status.OUT_OF_LIMITS), status
    ).astype(STATUS_DTYPE)
    min_clearance = None
    if collide is not None:  # (body, pairs, world): collision.check of every sample
        checked = collision.check_kernel(robot, *collide[:2], q.p, collide[2])
        hit = (status == Status.OK) & checked.collides
        status = jnp.where(hit, jnp.int8(Status.COLLISION), status).astype(STATUS_DTYPE)
        min_clearance = jnp.min(checked.clearance, axis=-1)
    bad = status != Status.OK
    feasible = ~jnp.any(bad, axis=-1)
    first_failure = jnp.where(feasible, -1, jnp.argmax(bad, axis=-1)).astype(jnp.int32)
    return Evaluation(
        q=q,
        status=status,
        feasible=feasible,
        first_failure=first_failure,
        min_margin=jnp.min(margin, axis=-1),
        branch=jnp.full(feasible.shape, branch_index, jnp.int8),
        costs=trajectory_costs(q, dt, limits, feasible),
        branches=branches,
        min_clearance=min_clearance,
    )


def _evaluate_impl(robot, path: Jet, limits: Limits, dt, branch: Any, collide=None) -> Evaluation:
    branches = robot.branches
    if branch != "best" or len(branches) == 1:
        index = 0 if branch == "best" else branches.index(branch)
        return _evaluate_branch(robot, path, limits, dt, index, collide)
    indices = jnp.arange(len(branches), dtype=jnp.int32)
    every = jax.vmap(lambda i: _evaluate_branch(robot, path, limits, dt, i, collide))(indices)
    # Per candidate: the feasible branch of least total (the first on ties); when none is
    # feasible, the one that fails latest along the path (it got furthest).
    total = jnp.where(every.feasible, every.costs.total, jnp.inf)
    choice = jnp.where(
        jnp.any(every.feasible, axis=0),
        jnp.argmin(total, axis=0),
        jnp.argmax(every.first_failure, axis=0),
    )

    def pick(x: Array) -> Array:
        index = choice.reshape((1, *choice.shape) + (1,) * (x.ndim - 1 - choice.ndim))
        return jnp.take_along_axis(x, index, axis=0)[0]

    return jax.tree.map(pick, every)


# Candidates are padded (the core of a path: its samples and the target's axes, per call).
_evaluate_jit = _batching.PaddedJit(jax.jit(_evaluate_impl, static_argnames=("branch",)), {})


# ------------------------------------------------------------------ public API
def evaluate(
    robot: Robot,
    path: Jet | ArrayLike,
    limits: Limits | None = None,
    branch: Any = None,
    dt: float = 1.0,
    chunk_size: int | None = None,
    world: Any = None,
) -> Evaluation:
    """Evaluate N candidate end-effector trajectories (see the module docstring).

    Args:
        robot: any robot of the protocol (``jaxkin.robot``).
        path: Jet (or plain targets, at rest) of shape ``(N, T, *robot.target.shape)``; build
            one from sampled points with ``jaxkin.paths.path_from_samples``. Host arrays (the
            same on every process), or global ``jax.Array``s split along the candidate axis
            only.
        limits: joint ``Limits``, intersected with the robot's own position, velocity and
            acceleration limits (``robot.joint_limits()``), which always apply.
        branch: the branch held along every candidate (one of ``robot.branches``; None for
            ``robot.default_branch``), or ``"best"``: every branch is evaluated and, per
            candidate, the feasible one with the lowest ``costs.total`` is kept.
        dt: sample spacing in time (for the integrated costs, jerk and the continuity check:
            it must be the spacing the path's rates were made with).
        chunk_size: candidates per call on one device (default
            ``_batching.plan_chunk_samples() // T``, divided by the number of branches for
            ``"best"``).
        world: a ``collision.World``: every solved sample is checked (``collision.check``,
            the robot's body against the world and itself) and one that collides gets the
            status ``COLLISION``; ``min_clearance`` is then each candidate's smallest clearance.

    Returns:
        An ``Evaluation``; ``branch`` tells which branch each candidate used. Zero candidates
        give empty arrays. With several devices its arrays are global, split along the
        candidate axis (replicated when N is not a multiple of ``jax.device_count()``).

    Raises:
        ValueError: not a robot, a path not of shape ``(N, T, *target)`` with T >= 2, an
            unknown branch, a non-positive dt, limits of the wrong size, a global path split
            along another axis, or host paths whose shapes differ between processes.
    """
    robot = as_robot(robot)
    if branch != "best":
        branch = robot.check_branch(branch)
    target = robot.target.shape
    path = _validate.as_jet(path, "path", coords=None)
    if path.p.ndim != 2 + len(target) or path.shape[2:] != target or path.shape[1] < 2:
        raise ValueError(
            f"path: expected shape (N, T, {', '.join(map(str, target))}) with T >= 2 for "
            f"{type(robot).__name__} ({robot.target.name} targets), got {path.shape}"
        )
    dt = _validate.positive_number(dt, "dt")
    limits = robot_limits(robot, limits)
    collide = None
    if world is not None:
        if not isinstance(world, collision.World):
            raise ValueError(f"world: expected a collision.World, got {type(world).__name__}")
        collide = (*collision.prepare(robot), world)
    n, t = path.shape[:2]
    # "best" holds every branch of a chunk at once
    held = len(robot.branches) if branch == "best" else 1
    if chunk_size is None:
        chunk_size = max(1, _batching.plan_chunk_samples() // (t * held))
    elif isinstance(chunk_size, bool) or not (isinstance(chunk_size, int) and chunk_size >= 1):
        raise ValueError(f"chunk_size must be a positive integer, got {chunk_size!r}")

    def call(chunk: Jet) -> Evaluation:
        candidates = chunk.shape[0]
        samples = _batching.padded_size(candidates) * t * held
        pad = samples <= _batching.PLAN_PAD_SAMPLES and {"path": 1 + len(target)}
        return _evaluate_jit(
            robot, chunk, limits, float(dt), branch, collide, batch=(candidates,), pad=pad
        )

    if n == 0:  # the kernel's shapes from one placeholder candidate, then none of it
        placeholder = jax.tree.map(lambda x: jnp.zeros((1, *x.shape[1:]), x.dtype), path)
        return jax.tree.map(lambda x: x[:0], call(placeholder))
    return _batching.map_candidates(call, path, chunk_size)


def best(evaluation: Evaluation, k: int) -> tuple[np.ndarray, np.ndarray]:
    """The ``k`` best feasible candidates by ``costs.total`` (host side).

    With an evaluation split over several processes (``jax.distributed``) every process calls
    it: each ranks the candidates it holds, the lists are gathered, and every process gets
    the same global answer.

    Returns:
        ``(indices, totals)``: candidate indices sorted by increasing ``costs.total`` (ties by
        index) and their costs, NumPy; fewer than ``k`` when fewer candidates are feasible.
    """
    if not (isinstance(k, int) and k >= 1):
        raise ValueError(f"k must be a positive integer, got {k!r}")
    indices, totals = [], []
    held = zip(
        _processes.local_rows(evaluation.costs.total),
        _processes.local_rows(evaluation.feasible),
        strict=True,
    )
    for (start, total), (_, feasible) in held:
        feasible = np.flatnonzero(feasible)
        order = feasible[np.argsort(total[feasible], kind="stable")][:k]
        indices.append(order + start)
        totals.append(total[order])
    index, total = np.concatenate(indices), np.concatenate(totals)
    if not _processes.fetchable(evaluation.costs.total):
        index, total = _processes.allgather_rows(index), _processes.allgather_rows(total)
        order = np.lexsort((index, total))[:k]  # by total, then by index: a stable sort
        index, total = index[order], total[order]
    return index, total
