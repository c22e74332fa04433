"""Exact signed distances between collision primitives, in closed form (cylinders: bisection
to rounding).

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
- segment against cylinder: apart, bisection on the sign of the slope of the convex, C1
  squared distance along the segment (the closest point of a line to a circle solves a
  quartic); overlapping, the smallest support value of ``cylinder - segment`` over the
  normals of its smooth boundary: the caps, the side, and the rims seen along the segment
  (half-ellipses, bisection on their convex part). See ``segment_cylinder``.

Gradients: the closest-point parameters are minimisers, so (Danskin's theorem) the gradient of
the distance is its partial gradient at fixed parameters; they are computed under
``stop_gradient`` and the distance is evaluated from them. Every square root and division goes
through a double ``where`` so that gradients stay finite in contact (distance 0), at coincident
centres and for degenerate segments; at such points the returned gradient is one of the valid
subgradients or zero.
"""

from __future__ import annotations

import functools
from typing import Any

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


def _bisection_steps(dtype) -> int:
    """Halvings of a unit bracket down to a quarter of the dtype's epsilon: a minimiser
    located to that, of a function that is L-Lipschitz in the parameter, is exact to
    ``L eps / 4`` (54 in float64, 25 in float32)."""
    return int(jnp.finfo(dtype).nmant) + 2


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


def _gap_slope(t, w0, wd, z0, dz, radius, half):
    """``g'(t) / 2`` for the squared distance ``g(t)`` from the segment's point ``p(t)`` to
    the cylinder: ``max(rho - r, 0) rho' + max(|z| - h, 0) sign(z) z'``, with ``rho(t) = |w0 +
    t wd|`` (``w = axis x (p - c)``; ``rho > 0`` where its term counts) and ``z(t) = z0 + t
    dz``."""
    w = _add(w0, _times(wd, t))
    rho = _vnorm(w)
    z = z0 + t * dz
    radial = jnp.maximum(rho - radius, 0.0) * _safe_ratio(_vdot(w, wd), rho)
    return radial + jnp.maximum(jnp.abs(z) - half, 0.0) * jnp.sign(z) * dz


def _gap(t, w0, wd, z0, dz, radius, half):
    """``g(t)``: the squared distance from ``p(t)`` to the cylinder (0 inside)."""
    rho = _vnorm(_add(w0, _times(wd, t)))
    z = z0 + t * dz
    return jnp.maximum(rho - radius, 0.0) ** 2 + jnp.maximum(jnp.abs(z) - half, 0.0) ** 2


def _arc_angle(tau: jax.Array) -> tuple[jax.Array, jax.Array]:
    """``(cos phi, sin phi)`` for ``phi = pi / 2 + 2 atan(tau)`` (``tau in [-1, 1]`` covers
    ``[0, pi]``; ``d phi / d tau`` lies in ``[1, 2]``, so a bracket on ``tau`` is one on
    ``phi``), without trigonometry."""
    den = 1.0 + tau * tau
    return -2.0 * tau / den, (1.0 - tau * tau) / den


def _arc_slope(tau, a_, b_, p, u):
    """A positive multiple of ``f'(phi)`` for ``f(phi) = (A cos phi - p)^2 + (B sin phi -
    u)^2``, the squared distance from ``(p, u)`` to the point of a half-ellipse at ``phi =
    pi / 2 + 2 atan(tau)`` (``_arc_angle``), as a polynomial in ``tau``: ``f'(phi) / 2 = (B
    sin - u) B cos - (A cos - p) A sin`` times ``(1 + tau^2)^2``."""
    den, cos, sin = 1.0 + tau * tau, -2.0 * tau, 1.0 - tau * tau
    return (b_ * sin - u * den) * b_ * cos - (a_ * cos - p * den) * a_ * sin


def _halve(lo: jax.Array, hi: jax.Array, up: jax.Array) -> tuple[jax.Array, jax.Array]:
    """The half of ``[lo, hi]`` that holds the minimiser, by the slope's sign at the middle."""
    mid = 0.5 * (lo + hi)
    return jnp.where(up, lo, mid), jnp.where(up, mid, hi)


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

    Apart: ``g(t) = dist(p(t), C)^2`` along ``p(t) = a + t (b - a)`` is convex and C1 (the
    squared distance to a convex set), so its minimiser is bracketed by bisection on the sign
    of ``g'`` (``_bisection_steps`` halvings; the distance is ``|b - a|``-Lipschitz in ``t``,
    so the value is exact to ``|b - a| eps / 4``). The closest point of the rim circle to a
    line is a root of a quartic: no closed form.

    Overlapping: the depth is ``min_n h_M(n)`` over unit ``n`` (``_support_difference``), the
    distance from the origin to the boundary of ``M = C - S`` (a disk plus the parallelogram
    of the axis and ``-S``). Its nearest boundary point seen from inside is a smooth point of
    ``M`` (the ball of that radius touches there), whose normal is ``+-axis`` (a cap: ``h -
    min z_i`` and ``h + max z_i``), perpendicular to the axis (the side: ``r - min_t
    rho(t)``, closed form) or perpendicular to the segment. The last family is the 2-D depth
    of the segment's projection ``P`` along itself in the projected cylinder, two
    half-ellipses (the caps' rims, semi-axes ``A = r`` and ``B = r |cos psi|``, centres
    ``+-H``, ``H = h sin psi``, ``psi`` the angle of axis and segment) joined by straight
    sides: the squared distance ``f(phi) = (A cos phi - p)^2 + (B sin phi - u)^2`` to a rim
    (``u`` the height of ``P`` above its centre) is, in ``xi = cos phi``, convex on ``[-1,
    1]`` when ``u >= 0`` and, when ``u < 0``, convex on ``|xi| <= sqrt(1 - (B |u| / (A^2 -
    B^2))^(2/3))`` and concave outside it (``f''(xi) = 2 (A^2 - B^2) + 2 B u / s^3``, ``s =
    sqrt(1 - xi^2)``), so its minimum is at ``xi = +-1`` or found by bisection on the convex
    part. The depth is the smallest of these candidates, each an exact support value (a valid
    upper bound whatever the rounding of the arcs' frame).

    Gradients: the parameters are located under ``stop_gradient`` and the value evaluated from
    them (Danskin's theorem). ``a, b, center, axis``: ``(..., 3)`` (unit ``axis``); ``radius,
    half``: ``(...)``; returns ``(...)``.
    """
    shape = jnp.broadcast_shapes(a.shape[:-1], b.shape[:-1], center.shape[:-1], axis.shape[:-1])
    shape = jnp.broadcast_shapes(shape, jnp.shape(radius), jnp.shape(half))
    dtype = jnp.result_type(a, b, center, axis, radius, half, float)
    sg = jax.lax.stop_gradient
    p0, p1, c, ax = (_vec(jnp.asarray(x, dtype)) for x in (a, b, center, axis))
    radius, half = jnp.asarray(radius, dtype), jnp.asarray(half, dtype)
    v0, d = _sub(p0, c), _sub(p1, p0)
    z0, z1 = _vdot(ax, v0), _vdot(ax, _sub(p1, c))
    w0, wd = _vcross(ax, v0), _vcross(ax, d)

    # the arcs' frame: ex along axis x d, ey = d^ x ex (axis . ey = sin psi >= 0), both
    # orthogonal to d (ex made so again after rounding)
    d_hat = _vunit([sg(x) for x in d])
    axs = [sg(x) for x in ax]
    cos_psi = _vdot(axs, d_hat)
    ex = _vunit(_vcross(axs, d_hat))
    ex = _vunit(_sub(ex, _times(d_hat, _vdot(ex, d_hat))))
    ey = _vcross(d_hat, ex)
    sin_psi = _vdot(axs, ey)
    r_, h_ = sg(radius), sg(half)
    big_a, big_b, big_h = r_, r_ * jnp.abs(cos_psi), h_ * sin_psi
    v0s = [sg(x) for x in v0]
    p, q = _vdot(v0s, ex), _vdot(v0s, ey)
    heights = (q - big_h, -(q + big_h))  # of P above the upper rim's centre, the lower's
    spread = (r_ * sin_psi) ** 2  # A^2 - B^2
    tau_max = []
    for u in heights:
        ratio = jnp.where(
            spread > 0.0, jnp.minimum(_safe_ratio(big_b * jnp.abs(u), spread), 1.0), 1.0
        )
        # the convex part: sin phi >= ratio^(1/3), |tau| <= (1 - k) / (1 + k), k = tan(phi_0/2)
        sin_0 = jnp.cbrt(ratio)
        k = sin_0 / (1.0 + jnp.sqrt(jnp.maximum(1.0 - sin_0 * sin_0, 0.0)))
        tau_max.append(jnp.broadcast_to(jnp.where(u >= 0.0, 1.0, (1.0 - k) / (1.0 + k)), shape))

    gap = ([sg(x) for x in w0], [sg(x) for x in wd], sg(z0), sg(z1 - z0), r_, h_)

    def halve(_, brackets):
        (t_lo, t_hi), upper, lower = brackets
        t_mid = 0.5 * (t_lo + t_hi)
        slopes = [_arc_slope(0.5 * (lo + hi), big_a, big_b, p, u) > 0.0
                  for (lo, hi), u in zip((upper, lower), heights, strict=True)]  # fmt: skip
        return (
            _halve(t_lo, t_hi, _gap_slope(t_mid, *gap) > 0.0),
            _halve(*upper, slopes[0]),
            _halve(*lower, slopes[1]),
        )

    zeros = jnp.zeros(shape, dtype)
    start = ((zeros, zeros + 1.0), *((-t, t) for t in tau_max))
    (t_lo, t_hi), upper, lower = jax.lax.fori_loop(0, _bisection_steps(dtype), halve, start)

    # apart: the distance at the bracket's lower end, which stays in the segment's part inside
    # the cylinder when there is one (g' = 0 exactly there)
    t = sg(t_lo)
    apart = _gap(t, *gap) > 0.0
    distance = _point_cylinder(_add(v0, _times(d, t)), ax, radius, half)

    # overlapping: the caps, the side, the arcs (their ends, +-ex, are the side's normals)
    depth = jnp.minimum(half - jnp.minimum(z0, z1), half + jnp.maximum(z0, z1))
    t_side = sg(jnp.clip(_safe_ratio(-_vdot(w0, wd), _vdot(wd, wd)), 0.0, 1.0))
    depth = jnp.minimum(depth, radius - _vnorm(_add(w0, _times(wd, t_side))))
    valid = (r_ > 0.0) & (sin_psi > 0.0)
    arcs = _arc_depth(
        (upper[0], lower[0]), (big_a, big_b, cos_psi, ex, ey), (p0, v0, d, c, ax, radius, half)
    )
    depth = jnp.where(valid, jnp.minimum(depth, arcs), depth)
    return jnp.broadcast_to(jnp.where(apart, distance, -jnp.maximum(depth, 0.0)), shape)


def _support_difference(n: list, v0: list, d: list, axis: list, radius, half) -> jax.Array:
    """``h_M(n)``, the support function of the Minkowski difference ``M = cylinder -
    segment`` (``v0 = a0 - c``, ``d = a1 - a0``): ``-v0 . n + h |axis . n| + r |axis x n| +
    max(0, -d . n)``, for any unit ``n``; the penetration depth is its minimum over ``n``."""
    return (
        -_vdot(v0, n)
        + half * jnp.abs(_vdot(axis, n))
        + radius * _vnorm(_vcross(axis, n))
        + jnp.maximum(-_vdot(d, n), 0.0)
    )


def _arc_depth(taus: tuple, frame: tuple, shapes: tuple) -> jax.Array:
    """The smaller support value ``h_M(n)`` at the outward normals ``n`` of the upper and the
    lower projected rim at ``taus`` (``_arc_angle``), with the gradient of the distance from
    that rim point to the segment's line (the same value at the minimiser; the arcs' points
    are the rim's, a set that does not depend on the parameters once parametrised by
    ``tau``)."""
    big_a, big_b, cos_psi, ex, ey = frame
    p0, v0, d, c, axis, radius, half = shapes
    sg = jax.lax.stop_gradient
    best: Any = None  # the first side's values, then the better side's
    pick: Any = None
    up: Any = None
    for side, tau in zip((1.0, -1.0), taus, strict=True):
        tau = sg(tau)
        # the ellipse (A xi, +-B s)'s outward normal (B xi, +-A s), times (1 + tau^2) / 2
        nx, ny = -big_b * tau, side * 0.5 * big_a * (1.0 - tau * tau)
        length = jnp.sqrt(nx * nx + ny * ny)
        flat = length == 0.0  # a flat rim's end: any unit normal gives a valid support value
        nx, length = jnp.where(flat, 1.0, nx), jnp.where(flat, 1.0, length)
        n = [sg((nx * e_x + ny * e_y) / length) for e_x, e_y in zip(ex, ey, strict=True)]
        support = sg(_support_difference(n, v0, d, axis, radius, half))
        if best is None:
            best, pick, up = support, tau, jnp.ones_like(tau)
        else:
            better = support < best
            best = jnp.where(better, support, best)
            pick, up = jnp.where(better, tau, pick), jnp.where(better, -1.0, up)
    # the rim point r = c +- h axis + r (xi e1 +- s e2) in a frame that moves with the
    # parameters (e2 . ey = cos psi)
    e1 = _vunit(_vcross(axis, d))
    e2 = _vcross(axis, e1)
    xi, s = _arc_angle(pick)
    turn = jnp.where(sg(cos_psi) >= 0.0, 1.0, -1.0)
    rim = _add(
        _add(c, _times(axis, up * half)),
        _add(_times(e1, radius * xi), _times(e2, radius * up * turn * s)),
    )
    line = _vnorm(_vcross(_sub(rim, p0), _vunit(d)))
    return best + line - sg(line)


def sphere_cylinder(c: jax.Array, r: jax.Array, *cylinder: jax.Array) -> jax.Array:
    """Signed distance between spheres ``(c, r)`` and cylinders ``(center, axis, radius,
    half)`` (``point_cylinder``'s)."""
    return point_cylinder(c, *cylinder) - r


def capsule_cylinder(a: jax.Array, b: jax.Array, r: jax.Array, *cylinder: jax.Array) -> jax.Array:
    """Signed distance between capsules ``(a, b, r)`` and cylinders ``(center, axis, radius,
    half)`` (``segment_cylinder``'s)."""
    return segment_cylinder(a, b, *cylinder) - r
