"""Test configuration: float64 on (the library itself never touches global config)."""

import jax

jax.config.update("jax_enable_x64", True)
