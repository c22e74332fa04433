"""``jaxkin._numerics``: the division-free derivative rules of ``rsqrt`` and ``safe_sqrt``."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from jaxkin._numerics import all_finite, all_last, isotropy, rsqrt, safe_sqrt, spd_det

X = jnp.asarray(np.random.default_rng(3).uniform(1e-3, 50.0, 200))


def _derivatives(f, x, order):
    """d^k f / dx^k at x for k = 0..order, elementwise (nested grad under vmap)."""
    out, g = [], f
    for _ in range(order + 1):
        out.append(jax.vmap(g)(x))
        g = jax.grad(g)
    return out


def test_rsqrt_and_its_derivatives_match_closed_forms():
    # x^(-1/2), -1/2 x^(-3/2), 3/4 x^(-5/2), -15/8 x^(-7/2)
    coefficients = [1.0, -0.5, 0.75, -1.875]
    for k, value in enumerate(_derivatives(rsqrt, X, 3)):
        exact = coefficients[k] * np.asarray(X) ** (-0.5 - k)
        np.testing.assert_allclose(value, exact, rtol=1e-14)


def test_safe_sqrt_derivatives_match_closed_forms_and_jnp_sqrt():
    coefficients = [1.0, 0.5, -0.25, 0.375]  # x^(1/2), 1/2 x^(-1/2), -1/4 x^(-3/2), ...
    ours = _derivatives(safe_sqrt, X, 3)
    reference = _derivatives(jnp.sqrt, X, 3)
    np.testing.assert_array_equal(ours[0], jnp.sqrt(X))  # the value is sqrt's, not x*rsqrt(x)
    for k in range(4):
        np.testing.assert_allclose(
            ours[k], coefficients[k] * np.asarray(X) ** (0.5 - k), rtol=1e-14
        )
        np.testing.assert_allclose(ours[k], reference[k], rtol=1e-14)
    # Second order through nested jvp (how jaxkin.lift uses it).
    v, a = 0.3, -0.7
    (_, y_dot), (_, y_ddot) = jax.jvp(
        lambda x, t: jax.jvp(safe_sqrt, (x,), (t,)),
        (X, jnp.full_like(X, v)),
        (jnp.full_like(X, v), jnp.full_like(X, a)),
    )
    np.testing.assert_allclose(y_dot, 0.5 * v / np.sqrt(X), rtol=1e-14)
    np.testing.assert_allclose(y_ddot, 0.5 * a / np.sqrt(X) - 0.25 * v * v * X**-1.5, rtol=1e-13)


def test_safe_sqrt_at_and_below_zero_is_zero_with_zero_gradients():
    x = jnp.array([0.0, -1.0, -1e-300])
    np.testing.assert_array_equal(safe_sqrt(x), 0.0)
    for derivative in _derivatives(safe_sqrt, x, 2)[1:]:
        np.testing.assert_array_equal(derivative, 0.0)


def test_spd_det_matches_numpy():
    """Compiled, the unrolled elimination gives numpy's determinant to 1e-12 relative, and 0
    (to rounding) for a singular matrix."""
    rng = np.random.default_rng(3)
    jac = rng.normal(size=(40, 6, 7))
    jac[:5, :, 6] = jac[:5, :, 5]  # rank 6 of 7 columns: J^T J singular
    gram = np.einsum("bki,bkj->bij", jac, jac)
    det = np.asarray(jax.jit(spd_det)(gram))
    outer = np.einsum("bik,bjk->bij", jac, jac)
    np.testing.assert_allclose(jax.jit(spd_det)(outer), np.linalg.det(outer), rtol=1e-12)
    assert np.all(det[:5] <= 1e-12 * np.linalg.det(gram[5:]).max())


def test_isotropy_matches_the_singular_values():
    """The isotropy against its definition from numpy's singular values, ``(prod s_i)^(1/k) /
    sqrt(mean s_i^2)``: to 1e-12 relative on full-rank Jacobians of 6 x 7 and 7 x 6; where
    one loses rank, finite and at most ``eps^(1/2k)`` (a determinant of rounding size,
    ``k = 6``)."""
    rng = np.random.default_rng(4)
    jac = rng.normal(size=(40, 6, 7))
    jac[:5, 5] = jac[:5, 4]  # rank 5: J J^T singular
    for j in (jac, np.swapaxes(jac, -1, -2)):
        s = np.linalg.svd(j, compute_uv=False)
        expected = np.exp(np.mean(np.log(s[5:]), axis=-1)) / np.sqrt(np.mean(s[5:] ** 2, -1))
        ours = np.asarray(isotropy(j))
        np.testing.assert_allclose(ours[5:], expected, rtol=1e-12, atol=0)
        assert np.all(np.isfinite(ours)) and np.all(ours[:5] <= 0.1)


def test_all_last_equals_jnp_all_for_one_element_and_batches():
    """One element (the columns and-ed one by one) and batches (a reduction): jnp.all's
    values and shapes, empty rows included; all_finite through it."""
    rng = np.random.default_rng(5)
    for shape in [(3,), (1, 4), (1, 1, 2), (5, 3), (2, 1, 3), (1, 0), (4, 0), (0, 3)]:
        x = rng.random(shape) > 0.3
        got = all_last(jnp.asarray(x))
        assert got.shape == shape[:-1] and got.dtype == jnp.bool_
        np.testing.assert_array_equal(got, np.all(x, axis=-1))
    for row in ([1.0, 2.0, 3.0], [1.0, np.nan, 3.0], [np.inf, 0.0, 0.0]):
        for shape in ((3,), (1, 3)):
            y = np.asarray(row).reshape(shape)
            np.testing.assert_array_equal(all_finite(y), np.all(np.isfinite(y), axis=-1))
    assert not bool(all_last(jnp.asarray([True, False, True])))
    assert bool(all_last(jnp.asarray([[True, True]]))[0])
