"""Trajectory optimisation: Bezier basis, gradients vs finite differences, cost decrease."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxkin import optimize, plan, scara, serial
from tests.helpers import tree_allfinite

ROBOT = scara.Scara.paper()  # [Noriega]: 150, 80, 50 mm
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


def _losses(interior, n_samples=30, duration=2.0):
    """DEFAULT_COST of each guess ``(B, K', 3)`` (branch +1, no limits): the objective
    ``optimize`` minimises, assembled from its parts."""
    basis = jnp.asarray(optimize.bezier_basis(interior.shape[-2] + 2, n_samples))
    controls = optimize._full_controls(interior, START, GOAL, False)
    dt = duration / (n_samples - 1)
    sample = optimize._sample(ROBOT, controls, basis, duration, dt, plan.Limits.create(3), 1)
    return optimize.DEFAULT_COST(sample)


def test_gradients_match_central_differences_also_outside_the_workspace():
    """The gradient of the cost equals central differences (h = 1e-4 mm, 1e-6 relative) for
    two noisy guesses and for one far outside the 130 mm reach, where it is finite and
    non-zero (the unreachable penalty pulls the path back). The guesses' costs are
    independent, so one perturbation of a coordinate serves all three."""
    guesses = [optimize.straight_line_guess(START, GOAL, 3, noise=15.0, seed=s)[0] for s in (0, 1)]
    far = optimize.straight_line_guess(START, GOAL, 3)[0] + np.array([200.0, 0.0, 0.0])
    interior = np.stack([*guesses, far])
    losses = jax.jit(_losses)
    grad = np.asarray(jax.jit(jax.grad(lambda x: jnp.sum(_losses(x))))(interior))
    assert tree_allfinite(grad)
    h = 1e-4
    fd = np.zeros_like(grad)
    for idx in np.ndindex(*interior.shape[1:]):
        e = np.zeros(interior.shape)
        e[(slice(None), *idx)] = h
        fd[(slice(None), *idx)] = (losses(interior + e) - losses(interior - e)) / (2 * h)
    for g, f in zip(grad, fd, strict=True):
        np.testing.assert_allclose(g, f, rtol=1e-6, atol=1e-8 * np.abs(f).max())
    assert np.abs(grad[2]).sum() > 0


def test_optimiser_decreases_cost_keeps_rest_to_rest_ends_and_leaves_workspace_violations():
    """Adam from five guesses, one starting partly outside the workspace: every cost decreases,
    every path ends feasible, and the fixed control points (start and goal twice each: the
    path starts and ends at rest) are kept exactly."""
    guesses = optimize.straight_line_guess(START, GOAL, 3, n_guesses=5, noise=20.0, seed=3)
    guesses[0] += np.array([80.0, 0.0, 0.0])  # starts partly unreachable
    res = optimize.optimize(
        ROBOT,
        START,
        GOAL,
        guesses,
        duration=2.0,
        n_samples=33,
        steps=60,
        optimizer=optimize.Adam(0.05),  # steps in units of the arm's reach (130 mm)
        rest_to_rest=True,
    )
    history = np.asarray(res.history)
    assert history.shape == (61, 5)
    assert np.all(history[-1] < history[0])
    np.testing.assert_array_equal(history[-1], res.cost)
    assert res.controls.shape == (5, 7, 3)
    np.testing.assert_array_equal(res.controls[:, :2], np.broadcast_to(START, (5, 2, 3)))
    np.testing.assert_array_equal(res.controls[:, -2:], np.broadcast_to(GOAL, (5, 2, 3)))
    np.testing.assert_allclose(res.path.p[:, 0], np.broadcast_to(START, (5, 3)), atol=1e-12)
    np.testing.assert_allclose(res.path.p[:, -1], np.broadcast_to(GOAL, (5, 3)), atol=1e-12)
    np.testing.assert_allclose(res.path.v[:, [0, -1]], 0.0, atol=1e-12)
    assert np.all(res.evaluation.feasible)
    assert 0 <= int(res.best) < 5 and float(res.cost[res.best]) == float(np.min(res.cost))


def test_bad_arguments():
    guesses = optimize.straight_line_guess(START, GOAL, 2)
    with pytest.raises(ValueError, match="start"):
        optimize.optimize(ROBOT, START[:2], GOAL, guesses)
    with pytest.raises(ValueError, match="interior"):
        optimize.optimize(ROBOT, START, GOAL, np.zeros((2, 2, 2)))
    with pytest.raises(ValueError, match="branch"):
        optimize.optimize(ROBOT, START, GOAL, guesses, branch="best")
    with pytest.raises(ValueError, match="points"):
        optimize.optimize(serial.Puma560(), START, GOAL, guesses)
    with pytest.raises(ValueError, match="threshold"):
        optimize.singularity_barrier(0.0)
