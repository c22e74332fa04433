"""Small numerical helpers shared by every kernel.

Every helper here is safe under ``jax.grad``: where a formula has a singular point (a square
root at zero, a division by zero) the unsafe input is first replaced by a harmless value, the
formula is evaluated, and the result is selected afterwards (the "double-where" trick). A
single ``jnp.where`` is not enough: the gradient of the unselected branch is still computed,
and ``0 * inf = nan`` would poison the whole batch.
"""

from __future__ import annotations

import functools
import math
import operator

import jax
import jax.numpy as jnp
from jax import Array
from jax.typing import ArrayLike


def eps(dtype) -> float:
    """Machine epsilon of a floating dtype, as a Python float (never promotes float32)."""
    return float(jnp.finfo(dtype).eps)


def singular_rtol(dtype) -> float:
    """Relative tolerance used to classify singular configurations: ``sqrt(eps(dtype))``.

    About 1.5e-8 in float64 and 3.5e-4 in float32. Multiply it by a length scale of the
    mechanism (for example the sum of its link lengths) to get an absolute tolerance.
    """
    return eps(dtype) ** 0.5


@jax.custom_jvp
def rsqrt(x: Array) -> Array:
    """``1 / sqrt(x)`` (``lax.rsqrt``) whose derivative rule has no division.

    ``d rsqrt(x) = -rsqrt(x)^3 / 2 dx``: JAX's own rule divides by ``x`` at every order of a
    nested ``jvp``; this one multiplies (divisions are slow on CPU).
    """
    return jax.lax.rsqrt(x)


@rsqrt.defjvp
def _rsqrt_jvp(primals, tangents):
    (x,), (x_dot,) = primals, tangents
    r = rsqrt(x)
    return r, -0.5 * r * r * r * x_dot


@jax.custom_jvp
def _sqrt(x: Array) -> Array:
    return jnp.sqrt(x)  # correctly rounded value; only the derivative rule changes


@_sqrt.defjvp
def _sqrt_jvp(primals, tangents):
    (x,), (x_dot,) = primals, tangents
    # d sqrt(x) = rsqrt(x) / 2 dx: one rsqrt shared by every order, no division (see rsqrt).
    return _sqrt(x), 0.5 * rsqrt(x) * x_dot


def safe_sqrt(x: ArrayLike) -> Array:
    """``sqrt(max(x, 0))`` with a finite (zero) gradient at and below zero.

    Above zero the derivative is ``rsqrt(x) / 2`` (division-free at every order, see
    ``rsqrt``); at and below zero the argument is replaced before the square root
    (double-where), so no ``inf`` reaches the derivative.
    """
    x = jnp.asarray(x)
    positive = x > 0
    return jnp.where(positive, _sqrt(jnp.where(positive, x, 1.0)), 0.0)


def safe_div(num: ArrayLike, den: ArrayLike, fill: float = 0.0) -> Array:
    """``num / den`` where ``den != 0``, ``fill`` elsewhere; finite gradient everywhere."""
    den = jnp.asarray(den)
    nonzero = den != 0
    return jnp.where(nonzero, num / jnp.where(nonzero, den, 1.0), fill)


def safe_norm(x: ArrayLike, axis: int = -1) -> Array:
    """Euclidean norm along ``axis`` with a zero (not NaN) gradient at the zero vector."""
    return safe_sqrt(jnp.sum(jnp.square(x), axis=axis))


def all_finite(x: ArrayLike, axis: int | tuple[int, ...] | None = -1) -> Array:
    """True where every entry along ``axis`` is finite (``axis=None``: elementwise)."""
    finite = jnp.isfinite(x)
    if axis is None:
        return finite
    return all_last(finite) if axis == -1 else jnp.all(finite, axis=axis)


def all_last(x: ArrayLike) -> Array:
    """``jnp.all(x, axis=-1)``: ``(..., k)`` -> ``(...)``.

    For a single element (leading shape of size 1: the single query) the ``k`` columns are
    and-ed one by one: there a reduction inside a fused loop costs every call of the compiled
    program a buffer that XLA's CPU runtime sets up anew, once per loop that reads it; in a
    batch the reduction is one loop that the others read.
    """
    x = jnp.asarray(x)
    if math.prod(x.shape[:-1]) != 1 or x.shape[-1] == 0:
        return jnp.all(x, axis=-1)
    return functools.reduce(operator.and_, (x[..., k] for k in range(x.shape[-1])))


def computed_once(x: Array) -> Array:
    """``x``, stored once rather than recomputed by each fused loop that reads it.

    XLA on CPU has no multi-output fusion: it fuses an elementwise producer into every loop
    that reads it, so a value read by ten output loops is computed ten times.
    ``lax.optimization_barrier`` makes ``x`` a materialised input of its readers. Pass one
    stacked array (``jnp.stack([...])``, one loop computes it): a tuple of separate arrays
    has no effect. Use it where few shared values feed many outputs (``docs/performance.md``).
    """
    return jax.lax.optimization_barrier(x)


def spd_det(g: Array) -> Array:
    """Determinant of symmetric positive semi-definite ``(..., k, k)`` matrices, ``>= 0``.

    The product of the pivots of an unrolled Cholesky (LDL^T) factorisation, each clamped at 0
    (rounding can make a pivot of a singular matrix slightly negative): elementwise arithmetic
    that fuses, where a batched ``jnp.linalg.det`` calls LAPACK per matrix.
    """
    k = g.shape[-1]
    rows = [[g[..., i, j] for j in range(k)] for i in range(k)]
    det = jnp.ones_like(rows[0][0])
    for i in range(k):
        pivot = jnp.maximum(rows[i][i], 0.0)
        det = det * pivot
        inv = jnp.where(pivot > 0, 1.0 / jnp.where(pivot > 0, pivot, 1.0), 0.0)
        for r in range(i + 1, k):
            factor = rows[r][i] * inv
            for c in range(i + 1, k):
                rows[r][c] = rows[r][c] - factor * rows[i][c]
    return det


def isotropy(jac: Array) -> Array:
    """How far a Jacobian ``(..., m, n)`` is from singular, in [0, 1], shape ``(...)``.

    With ``s_1 .. s_k`` its ``k = min(m, n)`` singular values: their geometric mean over their
    root mean square, ``(prod s_i)^(1/k) / sqrt(mean s_i^2)`` (at most 1 by the AM-GM
    inequality, 1 when every ``s_i`` is equal, 0 exactly when the Jacobian loses rank). Computed
    from ``G = J J^T`` (or ``J^T J``) as ``det(G)^(1/2k) / sqrt(trace(G) / k)``; invariant to a
    common scale of ``J``, so scale rows and columns to one set of units first (e.g. lengths
    divided by the robot's size). No LAPACK call: its first use in a process imports scipy
    (about 0.2 s), which a first call would pay.
    """
    m, n = jac.shape[-2:]
    if m <= n:
        g = jnp.einsum("...ik,...jk->...ij", jac, jac)
    else:
        g = jnp.einsum("...ki,...kj->...ij", jac, jac)
    k = g.shape[-1]
    mean_sq = jnp.trace(g, axis1=-2, axis2=-1) / k
    det = spd_det(g)
    positive = (mean_sq > 0) & (det > 0)
    ratio = det / jnp.where(positive, mean_sq, 1.0) ** k  # in [0, 1]
    root = jnp.exp(jnp.log(jnp.where(positive, ratio, 1.0)) / (2 * k))
    return jnp.where(positive, jnp.minimum(root, 1.0), 0.0)
