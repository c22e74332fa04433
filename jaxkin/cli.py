"""The ``jaxkin`` command: solve trajectory files, sweep workspaces, run the examples.

Subcommands (``jaxkin SUBCOMMAND --help`` for every option)::

    jaxkin demo [NAME] [--list]             run an example of examples/ (default scara-spiral)
    jaxkin ik ROBOT -i IN -o OUT [...]      joint trajectories from end-point trajectories
    jaxkin fk ROBOT -i IN -o OUT [...]      end-point trajectories from joint trajectories
    jaxkin workspace ROBOT [...]            chunked voxel sweep, prints the reachable volume

``ROBOT`` is ``scara``, ``delta`` or the serial arm ``anthropomorphic`` (seed 001's RRR arm,
``jaxkin.serial.arms.Anthropomorphic``; joint rates by ``jaxkin.lift`` of its analytic IK).
Geometry comes from ``--robot paper`` (the papers' robots: SCARA 150/80/50 mm of seed 000,
``Delta.paper()`` 7/2.5/15.5/30 cm of seed 002; seed 001 prints no arm lengths), from
``--robot FILE.toml|FILE.json`` (keys named like the options: ``l_oa = 150`` ...), and/or from
options (``--l-oa --l-ab --l-bc``; ``--r-base --r-platform --l-arm --l-rod``; ``--l1 --l2
--l3``), which override the file. With no geometry at all the paper's robot is used (with a
note). ``--mode``: SCARA assembly mode ``+1``/``-1``, Delta branch ``out``/``in``, arm branch
``front_up``/``front_down``/``back_up``/``back_down``.

Files (``jaxkin.io``): CSV with a header row, or ``.npz``; ``t,x,y,z`` plus optional
``candidate``, ``vx,vy,vz``, ``ax,ay,az`` for ``ik``; ``t`` and the joint columns (SCARA
``theta1,theta2,l3``, Delta ``theta1,theta2,theta3``, arm ``q1,q2,q3``) plus optional
``<joint>_dot`` and ``<joint>_ddot`` for ``fk`` (an ``ik`` output is a valid ``fk`` input).
Rates missing from the file are computed by a cubic spline in ``t`` per candidate
(``jaxkin.splines``, not-a-knot by default; rows with NaN/inf are left out of the fit). For
``fk`` of revolute joints wrapped to (-pi, pi], give the rate columns (as ``ik`` writes them):
a spline through a 2 pi jump is meaningless. The output has the same layout, the solved
columns, ``status`` (a ``jaxkin.Status`` name) per row and, for ``ik`` of SCARA and Delta,
``margin`` (the solver's distance to a singularity); the format follows the output's suffix.

Errors: bad input (missing or malformed file, missing columns, impossible geometry, bad
options) prints one line ``jaxkin: error: ...`` on stderr and exits with status 2, never a
traceback (``--traceback`` shows it for debugging). Rows with NaN/inf are not errors: they get
status ``INVALID_INPUT``, the rest is solved, and a warning gives their count. Outputs are
written atomically (``jaxkin.io.atomic_write``): a failed or interrupted run leaves an
existing output file untouched. Ctrl-C exits with status 130.

Precision: ``--dtype float64`` (default) turns on JAX's 64-bit mode *in this process* (an
application's choice; the library itself never changes JAX's configuration); ``float32``
solves in single precision.
"""

from __future__ import annotations

import argparse
import ast
import dataclasses
import json
import subprocess
import sys
import tomllib
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import jax
import numpy as np

from . import __version__, splines
from . import io as kio
from . import progress as kprogress

EXIT_ERROR = 2
EXIT_INTERRUPTED = 130
DEFAULT_CHUNK = 1 << 16
EXAMPLES_DIR = Path(__file__).resolve().parent.parent / "examples"
DEFAULT_DEMO = "scara-spiral"
MAX_VOXELS = 500_000_000  # a bool mask of this size is 0.5 GB
Bounds = tuple[tuple[float, float], tuple[float, float], tuple[float, float]]


class CliError(Exception):
    """A user-facing error: printed as one line, exit status 2."""


class _Parser(argparse.ArgumentParser):
    """argparse with one-line errors (raised, so ``main`` prints them and returns 2)."""

    def error(self, message: str) -> Any:  # type: ignore[override]
        raise CliError(f"{message} (see '{self.prog} --help')")


# ------------------------------------------------------------------------------------ robots


@dataclasses.dataclass(frozen=True)
class RobotKind:
    """How the command builds and solves one kind of robot."""

    name: str
    fields: tuple[str, ...]  # geometry keys; option --a-b for key a_b
    optional: tuple[str, ...]  # further keys accepted in a robot file
    paper: dict[str, float]
    unit: str  # the paper robot's length unit
    joints: tuple[str, ...]
    modes: dict[str, Any]  # --mode spelling -> library value
    default_mode: str
    build: Callable[[dict[str, Any]], Any]
    ik: Callable[..., tuple[Any, Any, Any]]  # (robot, Jet, mode) -> (q Jet, status, margin)
    fk: Callable[..., tuple[Any, Any]]  # (robot, q Jet) -> (p Jet, status)
    workspace: Callable[..., Any]  # (robot, mode, bounds, resolution, chunk, dtype, progress)
    extent: Callable[[Any], tuple[Bounds, float]]  # default box and resolution


def _scara_build(values: dict[str, Any]) -> Any:
    from . import scara

    return scara.Scara.create(
        values["l_oa"], values["l_ab"], values["l_bc"], limits=values.get("limits")
    )


def _scara_ik(robot: Any, d: Any, mode: int) -> tuple[Any, Any, Any]:
    from . import scara

    res = scara.ik(robot, d, mode=mode)
    return res.q, res.status, res.margin


def _scara_fk(robot: Any, q: Any) -> tuple[Any, Any]:
    import jax.numpy as jnp

    from . import scara
    from .status import Status

    p = scara.fk(robot, q)
    finite = jnp.all(jnp.isfinite(jnp.concatenate([q.p, q.v, q.a], -1)), -1)
    return p, jnp.where(finite, Status.OK, Status.INVALID_INPUT)


def _scara_extent(robot: Any) -> tuple[Bounds, float]:
    """Default box: the reach annulus' square, z from the floor to the arm plane (l3 in
    [0, l_oa], or the l3 limits); resolution reach / 50."""
    reach = float(robot.l_ab) + float(robot.l_bc)
    l3_range = (0.0, float(robot.l_oa))  # the end point between the floor and A
    if robot.limits is not None:
        lo, hi = (float(np.asarray(x)[2]) for x in (robot.limits.lower, robot.limits.upper))
        l3_range = (
            max(lo, 0.0) if np.isfinite(lo) else 0.0,
            hi if np.isfinite(hi) else float(robot.l_oa),
        )
    z_lo, z_hi = float(robot.l_oa) - l3_range[1], float(robot.l_oa) - l3_range[0]
    return ((-reach, reach), (-reach, reach), (z_lo, z_hi)), reach / 50.0


def _scara_workspace(robot, mode, bounds, resolution, chunk, dtype, progress):
    from . import scara, workspace
    from .status import Status

    return workspace.sweep(
        lambda pts: scara.ik(robot, pts, mode=mode).status,
        bounds,
        resolution,
        chunk_size=chunk,
        dtype=dtype,
        progress=progress,
        reachable=(Status.OK, Status.SINGULAR_EXTENDED, Status.SINGULAR_FOLDED),
    )


def _delta_build(values: dict[str, Any]) -> Any:
    from . import delta

    robot = delta.Delta(
        float(values["r_base"]),
        float(values["r_platform"]),
        float(values["l_arm"]),
        float(values["l_rod"]),
    )
    if "theta_min" in values or "theta_max" in values:
        robot = robot.with_limits(
            float(values.get("theta_min", -np.inf)), float(values.get("theta_max", np.inf))
        )
    return robot


def _delta_ik(robot: Any, p: Any, branch: str) -> tuple[Any, Any, Any]:
    from . import delta

    res = delta.ik(robot, p, branch=branch)
    return res.theta, res.status, res.margin


def _delta_fk(robot: Any, theta: Any) -> tuple[Any, Any]:
    from . import delta

    res = delta.fk(robot, theta)  # its default tolerance follows the dtype
    return res.p, res.status


def _delta_extent(robot: Any) -> tuple[Bounds, float]:
    """``jaxkin.delta.workspace``'s default box (x, y in [-R, R], z in [-0.9 R, 0.9 R] with
    R the maximum horizontal reach); resolution R / 50 (the paper's 1 cm grid)."""
    reach = float(robot.r_base) - float(robot.r_platform) + float(robot.l_arm)
    reach += float(robot.l_rod)
    return ((-reach, reach), (-reach, reach), (-0.9 * reach, 0.9 * reach)), reach / 50.0


def _delta_workspace(robot, mode, bounds, resolution, chunk, dtype, progress):
    from . import delta

    return delta.workspace(
        robot, bounds, resolution, branch=mode, chunk_size=chunk, dtype=dtype, progress=progress
    )


def _arm_build(values: dict[str, Any]) -> Any:
    from .serial import arms

    return arms.Anthropomorphic(float(values["l1"]), float(values["l2"]), float(values["l3"]))


def _arm_fk_core(robot: Any, q: Any) -> tuple[Any, Any]:
    import jax.numpy as jnp

    from .jet import lift
    from .serial import arms
    from .status import Status

    p = lift(lambda x: arms.fk(robot, x)[..., :3, 3])(q)
    finite = jnp.all(jnp.isfinite(jnp.concatenate([q.p, q.v, q.a], -1)), -1)
    return p, jnp.where(finite, Status.OK, Status.INVALID_INPUT)


_arm_fk_jit = jax.jit(_arm_fk_core)


def _arm_ik(robot: Any, p: Any, branch: str) -> tuple[Any, Any, Any]:
    """Analytic IK of one branch; rates by ``jaxkin.lift`` (zero where the status is not OK),
    the whole nested jvp compiled once."""
    from .serial import arms

    q, status = arms.ik_jet(robot, p, branch)
    return q, status, None


def _arm_fk(robot: Any, q: Any) -> tuple[Any, Any]:
    return _arm_fk_jit(robot, q)


def _arm_extent(robot: Any) -> tuple[Bounds, float]:
    """Default box: the cube around the reach sphere (centre at the shoulder, radius
    l2 + l3); resolution reach / 25."""
    l1, reach = float(robot.l1), float(robot.l2) + float(robot.l3)
    return ((-reach, reach), (-reach, reach), (l1 - reach, l1 + reach)), reach / 25.0


def _arm_workspace(robot, mode, bounds, resolution, chunk, dtype, progress):
    from . import workspace
    from .serial import arms
    from .status import Status

    return workspace.sweep(
        lambda pts: arms.ik(robot, pts).branch(mode).status,
        bounds,
        resolution,
        chunk_size=chunk,
        dtype=dtype,
        progress=progress,
        reachable=(Status.OK, Status.SINGULAR),
    )


ROBOTS: dict[str, RobotKind] = {
    "scara": RobotKind(
        name="scara",
        fields=("l_oa", "l_ab", "l_bc"),
        optional=("limits",),
        paper={"l_oa": 150.0, "l_ab": 80.0, "l_bc": 50.0},
        unit="mm",
        joints=("theta1", "theta2", "l3"),
        modes={"+1": 1, "1": 1, "-1": -1},
        default_mode="+1",
        build=_scara_build,
        ik=_scara_ik,
        fk=_scara_fk,
        workspace=_scara_workspace,
        extent=_scara_extent,
    ),
    "delta": RobotKind(
        name="delta",
        fields=("r_base", "r_platform", "l_arm", "l_rod"),
        optional=("theta_min", "theta_max"),
        paper={"r_base": 7.0, "r_platform": 2.5, "l_arm": 15.5, "l_rod": 30.0},
        unit="cm",
        joints=("theta1", "theta2", "theta3"),
        modes={"out": "out", "in": "in"},
        default_mode="out",
        build=_delta_build,
        ik=_delta_ik,
        fk=_delta_fk,
        workspace=_delta_workspace,
        extent=_delta_extent,
    ),
    "anthropomorphic": RobotKind(
        name="anthropomorphic",
        fields=("l1", "l2", "l3"),
        optional=(),
        paper={},  # seed 001 prints no link lengths (ERRATA)
        unit="m",
        joints=("q1", "q2", "q3"),
        modes={b: b for b in ("front_up", "front_down", "back_up", "back_down")},
        default_mode="front_up",
        build=_arm_build,
        ik=_arm_ik,
        fk=_arm_fk,
        workspace=_arm_workspace,
        extent=_arm_extent,
    ),
}


def _option(key: str) -> str:
    return "--" + key.replace("_", "-")


def _read_robot_file(path: Path) -> dict[str, Any]:
    if not path.exists():
        raise CliError(f"--robot {path}: no such file (or use --robot paper)")
    suffix = path.suffix.lower()
    try:
        if suffix == ".toml":
            values = tomllib.loads(path.read_text(encoding="utf-8-sig"))
        elif suffix == ".json":
            values = json.loads(path.read_text(encoding="utf-8-sig"))
        else:
            raise CliError(f"--robot {path}: expected a .toml or .json file, or 'paper'")
    except tomllib.TOMLDecodeError as exc:
        raise CliError(f"{path}: invalid TOML: {exc}") from None
    except json.JSONDecodeError as exc:
        raise CliError(f"{path}:{exc.lineno}: invalid JSON: {exc.msg}") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise CliError(f"{path}: cannot read: {exc}") from None
    if not isinstance(values, dict):
        raise CliError(f"{path}: expected a table/object of geometry values")
    return values


def _number(value: Any, where: str) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise CliError(f"{where} must be a number, got {value!r}")
    return float(value)


def robot_values(kind: RobotKind, args: argparse.Namespace) -> dict[str, Any]:
    """Geometry values from ``--robot`` and the options (options win)."""
    for other in ROBOTS.values():
        for key in other.fields:
            if other is not kind and key not in kind.fields and getattr(args, key) is not None:
                raise CliError(f"{_option(key)} is a {other.name} option, not for {kind.name}")
    values: dict[str, Any] = {}
    spec = args.robot
    if spec is not None and spec.strip().lower() == "paper":
        if not kind.paper:
            raise CliError(f"--robot paper: the papers give no {kind.name} dimensions")
        values.update(kind.paper)
    elif spec is not None:
        path = Path(spec)
        raw = _read_robot_file(path)
        declared = raw.pop("robot", raw.pop("type", kind.name))
        if declared != kind.name:
            raise CliError(f"{path}: describes a {declared!r} robot, not {kind.name!r}")
        unknown = sorted(set(raw) - set(kind.fields) - set(kind.optional))
        if unknown:
            expected = ", ".join(kind.fields + kind.optional)
            raise CliError(f"{path}: unknown key(s) {', '.join(unknown)} (expected {expected})")
        for key, value in raw.items():
            values[key] = value if key == "limits" else _number(value, f"{path}: {key}")
    options = {k: getattr(args, k) for k in kind.fields if getattr(args, k) is not None}
    values.update(options)
    if spec is None and not options and kind.paper:
        # Printed after a successful run only: a failing run prints exactly one line.
        args.notes.append(
            f"jaxkin: note: no geometry given, used the paper's {kind.name} "
            f"({_describe_geometry(kind, kind.paper)}); see --robot"
        )
        values.update(kind.paper)
    missing = [_option(k) for k in kind.fields if k not in values]
    if missing:
        raise CliError(
            f"missing geometry {', '.join(missing)} for {kind.name} "
            "(or give --robot paper / --robot FILE.toml)"
        )
    return values


def _describe_geometry(kind: RobotKind, values: dict[str, Any]) -> str:
    return ", ".join(f"{k} {values[k]:g}" for k in kind.fields) + f" {kind.unit}"


def build_robot(kind: RobotKind, args: argparse.Namespace) -> Any:
    """The robot described by ``args`` (``--robot`` and the geometry options)."""
    values = robot_values(kind, args)
    try:
        return kind.build(values)
    except (ValueError, TypeError) as exc:
        raise CliError(f"invalid {kind.name} geometry: {exc}") from None


def parse_mode(kind: RobotKind, mode: str | None) -> Any:
    mode = kind.default_mode if mode is None else mode.strip().lower()
    if mode not in kind.modes:
        raise CliError(
            f"--mode for {kind.name} must be one of {', '.join(dict.fromkeys(kind.modes))}, "
            f"got {mode!r}"
        )
    return kind.modes[mode]


def set_dtype(name: str) -> Any:
    """Configure JAX for ``name`` (float64 turns on x64 in this process) and return the dtype."""

    if name == "float64":
        jax.config.update("jax_enable_x64", True)
        return np.float64
    return np.float32


# ------------------------------------------------------------------------------------ solving


def complete_rates(traj: kio.Trajectory, end: str) -> tuple[np.ndarray, ...]:
    """Positions, velocities, accelerations (``(N, k)``) and the valid-row mask ``(N,)``.

    Rates missing from the file come from ``jaxkin.splines.by_group`` over the valid rows of
    each candidate; invalid rows (NaN/inf) get NaN rates, hence status ``INVALID_INPUT``.
    """
    valid = traj.valid
    if traj.v is not None and traj.a is not None:
        return traj.p, traj.v, traj.a, valid
    group = traj.candidate if traj.candidate is not None else np.zeros(len(traj.t), np.int64)
    for label in np.unique(group[valid]):
        rows = np.flatnonzero(valid & (group == label))
        bad = np.flatnonzero(np.diff(traj.t[rows]) <= 0)
        if bad.size:
            row = rows[bad[0] + 1]
            name = f"candidate {label}: " if traj.candidate is not None else ""
            raise kio.InputError(
                f"{traj.table.where(row)}: {name}t must increase strictly to compute rates "
                f"(t = {traj.t[row]:g} after {traj.t[rows[bad[0]]]:g}); or give the rate columns"
            )
    v, a = splines.by_group(traj.t, traj.p, group, end=end, valid=valid)
    return traj.p, traj.v if traj.v is not None else v, traj.a if traj.a is not None else a, valid


def solve_chunked(
    fn: Callable[..., tuple[Any, ...]],
    arrays: Sequence[np.ndarray],
    chunk: int,
    desc: str,
    quiet: bool,
) -> list[np.ndarray]:
    """Apply ``fn`` to row chunks of ``arrays`` and concatenate its outputs (a tuple of
    Jets/arrays, flattened to host arrays). Every chunk has the same padded shape (the last
    is padded with a copy of a real row), so ``fn`` compiles once per file."""

    n = len(arrays[0])
    # Pad to a power of two (at most ``chunk``): files of similar sizes share one compilation.
    chunk = max(1, min(chunk, 1 << max(n - 1, 0).bit_length()))
    parts: list[list[np.ndarray]] = []
    with kprogress.bar(n, desc, enabled=False if quiet else None) as bar:
        for start in range(0, n, chunk):
            stop = min(start + chunk, n)
            index = np.arange(start, start + chunk)
            index[stop - start :] = start  # pad with a real row, discarded below
            out = fn(*(x[index] for x in arrays))
            leaves = [np.asarray(x)[: stop - start] for x in jax.tree.leaves(out)]
            parts.append(leaves)
            bar.update(stop - start)
    return [np.concatenate(column) for column in zip(*parts, strict=True)]


def _summary(status: np.ndarray) -> str:
    from .status import status_names

    names, counts = np.unique(status_names(status), return_counts=True)
    return ", ".join(f"{n} {c}" for n, c in zip(names, counts, strict=True))


def _warn_invalid(traj: kio.Trajectory, valid: np.ndarray) -> None:
    bad = np.flatnonzero(~valid)
    if bad.size:
        print(
            f"jaxkin: warning: {bad.size} of {len(valid)} rows have NaN/inf input "
            f"(first at {traj.table.where(bad[0])}): status INVALID_INPUT, the rest is solved",
            file=sys.stderr,
        )


def _check_output(path: str, what: str = "--output") -> None:
    if path == "-":
        return
    try:  # fail before solving, with the checks atomic_write applies at the end
        kio.check_output_path(path)
    except kio.InputError as exc:
        raise CliError(f"{what} {exc}") from None


def _solve_file(args: argparse.Namespace, inverse: bool) -> int:
    kind = ROBOTS[args.kind]
    robot = build_robot(kind, args)
    mode = parse_mode(kind, args.mode) if inverse else None
    _check_output(args.output)
    if args.plot:
        _check_output(args.plot, "--plot")
        from . import plot

        plot.require_matplotlib()
    dtype = set_dtype(args.dtype)
    in_names, out_names = (kio.CARTESIAN, kind.joints) if inverse else (kind.joints, kio.CARTESIAN)
    traj = kio.read_trajectory(args.input, in_names)
    p, v, a, valid = complete_rates(traj, args.spline)
    _warn_invalid(traj, valid)
    from .jet import Jet

    def solve(p, v, a):
        jet = Jet.of(p.astype(dtype), v.astype(dtype), a.astype(dtype))
        if inverse:
            return kind.ik(robot, jet, mode)
        return kind.fk(robot, jet)

    desc = f"{kind.name} {'ik' if inverse else 'fk'}"
    outputs = solve_chunked(solve, (p, v, a), args.chunk_size, desc, args.quiet)
    q, qd, qdd, status = outputs[:4]
    for block in (q, qd, qdd):
        block[~valid] = np.nan  # nothing meaningful to report for invalid input
    if valid.any() and not np.any(status[valid] == 0):
        print(
            f"jaxkin: warning: no row has status OK ({_summary(status)}): check the geometry "
            "and the units of the input",
            file=sys.stderr,
        )
    from .status import status_names

    extra = {"margin": outputs[4]} if inverse and len(outputs) > 4 else None
    columns = kio.trajectory_columns(
        traj.t, traj.candidate, out_names, q, qd, qdd, status_names(status), extra
    )
    kio.write_table(args.output, columns)
    if args.plot:
        from . import plot

        plot.joint_trajectories(
            traj.t,
            q,
            qd,
            qdd,
            status,
            names=out_names,
            candidate=traj.candidate,
            path=args.plot,
        )
    if not args.quiet:
        what = f"{kind.name} {'ik' if inverse else 'fk'}"
        if inverse:
            what += f" (mode {args.mode or kind.default_mode})"
        print(
            f"jaxkin: {what}, {len(status)} rows, {np.dtype(dtype).name}: {_summary(status)}"
            f" -> {args.output}" + (f", {args.plot}" if args.plot else ""),
            file=sys.stderr,
        )
    return 0


def cmd_ik(args: argparse.Namespace) -> int:
    return _solve_file(args, inverse=True)


def cmd_fk(args: argparse.Namespace) -> int:
    return _solve_file(args, inverse=False)


def cmd_workspace(args: argparse.Namespace) -> int:
    kind = ROBOTS[args.kind]
    robot = build_robot(kind, args)
    mode = parse_mode(kind, args.mode)
    if args.output is not None:
        if kio.file_format(args.output) != "npz":
            raise CliError(f"--output {args.output}: the workspace is saved as .npz")
        _check_output(args.output)
    if args.plot:
        _check_output(args.plot, "--plot")
        from . import plot

        plot.require_matplotlib()
    if args.resolution is not None and not (np.isfinite(args.resolution) and args.resolution > 0):
        raise CliError(f"--resolution must be positive, got {args.resolution}")
    bounds, resolution = kind.extent(robot)
    if args.bounds is not None:
        b = args.bounds
        bounds = ((b[0], b[1]), (b[2], b[3]), (b[4], b[5]))
        for name, (lo, hi) in zip("xyz", bounds, strict=True):
            if not (np.isfinite(lo) and np.isfinite(hi) and lo <= hi):
                raise CliError(f"--bounds: need finite {name}min <= {name}max, got {lo:g} {hi:g}")
    resolution = args.resolution if args.resolution is not None else resolution
    counts = [int(np.floor((hi - lo) / resolution + 1e-9)) + 1 for lo, hi in bounds]
    if float(np.prod(counts, dtype=float)) > MAX_VOXELS:
        raise CliError(
            f"{' x '.join(map(str, counts))} voxels is too many (at most {MAX_VOXELS:.0e}): "
            "use a coarser --resolution or smaller --bounds"
        )
    dtype = set_dtype(args.dtype)
    progress = False if args.quiet else None
    result = kind.workspace(robot, mode, bounds, resolution, args.chunk_size, dtype, progress)
    if args.output is not None:
        geometry = {f"geometry_{k}": float(np.asarray(getattr(robot, k))) for k in kind.fields}
        with kio.atomic_write(args.output, "wb") as f:
            np.savez(
                f,
                mask=result.mask,
                x=result.axes[0],
                y=result.axes[1],
                z=result.axes[2],
                resolution=result.resolution,
                volume=result.volume,
                n_reachable=result.n_reachable,
                n_evaluated=result.n_evaluated,
                slice_areas=result.slice_areas,
                robot=kind.name,
                **geometry,
            )
    if args.plot:
        from . import plot

        plot.workspace_overview(result, title=f"{kind.name} workspace", path=args.plot)
    print(
        f"reachable volume: {result.volume:.6g} (length unit)^3 = {result.n_reachable} of "
        f"{result.n_evaluated} voxels of edge {result.resolution:g}"
    )
    return 0


# -------------------------------------------------------------------------------------- demos


def examples() -> dict[str, Path]:
    """Example scripts by name: ``examples/scara_spiral.py`` -> ``scara-spiral``
    (a ``_demo`` suffix is dropped: ``dyad_demo.py`` -> ``dyad``)."""
    if not EXAMPLES_DIR.is_dir():
        return {}
    found = {}
    for path in sorted(EXAMPLES_DIR.glob("*.py")):
        if path.name.startswith("_"):
            continue
        stem = path.stem.removesuffix("_demo")
        found[stem.replace("_", "-")] = path
    return found


def _first_doc_line(path: Path) -> str:
    try:
        doc = ast.get_docstring(ast.parse(path.read_text(encoding="utf-8")))
    except (OSError, SyntaxError, UnicodeDecodeError):
        return ""
    return doc.strip().splitlines()[0] if doc else ""


def cmd_demo(args: argparse.Namespace) -> int:
    found = examples()
    if not found:
        raise CliError(
            f"no examples found in {EXAMPLES_DIR}: 'jaxkin demo' runs the scripts of a source "
            "checkout of jaxkin"
        )
    if args.list:
        width = max(len(n) for n in found)
        for name, path in found.items():
            print(f"{name:{width}s}  {_first_doc_line(path)}")
        return 0
    name = resolve_example(args.name or DEFAULT_DEMO, found)
    if not args.quiet:
        print(f"jaxkin: running {found[name]}", file=sys.stderr)
    return subprocess.call([sys.executable, str(found[name]), *args.args])


def resolve_example(name: str, found: dict[str, Path]) -> str:
    """An example's name from an exact name or a unique prefix (``planner`` ->
    ``planner-scara``); ``CliError`` listing the available names otherwise."""
    name = name.strip().lower().replace("_", "-").removesuffix(".py")
    if name in found:
        return name
    matches = [n for n in found if n.startswith(name)]
    if len(matches) == 1:
        return matches[0]
    problem = "is ambiguous" if matches else "is not present"
    raise CliError(f"example {name!r} {problem} in {EXAMPLES_DIR}; available: {', '.join(found)}")


# ------------------------------------------------------------------------------------- parser


def _positive_int(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        value = 0
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be a positive integer, got {text}")
    return value


def _add_robot_options(parser: argparse.ArgumentParser, with_mode: bool = True) -> None:
    parser.add_argument(
        "kind", metavar="ROBOT", choices=list(ROBOTS), help="scara, delta or anthropomorphic"
    )
    geometry = parser.add_argument_group(
        "geometry", "--robot paper|FILE.toml|FILE.json, and/or the lengths (they override it)"
    )
    geometry.add_argument("--robot", metavar="SPEC", help="'paper' or a TOML/JSON file")
    for kind in ROBOTS.values():
        for key in kind.fields:
            paper = f" (paper robot: {kind.paper[key]:g} {kind.unit})" if kind.paper else ""
            geometry.add_argument(
                _option(key), dest=key, type=float, metavar="L", help=f"{kind.name}: {key}{paper}"
            )
    if with_mode:
        parser.add_argument(
            "--mode",
            help="scara assembly mode +1 (default) or -1; delta branch out (default) or in; "
            "anthropomorphic branch front_up (default), front_down, back_up or back_down",
        )
    parser.add_argument(
        "--dtype",
        choices=("float64", "float32"),
        default="float64",
        help="floating precision of the solve (default float64)",
    )
    parser.add_argument(
        "--chunk-size",
        type=_positive_int,
        default=DEFAULT_CHUNK,
        metavar="N",
        help=f"rows (voxels) per batched call (default {DEFAULT_CHUNK})",
    )
    parser.add_argument("-q", "--quiet", action="store_true", help="no progress bar or notes")


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(
        prog="jaxkin",
        description="Batched robot kinematics from the command line (SCARA, Delta, serial arm).",
        epilog="Run 'jaxkin SUBCOMMAND --help' for details; 'jaxkin demo --list' for examples.",
    )
    parser.add_argument("--version", action="version", version=f"jaxkin {__version__}")
    parser.add_argument("--traceback", action="store_true", help=argparse.SUPPRESS)
    sub = parser.add_subparsers(dest="command", metavar="SUBCOMMAND", parser_class=_Parser)
    sub.required = True

    demo = sub.add_parser(
        "demo",
        help="list and run the examples",
        description=(
            f"Run an example script of {EXAMPLES_DIR} by name (default {DEFAULT_DEMO}); "
            "--list shows them."
        ),
        epilog="example: jaxkin demo delta-workspace --resolution 2",
    )
    demo.add_argument("name", nargs="?", metavar="NAME", help=f"example (default {DEFAULT_DEMO})")
    demo.add_argument("--list", action="store_true", help="list the examples and exit")
    demo.add_argument(
        "args", nargs=argparse.REMAINDER, metavar="...", help="passed on to the example script"
    )
    demo.add_argument("-q", "--quiet", action="store_true", help="no notes")
    demo.set_defaults(func=cmd_demo)

    for name, func, what, example in (
        (
            "ik",
            cmd_ik,
            "joint trajectories from end-point trajectories (t,x,y,z[,candidate])",
            "jaxkin ik scara --robot paper -i spiral.csv -o joints.csv --plot joints.png",
        ),
        (
            "fk",
            cmd_fk,
            "end-point trajectories from joint trajectories",
            "jaxkin fk scara --robot paper -i joints.csv -o check.csv",
        ),
    ):
        p = sub.add_parser(
            name, help=what, description=f"{what}. " + _FILE_HELP, epilog=f"example: {example}"
        )
        _add_robot_options(p, with_mode=name == "ik")
        p.add_argument("-i", "--input", required=True, metavar="FILE", help="CSV or .npz")
        p.add_argument(
            "-o",
            "--output",
            required=True,
            metavar="FILE",
            help="CSV (or .npz by suffix; '-' for CSV on stdout), written atomically",
        )
        p.add_argument(
            "--spline",
            choices=splines.END_CONDITIONS,
            default="not-a-knot",
            help="end condition of the cubic spline for missing rates (default not-a-knot)",
        )
        p.add_argument("--plot", metavar="FILE.png", help="also plot the result (needs matplotlib)")
        p.set_defaults(func=func, mode=None)

    ws = sub.add_parser(
        "workspace",
        help="voxel sweep of the reachable workspace",
        description="Chunked voxel sweep of the reachable workspace; prints its volume "
        "(voxels whose IK is solved, the boundary included) in the geometry's length unit cubed.",
        epilog="example: jaxkin workspace delta --robot paper --plot ws.png --output ws.npz",
    )
    _add_robot_options(ws)
    ws.add_argument(
        "--resolution",
        type=float,
        metavar="H",
        help="voxel edge (default: the reach / 50, i.e. 1 cm for the paper's Delta)",
    )
    ws.add_argument(
        "--bounds",
        type=float,
        nargs=6,
        metavar=("XMIN", "XMAX", "YMIN", "YMAX", "ZMIN", "ZMAX"),
        help="box to sweep (default: the robot's reach)",
    )
    ws.add_argument("-o", "--output", metavar="FILE.npz", help="save the mask and grid (atomic)")
    ws.add_argument("--plot", metavar="FILE.png", help="slices and point cloud (needs matplotlib)")
    ws.set_defaults(func=cmd_workspace)
    return parser


_FILE_HELP = (
    "Input: CSV with a header row, or .npz; columns t, the positions, optional candidate and "
    "rates (missing rates are computed by a cubic spline in t per candidate). Output: the "
    "same layout with the solved columns and a status name per row."
)


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``jaxkin`` console script; returns the exit status."""
    argv = list(sys.argv[1:] if argv is None else argv)
    debug = "--traceback" in argv
    try:
        args = build_parser().parse_args(argv)
        args.notes = []
        code = int(args.func(args) or 0)
        if not getattr(args, "quiet", False):
            for note in args.notes:
                print(note, file=sys.stderr)
        return code
    except KeyboardInterrupt:
        print("jaxkin: interrupted (existing output files are unchanged)", file=sys.stderr)
        return EXIT_INTERRUPTED
    except MemoryError:
        if debug:
            raise
        print(
            "jaxkin: error: out of memory: reduce the problem (a coarser --resolution, a "
            "smaller --chunk-size or a smaller file)",
            file=sys.stderr,
        )
        return EXIT_ERROR
    except Exception as exc:  # one line, never a traceback (unless --traceback)
        if debug:
            raise
        known = isinstance(exc, CliError | ValueError | OSError)
        text = " ".join(str(exc).split()) or type(exc).__name__
        prefix = "" if known else f"internal error ({type(exc).__name__}): "
        print(f"jaxkin: error: {prefix}{text}", file=sys.stderr)
        return EXIT_ERROR


if __name__ == "__main__":
    sys.exit(main())
