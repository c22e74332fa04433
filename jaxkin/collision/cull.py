"""Bounding spheres checked first: the verdict's robot spheres against the world, culled.

Off by default (``collides_kernel(..., cull=True)`` turns it on): on the CPU the verdict's
blocks of every sphere-obstacle pair, reduced by halving, are faster than the compaction,
gathers and scatters below (``docs/performance.md``).

The robot's spheres are grouped, link by link, into groups of at most ``GROUP`` spheres
(consecutive indices of one link: a static grouping). Each group has a bounding sphere in its
link's frame, computed from the body's arrays (a new radius does not recompile): the centre
``g`` the middle of the spheres' bounding box, the radius ``R = max_s (|c_s - g| + r_s)``,
which contains every sphere of the group. A coarse pass tests each placed bounding sphere
against every obstacle; the (group, configuration) candidates it flags are compacted to a
fixed capacity (a prefix sum and a scatter), their spheres gathered, tested against every
obstacle with the same tests as the full pass, and each candidate's result scattered back to
its configuration. A chunk with more candidates than the capacity runs the full pass instead
(``lax.cond``), so the verdict never depends on the capacity.

Why no collision is lost. Each test of the verdict is monotone in the sphere: a point's
distance to a sphere, capsule, box or half-space is 1-Lipschitz, so for a sphere ``(c, r)``
inside a bounding sphere ``(g, R)``, ``d(g) - R <= d(c) - r``. The fine test flags a squared
excess ``d^2 - (r + r' + m)^2 <= slack`` (``collision.verdict``), i.e. ``d <= r + r' + m +
sqrt(slack)``, or a linear one ``<= tol``; the coarse test takes ``R + delta`` with ``delta
= sqrt(slack) + 2 tol`` (each placed centre rounds by less than ``tol``) and the same
comparison, so it flags every group whose spheres the fine test can flag. The candidates'
tests are the full pass's own, on the same placed rows: the culled verdict equals the full one.

Only the world pass is culled: the self pairs culled the same way (group pairs first) were
slower on the CPU than the full pass over the 700 sphere pairs (``docs/performance.md``).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable

import jax
import jax.numpy as jnp
import numpy as np
from jax import Array

__all__ = ["GROUP", "WORLD_CAPACITY", "Groups", "bounding_spheres", "cull_world", "sphere_groups"]

# Spheres per bounding sphere at most (the Panda's covers: 5 per link, 10 per finger)
GROUP = 5
# Capacity of the compacted (group, configuration) candidates, as a fraction of a chunk's
# groups x configurations; a chunk with more runs the full pass (the benchmark's scene: 34 %)
WORLD_CAPACITY = 0.4


@dataclasses.dataclass(frozen=True)
class Groups:
    """The static grouping of a body's spheres.

    Attributes:
        members: ``(n_groups, size)`` sphere indices per group, a short group padded by
            repeating its first sphere (a repeated sphere repeats a test, never changes it).
        link: the link of each group.
    """

    members: tuple[tuple[int, ...], ...]
    link: tuple[int, ...]


def sphere_groups(sphere_link: tuple[int, ...]) -> Groups:
    """Host side: the spheres of each link in runs of at most ``GROUP`` (static)."""
    link = np.asarray(sphere_link, dtype=np.int64)
    members, of_link = [], []
    for k in dict.fromkeys(link.tolist()):
        own = np.flatnonzero(link == k)
        for part in np.array_split(own, math.ceil(len(own) / GROUP)):
            members.append([int(i) for i in part])
            of_link.append(int(k))
    size = max((len(m) for m in members), default=0)
    return Groups(tuple(tuple(m + [m[0]] * (size - len(m))) for m in members), tuple(of_link))


def bounding_spheres(groups: Groups, center: Array, radius: Array) -> tuple[Array, Array]:
    """Per group, a sphere containing its spheres (link frame): centres ``(n_groups, 3)``
    (the middle of the spheres' bounding box) and radii ``(n_groups,)`` (``max_s |c_s - g| +
    r_s``, widened by ``8 eps`` relative for its own rounding)."""
    idx = np.asarray(groups.members, dtype=np.int32)
    c, r = center[idx], radius[idx]  # (n_groups, size, 3), (n_groups, size)
    g = 0.5 * (jnp.min(c - r[..., None], axis=1) + jnp.max(c + r[..., None], axis=1))
    reach = jnp.sqrt(jnp.sum((c - g[:, None]) ** 2, axis=-1)) + r
    eps = jnp.finfo(center.dtype).eps
    return g, jnp.max(reach, axis=1) * (1.0 + 8.0 * eps)


def _compact(flags: Array, cap: int) -> tuple[Array, Array]:
    """The first ``cap`` flat indices of ``flags`` that are set (padded with 0), and which of
    them are real: a prefix sum by ``associative_scan`` and a scatter (on the CPU,
    ``jnp.nonzero(..., size=cap)`` took about twice as long)."""
    flat = flags.ravel()
    position = jax.lax.associative_scan(jnp.add, flat.astype(jnp.int32))
    target = jnp.where(flat, position - 1, cap)
    source = jnp.arange(flat.shape[0], dtype=jnp.int32)
    idx = jnp.zeros((cap,), jnp.int32).at[target].set(source, mode="drop")
    return idx, jnp.arange(cap) < position[-1]


def cull_world(
    kinds: list[tuple[Callable, bool, tuple[Array, ...]]],
    groups: Groups,
    spheres: Array,
    radius: Array,
    centers: Array,
    reach: Array,
    margin: Array,
    slack: Array,
    tol: Array,
    full: Callable[[], Array],
) -> Array:
    """Robot spheres against the obstacles, through the groups' bounding spheres first.

    Args:
        kinds: per obstacle kind ``(test, squared, arrays (m, ...))``: ``test(x, r, margin,
            *obstacle)`` the excess of rows ``x`` (three arrays) of radii ``r`` against one
            obstacle (its arrays' entries), squared (flags ``<= slack``) or linear (``<= tol``).
        groups: the grouping; ``spheres (3, ns, C)`` and ``radius (ns,)`` the placed
            spheres; ``centers (3, n_groups, C)`` the placed bounding spheres and ``reach
            (n_groups, C)`` their radii widened by ``delta`` (module docstring).
        slack, tol: ``(C,)`` per configuration.
        full: the full pass, ``(C,)`` flags (a chunk past the capacity).

    Returns:
        ``(C,)``: the configurations with a flagged sphere-obstacle pair.
    """
    size = spheres.shape[-1]
    n_groups = len(groups.members)
    members = jnp.asarray(np.asarray(groups.members, dtype=np.int32).T)  # (size, n_groups)
    x = [centers[i] for i in range(3)]
    flags = None
    for test, squared, arrays in kinds:
        bound = slack if squared else tol
        for j in range(arrays[0].shape[0]):
            near = test(x, reach, margin, *(a[j] for a in arrays)) <= bound
            flags = near if flags is None else flags | near  # (n_groups, C)
    cap = max(1, math.ceil(n_groups * size * WORLD_CAPACITY))

    def fine() -> Array:
        idx, real = _compact(flags, cap)
        g, c = idx // size, idx % size
        s = members[:, g]  # (size, K)
        rows = [spheres[i][s, c[None, :]] for i in range(3)]
        r = radius[s]
        sq = lin = None
        for test, squared, arrays in kinds:
            for j in range(arrays[0].shape[0]):
                e = test(rows, r, margin, *(a[j] for a in arrays))
                if squared:
                    sq = e if sq is None else jnp.minimum(sq, e)
                else:
                    lin = e if lin is None else jnp.minimum(lin, e)
        hit = real
        near = jnp.zeros(c.shape, bool)
        if sq is not None:
            near = near | (jnp.min(sq, axis=0) <= slack[c])
        if lin is not None:
            near = near | (jnp.min(lin, axis=0) <= tol[c])
        hit = (hit & near).astype(jnp.int32)
        return jnp.zeros((size,), jnp.int32).at[c].max(hit, mode="drop") > 0

    count = jnp.sum(flags, dtype=jnp.int32)
    return jax.lax.cond(count <= cap, fine, full)
