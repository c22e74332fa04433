"""The chain IK's first call and compiled program, and its results on fixed poses.

Run each mode in a fresh process with ``JAXKIN_COMPILATION_CACHE=0``:

* ``python benchmarks/chain_ik_compile.py time [ROBOT]``: the first ``jaxkin.ik`` of one
  target of ``ROBOT`` (``panda`` or ``ur5``; wall and process CPU time), then the block program
  of ``serial.search.solve`` lowered and compiled alone with ``search.COMPILER_OPTIONS`` (as
  the library does; seconds, and the counts of operations, fusions and loops of its optimised
  HLO);
* ``... dump FILE``: statuses and joints of fixed Panda and UR5 poses (``.npz``);
* ``... compare OLD NEW``: statuses equal and joints within ``1e-12`` of each joint's range;
* ``... throughput N``: ``jaxkin.ik`` of ``N`` Panda poses per second, three calls after a
  warm one, the chain IK compiled with ``search.COMPILER_OPTIONS`` and with XLA's defaults
  interleaved in one process.
"""

from __future__ import annotations

import importlib.metadata
import os
import sys
import time

import numpy as np

os.environ.setdefault("JAXKIN_COMPILATION_CACHE", "0")

ROBOTS = importlib.metadata.distribution("example-robot-data").locate_file(
    "cmeel.prefix/share/example-robot-data/robots"
)
CHAINS = {
    "panda": ("panda_description/urdf/panda.urdf", "panda_hand"),
    "ur5": ("ur_description/urdf/ur5_robot.urdf", "tool0"),
}


def load(name):
    from jaxkin import serial

    urdf, tip = CHAINS[name]
    return serial.from_urdf(str(ROBOTS / urdf), tip)


def poses(chain, n=48, seed=0):
    """``n`` poses from joints uniform within the limits, one beyond reach, one NaN."""
    import jaxkin

    lower = np.where(np.isfinite(chain.lower), chain.lower, -np.pi)
    upper = np.where(np.isfinite(chain.upper), chain.upper, np.pi)
    q = np.random.default_rng(seed).uniform(lower, upper, (n, chain.n_joints))
    targets = np.array(jaxkin.fk(chain, q).x.p)
    if n > 2:
        targets[-2, :3, 3] *= 100.0
        targets[-1, 0, 0] = np.nan
    return targets


def time_first() -> None:
    import jax

    jax.config.update("jax_enable_x64", True)
    import jaxkin
    from jaxkin.jet import Jet
    from jaxkin.serial import search

    name = sys.argv[2] if len(sys.argv) > 2 else "panda"
    chain = load(name)
    target = poses(chain, 1)[0]
    start, cpu = time.perf_counter(), time.process_time()
    res = jaxkin.ik(chain, target)
    res.status.block_until_ready()
    first = time.perf_counter() - start, time.process_time() - cpu
    print(f"first jaxkin.ik (1 {name} target): {first[0]:.2f} s wall, {first[1]:.2f} s CPU")

    options = chain.IKOptions()
    tols = (np.float64(1e-10), np.float64(1e-10 * float(chain.length_scale())))
    budget = search.Budget(options.max_iter, options.restarts, options.max_iter)
    block = np.broadcast_to(target, (search.BLOCK, 4, 4))
    jet = Jet(block, np.zeros_like(block), np.zeros_like(block))

    def kernel(chain, jet, tols):
        return search.solve(chain, jet, tols, budget, True, True)

    start = time.perf_counter()
    lowered = jax.jit(kernel).lower(chain, jet, tols)
    traced = time.perf_counter() - start
    start, cpu = time.perf_counter(), time.process_time()
    compiled = lowered.compile(compiler_options=dict(getattr(search, "COMPILER_OPTIONS", ())))
    seconds, cpu = time.perf_counter() - start, time.process_time() - cpu
    text = compiled.as_text()
    if len(sys.argv) > 3:  # keep the optimised HLO for inspection
        with open(sys.argv[3], "w") as file:
            file.write(text)
    ops = sum(1 for line in text.splitlines() if " = " in line)
    fusions = sum(1 for line in text.splitlines() if " fusion(" in line)
    loops = sum(1 for line in text.splitlines() if " while(" in line)
    print(
        f"block program ({search.BLOCK} targets): trace+lower {traced:.2f} s, "
        f"compile {seconds:.2f} s ({cpu:.2f} s CPU), "
        f"optimised HLO {len(text.splitlines())} lines, {ops} ops, {fusions} fusions, "
        f"{loops} while loops"
    )
    print(f"load average: {os.getloadavg()}")


def throughput(n: int) -> None:
    import dataclasses

    import jax

    jax.config.update("jax_enable_x64", True)
    import jaxkin
    from jaxkin._execute import pipeline
    from jaxkin.serial import Chain

    chain = load("panda")
    targets = poses(chain, n + 2, seed=1)[:n]  # within reach
    tuned = Chain.ik_policy
    policies = {"library": tuned}
    if getattr(tuned, "compiler_options", ()):
        policies["XLA defaults"] = dataclasses.replace(tuned, compiler_options=())
    programs = {}
    for name, policy in policies.items():  # compile each once
        Chain.ik_policy, pipeline._PROGRAMS = policy, {}
        jaxkin.ik(chain, targets).status.block_until_ready()
        programs[name] = pipeline._PROGRAMS
    rates: dict[str, list[float]] = {name: [] for name in policies}
    for _ in range(3):
        for name, policy in policies.items():
            Chain.ik_policy, pipeline._PROGRAMS = policy, programs[name]
            start = time.perf_counter()
            jaxkin.ik(chain, targets).status.block_until_ready()
            rates[name].append(n / (time.perf_counter() - start))
    Chain.ik_policy = tuned
    for name, values in rates.items():
        print(f"{name}: {', '.join(f'{v:.0f}' for v in values)} poses/s")
    print(f"load average: {os.getloadavg()}")


def dump(path: str) -> None:
    import jax

    jax.config.update("jax_enable_x64", True)
    import jaxkin

    out = {}
    for name in CHAINS:
        chain = load(name)
        res = jaxkin.ik(chain, poses(chain))
        out[f"{name}_status"] = np.asarray(res.status)
        out[f"{name}_q"] = np.asarray(res.q.p)
        out[f"{name}_margin"] = np.asarray(res.margin)
        out[f"{name}_range"] = np.asarray(
            np.where(np.isfinite(chain.upper - chain.lower), chain.upper - chain.lower, 2 * np.pi)
        )
    np.savez(path, **out)


def compare(old: str, new: str) -> int:
    a, b = np.load(old), np.load(new)
    bad = 0
    for name in CHAINS:
        same = np.array_equal(a[f"{name}_status"], b[f"{name}_status"])
        diff = np.abs(a[f"{name}_q"] - b[f"{name}_q"]) / a[f"{name}_range"]
        worst = float(np.max(diff))
        margin = float(np.max(np.abs(a[f"{name}_margin"] - b[f"{name}_margin"])))
        print(
            f"{name}: {a[f'{name}_status'].size} poses, statuses equal {same}, "
            f"max |dq| / range {worst:.2e}, max |margin difference| {margin:.2e}"
        )
        bad += (not same) or not worst <= 1e-12
    return bad


if __name__ == "__main__":
    mode = sys.argv[1]
    if mode == "time":
        time_first()
    elif mode == "throughput":
        throughput(int(sys.argv[2]))
    elif mode == "dump":
        dump(sys.argv[2])
    else:
        sys.exit(compare(sys.argv[2], sys.argv[3]))
