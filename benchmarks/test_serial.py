"""Throughput of serial-arm FK and Newton IK beside NumPy references (float64).

Arms: planar 2R (links 1 m), [Lopez-Villagomez]'s anthropomorphic RRR (L = 0.5, 0.4, 0.3 m) and a
PUMA-560-type 6R (standard DH). FK: the DH kernel (``dh.transforms``, what the analytic arms
run) and ``jaxkin.fk`` of the arm's ``serial.Chain`` (``serial.from_dh``: products of
exponentials). IK:
``ik_newton`` (space frame, pseudo-inverse step, default tolerances 1e-3 rad / 1e-4 m,
max_iter 20) on reachable targets ``fk(q_true)`` from seeds ``q_true + U(-0.3, 0.3)`` rad; the
NumPy reference runs the same algorithm with ``np.linalg.pinv`` and early exit. Cases/s,
success fraction and mean iterations are recorded in ``extra_info``.
"""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxkin
from jaxkin import serial
from jaxkin.serial import dh
from tests.references.serial import ARMS, fk_dh_numpy, ik_newton_numpy, random_problems

SIZES = [1_000, 100_000]


def _table(arm):
    return dh.DHTable.create(**arm)


@pytest.mark.parametrize("n", SIZES)
@pytest.mark.parametrize("arm", list(ARMS))
def test_jaxkin_fk_dh(measure, n, arm):
    _, _, q0 = random_problems(ARMS[arm], n)
    table, q = _table(ARMS[arm]), jnp.asarray(q0)
    kernel = jax.jit(dh.transforms)
    measure(lambda: kernel(table, q), n, kernel=f"fk_dh[{arm}]", dtype="float64")


@pytest.mark.parametrize("n", SIZES)
@pytest.mark.parametrize("arm", list(ARMS))
def test_jaxkin_fk_poe(measure, n, arm):
    _, _, q0 = random_problems(ARMS[arm], n)
    chain, q = serial.from_dh(_table(ARMS[arm])), jnp.asarray(q0)
    measure(lambda: jaxkin.fk(chain, q).x.p, n, kernel=f"chain_fk[{arm}]", dtype="float64")


@pytest.mark.parametrize("n", SIZES)
@pytest.mark.parametrize("arm", list(ARMS))
def test_numpy_fk_dh(measure, n, arm):
    _, _, q0 = random_problems(ARMS[arm], n)
    measure(lambda: fk_dh_numpy(ARMS[arm], q0), n, kernel=f"numpy_fk[{arm}]", dtype="float64")


@pytest.mark.parametrize("n", SIZES)
@pytest.mark.parametrize("arm", list(ARMS))
def test_jaxkin_ik_newton(measure, benchmark, n, arm):
    _, targets, q0 = random_problems(ARMS[arm], n)
    chain = serial.from_dh(_table(ARMS[arm]))
    targets, q0 = jnp.asarray(targets), jnp.asarray(q0)
    res = measure(
        lambda: serial.ik_newton(chain, targets, q0),
        n,
        rounds=3,
        kernel=f"ik_newton[{arm}]",
        dtype="float64",
    )
    _record(benchmark, np.asarray(res.converged), np.asarray(res.iterations))


@pytest.mark.parametrize("n", SIZES)
@pytest.mark.parametrize("arm", list(ARMS))
def test_numpy_ik_newton(measure, benchmark, n, arm):
    _, targets, q0 = random_problems(ARMS[arm], n)
    q, ok, its = measure(
        lambda: ik_newton_numpy(ARMS[arm], targets, q0),
        n,
        rounds=1 if n > 10_000 else 3,
        kernel=f"numpy_ik_newton[{arm}]",
        dtype="float64",
    )
    _record(benchmark, ok, its)


def _record(benchmark, ok, iterations):
    benchmark.extra_info["success_fraction"] = float(ok.mean())
    benchmark.extra_info["mean_iterations"] = float(iterations[ok].mean())
    benchmark.extra_info["max_iterations"] = int(iterations.max())
