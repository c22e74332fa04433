"""Throughput of SCARA IK with velocities and accelerations: 1,000 trajectories x 1,000 samples.

Each trajectory is a helix like the paper's eq. 16 (random centre, radius, phase and speed,
all inside the workspace of l_OA = 150, l_AB = 80, l_BC = 50 mm), with exact derivatives. The
jaxkin kernels (analytic and autodiff, float64 and float32) run beside the plain NumPy
reference (benchmarks/reference_scara.py) and, when numba is installed, its fused-loop version.
``extra_info`` records cases/s and the largest deviation from the float64 NumPy reference.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxkin import Jet, scara
from tests.references.scara import ik_numpy, make_numba_ik

N_TRAJ, N_SAMPLES = 1000, 1000
N_CASES = N_TRAJ * N_SAMPLES
L_OA, L_AB, L_BC = 150.0, 80.0, 50.0


def trajectories(n_traj: int = N_TRAJ, n_samples: int = N_SAMPLES, seed: int = 0):
    """Helices ``centre + radius (sin(w t + ph), -cos(w t + ph))``, z rising; (N, T, 3) each."""
    rng = np.random.default_rng(seed)
    t = np.linspace(0.0, 8.0, n_samples)[None, :]
    cx = rng.uniform(70.0, 100.0, (n_traj, 1))
    cy = rng.uniform(-20.0, 20.0, (n_traj, 1))
    radius = rng.uniform(5.0, 20.0, (n_traj, 1))
    w = rng.uniform(0.5, 2.0, (n_traj, 1))
    ph = rng.uniform(0.0, 2.0 * np.pi, (n_traj, 1))
    s, c = np.sin(w * t + ph), np.cos(w * t + ph)
    ones = np.ones_like(s)
    p = np.stack([cx + radius * s, cy - radius * c, 50.0 + 10.0 * t * ones], -1)
    v = np.stack([radius * w * c, radius * w * s, 10.0 * ones], -1)
    a = np.stack([-radius * w * w * s, radius * w * w * c, 0.0 * ones], -1)
    return p, v, a


@pytest.fixture(scope="module")
def data():
    p, v, a = trajectories()
    q, q_d, q_dd = ik_numpy(p, v, a, L_OA, L_AB, L_BC, 1)
    return (p, v, a), np.stack([q, q_d, q_dd])


def _deviation(result_q: Jet, reference: np.ndarray) -> float:
    got = np.stack([np.asarray(x, np.float64) for x in (result_q.p, result_q.v, result_q.a)])
    scale = np.max(np.abs(reference), axis=(1, 2, 3), keepdims=True)
    return float(np.max(np.abs(got - reference) / scale))


@pytest.mark.parametrize("dtype", ["float64", "float32"])
@pytest.mark.parametrize("method", ["analytic", "autodiff"])
def test_scara_ik_jaxkin(measure, benchmark, data, method, dtype):
    (p, v, a), reference = data
    robot = scara.Scara.create(L_OA, L_AB, L_BC)
    d = jax.device_put(Jet.of(p, v, a).astype(jnp.dtype(dtype)))
    result = measure(
        lambda: scara.ik(robot, d, branch=1, method=method),
        N_CASES,
        rounds=3,
        batch=f"{N_TRAJ}x{N_SAMPLES}",
        dtype=dtype,
        method=method,
    )
    assert bool(jnp.all(result.ok))
    deviation = _deviation(result.q, reference)
    assert deviation < (1e-9 if dtype == "float64" else 1e-3)
    benchmark.extra_info["max_rel_deviation_from_numpy"] = deviation


@pytest.mark.parametrize("dtype", ["float64", "float32"])
def test_scara_ik_numpy(measure, data, dtype):
    (p, v, a), reference = data
    p, v, a = (x.astype(dtype) for x in (p, v, a))
    result = measure(
        lambda: ik_numpy(p, v, a, L_OA, L_AB, L_BC, 1),
        N_CASES,
        rounds=3,
        batch=f"{N_TRAJ}x{N_SAMPLES}",
        dtype=dtype,
        method="numpy",
    )
    assert np.isfinite(result[0]).all()


def test_scara_ik_numba(measure, data):
    pytest.importorskip("numba")
    (p, v, a), reference = data
    ik_loop = make_numba_ik()
    flat = [np.ascontiguousarray(x.reshape(-1, 3)) for x in (p, v, a)]
    out = np.empty((N_CASES, 9))

    def run():
        ik_loop(*flat, L_OA, L_AB, L_BC, 1, out)
        return out

    measure(run, N_CASES, rounds=3, batch=f"{N_TRAJ}x{N_SAMPLES}", dtype="float64", method="numba")
    got = out.reshape(N_TRAJ, N_SAMPLES, 3, 3).transpose(2, 0, 1, 3)
    np.testing.assert_allclose(got, reference, rtol=1e-12, atol=1e-12)
