"""The test helpers themselves: compilations counted through JAX's monitoring events."""

import jax
import jax.numpy as jnp

from tests.helpers import compilations, marked_slow


def test_compilations_counts_new_specialisations_only():
    def twice_plus_one(x):
        return 2.0 * x + 1.0

    fn = jax.jit(twice_plus_one)
    with compilations() as first:
        fn(jnp.ones(3))
    with compilations() as again:
        fn(jnp.zeros(3))  # same shape and dtype: the compiled program
    with compilations() as other:
        fn(jnp.ones(4))  # a new shape: a new specialisation
    assert first.compiled("twice_plus_one") == 1 and first.n >= 1
    assert again.n == 0
    assert other.compiled("twice_plus_one") == 1


def test_marked_slow_marks_the_named_cases():
    cases = marked_slow(["a", "b", "c"], ["b"])
    assert cases[0] == "a" and cases[2] == "c"
    assert cases[1].values == ("b",) and [m.name for m in cases[1].marks] == ["slow"]
