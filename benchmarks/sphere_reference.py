"""An independent sphere-model collision checker: one fused Numba loop per configuration.

Written from the published approach of the sphere-model checkers ([Thomason, Kingston &
Kavraki 2024], VAMP; [Sundaralingam et al. 2023], cuRobo), not from jaxkin's kernels, to time
jaxkin's ``collision.collides`` against (benchmarks/test_collision.py, test_goals.py). Per
configuration ``q``, in one compiled loop (``prange`` over blocks of configurations):

1. forward kinematics from the URDF's joints, read by this module's own parser
   (``read_urdf_joints``: ``<origin xyz rpy>``, ``<axis>``, type, parent and child), link by
   link in tree order::

       T_child = T_parent  T_origin  M(q_j),   M = Rot(axis, q_j) (revolute, continuous),
                                               Trans(q_j axis) (prismatic), I (fixed)

   with ``Rot(a, t) = I + sin t [a]x + (1 - cos t) [a]x^2`` (Rodrigues) and the origin's
   rotation ``Rz(yaw) Ry(pitch) Rx(roll)`` (URDF's fixed-axis roll-pitch-yaw). Joints beyond
   the configuration's joints (the Panda's fingers) are held at a fixed value (0: closed);
2. every sphere placed, ``x = R_link c + t_link``;
3. every sphere against every obstacle, obstacle by obstacle, stopping at the first obstacle
   hit: sphere-sphere
   ``|x - o|^2 <= R^2`` with ``R = r + r_o + margin`` (never when ``R < 0``); sphere-oriented
   box with ``u = B^T (x - c)`` (``B``: the box axes as columns), ``e_i = |u_i| - h_i``::

       R >= 0:  sum_i max(e_i, 0)^2 <= R^2      (clamped point within R of the centre)
       R <  0:  max_i e_i <= R                   (centre at least -R deep inside)

   with ``R = r + margin``: exactly ``signed distance - r <= margin``;
4. every self sphere pair, ``|x_i - x_j|^2 <= (r_i + r_j + margin)^2``, in runs of one
   sphere against contiguous ones (the pairs of a link pair), stopping at the first run hit.

A configuration collides where some test holds: its clearance is ``<= margin``, the rule of
jaxkin's ``check``/``collides``. The radii sums ``R`` and their squares are formed once on
the host in the working dtype (as the loop would form them). The input is data only: the
spheres (centre, radius, link), the obstacles and the self pairs are arrays; the caller
takes them from jaxkin's public objects (``Body``, ``World``, ``SelfPairs``) so both
checkers see the same model. No bounding spheres per link
(VAMP's first-level test) and no SIMD across configurations: each configuration is one loop
with early exits, each obstacle's test (and each run of self pairs) a branch-free pass over
the spheres that LLVM vectorises.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from dataclasses import dataclass, fields
from pathlib import Path

import numpy as np

__all__ = ["Joint", "SphereModel", "make_checker", "read_urdf_joints"]

# Configurations per block of the parallel loop: each block allocates its scratch once
BLOCK = 256

REVOLUTE, PRISMATIC, FIXED = 0, 1, 2
_KINDS = {"revolute": REVOLUTE, "continuous": REVOLUTE, "prismatic": PRISMATIC, "fixed": FIXED}


@dataclass(frozen=True)
class Joint:
    """One URDF joint: ``origin`` ``(4, 4)`` parent link <- joint frame, unit ``axis`` in the
    joint frame."""

    name: str
    kind: str
    parent: str
    child: str
    origin: np.ndarray
    axis: np.ndarray


def _rpy(roll: float, pitch: float, yaw: float) -> np.ndarray:
    """URDF's rotation ``Rz(yaw) Ry(pitch) Rx(roll)``."""
    cr, sr, cp, sp, cy, sy = (f(a) for a in (roll, pitch, yaw) for f in (math.cos, math.sin))
    rx = np.array([[1, 0, 0], [0, cr, -sr], [0, sr, cr]])
    ry = np.array([[cp, 0, sp], [0, 1, 0], [-sp, 0, cp]])
    rz = np.array([[cy, -sy, 0], [sy, cy, 0], [0, 0, 1]])
    return rz @ ry @ rx


def _floats(element, attribute: str, default: str) -> list[float]:
    text = default if element is None else element.get(attribute, default)
    return [float(v) for v in text.split()]


def read_urdf_joints(path: str | Path) -> list[Joint]:
    """The joints of a URDF file in tree order (every parent before its children)."""
    root = ET.parse(path).getroot()
    joints = []
    for element in root.findall("joint"):
        origin = element.find("origin")
        pose = np.eye(4)
        pose[:3, :3] = _rpy(*_floats(origin, "rpy", "0 0 0"))
        pose[:3, 3] = _floats(origin, "xyz", "0 0 0")
        axis = np.asarray(_floats(element.find("axis"), "xyz", "1 0 0"))
        kind = element.get("type")
        if kind not in _KINDS:
            raise ValueError(f"path: joint {element.get('name')!r} of type {kind!r} is not handled")
        joints.append(
            Joint(
                element.get("name"),
                kind,
                element.find("parent").get("link"),
                element.find("child").get("link"),
                pose,
                axis / np.linalg.norm(axis),
            )
        )
    ordered, placed = [], {j.parent for j in joints} - {j.child for j in joints}
    while len(ordered) < len(joints):
        ready = [j for j in joints if j.parent in placed and j.child not in placed]
        if not ready:
            raise ValueError("path: the URDF's joints do not form a tree")
        ordered += ready
        placed |= {j.child for j in ready}
    return ordered


@dataclass(frozen=True)
class SphereModel:
    """The arrays the loop reads, in one dtype (``arrays()`` in the kernel's argument order).

    Joints: ``joint_parent``, ``joint_child`` (link indices), ``joint_kind``, ``joint_q``
    (column of ``q``, or -1 for a joint held at ``joint_value``), ``joint_rot (nj, 3, 3)``,
    ``joint_pos (nj, 3)``, ``joint_k``, ``joint_k2 (nj, 3, 3)`` (``[a]x`` and ``[a]x^2``),
    ``joint_axis (nj, 3)``. Spheres: ``sphere_link``, ``sphere_center (ns, 3)``. Obstacle
    spheres: centres ``(no, 3)`` and ``obstacle_reach2 (no, ns)``, the squared sums ``R^2``,
    ``R = r + r_o + margin``, per robot sphere (-1 where ``R < 0``: never). Boxes:
    ``center (nb, 3)``, ``rotation (nb, 3, 3)``, ``half_extents (nb, 3)``; per robot sphere
    ``box_reach2 = R^2`` (-1 where ``R < 0``) and ``box_deep = R`` (-inf where ``R >= 0``),
    ``R = r + margin``. Self pairs as runs: sphere ``run_sphere[k]`` against the contiguous
    spheres ``run_start[k]:run_stop[k]``, whose ``(r_i + r_j + margin)^2`` (-1 where negative)
    start at ``pair_reach2[run_offset[k]]`` (the Panda's 700 pairs are 20 runs of 20-40).
    """

    joint_parent: np.ndarray
    joint_child: np.ndarray
    joint_kind: np.ndarray
    joint_q: np.ndarray
    joint_value: np.ndarray
    joint_rot: np.ndarray
    joint_pos: np.ndarray
    joint_k: np.ndarray
    joint_k2: np.ndarray
    joint_axis: np.ndarray
    n_links: int
    sphere_link: np.ndarray
    sphere_center: np.ndarray
    obstacle_center: np.ndarray
    obstacle_reach2: np.ndarray
    box_center: np.ndarray
    box_rotation: np.ndarray
    box_half: np.ndarray
    box_reach2: np.ndarray
    box_deep: np.ndarray
    run_sphere: np.ndarray
    run_start: np.ndarray
    run_stop: np.ndarray
    run_offset: np.ndarray
    pair_reach2: np.ndarray

    @classmethod
    def create(
        cls,
        joints: list[Joint],
        links: tuple[str, ...],
        dof: int,
        spheres: tuple[np.ndarray, np.ndarray, np.ndarray],
        obstacles: tuple[np.ndarray, np.ndarray],
        boxes: tuple[np.ndarray, np.ndarray, np.ndarray],
        pairs: tuple[np.ndarray, np.ndarray],
        margin: float,
        dtype,
    ) -> SphereModel:
        """The model from plain arrays.

        Args:
            joints: ``read_urdf_joints(...)``; movable joints take the columns of ``q`` in
                this order, the ones past ``dof`` are held at 0.
            links: link names; the spheres' ``link`` indices refer to them.
            dof: columns of ``q``.
            spheres: ``(link (ns,), center (ns, 3) in the link's frame, radius (ns,))``.
            obstacles: sphere obstacles ``(center (no, 3), radius (no,))``.
            boxes: ``(center (nb, 3), rotation (nb, 3, 3), half_extents (nb, 3))``.
            pairs: self sphere pairs ``(i (np,), j (np,))``, indices into ``spheres``.
            margin: a configuration collides where its clearance is ``<= margin``.
        """
        dtype = np.dtype(dtype)
        index = {name: i for i, name in enumerate(links)}
        kept = [j for j in joints if j.child in index]
        if any(j.parent not in index for j in kept):
            raise ValueError("links: a joint's parent link is missing")
        column, q_of = 0, []
        for j in kept:
            movable = j.kind != "fixed" and column < dof
            q_of.append(column if movable else -1)
            column += movable
        if column != dof:
            raise ValueError(f"dof: the URDF has {column} movable joints before the held ones")
        axis = np.array([j.axis for j in kept])
        k = np.zeros((len(kept), 3, 3))
        k[:, 0, 1], k[:, 0, 2], k[:, 1, 2] = -axis[:, 2], axis[:, 1], -axis[:, 0]
        k -= np.swapaxes(k, 1, 2)
        link, center, radius = (np.asarray(a) for a in spheres)
        o_center, o_radius = (np.asarray(a, np.float64) for a in obstacles)
        i, j = (np.asarray(a, np.int64) for a in pairs)
        order = np.lexsort((j, i))
        i, j = i[order], j[order]
        cut = np.flatnonzero((np.diff(i) != 0) | (np.diff(j) != 1)) + 1
        first, stop = np.r_[0, cut], np.r_[cut, len(i)]
        cast = lambda a: np.ascontiguousarray(a, dtype)  # noqa: E731
        # radius sums and squares formed in the working dtype, as the loop would form them
        r, m = radius.astype(dtype), dtype.type(margin)
        squared = lambda R: np.where(R >= 0, R * R, dtype.type(-1))  # noqa: E731
        o_reach = o_radius.astype(dtype)[:, None] + r[None, :] + m
        b_reach = r + m
        return cls(
            np.array([index[j.parent] for j in kept], np.int64),
            np.array([index[j.child] for j in kept], np.int64),
            np.array([_KINDS[j.kind] for j in kept], np.int64),
            np.array(q_of, np.int64),
            np.zeros(len(kept), dtype),
            cast([j.origin[:3, :3] for j in kept]),
            cast([j.origin[:3, 3] for j in kept]),
            cast(k),
            cast(k @ k),
            cast(axis),
            len(links),
            np.asarray(link, np.int64),
            cast(center),
            cast(o_center),
            cast(squared(o_reach)),
            *(cast(a) for a in boxes),
            cast(squared(b_reach)),
            cast(np.where(b_reach < 0, b_reach, dtype.type(-np.inf))),
            i[first],
            j[first],
            j[stop - 1] + 1,
            first,
            cast(squared(r[i] + r[j] + m)),
        )

    def arrays(self) -> tuple:
        """The fields in the loop's argument order."""
        return tuple(getattr(self, f.name) for f in fields(self))


def _collides(q, poses, placed, model):
    """One configuration (compiled by Numba): True at the first test that holds."""
    (
        parent,
        child,
        kind,
        q_of,
        value,
        j_rot,
        j_pos,
        j_k,
        j_k2,
        j_axis,
        _,
        s_link,
        s_center,
        o_center,
        o_reach2,
        b_center,
        b_rot,
        b_half,
        b_reach2,
        b_deep,
        run_sphere,
        run_start,
        run_stop,
        run_offset,
        p_reach2,
    ) = model  # SphereModel.arrays(), n_links unused here
    # 1. forward kinematics, link by link: T_child = T_parent T_origin M(q)
    for j in range(parent.shape[0]):
        p, c = parent[j], child[j]
        t = q[q_of[j]] if q_of[j] >= 0 else value[j]
        for a in range(3):
            for b in range(3):
                poses[c, a, b] = (
                    poses[p, a, 0] * j_rot[j, 0, b]
                    + poses[p, a, 1] * j_rot[j, 1, b]
                    + poses[p, a, 2] * j_rot[j, 2, b]
                )
            poses[c, a, 3] = (
                poses[p, a, 0] * j_pos[j, 0]
                + poses[p, a, 1] * j_pos[j, 1]
                + poses[p, a, 2] * j_pos[j, 2]
                + poses[p, a, 3]
            )
        if kind[j] == REVOLUTE:  # R <- R (I + K^2 + sin t K - cos t K^2)
            s, v = np.sin(t), np.cos(t)
            for a in range(3):
                r0, r1, r2 = poses[c, a, 0], poses[c, a, 1], poses[c, a, 2]
                for b in range(3):
                    m0 = j_k2[j, 0, b] + s * j_k[j, 0, b] - v * j_k2[j, 0, b]
                    m1 = j_k2[j, 1, b] + s * j_k[j, 1, b] - v * j_k2[j, 1, b]
                    m2 = j_k2[j, 2, b] + s * j_k[j, 2, b] - v * j_k2[j, 2, b]
                    poses[c, a, b] += r0 * m0 + r1 * m1 + r2 * m2
        elif kind[j] == PRISMATIC:  # t_child += t R axis
            for a in range(3):
                poses[c, a, 3] += t * (
                    poses[c, a, 0] * j_axis[j, 0]
                    + poses[c, a, 1] * j_axis[j, 1]
                    + poses[c, a, 2] * j_axis[j, 2]
                )
    # 2. every sphere placed, coordinates as rows (x, y, z): (3, ns)
    for k in range(s_link.shape[0]):
        L = s_link[k]
        for a in range(3):
            placed[a, k] = (
                poses[L, a, 0] * s_center[k, 0]
                + poses[L, a, 1] * s_center[k, 1]
                + poses[L, a, 2] * s_center[k, 2]
                + poses[L, a, 3]
            )
    px, py, pz = placed[0], placed[1], placed[2]
    zero = px[0] - px[0]
    # 3. the world, obstacle by obstacle: one branch-free pass over the spheres each
    for o in range(o_center.shape[0]):
        cx, cy, cz = o_center[o, 0], o_center[o, 1], o_center[o, 2]
        hit = False
        for k in range(px.shape[0]):
            dx, dy, dz = px[k] - cx, py[k] - cy, pz[k] - cz
            hit |= dx * dx + dy * dy + dz * dz <= o_reach2[o, k]
        if hit:
            return True
    for o in range(b_center.shape[0]):
        cx, cy, cz = b_center[o, 0], b_center[o, 1], b_center[o, 2]
        b00, b01, b02 = b_rot[o, 0, 0], b_rot[o, 0, 1], b_rot[o, 0, 2]
        b10, b11, b12 = b_rot[o, 1, 0], b_rot[o, 1, 1], b_rot[o, 1, 2]
        b20, b21, b22 = b_rot[o, 2, 0], b_rot[o, 2, 1], b_rot[o, 2, 2]
        h0, h1, h2 = b_half[o, 0], b_half[o, 1], b_half[o, 2]
        hit = False
        for k in range(px.shape[0]):
            dx, dy, dz = px[k] - cx, py[k] - cy, pz[k] - cz
            e0 = abs(dx * b00 + dy * b10 + dz * b20) - h0
            e1 = abs(dx * b01 + dy * b11 + dz * b21) - h1
            e2 = abs(dx * b02 + dy * b12 + dz * b22) - h2
            f0, f1, f2 = max(e0, zero), max(e1, zero), max(e2, zero)
            hit |= f0 * f0 + f1 * f1 + f2 * f2 <= b_reach2[k]
            hit |= max(e0, max(e1, e2)) <= b_deep[k]
        if hit:
            return True
    # 4. self pairs, run by run: one sphere against contiguous ones, a branch-free pass each
    for run in range(run_sphere.shape[0]):
        a, start, shift = run_sphere[run], run_start[run], run_offset[run] - run_start[run]
        cx, cy, cz = px[a], py[a], pz[a]
        hit = False
        for b in range(start, run_stop[run]):
            dx, dy, dz = px[b] - cx, py[b] - cy, pz[b] - cz
            hit |= dx * dx + dy * dy + dz * dz <= p_reach2[shift + b]
        if hit:
            return True
    return False


def _run(q, out, model):
    """``out[i] = collides(q[i])`` (compiled by Numba): ``prange`` over blocks of ``BLOCK``
    configurations, each block with its own scratch (link poses, placed spheres)."""
    n, n_links, n_spheres = q.shape[0], model[10], model[11].shape[0]
    for block in prange((n + BLOCK - 1) // BLOCK):
        poses = np.zeros((n_links, 3, 4), q.dtype)
        placed = np.empty((3, n_spheres), q.dtype)
        for a in range(3):
            poses[0, a, a] = 1  # the root link at the world's origin
        for i in range(block * BLOCK, min(n, (block + 1) * BLOCK)):
            out[i] = _collides(q[i], poses, placed, model)


try:  # numba is a benchmark extra; without it the module still imports (and its parser runs)
    import numba
    from numba import prange

    _collides = numba.njit(cache=True)(_collides)
    _run = numba.njit(parallel=True, cache=True)(_run)
except ImportError:  # pragma: no cover
    numba = None
    prange = range


def make_checker(model: SphereModel, threads: int = 2):
    """``check(q (n, dof)) -> collides (n,) bool`` in ``model``'s dtype on ``threads`` Numba
    threads (``q`` is copied first unless it is already contiguous in that dtype)."""
    if numba is None:
        raise ImportError("make_checker needs numba (pip install -e '.[bench]')")
    args = model.arrays()
    dtype = model.joint_rot.dtype
    threads = min(threads, numba.config.NUMBA_NUM_THREADS)

    def check(q: np.ndarray) -> np.ndarray:
        q = np.ascontiguousarray(q, dtype)
        out = np.empty(q.shape[0], np.bool_)
        before = numba.get_num_threads()  # other Numba loops in the process keep theirs
        numba.set_num_threads(threads)
        try:
            _run(q, out, args)
        finally:
            numba.set_num_threads(before)
        return out

    return check
