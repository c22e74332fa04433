"""Throughput against batch size (1 to 4e6) for the public kernels, and first-call time.

Batch 1 and 100 measure the per-call latency (dispatch and host-side checks); large batches
the throughput. ``test_compile_time`` clears JAX's caches and times the first call (trace +
compile + run) of each kernel at batch 1000. Float64, positions with velocities and
accelerations where the kernel returns them.
"""

import time

import jax
import numpy as np
import pytest

from jaxkin import Jet, delta, dyad, scara
from jaxkin.serial import arms

SIZES = [1, 100, 10_000, 1_000_000, 4_000_000]


def _jet(rng, n, center, spread):
    return Jet.of(
        *(center * (k == 0) + rng.normal(scale=spread, size=(n, len(center))) for k in range(3))
    )


def _kernels():
    """name -> (make inputs for batch n, call)."""
    scara_robot = scara.Scara.create(150.0, 80.0, 50.0)
    delta_robot = delta.Delta.paper()
    arm = arms.Anthropomorphic(0.3, 0.25, 0.2)
    rng = np.random.default_rng(0)
    return {
        "dyad.solve": (
            lambda n: (_jet(rng, n, np.zeros(2), 0.2), _jet(rng, n, np.array([1.5, 0.2]), 0.2)),
            lambda a, b: dyad.solve(a, b, 1.2, 0.9),
        ),
        "dyad.position": (
            lambda n: (
                rng.normal(scale=0.2, size=(n, 2)),
                rng.normal(scale=0.2, size=(n, 2)) + [1.5, 0.2],
            ),
            lambda a, b: dyad.position(a, b, 1.2, 0.9),
        ),
        "scara.ik": (
            lambda n: (_jet(rng, n, np.array([90.0, 20.0, 60.0]), 10.0),),
            lambda d: scara.ik(scara_robot, d),
        ),
        "delta.ik": (
            lambda n: (_jet(rng, n, np.array([0.0, 0.0, -30.0]), 3.0),),
            lambda p: delta.ik(delta_robot, p),
        ),
        "delta.fk": (
            lambda n: (rng.normal(scale=0.2, size=(n, 3)) + 0.3,),
            lambda theta: delta.fk(delta_robot, theta),
        ),
        "delta.fk_closed_form": (
            lambda n: (rng.normal(scale=0.2, size=(n, 3)) + 0.3,),
            lambda theta: delta.fk_closed_form(delta_robot, theta),
        ),
        "serial.ik_all_branches[anthropomorphic]": (
            lambda n: (rng.normal(scale=0.05, size=(n, 3)) + [0.25, 0.1, 0.35],),
            lambda target: arms.ik_all_branches(arm, target),
        ),
        "serial.fk[anthropomorphic]": (
            lambda n: (rng.normal(size=(n, 3)),),
            lambda q: arms.fk(arm, q),
        ),
    }


KERNELS = list(_kernels())


@pytest.mark.parametrize("n", SIZES)
@pytest.mark.parametrize("name", KERNELS)
def test_scaling(measure, name, n):
    make, call = _kernels()[name]
    args = make(n)
    measure(lambda: call(*args), n, kernel=name, dtype="float64", rounds=20 if n <= 10_000 else 3)


@pytest.mark.parametrize("name", KERNELS)
def test_compile_time(benchmark, name):
    make, call = _kernels()[name]
    args = make(1000)
    jax.clear_caches()
    start = time.perf_counter()
    jax.block_until_ready(call(*args))
    first = time.perf_counter() - start
    start = time.perf_counter()
    jax.block_until_ready(call(*args))
    steady = time.perf_counter() - start
    benchmark.extra_info.update(kernel=name, dtype="float64", compile_seconds=first - steady)
    benchmark.pedantic(lambda: None, rounds=1)
    assert first > steady
