"""The main demo: 10,000 candidate SCARA trajectories evaluated in one call, the best plotted.

Each candidate is a random cubic Bezier curve from START to GOAL (the same ends, random interior
control points), sampled at T = 100 instants over 2 s with exact velocity and acceleration.
``jaxkin.plan.evaluate`` solves the inverse kinematics of all 10^6 samples in both assembly
modes in one call, keeps per candidate the feasible mode with the smoothest joint motion, and
reports feasibility, where infeasible candidates first fail, and costs; ``plan.best`` ranks
them by cost, and by the duration of their time-optimal retiming (``by="duration"``). Writes
``planner_scara_best.csv`` (the best candidate's joints and rates) and, with matplotlib,
``planner_scara.png`` (every candidate in the arm's plane, the best five highlighted over the
robot at the start, and the best candidate's joint trajectories).

Run: ``jaxkin demo`` or ``python examples/planner_scara.py [N] [--output-dir DIR]``.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import jax
import numpy as np

from jaxkin import Status, paths, plan, scara

jax.config.update("jax_enable_x64", True)  # an application choice; the library never sets it

ROBOT = scara.Scara(150.0, 80.0, 50.0, limits={"theta1": (-2.5, 2.5)})  # mm, rad
START = np.array([110.0, -50.0, 40.0])
GOAL = np.array([-20.0, 100.0, 80.0])
DURATION, N_SAMPLES = 2.0, 100


def random_candidates(n: int, seed: int = 0) -> paths.Path:
    """Path (n, T, 3) of random cubic Bezier paths START -> GOAL, exact derivatives."""
    rng = np.random.default_rng(seed)
    interior = (START + GOAL) / 2 + rng.normal(scale=60.0, size=(n, 2, 3)) * [1, 1, 0.2]
    controls = np.concatenate(
        [np.broadcast_to(START, (n, 1, 3)), interior, np.broadcast_to(GOAL, (n, 1, 3))], axis=1
    )
    basis = paths.bezier_basis(4, N_SAMPLES)
    curves = paths.bezier_path(controls, basis, DURATION)
    return paths.Path.from_jet(curves, dt=DURATION / (N_SAMPLES - 1))


def plot(path, ev, best, output: Path) -> Path | None:
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        return None
    fig, (top, joints) = plt.subplots(1, 2, figsize=(11, 5))
    xy = np.asarray(path.p)[..., :2]
    feasible = np.asarray(ev.feasible)
    shown = np.random.default_rng(1).permutation(len(xy))[:1500]  # a readable sample
    for i in shown:
        colour = "tab:green" if feasible[i] else "tab:red"
        top.plot(*xy[i].T, color=colour, alpha=0.05, lw=0.6)
    for rank, i in enumerate(best):
        top.plot(*xy[i].T, lw=2.2, label=f"best {rank + 1}" if rank == 0 else None, color="k")
    q0 = np.asarray(ev.q.p[best[0], 0])
    links = np.asarray(ROBOT.link_segments(q0, np.asarray(path.p[best[0], 0])))[:2, :, :2]
    top.plot(*np.concatenate([links[0], links[1][1:]]).T, "o-", color="tab:blue", lw=3)
    top.set_aspect("equal")
    top.set_title(f"{len(xy):,} candidates (green feasible, red not); best five in black")
    top.set_xlabel("x (mm)")
    top.set_ylabel("y (mm)")
    t = np.arange(N_SAMPLES) * DURATION / (N_SAMPLES - 1)
    q = np.asarray(ev.q.p[best[0]])
    joints.plot(t, q[:, 0], label="theta1")
    joints.plot(t, q[:, 1], label="theta2")
    joints.set_xlabel("t (s)")
    joints.set_ylabel("rad")
    joints.legend(loc="upper left")
    column = joints.twinx()
    column.plot(t, q[:, 2], color="tab:green", label="l3")
    column.set_ylabel("l3 (mm)")
    column.legend(loc="upper right")
    joints.set_title("joint trajectories of the best candidate")
    fig.tight_layout()
    path_png = output / "planner_scara.png"
    fig.savefig(path_png, dpi=90)
    plt.close(fig)
    return path_png


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("n", nargs="?", type=int, default=10_000, help="candidates")
    parser.add_argument("--output-dir", type=Path, default=Path("."), help="where files go")
    args = parser.parse_args(argv)
    n, output = args.n, args.output_dir
    path = random_candidates(n)
    dt = path.dt
    # rad/s, rad/s, mm/s and rad/s^2, rad/s^2, mm/s^2
    limits = plan.Limits.create(3, v_max=[10.0, 12.0, 200.0], a_max=[40.0, 50.0, 2000.0])
    start = time.perf_counter()
    ev = jax.block_until_ready(plan.evaluate(ROBOT, path, limits, branch="best"))
    first = time.perf_counter() - start
    start = time.perf_counter()
    ev = jax.block_until_ready(plan.evaluate(ROBOT, path, limits, branch="best"))
    second = time.perf_counter() - start

    feasible = np.asarray(ev.feasible)
    print(f"SCARA planner: {n} candidates x {N_SAMPLES} samples, both assembly modes")
    print(
        f"  time: {second * 1e3:.1f} ms per call ({n / second:,.0f} candidates/s; "
        f"first call with compilation {first:.2f} s)"
    )
    print(f"  feasible: {feasible.sum()} of {n}")
    failed = ~feasible
    if failed.any():
        idx = np.flatnonzero(failed)
        status = np.asarray(ev.status)[idx, np.asarray(ev.first_failure)[idx]]
        codes, counts = np.unique(status, return_counts=True)
        reasons = {Status(s).name: int(c) for s, c in zip(codes, counts, strict=True)}
        print(f"  first failure reasons: {reasons}")
    modes = np.asarray(ev.branch)[feasible]
    print(f"  chosen mode among feasible: +1 x {np.sum(modes == 0)}, -1 x {np.sum(modes == 1)}")
    best, totals = plan.best(ev, 5)
    print("  best 5 (integrated squared joint acceleration, each joint's over its limit):")
    for i, total in zip(best, totals, strict=True):
        print(
            f"    candidate {i:5d}: cost {total:10.3f}, min margin {ev.min_margin[i]:.3f}, "
            f"peak speed {ev.costs.peak_speed[i]:.2f}, path length {ev.costs.path_length[i]:.2f}"
        )
    if best.size == 0:
        return 0
    fastest, durations = plan.best(ev, 5, by="duration")  # time-optimal retiming (TOPP-RA)
    print("  fastest 5 within the velocity and acceleration limits:")
    for i, duration in zip(fastest, durations, strict=True):
        print(f"    candidate {i:5d}: {duration:.3f} s (sampled over {DURATION:.1f} s)")
    t = np.arange(N_SAMPLES) * dt
    q = ev.q
    names = ROBOT.joint_names
    header = ["t", *names, *(f"{k}_dot" for k in names), *(f"{k}_ddot" for k in names)]
    rows = np.c_[t, q.p[best[0]], q.v[best[0]], q.a[best[0]]]
    csv = output / "planner_scara_best.csv"
    np.savetxt(csv, rows, delimiter=",", header=",".join(header), comments="")
    print(f"  wrote {csv}")
    figure = plot(path, ev, best, output)
    if figure is not None:
        print(f"  wrote {figure}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
