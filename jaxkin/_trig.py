"""Fast ``sincos``, ``sin_alone``/``cos_alone`` and ``atan2``: vectorisable polynomial forms.

XLA on CPU evaluates ``cos``, ``sin`` and ``atan2`` as slow opaque calls; the same fdlibm
algorithms written as elementwise arithmetic fuse into their readers' loops and vectorise
(timings in ``docs/performance.md``). Accuracy against libm (tests/test_trig.py): ``sincos``
within 1 ulp, ``atan2`` within 2 ulp, ``sin_alone``/``cos_alone`` within ``eps`` absolute, in
float64 and float32. Where to use them is decided per call site by measurement: XLA copies a
cheap polynomial into every fused loop that reads it, so an angle feeding many outputs is
either stored once (``computed_once``) or left to XLA's own function.

``sincos(x)``: one Cody-Waite reduction ``n = round(x 2/pi)``, ``r = x - n pi/2`` (pi/2 split
in parts so every ``n * part`` is exact), polynomials for ``sin r``, ``cos r`` on
``|r| <= pi/4``, then the quadrant of ``n mod 4``. Exact reduction for
``|x| <= REDUCTION_LIMIT[dtype]`` (1e8 rad in float64, 5e4 in float32); beyond it ``r`` carries
about half an ulp of ``x`` (the angle's own resolution) and values stay in [-1, 1].

``sin_alone``/``cos_alone``: one polynomial each, for stacked rows that are stored (a stored
stack computes each row on its own): ``n = round(x / pi)`` (sin) or ``floor(x / pi)`` (cos),
``r = x - k pi/2`` in [-pi/2, pi/2], ``+-S(r)`` with ``S(r) = r + r^3 P(r^2)``.

``atan2(y, x)``: fdlibm ``atan`` of ``u = min(|x|, |y|) / max(|x|, |y|)`` split as
``atan(c) + atan(t)`` (``c`` in {0, 1/2, 1}, ``|t| < 7/16``, one division), then the octant.
Special values follow C's ``atan2`` (``atan2(+-0, -0) = +-pi``, NaN in, NaN out). All carry the
usual derivative rules (``custom_jvp``): nested ``jvp`` and ``grad`` see ``d sin = cos`` and
``d atan2(y, x) = (x dy - y dx) / (x^2 + y^2)``, as ``jnp.arctan2`` does.

On an accelerator (``jax.default_backend()`` not ``"cpu"``) the four functions are XLA's own
``sin``, ``cos`` and ``atan2``, which GPUs evaluate in fast native code: the polynomial forms
are a CPU choice (``docs/scaling.md``).
"""

from __future__ import annotations

from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from jax import Array
from jax.typing import ArrayLike

# fdlibm k_sin.c / k_cos.c (|r| <= pi/4).
_SIN = (
    -1.66666666666666324348e-01,
    8.33333333332248946124e-03,
    -1.98412698298579493134e-04,
    2.75573137070700676789e-06,
    -2.50507602534068634195e-08,
    1.58969099521155010221e-10,
)
_COS = (
    4.16666666666666019037e-02,
    -1.38888888888741095749e-03,
    2.48015872894767294178e-05,
    -2.75573143513906633035e-07,
    2.08757232129817482790e-09,
    -1.13596475577881948265e-11,
)
_TWO_OVER_PI = 6.36619772367581382433e-01
# pi/2 = part_1 + ... + part_k + tail: every part but the tail has few enough significant
# bits (27 in float64, 9 in float32) that n * part is exact for every |n| < 2^26 (float64)
# or 2^15 (float32); the subtractions are then exact (two-sums), only the tail rounds.
# Computed from 100 digits of pi (tests/test_trig.py checks the split).
_PIO2_PARTS = {
    np.dtype(np.float64): (
        1.570796325802803,
        9.920935739593517e-10,
        5.721188709663575e-18,
        1.6446256936324258e-26,  # tail
    ),
    np.dtype(np.float32): (
        1.5703125,
        0.00048351287841796875,
        3.1385570764541626e-07,
        6.070877134334296e-11,
        6.223371969669989e-14,  # tail
    ),
}
REDUCTION_LIMIT = {np.dtype(np.float64): 1.0e8, np.dtype(np.float32): 5.0e4}

# fdlibm s_atan.c: atan(c) as hi + lo for c = 1/2, 1 (pi/4), and the polynomial on |t| < 7/16.
_ATAN_HALF = (4.63647609000806093515e-01, 2.26987774529616870924e-17)
_PI_OVER_4 = (7.85398163397448278999e-01, 3.06161699786838301793e-17)
_PI_OVER_2 = (1.57079632679489655800e00, 6.12323399573676603587e-17)
_PI = (3.14159265358979311600e00, 1.22464679914735317720e-16)
_ATAN = (
    3.33333333333329318027e-01,
    -1.99999999998764832476e-01,
    1.42857142725034663711e-01,
    -1.11111104054623557880e-01,
    9.09088713343650656196e-02,
    -7.69187620504482999495e-02,
    6.66107313738753120669e-02,
    -5.83357013379057348645e-02,
    4.97687799461593236017e-02,
    -3.65315727442169155270e-02,
    1.62858201153657823623e-02,
)


def _horner(z: Array, coefficients: tuple[float, ...]) -> Array:
    """``c0 + z (c1 + z (c2 + ...))``."""
    result: Any = coefficients[-1]  # a float until the first step
    for c in reversed(coefficients[:-1]):
        result = c + z * result
    return result


def _two_sum(a: Array, b: Array) -> tuple[Array, Array]:
    """``(s, e)`` with ``s = fl(a + b)`` and ``s + e = a + b`` exactly (Knuth's TwoSum)."""
    s = a + b
    b_virtual = s - a
    return s, (a - (s - b_virtual)) + (b - b_virtual)


def _sincos_reduced(x: Array) -> tuple[Array, Array]:
    """Polynomial sin and cos (module docstring for the accuracy by range; NaN/inf -> NaN)."""
    first, *parts, tail = _PIO2_PARTS[np.dtype(x.dtype)]
    n = jnp.round(x * _TWO_OVER_PI)
    r = x - n * first  # exact (Sterbenz: n * first is exact and close to x)
    error = jnp.zeros_like(r)
    for part in parts:  # r + error = x - n (first + ...): exact products, exact two-sums
        r, rounding = _two_sum(r, -(n * part))
        error = error + rounding
    error = error - n * tail
    hi = r + error
    lo = (r - hi) + error  # what hi lost: fdlibm's y
    # |hi| <= pi/4 within the reduction limit; far beyond it, keep the polynomials bounded.
    bounded = jnp.clip(hi, -1.0, 1.0)
    lo = jnp.where(bounded == hi, lo, 0.0)
    hi = bounded
    z = hi * hi
    v = z * hi
    sin_r = hi - ((z * (0.5 * lo - v * _horner(z, _SIN[1:])) - lo) - v * _SIN[0])
    half_z = 0.5 * z
    w = 1.0 - half_z
    cos_r = w + (((1.0 - w) - half_z) + (z * z * _horner(z, _COS) - hi * lo))
    quadrant = n - 4.0 * jnp.floor(0.25 * n)  # n mod 4, exact
    odd = (quadrant == 1.0) | (quadrant == 3.0)
    sin_x = jnp.where(odd, cos_r, sin_r)
    cos_x = jnp.where(odd, sin_r, cos_r)
    sin_x = jnp.where(quadrant >= 2.0, -sin_x, sin_x)
    sin_x = jnp.where(x == 0, x, sin_x)  # sin(-0) = -0 (the reduction made r = +0)
    cos_x = jnp.where((quadrant == 1.0) | (quadrant == 2.0), -cos_x, cos_x)
    return sin_x, cos_x


@jax.custom_jvp
def _sincos(x: Array) -> tuple[Array, Array]:
    if np.dtype(x.dtype) not in _PIO2_PARTS:
        return jnp.sin(x), jnp.cos(x)
    return _sincos_reduced(x)


@_sincos.defjvp
def _sincos_jvp(primals, tangents):
    (x,), (x_dot,) = primals, tangents
    sin_x, cos_x = _sincos(x)
    return (sin_x, cos_x), (cos_x * x_dot, -sin_x * x_dot)


def _float(x: ArrayLike) -> Array:
    x = jnp.asarray(x)
    if not jnp.issubdtype(x.dtype, jnp.floating):
        x = x.astype(jnp.result_type(float))
    return x


def _native() -> bool:
    """XLA's own functions: on an accelerator (module docstring)."""
    return jax.default_backend() != "cpu"


def sincos(x: ArrayLike) -> tuple[Array, Array]:
    """``(sin x, cos x)`` elementwise, any shape; float64/float32 within 1 ulp.

    Other dtypes (float16, bfloat16, integers promoted to float) use ``jnp.sin``/``jnp.cos``.
    """
    if _native():
        x = _float(x)
        return jnp.sin(x), jnp.cos(x)
    return _sincos(_float(x))


# sin r = r + r^3 P(r^2) on |r| <= pi/2 + 0.01: P is mpmath.chebyfit of
# (sin sqrt(z) - sqrt(z)) / z^(3/2) on [0, (pi/2 + 0.01)^2] (40 digits), degree 7 for
# float64 (fit error 1.5e-18 in sin) and degree 4 for float32 (1e-8); coefficients ascending.
_SIN_HALF_TURN = {
    np.dtype(np.float64): (
        -0.16666666666666666,
        0.008333333333333314,
        -0.00019841269841253803,
        2.755731921884876e-06,
        -2.50521075772035e-08,
        1.6058974748931153e-10,
        -7.643888970621481e-13,
        2.7304371554532578e-15,
    ),
    np.dtype(np.float32): (
        -0.16666666663699856,
        0.008333332739571844,
        -0.00019841079516132477,
        2.7535934248586835e-06,
        -2.406801493126407e-08,
    ),
}


def _sin_odd_multiple(x: Array, cosine: bool) -> Array:
    """``cos x`` (``cosine``) or ``sin x`` by one polynomial on ``|r| <= pi/2``.

    ``x = k pi/2 + r`` with ``k = 2n`` (sin, ``n = round(x / pi)``) or ``k = 2n + 1`` (cos,
    ``n = floor(x / pi)``); then ``sin x = (-1)^n sin r`` and ``cos x = -(-1)^n sin r``.
    """
    *parts, _ = _PIO2_PARTS[np.dtype(x.dtype)]
    half_turns = x * (1.0 / np.pi)
    n = jnp.floor(half_turns) if cosine else jnp.round(half_turns)
    k = 2.0 * n + 1.0 if cosine else 2.0 * n
    r = x
    for part in parts:  # k * part exact (see _PIO2_PARTS); the tail is below an ulp of 1
        r = r - k * part
    # Beyond the reduction limit r carries the angle's own rounding; keep the polynomial bounded.
    r = jnp.clip(r, -2.0, 2.0)
    z = r * r
    value = r + r * (z * _horner(z, _SIN_HALF_TURN[np.dtype(x.dtype)]))
    n_even = n == 2.0 * jnp.floor(0.5 * n)
    return jnp.where(n_even == cosine, -value, value)


@jax.custom_jvp
def _sin_alone(x: Array) -> Array:
    if np.dtype(x.dtype) not in _SIN_HALF_TURN:
        return jnp.sin(x)
    return _sin_odd_multiple(x, cosine=False)


@jax.custom_jvp
def _cos_alone(x: Array) -> Array:
    if np.dtype(x.dtype) not in _SIN_HALF_TURN:
        return jnp.cos(x)
    return _sin_odd_multiple(x, cosine=True)


@_sin_alone.defjvp
def _sin_alone_jvp(primals, tangents):
    (x,), (x_dot,) = primals, tangents
    return _sin_alone(x), _cos_alone(x) * x_dot


@_cos_alone.defjvp
def _cos_alone_jvp(primals, tangents):
    (x,), (x_dot,) = primals, tangents
    return _cos_alone(x), -_sin_alone(x) * x_dot


def sin_alone(x: ArrayLike) -> Array:
    """``sin x`` elementwise on its own (no shared reduction), to absolute accuracy.

    For angles whose sin and cos are stored as separate rows (module docstring).
    """
    return jnp.sin(_float(x)) if _native() else _sin_alone(_float(x))


def cos_alone(x: ArrayLike) -> Array:
    """``cos x`` elementwise on its own, to absolute accuracy (see ``sin_alone``)."""
    return jnp.cos(_float(x)) if _native() else _cos_alone(_float(x))


def _atan2_value(y: Array, x: Array) -> Array:
    dtype = jnp.result_type(y, x)
    y, x = jnp.asarray(y, dtype), jnp.asarray(x, dtype)
    abs_x, abs_y = jnp.abs(x), jnp.abs(y)
    swapped = abs_y > abs_x
    small = jnp.minimum(abs_x, abs_y)
    large = jnp.maximum(abs_x, abs_y)
    both_inf = jnp.isinf(small)  # then large is inf too: atan(1), from m = M = 1
    small = jnp.where(both_inf, 1.0, small)
    large = jnp.where(both_inf, 1.0, large)
    direct = small <= 0.4375 * large
    middle = ~direct & (small <= 0.6875 * large)
    num = jnp.where(direct, small, jnp.where(middle, 2.0 * small - large, small - large))
    den = jnp.where(direct, large, jnp.where(middle, 2.0 * large + small, small + large))
    t = num / jnp.where(den == 0, 1.0, den)  # den = 0 only at x = y = 0: t = 0
    z = t * t
    w = z * z
    odd_terms = z * _horner(w, _ATAN[0::2])
    even_terms = w * _horner(w, _ATAN[1::2])
    series = t * (odd_terms + even_terms)
    hi = jnp.where(direct, 0.0, jnp.where(middle, _ATAN_HALF[0], _PI_OVER_4[0]))
    lo = jnp.where(direct, 0.0, jnp.where(middle, _ATAN_HALF[1], _PI_OVER_4[1]))
    angle = hi - ((series - lo) - t)  # atan(small / large) in [0, pi/4]
    angle = jnp.where(swapped, (_PI_OVER_2[0] - angle) + _PI_OVER_2[1], angle)
    angle = jnp.where(jnp.signbit(x), (_PI[0] - angle) + _PI[1], angle)
    return jnp.where(jnp.signbit(y), -angle, angle)


@jax.custom_jvp
def _atan2(y: Array, x: Array) -> Array:
    if np.dtype(jnp.result_type(y, x)) not in _PIO2_PARTS:
        return jnp.arctan2(y, x)
    return _atan2_value(y, x)


@_atan2.defjvp
def _atan2_jvp(primals, tangents):
    (y, x), (y_dot, x_dot) = primals, tangents
    inv_r2 = 1.0 / (x * x + y * y)
    return _atan2(y, x), (x * y_dot - y * x_dot) * inv_r2


def atan2(y: ArrayLike, x: ArrayLike) -> Array:
    """``atan2(y, x)`` elementwise with broadcasting, like ``jnp.arctan2`` (within 2 ulp)."""
    y, x = jnp.asarray(y), jnp.asarray(x)
    dtype = jnp.result_type(y, x, float)
    y, x = jnp.broadcast_arrays(y.astype(dtype), x.astype(dtype))
    return jnp.arctan2(y, x) if _native() else _atan2(y, x)
