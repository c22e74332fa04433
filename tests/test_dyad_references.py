"""The benchmark references compute what jaxkin computes (so benchmark ratios compare like
with like). The references live in benchmarks/ and are not part of the library."""

import numpy as np
import pytest

from jaxkin import Jet, dyad
from tests.references.dyad import dyad_numpy, dyad_rows, make_numba_dyad, random_dyads


@pytest.mark.parametrize("mode", [1, -1])
@pytest.mark.slow
def test_numpy_and_numba_references_equal_jaxkin(mode):
    arrays, l_ac, l_bc = random_dyads(2000, seed=7)
    res = dyad.solve(Jet.of(*arrays[:3]), Jet.of(*arrays[3:]), l_ac, l_bc, mode)
    ok = np.asarray(res.status == 0) & (np.asarray(res.margin) > 1e-4)
    implementations = [dyad_numpy]
    numba_run = make_numba_dyad()
    if numba_run is not None:
        rows_run = make_numba_dyad(rows=True)

        def via_rows(*arrays_and_lengths):
            *arrs, l_ac, l_bc, mode = arrays_and_lengths
            out = rows_run(dyad_rows(*arrs), l_ac, l_bc, mode)
            return out[0:2].T, out[2:4].T, out[4:6].T, out[6], out[7], out[8]

        implementations += [numba_run, via_rows]
    for impl in implementations:
        c_p, c_v, c_a, phi, phi_dot, phi_ddot = impl(*arrays, l_ac, l_bc, mode)[:6]
        for mine, theirs in ((res.c.p, c_p), (res.c.v, c_v), (res.c.a, c_a)):
            theirs = np.asarray(theirs)[ok]
            scale = np.abs(theirs).max()
            np.testing.assert_allclose(np.asarray(mine)[ok], theirs, atol=1e-9 * scale)
        np.testing.assert_allclose(np.asarray(res.phi.p)[ok], np.asarray(phi)[ok], atol=1e-12)
        np.testing.assert_allclose(
            np.asarray(res.phi.a)[ok], np.asarray(phi_ddot)[ok], rtol=1e-8, atol=1e-8
        )
