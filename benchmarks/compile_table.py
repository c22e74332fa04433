"""Compile time of the collision checks against joints, primitives and obstacles (a script).

Each row compiles ``collision.collides`` (the verdict) and ``collision.check`` (clearance and
pairs) of one configuration and of a batch of 1,024 (with the checks' XLA options) for a
serial chain of ``n`` revolute joints (random screws, links about 0.3 long), ``k`` spheres
spread over its links with their self pairs (links two or more apart), and a world of ``m``
spheres and ``m`` boxes, float32, JAX's persistent cache off; seconds of
``lower().compile()``, wall / process CPU time (the latter moves less with the machine's
load), in a process of its own per row, so no row reuses another's programs.
Prints a Markdown table
(``docs/performance.md``, "Compile time against size")::

    .venv/bin/python benchmarks/compile_table.py            # every row
    .venv/bin/python benchmarks/compile_table.py 7 60 10    # one row: joints spheres obstacles
"""

from __future__ import annotations

import os
import subprocess
import sys
import time

ROWS = [
    (3, 60, 10),
    (6, 60, 10),
    (7, 60, 10),
    (12, 60, 10),
    (7, 200, 10),
    (7, 400, 10),
    (7, 60, 100),
    (7, 400, 100),
]


def _row(joints: int, spheres: int, obstacles: int) -> str:
    import jax
    import jax.numpy as jnp
    import numpy as np

    from jaxkin import collision, serial

    try:
        from jaxkin.collision.rows import COMPILER_OPTIONS
    except ImportError:  # a checkout from before the rows layout, for comparison
        COMPILER_OPTIONS = ()

    rng = np.random.default_rng(joints * 1000 + spheres + obstacles)
    axes = rng.normal(size=(joints, 3))
    axes /= np.linalg.norm(axes, axis=1, keepdims=True)
    points = np.cumsum(rng.normal(scale=0.3, size=(joints, 3)), axis=0)
    screws = np.concatenate([axes, -np.cross(axes, points)], axis=1)
    home = np.eye(4)
    home[:3, 3] = points[-1] + 0.2
    chain = serial.from_screws(screws, home)
    body = chain.collision_body()
    names = body.links
    per_link = np.array_split(np.arange(spheres), len(names))
    chain = chain.with_link_spheres(
        {
            name: (rng.normal(scale=0.05, size=(len(ids), 3)), np.full(len(ids), 0.03))
            for name, ids in zip(names, per_link, strict=True)
            if len(ids)
        }
    )
    body, pairs = collision.prepare(chain)
    world = collision.World.create(
        spheres=collision.Spheres.create(
            rng.uniform(-1, 1, (obstacles, 3)), rng.uniform(0.02, 0.1, obstacles)
        ),
        boxes=collision.Boxes.create(
            rng.uniform(-1, 1, (obstacles, 3)), rng.uniform(0.02, 0.1, (obstacles, 3))
        ),
        dtype=np.float32,
    )
    cells = []
    for kernel in (collision.collides_kernel, collision.check_kernel):
        for batch in (1, 1024):
            q = jnp.zeros((batch, joints), jnp.float32)
            fn = jax.jit(
                lambda q, w, kernel=kernel: kernel(chain, body, pairs, q, w, 0.0),
                compiler_options=dict(COMPILER_OPTIONS),
            )
            start, cpu = time.perf_counter(), time.process_time()
            fn.lower(q, world).compile()
            cells.append(f"{time.perf_counter() - start:.2f} / {time.process_time() - cpu:.2f}")
    load = os.getloadavg()[0]
    prims = f"{body.num_spheres} spheres, {pairs.num_primitive_pairs} self pairs"
    return f"| {joints} | {prims} | {2 * obstacles} | " + " | ".join(cells) + f" | {load:.1f} |"


def main(argv: list[str]) -> None:
    if len(argv) == 4 and argv[0] == "--row":
        print(_row(*(int(x) for x in argv[1:])), flush=True)
        return
    rows = [tuple(int(x) for x in argv)] if len(argv) == 3 else ROWS
    print(
        "| joints | body | obstacles | collides (1) s | collides (1024) s | check (1) s | "
        "check (1024) s | load (1 min) |"
    )
    print("| --- | --- | --- | --- | --- | --- | --- | --- |")
    env = {k: v for k, v in os.environ.items() if not k.startswith("JAX_COMPILATION_CACHE")}
    env["JAX_ENABLE_X64"] = "0"
    for row in rows:
        out = subprocess.run(
            [sys.executable, __file__, "--row", *map(str, row)],
            env=env,
            capture_output=True,
            text=True,
        )
        print(out.stdout.strip() or f"| {row} | failed: {out.stderr.strip()[-300:]} |", flush=True)


if __name__ == "__main__":
    main(sys.argv[1:])
