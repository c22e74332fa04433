"""Trajectory optimisation: Bezier basis, gradients vs finite differences, cost decrease."""

import jax
import jax.numpy as jnp
import numpy as np
import optax
import pytest
from helpers import tree_allfinite

from jaxkin import optimize, plan, scara

ROBOT = scara.Scara.create(150.0, 80.0, 50.0)
START = np.array([100.0, -60.0, 50.0])
GOAL = np.array([100.0, 60.0, 70.0])


def test_bezier_basis_partition_of_unity_and_derivatives():
    basis = optimize.bezier_basis(5, 201)
    np.testing.assert_allclose(basis[0].sum(1), 1.0, rtol=1e-14)
    np.testing.assert_allclose(basis[1].sum(1), 0.0, atol=1e-12)
    s = np.linspace(0, 1, 201)
    # Independent check: numpy polynomial derivatives of each Bernstein polynomial.
    from math import comb

    for i in range(5):
        poly = np.polynomial.Polynomial([0, 1]) ** i * np.polynomial.Polynomial([1, -1]) ** (4 - i)
        poly = comb(4, i) * poly
        np.testing.assert_allclose(basis[0][:, i], poly(s), atol=1e-14)
        np.testing.assert_allclose(basis[1][:, i], poly.deriv()(s), atol=1e-12)
        np.testing.assert_allclose(basis[2][:, i], poly.deriv(2)(s), atol=1e-11)


def _loss_fn(interior, n_samples=30, duration=2.0):
    basis = jnp.asarray(optimize.bezier_basis(interior.shape[0] + 2, n_samples))
    controls = optimize._full_controls(interior, START, GOAL, False)
    dt = duration / (n_samples - 1)
    sample = optimize._sample(ROBOT, controls, basis, duration, dt, plan.Limits.create(3), 1)
    return jnp.sum(optimize.DEFAULT_COST(sample))


@pytest.mark.parametrize("seed", [0, 1])
def test_gradient_matches_central_differences(seed):
    interior = jnp.asarray(optimize.straight_line_guess(START, GOAL, 3, noise=15.0, seed=seed)[0])
    grad = np.asarray(jax.grad(_loss_fn)(interior))
    h = 1e-4
    fd = np.zeros_like(grad)
    for idx in np.ndindex(*interior.shape):
        e = np.zeros(interior.shape)
        e[idx] = h
        fd[idx] = (_loss_fn(interior + e) - _loss_fn(interior - e)) / (2 * h)
    np.testing.assert_allclose(grad, fd, rtol=1e-6, atol=1e-8 * np.abs(fd).max())


def test_gradients_finite_when_some_candidates_leave_the_workspace():
    guesses = optimize.straight_line_guess(START, GOAL, 3, n_guesses=2)
    guesses[1] += np.array([200.0, 0.0, 0.0])  # far outside the 130 mm reach
    grad = jax.grad(lambda x: jnp.sum(jax.vmap(_loss_fn)(x)))(jnp.asarray(guesses))
    assert tree_allfinite(grad)
    assert np.abs(np.asarray(grad[1])).sum() > 0  # the unreachable penalty pulls it back


def test_optimiser_decreases_cost_keeps_endpoints_and_leaves_workspace_violations():
    guesses = optimize.straight_line_guess(START, GOAL, 3, n_guesses=4, noise=20.0, seed=3)
    guesses[0] += np.array([80.0, 0.0, 0.0])  # starts partly unreachable
    res = optimize.optimize(
        ROBOT,
        START,
        GOAL,
        guesses,
        duration=2.0,
        n_samples=40,
        steps=150,
        optimizer=optax.adam(2.0),
    )
    history = np.asarray(res.history)
    assert history.shape == (151, 4)
    assert np.all(history[-1] < history[0])
    np.testing.assert_array_equal(res.controls[:, 0], np.broadcast_to(START, (4, 3)))
    np.testing.assert_array_equal(res.controls[:, -1], np.broadcast_to(GOAL, (4, 3)))
    np.testing.assert_allclose(res.path.p[:, 0], np.broadcast_to(START, (4, 3)), atol=1e-12)
    np.testing.assert_allclose(res.path.p[:, -1], np.broadcast_to(GOAL, (4, 3)), atol=1e-12)
    assert np.all(res.evaluation.feasible)


def test_rest_to_rest_paths_start_and_end_at_rest():
    guesses = optimize.straight_line_guess(START, GOAL, 2, n_guesses=1)
    res = optimize.optimize(ROBOT, START, GOAL, guesses, steps=5, rest_to_rest=True)
    np.testing.assert_allclose(res.path.v[:, [0, -1]], 0.0, atol=1e-12)


def test_bad_arguments():
    guesses = optimize.straight_line_guess(START, GOAL, 2)
    with pytest.raises(ValueError, match="start"):
        optimize.optimize(ROBOT, START[:2], GOAL, guesses)
    with pytest.raises(ValueError, match="interior"):
        optimize.optimize(ROBOT, START, GOAL, np.zeros((2, 2, 2)))
    with pytest.raises(ValueError, match="mode"):
        optimize.optimize(ROBOT, START, GOAL, guesses, mode="best")
    with pytest.raises(ValueError, match="threshold"):
        optimize.singularity_barrier(0.0)
