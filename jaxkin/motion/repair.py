"""Certified mode's repair of found paths: an edge that cannot be certified is planned again.

A path found with the discrete check (``planner``: the search at the resolution) has every
edge certified afterwards. An edge that fails (it grazes an obstacle between two of its
states, or passes closer than the clearance balls can resolve) becomes a problem of its own,
from its first waypoint to its second, searched with certified edges on a smaller budget; its
path then replaces the edge (``splice``): the expensive check spent only on the edges of a path
found with a cheaper one, as Lazy PRM does [Bohlin & Kavraki 2000]. Host side, NumPy,
vectorised over the problems.
"""

from __future__ import annotations

import numpy as np

__all__ = ["bad_edges", "splice"]


def bad_edges(
    count: np.ndarray, edge_good: np.ndarray, solved: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """The edges to plan again: ``(problem, edge)`` ``(m,)`` each, in order of problem then
    edge, for every solved problem's edge ``k < count - 1`` not good (``edge_good (B, P -
    1)``)."""
    live = np.arange(edge_good.shape[1])[None, :] < (count - 1)[:, None]
    problem, edge = np.nonzero(~edge_good & live & solved[:, None])
    return problem, edge


def splice(
    path: np.ndarray,
    count: np.ndarray,
    problem: np.ndarray,
    edge: np.ndarray,
    sub_path: np.ndarray,
    sub_count: np.ndarray,
    sub_solved: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Each path ``(B, P, n)`` with its edges ``(problem, edge)`` (``bad_edges``) replaced by
    the paths found between their ends (``sub_path (m, Q, n)``, ``sub_count (m,)``: from the
    edge's first waypoint to its second). Returns the paths, their counts and ``failed (B,)``:
    a problem with an edge whose path was not found, or whose spliced path would not fit in
    ``P`` waypoints (its path and count are then left as they were)."""
    b, p, n = path.shape
    failed = np.zeros(b, bool)
    failed[problem[~sub_solved]] = True
    # the waypoints each edge's path puts between the edge's ends
    inner = np.zeros((b, p), np.int64)
    inner[problem, edge] = np.where(sub_solved, np.maximum(sub_count - 2, 0), 0)
    live = np.arange(p)[None, :] < count[:, None]
    emitted = np.where(live, 1 + inner, 0)
    new_count = emitted.sum(1)
    failed |= new_count > p
    touched = np.zeros(b, bool)
    touched[problem] = True
    take = touched & ~failed
    first = np.cumsum(emitted, 1) - emitted  # where waypoint j lands
    out = path.copy()
    rows, cols = np.nonzero(live & take[:, None])
    out[rows, first[rows, cols]] = path[rows, cols]
    # each solved edge path's inner waypoints after its first waypoint
    q = sub_path.shape[1]
    own = sub_solved & take[problem]
    m_idx, j_idx = np.nonzero(own[:, None] & (np.arange(1, q)[None, :] < sub_count[:, None] - 1))
    landing = first[problem[m_idx], edge[m_idx]] + j_idx + 1
    out[problem[m_idx], landing] = sub_path[m_idx, j_idx + 1]
    new_count = np.where(take, new_count, count).astype(count.dtype)
    last = out[np.arange(b), np.maximum(new_count - 1, 0)]
    tail = (np.arange(p)[None, :] >= new_count[:, None]) & take[:, None]
    return np.where(tail[..., None], last[:, None, :], out), new_count, failed
