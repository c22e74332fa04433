"""Generic batched Newton-Raphson: convergence, statuses, implicit derivatives, batching."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxkin import Jet, Status, lift, newton
from tests.helpers import BATCH_SHAPES, compilations, tree_allfinite


def sqrt_residual(x, c, _shared):
    return (x[0] * x[0] - c,)


def circle_line(x, c, _shared):
    # x^2 + y^2 = c, x = y  ->  x = y = sqrt(c / 2)
    return (x[0] * x[0] + x[1] * x[1] - c, x[0] - x[1])


def sphere_planes(x, args, shared):
    # |x|^2 = r^2, x = y, y = 2 z (shared = r)
    return (x[0] * x[0] + x[1] * x[1] + x[2] * x[2] - shared * shared, x[0] - x[1], x[1] - 2 * x[2])


def four_unknowns(x, b, _shared):
    # A x + 0.1 x^3 = b: a mildly nonlinear 4x4 system (LU fallback path)
    a = ((4.0, 1.0, 0.0, 0.5), (1.0, 3.0, 1.0, 0.0), (0.0, 1.0, 5.0, 1.0), (0.5, 0.0, 1.0, 2.0))
    return tuple(sum(a[i][j] * x[j] for j in range(4)) + 0.1 * x[i] ** 3 - b[i] for i in range(4))


def test_scalar_sqrt_per_element_iterations():
    c = jnp.array([4.0, 2.0, 1.0, 100.0])
    result = newton.solve(sqrt_residual, jnp.ones((4, 1)), c, tol=1e-14, scale=c)
    np.testing.assert_allclose(result.x[:, 0], np.sqrt(np.asarray(c)), rtol=1e-14)
    assert result.status.tolist() == [0, 0, 0, 0]
    iterations = np.asarray(result.iterations)
    assert iterations[2] == 0  # the guess is the root
    assert len(set(iterations.tolist())) > 1  # each element stops on its own
    assert np.all(iterations <= 10)


def test_two_and_three_unknowns():
    res2 = newton.solve(circle_line, jnp.ones((3, 2)), jnp.array([2.0, 8.0, 0.5]))
    expected = np.sqrt(np.array([2.0, 8.0, 0.5]) / 2.0)
    np.testing.assert_allclose(res2.x, np.stack([expected, expected], -1), rtol=1e-12)
    res3 = newton.solve(sphere_planes, jnp.array([1.0, 1.0, 1.0]), (), 3.0)
    z = 3.0 / 3.0  # x = y = 2 z, 9 z^2 = 9
    np.testing.assert_allclose(res3.x, [2 * z, 2 * z, z], rtol=1e-12)
    assert int(res3.status) == Status.OK


def test_four_unknowns_lu_fallback_against_numpy():
    rng = np.random.default_rng(1)
    b = rng.normal(size=(4, 5))
    result = newton.solve(four_unknowns, jnp.zeros((5, 4)), tuple(jnp.asarray(b)))
    assert np.all(np.asarray(result.status) == Status.OK)
    x = np.asarray(result.x)
    a = np.array(
        [[4.0, 1.0, 0.0, 0.5], [1.0, 3.0, 1.0, 0.0], [0.0, 1.0, 5.0, 1.0], [0.5, 0.0, 1.0, 2.0]]
    )
    np.testing.assert_allclose(x @ a.T + 0.1 * x**3, b.T, atol=1e-11)


def test_not_converged_and_singular_statuses_are_finite():
    # x^2 + 1 = 0 has no real root; x^2 = 0 at x = 0 is a root with a zero Jacobian
    # (converged, but SINGULAR: position valid, derivatives not).
    c = jnp.array([-1.0, 0.0, 4.0])
    x0 = jnp.array([[0.7], [0.0], [1.0]])
    result = newton.solve(sqrt_residual, x0, c, max_iter=20)
    assert result.status.tolist() == [Status.NOT_CONVERGED, Status.SINGULAR, Status.OK]
    assert result.converged.tolist() == [False, True, True]
    assert int(result.iterations[0]) == 20
    singular = newton.solve(sqrt_residual, jnp.array([[0.0]]), jnp.array([1.0]))
    assert int(singular.status[0]) == Status.SINGULAR
    assert int(singular.iterations[0]) == 0
    assert tree_allfinite((result, singular))


def test_implicit_derivatives_first_second_and_reverse():
    # x(c) = sqrt(c / 2) from the circle-line system: x' = 1 / (4 x), x'' = -1 / (16 x^3)
    def root(c):
        return newton.solve(circle_line, jnp.ones(2), c).x[0]

    c = 2.0
    x = np.sqrt(c / 2.0)
    np.testing.assert_allclose(jax.grad(root)(c), 1.0 / (4.0 * x), rtol=1e-12)
    np.testing.assert_allclose(jax.jacfwd(root)(c), 1.0 / (4.0 * x), rtol=1e-12)
    lifted = lift(root)(Jet.of(c, 1.0, 0.0))
    np.testing.assert_allclose(lifted.v, 1.0 / (4.0 * x), rtol=1e-12)
    np.testing.assert_allclose(lifted.a, -1.0 / (16.0 * x**3), rtol=1e-10)
    # derivative with respect to the shared argument (sphere radius): x = 2 r / 3
    d_shared = jax.grad(lambda r: newton.solve(sphere_planes, jnp.ones(3), (), r).x[0])(3.0)
    np.testing.assert_allclose(d_shared, 2.0 / 3.0, rtol=1e-12)


@pytest.mark.parametrize("shape", BATCH_SHAPES)
def test_batch_shapes(shape):
    c = jnp.full(shape, 8.0)
    result = newton.solve(circle_line, jnp.ones((*shape, 2)), c)
    assert result.x.shape == (*shape, 2)
    assert result.status.shape == shape
    np.testing.assert_allclose(result.x, 2.0, rtol=1e-12)


def test_jit_and_vmap_match_eager_without_recompiling():
    c = jnp.linspace(1.0, 9.0, 6)
    eager = newton.solve(circle_line, jnp.ones((6, 2)), c).x
    jitted = jax.jit(lambda c: newton.solve(circle_line, jnp.ones((6, 2)), c).x)
    np.testing.assert_allclose(jitted(c), eager, rtol=1e-14)
    shifted = c + 1.0
    with compilations() as count:
        jitted(shifted)
    assert count.n == 0
    vmapped = jax.vmap(lambda c: newton.solve(circle_line, jnp.ones(2), c).x)(c)
    np.testing.assert_allclose(vmapped, eager, rtol=1e-14)


def test_small_solves_against_numpy():
    """The component solve and Hadamard ratio against NumPy's determinant and solve."""
    rng = np.random.default_rng(0)
    q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    rows = [[jnp.asarray(q[i, j]) for j in range(3)] for i in range(3)]
    np.testing.assert_allclose(newton.hadamard_ratio_components(rows), 1.0, rtol=1e-12)
    for n in (1, 2, 3):
        m = rng.normal(size=(7, n, n))
        m[0, -1] = m[0, 0]  # singular
        m[1] = 0.0  # zero rows: ratio 0, not NaN
        rows = [[jnp.asarray(m[:, i, j]) for j in range(n)] for i in range(n)]
        bound = np.prod(np.linalg.norm(m, axis=-1), axis=-1)
        expected = np.abs(np.linalg.det(m)) / np.where(bound > 0, bound, 1.0)
        got = newton.hadamard_ratio_components(rows)
        np.testing.assert_allclose(got, expected, rtol=1e-12, atol=1e-15)
        # the component solve: numpy's solve where regular, finite placeholders where singular
        b = rng.normal(size=(7, n))
        x = newton.solve_components(rows, tuple(jnp.asarray(b[:, i]) for i in range(n)))
        x = np.stack([np.asarray(v) for v in x], axis=-1)
        regular = slice(2, None)
        np.testing.assert_allclose(
            x[regular], np.linalg.solve(m[regular], b[regular][..., None])[..., 0], rtol=1e-10
        )
        assert np.all(np.isfinite(x))


def test_bad_arguments_raise():
    with pytest.raises(ValueError, match="x0"):
        newton.solve(sqrt_residual, 1.0, 1.0)
    with pytest.raises(ValueError, match="max_iter"):
        newton.solve(sqrt_residual, jnp.ones(1), 1.0, max_iter=-1)
    with pytest.raises(ValueError, match="tol"):
        newton.solve(sqrt_residual, jnp.ones(1), 1.0, tol=0.0)
