"""The NumPy benchmark references compute what jaxkin.serial computes (so benchmark ratios
compare like with like). The references live in benchmarks/ and are not part of the library."""

import numpy as np
import pytest

import jaxkin
from jaxkin import serial
from jaxkin.serial import dh
from tests.references.serial import ARMS, ik_newton_numpy, random_problems


@pytest.mark.parametrize("arm", list(ARMS))
def test_fk_references_equal_jaxkin(arm):
    q_true, targets, _ = random_problems(ARMS[arm], 50, seed=3)
    table = dh.DHTable.create(**ARMS[arm])
    np.testing.assert_allclose(dh.transforms(table, q_true), targets, atol=1e-14)
    chain = serial.from_dh(table)
    np.testing.assert_allclose(jaxkin.fk(chain, q_true).x.p, targets, atol=1e-13)


@pytest.mark.parametrize("arm", ["2R", "anthropomorphic"])
def test_newton_reference_takes_the_same_path(arm):
    _, targets, q0 = random_problems(ARMS[arm], 200, seed=4)
    q_np, ok_np, its_np = ik_newton_numpy(ARMS[arm], targets, q0)
    res = serial.ik_newton(serial.from_dh(dh.DHTable.create(**ARMS[arm])), targets, q0)
    ok = np.asarray(res.converged)
    assert ok.mean() == 1.0 and ok_np.mean() == 1.0
    same = np.asarray(res.iterations) == its_np
    assert same.mean() >= 0.95
    # Same iterates up to the pseudo-inverse soft cut-off (relative ~1e-7 per step).
    np.testing.assert_allclose(np.asarray(res.q)[same], q_np[same], atol=1e-6)
