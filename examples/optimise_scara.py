"""Gradient-based trajectory optimisation through SCARA IK with optax.

A pick-and-place move from START to GOAL whose straight line passes close to the inner
workspace boundary (a singularity of the arm). Eight perturbed initial guesses (quintic
Bezier curves, rest to rest) are optimised at once with Adam, minimising the integrated
squared joint acceleration plus a barrier on the singularity margin and a penalty for leaving
the workspace. Prints the cost before and after and the smallest margin; with matplotlib
installed, writes examples/output/optimise_scara.png (paths before/after and cost curves).

Run: ``python examples/optimise_scara.py``.
"""

from __future__ import annotations

from pathlib import Path

import jax
import numpy as np
import optax

from jaxkin import optimize, scara

jax.config.update("jax_enable_x64", True)

ROBOT = scara.Scara.create(150.0, 80.0, 50.0)  # annulus 30 mm <= r <= 130 mm
START = np.array([110.0, -20.0, 50.0])
GOAL = np.array([-50.0, 70.0, 80.0])
OUTPUT = Path(__file__).resolve().parent / "output"


def main() -> None:
    guesses = optimize.straight_line_guess(START, GOAL, 2, n_guesses=8, noise=8.0, seed=1)
    cost = optimize.compose(
        (1.0, optimize.acceleration),
        (100.0, optimize.singularity_barrier(0.2)),
        (1e6, optimize.unreachable_penalty),
    )
    common = dict(duration=2.0, n_samples=80, cost=cost, mode=1, rest_to_rest=True)
    before = optimize.optimize(ROBOT, START, GOAL, guesses, steps=0, **common)
    result = optimize.optimize(
        ROBOT, START, GOAL, guesses, steps=400, optimizer=optax.adam(1.0), **common
    )
    history = np.asarray(result.history)
    best = int(np.argmin(history[-1]))
    print("SCARA trajectory optimisation: 8 initial guesses, 400 Adam steps (rest to rest)")
    print(f"  cost before: min {history[0].min():.4g}, median {np.median(history[0]):.4g}")
    print(f"  cost after:  min {history[-1].min():.4g}, median {np.median(history[-1]):.4g}")
    print(
        f"  feasible before: {int(np.sum(before.evaluation.feasible))} of 8, "
        f"after: {int(np.sum(result.evaluation.feasible))} of 8"
    )
    print(
        f"  smallest margin along the best path: before "
        f"{float(before.evaluation.min_margin[best]):.4f}, after "
        f"{float(result.evaluation.min_margin[best]):.4f}"
    )
    print(
        f"  endpoints kept: {np.allclose(result.path.p[:, 0], START)} "
        f"{np.allclose(result.path.p[:, -1], GOAL)}"
    )
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        print("  (install the plot extra for a PNG: pip install 'jaxkin[plot]')")
        return
    OUTPUT.mkdir(exist_ok=True)
    fig, (ax_path, ax_cost) = plt.subplots(1, 2, figsize=(11, 5))
    angle = np.linspace(0, 2 * np.pi, 200)
    for radius in (30.0, 130.0):
        ax_path.plot(radius * np.cos(angle), radius * np.sin(angle), "k--", lw=0.8)
    for i in range(8):
        ax_path.plot(*np.asarray(before.path.p[i, :, :2]).T, color="0.7", lw=0.8)
        ax_path.plot(*np.asarray(result.path.p[i, :, :2]).T, color="C0", lw=1.2)
    ax_path.set_aspect("equal")
    ax_path.set_title("paths in the XY plane (grey: initial, blue: optimised)")
    ax_cost.semilogy(history)
    ax_cost.set_xlabel("Adam step")
    ax_cost.set_ylabel("cost")
    ax_cost.set_title("cost per initial guess")
    fig.tight_layout()
    fig.savefig(OUTPUT / "optimise_scara.png", dpi=90)
    print(f"  wrote {OUTPUT / 'optimise_scara.png'}")


if __name__ == "__main__":
    main()
