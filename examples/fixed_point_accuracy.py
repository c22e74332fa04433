"""A fixed-point accuracy study of the anthropomorphic arm on a triangle path ([Lopez-Villagomez]).

The paper gives neither link lengths nor the triangle (``docs/errata.md``); this script chooses:

* arm ``Anthropomorphic(l1=0.30, l2=0.25, l3=0.20)`` (metres; shoulder height, upper arm,
  forearm), branch ``front_up``;
* triangle with vertices (0.25, -0.10, 0.30), (0.25, 0.10, 0.30), (0.30, 0.00, 0.45) m,
  100 points per edge (300 wrist positions, all well inside the workspace);
* bit widths 1..40 fractional bits, truncation toward -inf (the paper's) and, for
  comparison, round-to-nearest;
* tolerance: RMS Cartesian error <= 1 mm.

It prints, per width, the RMS joint-angle error (per joint and overall, radians) and the RMS
and maximum Cartesian error (the exact forward kinematics of the fixed-point angles against
the path), then the smallest width that keeps the RMS Cartesian error under the tolerance,
and writes ``fixed_point_accuracy.csv`` and, when matplotlib is installed,
``fixed_point_accuracy.png`` into ``--output-dir`` (default: the current directory).

Run: ``jaxkin demo fixed-point-accuracy`` or ``python examples/fixed_point_accuracy.py``.
"""

from __future__ import annotations

import argparse
import pathlib

import jax

jax.config.update("jax_enable_x64", True)  # the emulation needs float64 (see jaxkin.fixedpoint)

import numpy as np  # noqa: E402

from jaxkin import fixedpoint  # noqa: E402
from jaxkin.serial.arms import Anthropomorphic  # noqa: E402

LENGTHS = (0.30, 0.25, 0.20)
TRIANGLE = np.array([[0.25, -0.10, 0.30], [0.25, 0.10, 0.30], [0.30, 0.00, 0.45]])
POINTS_PER_EDGE = 100
BITS = np.arange(1, 41)
TOLERANCE = 1e-3  # metres, RMS Cartesian error
PAPER_BITS = 10


def triangle_path(vertices: np.ndarray, per_edge: int) -> np.ndarray:
    """Points along the closed triangle, ``(3 * per_edge, 3)``, each edge without its end."""
    t = np.linspace(0.0, 1.0, per_edge, endpoint=False)[:, None]
    edges = [vertices[i] + t * (vertices[(i + 1) % 3] - vertices[i]) for i in range(3)]
    return np.concatenate(edges)


def study(output: pathlib.Path) -> dict:
    """Run the study, print it, write its files into ``output``; the key numbers."""
    robot = Anthropomorphic(*LENGTHS)
    path = triangle_path(TRIANGLE, POINTS_PER_EDGE)
    studies = {
        rounding: fixedpoint.accuracy_study(robot, path, BITS, rounding=rounding)
        for rounding in fixedpoint.ROUNDINGS
    }
    floor = studies["floor"]
    joint_rms = np.asarray(floor.joint_rms)
    cart_rms = np.asarray(floor.cartesian_rms)
    cart_max = np.asarray(floor.cartesian_max)
    nearest_rms = np.asarray(studies["nearest"].cartesian_rms)

    print(f"arm l1, l2, l3 = {LENGTHS} m; triangle {TRIANGLE.tolist()} m; {len(path)} points")
    print(
        " bits  rms q1 [rad]  rms q2 [rad]  rms q3 [rad]  rms xyz [m]  max xyz [m]  "
        "rms xyz nearest [m]"
    )
    for i, n in enumerate(BITS):
        print(
            f"{n:5d}  {joint_rms[i, 0]:12.3e}  {joint_rms[i, 1]:12.3e}  {joint_rms[i, 2]:12.3e}"
            f"  {cart_rms[i]:11.3e}  {cart_max[i]:11.3e}  {nearest_rms[i]:11.3e}"
        )
    width = fixedpoint.smallest_width(BITS, cart_rms, TOLERANCE)
    width_nearest = fixedpoint.smallest_width(BITS, nearest_rms, TOLERANCE)
    at_paper = cart_rms[BITS == PAPER_BITS][0]
    print(
        f"\nsmallest width with RMS Cartesian error <= {TOLERANCE * 1e3:g} mm: {width} bits "
        f"(truncation), {width_nearest} bits (round to nearest)"
    )
    verdict = "agree" if width is not None and width <= PAPER_BITS else "do not agree"
    print(
        f"at {PAPER_BITS} bits the RMS Cartesian error is {at_paper * 1e3:.2f} mm "
        f"({at_paper / np.ptp(TRIANGLE, axis=0).max() * 100:.1f} % of the triangle's size): "
        f"for this geometry and tolerance we {verdict} with the paper's 10-bit claim."
    )

    table = np.column_stack([BITS, joint_rms, floor.joint_rms_all, cart_rms, cart_max, nearest_rms])
    np.savetxt(
        output / "fixed_point_accuracy.csv",
        table,
        delimiter=",",
        header="bits,rms_q1,rms_q2,rms_q3,rms_q,rms_xyz,max_xyz,rms_xyz_nearest",
        comments="",
    )
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        print("matplotlib not installed: no plot")
    else:
        fig, (ax_q, ax_x) = plt.subplots(1, 2, figsize=(11, 4.2))
        for j in range(3):
            ax_q.semilogy(BITS, joint_rms[:, j], label=f"theta{j + 1}")
        ax_q.set(
            xlabel="fractional bits",
            ylabel="RMS joint error [rad]",
            title="Joint angles (truncation)",
        )
        ax_q.legend()
        ax_x.semilogy(BITS, cart_rms, label="RMS, truncation")
        ax_x.semilogy(BITS, cart_max, "--", label="max, truncation")
        ax_x.semilogy(BITS, nearest_rms, ":", label="RMS, round to nearest")
        ax_x.axhline(TOLERANCE, color="k", lw=0.8, label=f"tolerance {TOLERANCE * 1e3:g} mm")
        ax_x.axvline(PAPER_BITS, color="grey", lw=0.8, ls="-.", label="paper: 10 bits")
        ax_x.set(
            xlabel="fractional bits",
            ylabel="Cartesian error [m]",
            title="Wrist position along the triangle",
        )
        ax_x.legend(fontsize=8)
        fig.tight_layout()
        fig.savefig(output / "fixed_point_accuracy.png", dpi=110)
        plt.close(fig)
        print(f"wrote {output / 'fixed_point_accuracy.png'}")
    return {"width": width, "width_nearest": width_nearest, "rms_at_10": float(at_paper)}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--output-dir", type=pathlib.Path, default=pathlib.Path("."))
    study(parser.parse_args(argv).output_dir)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
