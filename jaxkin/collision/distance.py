"""Exact signed distances between collision primitives, in closed form.

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
- half-space: unit normal ``n`` and offset ``o``; the solid is ``{x : n . x <= o}``.

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
- point/segment against half-space: ``min(n . a, n . b) - o``.

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
    "capsule_halfspace",
    "point_box",
    "point_segment",
    "segment_box",
    "segment_segment",
    "sphere_box",
    "sphere_capsule",
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
