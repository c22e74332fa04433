"""Trajectory optimisation around an obstacle: the straight line is blocked, the optimum is not.

A SCARA pick-and-place move from START to GOAL (rest to rest, 2 s) whose straight line runs
through a cylindrical post (a sphere in the arm's plane, radius 18 mm, plus a 6 mm safety
distance, checked against the end point and both links). Sixteen noisy straight-line guesses
(quintic Bezier curves) are optimised at once with the defaults: L-BFGS per guess, minimising
the integrated squared joint acceleration, a barrier on the singularity margin, a penalty for
leaving the workspace, plus the obstacle term. A second call with the obstacle moved reuses the
compilation. With matplotlib installed, writes ``optimise_scara.png`` (paths before and after,
the post, and each guess's cost per step).

Run: ``jaxkin demo optimise`` or ``python examples/optimise_scara.py [--output-dir DIR]``.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import jax
import numpy as np

from jaxkin import costs, optimize, paths, scara

jax.config.update("jax_enable_x64", True)  # an application choice; the library never sets it

ROBOT = scara.Scara.paper()  # 150, 80, 50 mm: the tool moves in the annulus 30 mm <= r <= 130 mm
START = np.array([100.0, -40.0, 50.0])
GOAL = np.array([-40.0, 100.0, 80.0])
POST, RADIUS, SAFETY = np.array([30.0, 30.0, 65.0]), 18.0, 6.0


def solve(post: np.ndarray, guesses: np.ndarray) -> optimize.OptimizationResult:
    """Optimise every guess around a post at ``post`` (a new position reuses the compilation)."""
    obstacle = costs.Obstacles.create(spheres=([post], [RADIUS]), safety=SAFETY)
    cost = costs.compose(
        (1.0, costs.acceleration),
        (100.0, costs.singularity_barrier(0.05)),
        (1e6, costs.unreachable_penalty),
        (1e4, obstacle),
    )
    return optimize.optimize(
        ROBOT, START, GOAL, guesses, duration=2.0, n_samples=80, cost=cost, rest_to_rest=True
    )


def clearance(path_xy: np.ndarray, post: np.ndarray) -> float:
    """Smallest distance from the tool's path to the post's surface, in mm."""
    return float(np.min(np.linalg.norm(path_xy - post[:2], axis=-1)) - RADIUS)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--output-dir", type=Path, default=Path("."), help="where files go")
    args = parser.parse_args(argv)
    guesses = paths.straight_line_guess(START, GOAL, 2, n_guesses=16, noise=10.0, seed=1)
    line = START[:2] + np.linspace(0, 1, 200)[:, None] * (GOAL - START)[:2]

    start = time.perf_counter()
    result = jax.block_until_ready(solve(POST, guesses))
    first = time.perf_counter() - start
    best = int(result.best)
    path = np.asarray(result.path.p)
    print("SCARA trajectory optimisation around a post: 16 guesses, L-BFGS per guess")
    print(f"  straight line's clearance from the post: {clearance(line, POST):7.1f} mm")
    best_clearance = clearance(path[best, :, :2], POST)
    print(f"  best path's clearance from the post:     {best_clearance:7.1f} mm")
    stops = np.bincount(np.asarray(result.stop), minlength=len(optimize.Stop))
    reasons = ", ".join(f"{stop.name.lower()} {stops[stop]}" for stop in optimize.Stop)
    print(
        f"  best cost {float(result.cost[best]):.4g}; guesses stopped: {reasons} (of 16); "
        f"feasible {int(result.evaluation.feasible.sum())} of 16; "
        f"first call {first:.1f} s (with compilation)"
    )
    moved = POST + np.array([-15.0, 10.0, 0.0])
    start = time.perf_counter()
    again = jax.block_until_ready(solve(moved, guesses))
    moved_clearance = clearance(np.asarray(again.path.p)[int(again.best), :, :2], moved)
    print(
        f"  post moved: clearance {moved_clearance:.1f} mm, "
        f"replanned in {time.perf_counter() - start:.2f} s (no new compilation)"
    )
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        print("  (install the plot extra for a figure: pip install 'jaxkin[plot]')")
        return 0
    fig, (ax_path, ax_cost) = plt.subplots(1, 2, figsize=(11, 5))
    angle = np.linspace(0, 2 * np.pi, 200)
    circle = np.c_[np.cos(angle), np.sin(angle)]
    for radius in (30.0, 130.0):
        ax_path.plot(*(radius * circle).T, "k--", lw=0.8)
    ax_path.fill(*(POST[:2] + RADIUS * circle).T, color="tab:red", alpha=0.4, label="post")
    for i in range(len(guesses)):
        full = np.vstack([START[:2], guesses[i, :, :2], GOAL[:2]])
        ax_path.plot(*full.T, color="0.8", lw=0.6)
        ax_path.plot(*path[i, :, :2].T, color="C0", lw=0.8, alpha=0.5)
    ax_path.plot(*path[best, :, :2].T, color="k", lw=2, label="best")
    ax_path.plot(*line.T, "r:", label="straight line")
    ax_path.set_aspect("equal")
    ax_path.legend(loc="lower left")
    ax_path.set_title("tool paths in the XY plane (mm; grey: guesses' control polygons)")
    ax_cost.semilogy(np.asarray(result.history))
    ax_cost.set_xlabel("L-BFGS step")
    ax_cost.set_ylabel("cost")
    ax_cost.set_title("cost per guess")
    fig.tight_layout()
    figure = args.output_dir / "optimise_scara.png"
    fig.savefig(figure, dpi=90)
    plt.close(fig)
    print(f"  wrote {figure}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
