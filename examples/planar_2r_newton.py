"""A worked Newton-Raphson example: a planar 2R arm, body-frame update ([Pineiro]).

Links of 1 m; home M = Trans(2, 0, 0); body screws B1 = (0, 0, 1, 0, 2, 0) and
B2 = (0, 0, 1, 0, 1, 0); target (x, y) = (0.366, 1.366) m with the end-effector x axis at
120 degrees; seed theta0 = (0, 30 deg); tolerances eps_omega = 1e-3 rad, eps_v = 1e-4 m.

The script runs ``jaxkin.serial.ik_newton`` and prints every iterate (joint angles, end
position, body twist V_b = log(T_sb^-1 T_sd)) beside the table printed in the source. As
``docs/errata.md`` notes, the table is that of the body-frame update theta += J_b^+ V_b, and its
4 rows are 3 updates. Writes ``planar_2r_newton.csv`` and, with matplotlib installed,
``planar_2r_newton.png`` into ``--output-dir``. Run: ``jaxkin demo planar-2r-newton``.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import jax
import numpy as np

import jaxkin
from jaxkin import lie, serial

jax.config.update("jax_enable_x64", True)  # an application choice; the library never sets it

# [Pineiro]'s table of the 2R example (transcribed): i, theta1, theta2 [deg], x, y [m],
# V_b = (omega_zb, v_xb, v_yb). Printed precision: 2 decimals for angles, 3 for the rest.
PAPER_TABLE = np.array(
    [
        [0, 0.00, 30.00, 1.866, 0.500, 1.571, 0.498, 1.858],
        [1, 34.23, 79.18, 0.429, 1.480, 0.115, -0.074, 0.108],
        [2, 29.98, 90.22, 0.363, 1.364, -0.004, 0.000, -0.004],
        [3, 30.00, 90.00, 0.366, 1.366, 0.000, 0.000, 0.000],
    ]
)
PAPER_DECIMALS = np.array([0, 2, 2, 3, 3, 3, 3, 3])
COLUMNS = ["i", "theta1_deg", "theta2_deg", "x_m", "y_m", "omega_zb", "v_xb", "v_yb"]


def chain() -> serial.Chain:
    home = np.eye(4)
    home[0, 3] = 2.0
    screws = np.array([[0, 0, 1, 0, 2, 0], [0, 0, 1, 0, 1, 0]], dtype=np.float64)
    return serial.from_screws(screws, home, frame="body")


def target() -> np.ndarray:
    c, s = np.cos(np.radians(30.0)), np.sin(np.radians(30.0))
    return np.array(
        [[-s, -c, 0.0, 0.366], [c, -s, 0.0, 1.366], [0.0, 0.0, 1.0, 0.0], [0.0, 0.0, 0.0, 1.0]]
    )


def run() -> tuple[np.ndarray, serial.NewtonIKResult]:
    """Solve the example; return the computed table (one row per iterate) and the result."""
    arm, t_sd = chain(), target()
    result = serial.ik_newton(
        arm, t_sd, np.radians([0.0, 30.0]), eps_omega=1e-3, eps_v=1e-4, max_iter=20, frame="body"
    )
    iterates = np.asarray(result.history[: int(result.iterations) + 1])
    t_sb = np.asarray(jaxkin.fk(arm, iterates).x.p)
    twist = np.asarray(lie.se3_log(lie.se3_inverse(t_sb) @ t_sd))
    rows = np.column_stack(
        [
            np.arange(len(iterates)),
            np.degrees(iterates),
            t_sb[:, 0, 3],
            t_sb[:, 1, 3],
            twist[:, 2],
            twist[:, 3],
            twist[:, 4],
        ]
    )
    return rows, result


def _fmt(row: np.ndarray) -> str:
    return (
        f"{int(row[0]):>2}  ({row[1]:6.2f}, {row[2]:6.2f})  ({row[3]:.3f}, {row[4]:.3f})  "
        f"({row[5]:6.3f}, {row[6]:6.3f}, {row[7]:6.3f})"
    )


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--output-dir", type=Path, default=Path("."), help="where files go")
    output = parser.parse_args(argv).output_dir
    rows, result = run()
    print("Planar 2R Newton-Raphson example (body frame), jaxkin vs the paper")
    print(" i  (theta1, theta2) deg   (x, y) m          V_b = (w_zb, v_xb, v_yb)")
    for i in range(max(len(rows), len(PAPER_TABLE))):
        if i < len(rows):
            print("jaxkin " + _fmt(rows[i]))
        if i < len(PAPER_TABLE):
            print("paper  " + _fmt(PAPER_TABLE[i]))
    worst = 0.0
    n = min(len(rows), len(PAPER_TABLE))
    for col in range(1, 8):
        diff = np.abs(np.round(rows[:n, col], PAPER_DECIMALS[col]) - PAPER_TABLE[:n, col])
        worst = max(worst, float(diff.max() / 10.0 ** -PAPER_DECIMALS[col]))
    print(
        f"\nstatus {int(result.status)} (0 = OK) after {int(result.iterations)} updates "
        f"({int(result.iterations) + 1} table rows); final error |omega| = "
        f"{float(result.error[0]):.2e} rad, |v| = {float(result.error[1]):.2e} m"
    )
    print(f"final theta = ({rows[-1, 1]:.4f}, {rows[-1, 2]:.4f}) deg; exact solution (30, 90) deg")
    print(f"largest difference from the paper after rounding: {worst:.0f} unit(s) of last digit")

    np.savetxt(
        output / "planar_2r_newton.csv", rows, delimiter=",", header=",".join(COLUMNS),
        comments="", fmt="%.10g",
    )  # fmt: skip
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        return 0
    fig, ax = plt.subplots(figsize=(5, 5))
    for row in rows:
        t1, t2 = np.radians(row[1]), np.radians(row[2])
        xs = [0.0, np.cos(t1), np.cos(t1) + np.cos(t1 + t2)]
        ys = [0.0, np.sin(t1), np.sin(t1) + np.sin(t1 + t2)]
        ax.plot(xs, ys, "o-", label=f"iterate {int(row[0])}")
    ax.plot([0.366], [1.366], "k*", markersize=14, label="target")
    ax.set_aspect("equal")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_title("Planar 2R Newton-Raphson (body frame)")
    ax.legend()
    fig.savefig(output / "planar_2r_newton.png", dpi=100)
    plt.close(fig)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
