"""SCARA inverse kinematics along a spiral, both branches, with rates ([Noriega, eq. 16, Fig. 6]).

Robot: l_OA = 150 mm (column), l_AB = 80 mm (arm), l_BC = 50 mm (forearm). The end point D
follows the helix of eq. 16 for t in [0, 8] s::

    x_D = 100 + 20 sin(pi t / 2),   y_D = -20 cos(pi t / 2),   z_D = 50 + 10 t     (mm)

sampled at 1,001 instants, with velocity and acceleration from the exact derivatives of eq. 16.
Both branches (the dyad's assembly modes +1 and -1) are solved in one batched call each
(``jaxkin.scara.ik``). Writes ``scara_spiral.csv`` (t, theta1, theta1_dot, theta1_ddot, theta2,
theta2_dot, theta2_ddot, l3, l3_dot, l3_ddot, status, branch; angles in rad, lengths in mm, time
in s) and, when matplotlib is installed, ``scara_spiral.png`` in the spirit of the paper's
Fig. 6: the robot at the final instant, theta1 and its two derivatives, and the singularity
indicator (the dyad's margin sin(beta)^2 and whether any sample was singular).

theta2 follows [Noriega, eq. 15] (theta1 - theta_BC: the negative of the usual relative elbow
angle). With the printed acceleration formulas corrected (``docs/errata.md``), theta1_ddot(0) =
0.309 rad/s^2 on branch +1; the script prints it for both branches.

Run: ``jaxkin demo scara-spiral`` or ``python examples/scara_spiral.py [--output-dir DIR]``.
"""

from __future__ import annotations

import argparse
import csv
import time
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

from jaxkin import IKResult, Jet, Status, scara
from jaxkin.status import status_names

# Examples may set global config (the library never does): float64 for table-grade values.
jax.config.update("jax_enable_x64", True)

L_OA, L_AB, L_BC = 150.0, 80.0, 50.0
T_END, N_SAMPLES = 8.0, 1001
COLUMNS = [
    "t",
    "theta1",
    "theta1_dot",
    "theta1_ddot",
    "theta2",
    "theta2_dot",
    "theta2_ddot",
    "l3",
    "l3_dot",
    "l3_ddot",
    "status",
    "branch",
]


def spiral(t: np.ndarray) -> Jet:
    """Eq. 16 and its exact first and second time derivatives; shape (len(t), 3)."""
    w = np.pi / 2.0
    s, c = np.sin(w * t), np.cos(w * t)
    p = np.stack([100.0 + 20.0 * s, -20.0 * c, 50.0 + 10.0 * t], axis=-1)
    v = np.stack([20.0 * w * c, 20.0 * w * s, np.full_like(t, 10.0)], axis=-1)
    a = np.stack([-20.0 * w * w * s, 20.0 * w * w * c, np.zeros_like(t)], axis=-1)
    return Jet.of(p, v, a)


def solve(robot: scara.Scara, d: Jet) -> dict[int, IKResult]:
    return {branch: scara.ik(robot, d, branch=branch) for branch in robot.branches}


def write_csv(path: Path, t: np.ndarray, results: dict[int, IKResult]) -> None:
    with path.open("w", newline="") as f:
        writer = csv.writer(f)
        writer.writerow(COLUMNS)
        for branch, res in results.items():
            q, qd, qdd = (np.asarray(x) for x in (res.q.p, res.q.v, res.q.a))
            names = status_names(res.status)
            for i in range(len(t)):
                row = [t[i]]
                for j in range(3):
                    row += [q[i, j], qd[i, j], qdd[i, j]]
                writer.writerow([f"{x:.17g}" for x in row] + [names[i], branch])


def plot(
    path: Path, robot: scara.Scara, robot_d: Jet, t: np.ndarray, results: dict[int, IKResult]
) -> bool:
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        return False
    fig, axes = plt.subplots(2, 3, figsize=(13, 7.5))
    colours = {1: "tab:blue", -1: "tab:orange"}
    p = np.asarray(robot_d.p)
    # The elbow B at the final instant: the end of the arm's segment, in the arm plane.
    elbows = {
        branch: robot.link_segments(res.q.p[-1], robot_d.p[-1])[0, 1, :2]
        for branch, res in results.items()
    }
    ax = axes[0, 0]  # plan view: path and the robot at the final instant
    ax.plot(p[:, 0], p[:, 1], "k-", lw=0.8, label="path of D (eq. 16)")
    for branch, elbow in elbows.items():
        b = np.asarray(elbow)
        ax.plot(
            [0, b[0], p[-1, 0]],
            [0, b[1], p[-1, 1]],
            "o-",
            color=colours[branch],
            label=f"branch {branch:+d} at t = {t[-1]:g} s",
        )
    ax.set_aspect("equal")
    ax.set_xlabel("x (mm)")
    ax.set_ylabel("y (mm)")
    ax.set_title("Plan view")
    ax.legend(fontsize=7)
    ax = axes[1, 0]  # side view at the final instant
    for branch, elbow in elbows.items():
        b = np.asarray(elbow)
        ax.plot(
            [0, 0, b[0], p[-1, 0], p[-1, 0]],
            [0, L_OA, L_OA, L_OA, p[-1, 2]],
            "o-",
            color=colours[branch],
            label=f"branch {branch:+d}",
        )
    ax.plot(p[:, 0], p[:, 2], "k-", lw=0.8)
    ax.set_xlabel("x (mm)")
    ax.set_ylabel("z (mm)")
    ax.set_title("Side view (x-z), final instant")
    ax.legend(fontsize=7)
    panels = [
        (axes[0, 1], "p", r"$\theta_1$ (rad)"),
        (axes[0, 2], "v", r"$\dot\theta_1$ (rad/s)"),
        (axes[1, 1], "a", r"$\ddot\theta_1$ (rad/s$^2$)"),
    ]
    for ax, field, label in panels:
        for branch, res in results.items():
            ax.plot(
                t,
                np.asarray(getattr(res.q, field))[:, 0],
                color=colours[branch],
                label=f"branch {branch:+d}",
            )
        ax.set_xlabel("t (s)")
        ax.set_ylabel(label)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7)
    ax = axes[1, 2]  # singularity indicator
    for branch, res in results.items():
        ax.plot(
            t,
            np.asarray(res.margin),
            color=colours[branch],
            label=f"margin sin²β, branch {branch:+d}",
        )
        singular = np.asarray(res.status) != Status.OK
        ax.plot(
            t,
            singular.astype(float),
            "--",
            color=colours[branch],
            label=f"singular/failed, branch {branch:+d}",
        )
    ax.set_ylim(-0.05, 1.05)
    ax.set_xlabel("t (s)")
    ax.set_title("Singularity indicator")
    ax.legend(fontsize=7)
    fig.suptitle("SCARA on the spiral of eq. 16 ([Noriega, Fig. 6])")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return True


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--output-dir", type=Path, default=Path("."), help="where files go")
    output = parser.parse_args(argv).output_dir
    robot = scara.Scara(L_OA, L_AB, L_BC)
    t = np.linspace(0.0, T_END, N_SAMPLES)
    d = spiral(t)
    solve(robot, d)  # compile once, so the timing below is the solve itself
    start = time.perf_counter()
    results = solve(robot, d)
    for res in results.values():
        res.q.p.block_until_ready()
    elapsed = time.perf_counter() - start

    csv_path = output / "scara_spiral.csv"
    write_csv(csv_path, t, results)
    png_path = output / "scara_spiral.png"
    plotted = plot(png_path, robot, d, t, results)

    print(
        f"SCARA spiral (eq. 16): l_OA={L_OA:g}, l_AB={L_AB:g}, l_BC={L_BC:g} mm, "
        f"t in [0, {T_END:g}] s, {N_SAMPLES} samples"
    )
    print(f"solved both branches with velocities and accelerations in {elapsed * 1e3:.1f} ms")
    for branch, res in results.items():
        q, qd, qdd = (np.asarray(x) for x in (res.q.p, res.q.v, res.q.a))
        names, counts = np.unique(status_names(res.status), return_counts=True)
        statuses = ", ".join(f"{n} x{c}" for n, c in zip(names, counts, strict=True))
        print(
            f"branch {branch:+d}: status {statuses}; min margin sin^2(beta) = "
            f"{float(jnp.min(res.margin)):.3f}"
        )
        for j, name in enumerate(("theta1", "theta2", "l3")):
            unit = "mm" if name == "l3" else "rad"
            print(
                f"  {name:6s} in [{q[:, j].min():9.4f}, {q[:, j].max():9.4f}] {unit}; "
                f"|rate| <= {np.abs(qd[:, j]).max():.4f}, |accel| <= {np.abs(qdd[:, j]).max():.4f}"
            )
        print(f"  theta1_ddot(t=0) = {qdd[0, 0]:.4f} rad/s^2")
    print(
        "with the corrected acceleration formulas theta1_ddot(0) = 0.309 rad/s^2 on branch +1 "
        f"(here {float(results[1].q.a[0, 0]):.4f}; see docs/errata.md)"
    )
    print(f"wrote {csv_path}")
    print(f"wrote {png_path}" if plotted else "matplotlib not installed: no PNG")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
