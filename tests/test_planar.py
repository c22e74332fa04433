"""Angle and distance rates [Noriega, Figs. 2-3] against sympy, the errata example and FD."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
import sympy as sp

from jaxkin import Jet, planar

t = sp.symbols("t", real=True)


def _eval(expr, t0):
    return float(expr.subs(t, t0))


@pytest.mark.parametrize(
    "x_expr, y_expr, t0",
    [
        (1 + sp.cos(t), sp.sin(2 * t) - 0.5, 0.4),  # x > 0
        (-2 + t**2, 1 + t / 3, 0.7),  # x < 0, y > 0
        (-1 - t, -0.3 - sp.sin(t), 1.1),  # x < 0, y < 0 (third quadrant)
        (sp.Integer(0) + t - 0.5, -1 + t**2, 0.5),  # crosses x = 0 with y < 0
    ],
)
def test_angle_rates_match_sympy(x_expr, y_expr, t0):
    theta = sp.atan2(y_expr, x_expr)
    jet = Jet.of(
        [_eval(x_expr, t0), _eval(y_expr, t0)],
        [_eval(sp.diff(x_expr, t), t0), _eval(sp.diff(y_expr, t), t0)],
        [_eval(sp.diff(x_expr, t, 2), t0), _eval(sp.diff(y_expr, t, 2), t0)],
    )
    out, defined = planar.angle(jet)
    assert bool(defined)
    np.testing.assert_allclose(out.p, _eval(theta, t0), rtol=1e-14)
    np.testing.assert_allclose(out.v, _eval(sp.diff(theta, t), t0), rtol=1e-12)
    np.testing.assert_allclose(out.a, _eval(sp.diff(theta, t, 2), t0), rtol=1e-12)


def test_angle_errata_example_on_negative_y_axis():
    # docs/errata.md: at (0, -1), velocity (1, 2), acceleration (0, 6):
    # theta_dot = 1, theta_ddot = 4 (derived by hand from theta = atan2(y, x)).
    out, _ = planar.angle(Jet.of([0.0, -1.0], [1.0, 2.0], [0.0, 6.0]))
    np.testing.assert_allclose([out.p, out.v, out.a], [-np.pi / 2, 1.0, 4.0], rtol=1e-15)


def test_angle_on_negative_x_axis_is_plus_pi_for_both_zero_signs():
    for y in (0.0, -0.0):
        out, _ = planar.angle(Jet.constant([-2.0, y]))
        assert float(out.p) == pytest.approx(np.pi, abs=0)


def test_angle_of_zero_vector_is_reported_with_finite_values_and_gradients():
    zero = Jet.of(jnp.zeros((3, 2)), jnp.ones((3, 2)), jnp.ones((3, 2)))
    out, defined = planar.angle(zero)
    assert not np.any(defined)
    np.testing.assert_array_equal([out.p, out.v, out.a], 0.0)
    grad = jax.grad(lambda p: jnp.sum(planar.angle(Jet(p, zero.v, zero.a))[0].a))(zero.p)
    assert np.all(np.isfinite(grad))


def test_distance_rates_match_sympy():
    ax, ay = sp.cos(t), 0.5 * t
    bx, by = 2 + t**2, -1 + sp.sin(3 * t)
    dist = sp.sqrt((bx - ax) ** 2 + (by - ay) ** 2)
    t0 = 0.8

    def jet_of(x_expr, y_expr):
        return Jet.of(
            [_eval(x_expr, t0), _eval(y_expr, t0)],
            [_eval(sp.diff(x_expr, t), t0), _eval(sp.diff(y_expr, t), t0)],
            [_eval(sp.diff(x_expr, t, 2), t0), _eval(sp.diff(y_expr, t, 2), t0)],
        )

    out, defined = planar.distance(jet_of(ax, ay), jet_of(bx, by))
    assert bool(defined)
    np.testing.assert_allclose(out.p, _eval(dist, t0), rtol=1e-14)
    np.testing.assert_allclose(out.v, _eval(sp.diff(dist, t), t0), rtol=1e-13)
    np.testing.assert_allclose(out.a, _eval(sp.diff(dist, t, 2), t0), rtol=1e-12)


def test_zero_distance_is_reported_with_finite_values_and_gradients():
    a = Jet.of(jnp.ones((2, 2)), jnp.zeros((2, 2)), jnp.ones((2, 2)))
    out, defined = planar.distance(a, a)
    assert not np.any(defined)
    np.testing.assert_array_equal([out.p, out.v, out.a], 0.0)

    def loss(p):
        return jnp.sum(planar.distance(Jet(p, a.v, a.a), a)[0].a)

    assert np.all(np.isfinite(jax.grad(loss)(a.p)))


def test_batched_shapes():
    rng = np.random.default_rng(0)
    jet = Jet.of(*(rng.normal(size=(3, 5, 2)) for _ in range(3)))
    out, defined = planar.angle(jet)
    assert out.shape == (3, 5) and defined.shape == (3, 5)
    np.testing.assert_allclose(out.p, np.arctan2(jet.p[..., 1], jet.p[..., 0]), rtol=1e-15)


@pytest.mark.parametrize("phi_expr, t0", [(0.3 + 2 * t - t**2, 0.4), (sp.sin(3 * t) - 2.0, 1.3)])
def test_link_end_rates_match_sympy(phi_expr, t0):
    """Velocity and acceleration of length * (cos phi(t), sin phi(t)), differentiated by sympy."""
    length = 1.7
    end = [length * sp.cos(phi_expr), length * sp.sin(phi_expr)]
    phi = _eval(phi_expr, t0)
    got = planar.link_end_rates(
        jnp.asarray(length),
        jnp.cos(phi),
        jnp.sin(phi),
        jnp.asarray(_eval(sp.diff(phi_expr, t), t0)),
        jnp.asarray(_eval(sp.diff(phi_expr, t, 2), t0)),
    )
    expected = [_eval(sp.diff(c, t, order), t0) for order in (1, 2) for c in end]
    np.testing.assert_allclose(np.asarray(got), expected, rtol=1e-13, atol=1e-14)
