"""Jet pytree behaviour and the generic lift (nested jvp) against independent derivatives."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from jax.experimental import jet as jax_jet

from jaxkin import Jet, lift


def _sample_jet(shape=(4, 3), seed=0):
    rng = np.random.default_rng(seed)
    return Jet.of(*(rng.normal(size=shape) for _ in range(3)))


def test_jet_is_a_pytree_under_jit_vmap_and_tree_utils():
    x = _sample_jet()
    leaves, treedef = jax.tree.flatten(x)
    assert len(leaves) == 3
    rebuilt = jax.tree.unflatten(treedef, leaves)
    np.testing.assert_array_equal(rebuilt.a, x.a)
    doubled = jax.jit(lambda j: jax.tree.map(lambda a: 2 * a, j))(x)
    np.testing.assert_array_equal(doubled.v, 2 * x.v)
    row_sums = jax.vmap(lambda j: Jet(j.p.sum(), j.v.sum(), j.a.sum()))(x)
    assert row_sums.shape == (4,)
    np.testing.assert_allclose(row_sums.a, x.a.sum(axis=1))


def test_jet_under_grad():
    x = _sample_jet((3,))

    def loss(j):
        return jnp.sum(j.p**2 + 3 * j.v + j.a)

    g = jax.grad(loss)(x)
    assert isinstance(g, Jet)
    np.testing.assert_allclose(g.p, 2 * x.p)
    np.testing.assert_allclose(g.v, 3.0)
    np.testing.assert_allclose(g.a, 1.0)


def test_constructors_indexing_and_dtype():
    c = Jet.constant(np.arange(6.0).reshape(3, 2))
    assert c.shape == (3, 2)
    np.testing.assert_array_equal(c.v, 0.0)
    np.testing.assert_array_equal(c[..., 1].p, [1.0, 3.0, 5.0])
    f32 = Jet.of(np.ones(2, np.float32), np.ones(2, np.float32))
    assert f32.dtype == jnp.float32 and f32.a.dtype == jnp.float32
    assert Jet.constant([1, 2]).dtype == jnp.float64  # integers become floats
    stacked = Jet.stack([c[..., 0], c[..., 1]])
    np.testing.assert_array_equal(stacked.p, c.p)


def test_lift_matches_hand_derivatives_of_sin():
    x = _sample_jet((5,), seed=1)
    y = lift(jnp.sin)(x)
    np.testing.assert_allclose(y.p, np.sin(x.p), rtol=1e-15)
    np.testing.assert_allclose(y.v, np.cos(x.p) * x.v, rtol=1e-14)
    expected_a = -np.sin(x.p) * x.v**2 + np.cos(x.p) * x.a
    np.testing.assert_allclose(y.a, expected_a, rtol=1e-13, atol=1e-15)


def test_lift_matches_jax_experimental_jet_on_a_vector_function():
    def f(p):
        return jnp.stack([jnp.exp(p[0]) * p[1], jnp.tanh(p[0] * p[1] ** 2)])

    x = _sample_jet((2,), seed=2)
    y = lift(f)(x)
    # jax.experimental.jet takes derivative coefficients: x(t) = p + v t + a t^2 / 2!.
    primal, (c1, c2) = jax_jet.jet(f, (x.p,), ((x.v, x.a),))
    np.testing.assert_allclose(y.p, primal, rtol=1e-14)
    np.testing.assert_allclose(y.v, c1, rtol=1e-13)
    np.testing.assert_allclose(y.a, c2, rtol=1e-12)


def test_lift_with_two_jets_a_constant_and_integer_outputs():
    def f(a, k, b):
        return {"prod": a * b * k, "sign": (a > 0).astype(jnp.int8)}

    a, b = _sample_jet((4,), 3), _sample_jet((4,), 4)
    out = lift(f)(a, 3.0, b)
    assert isinstance(out["prod"], Jet)
    assert out["sign"].dtype == jnp.int8
    # Product rule, by hand: (ab)' = a'b + ab', (ab)'' = a''b + 2a'b' + ab''.
    np.testing.assert_allclose(out["prod"].v, 3 * (a.v * b.p + a.p * b.v), rtol=1e-14)
    np.testing.assert_allclose(
        out["prod"].a, 3 * (a.a * b.p + 2 * a.v * b.v + a.p * b.a), rtol=1e-13
    )


@pytest.mark.parametrize("t", [0.3, 1.7])
def test_lift_matches_finite_differences_along_a_trajectory(t):
    def traj(s):  # a smooth path and its exact derivatives
        return np.array([np.cos(2 * s), s**3])

    def traj_jet(s):
        return Jet.of(traj(s), [-2 * np.sin(2 * s), 3 * s**2], [-4 * np.cos(2 * s), 6 * s])

    def f(p):
        return jnp.arctan2(p[1], p[0]) * jnp.sqrt(1.0 + p[0] ** 2)

    from tests.helpers import fd_rates

    y = lift(f)(traj_jet(t))
    v_fd, a_fd = fd_rates(lambda s: np.asarray(f(jnp.asarray(traj(s)))), t)
    np.testing.assert_allclose(y.v, v_fd, rtol=1e-9)
    np.testing.assert_allclose(y.a, a_fd, rtol=1e-7)
