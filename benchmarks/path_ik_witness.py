"""The path IK on witnessed pose paths of real arms: how many it finds feasible, and how fast.

``python benchmarks/path_ik_witness.py [PATHS] [SAMPLES] [SPREAD] [ARM ...]`` (default 40
paths of 64 samples, control points within ``SPREAD`` = 0.8 rad of the first, on every arm of
``tests/references/witnessed_paths.ARMS``, float64): per arm the pose paths of smooth joint
motions inside the limits (each one's witness proves a continuous answer within every limit
exists), ``plan.evaluate`` on all of them in one call (the default path IK:
``Chain.ik_path_kernel``), then the independent check of every feasible answer (Pinocchio's
poses and Jacobians, the limits, each step against the answer's own rates). Prints per arm the
feasible fraction, the feasible answers that fail the check (must be 0), the statuses of the
others, and the seconds of the first call (with its compilation) and of a repeated one.
"""

from __future__ import annotations

import os
import sys
import time

import jax
import numpy as np

jax.config.update("jax_enable_x64", True)
sys.path.insert(0, os.path.join(os.path.dirname(__file__), ".."))

from jaxkin import paths, plan, serial  # noqa: E402
from jaxkin.status import Status  # noqa: E402
from tests.references import witnessed_paths as wp  # noqa: E402


def run(name: str, count: int, samples: int, rng: np.random.Generator, spread: float) -> dict:
    urdf, tip = wp.ARMS[name]
    chain = serial.from_urdf(str(wp.ROBOTS / urdf), tip)
    arm = wp.Arm(name, list(chain.joint_names))
    (q, q_dot, q_ddot), dt = wp.witnesses(chain, count, samples, rng, spread)
    p, v, a = wp.pose_path(arm, q, q_dot, q_ddot)
    path = paths.Path(p, v, a, dt=dt)
    start = time.perf_counter()
    ev = plan.evaluate(chain, path)
    jax.block_until_ready(ev.feasible)
    first = time.perf_counter() - start
    start = time.perf_counter()
    ev = plan.evaluate(chain, path)
    jax.block_until_ready(ev.feasible)
    again = time.perf_counter() - start
    feasible = np.asarray(ev.feasible)
    answer = tuple(np.asarray(x, float) for x in (ev.q.p, ev.q.v, ev.q.a))
    check = wp.check_answers(arm, chain, answer, p, v, dt)
    good = (
        (check["pose"] <= 1e-8)
        & check["within"]
        & check["slow"]
        & check["explained"]
        & (check["rates"] <= 1e-6)
    )
    status = np.asarray(ev.status)
    bad = feasible & ~good
    if bad.any():
        print(
            f"{name}: feasible answers that fail the check:", {k: v[bad] for k, v in check.items()}
        )
    first_bad = [Status(int(s[s != Status.OK][0])).name for s in status[~feasible]]
    return {
        "arm": name,
        "n": chain.n_joints,
        "feasible": int(feasible.sum()),
        "paths": count,
        "bad": int(np.sum(feasible & ~good)),
        "failures": {k: first_bad.count(k) for k in sorted(set(first_bad))},
        "first_s": first,
        "again_s": again,
    }


def main() -> None:
    args = sys.argv[1:]
    count = int(args[0]) if args else 40
    samples = int(args[1]) if len(args) > 1 else 64
    spread = float(args[2]) if len(args) > 2 else wp.SPREAD
    arms = args[3:] or list(wp.ARMS)
    print(
        f"load {os.getloadavg()[0]:.2f}; {count} paths x {samples} samples, spread {spread}, "
        "float64"
    )
    for name in arms:
        out = run(name, count, samples, np.random.default_rng(sum(map(ord, name))), spread)
        print(
            f"{out['arm']:7s} n={out['n']} feasible {out['feasible']}/{out['paths']} "
            f"({100 * out['feasible'] / out['paths']:.1f} %), bad feasible {out['bad']}, "
            f"failures {out['failures']}, first call {out['first_s']:.1f} s, "
            f"repeated {out['again_s']:.2f} s ({1e3 * out['again_s'] / out['paths']:.1f} ms/path)"
        )
        sys.stdout.flush()


if __name__ == "__main__":
    main()
