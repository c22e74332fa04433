"""Trajectory optimisation against a reference solver: scipy's L-BFGS-B on the same objective.

Problems: the paper's SCARA (150, 80, 50 mm), pick-and-place moves from a start to a goal,
rest to rest, 3 interior Bezier control points, 16 noisy straight-line guesses, T = 100
samples over 1 s, cost ``costs.acceleration`` (the integrated squared joint acceleration),
every other argument of ``optimize.optimize`` at its default (L-BFGS per guess). Two more
problems start every other guess 80 mm further out, partly outside the 130 mm reach: one
with the acceleration alone, one with the default cost (acceleration, singularity barrier,
unreachable penalty; the limit penalty is zero for this robot, which has no limits).

Reference: ``scipy.optimize.minimize(method="L-BFGS-B")`` run one guess after another on the
same objective, written here from the public pieces (the Bezier basis, ``jaxkin.ik``, the
acceleration integral), its value and gradient compiled once with JAX. The reference optimum
of a problem is the least cost scipy reaches from the same guesses or polishing jaxkin's own
results. Reported per problem (``extra_info`` and printed): the cost ratio of jaxkin's best
guess to the reference optimum (goal: within 0.1 %) and the time of jaxkin's compiled call
(compiled on another problem of the same shapes, so no compilation is timed) over the time of
scipy's solve of the 16 guesses (goal: below 1). Float64.
"""

from __future__ import annotations

import time

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy.optimize import minimize

import jaxkin
from jaxkin import costs, optimize, paths, scara

ROBOT = scara.Scara.paper()
N_SAMPLES, N_INTERIOR, N_GUESSES = 100, 3, 16
PROBLEMS = {
    "across the front": ([100.0, -60.0, 50.0], [100.0, 60.0, 70.0]),
    "around the inner boundary": ([110.0, -20.0, 50.0], [-50.0, 70.0, 80.0]),
    "long sweep": ([120.0, 20.0, 40.0], [-90.0, 60.0, 60.0]),
    "short hop": ([60.0, 60.0, 50.0], [40.0, 90.0, 40.0]),
    "guesses outside": ([100.0, -60.0, 50.0], [100.0, 60.0, 70.0]),
    "guesses outside, default cost": ([100.0, -60.0, 50.0], [100.0, 60.0, 70.0]),
}
OUTSIDE = np.array([80.0, 0.0, 0.0])  # added to every other guess of the last two problems
WARM_UP = ([90.0, -70.0, 50.0], [80.0, 80.0, 60.0])  # same shapes, compiles the call


def reference_objective(start: np.ndarray, goal: np.ndarray, default_cost: bool = False):
    """scipy's ``fun(x) -> (value, gradient)`` of one guess's interior points ``x`` (flat)."""
    basis = jnp.asarray(paths.bezier_basis(N_INTERIOR + 4, N_SAMPLES))
    dt = 1.0 / (N_SAMPLES - 1)
    ends = jnp.asarray(start), jnp.asarray(goal)

    @jax.jit
    def value_and_grad(x):
        def cost(x):
            controls = jnp.concatenate(
                [jnp.stack([ends[0]] * 2), x.reshape(N_INTERIOR, 3), jnp.stack([ends[1]] * 2)]
            )
            path = jaxkin.Jet(basis[0] @ controls, basis[1] @ controls, basis[2] @ controls)
            res = jaxkin.ik(ROBOT, path)
            value = jnp.sum(res.q.a**2) * dt
            if default_cost:  # DEFAULT_COST's barrier (0.05, weight 100), unreachable (1e6)
                barrier = jnp.sum((jax.nn.relu(0.05 - res.margin) / 0.05) ** 2)
                value = value + 100.0 * barrier + 1e6 * jnp.sum(jax.nn.relu(-res.margin) ** 2)
            return value

        return jax.value_and_grad(cost)(x)

    def fun(x):
        value, grad = value_and_grad(jnp.asarray(x))
        return float(value), np.asarray(grad)

    fun(np.zeros(3 * N_INTERIOR))  # compile outside any timer
    return fun


def solve(start, goal, guesses, cost=costs.acceleration) -> optimize.OptimizationResult:
    return optimize.optimize(
        ROBOT, start, goal, guesses, cost=cost, rest_to_rest=True, n_samples=N_SAMPLES
    )


@pytest.mark.parametrize("name", list(PROBLEMS))
def test_optimize_against_scipy_lbfgsb(benchmark, name):
    start, goal = (np.asarray(x) for x in PROBLEMS[name])
    guesses = paths.straight_line_guess(start, goal, N_INTERIOR, N_GUESSES, noise=10.0, seed=1)
    if name.startswith("guesses outside"):
        guesses[::2] += OUTSIDE
    default_cost = name.endswith("default cost")
    cost = costs.DEFAULT_COST if default_cost else costs.acceleration
    warm = [np.asarray(x) for x in WARM_UP]
    jax.block_until_ready(solve(*warm, guesses + 1.0, cost))  # compile on another problem
    cpu = []

    def timed():
        began = time.process_time()
        out = jax.block_until_ready(solve(start, goal, guesses, cost))
        cpu.append(time.process_time() - began)
        return out

    result = benchmark.pedantic(timed, rounds=3, iterations=1)
    jaxkin_time = benchmark.stats.stats.min

    fun = reference_objective(start, goal, default_cost)
    began, began_cpu = time.perf_counter(), time.process_time()
    from_guesses = [minimize(fun, g.ravel(), jac=True, method="L-BFGS-B") for g in guesses]
    scipy_time = time.perf_counter() - began
    scipy_cpu = time.process_time() - began_cpu
    polished = [
        minimize(fun, np.asarray(c[2:-2]).ravel(), jac=True, method="L-BFGS-B")
        for c in result.controls
    ]
    reference = min(r.fun for r in from_guesses + polished)
    best = float(result.cost[int(result.best)])
    benchmark.extra_info.update(
        kernel=f"optimize vs scipy L-BFGS-B: {name}",
        dtype="float64",
        n_cases=N_GUESSES,
        cost_ratio=best / reference,
        time_ratio=jaxkin_time / scipy_time,
        cpu_ratio=min(cpu) / scipy_cpu,
        scipy_seconds=scipy_time,
        scipy_evaluations=int(sum(r.nfev for r in from_guesses)),
        converged=int(np.sum(result.converged)),
        max_iterations=int(np.max(result.iterations)),
    )
    print(
        f"\n{name}: best cost {best:.6g}, reference {reference:.6g} "
        f"(ratio {best / reference:.6f}); jaxkin {jaxkin_time * 1e3:.0f} ms, "
        f"scipy {scipy_time * 1e3:.0f} ms for {N_GUESSES} guesses "
        f"(time ratio {jaxkin_time / scipy_time:.3f}, CPU time ratio "
        f"{min(cpu) / scipy_cpu:.3f})"
    )
    assert np.isfinite(best) and np.isfinite(reference)  # speed and ratios are reported only
