"""How fast any point of the robot's body moves per unit of joint motion (conservative
advancement [Schwarzer, Saha & Latombe 2005]).

For a joint step ``dq`` a point ``c`` attached to link ``k`` moves at most::

    |dc| <= sum_j r_jk |dq_j|

with ``r_jk`` an upper bound of ``|dc / dq_j|`` over every configuration: the point's distance
from joint ``j``'s axis for a revolute joint, the axis' speed (1 for a unit prismatic joint).
A primitive's surface moves no faster than its centre (its radius is fixed), so a straight
edge ``q(t) = a + t dq``, ``t in [0, 1]``, whose state ``t_i`` has clearance ``d_i`` is free for
``|t - t_i| < d_i / B`` with ``B = max_k sum_j r_jk |dq_j|``: the edge cannot slip through an
obstacle between states whose balls overlap. Two links checked against each other approach
at most as fast as the joints that move one and not the other move them (a joint moving both
turns them rigidly), so a self pair ``(k, l)`` gets the row ``r_k (m_k & ~m_l) + r_l (m_l &
~m_k)`` (``m_k`` the joints that move link ``k``), and ``B`` is the largest row times
``|dq|``.

The second derivative bounds how far a point strays from the chord of a short piece of an
edge (``swept``). For joints ``j`` and ``k`` both moving ``c``, ``j`` before ``k`` on its
chain (``k``'s links a subset of ``j``'s) and ``w_j`` the rotation rate of ``j``'s twist (0 for
a prismatic joint)::

    |d2c / dq_j dq_k| = |w_j u_j x dc/dq_k| <= w_j r_kc

(``j`` turns ``k``'s axis and ``c`` about it rigidly; a prismatic ``j`` changes neither, and
a later joint's derivative along ``q_k``'s is the same term). So along ``q(t) = a + t dq``::

    |c''(t)| <= |dq|^T M_k |dq|,   M_k[j, l] = w_first r_second,  M_k[l, j] = M_k[j, l]

and over a piece ``[t0, t1]`` the point stays within ``|c''| (t1 - t0)^2 / 8`` of the chord
from ``c(t0)`` to ``c(t1)`` (the interpolation error of a function whose second derivative is
bounded). ``MotionBound.curvature`` holds ``M_k`` per primitive for a proved tree; a sampled
bound has none.

The bounds are read through the robot protocol alone (``link_poses`` and its Jacobian, the
body's primitives, ``joint_types``, ``joint_limits``): at a few configurations each joint's
twist ``dT_l/dq_j T_l^-1`` is measured on every link. When every joint moves a set of links
rigidly with one twist, and these sets nest (a kinematic tree of revolute and prismatic
joints: URDF chains, the analytic arms, the SCARA), the bound is proved: walking from a
primitive's centre ``c`` up its joints, ``b_m`` the foot of ``c`` on the last axis, ``b_{i}``
the foot of ``b_{i+1}`` on the axis before, every ``|b_{i+1} - b_i|`` is constant (both points
fixed in the link between the two joints), so ``r_{j_i} = |c - b_m| + sum_{l > i} |b_{l+1} -
b_l|`` bounds the distance from axis ``j_i`` in every configuration; a prismatic joint adds its
stroke. Otherwise (a closed chain such as the Delta, whose rods and platform move with every
actuator at rates that grow without bound near its singularities) the bound is the largest
``|dc/dq_j|`` over ``SAMPLES`` configurations within the limits times ``SAFETY``, and
``MotionBound.proved`` is False: such a robot's certified edges are as good as that sample.
"""

from __future__ import annotations

import dataclasses
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from jax import Array

from .._execute import Kernel
from .._validate import on_device
from . import collider
from .space import joint_space

__all__ = [
    "MotionBound",
    "curvature_bound",
    "motion_bound",
    "part_speeds",
    "speed_bound",
    "speed_rows",
]

SAMPLES = 4096  # configurations of the sampled bound (closed chains)
SAFETY = 1.5  # factor on the sampled bound
_PROBES = 3  # configurations at which the tree structure is verified


@jax.tree_util.register_dataclass
@dataclasses.dataclass(frozen=True)
class MotionBound:
    """How far the body moves along a joint step ``dq`` (robot units): primitive ``p`` at
    most ``prims[p] . |dq|``, the two links of self pair ``k`` approach by at most
    ``pairs[k] . |dq|``.

    Attributes:
        prims: ``(ns + nc, n)``, one row per body primitive (spheres, then capsules): its
            link's row.
        pairs: ``(len(link_pairs), n)``, one row per checked self link pair.
        proved: static, True when the rows are proved bounds (a kinematic tree), False when
            sampled (module docstring).
        curvature: ``(ns + nc, n, n)``, per primitive its link's ``M_k``: ``|c''| <= |dq|^T
            M_k |dq|`` along a straight edge (module docstring); None for a sampled bound.
    """

    prims: Array
    pairs: Array
    proved: bool = dataclasses.field(metadata=dict(static=True), default=True)
    curvature: Array | None = None

    @property
    def rows(self) -> Array:
        """Every row, primitives then pairs ``(R, n)``."""
        return jnp.concatenate([self.prims, self.pairs])

    def astype(self, dtype: Any) -> MotionBound:
        curvature = None if self.curvature is None else on_device(self.curvature, dtype)
        return MotionBound(
            on_device(self.prims, dtype), on_device(self.pairs, dtype), self.proved, curvature
        )


def speed_bound(bound: MotionBound, dq: Array) -> Array:
    """``max_r rows[r] . |dq|``, the bound of every point, for steps ``dq (..., n)``."""
    rows = bound.rows.astype(dq.dtype)
    return jnp.max(jnp.einsum("...j,rj->...r", jnp.abs(dq), rows), axis=-1)


def part_speeds(bound: MotionBound, dq: Array) -> tuple[Array, Array]:
    """Per primitive ``(..., ns + nc)`` and per self pair ``(..., P)`` bounds of a step."""
    a = jnp.abs(dq)
    prims = jnp.einsum("...j,rj->...r", a, bound.prims.astype(dq.dtype))
    pairs = jnp.einsum("...j,rj->...r", a, bound.pairs.astype(dq.dtype))
    return prims, pairs


def curvature_bound(curvature: Array, dq: Array) -> Array:
    """Per primitive ``(..., ns + nc)``: ``|dq|^T M |dq|`` (``MotionBound.curvature``), a
    bound of the second derivative of its points along ``a + t dq``, for steps ``dq (...,
    n)``."""
    a = jnp.abs(dq)
    return jnp.einsum("...j,pjk,...k->...p", a, curvature.astype(dq.dtype), a)


def speed_rows(bound: MotionBound, body: Any) -> np.ndarray:
    """The rows ``(L + Q, n)`` of ``collider.clearances``' distances: each link with geometry
    (``collider.link_groups``: its primitives share its row), then each self pair (host
    side, a NumPy array)."""
    first = collider.link_groups(body)[:, 0]
    return np.concatenate([np.asarray(bound.prims)[first], np.asarray(bound.pairs)])


def _twists(robot: Any, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per configuration ``q (K, n)`` the link poses ``(K, L, 4, 4)`` and twists ``(K, L, n,
    6)`` (``omega, v`` of ``dT/dq_j T^-1``), in one compiled program."""

    def poses_and_jacobian(x: Array) -> tuple[Array, Array]:
        return robot.link_poses(x), jax.jacfwd(robot.link_poses)(x)

    q_host = np.asarray(q, jnp.result_type(float))  # float64 when x64 is on
    poses, jac = Kernel(jax.vmap(poses_and_jacobian))(q_host)  # (K, L, 4, 4), (K, L, 4, 4, n)
    poses, jac = np.asarray(poses, float), np.asarray(jac, float)
    inv = np.linalg.inv(poses)
    xi = np.einsum("klijn,kljm->klnim", jac, inv)
    omega = np.stack([xi[..., 2, 1], xi[..., 0, 2], xi[..., 1, 0]], -1)
    v = xi[..., :3, 3]
    return poses, np.concatenate([omega, v], -1)


def _centres(body: Any) -> tuple[np.ndarray, np.ndarray]:
    """Every primitive's points in its link's frame ``(P, 3)`` and link: a sphere's centre, a
    capsule's two ends (a point's speed about an axis, its distance from it, is convex in the
    point, so the ends bound the whole segment)."""
    points = [np.asarray(body.sphere_center, float).reshape(-1, 3)]
    links = [np.asarray(body.sphere_link, int)]
    if body.num_capsules:
        points += [np.asarray(body.capsule_a, float).reshape(-1, 3)]
        points += [np.asarray(body.capsule_b, float).reshape(-1, 3)]
        links += [np.asarray(body.capsule_link, int)] * 2
    return np.concatenate(points), np.concatenate(links)


def _tree_rows(robot, body, poses, twists, space, scale) -> tuple[np.ndarray, ...] | None:
    """Per-link proved rows ``(L, n)``, which joints move which link ``(L, n)`` and the
    curvature matrices ``M_k`` ``(L, n, n)`` (module docstring), or None when the joints are
    not a tree of rigid revolute/prismatic motions at this configuration."""
    n_links, n = twists.shape[:2]
    size = np.linalg.norm(twists, axis=-1)
    moves = size > 1e-7 * (1.0 + scale)  # (L, n)
    types = robot.joint_types
    # per joint (kind, speed, unit axis or None, a point on the axis or the stroke)
    axes: list[tuple[str, float, Any, Any]] = []
    for j in range(n):
        links = np.flatnonzero(moves[:, j])
        if not links.size:
            axes.append(("-", 0.0, None, None))  # moves no link: in no chain
            continue
        xi = twists[links, j]
        if np.max(np.abs(xi - xi[0])) > 1e-6 * (1.0 + np.max(np.abs(xi[0]))):
            return None  # not one rigid motion of its links (a closed chain, a mimic joint)
        omega, v = xi[0, :3], xi[0, 3:]
        if types[j] == "R":
            w = np.linalg.norm(omega)
            if w < 1e-9 or abs(np.dot(omega, v)) > 1e-6 * w * (np.linalg.norm(v) + scale):
                return None  # not a pure rotation
            axes.append(("R", float(w), omega / w, np.cross(omega, v) / (w * w)))
        else:
            if np.linalg.norm(omega) > 1e-9:
                return None
            stroke = float(space.upper[j] - space.lower[j])
            axes.append(("P", float(np.linalg.norm(v)), None, stroke))
    sets = [frozenset(np.flatnonzero(moves[:, j]).tolist()) for j in range(n)]
    for i in range(n):
        for j in range(n):
            if sets[i] & sets[j] and not (sets[i] <= sets[j] or sets[j] <= sets[i]):
                return None  # the moved sets do not nest
    points, links = _centres(body)
    world_points = np.einsum("pij,pj->pi", poses[links, :3, :3], points) + poses[links, :3, 3]
    rows = np.zeros((n_links, n))
    for c, link in zip(world_points, links, strict=True):
        chain = [j for j in range(n) if moves[link, j]]
        chain.sort(key=lambda j: -len(sets[j]))  # root first
        point, acc = c, 0.0
        for j in reversed(chain):
            kind, speed, direction, extra = axes[j]
            if kind == "R":
                foot = extra + direction * np.dot(point - extra, direction)
                acc += float(np.linalg.norm(point - foot))
                rows[link, j] = max(rows[link, j], speed * acc)
                point = foot
            else:
                rows[link, j] = max(rows[link, j], speed)
                acc += speed * extra  # the stroke moves every point after it
    rate = np.array([speed if kind == "R" else 0.0 for kind, speed, _, _ in axes])
    curvature = np.zeros((n_links, n, n))
    for j in range(n):
        for k in range(n):
            if sets[k] and sets[k] <= sets[j]:  # j before k (or j = k) on k's chain
                term = (moves[:, j] & moves[:, k]) * rate[j] * rows[:, k]
                curvature[:, j, k] = np.maximum(curvature[:, j, k], term)
    return rows, moves, np.maximum(curvature, np.swapaxes(curvature, 1, 2))


def _pair_rows(link_rows: np.ndarray, moves: np.ndarray, pairs: Any, proved: bool) -> np.ndarray:
    out = []
    for k, l in pairs:
        if proved:
            own_k = moves[k] & ~moves[l]
            own_l = moves[l] & ~moves[k]
            out.append(link_rows[k] * own_k + link_rows[l] * own_l)
        else:
            out.append(link_rows[k] + link_rows[l])
    return np.asarray(out).reshape(-1, link_rows.shape[1])


def _proved_rows(
    robot: Any, body: Any, space: Any, scale: float, probes: np.ndarray
) -> tuple[np.ndarray, ...] | None:
    """``_tree_rows``' largest rows, moved links and curvature over the probe
    configurations, or None when one of them is not a tree of rigid motions."""
    found: tuple[np.ndarray, ...] | None = None
    for poses, twists in zip(*_twists(robot, probes), strict=True):
        one = _tree_rows(robot, body, poses, twists, space, scale)
        if one is None:
            return None
        rows, moves, curvature = one
        if found is not None:
            rows = np.maximum(rows, found[0])
            moves = moves | found[1]
            curvature = np.maximum(curvature, found[2])
        found = (rows, moves, curvature)
    return found


def motion_bound(robot: Any, body: Any, link_pairs: Any) -> MotionBound:
    """Host side: the ``MotionBound`` of a robot of the protocol (module docstring)."""
    space = joint_space(robot)
    scale = float(np.asarray(robot.length_scale()))
    rng = np.random.default_rng(0)
    lower, upper = np.asarray(space.lower), np.asarray(space.upper)
    probes = lower + rng.uniform(size=(_PROBES, len(lower))) * (upper - lower)
    found = _proved_rows(robot, body, space, scale, probes)
    proved = found is not None and bool(np.all(np.isfinite(found[0])))
    curvature = None
    if found is not None and proved:
        rows, moves, curvature = found
    else:
        rows, moves = _sampled_rows(robot, body, space)
    pair_rows = _pair_rows(rows, moves, link_pairs, proved)
    prim_link = np.asarray(tuple(body.sphere_link) + tuple(body.capsule_link), int)
    n = rows.shape[1]
    return MotionBound(
        on_device(rows[prim_link].reshape(-1, n)),
        on_device(pair_rows),
        proved,
        None if curvature is None else on_device(curvature[prim_link].reshape(-1, n, n)),
    )


def _sampled_rows(robot: Any, body: Any, space: Any) -> tuple[np.ndarray, np.ndarray]:
    """The largest ``|dc/dq_j|`` per link over sampled configurations, times ``SAFETY``."""
    points, links = _centres(body)
    n = len(space.lower)
    q = space.lower + np.random.default_rng(1).uniform(size=(SAMPLES, n)) * (
        space.upper - space.lower
    )
    dtype = jnp.result_type(float)  # float64 when x64 is on

    def placed(q):
        poses = robot.link_poses(q)
        return jnp.einsum("pij,pj->pi", poses[links, :3, :3], points) + poses[links, :3, 3]

    jac = Kernel(jax.vmap(jax.jacfwd(placed)))(jnp.asarray(q, dtype))  # (S, P, 3, n)
    ok = np.asarray(jax.vmap(robot.placeable)(jnp.asarray(q, dtype)), bool)
    speed = np.linalg.norm(np.asarray(jac, float), axis=-2)[ok]  # (S', P, n)
    speed = np.where(np.isfinite(speed), speed, np.inf)
    n_links = len(body.links)
    rows = np.zeros((n_links, n))
    for p, link in enumerate(links):
        rows[link] = np.maximum(rows[link], SAFETY * np.max(speed[:, p], axis=0, initial=0.0))
    return rows, rows > 0
