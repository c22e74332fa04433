"""Shared test utilities: finite differences along trajectories, batch shapes, compile counts."""

from __future__ import annotations

import contextlib
from collections.abc import Callable, Collection, Iterable, Iterator
from typing import Any

import jax
import numpy as np
import pytest
from jax import monitoring

BATCH_SHAPES = [(), (1,), (7,), (3, 5)]


def marked_slow(values: Iterable[Any], slow: Collection[Any]) -> list[Any]:
    """``values`` for ``pytest.mark.parametrize`` with those in ``slow`` marked
    ``pytest.mark.slow`` (left out of ``make test``; their ids stay the values')."""
    slow = set(slow)
    unknown = slow.difference(values := list(values))
    assert not unknown, f"marked slow but not parametrised: {sorted(unknown)}"
    return [pytest.param(v, marks=pytest.mark.slow) if v in slow else v for v in values]


def central_differences(
    position: Callable[[float], np.ndarray], t: float, h: float
) -> tuple[np.ndarray, np.ndarray]:
    """First and second central differences of ``position(t)`` (error O(h^2)).

    Returns ``(velocity, acceleration)``. With ``h ~ eps^(1/4)`` times the time scale the second
    difference is accurate to ~1e-7 relative in float64; with ``h ~ eps^(1/3)`` the first is
    accurate to ~1e-10.
    """
    plus, zero, minus = (np.asarray(position(t + s)) for s in (h, 0.0, -h))
    return (plus - minus) / (2.0 * h), (plus - 2.0 * zero + minus) / (h * h)


def fd_rates(
    position: Callable[[float], np.ndarray], t: float, scale: float = 1.0
) -> tuple[np.ndarray, np.ndarray]:
    """Velocity and acceleration by central differences, each with its best float64 step.

    Richardson-extrapolated (two step sizes) to O(h^4), so velocities agree with analytic ones
    to ~1e-11 and accelerations to ~1e-8 relative for smooth trajectories of time scale
    ``scale``.
    """
    h1 = 2e-3 * scale
    v1, a1 = central_differences(position, t, h1)
    v2, a2 = central_differences(position, t, h1 / 2.0)
    return (4.0 * v2 - v1) / 3.0, (4.0 * a2 - a1) / 3.0


_EVENTS: list[str] = []
monitoring.register_event_duration_secs_listener(lambda name, *_, **__: _EVENTS.append(name))
# A trace, an XLA compilation, or a program loaded from the persistent compilation cache (the
# tests share one): each means the call was not served by a function's own compiled cache.
_COMPILE_EVENTS = ("jaxpr_trace_duration", "backend_compile_duration", "cache_retrieval_time_sec")


@contextlib.contextmanager
def compilations() -> Iterator[dict[str, int]]:
    """Count traces and compilations inside the block: ``with compilations() as count``,
    then ``count["n"]``."""
    start = len(_EVENTS)
    counter = {"n": 0}
    yield counter
    counter["n"] = sum(1 for n in _EVENTS[start:] if n.endswith(_COMPILE_EVENTS))


def compile_count(jitted: Callable) -> int:
    """Number of compiled specialisations held by a ``jax.jit`` function."""
    return jitted._cache_size()


def tree_allfinite(tree) -> bool:
    """True when every floating leaf of a pytree is finite."""
    leaves = [np.asarray(x) for x in jax.tree.leaves(tree)]
    return all(np.all(np.isfinite(x)) for x in leaves if np.issubdtype(x.dtype, np.floating))
