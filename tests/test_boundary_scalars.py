"""NumPy scalars at the boundary: ``np.float32(1.0)`` is a number wherever a number is asked
(time steps, weights, safety distances, thresholds), and ``np.int64(3)`` a count wherever a
count is asked, through the shared validators of ``jaxkin._validate``; booleans, strings,
arrays and non-finite values stay refused."""

import jax
import numpy as np
import pytest

from jaxkin import _validate, costs, paths

SCALARS = [np.float32(0.5), np.float64(0.5), np.int64(2), np.asarray(0.5), np.float16(0.5)]


@pytest.mark.parametrize("value", SCALARS, ids=lambda v: type(v).__name__)
def test_numpy_scalars_are_accepted(value):
    expected = float(value)
    positions = np.stack([np.linspace(0.0, 1.0, 5)] * 2, -1)
    ref = paths.path_from_samples(positions, expected)
    got = paths.path_from_samples(positions, value)
    np.testing.assert_array_equal(np.asarray(got.v), np.asarray(ref.v))
    assert costs.singularity_barrier(value).threshold == expected
    assert float(costs.Obstacles.create(safety=value).safety) == expected
    total = costs.compose((value, costs.jerk))
    assert [float(w) for w in jax.tree.leaves(total)] == [expected]


@pytest.mark.parametrize(
    "value", [True, np.bool_(True), "1.0", np.array([1.0]), np.nan, np.float32(np.inf), -1.0, 0]
)
def test_non_numbers_and_bad_values_are_refused(value):
    with pytest.raises(ValueError, match="dt must be a positive finite number"):
        paths.path_from_samples(np.zeros((3, 2)), value)
    with pytest.raises(ValueError, match="threshold must be a positive finite number"):
        costs.singularity_barrier(value)


def test_validators_name_the_argument_and_return_floats():
    assert type(_validate.positive_number(np.float32(2.0), "dt")) is float
    assert _validate.finite_number(np.float32(-2.0), "w") == -2.0
    assert _validate.nonnegative_number(np.float64(np.inf), "duration") == np.inf
    with pytest.raises(ValueError, match="w must be a finite number"):
        _validate.finite_number(np.float32(np.nan), "w")
    with pytest.raises(ValueError, match="duration must be a non-negative number"):
        _validate.nonnegative_number(np.float32(-1.0), "duration")


def test_delta_fk_tolerance_takes_a_numpy_scalar():
    from jaxkin.delta.options import DeltaFKOptions

    assert DeltaFKOptions(tol=np.float32(0.5)).tol == 0.5
    with pytest.raises(ValueError, match="tol must be a positive finite number"):
        DeltaFKOptions(tol=np.float32(-1.0))


COUNTS = [np.int64(3), np.int32(3), np.uint8(3), np.asarray(3)]
NOT_COUNTS = [True, np.bool_(True), 2.5, np.float64(3.0), "3", np.array([3]), None]


def count_arguments():
    """Every count argument of the public API, as ``(name, call)``: ``call(n)`` passes the
    count ``n`` (the other arguments valid) and returns what it made of it, cheaply (host
    side or a small program); ``None`` where only the refusal is cheap to test."""
    from jaxkin import collision, newton, plan, plot, robot, scara, serial, timing, workspace
    from jaxkin.delta.options import DeltaFKOptions
    from jaxkin.serial.search import ChainIKOptions

    timed = timing.Timing(
        np.array([0.2, 0.0]), np.array([0, 9], np.int8), np.array([[0.0, 0.1, 0.2]] * 2),
        np.zeros((2, 3)), np.zeros((2, 2)),
    )  # fmt: skip
    grid = timing.JointPath(*(np.zeros((2, 3, 1)) if k else np.zeros((2, 3)) for k in range(4)))
    totals = plan.Costs(*([np.array([1.0, np.inf])] * 9))
    ev = plan.Evaluation(None, None, np.array([True, False]), None, None, None, totals)
    way, arm = np.zeros((1, 2, 1)), scara.Scara.paper()
    chain = serial.Chain.create([[0.0, 0.0, 1.0, 0.0, 0.0, 0.0]], np.eye(4))
    return [
        ("subdivisions", lambda n: timing.path_from_waypoints(way, n).s.shape[-1] - 1),
        ("num", lambda n: timing.sample(grid, timed, 0.1, num=n).t.shape[0]),
        ("k", lambda n: len(timing.best(timed, n)[0]) * n),
        ("k", lambda n: len(plan.best(ev, n)[0]) * n),
        ("n_joints", lambda n: plan.Limits.create(n).q_min.shape[0]),
        ("steps", lambda n: paths.path_from_joint_waypoints(way, 0.1, n).shape[1] - 1),
        ("n_ctrl", lambda n: paths.bezier_basis(n, 4).shape[-1]),
        ("n_samples", lambda n: paths.bezier_basis(2, n).shape[1]),
        ("n_interior", lambda n: paths.straight_line_guess([0.0], [1.0], n).shape[1]),
        ("n_guesses", lambda n: paths.straight_line_guess([0.0], [1.0], 1, n).shape[0]),
        ("n", lambda n: robot.JointLimits.unbounded(n).lower.shape[0]),
        ("max_iter", lambda n: DeltaFKOptions(max_iter=n).max_iter),
        ("restarts", lambda n: ChainIKOptions(restarts=n).restarts),
        ("max_iter", lambda n: ChainIKOptions(max_iter=n).max_iter),
        ("warm_iter", lambda n: ChainIKOptions(warm_iter=n).warm_iter),
        ("max_iter", lambda n: newton.solve(lambda x, a, s: (x[0] - 1,), [0.0], max_iter=n) and n),
        ("max_iter", lambda n: serial.ik_newton(chain, np.eye(4), [0.0], max_iter=n) and n),
        ("chunk_size", None, lambda n: workspace.sweep(arm, chunk_size=n)),
        (
            "chunk_size",
            None,
            lambda n: plan.evaluate(
                arm, paths.path_from_samples(np.zeros((1, 3, 3)), 0.1), chunk_size=n
            ),
        ),  # fmt: skip
        (
            "samples",
            None,
            lambda n: collision.validate_motions(
                arm, np.zeros(3), np.ones(3), collision.World.create(), 1.0, samples=n
            ),
        ),  # fmt: skip
        ("n_slices", None, lambda n: plot.workspace_slices(None, n_slices=n)),
    ]


def test_numpy_integers_are_counts_everywhere():
    """Every count argument takes a NumPy integer (or a 0-d integer array) as its int: the
    same result as ``3`` (they were refused: ``isinstance(n, int)``)."""
    for name, call, *_ in count_arguments():
        if call is None:
            continue
        expected = call(3)
        for value in COUNTS:
            assert call(value) == expected, (name, value)


@pytest.mark.parametrize("value", NOT_COUNTS, ids=repr)
def test_bools_floats_and_non_numbers_are_not_counts(value):
    """Booleans, floats (with a fraction or not), strings, arrays and None are refused,
    naming the argument (None is a count's default for ``num`` and ``samples`` only)."""
    for name, *calls in count_arguments():
        call = calls[-1]
        if value is None and name in ("num", "samples", "chunk_size"):
            continue
        with pytest.raises(ValueError, match=f"{name} must be an integer >= "):
            call(value)
    assert (
        _validate.count(np.int64(0), "n", minimum=0) == 0
        and type(_validate.count(np.uint8(3), "n")) is int
    )
