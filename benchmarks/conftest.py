"""Benchmark configuration: float64 available (each benchmark states the dtype it uses).

Timing rules (DESIGN.md): compile and warm up outside the timer; time
``jax.block_until_ready(f(...))`` on the result; record batch size, dtype and throughput
(cases per second) in ``benchmark.extra_info``.
"""

from __future__ import annotations

from collections.abc import Callable

import jax
import pytest

jax.config.update("jax_enable_x64", True)


@pytest.fixture
def measure(benchmark) -> Callable:
    """``measure(fn, n_cases, **info)``: warm ``fn`` up, time it, record cases/s."""

    def run(fn: Callable[[], object], n_cases: int, rounds: int = 5, **info):
        jax.block_until_ready(fn())  # compile + warm-up, outside the timer
        result = benchmark.pedantic(
            lambda: jax.block_until_ready(fn()), rounds=rounds, iterations=1, warmup_rounds=1
        )
        best = benchmark.stats.stats.min
        benchmark.extra_info.update(info)
        benchmark.extra_info["n_cases"] = n_cases
        benchmark.extra_info["cases_per_second"] = n_cases / best
        return result

    return run
