"""Host-side validation at the public boundary: clear ``ValueError``s, never inside jit.

Value checks run only on concrete inputs; under a user's ``jit`` the arguments are tracers and
only shape checks apply (per-element problems then surface as statuses).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from jax.typing import ArrayLike

from .jet import Jet


def is_concrete(x: Any) -> bool:
    """True when ``x`` holds values on the host side (not a tracer)."""
    return not isinstance(x, jax.core.Tracer)


def as_array(x: Any, dtype: Any = None) -> Any:
    """``x`` as an array of ``dtype`` (None: its own): a NumPy array when ``x`` is concrete
    (converted on the host: JAX's eager conversion compiles a program in every fresh process),
    else ``jnp.asarray``. A concrete ``jax.Array`` already in ``dtype`` is kept as it is."""
    if not is_concrete(x):
        return jnp.asarray(x, dtype)
    if isinstance(x, jax.Array) and (dtype is None or x.dtype == jnp.dtype(dtype)):
        return x
    return np.asarray(x, dtype)


def on_device(x: Any, dtype: Any = None) -> Any:
    """``x`` as a device array of ``dtype``, converted on the host when concrete
    (``as_array``); a traced ``x`` through ``jnp.asarray``."""
    if not is_concrete(x):
        return jnp.asarray(x, dtype)
    return jax.device_put(as_array(x, dtype))


def broadcast(x: Any, shape: tuple[int, ...]) -> Any:
    """``x`` broadcast to ``shape``: itself when it has that shape, else on the host when
    concrete (``as_array``)."""
    if np.shape(x) == tuple(shape):
        return x
    if is_concrete(x):
        return np.broadcast_to(np.asarray(x), shape)
    return jnp.broadcast_to(x, shape)


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
    if isinstance(x, jax.Array):
        arr = x
    elif isinstance(x, np.ndarray | np.generic):
        arr = jax.device_put(x)  # as jnp.asarray, without compiling a program per shape
    else:
        arr = jnp.asarray(x)
    if not jnp.issubdtype(arr.dtype, jnp.inexact):
        arr = arr.astype(jnp.result_type(float))
    return arr


def owned_float(x: ArrayLike) -> jax.Array:
    """``as_float(x)`` sharing no memory with the caller: a host (NumPy) array is copied
    first, since ``jax.device_put`` may alias its buffer on CPU, and an edit of the caller's
    array would then change a robot built from it. For values kept beyond the call (a
    geometry's fields, obstacles); the JAX array is read-only."""
    if isinstance(x, np.ndarray | np.generic):
        x = np.array(x, copy=True)
    return as_float(x)


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


Progress = Callable[[int, int], object]
"""A progress callback ``progress(done, total)``: ``done`` of ``total`` units of work are
finished (a long call reports ``(0, total)`` first, then after every part of its work)."""


def no_progress(done: int, total: int) -> None:
    """The progress callback of a call given none: it does nothing."""


def progress(value: Any, name: str = "progress") -> Progress | None:
    """A progress callback (``Progress``) or None, checked."""
    if value is not None and not callable(value):
        raise ValueError(
            f"{name} must be None or a callable progress(done, total) (the command line "
            f"passes its progress bar), got {value!r}"
        )
    return value


def cast_leaves(tree: Any, dtype: Any) -> Any:
    """``tree`` with every array leaf in ``dtype``; the same object when it already is.

    Skipping the no-op casts saves a few microseconds of dispatch per leaf on every call.
    """
    if all(leaf.dtype == dtype for leaf in jax.tree.leaves(tree)):
        return tree
    return jax.tree.map(lambda leaf: leaf.astype(dtype), tree)


def _real_scalar(value: Any) -> float | None:
    """``value`` as a float when it is one real number (Python, NumPy or a concrete 0-d
    array; not a bool), else None."""
    if isinstance(value, bool | np.bool_ | str | bytes) or value is None or not is_concrete(value):
        return None
    if isinstance(value, int | float):
        return float(value)
    dtype = getattr(value, "dtype", None)
    if dtype is None or np.dtype(dtype).kind not in "fiu" or np.ndim(value) != 0:
        return None
    return float(value)


def count(value: Any, name: str, minimum: int = 1) -> int:
    """A count (of samples, steps, candidates, iterations) ``>= minimum`` as a Python int.

    Python ints, NumPy integer scalars (``np.int64(5)``, as ``len`` of an array or an index
    gives) and concrete 0-d integer arrays are accepted; bools, floats (even ``3.0``: as
    ``range`` and ``np.zeros``) and anything else raise a ``ValueError`` naming ``name``.
    """
    integer = not isinstance(value, bool | np.bool_) and is_concrete(value)
    if integer and not isinstance(value, int | np.integer):
        dtype = getattr(value, "dtype", None)
        integer = dtype is not None and np.dtype(dtype).kind in "iu" and np.ndim(value) == 0
    if not integer or int(value) < minimum:
        raise ValueError(f"{name} must be an integer >= {minimum}, got {value!r}")
    return int(value)


def positive_number(value: Any, name: str) -> float:
    """A positive finite real number (a time step, a distance, a threshold) as a float.

    Python ints and floats, NumPy scalars (``np.float32(1.0)``) and 0-d arrays are accepted.
    """
    number = _real_scalar(value)
    if number is None or not (math.isfinite(number) and number > 0):
        raise ValueError(f"{name} must be a positive finite number, got {value!r}")
    return number


def finite_number(value: Any, name: str) -> float:
    """A finite real number (a weight) as a float; NumPy scalars and 0-d arrays accepted."""
    number = _real_scalar(value)
    if number is None or not math.isfinite(number):
        raise ValueError(f"{name} must be a finite number, got {value!r}")
    return number


def nonnegative_number(value: Any, name: str) -> float:
    """A real number ``>= 0`` (inf allowed) as a float; NumPy scalars and 0-d arrays
    accepted."""
    number = _real_scalar(value)
    if number is None or not number >= 0:
        raise ValueError(f"{name} must be a non-negative number, got {value!r}")
    return number


def unit_quaternions(quaternions: ArrayLike) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Quaternions ``(..., 4)`` of any length scaled to unit length (host side, float64).

    The one rule for quaternions given as data (``jaxkin.paths`` and the command line's pose
    files): ``q`` and ``c q`` (``c > 0``) are one rotation, so each is divided by its largest
    absolute component and then by its length, which neither overflows (lengths up to the
    largest float) nor underflows (subnormal components).

    Returns:
        ``(unit, length, ok)``: ``unit`` ``(..., 4)``; ``length`` ``(...)`` such that
        ``q = length * unit`` (a quaternion's rates divided by it are the unit quaternion's
        rates at that instant); ``ok`` ``(...)``, False for a zero or non-finite quaternion,
        whose ``unit`` is then NaN.
    """
    q = np.asarray(quaternions, dtype=np.float64)
    big = np.max(np.abs(q), axis=-1)
    ok = np.all(np.isfinite(q), axis=-1) & (big > 0)
    safe = np.where(ok, big, 1.0)[..., None]
    scaled = q / safe
    norm = np.where(ok, np.linalg.norm(scaled, axis=-1), 1.0)  # in [1, 2] where ok
    unit = np.where(ok[..., None], scaled / norm[..., None], np.nan)
    with np.errstate(over="ignore"):
        length = np.where(ok, safe[..., 0] * norm, np.nan)
    return unit, length, ok


def quaternion_samples(quaternions: ArrayLike, name: str) -> np.ndarray:
    """Unit quaternions from ``(..., 4)`` samples (``unit_quaternions``; a non-finite sample
    gives NaN, which the caller reports per element), or a ``ValueError`` naming the first
    zero sample, e.g. ``quaternions[2, 5]``."""
    q = np.asarray(quaternions, dtype=np.float64)
    unit, _, ok = unit_quaternions(q)
    zero = ~ok & np.all(np.isfinite(q), axis=-1)
    if np.any(zero):
        index = tuple(int(i) for i in np.argwhere(zero)[0])
        where = f"{name}[{', '.join(map(str, index))}]" if index else name
        raise ValueError(f"{where} is zero: a quaternion must be non-zero (any length)")
    return unit
