"""The Fig. 4 comparison formulations (benchmarks/formulations.py) solve the same dyads as
jaxkin.dyad, so their timings compare like with like."""

import jax
import numpy as np
import pytest

from jaxkin import Jet, dyad
from tests.references import formulations
from tests.references.dyad import random_dyads


@pytest.mark.parametrize("mode", [1, -1])
def test_relative_and_natural_coordinates_agree_with_the_closed_form(mode):
    arrays, l_ac, l_bc = random_dyads(500, seed=11)
    a, b = Jet.of(*arrays[:3]), Jet.of(*arrays[3:])
    ref = dyad.solve(a, b, l_ac, l_bc, mode)
    ok = np.asarray((ref.status == 0) & (ref.margin > 0.01))
    rel_c, rel_phi = formulations.relative(a, b, l_ac, l_bc, mode)
    nat_c, nat_phi, _ = formulations.natural(a, b, l_ac, l_bc, jax.random.key(0), mode)
    for c in (rel_c, nat_c):
        for field in ("p", "v", "a"):
            mine = np.asarray(getattr(ref.c, field))[ok]
            np.testing.assert_allclose(
                np.asarray(getattr(c, field))[ok], mine, atol=1e-8 * np.abs(mine).max()
            )
    wrap = np.angle(np.exp(1j * (np.asarray(nat_phi.p) - np.asarray(ref.phi.p))))
    np.testing.assert_allclose(wrap[ok], 0.0, atol=1e-10)
    np.testing.assert_allclose(
        np.asarray(nat_phi.a)[ok], np.asarray(ref.phi.a)[ok], rtol=1e-7, atol=1e-7
    )
