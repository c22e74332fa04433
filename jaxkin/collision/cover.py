"""Conservative covers of link geometry by spheres and capsules (host side, NumPy).

- ``mesh_cover``: spheres and capsules whose union contains every triangle of a mesh (so every
  vertex and every point of the surface; a convex primitive holds a triangle when it holds its
  three vertices). The triangles are first subdivided until their edges are short against the
  primitives wanted (a primitive must hold whole triangles, so long triangles force large
  primitives). The cover is built top down: one primitive holds every triangle, then the
  group whose primitive reaches farthest past the mesh is split in two (at the median along
  each of its principal axes, or by 2-means; the split whose worse half reaches least) until
  the budget is spent or the worst reach is at most ``max_overshoot``. Each group gets
  whichever of its enclosing ball and its enclosing capsule reaches less far: the capsule's
  axis is the group's principal axis through the centre of the smallest circle holding the
  points projected across it, its radius that circle's, its segment the shortest that keeps
  every point within the radius (closed form). Tubes and elongated links get capsules that
  hug them, where balls overshoot by about their half-length.
- ``mesh_sphere_cover``: the same with spheres only.
- Overshoot: a point of a ball ``(c, r)`` lies within ``r + sd(c)`` of the mesh's solid, a
  point of a capsule within ``r + max sd`` over its segment (``sd`` the signed distance to the
  solid, negative inside; for a mesh of several closed parts, inside means the deepest in one
  part); the cover's ``overshoot`` is the largest such bound (an upper bound on how far the
  cover reaches past the mesh).
- ``box_capsules``: capsules along a box's longest axis that contain the whole solid box.

Radii are grown by a relative 1e-6 of the mesh size so the covers survive rounding to float32.
"""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np

__all__ = ["MeshCover", "SphereCover", "box_capsules", "mesh_cover", "mesh_sphere_cover"]

import os

EDGE_DIV = float(os.environ.get("EDGE_DIV", "2"))
_ROUNDING_MARGIN = 1e-6  # relative to the mesh size: float32 rounding of centres and radii


@dataclasses.dataclass(frozen=True)
class SphereCover:
    """Spheres covering a mesh: ``centers (k, 3)``, ``radii (k,)``, and ``overshoot`` (the
    largest distance a point of the cover can lie from the mesh surface, an upper bound)."""

    centers: np.ndarray
    radii: np.ndarray
    overshoot: float


@dataclasses.dataclass(frozen=True)
class MeshCover:
    """Spheres ``centers (k, 3)``, ``radii (k,)`` and capsules ``a, b (m, 3)``,
    ``capsule_radii (m,)`` whose union contains a mesh, and ``overshoot`` (an upper bound on
    the distance from any point of the cover to the mesh)."""

    centers: np.ndarray
    radii: np.ndarray
    a: np.ndarray
    b: np.ndarray
    capsule_radii: np.ndarray
    overshoot: float

    @property
    def num_primitives(self) -> int:
        return len(self.radii) + len(self.capsule_radii)


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


def _signed_distance(
    surface: np.ndarray, bodies: list[np.ndarray] | None, p: np.ndarray
) -> np.ndarray:
    """An upper bound on the signed distance of points ``p (n, 3)`` to the solid, 1-Lipschitz:
    outside, the distance to the triangles ``surface``; inside the union of the closed
    ``bodies`` (each a triangle array, overlapping or not), minus the largest depth in one body
    that holds the point (the union is at least that deep there; the triangles of one body
    inside another are not the union's surface). ``bodies`` None (a mesh that is not closed):
    every point counts as outside."""

    def gap(tri: np.ndarray) -> np.ndarray:
        rows = np.broadcast_to(tri, (len(p), *tri.shape)).reshape(-1, 3, 3)
        return (
            _closest_on_triangles(rows, np.repeat(p, len(tri), axis=0)).reshape(len(p), -1).min(1)
        )

    if bodies is None:
        return gap(surface)
    dist = np.stack([gap(tri) for tri in bodies], axis=1)  # (n, bodies)
    inside = np.stack([_winding_numbers(tri, p) > 0.5 for tri in bodies], axis=1)
    depth = np.where(inside, dist, -np.inf).max(axis=1)
    return np.where(inside.any(axis=1), -depth, dist.min(axis=1))


def _closed_bodies(vertices: np.ndarray, faces: np.ndarray) -> list[np.ndarray] | None:
    """The triangles of each connected part of the mesh, when every part is closed (every
    edge shared by exactly two faces); None otherwise."""
    import trimesh

    if not _watertight(vertices, faces):
        return None
    parts = trimesh.graph.connected_components(
        trimesh.graph.face_adjacency(faces), nodes=np.arange(len(faces)), min_len=1
    )
    return [vertices[faces[np.asarray(part)]] for part in parts]


def _enclosing_capsule(points: np.ndarray, margin: float) -> tuple[np.ndarray, np.ndarray, float]:
    """A capsule ``(a, b, r)`` containing ``points``: the axis along their principal direction
    ``u`` through the centre of a near-smallest circle holding their projection across ``u``
    (radius ``r``); a point at axial coordinate ``t`` and distance ``rho <= r`` from the axis
    is within ``r`` of the segment ``[t0, t1]`` iff ``t0 <= t + s`` and ``t1 >= t - s``,
    ``s = sqrt(r^2 - rho^2)``, so the shortest segment is ``t0 = min(t + s)``, ``t1 = max(t -
    s)`` (a point where these cross). The radius is finally the exact largest distance of the
    points from the segment, plus ``margin``."""
    points = np.unique(points, axis=0)
    mean = points.mean(axis=0)
    basis = np.linalg.svd(points - mean, full_matrices=False)[2]
    if len(basis) < 3:  # fewer than 3 distinct points: any completed frame
        basis = np.linalg.qr(np.concatenate([basis.T, np.eye(3)], axis=1))[0].T[:3]
    u, across = basis[0], basis[1:3]
    flat = (points - mean) @ across.T
    center2, radius = _enclosing_ball(flat)
    origin = mean + center2 @ across
    t = (points - origin) @ u
    rho2 = (((points - origin) @ across.T) ** 2).sum(axis=1)
    s = np.sqrt(np.maximum(radius**2 - rho2, 0.0))
    t0, t1 = (t + s).min(), (t - s).max()
    if t0 > t1:  # a short group: any point between is a ball centre holding them all
        t0 = t1 = 0.5 * (t0 + t1)
    a, b = origin + t0 * u, origin + t1 * u
    along = np.clip((points - a) @ (b - a) / max(float((b - a) @ (b - a)), 1e-300), 0.0, 1.0)
    reach = np.linalg.norm(points - a - along[:, None] * (b - a), axis=1).max()
    return a, b, float(reach) + margin


def _fit(
    points: np.ndarray,
    surface: np.ndarray,
    solid: list[np.ndarray] | None,
    margin: float,
    capsules: bool,
) -> tuple[float, tuple]:
    """The primitive holding the ``points (m, 3)`` (a group's triangles' vertices: a convex
    primitive holding them holds the triangles) that reaches least past the mesh, and that
    reach: ``(reach, ("sphere", c, r))`` or ``(reach, ("capsule", a, b, r))``.

    A point of a ball ``(c, r)`` lies within ``r + sd(c)`` of the solid (``sd`` the signed
    distance to the mesh: minus the depth inside the closed mesh); a point of a capsule
    ``(a, b, r)`` within ``r + max_s sd(s)`` over its segment, bounded from ``n`` samples
    ``h`` apart by the sampled maximum plus ``h / 2`` (``sd`` is 1-Lipschitz). ``surface``:
    the mesh's triangles; ``solid``: its closed parts, or None (not closed: every point counts
    as outside).
    """
    center, radius = _enclosing_ball(points)
    reach = radius + margin + _signed_distance(surface, solid, center[None])[0]
    best: tuple[float, tuple[Any, ...]] = (reach, ("sphere", center, radius + margin))
    if capsules:
        a, b, r = _enclosing_capsule(points, margin)
        length = float(np.linalg.norm(b - a))
        if length > 0:
            n = int(np.ceil(length / max(0.25 * r, 1e-12))) + 1
            samples = a + np.linspace(0.0, 1.0, n)[:, None] * (b - a)
            reach = r + _signed_distance(surface, solid, samples).max() + 0.5 * length / (n - 1)
            if reach < best[0]:
                best = (reach, ("capsule", a, b, r))
    return best


def _halves(centroids: np.ndarray) -> list[np.ndarray]:
    """Candidate splits of a group in two (boolean masks): at the median along its principal
    axis, and 2-means on the centroids."""
    from scipy.cluster.vq import kmeans2

    centred = centroids - centroids.mean(axis=0)
    out = []
    for axis in np.linalg.svd(centred, full_matrices=False)[2]:
        along = centred @ axis
        out.append(along > np.median(along))
    _, labels = kmeans2(centroids, 2, minit="++", seed=0)
    out.append(labels == 1)
    return [m for m in out if 0 < m.sum() < len(m)]


def _split_cover(
    vertices: np.ndarray,
    faces: np.ndarray,
    surface: np.ndarray,
    solid: list[np.ndarray] | None,
    margin: float,
    capsules: bool,
    budget: int,
    max_overshoot: float | None,
) -> MeshCover:
    """Top-down over the triangles ``faces`` of ``vertices``: start from one primitive holding
    every triangle, and split the group whose primitive reaches farthest in two (of the
    candidate splits, the one whose worse half reaches least) until the budget is spent or the
    worst reach is at most ``max_overshoot``."""

    def fit(members: np.ndarray) -> tuple[float, tuple]:
        points = vertices[np.unique(faces[members])]
        return _fit(points, surface, solid, margin, capsules)

    groups = [np.arange(len(faces))]
    fits = [fit(groups[0])]
    centroids = vertices[faces].mean(axis=1)
    stuck: set[int] = set()
    while len(groups) < budget:
        order = [i for i in np.argsort([-f[0] for f in fits]) if int(i) not in stuck]
        if not order or (max_overshoot is not None and fits[order[0]][0] <= max_overshoot):
            break
        worst = int(order[0])
        members = groups[worst]
        options = []
        for mask in _halves(centroids[members]):
            parts = (members[mask], members[~mask])
            pair = [fit(part) for part in parts]
            options.append((max(pair[0][0], pair[1][0]), parts, pair))
        if not options:
            stuck.add(worst)  # a single triangle
            continue
        _, parts, pair = min(options, key=lambda o: (o[0], o[2][0][0] + o[2][1][0]))
        groups[worst], fits[worst] = parts[0], pair[0]
        groups.append(parts[1])
        fits.append(pair[1])
    balls = [f[1] for f in fits if f[1][0] == "sphere"]
    caps = [f[1] for f in fits if f[1][0] == "capsule"]
    return MeshCover(
        np.array([x[1] for x in balls]).reshape(-1, 3),
        np.array([x[2] for x in balls]),
        np.array([x[1] for x in caps]).reshape(-1, 3),
        np.array([x[2] for x in caps]).reshape(-1, 3),
        np.array([x[3] for x in caps]),
        float(max(max(f[0] for f in fits), 0.0)),
    )


def _watertight(vertices: np.ndarray, faces: np.ndarray) -> bool:
    """Every edge shared by exactly two faces (a closed surface, so inside is defined)."""
    edges = np.sort(faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1)
    _, counts = np.unique(edges, axis=0, return_counts=True)
    return bool(np.all(counts == 2))


def mesh_cover(
    vertices: np.ndarray,
    faces: np.ndarray,
    max_primitives: int = 16,
    max_overshoot: float | None = None,
    capsules: bool = True,
) -> MeshCover:
    """Spheres and capsules containing every triangle of the mesh ``(vertices (v, 3), faces
    (f, 3))``.

    Args:
        vertices, faces: the mesh, in the frame the primitives are wanted in.
        max_primitives: the budget of spheres and capsules together (at least 1).
        max_overshoot: stop at the first count (1, 2, 4, ...) whose overshoot bound is at most
            this; ``None`` uses the whole budget.
        capsules: allow capsules (else spheres only).
    """
    import trimesh

    vertices = np.asarray(vertices, dtype=float)
    faces = np.asarray(faces, dtype=np.int64)
    if vertices.ndim != 2 or vertices.shape[1] != 3 or len(vertices) == 0:
        raise ValueError(f"vertices: expected shape (v, 3) with v >= 1, got {vertices.shape}")
    if faces.ndim != 2 or faces.shape[1] != 3 or len(faces) == 0:
        raise ValueError(f"faces: expected shape (f, 3) with f >= 1, got {faces.shape}")
    if int(max_primitives) < 1:
        raise ValueError(f"max_primitives must be >= 1, got {max_primitives}")
    size = float(np.linalg.norm(vertices.max(axis=0) - vertices.min(axis=0)))
    margin = _ROUNDING_MARGIN * max(size, float(np.abs(vertices).max()))
    # triangles much smaller than the smallest primitive wanted, so groups can be tight
    edge = size / (4.0 * np.sqrt(max_primitives)) if size > 0 else 1.0
    v, f = trimesh.remesh.subdivide_to_size(vertices, faces, max_edge=edge, max_iter=10)
    solid = _closed_bodies(vertices, faces)
    return _split_cover(
        np.asarray(v),
        np.asarray(f),
        vertices[faces],
        solid,
        margin,
        capsules,
        int(max_primitives),
        max_overshoot,
    )


def mesh_sphere_cover(
    vertices: np.ndarray,
    faces: np.ndarray,
    max_spheres: int = 16,
    max_overshoot: float | None = None,
) -> SphereCover:
    """Spheres only containing every triangle of the mesh (``mesh_cover`` without capsules).

    Args:
        vertices, faces: the mesh, in the frame the spheres are wanted in.
        max_spheres: the sphere budget (at least 1).
        max_overshoot: stop at the first sphere count (1, 2, 4, ...) whose overshoot bound is
            at most this; ``None`` uses the whole budget.
    """
    if int(max_spheres) < 1:
        raise ValueError(f"max_spheres must be >= 1, got {max_spheres}")
    cover = mesh_cover(vertices, faces, max_spheres, max_overshoot, capsules=False)
    return SphereCover(cover.centers, cover.radii, cover.overshoot)


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
