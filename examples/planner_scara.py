"""Planner backend demo: 10,000 random SCARA candidate paths between two poses, one call.

Each candidate is a random cubic Bezier curve from START to GOAL (the same fixed ends, random
interior control points), sampled at T = 100 instants over 2 s with exact velocity and
acceleration. ``jaxkin.plan.evaluate`` solves the IK of all 1e6 samples in both assembly
modes, keeps per candidate the feasible mode with the smoothest joint motion, and reports
feasibility, where infeasible candidates first fail, and costs; ``plan.best`` ranks them.

Run: ``python examples/planner_scara.py [N]``.
"""

from __future__ import annotations

import sys
import time

import jax
import numpy as np

from jaxkin import Status, optimize, plan, scara

jax.config.update("jax_enable_x64", True)  # an application choice; the library never sets it

ROBOT = scara.Scara.create(150.0, 80.0, 50.0, limits={"theta1": (-2.5, 2.5)})  # mm, rad
START = np.array([110.0, -50.0, 40.0])
GOAL = np.array([-20.0, 100.0, 80.0])
DURATION, N_SAMPLES = 2.0, 100


def random_candidates(n: int, seed: int = 0):
    """Jet (n, T, 3) of random cubic Bezier paths START -> GOAL, exact derivatives."""
    rng = np.random.default_rng(seed)
    interior = (START + GOAL) / 2 + rng.normal(scale=60.0, size=(n, 2, 3)) * [1, 1, 0.2]
    controls = np.concatenate(
        [np.broadcast_to(START, (n, 1, 3)), interior, np.broadcast_to(GOAL, (n, 1, 3))], axis=1
    )
    basis = optimize.bezier_basis(4, N_SAMPLES)
    return optimize.bezier_path(controls, basis, DURATION)


def main(n: int = 10_000) -> None:
    path = random_candidates(n)
    dt = DURATION / (N_SAMPLES - 1)
    limits = plan.Limits.create(3, v_max=[10.0, 12.0, 200.0])  # rad/s, rad/s, mm/s
    start = time.perf_counter()
    ev = jax.block_until_ready(plan.evaluate(ROBOT, path, limits, mode="best", dt=dt))
    first = time.perf_counter() - start
    start = time.perf_counter()
    ev = jax.block_until_ready(plan.evaluate(ROBOT, path, limits, mode="best", dt=dt))
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
        print(f"  median first failing sample: {int(np.median(np.asarray(ev.first_failure)[idx]))}")
    modes = np.asarray(ev.branch)[feasible]
    print(f"  chosen mode among feasible: +1 x {np.sum(modes == 0)}, -1 x {np.sum(modes == 1)}")
    idx, totals = plan.best(ev, 5)
    print("  best 5 (integrated squared joint acceleration):")
    for i, total in zip(idx, totals, strict=True):
        print(
            f"    candidate {i:5d}: cost {total:10.3f}, min margin {ev.min_margin[i]:.3f}, "
            f"peak speed {ev.costs.peak_speed[i]:.2f}, path length {ev.costs.path_length[i]:.2f}"
        )


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 10_000)
