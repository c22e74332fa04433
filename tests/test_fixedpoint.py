"""jaxkin.fixedpoint: quantiser values, the paper-sequence IK against the analytic arm IK
(``jaxkin.serial.ik_all_branches``), sweeps."""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np
import pytest

from jaxkin import fixedpoint
from jaxkin.serial.arms import Anthropomorphic, ik_all_branches
from jaxkin.serial.dh import transforms


def fk(robot, q):
    """The DH forward kinematics of an arm: the 4x4 transform of its last frame."""
    q = jnp.asarray(q)
    return transforms(robot.dh_table(q.dtype), q)


ROBOT = Anthropomorphic(0.3, 0.25, 0.2)


def _reachable_targets(n: int, seed: int = 0) -> np.ndarray:
    """Wrist positions of random joint vectors away from elbow and base-axis singularities."""
    rng = np.random.default_rng(seed)
    out = []
    while len(out) < n:
        q = rng.uniform(-np.pi, np.pi, 3)
        reach = 0.25 * np.cos(q[1]) + 0.2 * np.cos(q[1] + q[2])
        if abs(np.sin(q[2])) > 0.2 and abs(reach) > 0.05:
            out.append(q)
    return np.asarray(fk(ROBOT, np.array(out))[..., :3, 3])


def test_quantize_known_values():
    # floor(x 2^n) / 2^n, hand-computed.
    np.testing.assert_array_equal(
        np.asarray(fixedpoint.quantize(jnp.array([0.7, -0.3, 0.8, 1.0]), 1)), [0.5, -0.5, 0.5, 1.0]
    )
    np.testing.assert_array_equal(
        np.asarray(fixedpoint.quantize(jnp.array([0.7, -0.3, 0.8]), 1, "nearest")), [0.5, -0.5, 1.0]
    )
    assert float(fixedpoint.quantize(np.pi, 3)) == 3.125  # 25 / 8
    assert float(fixedpoint.quantize(-np.pi, 3)) == -3.25  # toward -inf
    # Broadcast over bit widths.
    q = np.asarray(fixedpoint.quantize(jnp.array([0.1]), jnp.arange(1, 5)[:, None]))
    np.testing.assert_array_equal(q[:, 0], [0.0, 0.0, 0.0, 0.0625])


def test_quantize_error_bounds_and_grid():
    x = np.random.default_rng(1).uniform(-4, 4, 1000)
    for n in (1, 7, 20, 40):
        floor = np.asarray(fixedpoint.quantize(x, n))
        nearest = np.asarray(fixedpoint.quantize(x, n, "nearest"))
        step = 2.0**-n
        assert np.all((x - floor >= 0) & (x - floor < step))
        assert np.all(np.abs(x - nearest) <= step / 2)
        np.testing.assert_array_equal(floor * 2.0**n, np.round(floor * 2.0**n))


def test_unquantised_paper_equations_match_serial_ik():
    """[Lopez-Villagomez]'s sequence (eq. 14's C, acos, eq. 11) vs the two-link solver of
    serial.ik_all_branches.

    1e-9, not 1e-12: the acos of eq. 14's C / rho loses digits when the elbow is nearly
    straight (the targets keep |sin q3| > 0.2; observed ~2e-12).
    """
    target = _reachable_targets(40)
    paper = np.asarray(fixedpoint.anthropomorphic_ik(ROBOT, target))
    ref = np.asarray(ik_all_branches(ROBOT, target).q)
    assert paper.shape == ref.shape == (40, 4, 3)
    np.testing.assert_allclose(paper, ref, atol=1e-9)
    # ...and every branch reproduces the target through the DH forward kinematics.
    np.testing.assert_allclose(
        np.asarray(fk(ROBOT, paper))[..., :3, 3],
        np.broadcast_to(target[:, None], paper.shape),
        atol=1e-10,
    )


def test_quantised_outputs_lie_on_the_grid_and_converge():
    target = _reachable_targets(40, seed=2)
    ref = np.asarray(ik_all_branches(ROBOT, target).q)
    for n in (4, 10, 16):
        q = np.asarray(fixedpoint.anthropomorphic_ik(ROBOT, target, n))
        np.testing.assert_array_equal(q * 2.0**n, np.round(q * 2.0**n))
    errors = []
    for n in (8, 16, 24, 32, 40):
        q = np.asarray(fixedpoint.anthropomorphic_ik(ROBOT, target, n))
        d = np.angle(np.exp(1j * (q - ref)))
        errors.append(np.sqrt(np.mean(d * d)))
    errors = np.array(errors)
    # Each 8 extra bits divide the error by ~2^8 (allow 2^5): truncation error ~ C 2^-n.
    assert np.all(errors[1:] < errors[:-1] / 32), errors
    assert errors[-1] < 1e-9


@pytest.mark.slow
def test_sweep_over_bits_equals_separate_calls():
    target = _reachable_targets(6, seed=3)
    bits = np.array([3, 9, 17, 40])
    batched = np.asarray(fixedpoint.anthropomorphic_ik(ROBOT, target, bits[:, None], "nearest"))
    assert batched.shape == (4, 6, 4, 3)
    for i, n in enumerate(bits):
        single = np.asarray(fixedpoint.anthropomorphic_ik(ROBOT, target, int(n), "nearest"))
        np.testing.assert_array_equal(batched[i], single)


def test_low_widths_stay_finite():
    """At 1-3 bits lengths and ratios quantise to 0 or saturate: angles stay finite."""
    target = _reachable_targets(10, seed=4)
    q = np.asarray(fixedpoint.anthropomorphic_ik(ROBOT, target, jnp.arange(1, 4)[:, None]))
    assert np.all(np.isfinite(q))


@pytest.mark.slow
def test_accuracy_study_and_smallest_width():
    path = _reachable_targets(30, seed=5)
    bits = np.arange(1, 41)
    study = fixedpoint.accuracy_study(ROBOT, path, bits)
    assert study.q.shape == (40, 30, 3) and study.joint_rms.shape == (40, 3)
    assert study.cartesian_rms.shape == study.cartesian_max.shape == (40,)
    rms = np.asarray(study.cartesian_rms)
    assert np.all(rms <= np.asarray(study.cartesian_max) + 1e-18)
    # Cartesian error recomputed by hand from the returned angles (exact numpy FK).
    q = np.asarray(study.q)[9]
    reach = 0.25 * np.cos(q[:, 1]) + 0.2 * np.cos(q[:, 1] + q[:, 2])
    p = np.stack(
        [
            np.cos(q[:, 0]) * reach,
            np.sin(q[:, 0]) * reach,
            0.3 + 0.25 * np.sin(q[:, 1]) + 0.2 * np.sin(q[:, 1] + q[:, 2]),
        ],
        -1,
    )
    np.testing.assert_allclose(rms[9], np.sqrt(np.mean(np.sum((p - path) ** 2, -1))), rtol=1e-12)
    assert rms[-1] < 1e-10 and rms[0] > 1e-2
    width = fixedpoint.smallest_width(bits, rms, 1e-3)
    assert width is not None and np.all(rms[width - 1 :] <= 1e-3) and rms[width - 2] > 1e-3
    assert fixedpoint.smallest_width(bits, rms, 0.0) is None
    assert fixedpoint.smallest_width([1, 2, 3], [0.5, 2.0, 0.1], 1.0) == 3
    assert fixedpoint.smallest_width([1, 2, 3], [0.5, 0.2, 0.1], 1.0) == 1


def test_bad_arguments_raise():
    target = np.zeros(3) + 0.3
    for bits in (0, 41, 2.5, np.nan):
        with pytest.raises(ValueError, match="bits"):
            fixedpoint.anthropomorphic_ik(ROBOT, target, bits)
    with pytest.raises(ValueError, match="rounding"):
        fixedpoint.quantize(0.5, 3, "ceil")
    with pytest.raises(ValueError, match="target"):
        fixedpoint.anthropomorphic_ik(ROBOT, np.zeros(2))
    with pytest.raises(ValueError, match="robot"):
        fixedpoint.anthropomorphic_ik("arm", target)
    with pytest.raises(ValueError, match="branch"):
        fixedpoint.accuracy_study(ROBOT, target[None], np.arange(1, 3), branch="left")
    with pytest.raises(ValueError, match="path"):
        fixedpoint.accuracy_study(ROBOT, target, np.arange(1, 3))
    with pytest.raises(ValueError, match="bits"):
        fixedpoint.anthropomorphic_ik(ROBOT, np.zeros((3, 3)), np.ones(2, int) * 4)
