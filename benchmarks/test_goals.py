"""The goal ratios, measured as they are judged: one process, rounds interleaved.

jaxkin's dyad (analytic and autodiff paths) and Delta FK (Newton and closed form) run beside
the fused Numba and NumPy references on the same float64 inputs at batch 1e6; each round calls
every contender once, in turn, and each keeps its best round. The per-kernel rows of the other
files time one kernel at a time, so machine load and the allocator's state (page faults, see
README "Variance and page faults") can differ between a kernel and its reference; here they
hit every contender alike. Skipped without numba (``pip install -e '.[bench]'``).
"""

from __future__ import annotations

import time

import jax
import jax.numpy as jnp
import pytest
from test_delta import ROBOT, data

import tests.references.delta as ref_delta
from jaxkin import Jet, delta, dyad
from tests.references.dyad import dyad_numpy, make_numba_dyad, random_dyads

N = 1_000_000
ROUNDS = 9
# The goals: (numerator, denominator, goal) in throughput; the autodiff goal is a
# time ratio (<= 1.25x the analytic time), i.e. a throughput ratio >= 0.8.
GOALS = {
    "dyad analytic / numba": ("dyad analytic", "dyad numba", 0.9),
    "dyad analytic / numpy": ("dyad analytic", "dyad numpy", 3.0),
    "dyad autodiff / analytic": ("dyad autodiff", "dyad analytic", 1 / 1.25),
    "delta.fk / numba newton x8": ("delta.fk", "delta fk numba", 0.7),
    "delta.fk_closed_form / numpy": ("delta.fk_closed_form", "delta closed form numpy", 1.5),
}


def test_goal_ratios(benchmark):
    pytest.importorskip("numba")
    arrays, l_ac, l_bc = random_dyads(N)
    a, b = Jet.of(*arrays[:3]), Jet.of(*arrays[3:])
    dyad_numba = make_numba_dyad()
    _, theta = data(N)
    theta_dev = jnp.asarray(theta)
    fk_numba = ref_delta.make_numba_fk_newton()
    contenders = {
        "dyad analytic": lambda: dyad.solve(a, b, l_ac, l_bc),
        "dyad autodiff": lambda: dyad.solve(a, b, l_ac, l_bc, 1, "autodiff"),
        "dyad numba": lambda: dyad_numba(*arrays, l_ac, l_bc),
        "dyad numpy": lambda: dyad_numpy(*arrays, l_ac, l_bc),
        "delta.fk": lambda: delta.fk(ROBOT, theta_dev),
        "delta fk numba": lambda: fk_numba(theta),
        "delta.fk_closed_form": lambda: delta.fk_closed_form(ROBOT, theta_dev),
        "delta closed form numpy": lambda: ref_delta.fk_closed_form_numpy(theta),
    }
    best = dict.fromkeys(contenders, float("inf"))
    for fn in contenders.values():
        jax.block_until_ready(fn())  # compile and warm up, outside the timer
    for _ in range(ROUNDS):
        for name, fn in contenders.items():
            start = time.perf_counter()
            jax.block_until_ready(fn())
            best[name] = min(best[name], time.perf_counter() - start)
    rate = {name: N / seconds for name, seconds in best.items()}
    ratios = {goal: rate[num] / rate[den] for goal, (num, den, _) in GOALS.items()}
    benchmark.extra_info.update(kernel="goal ratios, interleaved", dtype="float64")
    benchmark.extra_info["n_cases"] = N
    benchmark.extra_info.update({f"{name} (cases/s)": round(r) for name, r in rate.items()})
    benchmark.extra_info.update({goal: round(r, 2) for goal, r in ratios.items()})
    benchmark.pedantic(lambda: None, rounds=1, iterations=1)
    for goal, (_, _, target) in GOALS.items():
        met = "met" if ratios[goal] >= target else "MISSED"
        print(f"{goal:32s} {ratios[goal]:6.2f}  (goal {target:.2f}: {met})")
