"""Test configuration: float64 on (the library itself never touches global config), and JAX's
persistent compilation cache shared by the test processes, so that a program compiled once (by
another test or another worker with the same computation) is loaded rather than compiled
again. Tests that count compilations count ``jax.jit`` specialisations, which the cache does
not change. Slow tests are marked ``@pytest.mark.slow`` at the test (``make test`` leaves them
out, ``make test-slow`` runs them)."""

import os
import tempfile

import jax

jax.config.update("jax_enable_x64", True)
jax.config.update(
    "jax_compilation_cache_dir",
    os.environ.get("JAXKIN_TEST_CACHE", os.path.join(tempfile.gettempdir(), "jaxkin-test-cache")),
)
jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.2)
