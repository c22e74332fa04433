"""Host-side validation at the public boundary: clear ``ValueError``s, never inside jit.

Value checks run only on concrete inputs; under a user's ``jit`` the arguments are tracers and
only shape checks apply (per-element problems then surface as statuses).
"""

from __future__ import annotations

from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from jax.typing import ArrayLike

from .jet import Jet


def is_concrete(x: Any) -> bool:
    """True when ``x`` holds values on the host side (not a tracer)."""
    return not isinstance(x, jax.core.Tracer)


def as_jet(x: Jet | ArrayLike, name: str, coords: int | None) -> Jet:
    """Accept a Jet, or a plain array of positions (taken at rest); check the last axis."""
    jet = x if isinstance(x, Jet) else Jet.constant(x)
    shapes = {tuple(jnp.shape(arr)) for arr in (jet.p, jet.v, jet.a)}
    if len(shapes) != 1:
        raise ValueError(f"{name}: p, v and a must have one shape, got {sorted(shapes)}")
    if coords is not None:
        point(jet.p, name, coords)
    dtype = jnp.result_type(jet.p, jet.v, jet.a, float)
    return jet.astype(dtype)


def as_float(x: ArrayLike) -> jax.Array:
    """``x`` as a JAX array of an inexact dtype: integers and booleans become JAX's default
    float (float32, or float64 with x64); floating input keeps its dtype. Works on tracers."""
    arr = x if isinstance(x, jax.Array) else jnp.asarray(x)
    if not jnp.issubdtype(arr.dtype, jnp.inexact):
        arr = arr.astype(jnp.result_type(float))
    return arr


def point(x: ArrayLike, name: str, coords: int) -> jax.Array:
    """A floating array of points, shape ``(..., coords)``."""
    arr = x if isinstance(x, jax.Array) else jnp.asarray(x)
    if arr.ndim == 0 or arr.shape[-1] != coords:
        raise ValueError(
            f"{name}: expected shape (..., {coords}) (last axis = coordinates), "
            f"got {tuple(arr.shape)}"
        )
    return as_float(arr)


def positive_length(x: ArrayLike, name: str, allow_nonfinite: bool = False) -> jax.Array | float:
    """A link length: positive values (checked when concrete); Python floats pass unchanged.

    With ``allow_nonfinite`` NaN/inf entries pass (a batched kernel reports them per element
    as ``INVALID_INPUT``); zero and negative values always raise.
    """
    if is_concrete(x):
        raw = None if isinstance(x, bool | str | bytes) or x is None else np.asarray(x)
        if raw is None or raw.dtype.kind not in "fiu":
            raise ValueError(f"{name} must be a positive length (a real number), got {x!r}")
        values = raw.astype(float)
        finite = np.isfinite(values)
        if np.any(values[finite] <= 0) or not (allow_nonfinite or np.all(finite)):
            raise ValueError(f"{name} must be positive and finite, got {values}")
    if isinstance(x, float):
        return x  # weakly typed: kernels cast it to their inputs' dtype, no dispatch here
    return as_float(x)


def batch_shape(name_shapes: dict[str, tuple[int, ...]]) -> tuple[int, ...]:
    """Broadcast batch shapes numpy-style, or raise naming every argument's shape."""
    try:
        return tuple(np.broadcast_shapes(*name_shapes.values()))
    except ValueError:
        listed = ", ".join(f"{name} {shape}" for name, shape in name_shapes.items())
        raise ValueError(f"batch shapes do not broadcast: {listed}") from None


def choice(value: Any, name: str, allowed: tuple[Any, ...]) -> Any:
    """A discrete option (mode, method, branch): one of ``allowed``."""
    if isinstance(value, bool) or value not in allowed:
        raise ValueError(f"{name} must be one of {allowed}, got {value!r}")
    return value


def cast_leaves(tree: Any, dtype: Any) -> Any:
    """``tree`` with every array leaf in ``dtype``; the same object when it already is.

    Skipping the no-op casts saves a few microseconds of dispatch per leaf on every call.
    """
    if all(leaf.dtype == dtype for leaf in jax.tree.leaves(tree)):
        return tree
    return jax.tree.map(lambda leaf: leaf.astype(dtype), tree)
