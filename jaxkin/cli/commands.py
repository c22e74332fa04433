"""The ``ik``, ``fk`` and ``workspace`` subcommands, written against the robot protocol only."""

from __future__ import annotations

import argparse
import dataclasses
import os
import sys
from pathlib import Path
from typing import Any

import jax
import numpy as np

from .. import _batching, _processes, paths
from ..jet import Jet
from ..robot import POSE, Robot, fk, ik
from ..status import status_names
from . import distributed, files
from .robots import ROBOTS, CliError, build_robot, geometry_values, option, parse_branch

__all__ = ["cmd_fk", "cmd_ik", "cmd_workspace", "robot_from_args", "set_dtype"]

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


def _summary(status: np.ndarray) -> str:
    names, counts = np.unique(status_names(status), return_counts=True)
    return ", ".join(f"{n} {c}" for n, c in zip(names, counts, strict=True))


def _warn_invalid(traj: files.Trajectory, valid: np.ndarray) -> None:
    bad = np.flatnonzero(~valid)
    if bad.size:
        print(
            f"jaxkin: warning: {bad.size} of {len(valid)} rows have NaN/inf input "
            f"(first at {traj.table.where(bad[0])}): status INVALID_INPUT, the rest is solved",
            file=sys.stderr,
        )


def _same_file(first: str, second: str) -> bool:
    """True when two spellings name one file (symlinks, ``./``, ``..`` included)."""
    a, b = Path(first), Path(second)
    try:
        if a.exists() and b.exists():
            return os.path.samefile(a, b)
        return a.resolve() == b.resolve()
    except OSError:
        return False


def _check_output(path: str, what: str = "--output", source: str | None = None) -> None:
    if path == "-":
        return
    if source is not None and _same_file(source, path):
        raise CliError(
            f"{what} {path} is the input file {source}: it would be overwritten; choose another"
        )
    try:  # fail before solving, with the checks atomic_write applies at the end
        files.check_output_path(path)
    except files.InputError as exc:
        raise CliError(f"{what} {exc}") from None


def _solve_file(args: argparse.Namespace, inverse: bool) -> int:
    _join(args)
    robot = robot_from_args(args)
    pose = robot.target == POSE
    if not (robot.target.is_point or pose):
        raise CliError(f"{args.kind}: files of {robot.target.name} targets are not supported")
    branch = parse_branch(robot, args.branch) if inverse else None
    _check_output(args.output, source=args.input)
    if args.plot:
        _check_output(args.plot, "--plot", source=args.input)
        from .. import plot

        plot.require_matplotlib()
    dtype = set_dtype(args.dtype)
    targets, joints = robot.target.coordinates, robot.joint_names
    in_names, out_names = (targets, joints) if inverse else (joints, targets)
    traj = files.read_trajectory(args.input, in_names)
    if pose and inverse:
        traj = files.continuous_quaternions(traj)
    p, v, a, valid = files.complete_rates(traj, args.spline)
    if distributed.is_writer():
        _warn_invalid(traj, valid)

    def solve(p, v, a):
        if pose and inverse:  # x, y, z, qw, qx, qy, qz rows -> 4x4 transforms with rates
            jet = paths.pose_from_quaternions(p, v, a).astype(dtype)
        else:
            jet = Jet.of(p.astype(dtype), v.astype(dtype), a.astype(dtype))
        if inverse:
            res = ik(robot, jet, branch)
            return res.q, res.status, res.margin
        res = fk(robot, jet)
        return res.x, res.status

    desc = f"{args.kind} {'ik' if inverse else 'fk'}"
    chunk = args.chunk_size or _batching.HOST_CHUNK
    outputs = distributed.solve_rows(
        files.solve_in_chunks, solve, (p, v, a), chunk, desc, args.quiet
    )
    q, qd, qdd, status = outputs[:4]
    if pose and not inverse:  # 4x4 transforms -> x, y, z, qw, qx, qy, qz rows
        q, qd, qdd = paths.quaternions_from_pose(Jet(q, qd, qdd))
        sign = files.quaternion_signs(traj.t, traj.candidate, valid, q[:, 3:])[:, None]
        for block in (q, qd, qdd):  # continuous along each candidate, as splines need
            block[:, 3:] *= sign
    for block in (q, qd, qdd):
        block[~valid] = np.nan  # nothing meaningful to report for invalid input
    if not distributed.is_writer():
        return 0
    if valid.any() and not np.any(status[valid] == 0):
        print(
            f"jaxkin: warning: no row has status OK ({_summary(status)}): check the geometry "
            "and the units of the input",
            file=sys.stderr,
        )
    extra = {"margin": outputs[4]} if inverse else None
    columns = files.trajectory_columns(
        traj.t, traj.candidate, out_names, q, qd, qdd, status_names(status), extra
    )
    files.write_table(args.output, columns)
    if args.plot:
        from .. import plot

        plot.joint_trajectories(
            traj.t, q, qd, qdd, status, names=out_names, candidate=traj.candidate, path=args.plot
        )
    if not args.quiet:
        what = f"{args.kind} {'ik' if inverse else 'fk'}"
        if inverse:
            what += f" (branch {branch})"
        print(
            f"jaxkin: {what}, {len(status)} rows, {np.dtype(dtype).name}: {_summary(status)}"
            f" -> {args.output}" + (f", {args.plot}" if args.plot else ""),
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
    robot = robot_from_args(args)
    if not robot.target.is_point:
        raise CliError(f"{args.kind}: a voxel workspace needs a robot whose targets are points")
    branch = parse_branch(robot, args.branch)
    if args.output is not None:
        if files.file_format(args.output) != "npz":
            raise CliError(f"--output {args.output}: the workspace is saved as .npz")
        _check_output(args.output)
    if args.plot:
        _check_output(args.plot, "--plot")
        from .. import plot

        plot.require_matplotlib()
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
    dtype = set_dtype(args.dtype)
    progress = False if args.quiet else None
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
        with files.atomic_write(args.output, "wb") as f:
            np.savez(
                f,
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
    if args.plot:
        from .. import plot

        plot.workspace_overview(result, title=f"{args.kind} workspace", path=args.plot)
    unit = "^3" if dims == 3 else "^2"
    print(
        f"reachable {'volume' if dims == 3 else 'area'}: {result.volume:.6g} (length unit){unit} "
        f"= {result.n_reachable} of {result.n_evaluated} voxels of edge {result.resolution:g}"
    )
    return 0
