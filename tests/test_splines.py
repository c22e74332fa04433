"""Cubic-spline rates (jaxkin._splines) against analytic derivatives and an independent solve."""

import numpy as np
import pytest

from jaxkin import _splines as splines


def _nonuniform_times(rng, n, t0=0.3, span=2.0):
    steps = rng.uniform(0.5, 1.5, n - 1)
    return t0 + np.concatenate([[0.0], np.cumsum(steps)]) * span / steps.sum()


def _dense_spline(t, y, end):
    """Independent reference: solve for the 4 (n-1) coefficients of the pieces
    c0 + c1 (t - t_i) + c2 (t - t_i)^2 + c3 (t - t_i)^3 with a dense linear system."""
    n = len(t)
    m = n - 1
    rows, rhs = [], []

    def row(entries):
        r = np.zeros(4 * m)
        for index, value in entries:
            r[index] += value
        return r

    for i in range(m):
        h = t[i + 1] - t[i]
        rows.append(row([(4 * i, 1.0)]))
        rhs.append(y[i])
        rows.append(row([(4 * i, 1.0), (4 * i + 1, h), (4 * i + 2, h * h), (4 * i + 3, h**3)]))
        rhs.append(y[i + 1])
    for i in range(m - 1):  # C1 and C2 at t_{i+1}
        h = t[i + 1] - t[i]
        rows.append(
            row([(4 * i + 1, 1.0), (4 * i + 2, 2 * h), (4 * i + 3, 3 * h * h), (4 * i + 5, -1.0)])
        )
        rhs.append(0.0)
        rows.append(row([(4 * i + 2, 2.0), (4 * i + 3, 6 * h), (4 * i + 6, -2.0)]))
        rhs.append(0.0)
    if end == "natural":
        rows.append(row([(2, 2.0)]))
        rhs.append(0.0)
        h = t[-1] - t[-2]
        rows.append(row([(4 * (m - 1) + 2, 2.0), (4 * (m - 1) + 3, 6 * h)]))
        rhs.append(0.0)
    else:  # third derivative continuous at t_1 and t_{n-2}
        rows.append(row([(3, 1.0), (7, -1.0)]))
        rhs.append(0.0)
        rows.append(row([(4 * (m - 2) + 3, 1.0), (4 * (m - 1) + 3, -1.0)]))
        rhs.append(0.0)
    c = np.linalg.solve(np.array(rows), np.array(rhs))
    c = c.reshape(m, 4)
    v = np.append(
        c[:, 1], c[-1, 1] + 2 * c[-1, 2] * (t[-1] - t[-2]) + 3 * c[-1, 3] * (t[-1] - t[-2]) ** 2
    )
    a = np.append(2 * c[:, 2], 2 * c[-1, 2] + 6 * c[-1, 3] * (t[-1] - t[-2]))
    return v, a


@pytest.mark.parametrize("n", [4, 5, 9, 30])
def test_not_a_knot_reproduces_cubics_exactly(n):
    rng = np.random.default_rng(n)
    t = _nonuniform_times(rng, n)
    coef = rng.normal(size=(4, 3))  # three cubics at once (k = 3 coordinates)
    y = coef[0] + np.outer(t, coef[1]) + np.outer(t**2, coef[2]) + np.outer(t**3, coef[3])
    v_true = coef[1] + 2 * np.outer(t, coef[2]) + 3 * np.outer(t**2, coef[3])
    a_true = 2 * coef[2] + 6 * np.outer(t, coef[3])
    v, a = splines.derivatives(t, y)
    scale = np.abs(y).max() / (t[-1] - t[0])
    np.testing.assert_allclose(v, v_true, rtol=0, atol=1e-10 * scale * 10)
    np.testing.assert_allclose(a, a_true, rtol=0, atol=1e-9 * scale * 10)


def test_natural_reproduces_lines_exactly():
    rng = np.random.default_rng(1)
    t = _nonuniform_times(rng, 7)
    y = 2.5 - 1.5 * t
    v, a = splines.derivatives(t, y, end="natural")
    np.testing.assert_allclose(v, -1.5, rtol=1e-12)
    np.testing.assert_allclose(a, 0.0, atol=1e-12)


@pytest.mark.parametrize("end", ["natural", "not-a-knot"])
@pytest.mark.parametrize("n", [4, 6, 11])
def test_matches_dense_coefficient_solve(end, n):
    rng = np.random.default_rng(10 + n)
    t = _nonuniform_times(rng, n)
    y = rng.normal(size=n)
    v_ref, a_ref = _dense_spline(t, y, end)
    v, a = splines.derivatives(t, y, end=end)
    np.testing.assert_allclose(v, v_ref, rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(a, a_ref, rtol=1e-9, atol=1e-9)


def test_sine_converges_at_the_expected_order():
    errors = []
    for n in (41, 81, 161):
        t = np.linspace(0.0, 4.0, n)
        v, a = splines.derivatives(t, np.sin(2 * t))
        errors.append((np.abs(v - 2 * np.cos(2 * t)).max(), np.abs(a + 4 * np.sin(2 * t)).max()))
    errors = np.array(errors)
    # Halving h divides the velocity error by ~2^3 (or more) and the acceleration error by ~2^2.
    assert np.all(errors[:-1, 0] / errors[1:, 0] > 6.0)
    assert np.all(errors[:-1, 1] / errors[1:, 1] > 3.5)
    assert errors[-1, 0] < 1e-4 and errors[-1, 1] < 1e-2  # h = 0.025, |y''''| = 16


def test_natural_has_zero_end_acceleration():
    t = np.linspace(0.0, 1.0, 9)
    _, a = splines.derivatives(t, np.exp(t), end="natural")
    assert a[0] == pytest.approx(0.0, abs=1e-12)
    assert a[-1] == pytest.approx(0.0, abs=1e-12)


def test_few_samples():
    v, a = splines.derivatives(np.array([1.0]), np.array([3.0]))
    assert v.tolist() == [0.0] and a.tolist() == [0.0]
    v, a = splines.derivatives(np.array([0.0, 2.0]), np.array([1.0, 5.0]), end="natural")
    np.testing.assert_allclose(v, [2.0, 2.0])
    np.testing.assert_allclose(a, [0.0, 0.0])
    t = np.array([0.0, 0.5, 2.0])  # parabola y = 1 + t - 3 t^2
    v, a = splines.derivatives(t, 1 + t - 3 * t**2)
    np.testing.assert_allclose(v, 1 - 6 * t, rtol=1e-12)
    np.testing.assert_allclose(a, -6.0, rtol=1e-12)


def test_batched_equals_loop():
    rng = np.random.default_rng(3)
    t = np.stack([_nonuniform_times(rng, 8) for _ in range(5)])
    y = rng.normal(size=(5, 8, 2))
    v, a = splines.derivatives(t, y)
    for i in range(5):
        vi, ai = splines.derivatives(t[i], y[i])
        np.testing.assert_allclose(v[i], vi, rtol=1e-13, atol=1e-13)
        np.testing.assert_allclose(a[i], ai, rtol=1e-13, atol=1e-13)


def test_by_group_interleaved_with_invalid_rows():
    t = np.array([0.0, 0.0, 1.0, 1.0, 2.0, 2.0, 3.0, 3.0, 4.0])
    group = np.array([0, 1, 0, 1, 0, 1, 0, 1, 0])
    y = np.stack([t**3, 2 * t**2], axis=-1)
    y[5] = np.nan  # candidate 1, t = 2: left out
    v, a = splines.by_group(t, y, group)
    assert np.all(np.isnan(v[5])) and np.all(np.isnan(a[5]))
    rows0 = group == 0
    np.testing.assert_allclose(v[rows0, 0], 3 * t[rows0] ** 2, atol=1e-9)
    np.testing.assert_allclose(a[rows0, 1], 4.0, atol=1e-9)
    rows1 = np.array([1, 3, 7])  # three valid samples: the parabola, exact for 2 t^2
    np.testing.assert_allclose(v[rows1, 1], 4 * t[rows1], atol=1e-9)


def test_errors():
    with pytest.raises(ValueError, match="strictly increasing"):
        splines.derivatives(np.array([0.0, 1.0, 1.0, 2.0]), np.zeros(4))
    with pytest.raises(ValueError, match="end must be"):
        splines.derivatives(np.arange(4.0), np.zeros(4), end="clamped")
    with pytest.raises(ValueError, match="finite"):
        splines.derivatives(np.arange(4.0), np.array([0, np.nan, 0, 0]))
    with pytest.raises(ValueError, match="candidate 2: t must be strictly increasing"):
        splines.by_group(np.array([0.0, 2.0, 1.0]), np.zeros((3, 1)), np.array([2, 2, 2]))
