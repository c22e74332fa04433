"""The optimiser converges, says so, compiles once, keeps guesses apart and avoids obstacles.

The reference optimum comes from scipy's L-BFGS-B run guess by guess on the same objective
(written here from the public pieces: the Bezier basis, the IK through ``jaxkin.ik`` and the
integrated squared joint acceleration), started both from the same guesses and from jaxkin's
own results; compilations are counted with JAX's monitoring events.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy.optimize import minimize

import jaxkin
from jaxkin import Status, delta, optimize, scara, serial
from tests.helpers import compilations

ROBOT = scara.Scara.paper()
START = np.array([100.0, -60.0, 50.0])
GOAL = np.array([100.0, 60.0, 70.0])
N_SAMPLES = 60


def _reference_objective(start, goal, n_interior):
    """The rest-to-rest acceleration objective of one guess, written from the public API."""
    basis = jnp.asarray(optimize.bezier_basis(n_interior + 4, N_SAMPLES))
    dt = 1.0 / (N_SAMPLES - 1)

    @jax.jit
    def value_and_grad(x):
        def f(x):
            interior = x.reshape(n_interior, 3)
            controls = jnp.concatenate(
                [jnp.stack([start, start]), interior, jnp.stack([goal, goal])]
            )
            p = basis[0] @ controls
            path = jaxkin.Jet(p, basis[1] @ controls, basis[2] @ controls)
            q = jaxkin.ik(ROBOT, path).q
            return jnp.sum(q.a**2) * dt

        return jax.value_and_grad(f)(x)

    def scipy_fun(x):
        value, grad = value_and_grad(jnp.asarray(x))
        return float(value), np.asarray(grad)

    return scipy_fun


@pytest.fixture(scope="module")
def problem():
    guesses = optimize.straight_line_guess(START, GOAL, 3, n_guesses=6, noise=10.0, seed=1)
    result = optimize.optimize(
        ROBOT,
        START,
        GOAL,
        guesses,
        rest_to_rest=True,
        cost=optimize.acceleration,
        n_samples=N_SAMPLES,
    )
    return guesses, result


def test_defaults_reach_the_reference_optimum_and_say_so(problem):
    guesses, result = problem
    fun = _reference_objective(jnp.asarray(START), jnp.asarray(GOAL), 3)
    reference = min(
        minimize(fun, g.ravel(), jac=True, method="L-BFGS-B", options=dict(maxiter=2000)).fun
        for g in guesses
    )
    polished = min(
        minimize(fun, np.asarray(c[2:-2]).ravel(), jac=True, method="L-BFGS-B").fun
        for c in result.controls
    )
    best = float(result.cost[int(result.best)])
    assert best <= 1.001 * min(reference, polished)  # within 0.1 % of the reference optimum
    # jaxkin's own cost equals the independently written objective at its controls.
    np.testing.assert_allclose(
        fun(np.asarray(result.controls[0, 2:-2]).ravel())[0], result.cost[0], rtol=1e-10
    )
    assert np.all(np.asarray(result.converged))
    assert np.all(np.asarray(result.iterations) < 500)
    assert np.all(np.asarray(result.grad_norm) >= 0)
    history = np.asarray(result.history)
    assert history.shape == (501, len(guesses))
    np.testing.assert_array_equal(history[-1], result.cost)
    assert np.all(history[-1] <= history[0])


def test_second_call_compiles_nothing(problem):
    guesses, _ = problem
    kwargs = dict(rest_to_rest=True, cost=optimize.acceleration, n_samples=N_SAMPLES, steps=20)
    optimize.optimize(ROBOT, START, GOAL, guesses, **kwargs)
    new = [START + [5.0, 5.0, 0.0], GOAL - [5.0, 0.0, 5.0], guesses + 1.0]
    new = [np.asarray(x) for x in new]
    with compilations() as count:
        optimize.optimize(ROBOT, *new, **kwargs)
    assert count["n"] == 0

    # A composed cost with new weights, a new threshold and moved obstacles: still none.
    def cost(w, threshold, centre):
        obstacles = optimize.Obstacles.create(spheres=([centre], [10.0]), safety=5.0)
        return optimize.compose(
            (w, optimize.acceleration),
            (10.0, optimize.SingularityBarrier(threshold)),
            (1.0, obstacles),
        )

    kwargs.pop("cost")
    optimize.optimize(ROBOT, START, GOAL, guesses, cost=cost(1.0, 0.05, [90.0, 0, 60]), **kwargs)
    costs = [cost(2.0, 0.1, [95.0, 5.0, 60.0]), cost(3.0, 0.2, [85.0, -5.0, 60.0])]
    with compilations() as count:
        for c in costs:
            optimize.optimize(ROBOT, START, GOAL, guesses, cost=c, **kwargs)
    assert count["n"] == 0


def test_guesses_are_independent(problem):
    """A guess optimised alone follows the path it follows among others (its own history and
    line search): the same costs step by step (to 1e-12, the rounding of a differently sized
    batch; at this flat optimum such rounding later changes the iterates by ~1e-5 of the
    robot's size), the same final cost to 1e-9."""
    guesses, result = problem
    alone = optimize.optimize(
        ROBOT,
        START,
        GOAL,
        guesses[2:3],
        rest_to_rest=True,
        cost=optimize.acceleration,
        n_samples=N_SAMPLES,
    )
    np.testing.assert_allclose(alone.history[:40, 0], result.history[:40, 2], rtol=1e-12)
    np.testing.assert_allclose(alone.cost[0], result.cost[2], rtol=1e-9)
    # Coupled guesses (one objective summed over guesses) would change guess 2's first step.
    assert not np.allclose(result.history[1, 2], result.history[1, 3])


def test_adam_and_any_optax_method_remain_available():
    guesses = optimize.straight_line_guess(START, GOAL, 2, n_guesses=2, noise=5.0)
    for method in (optimize.Adam(1e-2), __import__("optax").rmsprop(1e-3)):
        res = optimize.optimize(
            ROBOT, START, GOAL, guesses, optimizer=method, steps=30, n_samples=N_SAMPLES
        )
        assert np.all(np.asarray(res.history[-1]) < np.asarray(res.history[0]))


def test_obstacle_blocking_the_straight_line_is_avoided():
    """A sphere on the straight segment from start to goal: the optimised path keeps every
    link at the safety distance from it (checked with the segments written here)."""
    start, goal = np.array([110.0, -40.0, 60.0]), np.array([110.0, 40.0, 60.0])
    centre, radius, safety = np.array([110.0, 0.0, 60.0]), 8.0, 5.0
    obstacles = optimize.Obstacles.create(spheres=([centre], [radius]), safety=safety)
    cost = optimize.compose((1.0, optimize.acceleration), (1e4, obstacles))
    guesses = optimize.straight_line_guess(start, goal, 3, n_guesses=4, noise=3.0, seed=2)
    res = optimize.optimize(ROBOT, start, goal, guesses, cost=cost, n_samples=40)
    best = int(res.best)
    path = np.asarray(res.path.p[best])
    q = np.asarray(jaxkin.ik(ROBOT, path).q.p)
    theta1, theta2 = q[:, 0], q[:, 1]
    shoulder = np.array([0.0, 0.0, 150.0])
    elbow = shoulder + 80.0 * np.stack([np.cos(theta1), np.sin(theta1), 0 * theta1], -1)
    wrist = elbow + 50.0 * np.stack(
        [np.cos(theta1 - theta2), np.sin(theta1 - theta2), 0 * q[:, 0]], -1
    )

    def distance(a, b):
        ab, ac = b - a, centre - a
        t = np.clip(np.sum(ac * ab, -1) / np.maximum(np.sum(ab * ab, -1), 1e-300), 0, 1)
        return np.linalg.norm(a + t[:, None] * ab - centre, axis=-1) - radius

    clearance = min(
        distance(np.broadcast_to(shoulder, elbow.shape), elbow).min(),
        distance(elbow, wrist).min(),
        distance(wrist, path).min(),
    )
    assert clearance > 0.8 * safety
    straight = start + np.linspace(0, 1, 40)[:, None] * (goal - start)
    assert np.linalg.norm(straight - centre, axis=-1).min() < radius  # the line was blocked
    assert bool(res.evaluation.feasible[best])


@pytest.mark.parametrize(
    ("robot", "start", "goal"),
    [
        (delta.Delta.paper(), [0.0, -5.0, -30.0], [4.0, 5.0, -28.0]),
        (serial.Anthropomorphic(0.3, 0.25, 0.2), [0.3, 0.1, 0.4], [0.1, 0.3, 0.35]),
    ],
)
def test_other_robots_and_joint_space_ends(robot, start, goal):
    guesses = optimize.straight_line_guess(start, goal, 2, n_guesses=2, noise=0.0)
    res = optimize.optimize(robot, start, goal, guesses, n_samples=30, steps=60)
    assert np.all(np.asarray(res.history[-1]) <= np.asarray(res.history[0]))
    assert np.all(np.asarray(res.evaluation.status) == Status.OK)
    q_start, q_goal = (jaxkin.ik(robot, np.asarray(x)).q.p for x in (start, goal))
    joint = optimize.optimize(robot, q_start, q_goal, guesses, n_samples=30, steps=0, space="joint")
    np.testing.assert_allclose(joint.path.p[:, 0], np.broadcast_to(start, (2, 3)), atol=1e-9)
    np.testing.assert_allclose(joint.path.p[:, -1], np.broadcast_to(goal, (2, 3)), atol=1e-9)
