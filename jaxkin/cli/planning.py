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
holding about ``chunk`` samples. A candidate longer than a window (``window_size(chunk)``, a
power of two) is solved window by window (``PathSolver``), with the whole path's result:

* each window's IK is warm-started from the joints of the last solved sample before it
  (``plan.path_ik``'s ``seed``) on the branch held, and its joints unwrapped from the previous
  window's last sample and its whole turns (``plan.unwrapped``'s ``turns``); the range of the
  solved samples and whether the path moves are accumulated;
* the windows' samples go to a temporary file: the whole turns that bring a joint's range
  within its limits (``plan.range_turns``) are known only at the path's end;
* then the checks (``plan.checked_samples`` with those ``turns``) run window by window, each
  window prefixed with the previous one's last sample, so its first step is checked for
  continuity with that sample's rates, and the rows are written.

Memory is bounded by a window, not by the path; every window is padded to the window's size
(the last one too), so a file of any length compiles the same programs.

``jaxkin plan`` evaluates a file of candidates with ``plan.evaluate`` (task or joint space:
the library's checks, feasibility and costs), ranks them with ``plan.best`` by ``costs.total``
or by the duration of their time-optimal retiming (``plan.retime``) and samples the best at a
control period.
"""

from __future__ import annotations

import dataclasses
import tempfile
from collections.abc import Callable, Iterator, Sequence
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

from .. import paths, plan, timing
from .._execute import Kernel
from ..jet import Jet
from ..robot import Robot
from ..status import Status

__all__ = [
    "PathSolver",
    "Ranked",
    "evaluate",
    "joint_limits",
    "rank",
    "solve_paths",
    "window_size",
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


_follow_jit = Kernel(_follow, static=("index",))


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


# ------------------------------------------------------------------ long paths in windows
def window_size(chunk: int) -> int:
    """Samples per window of a long path: the largest power of two within ``chunk`` (at least
    ``MIN_SAMPLES``); a path of more samples is solved in windows."""
    return max(MIN_SAMPLES, 1 << (max(int(chunk), 1).bit_length() - 1))


def _window(robot: Robot, path: Jet, real: Any, index: int, carry: dict | None):
    """The IK of one window ``(1, W, *target)`` of a path (``real`` ``(1, W)`` False on
    padding), continuing ``carry`` (None for the first window). Returns the unwrapped joints
    (Jet ``(1, W, n)``, not yet shifted by ``within``'s whole turns), the statuses of the IK
    (``INVALID_INPUT`` on padding), margins, and the carry of the path so far: ``seed`` (the
    joints the next window's IK starts from) and the target they solve (``target``: its
    position and rates), the last sample's joints as solved (``raw``) and its whole turns
    (``turns``), the range of the solved samples (``low``, ``high``) and whether any sample
    moves (``moving``)."""
    rows = (path.p, path.v, path.a)
    if carry is None:
        res = plan.path_ik(robot, path, index)
    else:
        # Prefixed with the seed's own target (dropped again): an iterative IK takes the path
        # up there as the whole path's did (its rates, the time of the next step).
        # Then padded, at rest, to a multiple of 16 samples (the widest vector of float32
        # lanes): a sample in a remainder loop may round otherwise.
        size = real.shape[1]
        pad = -(size + 1) % 16
        tail = (x[:, -1:] * keep for x, keep in zip(rows, (1.0, 0.0, 0.0), strict=True))
        tail = (jnp.repeat(x, pad, axis=1) for x in tail)
        pieces = zip(carry["target"], rows, tail, strict=True)
        joined = Jet(*(jnp.concatenate([c[:, None], x, r], axis=1) for c, x, r in pieces))
        res = plan.path_ik(robot, joined, index, seed=carry["seed"])
        res = dataclasses.replace(
            res,
            q=res.q.map(lambda x: x[:, 1 : size + 1]),
            status=res.status[:, 1 : size + 1],
            margin=res.margin[:, 1 : size + 1],
        )
    status = jnp.where(real, res.status, jnp.int8(Status.INVALID_INPUT))
    revolute = np.array([kind == "R" for kind in robot.joint_types])
    raw = res.q.p
    if carry is None:
        p, turns = plan.unwrapped(raw, revolute), plan.unwrapping_turns(raw, revolute)
    else:  # prefixed with the previous window's last sample, which is dropped again
        behind = jnp.concatenate([carry["raw"][:, None, :], raw], axis=1)
        p = plan.unwrapped(behind, revolute, carry["turns"])[:, 1:]
        turns = plan.unwrapping_turns(behind, revolute, carry["turns"])[:, 1:]
    low, high = plan.solved_range(p, status == Status.OK)
    axes = tuple(range(2, path.p.ndim))
    nonzero = (path.v != 0) | (path.a != 0)
    moving = jnp.any(nonzero & real.reshape(real.shape + (1,) * len(axes)), axis=(1, *axes))
    # The warm start the whole path's IK would carry: the last sample solved (in or outside
    # the limits), else the one it was given.
    good = ((res.status == Status.OK) | (res.status == Status.OUT_OF_LIMITS)) & real
    size = real.shape[1]
    last_good = size - 1 - jnp.argmax(good[:, ::-1], axis=1)
    last = jnp.sum(real, axis=1) - 1

    def at(x, i):
        index = i.reshape(-1, 1, *([1] * (x.ndim - 2)))
        return jnp.take_along_axis(x, index, axis=1)[:, 0]

    before = raw[:, 0] if carry is None else carry["seed"]
    solved = jnp.any(good, axis=1)
    earlier = tuple(x[:, 0] for x in rows) if carry is None else carry["target"]
    target = tuple(
        jnp.where(solved.reshape(-1, *([1] * (x.ndim - 2))), at(x, last_good), e)
        for x, e in zip(rows, earlier, strict=True)
    )
    out = {
        "seed": jnp.where(solved[:, None], at(raw, last_good), before),
        "target": target,
        "raw": at(raw, last),
        "turns": at(turns, last),
        "low": low,
        "high": high,
        "moving": moving,
    }
    if carry is not None:
        out["low"] = jnp.minimum(carry["low"], low)
        out["high"] = jnp.maximum(carry["high"], high)
        out["moving"] = carry["moving"] | moving
    return Jet(p, res.q.v, res.q.a), status, res.margin, out


_window_jit = Kernel(_window, static=("index",))


def _window_checks(robot: Robot, q: Jet, status: Any, moving: Any, limits, dt: Any, turns: Any):
    """``plan.checked_samples`` of a window prefixed with the previous one's last sample,
    the joints shifted by the whole path's ``turns``."""
    q, status, _ = plan.checked_samples(robot, q, status, moving, limits, dt, turns=turns)
    return q, status


_window_checks_jit = Kernel(_window_checks)


@dataclasses.dataclass
class _Rows:
    """File rows: times, candidate labels, positions, velocities, accelerations, valid."""

    t: np.ndarray
    label: np.ndarray
    p: np.ndarray
    v: np.ndarray
    a: np.ndarray
    valid: np.ndarray

    def __len__(self) -> int:
        return len(self.t)

    def __getitem__(self, rows: Any) -> _Rows:
        return _Rows(*(x[rows] for x in dataclasses.astuple(self)))

    @staticmethod
    def joined(first: _Rows | None, second: _Rows) -> _Rows:
        if first is None or not len(first):
            return second
        return _Rows(
            *(np.concatenate([x, y]) for x, y in zip(dataclasses.astuple(first),
                                                      dataclasses.astuple(second), strict=True))
        )  # fmt: skip


# Rows solved: (t, candidate labels or None, valid, [q, q_dot, q_ddot, status, margin]).
Block = tuple[np.ndarray, "np.ndarray | None", np.ndarray, list[np.ndarray]]


class PathSolver:
    """Every candidate of a file read in parts solved as one path (module docstring), the
    rows given back in file order as soon as they are final: ``feed`` each part, then
    ``finish``. A candidate of at most ``window_size(chunk)`` rows is solved whole (batched
    with others, ``solve_paths``); a longer one window by window (``_LongPath``). Candidates
    must be contiguous in the file (``files.completed_parts`` checks it)."""

    def __init__(
        self,
        robot: Robot,
        to_target: Callable[[np.ndarray, np.ndarray, np.ndarray], Jet],
        branch: Any,
        limits: plan.Limits,
        chunk: int,
    ) -> None:
        self.robot, self.to_target, self.limits, self.chunk = robot, to_target, limits, chunk
        self.branch, self.index = branch, robot.branches.index(branch)
        self.window = window_size(chunk)
        self.labelled: bool | None = None
        self.dtype: Any = None  # of the outputs until a window is solved
        self.held: _Rows | None = None  # rows of a candidate not yet known to be short or long
        self.long: _LongPath | None = None

    def feed(
        self,
        t: np.ndarray,
        candidate: np.ndarray | None,
        rates: tuple[np.ndarray, np.ndarray, np.ndarray],
        valid: np.ndarray,
    ) -> Iterator[Block]:
        """The rows that are final once this part is read (file order)."""
        if self.labelled is None:
            self.labelled = candidate is not None
            self.dtype = self.to_target(*(x[:1] for x in rates)).dtype
        label = np.zeros(len(t), np.int64) if candidate is None else np.asarray(candidate)
        if not _candidates(label, valid)[1]:  # interleaved: the whole file, read at once
            rows = _Rows(np.asarray(t, float), label, *rates, valid)
            yield from self._whole(rows)
            return
        rows = _Rows.joined(self.held, _Rows(np.asarray(t, float), label, *rates, valid))
        self.held = None
        yield from self._solve(rows, final=False)

    def finish(self) -> Iterator[Block]:
        """The rows still held, at the end of the file."""
        rows, self.held = self.held, None
        if rows is not None and len(rows):
            yield from self._solve(rows, final=True)
        if self.long is not None:  # a long path ending exactly at the end of a part
            yield from self.long.add(None, done=True)
            self.long = None

    def _solve(self, rows: _Rows, final: bool) -> Iterator[Block]:
        while len(rows):
            if self.long is not None:
                other = np.flatnonzero(rows.label != self.long.label)
                end = int(other[0]) if other.size else len(rows)
                done = end < len(rows) or final
                yield from self.long.add(rows[:end], done)
                if done:
                    self.long = None
                rows = rows[end:]
                continue
            bounds = [0, *(np.flatnonzero(np.diff(rows.label)) + 1).tolist(), len(rows)]
            short, arriving = 0, False  # rows of the complete candidates short enough
            for k in range(len(bounds) - 1):
                size, complete = bounds[k + 1] - bounds[k], k < len(bounds) - 2 or final
                arriving = size <= self.window and not complete
                if size > self.window or arriving:
                    break
                short = bounds[k + 1]
            if arriving and short < self.chunk:  # batched with the candidates still to come
                self.held = rows
                return
            if short:
                yield from self._whole(rows[:short])
                rows = rows[short:]
            elif len(rows):
                self.long = _LongPath(self, int(rows.label[0]))

    def _whole(self, rows: _Rows) -> Iterator[Block]:
        labels = rows.label if self.labelled else None
        for start, stop, outputs in solve_paths(
            self.robot,
            self.to_target,
            rows.t,
            (rows.p, rows.v, rows.a),
            labels,
            rows.valid,
            self.branch,
            self.limits,
            self.chunk,
        ):
            part = slice(start, stop)
            yield rows.t[part], None if labels is None else labels[part], rows.valid[part], outputs


class _LongPath:
    """One candidate longer than a window, solved window by window (module docstring): its
    valid samples (IK results) and its file rows (times, valid) go to temporary files, then
    the checks run and the rows are given back."""

    def __init__(self, solver: PathSolver, label: int) -> None:
        self.solver, self.label = solver, label
        self.samples = tempfile.TemporaryFile()  # per sample: t, q, q_dot, q_ddot, status, margin
        self.rows = tempfile.TemporaryFile()  # per file row: t, valid
        self.pending: _Rows | None = None  # valid rows waiting for a full window
        self.carry: dict | None = None
        self.dtype: Any = solver.dtype

    def add(self, rows: _Rows | None, done: bool) -> Iterator[Block]:
        """Take the candidate's next rows; at its end (``done``) give back all its rows."""
        window = self.solver.window
        if rows is not None and len(rows):
            self.rows.write(np.stack([rows.t, rows.valid.astype(float)], -1).tobytes())
            self.pending = _Rows.joined(self.pending, rows[rows.valid])
        while self.pending is not None and len(self.pending) >= window:
            self._solve(self.pending[:window])
            self.pending = self.pending[window:]
        if not done:
            return
        if self.pending is not None and len(self.pending):
            self._solve(self.pending)
        self.pending = None
        yield from self._checked()
        self.samples.close()
        self.rows.close()

    def _solve(self, rows: _Rows) -> None:
        """The IK of a window of valid rows (padded, at rest, to the window's size)."""
        solver = self.solver
        size, count = solver.window, len(rows)
        take = np.minimum(np.arange(size), count - 1)
        real = np.arange(size) < count
        p = rows.p[take]
        v, a = (np.where(real[:, None], x[take], 0.0) for x in (rows.v, rows.a))
        target = solver.to_target(p, v, a)
        target = target.map(lambda x: x.reshape(1, size, *x.shape[1:]))
        target = target.astype(solver.robot.work_dtype(target.dtype))
        q, status, margin, self.carry = _window_jit(
            solver.robot, target, jnp.asarray(real[None]), solver.index, self.carry
        )
        self.dtype = q.p.dtype
        record = np.concatenate(
            [
                rows.t[:, None],
                *(np.asarray(x, float)[0, :count] for x in (q.p, q.v, q.a)),
                np.asarray(status, float)[0, :count, None],
                np.asarray(margin, float)[0, :count, None],
            ],
            axis=-1,
        )
        self.samples.write(record.tobytes())

    def _checked(self) -> Iterator[Block]:
        """The checks of the spooled samples, a window of file rows at a time, and the rows."""
        solver, robot = self.solver, self.solver.robot
        n, size, dtype = robot.n_joints, solver.window, self.dtype
        width = 3 * n + 3
        self.rows.seek(0)
        self.samples.seek(0)
        turns = moving = None
        if self.carry is not None:
            revolute = np.array([kind == "R" for kind in robot.joint_types])
            lower, upper = (x.astype(dtype) for x in (solver.limits.q_min, solver.limits.q_max))
            turns = plan.range_turns(self.carry["low"], self.carry["high"], revolute, lower, upper)
            moving = self.carry["moving"]
        previous = None  # the last sample given to the checks: (record, kernel status)
        while True:
            block = np.frombuffer(self.rows.read(size * 2 * 8), float).reshape(-1, 2)
            if not len(block):
                return
            t, valid = block[:, 0].copy(), block[:, 1] > 0
            count = int(valid.sum())
            samples = np.frombuffer(self.samples.read(count * width * 8), float)
            samples = samples.reshape(count, width)
            q = [np.full((len(t), n), np.nan, dtype) for _ in range(3)]
            status = np.full(len(t), Status.INVALID_INPUT, np.int8)
            margin = np.full(len(t), -1.0, dtype)
            if count:
                checked_q, checked_status = self._check(samples, previous, turns, moving)
                for column, values in zip(q, checked_q, strict=True):
                    column[valid] = values
                status[valid] = checked_status
                margin[valid] = samples[:, -1]
                previous = samples[-1]
            labels = np.full(len(t), self.label, np.int64) if solver.labelled else None
            yield t, labels, valid, [*q, status, margin]

    def _check(self, samples: np.ndarray, previous: np.ndarray | None, turns, moving):
        """``_window_checks`` of ``samples`` (records) prefixed with ``previous`` (a record,
        or a placeholder that no check reads); padded to the window's size."""
        solver = self.solver
        n, size, count = solver.robot.n_joints, solver.window, len(samples)
        first = samples[0] if previous is None else previous
        take = np.minimum(np.arange(size), count - 1)
        joined = np.concatenate([first[None], samples[take]])  # (size + 1, width)
        real = np.r_[previous is not None, np.arange(size) < count]
        status = np.where(real, joined[:, 3 * n + 1], Status.INVALID_INPUT).astype(np.int8)
        steps = np.diff(joined[:, 0])
        steps = np.where(real[1:] & real[:-1] & (steps > 0), steps, 1.0)
        dtype = self.dtype
        q = Jet(*(jnp.asarray(joined[None, :, 1 + k * n : 1 + (k + 1) * n], dtype)
                  for k in range(3)))  # fmt: skip
        checked, status = _window_checks_jit(
            solver.robot,
            q,
            jnp.asarray(status[None]),
            moving,
            solver.limits,
            jnp.asarray(steps[None], dtype),
            turns,
        )
        rows = slice(1, 1 + count)
        values = [np.asarray(x)[0, rows] for x in (checked.p, checked.v, checked.a)]
        return values, np.asarray(status)[0, rows]


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
            ``(k, T, n)`` and the valid counts ``(k,)`` (0 for one not timed); None when
            none could be retimed.
        untimed: why the candidates could not be retimed at all ("" when they could).
        violations: the joint and limit each ``OUT_OF_LIMITS`` candidate passes first
            (``plan.limit_violations``).
    """

    order: np.ndarray
    cost: np.ndarray
    feasible: np.ndarray
    first_failure: np.ndarray
    failure: np.ndarray
    duration: np.ndarray
    retimed: timing.RetimedTrajectory | None
    violations: plan.LimitViolations
    untimed: str = ""


def evaluate(
    robot: Robot,
    path: paths.Path,
    limits: plan.Limits,
    branch: Any,
    samples: int | None,
    world: Any = None,
) -> plan.Evaluation:
    """Task-space (``(N, T, *target)``) or joint-space (``(N, T, n)``) candidates by
    ``plan.evaluate``, the library's own checks (the robot's limits apply there too;
    ``limits`` can only tighten them; with a ``world``, its collision check), about
    ``samples`` samples per call (None: its default)."""
    chunk = None if samples is None else max(1, samples // path.shape[1])
    return plan.evaluate(robot, path, limits=limits, branch=branch, chunk_size=chunk, world=world)


def rank(evaluation: plan.Evaluation, k: int, by: str, period: float) -> Ranked:
    """Rank the candidates of ``evaluation`` by ``"cost"`` or ``"duration"`` (``plan.best``)
    and sample the ``k`` best every ``period``, retimed by ``plan.retime`` (from rest to rest,
    speeds bounded between samples too, as a controller needs: ``speed_bound="interval"``).

    The joint path of a candidate is its samples with their rates in the file's time, so the
    retimed trajectory follows the same geometric path. With ``by="cost"``, when the
    candidates cannot be retimed (``plan.retime`` refuses them: ``untimed`` says why) or a
    chosen one is not timed (its ``duration`` is NaN), the caller writes it at its samples.

    Raises:
        ValueError: ``by="duration"`` and ``plan.retime`` refuses the candidates (a joint
            without an acceleration limit, named; fewer than 3 samples).
    """
    feasible = np.asarray(evaluation.feasible)
    cost = np.asarray(evaluation.costs.total, float)
    status = np.asarray(evaluation.status)
    first = np.asarray(evaluation.first_failure)
    failure = np.array(
        ["" if f < 0 else Status(int(status[i, f])).name for i, f in enumerate(first.tolist())],
        dtype=object,
    )
    duration = np.full(len(feasible), np.nan)
    timed, untimed = None, ""
    try:
        timed = plan.retime(evaluation, speed_bound="interval")
    except ValueError as exc:
        if by == "duration":
            raise
        untimed = str(exc)
    else:
        duration = np.where(np.asarray(timed.ok), np.asarray(timed.duration, float), np.nan)
    order, _ = plan.best(evaluation, k, by=by, timing=timed)
    retimed = None
    if timed is not None and len(order):
        chosen = jnp.asarray(order)
        path = jax.tree.map(lambda x: x[chosen], plan.joint_path(evaluation))
        retimed = timing.sample(path, jax.tree.map(lambda x: x[chosen], timed), period)
    violations = plan.limit_violations(evaluation)
    return Ranked(
        np.asarray(order), cost, feasible, first, failure, duration, retimed, violations, untimed
    )
