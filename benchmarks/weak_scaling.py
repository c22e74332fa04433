"""Weak scaling of ``plan.evaluate`` over processes joined by ``jax.distributed`` (CPU).

``python benchmarks/weak_scaling.py [--candidates-per-process N] [--processes 1 2]`` launches,
for each process count P, P processes on this machine (loopback, a free port, gloo
collectives), each pinned to its own core (``taskset``) with one host thread for jaxkin and
XLA. Every process calls ``plan.evaluate`` on the same global batch of P x N SCARA candidates
(100 samples each, ``branch="best"``) and then ``plan.best``; the batch is split over the
processes, so each process evaluates N candidates whatever P is (weak scaling). Reported per P:
the median wall time of 5 timed calls after one warm-up call, and candidates per second per
process and in all. Ideal weak scaling keeps the per-process rate constant.

Run it where the cores are otherwise idle; ``docs/scaling.md`` records a run.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import socket
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
T, DT, CALLS = 100, 0.02, 5


def _worker(n_per_process: int) -> None:
    """One process: join, evaluate the global batch, print timings as JSON (process 0)."""
    import jax

    jax.config.update("jax_enable_x64", True)
    jax.config.update("jax_cpu_collectives_implementation", "gloo")
    jax.distributed.initialize(
        os.environ["JAX_COORDINATOR_ADDRESS"],
        num_processes=int(os.environ["JAX_NUM_PROCESSES"]),
        process_id=int(os.environ["JAX_PROCESS_ID"]),
    )
    import numpy as np

    from jaxkin import _batching, paths, plan, scara

    _batching.set_num_threads(1)
    robot = scara.Scara.paper()
    total = n_per_process * jax.process_count()
    s = np.linspace(0.0, 1.0, T)[None, :, None]
    offsets = np.random.default_rng(0).normal(scale=20.0, size=(total, 1, 3)) * [1, 1, 0]
    start, goal = np.array([110.0, -50.0, 40.0]), np.array([-20.0, 100.0, 80.0])
    path = paths.path_from_samples(start + s * (goal - start) + np.sin(np.pi * s) * offsets, DT)
    times = []
    for _ in range(CALLS + 1):
        began = time.perf_counter()
        ev = plan.evaluate(robot, path, branch="best", dt=DT)
        jax.block_until_ready(ev.costs.total)
        indices, _ = plan.best(ev, 5)
        times.append(time.perf_counter() - began)
    if jax.process_index() == 0:
        seconds = float(np.median(times[1:]))
        report = dict(processes=jax.process_count(), candidates=total, seconds=seconds)
        print(json.dumps({**report, "best": indices.tolist()}))


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _launch(processes: int, n_per_process: int) -> dict:
    env = {k: v for k, v in os.environ.items() if not k.startswith(("JAX_", "XLA_"))}
    env.update(
        JAX_COORDINATOR_ADDRESS=f"127.0.0.1:{_free_port()}",
        JAX_NUM_PROCESSES=str(processes),
        JAX_PLATFORMS="cpu",
        XLA_FLAGS="--xla_cpu_multi_thread_eigen=false intra_op_parallelism_threads=1",
    )
    pin = shutil.which("taskset")
    procs = []
    for i in range(processes):
        command = [sys.executable, __file__, "--worker", str(n_per_process)]
        if pin:
            command = [pin, "-c", str(i % os.cpu_count()), *command]
        procs.append(
            subprocess.Popen(
                command, cwd=ROOT, env={**env, "JAX_PROCESS_ID": str(i)}, stdout=subprocess.PIPE
            )
        )
    outputs = [p.communicate(timeout=900)[0] for p in procs]
    if any(p.returncode for p in procs):
        raise SystemExit(f"a worker failed: {[p.returncode for p in procs]}")
    return json.loads(outputs[0].decode().strip().splitlines()[-1])


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--worker", type=int, help=argparse.SUPPRESS)
    parser.add_argument("--candidates-per-process", type=int, default=4096)
    parser.add_argument("--processes", type=int, nargs="+", default=[1, 2])
    args = parser.parse_args(argv)
    if args.worker is not None:
        _worker(args.worker)
        return 0
    rows = []
    for p in args.processes:
        result = _launch(p, args.candidates_per_process)
        rate = result["candidates"] / result["seconds"]
        rows.append((p, result["candidates"], result["seconds"], rate, rate / p))
    print(
        "| processes | candidates (x 100 samples) | seconds per call | candidates/s | per process |"
    )
    print("| --- | --- | --- | --- | --- |")
    for p, n, sec, rate, per in rows:
        print(f"| {p} | {n} | {sec:.3f} | {rate:,.0f} | {per:,.0f} |")
    if len(rows) > 1:
        print(
            f"\nweak-scaling efficiency at {rows[-1][0]} processes: {rows[-1][4] / rows[0][4]:.2f}"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
