"""``jaxkin motion``: plan a robot from joints to joints among the obstacles of a scene file,
write the timed trajectory (``jaxkin.motion.plan``)."""

from __future__ import annotations

import argparse
from typing import Any

import numpy as np

from .. import files, motion
from .robots import CliError

__all__ = ["add_parser", "cmd_motion"]


def add_parser(sub: Any, add_robot_options: Any, numbers: Any) -> None:
    """The ``motion`` subcommand on ``sub`` (``add_robot_options`` the robot's options,
    ``numbers`` the parser of comma-separated numbers)."""
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
    add_robot_options(p, with_branch=False)
    p.add_argument("--from", dest="start", type=numbers, required=True, metavar="Q[,Q...]")
    p.add_argument("--to", dest="goal", type=numbers, required=True, metavar="Q[,Q...]")
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
    p.set_defaults(func=cmd_motion, branch=None)


def cmd_motion(args: argparse.Namespace) -> int:
    from .commands import _world, robot_from_args, set_dtype

    set_dtype(args.dtype)
    robot = robot_from_args(args)
    if args.srdf:
        try:
            robot = robot.with_srdf(args.srdf)
        except (AttributeError, ValueError) as exc:
            raise CliError(f"--srdf {args.srdf}: {exc}") from None
    if args.link_radius is not None:
        if "link_radius" not in getattr(robot, "__dataclass_fields__", {}):
            raise CliError(f"--link-radius is not an option of {args.kind}")
        robot = robot.replace(link_radius=args.link_radius)
    world = _world(args.world)
    n = robot.n_joints
    for flag, q in (("--from", args.start), ("--to", args.goal)):
        if len(q) != n:
            raise CliError(f"{flag}: {len(q)} values for the {n} joints of {args.kind}")
    try:
        result = motion.plan(
            robot,
            np.array(args.start),
            world,
            goal=np.array(args.goal),
            mode=args.mode,
            period=args.period,
        )
    except ValueError as exc:
        raise CliError(str(exc)) from None
    status = motion.status_names(result.status)[0]
    if status != "SOLVED":
        raise CliError(f"no motion: {motion.describe(int(result.status[0]))}")
    traj = result.trajectory
    count = int(traj.count[0])
    t = np.asarray(traj.t)[:count, None]
    q, v, a = (np.asarray(x[0, :count]) for x in (traj.q.p, traj.q.v, traj.q.a))
    names = list(robot.joint_names)
    header = ["t", *names, *(f"{j}_v" for j in names), *(f"{j}_a" for j in names)]
    with files.atomic_write(args.output) as f:
        np.savetxt(f, np.hstack([t, q, v, a]), delimiter=",", header=",".join(header), comments="")
    if not args.quiet:
        print(
            f"{status}: {count} samples, {float(result.duration[0]):.3f} s "
            f"({'smoothed' if result.smooth[0] else 'polygon'}, "
            f"{'certified' if result.certified[0] else args.mode}) -> {args.output}"
        )
    return 0
