"""The "Latency" table of docs/performance.md: one fresh process per robot and call.

    python benchmarks/latency_table.py [ROBOT:CALL ...]      (default: every row)
    python benchmarks/latency_table.py --parts ROBOT:CALL   (where one hot query's time goes)

Each row runs in its own Python process (float64, no persistent compilation cache): the first
call is a batch of 5 (trace and compile), then a batch of 7 (a new batch size), then the first
single query (its own program), then 2,000 single queries from a JAX array (median and 10th
percentile; the hot program of ``jaxkin.robot`` is built during the first of them and its
build time reported apart). The load average is printed with every row.

``--parts`` times, in one process and in interleaved rounds of 1,000 calls (the lowest and the
middle of the rounds' medians: on a shared machine a round can be slowed as a whole), the hot
single query taken apart: the whole call as the benchmark times it (``jax.block_until_ready``
of ``jaxkin.ik``'s result), the call without the block, the hot program without ``jaxkin.ik``'s
lookup, its compiled executable alone (with and without the block), and two floors: a program
with the same outputs (shapes and dtypes) computed trivially, and one with a single output.
For the SCARA's IK, a reachable and an unreachable target.
"""

from __future__ import annotations

import os
import subprocess
import sys
import time

ROWS = (
    "scara:ik",
    "scara:fk",
    "delta:ik",
    "delta:fk",
    "puma560:ik",
    "puma560:fk",
    "panda:ik",
    "panda:fk",
)


def _robot(name: str):
    import importlib.metadata

    import numpy as np

    from jaxkin import delta, scara, serial

    if name == "scara":
        return scara.Scara.paper(), np.array([0.3, 1.2, 40.0])
    if name == "delta":
        return delta.Delta.paper(), np.array([0.4, 0.5, 0.6])
    if name == "puma560":
        return serial.Puma560(), np.full(6, 0.3)
    robots = importlib.metadata.distribution("example-robot-data").locate_file(
        "cmeel.prefix/share/example-robot-data/robots"
    )
    urdf = robots / "panda_description/urdf/panda.urdf"
    return serial.from_urdf(str(urdf), "panda_hand"), np.array(
        [0.1, -0.3, 0.2, -1.8, 0.1, 1.6, 0.4]
    )


def _row(spec: str) -> str:
    """One row, measured in this process."""
    import jax

    jax.config.update("jax_enable_x64", True)
    import jax.numpy as jnp
    import numpy as np

    import jaxkin
    from jaxkin import _batching
    from jaxkin._execute import pipeline

    name, call = spec.split(":")
    robot, q = _robot(name)
    if call == "ik":
        inputs = np.asarray(jaxkin.fk(robot, q[None] + 0.01 * np.arange(7)[:, None]).x.p)
        run = lambda x: jaxkin.ik(robot, x)  # noqa: E731
    else:
        inputs = q[None] + 0.01 * np.arange(7)[:, None]
        run = lambda x: jaxkin.fk(robot, x)  # noqa: E731

    def timed(x):
        start = time.perf_counter()
        jax.block_until_ready(run(x))
        return time.perf_counter() - start

    first = timed(inputs[:5])
    new_size = timed(inputs[:7])
    one = jnp.asarray(inputs[0])
    first_single = timed(one)
    times = [timed(one) for _ in range(_batching.HOT_AFTER + 1)]
    hot = any(program is not None for _, program in pipeline.HOT.programs.values())
    build = f"{max(times):.2f}" if hot else "-"  # the build is in the HOT_AFTER-th call
    times = [timed(one) for _ in range(2000)]
    load = os.getloadavg()[0]
    return (
        f"| {name} | {call} | {first:.2f} | {new_size * 1e3:.1f} | {first_single:.2f} | "
        f"{build} | {np.median(times) * 1e6:.0f} | {np.percentile(times, 10) * 1e6:.0f} | "
        f"{load:.1f} |"
    )


def _parts(spec: str) -> None:
    """Prints where one hot single query's time goes (see the module's docstring)."""
    import statistics

    import jax

    jax.config.update("jax_enable_x64", True)
    import jax.numpy as jnp
    import numpy as np

    import jaxkin
    from jaxkin import _batching
    from jaxkin._execute import pipeline

    name, call = spec.split(":")
    robot, q = _robot(name)
    run = jaxkin.ik if call == "ik" else jaxkin.fk
    inputs = {"": jnp.asarray(q)}
    if call == "ik":
        inputs = {"reachable": jaxkin.fk(robot, jnp.asarray(q)).x.p}
        if name == "scara":
            inputs["unreachable"] = jnp.asarray([500.0, 0.0, 40.0])
    block = jax.block_until_ready
    timed = {}
    for label, x in inputs.items():
        for _ in range(_batching.HOT_AFTER + 1):
            result = run(robot, x)
        program = next((p for owner, p in pipeline.HOT.programs.values() if owner is robot), None)
        if program is None:
            print(f"{spec}: no hot program")
            return
        statuses = np.asarray(result.status).ravel().tolist()
        compiled = program.compiled
        tag = f"{label} " if label else ""
        timed[f"{tag}whole call, blocked (the benchmark)"] = lambda x=x: block(run(robot, x))
        timed[f"{tag}whole call"] = lambda x=x: run(robot, x)
        timed[f"{tag}hot program (no lookup)"] = lambda x=x, p=program: p(x)
        timed[f"{tag}executable alone"] = lambda x=x, c=compiled: c(x)
        timed[f"{tag}executable alone, blocked"] = lambda x=x, c=compiled: block(c(x))
        print(f"{tag}status {statuses}", flush=True)
    x = next(iter(inputs.values()))
    outs = [jax.ShapeDtypeStruct(o.shape, o.dtype) for o in compiled(x)]
    trivial = (
        jax.jit(lambda y: [jnp.broadcast_to(y.ravel()[0], o.shape).astype(o.dtype) for o in outs])
        .lower(x)
        .compile()
    )
    single = jax.jit(lambda y: y + 0.0).lower(x).compile()
    timed[f"floor: {len(outs)} trivial outputs, blocked"] = lambda: block(trivial(x))
    timed["floor: 1 output, blocked"] = lambda: block(single(x))
    for fn in timed.values():
        for _ in range(200):
            fn()
    medians = {label: [] for label in timed}
    for _ in range(7):
        for label, fn in timed.items():
            times = []
            for _ in range(1000):
                start = time.perf_counter_ns()
                fn()
                times.append(time.perf_counter_ns() - start)
            medians[label].append(statistics.median(times) / 1e3)
    print(f"{spec}, float64, median us of 1,000 calls, lowest and middle of 7 rounds")
    for label, values in medians.items():
        print(f"  {label:48s} {min(values):6.1f} {statistics.median(values):6.1f}")
    print(f"  load average (1 min): {os.getloadavg()[0]:.1f}")


def main(argv: list[str]) -> None:
    if len(argv) == 2 and argv[0] == "--row":
        print(_row(argv[1]), flush=True)
        return
    if len(argv) == 2 and argv[0] == "--parts":
        _parts(argv[1])
        return
    print(
        "| robot | call | first call (s) | new batch size (ms) | first single query (s) | "
        "hot build (s) | single query median (us) | 10th percentile (us) | load (1 min) |"
    )
    print("| --- | --- | --- | --- | --- | --- | --- | --- | --- |")
    env = {**os.environ, "JAX_COMPILATION_CACHE_DIR": ""}
    for spec in argv or ROWS:
        out = subprocess.run(
            [sys.executable, __file__, "--row", spec], env=env, capture_output=True, text=True
        )
        print(out.stdout.strip() or f"| {spec} | failed: {out.stderr.strip()[-200:]} |", flush=True)


if __name__ == "__main__":
    main(sys.argv[1:])
