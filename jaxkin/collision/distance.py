"""Exact signed distances between collision primitives, in closed form (segment-cylinder:
but for a quartic's root, found by Newton's method to rounding).

Every function here works on plain arrays and broadcasts numpy-style over leading axes (the last
axis of a point is its 3 coordinates; a rotation is ``(..., 3, 3)``), so one call evaluates a
whole matrix of pairs. The signed distance of two convex shapes is their Euclidean distance when
apart and minus their penetration depth (the length of the shortest translation that separates
them) when they overlap; it is zero in contact.

Shapes:
- sphere: centre ``c``, radius ``r``;
- capsule: segment ``a``-``b`` swept by a ball of radius ``r`` (a sphere when ``a == b``);
- box: centre ``c``, rotation ``R`` (columns are the box axes in the world frame), half extents
  ``h``; the box is ``{c + R u : |u_i| <= h_i}``;
- half-space: unit normal ``n`` and offset ``o``; the solid is ``{x : n . x <= o}``;
- cylinder: centre ``c``, unit axis ``a``, radius ``r``, half-length ``h``; the solid is
  ``{c + z a + w : |z| <= h, w . a = 0, |w| <= r}``.

A sphere or capsule is a point or segment grown by a ball, and for any convex ``K`` the signed
distance to ``K`` grown by radius ``r`` is the signed distance to ``K`` minus ``r`` (inside and
outside), so every pair reduces to a point or segment against the other shape:

- point/segment against point/segment: a segment has no volume, so two segments never
  penetrate and their signed distance is their distance (closest points: the interior critical
  point of ``|p(s) - q(t)|^2`` and the four edges of ``[0, 1]^2``, each a point-segment
  projection; the smallest is exact, also for parallel segments);
- point against box: ``|max(|u| - h, 0)|`` outside, ``max_i(|u_i| - h_i)`` inside;
- segment against box: outside, ``f(t) = sum_i max(|u_i(t)| - h_i, 0)^2`` is a convex, C1,
  piecewise quadratic in ``t`` whose pieces change at the knots where ``u_i(t) = +-h_i``;
  ``f'`` is nondecreasing, so the minimiser lies between the last knot with ``f' <= 0`` and
  the first with ``f' > 0``, where the active faces are fixed and the quadratic's minimiser is
  closed form: exact, with no sort.
  The Minkowski difference ``box - segment`` is a zonotope whose facet normals are the box axes
  and the cross products of the segment's direction with them; its smallest support value
  ``sum_i h_i |m_i| - min(m . u(0), m . u(1))`` over those six unit normals ``m`` and their
  opposites is positive exactly when the shapes overlap (separating axes), and is then the
  penetration depth (the distance from the origin to the zonotope's boundary);
- point/segment against half-space: ``min(n . a, n . b) - o``;
- point against cylinder: the rectangle ``rho <= r, |z| <= h`` in the half-plane of the
  point's distance ``rho`` from the axis and its height ``z``, as point against box;
- segment against cylinder: the smallest support value of ``cylinder - segment`` over the
  normals of its smooth boundary (the caps, the side, and the rims seen along the segment,
  quarter ellipses whose nearest point solves a quartic: Newton's method from a closed-form
  start) is the depth where they overlap; apart, the distance is an end's (the sign of the
  convex squared distance's slope at the ends says which) or the segment's line's (the
  largest of minus those support values). See ``segment_cylinder``.

Gradients: the closest-point parameters are minimisers, so (Danskin's theorem) the gradient of
the distance is its partial gradient at fixed parameters; they are computed under
``stop_gradient`` and the distance is evaluated from them. Every square root and division goes
through a double ``where`` so that gradients stay finite in contact (distance 0), at coincident
centres and for degenerate segments; at such points the returned gradient is one of the valid
subgradients or zero.
"""

from __future__ import annotations

import functools

import jax
import jax.numpy as jnp
from jax.typing import ArrayLike

__all__ = [
    "capsule_box",
    "capsule_capsule",
    "capsule_cylinder",
    "capsule_halfspace",
    "point_box",
    "point_cylinder",
    "point_segment",
    "segment_box",
    "segment_cylinder",
    "segment_segment",
    "sphere_box",
    "sphere_capsule",
    "sphere_cylinder",
    "sphere_halfspace",
    "sphere_sphere",
]


def _dot(x: jax.Array, y: jax.Array) -> jax.Array:
    # products written out, not a reduction: XLA on CPU vectorises elementwise code, not
    # size-3 sums (any dimension: the planar robots' obstacle costs use d = 2)
    out = x[..., 0] * y[..., 0]
    for i in range(1, x.shape[-1]):
        out = out + x[..., i] * y[..., i]
    return out


def _norm(x: jax.Array) -> jax.Array:
    """Euclidean norm over the last axis, with a zero (not NaN) gradient at the origin."""
    sq = _dot(x, x)
    positive = sq > 0.0
    # double where: sqrt's derivative is infinite at 0, so feed it 1 there and select 0 after
    return jnp.where(positive, jnp.sqrt(jnp.where(positive, sq, 1.0)), 0.0)


def _safe_ratio(num: ArrayLike, den: ArrayLike) -> jax.Array:
    """``num / den`` where ``den != 0``, else 0 (a degenerate segment's parameter)."""
    nonzero = den != 0.0
    return jnp.where(nonzero, num / jnp.where(nonzero, den, 1.0), 0.0)


def _segment_parameter(p: jax.Array, a: jax.Array, d: jax.Array) -> jax.Array:
    """The parameter ``t in [0, 1]`` of the point of ``a + t d`` nearest to ``p``."""
    return jnp.clip(_safe_ratio(_dot(p - a, d), _dot(d, d)), 0.0, 1.0)


def point_segment(p: jax.Array, a: jax.Array, b: jax.Array) -> jax.Array:
    """Distance from points ``p`` to segments ``a``-``b``; shapes ``(..., d)`` -> ``(...)``
    (``d = 3``, or any other dimension). The nearest point is ``a + t (b - a)`` with ``t =
    clip((p - a).(b - a) / |b - a|^2, 0, 1)`` (``t = 0`` for a zero-length segment)."""
    d = b - a
    t = jax.lax.stop_gradient(_segment_parameter(p, a, d))
    return _norm(p - (a + t[..., None] * d))


def segment_segment(a0: jax.Array, a1: jax.Array, b0: jax.Array, b1: jax.Array) -> jax.Array:
    """Distance between segments ``a0``-``a1`` and ``b0``-``b1``; ``(..., 3)`` -> ``(...)``.

    Closest points of ``p(s) = a0 + s da`` and ``q(t) = b0 + t db`` over ``[0, 1]^2``: the
    interior critical point ``s = (b f - c e) / (a e - b^2)``, ``t = (a f - b c) / (a e - b^2)``
    with ``a = da.da, b = da.db, e = db.db, c = da.r, f = db.r, r = a0 - b0`` (used only when it
    lies inside the square), else the best of the four edges (an endpoint against the other
    segment). Exact for parallel and degenerate segments.
    """
    da, db = a1 - a0, b1 - b0
    r = a0 - b0
    a, b, e = _dot(da, da), _dot(da, db), _dot(db, db)
    c, f = _dot(da, r), _dot(db, r)
    den = a * e - b * b
    s_in = _safe_ratio(b * f - c * e, den)
    t_in = _safe_ratio(a * f - b * c, den)
    inside = (den > 0.0) & (s_in >= 0.0) & (s_in <= 1.0) & (t_in >= 0.0) & (t_in <= 1.0)
    zero, one = jnp.zeros_like(a), jnp.ones_like(a)
    # candidates (s, t): interior, then a0 / a1 against segment b, b0 / b1 against segment a
    candidates = [
        (s_in, t_in),
        (zero, jnp.clip(_safe_ratio(f, e), 0.0, 1.0)),
        (one, jnp.clip(_safe_ratio(f + b, e), 0.0, 1.0)),
        (jnp.clip(_safe_ratio(-c, a), 0.0, 1.0), zero),
        (jnp.clip(_safe_ratio(b - c, a), 0.0, 1.0), one),
    ]
    rx, ry, rz = _coords(r)
    ax, ay, az = _coords(da)
    bx, by, bz = _coords(db)
    squares = []
    for s, t in candidates:
        # the parameters are stopped: the min's gradient is the partial one at the closest pair
        s, t = jax.lax.stop_gradient(s), jax.lax.stop_gradient(t)
        sq = (rx + s * ax - t * bx) ** 2 + (ry + s * ay - t * by) ** 2 + (rz + s * az - t * bz) ** 2
        squares.append(sq)
    best = functools.reduce(jnp.minimum, squares[1:], jnp.where(inside, squares[0], jnp.inf))
    positive = best > 0.0
    return jnp.where(positive, jnp.sqrt(jnp.where(positive, best, 1.0)), 0.0)


def _to_box(p: jax.Array, center: jax.Array, rotation: jax.Array | None) -> list[jax.Array]:
    """Coordinates of world points ``p`` in a box's frame, ``R^T (p - c)``, as three arrays
    (``p - c`` per coordinate when ``rotation`` is None: an axis-aligned box).

    Written out per coordinate: a batched 3x3 product is an unfused dot on CPU, and the
    kernels below run fastest on separate coordinate arrays (elementwise code vectorises).
    """
    x = [p[..., j] - center[..., j] for j in range(p.shape[-1])]  # split: no (..., 3) temporary
    if rotation is None:  # axis-aligned, any dimension
        return x
    return [
        rotation[..., 0, i] * x[0] + rotation[..., 1, i] * x[1] + rotation[..., 2, i] * x[2]
        for i in range(3)
    ]


def _coords(x: jax.Array) -> list[jax.Array]:
    return [x[..., i] for i in range(x.shape[-1])]


def point_box(
    p: jax.Array, center: jax.Array, rotation: jax.Array | None, half: jax.Array
) -> jax.Array:
    """Signed distance from points ``p`` to oriented boxes; negative inside (minus the depth
    to the nearest face).

    ``p, center, half``: ``(..., 3)``; ``rotation``: ``(..., 3, 3)``, or None for boxes
    aligned with the axes (then any dimension ``d``: ``p, center, half`` ``(..., d)``);
    returns ``(...)``.
    """
    u, h = _to_box(p, center, rotation), _coords(half)
    q = [jnp.abs(u[i]) - h[i] for i in range(len(h))]
    out_sq = sum(jnp.maximum(qi, 0.0) ** 2 for qi in q)
    positive = out_sq > 0.0
    outside = jnp.where(positive, jnp.sqrt(jnp.where(positive, out_sq, 1.0)), 0.0)
    inside = q[0]
    for qi in q[1:]:
        inside = jnp.maximum(inside, qi)
    return jnp.where(positive, outside, inside)


def _segment_box_parameter(u: list, d: list, h: list) -> jax.Array:
    """The ``t in [0, 1]`` minimising the squared distance from ``u0 + t du`` to the box.

    ``f(t) = sum_i max(|u0_i + t du_i| - h_i, 0)^2`` is convex, C1, and quadratic between the
    knots ``0, 1`` and ``t = (+-h_i - u0_i) / du_i``, so ``f'`` is nondecreasing: the minimiser
    lies between the last knot with ``f' <= 0`` and the first with ``f' > 0``, an interval
    with no knot inside. There the active faces (sign ``s_i`` where ``|u_i| > h_i`` at its
    midpoint) are fixed and ``t* = sum_i (s_i h_i - u0_i) du_i / sum_i du_i^2``, clipped to
    the interval (its midpoint when no face is active). No sort: two running extrema, written
    per coordinate (elementwise code vectorises on CPU; size-3 axes do not).
    """
    knots = [jnp.zeros_like(u[0]), jnp.ones_like(u[0])]
    for i in range(3):
        knots += [jnp.clip(_safe_ratio(h[i] - u[i], d[i]), 0.0, 1.0)]
        knots += [jnp.clip(_safe_ratio(-h[i] - u[i], d[i]), 0.0, 1.0)]
    lo, hi = jnp.zeros_like(u[0]), jnp.ones_like(u[0])
    for t in knots:
        slope = 0.0  # f'(t) / 2
        for i in range(3):
            ui = u[i] + t * d[i]
            slope = slope + jnp.sign(ui) * jnp.maximum(jnp.abs(ui) - h[i], 0.0) * d[i]
        lo = jnp.where(slope <= 0.0, jnp.maximum(lo, t), lo)
        hi = jnp.where(slope > 0.0, jnp.minimum(hi, t), hi)
    hi = jnp.maximum(hi, lo)
    mid = 0.5 * (lo + hi)
    num, den = 0.0, 0.0
    for i in range(3):
        ui = u[i] + mid * d[i]
        sign = jnp.where(ui > h[i], 1.0, jnp.where(ui < -h[i], -1.0, 0.0))
        num = num + jnp.abs(sign) * (sign * h[i] - u[i]) * d[i]
        den = den + jnp.abs(sign) * d[i] * d[i]
    return jnp.clip(jnp.where(den > 0.0, _safe_ratio(num, den), mid), lo, hi)


def _segment_box_depth(u: list, v: list, h: list) -> jax.Array:
    """The smallest support value of the zonotope ``box - segment`` over its facet normals
    (positive exactly when the box-frame segment ``u0``-``u1`` overlaps the box, and then its
    penetration depth).

    Normals: the box axes ``+-e_i``, with support values ``h_i - min(u0_i, u1_i)`` and
    ``h_i + max(u0_i, u1_i)``; and the unit cross products ``m = d x e_i / |d x e_i|``
    (``d = u1 - u0``), perpendicular to ``d`` so ``m . u0 = m . u1``, with support value
    ``sum_j h_j |m_j| - |m . u0|`` over the pair ``+-m``. A zero cross product (the segment
    along that axis, or a point) adds no facet.
    """
    d = [v[i] - u[i] for i in range(3)]
    depth = jnp.minimum(h[0] - jnp.minimum(u[0], v[0]), h[0] + jnp.maximum(u[0], v[0]))
    for i in (1, 2):
        depth = jnp.minimum(depth, h[i] - jnp.minimum(u[i], v[i]))
        depth = jnp.minimum(depth, h[i] + jnp.maximum(u[i], v[i]))
    for i in range(3):
        j, k = (i + 1) % 3, (i + 2) % 3
        # d x e_i has components d_k along j and -d_j along k (cyclic order i, j, k)
        length_sq = d[j] * d[j] + d[k] * d[k]
        valid = length_sq > 0.0
        length = jnp.sqrt(jnp.where(valid, length_sq, 1.0))
        support = (h[j] * jnp.abs(d[k]) + h[k] * jnp.abs(d[j])) / length
        along = jnp.abs(d[k] * u[j] - d[j] * u[k]) / length
        depth = jnp.where(valid, jnp.minimum(depth, support - along), depth)
    return depth


def segment_box(
    a: jax.Array, b: jax.Array, center: jax.Array, rotation: jax.Array, half: jax.Array
) -> jax.Array:
    """Signed distance from segments ``a``-``b`` to oriented boxes; minus the depth inside.

    ``a, b, center, half``: ``(..., 3)``; ``rotation``: ``(..., 3, 3)``; returns ``(...)``.
    """
    u, v, h = _to_box(a, center, rotation), _to_box(b, center, rotation), _coords(half)
    d = [v[i] - u[i] for i in range(3)]
    t = jax.lax.stop_gradient(_segment_box_parameter(u, d, h))
    out_sq = sum(jnp.maximum(jnp.abs(u[i] + t * d[i]) - h[i], 0.0) ** 2 for i in range(3))
    positive = out_sq > 0.0
    outside = jnp.where(positive, jnp.sqrt(jnp.where(positive, out_sq, 1.0)), 0.0)
    # overlap test by separating axes (origin inside the zonotope: every support value > 0),
    # not by the excess at t: at a face the excess can round to either side of zero
    depth = _segment_box_depth(u, v, h)
    return jnp.where(depth > 0.0, -depth, outside)


def sphere_sphere(c1: jax.Array, r1: jax.Array, c2: jax.Array, r2: jax.Array) -> jax.Array:
    """Signed distance between spheres: ``|c1 - c2| - r1 - r2``."""
    sq = sum((c1[..., i] - c2[..., i]) ** 2 for i in range(3))
    positive = sq > 0.0
    return jnp.where(positive, jnp.sqrt(jnp.where(positive, sq, 1.0)), 0.0) - r1 - r2


def sphere_capsule(
    c: jax.Array, rc: jax.Array, a: jax.Array, b: jax.Array, r: jax.Array
) -> jax.Array:
    """Signed distance between spheres ``(c, rc)`` and capsules ``(a, b, r)``."""
    return point_segment(c, a, b) - rc - r


def capsule_capsule(
    a0: jax.Array, a1: jax.Array, ra: jax.Array, b0: jax.Array, b1: jax.Array, rb: jax.Array
) -> jax.Array:
    """Signed distance between capsules ``(a0, a1, ra)`` and ``(b0, b1, rb)``."""
    return segment_segment(a0, a1, b0, b1) - ra - rb


def sphere_box(
    c: jax.Array, r: jax.Array, center: jax.Array, rotation: jax.Array, half: jax.Array
) -> jax.Array:
    """Signed distance between spheres ``(c, r)`` and oriented boxes."""
    return point_box(c, center, rotation, half) - r


def capsule_box(
    a: jax.Array,
    b: jax.Array,
    r: jax.Array,
    center: jax.Array,
    rotation: jax.Array,
    half: jax.Array,
) -> jax.Array:
    """Signed distance between capsules ``(a, b, r)`` and oriented boxes."""
    return segment_box(a, b, center, rotation, half) - r


def sphere_halfspace(c: jax.Array, r: jax.Array, normal: jax.Array, offset: jax.Array) -> jax.Array:
    """Signed distance between spheres and half-spaces ``{x : n . x <= offset}`` (unit ``n``)."""
    return _dot(normal, c) - offset - r


def capsule_halfspace(
    a: jax.Array, b: jax.Array, r: jax.Array, normal: jax.Array, offset: jax.Array
) -> jax.Array:
    """Signed distance between capsules and half-spaces ``{x : n . x <= offset}``."""
    return jnp.minimum(_dot(normal, a), _dot(normal, b)) - offset - r


# ------------------------------------------------------------------------------ cylinders
# Vectors as lists of their three coordinate arrays: elementwise code vectorises on CPU,
# ``(..., 3)`` temporaries and size-3 reductions do not.
def _vec(x: jax.Array) -> list[jax.Array]:
    return [x[..., i] for i in range(3)]


def _sub(x: list, y: list) -> list:
    return [xi - yi for xi, yi in zip(x, y, strict=True)]


def _add(x: list, y: list) -> list:
    return [xi + yi for xi, yi in zip(x, y, strict=True)]


def _times(x: list, s: jax.Array) -> list:
    return [xi * s for xi in x]


def _vdot(x: list, y: list) -> jax.Array:
    return x[0] * y[0] + x[1] * y[1] + x[2] * y[2]


def _vcross(x: list, y: list) -> list:
    return [x[1] * y[2] - x[2] * y[1], x[2] * y[0] - x[0] * y[2], x[0] * y[1] - x[1] * y[0]]


def _vnorm(x: list) -> jax.Array:
    """``|x|`` with a zero (not NaN) gradient at the origin."""
    sq = _vdot(x, x)
    positive = sq > 0.0
    return jnp.where(positive, jnp.sqrt(jnp.where(positive, sq, 1.0)), 0.0)


def _vunit(x: list) -> list:
    """``x / |x|``, 0 where ``x = 0``."""
    return _times(x, _safe_ratio(1.0, _vnorm(x)))


def _point_cylinder(v: list, axis: list, radius: jax.Array, half: jax.Array) -> jax.Array:
    """``point_cylinder`` of ``v = p - center`` in coordinate lists."""
    q_r = _vnorm(_vcross(axis, v)) - radius
    q_z = jnp.abs(_vdot(axis, v)) - half
    out_sq = jnp.maximum(q_r, 0.0) ** 2 + jnp.maximum(q_z, 0.0) ** 2
    positive = out_sq > 0.0
    outside = jnp.where(positive, jnp.sqrt(jnp.where(positive, out_sq, 1.0)), 0.0)
    return jnp.where(positive, outside, jnp.maximum(q_r, q_z))


def point_cylinder(
    p: jax.Array, center: jax.Array, axis: jax.Array, radius: jax.Array, half: jax.Array
) -> jax.Array:
    """Signed distance from points ``p`` to solid cylinders; negative inside.

    With ``z = axis . (p - c)`` and ``rho = |axis x (p - c)|`` (unit ``axis``) the cylinder is
    the rectangle ``rho <= r, |z| <= h`` of the half-plane ``(rho, z)``, and the distance is
    that rectangle's: ``|(max(rho - r, 0), max(|z| - h, 0))|`` outside, ``max(rho - r, |z| -
    h)`` inside. ``p, center, axis``: ``(..., 3)``; ``radius, half``: ``(...)``.
    """
    return _point_cylinder(_sub(_vec(p), _vec(center)), _vec(axis), radius, half)


# Newton steps taken for every pair in one fused pass; a loop finishes the few pairs that
# have not converged by then (at most _ARC_MAX_STEPS steps in all)
_ARC_STEPS = 10
_ARC_MAX_STEPS = 64


def _arc_nudge(dtype) -> float:
    """The relative size of the perturbations that keep the rim problem regular (``eps^2``):
    far below rounding in the result, which they move only to second order."""
    return float(jnp.finfo(dtype).eps) ** 2


def _cube_root_above(y: jax.Array) -> jax.Array:
    """A power of two in ``[cbrt(y), 2 cbrt(y))`` for ``y >= 0`` (``2^-42`` below float32's
    normal range), from the exponent bits of ``y`` in float32: ``2^ceil((e + 1) / 3)`` for
    ``y in [2^e, 2^(e + 1))``. ``jnp.cbrt`` is a scalar library call on CPU; this is four
    integer operations (rounding to float32 never lowers the binade)."""
    bits = jax.lax.bitcast_convert_type(y.astype(jnp.float32), jnp.int32)
    # exponent field E = e + 127 -> ceil((E - 126) / 3) + 127 = (E + 2) // 3 + 85
    power = jax.lax.div((bits >> 23) + 2, jnp.int32(3)) + 85  # truncation: E + 2 > 0
    return jax.lax.bitcast_convert_type(power << 23, jnp.float32).astype(y.dtype)


def _binade(y: jax.Array) -> jax.Array:
    """The power of two ``2^floor(log2 y)`` for normal ``y > 0`` (0 for 0 and subnormals): the
    exponent bits of ``y`` with its mantissa cleared. Scaling by it is exact."""
    info = jnp.finfo(y.dtype)
    integer = jnp.int32 if info.bits == 32 else jnp.int64
    mask = ((1 << info.nexp) - 1) << info.nmant
    bits = jax.lax.bitcast_convert_type(y, integer) & jnp.asarray(mask, integer)
    return jax.lax.bitcast_convert_type(bits, y.dtype)


def _rim_frame(v0: list, d: list, axis: list):
    """The plane perpendicular to the segment, in vectors of the same length ``L^2 M`` (``L =
    |d|``, ``m = axis x d``, ``M = |m|``): ``m' = L^2 m - (m . d) d`` (``m`` made orthogonal to
    ``d`` again after rounding, which matters when ``m`` is mostly rounding: a segment nearly
    along the axis) and ``L n``, ``n = d x m``. Returns ``m', n, m . m, d . d, |axis . d|`` and
    the line's coordinates ``v0 . m', v0 . n``."""
    m = _vcross(axis, d)
    dd, md = _vdot(d, d), _vdot(m, d)
    m_ = _sub(_times(m, dd), _times(d, md))
    n = _vcross(d, m)
    return m_, n, _vdot(m, m), dd, jnp.abs(_vdot(axis, d)), _vdot(v0, m_), _vdot(v0, n)


def _arc_problem(v0: list, d: list, axis: list, radius, half):
    """The rim problem of ``segment_cylinder`` in closed form: ``lo``, the coefficients ``B
    u, c3, c1`` of the quartic ``S``, Newton's start (``_arc_parameter``) and ``B / A`` (as
    ``|axis . d| + nudge`` and ``L``).

    Projected along the segment (``_rim_frame``) the rim is the ellipse ``A = r, B = r |axis .
    d| / L`` about ``(0, H)``, ``H = h M / L``, and the segment's line is the point ``(p, q) =
    (|v0 . m'| / (L^2 M), |v0 . n| / (L M))`` (folded), ``u = q - H``. The quartic's roots do
    not change when its coefficients are scaled: by ``L^2 M`` here, which leaves a single
    square root, ``M``. Lengths are in units of ``s``, the power of two at most ``r + h``
    (float32's range; exact, so the frame is the one ``_arc_normal`` computes from the
    unscaled vectors, which matters where it is mostly rounding). Two regularising nudges of
    relative size ``eps^2`` (``_arc_nudge``): ``|axis . d| + eps^2 |d|_1`` for ``|axis . d|``
    (a flat rim, ``B = 0``, has a fan of normals at its ends; the nudged ellipse's normal
    there is the limit of those of ``B > 0``) and ``r + eps^2 s`` for ``r`` (the same for a
    rim of radius 0). Every expensive operation here (square roots, divisions) has a single
    use: XLA then fuses the whole pass into one loop.
    """
    tiny = _arc_nudge(jnp.result_type(radius))
    # a power of two: the frame is then exactly the one _arc_normal computes unscaled (when
    # it is mostly rounding, a segment nearly along the axis, another rounding would turn it)
    size = _binade(radius + half)
    unit = 1.0 / jnp.where(size > 0.0, size, 1.0)
    v0, d = _times(v0, unit), _times(d, unit)
    r, h = radius * unit + tiny, half * unit
    _, _, mm, dd, along, v0m, v0n = _rim_frame(v0, d, axis)
    nudge = tiny * (jnp.abs(d[0]) + jnp.abs(d[1]) + jnp.abs(d[2]))
    flat = along + nudge
    bu = r * flat * (jnp.abs(v0n) - h * mm)
    # (A^2 - B^2) (L M)^2 / M, with L^2 - (|a.d| + nudge)^2 = M^2 - nudge (2 |a.d| + nudge)
    spread = r * r * jnp.sqrt(mm) * jnp.maximum(mm - nudge * (2.0 * along + nudge), 0.0)
    ap = r * jnp.abs(v0m)
    c3, c1 = 2.0 * (spread + ap), 2.0 * (ap - spread)
    # below the rim's centre by more than (A^2 - B^2) / B the arc's convex part is its top
    lo = jnp.where(-bu > spread, 1.0, 0.0)
    positive = c3 > 0.0
    c3_ = jnp.where(positive, c3, 1.0)
    # S >= c3 t^3 + c1 t - B u when u >= 0 (and S >= c3 t^3 + c1 t when u < 0), whose
    # largest root is at most cbrt(B u / c3) + sqrt(-c1 / c3), and at most B u / c1 when c1 > 0
    rising = c1 > 0.0
    ratio = jnp.where(rising, bu / jnp.where(rising, c1, 1.0), 2.0)
    start = _cube_root_above(jnp.maximum(bu, 0.0) / c3_) + jnp.sqrt(jnp.maximum(-c1, 0.0) / c3_)
    start = jnp.where(positive, jnp.clip(jnp.minimum(start, ratio), lo, 1.0), 1.0)
    return lo, bu, c3, c1, start, flat, dd


def _arc_newton(x, lo, bu, c3, c1):
    """One Newton step on ``S(tau) = B u tau^4 + c3 tau^3 + c1 tau - B u`` (``_arc_parameter``),
    kept in ``[lo, 1]``; where ``S > 0`` but ``S' <= 0`` there is no root left of ``x`` and
    the step goes to ``lo``."""
    s = ((bu * x + c3) * x * x + c1) * x - bu
    ds = (4.0 * bu * x + 3.0 * c3) * x * x + c1
    rising = ds > 0.0
    step = jnp.where(rising, s / jnp.where(rising, ds, 1.0), jnp.where(s > 0.0, 2.0, 0.0))
    return jnp.clip(x - step, lo, 1.0)


def _half_angle(x, y):
    """``tan(atan2(y, x) / 2)`` for ``x, y >= 0``, without cancellation: ``y / (x + |(x, y)|)``
    (0 at ``x = y = 0``: a segment of length 0, whose rim problem is empty)."""
    den = x + jnp.sqrt(x * x + y * y)
    positive = den > 0.0
    return jnp.where(positive, y / jnp.where(positive, den, 1.0), 0.0)


def _normal_of_point(tau, flat, dd):
    """``tan(alpha / 2)`` of the normal ``(B (1 - tau^2), 2 A tau)`` at the ellipse's point
    ``tau`` (``B / A = flat / sqrt(dd)``)."""
    return _half_angle(flat * (1.0 - tau * tau), 2.0 * jnp.sqrt(dd) * tau)


def _point_of_normal(t, flat, dd):
    """The inverse of ``_normal_of_point``: ``tan(phi / 2)`` for ``tan(phi) = (B / A)
    tan(alpha)``."""
    return _half_angle(jnp.sqrt(dd) * (1.0 - t * t), 2.0 * t * flat)


def _code(t, done):
    """``t`` where ``done``, else ``-1 - t`` (``t`` in ``[0, 1]``), with ``t`` used once (an
    expensive operation with two uses splits XLA's fusion)."""
    return jnp.where(done, 0.0, -1.0) + jnp.where(done, 1.0, -1.0) * t


def _arc_parameter(problem, tol: float) -> jax.Array:
    """The normal's parameter ``t = tan(alpha / 2) in [0, 1]`` at the point ``(A cos phi, B sin
    phi)`` of a quarter ellipse (``A >= B >= 0``) nearest to ``(p, u)``, ``p >= 0``, where the
    squared distance has a local minimum (``phi = 0`` if it has none; ``phi = pi / 2`` when the
    rim's convex part is its top, see below). ``problem()`` returns ``_arc_problem``'s values;
    it is called again inside the loop, so that nothing but ``t`` is stored between passes.

    In ``tau = tan(phi / 2)`` the slope of the squared distance, times ``(1 + tau^2)^2 / 2``,
    is the quartic ``S(tau) = B u tau^4 + c3 tau^3 + c1 tau - B u`` with ``c3 = 2 (A^2 - B^2 +
    A p) >= 0`` and ``c1 = 2 (A p - A^2 + B^2)``; ``S(1) = 4 A p >= 0``. Its second derivative
    ``12 tau (B u tau + c3 / 2)`` is >= 0 on ``[0, 1]`` unless ``-B u > A^2 - B^2``; then
    (``lo = 1``) the squared distance is concave in ``xi = cos phi`` wherever it is not convex
    (``B |u| / (A^2 - B^2) > sin^3 phi``, the sign of its second derivative ``A^2 - B^2 + B u /
    sin^3 phi``) and its only candidates are the arc's ends, the top and the side's end
    (already a candidate of the side). Otherwise ``S`` is convex and the local minimum is its
    largest root, where ``S`` turns positive (none: the distance grows along the whole arc,
    ``tau = 0``). Newton's method on a convex function from a point right of its largest
    root, with ``S >= 0``, stays right of it and converges monotonically. The start is such a
    point in closed form: ``S`` minus its quartic term, ``B u tau^4 >= 0`` (when ``u < 0`` the
    quartic and constant terms add ``B |u| (1 - tau^4) >= 0``), is the cubic ``c3 tau^3 + c1
    tau - B max(u, 0)``, whose largest root is at most ``cbrt(B u / c3) + sqrt(-c1 / c3)``
    and at most ``B u / c1`` when ``c1 > 0`` (and within a factor 2 of the smaller bound); the
    cube root is bounded by a power of two (``_cube_root_above``). The start is tight where
    the quartic term is negligible, which is where Newton's method from afar would be slow
    (near the evolute's cusp ``p = (A^2 - B^2) / A, u = 0`` the root is near 0 and ``S``
    nearly cubic). A pair has converged when a step moves ``tau`` by at most ``tol tau``
    (``tol = sqrt(eps)``): the convergence is quadratic, so ``tau`` is then exact to about
    ``eps tau``; where it is only linear (a double root, at the cusp) the support value is
    flat to fourth order in ``tau``. ``_ARC_STEPS`` steps for every pair in one fused pass,
    then a ``lax.while_loop`` until every pair has converged (at most ``_ARC_MAX_STEPS``
    steps), each pair stopping at its own convergence: no pair's result depends on the
    others. The result is the normal's parameter ``t``, computed with the same ``B / A`` as
    ``tau`` (``_normal_of_point``): near a flat rim's end (``B`` of the order of rounding,
    where ``tau`` is proportional to ``B``) the normal does not depend on ``B``, while ``B``
    recomputed elsewhere would differ by its own size. Between the passes ``t`` alone is
    stored, as ``-1 - t`` while not converged.
    """
    lo, bu, c3, c1, x, flat, dd = problem()
    for _ in range(_ARC_STEPS - 1):
        x = _arc_newton(x, lo, bu, c3, c1)
    new = _arc_newton(x, lo, bu, c3, c1)
    coded = _code(_normal_of_point(new, flat, dd), jnp.abs(new - x) <= tol * new)

    def unfinished(state):
        k, coded = state
        return (k < _ARC_MAX_STEPS) & jnp.any(coded < 0.0)

    def step(state):
        k, coded = state
        lo, bu, c3, c1, _, flat, dd = problem()
        going = coded < 0.0
        x = _point_of_normal(jnp.where(going, -1.0 - coded, coded), flat, dd)
        new = _arc_newton(x, lo, bu, c3, c1)
        t = _code(_normal_of_point(new, flat, dd), jnp.abs(new - x) <= tol * new)
        return k + 1, jnp.where(going, t, coded)

    def finish(coded):
        return jax.lax.while_loop(unfinished, step, (jnp.int32(_ARC_STEPS), coded))[1]

    # the loop inside a branch: XLA hoists the loop's invariants (the problem) out of the
    # loop, and would otherwise compute and store them for every pair on every call
    coded = jax.lax.cond(jnp.any(coded < 0.0), finish, lambda coded: coded, coded)
    return jnp.where(coded < 0.0, -1.0 - coded, coded)


def _arc_normal(v0: list, d: list, axis: list, t) -> list:
    """The normal at the arc's point, unnormalised: ``(1 - t^2) m' + 2 t L (L n)`` up to the
    fold's signs (``sign(v0 . m')``, ``sign(v0 . n)``), ``m'`` and ``L n`` of length ``L^2
    M`` (``_rim_frame``)."""
    m_, n, _, dd, _, v0m, v0n = _rim_frame(v0, d, axis)
    sx = jnp.where(v0m >= 0.0, 1.0, -1.0) * (1.0 - t * t)
    sy = jnp.where(v0n >= 0.0, 2.0, -2.0) * t * jnp.sqrt(dd)
    return [sx * x + sy * y for x, y in zip(m_, n, strict=True)]


@jax.custom_jvp
def _arc_support(v0: list, d: list, axis: list, radius, half, t) -> jax.Array:
    """``h_M(w) / |w|``, the support value of ``cylinder - segment`` at the normal ``w`` of the
    rim's projection (``_arc_normal``): ``(-v0 . w + h |axis . w| + r |axis x w| + max(0, -d .
    w)) / |w|``, computed from the vector itself, so a true support value whatever the
    rounding of the frame (0 where ``w = 0``, a segment along the axis or of length 0). Its
    derivative is that of the distance from the rim's point to the segment's line
    (``_arc_distance``), which has the same value at the minimiser (Danskin's theorem over the
    rim's points; ``h_M`` itself is not differentiable in ``d`` there, the normal being
    perpendicular to ``d``)."""
    w = _arc_normal(v0, d, axis, t)
    top = (
        -_vdot(v0, w)
        + half * jnp.abs(_vdot(axis, w))
        + radius * _vnorm(_vcross(axis, w))
        + jnp.maximum(-_vdot(d, w), 0.0)
    )
    sq = _vdot(w, w)
    valid = sq > 0.0
    return jnp.where(valid, top / jnp.sqrt(jnp.where(valid, sq, 1.0)), 0.0)


def _arc_distance(v0: list, d: list, axis: list, radius, half, t) -> jax.Array:
    """The distance from the rim's point of normal parameter ``t`` to the segment's line: the
    point ``c + sy h a + r (sx cos phi e1 + sy sin phi e2)`` (``e1 = a x d / |.|``, ``e2 =
    sign(a . d) a x e1``; ``sx, sy`` the fold's signs; ``tan phi = |a . d| / L tan alpha``)."""
    sg = jax.lax.stop_gradient
    _, _, _, dd, along, v0m, v0n = _rim_frame(*([sg(x) for x in y] for y in (v0, d, axis)))
    sx = jnp.where(v0m >= 0.0, 1.0, -1.0)
    sy = jnp.where(v0n >= 0.0, 1.0, -1.0)
    turn = jnp.where(sg(_vdot(axis, d)) >= 0.0, 1.0, -1.0)
    x, y = jnp.sqrt(dd) * (1.0 - t * t), 2.0 * t * along
    length = jnp.sqrt(x * x + y * y)
    flat = length == 0.0
    cos_phi = jnp.where(flat, 1.0, x / jnp.where(flat, 1.0, length))
    sin_phi = jnp.where(flat, 0.0, y / jnp.where(flat, 1.0, length))
    e1 = _vunit(_vcross(axis, d))
    e2 = _times(_vcross(axis, e1), turn)
    rim = _add(
        _times(axis, sy * half),
        _add(_times(e1, radius * sx * cos_phi), _times(e2, radius * sy * sin_phi)),
    )
    return _vnorm(_vcross(_sub(rim, v0), _vunit(d)))


@_arc_support.defjvp
def _arc_support_jvp(primals, tangents):
    value = _arc_support(*primals)
    t = primals[-1]
    _, slope = jax.jvp(lambda *x: _arc_distance(*x, t), primals[:-1], tangents[:-1])
    return value, jnp.where(value >= 0.0, 1.0, -1.0) * slope


def _end_slope(z: jax.Array, w: list, wd: list, dz: jax.Array, radius, half) -> jax.Array:
    """The sign of ``g'`` at an end of the segment, ``g(t)`` the squared distance from
    ``p(t)`` to the cylinder: that of ``max(1 - r / rho, 0) (w . wd) + max(|z| - h, 0) sign(z)
    dz`` (``w = axis x v``, ``rho = |w|``, ``z = axis . v`` of that end)."""
    sq = _vdot(w, w)
    positive = sq > 0.0
    # r / rho through one reciprocal square root (inf on the axis: no radial term)
    near = jnp.where(positive, radius * jax.lax.rsqrt(jnp.where(positive, sq, 1.0)), jnp.inf)
    radial = jnp.maximum(1.0 - near, 0.0) * _vdot(w, wd)
    return radial + jnp.maximum(jnp.abs(z) - half, 0.0) * jnp.sign(z) * dz


def segment_cylinder(
    a: jax.Array,
    b: jax.Array,
    center: jax.Array,
    axis: jax.Array,
    radius: jax.Array,
    half: jax.Array,
) -> jax.Array:
    """Signed distance from segments ``a``-``b`` to solid cylinders; minus the penetration
    depth where they overlap.

    The signed distance of convex shapes is ``-min_n h_M(n)`` over unit ``n``, ``h_M`` the
    support function of ``M = C - S``, ``h_M(n) = -v0 . n + h |axis . n| + r |axis x n| +
    max(0, -d . n)`` (``v0 = a - c``, ``d = b - a``): minus the distance from the
    origin to ``M`` outside, its depth inside. The minimising ``n`` is the normal of a smooth
    boundary point of ``M`` (from inside, the largest ball touches one; from outside, the
    nearest point's), and ``M``'s smooth patches have three families of normals: the axis
    (the caps: ``h - min z_i``, ``h + max z_i``), perpendicular to the axis (the side, swept
    by an end; the best is ``r - min_t rho(t)``, ``rho`` the distance from the axis along the
    segment, closed form) and perpendicular to the segment (the rims swept along it).

    The last family is two-dimensional: projected along the segment, the cylinder is the
    stadium of an ellipse (semi-axes ``A = r`` along ``ex = axis x d / |.|`` and ``B = r |cos
    psi|``, ``psi`` the angle of axis and segment) swept by ``+-H`` along ``ey = d x ex / |.|``
    (``H = h sin psi``), and the segment's line is the point ``P``. By the stadium's
    symmetries ``P`` folds to ``(p, q) >= 0``; its nearest boundary point is on the straight
    side (normal ``ex``: the side family again) or on the upper arc, a point of the quarter
    ellipse about ``(0, H)`` nearest to ``(p, u = q - H)``: closed form but for a quartic's
    root, found by Newton's method from a closed-form start (``_arc_parameter``). The arc's
    value is ``h_M`` at that point's normal, in closed form (``_arc_support``): a true support
    value whatever the parameter, and, ``h_M`` being stationary there, in error only to
    second order in the parameter's.

    Overlapping (every candidate > 0: the candidates include a separating direction whenever
    the shapes are apart, see below), the depth is the smallest candidate. Apart, ``g(t)``,
    the squared distance along the segment, is convex: when its slope at ``t = 0`` is >= 0
    the distance is the point ``a``'s, at ``t = 1`` <= 0 the point ``b``'s, and otherwise the
    nearest point is inside the segment, the normal there is perpendicular to it and the
    distance is the line's, ``-min h_M`` over that family: the stadium's straight side (the
    line's distance from the axis minus ``r``) or ``-arc``. Every candidate is an attained
    support value, so minus each bounds the distance from below, and the value taken is minus
    the smallest candidate, as where they overlap (``-side``, the segment's own distance from
    the axis minus ``r``, is at least the line's and needs no frame): exact where the frame
    is well defined, and where it is mostly rounding (a segment nearly along the axis) the
    arc's problem and its normal are posed in the same frame, in which the projected rims are
    nearly circles: off only by ``h`` times rounding. Every branch is continuous across its
    boundary: no decision on a quantity that is zero to rounding changes the value by more
    than rounding. Separating candidates: apart, the nearest point of the segment is inside
    it (the line misses the cylinder: a negative value in the family perpendicular to the
    segment) or an end; then the line enters the cylinder behind that end through a cap
    (every point of the segment is beyond that cap's plane: a cap's value < 0) or the side
    (``rho`` is convex and grows past the exit: the side's value < 0), or misses it.

    Gradients: the parameters (``tau``, the point nearest the axis) are located under
    ``stop_gradient`` and the value evaluated from them (Danskin's theorem); the arc's
    gradient is that of the distance from its rim point to the segment's line. Every
    expensive operation has a single use, so that XLA fuses the value into one loop over the
    pairs (and the rim's parameter into another). ``a, b, center, axis``: ``(..., 3)`` (unit
    ``axis``); ``radius, half``: ``(...)``; returns ``(...)``.
    """
    shape = jnp.broadcast_shapes(a.shape[:-1], b.shape[:-1], center.shape[:-1], axis.shape[:-1])
    shape = jnp.broadcast_shapes(shape, jnp.shape(radius), jnp.shape(half))
    dtype = jnp.result_type(a, b, center, axis, radius, half, float)
    sg = jax.lax.stop_gradient
    a, b, center, axis, radius, half = (
        jnp.asarray(x, dtype) for x in (a, b, center, axis, radius, half)
    )

    def problem():  # from the inputs themselves: the loop stores nothing else
        p0, c = _vec(sg(a)), _vec(sg(center))
        v0, d = _sub(p0, c), _sub(_vec(sg(b)), p0)
        return _arc_problem(v0, d, _vec(sg(axis)), sg(radius), sg(half))

    tau = _arc_parameter(problem, float(jnp.finfo(dtype).eps) ** 0.5)
    p0, p1, c, ax = _vec(a), _vec(b), _vec(center), _vec(axis)
    v0, v1, d = _sub(p0, c), _sub(p1, c), _sub(p1, p0)
    z0, z1 = _vdot(ax, v0), _vdot(ax, v1)
    w0, wd = _vcross(ax, v0), _vcross(ax, d)
    mm = _vdot(wd, wd)

    # the caps; the side (the best radial normal: the segment's point nearest the axis)
    caps = jnp.minimum(half - jnp.minimum(z0, z1), half + jnp.maximum(z0, z1))
    t_side = sg(jnp.clip(_safe_ratio(-_vdot(w0, wd), mm), 0.0, 1.0))
    side = radius - _vnorm(_add(w0, _times(wd, t_side)))
    m_, _, _, _, _, _, _ = _rim_frame([sg(x) for x in v0], [sg(x) for x in d], [sg(x) for x in ax])
    valid = _vdot(m_, m_) > 0.0  # a segment of length > 0, not along the axis
    arc = _arc_support(v0, d, ax, radius, half, tau)

    # the smallest support value: the depth, and apart, when the nearest point is inside the
    # segment, minus the distance
    least = jnp.minimum(jnp.minimum(caps, side), jnp.where(valid, arc, jnp.inf))
    dz, w0s, wds = sg(z1 - z0), [sg(x) for x in w0], [sg(x) for x in wd]
    r_, h_ = sg(radius), sg(half)
    slope_a = _end_slope(sg(z0), w0s, wds, dz, r_, h_)
    slope_b = _end_slope(sg(z1), _add(w0s, wds), wds, dz, r_, h_)
    first, end = slope_a >= 0.0, (slope_a >= 0.0) | (slope_b <= 0.0)
    nearest = _point_cylinder([jnp.where(first, x, y) for x, y in zip(v0, v1, strict=True)],
                              ax, radius, half)  # fmt: skip
    return jnp.broadcast_to(jnp.where(end & (least <= 0.0), nearest, -least), shape)


def sphere_cylinder(c: jax.Array, r: jax.Array, *cylinder: jax.Array) -> jax.Array:
    """Signed distance between spheres ``(c, r)`` and cylinders ``(center, axis, radius,
    half)`` (``point_cylinder``'s)."""
    return point_cylinder(c, *cylinder) - r


def capsule_cylinder(a: jax.Array, b: jax.Array, r: jax.Array, *cylinder: jax.Array) -> jax.Array:
    """Signed distance between capsules ``(a, b, r)`` and cylinders ``(center, axis, radius,
    half)`` (``segment_cylinder``'s)."""
    return segment_cylinder(a, b, *cylinder) - r
