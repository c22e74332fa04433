"""Triangle meshes of the collision primitives, for drawing (host side, NumPy).

Every function returns a ``Surface``: vertices ``(V, 3)`` on the primitive's boundary and
faces ``(F, 3)`` (vertex indices, outward by the right-hand rule). Curved surfaces are
sampled on ``segments`` meridians (a sphere and a capsule's caps on ``segments // 2``
parallels as well): every vertex lies on the exact surface, so a drawing is the primitive to
within its chord error ``r (1 - cos(pi / segments))``.

``body_surfaces(body, link_poses)`` gives a robot body's primitives placed at one set of link
poses (``link_poses(robot, q)``: ``robot.link_poses(q)`` compiled, on the host),
``link_surfaces(body)`` each link's in its own frame (a viewer moves the link),
``world_surfaces(world, extent)`` every obstacle; a half-space, which is unbounded, is drawn
as the square of side ``2 extent`` of its plane centred on the point of the plane nearest the
origin of the drawing (``center``).
"""

from __future__ import annotations

import dataclasses
from typing import Any

import jax.numpy as jnp
import numpy as np

from .._execute import kernel
from .body import Body
from .world import World

__all__ = [
    "Surface",
    "body_surfaces",
    "bounding_cube",
    "box",
    "capsule",
    "cylinder",
    "halfspace",
    "link_poses",
    "link_surfaces",
    "scene_joints",
    "sphere",
    "world_surfaces",
]

SEGMENTS = 16


@dataclasses.dataclass(frozen=True)
class Surface:
    """A primitive's triangle mesh: ``vertices (V, 3)``, ``faces (F, 3)``; ``name`` says
    which primitive it is (``"sphere 3"``, ``"box 0"``, ``"link3 capsule 1"``)."""

    vertices: np.ndarray
    faces: np.ndarray
    name: str = ""


def _frame(axis: np.ndarray) -> np.ndarray:
    """A rotation ``(3, 3)`` whose third column is the unit vector ``axis``."""
    z = axis / np.linalg.norm(axis)
    helper = np.array([1.0, 0.0, 0.0]) if abs(z[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    x = np.cross(helper, z)
    x /= np.linalg.norm(x)
    return np.stack([x, np.cross(z, x), z], axis=1)


def _grid_faces(rings: int, segments: int, offset: int = 0) -> np.ndarray:
    """Two triangles per cell of ``rings`` rings of ``segments`` vertices (ring-major)."""
    r, s = np.meshgrid(np.arange(rings - 1), np.arange(segments), indexing="ij")
    a = offset + r * segments + s
    b = offset + r * segments + (s + 1) % segments
    c, d = a + segments, b + segments
    return np.concatenate([np.stack([a, b, d], -1), np.stack([a, d, c], -1)]).reshape(-1, 3)


def _capped(
    rings: np.ndarray, bottom: np.ndarray, top: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """A closed mesh: ``rings (R, S, 3)`` joined in order, each end closed by a fan to its
    pole (``bottom``, ``top``)."""
    count, segments = rings.shape[:2]
    vertices = np.concatenate([rings.reshape(-1, 3), bottom[None], top[None]])
    s = np.arange(segments)
    low, high = count * segments, count * segments + 1
    last = (count - 1) * segments
    faces = np.concatenate(
        [
            _grid_faces(count, segments),
            np.stack([np.full(segments, low), (s + 1) % segments, s], -1),
            np.stack([np.full(segments, high), last + s, last + (s + 1) % segments], -1),
        ]
    )
    return vertices, faces


def _rounded(
    a: np.ndarray, b: np.ndarray, radius: float, segments: int
) -> tuple[np.ndarray, np.ndarray]:
    """A capsule's mesh: the sphere of ``radius`` cut at its equator, the lower half at ``a``,
    the upper at ``b`` (a sphere where ``a == b``)."""
    axis = b - a
    length = float(np.linalg.norm(axis))
    rot = _frame(axis) if length > 0 else np.eye(3)
    half = max(segments // 4, 1)
    polar = np.concatenate(
        [np.linspace(np.pi, np.pi / 2, half + 1)[1:], np.linspace(np.pi / 2, 0, half + 1)[:-1]]
    )
    around = np.linspace(0.0, 2 * np.pi, segments, endpoint=False)
    ring = np.stack(
        [
            np.sin(polar)[:, None] * np.cos(around),
            np.sin(polar)[:, None] * np.sin(around),
            np.cos(polar)[:, None] * np.ones_like(around),
        ],
        -1,
    )  # (R, S, 3) unit sphere, south to north, the equator twice
    upper = np.arange(len(polar)) >= half
    local = radius * ring + np.where(upper, length, 0.0)[:, None, None] * [0.0, 0.0, 1.0]
    rings = a + local @ rot.T
    bottom = a - radius * rot[:, 2]
    top = b + radius * rot[:, 2] if length > 0 else a + radius * rot[:, 2]
    return _capped(rings, bottom, top)


def sphere(center: Any, radius: float, segments: int = SEGMENTS) -> Surface:
    """A sphere's mesh (its vertices at distance ``radius`` from ``center``)."""
    c = np.asarray(center, float)
    return Surface(*_rounded(c, c, float(radius), segments))


def capsule(a: Any, b: Any, radius: float, segments: int = SEGMENTS) -> Surface:
    """A capsule's mesh (its vertices at distance ``radius`` from the segment ``a``-``b``)."""
    return Surface(*_rounded(np.asarray(a, float), np.asarray(b, float), float(radius), segments))


def cylinder(
    center: Any, axis: Any, radius: float, half_length: float, segments: int = SEGMENTS
) -> Surface:
    """A solid cylinder's mesh: its side and two capped ends."""
    c, rot = np.asarray(center, float), _frame(np.asarray(axis, float))
    around = np.linspace(0.0, 2 * np.pi, segments, endpoint=False)
    circle = np.stack([np.cos(around), np.sin(around), np.zeros_like(around)], -1) * radius
    ends = np.stack([circle - [0, 0, half_length], circle + [0, 0, half_length]])
    rings = c + ends @ rot.T
    return Surface(*_capped(rings, c - half_length * rot[:, 2], c + half_length * rot[:, 2]))


_BOX_FACES = np.array(
    [
        [0, 1, 2], [1, 3, 2], [4, 6, 5], [5, 6, 7], [0, 4, 1], [1, 4, 5],
        [2, 3, 6], [3, 7, 6], [0, 2, 4], [2, 6, 4], [1, 5, 3], [3, 5, 7],
    ]
)  # fmt: skip


def box(center: Any, rotation: Any, half_extents: Any) -> Surface:
    """An oriented box's mesh: its 8 corners ``center + rotation @ (+-h)`` and 12 triangles."""
    signs = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], float)
    corners = (signs * np.asarray(half_extents, float)) @ np.asarray(rotation, float).T
    return Surface(np.asarray(center, float) + corners, _BOX_FACES.copy())


def halfspace(normal: Any, offset: float, center: Any = (0.0, 0.0, 0.0), extent=1.0) -> Surface:
    """The square of side ``2 extent`` of the plane ``normal . x = offset`` centred on the
    point of the plane nearest ``center`` (two triangles, facing along ``normal``)."""
    n = np.asarray(normal, float) / np.linalg.norm(normal)
    c = np.asarray(center, float)
    foot = c - (n @ c - offset) * n
    rot = _frame(n)
    square = np.array([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], float) * extent
    return Surface(foot + square @ rot.T, np.array([[0, 1, 2], [0, 2, 3]]))


@kernel
def _link_poses(robot: Any, q: Any) -> Any:
    return robot.link_poses(q)


def link_poses(robot: Any, q: Any) -> np.ndarray:
    """Host side: ``robot.link_poses(q)`` ``(..., L, 4, 4)`` at joints ``q`` ``(..., n)`` in
    the default float dtype, one compiled call (per robot class and shapes)."""
    return np.asarray(_link_poses(robot, jnp.asarray(q)))


def scene_joints(n: int, q: Any, motion: Any, at_rest: bool = False) -> tuple[Any, Any]:
    """The joints ``(n,)`` to draw a robot at and a motion's joints ``(T, n)`` (or None),
    checked: ``q`` as given, else the motion's last sample, else zeros when ``at_rest``
    (a ``Jet`` stands for its positions).

    Raises:
        ValueError: ``q`` or ``motion`` of another shape, or neither given without
            ``at_rest`` (naming the argument).
    """
    moves = None
    if motion is not None:
        moves = np.asarray(getattr(motion, "p", motion), float)
        if moves.ndim != 2 or moves.shape[1] != n or len(moves) == 0:
            raise ValueError(f"motion: expected joints of shape (T, {n}), got {moves.shape}")
    if q is None:
        if moves is None and not at_rest:
            raise ValueError("q: give the joints to draw (or a motion)")
        q = np.zeros(n) if moves is None else moves[-1]
    q = np.asarray(getattr(q, "p", q), float)
    if q.shape != (n,):
        raise ValueError(f"q: expected joints of shape ({n},), got {q.shape}")
    return q, moves


def bounding_cube(points: Any) -> tuple[np.ndarray, float]:
    """``(centre (3,), half edge)`` of the smallest axis-aligned cube about ``points``
    ``(..., 3)``: where a drawing's half-spaces are centred and how large they are."""
    cloud = np.reshape(np.asarray(points, float), (-1, 3))
    centre = (cloud.max(0) + cloud.min(0)) / 2.0
    return centre, max(float(np.ptp(cloud, axis=0).max()) / 2.0, 1e-9)


def body_surfaces(body: Body, link_poses: Any, segments: int = SEGMENTS) -> list[Surface]:
    """A body's spheres and capsules placed at ``link_poses`` ``(len(body.links), 4, 4)``
    (one configuration: ``robot.link_poses(q)``), each named by its link."""
    spheres, capsules = body.place(jnp.asarray(link_poses))
    out = []
    for i, link in enumerate(body.sphere_link):
        center, radius = np.asarray(spheres.center[i]), float(spheres.radius[i])
        out.append(dataclasses.replace(sphere(center, radius, segments), name=body.links[link]))
    for i, link in enumerate(body.capsule_link):
        a, b = np.asarray(capsules.a[i]), np.asarray(capsules.b[i])
        shape = capsule(a, b, float(capsules.radius[i]), segments)
        out.append(dataclasses.replace(shape, name=body.links[link]))
    return out


def link_surfaces(body: Body, segments: int = SEGMENTS) -> dict[str, list[Surface]]:
    """Each link's primitives in its own frame, by link name (links without any left out)."""
    spheres, capsules = body.per_link()
    out: dict[str, list[Surface]] = {}
    for link, (centers, radii) in spheres.items():
        for k, (c, r) in enumerate(zip(centers, radii, strict=True)):
            shape = sphere(c, float(r), segments)
            out.setdefault(link, []).append(dataclasses.replace(shape, name=f"sphere {k}"))
    for link, (a, b, radii) in capsules.items():
        for k, (p, q, r) in enumerate(zip(a, b, radii, strict=True)):
            shape = capsule(p, q, float(r), segments)
            out.setdefault(link, []).append(dataclasses.replace(shape, name=f"capsule {k}"))
    return out


def world_surfaces(
    world: World, extent: float = 1.0, center: Any = (0.0, 0.0, 0.0), segments: int = SEGMENTS
) -> list[Surface]:
    """Every obstacle of an unbatched ``world`` (half-spaces as squares of side
    ``2 extent`` about ``center``), named ``"<kind> <index>"``."""
    if world.batched():
        raise ValueError("world: drawing needs a world without batch axes")
    out = []

    def named(shape: Surface, kind: str, i: int) -> None:
        out.append(dataclasses.replace(shape, name=f"{kind} {i}"))

    s, c, b, h, y = world.spheres, world.capsules, world.boxes, world.halfspaces, world.cylinders
    for i in range(len(s)):
        named(sphere(np.asarray(s.center[i]), float(s.radius[i]), segments), "sphere", i)
    for i in range(len(c)):
        shape = capsule(np.asarray(c.a[i]), np.asarray(c.b[i]), float(c.radius[i]), segments)
        named(shape, "capsule", i)
    for i in range(len(b)):
        shape = box(np.asarray(b.center[i]), np.asarray(b.rotation[i]), b.half_extents[i])
        named(shape, "box", i)
    for i in range(len(y)):
        shape = cylinder(
            np.asarray(y.center[i]),
            np.asarray(y.axis[i]),
            float(y.radius[i]),
            float(y.half_length[i]),
            segments,
        )
        named(shape, "cylinder", i)
    for i in range(len(h)):
        shape = halfspace(np.asarray(h.normal[i]), float(h.offset[i]), center, extent)
        named(shape, "halfspace", i)
    return out
