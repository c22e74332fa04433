"""A UR5 from its URDF: 10,000 pose targets solved without a seed, then a pose path planned.

Loads ``ur5.urdf`` (shipped beside this script: the arm's published joint placements and
limits, a finger on a side branch that the chain ignores) with ``serial.from_urdf``, solves
``N`` (default 10,000) pose targets made from random joints within the limits, with no seed
(Levenberg-Marquardt with restarts within the joint limits), and checks every answer by the
chain's forward kinematics. Then it plans: 64 candidate pose paths (the tool moves 30 cm along
a bent line while it turns 90 degrees about its own axis), splined by ``paths.path_from_poses``
and evaluated by ``plan.evaluate`` with Newton warm-started along each candidate; the best
candidate's joints go to ``urdf_arm_best.csv`` in ``--output-dir``.

Usage: ``python examples/urdf_arm.py [N] [--output-dir DIR]`` (needs the ``urdf`` extra).
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import jax
import numpy as np

jax.config.update("jax_enable_x64", True)  # an application choice; the library never does this

import jaxkin  # noqa: E402
from jaxkin import Status, paths, plan, serial  # noqa: E402

URDF = Path(__file__).with_name("ur5.urdf")


def _quaternion_about_z(angle: np.ndarray, base: np.ndarray) -> np.ndarray:
    """``base * (cos(angle/2), 0, 0, sin(angle/2))``: the tool turned about its own z axis."""
    c, s = np.cos(angle / 2), np.sin(angle / 2)
    w, x, y, z = base
    return np.stack([w * c - z * s, x * c + y * s, y * c - x * s, z * c + w * s], -1)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("n", nargs="?", type=int, default=10_000, help="pose targets")
    parser.add_argument("--output-dir", type=Path, default=Path("."), help="where files go")
    args = parser.parse_args(argv)

    arm = serial.from_urdf(URDF, "tool0")
    print(f"{URDF.name}: joints {', '.join(arm.joint_names)} ({arm.joint_types})")
    q = np.random.default_rng(0).uniform(arm.lower, arm.upper, size=(args.n, arm.n_joints))
    targets = jaxkin.fk(arm, q).x.p
    began = time.perf_counter()
    res = jaxkin.ik(arm, targets)  # no seed
    jax.block_until_ready(res.q.p)
    first = time.perf_counter() - began
    began = time.perf_counter()
    res = jaxkin.ik(arm, targets)
    jax.block_until_ready(res.q.p)
    again = time.perf_counter() - began
    status = np.asarray(res.status)
    ok = status == Status.OK
    reached = np.asarray(jaxkin.fk(arm, res.q.p[ok]).x.p)
    error = np.abs(reached[:, :3, 3] - np.asarray(targets)[ok][:, :3, 3]).max(initial=0.0)
    within = np.all((res.q.p[ok] >= arm.lower) & (res.q.p[ok] <= arm.upper))
    print(
        f"{args.n:,} pose targets, no seed: {ok.mean():.2%} OK, largest position error "
        f"{error:.1e} m, every OK answer within the limits: {bool(within)}"
    )
    print(f"time: {first:.1f} s with compilation, {again:.2f} s again ({args.n / again:,.0f}/s)")

    n, t, dt = 64, 50, 0.04
    s = np.linspace(0.0, 1.0, t)[None, :, None]
    start, goal = np.array([0.45, -0.15, 0.35]), np.array([0.45, 0.15, 0.35])
    bend = np.random.default_rng(1).normal(scale=0.05, size=(n, 1, 3))
    positions = start + s * (goal - start) + np.sin(np.pi * s) * bend  # (n, t, 3)
    down = np.array([0.0, 1.0, 0.0, 0.0])  # the tool pointing down: a half turn about x
    quaternions = np.broadcast_to(_quaternion_about_z(0.5 * np.pi * s[..., 0], down), (n, t, 4))
    path = paths.path_from_poses(positions, quaternions, dt)  # (64, 50, 4, 4)
    began = time.perf_counter()
    ev = plan.evaluate(arm, path)  # the path carries its dt
    jax.block_until_ready(ev.costs.total)
    elapsed = time.perf_counter() - began
    feasible = np.asarray(ev.feasible)
    print(f"pose paths: {feasible.sum()} of {n} feasible ({elapsed:.1f} s with compilation)")
    if not feasible.any():
        return 1
    (best,), (cost,) = plan.best(ev, 1)
    back = jaxkin.fk(arm, ev.q[best]).x
    drift = np.abs(np.asarray(back.p) - np.asarray(path.p[best])).max()
    print(f"best candidate {best}: integrated squared joint acceleration {cost:.3g}, "
          f"tool pose from its joints within {drift:.1e} of the path")  # fmt: skip
    table = np.c_[np.arange(t) * dt, ev.q.p[best], ev.q.v[best], ev.q.a[best]]
    names = arm.joint_names
    header = ["t", *names, *(f"{j}_dot" for j in names), *(f"{j}_ddot" for j in names)]
    output = args.output_dir / "urdf_arm_best.csv"
    np.savetxt(output, table, delimiter=",", header=",".join(header), comments="")
    print(f"wrote {output}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
