"""One state and one edge from a planner's loop, through compiled handles (a script).

The Panda with VAMP's 59-sphere body (``benchmarks/mbm/panda_spherized.urdf`` and its SRDF)
and with the default body read from example-robot-data's URDF, in a MotionBenchMaker-sized
world (20 obstacles: 12 spheres, 8 boxes), float32 and float64. Per robot body, in one
process, interleaved rounds of 2,000 calls each (the median of each round's median, and the
best round's median), microseconds per call:

- ``handle``: ``jaxkin.compiled(collision.collides, robot, world, batch=())`` called with one
  configuration, and ``jaxkin.compiled(collision.validate_motions, robot, world, resolution,
  32, batch=1, clearance=False)`` with one 32-state edge (the OMPL example's two queries);
- ``bare jit``: the same kernels (``collision.collides_kernel`` and
  ``collision.validate_motions_kernel`` on the prepared body and pairs) under a plain
  ``jax.jit`` with the world as an argument: the reference the handles are held to (within 2x);
- ``public``: ``collision.collides`` / ``collision.validate_motions`` called as a user would.

Every call is blocked on (``jax.block_until_ready``). Prints a Markdown table with the load
average (``docs/performance.md``, "The execution layer"), with JAX's default CPU runtime or
after ``jaxkin.enable_low_latency()``::

    .venv/bin/python benchmarks/handles_latency.py [--low-latency]
"""

from __future__ import annotations

import argparse
import os
import statistics
import time
from pathlib import Path

import jax

jax.config.update("jax_enable_x64", True)

import numpy as np  # noqa: E402
from cover_quality import robots_folder  # noqa: E402  # this script's folder is on sys.path

import jaxkin  # noqa: E402
from jaxkin import collision, serial  # noqa: E402

HERE = Path(__file__).resolve().parent
RESOLUTION = 32.0
SAMPLES = 32
ROUNDS, CALLS = 5, 2000


def _robots():
    root = robots_folder()
    srdf = root / "panda_description/srdf/panda.srdf"
    vamp = serial.from_urdf(HERE / "mbm" / "panda_spherized.urdf", "panda_hand")
    default = serial.from_urdf(root / "panda_description/urdf/panda.urdf", "panda_hand")
    return {
        "VAMP's 59 spheres": vamp.with_srdf(HERE / "mbm" / "panda.srdf"),
        "default URDF body": default.with_srdf(srdf),
    }


def _world(dtype) -> collision.World:
    rng = np.random.default_rng(3)
    low, high = [-0.7, -0.7, 0.0], [0.7, 0.7, 1.1]
    rot = np.stack([np.linalg.qr(rng.normal(size=(3, 3)))[0] for _ in range(8)])
    return collision.World.create(
        spheres=collision.Spheres.create(
            rng.uniform(low, high, (12, 3)), rng.uniform(0.04, 0.12, 12)
        ),
        boxes=collision.Boxes.create(
            rng.uniform(low, high, (8, 3)), rng.uniform(0.03, 0.12, (8, 3)), rot
        ),
        dtype=dtype,
    )


def _time(fn, *args) -> float:
    """Median microseconds of ``CALLS`` blocked calls."""
    times = []
    for _ in range(CALLS):
        start = time.perf_counter()
        jax.block_until_ready(fn(*args))
        times.append(time.perf_counter() - start)
    return 1e6 * statistics.median(times)


def _calls(robot, world, dtype):
    """``{(query, route): (fn, args)}`` for the state and the edge."""
    rng = np.random.default_rng(0)
    low, high = np.asarray(robot.lower), np.asarray(robot.upper)
    q = rng.uniform(low, high).astype(dtype)
    a, b = (rng.uniform(low, high, (1, robot.n_joints)).astype(dtype) for _ in range(2))
    body, pairs = collision.prepare(robot)
    state = jaxkin.compiled(collision.collides, robot, world, batch=(), dtype=dtype)
    edge = jaxkin.compiled(
        collision.validate_motions, robot, world, RESOLUTION, SAMPLES, batch=1,
        clearance=False, dtype=dtype,
    )  # fmt: skip
    bare_state = jax.jit(
        lambda q, w: collision.collides_kernel(robot, body, pairs, q, w, 0.0).collides
    )
    bare_edge = jax.jit(
        lambda a, b, w: (
            collision.validate_motions_kernel(
                robot, body, pairs, a, b, w, RESOLUTION, SAMPLES, 0.0, False
            ).valid
        )
    )
    qj, aj, bj = (jax.device_put(x) for x in (q, a, b))
    return {
        ("state", "handle"): (state, (q,)),
        ("state", "bare jit"): (bare_state, (qj, world)),
        ("state", "public"): (lambda q: collision.collides(robot, q, world).collides, (q,)),
        ("edge", "handle"): (edge, (a, b)),
        ("edge", "bare jit"): (bare_edge, (aj, bj, world)),
        ("edge", "public"): (
            lambda a, b: (
                collision.validate_motions(
                    robot, a, b, world, RESOLUTION, samples=SAMPLES, clearance=False
                ).valid
            ),
            (a, b),
        ),
    }


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--low-latency", action="store_true", help="jaxkin.enable_low_latency() first"
    )
    if parser.parse_args(argv).low_latency:
        jaxkin.enable_low_latency()  # before the first computation
    print("| body | dtype | query | handle us | bare jit us | public us | handle / jit | load |")
    print("| --- | --- | --- | --- | --- | --- | --- | --- |")
    for name, robot in _robots().items():
        for dtype in (np.float32, np.float64):
            world = _world(dtype)
            calls = _calls(robot, world, dtype)
            for fn, args in calls.values():  # compile and warm every route first
                for _ in range(20):
                    jax.block_until_ready(fn(*args))
            rounds: dict = {key: [] for key in calls}
            for _ in range(ROUNDS):
                for key, (fn, args) in calls.items():
                    rounds[key].append(_time(fn, *args))
            load = os.getloadavg()[0]
            for query in ("state", "edge"):
                cells = []
                for route in ("handle", "bare jit", "public"):
                    r = rounds[(query, route)]
                    cells.append(f"{statistics.median(r):.1f} ({min(r):.1f})")
                ratio = statistics.median(rounds[(query, "handle")]) / statistics.median(
                    rounds[(query, "bare jit")]
                )
                print(
                    f"| {name} | {np.dtype(dtype).name} | {query} | "
                    + " | ".join(cells)
                    + f" | {ratio:.2f} | {load:.1f} |",
                    flush=True,
                )


if __name__ == "__main__":
    main()
