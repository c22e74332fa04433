"""Conservative covers of link geometry by spheres (and capsules), host side, NumPy only.

**Sphere covers with an overshoot bound** (``mesh_sphere_cover``, ``box_sphere_cover``; the
default of ``body_from_urdf``). The union of the spheres contains every point of every
triangle of the mesh, and every point of every sphere lies within the bound ``delta`` of the
mesh's solid; among such covers, few spheres. The method:

1. Medial candidates. The triangles are cut into pieces with edges of at most ``delta / 3``
   (``triangles.subdivide``). From pieces about ``1.5 delta`` apart (one per cell, a fixed
   permutation choosing), the point ``c = p - t n`` goes inward along the piece's outward
   normal ``n`` from its centroid ``p``, ``t`` doubling from ``delta / 8`` and then bisected,
   to the largest ``t`` at which the ball ``B(c, t)`` is still empty of triangles (the
   exact distance ``d(c) = t``: the ball touches the surface only at ``p``): the medial ball
   at ``p`` of the shrinking-ball method [Ma, Bae & Choi 2012]. An empty ball touching
   ``p`` from the inner side of a closed, consistently oriented part lies inside its solid,
   so the sphere ``(c, d(c) + delta)`` reaches at most ``delta`` past the solid; it also holds
   every such sphere from ``p`` with a smaller ``t`` (``B(c_s, s + delta)`` lies in
   ``B(c_t, t + delta)`` for ``s < t``), so only the deepest is kept. A part that is not
   closed has no inside: its candidates are its pieces' centroids with radius ``delta``.
   Candidates within ``delta / 2`` of one another keep the deepest.
2. Greedy set cover [Chvatal 1979]. The pieces are grouped by cells of ``delta / 2``, each
   group held in a ball; a candidate holds a group when the group's ball lies in its sphere.
   The candidate holding most groups not yet held is taken until every group is held (a group
   no candidate holds is replaced by its pieces, each held by a sphere of radius ``delta`` at
   its centroid).
3. Exact pruning and shrinking. Against the chosen spheres, each piece is held when its three
   corners are (a ball holds a triangle when it holds its corners); in reverse order of choice
   a sphere whose pieces are all held by others is dropped; each piece is given to the sphere
   that holds it most centrally and every radius shrinks to the farthest corner it must hold.
   The overshoot bound of a sphere is ``r - d(c)`` (a point of the sphere is within ``r`` of
   ``c``, whose ball of radius ``d(c)`` is solid); the cover's is the largest.

The bound is met when it can be within ``max_spheres`` (a budget per mesh or box); when not,
it is relaxed (by ``sqrt(count / budget)`` at a time) until the cover fits, and the cover's
``overshoot`` says what was reached. Everything is deterministic (a fixed permutation picks the
sample pieces).

**Mixed covers** (``mesh_cover``, the former default, still chosen with
``body_from_urdf(max_primitives_per_mesh=k)``): spheres and capsules, top down. One primitive
holds every triangle, then the group whose primitive reaches farthest past the mesh is split in
two (at the median along one of its principal axes, or by 2-means) until the budget is spent or
the worst reach is at most ``max_overshoot``; each group gets whichever of its enclosing ball
and its enclosing capsule reaches less far (the capsule's axis its principal axis through the
centre of the smallest circle holding the points across it, its segment the shortest that keeps
every point within the radius). A point of a ball ``(c, r)`` lies within ``r + sd(c)`` of the
solid, a point of a capsule within ``r + max sd`` over its segment (``sd`` the signed distance,
negative inside; for several closed parts, inside means the deepest in one part).

``box_capsules``: capsules along a box's longest axis that contain the whole solid box.

Radii are grown by a relative 1e-6 of the mesh size so the covers survive rounding to float32.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np

from . import triangles as tri_ops

__all__ = [
    "MeshCover",
    "SphereCover",
    "box_capsules",
    "box_sphere_cover",
    "mesh_cover",
    "mesh_sphere_cover",
]

_ROUNDING_MARGIN = 1e-6  # relative to the mesh size: float32 rounding of centres and radii
_EDGE = 1.0 / 3.0  # longest edge of the pieces, in units of the bound
_GROUP = 0.5  # cell of the groups of pieces the greedy cover holds, in units of the bound
_SAMPLE = 1.5  # cell of the sample pieces the candidates start from
_DEDUPE = 0.5  # candidates within one cell of this size keep the largest
_BISECT = 6  # bisection steps of the medial depth (to 1.6 %)
_MAX_PIECES = 300_000  # the bound is raised first so that the pieces stay below this
_MAX_BOX_CAPSULES = 8  # box_capsules: strips across the box at most


@dataclasses.dataclass(frozen=True)
class SphereCover:
    """Spheres covering a mesh: ``centers (k, 3)``, ``radii (k,)``, and ``overshoot`` (the
    largest distance a point of the cover can lie from the mesh's solid, an upper bound)."""

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


# ---------------------------------------------------------------- sphere covers with a bound
def _voxel_keys(x: np.ndarray, size: float) -> np.ndarray:
    """One integer per point: the cell of side ``size`` that holds it."""
    ijk = np.floor((x - x.min(axis=0)) / size).astype(np.int64)
    span = ijk.max(axis=0) + 1
    return (ijk[:, 0] * span[1] + ijk[:, 1]) * span[2] + ijk[:, 2]


def _medial_depths(
    part: tri_ops.Part, p: np.ndarray, n: np.ndarray, delta: float, extent: float
) -> tuple[np.ndarray, np.ndarray]:
    """For surface points ``p (s, 3)`` of a closed part with outward normals ``n (s, 3)``,
    the largest ``t`` (to a relative ``2^-_BISECT``) such that the ball ``B(p - t n, t)`` holds
    no point of the part's triangles in its interior: it touches the surface at ``p`` and lies
    inside the solid (module docstring, step 1). Returns ``t`` and the exact distance ``d <=
    t`` of ``p - t n`` to the triangles (``t - d`` is below ``1e-9`` of the part's size: the
    empty ball ``B(p - t n, d)`` is the certified depth); both 0 where ``delta / 8`` fails."""
    tol = 1e-9 * extent
    depth = np.zeros(len(p))

    def empty(idx: np.ndarray, t: np.ndarray) -> np.ndarray:
        d = tri_ops.nearest_distance(p[idx] - t[:, None] * n[idx], t + tol, part.triangles)
        ok = d >= t - tol
        depth[idx[ok]] = np.minimum(d[ok], t[ok])
        return ok

    lo = np.zeros(len(p))
    hi = np.full(len(p), np.inf)
    t = 0.125 * delta
    idx = np.arange(len(p))
    while len(idx) and t <= extent:  # doubling while the ball stays empty
        ok = empty(idx, np.full(len(idx), t))
        lo[idx[ok]] = t
        hi[idx[~ok]] = t
        idx, t = idx[ok], 2.0 * t
    for _ in range(_BISECT):
        idx = np.flatnonzero((lo > 0) & np.isfinite(hi))
        mid = 0.5 * (lo[idx] + hi[idx])
        ok = empty(idx, mid)
        lo[idx[ok]] = mid[ok]
        hi[idx[~ok]] = mid[~ok]
    return lo, depth


def _greedy(cand: np.ndarray, elem: np.ndarray, n_cand: int, n_elem: int) -> np.ndarray:
    """Greedy set cover: the pairs ``(cand[i], elem[i])`` (candidate holds element, ordered by
    candidate); repeatedly the candidate holding most elements not yet held. Returns the
    chosen candidates in order of choice."""
    by_elem = np.argsort(elem, kind="stable")
    elem_start = np.searchsorted(elem[by_elem], np.arange(n_elem + 1))
    cand_start = np.searchsorted(cand, np.arange(n_cand + 1))
    gain = np.bincount(cand, minlength=n_cand)
    held = np.zeros(n_elem, bool)
    chosen: list[int] = []
    while True:
        best = int(np.argmax(gain))
        if gain[best] == 0:
            return np.asarray(chosen, dtype=np.int64)
        mine = elem[cand_start[best] : cand_start[best + 1]]
        new = mine[~held[mine]]
        held[new] = True
        # every candidate holding a newly held element gains one less
        count = elem_start[new + 1] - elem_start[new]
        rows = np.repeat(elem_start[new], count) + _ranks(count)
        gain -= np.bincount(cand[by_elem[rows]], minlength=n_cand)
        chosen.append(best)


def _ranks(count: np.ndarray) -> np.ndarray:
    """``0 .. count[i] - 1`` for each ``i``, concatenated."""
    return np.arange(int(count.sum())) - np.repeat(np.cumsum(count) - count, count)


def _holds(
    centre: np.ndarray, radius: np.ndarray, pieces: np.ndarray, middle: np.ndarray, rho: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The pairs ``(sphere, piece)`` whose piece's three corners lie in the sphere, ordered by
    sphere, and each pair's farthest corner distance."""
    si, pi = tri_ops.near_pairs(centre, radius, middle, rho)
    far = np.linalg.norm(middle[pi] - centre[si], axis=1) + rho[pi]
    unsure = np.flatnonzero(far > radius[si])
    corners = pieces[pi[unsure]] - centre[si[unsure], None]
    far[unsure] = np.sqrt(np.einsum("kvj,kvj->kv", corners, corners).max(axis=1))
    keep = far <= radius[si] * (1.0 + 1e-12)  # the groups' test, up to its rounding
    return si[keep], pi[keep], far[keep]


def _cover_at(parts: list[tri_ops.Part], delta: float) -> tuple[np.ndarray, ...]:
    """Spheres holding every triangle of ``parts``, each reaching at most ``delta`` past the
    solid (module docstring): ``(centres (k, 3), radii (k,), reach (k,))``, radii not yet
    grown by the rounding margin."""
    rng = np.random.default_rng(0)
    per_part = [tri_ops.subdivide(part.triangles, _EDGE * delta) for part in parts]
    owner = np.concatenate([np.full(len(x), k) for k, x in enumerate(per_part)])
    pieces = np.concatenate(per_part)
    middle = pieces.mean(axis=1)
    rho = np.sqrt(np.einsum("kvj,kvj->kv", pieces - middle[:, None], pieces - middle[:, None]))
    rho = rho.max(axis=1)
    normal = np.cross(pieces[:, 1] - pieces[:, 0], pieces[:, 2] - pieces[:, 0])
    area2 = np.linalg.norm(normal, axis=1)
    normal = normal / np.maximum(area2, 1e-300)[:, None]
    corners = pieces.reshape(-1, 3)
    extent = float((corners.max(axis=0) - corners.min(axis=0)).max())

    def candidates(samples: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Medial candidates from the sample pieces of closed parts, centroids of open ones;
        within one ``_DEDUPE`` cell, the deepest: ``(centres, certified depths)``."""
        centres, depths = [], []
        for k, part in enumerate(parts):
            own = samples[owner[samples] == k]
            t, d = np.zeros(len(own)), np.zeros(len(own))
            if part.closed:
                t, d = _medial_depths(part, middle[own], normal[own], delta, extent)
            c = middle[own] - t[:, None] * normal[own]
            centres.append(c)
            depths.append(d)
        c, d = np.concatenate(centres), np.concatenate(depths)
        key = _voxel_keys(c, _DEDUPE * delta) if len(c) else np.zeros(0, np.int64)
        by_key = np.lexsort((-d, key))
        first = by_key[np.r_[True, key[by_key][1:] != key[by_key][:-1]]] if len(c) else by_key
        return c[first], d[first]

    def held(centre, radius, e_middle, e_radius) -> tuple[np.ndarray, np.ndarray]:
        ci, ei = tri_ops.near_pairs(centre, radius, e_middle, e_radius)
        inside = np.linalg.norm(e_middle[ei] - centre[ci], axis=1) + e_radius[ei] <= radius[ci]
        return ci[inside], ei[inside]

    # 1. candidates: medial balls from sample pieces about _SAMPLE * delta apart
    order = rng.permutation(len(pieces))
    order = order[area2[order] > 0]
    key = _voxel_keys(middle[order], _SAMPLE * delta) * len(parts) + owner[order]
    centre, depth = candidates(order[np.sort(np.unique(key, return_index=True)[1])])

    # 2. greedy cover of groups of pieces (balls about the middle of their corners' box)
    group = np.unique(_voxel_keys(middle, _GROUP * delta), return_inverse=True)[1].reshape(-1)
    n_groups = int(group.max()) + 1
    by_group = np.argsort(group, kind="stable")
    first = np.searchsorted(group[by_group], np.arange(n_groups))
    lo = np.minimum.reduceat(pieces.min(axis=1)[by_group], first)
    hi = np.maximum.reduceat(pieces.max(axis=1)[by_group], first)
    g_middle = 0.5 * (lo + hi)
    reach = pieces - g_middle[group, None]
    reach = np.sqrt(np.einsum("kvj,kvj->kv", reach, reach).max(axis=1))
    g_radius = np.maximum.reduceat(reach[by_group], first)
    ci, ei = held(centre, depth + delta, g_middle, g_radius)
    lone = np.bincount(ei, minlength=n_groups) == 0
    if lone.any():
        # more candidates where none holds a group: from its largest piece
        lone_pieces = np.flatnonzero(lone[group] & (area2 > 0))
        by_group = lone_pieces[np.lexsort((-area2[lone_pieces], group[lone_pieces]))]
        first = np.r_[True, group[by_group][1:] != group[by_group][:-1]]
        more, more_depth = candidates(by_group[first])
        c2, e2 = held(more, more_depth + delta, g_middle, g_radius)
        ci, ei = np.concatenate([ci, c2 + len(centre)]), np.concatenate([ei, e2])
        centre, depth = np.concatenate([centre, more]), np.concatenate([depth, more_depth])
        lone = np.bincount(ei, minlength=n_groups) == 0
    radius = depth + delta
    if lone.any():
        # a group still not held: its pieces become elements, each held by a sphere of
        # radius delta at its centroid (on the surface, so it reaches at most delta past it)
        split = np.flatnonzero(lone[group])
        centre = np.concatenate([centre, middle[split]])
        depth = np.concatenate([depth, np.zeros(len(split))])
        radius = np.concatenate([radius, np.full(len(split), delta)])
        kept = np.flatnonzero(~lone)
        e_middle = np.concatenate([g_middle[kept], middle[split]])
        e_radius = np.concatenate([g_radius[kept], rho[split]])
        ci, ei = held(centre, radius, e_middle, e_radius)
        n_groups = len(e_middle)
    chosen = _greedy(ci, ei, len(centre), n_groups)

    # 3. exact: pieces against the chosen spheres; prune in reverse order; shrink
    centre, depth, radius = centre[chosen], depth[chosen], radius[chosen]
    si, pi, far = _holds(centre, radius, pieces, middle, rho)
    holders = np.bincount(pi, minlength=len(pieces))
    if np.any(holders == 0):
        raise RuntimeError("sphere cover: a piece is held by no chosen sphere")
    start = np.searchsorted(si, np.arange(len(centre) + 1))
    kept = np.ones(len(centre), bool)
    for j in range(len(centre) - 1, -1, -1):
        mine = pi[start[j] : start[j + 1]]
        if np.all(holders[mine] >= 2):
            holders[mine] -= 1
            kept[j] = False
    use = kept[si]
    si, pi, far = si[use], pi[use], far[use]
    by_piece = np.lexsort((far / radius[si], pi))
    first = by_piece[np.r_[True, pi[by_piece][1:] != pi[by_piece][:-1]]]
    owner_of, far = si[first], far[first]  # each piece's sphere
    shrunk = np.zeros(len(centre))
    by_owner = np.argsort(owner_of, kind="stable")
    owners, start = np.unique(owner_of[by_owner], return_index=True)
    shrunk[owners] = np.maximum.reduceat(far[by_owner], start)
    keep = owners
    return centre[keep], shrunk[keep], shrunk[keep] - depth[keep]


def _sphere_cover(
    parts: list[tri_ops.Part], bound: float | None, budget: int | None, margin: float
) -> SphereCover:
    """The cover of ``parts`` within ``bound`` (None: the smallest bound the budget allows,
    within 10 %), relaxed until it has at most ``budget`` spheres (module docstring)."""
    triangles = np.concatenate([part.triangles for part in parts])
    corners = triangles.reshape(-1, 3)
    size = float(np.linalg.norm(corners.max(axis=0) - corners.min(axis=0)))
    area = 0.5 * float(
        np.linalg.norm(
            np.cross(triangles[:, 1] - triangles[:, 0], triangles[:, 2] - triangles[:, 0]), axis=1
        ).sum()
    )
    # pieces of edge e = delta / 3 have an area of about e^2 / 4 (slivers less): keep them few
    floor = math.sqrt(8.0 * area / _MAX_PIECES) / _EDGE if area > 0 else 0.0
    floor = max(floor, 1e-6 * size, 1e-12) + 2.0 * margin
    if budget is not None and area > 0:
        # a sphere of radius d + delta, d at most half the thinnest extent, holds at most a
        # cap of area pi (2 d delta + delta^2) on each of two sides: a bound that needs more
        # spheres than the budget is not tried (the loop below still enforces the budget)
        depth = 0.5 * float(np.ptp(corners, axis=0).min())
        share = area / (2.0 * math.pi * budget)
        floor = max(floor, math.sqrt(depth * depth + share) - depth)

    def attempt(delta: float) -> tuple[np.ndarray, ...]:
        # the rounding margin is part of the bound: the reported overshoot is at most delta
        return _cover_at(parts, max(delta, floor) - margin)

    if bound is None:
        if budget is None:
            raise ValueError("a sphere cover needs a bound or a budget")
        # from a bound one sphere meets, halve while the budget holds, then bisect
        delta, best = max(size, floor), None
        while True:
            found = attempt(delta)
            if len(found[1]) > budget:
                break
            best, good = found, delta
            if delta <= floor:
                break
            delta *= 0.5
        if best is None:  # pragma: no cover - one sphere always fits at the mesh's size
            best, good = found, delta
        bad = delta
        while bad < good and good / bad > 1.1:
            mid = math.sqrt(good * bad)
            found = attempt(mid)
            if len(found[1]) <= budget:
                best, good = found, mid
            else:
                bad = mid
    else:
        delta = max(bound, floor)
        best = attempt(delta)
        while budget is not None and len(best[1]) > budget:
            delta *= max(1.1, math.sqrt(len(best[1]) / budget))
            best = attempt(delta)
    centers, radii, reach = best
    return SphereCover(centers, radii + margin, float(reach.max(initial=0.0)) + margin)


def _checked_mesh(vertices: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    vertices = np.asarray(vertices, dtype=float)
    faces = np.asarray(faces)
    if vertices.ndim != 2 or vertices.shape[1] != 3 or len(vertices) == 0:
        raise ValueError(f"vertices: expected shape (v, 3) with v >= 1, got {vertices.shape}")
    if not np.all(np.isfinite(vertices)):
        raise ValueError("vertices: expected finite coordinates, got NaN or inf")
    if faces.ndim != 2 or faces.shape[1] != 3 or len(faces) == 0:
        raise ValueError(f"faces: expected shape (f, 3) with f >= 1, got {faces.shape}")
    if (
        not np.issubdtype(faces.dtype, np.integer)
        or faces.min() < 0
        or faces.max() >= len(vertices)
    ):
        raise ValueError(f"faces: expected vertex indices in [0, {len(vertices)})")
    return vertices, faces.astype(np.int64)


def _budget(value: int | None, name: str) -> int | None:
    if value is None:
        return None
    if isinstance(value, bool) or not isinstance(value, int | np.integer) or value < 1:
        raise ValueError(f"{name} must be an integer >= 1 or None, got {value!r}")
    return int(value)


def _bound(value: float | None, name: str = "max_overshoot") -> float | None:
    if value is None:
        return None
    if isinstance(value, bool) or not np.isfinite(value) or value <= 0:
        raise ValueError(f"{name} must be a positive length or None, got {value!r}")
    return float(value)


def mesh_sphere_cover(
    vertices: np.ndarray,
    faces: np.ndarray,
    max_spheres: int | None = None,
    max_overshoot: float | None = 0.01,
) -> SphereCover:
    """Spheres containing every triangle of the mesh ``(vertices (v, 3), faces (f, 3))``,
    each reaching at most ``max_overshoot`` past the mesh's solid (module docstring).

    Args:
        vertices, faces: the mesh, in the frame the spheres are wanted in (length units of
            the bound, metres by default).
        max_spheres: the budget: when the bound needs more spheres, it is relaxed until the
            cover fits (``overshoot`` says what was reached); None for no budget.
        max_overshoot: the bound; None for the smallest bound the budget allows (within 10
            %; needs ``max_spheres``).
    """
    vertices, faces = _checked_mesh(vertices, faces)
    max_spheres = _budget(max_spheres, "max_spheres")
    max_overshoot = _bound(max_overshoot)
    if max_overshoot is None and max_spheres is None:
        raise ValueError("mesh_sphere_cover: give max_overshoot, max_spheres or both")
    parts = tri_ops.parts(vertices, faces)
    if not parts:
        raise ValueError("faces: no triangle with three distinct vertices")
    margin = _ROUNDING_MARGIN * max(
        float(np.linalg.norm(np.ptp(vertices, axis=0))), float(np.abs(vertices).max())
    )
    return _sphere_cover(parts, max_overshoot, max_spheres, margin)


def box_mesh(half_extents: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The closed, outward-oriented surface of the box ``|u_i| <= h_i``: 8 corners, 12
    triangles."""
    h = np.asarray(half_extents, dtype=float)
    corners = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)]) * h
    faces = np.array(
        [
            [0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5],  # -x, +x
            [0, 4, 5], [0, 5, 1], [2, 3, 7], [2, 7, 6],  # -y, +y
            [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3],  # -z, +z
        ]
    )  # fmt: skip
    return corners, faces


def box_sphere_cover(
    half_extents: np.ndarray, max_spheres: int | None = 32, max_overshoot: float | None = 0.01
) -> SphereCover:
    """``mesh_sphere_cover`` of the solid box ``|u_i| <= h_i`` (in its frame): a thin or flat
    box is held by at most ``max_spheres``, its bound relaxed as far as needed."""
    h = np.asarray(half_extents, dtype=float)
    if h.shape != (3,) or not np.all(np.isfinite(h)) or np.any(h < 0):
        raise ValueError(f"half_extents: expected three finite lengths >= 0, got {h}")
    if not np.any(h > 0):
        return SphereCover(np.zeros((1, 3)), np.zeros(1), 0.0)
    return mesh_sphere_cover(*box_mesh(h), max_spheres, max_overshoot)


# ---------------------------------------------------------------- mixed covers (top down)
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
        return tri_ops.point_triangle_distance(p[:, None], tri[None]).min(axis=1)

    if bodies is None:
        return gap(surface)
    dist = np.stack([gap(tri) for tri in bodies], axis=1)  # (n, bodies)
    inside = np.stack([_winding_numbers(tri, p) > 0.5 for tri in bodies], axis=1)
    depth = np.where(inside, dist, -np.inf).max(axis=1)
    return np.where(inside.any(axis=1), -depth, dist.min(axis=1))


def _closed_bodies(vertices: np.ndarray, faces: np.ndarray) -> list[np.ndarray] | None:
    """The triangles of each connected part of the mesh, when every part is closed and
    consistently oriented; None otherwise."""
    found = tri_ops.parts(vertices, faces)
    if not all(part.closed for part in found):
        return None
    return [part.triangles for part in found]


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
    pieces: np.ndarray,
    surface: np.ndarray,
    solid: list[np.ndarray] | None,
    margin: float,
    budget: int,
    max_overshoot: float | None,
    capsules: bool,
) -> MeshCover:
    """Top-down over the triangles ``pieces (k, 3, 3)``: start from one primitive holding
    every triangle, and split the group whose primitive reaches farthest in two (of the
    candidate splits, the one whose worse half reaches least) until the budget is spent or the
    worst reach is at most ``max_overshoot``."""

    def fit(members: np.ndarray) -> tuple[float, tuple]:
        return _fit(pieces[members].reshape(-1, 3), surface, solid, margin, capsules)

    groups = [np.arange(len(pieces))]
    fits = [fit(groups[0])]
    centroids = pieces.mean(axis=1)
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


def mesh_cover(
    vertices: np.ndarray,
    faces: np.ndarray,
    max_primitives: int = 16,
    max_overshoot: float | None = None,
    capsules: bool = True,
) -> MeshCover:
    """Spheres and capsules containing every triangle of the mesh ``(vertices (v, 3), faces
    (f, 3))``, top down (module docstring; the sphere covers of ``mesh_sphere_cover`` are the
    default of ``body_from_urdf``).

    Args:
        vertices, faces: the mesh, in the frame the primitives are wanted in.
        max_primitives: the budget of spheres and capsules together (at least 1).
        max_overshoot: stop at the first count (1, 2, 4, ...) whose overshoot bound is at most
            this; ``None`` uses the whole budget.
        capsules: allow capsules (else spheres only).
    """
    vertices, faces = _checked_mesh(vertices, faces)
    budget = _budget(max_primitives, "max_primitives")
    if budget is None:
        raise ValueError("max_primitives must be an integer >= 1, got None")
    max_overshoot = _bound(max_overshoot)
    size = float(np.linalg.norm(vertices.max(axis=0) - vertices.min(axis=0)))
    margin = _ROUNDING_MARGIN * max(size, float(np.abs(vertices).max()))
    # triangles much smaller than the smallest primitive wanted, so groups can be tight
    edge = size / (4.0 * np.sqrt(budget)) if size > 0 else 1.0
    pieces = tri_ops.subdivide(vertices[faces], edge)
    return _split_cover(
        pieces,
        vertices[faces],
        _closed_bodies(vertices, faces),
        margin,
        budget,
        max_overshoot,
        capsules,
    )


def box_capsules(half_extents: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Capsules, in the box's frame, whose union contains the solid box ``|u_i| <= h_i``.

    The axis is the box's longest; the cross-section ``2w x 2t`` (``w >= t``) is cut into
    ``k = min(ceil(w / t), 8)`` strips along ``w``, each covered by a capsule through the
    strip's centre line with radius ``sqrt((w / k)^2 + t^2)`` (the strip's half diagonal) and
    end points at the box's end faces (a flat box gets at most 8 capsules, wider ones).
    Returns ``(a (k, 3), b (k, 3), radii (k,))``.
    """
    h = np.asarray(half_extents, dtype=float)
    axis = int(np.argmax(h))
    others = [i for i in range(3) if i != axis]
    wide, thin = sorted(others, key=lambda i: -h[i])
    w, t = h[wide], h[thin]
    k = 1 if t <= 0 or w <= 0 else int(np.ceil(w / t - 1e-9))
    k = min(max(k, 1), _MAX_BOX_CAPSULES)
    offsets = (np.arange(k) + 0.5) * (2.0 * w / k) - w
    a = np.zeros((k, 3))
    a[:, wide] = offsets
    b = a.copy()
    a[:, axis], b[:, axis] = -h[axis], h[axis]
    radius = np.sqrt((w / k) ** 2 + t**2) * (1.0 + _ROUNDING_MARGIN)
    return a, b, np.full(k, radius)
