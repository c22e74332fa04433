"""Single-query latency: one configuration through ``jaxkin.fk`` and one target through
``jaxkin.ik``, per robot kind, float64, after compilation.

The shape a planner asks between batches (an OMPL-style validity checker asks one state at a
time). The time is the whole call from Python, returned values ready; the goal for the FK of a
7-joint chain (the Franka Panda from example-robot-data, ``serial.from_urdf``) and the IK of a
SCARA target is 30 us each on a 2-core CPU. A plain ``jax.jit`` of an identity on one small
array is measured beside them as the floor of any JAX call. The warm-up rounds run the robot's
hot single query (``jaxkin.robot``: built at the ``_batching.HOT_AFTER``-th call of one robot
object), so the timed rounds measure it where the robot has one. Each row records the median
wall time, the median CPU time of the calling thread over 2,000 more calls (``cpu_median_us``:
on a shared machine the wall time's median counts calls that waited for a core) and the
1-minute load average.
"""

from __future__ import annotations

import importlib.metadata
import os
import time

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxkin
from jaxkin import delta, scara, serial


def _panda():
    robots = importlib.metadata.distribution("example-robot-data").locate_file(
        "cmeel.prefix/share/example-robot-data/robots"
    )
    return serial.from_urdf(str(robots / "panda_description/urdf/panda.urdf"), "panda_hand")


ROBOTS = {
    "scara": (scara.Scara.paper, np.array([0.3, 1.2, 40.0])),
    "delta": (delta.Delta.paper, np.array([0.4, 0.5, 0.6])),
    "anthropomorphic": (lambda: serial.Anthropomorphic(0.3, 0.25, 0.2), np.full(3, 0.5)),
    "puma560": (serial.Puma560, np.full(6, 0.3)),
    "panda": (_panda, np.array([0.1, -0.3, 0.2, -1.8, 0.1, 1.6, 0.4])),
}


def _latency(benchmark, fn, **info):
    jax.block_until_ready(fn())  # compile and warm up outside the timer
    benchmark.pedantic(
        lambda: jax.block_until_ready(fn()), rounds=2000, iterations=1, warmup_rounds=50
    )
    benchmark.extra_info.update(info, n_cases=1, dtype="float64")
    benchmark.extra_info["median_us"] = benchmark.stats.stats.median * 1e6
    benchmark.extra_info["cpu_median_us"] = _cpu_median(fn) * 1e6
    benchmark.extra_info["load_1min"] = os.getloadavg()[0]


def _cpu_median(fn, calls: int = 2000) -> float:
    """Median thread CPU time of one call (s): on a shared machine the wall time's median
    counts the calls that waited for a core; the calling thread's CPU time does not (the
    programs timed here run on it)."""
    times = []
    for _ in range(calls):
        start = time.thread_time_ns()
        jax.block_until_ready(fn())
        times.append(time.thread_time_ns() - start)
    return float(np.median(times)) * 1e-9


@pytest.mark.parametrize("name", list(ROBOTS))
def test_single_fk(benchmark, name):
    make, q = ROBOTS[name]
    robot = make()
    q = jnp.asarray(q)
    _latency(benchmark, lambda: jaxkin.fk(robot, q), kernel=f"fk[{name}] x1")


@pytest.mark.parametrize("name", list(ROBOTS))
def test_single_ik(benchmark, name):
    make, q = ROBOTS[name]
    robot = make()
    target = jaxkin.fk(robot, jnp.asarray(q)).x.p
    _latency(benchmark, lambda: jaxkin.ik(robot, target), kernel=f"ik[{name}] x1")


def test_single_ik_unreachable_scara(benchmark):
    """A target outside the SCARA's annulus: the same program and outputs as a reachable one
    (statuses and placeholders are data), so the same time."""
    robot = scara.Scara.paper()
    target = jnp.asarray([500.0, 0.0, 40.0])
    assert int(jaxkin.ik(robot, target).status) == int(jaxkin.Status.UNREACHABLE)
    _latency(benchmark, lambda: jaxkin.ik(robot, target), kernel="ik[scara, unreachable] x1")


def test_bare_jit_floor(benchmark):
    identity = jax.jit(lambda x: x + 0.0)
    x = jnp.zeros(3)
    _latency(benchmark, lambda: identity(x), kernel="jax.jit identity x1")
