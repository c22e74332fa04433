"""NumPy scalars at the boundary: ``np.float32(1.0)`` is a number wherever a number is asked
(time steps, weights, safety distances, thresholds), through the shared validators of
``jaxkin._validate``; booleans, strings, arrays and non-finite values stay refused."""

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
