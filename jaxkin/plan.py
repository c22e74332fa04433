"""Planner backend: evaluate N candidate end-effector trajectories in one call, and rank them.

A planner hands ``evaluate`` a ``Jet`` of end-effector paths, shape ``(N, T, 3)`` (N candidates,
T samples at a fixed time step ``dt``) and gets back, per candidate, the joint trajectories,
feasibility, the first failing sample, the smallest singularity margin and costs.

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

``total`` is the documented ranking cost used by ``best`` and by ``mode="best"``: the smoothest
feasible joint motion wins. Jerk is the only finite difference here (of the exact
accelerations); positions, velocities and accelerations come from the kernels.

Feasible means every sample's status is ``OK``: the IK solved it (reachable, not singular, not
invalid) and no position, velocity or acceleration limit is violated (``OUT_OF_LIMITS``
otherwise). A candidate keeps one assembly mode/branch from start to end: a path that would
need a switch passes through a singularity, which the kernel reports, so it is infeasible.

Scale: when JAX sees more than one device the candidate axis is sharded across all of them
(``jax.sharding.NamedSharding``); huge N is processed in chunks of ``chunk_size`` candidates
(default: ``DEFAULT_CHUNK_SAMPLES // T``, i.e. about 2**17 samples per call, a hundred MB or
so of intermediates in float64), so memory stays bounded besides the returned arrays; on one
device the chunks run concurrently on the host threads (``jaxkin.set_num_threads``).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from jax import Array
from jax.sharding import Mesh, NamedSharding, PartitionSpec
from jax.typing import ArrayLike

from . import _threads, _validate, delta, scara, splines
from ._numerics import computed_once, safe_div, safe_norm, safe_sqrt
from .jet import Jet
from .result import SolverResult
from .serial import arms
from .status import STATUS_DTYPE, Status

# Samples per planner call. Smaller calls keep the intermediates small: XLA maps a large
# temporary buffer afresh on every call (page faults), and two chunks run on two threads.
# Measured with N = 1e4, T = 100, float64 (2-core CPU): 2**17 per call, two threads, 1.8-2x
# the throughput of 2**18 per call one after the other; 2**16 no better than 2**17.
DEFAULT_CHUNK_SAMPLES = 2**17


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
    """

    q: Jet
    status: Array
    feasible: Array
    first_failure: Array
    min_margin: Array
    branch: Array
    costs: Costs
    branches: tuple = dataclasses.field(metadata=dict(static=True), default=())


# ------------------------------------------------------------------ robot adapters
def _is_point_arm(robot: Any) -> bool:
    return isinstance(robot, arms.ARMS) and robot.TARGET_SHAPE == (3,)


def _branches(robot: Any) -> tuple:
    if isinstance(robot, scara.Scara):
        return scara.MODES
    if isinstance(robot, delta.Delta):
        return delta.BRANCHES
    if _is_point_arm(robot):
        return robot.BRANCHES
    raise ValueError(
        "robot must be a jaxkin.scara.Scara, a jaxkin.delta.Delta or a serial arm with a 3-D "
        f"point target (Anthropomorphic, Cylindrical, Spherical), got {type(robot).__name__}"
    )


def _n_joints(robot: Any) -> int:
    return 3  # every supported robot has three joints


def _arm_margin(robot: Any, q: Array) -> Array:
    """Normalised Jacobian determinant ``|det J| / (|J|_F / sqrt(3))^3`` of the wrist position,
    in [0, 1]: 1 for a scaled rotation, 0 at a singularity (dimensionless for 3R arms)."""

    def position(joints):
        return arms.fk(robot, joints)[..., :3, 3]

    jac = jnp.vectorize(jax.jacfwd(position), signature="(n)->(m,n)")(q)
    det = jnp.linalg.det(jac)
    scale = jnp.sum(jac * jac, axis=(-2, -1)) / 3.0
    return jnp.abs(det) * safe_div(1.0, scale * safe_sqrt(scale))


def _solve(robot: Any, path: Jet, branch: Any) -> tuple[Jet, Array, Array]:
    """Joint Jet, status and margin of one branch (inside jit: tracers skip host checks)."""
    if isinstance(robot, scara.Scara):
        res = scara.ik(robot, path, mode=branch)
        return res.q, res.status, res.margin
    if isinstance(robot, delta.Delta):
        res = delta.ik(robot, path, branch=branch)
        return res.theta, res.status, res.margin
    q, status = arms.ik_jet(robot, path, branch)
    return q, status, _arm_margin(robot, q.p)


def _robot_position_limits(robot: Any, n: int) -> tuple[Any, Any]:
    if isinstance(robot, scara.Scara) and robot.limits is not None:
        return robot.limits.lower, robot.limits.upper
    if isinstance(robot, delta.Delta):
        return jnp.full(n, robot.theta_min, float), jnp.full(n, robot.theta_max, float)
    return jnp.full(n, -jnp.inf), jnp.full(n, jnp.inf)


# ------------------------------------------------------------------ costs (reused by optimize)
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
def _evaluate_branch(robot, path: Jet, limits: Limits, dt, branch_index: int) -> Evaluation:
    branches = _branches(robot)
    q, status, margin = _solve(robot, path, branches[branch_index])
    # Stored once: about ten cost and status reductions read q; without the barrier XLA fuses
    # IK work into them (measured: SCARA 84k -> 141k, Delta 31k -> 35k candidates/s, 1e3 x 100
    # samples, float64).
    q = Jet(*computed_once(jnp.stack([q.p, q.v, q.a])))
    violated = limit_excess(q, limits) > 0
    status = jnp.where(
        (status == Status.OK) & violated, jnp.int8(Status.OUT_OF_LIMITS), status
    ).astype(STATUS_DTYPE)
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
    )


def _pick(better: Array, a: Evaluation, b: Evaluation) -> Evaluation:
    """Per candidate: ``a`` where ``better`` else ``b`` (leaves with leading axis N)."""

    def choose(x, y):
        mask = better.reshape(better.shape + (1,) * (jnp.ndim(x) - better.ndim))
        return jnp.where(mask, x, y)

    return jax.tree.map(choose, a, b)


def _evaluate_impl(robot, path: Jet, limits: Limits, dt, mode: Any) -> Evaluation:
    branches = _branches(robot)
    if mode != "best":
        return _evaluate_branch(robot, path, limits, dt, branches.index(mode))
    best = _evaluate_branch(robot, path, limits, dt, 0)
    for index in range(1, len(branches)):
        other = _evaluate_branch(robot, path, limits, dt, index)
        # Lower total wins (infeasible = inf); when neither is feasible, the one that fails
        # later is reported (it got further along the path).
        later = (other.first_failure > best.first_failure) & ~best.feasible & ~other.feasible
        best = _pick((other.costs.total < best.costs.total) | later, other, best)
    return best


_evaluate_jit = jax.jit(_evaluate_impl, static_argnames=("mode",))


# ------------------------------------------------------------------ sharding and chunking
def _candidate_sharding(n_devices: int) -> NamedSharding | None:
    if n_devices == 1:
        return None
    mesh = Mesh(np.asarray(jax.devices()), ("candidates",))
    return NamedSharding(mesh, PartitionSpec("candidates"))


def map_candidates(fn: Callable[[Any], Any], tree: Any, chunk_size: int) -> Any:
    """Apply ``fn`` to a pytree whose leaves share a leading candidate axis N, in chunks.

    The chunks have one size, at most ``chunk_size`` candidates (the last one overlaps its
    neighbour rather than being padded: ``jaxkin._threads.overlapping_parts``), so one
    compilation serves them all. With several devices each chunk is sharded across all of them;
    with one, chunks run on the host threads concurrently (``jaxkin._threads``). The results
    are joined back to N candidates.
    """
    n = jax.tree.leaves(tree)[0].shape[0]
    n_devices = jax.device_count()
    # Sharded chunks need a multiple of the device count: repeat the last candidate.
    pad = (-n) % n_devices
    if pad:
        tree = jax.tree.map(lambda x: jnp.concatenate([x, jnp.repeat(x[-1:], pad, 0)]), tree)
    size = n + pad
    chunk, starts = _threads.overlapping_parts(
        size, math.ceil(size / max(1, min(chunk_size, size))), multiple=n_devices
    )
    sharding = _candidate_sharding(n_devices)

    def run(start: int) -> Any:
        part = tree if chunk == size else jax.tree.map(lambda x: x[start : start + chunk], tree)
        if sharding is not None:
            part = jax.device_put(part, sharding)
        return fn(part)

    if sharding is not None:  # the devices share the work: one chunk at a time
        outputs = [run(start) for start in starts]
    else:
        outputs = _threads.run_parts(run, starts)
    result = (
        outputs[0]
        if len(outputs) == 1
        else _threads.join(outputs, (size,), len(starts) * chunk - size)
    )
    return jax.tree.map(lambda x: x[:n], result) if pad else result


# ------------------------------------------------------------------ public API
def evaluate(
    robot: Any,
    path: Jet | ArrayLike,
    limits: Limits | None = None,
    mode: Any = 1,
    dt: float = 1.0,
    chunk_size: int | None = None,
) -> Evaluation:
    """Evaluate N candidate end-effector trajectories (see the module docstring).

    Args:
        robot: a ``jaxkin.scara.Scara``, a ``jaxkin.delta.Delta``, or a serial arm whose IK
            target is a 3-D point (``Anthropomorphic``, ``Cylindrical``, ``Spherical``; their
            margin is the normalised Jacobian determinant, see ``_arm_margin``).
        path: Jet (or plain positions, at rest) of shape ``(N, T, 3)``; build one from
            sampled positions with ``path_from_samples``.
        limits: joint ``Limits``; the robot's own position limits always apply too.
        mode: the assembly mode/branch held along every candidate (``+1``/``-1`` for a SCARA,
            ``"out"``/``"in"`` for a Delta, a branch name such as ``"front_up"`` for an arm),
            or ``"best"``: every branch is evaluated and, per
            candidate, the feasible one with the lowest ``costs.total`` is kept.
        dt: sample spacing in time (for the integrated costs and jerk).
        chunk_size: candidates per call (default ``DEFAULT_CHUNK_SAMPLES // T``).

    Returns:
        An ``Evaluation``; ``branch`` tells which branch each candidate used.

    Raises:
        ValueError: unsupported robot, path not of shape ``(N, T, 3)`` with T >= 2, unknown
            mode, non-positive dt, or limits of the wrong size.
    """
    branches = _branches(robot)
    if mode != "best":
        _validate.choice(mode, "mode", branches)
    path = _validate.as_jet(path, "path", coords=3)
    if path.p.ndim != 3 or path.p.shape[1] < 2:
        raise ValueError(f"path: expected shape (N, T, 3) with T >= 2, got {path.shape}")
    if not (isinstance(dt, int | float) and dt > 0 and math.isfinite(dt)):
        raise ValueError(f"dt must be a positive finite number, got {dt!r}")
    n_joints = _n_joints(robot)
    if limits is None:
        limits = Limits.create(n_joints)
    elif not isinstance(limits, Limits) or limits.q_min.shape != (n_joints,):
        raise ValueError(f"limits must be a Limits for {n_joints} joints (Limits.create)")
    limits = limits.tightened(*_robot_position_limits(robot, n_joints))
    if chunk_size is None:
        chunk_size = max(1, DEFAULT_CHUNK_SAMPLES // path.shape[1])
    elif not (isinstance(chunk_size, int) and chunk_size >= 1):
        raise ValueError(f"chunk_size must be a positive integer, got {chunk_size!r}")
    return map_candidates(
        lambda chunk: _evaluate_jit(robot, chunk, limits, float(dt), mode), path, chunk_size
    )


def path_from_samples(positions: ArrayLike, dt: float, end: str = "not-a-knot") -> Jet:
    """Jet of paths sampled at a fixed time step, rates from a cubic spline (host side).

    Each coordinate of each candidate is interpolated by a cubic spline through its samples
    (``jaxkin.splines.derivatives``; ``"not-a-knot"`` ends reproduce any cubic exactly) and
    the spline's exact first and second derivatives at the samples are the velocity and
    acceleration: no finite differences.

    Args:
        positions: shape ``(N, T, 3)`` (any leading dims), samples ``dt`` apart.
        dt: the time step (positive).
        end: the spline end condition, ``"not-a-knot"`` or ``"natural"``.
    """
    positions = np.asarray(positions, dtype=float)
    if positions.ndim < 2 or positions.shape[-2] < 2:
        raise ValueError(
            f"positions: expected shape (..., T, 3) with T >= 2, got {positions.shape}"
        )
    if not (dt > 0 and math.isfinite(dt)):
        raise ValueError(f"dt must be a positive finite number, got {dt!r}")
    t = np.broadcast_to(np.arange(positions.shape[-2]) * float(dt), positions.shape[:-1])
    velocity, acceleration = splines.derivatives(t, positions, end=end)
    return Jet.of(positions, velocity, acceleration)


def best(evaluation: Evaluation, k: int) -> tuple[np.ndarray, np.ndarray]:
    """The ``k`` best feasible candidates by ``costs.total`` (host side).

    Returns:
        ``(indices, totals)``: candidate indices sorted by increasing ``costs.total`` and
        their costs; fewer than ``k`` when fewer candidates are feasible.
    """
    if not (isinstance(k, int) and k >= 1):
        raise ValueError(f"k must be a positive integer, got {k!r}")
    total = np.asarray(evaluation.costs.total)
    feasible = np.flatnonzero(np.asarray(evaluation.feasible))
    order = feasible[np.argsort(total[feasible], kind="stable")][:k]
    return order, total[order]
