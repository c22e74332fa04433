"""The world: obstacles of every kind as arrays, and each robot primitive's nearest obstacle.

``World`` holds ``Spheres``, ``Capsules``, ``Boxes``, ``HalfSpaces`` and ``Cylinders`` (any of
them empty).
Its arrays are pytree leaves: moving, resizing or re-orienting obstacles keeps the shapes and
so reuses a compiled check; adding or removing an obstacle changes a shape (pad with far-away
obstacles to avoid that).

``nearest_obstacles(spheres, capsules, world)`` gives, for every robot sphere and capsule (in
world coordinates, any leading batch axes), the smallest signed distance over all obstacles and
which obstacle attains it (``kind`` from ``SPHERE, CAPSULE, BOX, HALFSPACE, CYLINDER`` and the
index within that kind). With no obstacle at all the distance is the dtype's largest finite value
and ``kind = index = -1``.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

from .._validate import on_device, owned_float
from . import distance as sd
from .primitives import Boxes, Capsules, Cylinders, HalfSpaces, Spheres

__all__ = [
    "OBSTACLE_BUCKET",
    "BOX",
    "CAPSULE",
    "CYLINDER",
    "HALFSPACE",
    "SPHERE",
    "Nearest",
    "World",
    "nearest_obstacles",
]

SPHERE, CAPSULE, BOX, HALFSPACE, CYLINDER = 0, 1, 2, 3, 4

# Obstacles of a kind are padded to a multiple of this (``World.bucketed``): the checks' loops
# take them in groups of as many (``rows.OBSTACLE_CHUNK``), so the padding costs nothing.
OBSTACLE_BUCKET = 8


def _owned(x: jax.Array, dtype) -> jax.Array:
    arr = owned_float(x)
    return arr if arr.dtype == dtype else arr.astype(dtype)


@jax.tree_util.register_dataclass
@dataclasses.dataclass(frozen=True)
class World:
    """Obstacles by kind; build with ``World.create(spheres=..., boxes=...)`` (missing kinds
    are empty)."""

    spheres: Spheres
    capsules: Capsules
    boxes: Boxes
    halfspaces: HalfSpaces
    cylinders: Cylinders

    @classmethod
    def create(
        cls,
        spheres: Spheres | None = None,
        capsules: Capsules | None = None,
        boxes: Boxes | None = None,
        halfspaces: HalfSpaces | None = None,
        dtype=None,
        *,
        cylinders: Cylinders | None = None,
    ) -> World:
        given = {
            "spheres": spheres,
            "capsules": capsules,
            "boxes": boxes,
            "halfspaces": halfspaces,
            "cylinders": cylinders,
        }
        kinds: dict[str, Any] = {
            "spheres": Spheres,
            "capsules": Capsules,
            "boxes": Boxes,
            "halfspaces": HalfSpaces,
            "cylinders": Cylinders,
        }
        for name, value in given.items():
            if value is not None and not isinstance(value, kinds[name]):
                raise ValueError(
                    f"{name} must be {kinds[name].__name__}, got {type(value).__name__}"
                )
        if dtype is None:
            leaves = [leaf for v in given.values() if v is not None for leaf in jax.tree.leaves(v)]
            dtype = jnp.result_type(*leaves) if leaves else jnp.result_type(float)
        # Copies of host arrays (a primitive built by its plain constructor from NumPy arrays):
        # an edit of the caller's array must not move an obstacle.
        parts = {
            name: jax.tree.map(lambda x: _owned(x, dtype), value)
            if value is not None
            else kinds[name].empty(dtype)
            for name, value in given.items()
        }
        return cls(**parts)

    def astype(self, dtype) -> World:
        """This world in ``dtype``: itself when every field is in it already (no copy)."""
        if all(jnp.result_type(x) == dtype for x in jax.tree.leaves(self)):
            return self
        return jax.tree.map(lambda x: on_device(x, dtype), self)

    def bucketed(self) -> World:
        """This world with each kind's obstacles padded to a multiple of ``OBSTACLE_BUCKET``
        by repeating the kind's last obstacle: a repeated obstacle repeats a test, so no
        verdict, clearance or reported obstacle changes (a tie goes to the first), and a
        world whose counts stay within their buckets reuses a compiled check. A kind with no
        obstacle, and a world with leading batch axes, are left as they are."""
        if self.batched():
            return self
        cached = self.__dict__.get("_bucketed")
        if cached is not None:
            return cached

        def padded(kind: Any) -> Any:
            count = len(kind)
            pad = -count % OBSTACLE_BUCKET
            if not count or not pad:
                return kind
            return jax.tree.map(lambda x: _repeat_last(x, pad), kind)

        world = World(**{f.name: padded(getattr(self, f.name)) for f in dataclasses.fields(self)})
        if not any(isinstance(x, jax.core.Tracer) for x in jax.tree.leaves(self)):
            # a concrete world is padded and sent to the device once, not at every check
            object.__setattr__(self, "_bucketed", world)
        return world

    def batched(self) -> bool:
        """True when the obstacles carry leading batch axes (a world per configuration)."""
        return (
            self.spheres.radius.ndim > 1
            or self.capsules.radius.ndim > 1
            or self.boxes.half_extents.ndim > 2
            or self.halfspaces.offset.ndim > 1
            or self.cylinders.radius.ndim > 1
        )

    def layout(self) -> tuple:
        """The world's structure: its tree and every array's shape (``packed``/``unpacked``;
        two worlds of one layout share a compiled program)."""
        leaves, tree = jax.tree.flatten(self)
        return tree, tuple(tuple(np.shape(x)) for x in leaves)

    def packed(self, dtype: Any) -> np.ndarray:
        """Every array of the world in one flat host array of ``dtype`` (``layout`` order): a
        compiled handle takes a world as one argument (one transfer per call, not one per
        array)."""
        leaves = jax.tree.leaves(self)
        if not leaves:
            return np.zeros(0, dtype)
        return np.concatenate([np.asarray(x, dtype).ravel() for x in leaves])

    @staticmethod
    def unpacked(flat: Any, layout: tuple) -> World:
        """The world of ``layout`` from its ``packed`` array (traceable: static slices)."""
        tree, shapes = layout
        leaves, start = [], 0
        for shape in shapes:
            size = math.prod(shape)
            leaves.append(flat[start : start + size].reshape(shape))
            start += size
        return jax.tree.unflatten(tree, leaves)

    def counts(self) -> dict[str, int]:
        """The number of obstacles of each kind, by field name."""
        return {f.name: len(getattr(self, f.name)) for f in dataclasses.fields(self)}


@jax.tree_util.register_dataclass
@dataclasses.dataclass(frozen=True)
class Nearest:
    """Per robot primitive: ``distance`` (signed, smallest over the world), the obstacle's
    ``kind`` (int8: ``SPHERE, CAPSULE, BOX, HALFSPACE, CYLINDER``; -1 with no obstacle) and its
    ``index`` (int32) within that kind. Shapes ``(..., n)``."""

    distance: jax.Array
    kind: jax.Array
    index: jax.Array


def _obstacle_args(world: World) -> list[tuple[int, tuple[jax.Array, ...]]]:
    """Each non-empty kind of obstacle with its arrays, given a new axis for the robot
    primitives: ``(kind, arrays (..., 1, m_kind, ...))``."""
    w, c = world, world.cylinders
    kinds: list[tuple[int, Any, tuple[jax.Array, ...]]] = [
        (SPHERE, w.spheres, (w.spheres.center, w.spheres.radius)),
        (CAPSULE, w.capsules, (w.capsules.a, w.capsules.b, w.capsules.radius)),
        (BOX, w.boxes, (w.boxes.center, w.boxes.rotation, w.boxes.half_extents)),
        (HALFSPACE, w.halfspaces, (w.halfspaces.normal, w.halfspaces.offset)),
        (CYLINDER, w.cylinders, (c.center, c.axis, c.radius, c.half_length)),
    ]
    core = {
        SPHERE: (1, 0),
        CAPSULE: (1, 1, 0),
        BOX: (1, 2, 1),
        HALFSPACE: (1, 0),
        CYLINDER: (1, 1, 0, 0),
    }
    return [
        (
            kind,
            tuple(
                x[(..., None) + (slice(None),) * (1 + c)]
                for x, c in zip(xs, core[kind], strict=True)
            ),
        )
        for kind, prims, xs in kinds
        if len(prims)
    ]


# Per robot primitive, the distance to each kind of obstacle (robot arguments first).
_SPHERE_TO = {
    SPHERE: sd.sphere_sphere,
    CAPSULE: sd.sphere_capsule,
    BOX: sd.sphere_box,
    HALFSPACE: sd.sphere_halfspace,
    CYLINDER: sd.sphere_cylinder,
}
_CAPSULE_TO = {
    SPHERE: lambda a, b, r, c, rc: sd.sphere_capsule(c, rc, a, b, r),
    CAPSULE: sd.capsule_capsule,
    BOX: sd.capsule_box,
    HALFSPACE: sd.capsule_halfspace,
    CYLINDER: sd.capsule_cylinder,
}


def _pairs(distance_to: dict, robot: tuple[jax.Array, ...], cores: tuple[int, ...], world):
    """Signed distances ``(..., n, m_kind)`` from the robot primitives ``robot`` (arrays
    ``(..., n, *core)`` with ``len(core)`` in ``cores``) to each non-empty kind of obstacle."""
    ri = tuple(
        x[(..., slice(None), None) + (slice(None),) * c] for x, c in zip(robot, cores, strict=True)
    )
    return [(kind, distance_to[kind](*ri, *args)) for kind, args in _obstacle_args(world)]


def _reduce(per_kind: list[tuple[int, jax.Array]], batch: tuple[int, ...], dtype) -> Nearest:
    """Smallest distance over the kinds' ``(..., n, m)`` matrices, and where it is."""
    if not per_kind:
        big = jnp.full(batch, jnp.finfo(dtype).max, dtype)
        none = jnp.full(batch, -1)
        return Nearest(big, none.astype(jnp.int8), none.astype(jnp.int32))
    dists = jnp.stack([jnp.min(d, axis=-1) for _, d in per_kind], axis=-1)
    which = jnp.stack([jnp.argmin(d, axis=-1) for _, d in per_kind], axis=-1)
    kinds = jnp.asarray([k for k, _ in per_kind], dtype=jnp.int8)
    best = jnp.argmin(dists, axis=-1)
    distance = jnp.take_along_axis(dists, best[..., None], axis=-1)[..., 0]
    index = jnp.take_along_axis(which, best[..., None], axis=-1)[..., 0]
    return Nearest(distance, kinds[best], index.astype(jnp.int32))


def nearest_obstacles(
    spheres: Spheres, capsules: Capsules, world: World
) -> tuple[Nearest, Nearest]:
    """Each robot sphere's and capsule's nearest obstacle (smallest signed distance).

    Args:
        spheres: robot spheres in world coordinates, ``center (..., ns, 3)``.
        capsules: robot capsules in world coordinates, ``a, b (..., nc, 3)``.
        world: the obstacles (leading axes, if any, broadcast against the robot's).

    Returns:
        ``(for_spheres, for_capsules)``: ``Nearest`` with shapes ``(..., ns)`` and ``(..., nc)``.
    """
    dtype = jnp.result_type(spheres.radius, capsules.radius)
    robot_spheres = (spheres.center, spheres.radius)
    s = _reduce(_pairs(_SPHERE_TO, robot_spheres, (1, 0), world), spheres.radius.shape, dtype)
    robot_capsules = (capsules.a, capsules.b, capsules.radius)
    c = _reduce(_pairs(_CAPSULE_TO, robot_capsules, (1, 1, 0), world), capsules.radius.shape, dtype)
    return s, c


def _repeat_last(x: Any, pad: int) -> Any:
    """``x`` with its last row repeated ``pad`` times: on the host for a concrete array (no
    program per shape), else traced."""
    if isinstance(x, jax.core.Tracer):
        return jnp.concatenate([x, jnp.repeat(x[-1:], pad, axis=0)])
    host = np.asarray(x)
    return jax.device_put(np.concatenate([host, np.repeat(host[-1:], pad, axis=0)]))
