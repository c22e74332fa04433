"""``jaxkin._lbfgs.LBFGS``, the optimiser's default method, used as an optax-shaped
transformation on problems with known minima (Rosenbrock's, a quadratic's, scipy's L-BFGS-B),
and its line search's failure path (a gradient of the wrong sign: a restart, then it gives up)."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
from scipy.optimize import minimize

from jaxkin._lbfgs import LBFGS


def _rosenbrock(x):
    return jnp.sum(100.0 * (x[1:] - x[:-1] ** 2) ** 2 + (1.0 - x[:-1]) ** 2)


def _run(method, fn, x0, updates):
    """``updates`` updates from ``x0``: the final state and the accepted points' costs."""
    value_and_grad = jax.value_and_grad(fn)

    @jax.jit
    def step(carry, _):
        x, f, g, state = carry
        taken, state = method.update(g, state, x, value=f, value_fn=fn)
        return (state.params, state.value, state.grad, state), (state.value, x + taken)

    f, g = value_and_grad(x0)
    (x, f, g, state), (values, summed) = jax.lax.scan(
        step, (x0, f, g, method.init(x0)), None, length=updates
    )
    return state, values, summed


def test_reaches_the_rosenbrock_minimum():
    """From the textbook start (-1.2, 1): the minimum (1, 1) (closed form) to 1e-8, the one
    scipy's L-BFGS-B finds (to its default tolerance, 1e-4); the accepted costs never
    increase; the state's value and gradient are those of its point, and ``params +
    updates`` is it to rounding."""
    x0 = jnp.array([-1.2, 1.0])
    state, values, summed = _run(LBFGS(), _rosenbrock, x0, 300)
    np.testing.assert_allclose(state.params, [1.0, 1.0], atol=1e-8)
    reference = minimize(
        lambda x: float(_rosenbrock(jnp.asarray(x))),
        np.asarray(x0),
        jac=lambda x: np.asarray(jax.grad(_rosenbrock)(jnp.asarray(x))),
        method="L-BFGS-B",
    )
    np.testing.assert_allclose(reference.x, state.params, atol=1e-4)
    assert np.all(np.diff(np.asarray(values)) <= 0)
    value, grad = jax.value_and_grad(_rosenbrock)(state.params)
    assert float(state.value) == float(value)
    np.testing.assert_array_equal(state.grad, grad)
    np.testing.assert_allclose(summed[-1], state.params, rtol=1e-15, atol=1e-15)


def test_a_quadratic_in_as_many_steps_as_dimensions():
    """On ``x^T A x / 2 - b^T x`` (A SPD, n = 4) L-BFGS with exact curvature pairs solves
    ``A x = b`` (numpy.linalg.solve) to 1e-10 within a few n steps; the state says how many
    updates took a step."""
    rng = np.random.default_rng(0)
    m = rng.normal(size=(4, 4))
    a, b = jnp.asarray(m @ m.T + 4 * np.eye(4)), jnp.asarray(rng.normal(size=4))

    def quadratic(x):
        return 0.5 * x @ a @ x - b @ x

    state, _, _ = _run(LBFGS(memory=4), quadratic, jnp.zeros(4), 40)
    np.testing.assert_allclose(state.params, np.linalg.solve(a, b), atol=1e-10)
    assert int(state.memory.pairs) >= 4


@jax.custom_jvp
def _wrong_slope(x):
    return jnp.sum(x * x)


@_wrong_slope.defjvp
def _wrong_slope_jvp(primals, tangents):
    (x,), (dx,) = primals, tangents
    return _wrong_slope(x), jnp.sum(-2.0 * x * dx)  # the gradient's sign flipped


def test_a_failed_line_search_restarts_then_gives_up():
    """A gradient of the wrong sign: no trial lowers the cost. After ``linesearch_steps``
    refused trials the memory is cleared and the search restarts by steepest descent; when
    that fails too the state gives up; no update moved the point (zero updates)."""
    method = LBFGS(memory=3, linesearch_steps=3)
    x = jnp.array([0.5, -1.0, 2.0])
    f, g = jax.value_and_grad(_wrong_slope)(x)
    state = method.init(x)
    seen = []
    for _ in range(6):
        taken, state = method.update(g, state, x, value=f, value_fn=_wrong_slope)
        seen.append((bool(state.accepted), bool(state.restarted), bool(state.gave_up)))
        np.testing.assert_array_equal(taken, 0.0)
        np.testing.assert_array_equal(state.params, x)
    assert seen == [(False, False, False)] * 2 + [(False, True, False)] * 3 + [(False, True, True)]


def test_vmapped_problems_advance_on_their_own():
    """Two problems vmapped: each one's accepted costs, update by update, are those it has
    alone (a problem's line search never waits for another's), to rounding: the vmapped and
    the single program round apart, 1e-11 after 60 updates along Rosenbrock's valley."""
    method = LBFGS()
    starts = jnp.array([[-1.2, 1.0], [0.5, 2.5]])
    alone = [_run(method, _rosenbrock, x0, 60)[1] for x0 in starts]
    together = jax.vmap(lambda x0: _run(method, _rosenbrock, x0, 60)[1])(starts)
    np.testing.assert_allclose(together, np.stack(alone), rtol=1e-9, atol=1e-300)
    assert not np.allclose(alone[0][:20], alone[1][:20])
