"""Delta robot throughput (float64): ik, fk (Newton, cold and warm start), fk_closed_form.

Each jaxkin kernel is timed beside a reference on the same inputs (``reference_delta.py``):
NumPy vectorised closed-form IK and three-sphere FK, a NumPy fixed-iteration Newton, and a fused
Numba Newton (8 iterations; skipped without numba). Compilation and warm-up happen outside the
timer (``measure`` fixture); ``extra_info`` records cases/s and the max error.

Run one size only with e.g. ``pytest benchmarks/test_delta.py -k 1000 --benchmark-only``.
"""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import tests.references.delta as ref
from jaxkin import _batching, delta

SIZES = [1_000, 100_000, 1_000_000]
ROBOT = delta.Delta.paper()


def workspace_points(n: int, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    r = 15.0 * np.sqrt(rng.uniform(size=n))
    a = rng.uniform(0, 2 * np.pi, n)
    return np.stack([r * np.cos(a), r * np.sin(a), rng.uniform(-40.0, -20.0, n)], -1)


def trajectory(n: int) -> np.ndarray:
    """n samples of smooth motion at 1 kHz (a 10 cm circle at 1 m/s, with a vertical wave)."""
    t = np.arange(n + 1) * 1e-3
    return np.stack([10 * np.cos(10 * t), 10 * np.sin(10 * t), -30.0 + 3.0 * np.sin(3 * t)], -1)


_cache: dict[int, tuple[np.ndarray, np.ndarray]] = {}


def data(n: int) -> tuple[np.ndarray, np.ndarray]:
    if n not in _cache:
        p = workspace_points(n)
        _cache[n] = (p, ref.ik_numpy(p))
    return _cache[n]


@pytest.mark.parametrize("n", SIZES)
def test_ik_jaxkin(measure, n):
    p, theta = data(n)
    p_dev = jnp.asarray(p)
    result = measure(lambda: delta.ik(ROBOT, p_dev).q.p, n, kernel="delta.ik", dtype="float64")
    assert np.abs(np.asarray(result) - theta).max() < 1e-9


@pytest.mark.parametrize("n", SIZES)
def test_ik_numpy(measure, n):
    p, theta = data(n)
    result = measure(lambda: ref.ik_numpy(p), n, kernel="numpy ik", dtype="float64")
    assert np.abs(result - theta).max() < 1e-9


@pytest.mark.parametrize("n", SIZES)
def test_fk_cold_jaxkin(measure, n):
    p, theta = data(n)
    theta_dev = jnp.asarray(theta)
    fk = delta.fk(ROBOT, theta_dev)
    iterations = np.asarray(fk.iterations)
    result = measure(
        lambda: delta.fk(ROBOT, theta_dev).x.p,
        n,
        kernel="delta.fk (default guess)",
        dtype="float64",
        max_iterations=int(iterations.max()),
        mean_iterations=float(iterations.mean()),
    )
    assert np.abs(np.asarray(result) - p).max() < 1e-9


@pytest.mark.parametrize("n", SIZES)
def test_fk_cold_jaxkin_one_thread(measure, n):
    """The same kernel, never split across host threads (``jaxkin._batching``): the gain."""
    p, theta = data(n)
    theta_dev = jnp.asarray(theta)
    _batching.set_num_threads(1)
    try:
        result = measure(
            lambda: delta.fk(ROBOT, theta_dev).x.p,
            n,
            kernel="delta.fk (default guess, one host thread)",
            dtype="float64",
        )
    finally:
        _batching.set_num_threads(None)
    assert np.abs(np.asarray(result) - p).max() < 1e-9


@pytest.mark.parametrize("n", SIZES)
def test_fk_warm_jaxkin(measure, n):
    path = trajectory(n)
    theta = jnp.asarray(ref.ik_numpy(path[1:]))
    guess = jnp.asarray(path[:-1])  # the previous sample
    fk = delta.fk(ROBOT, theta, guess=guess)
    iterations = np.asarray(fk.iterations)
    assert iterations.max() <= 3
    result = measure(
        lambda: delta.fk(ROBOT, theta, guess=guess).x.p,
        n,
        kernel="delta.fk (warm start)",
        dtype="float64",
        max_iterations=int(iterations.max()),
    )
    assert np.abs(np.asarray(result) - path[1:]).max() < 1e-9


@pytest.mark.parametrize("n", SIZES)
def test_fk_newton_numpy(measure, n):
    p, theta = data(n)
    result = measure(lambda: ref.fk_newton_numpy(theta, iterations=8), n, kernel="numpy newton x8")
    assert np.abs(result - p).max() < 1e-9


@pytest.mark.parametrize("n", SIZES)
def test_fk_newton_numba(measure, n):
    pytest.importorskip("numba")
    p, theta = data(n)
    fk = ref.make_numba_fk_newton()
    result = measure(lambda: fk(theta), n, kernel="numba newton x8 (prange)")
    assert np.abs(result - p).max() < 1e-9


@pytest.mark.parametrize("n", SIZES)
def test_fk_closed_form_jaxkin(measure, n):
    p, theta = data(n)
    theta_dev = jnp.asarray(theta)
    result = measure(
        lambda: delta.fk_closed_form(ROBOT, theta_dev).x, n, kernel="delta.fk_closed_form"
    )
    assert np.abs(np.asarray(result) - p).max() < 1e-9


@pytest.mark.parametrize("n", SIZES)
def test_fk_closed_form_numpy(measure, n):
    p, theta = data(n)
    result = measure(lambda: ref.fk_closed_form_numpy(theta), n, kernel="numpy closed form")
    assert np.abs(result - p).max() < 1e-9


def test_ratio_summary_1e5(benchmark):
    """One-run ratios at 1e5 (printed; the per-kernel rows above are the measurements)."""
    n = 100_000
    p, theta = data(n)
    theta_dev = jnp.asarray(theta)
    p_dev = jnp.asarray(p)

    def best(fn, rounds=5):
        jax.block_until_ready(fn())
        times = []
        for _ in range(rounds):
            start = __import__("time").perf_counter()
            jax.block_until_ready(fn())
            times.append(__import__("time").perf_counter() - start)
        return n / min(times)

    rows = {
        "ik jaxkin": best(lambda: delta.ik(ROBOT, p_dev).q.p),
        "ik numpy": best(lambda: ref.ik_numpy(p)),
        "fk jaxkin": best(lambda: delta.fk(ROBOT, theta_dev).x.p),
        "fk numpy newton x8": best(lambda: ref.fk_newton_numpy(theta)),
        "fk_closed_form jaxkin": best(lambda: delta.fk_closed_form(ROBOT, theta_dev).x),
        "fk_closed_form numpy": best(lambda: ref.fk_closed_form_numpy(theta)),
    }
    benchmark.extra_info.update({k: v for k, v in rows.items() if math.isfinite(v)})
    benchmark.pedantic(lambda: None, rounds=1, iterations=1)
    for name, rate in rows.items():
        print(f"{name:24s} {rate / 1e6:8.2f} M cases/s")
