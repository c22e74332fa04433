"""Throughput of jaxkin.dyad.solve (position + velocity + acceleration) beside references.

Batch sizes 1e3, 1e5, 1e6; float64 and float32; analytic and autodiff paths; the NumPy
reference of the same formulas (and a fused Numba loop when numba is installed). Each records
cases/s in ``extra_info``; compare ratios within one run (absolute times are noisy).
"""

import numpy as np
import pytest

from jaxkin import Jet, dyad
from tests.references.dyad import dyad_numpy, make_numba_dyad, random_dyads

SIZES = [1_000, 100_000, 1_000_000]


@pytest.mark.parametrize("n", SIZES)
@pytest.mark.parametrize("dtype", ["float64", "float32"])
@pytest.mark.parametrize("method", ["analytic", "autodiff"])
def test_jaxkin_dyad(measure, n, dtype, method):
    arrays, l_ac, l_bc = random_dyads(n, dtype=np.dtype(dtype))
    a, b = Jet.of(*arrays[:3]), Jet.of(*arrays[3:])
    measure(
        lambda: dyad.solve(a, b, l_ac, l_bc, 1, method),
        n,
        kernel=f"jaxkin.dyad[{method}]",
        dtype=dtype,
    )


@pytest.mark.parametrize("n", SIZES)
@pytest.mark.parametrize("dtype", ["float64", "float32"])
def test_numpy_reference_dyad(measure, n, dtype):
    arrays, l_ac, l_bc = random_dyads(n, dtype=np.dtype(dtype))
    measure(lambda: dyad_numpy(*arrays, l_ac, l_bc), n, kernel="numpy", dtype=dtype)


@pytest.mark.parametrize("n", SIZES)
def test_numba_reference_dyad(measure, n):
    run = make_numba_dyad()
    if run is None:
        pytest.skip("numba not installed (pip install -e '.[bench]')")
    arrays, l_ac, l_bc = random_dyads(n)
    measure(lambda: run(*arrays, l_ac, l_bc), n, kernel="numba", dtype="float64")
