"""MotionBenchMaker through ``jaxkin.motion.plan``: success and times per scene, re-checked.

Run: ``python benchmarks/mbm_benchmark.py --robot panda --mode discrete [--per-scene 100]
[--batch] [--ompl 5] [--output benchmarks/mbm_results.md] [--default-runtime]``.

Per problem, after compiling on the first (every world padded to the largest obstacle count of
the robot's archive, ``collider.stack_worlds``, so that one program serves every problem), one
``plan`` call per problem: its ``seconds`` give the planning (search) and simplification
times. ``--batch`` also plans every problem of the robot in one call (``B`` = all of them, one
world per problem). Every returned path is re-checked by ``mbm_recheck.Reference`` (Pinocchio
+ NumPy, exact cylinders) at 8 times the planning resolution: the search's straight edges and
the executed simplified path (the spline when ``smooth``, else the polygon). ``--ompl K``
plans the first ``K`` problems of each scene with OMPL's RRT-Connect, jaxkin checking its
states and edges (``examples/ompl_ur5.py``'s route; VAMP's range, resolution 32, 10 s).
The process runs with ``jaxkin.enable_low_latency()`` (each loop of the search compiled as one
function, calls run inline) unless ``--default-runtime``. VAMP's published reference (AMD
Ryzen 9 7950X, one thread; ``resources/README.md`` of its repository) is printed beside.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import jax
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

import mbm_problems  # noqa: E402
from mbm_recheck import Reference, dense_states  # noqa: E402

import jaxkin  # noqa: E402
from jaxkin import collision  # noqa: E402
from jaxkin.motion import collider, plan  # noqa: E402
from jaxkin.motion.status import MotionStatus, status_names  # noqa: E402

VAMP = {  # median / mean / p95 planning, mean simplification (us), solved / valid
    "panda": "35 / 76 / 343 us planning, 67 us simplification, 699 / 699 solved",
    "ur5": "39 / 161 / 776 us planning, 66 us simplification, 608 / 608 solved",
}


def _stats(x) -> str:
    x = np.asarray(x, float)
    if not x.size:
        return "-"
    return f"{np.median(x):.3g} / {np.mean(x):.3g} / {np.percentile(x, 95):.3g}"


def _length(path: np.ndarray, count: int) -> float:
    return float(np.sum(np.linalg.norm(np.diff(path[:count], axis=0), axis=-1)))


def _recheck(ref: Reference, knots: np.ndarray, smooth: bool, world) -> float:
    return float(np.min(ref.clearances(dense_states(knots, smooth), world)))


_HANDLES: dict = {}


def _checks(robot, world):
    """The state and edge handles (``jaxkin.compiled``, float32) for ``world``: compiled for
    the first world, rebound to the next ones (every world padded to one layout)."""
    if id(robot) not in _HANDLES:
        state = jaxkin.compiled(collision.collides, robot, world, batch=(), dtype=np.float32)
        edge = jaxkin.compiled(
            collision.validate_motions, robot, world, 32.0, 256, batch=1, clearance=False,
            dtype=np.float32,
        )  # fmt: skip
        _HANDLES[id(robot)] = (robot, state, edge)
    _, state, edge = _HANDLES[id(robot)]
    return state.rebound(world), edge.rebound(world)


def run_ompl(robot, world, start, goal, range_: float, budget: float = 10.0):
    """OMPL RRT-Connect with jaxkin's checks through compiled handles (made before the
    clock starts); ``(solved, seconds)``."""
    from ompl import base as ob
    from ompl import geometric as og
    from ompl import util as ou

    ou.setLogLevel(ou.LOG_WARN)
    n = robot.n_joints
    space = ob.RealVectorStateSpace(n)
    bounds = ob.RealVectorBounds(n)
    lower, upper = np.asarray(robot.lower), np.asarray(robot.upper)
    for i in range(n):
        bounds.setLow(i, float(lower[i]))
        bounds.setHigh(i, float(upper[i]))
    space.setBounds(bounds)
    setup = og.SimpleSetup(space)
    si = setup.getSpaceInformation()

    state_check, edge_check = _checks(robot, world)

    def valid(state) -> bool:
        q = np.array([state[i] for i in range(n)], np.float32)
        return not bool(state_check(q).collides)

    class Motion(ob.MotionValidator):
        def checkMotion(self, s1, s2, *rest):
            a = np.array([[s1[i] for i in range(n)]], np.float32)
            b = np.array([[s2[i] for i in range(n)]], np.float32)
            return bool(edge_check(a, b).valid[0])

    setup.setStateValidityChecker(valid)
    si.setMotionValidator(Motion(si))
    begin, end = space.allocState(), space.allocState()
    for i in range(n):
        begin[i], end[i] = float(start[i]), float(goal[i])
    setup.setStartAndGoalStates(begin, end)
    planner = og.RRTConnect(si)
    planner.setRange(range_)
    setup.setPlanner(planner)
    t0 = time.perf_counter()
    stop = ob.PlannerTerminationCondition(lambda: time.perf_counter() - t0 > budget)
    solved = bool(setup.solve(stop)) and setup.haveExactSolutionPath()
    return solved, time.perf_counter() - t0


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--robot", choices=("panda", "ur5"), default="panda")
    parser.add_argument("--mode", choices=("discrete", "certified"), default="discrete")
    parser.add_argument("--per-scene", type=int, default=100)
    parser.add_argument("--lanes", type=int, default=8)
    parser.add_argument("--team", type=int, default=None, help="MotionOptions.team")
    parser.add_argument(
        "--domain", type=float, default=None, help="MotionOptions.domain (inf: none)"
    )
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--batch", action="store_true")
    parser.add_argument("--batch-only", action="store_true", help="skip the single calls")
    parser.add_argument("--batch-lanes", type=int, default=8)
    parser.add_argument("--ompl", type=int, default=0)
    parser.add_argument("--no-recheck", action="store_true")
    parser.add_argument("--output", type=Path, default=Path(__file__).parent / "mbm_results.md")
    parser.add_argument(
        "--default-runtime",
        action="store_true",
        help="leave JAX's CPU runtime as it is (no jaxkin.enable_low_latency())",
    )
    args = parser.parse_args(argv)
    if not args.default_runtime:
        jaxkin.enable_low_latency()  # before the first computation (docs/execution.md)
    jax.config.update("jax_enable_x64", False)

    robot = mbm_problems.robot(args.robot)
    sets = mbm_problems.problems(args.robot)
    chosen = [p for s in mbm_problems.SCENES for p in sets[s][: args.per_scene]]
    worlds = [p.world.astype("float32") for p in chosen]
    stacked = collider.stack_worlds(worlds)
    padded = [jax.tree.map(lambda x, i=i: x[i], stacked) for i in range(len(chosen))]
    options = dict(
        mode=args.mode,
        range=mbm_problems.RANGES[args.robot],
        lanes=args.lanes,
        team=args.team,
        period=None,
        seed=args.seed,
    )
    if args.domain is not None:
        options["domain"] = args.domain
    body, pairs = collider.prepare(robot)
    names = [(body.links[a], body.links[b]) for a, b in pairs.link_pairs]
    ref = Reference(args.robot, names, robot.joint_names)

    compile_s = 0.0
    if not args.batch_only:
        t0 = time.perf_counter()
        first = plan(robot, chosen[0].start, padded[0], goal=chosen[0].goal, **options)
        compile_s = time.perf_counter() - t0
        print(f"first call (compiles): {compile_s:.1f} s, {status_names(first.status)}", flush=True)
    rows = []
    for p, world in zip(chosen, padded, strict=True):
        if args.batch_only:
            break
        r = plan(robot, p.start, world, goal=p.goal, **options)
        st = int(r.status[0])
        row = {
            "scene": p.scene,
            "index": p.index,
            "status": status_names(st),
            "search": r.seconds["search"],
            "simplify": r.seconds["simplify"],
            "iterations": int(r.iterations[0]),
            "searched_again": int(r.seconds.get("searched_again", 0)),
            "edges_again": int(r.seconds.get("edges_searched_again", 0)),
        }
        if st == MotionStatus.SOLVED:
            row["length"] = _length(r.path[0], int(r.path_count[0]))
            row["simple_length"] = _length(r.simplified[0], int(r.simplified_count[0]))
            row["smooth"] = bool(r.smooth[0])
            if not args.no_recheck:
                raw = r.path[0][: int(r.path_count[0])]
                simple = r.simplified[0][: int(r.simplified_count[0])]
                row["recheck_raw"] = _recheck(ref, raw, False, p.world)
                row["recheck_simple"] = _recheck(ref, simple, bool(r.smooth[0]), p.world)
        rows.append(row)
        print(json.dumps(row), flush=True)
    batch = None
    if args.batch or args.batch_only:
        starts = np.stack([p.start for p in chosen])
        goals = np.stack([p.goal for p in chosen])
        bopts = dict(options, lanes=args.batch_lanes)
        t0 = time.perf_counter()
        plan(robot, starts, worlds, goal=goals, **bopts)  # compiles
        batch_compile = time.perf_counter() - t0
        t0 = time.perf_counter()
        rb = plan(robot, starts, worlds, goal=goals, **bopts)
        batch = {
            "problems": len(chosen),
            "seconds": time.perf_counter() - t0,
            "solved": int(np.sum(rb.solved)),
            "search": rb.seconds["search"],
            "simplify": rb.seconds["simplify"],
            "lanes": args.batch_lanes,
            "first_call": batch_compile,
        }
        print(json.dumps(batch), flush=True)
    ompl_rows = []
    if args.ompl:
        for s in mbm_problems.SCENES:
            for p, world in [(p, w) for p, w in zip(chosen, padded, strict=True) if p.scene == s][
                : args.ompl
            ]:
                ok, sec = run_ompl(robot, world, p.start, p.goal, mbm_problems.RANGES[args.robot])
                ompl_rows.append({"scene": s, "index": p.index, "solved": ok, "seconds": sec})
                print(json.dumps(ompl_rows[-1]), flush=True)
    _report(args, rows, batch, ompl_rows, compile_s)
    return 0


def _report(args, rows, batch, ompl_rows, compile_s) -> None:
    import os

    load = os.getloadavg()
    lines = [
        f"### {args.robot}, {args.mode} mode, float32, {args.lanes} lanes per problem, "
        f"domain {args.domain if args.domain is not None else 'default'}, seed {args.seed}",
        "",
        f"Machine load average {load[0]:.1f} / {load[1]:.1f} / {load[2]:.1f} (2 cores, shared); "
        f"first call (compilation) {compile_s:.1f} s. Times in ms, median / mean / p95. VAMP "
        f"(Ryzen 9 7950X, one thread): {VAMP[args.robot]}.",
    ]
    if rows:
        lines += [
            "",
            "| scene | solved / valid | planning (ms) | simplification (ms) | lane iterations "
            "(median) | path length raw / simplified (median) | smooth | edges planned again "
            "| searched again | re-check failures |",
            "| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |",
        ]
    for s in [*mbm_problems.SCENES, "all"] if rows else []:
        sel = [r for r in rows if s in ("all", r["scene"])]
        valid = [r for r in sel if r["status"] not in ("INVALID_START", "INVALID_GOAL")]
        ok = [r for r in valid if r["status"] == "SOLVED"]
        fails = sum(1 for r in ok if min(r.get("recheck_raw", 1), r.get("recheck_simple", 1)) <= 0)
        lines.append(
            f"| {s} | {len(ok)} / {len(valid)} | {_stats([1e3 * r['search'] for r in valid])} | "
            f"{_stats([1e3 * r['simplify'] for r in ok])} | "
            f"{np.median([r['iterations'] for r in valid]) if valid else '-'} | "
            f"{np.median([r['length'] for r in ok]) if ok else 0:.2f} / "
            f"{np.median([r['simple_length'] for r in ok]) if ok else 0:.2f} | "
            f"{sum(r['smooth'] for r in ok)} | {sum(r['edges_again'] for r in valid)} | "
            f"{sum(r['searched_again'] for r in valid)} | "
            f"{fails if not args.no_recheck else '-'} |"
        )
    if batch:
        lines += [
            "",
            f"All {batch['problems']} problems in one call ({batch['lanes']} lanes): "
            f"{batch['seconds']:.1f} s (in parts on the host threads: search {batch['search']:.1f} "
            f"s, simplification {batch['simplify']:.1f} s, summed over the parts), "
            f"{batch['solved']} solved (first call, compiling: "
            f"{batch['first_call']:.0f} s).",
        ]
    if ompl_rows:
        ok = [r for r in ompl_rows if r["solved"]]
        lines += [
            "",
            f"OMPL RRT-Connect with jaxkin's checks, {len(ompl_rows)} problems "
            f"(the first of each scene): {len(ok)} solved, planning "
            f"{_stats([1e3 * r['seconds'] for r in ok])} ms.",
        ]
    text = "\n".join(lines) + "\n\n"
    with open(args.output, "a", encoding="utf-8") as f:
        f.write(text)
    print(text)


if __name__ == "__main__":
    raise SystemExit(main())
