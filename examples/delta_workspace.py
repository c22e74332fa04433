"""The Delta robot's ideal workspace [Cardona, sec. V, Figs. 7 and 8].

Sweeps a 1 cm voxel grid over x, y in [-50, 50] cm and z in [-45, 45] cm (101 x 101 x 91 =
928,291 voxels, the count the paper reports as evaluated) with the paper's robot (base 7 cm,
platform 2.5 cm, arm 15.5 cm, parallelogram 30 cm), classifies each voxel with the closed-form
IK, and prints the reachable voxel count and volume, and the area of horizontal slices, which
shrinks as z becomes more negative (the paper's Fig. 8). With matplotlib it writes
``delta_workspace_3d.png`` (Fig. 7: the intersection of three tori) and
``delta_workspace_slices.png`` (Fig. 8) into ``--output-dir`` (default: the current directory).

Usage: ``python examples/delta_workspace.py [--resolution CM] [--output-dir DIR]`` (default
1.0 cm; tests use a coarse grid).
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import jax
import numpy as np

jax.config.update("jax_enable_x64", True)  # an application choice; the library never does this

from jaxkin import delta, workspace  # noqa: E402


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--resolution", type=float, default=1.0, help="voxel size in cm")
    parser.add_argument("--output-dir", type=Path, default=Path("."), help="where files go")
    args = parser.parse_args(argv)
    output = args.output_dir

    robot = delta.Delta.paper()
    bounds = ((-50.0, 50.0), (-50.0, 50.0), (-45.0, 45.0))
    start = time.perf_counter()
    ws = workspace.sweep(robot, bounds, args.resolution)
    elapsed = time.perf_counter() - start

    print(f"Delta robot {robot.r_base}/{robot.r_platform}/{robot.l_arm}/{robot.l_rod} cm")
    print(
        f"voxels evaluated: {ws.n_evaluated:,} ({' x '.join(str(len(a)) for a in ws.axes)}, "
        f"{args.resolution:g} cm grid; the paper evaluated 928,291 = 101 x 101 x 91)"
    )
    print(f"reachable voxels: {ws.n_reachable:,} ({100.0 * ws.n_reachable / ws.n_evaluated:.1f} %)")
    print(f"reachable volume: {ws.volume:,.0f} cm^3 ({ws.volume / 1000.0:.2f} litres)")
    print(f"sweep time: {elapsed:.2f} s ({ws.n_evaluated / elapsed / 1e6:.1f} M voxels/s)")
    zs = ws.axes[2]
    below = int(ws.mask[:, :, zs < 0].sum())
    print(
        f"below the base (z < 0, the hanging robot's half; the torus intersection is symmetric "
        f"about z = 0): {below:,} voxels"
    )
    nonzero = np.nonzero(ws.slice_areas)[0]
    print(f"reachable z range: [{zs[nonzero[0]]:g}, {zs[nonzero[-1]]:g}] cm")
    widest = nonzero[np.argmax(ws.slice_areas[nonzero])]
    print(f"widest slice: z = {zs[widest]:g} cm, {ws.slice_areas[widest]:.0f} cm^2")
    print("slice areas below the widest (the workspace shrinks with depth, Fig. 8):")
    for z in (-25.0, -30.0, -35.0, -40.0, -45.0):
        k = int(np.argmin(np.abs(zs - z)))
        print(f"  z = {zs[k]:6.1f} cm: {ws.slice_areas[k]:7.0f} cm^2")

    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        print("matplotlib not installed: no PNGs (pip install jaxkin[plot])")
        return 0
    xs, ys, _ = ws.axes
    mask = ws.mask
    # Fig. 7: boundary voxels of the reachable set (a voxel with an unreachable neighbour).
    padded = np.pad(mask, 1)
    interior = mask.copy()
    for axis in range(3):
        for shift in (-1, 1):
            interior &= np.roll(padded, shift, axis=axis)[1:-1, 1:-1, 1:-1]
    i, j, k = np.nonzero(mask & ~interior)
    rng = np.random.default_rng(0)
    keep = rng.permutation(len(i))[:20000]
    fig = plt.figure(figsize=(7, 6))
    ax = fig.add_subplot(projection="3d")
    ax.scatter(xs[i[keep]], ys[j[keep]], zs[k[keep]], s=1, c=zs[k[keep]], cmap="viridis")
    ax.set(xlabel="x [cm]", ylabel="y [cm]", zlabel="z [cm]")
    ax.set_title(f"Delta ideal workspace: {ws.n_reachable:,} voxels ({ws.volume / 1e3:.1f} l)")
    path3d = output / "delta_workspace_3d.png"
    fig.savefig(path3d, dpi=110)
    plt.close(fig)
    # Fig. 8: horizontal slices at decreasing z.
    levels = [z for z in (-20.0, -25.0, -30.0, -35.0, -40.0, -44.0) if zs[0] <= z <= zs[-1]]
    fig, axes = plt.subplots(2, 3, figsize=(11, 7), sharex=True, sharey=True)
    for ax, z in zip(axes.ravel(), levels, strict=False):
        kk = int(np.argmin(np.abs(zs - z)))
        ax.imshow(
            mask[:, :, kk].T,
            origin="lower",
            extent=(xs[0], xs[-1], ys[0], ys[-1]),
            cmap="Blues",
            vmin=0,
            vmax=1,
        )
        ax.set_title(f"z = {zs[kk]:g} cm: {ws.slice_areas[kk]:.0f} cm^2")
        ax.set(xlabel="x [cm]", ylabel="y [cm]")
    fig.suptitle("Delta workspace slices (shrinking with depth)")
    fig.tight_layout()
    path_slices = output / "delta_workspace_slices.png"
    fig.savefig(path_slices, dpi=110)
    plt.close(fig)
    print(f"wrote {path3d} and {path_slices}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
