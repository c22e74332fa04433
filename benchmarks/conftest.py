"""Benchmark configuration: float64 available (each benchmark states the dtype it uses).

Timing rules (DESIGN.md): compile and warm up outside the timer; time
``jax.block_until_ready(f(...))`` on the result; record batch size, dtype and throughput
(cases per second) in ``benchmark.extra_info``.
"""

from __future__ import annotations

import os
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


def pytest_sessionfinish(session, exitstatus):
    """Write benchmarks/results.md: one row per benchmark, from this run's measurements."""
    bench_session = getattr(session.config, "_benchmarksession", None)
    if bench_session is None or not bench_session.benchmarks:
        return
    if all("test_peers.py::" in b.fullname for b in bench_session.benchmarks):
        return  # peer runs write benchmarks/peers_results.md instead
    import platform
    from pathlib import Path

    rows = []
    for bench in bench_session.benchmarks:
        if not getattr(bench, "stats", None):
            continue
        info = dict(bench.extra_info)
        best = bench.stats.min
        rate = info.pop("cases_per_second", None)
        n = info.pop("n_cases", "")
        kernel = info.pop("kernel", bench.group or "")
        dtype = info.pop("dtype", "")
        extra = ", ".join(
            f"{k}={v:.3g}" if isinstance(v, float) else f"{k}={v}" for k, v in info.items()
        )
        rows.append(
            f"| {bench.fullname.split('::')[-1]} | {kernel} | {dtype} | {n} | "
            f"{best * 1e3:.3f} | {'' if rate is None else f'{rate:,.0f}'} | {extra} |"
        )
    header = [
        "# Benchmark results",
        "",
        f"One `make bench` run: {platform.machine()}, {platform.processor() or 'cpu'}, "
        f"{os.cpu_count()} logical CPUs, Python {platform.python_version()}, "
        f"JAX {jax.__version__}. Times are the minimum over rounds, after compilation.",
        "",
        "| benchmark | kernel | dtype | cases | best time (ms) | cases/s | notes |",
        "| --- | --- | --- | --- | --- | --- | --- |",
    ]
    Path(__file__).with_name("results.md").write_text("\n".join(header + rows) + "\n")
