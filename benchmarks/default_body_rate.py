"""The Panda's default collision body beside the benchmarks' small body, in one process.

The Panda of example-robot-data from its URDF and SRDF (``serial.from_urdf(...).with_srdf``):
its default body (the URDF's meshes covered within 1 cm, ``collision.body_from_urdf``'s
defaults) and the small body of ``benchmarks/test_collision.py`` (``max_spheres_per_mesh=5``,
``with_link_spheres``: 65 spheres with the former covers, 59 with the 1 cm covers). 12
spheres and 8 boxes around the arm, each at least 5 cm from the links that never move; random
configurations within the joint limits.
Printed per body: spheres, sphere pairs, the body's build time (CPU seconds, the covers of
the meshes read with the chain), the first ``collides`` (compile included), configurations
per second of ``collision.collides`` (the verdict) and ``collision.check`` (the exhaustive
clearance), best of ``--rounds``, whether the two verdicts agree on every configuration, and
the colliding share. ``--bounds`` adds a body per cover bound (``max_overshoot``, metres),
timed in the same process. ``docs/performance.md`` records a run. Low latency is on
(``jaxkin.enable_low_latency``, as ``benchmarks/conftest.py``; ``JAXKIN_LOW_LATENCY=0`` for
JAX's defaults).

    .venv/bin/python benchmarks/default_body_rate.py [--n 10000] [--dtype float32] [--rounds 5]
        [--bounds 0.005 ...]
"""

from __future__ import annotations

import argparse
import time

import jax
import numpy as np
from cover_quality import robots_folder  # this script's folder is on sys.path

from jaxkin._execute.latency import enable_for_command

enable_for_command()  # as the benchmarks (conftest.py): before JAX runs anything


def best_rate(fn, n: int, rounds: int) -> float:
    """Configurations per second: ``n`` over the best of ``rounds`` timed calls."""
    times = []
    for _ in range(rounds):
        start = time.perf_counter()
        jax.block_until_ready(fn())
        times.append(time.perf_counter() - start)
    return n / min(times)


def scene(n: int, dtype: str) -> tuple:
    """``(default, built_default, small, built_small, world, q)``: the two Pandas and their
    build times (CPU seconds), the 12 spheres and 8 boxes, ``n`` random configurations."""
    from scipy.spatial.transform import Rotation

    from jaxkin import collision, serial

    root = robots_folder()
    urdf = root / "panda_description/urdf/panda.urdf"
    srdf = root / "panda_description/srdf/panda.srdf"
    start = time.process_time()
    default = serial.from_urdf(urdf, "panda_hand").with_srdf(srdf)
    default.collision_body()
    built_default = time.process_time() - start
    start = time.process_time()
    _, capsules = collision.body_from_urdf(urdf, max_spheres_per_mesh=5).body.per_link()
    fingers = {
        name: (0.5 * (a + b), r + 0.5 * np.linalg.norm(b - a, axis=-1))
        for name, (a, b, r) in capsules.items()
    }
    spheres, _ = collision.body_from_urdf(
        urdf, max_spheres_per_mesh=5, link_spheres=fingers
    ).body.per_link()
    small = serial.from_urdf(urdf, "panda_hand").with_srdf(srdf).with_link_spheres(spheres)
    built_small = time.process_time() - start

    # obstacles at least 5 cm from the links that never move (they would collide always)
    body = default.collision_body()
    poses = np.asarray(default.link_poses(np.zeros(default.n_path_joints)))
    spheres_at_home, _ = body.place(poses)
    still = np.isin(
        np.asarray(body.sphere_link), np.flatnonzero(np.asarray(default.links.moved_by) == 0)
    )
    fixed_c = np.asarray(spheres_at_home.center)[still]
    fixed_r = np.asarray(spheres_at_home.radius)[still]
    rng = np.random.default_rng(3)
    low, high = np.array([-0.8, -0.8, 0.0]), np.array([0.8, 0.8, 1.2])
    s_c, s_r, b_c, b_h = [], [], [], []
    while len(s_r) < 12 or len(b_h) < 8:
        centre = rng.uniform(low, high)
        if len(s_r) < 12:
            radius = rng.uniform(0.04, 0.12)
            if np.all(np.linalg.norm(fixed_c - centre, axis=1) - fixed_r - radius >= 0.05):
                s_c.append(centre)
                s_r.append(radius)
        else:
            half = rng.uniform(0.03, 0.12, 3)
            reach = np.linalg.norm(half)  # the box's bounding sphere
            if np.all(np.linalg.norm(fixed_c - centre, axis=1) - fixed_r - reach >= 0.05):
                b_c.append(centre)
                b_h.append(half)
    world = collision.World.create(
        spheres=collision.Spheres.create(np.array(s_c), np.array(s_r)),
        boxes=collision.Boxes.create(
            np.array(b_c), np.array(b_h), Rotation.random(8, random_state=3).as_matrix()
        ),
    ).astype(dtype)

    lower, upper = np.asarray(default.lower), np.asarray(default.upper)
    q = rng.uniform(lower, upper, (n, len(lower))).astype(dtype)
    return default, built_default, small, built_small, world, q


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=int, default=10_000, help="configurations per call")
    parser.add_argument("--dtype", default="float32", choices=["float32", "float64"])
    parser.add_argument("--rounds", type=int, default=5)
    parser.add_argument(
        "--bounds", type=float, nargs="*", default=[], help="max_overshoot besides the default"
    )
    args = parser.parse_args()
    if args.dtype == "float64":
        jax.config.update("jax_enable_x64", True)
    from jaxkin import collision

    default, built_default, small, built_small, world, q = scene(args.n, args.dtype)
    print(
        f"Panda, {args.n} configurations, {args.dtype}, 12 spheres + 8 boxes, best of {args.rounds}"
    )
    rows = [("default", default, built_default), ("small", small, built_small)]
    urdf = robots_folder() / "panda_description/urdf/panda.urdf"
    for bound in args.bounds:
        start = time.process_time()
        tight = collision.body_from_urdf(urdf, max_overshoot=bound).body
        rows.append((f"{100 * bound:g} cm", default.with_body(tight), time.process_time() - start))
    for label, robot, built in rows:
        body, pairs = collision.prepare(robot)
        start = time.perf_counter()
        verdict = np.asarray(collision.collides(robot, q, world).collides)
        first = time.perf_counter() - start
        exhaustive = np.asarray(collision.check(robot, q, world).collides)
        rate = best_rate(lambda robot=robot: collision.collides(robot, q, world).collides,
                         args.n, args.rounds)  # fmt: skip
        rate_check = best_rate(lambda robot=robot: collision.check(robot, q, world).clearance,
                               args.n, args.rounds)  # fmt: skip
        print(
            f"{label:10s} {body.num_spheres:4d} spheres + {body.num_capsules} capsules, "
            f"{len(pairs.ss[0]):6d} sphere pairs; body {built:.2f} s CPU; first collides "
            f"{first:.2f} s; collides {rate:,.0f}/s, check {rate_check:,.0f}/s; verdicts "
            f"{'identical' if np.array_equal(verdict, exhaustive) else 'DIFFER'} "
            f"({np.sum(verdict != exhaustive)} differ); {verdict.mean():.2f} colliding",
            flush=True,
        )


if __name__ == "__main__":
    main()
