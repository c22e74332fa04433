"""The command line's calls into the planner (``jaxkin.plan``, ``jaxkin.timing``), in one place.

Trajectory files solved as paths (``jaxkin ik`` on a file with a ``t`` column):

* each candidate's valid rows, in file order, are one path: its samples are solved by the
  robot's ``ik_path_kernel`` (an iterative IK warm-starts every sample from the previous
  one; the branch is held from start to end);
* revolute joints are unwrapped along the path (``plan.unwrapped``) and moved by the whole
  turns that bring their range within the limits, if any (``plan.within_turns``);
* a solved sample whose step from the previous one its rates do not explain
  (``plan.unexplained_steps``, with the file's own time steps, which may vary) is
  ``DISCONTINUOUS``; a solved sample outside a position, speed or acceleration limit is
  ``OUT_OF_LIMITS``: the statuses of ``plan.evaluate``.

Candidates are batched (padded to a few sizes, so a file compiles a few programs), a batch
holding about ``chunk`` samples; a candidate longer than that is solved whole.

``jaxkin plan`` evaluates a file of candidates with ``plan.evaluate`` (task space) or by
forward kinematics (joint space), ranks them by ``costs.total`` or by the duration of their
time-optimal retiming (``jaxkin.timing``) and samples the best at a control period.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Iterator, Sequence
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

from .. import _compile_cache, plan, timing
from ..jet import Jet
from ..robot import Robot, fk
from ..status import STATUS_DTYPE, Status

__all__ = [
    "Ranked",
    "evaluate_joints",
    "evaluate_targets",
    "joint_limits",
    "rank",
    "solve_paths",
]

MIN_SAMPLES = 8  # a path's samples are padded to a power of two, at least this


def joint_limits(
    robot: Robot, v_max: Sequence[float] | None = None, a_max: Sequence[float] | None = None
) -> plan.Limits:
    """The robot's own limits (``robot.joint_limits()``), the speed and acceleration bounds
    tightened to ``v_max`` / ``a_max`` where given (one value for every joint or one per
    joint), as ``plan.evaluate`` intersects its ``limits`` with the robot's.

    Raises:
        ValueError: a bound of the wrong length, negative or NaN (naming the option).
    """
    own = robot.joint_limits()
    n = robot.n_joints
    rates = []
    for given, name, default in (
        (v_max, "--v-max", own.velocity),
        (a_max, "--a-max", own.acceleration),
    ):
        if given is None:
            rates.append(np.broadcast_to(np.asarray(default, float), (n,)))
            continue
        values = np.asarray(given, float)
        if values.size not in (1, n):
            raise ValueError(f"{name}: give one value or {n} (one per joint), got {values.size}")
        if np.any(np.isnan(values)) or np.any(values < 0):
            raise ValueError(f"{name} must be >= 0 (inf for none), got {values.tolist()}")
        rates.append(np.minimum(np.broadcast_to(values, (n,)), np.asarray(default, float)))
    return plan.Limits.create(n, own.lower, own.upper, rates[0], rates[1])


# ------------------------------------------------------------------ trajectories as paths
def _follow(robot: Robot, path: Jet, dt: Any, real: Any, limits: plan.Limits, index: int):
    """``plan.evaluate``'s kernel with a time step per step: ``path`` ``(N, T, *target)``,
    ``dt`` ``(N, T - 1)``, ``real`` ``(N, T)`` False on padding. Returns the joints (Jet
    ``(N, T, n)``), the per-sample statuses and margins."""
    res = robot.ik_path_kernel(path, index, robot.IKOptions())
    # Padding samples are left alone by the checks (any status but OK) and cut by the caller.
    status = jnp.where(real, res.status, jnp.int8(Status.INVALID_INPUT))
    axes = tuple(range(2, path.p.ndim))
    nonzero = (path.v != 0) | (path.a != 0)
    moving = jnp.any(nonzero & real.reshape(real.shape + (1,) * len(axes)), axis=(1, *axes))
    q, status, _ = plan.checked_samples(robot, res.q, status, moving, limits, dt)
    return q, status, res.margin


_follow_jit = _compile_cache.stored_jit(_follow, static_argnames=("index",))


def _padded(size: int, smallest: int) -> int:
    return max(smallest, 1 << max(size - 1, 0).bit_length())


@dataclasses.dataclass
class _Batch:
    """Candidates solved in one call: each one's file rows (its valid rows, in order)."""

    rows: list[np.ndarray]

    @property
    def samples(self) -> int:
        return _padded(len(self.rows), 1) * _padded(max(map(len, self.rows)), MIN_SAMPLES)


def _candidates(candidate: np.ndarray | None, valid: np.ndarray) -> tuple[list, bool]:
    """Every candidate's valid rows (file order), candidates by first row; and whether each
    candidate's rows are one contiguous block of the file (so batches can be written as they
    are solved)."""
    n = len(valid)
    if candidate is None:
        return [np.flatnonzero(valid)], True
    order = np.argsort(candidate, kind="stable")
    labels, starts = np.unique(candidate[order], return_index=True)
    groups = np.split(order, starts[1:])
    groups.sort(key=lambda rows: rows[0])
    contiguous = all(rows[-1] - rows[0] + 1 == len(rows) for rows in groups) and n > 0
    return [rows[valid[rows]] for rows in groups], contiguous


def _batches(groups: list[np.ndarray], chunk: int) -> Iterator[_Batch]:
    batch = _Batch([])
    for rows in groups:
        if not len(rows):
            continue
        trial = _Batch([*batch.rows, rows])
        if batch.rows and trial.samples > chunk:
            yield batch
            trial = _Batch([rows])
        batch = trial
    if batch.rows:
        yield batch


def solve_paths(
    robot: Robot,
    to_target: Callable[[np.ndarray, np.ndarray, np.ndarray], Jet],
    t: np.ndarray,
    rates: tuple[np.ndarray, np.ndarray, np.ndarray],
    candidate: np.ndarray | None,
    valid: np.ndarray,
    branch: Any,
    limits: plan.Limits,
    chunk: int,
) -> Iterator[tuple[int, int, list[np.ndarray]]]:
    """``(start, stop, [q, q_dot, q_ddot, status, margin])`` for file rows ``start:stop``,
    in file order: every candidate solved as one path (module docstring).

    Args:
        robot: the robot.
        to_target: ``(p, v, a)`` rows ``(m, k)`` of file coordinates -> the target Jet
            ``(m, *target)`` in the solve's dtype.
        t: times ``(N,)``; strictly increasing along each candidate's valid rows.
        rates: positions, velocities and accelerations ``(N, k)`` (NaN-free on valid rows).
        candidate: labels ``(N,)`` or None (one path).
        valid: ``(N,)`` rows to solve; the others get ``INVALID_INPUT``, NaN joints.
        branch: one of ``robot.branches``.
        limits: the limits checked (``joint_limits``).
        chunk: about how many samples one call holds.
    """
    n_rows, n_joints = len(t), robot.n_joints
    groups, contiguous = _candidates(candidate, valid)
    index = robot.branches.index(branch)

    dtype = to_target(*(x[:1] for x in rates)).dtype  # of the outputs, as the kernel's

    def empty(size: int) -> list[np.ndarray]:
        q = [np.full((size, n_joints), np.nan, dtype) for _ in range(3)]
        status = np.full(size, Status.INVALID_INPUT, np.int8)
        return [*q, status, np.full(size, -1.0, dtype)]

    every = None if contiguous else empty(n_rows)
    done = 0  # rows written so far (contiguous files)
    for batch in _batches(groups, chunk):
        outputs = _solve_batch(robot, to_target, t, rates, batch, index, limits)
        dtype = outputs[0][0].dtype
        if every is not None:
            for rows, solved in zip(batch.rows, outputs, strict=True):
                for column, values in zip(every, solved, strict=True):
                    column[rows] = values
            continue
        stop = int(batch.rows[-1][-1]) + 1
        part = empty(stop - done)
        for rows, solved in zip(batch.rows, outputs, strict=True):
            for column, values in zip(part, solved, strict=True):
                column[rows - done] = values
        yield done, stop, part
        done = stop
    if every is not None:
        yield 0, n_rows, every
    elif done < n_rows:  # trailing rows that no path holds (invalid input)
        yield done, n_rows, empty(n_rows - done)


def _solve_batch(robot, to_target, t, rates, batch: _Batch, index: int, limits):
    """One call for the candidates of ``batch``: per candidate ``[q, qd, qdd, status,
    margin]`` for its rows."""
    count, length = len(batch.rows), max(map(len, batch.rows))
    n_pad, t_pad = _padded(count, 1), _padded(length, MIN_SAMPLES)
    # Padding repeats a candidate's last sample at rest (the first candidate's rows fill
    # padded candidates); ``real`` keeps it out of every status and range.
    take = np.empty((n_pad, t_pad), np.int64)
    real = np.zeros((n_pad, t_pad), bool)
    for i in range(n_pad):
        rows = batch.rows[i] if i < count else batch.rows[0]
        take[i, : len(rows)], take[i, len(rows) :] = rows, rows[-1]
        real[i, : len(rows)] = i < count
    at_rest = np.ones((n_pad, t_pad), bool)
    for i, rows in enumerate(batch.rows):
        at_rest[i, : len(rows)] = False
    p, v, a = (x[take] for x in rates)
    v, a = (np.where(at_rest[..., None], 0.0, x) for x in (v, a))
    times = t[take]
    dt = np.diff(times, axis=1)
    dt = np.where(dt > 0, dt, 1.0)  # padding: any positive step
    width = p.shape[-1]
    target = to_target(*(x.reshape(-1, width) for x in (p, v, a)))
    target = target.map(lambda x: x.reshape(n_pad, t_pad, *x.shape[1:]))
    target = target.astype(robot.work_dtype(target.dtype))
    q, status, margin = _follow_jit(
        robot, target, jnp.asarray(dt, target.dtype), jnp.asarray(real), limits, index
    )
    q = [np.asarray(x) for x in (q.p, q.v, q.a)]
    status, margin = np.asarray(status), np.asarray(margin)
    return [
        [*(x[i, : len(rows)] for x in q), status[i, : len(rows)], margin[i, : len(rows)]]
        for i, rows in enumerate(batch.rows)
    ]


# ------------------------------------------------------------------ jaxkin plan
@dataclasses.dataclass
class Ranked:
    """Candidates evaluated, ranked and retimed (``rank``).

    Attributes:
        order: the chosen candidates' indices (into the file's candidates), best first.
        cost: every candidate's ``costs.total`` (``inf`` where infeasible), ``(N,)``.
        feasible: ``(N,)``.
        first_failure: sample index of the first non-OK status, -1 when feasible, ``(N,)``.
        failure: status name at the first failure ("" when feasible), ``(N,)``.
        duration: time-optimal duration under the limits (``nan`` where not timed), ``(N,)``.
        retimed: the chosen candidates sampled every ``period``: ``t`` ``(T,)``, Jet
            ``(k, T, n)`` and the valid counts ``(k,)``.
    """

    order: np.ndarray
    cost: np.ndarray
    feasible: np.ndarray
    first_failure: np.ndarray
    failure: np.ndarray
    duration: np.ndarray
    retimed: timing.RetimedTrajectory | None


def evaluate_joints(robot: Robot, q: Jet, dt: float, limits: plan.Limits) -> plan.Evaluation:
    """Joint-space candidates ``(N, T, n)``: forward kinematics along each (its statuses),
    then ``OUT_OF_LIMITS`` where a joint leaves its limits, and ``plan.evaluate``'s costs."""
    res = fk(robot, q)
    status = jnp.asarray(res.status)
    violated = plan.limit_excess(q, limits) > 0
    status = jnp.where((status == Status.OK) & violated, jnp.int8(Status.OUT_OF_LIMITS), status)
    bad = status != Status.OK
    feasible = ~jnp.any(bad, axis=-1)
    first = jnp.where(feasible, -1, jnp.argmax(bad, axis=-1)).astype(jnp.int32)
    return plan.Evaluation(
        q=q,
        status=status.astype(STATUS_DTYPE),
        feasible=feasible,
        first_failure=first,
        min_margin=jnp.zeros(feasible.shape, q.p.dtype),
        branch=jnp.zeros(feasible.shape, jnp.int8),
        costs=plan.trajectory_costs(q, dt, limits, feasible),
        branches=robot.branches,
    )


def evaluate_targets(
    robot: Robot, path: Jet, dt: float, limits: plan.Limits, branch: Any, samples: int | None
) -> plan.Evaluation:
    """Task-space candidates ``(N, T, *target)`` by ``plan.evaluate`` (the robot's own limits
    apply there too; ``limits`` can only tighten them), about ``samples`` samples per call
    (None: its default)."""
    chunk = None if samples is None else max(1, samples // path.shape[1])
    return plan.evaluate(robot, path, limits=limits, branch=branch, dt=dt, chunk_size=chunk)


def rank(
    evaluation: plan.Evaluation,
    dt: float,
    limits: plan.Limits,
    k: int,
    by: str,
    period: float,
) -> Ranked:
    """Rank the candidates of ``evaluation`` by ``"cost"`` (``costs.total``) or ``"duration"``
    (the time-optimal timing, ``jaxkin.timing.retime``, of each feasible candidate's joint
    path under the speed and acceleration limits, from rest to rest, speeds bounded between
    grid points too: ``speed_bound="interval"``) and sample the ``k`` best every ``period``.

    The joint path of a candidate is its samples with their rates in the file's time
    (``s = t``: ``dq/ds = q_dot``), so the retimed trajectory follows the same geometric path.

    Raises:
        ValueError: ``by="duration"`` with a joint whose speed or acceleration bound is
            infinite (no finite minimum duration).
    """
    feasible = np.asarray(evaluation.feasible)
    cost = np.asarray(evaluation.costs.total, float)
    status = np.asarray(evaluation.status)
    first = np.asarray(evaluation.first_failure)
    failure = np.array(
        ["" if f < 0 else Status(int(status[i, f])).name for i, f in enumerate(first.tolist())],
        dtype=object,
    )
    q = evaluation.q
    n_cand, n_samples = q.p.shape[:2]
    v_max, a_max = (np.asarray(x, float) for x in (limits.v_max, limits.a_max))
    timed = bool(np.all(np.isfinite(v_max)) and np.all(np.isfinite(a_max)))
    if by == "duration" and not timed:
        raise ValueError(
            "ranking by duration needs finite speed and acceleration limits for every joint: "
            "the robot has none for some; give --v-max and --a-max (or --by cost)"
        )
    duration = np.full(n_cand, np.nan)
    path = timing_result = None
    if timed and n_cand:
        s = np.arange(n_samples) * dt
        path = timing.JointPath(jnp.asarray(s, q.p.dtype), q.p, q.v, q.a)
        # "interval": the sampled speeds hold between grid points too, as a controller needs
        timing_result = timing.retime(path, v_max, a_max, speed_bound="interval")
        ok = np.asarray(timing_result.ok) & feasible
        duration = np.where(ok, np.asarray(timing_result.duration, float), np.nan)
    if by == "duration":
        candidates = np.flatnonzero(np.isfinite(duration))
        order = candidates[np.argsort(duration[candidates], kind="stable")][:k]
    else:
        order, _ = plan.best(evaluation, k)
    retimed = None
    if path is not None and len(order):
        chosen = jnp.asarray(order)
        sub = jax.tree.map(lambda x: x[chosen] if x.ndim > 1 else x, path)
        sub_timing = jax.tree.map(lambda x: x[chosen], timing_result)
        retimed = timing.sample(sub, sub_timing, period)
    return Ranked(np.asarray(order), cost, feasible, first, failure, duration, retimed)
