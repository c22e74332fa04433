"""Independent references for signed distances to solid cylinders, and pairs in every regime.

Written from the definitions, not from ``jaxkin.collision.distance``'s method:

- ``point``: the cylinder is the rectangle ``rho <= r, |z| <= h`` in the half-plane of the
  point's distance ``rho`` from the axis and its height ``z``; the rectangle's signed distance;
- ``along``: separated, the distance of a segment is the minimum over ``t`` of its point's
  distance, a convex function of ``t``: dense samples, then golden-section search on the best
  bracket down to ``1e-15`` in ``t``;
- ``support``: for any convex pair the signed distance is ``-min_n h_M(n)`` over unit ``n``,
  ``h_M`` the support function of ``M = cylinder - segment``, smooth but on two great circles
  and two points of the sphere: the best of those (a dense search along each circle, refined
  by golden-section search) and, if given, of dense directions on the sphere (a Fibonacci
  lattice), each refined by a grid search in its tangent plane. Every value it returns is an
  attained support value, so it bounds ``-sd`` from above (``sd`` from below) and converges
  to it; where the shapes overlap the circles and the two points alone are exact. The
  cylinder's support term is ``r |axis x n|`` (``r sqrt(1 - (axis . n)^2)`` loses half the
  digits near the caps' normals).

Both searches are vectorised over the pairs (NumPy, float64).

``pairs(rng, n)`` draws segments and cylinders in named regimes (random, parallel and
perpendicular to the axis, exactly or nearly, through the axis, at the rim, a cap or the side
within a hair's breadth either way, points, cylinders of radius or length 0, near the cusp of
the evolute of the rim's projection, where the rim problem's root is double).
"""

from __future__ import annotations

import numpy as np


def point(p, c, axis, radius, half) -> np.ndarray:
    """Signed distances from points to solid cylinders (the rectangle in ``(rho, z)``); every
    argument broadcasts over leading axes."""
    u = np.asarray(p, float) - c
    z = np.sum(u * axis, axis=-1)
    rho = np.linalg.norm(u - z[..., None] * axis, axis=-1)
    out = np.hypot(np.maximum(rho - radius, 0.0), np.maximum(np.abs(z) - half, 0.0))
    return np.where(out > 0, out, np.maximum(rho - radius, np.abs(z) - half))


def _golden(f, lo: np.ndarray, hi: np.ndarray, tol: float = 1e-15) -> np.ndarray:
    """The smallest values golden-section search finds on each ``[lo, hi]`` (``f`` maps an
    array of parameters shaped like ``lo`` to values; every bracket shrinks until ``tol``)."""
    ratio = (np.sqrt(5.0) - 1.0) / 2.0
    x1, x2 = hi - ratio * (hi - lo), lo + ratio * (hi - lo)
    f1, f2 = f(x1), f(x2)
    for _ in range(200):  # a bracket of 2 ulps may no longer shrink
        if np.all(hi - lo <= tol):
            break
        left = f1 <= f2  # the minimum is in [lo, x2]
        lo, hi = np.where(left, lo, x1), np.where(left, x2, hi)
        x1, x2 = (
            np.where(left, hi - ratio * (hi - lo), x2),
            np.where(left, x1, lo + ratio * (hi - lo)),
        )
        fx = f(np.where(left, x1, x2))
        f1, f2 = np.where(left, fx, f2), np.where(left, f1, fx)
    return np.minimum(f1, f2)


def along(a, b, c, axis, radius, half) -> np.ndarray:
    """The smallest of ``point`` along each segment (``(n, 3)`` and ``(n,)`` arguments): its
    minimum when the shapes are apart, a convex function of ``t``: 257 samples, then
    golden-section search on the best sample's bracket down to ``1e-15`` in ``t``."""
    a, b, c, axis = (np.asarray(x, float)[:, None] for x in (a, b, c, axis))
    radius, half = (np.asarray(x, float)[:, None] for x in (radius, half))

    def f(t):  # t: (n, k)
        return point(a + t[..., None] * (b - a), c, axis, radius, half)

    ts = np.broadcast_to(np.linspace(0.0, 1.0, 257), (len(a), 257))
    values = f(ts)
    k = np.argmin(values, axis=1)[:, None]
    lo, hi = ts[0][np.maximum(k - 1, 0)], ts[0][np.minimum(k + 1, 256)]
    return np.minimum(values.min(axis=1), _golden(f, lo, hi)[:, 0])


def fibonacci_sphere(k: int) -> np.ndarray:
    i = np.arange(k) + 0.5
    polar, turn = np.arccos(1.0 - 2.0 * i / k), np.pi * (1.0 + 5**0.5) * i
    return np.stack([np.cos(turn) * np.sin(polar), np.sin(turn) * np.sin(polar), np.cos(polar)], -1)


def _unit(x):
    return x / np.linalg.norm(x, axis=-1, keepdims=True)


def _tangents(n):
    """Two unit vectors spanning the plane perpendicular to each unit ``n`` (``(..., 3)``)."""
    helper = np.where(np.abs(n[..., :1]) < 0.9, [1.0, 0.0, 0.0], [0.0, 1.0, 0.0])
    e1 = _unit(np.cross(n, helper))
    return e1, np.cross(n, e1)


def support(a, b, c, axis, radius, half, directions=None, polish: int = 4) -> np.ndarray:
    """``-min_n h_M(n)``: the signed distances of segments ``a``-``b`` and cylinders
    (``(n, 3)`` and ``(n,)`` arguments).

    ``h_M(n) = c . n + h |axis . n| + r |axis x n| - min(a . n, b . n)`` is smooth but on the
    great circles ``axis . n = 0`` and ``(b - a) . n = 0`` and at ``n = +-axis``; its minimum
    is at one of those or at a smooth local minimum. Candidates: ``+-axis``; each circle
    sampled at 4096 angles, the best five refined by golden-section search; the best
    ``polish`` of ``directions``, each refined by a grid search in its tangent plane (21 x 21
    points; the window follows the best point and shrinks fourfold when that point is inside
    it, down to 1e-13). Without ``directions`` only ``+-axis`` and the circles: exact where
    the shapes overlap (from inside, the nearest boundary point of ``M`` is touched by a ball
    in ``M``, so it is a smooth point, whose normal is ``+-axis``, perpendicular to the axis (a
    side) or perpendicular to the segment), a lower bound of the distance where they are
    apart."""
    a, b, c, axis = (np.asarray(x, float)[:, None] for x in (a, b, c, axis))
    radius, half = (np.asarray(x, float)[:, None] for x in (radius, half))

    def h(n):  # n: (pairs, k, 3) -> (pairs, k)
        n = _unit(n)
        cyl = np.sum(n * c, -1) + half * np.abs(np.sum(n * axis, -1))
        cyl += radius * np.linalg.norm(np.cross(n, axis), axis=-1)
        return cyl - np.minimum(np.sum(n * a, -1), np.sum(n * b, -1))

    best = np.minimum(h(axis), h(-axis))[:, 0]
    angles = np.linspace(0.0, 2.0 * np.pi, 4097)
    for normal in (axis, b - a):
        length = np.linalg.norm(normal, axis=-1, keepdims=True)
        e1, e2 = _tangents(np.where(length > 0, normal, axis) / np.where(length > 0, length, 1.0))

        def circle(t, e1=e1, e2=e2):
            return h(np.cos(t)[..., None] * e1 + np.sin(t)[..., None] * e2)

        values = circle(np.broadcast_to(angles, (len(a), len(angles))))
        k = np.argsort(values, axis=1)[:, :5]
        found = _golden(circle, angles[k] - angles[1], angles[k] + angles[1]).min(axis=1)
        found = np.minimum(values.min(axis=1), found)
        best = np.where(length[:, 0, 0] > 0, np.minimum(best, found), best)
    if directions is None:
        return -best
    values = h(np.broadcast_to(directions, (len(a), *directions.shape)))
    best = np.minimum(best, values.min(axis=1))
    grid = np.linspace(-1.0, 1.0, 21)
    u, v = (x.reshape(-1, 1) for x in np.meshgrid(grid, grid))
    n = np.take(directions, np.argsort(values, axis=1)[:, :polish], axis=0)  # (pairs, polish, 3)
    n = n.reshape(-1, 3)
    pairs = np.repeat(np.arange(len(a)), polish)
    e1, e2 = _tangents(n)
    width = np.full((len(n), 1, 1), 4.0 * np.sqrt(4.0 * np.pi / len(directions)))
    for _ in range(1000):
        if np.all(width < 1e-13):
            break
        candidates = n[:, None] + width * (u * e1[:, None] + v * e2[:, None])
        trial = h(candidates.reshape(len(a), -1, 3)).reshape(len(n), -1)
        j = np.argmin(trial, axis=1)
        n = _unit(candidates[np.arange(len(n)), j])
        e1 = _unit(e1 - np.sum(e1 * n, -1, keepdims=True) * n)
        e2 = np.cross(n, e1)
        np.minimum.at(best, pairs, trial[np.arange(len(n)), j])
        inside = (np.abs(u[j, 0]) < 1.0) & (np.abs(v[j, 0]) < 1.0)
        width = np.where(inside[:, None, None], width / 4.0, width)  # zoom in
    return -best


def _frame(axis, d):
    """``ex = axis x d / |.|``, ``ey = d^ x ex`` (rows), for ``d`` not along ``axis``."""
    ex = _unit(np.cross(axis, d))
    return ex, np.cross(_unit(d), ex)


REGIMES = (
    "random",
    "parallel",
    "nearly parallel",
    "perpendicular",
    "exactly perpendicular",
    "through the axis",
    "touching the rim",
    "touching a cap",
    "touching the side",
    "point",
    "radius 0",
    "half-length 0",
    "evolute cusp",
    "along the axis",
)


def pairs(rng: np.random.Generator, n: int, regime: str):
    """``n`` segments ``(a, b)`` and cylinders ``(c, axis, radius, half)`` of one regime, at
    scales from 0.1 to 10, about half overlapping; returns ``a, b, c, axis, radius, half``."""
    scale = 10.0 ** rng.uniform(-1, 1, (n, 1))
    c = rng.normal(size=(n, 3)) * scale
    axis = _unit(rng.normal(size=(n, 3)))
    radius = rng.uniform(0.05, 1.0, n) * scale[:, 0]
    half = rng.uniform(0.05, 1.0, n) * scale[:, 0]
    size = np.maximum(radius, half)[:, None]
    a = c + rng.normal(size=(n, 3)) * size * 1.2
    d = rng.normal(size=(n, 3)) * size * 1.5
    sign = rng.choice([-1.0, 1.0], (n, 1))
    hair = sign * 10.0 ** rng.uniform(-12, -4, (n, 1)) * size
    if regime == "parallel":
        d = axis * rng.uniform(-3, 3, (n, 1)) * size
    elif regime == "nearly parallel":
        d = axis * rng.uniform(-3, 3, (n, 1)) * size
        d += 10.0 ** rng.uniform(-12, -5, (n, 1)) * rng.normal(size=(n, 3)) * size
    elif regime == "perpendicular":
        d -= np.einsum("ij,ij->i", d, axis)[:, None] * axis
    elif regime == "exactly perpendicular":  # axis along a coordinate axis, d in its plane
        k = rng.integers(0, 3, n)
        axis = np.eye(3)[k] * rng.choice([-1.0, 1.0], (n, 1))
        d[np.arange(n), k] = 0.0
    elif regime == "through the axis":  # the line crosses the axis's line
        z = rng.uniform(-1.5, 1.5, (n, 1)) * half[:, None]
        a = c + z * axis - rng.uniform(0.2, 0.8, (n, 1)) * d
    elif regime == "touching the rim":  # a segment through the rim point along a tangent plane
        side = _unit(np.cross(axis, rng.normal(size=(n, 3))))
        rim = c + sign * half[:, None] * axis + radius[:, None] * side
        normal = _unit(side + sign * axis * rng.uniform(0.1, 10, (n, 1)))
        d -= np.einsum("ij,ij->i", d, normal)[:, None] * normal
        a = rim + hair * normal - rng.uniform(0, 1, (n, 1)) * d
    elif regime == "touching a cap":  # in the cap's plane, inside its disk
        cap = c + sign * half[:, None] * axis
        d -= np.einsum("ij,ij->i", d, axis)[:, None] * axis
        a = cap + hair * axis * sign - rng.uniform(0, 1, (n, 1)) * d
        a += rng.uniform(0, 0.5, (n, 1)) * radius[:, None] * _unit(np.cross(axis, d))
    elif regime == "touching the side":  # parallel to the axis at distance r
        side = _unit(np.cross(axis, rng.normal(size=(n, 3))))
        d = axis * rng.uniform(-2, 2, (n, 1)) * size
        a = c + (radius[:, None] + hair) * side + rng.uniform(-1, 1, (n, 1)) * half[:, None] * axis
    elif regime == "point":
        d = np.zeros_like(d)
    elif regime == "radius 0":
        radius = np.zeros(n)
    elif regime == "half-length 0":
        half = np.zeros(n)
    elif regime == "evolute cusp":
        # the line's projection at the cusp (A^2 - B^2) / A of the rim's projected ellipse
        # (A = r, B = r |cos psi|) about (0, H): the rim problem's root is double there
        ex, ey = _frame(axis, d)
        cos = np.abs(np.einsum("ij,ij->i", axis, _unit(d)))[:, None]
        sin = np.sqrt(np.maximum(1.0 - cos**2, 0.0))
        p = radius[:, None] * sin**2 * (1.0 + rng.choice([0.0, 1.0], (n, 1)) * hair / size)
        q = half[:, None] * sin + rng.choice([0.0, 1.0], (n, 1)) * hair
        a = c + p * ex + q * ey - rng.uniform(0, 1, (n, 1)) * d
    elif regime == "along the axis":
        d = axis * rng.uniform(-3, 3, (n, 1)) * size
        a = c + axis * rng.uniform(-2, 2, (n, 1)) * size
    elif regime != "random":
        raise ValueError(f"regime: unknown {regime!r}")
    return a, a + d, c, axis, radius, half
