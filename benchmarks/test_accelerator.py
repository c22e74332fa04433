"""The same kernels on the first accelerator and on the CPU, timed in one process.

Skipped where JAX sees no GPU or TPU; unchanged otherwise: inputs are placed on each device
with ``jax.device_put`` and the kernels follow their inputs. Float64 where the accelerator
supports it (float32 otherwise), positions with velocities and accelerations. The backend
keyed choices (``docs/scaling.md``: no host threads, larger planner calls, XLA's own
trigonometry) apply to the accelerator's runs by themselves.
"""

from __future__ import annotations

import jax
import numpy as np
import pytest

from jaxkin import Jet, delta, dyad, paths, plan, scara


def _accelerator():
    for backend in ("gpu", "tpu"):
        try:
            return jax.devices(backend)[0]
        except RuntimeError:
            continue
    return None


ACCELERATOR = _accelerator()
pytestmark = pytest.mark.skipif(ACCELERATOR is None, reason="no GPU or TPU")
DEVICES = {"cpu": lambda: jax.devices("cpu")[0], "accelerator": lambda: ACCELERATOR}


def _dtype(device) -> np.dtype:
    return np.dtype("float32") if device.platform == "tpu" else np.dtype("float64")


def _on(device, tree):
    dtype = _dtype(device)
    return jax.device_put(jax.tree.map(lambda x: np.asarray(x, dtype), tree), device)


@pytest.mark.parametrize("where", list(DEVICES))
def test_dyad_solve(measure, where):
    device = DEVICES[where]()
    n = 1_000_000
    rng = np.random.default_rng(0)
    a = Jet.of(*(rng.normal(size=(n, 2)) for _ in range(3)))
    b = Jet.of(*(rng.normal(size=(n, 2)) + [1.5, 0.0] * (k == 0) for k in range(3)))
    a, b = _on(device, (a, b))
    measure(lambda: dyad.solve(a, b, 1.5, 1.0, mode=1), n, kernel="dyad.solve", where=where)


@pytest.mark.parametrize("where", list(DEVICES))
def test_delta_newton_fk(measure, where):
    device = DEVICES[where]()
    robot = delta.Delta.paper()
    n = 1_000_000
    rng = np.random.default_rng(1)
    p = np.array([0.0, 0.0, -30.0]) + rng.uniform(-5.0, 5.0, size=(n, 3))
    q = _on(device, delta.ik(robot, p).q)
    measure(lambda: delta.fk(robot, q), n, kernel="delta.fk", where=where)


@pytest.mark.parametrize("where", list(DEVICES))
def test_plan_evaluate(measure, where):
    device = DEVICES[where]()
    robot = scara.Scara.paper()
    n, t = 10_000, 100
    s = np.linspace(0.0, 1.0, t)[None, :, None]
    offsets = np.random.default_rng(2).normal(scale=20.0, size=(n, 1, 3)) * [1, 1, 0]
    start, goal = np.array([110.0, -50.0, 40.0]), np.array([-20.0, 100.0, 80.0])
    path = paths.path_from_samples(start + s * (goal - start) + np.sin(np.pi * s) * offsets, 0.02)
    path = _on(device, path)
    measure(lambda: plan.evaluate(robot, path, dt=0.02), n, kernel="plan.evaluate", where=where)
