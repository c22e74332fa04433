"""Test configuration: float64 on (the library itself never touches global config), and JAX's
persistent compilation cache shared by the test processes, so that a program compiled once (by
another test or another worker with the same computation) is loaded rather than compiled
again. Tests that count compilations count ``jax.jit`` specialisations, which the cache does
not change. Slow tests are marked ``@pytest.mark.slow`` at the test (``make test`` leaves them
out, ``make test-slow`` runs them).

A worker releases its compiled programs after a test file once it holds many memory mappings: a
worker that kept every program it compiled grew past the kernel's limit (``vm.max_map_count``,
65530 by default; XLA maps a few regions per program), and XLA aborted the process when it
could map no more."""

import gc
import os
import tempfile

import jax
import pytest

jax.config.update("jax_enable_x64", True)
jax.config.update(
    "jax_compilation_cache_dir",
    os.environ.get("JAXKIN_TEST_CACHE", os.path.join(tempfile.gettempdir(), "jaxkin-test-cache")),
)
jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.2)


# Mappings after which a worker drops its programs (a test file adds a few thousand at most)
RELEASE_AFTER_MAPPINGS = 20_000


def _memory_mappings() -> int:
    """The number of this process's memory mappings (Linux), or a count that forces a release."""
    try:
        with open("/proc/self/maps", "rb") as maps:
            return sum(1 for _ in maps)
    except OSError:
        return RELEASE_AFTER_MAPPINGS


@pytest.fixture(autouse=True, scope="module")
def _release_compiled_programs():
    """After a test file, drop JAX's compiled programs if the worker holds many mappings (a later
    file loads the programs it needs again from the persistent cache)."""
    yield
    if _memory_mappings() >= RELEASE_AFTER_MAPPINGS:
        jax.clear_caches()
        gc.collect()


@pytest.fixture(autouse=True)
def _keep_runtime_options():
    """The command line, run in this process by some tests, turns ``enable_low_latency`` and
    the program store on: put ``XLA_FLAGS``, JAX's dispatch option and the store back after
    each test (in a process whose JAX runs already they change no program, but later tests'
    subprocesses would inherit the flags)."""
    from jaxkin._execute import store  # imported after the configuration above

    flags = os.environ.get("XLA_FLAGS")
    dispatch = jax.config.read("jax_cpu_enable_async_dispatch")
    programs = store.keeps_programs()
    yield
    if flags is None:
        os.environ.pop("XLA_FLAGS", None)
    else:
        os.environ["XLA_FLAGS"] = flags
    jax.config.update("jax_cpu_enable_async_dispatch", dispatch)
    store.keep_programs(programs)


@pytest.fixture
def hot_after_two(monkeypatch):
    """Programs built at the second call (the default waits longer), from an empty table."""
    from jaxkin import _batching  # imported after the configuration above
    from jaxkin._execute import pipeline

    monkeypatch.setattr(_batching, "HOT_AFTER", 2)
    pipeline.HOT.clear()
    yield
    pipeline.HOT.clear()
