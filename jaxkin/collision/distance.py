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
- segment against box: outside, ``f(t) = sum_i max(|u_i(t)| - h_i, 0)^2`` is a convex
  piecewise quadratic in ``t`` whose pieces change where ``u_i(t) = +-h_i``: on each of the
  seven intervals between the sorted breakpoints (and 0, 1) the active faces are fixed, the
  quadratic's minimiser is closed form, and the smallest of the seven is the exact minimum.
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

import jax
import jax.numpy as jnp

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
    return jnp.sum(x * y, axis=-1)


def _norm(x: jax.Array) -> jax.Array:
    """Euclidean norm over the last axis, with a zero (not NaN) gradient at the origin."""
    sq = _dot(x, x)
    positive = sq > 0.0
    # double where: sqrt's derivative is infinite at 0, so feed it 1 there and select 0 after
    return jnp.where(positive, jnp.sqrt(jnp.where(positive, sq, 1.0)), 0.0)


def _safe_ratio(num: jax.Array, den: jax.Array) -> jax.Array:
    """``num / den`` where ``den != 0``, else 0 (a degenerate segment's parameter)."""
    nonzero = den != 0.0
    return jnp.where(nonzero, num / jnp.where(nonzero, den, 1.0), 0.0)


def _segment_parameter(p: jax.Array, a: jax.Array, d: jax.Array) -> jax.Array:
    """The parameter ``t in [0, 1]`` of the point of ``a + t d`` nearest to ``p``."""
    return jnp.clip(_safe_ratio(_dot(p - a, d), _dot(d, d)), 0.0, 1.0)


def point_segment(p: jax.Array, a: jax.Array, b: jax.Array) -> jax.Array:
    """Distance from points ``p`` to segments ``a``-``b``; shapes ``(..., 3)`` -> ``(...)``."""
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
    a0, a1, b0, b1 = jnp.broadcast_arrays(a0, a1, b0, b1)
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
    s_cand = jnp.stack(
        [
            s_in,
            zero,
            one,
            _segment_parameter(b0, a0, da),
            _segment_parameter(b1, a0, da),
        ],
        axis=-1,
    )
    t_cand = jnp.stack(
        [
            t_in,
            _segment_parameter(a0, b0, db),
            _segment_parameter(a1, b0, db),
            zero,
            one,
        ],
        axis=-1,
    )
    gap = (
        r[..., None, :]
        + s_cand[..., None] * da[..., None, :]
        - t_cand[..., None] * db[..., None, :]
    )
    sq = _dot(gap, gap)
    sq = sq.at[..., 0].set(jnp.where(inside, sq[..., 0], jnp.inf))
    best = jnp.argmin(sq, axis=-1)[..., None]
    s = jax.lax.stop_gradient(jnp.take_along_axis(s_cand, best, axis=-1))
    t = jax.lax.stop_gradient(jnp.take_along_axis(t_cand, best, axis=-1))
    return _norm(r + s * da - t * db)


def _to_box(p: jax.Array, center: jax.Array, rotation: jax.Array) -> jax.Array:
    """Coordinates of world points ``p`` in a box's frame: ``R^T (p - c)``."""
    return jnp.einsum("...ji,...j->...i", rotation, p - center)


def _box_local_signed(u: jax.Array, half: jax.Array) -> jax.Array:
    """Signed distance of box-frame points ``u`` to the box ``|u_i| <= h_i``."""
    q = jnp.abs(u) - half
    outside = _norm(jnp.maximum(q, 0.0))
    return jnp.where(jnp.all(q <= 0.0, axis=-1), jnp.max(q, axis=-1), outside)


def point_box(p: jax.Array, center: jax.Array, rotation: jax.Array, half: jax.Array) -> jax.Array:
    """Signed distance from points ``p`` to oriented boxes; negative inside.

    ``p, center, half``: ``(..., 3)``; ``rotation``: ``(..., 3, 3)``; returns ``(...)``.
    """
    return _box_local_signed(_to_box(p, center, rotation), half)


def _segment_box_parameter(u0: jax.Array, du: jax.Array, half: jax.Array) -> jax.Array:
    """The ``t in [0, 1]`` minimising the squared distance from ``u0 + t du`` to the box.

    ``f(t) = sum_i max(|u0_i + t du_i| - h_i, 0)^2`` is convex and quadratic between the
    breakpoints ``t = (+-h_i - u0_i) / du_i``; on each interval the active faces (sign ``s_i``
    where ``|u_i| > h_i`` at its midpoint) give ``t* = sum_i (s_i h_i - u0_i) du_i / sum_i
    du_i^2``, clipped to the interval. The best of the seven clipped minimisers is exact.
    """
    breaks = jnp.concatenate([_safe_ratio(half - u0, du), _safe_ratio(-half - u0, du)], axis=-1)
    zero = jnp.zeros_like(breaks[..., :1])
    knots = jnp.sort(jnp.concatenate([zero, zero + 1.0, jnp.clip(breaks, 0.0, 1.0)], -1), -1)
    lo, hi = knots[..., :-1], knots[..., 1:]  # (..., 7)
    mid = 0.5 * (lo + hi)
    u_mid = u0[..., None, :] + mid[..., None] * du[..., None, :]  # (..., 7, 3)
    h = half[..., None, :]
    sign = jnp.where(u_mid > h, 1.0, jnp.where(u_mid < -h, -1.0, 0.0))
    active = sign != 0.0
    du7 = du[..., None, :]
    num = jnp.sum(jnp.where(active, (sign * h - u0[..., None, :]) * du7, 0.0), axis=-1)
    den = jnp.sum(jnp.where(active, du7 * du7, 0.0), axis=-1)
    t = jnp.clip(jnp.where(den > 0.0, _safe_ratio(num, den), mid), lo, hi)
    u_t = u0[..., None, :] + t[..., None] * du7
    excess = jnp.maximum(jnp.abs(u_t) - h, 0.0)
    best = jnp.argmin(_dot(excess, excess), axis=-1)[..., None]
    return jnp.take_along_axis(t, best, axis=-1)[..., 0]


def _segment_box_depth(u0: jax.Array, u1: jax.Array, half: jax.Array) -> jax.Array:
    """Penetration depth of a box-frame segment ``u0``-``u1`` into the box (>= 0 inside).

    The smallest support value of the zonotope ``box - segment`` over its facet normals: the
    three box axes and the unit cross products of the segment direction with them (a zero cross
    product, for a segment along an axis or of zero length, falls back to that box axis).
    """
    eye = jnp.eye(3, dtype=u0.dtype)
    du = u1 - u0
    cross = jnp.cross(du[..., None, :], eye)  # (..., 3, 3): du x e_i
    length = _norm(cross)
    valid = length > 0.0
    normals = jnp.where(valid[..., None], cross / jnp.where(valid, length, 1.0)[..., None], eye)
    normals = jnp.concatenate([eye + jnp.zeros_like(normals), normals], axis=-2)  # (..., 6, 3)
    box_support = jnp.sum(half[..., None, :] * jnp.abs(normals), axis=-1)
    m0 = _dot(normals, u0[..., None, :])
    m1 = _dot(normals, u1[..., None, :])
    # facet m: h_M(m) = |box|_m - min(m.u0, m.u1); facet -m: |box|_m + max(m.u0, m.u1)
    plus = box_support - jnp.minimum(m0, m1)
    minus = box_support + jnp.maximum(m0, m1)
    return jnp.minimum(jnp.min(plus, axis=-1), jnp.min(minus, axis=-1))


def segment_box(
    a: jax.Array, b: jax.Array, center: jax.Array, rotation: jax.Array, half: jax.Array
) -> jax.Array:
    """Signed distance from segments ``a``-``b`` to oriented boxes; minus the depth inside.

    ``a, b, center, half``: ``(..., 3)``; ``rotation``: ``(..., 3, 3)``; returns ``(...)``.
    """
    u0 = _to_box(a, center, rotation)
    u1 = _to_box(b, center, rotation)
    du = u1 - u0
    t = jax.lax.stop_gradient(_segment_box_parameter(u0, du, half))
    outside = _norm(jnp.maximum(jnp.abs(u0 + t[..., None] * du) - half, 0.0))
    # overlap test by separating axes (origin inside the zonotope: every support value > 0),
    # not by the excess at t: at a face the excess can round to either side of zero
    depth = _segment_box_depth(u0, u1, half)
    return jnp.where(depth > 0.0, -depth, outside)


def sphere_sphere(c1: jax.Array, r1: jax.Array, c2: jax.Array, r2: jax.Array) -> jax.Array:
    """Signed distance between spheres: ``|c1 - c2| - r1 - r2``."""
    return _norm(c1 - c2) - r1 - r2


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
