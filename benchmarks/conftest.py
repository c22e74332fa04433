"""Benchmark configuration: float64 available (each benchmark states the dtype it uses), and
JAX's CPU runtime as the command line sets it (``jaxkin.enable_low_latency()``, before JAX
runs anything; ``JAXKIN_LOW_LATENCY=0`` measures JAX's defaults instead).

Timing rules: compile and warm up outside the timer; time
``jax.block_until_ready(f(...))`` on the result; record batch size, dtype and throughput
(cases per second) in ``benchmark.extra_info``.
"""

from __future__ import annotations

import os
from collections.abc import Callable

import jax
import pytest

from jaxkin._execute.latency import enable_for_command

enable_for_command()  # first: JAX reads these options when its CPU backend starts
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
    """Write benchmarks/results.md (one row per benchmark) and scaling.png from this run.

    Only when ``JAXKIN_WRITE_RESULTS`` is set (``make bench`` sets it), so running a subset of
    the benchmarks never replaces the full table.
    """
    if not os.environ.get("JAXKIN_WRITE_RESULTS"):
        return
    bench_session = getattr(session.config, "_benchmarksession", None)
    if bench_session is None or not bench_session.benchmarks:
        return
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
    _scaling_plot(bench_session.benchmarks, Path(__file__).with_name("scaling.png"))


def _scaling_plot(benchmarks, path) -> None:
    """Throughput against batch size per kernel (test_scaling rows), when matplotlib exists."""
    curves: dict[str, list[tuple[int, float]]] = {}
    for bench in benchmarks:
        info = bench.extra_info
        if "test_scaling[" in bench.fullname and info.get("cases_per_second"):
            curves.setdefault(info["kernel"], []).append(
                (info["n_cases"], info["cases_per_second"])
            )
    if not curves:
        return
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        return
    fig, ax = plt.subplots(figsize=(7, 4.5))
    for kernel, points in sorted(curves.items()):
        n, rate = zip(*sorted(points), strict=True)
        ax.loglog(n, rate, marker="o", label=kernel)
    ax.set_xlabel("batch size (cases per call)")
    ax.set_ylabel("cases per second (float64)")
    ax.set_title("jaxkin throughput against batch size")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
