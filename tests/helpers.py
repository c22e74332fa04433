"""Shared test utilities: finite differences along trajectories, batch shapes, compile counts,
the example UR5 with a mixed body."""

from __future__ import annotations

import contextlib
import dataclasses
import subprocess
import sys
from collections.abc import Callable, Collection, Iterable, Iterator
from pathlib import Path
from typing import Any

import jax
import numpy as np
import pytest
from jax import monitoring

from jaxkin import serial

BATCH_SHAPES = [(), (1,), (7,), (3, 5)]
UR5 = Path(__file__).resolve().parents[1] / "examples" / "ur5.urdf"


def ur5_mixed_body() -> Any:
    """The example UR5 (``examples/ur5.urdf``, tip ``tool0``): spheres on three links, the
    skeleton's capsules (radius 4 cm) on the others."""
    spheres = {
        "upper_arm_link": (np.array([[0.0, 0.0, 0.1], [0.0, 0.0, 0.3]]), np.array([0.07, 0.06])),
        "forearm_link": (np.array([[0.0, 0.0, 0.05], [0.0, 0.0, 0.25]]), np.array([0.06, 0.05])),
        "wrist_3_link": (np.zeros((1, 3)), np.array([0.05])),
    }
    return serial.from_urdf(UR5, "tool0").with_link_radius(0.04).with_link_spheres(spheres)


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


_TRACE = "/jax/core/compile/jaxpr_trace_duration"
_COMPILE = "/jax/core/compile/backend_compile_duration"
_EVENTS: list[tuple[str, str]] = []  # (event, function name), appended from any thread


def _record(event: str, duration: float, **kwargs: Any) -> None:
    if event in (_TRACE, _COMPILE):
        _EVENTS.append((event, str(kwargs.get("fun_name", ""))))


monitoring.register_event_duration_secs_listener(_record)


@dataclasses.dataclass
class Compilations:
    """Traces and XLA compilations seen by JAX's public monitoring events inside a block.

    A top-level ``jax.jit`` trace (``jaxpr_trace_duration``) or a compilation
    (``backend_compile_duration``: XLA, or a program loaded from the persistent compilation
    cache the tests share) each mean a call was not served by a function's compiled cache.
    """

    events: list[tuple[str, str]] = dataclasses.field(default_factory=list)

    @property
    def n(self) -> int:
        """Traces plus compilations of any function."""
        return len(self.events)

    def compiled(self, name: str) -> int:
        """Compilations of the jitted function called ``name`` (its ``__name__``)."""
        return sum(1 for event, fun in self.events if event == _COMPILE and fun == f"jit({name})")


@contextlib.contextmanager
def compilations() -> Iterator[Compilations]:
    """Count traces and compilations inside the block: ``with compilations() as count``,
    then ``count.n`` or ``count.compiled(name)``."""
    start = len(_EVENTS)
    counter = Compilations()
    try:
        yield counter
    finally:
        counter.events = _EVENTS[start:]


def tree_allfinite(tree) -> bool:
    """True when every floating leaf of a pytree is finite."""
    leaves = [np.asarray(x) for x in jax.tree.leaves(tree)]
    return all(np.all(np.isfinite(x)) for x in leaves if np.issubdtype(x.dtype, np.floating))


def gradient_against_differences(
    fn: Callable[..., Any], args: Iterable[Any], grad: Callable[..., Any] | None = None,
    h: float = 1e-6, tol: float = 1e-7,
) -> None:  # fmt: skip
    """The gradient of the scalar ``fn`` (``grad``, by default ``jax.grad`` over every
    argument) against central differences of step ``h``, argument by argument, to ``tol``."""
    args = [np.asarray(x, dtype=float) for x in args]
    grad = grad or jax.grad(fn, argnums=tuple(range(len(args))))
    grads = grad(*[jax.numpy.asarray(x) for x in args])
    for i, (x, g) in enumerate(zip(args, grads, strict=True)):
        num = np.zeros_like(x)
        for idx in np.ndindex(x.shape):
            plus, minus = [y.copy() for y in args], [y.copy() for y in args]
            plus[i][idx] += h
            minus[i][idx] -= h
            num[idx] = (float(fn(*plus)) - float(fn(*minus))) / (2 * h)
        np.testing.assert_allclose(np.asarray(g), num, atol=tol, err_msg=f"argument {i}")


def script_line(script: str, prefix: str, cwd: Path, env: dict, *argv: str) -> list[str]:
    """Run the Python source ``script`` (with ``argv``) in a fresh process and return the
    words after ``prefix`` on the line of its output that starts with it."""
    proc = subprocess.run(
        [sys.executable, "-c", script, *argv],
        capture_output=True,
        text=True,
        timeout=900,
        cwd=cwd,
        env=env,
    )
    assert proc.returncode == 0, proc.stderr
    return next(x for x in proc.stdout.splitlines() if x.startswith(prefix)).split()[1:]
