"""``jaxkin._trig``: polynomial sincos/atan2 against NumPy's libm (the independent reference)."""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxkin import _trig

RNG = np.random.default_rng(5)


def _ulps(got, exact, dtype):
    """|got - exact| in units of the spacing of ``dtype`` at the exact value (rounded)."""
    exact_in_dtype = np.asarray(exact).astype(dtype)
    spacing = np.spacing(np.abs(exact_in_dtype)).astype(np.float64)
    return np.abs(np.asarray(got, np.float64) - exact_in_dtype.astype(np.float64)) / spacing


def _angles(dtype):
    limit = _trig.REDUCTION_LIMIT[np.dtype(dtype)]
    return np.concatenate(
        [
            RNG.uniform(-10.0, 10.0, 200_000),
            RNG.uniform(-limit, limit, 200_000),
            np.arange(-400, 401) * (np.pi / 4),  # near the quadrant boundaries
            [0.0, -0.0, 1e-30, -1e-30, limit, -limit],
        ]
    ).astype(dtype)


@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test_sincos_within_one_ulp(dtype):
    x = _angles(dtype)
    exact = x.astype(np.float64)
    sin_x, cos_x = jax.jit(_trig.sincos)(x)
    assert sin_x.dtype == dtype and cos_x.dtype == dtype
    assert _ulps(sin_x, np.sin(exact), dtype).max() <= 1.0
    assert _ulps(cos_x, np.cos(exact), dtype).max() <= 1.0
    signed = np.asarray(x[-6:-2])  # 0, -0, tiny, -tiny: sin keeps the sign (sin(-0) = -0)
    assert np.array_equal(np.signbit(np.asarray(sin_x)[-6:-2]), np.signbit(signed))


def test_pi_over_2_parts_are_exact_splits_of_pi():
    from decimal import Decimal, getcontext
    from fractions import Fraction

    getcontext().prec = 60
    half_pi = Fraction(Decimal("3.14159265358979323846264338327950288419716939937510582097")) / 2
    for dtype, bits in ((np.float64, 27), (np.float32, 9)):
        *parts, tail = _trig._PIO2_PARTS[np.dtype(dtype)]
        for part in parts:  # few significant bits, so n * part is exact for |n| < limit
            assert np.asarray(part, dtype) == part
            mantissa = Fraction(part) / Fraction(2) ** math.floor(math.log2(part))
            assert (mantissa * 2 ** (bits - 1)).denominator == 1
        remainder = half_pi - sum(Fraction(p) for p in parts) - Fraction(tail)
        assert abs(remainder) < Fraction(tail) * np.finfo(dtype).eps


@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test_sincos_beyond_reduction_limit_and_non_finite(dtype):
    # Beyond the limit the error is about half an ulp of x (the angle's own resolution); the
    # values stay in [-1, 1] for every finite x; NaN and inf give NaN.
    limit = _trig.REDUCTION_LIMIT[np.dtype(dtype)]
    big = np.finfo(dtype).max
    for scale in (10.0 * limit, 1e4 * limit):
        x = (RNG.uniform(-1.0, 1.0, 20_000) * scale).astype(dtype)
        sin_x, cos_x = _trig.sincos(x)
        exact = x.astype(np.float64)
        bound = np.spacing(np.abs(x)).astype(np.float64)  # one ulp of x
        assert np.all(np.abs(np.asarray(sin_x, np.float64) - np.sin(exact)) <= bound)
        assert np.all(np.abs(np.asarray(cos_x, np.float64) - np.cos(exact)) <= bound)
    huge = np.array([big, -big, big / 3, np.nan, np.inf, -np.inf], dtype)
    sin_x, cos_x = _trig.sincos(huge)
    assert np.all(np.abs(sin_x[:3]) <= 1.0) and np.all(np.abs(cos_x[:3]) <= 1.0)
    assert np.isnan(np.asarray(sin_x)[3:]).all() and np.isnan(np.asarray(cos_x)[3:]).all()


def test_sincos_derivatives_vmap_and_other_dtypes():
    x = jnp.asarray(RNG.uniform(-5.0, 5.0, 64))
    (s, c), (s_dot, c_dot) = jax.jvp(_trig.sincos, (x,), (jnp.ones_like(x),))
    np.testing.assert_array_equal(s_dot, c)
    np.testing.assert_array_equal(c_dot, -s)
    second = jax.vmap(jax.grad(jax.grad(lambda t: _trig.sincos(t)[0])))(x)
    np.testing.assert_allclose(second, -np.sin(np.asarray(x)), rtol=0, atol=2e-16)
    batched = jax.vmap(_trig.sincos)(jnp.reshape(x, (8, 8)))
    np.testing.assert_array_equal(batched[0], jnp.reshape(s, (8, 8)))
    half = _trig.sincos(jnp.asarray([0.5, 1.0], jnp.float16))
    assert half[0].dtype == jnp.float16
    np.testing.assert_allclose(np.asarray(half[0], np.float64), np.sin([0.5, 1.0]), atol=1e-3)
    ints = _trig.sincos(jnp.arange(3))
    np.testing.assert_allclose(ints[1], np.cos(np.arange(3)), rtol=1e-15)


@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test_sin_cos_alone_within_one_epsilon_absolute(dtype):
    # Absolute accuracy (the contract): |error| <= eps(dtype) over the reduction range,
    # including the multiples of pi/4 where the reduction cancels.
    x = _angles(dtype)
    exact = x.astype(np.float64)
    eps = np.finfo(dtype).eps
    sin_x, cos_x = jax.jit(_trig.sin_alone)(x), jax.jit(_trig.cos_alone)(x)
    assert sin_x.dtype == dtype and cos_x.dtype == dtype
    assert np.abs(np.asarray(sin_x, np.float64) - np.sin(exact)).max() <= eps
    assert np.abs(np.asarray(cos_x, np.float64) - np.cos(exact)).max() <= eps
    # Near zero sin keeps its relative accuracy (r = x exactly there).
    tiny = np.geomspace(1e-30, 1e-3, 200).astype(dtype)
    assert _ulps(_trig.sin_alone(tiny), np.sin(tiny.astype(np.float64)), dtype).max() <= 1.0


@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test_sin_cos_alone_beyond_reduction_limit_and_non_finite(dtype):
    limit = _trig.REDUCTION_LIMIT[np.dtype(dtype)]
    big = np.finfo(dtype).max
    x = (RNG.uniform(-1.0, 1.0, 20_000) * 10.0 * limit).astype(dtype)
    bound = np.spacing(np.abs(x)).astype(np.float64)  # the angle's own resolution
    for ours, reference in ((_trig.sin_alone, np.sin), (_trig.cos_alone, np.cos)):
        error = np.abs(np.asarray(ours(x), np.float64) - reference(x.astype(np.float64)))
        assert np.all(error <= bound)
        values = np.asarray(ours(np.array([big, -big, big / 3, np.nan, np.inf, -np.inf], dtype)))
        assert np.all(np.abs(values[:3]) <= 1.0) and np.isnan(values[3:]).all()


def test_sin_cos_alone_derivatives_and_other_dtypes():
    x = jnp.asarray(RNG.uniform(-5.0, 5.0, 64))
    s, s_dot = jax.jvp(_trig.sin_alone, (x,), (jnp.ones_like(x),))
    c, c_dot = jax.jvp(_trig.cos_alone, (x,), (jnp.ones_like(x),))
    np.testing.assert_array_equal(s_dot, c)
    np.testing.assert_array_equal(c_dot, -s)
    second = jax.vmap(jax.grad(jax.grad(_trig.cos_alone)))(x)
    np.testing.assert_allclose(second, -np.cos(np.asarray(x)), rtol=0, atol=3e-16)
    half = _trig.cos_alone(jnp.asarray([0.5, 1.0], jnp.float16))
    assert half.dtype == jnp.float16
    np.testing.assert_allclose(np.asarray(half, np.float64), np.cos([0.5, 1.0]), atol=1e-3)
    np.testing.assert_allclose(_trig.sin_alone(jnp.arange(3)), np.sin(np.arange(3)), atol=3e-16)


@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test_atan2_within_two_ulp(dtype):
    y = np.concatenate(
        [RNG.normal(size=200_000), 1e-3 * RNG.uniform(-1, 1, 50_000), RNG.uniform(-1, 1, 9)]
    )
    x = np.concatenate(
        [RNG.normal(size=200_000), RNG.uniform(-1, 1, 50_000), [1, -1, 0.5, 2, 0.7, 1.4, 1, 0, 0]]
    )
    y, x = y.astype(dtype), x.astype(dtype)
    got = jax.jit(_trig.atan2)(y, x)
    assert got.dtype == dtype
    assert _ulps(got, np.arctan2(y.astype(np.float64), x.astype(np.float64)), dtype).max() <= 2.0


def test_atan2_special_values_follow_c():
    values = np.array([0.0, -0.0, 1.0, -1.0, np.inf, -np.inf, np.nan, 1e-300])
    y, x = (a.ravel() for a in np.meshgrid(values, values))
    got, expected = np.asarray(_trig.atan2(y, x)), np.arctan2(y, x)
    np.testing.assert_allclose(got, expected, rtol=2 * np.finfo(float).eps)  # NaN == NaN
    finite = np.isfinite(expected)
    np.testing.assert_array_equal(np.signbit(got[finite]), np.signbit(expected[finite]))


@pytest.mark.slow
def test_atan2_broadcasts_and_has_arctan2_derivatives():
    y = jnp.asarray(RNG.normal(size=(4, 1)))
    x = jnp.asarray(RNG.normal(size=(5,)))
    assert _trig.atan2(y, x).shape == (4, 5)
    assert _trig.atan2(1, 2).dtype == jnp.float64
    ours = jax.jacfwd(lambda v: _trig.atan2(v[0], v[1]))
    reference = jax.jacfwd(lambda v: jnp.arctan2(v[0], v[1]))
    points = RNG.normal(size=(20, 2))
    for v in points:
        np.testing.assert_allclose(ours(v), reference(v), rtol=1e-15, atol=1e-16)
    hess = jax.hessian(lambda v: _trig.atan2(v[0], v[1]))(points[0])
    hess_ref = jax.hessian(lambda v: jnp.arctan2(v[0], v[1]))(points[0])
    np.testing.assert_allclose(hess, hess_ref, rtol=1e-13)
