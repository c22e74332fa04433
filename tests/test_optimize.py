"""Trajectory optimisation: the Bezier basis, gradients, convergence to a reference optimum,
one compilation per configuration, independent guesses, obstacles and every robot.

The reference optimum comes from scipy's L-BFGS-B run guess by guess on the same objective
(written here from the public pieces: the Bezier basis, the IK through ``jaxkin.ik`` and the
integrated squared joint acceleration), started both from the same guesses and from jaxkin's
own results; compilations are counted with JAX's monitoring events. The tests share a few
configurations (method, cost structure, shapes), so each compiles once in this file.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import optax
import pytest
from scipy.optimize import minimize

import jaxkin
from jaxkin import Status, costs, delta, optimize, paths, plan, scara, serial
from tests.helpers import compilations, tree_allfinite

ROBOT = scara.Scara.paper()  # [Noriega]: 150, 80, 50 mm
START = np.array([100.0, -60.0, 50.0])
GOAL = np.array([100.0, 60.0, 70.0])
N_SAMPLES = 60
# The shared configuration: 6 guesses of 3 interior points, rest to rest, 60 samples.
KWARGS = dict(rest_to_rest=True, n_samples=N_SAMPLES)


def _guesses(seed=1, noise=10.0, start=START, goal=GOAL):
    return paths.straight_line_guess(start, goal, 3, n_guesses=6, noise=noise, seed=seed)


def _with_obstacle(weight, threshold, centre, radius=10.0, safety=5.0):
    """The composed cost shared by the tests below (one structure: one compilation)."""
    obstacles = costs.Obstacles.create(spheres=([centre], [radius]), safety=safety)
    return costs.compose(
        (weight, costs.acceleration),
        (10.0, costs.SingularityBarrier(threshold)),
        (1e4, obstacles),
    )


def test_bezier_basis_partition_of_unity_and_derivatives():
    basis = paths.bezier_basis(5, 201)
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
    basis = jnp.asarray(paths.bezier_basis(interior.shape[-2] + 2, n_samples))
    controls = paths.bezier_controls(interior, START, GOAL, False)
    dt = duration / (n_samples - 1)
    sample = optimize._sample(ROBOT, controls, basis, duration, dt, plan.Limits.create(3), 1)
    return costs.DEFAULT_COST(sample)


def test_gradients_match_central_differences_also_outside_the_workspace():
    """The gradient of the cost equals central differences (h = 1e-4 mm, 1e-6 relative) for
    two noisy guesses and for one far outside the 130 mm reach, where it is finite and
    non-zero (the unreachable penalty pulls the path back). The guesses' costs are
    independent, so one perturbation of a coordinate serves all three."""
    guesses = [paths.straight_line_guess(START, GOAL, 3, noise=15.0, seed=s)[0] for s in (0, 1)]
    far = paths.straight_line_guess(START, GOAL, 3)[0] + np.array([200.0, 0.0, 0.0])
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


@pytest.mark.slow
def test_adam_decreases_cost_keeps_rest_to_rest_ends_and_leaves_workspace_violations():
    """Adam from six guesses, one starting partly outside the workspace: every cost decreases,
    every path ends feasible, and the fixed control points (start and goal twice each: the
    path starts and ends at rest) are kept exactly. Any optax transformation works too."""
    guesses = _guesses(seed=3, noise=20.0)
    guesses[0] += np.array([80.0, 0.0, 0.0])  # starts partly unreachable
    res = optimize.optimize(
        ROBOT, START, GOAL, guesses, steps=60, optimizer=optimize.Adam(0.05), **KWARGS
    )
    history = np.asarray(res.history)
    assert history.shape == (61, 6)
    assert np.all(history[-1] < history[0])
    np.testing.assert_array_equal(history[-1], res.cost)
    assert res.controls.shape == (6, 7, 3)
    np.testing.assert_array_equal(res.controls[:, :2], np.broadcast_to(START, (6, 2, 3)))
    np.testing.assert_array_equal(res.controls[:, -2:], np.broadcast_to(GOAL, (6, 2, 3)))
    np.testing.assert_allclose(res.path.p[:, 0], np.broadcast_to(START, (6, 3)), atol=1e-12)
    np.testing.assert_allclose(res.path.p[:, -1], np.broadcast_to(GOAL, (6, 3)), atol=1e-12)
    np.testing.assert_allclose(res.path.v[:, [0, -1]], 0.0, atol=1e-12)
    assert np.all(res.evaluation.feasible)
    assert 0 <= int(res.best) < 6 and float(res.cost[res.best]) == float(np.min(res.cost))
    other = optimize.optimize(
        ROBOT, START, GOAL, guesses, steps=60, optimizer=optax.rmsprop(1e-3), **KWARGS
    )
    assert np.all(np.asarray(other.history[-1]) < np.asarray(other.history[0]))


def _reference_objective(start, goal, n_interior):
    """The rest-to-rest acceleration objective of one guess, written from the public API."""
    basis = jnp.asarray(paths.bezier_basis(n_interior + 4, N_SAMPLES))
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
    guesses = _guesses()
    result = optimize.optimize(ROBOT, START, GOAL, guesses, cost=costs.acceleration, **KWARGS)
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
    new = [START + [5.0, 5.0, 0.0], GOAL - [5.0, 0.0, 5.0], guesses + 1.0]
    new = [np.asarray(x) for x in new]
    with compilations() as count:  # NumPy scalars are numbers too
        optimize.optimize(
            ROBOT, *new, cost=costs.acceleration, duration=np.float32(1.0), steps=np.int64(500),
            gtol=np.float64(1e-7), rest_to_rest=True, n_samples=np.int32(N_SAMPLES),
        )  # fmt: skip
    assert count.n == 0

    # A composed cost with new weights, a new threshold and moved obstacles: one compilation
    # for the first, none for the others.
    optimize.optimize(
        ROBOT, START, GOAL, guesses, cost=_with_obstacle(1.0, 0.05, [90.0, 0, 60]), **KWARGS
    )
    moved = [
        _with_obstacle(2.0, 0.1, [95.0, 5.0, 60.0]),
        _with_obstacle(3.0, 0.2, [85.0, -5.0, 60.0]),
    ]
    with compilations() as count:
        for c in moved:
            optimize.optimize(ROBOT, START, GOAL, guesses, cost=c, **KWARGS)
    assert count.n == 0


def test_progress_hears_the_steps_and_changes_nothing(problem):
    """``progress(done, total)`` hears the furthest guess's steps every ``PROGRESS_BLOCK``
    loop iterations (the loop then runs in blocks): the result is the one run without it."""
    guesses, result = problem
    calls = []
    report = lambda done, total: calls.append((done, total))  # noqa: E731
    again = optimize.optimize(
        ROBOT, START, GOAL, guesses, cost=costs.acceleration, progress=report, **KWARGS
    )
    np.testing.assert_array_equal(again.history, result.history)
    np.testing.assert_array_equal(again.controls, result.controls)
    done, totals = zip(*calls, strict=True)
    assert set(totals) == {500} and done[0] == 0 and len(calls) > 2
    assert list(done) == sorted(done) and done[-1] == int(np.max(result.iterations))


def test_converged_only_where_the_stopping_rule_held_near_the_workspace(problem):
    """A guess 100 robot sizes away (every sample unreachable: its cost, the acceleration,
    is flat there) meets the gradient rule where it starts, far outside the workspace box:
    it is reported diverged, not converged; the fixture's guesses converged. Same shapes as
    the fixture: no compilation."""
    guesses, result = problem
    assert np.all(np.asarray(result.stop) == optimize.Stop.CONVERGED)
    far = guesses.copy()
    far[4] += 100 * 130.0
    res = optimize.optimize(ROBOT, START, GOAL, far, cost=costs.acceleration, **KWARGS)
    stop = np.asarray(res.stop)
    assert stop[4] == optimize.Stop.DIVERGED and not bool(res.converged[4])
    np.testing.assert_array_equal(np.asarray(res.converged), stop == optimize.Stop.CONVERGED)
    np.testing.assert_array_equal(stop[[0, 1, 2, 3, 5]], optimize.Stop.CONVERGED)
    assert not bool(res.evaluation.feasible[4])


def test_guesses_are_independent(problem):
    """A guess optimised among other guesses follows the path it follows among the fixture's
    (its own history and line search): with every other guess replaced, guess 2's costs step
    by step and its result are the same to rounding."""
    guesses, result = problem
    others = _guesses(seed=7, noise=15.0)
    others[2] = guesses[2]
    again = optimize.optimize(ROBOT, START, GOAL, others, cost=costs.acceleration, **KWARGS)
    np.testing.assert_allclose(again.history[:, 2], result.history[:, 2], rtol=1e-12)
    np.testing.assert_allclose(again.controls[2], result.controls[2], rtol=1e-12)
    assert not np.allclose(again.history[:, 3], result.history[:, 3])
    # Coupled guesses (one objective summed over guesses) would change guess 2's first step.
    assert not np.allclose(result.history[1, 2], result.history[1, 3])


def test_obstacle_blocking_the_straight_line_is_avoided():
    """A sphere on the straight segment from start to goal: the optimised path keeps every
    link at the safety distance from it (checked with the segments written here)."""
    start, goal = np.array([110.0, -40.0, 60.0]), np.array([110.0, 40.0, 60.0])
    centre, radius, safety = np.array([110.0, 0.0, 60.0]), 8.0, 5.0
    cost = _with_obstacle(1.0, 0.05, centre, radius, safety)
    guesses = _guesses(seed=2, noise=3.0, start=start, goal=goal)
    res = optimize.optimize(ROBOT, start, goal, guesses, cost=cost, **KWARGS)
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
    straight = start + np.linspace(0, 1, N_SAMPLES)[:, None] * (goal - start)
    assert np.linalg.norm(straight - centre, axis=-1).min() < radius  # the line was blocked
    assert bool(res.evaluation.feasible[best])


@pytest.mark.slow
@pytest.mark.parametrize(
    ("robot", "start", "goal"),
    [
        (delta.Delta.paper(), [0.0, -5.0, -30.0], [4.0, 5.0, -28.0]),
        (serial.Anthropomorphic(0.3, 0.25, 0.2), [0.3, 0.1, 0.4], [0.1, 0.3, 0.35]),
    ],
)
def test_other_robots_and_joint_space_ends(robot, start, goal):
    """The defaults on other robots; the same ends given as joints (their forward kinematics)
    give the same problem (no new compilation either)."""
    guesses = paths.straight_line_guess(start, goal, 2, n_guesses=2, noise=0.0)
    res = optimize.optimize(robot, start, goal, guesses, n_samples=30, steps=60)
    assert np.all(np.asarray(res.history[-1]) <= np.asarray(res.history[0]))
    assert np.all(np.asarray(res.evaluation.status) == Status.OK)
    q_start, q_goal = (jaxkin.ik(robot, np.asarray(x)).q.p for x in (start, goal))
    jaxkin.fk(robot, q_start)  # the ends' forward kinematics compiles on its own
    with compilations() as count:
        joint = optimize.optimize(
            robot, q_start, q_goal, guesses, n_samples=30, steps=60, space="joint"
        )
    assert count.n == 0
    np.testing.assert_allclose(joint.path.p[:, 0], np.broadcast_to(start, (2, 3)), atol=1e-9)
    np.testing.assert_allclose(joint.path.p[:, -1], np.broadcast_to(goal, (2, 3)), atol=1e-9)
    np.testing.assert_allclose(joint.cost, res.cost, rtol=1e-9)


def _joint_controls(a_max):
    """The SCARA optimised with joint-space controls between the ends' joints (a short run
    of the shared shape: 2 guesses, 20 samples)."""
    limits = plan.Limits.create(3, v_max=[3.0, 3.0, 300.0], a_max=a_max)
    q_ends = [np.asarray(jaxkin.ik(ROBOT, x).q.p) for x in (START, GOAL)]
    guesses = paths.straight_line_guess(*q_ends, 3, n_guesses=2, noise=0.01, seed=1)
    kwargs = dict(n_samples=20, steps=10, space="joint", controls="joint")
    return optimize.optimize(
        ROBOT, *q_ends, guesses, limits=limits, cost=costs.acceleration, **kwargs
    ).evaluation


def test_joint_controls_evaluation_can_be_retimed():
    """Joint-space controls: the optimiser's evaluation is a first-class ``plan.Evaluation``
    (it carried no dt, space or limits, so ``plan.retime`` refused it): ``plan.retime`` and
    ``best(by="duration")`` take it, with the durations of ``timing.retime`` on its joint
    path under the limits applied (1e-12)."""
    from jaxkin import timing

    ev = _joint_controls([20.0, 20.0, 2000.0])
    assert ev.space == "joint" and ev.dt == pytest.approx(1.0 / 19)
    timed = plan.retime(ev)
    alone = timing.retime(plan.joint_path(ev), [3.0, 3.0, 300.0], [20.0, 20.0, 2000.0])
    ok = np.asarray(timed.ok)
    assert np.all(ok == np.asarray(ev.feasible)) and np.any(ok)
    np.testing.assert_allclose(timed.duration[ok], alone.duration[ok], rtol=1e-12)
    order, durations = plan.best(ev, 2, by="duration", timing=timed)
    np.testing.assert_allclose(durations, np.sort(np.asarray(alone.duration)[ok]), rtol=1e-12)


@pytest.mark.slow
def test_joint_controls_costs_are_the_planners():
    """The joint-space controls' costs are the planner's evaluation of the same joint
    trajectories (each joint in its unit: the column's 130 mm, where they were in 1 mm);
    an acceleration limit missing on the column is named by ``plan.retime``."""
    ev = _joint_controls([20.0, 20.0, np.inf])
    limits = ev.applied_limits()
    planner = plan.evaluate(ROBOT, paths.Path.from_jet(ev.q, ev.dt, "joint"), limits)
    np.testing.assert_array_equal(ev.feasible, planner.feasible)
    for name in ("path_length", "integrated_speed", "integrated_acceleration", "total"):
        np.testing.assert_allclose(
            getattr(ev.costs, name), getattr(planner.costs, name), rtol=1e-12
        )
    with pytest.raises(ValueError, match="l3 has none"):
        plan.retime(ev)


def test_bad_arguments():
    guesses = paths.straight_line_guess(START, GOAL, 2)
    with pytest.raises(ValueError, match="start"):
        optimize.optimize(ROBOT, START[:2], GOAL, guesses)
    with pytest.raises(ValueError, match="interior"):
        optimize.optimize(ROBOT, START, GOAL, np.zeros((2, 2, 2)))
    with pytest.raises(ValueError, match="interior: no guesses"):
        optimize.optimize(ROBOT, START, GOAL, np.zeros((0, 2, 3)))
    for duration in (np.inf, np.nan, 0.0, -1.0, "1"):
        with pytest.raises(ValueError, match="duration"):
            optimize.optimize(ROBOT, START, GOAL, guesses, duration=duration)
    with pytest.raises(ValueError, match="branch"):
        optimize.optimize(ROBOT, START, GOAL, guesses, branch="best")
    with pytest.raises(ValueError, match="controls"):
        optimize.optimize(serial.Puma560(), START, GOAL, guesses, controls="task")
    with pytest.raises(ValueError, match="controls"):
        optimize.optimize(ROBOT, START, GOAL, guesses, controls="cartesian")
    with pytest.raises(ValueError, match="progress must be None or a callable"):
        optimize.optimize(ROBOT, START, GOAL, guesses, progress=True)
    # Pose ends: a 4x4 matrix whose rotation is not orthonormal, a zero quaternion.
    puma, pose = serial.Puma560(), np.eye(4)
    joints = np.zeros((1, 2, 6))
    with pytest.raises(ValueError, match="start: a pose"):
        optimize.optimize(puma, 1.05 * pose, pose, joints)
    with pytest.raises(ValueError, match="goal"):
        optimize.optimize(puma, pose, (np.zeros(3), np.zeros(4)), joints)
    with pytest.raises(ValueError, match="start"):
        optimize.optimize(puma, START, pose, joints)
    with pytest.raises(ValueError, match="threshold"):
        costs.singularity_barrier(0.0)


def _joint_acceleration_cost(controls, n_samples, duration):
    """``sum_t |q_ddot|^2 dt`` of joint Bezier curves ``(B, K, n)``, with NumPy's own
    Bernstein second derivatives (independent of ``paths.bezier_basis``)."""
    from math import comb

    k = controls.shape[1] - 1
    s = np.linspace(0.0, 1.0, n_samples)
    second = np.stack(
        [
            (comb(k, i) * np.polynomial.Polynomial([0, 1]) ** i
             * np.polynomial.Polynomial([1, -1]) ** (k - i)).deriv(2)(s)
            for i in range(k + 1)
        ],
        axis=1,
    )  # fmt: skip
    acc = np.einsum("tk,bkn->btn", second, controls) / duration**2
    return np.sum(acc**2, axis=(1, 2)) * duration / (n_samples - 1)


def _quaternion(rotation):
    """``(w, x, y, z)`` of a rotation matrix (w > 0 here), by the trace formula."""
    w = 0.5 * np.sqrt(1.0 + np.trace(rotation))
    r = rotation
    return np.array([w, r[2, 1] - r[1, 2], r[0, 2] - r[2, 0], r[1, 0] - r[0, 1]]) / [
        1,
        *[4 * w] * 3,
    ]


ARMS = {
    "puma560": lambda: serial.Puma560(),
    "ur5 urdf": lambda: serial.from_urdf("examples/ur5.urdf", "tool0"),
}


@pytest.mark.slow
@pytest.mark.parametrize("name", list(ARMS))
def test_pose_target_arms_in_joint_space(name):
    """A pose-target arm (PUMA 560, the UR5 chain from URDF): pose ends as 4x4 matrices and
    as (position, quaternion) give the same problem; the optimised trajectories start and
    end at those poses (forward kinematics of the ends), their cost equals the joint
    acceleration integral of the returned controls written with NumPy (1e-9 relative), the
    joints are those controls' curve, every guess converged and is feasible, the solved goal
    is the turn of each revolute joint nearest the start, and those joint ends give the same
    result without a new compilation."""
    arm = ARMS[name]()
    q_start = np.array([0.3, -0.9, 0.8, 0.2, 0.5, 0.1])
    q_goal = np.array([1.1, -0.5, 0.4, -0.4, 0.9, 0.7])
    poses = [np.asarray(jaxkin.fk(arm, q).x.p) for q in (q_start, q_goal)]
    solved = [np.asarray(jaxkin.ik(arm, pose).q.p) for pose in poses]
    guesses = paths.straight_line_guess(*solved, 2, n_guesses=3, noise=0.1, seed=0)
    kwargs = dict(n_samples=30, steps=200, rest_to_rest=True, cost=costs.acceleration)
    res = optimize.optimize(arm, *poses, guesses, **kwargs)
    quat = [(pose[:3, 3], _quaternion(pose[:3, :3])) for pose in poses]
    again = optimize.optimize(arm, *quat, guesses, **kwargs)
    np.testing.assert_allclose(again.cost, res.cost, rtol=1e-9, atol=1e-12)
    for end, pose in ((0, poses[0]), (-1, poses[1])):
        np.testing.assert_allclose(res.path.p[:, end], np.broadcast_to(pose, (3, 4, 4)), atol=1e-9)
    controls = np.asarray(res.controls)
    assert controls.shape == (3, 6, 6)
    expected = _joint_acceleration_cost(controls, 30, 1.0)
    np.testing.assert_allclose(res.cost, expected, rtol=1e-9, atol=1e-12)
    assert np.all(np.asarray(res.converged)) and np.all(np.asarray(res.evaluation.feasible))
    assert np.all(np.asarray(res.cost) <= np.asarray(res.history[0]))
    fk_path = jaxkin.fk(arm, res.evaluation.q).x
    np.testing.assert_allclose(fk_path.p, res.path.p, atol=1e-9)
    # The goal's revolute joints were moved by whole turns to those nearest the start's.
    ends = controls[0, 0], controls[0, -1]
    np.testing.assert_allclose(jaxkin.fk(arm, ends[1]).x.p, poses[1], atol=1e-9)
    turns = (ends[1] - solved[1]) / (2 * np.pi)
    np.testing.assert_allclose(turns, np.round(turns), atol=1e-9)
    assert np.all(np.abs(ends[1] - ends[0]) <= np.pi + 1e-9)
    with compilations() as count:
        joint = optimize.optimize(arm, *ends, guesses, space="joint", **kwargs)
    assert count.n == 0
    np.testing.assert_allclose(joint.cost, res.cost, rtol=1e-9, atol=1e-12)


@pytest.mark.slow
@pytest.mark.parametrize(
    ("robot", "q_start", "q_goal"),
    [
        (scara.Scara.paper(), [0.3, 1.0, 30.0], [2.0, 1.2, 60.0]),
        (delta.Delta.paper(), [-0.2, 0.1, 0.3], [0.2, 0.3, -0.1]),
    ],
)
def test_point_robots_in_joint_space(robot, q_start, q_goal):
    """Joint-space controls for point robots (SCARA, Delta): joint ends kept exactly, the
    tool path their forward kinematics, the cost the NumPy acceleration integral, and a
    joint limit that the straight joint line passes (the robot's own position limits
    intersected with ``limits``) respected by the optimum through the default cost."""
    q_start, q_goal = np.asarray(q_start), np.asarray(q_goal)
    guesses = paths.straight_line_guess(q_start, q_goal, 2, n_guesses=2, noise=0.05, seed=0)
    kwargs = dict(n_samples=30, steps=200, rest_to_rest=True, space="joint", controls="joint")
    res = optimize.optimize(robot, q_start, q_goal, guesses, cost=costs.acceleration, **kwargs)
    controls = np.asarray(res.controls)
    np.testing.assert_array_equal(controls[:, 0], np.broadcast_to(q_start, (2, 3)))
    np.testing.assert_array_equal(controls[:, -1], np.broadcast_to(q_goal, (2, 3)))
    np.testing.assert_allclose(res.cost, _joint_acceleration_cost(controls, 30, 1.0), rtol=1e-9)
    np.testing.assert_allclose(res.path.p, jaxkin.fk(robot, res.evaluation.q.p).x.p, atol=1e-9)
    assert np.all(np.asarray(res.converged))
    # A bound on joint 0 that the rest-to-rest optimum (which overshoots nothing) keeps, and
    # the default cost's limit penalty keeping the optimum inside a speed limit it passes.
    peak = float(np.max(np.abs(np.asarray(res.evaluation.q.v[..., 0]))))
    limits = plan.Limits.create(3, v_max=[0.9 * peak, np.inf, np.inf])
    limited = optimize.optimize(robot, q_start, q_goal, guesses, limits=limits, **kwargs)
    assert not np.all(np.asarray(res.evaluation.q.v[..., 0]) <= 0.9 * peak)
    speed = np.abs(np.asarray(limited.evaluation.q.v[..., 0]))
    assert np.max(speed) <= 0.9 * peak * (1 + 1e-3)
