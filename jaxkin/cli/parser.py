"""The ``jaxkin`` command line: subcommands, options and help.

Building the parser and printing ``--help`` import neither JAX nor jaxkin's numeric modules
(``jaxkin --help`` answers in a fraction of the second JAX takes to load): a subcommand's
module is imported when the subcommand runs (``_command``), and the few constants the options
show are spelled here (``SPLINE_ENDS`` is ``jaxkin._splines.END_CONDITIONS``, a test holds
them equal).
"""

from __future__ import annotations

import argparse
import importlib
import math
from collections.abc import Callable
from typing import Any

from .. import __version__
from . import demo
from .robots import ROBOTS, CliError, option

__all__ = ["DISTRIBUTED_TIMEOUT", "SPLINE_ENDS", "build_parser"]

DISTRIBUTED_TIMEOUT = 60.0  # seconds for every process to join (--distributed-timeout)
SPLINE_ENDS = ("not-a-knot", "natural")  # the end conditions of jaxkin._splines


class _Parser(argparse.ArgumentParser):
    """argparse with one-line errors (raised, so ``main`` prints them and returns 2)."""

    def error(self, message: str) -> Any:  # type: ignore[override]
        raise CliError(f"{message} (see '{self.prog} --help')")


def _positive_int(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        value = 0
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be a positive integer, got {text}")
    return value


def _add_robot_options(parser: argparse.ArgumentParser, with_branch: bool = True) -> None:
    names = ", ".join(ROBOTS)
    parser.add_argument("kind", metavar="ROBOT", choices=list(ROBOTS), help=names)
    geometry = parser.add_argument_group(
        "geometry", "--robot paper|FILE.toml|FILE.json, and/or the lengths (they override it)"
    )
    geometry.add_argument(
        "--robot", metavar="SPEC", help="'paper' or a TOML/JSON file (urdf: the URDF file)"
    )
    geometry.add_argument("--tip", metavar="LINK", help="urdf: the link whose pose is solved")
    geometry.add_argument("--base", metavar="LINK", help="urdf: the base link (default: the root)")
    users: dict[str, list[str]] = {}
    for entry in ROBOTS.values():
        for key in entry.fields:
            users.setdefault(key, []).append(entry.name)
    for key, robots in users.items():
        geometry.add_argument(
            option(key), dest=key, type=float, metavar="L", help=f"{'/'.join(robots)}: {key}"
        )
    if with_branch:
        parser.add_argument(
            "--branch",
            "--mode",
            dest="branch",
            help="the IK branch: scara +1 (default) or -1; delta out (default) or in; "
            "anthropomorphic front_up (default), front_down, back_up or back_down; ...",
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
        default=None,
        metavar="N",
        help="rows (voxels) per batched call (default 65536 rows, 262144 voxels)",
    )
    parser.add_argument("-q", "--quiet", action="store_true", help="no progress bar or notes")


def _numbers(text: str) -> list[float]:
    try:
        return [float(x) for x in text.split(",")]
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"expected a number or comma-separated numbers (one per joint), got {text!r}"
        ) from None


def _add_path_options(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--each-row",
        action="store_true",
        help="solve every row on its own (default for a file with a t column: each candidate "
        "is one path, warm-started, continuous, the branch held, within the limits)",
    )
    for flag, what in (("--v-max", "speed"), ("--a-max", "acceleration")):
        parser.add_argument(
            flag,
            type=_numbers,
            metavar="V[,V...]",
            help=f"joint {what} bound, one for every joint or one per joint (tightens the "
            "robot's own)",
        )


_FILE_HELP = (
    "Input: CSV with a header row, or .npz; columns t, the positions, optional candidate and "
    "rates (missing rates are computed by a cubic spline in t per candidate; without t the "
    "rows are independent, at rest). Output: the same layout with the solved columns and a "
    "status name per row."
)


def _command(module: str, name: str) -> Callable[[argparse.Namespace], Any]:
    """The subcommand function ``name`` of ``jaxkin.cli.<module>``, imported when it runs."""

    def run(args: argparse.Namespace) -> Any:
        return getattr(importlib.import_module(f"{__package__}.{module}"), name)(args)

    run.__name__ = run.__qualname__ = name
    return run


def _positive_seconds(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not (value > 0 and math.isfinite(value)):
        raise argparse.ArgumentTypeError(f"must be a positive number of seconds, got {text}")
    return value


def _add_distributed_options(parser: argparse.ArgumentParser) -> None:
    """The ``--distributed`` and ``--distributed-timeout`` options (``jaxkin.cli.distributed``)."""
    parser.add_argument(
        "--distributed",
        action="store_true",
        help="run as one of several processes (jax.distributed: JAX_COORDINATOR_ADDRESS, "
        "JAX_NUM_PROCESSES, JAX_PROCESS_ID, or the cluster's own variables, e.g. SLURM's); "
        "every process runs the same command and process 0 writes the output",
    )
    parser.add_argument(
        "--distributed-timeout",
        type=_positive_seconds,
        default=DISTRIBUTED_TIMEOUT,
        metavar="S",
        help=f"seconds to wait for every process to join (default {DISTRIBUTED_TIMEOUT:g}); "
        "then exit 2 naming the missing processes",
    )


def _add_motion_parser(sub: Any) -> None:
    """The ``motion`` subcommand on ``sub`` (``jaxkin.cli.motion``)."""
    p = sub.add_parser(
        "motion",
        help="plan a collision-free motion among a scene's obstacles; write it timed",
        description="Plan a motion of the robot from joints --from to joints --to among the "
        "obstacles of a world file or a MoveIt planning scene (YAML: boxes, spheres, "
        "cylinders; --world), "
        "shorten and smooth it, time it within the joints' speed and acceleration limits and "
        "write it sampled every --period: columns t, the joints, their rates and "
        "accelerations. A YAML file needs PyYAML (the yaml extra).",
        epilog="example: jaxkin motion planar-2r --l1 1 --l2 0.8 --link-radius 0.05 "
        "--from 0,0.3 --to 2.5,0.4 --world scene.yaml -o motion.csv",
    )
    _add_robot_options(p, with_branch=False)
    p.add_argument("--from", dest="start", type=_numbers, required=True, metavar="Q[,Q...]")
    p.add_argument("--to", dest="goal", type=_numbers, required=True, metavar="Q[,Q...]")
    p.add_argument(
        "--world",
        required=True,
        metavar="FILE",
        help="a world file (.json, .yaml) or a MoveIt planning scene (.yaml)",
    )
    p.add_argument("-o", "--output", required=True, metavar="FILE.csv", help="written atomically")
    p.add_argument(
        "--srdf", metavar="FILE", help="urdf: pairs the SRDF leaves out of self-collision"
    )
    p.add_argument("--link-radius", type=float, metavar="R", help="arms: the links' radius")
    p.add_argument(
        "--mode",
        choices=("certified", "discrete"),
        default="certified",
        help="edge checks: certified (default: nothing slips through) or discrete",
    )
    p.add_argument("--period", type=float, default=0.01, metavar="DT", help="default 0.01")
    p.add_argument(
        "--seed",
        type=int,
        default=0,
        metavar="S",
        help="the search's stream of samples (default 0; another seed, another search)",
    )
    p.set_defaults(func=_command("motion", "cmd_motion"), branch=None)


def build_parser() -> argparse.ArgumentParser:
    """The ``jaxkin`` argument parser."""
    parser = _Parser(
        prog="jaxkin",
        description="Batched robot kinematics from the command line.",
        epilog="Run 'jaxkin SUBCOMMAND --help' for details; 'jaxkin demo --list' for examples.",
    )
    parser.add_argument("--version", action="version", version=f"jaxkin {__version__}")
    parser.add_argument("--traceback", action="store_true", help=argparse.SUPPRESS)
    sub = parser.add_subparsers(dest="command", metavar="SUBCOMMAND", parser_class=_Parser)
    sub.required = True

    run = sub.add_parser(
        "demo",
        help="the main demo (a planner on 10,000 candidate paths) and the examples",
        description=(
            f"Run the main demo ({demo.DEFAULT}: thousands of candidate trajectories evaluated "
            "in one call, the best picked and plotted) or an example by name; --list shows "
            "them. Files go to the current directory (or --output-dir)."
        ),
        epilog="example: jaxkin demo delta-workspace --resolution 2",
    )
    run.add_argument("name", nargs="?", metavar="NAME", help=f"example (default {demo.DEFAULT})")
    run.add_argument("--list", action="store_true", help="list the examples and exit")
    run.add_argument(
        "--output-dir", metavar="DIR", default=".", help="where files go (default: here)"
    )
    run.add_argument(
        "args", nargs=argparse.REMAINDER, metavar="...", help="passed on to the example"
    )
    run.add_argument("-q", "--quiet", action="store_true", help="no notes")
    run.set_defaults(func=demo.cmd_demo)

    for name, func, what, example in (
        (
            "ik",
            _command("commands", "cmd_ik"),
            "joint trajectories from end-point trajectories (t,x,y,z[,candidate])",
            "jaxkin ik scara --robot paper -i spiral.csv -o joints.csv --plot joints.png",
        ),
        (
            "fk",
            _command("commands", "cmd_fk"),
            "end-point trajectories from joint trajectories",
            "jaxkin fk scara --robot paper -i joints.csv -o check.csv",
        ),
    ):
        p = sub.add_parser(
            name, help=what, description=f"{what}. " + _FILE_HELP, epilog=f"example: {example}"
        )
        _add_robot_options(p, with_branch=name == "ik")
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
            choices=SPLINE_ENDS,
            default="not-a-knot",
            help="end condition of the cubic spline for missing rates (default not-a-knot)",
        )
        p.add_argument("--plot", metavar="FILE.png", help="also plot the result (needs matplotlib)")
        if name == "ik":
            _add_path_options(p)
        _add_distributed_options(p)
        p.set_defaults(func=func, branch=None)

    pl = sub.add_parser(
        "plan",
        help="rank candidate paths; write the best, retimed",
        description="Evaluate a file of N candidate paths (plan.evaluate: joints along each, "
        "continuous, within the robot's limits, costs), rank the feasible ones by the "
        "duration of their time-optimal retiming under the speed and acceleration limits (or "
        "by cost) and write the k best sampled every --period. Input: CSV or .npz with "
        "columns candidate, t and the robot's target coordinates (task-space candidates) or "
        "its joint names (joint-space candidates), optional rates (else splined); every "
        "candidate has the same number of samples, one period apart.",
        epilog="example: jaxkin plan scara --robot paper -i candidates.csv -o best.csv "
        "--best 3 --v-max 2 --a-max 10 --period 0.01",
    )
    _add_robot_options(pl)
    pl.add_argument("-i", "--input", required=True, metavar="FILE", help="CSV or .npz")
    pl.add_argument(
        "-o",
        "--output",
        required=True,
        metavar="FILE",
        help="the best candidates' trajectories: rank, candidate, t, joints and rates",
    )
    pl.add_argument("-k", "--best", type=_positive_int, default=1, metavar="K", help="default 1")
    pl.add_argument(
        "--by",
        choices=("duration", "cost"),
        default="duration",
        help="rank by the time-optimal duration (default) or by costs.total",
    )
    pl.add_argument(
        "--period",
        type=float,
        metavar="DT",
        help="control period of the written trajectories (default: the file's sample period)",
    )
    pl.add_argument("--ranking", metavar="FILE", help="also write every candidate's scores")
    pl.add_argument(
        "--world",
        metavar="FILE",
        help="obstacles: a world file (.json, .yaml; collision.read_world) or a MoveIt "
        "planning scene (.yaml), in the robot's base frame and length unit: a sample whose "
        "body touches them or itself fails (COLLISION)",
    )
    pl.add_argument(
        "--spline",
        choices=SPLINE_ENDS,
        default="not-a-knot",
        help="end condition of the cubic spline for missing rates (default not-a-knot)",
    )
    for flag, what in (("--v-max", "speed"), ("--a-max", "acceleration")):
        pl.add_argument(
            flag,
            type=_numbers,
            metavar="V[,V...]",
            help=f"joint {what} bound, one for every joint or one per joint (tightens the "
            "robot's own)",
        )
    pl.set_defaults(func=_command("commands", "cmd_plan"))

    _add_motion_parser(sub)

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
        help="voxel edge (default: the robot's, e.g. 1 cm for the paper's Delta)",
    )
    ws.add_argument(
        "--bounds",
        type=float,
        nargs="+",
        metavar="LO HI",
        help="box to sweep, lo hi per axis: XMIN XMAX YMIN YMAX [ZMIN ZMAX] (default: the "
        "robot's reach)",
    )
    ws.add_argument("-o", "--output", metavar="FILE.npz", help="save the mask and grid (atomic)")
    ws.add_argument("--plot", metavar="FILE.png", help="slices and point cloud (needs matplotlib)")
    _add_distributed_options(ws)
    ws.set_defaults(func=_command("commands", "cmd_workspace"))
    return parser
