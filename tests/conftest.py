"""Test configuration: float64 on (the library itself never touches global config), and JAX's
persistent compilation cache shared by the test processes, so that a program compiled once (by
another test or another worker with the same computation) is loaded rather than compiled
again. Tests that count compilations count ``jax.jit`` specialisations, which the cache does
not change. Slow tests are marked ``@pytest.mark.slow`` at the test (``make test`` leaves them
out, ``make test-slow`` runs them).

Each test file's compiled programs are released when the file is done: a worker that kept every
program it compiled grew past the kernel's limit on memory mappings (``vm.max_map_count``, 65530
by default; XLA maps a few regions per program), and XLA aborted the process when it could map
no more."""

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


@pytest.fixture(autouse=True, scope="module")
def _release_compiled_programs():
    """Drop JAX's compiled programs after each test file (a later file loads them again from the
    persistent cache when it needs them)."""
    yield
    jax.clear_caches()
    gc.collect()
