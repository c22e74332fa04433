"""The ``ik``, ``fk`` and ``workspace`` subcommands, written against the robot protocol only."""

from __future__ import annotations

import argparse
import dataclasses
import itertools
import sys
from pathlib import Path
from typing import Any

import jax
import numpy as np

from .. import _batching, _processes, paths
from ..jet import Jet
from ..robot import POSE, Robot, fk, ik
from ..status import Status, status_names
from . import distributed, files, planning
from .progress import reporting
from .robots import ROBOTS, CliError, build_robot, geometry_values, option, parse_branch

__all__ = ["cmd_fk", "cmd_ik", "cmd_plan", "cmd_workspace", "robot_from_args", "set_dtype"]

MAX_VOXELS = 500_000_000  # a bool mask of this size is 0.5 GB


def robot_from_args(args: argparse.Namespace) -> Robot:
    """The robot described by ``--robot`` and the geometry options of ``args``."""
    entry = ROBOTS[args.kind]
    links = {"--tip": getattr(args, "tip", None), "--base": getattr(args, "base", None)}
    if entry.from_file:
        if args.robot is None or args.robot.strip().lower() == "paper":
            raise CliError(f"{entry.name}: --robot FILE is required (the robot's description)")
        if links["--tip"] is None:
            raise CliError(f"{entry.name}: --tip LINK is required (the link whose pose is solved)")
        try:
            return entry.build(args.robot, links["--tip"], links["--base"])
        except ImportError as exc:
            raise CliError(str(exc)) from None
        except ValueError as exc:
            raise CliError(f"--robot {args.robot}: {exc}") from None
    given = [name for name, value in links.items() if value is not None]
    if given:
        raise CliError(f"{given[0]} is for robots described by a file (urdf), not {entry.name}")
    for key, users in _field_users().items():
        if key not in entry.fields and getattr(args, key, None) is not None:
            raise CliError(f"{option(key)} is a {'/'.join(users)} option, not for {entry.name}")
    options = {k: getattr(args, k) for k in entry.fields if getattr(args, k, None) is not None}
    values = geometry_values(entry, args.robot, options, args.notes)
    return build_robot(entry, values)


def _field_users() -> dict[str, list[str]]:
    users: dict[str, list[str]] = {}
    for entry in ROBOTS.values():
        for key in entry.fields:
            users.setdefault(key, []).append(entry.name)
    return users


def set_dtype(name: str) -> Any:
    """Configure JAX for ``name`` (float64 turns on x64 in this process) and return the dtype."""
    if name == "float64":
        jax.config.update("jax_enable_x64", True)
        return np.float64
    return np.float32


def _join(args: argparse.Namespace) -> None:
    """``--distributed``: join JAX's processes; only process 0 prints (and writes)."""
    distributed.join(args)
    if not distributed.is_writer():
        args.quiet = True


def _robot_file(args: argparse.Namespace) -> str | None:
    """The ``--robot`` argument when it names a file (not ``paper``)."""
    spec = getattr(args, "robot", None)
    return None if spec is None or spec.strip().lower() == "paper" else spec


def _check_paths(args: argparse.Namespace) -> None:
    """Every output against every input and each other, and writable; before any work."""
    inputs = {"--input": getattr(args, "input", None), "--robot": _robot_file(args)}
    outputs = {"--output": args.output, "--plot": args.plot}
    try:
        files.check_outputs(outputs, inputs)
    except files.InputError as exc:
        raise CliError(str(exc)) from None
    if args.plot:
        from .. import plot

        plot.require_matplotlib()
        from matplotlib.backend_bases import FigureCanvasBase

        fmt = Path(args.plot).suffix.lstrip(".").lower() or "png"
        known = FigureCanvasBase.get_supported_filetypes()
        if fmt not in known:
            raise CliError(
                f"--plot {args.plot}: matplotlib cannot write .{fmt} files (it writes "
                f"{', '.join(sorted(known))})"
            )


def _counted(counts: np.ndarray) -> str:
    """``"OK 12, UNREACHABLE 3"`` from counts per status code."""
    names = status_names(np.flatnonzero(counts))
    return ", ".join(f"{n} {c}" for n, c in zip(names, counts[counts > 0], strict=True))


def _parts(args: argparse.Namespace, names: tuple[str, ...], quaternions: bool, inverse: bool):
    """``(as_path, parts)``: whether the rows are solved as paths, and the file's rows with
    their rates, ``(part, p, v, a, valid)``, a part at a time when the file can be streamed
    (a CSV file, no --plot, one process: memory bounded by a part), else one part."""
    chunk = args.chunk_size or _batching.HOST_CHUNK
    streamed = (
        files.file_format(args.input) == "csv" and not args.plot and _processes.process_count() == 1
    )
    parts = files.trajectory_parts(
        args.input, names, timed=False, block=min(chunk, files.READ_BLOCK)
    )
    first = next(parts)
    # A trajectory (rows with times) is solved as one path per candidate; rows without
    # times, or with --each-row, each on its own.
    as_path = inverse and first.t is not None and not args.each_row
    if streamed and not (args.output == "-" and first.candidate is not None):
        chained = itertools.chain([first], parts)
        if as_path:
            streamed_parts = files.completed_parts(
                chained, args.spline, chunk, quaternions, False, "along a path",
                "; or give --each-row", ordered=True,
            )  # fmt: skip
        else:
            streamed_parts = files.completed_parts(chained, args.spline, chunk, quaternions)
        return as_path, streamed_parts
    traj = files.read_trajectory(args.input, names, timed=False)
    return as_path, _whole(traj, args.spline, quaternions, as_path)


def _whole(traj: files.Trajectory, spline: str, quaternions: bool, as_path: bool):
    if quaternions:
        traj = files.continuous_quaternions(traj)
    p, v, a, valid = files.complete_rates(traj, spline)
    if as_path:
        files.check_times(traj, valid, "along a path", "; or give --each-row")
    yield traj, p, v, a, valid


def _solve_file(args: argparse.Namespace, inverse: bool) -> int:
    _join(args)
    _check_paths(args)
    dtype = set_dtype(args.dtype)  # before the robot: its geometry's arrays take the dtype
    robot = robot_from_args(args)
    pose = robot.target == POSE
    if not (robot.target.is_point or pose):
        raise CliError(f"{args.kind}: files of {robot.target.name} targets are not supported")
    branch = parse_branch(robot, args.branch) if inverse else None
    targets, joints = robot.target.coordinates, robot.joint_names
    in_names, out_names = (targets, joints) if inverse else (joints, targets)
    limits = None
    if inverse:
        try:
            limits = planning.joint_limits(robot, args.v_max, args.a_max)
        except ValueError as exc:
            raise CliError(str(exc)) from None
    quaternions = pose and inverse
    try:
        as_path, parts = _parts(args, in_names, quaternions, inverse)
        return _write_solved(args, inverse, robot, dtype, branch, limits, out_names, as_path, parts)
    except files.NotContiguous:  # a candidate split by another: read the file whole
        args.notes.append("jaxkin: note: candidates' rows are interleaved: the file is read whole")
        traj = files.read_trajectory(args.input, in_names, timed=False)
        as_path = inverse and traj.t is not None and not args.each_row
        parts = _whole(traj, args.spline, quaternions, as_path)
        return _write_solved(args, inverse, robot, dtype, branch, limits, out_names, as_path, parts)


def _write_solved(args, inverse, robot, dtype, branch, limits, out_names, as_path, parts) -> int:
    """Solve the parts' rows (``_parts``) and write them, part by part."""
    pose = robot.target == POSE
    quaternions = pose and inverse

    def target(p, v, a):
        if quaternions:  # x, y, z, qw, qx, qy, qz rows -> 4x4 transforms with rates
            return paths.pose_from_quaternions(p, v, a).astype(dtype)
        # Host arrays (jnp.asarray would compile a program per shape in every run).
        return Jet(p.astype(dtype), v.astype(dtype), a.astype(dtype))

    def solve(p, v, a):
        jet = target(p, v, a)
        if inverse:
            res = ik(robot, jet, branch)
            out = res.q, res.status, res.margin
        else:
            res = fk(robot, jet)
            out = res.x, res.status
        # On the host at once: cutting a device array compiles a program in every run.
        return jax.tree.map(np.asarray, out)

    desc = f"{args.kind} {'ik' if inverse else 'fk'}"
    chunk = args.chunk_size or _batching.HOST_CHUNK
    writer = distributed.is_writer()
    signs = files.QuaternionSigns() if pose and not inverse else None
    counts = np.zeros(len(Status), np.int64)  # rows per status
    solved_valid, n_valid, n_invalid, first_invalid = 0, 0, 0, None
    kept, statuses, times, labels = [], [], [], []  # only for --plot

    def solved():
        """``(t, candidate, valid, outputs)`` of the rows in file order, as they are solved."""
        nonlocal n_invalid, n_valid, first_invalid
        # Every process solves every path (they are not split); a long path is solved in
        # windows, carried from part to part.
        solver = planning.PathSolver(robot, target, branch, limits, chunk) if as_path else None
        for traj, p, v, a, valid in parts:
            bad = np.flatnonzero(~valid)
            if bad.size and first_invalid is None:
                first_invalid = traj.table.where(bad[0])
            n_invalid, n_valid = n_invalid + bad.size, n_valid + len(valid) - bad.size
            if solver is not None:
                yield from solver.feed(traj.t, traj.candidate, (p, v, a), valid)
                continue
            chunks = distributed.solved_chunks(solve, (p, v, a), chunk, desc, args.quiet)
            for start, stop, outputs in chunks:
                rows = slice(start, stop)
                yield (
                    None if traj.t is None else traj.t[rows],
                    None if traj.candidate is None else traj.candidate[rows],
                    valid[rows],
                    outputs,
                )
        if solver is not None:
            yield from solver.finish()

    written = 0  # rows
    with files.table_writer(args.output if writer else None) as write:
        for t_rows, candidate, ok, outputs in solved():
            q, qd, qdd, status = outputs[:4]
            start, stop = written, written + len(ok)
            written = stop
            if signs is not None:  # 4x4 transforms -> x, y, z, qw, qx, qy, qz rows
                q, qd, qdd = paths.quaternions_from_pose(Jet(q, qd, qdd))
                sign = signs(candidate, ok, q[:, 3:])[:, None]
                for block in (q, qd, qdd):  # continuous along each candidate
                    block[:, 3:] *= sign
            for block in (q, qd, qdd):
                block[~ok] = np.nan  # nothing meaningful to report for invalid input
            status = np.asarray(status, np.int8)
            counts += np.bincount(status, minlength=len(counts))
            solved_valid += int(np.sum(status[ok] == Status.OK))
            if args.plot and writer:
                kept.append((q, qd, qdd))
                statuses.append(status)
                times.append(np.arange(start, stop) if t_rows is None else t_rows)
                labels.append(candidate)
            extra = {"margin": outputs[4]} if inverse else None
            write(
                files.trajectory_columns(
                    t_rows,
                    candidate,
                    out_names,
                    q,
                    qd,
                    qdd,
                    status_names(status),
                    extra,
                )
            )
    if not writer:
        return 0
    if n_invalid:
        what = "NaN/inf input or a zero quaternion" if quaternions else "NaN/inf input"
        print(
            f"jaxkin: warning: {n_invalid} of {n_invalid + n_valid} rows have {what} (first "
            f"at {first_invalid}): status INVALID_INPUT, the rest is solved",
            file=sys.stderr,
        )
    if n_valid and not solved_valid:
        print(
            f"jaxkin: warning: no row has status OK ({_counted(counts)}): check the geometry "
            "and the units of the input",
            file=sys.stderr,
        )
    if args.plot:
        from .. import plot

        q, qd, qdd = (np.concatenate(block) for block in zip(*kept, strict=True))
        candidate = None if labels[0] is None else np.concatenate(labels)
        plot.joint_trajectories(
            np.concatenate(times).astype(float),
            q,
            qd,
            qdd,
            np.concatenate(statuses),
            names=out_names,
            candidate=candidate,
            path=args.plot,
        )
    if not args.quiet:
        what = f"{args.kind} {'ik' if inverse else 'fk'}"
        if inverse:
            what += f" (branch {branch})"
        how = (
            (", one path per candidate" if as_path else ", each row on its own") if inverse else ""
        )
        print(
            f"jaxkin: {what}, {int(counts.sum())} rows{how}, {np.dtype(dtype).name}: "
            f"{_counted(counts)} -> {args.output}" + (f", {args.plot}" if args.plot else ""),
            file=sys.stderr,
        )
    return 0


def cmd_ik(args: argparse.Namespace) -> int:
    """``jaxkin ik``: joint trajectories from end-point trajectories."""
    return _solve_file(args, inverse=True)


def cmd_fk(args: argparse.Namespace) -> int:
    """``jaxkin fk``: end-point trajectories from joint trajectories."""
    return _solve_file(args, inverse=False)


def cmd_workspace(args: argparse.Namespace) -> int:
    """``jaxkin workspace``: a voxel sweep; prints the reachable volume."""
    from .. import workspace

    _join(args)
    dtype = set_dtype(args.dtype)  # before the robot: its geometry's arrays take the dtype
    robot = robot_from_args(args)
    if not robot.target.is_point:
        raise CliError(f"{args.kind}: a voxel workspace needs a robot whose targets are points")
    branch = parse_branch(robot, args.branch)
    if args.output is not None:
        if files.file_format(args.output) != "npz":
            raise CliError(f"--output {args.output}: the workspace is saved as .npz")
    _check_paths(args)
    if args.resolution is not None and not (np.isfinite(args.resolution) and args.resolution > 0):
        raise CliError(f"--resolution must be positive, got {args.resolution}")
    dims = robot.target.shape[0]
    try:
        bounds, resolution = robot.workspace_box()
    except ValueError:
        bounds, resolution = None, None
    if args.bounds is not None:
        b = args.bounds
        if len(b) != 2 * dims:
            raise CliError(f"--bounds: {args.kind} needs {2 * dims} numbers (lo hi per axis)")
        bounds = tuple((b[2 * k], b[2 * k + 1]) for k in range(dims))
        for name, (lo, hi) in zip("xyz", bounds, strict=False):
            if not (np.isfinite(lo) and np.isfinite(hi) and lo <= hi):
                raise CliError(f"--bounds: need finite {name}min <= {name}max, got {lo:g} {hi:g}")
    if bounds is None:
        raise CliError(f"{args.kind} has no default workspace box: give --bounds")
    resolution = args.resolution if args.resolution is not None else resolution
    if resolution is None:
        resolution = max(hi - lo for lo, hi in bounds) / 50.0
    counts = [int(np.floor((hi - lo) / resolution + 1e-9)) + 1 for lo, hi in bounds]
    if float(np.prod(counts, dtype=float)) > MAX_VOXELS:
        raise CliError(
            f"{' x '.join(map(str, counts))} voxels is too many (at most {MAX_VOXELS:.0e}): "
            "use a coarser --resolution or smaller --bounds"
        )
    with reporting("workspace", enabled=False if args.quiet else None) as progress:
        result = workspace.sweep(
            robot,
            bounds,
            resolution,
            branch=branch,
            chunk_size=args.chunk_size or _batching.SWEEP_CHUNK,
            dtype=dtype,
            progress=progress,
        )
    if not _processes.fetchable(result.mask):  # every process takes part in the gather
        result = dataclasses.replace(result, mask=_processes.to_host(result.mask))
    if not distributed.is_writer():
        return 0
    if args.output is not None:
        entry = ROBOTS[args.kind]
        geometry = {f"geometry_{k}": float(np.asarray(getattr(robot, k))) for k in entry.fields}
        axes = dict(zip("xyz", result.axes, strict=False))
        saved: dict[str, Any] = dict(
            mask=result.mask,
            **axes,
            resolution=result.resolution,
            volume=result.volume,
            n_reachable=result.n_reachable,
            n_evaluated=result.n_evaluated,
            slice_areas=result.slice_areas,
            robot=args.kind,
            **geometry,
        )
        with files.atomic_write(args.output, "wb") as f:
            np.savez(f, **saved)
    if args.plot:
        from .. import plot

        plot.workspace_overview(result, title=f"{args.kind} workspace", path=args.plot)
    unit = "^3" if dims == 3 else "^2"
    print(
        f"reachable {'volume' if dims == 3 else 'area'}: {result.volume:.6g} (length unit){unit} "
        f"= {result.n_reachable} of {result.n_evaluated} voxels of edge {result.resolution:g}"
    )
    return 0


def _world(path: str) -> Any:
    """The obstacles of ``--world`` (a world file or a MoveIt scene), or a ``CliError``."""
    from .. import collision

    try:
        return collision.read_world(path)
    except (ValueError, ImportError) as exc:
        raise CliError(f"--world {path}: {exc}") from None


def _checked(evaluate: Any, *args: Any, **kwargs: Any) -> Any:
    """``evaluate(*args, **kwargs)``, a ``ValueError`` (a world the checks refuse) as a
    ``CliError``."""
    try:
        return evaluate(*args, **kwargs)
    except ValueError as exc:
        raise CliError(f"--world: {exc}") from None


def _candidate_samples(traj: files.Trajectory, valid: np.ndarray) -> tuple[list[np.ndarray], float]:
    """The rows of every candidate (first-appearance order) and the common sample period:
    every candidate must have the same number of samples, uniformly spaced by one period,
    all valid (``plan.evaluate`` takes ``(N, T)`` samples at one ``dt``)."""
    if traj.t is None:
        raise CliError(f"{traj.table.source}: a file of candidate paths needs a t column")
    labels = traj.candidate if traj.candidate is not None else np.zeros(len(traj.t), np.int64)
    bad = np.flatnonzero(~valid)
    if bad.size:
        raise CliError(
            f"{traj.table.where(bad[0])}: NaN/inf (or a zero quaternion) in a candidate path"
        )
    _, first, inverse = np.unique(labels, return_index=True, return_inverse=True)
    groups = [np.flatnonzero(inverse == k) for k in np.argsort(first)]
    counts = {len(rows) for rows in groups}
    if len(counts) != 1 or min(counts) < 2:
        raise CliError(
            f"{traj.table.source}: every candidate needs the same number of samples (>= 2), "
            f"got {sorted(counts)}"
        )
    files.check_times(traj, valid, "along a path")
    steps = np.stack([np.diff(traj.t[rows]) for rows in groups])
    dt = float(steps[0, 0])
    off = np.flatnonzero(np.abs(steps - dt).max(axis=1) > 1e-9 * max(dt, abs(traj.t).max()))
    if off.size:
        label = labels[groups[off[0]][0]]
        raise CliError(
            f"{traj.table.source}: candidate {label}: samples must be spaced by one period "
            f"(the first candidate's {dt:g}) in every candidate"
        )
    return groups, dt


def _failures(ranked: Any, labels: np.ndarray, t: np.ndarray, units: tuple[str, ...]):
    """One line per kind of failure: how many candidates failed so, and where the first of
    them failed (for ``OUT_OF_LIMITS``, the joint and the limit, with their units)."""
    for name in sorted(set(ranked.failure.tolist()) - {""}):
        which = np.flatnonzero(ranked.failure == name)
        first = int(which[0])
        sample = int(ranked.first_failure[first])
        detail = ranked.violations.message(first, units)
        yield (
            f"jaxkin: {len(which)} candidate{'s' if len(which) > 1 else ''} {name}; the first, "
            f"candidate {labels[first]}, at sample {sample} (t {t[first, sample]:g})"
            + (f": {detail}" if detail else "")
        )


def cmd_plan(args: argparse.Namespace) -> int:
    """``jaxkin plan``: evaluate a file of candidate paths, rank them, write the best retimed."""
    _join(args)
    inputs = {"--input": args.input, "--robot": _robot_file(args), "--world": args.world}
    outputs = {"--output": args.output, "--ranking": args.ranking}
    try:
        files.check_outputs(outputs, inputs)
    except files.InputError as exc:
        raise CliError(str(exc)) from None
    if args.period is not None and not (np.isfinite(args.period) and args.period > 0):
        raise CliError(f"--period must be a positive number, got {args.period:g}")
    dtype = set_dtype(args.dtype)
    robot = robot_from_args(args)
    world = None if args.world is None else _world(args.world)
    pose = robot.target == POSE
    if not (robot.target.is_point or pose):
        raise CliError(f"{args.kind}: files of {robot.target.name} targets are not supported")
    targets, joints = robot.target.coordinates, robot.joint_names
    columns = files.read_table(args.input, ("t", "candidate", *targets, *joints)).columns
    joint_space = all(n in columns for n in joints) and not all(n in columns for n in targets)
    names = joints if joint_space else targets
    traj = files.read_trajectory(args.input, names)
    if pose and not joint_space:
        traj = files.continuous_quaternions(traj)
    p, v, a, valid = files.complete_rates(traj, args.spline)
    groups, dt = _candidate_samples(traj, valid)
    take = np.stack(groups)
    try:
        limits = planning.joint_limits(robot, args.v_max, args.a_max)
    except ValueError as exc:
        raise CliError(str(exc)) from None
    branch = None
    if joint_space:
        jet = Jet.of(*(x[take].astype(dtype) for x in (p, v, a)))
    else:
        branch = "best" if args.branch == "best" else parse_branch(robot, args.branch)
        flat = [x[take].reshape(-1, x.shape[-1]) for x in (p, v, a)]
        if pose:
            jet = paths.pose_from_quaternions(*flat).astype(dtype)
        else:
            jet = Jet.of(*(x.astype(dtype) for x in flat))
        jet = jet.map(lambda x: x.reshape(*take.shape, *x.shape[1:]))
    path = paths.Path.from_jet(jet, dt, "joint" if joint_space else "task")
    evaluation = planning.evaluate(robot, path, limits, branch, args.chunk_size, world=world)
    period = args.period if args.period is not None else dt
    try:
        ranked = planning.rank(evaluation, args.best, args.by, period)
    except ValueError as exc:
        raise CliError(str(exc).replace("a_max", "--a-max")) from None
    if not distributed.is_writer():
        return 0
    labels = traj.candidate[take[:, 0]] if traj.candidate is not None else np.zeros(len(take))
    labels = labels.astype(np.int64)
    if args.ranking is not None:
        rank_of = np.full(len(take), -1)
        rank_of[ranked.order] = np.arange(1, len(ranked.order) + 1)
        files.write_table(
            args.ranking,
            {
                "candidate": labels,
                "rank": rank_of,
                "feasible": ranked.feasible,
                "first_failure": ranked.first_failure,
                "failure": ranked.failure.astype(str),
                "joint": ranked.violations.joint_name.astype(str),
                "limit": ranked.violations.limit.astype(str),
                "value": ranked.violations.value,
                "bound": ranked.violations.bound,
                "cost": np.where(np.isfinite(ranked.cost), ranked.cost, np.nan),
                "duration": ranked.duration,
                **({} if world is None else {"clearance": np.asarray(evaluation.min_clearance)}),
            },
        )
    at_samples = []  # chosen candidates not retimed, written at the file's samples
    with files.table_writer(args.output) as write:
        for place, index in enumerate(ranked.order.tolist()):
            if ranked.retimed is not None and np.isfinite(ranked.duration[index]):
                count = int(ranked.retimed.count[place])
                t = np.asarray(ranked.retimed.t)[:count]
                jet = ranked.retimed.q
                q = [np.asarray(x)[place, :count] for x in (jet.p, jet.v, jet.a)]
            else:
                at_samples.append(int(labels[index]))
                t = np.asarray(traj.t)[take[index]]
                jet = evaluation.q
                q = [np.asarray(x)[index] for x in (jet.p, jet.v, jet.a)]
            written = {"rank": np.full(len(t), place + 1)}
            labelled = np.full(len(t), labels[index])
            written |= files.trajectory_columns(t, labelled, joints, q[0], q[1], q[2])
            write(written)
    if not args.quiet:
        print(f"{'rank':>4} {'candidate':>9} {'cost':>12} {'duration':>10}")
        for place, index in enumerate(ranked.order.tolist()):
            print(
                f"{place + 1:>4} {labels[index]:>9} {ranked.cost[index]:>12.6g} "
                f"{ranked.duration[index]:>10.6g}"
            )
        feasible = int(np.sum(ranked.feasible))
        how = "time-optimal duration" if args.by == "duration" else "cost"
        units = tuple(
            "rad" if kind == "R" else ROBOTS[args.kind].unit for kind in robot.joint_types
        )
        for line in _failures(ranked, labels, np.asarray(traj.t)[take], units):
            print(line, file=sys.stderr)
        print(
            f"jaxkin: {args.kind} plan, {len(take)} candidates of {take.shape[1]} samples "
            f"({'joint' if joint_space else 'task'} space), {feasible} feasible; the "
            f"{len(ranked.order)} best by {how} -> {args.output}",
            file=sys.stderr,
        )
    if ranked.untimed:
        print(
            f"jaxkin: warning: not retimed ({ranked.untimed}): the best are written at the "
            "file's samples",
            file=sys.stderr,
        )
    elif at_samples:
        print(
            f"jaxkin: warning: candidate(s) {', '.join(map(str, at_samples))} could not be "
            "retimed (UNTIMEABLE): written at the file's samples",
            file=sys.stderr,
        )
    if not len(ranked.order):
        print("jaxkin: warning: no candidate is feasible (and timed)", file=sys.stderr)
    return 0
