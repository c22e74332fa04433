"""Batched Newton-Raphson for small square systems, with implicit differentiation.

A residual ``r(x, args, shared)`` couples the ``n`` unknowns of a sample (``n`` small, 1-6) but
never two samples. It is written on *components*: ``x`` is a tuple of ``n`` batch-shaped arrays
and the residual returns ``n`` batch-shaped arrays from elementwise operations only, the
"structure of arrays" form that XLA on CPU fuses into one vectorised loop (stacked ``(N, 3)``
arrays run many times slower). ``solve`` takes and returns ``(..., n)`` arrays and splits them
itself. For each sample::

    J_k = dr/dx (x_k)                  forward mode, one pass per unknown (samples independent)
    x_{k+1} = x_k - J_k^{-1} r(x_k)    explicit adjugate solve for n <= 3, LU otherwise

Each element converges on its own inside one ``lax.while_loop`` (a stopped element is frozen
and reports its own iteration count). It stops when ``max|r| <= tol * scale`` (converged), when
its Jacobian is numerically singular (``conditioning <= sqrt(eps(dtype))``), when ``x`` stops
being finite, or after ``max_iter`` updates. ``conditioning`` is the Hadamard ratio
``|det J| / prod_i |J_i|`` in [0, 1], invariant to the scaling of each equation.

Derivatives come from the implicit function theorem (``jax.lax.custom_root``), never from the
unrolled iterations; nested ``jax.jvp`` works, so ``jaxkin.lift`` of a Newton-based solver gives
velocity and acceleration, and ``jax.grad`` works too. Where the Jacobian is singular the
tangent solve uses a placeholder determinant of 1: callers mask rates by the status. The
returned ``x`` is always finite, with ``status`` ``OK``, ``NOT_CONVERGED`` or ``SINGULAR``.
"""

from __future__ import annotations

import dataclasses
import functools
import operator
from collections.abc import Callable
from typing import Any

import jax
import jax.numpy as jnp
from jax import Array
from jax.typing import ArrayLike

from . import _validate
from ._numerics import singular_rtol
from .lie import cross_soa
from .result import SolverResult
from .status import STATUS_DTYPE, Status

__all__ = ["NewtonResult", "hadamard_ratio_components", "solve", "solve_components"]

Residual = Callable[[tuple[Array, ...], Any, Any], Any]


@jax.tree_util.register_dataclass
@dataclasses.dataclass(frozen=True)
class NewtonResult(SolverResult):
    """Result of a batched Newton-Raphson solve.

    Attributes:
        x: solution, shape ``(..., n)``; finite everywhere (see the module docstring).
        converged: ``max|r| <= tol * scale`` at ``x``, shape ``(...)``.
        iterations: Newton updates applied, ``int32``, shape ``(...)``.
        residual: ``max|r(x)|`` at the returned ``x``, shape ``(...)``.
        conditioning: Hadamard ratio of the Jacobian at ``x`` (0 = singular), shape ``(...)``.
        status: ``OK``, ``NOT_CONVERGED`` or ``SINGULAR`` (``int8``), shape ``(...)``.
    """

    x: Array
    converged: Array
    iterations: Array
    residual: Array
    conditioning: Array
    status: Array


Components = tuple[Array, ...]


def _jacobian_rows(linear: Callable[[Components], Any], like: Components) -> list[list[Array]]:
    """Per-sample Jacobian ``J[i][j]`` (each of the batch shape) of a component-wise linear map.

    Column j is the map applied to the unit vector e_j in every sample at once; exact because
    the residual never couples two samples.
    """
    n = len(like)
    zero, one = jnp.zeros_like(like[0]), jnp.ones_like(like[0])
    cols = [tuple(linear(tuple(one if k == j else zero for k in range(n)))) for j in range(n)]
    return [[cols[j][i] for j in range(n)] for i in range(n)]


def _residual_and_jacobian(
    f: Callable[[Components], Components], x: Components
) -> tuple[Components, list[list[Array]]]:
    """``f(x)`` and its per-sample Jacobian ``J[i][j]``, one forward pass per unknown.

    Column j differentiates with respect to ``x[j]`` alone: the other unknowns are constants
    of that pass, so their tangents are symbolic zeros and drop out. Pushing unit vectors
    through ``jax.linearize`` instead multiplies by explicit zero arrays, which XLA keeps
    (``0 * x`` is not 0 for non-finite x): a third of the operations of each Newton trip of
    the Delta FK (counted in the compiled loop). The primal work of the n passes is identical
    and XLA computes it once.
    """
    n = len(x)
    cols = []
    for j in range(n):

        def f_j(x_j, j=j):
            return tuple(f((*x[:j], x_j, *x[j + 1 :])))

        r, col = jax.jvp(f_j, (x[j],), (jnp.ones_like(x[j]),))
        cols.append(col)
    return r, [[cols[j][i] for j in range(n)] for i in range(n)]


def _max_abs(r: Components) -> Array:
    return functools.reduce(jnp.maximum, [jnp.abs(v) for v in r])


def _all_finite(x: Components) -> Array:
    return functools.reduce(operator.and_, [jnp.isfinite(v) for v in x])


def _solve_components(
    m: list[list[Array]], b: Components
) -> tuple[Components, tuple[Array, Array]]:
    """``m^{-1} b`` per sample (``m[i][j]``, ``b[i]`` batch arrays), and ``(det^2, prod_i |m_i|^2)``
    whose ratio is the squared Hadamard ratio (kept apart: no division in the Newton loop); a
    placeholder determinant of 1 where ``m`` is singular (double-where)."""
    n = len(b)
    bound_sq = functools.reduce(
        operator.mul, [functools.reduce(operator.add, [v * v for v in row]) for row in m]
    )
    adj_b: tuple[Array, ...] | None
    if n == 1:
        det, adj_b = m[0][0], (b[0],)
    elif n == 2:
        det = m[0][0] * m[1][1] - m[0][1] * m[1][0]
        adj_b = (m[1][1] * b[0] - m[0][1] * b[1], m[0][0] * b[1] - m[1][0] * b[0])
    elif n == 3:
        c0, c1, c2 = cross_soa(m[1], m[2]), cross_soa(m[2], m[0]), cross_soa(m[0], m[1])
        det = m[0][0] * c0[0] + m[0][1] * c0[1] + m[0][2] * c0[2]
        adj_b = tuple(c0[k] * b[0] + c1[k] * b[1] + c2[k] * b[2] for k in range(3))
    else:
        det, adj_b = None, None
    if det is None:
        mm = jnp.stack([jnp.stack(row, axis=-1) for row in m], axis=-2)
        det = jnp.linalg.det(mm)
    # ratio^2 <= rtol^2 tested without a division: det^2 <= rtol^2 bound^2 (bound^2 >= 0).
    rtol_sq = singular_rtol(det.dtype) ** 2
    singular = det * det <= rtol_sq * bound_sq
    det_sq = det * det
    if adj_b is None:
        mm = jnp.where(singular[..., None, None], jnp.eye(n, dtype=det.dtype), mm)
        x = jnp.linalg.solve(mm, jnp.stack(b, axis=-1)[..., None])[..., 0]
        return tuple(x[..., k] for k in range(n)), (det_sq, bound_sq)
    inv_det = 1.0 / jnp.where(singular, 1.0, det)  # one division, n multiplications
    return tuple(v * inv_det for v in adj_b), (det_sq, bound_sq)


def solve_components(m: list[list[Array]], b: Components) -> Components:
    """``m^{-1} b`` per sample, on components (``m[i][j]`` and ``b[i]`` batch-shaped arrays).

    Cramer's rule for n <= 3. Where ``m`` is numerically singular (Hadamard ratio <=
    ``sqrt(eps)``) the determinant is replaced by 1: finite, meaningless values that the
    caller masks by its status.
    """
    return _solve_components(m, b)[0]


def _ratio(det_sq: Array, bound_sq: Array) -> Array:
    positive = bound_sq > 0
    return jnp.sqrt(jnp.where(positive, det_sq / jnp.where(positive, bound_sq, 1.0), 0.0))


def hadamard_ratio_components(m: list[list[Array]]) -> Array:
    """The Hadamard ratio ``|det m| / prod_i |m_i|`` of per-sample matrices ``m[i][j]``.

    Elementwise only, so it fuses into one loop with its producers.
    """
    _, ratio_sq = _solve_components(m, tuple(m[0]))  # the solve itself is dead code
    return _ratio(*ratio_sq)


def _solve_batch(
    residual: Residual,
    x0: Components,
    args: Any,
    shared: Any,
    threshold: Array,
    max_iter: int,
) -> tuple[Components, tuple[Array, Array, Array, Array]]:
    """Newton-Raphson on component arrays, differentiable by the implicit function theorem
    (``custom_root`` over the whole batch: the system is block diagonal)."""
    rtol_sq = singular_rtol(x0[0].dtype) ** 2

    def f(x: Components) -> Components:
        return tuple(residual(x, args, shared))

    def newton(f: Callable[[Components], Components], guess: Components):
        def linear_solve(x):
            """The Newton step at ``x``, ``max|r(x)|`` and the Jacobian's (det^2, bound^2)."""
            r, jacobian = _residual_and_jacobian(f, x)
            dx, ratio_sq = _solve_components(jacobian, r)
            return dx, _max_abs(r), ratio_sq

        def active(x, it):
            """Still iterating: residual above threshold, finite, regular, under max_iter."""
            _, res, (det_sq, bound_sq) = linear_solve(x)  # the step itself is dead code here
            # A NaN residual compares False, so non-finite iterates stop too.
            act = (res > threshold) & _all_finite(x) & (it < max_iter)
            return act & (det_sq > rtol_sq * bound_sq)  # a singular Jacobian stops the element

        # Each trip steps the active elements, then tests them at their new x. The loop
        # carries only (x, iterations, active): values shared by the per-component update loops
        # XLA generates are recomputed there, never stored. Testing after the step (rather than
        # before it) saves the trip that would only find every element stopped.
        def body(state):
            x, it, act = state
            dx = linear_solve(x)[0]
            x = tuple(jnp.where(act, a - b, a) for a, b in zip(x, dx, strict=True))
            it = it + act.astype(jnp.int32)
            return x, it, act & active(x, it)

        it0 = jnp.zeros(guess[0].shape, jnp.int32)
        init = (guess, it0, active(guess, it0))
        x, it, _ = jax.lax.while_loop(lambda state: jnp.any(state[-1]), body, init)
        _, res, ratio_sq = linear_solve(x)
        # Failure is data: a non-finite iterate is replaced by the guess (double-where).
        finite = _all_finite(x) & jnp.isfinite(res)
        x = tuple(jnp.where(finite, a, g) for a, g in zip(x, guess, strict=True))
        res = jnp.where(finite, res, jnp.inf)
        # custom_root's jvp rule gives aux outputs float tangents: keep them floating.
        return x, (res, _ratio(*ratio_sq), it.astype(res.dtype))

    def tangent_solve(g: Callable[[Components], Any], y: Components) -> Components:
        # The per-sample Jacobians do not depend on y, so this is linear in y (transposable).
        return _solve_components(_jacobian_rows(g, y), tuple(y))[0]

    x, (res, ratio, it) = jax.lax.custom_root(f, x0, newton, tangent_solve, has_aux=True)
    converged = jnp.isfinite(res) & (res <= threshold)
    return x, (res, ratio, it.astype(jnp.int32), converged)


def solve(
    residual: Residual,
    x0: ArrayLike,
    args: Any = (),
    shared: Any = None,
    *,
    tol: float = 1e-12,
    scale: ArrayLike = 1.0,
    max_iter: int = 30,
) -> NewtonResult:
    """Solve ``residual(x, args, shared) = 0`` for a batch of small square systems.

    Args:
        residual: component-wise residual (module docstring): ``x`` a tuple of ``n`` arrays of
            the batch shape -> a sequence of ``n`` such arrays; elementwise, traceable by JAX.
        x0: initial guesses, shape ``(*batch, n)``.
        args: pytree passed to the residual unchanged (e.g. per-sample data as components).
        shared: another pytree passed unchanged (e.g. a geometry); both are differentiable.
        tol: relative tolerance: converged where ``max|r| <= tol * scale``.
        scale: scale of the residual (same units), scalar or batch-shaped.
        max_iter: maximum number of Newton updates (static).

    Returns:
        ``NewtonResult``, batch shape of ``x0``. Differentiable with respect to ``args`` and
        ``shared`` (implicit function theorem; forward and reverse mode, nested jvp).

    This function is jit-able; callers usually call it inside their own jitted kernel.
    """
    x0 = jnp.asarray(x0)
    if x0.ndim == 0:
        raise ValueError(f"x0: expected shape (..., n), got {tuple(x0.shape)}")
    x0 = _validate.as_float(x0)
    max_iter = _validate.count(max_iter, "max_iter", minimum=0)
    if not tol > 0:
        raise ValueError(f"tol must be positive, got {tol}")
    batch = x0.shape[:-1]
    threshold = float(tol) * jnp.broadcast_to(jnp.asarray(scale, x0.dtype), batch)
    components = tuple(x0[..., k] for k in range(x0.shape[-1]))
    x, (res, ratio, it, converged) = _solve_batch(
        residual, components, args, shared, threshold, int(max_iter)
    )
    status = jnp.where(
        ratio <= singular_rtol(x0.dtype),
        Status.SINGULAR,
        jnp.where(converged, Status.OK, Status.NOT_CONVERGED),
    ).astype(STATUS_DTYPE)
    return NewtonResult(
        x=jnp.stack(x, axis=-1),
        converged=converged,
        iterations=it,
        residual=jnp.where(jnp.isfinite(res), res, jnp.finfo(x0.dtype).max),
        conditioning=ratio,
        status=status,
    )
