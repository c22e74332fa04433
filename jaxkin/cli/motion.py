"""``jaxkin motion``: plan a robot from joints to joints among the obstacles of a scene file,
write the timed trajectory (``jaxkin.motion.plan``; the options in ``jaxkin.cli.parser``)."""

from __future__ import annotations

import argparse

import numpy as np

from .. import motion
from . import files
from .commands import _world, robot_from_args, set_dtype
from .robots import CliError

__all__ = ["cmd_motion"]


def cmd_motion(args: argparse.Namespace) -> int:
    set_dtype(args.dtype)
    robot = robot_from_args(args)
    if args.srdf:
        with_srdf = getattr(robot, "with_srdf", None)
        if with_srdf is None:
            raise CliError(f"--srdf is an option of URDF arms, not of {args.kind}")
        try:
            robot = with_srdf(args.srdf)
        except ValueError as exc:
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
            seed=args.seed,
        )
    except ValueError as exc:
        raise CliError(str(exc)) from None
    status = motion.status_names(result.status)[0]
    if status != "SOLVED":
        hint = " (another --seed searches again)" if status == "NO_PATH" else ""
        raise CliError(f"no motion: {motion.describe(int(result.status[0]))}{hint}")
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
