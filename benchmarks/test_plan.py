"""Planner throughput: candidates per second for N = 1e2, 1e3, 1e4 candidates of T = 100
samples (SCARA and Delta, float32 and float64, one fixed branch), and optimiser steps per second.
"""

import jax
import numpy as np
import pytest

from jaxkin import delta, optimize, paths, plan, scara

T = 100
SIZES = [100, 1_000, 10_000]


def _bezier_paths(n, start, goal, spread, dtype):
    rng = np.random.default_rng(0)
    interior = (start + goal) / 2 + rng.normal(scale=spread, size=(n, 2, 3))
    controls = np.concatenate(
        [np.broadcast_to(start, (n, 1, 3)), interior, np.broadcast_to(goal, (n, 1, 3))], axis=1
    )
    path = paths.bezier_path(controls, paths.bezier_basis(4, T), 2.0)
    return path.astype(dtype)


ROBOTS = {
    "scara": (
        scara.Scara.create(150.0, 80.0, 50.0),
        np.array([110.0, -50.0, 40.0]),
        np.array([-20.0, 100.0, 80.0]),
        30.0,
        1,
    ),
    "delta": (
        delta.Delta.paper(),
        np.array([-8.0, -5.0, -30.0]),
        np.array([8.0, 6.0, -34.0]),
        4.0,
        "out",
    ),
}


@pytest.mark.parametrize("n", SIZES)
@pytest.mark.parametrize("dtype", ["float64", "float32"])
@pytest.mark.parametrize("robot_name", list(ROBOTS))
def test_plan_evaluate(measure, robot_name, dtype, n):
    robot, start, goal, spread, branch = ROBOTS[robot_name]
    path = _bezier_paths(n, start, goal, spread, np.dtype(dtype))
    measure(
        lambda: plan.evaluate(robot, path, branch=branch, dt=2.0 / (T - 1)),
        n,
        kernel=f"plan.evaluate[{robot_name}]",
        dtype=dtype,
        samples_per_candidate=T,
    )


@pytest.mark.parametrize("n_guesses", [8, 64])
def test_optimiser_steps(measure, n_guesses):
    robot, start, goal, _, _ = ROBOTS["scara"]
    guesses = paths.straight_line_guess(start, goal, 3, n_guesses=n_guesses, noise=5.0)
    steps = 50
    result = measure(
        lambda: optimize.optimize(robot, start, goal, guesses, n_samples=T, steps=steps).history,
        steps,
        kernel="optimize.optimize (steps/s)",
        dtype="float64",
        n_guesses=n_guesses,
    )
    assert np.all(np.isfinite(np.asarray(jax.device_get(result))))


def _joint_candidates(n):
    """SCARA joint-space candidates: splines through 4 random waypoints, T samples."""
    rng = np.random.default_rng(1)
    start, goal = np.array([0.2, 1.2, 60.0]), np.array([1.4, 0.6, 90.0])
    middle = start + (goal - start) * np.array([[1 / 3], [2 / 3]])
    middle = middle + rng.normal(size=(n, 2, 3)) * [0.1, 0.1, 3.0]
    ends = [np.broadcast_to(x, (n, 1, 3)) for x in (start, goal)]
    waypoints = np.concatenate([ends[0], middle, ends[1]], axis=1)
    return paths.path_from_joint_waypoints(waypoints, 0.02, (T - 1) // 3)


JOINT_LIMITS = plan.Limits.create(
    3, v_max=[3.0, 3.0, 150.0], a_max=[12.0, 12.0, 600.0]
)  # rad, mm per second


@pytest.mark.parametrize("n", [1_000])
def test_plan_evaluate_joint_space(measure, n):
    robot, path = ROBOTS["scara"][0], _joint_candidates(n)
    measure(
        lambda: plan.evaluate(robot, path, JOINT_LIMITS),
        n,
        kernel="plan.evaluate[scara, joint space]",
        dtype="float64",
        samples_per_candidate=path.shape[1],
    )


@pytest.mark.parametrize("n", [1_000])
def test_plan_retime(measure, n):
    ev = plan.evaluate(ROBOTS["scara"][0], _joint_candidates(n), JOINT_LIMITS)
    measure(
        lambda: plan.retime(ev).duration,
        n,
        kernel="plan.retime[scara]",
        dtype="float64",
        samples_per_candidate=ev.q.shape[1],
    )
