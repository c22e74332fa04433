"""Planner backend: evaluate N candidate trajectories of any robot in one call, and rank them.

A planner hands ``evaluate`` N candidates of T samples taken every ``dt``, as a
``paths.Path`` (a ``Jet`` that carries ``dt`` and its space, so the sampling period is given
once, where the rates are made):

* **task space**, shape ``(N, T, *target)`` (``target`` the robot's target shape, e.g.
  ``(3,)`` for a point, ``(4, 4)`` for a pose; ``paths.path_from_samples``,
  ``paths.path_from_poses``): the inverse kinematics of every sample with rates, on one branch
  or the best one per candidate;
* **joint space**, shape ``(N, T, n_joints)`` (``paths.path_from_joint_waypoints``,
  ``paths.path_from_samples(..., space="joint")``): the forward kinematics of every sample
  with rates gives the tool path (``Evaluation.tool``); the singularity margin is the IK's on
  the branch whose joints are nearest the given ones (``Evaluation.branch``).

It gets back, per candidate, the joint trajectories, feasibility, the first failing sample,
the smallest singularity margin and costs. Plain arrays (positions without rates) are
refused: every rate cost would be zero and the continuity check blind. The robot is anything
implementing the robot protocol (``jaxkin.robot``).

Costs, per candidate, each joint in its own units divided by its scale so that no cost adds
radians to millimetres (``joint_scales``): positions by the joint's unit ``u_j`` (1 rad, or
the robot's length ``robot.length_scale()`` for a prismatic joint), speeds by its velocity
limit ``v_max_j`` and accelerations (and jerks) by its acceleration limit ``a_max_j`` where
those are finite, by ``u_j`` (per time unit) otherwise; user ``weights`` ``w_j`` multiply
every term of joint ``j``. With ``v~ = w q_dot / v_max``, ``a~ = w q_ddot / a_max`` (sums run
over joints and samples, ``dt`` the sample spacing)::

    path_length             sum_t |w (q[t+1] - q[t]) / u|           (Euclidean norm over joints)
    peak_speed              max_t max_j |v~|                        (1 = at the limit)
    integrated_speed        sum_t |v~|^2 dt
    peak_acceleration       max_t max_j |a~|
    integrated_acceleration sum_t |a~|^2 dt
    peak_jerk               max_t max_j |j~|,   j~[t] = w (q_ddot[t+1] - q_ddot[t]) / (dt a_max)
    integrated_jerk         sum_t |j~|^2 dt
    limit_violation         sum_t sum_j of how far q, |q_dot|, |q_ddot| exceed their limits,
                            each excess divided by the same scale
    total                   integrated_acceleration where feasible, +inf otherwise

Changing a unit (millimetres to metres for a prismatic joint, with its limits) changes no
cost. ``total`` ranks candidates in ``best`` and ``branch="best"``: the smoothest feasible
joint motion wins. Jerk is the only finite difference (of the exact accelerations).

Feasible means every sample's status is ``OK``: solved (task space: the IK; joint space:
finite joints and rates), regular (task space: a singular sample has no joint rates),
continuous and within every position, speed and acceleration limit. The limits are the robot's
own (``robot.joint_limits()``) intersected with the user's ``Limits``. A task-space candidate
keeps one branch from start to end: a path that would need a switch passes through a
singularity, which the kernel reports. Per-sample checks run in order on the samples still
``OK`` (``_checked``): ``DISCONTINUOUS`` then ``OUT_OF_LIMITS``.

Continuity: revolute joints are unwrapped along each candidate (``unwrapped``: each sample the
``2 pi`` representative nearest the previous one), a candidate that leaves a joint's range is
moved by the whole turns (nearest zero) that bring it inside, if any (``within_turns``), and
then the limits are checked. A sample whose step from the previous one its rates do not
explain (``unexplained_steps``: the solution switched) is ``DISCONTINUOUS``, which wins over
``OUT_OF_LIMITS`` at the same sample. A candidate given as a ``Jet`` whose rates are all zero
(a path explicitly at rest) has no rates to explain its steps: it is only unwrapped.

A path too long for memory is solved in windows of its samples with the same result
(``jaxkin ik`` does so): ``path_ik`` with ``seed`` (the last solved joints before the window)
warm-starts an iterative IK where the whole path's would be; ``unwrapped`` with ``turns``
(prefix the window with the previous one's last sample and give that sample's turns) continues
the unwrapping; ``solved_range`` accumulated over the windows, and ``range_turns`` of it, gives
the whole turns ``within_turns`` would apply; ``checked_samples`` with ``turns`` then checks
each window prefixed with the previous window's last sample, so the first step is checked too.

Duration: ``retime`` times every feasible candidate's joint path as fast as the velocity and
acceleration limits allow (``jaxkin.timing``, batched TOPP-RA, one compiled call), and
``best(ev, k, by="duration")`` ranks by that duration; a candidate that is not feasible or
cannot be timed is ``UNTIMEABLE`` and left out. Every joint needs a finite acceleration limit
for it (a joint without one has no time-optimal motion: ``retime`` names it).

Scale: huge N is processed in chunks of about ``jaxkin._batching.plan_chunk_samples()`` samples,
so memory stays bounded besides the returned arrays; the chunks run on the host threads. With
several JAX devices, in one process or in many joined by ``jax.distributed`` (every process
then calls ``evaluate`` with the same arguments), the candidates are split into one block per
device, each process evaluates its own devices' blocks, and the results are global arrays
split along the candidate axis (``jaxkin._execute.map_candidates``; ``docs/scaling.md``).
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
from . import timing as _timing
from ._execute import Kernel, Policy, as_robot, kernel, map_candidates
from ._numerics import computed_once, safe_norm
from .jet import Jet
from .paths import Path
from .result import IKResult, SolverResult
from .robot import Robot
from .status import STATUS_DTYPE, Status

__all__ = [
    "Costs",
    "Evaluation",
    "LIMITS",
    "LimitViolations",
    "Limits",
    "STEP_RTOL",
    "RANKINGS",
    "best",
    "checked_samples",
    "evaluate",
    "jerk",
    "joint_path",
    "joint_scales",
    "joint_units",
    "limit_excess",
    "limit_violations",
    "path_ik",
    "range_turns",
    "retime",
    "solved_range",
    "trajectory_costs",
    "unexplained_steps",
    "unwrapped",
    "unwrapping_turns",
    "with_context",
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
        n_joints = _validate.count(n_joints, "n_joints")

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
        return cls(*(jax.device_put(x) for x in (q_lo, q_hi, v, a)))  # no program to compile


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
        tool: for joint-space candidates, Jet of the tool path by forward kinematics, shape
            ``(N, T, *robot.target.shape)``; None for task-space ones (it is the given path).
        dt: the sampling period the candidates were evaluated at (static).
        space: ``"task"`` or ``"joint"``, the kind of candidates (static).
        limits: the limits applied, ``(q_min, q_max, v_max, a_max)`` as tuples of floats
            (static; ``applied_limits()`` gives them as ``Limits``).
        min_clearance: with a ``world``, the smallest clearance along the candidate
            (``collision.check``: signed distance, robot-world and self) over the samples
            the solve reached (the others have no joints to place), 0 for a candidate with
            none, ``(N,)``; else None.
        joint_names: the robot's joint names (static), for messages.
    """

    q: Jet
    status: Array
    feasible: Array
    first_failure: Array
    min_margin: Array
    branch: Array
    costs: Costs
    branches: tuple = dataclasses.field(metadata=dict(static=True), default=())
    tool: Jet | None = None
    dt: float | None = dataclasses.field(metadata=dict(static=True), default=None)
    space: str = dataclasses.field(metadata=dict(static=True), default="task")
    limits: tuple = dataclasses.field(metadata=dict(static=True), default=())
    min_clearance: Array | None = None
    joint_names: tuple = dataclasses.field(metadata=dict(static=True), default=())

    def applied_limits(self) -> Limits:
        """The joint limits this evaluation applied (the robot's and the user's)."""
        if not self.limits:
            raise ValueError(
                "evaluation carries no limits: use the Evaluation returned by plan.evaluate"
            )
        return Limits(*(jax.device_put(np.asarray(x, dtype=float)) for x in self.limits))


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
    # on the host (as Limits.create): no program to compile in a fresh process
    return Limits(
        *(
            jax.device_put(bound(*map(np.asarray, pair)))
            for bound, pair in (
                (np.maximum, (limits.q_min, own.lower)),
                (np.minimum, (limits.q_max, own.upper)),
                (np.minimum, (limits.v_max, own.velocity)),
                (np.minimum, (limits.a_max, own.acceleration)),
            )
        )
    )


# ------------------------------------------------------------------ continuity
# A step is unexplained when it misses the rates' prediction by half their reach.
STEP_RTOL = 0.5


def unwrapping_turns(q: Array, revolute: Any, turns: Array | None = None) -> Array:
    """The whole turns ``K`` ``(..., T, n)`` that ``unwrapped`` subtracts from joints
    ``(..., T, n)``: ``K[t] = turns + sum_{0 < s <= t} round((q[s] - q[s-1]) / (2 pi))`` on
    revolute joints (``revolute``: ``(n,)`` bools), 0 on the others; ``turns`` ``(..., n)``
    those of the first sample (None: 0), so that a path unwrapped in windows, each window
    starting with the previous one's last sample and its turns, gets the whole path's."""
    turn = 2.0 * math.pi
    steps = jnp.round((q[..., 1:, :] - q[..., :-1, :]) / turn)
    steps = jnp.where(jnp.asarray(revolute) & jnp.isfinite(steps), steps, 0.0)
    k = jnp.cumsum(steps, axis=-2)
    k = jnp.concatenate([jnp.zeros_like(k[..., :1, :]), k], axis=-2)
    return k if turns is None else k + jnp.asarray(turns, k.dtype)[..., None, :]


def unwrapped(q: Array, revolute: Any, turns: Array | None = None) -> Array:
    """Joint positions ``(..., T, n)`` made continuous along ``T``: every sample of a revolute
    joint (``revolute``: ``(n,)`` bools) moved by a multiple of ``2 pi`` to the representative
    nearest the previous (unwrapped) sample; the first sample keeps its own (less ``turns``
    ``(..., n)`` whole turns when given: ``unwrapping_turns``). That is ``q[t] - 2 pi K[t]``
    with ``K[t] = sum_{s <= t} round((q[s] - q[s-1]) / (2 pi))``: only whole turns are
    subtracted, so the values are exact and the rates unchanged."""
    return q - 2.0 * math.pi * unwrapping_turns(q, revolute, turns)


def range_turns(low: Array, high: Array, revolute: Any, lower: Array, upper: Array) -> Array:
    """The whole turns ``(..., n)`` nearest zero that put a continuous joint range
    ``[low, high]`` ``(..., n)`` within ``[lower, upper]``: 0 when the range already fits,
    when no whole turn makes it fit, on prismatic joints and where the range is empty
    (``low > high``: no solved sample). The fitting shifts are ``[lower - low, upper - high]``;
    ``within_turns`` applies them to a path's samples, and a path checked in windows
    (``checked_samples``' ``turns``) gets them from its whole range."""
    turn = 2.0 * math.pi
    first, last = lower - low, upper - high  # the shifts that fit
    turns = jnp.where(
        first > 0, jnp.ceil(first / turn), jnp.where(last < 0, jnp.floor(last / turn), 0.0)
    )
    fits = (turns * turn >= first) & (turns * turn <= last) & jnp.isfinite(turns)
    return jnp.where(fits & jnp.asarray(revolute) & (low <= high), turns, 0.0)


def solved_range(q: Array, solved: Array) -> tuple[Array, Array]:
    """``(low, high)`` ``(..., n)``: each joint's least and greatest value over the ``solved``
    samples ``(..., T)`` of joints ``(..., T, n)`` (the dtype's largest finite value and its
    negative when none is solved)."""
    big = jnp.asarray(jnp.finfo(q.dtype).max, q.dtype)
    inside = solved[..., None]
    low = jnp.min(jnp.where(inside, q, big), axis=-2)
    high = jnp.max(jnp.where(inside, q, -big), axis=-2)
    return low, high


def within_turns(q: Array, revolute: Any, solved: Array, lower: Array, upper: Array) -> Array:
    """Continuous joints ``(..., T, n)`` shifted, per candidate and revolute joint, by the
    whole number of turns nearest zero that puts their range (over the ``solved`` samples,
    ``(..., T)``) within ``[lower, upper]``; unshifted when the range already fits or when no
    whole turn makes it fit (``range_turns`` of ``solved_range``)."""
    turns = range_turns(*solved_range(q, solved), revolute, lower, upper)
    return q + 2.0 * math.pi * turns[..., None, :]


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
def limit_excess(q: Jet, limits: Limits, scales: Any = (1.0, 1.0, 1.0)) -> Array:
    """How far each sample exceeds its limits, summed over joints: shape ``q.shape[:-1]``;
    each kind of excess divided by its per-joint scale (``scales``: position, speed and
    acceleration, as ``joint_scales`` returns; 1 by default: the joints' own units)."""
    dtype = q.p.dtype
    position, speed, acceleration = scales
    excess = (
        jax.nn.relu(q.p - limits.q_max.astype(dtype)) / position
        + jax.nn.relu(limits.q_min.astype(dtype) - q.p) / position
        + jax.nn.relu(jnp.abs(q.v) - limits.v_max.astype(dtype)) / speed
        + jax.nn.relu(jnp.abs(q.a) - limits.a_max.astype(dtype)) / acceleration
    )
    return jnp.sum(excess, axis=-1)


def jerk(q: Jet, dt: ArrayLike) -> Array:
    """Jerk by a forward difference of the exact accelerations, shape ``(..., T - 1, n)``."""
    return (q.a[..., 1:, :] - q.a[..., :-1, :]) / dt


def joint_scales(limits: Limits, unit: Any, weights: Any) -> tuple[Array, Array, Array]:
    """Per-joint scales ``(position, speed, acceleration)``, each ``(n,)``, that make every
    cost term dimensionless: ``unit / w`` for positions (``unit``: 1 rad, or the robot's
    length for a prismatic joint; ``w`` the user's weight), ``v_max / w`` for speeds and
    ``a_max / w`` for accelerations where the limit is finite and positive, ``unit / w`` (per
    time unit) otherwise."""
    unit = jnp.asarray(unit)
    dtype = unit.dtype
    weights = jnp.asarray(weights, dtype)

    def scale(bound):
        bound = bound.astype(dtype)
        finite = jnp.isfinite(bound) & (bound > 0)
        return jnp.where(finite, bound, unit) / weights

    return unit / weights, scale(limits.v_max), scale(limits.a_max)


def trajectory_costs(
    q: Jet, dt: ArrayLike, limits: Limits, feasible: Array, unit: Any = 1.0, weights: Any = 1.0
) -> Costs:
    """All per-candidate costs of joint trajectories ``q`` of shape ``(..., T, n)``, each
    joint in its own units divided by its scale (``joint_scales``)."""
    position, speed, acceleration = joint_scales(limits, jnp.asarray(unit, q.p.dtype), weights)
    step = (q.p[..., 1:, :] - q.p[..., :-1, :]) / position
    path_length = jnp.sum(safe_norm(step), axis=-1)  # safe: zero steps keep finite gradients
    v = q.v / speed
    a = q.a / acceleration
    j = jerk(q, dt) / acceleration

    def peak(x):
        return jnp.max(jnp.abs(x), axis=(-2, -1))

    def integral(x):
        return jnp.sum(x * x, axis=(-2, -1)) * dt

    integrated_acceleration = integral(a)
    return Costs(
        path_length=path_length,
        peak_speed=peak(v),
        integrated_speed=integral(v),
        peak_acceleration=peak(a),
        integrated_acceleration=integrated_acceleration,
        peak_jerk=peak(j),
        integrated_jerk=integral(j),
        limit_violation=jnp.sum(limit_excess(q, limits, (position, speed, acceleration)), -1),
        total=jnp.where(feasible, integrated_acceleration, jnp.inf),
    )


# ------------------------------------------------------------------ the kernel
def joint_units(robot: Robot, dtype: Any) -> Array:
    """The size of each joint, ``(n,)``: 1 rad, or the robot's length (``length_scale()``)
    for a prismatic one: the position scale of the costs (``joint_scales``)."""
    revolute = np.array([kind == "R" for kind in robot.joint_types])
    return jnp.where(jnp.asarray(revolute), 1.0, robot.length_scale()).astype(dtype)


def checked_samples(
    robot,
    q: Jet,
    status: Array,
    moving: Array,
    limits: Limits,
    dt,
    collide: Any = None,
    *,
    turns: Array | None = None,
) -> tuple[Jet, Array, Array | None]:
    """The per-sample checks every candidate goes through (``plan.evaluate``'s and the
    command line's trajectories).

    ``q``: joints ``(N, T, n)`` as solved or given; ``status`` ``(N, T)`` of the solve (OK
    where there are joints to check; anything else on samples to leave alone, such as
    padding); ``moving`` ``(N,)``: False for a path at rest, whose steps no rates explain;
    ``dt`` the sampling period, a scalar or one time step per step ``(N, T - 1)``. Revolute
    joints are unwrapped and brought within their limits, then the checks run in order, each
    only on the samples still OK, so the first failing check names a sample: continuity, then
    limits, then collision (``collide``: ``(body, pairs, world)`` of ``collision.prepare``, or
    None). Returns the joints, the statuses ``(N, T)`` and each candidate's least clearance
    over its solved samples (None without ``collide``).

    A long path checked in windows (the module docstring) passes ``turns`` ``(N, n)``: its
    joints are then already unwrapped (``unwrapped`` with the previous window's turns), they
    are shifted by these whole turns (``range_turns`` of the whole path's ``solved_range``)
    instead of those of their own range, and each window starts with the previous one's last
    sample (whose own status is dropped), so that every step is checked.
    """
    revolute = np.array([kind == "R" for kind in robot.joint_types])
    solved = status == Status.OK
    dtype = q.p.dtype
    lower, upper = limits.q_min.astype(dtype), limits.q_max.astype(dtype)
    if turns is None:
        p = within_turns(unwrapped(q.p, revolute), revolute, solved, lower, upper)
    else:
        p = q.p + 2.0 * math.pi * jnp.asarray(turns, dtype)[..., None, :]
    q = Jet(p, q.v, q.a)
    # Stored once: about ten cost and status reductions read q; without the barrier XLA fuses
    # IK work into each of them.
    q = Jet(*computed_once(jnp.stack([q.p, q.v, q.a])))
    unit = joint_units(robot, dtype)
    step = jnp.asarray(dt, dtype)
    step = step[..., None] if step.ndim else step  # per-step dt (N, T - 1) over the joints
    jumped = unexplained_steps(q, step, unit) & solved[..., :-1] & moving[:, None]
    jumped = jnp.concatenate([jnp.zeros_like(jumped[..., :1]), jumped], axis=-1)
    checks = [
        (jumped, Status.DISCONTINUOUS),
        (limit_excess(q, limits) > 0, Status.OUT_OF_LIMITS),
    ]
    min_clearance = None
    if collide is not None:  # collision.check of every sample: the body against world and self
        body, pairs, world = collide
        checked = collision.check_kernel(robot, body, pairs, q.p, world)
        checks.append((checked.collides, Status.COLLISION))
        # an unsolved sample's joints are a placeholder: its clearance says nothing
        clearance = jnp.where(solved, checked.clearance, jnp.inf)
        min_clearance = jnp.where(jnp.any(solved, -1), jnp.min(clearance, axis=-1), 0.0)
    for failed, code in checks:
        status = jnp.where((status == Status.OK) & failed, jnp.int8(code), status)
    return q, status.astype(STATUS_DTYPE), min_clearance


def _checked(
    robot,
    q: Jet,
    status: Array,
    margin: Array,
    moving: Array,
    limits: Limits,
    dt,
    weights,
    collide: Any = None,
) -> Evaluation:
    """The per-sample checks (``checked_samples``), then the summaries and costs; ``dt`` the
    sampling period, a scalar."""
    q, status, min_clearance = checked_samples(robot, q, status, moving, limits, dt, collide)
    bad = status != Status.OK
    feasible = ~jnp.any(bad, axis=-1)
    first_failure = jnp.where(feasible, -1, jnp.argmax(bad, axis=-1)).astype(jnp.int32)
    unit = joint_units(robot, q.p.dtype)
    return Evaluation(
        q=q,
        status=status,
        feasible=feasible,
        first_failure=first_failure,
        min_margin=jnp.min(margin, axis=-1),
        branch=jnp.zeros(feasible.shape, jnp.int8),
        costs=trajectory_costs(q, dt, limits, feasible, unit, weights),
        branches=robot.branches,
        min_clearance=min_clearance,
    )


def _moving(path: Jet) -> Array:
    """``(N,)``: False for a candidate whose rates are all zero (a path at rest)."""
    return jnp.any((path.v != 0) | (path.a != 0), axis=tuple(range(1, path.p.ndim)))


def path_ik(robot, path: Jet, branch_index: Any, *, seed: Any = None) -> IKResult:
    """The IK along sampled paths ``(N, T, *target)`` on branch ``robot.branches[branch_index]``
    (an int or a traced ``int32``), in the robot's work dtype: its ``ik_path_kernel`` (an
    iterative IK warm-starts every sample from the previous solution; the branch is held).
    Pure and traceable (the kernel of ``evaluate``).

    ``seed`` ``(N, n)``: for a long path solved in windows, the joints (as this function
    returned them) of the last sample before the window whose status was ``OK`` or
    ``OUT_OF_LIMITS`` (else the seed the previous window was given; for the first window,
    leave it None: its first sample is then found by the full search, as in ``evaluate``).
    An iterative IK warm-starts the window's first sample from it, so the windows give the
    whole path's solution; an analytic IK ignores it. None (the default): unchanged.
    """
    path = _work_targets(robot, path)
    given = {} if seed is None else {"seed": jnp.asarray(seed, path.dtype)}
    return robot.ik_path_kernel(path, branch_index, robot.IKOptions(), **given)


def _work_targets(robot, path: Jet) -> Jet:
    """Task-space targets in the robot's work dtype, positions through ``robot.work_target``
    (a chain's pose given in a less precise dtype gets the nearest rotation in it)."""
    dtype = robot.work_dtype(path.dtype)
    if path.dtype == dtype:
        return path.astype(dtype)
    return Jet(robot.work_target(path.p, dtype), path.v.astype(dtype), path.a.astype(dtype))


def _evaluate_branch(
    robot, path: Jet, limits: Limits, dt, weights, branch_index, collide=None
) -> Evaluation:
    """Every task-space candidate on one branch; ``branch_index`` an int, or a traced one."""
    path = _work_targets(robot, path)
    res = path_ik(robot, path, branch_index)
    moving = _moving(path)
    ev = _checked(robot, res.q, res.status, res.margin, moving, limits, dt, weights, collide)
    return dataclasses.replace(ev, branch=jnp.full(ev.feasible.shape, branch_index, jnp.int8))


def _wrapped_distance(q: Array, reference: Array, revolute: Any, unit: Array) -> Array:
    """Mean over samples of the largest per-joint distance, revolute joints modulo 2 pi,
    each joint in its ``unit``: ``(N, T, n)`` pairs -> ``(N,)``."""
    turn = 2.0 * math.pi
    d = q - reference
    d = jnp.where(jnp.asarray(revolute), d - turn * jnp.round(d / turn), d) / unit
    d = jnp.where(jnp.isfinite(d), jnp.abs(d), jnp.inf)
    return jnp.mean(jnp.max(d, axis=-1), axis=-1)


def _evaluate_joint(robot, path: Jet, limits: Limits, dt, weights, collide=None) -> Evaluation:
    """Joint-space candidates ``(N, T, n)``: the tool path by forward kinematics with rates,
    then the checks of ``_checked``; the margin and branch from the IK of the tool path on
    the branch whose joints are nearest the given ones."""
    q = path.astype(robot.work_dtype(path.dtype))
    fk = robot.fk_kernel(q, robot.FKOptions(), True)
    revolute = np.array([kind == "R" for kind in robot.joint_types])
    unit = joint_units(robot, q.dtype)
    # The IK of the tool path on every branch; the nearest to the given joints is theirs.
    indices = jnp.arange(len(robot.branches), dtype=jnp.int32)
    every = jax.vmap(lambda i: robot.ik_path_kernel(fk.x, i, robot.IKOptions()))(indices)
    distance = jax.vmap(lambda other: _wrapped_distance(other, q.p, revolute, unit))(every.q.p)
    branch = jnp.argmin(distance, axis=0)
    margin = jnp.take_along_axis(every.margin, branch[None, :, None], axis=0)[0]
    ev = _checked(robot, q, fk.status, margin, _moving(q), limits, dt, weights, collide)
    return dataclasses.replace(ev, branch=branch.astype(jnp.int8), tool=fk.x)


def _evaluate_impl(
    robot, path: Jet, limits: Limits, dt, weights, branch: Any, space: str, collide=None
) -> Evaluation:
    if space == "joint":
        return _evaluate_joint(robot, path, limits, dt, weights, collide)
    branches = robot.branches
    if branch != "best" or len(branches) == 1:
        index = 0 if branch == "best" else branches.index(branch)
        return _evaluate_branch(robot, path, limits, dt, weights, index, collide)
    indices = jnp.arange(len(branches), dtype=jnp.int32)
    every = jax.vmap(lambda i: _evaluate_branch(robot, path, limits, dt, weights, i, collide))(
        indices
    )
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


# Candidates are padded (the core of a path: its samples and the target's axes, per call) to
# a power of two from 1: a candidate is a whole path, padding to 64 would multiply its time.
_evaluate_jit = Kernel(
    _evaluate_impl, static=("branch", "space"), policy=Policy(pad=True, pad_min=1)
)
# With a world: the collision checks' XLA options (their loops over obstacles and pairs)
_evaluate_world_jit = Kernel(
    _evaluate_impl,
    static=("branch", "space"),
    policy=Policy(pad=True, pad_min=1, compiler_options=collision.rows.COMPILER_OPTIONS),
)


# ------------------------------------------------------------------ public API
def evaluate(
    robot: Robot,
    path: Jet,
    limits: Limits | None = None,
    branch: Any = None,
    dt: float | None = None,
    chunk_size: int | None = None,
    *,
    weights: ArrayLike | None = None,
    world: Any = None,
) -> Evaluation:
    """Evaluate N candidate trajectories, in task or joint space (see the module docstring).

    Args:
        robot: any robot of the protocol (``jaxkin.robot``).
        path: a ``paths.Path`` (a ``Jet`` that carries its sampling period and space): task
            space ``(N, T, *robot.target.shape)`` from ``paths.path_from_samples`` or
            ``paths.path_from_poses``, joint space ``(N, T, n_joints)`` from
            ``paths.path_from_joint_waypoints`` or ``paths.path_from_samples(..., space=
            "joint")``; or a plain task-space ``Jet`` with ``dt``. Host arrays (the same on
            every process), or global ``jax.Array``s split along the candidate axis only.
        limits: joint ``Limits``, intersected with the robot's own position, velocity and
            acceleration limits (``robot.joint_limits()``), which always apply.
        branch: for task-space candidates, the branch held along every candidate (one of
            ``robot.branches``; None for ``robot.default_branch``), or ``"best"``: every
            branch is evaluated and, per candidate, the feasible one with the lowest
            ``costs.total`` is kept. Joint-space candidates have their branch read from the
            joints (it is not a choice).
        dt: the sample spacing in time, for a plain ``Jet`` (required: the rates' time unit);
            a ``Path`` carries its own (an equal ``dt`` may be repeated, another one is an
            error).
        chunk_size: candidates per call on one device (default
            ``_batching.plan_chunk_samples() // T``, divided by the number of branches for
            ``"best"``).
        weights: per-joint weights ``(n,)`` of the costs (default 1): each joint's terms are
            multiplied by its weight (``joint_scales``).
        world: a ``collision.World``: every solved sample is checked (``collision.check``,
            the robot's body against the world and itself) and one that collides gets the
            status ``COLLISION``; ``min_clearance`` is then each candidate's smallest clearance.

    Returns:
        An ``Evaluation``; ``branch`` tells which branch each candidate used. Zero candidates
        give empty arrays. With several devices its arrays are global, split along the
        candidate axis (replicated when N is not a multiple of ``jax.device_count()``).

    Raises:
        ValueError: not a robot, plain arrays (no rates: build a path), a path not of shape
            ``(N, T, *target)`` (task) or ``(N, T, n_joints)`` (joint) with T >= 2, an
            unknown branch, a missing, conflicting or non-positive dt, limits or weights of
            the wrong size, a global path split along another axis, or host paths whose
            shapes differ between processes.
    """
    robot = as_robot(robot)
    path, dt, space = _as_path(path, dt)
    if space == "task" and branch != "best":
        branch = robot.check_branch(branch)
    if space == "joint":
        branch = robot.default_branch
    target = robot.target.shape if space == "task" else (robot.n_joints,)
    if path.p.ndim != 2 + len(target) or path.shape[2:] != target or path.shape[1] < 2:
        kind = f"{robot.target.name} targets" if space == "task" else "joint coordinates"
        raise ValueError(
            f"path: expected shape (N, T, {', '.join(map(str, target))}) with T >= 2 for "
            f"{type(robot).__name__} ({space} space: {kind}), got {path.shape}"
        )
    if space == "task" and path.dtype != robot.work_dtype(path.dtype):
        # In the work dtype before the kernel (one program for either dtype), host data kept
        # on the host (each process's own candidates).
        path = jax.tree.map(
            lambda new, old: np.asarray(new) if isinstance(old, np.ndarray) else new,
            _work_targets(robot, path),
            path,
        )
    limits = robot_limits(robot, limits)
    weights = _weights(weights, robot.n_joints)
    collide = None
    if world is not None:
        if not isinstance(world, collision.World):
            raise ValueError(f"world: expected a collision.World, got {type(world).__name__}")
        collide = (*collision.prepare(robot), world.bucketed())
    n, t = path.shape[:2]
    # "best" holds every branch of a chunk at once; a joint path solves every branch once
    held = len(robot.branches) if (branch == "best" or space == "joint") else 1
    if chunk_size is None:
        chunk_size = max(1, _batching.plan_chunk_samples() // (t * held))
    else:
        chunk_size = _validate.count(chunk_size, "chunk_size")

    def call(chunk: Jet) -> Evaluation:
        candidates = chunk.shape[0]
        kernel = _evaluate_jit if collide is None else _evaluate_world_jit
        samples = _batching.padded_size(candidates, kernel.policy.pad_min) * t * held
        pad = samples <= _batching.PLAN_PAD_SAMPLES and {"path": 1 + len(target)}
        return kernel(
            robot,
            chunk,
            limits,
            dt,
            weights,
            branch,
            space,
            collide,
            batch=(candidates,),
            pad=pad,
        )

    if n == 0:  # the kernel's shapes from one placeholder candidate, then none of it
        placeholder = jax.tree.map(lambda x: jnp.zeros((1, *x.shape[1:]), x.dtype), path)
        ev = jax.tree.map(lambda x: x[:0], call(placeholder))
    else:
        ev = map_candidates(call, path, chunk_size)
    return with_context(ev, robot, limits, dt, space)


def with_context(
    evaluation: Evaluation, robot: Robot, limits: Limits, dt: float, space: str
) -> Evaluation:
    """``evaluation`` carrying what ``retime`` and ``best`` read besides its arrays: the
    sampling period, the space, the limits applied and the robot's joint names."""
    applied = tuple(tuple(float(x) for x in np.asarray(b)) for b in jax.tree.leaves(limits))
    return dataclasses.replace(
        evaluation,
        dt=float(dt),
        space=space,
        limits=applied,
        joint_names=tuple(robot.joint_names),
    )


# The limits a sample is checked against, in the order ``limit_excess`` adds them.
LIMITS = ("q_min", "q_max", "v_max", "a_max")
_LIMIT_VALUES = ("q", "q", "|q_dot|", "|q_ddot|")


@dataclasses.dataclass(frozen=True)
class LimitViolations:
    """Which joint limit each candidate passes at its first failing sample, when that
    sample is ``OUT_OF_LIMITS`` (``limit_violations``). NumPy arrays ``(N,)``.

    Attributes:
        sample: the first failing sample (-1 where the candidate is feasible).
        joint: the joint's index, -1 where the first failure is not ``OUT_OF_LIMITS``.
        joint_name: its name ("" there).
        limit: ``"q_min"``, ``"q_max"``, ``"v_max"`` or ``"a_max"`` ("" there).
        value: what passed the limit there: ``q``, ``|q_dot|`` or ``|q_ddot|`` (NaN there).
        bound: the limit applied (the robot's own or the user's, the tighter; NaN there).
        others: how many more (joint, limit) pairs that sample passes.
    """

    sample: np.ndarray
    joint: np.ndarray
    joint_name: np.ndarray
    limit: np.ndarray
    value: np.ndarray
    bound: np.ndarray
    others: np.ndarray

    def message(self, candidate: int, units: tuple[str, ...] | None = None) -> str:
        """``"theta2 |q_dot| 2.5 > v_max 2"`` for one candidate ("" when it passes no
        limit); ``units`` per joint (``"rad"``, ``"mm"``) adds the unit and its rate
        (``rad/s``, ``rad/s^2``)."""
        j = int(self.joint[candidate])
        if j < 0:
            return ""
        kind = LIMITS.index(str(self.limit[candidate]))
        unit = ""
        if units is not None:
            unit = " " + units[j] + ("", "", "/s", "/s^2")[kind]
        sign = "<" if kind == 0 else ">"
        text = (
            f"{self.joint_name[candidate]} {_LIMIT_VALUES[kind]} {self.value[candidate]:.6g}"
            f"{unit} {sign} {LIMITS[kind]} {self.bound[candidate]:.6g}{unit}"
        )
        more = int(self.others[candidate])
        return text + (f" (and {more} more)" if more else "")


def limit_violations(evaluation: Evaluation) -> LimitViolations:
    """Host side: for each candidate whose first failing sample is ``OUT_OF_LIMITS``, the
    joint and the limit it passes there (the one passed by the largest fraction of its bound,
    ``(value - bound) / |bound|``, when several are), read from the joints the checks saw
    (``evaluation.q``: unwrapped and shifted by whole turns) and the limits applied.

    Raises:
        ValueError: an evaluation without limits (not from ``evaluate``).
    """
    limits = evaluation.applied_limits()
    first = _processes.to_host(evaluation.first_failure).astype(np.int64)
    status = _processes.to_host(evaluation.status)
    n = first.shape[0]
    rows = np.arange(n)
    at = np.maximum(first, 0)
    out = (status[rows, at] == Status.OUT_OF_LIMITS) & (first >= 0)
    # the first failing samples' joints alone come to the host, not every candidate's path
    picked = (jnp.arange(n), jnp.asarray(at))
    q = [_processes.to_host(x[picked]) for x in (evaluation.q.p, evaluation.q.v, evaluation.q.a)]
    values = np.stack([q[0], q[0], np.abs(q[1]), np.abs(q[2])], axis=1)  # (N, 4, n)
    bounds = np.stack([np.asarray(x, float) for x in jax.tree.leaves(limits)])  # (4, n)
    sign = np.array([-1.0, 1.0, 1.0, 1.0])[:, None]  # q_min is passed from above
    with np.errstate(divide="ignore", invalid="ignore"):
        excess = sign * (values - bounds)
        relative = np.where(excess > 0, excess / np.abs(bounds), -np.inf)
        relative = np.where((excess > 0) & (bounds == 0), np.inf, relative)
    flat = relative.reshape(n, bounds.size)
    worst = np.argmax(flat, axis=1) if n else np.zeros(0, np.int64)
    kind, joint = np.divmod(worst, bounds.shape[1])
    out &= flat[rows, worst] > -np.inf
    names = np.array(evaluation.joint_names or [f"joint {j}" for j in range(bounds.shape[1])])
    return LimitViolations(
        sample=np.where(first >= 0, first, -1),
        joint=np.where(out, joint, -1),
        joint_name=np.where(out, names[joint], "").astype(object),
        limit=np.where(out, np.array(LIMITS)[kind], "").astype(object),
        value=np.where(out, values[rows, kind, joint], np.nan),
        bound=np.where(out, bounds[kind, joint], np.nan),
        others=np.where(out, np.sum(flat > -np.inf, axis=1) - 1, 0),
    )


PLAIN_ARRAY_HELP = (
    "path: plain positions have no rates (every rate cost would be 0 and the continuity "
    "check blind); build a path that carries its rates and sampling period: "
    "paths.path_from_samples(positions, dt) (task space; space='joint' for joint "
    "samples), paths.path_from_poses(positions, quaternions, dt) or "
    "paths.path_from_joint_waypoints(waypoints, dt, steps)"
)


def _as_path(path: Any, dt: Any) -> tuple[Jet, float, str]:
    """The candidates as a plain ``Jet``, their sampling period and space (host side)."""
    if not isinstance(path, Jet):
        raise ValueError(PLAIN_ARRAY_HELP + f", got {type(path).__name__}")
    if isinstance(path, Path):
        if dt is not None and _validate.positive_number(dt, "dt") != path.dt:
            raise ValueError(
                f"dt: the path carries its sampling period {path.dt}, got another dt={dt!r} "
                "(give it once: leave dt out)"
            )
        dt, space = path.dt, path.space
    elif dt is None:
        raise ValueError(
            "dt is required for a plain Jet path (the time step its rates were made with); "
            "or build a path that carries it: paths.path_from_samples(positions, dt)"
        )
    else:
        space = "task"
    dt = _validate.positive_number(dt, "dt")
    jet = _validate.as_jet(Jet(path.p, path.v, path.a), "path", coords=None)
    return jet, dt, space


def _weights(weights: Any, n: int) -> Array:
    """Per-joint cost weights ``(n,)``: positive and finite (1 when None)."""
    if weights is None:
        return jax.device_put(np.ones(n))  # no program to compile
    arr = np.asarray(weights, dtype=float)
    try:
        arr = np.broadcast_to(arr, (n,)).astype(float)
    except ValueError:
        raise ValueError(f"weights must broadcast to shape ({n},), got {arr.shape}") from None
    if not np.all(np.isfinite(arr) & (arr > 0)):
        raise ValueError(f"weights must be positive and finite, got {arr}")
    return jax.device_put(arr)


RANKINGS = ("cost", "duration")


@kernel
def _feasible_only(timed: _timing.Timing, feasible: Array) -> _timing.Timing:
    """``timed`` with the candidates that are not feasible marked ``UNTIMEABLE`` (zeros)."""
    ok = feasible & (timed.status == Status.OK)
    status = jnp.where(feasible, timed.status, jnp.int8(Status.UNTIMEABLE)).astype(STATUS_DTYPE)

    def zero(x):
        return jnp.where(ok.reshape(ok.shape + (1,) * (x.ndim - ok.ndim)), x, 0.0)

    return _timing.Timing(
        zero(timed.duration), status, zero(timed.t), zero(timed.speed), zero(timed.acceleration)
    )


def joint_path(evaluation: Evaluation) -> _timing.JointPath:
    """Each candidate's joint trajectory as a geometric path to retime: the path parameter is
    the sample time ``s = k dt``, so ``dq/ds`` and ``d2q/ds2`` are the joint rates."""
    if evaluation.dt is None:
        raise ValueError("evaluation has no dt: use the Evaluation returned by plan.evaluate")
    q = evaluation.q
    times = np.arange(q.shape[-2], dtype=q.dtype) * np.asarray(evaluation.dt, q.dtype)  # host
    return _timing.JointPath(jax.device_put(np.broadcast_to(times, q.shape[:-1])), q.p, q.v, q.a)


def retime(
    evaluation: Evaluation, *, scheme: str = "interpolation", speed_bound: str = "grid"
) -> _timing.Timing:
    """The time-optimal timing of every candidate's joint path (``jaxkin.timing.retime``,
    batched TOPP-RA: one compiled call for the N candidates) under the velocity and
    acceleration limits the evaluation applied, from rest to rest.

    The geometric path of a candidate is its joint trajectory ``ev.q`` with the sample time
    as path parameter (``joint_path``); between samples, the cubic Hermite interpolant of the
    joints and their rates. A candidate that is not feasible, or whose path cannot be timed,
    has status ``UNTIMEABLE`` (``INVALID_INPUT`` for non-finite joints of a feasible one) and
    zero placeholders. ``timing.sample(plan.joint_path(ev), timed, period)`` samples the
    retimed trajectories at a control period.

    Every joint needs a finite acceleration limit (its speed limit may be ``inf``): without
    one, a joint's time-optimal speed changes within one sample, at an acceleration set by the
    sample spacing alone, and with no speed limit either it moves in no time (``jaxkin.timing``
    would report every candidate that moves it ``UNTIMEABLE``). A URDF gives no acceleration
    limits: give them in ``evaluate``'s ``limits``.

    Raises:
        ValueError: an evaluation without limits or dt (not from ``evaluate``), a joint
            without a finite acceleration limit (named), or candidates of fewer than 3
            samples (a rest-to-rest motion over one interval does not exist).
    """
    limits = evaluation.applied_limits()
    v_max, a_max = np.asarray(limits.v_max), np.asarray(limits.a_max)
    unlimited = np.flatnonzero(~np.isfinite(a_max))
    if unlimited.size:
        names = evaluation.joint_names or tuple(f"joint {j}" for j in range(len(a_max)))
        listed = ", ".join(str(names[j]) for j in unlimited)
        raise ValueError(
            f"retiming needs a finite acceleration limit for every joint; {listed} "
            f"{'has' if unlimited.size == 1 else 'have'} none (its time-optimal speed would "
            "change within one sample, and with no speed limit either it would move in no "
            "time): give every joint an acceleration limit, a_max"
        )
    if evaluation.q.shape[-2] < 3:
        raise ValueError(
            f"retiming from rest to rest needs candidates of at least 3 samples, got "
            f"{evaluation.q.shape[-2]} (a motion over one interval that starts and ends at "
            "rest does not exist)"
        )
    path = joint_path(evaluation)
    dtype = path.q.dtype
    timed = _timing.retime(
        path,
        jnp.asarray(v_max, dtype),
        jnp.asarray(a_max, dtype),
        scheme=scheme,
        speed_bound=speed_bound,
    )
    return _feasible_only(timed, evaluation.feasible)


def best(
    evaluation: Evaluation,
    k: int,
    by: str = "cost",
    timing: _timing.Timing | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """The ``k`` best feasible candidates (host side), by cost or by duration.

    With an evaluation split over several processes (``jax.distributed``) every process calls
    it: each ranks the candidates it holds, the lists are gathered, and every process gets
    the same global answer.

    Args:
        evaluation: from ``evaluate``.
        k: how many, a positive integer.
        by: ``"cost"`` (``costs.total``, the smoothest first) or ``"duration"`` (the
            minimum duration under the joints' velocity and acceleration limits, the fastest
            first: ``retime``; candidates that cannot be timed are left out).
        timing: ``retime(evaluation)`` when already computed (for ``by="duration"``); any
            timing of the candidates is ranked over the feasible ones only.

    Returns:
        ``(indices, values)``: candidate indices sorted by increasing cost or duration (ties
        by index) and those values, NumPy; fewer than ``k`` when fewer candidates are
        feasible (and timed).
    """
    k = _validate.count(k, "k")
    _validate.choice(by, "by", RANKINGS)
    if by == "cost":
        key, usable = evaluation.costs.total, evaluation.feasible
    else:
        if timing is None:
            timing = retime(evaluation)
        elif not isinstance(timing, _timing.Timing):
            raise ValueError(f"timing must be plan.retime's Timing, got {type(timing).__name__}")
        elif jnp.shape(timing.duration) != jnp.shape(evaluation.feasible):
            raise ValueError(
                f"timing: expected one duration per candidate {jnp.shape(evaluation.feasible)}, "
                f"got {jnp.shape(timing.duration)}"
            )
        # A timing of the joint paths alone (timing.retime) times infeasible candidates too.
        key, usable = timing.duration, (timing.status == Status.OK) & evaluation.feasible
    indices, values = [], []
    held = zip(_processes.local_rows(key), _processes.local_rows(usable), strict=True)
    for (start, value), (_, ok) in held:
        ok = np.flatnonzero(ok)
        order = ok[np.argsort(value[ok], kind="stable")][:k]
        indices.append(order + start)
        values.append(value[order])
    index, value = np.concatenate(indices), np.concatenate(values)
    if not _processes.fetchable(key):
        index, value = _processes.allgather_rows(index), _processes.allgather_rows(value)
        order = np.lexsort((index, value))[:k]  # by value, then by index: a stable sort
        index, value = index[order], value[order]
    return index, value
