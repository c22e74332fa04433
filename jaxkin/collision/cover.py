"""Conservative covers of link geometry by spheres and capsules (host side, NumPy).

- ``mesh_sphere_cover``: spheres whose union contains every triangle of a mesh (so every
  vertex and every point of the surface). The triangles are first subdivided until their edges
  are short against the target sphere size, then grouped by k-means on their centroids; each
  group gets the (near-)smallest ball holding all its triangles' vertices, and a ball holds a
  triangle when it holds its three vertices (a ball is convex). The number of spheres is doubled
  from 1 until the cover's overshoot bound is at most ``max_overshoot`` or the budget
  ``max_spheres`` is reached.
- Overshoot: every point of a sphere lies within ``r + d(c, T)`` of the mesh surface, ``d(c, T)``
  the distance from its centre to its nearest own triangle; the cover's ``overshoot`` is the
  largest such bound (an upper bound on how far the cover reaches past the surface).
- ``box_capsules``: capsules along a box's longest axis that contain the whole solid box.

Radii are grown by a relative 1e-6 of the mesh size so the covers survive rounding to float32.
"""

from __future__ import annotations

import dataclasses

import numpy as np

__all__ = ["SphereCover", "box_capsules", "mesh_sphere_cover"]

_ROUNDING_MARGIN = 1e-6  # relative to the mesh size: float32 rounding of centres and radii


@dataclasses.dataclass(frozen=True)
class SphereCover:
    """Spheres covering a mesh: ``centers (k, 3)``, ``radii (k,)``, and ``overshoot`` (the
    largest distance a point of the cover can lie from the mesh surface, an upper bound)."""

    centers: np.ndarray
    radii: np.ndarray
    overshoot: float


def _enclosing_ball(points: np.ndarray, iterations: int = 100) -> tuple[np.ndarray, float]:
    """A near-smallest ball containing ``points`` (Badoiu-Clarkson steps from the box centre);
    the radius is exact for the returned centre, so the ball always contains the points."""
    points = np.unique(points, axis=0)
    center = 0.5 * (points.min(axis=0) + points.max(axis=0))
    best_c, best_r = center, np.sqrt(((points - center) ** 2).sum(axis=1).max())
    for i in range(1, iterations + 1):
        sq = ((points - center) ** 2).sum(axis=1)
        far = int(np.argmax(sq))
        if i > 1 and np.sqrt(sq[far]) < best_r:
            best_c, best_r = center, np.sqrt(sq[far])
        center = center + (points[far] - center) / (i + 1)
    return best_c, float(best_r)


def _winding_numbers(tri: np.ndarray, p: np.ndarray) -> np.ndarray:
    """Generalised winding numbers of points ``p (n, 3)`` with respect to the closed triangle
    soup ``tri (m, 3, 3)`` (van Oosterom-Strackee solid angles): ~1 inside, ~0 outside."""
    r = tri[None, :, :, :] - p[:, None, None, :]  # (n, m, 3, 3)
    a, b, c = r[..., 0, :], r[..., 1, :], r[..., 2, :]
    la, lb, lc = (np.linalg.norm(x, axis=-1) for x in (a, b, c))
    num = np.einsum("...i,...i->...", a, np.cross(b, c))
    den = (
        la * lb * lc
        + np.einsum("...i,...i->...", a, b) * lc
        + np.einsum("...i,...i->...", b, c) * la
        + np.einsum("...i,...i->...", c, a) * lb
    )
    return np.arctan2(num, den).sum(axis=1) / (2.0 * np.pi)


def _closest_on_triangles(tri: np.ndarray, p: np.ndarray) -> np.ndarray:
    """Distance from points ``p (n, 3)`` to triangles ``tri (n, 3, 3)``, pairwise (Ericson's
    Voronoi-region test, vectorised)."""
    a, b, c = tri[:, 0], tri[:, 1], tri[:, 2]
    ab, ac, ap = b - a, c - a, p - a

    def dot(x, y):
        return np.einsum("ij,ij->i", x, y)

    d1, d2 = dot(ab, ap), dot(ac, ap)
    bp, cp = p - b, p - c
    d3, d4 = dot(ab, bp), dot(ac, bp)
    d5, d6 = dot(ab, cp), dot(ac, cp)
    va = d3 * d6 - d5 * d4
    vb = d5 * d2 - d1 * d6
    vc = d1 * d4 - d3 * d2
    with np.errstate(divide="ignore", invalid="ignore"):
        denom = va + vb + vc
        v = np.where(denom != 0, vb / denom, 0.0)
        w = np.where(denom != 0, vc / denom, 0.0)
        out = a + ab * v[:, None] + ac * w[:, None]  # interior
        # edges and vertices (checked in reverse priority so the first region wins)
        t_bc = np.clip(
            np.where((d4 - d3) + (d5 - d6) != 0, (d4 - d3) / ((d4 - d3) + (d5 - d6)), 0), 0, 1
        )
        out = np.where(
            ((va <= 0) & (d4 - d3 >= 0) & (d5 - d6 >= 0))[:, None], b + (c - b) * t_bc[:, None], out
        )
        t_ac = np.clip(np.where(d2 - d6 != 0, d2 / (d2 - d6), 0), 0, 1)
        out = np.where(((vb <= 0) & (d2 >= 0) & (d6 <= 0))[:, None], a + ac * t_ac[:, None], out)
        out = np.where(((d6 >= 0) & (d5 <= d6))[:, None], c, out)
        t_ab = np.clip(np.where(d1 - d3 != 0, d1 / (d1 - d3), 0), 0, 1)
        out = np.where(((vc <= 0) & (d1 >= 0) & (d3 <= 0))[:, None], a + ab * t_ab[:, None], out)
        out = np.where(((d3 >= 0) & (d4 <= d3))[:, None], b, out)
        out = np.where(((d1 <= 0) & (d2 <= 0))[:, None], a, out)
    return np.linalg.norm(p - out, axis=1)


def _spheres_over(
    tri: np.ndarray, labels: np.ndarray, solid: np.ndarray | None, margin: float
) -> SphereCover:
    """One enclosing ball per group of triangles and the cover's overshoot bound.

    A ball ``(c, r)`` reaches at most ``r - d`` past the solid when ``c`` is inside it at
    distance ``d`` from its surface (the ball of radius ``d`` about ``c`` is inside), and at
    most ``r + d`` past the surface otherwise. ``solid``: the original closed mesh's triangles,
    or None (not watertight: every centre counts as outside).
    """
    centers, radii = [], []
    for label in np.unique(labels):
        center, radius = _enclosing_ball(tri[labels == label].reshape(-1, 3))
        centers.append(center)
        radii.append(radius + margin)
    centers, radii = np.asarray(centers), np.asarray(radii)
    surface = tri if solid is None else solid
    gap = np.array(
        [
            _closest_on_triangles(surface, np.broadcast_to(c, (len(surface), 3))).min()
            for c in centers
        ]
    )
    inside = (
        np.zeros(len(centers), bool) if solid is None else _winding_numbers(solid, centers) > 0.5
    )
    reach = np.where(inside, radii - gap, radii + gap)
    return SphereCover(centers, radii, float(max(reach.max(), 0.0)))


def _groups(tri: np.ndarray, k: int) -> list[np.ndarray]:
    """Candidate groupings of the triangles into at most ``k`` groups: k-means on the
    centroids, and slices along the principal axis (rings around elongated links, whose
    enclosing balls centre near the axis)."""
    from scipy.cluster.vq import kmeans2

    centroids = tri.mean(axis=1)
    k = min(k, len(tri))
    if k <= 1:
        return [np.zeros(len(tri), dtype=int)]
    _, spatial = kmeans2(centroids, k, minit="++", seed=0)
    centred = centroids - centroids.mean(axis=0)
    axis = np.linalg.svd(centred, full_matrices=False)[2][0]
    along = centred @ axis
    edges = np.quantile(along, np.linspace(0.0, 1.0, k + 1)[1:-1])
    slices = np.searchsorted(edges, along)
    return [spatial, slices]


def _watertight(vertices: np.ndarray, faces: np.ndarray) -> bool:
    """Every edge shared by exactly two faces (a closed surface, so inside is defined)."""
    edges = np.sort(faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1)
    _, counts = np.unique(edges, axis=0, return_counts=True)
    return bool(np.all(counts == 2))


def mesh_sphere_cover(
    vertices: np.ndarray,
    faces: np.ndarray,
    max_spheres: int = 16,
    max_overshoot: float | None = None,
) -> SphereCover:
    """Spheres containing every triangle of the mesh ``(vertices (v, 3), faces (f, 3))``.

    Args:
        vertices, faces: the mesh, in the frame the spheres are wanted in.
        max_spheres: the sphere budget (at least 1).
        max_overshoot: stop at the first sphere count (1, 2, 4, ...) whose overshoot bound is
            at most this; ``None`` uses the whole budget.
    """
    import trimesh

    vertices = np.asarray(vertices, dtype=float)
    faces = np.asarray(faces, dtype=np.int64)
    if vertices.ndim != 2 or vertices.shape[1] != 3 or len(vertices) == 0:
        raise ValueError(f"vertices: expected shape (v, 3) with v >= 1, got {vertices.shape}")
    if faces.ndim != 2 or faces.shape[1] != 3 or len(faces) == 0:
        raise ValueError(f"faces: expected shape (f, 3) with f >= 1, got {faces.shape}")
    if int(max_spheres) < 1:
        raise ValueError(f"max_spheres must be >= 1, got {max_spheres}")
    size = float(np.linalg.norm(vertices.max(axis=0) - vertices.min(axis=0)))
    margin = _ROUNDING_MARGIN * max(size, float(np.abs(vertices).max()))
    # triangles much smaller than the smallest sphere wanted, so groups can be tight
    edge = size / (2.0 * np.sqrt(max_spheres)) if size > 0 else 1.0
    v, f = trimesh.remesh.subdivide_to_size(vertices, faces, max_edge=edge, max_iter=10)
    tri = np.asarray(v)[np.asarray(f)]
    solid = np.asarray(vertices)[faces] if _watertight(vertices, faces) else None
    k = 1 if max_overshoot is not None else int(max_spheres)
    while True:
        covers = [_spheres_over(tri, labels, solid, margin) for labels in _groups(tri, k)]
        best = min(covers, key=lambda c: c.overshoot)
        if (max_overshoot is not None and best.overshoot <= max_overshoot) or k >= max_spheres:
            return best
        k = min(2 * k, int(max_spheres))


def box_capsules(half_extents: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Capsules, in the box's frame, whose union contains the solid box ``|u_i| <= h_i``.

    The axis is the box's longest; the cross-section ``2w x 2t`` (``w >= t``) is cut into
    ``ceil(w / t)`` strips along ``w``, each covered by a capsule through the strip's centre line
    with radius ``sqrt((w / k)^2 + t^2)`` (the strip's half diagonal) and end points at the
    box's end faces. Returns ``(a (k, 3), b (k, 3), radii (k,))``.
    """
    h = np.asarray(half_extents, dtype=float)
    axis = int(np.argmax(h))
    others = [i for i in range(3) if i != axis]
    wide, thin = sorted(others, key=lambda i: -h[i])
    w, t = h[wide], h[thin]
    k = 1 if t <= 0 or w <= 0 else int(np.ceil(w / t - 1e-9))
    k = max(k, 1)
    offsets = (np.arange(k) + 0.5) * (2.0 * w / k) - w
    a = np.zeros((k, 3))
    a[:, wide] = offsets
    b = a.copy()
    a[:, axis], b[:, axis] = -h[axis], h[axis]
    radius = np.sqrt((w / k) ** 2 + t**2) * (1.0 + _ROUNDING_MARGIN)
    return a, b, np.full(k, radius)
