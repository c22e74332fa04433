"""Triangle soups on the host (NumPy only): subdivision, exact distances, parts, near pairs.

- ``subdivide``: longest-edge bisection until every edge is at most a length (the pieces tile
  each triangle exactly: a convex set holding a piece's three corners holds the piece).
- ``point_triangle_distance``: the exact Euclidean distance from points to triangles
  (broadcasting): the distance to the plane where the point projects inside the triangle,
  else the distance to the nearest of its three edges [Ericson 2005, sec. 5.1.5].
- ``parts``: the connected parts of an indexed mesh (faces sharing a vertex), each with
  whether it is closed and consistently oriented (every directed edge used once and its
  reverse once: a closed, oriented surface, so inside is defined) and with its triangles
  turned outward (a negative enclosed volume flips them).
- ``near_pairs``: every pair of a query ball and an item ball that overlap, through a uniform
  grid of the items (the exact test on the pairs of the cells the query can reach), so the
  work grows with the pairs found, not with queries times items.
- ``nearest_distance``: the exact distance from points to a triangle set, given for each point
  an upper bound (only the triangles that bound can reach are measured).
"""

from __future__ import annotations

import dataclasses

import numpy as np

__all__ = [
    "Part",
    "near_pairs",
    "nearest_distance",
    "parts",
    "point_triangle_distance",
    "subdivide",
]

# Entries of the largest temporary of a dense chunk (queries x cells, points x triangles)
_CHUNK = 1 << 21


def _strips(tri: np.ndarray, max_edge: float) -> np.ndarray:
    """Needles ``(a, b, c)`` whose edge ``bc`` is at most ``max_edge / 2``, cut into strips
    across their length: with ``P_k = a + (k / n)(b - a)`` and ``Q_k = a + (k / n)(c - a)``,
    the triangles ``(P_k, P_k+1, Q_k+1)`` and ``(P_k, Q_k+1, Q_k)``, each edge at most ``|bc| +
    max(|ab|, |ac|) / n <= max_edge`` for ``n = ceil(2 max(|ab|, |ac|) / max_edge)``."""
    a, b, c = tri[:, 0], tri[:, 1], tri[:, 2]
    long = np.maximum(np.linalg.norm(b - a, axis=1), np.linalg.norm(c - a, axis=1))
    n = np.maximum(np.ceil(2.0 * long / max_edge), 1).astype(np.int64)
    which = np.repeat(np.arange(len(tri)), n)
    k = (np.arange(int(n.sum())) - np.repeat(np.cumsum(n) - n, n))[:, None]
    step = 1.0 / n[which, None]
    a, b, c = a[which], b[which], c[which]
    p0, p1 = a + k * step * (b - a), a + (k + 1) * step * (b - a)
    q0, q1 = a + k * step * (c - a), a + (k + 1) * step * (c - a)
    first = np.stack([p0, p1, q1], axis=1)
    second = np.stack([p0, q1, q0], axis=1)[k[:, 0] > 0]  # at the apex P_0 = Q_0
    return np.concatenate([first, second])


def _fans(tri: np.ndarray, max_edge: float) -> np.ndarray:
    """Triangles ``(a, b, c)`` cut into ``m = ceil(2 |bc| / max_edge)`` triangles ``(a,
    B_j, B_j+1)``, ``B_j = b + (j / m)(c - b)``: needles with bases of at most
    ``max_edge / 2``."""
    a, b, c = tri[:, 0], tri[:, 1], tri[:, 2]
    m = np.maximum(np.ceil(2.0 * np.linalg.norm(c - b, axis=1) / max_edge), 1).astype(np.int64)
    which = np.repeat(np.arange(len(tri)), m)
    j = (np.arange(int(m.sum())) - np.repeat(np.cumsum(m) - m, m))[:, None]
    step = 1.0 / m[which, None]
    a, b, c = a[which], b[which], c[which]
    return np.stack([a, b + j * step * (c - b), b + (j + 1) * step * (c - b)], axis=1)


def subdivide(tri: np.ndarray, max_edge: float) -> np.ndarray:
    """Triangles ``(m, 3, 3)`` cut until every edge is at most ``max_edge`` (> 0); returns the
    pieces ``(k, 3, 3)``, which tile the triangles with their orientation.

    A triangle is bisected at the midpoint of its longest edge ``L``, which gives some
    ``0.3 (L / max_edge)^2`` pieces however thin it is (measured: 0.27-0.43). A needle (its
    shortest edge ``w`` below ``L / 10``) is cut along its length instead when that gives
    fewer, ``m (2 n - 1) < (L / max_edge)^2 / 4``: fanned from its apex into ``m = ceil(2 w /
    max_edge)`` needles (``_fans``), each cut into ``2 n - 1`` strips (``_strips``); another
    thin triangle (its height onto ``L`` below ``L / 10``) is first split at the foot of that
    height (kept within the middle half of ``L``) into two triangles."""
    done = []
    while len(tri):
        edges = np.stack(
            [
                np.linalg.norm(tri[:, 1] - tri[:, 2], axis=1),
                np.linalg.norm(tri[:, 2] - tri[:, 0], axis=1),
                np.linalg.norm(tri[:, 0] - tri[:, 1], axis=1),
            ],
            axis=1,
        )
        longest, shortest = edges.max(axis=1), edges.min(axis=1)
        small = longest <= max_edge
        done.append(tri[small])
        keep = ~small
        tri, edges, longest, shortest = tri[keep], edges[keep], longest[keep], shortest[keep]
        if not len(tri):
            break
        area2 = np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
        pointed = shortest <= 0.1 * longest
        thin = (area2 <= 0.1 * longest * longest) & ~pointed  # a cap: its height is short
        fans = np.ceil(2.0 * shortest / max_edge) * (2.0 * np.ceil(2.0 * longest / max_edge) - 1)
        needle = pointed & (fans < 0.25 * (longest / max_edge) ** 2)
        # vertex 0 opposite the edge to cut: the shortest for needles, else the longest
        k = np.where(needle, edges.argmin(axis=1), edges.argmax(axis=1))
        order = np.stack([k, (k + 1) % 3, (k + 2) % 3], axis=1)
        tri = np.take_along_axis(tri, order[:, :, None], axis=1)
        narrow = needle & (shortest <= 0.5 * max_edge)
        if narrow.any():
            done.append(_strips(tri[narrow], max_edge))
        wide = _fans(tri[needle & ~narrow], max_edge) if np.any(needle & ~narrow) else tri[:0]
        rest = tri[~needle]
        a, b, c = rest[:, 0], rest[:, 1], rest[:, 2]
        # split bc at the foot of the height from a (thin; kept within the middle half of bc,
        # so that each split halves something) or at its midpoint (fat)
        t = np.einsum("ij,ij->i", a - b, c - b) / np.maximum(
            np.einsum("ij,ij->i", c - b, c - b), 1e-300
        )
        t = np.where(thin[~needle], np.clip(t, 0.25, 0.75), 0.5)
        mid = b + t[:, None] * (c - b)
        tri = np.concatenate([wide, np.stack([a, b, mid], 1), np.stack([a, mid, c], 1)])
    return np.concatenate(done) if done else np.zeros((0, 3, 3))


def point_triangle_distance(p: np.ndarray, tri: np.ndarray) -> np.ndarray:
    """Distance from points ``p (..., 3)`` to triangles ``tri (..., 3, 3)`` (broadcast
    together, e.g. ``p[:, None]`` against ``tri[None]`` for every pair). Exact: the distance
    to the plane when the point projects inside the triangle (the three edge tests
    ``(n x e) . (p - v) >= 0``), else the smallest distance to the three edges as segments;
    a degenerate triangle (zero area) is its edges."""

    def comp(x: np.ndarray) -> list[np.ndarray]:
        return [x[..., k] for k in range(3)]

    def sub(x, y):
        return [x[0] - y[0], x[1] - y[1], x[2] - y[2]]

    def dot(x, y):
        return x[0] * y[0] + x[1] * y[1] + x[2] * y[2]

    def cross(x, y):
        return [x[1] * y[2] - x[2] * y[1], x[2] * y[0] - x[0] * y[2], x[0] * y[1] - x[1] * y[0]]

    q, a, b, c = comp(p), comp(tri[..., 0, :]), comp(tri[..., 1, :]), comp(tri[..., 2, :])
    ab, ac, bc = sub(b, a), sub(c, a), sub(c, b)
    normal = cross(ab, ac)
    n2 = dot(normal, normal)
    qa, qb = sub(q, a), sub(q, b)

    def to_segment(w, d):
        t = np.clip(dot(w, d) / np.maximum(dot(d, d), 1e-300), 0.0, 1.0)
        r = [w[0] - t * d[0], w[1] - t * d[1], w[2] - t * d[2]]
        return dot(r, r)

    edge = np.minimum(np.minimum(to_segment(qa, ab), to_segment(qa, ac)), to_segment(qb, bc))
    inside = (
        (dot(qa, cross(normal, ab)) >= 0)
        & (dot(qb, cross(normal, bc)) >= 0)
        & (dot(qa, cross(ac, normal)) >= 0)
        & (n2 > 0)
    )
    height = dot(qa, normal)
    plane = height * height / np.maximum(n2, 1e-300)
    return np.sqrt(np.where(inside, np.minimum(plane, edge), edge))


@dataclasses.dataclass(frozen=True)
class Part:
    """One connected part of a mesh: its triangles ``(m, 3, 3)`` (turned outward when
    ``closed``) and whether it is a closed, consistently oriented surface."""

    triangles: np.ndarray
    closed: bool


def _components(n_vertices: int, faces: np.ndarray) -> np.ndarray:
    """A component label per vertex (faces join their vertices): union by hooking roots to
    the smaller root, then pointer jumping, until nothing changes."""
    root = np.arange(n_vertices)
    u = np.concatenate([faces[:, 0], faces[:, 1]])
    v = np.concatenate([faces[:, 1], faces[:, 2]])
    while True:
        ru, rv = root[u], root[v]
        if np.array_equal(ru, rv):
            return root
        np.minimum.at(root, np.maximum(ru, rv), np.minimum(ru, rv))
        while True:
            jumped = root[root]
            if np.array_equal(jumped, root):
                break
            root = jumped


def _closed_and_oriented(faces: np.ndarray) -> bool:
    """Every directed edge used by exactly one face and its reverse by exactly one other."""
    directed = faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2)
    keys = np.unique(directed, axis=0, return_counts=True)
    if np.any(keys[1] != 1):
        return False
    forward = {tuple(e) for e in keys[0].tolist()}
    return all((b, a) in forward for a, b in forward)


def parts(vertices: np.ndarray, faces: np.ndarray) -> list[Part]:
    """The connected parts of the mesh ``(vertices (v, 3), faces (f, 3))`` (module
    docstring); vertices at the same coordinates count as one. A face with a repeated vertex
    (a segment or a point) stays in its part's triangles but plays no part in closedness."""
    vertices = np.asarray(vertices, dtype=float)
    unique, index = np.unique(vertices, axis=0, return_inverse=True)
    faces = index.reshape(-1)[np.asarray(faces, dtype=np.int64)]
    proper = (faces[:, 0] != faces[:, 1]) & (faces[:, 1] != faces[:, 2])
    proper &= faces[:, 0] != faces[:, 2]
    label = _components(len(unique), faces)[faces[:, 0]]
    out = []
    for part in np.unique(label):
        mine = label == part
        own = faces[mine & proper]
        closed = bool(len(own)) and _closed_and_oriented(own)
        tri = unique[faces[mine]]
        if closed:
            # divergence theorem: 6 V = sum a . (b x c); negative means inward faces
            volume = np.einsum("ij,ij->i", tri[:, 0], np.cross(tri[:, 1], tri[:, 2])).sum()
            if volume < 0:
                tri = tri[:, ::-1]
        out.append(Part(tri, closed))
    return out


def near_pairs(
    query: np.ndarray,
    reach: np.ndarray,
    centre: np.ndarray,
    radius: np.ndarray,
    per_cell: float = 12.0,
) -> tuple[np.ndarray, np.ndarray]:
    """Every ``(i, j)`` with ``|query_i - centre_j| <= reach_i + radius_j``, ordered by ``i``.

    The items are binned in a uniform grid (about 32 per occupied cell); each cell gets the
    ball about its middle that holds its items' balls, and a query is tested exactly against
    the items of the cells whose ball its own ball meets."""
    query, centre = np.asarray(query, float), np.asarray(centre, float)
    reach, radius = np.asarray(reach, float), np.asarray(radius, float)
    empty = np.zeros(0, np.int64)
    if len(query) == 0 or len(centre) == 0:
        return empty, empty
    lo = centre.min(axis=0)
    extent = float((centre.max(axis=0) - lo).max())
    cell = extent / max(1.0, np.sqrt(len(centre) / per_cell)) if extent > 0 else 1.0
    ijk = np.floor((centre - lo) / cell).astype(np.int64)
    key = (ijk[:, 0] * (ijk[:, 1].max() + 1) + ijk[:, 1]) * (ijk[:, 2].max() + 1) + ijk[:, 2]
    order = np.argsort(key, kind="stable")
    cells, start, count = np.unique(key[order], return_index=True, return_counts=True)
    middle = lo + (ijk[order[start]] + 0.5) * cell
    centre, radius = centre[order], radius[order]  # items by cell: a cell is a range
    owner = np.repeat(np.arange(len(cells)), count)
    spread = np.linalg.norm(centre - middle[owner], axis=1) + radius
    hold = np.maximum.reduceat(spread, start)
    rows, items = [], []
    step = max(1, _CHUNK // len(cells))
    for s in range(0, len(query), step):
        q = query[s : s + step]
        gap2 = sum((q[:, k, None] - middle[None, :, k]) ** 2 for k in range(3))
        qi, ci = np.nonzero(gap2 <= (reach[s : s + step, None] + hold[None]) ** 2)
        n = count[ci]
        qi = np.repeat(qi + s, n)
        mi = np.repeat(start[ci] - (np.cumsum(n) - n), n) + np.arange(n.sum())
        d = query[qi] - centre[mi]
        keep = np.einsum("ij,ij->i", d, d) <= (reach[qi] + radius[mi]) ** 2
        rows.append(qi[keep])
        items.append(order[mi[keep]])
    return np.concatenate(rows), np.concatenate(items)


def nearest_distance(points: np.ndarray, bound: np.ndarray, tri: np.ndarray) -> np.ndarray:
    """The exact distance from each point ``(n, 3)`` to the triangles ``(m, 3, 3)``, given
    an upper bound per point (some triangle lies within it); a triangle farther than the bound
    from every point of its bounding ball is not measured."""
    middle = tri.mean(axis=1)
    radius = np.linalg.norm(tri - middle[:, None], axis=-1).max(axis=1)
    qi, ti = near_pairs(points, bound, middle, radius)
    out = np.full(len(points), np.inf)
    if len(qi):
        d = point_triangle_distance(points[qi], tri[ti])
        first = np.flatnonzero(np.diff(qi, prepend=-1))  # the pairs come ordered by point
        out[qi[first]] = np.minimum.reduceat(d, first)
    return out
