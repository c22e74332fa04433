"""Collision primitives as array data: spheres, capsules, oriented boxes, cylinders, half-spaces.

Each kind is a frozen dataclass registered as a pytree whose fields are arrays with one row per
primitive (shape ``(n, ...)``, any further leading axes broadcast), so moving or resizing a
primitive changes values, never shapes, and a jitted check does not recompile. Build them with
``create``, which validates concrete values on the host and raises ``ValueError`` naming the
argument; the plain constructor is JAX's path (tracers, cotangents) and checks nothing.

Point clouds enter as spheres: ``point_cloud_spheres`` down-samples on a voxel grid (host side)
and puts one sphere on each occupied voxel's mean point, with a radius that contains every point
of that voxel grown by the requested point radius.
"""

from __future__ import annotations

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np
from jax.typing import ArrayLike

from .._validate import finite_number, positive_number

__all__ = ["Boxes", "Capsules", "Cylinders", "HalfSpaces", "Spheres", "point_cloud_spheres"]


def _floats(x: ArrayLike, name: str, shape_tail: tuple[int, ...], dtype=None) -> np.ndarray:
    """A finite float array whose trailing axes are ``shape_tail`` (checked on the host)."""
    arr = np.asarray(x)
    if arr.dtype.kind not in "fiu":
        raise ValueError(f"{name} must hold real numbers, got dtype {arr.dtype}")
    if shape_tail and arr.shape == shape_tail:
        arr = arr[None]  # one primitive
    tail = arr.shape[arr.ndim - len(shape_tail) :] if len(shape_tail) else ()
    if arr.ndim < len(shape_tail) + 1 or tail != shape_tail:
        want = ", ".join(["n", *map(str, shape_tail)])
        raise ValueError(f"{name}: expected shape (..., {want}), got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} must be finite")
    return arr.astype(dtype or jnp.result_type(float))


def _per_primitive(x: ArrayLike, name: str, shape: tuple[int, ...]) -> np.ndarray:
    """``x`` broadcast to ``shape`` (one value per primitive, or one for all), or a
    ``ValueError`` naming it."""
    arr = np.asarray(x)
    try:
        return np.broadcast_to(arr, shape)
    except ValueError:
        raise ValueError(
            f"{name}: shape {arr.shape} does not broadcast to {shape} (one per primitive)"
        ) from None


def _nonnegative(arr: np.ndarray, name: str) -> np.ndarray:
    if np.any(arr < 0):
        raise ValueError(f"{name} must be >= 0, got minimum {arr.min()}")
    return arr


def _count(name: str, *arrays: np.ndarray, axes: tuple[int, ...]) -> None:
    """Every field must have the same number of primitives (its row axis)."""
    counts = {arr.shape[arr.ndim - k] for arr, k in zip(arrays, axes, strict=True)}
    if len(counts) != 1:
        raise ValueError(f"{name}: fields disagree on the number of primitives: {sorted(counts)}")


def _rotations(rotation: ArrayLike, dtype=None) -> np.ndarray:
    """Proper rotation matrices ``(..., 3, 3)`` (host side), or a ``ValueError`` naming
    ``rotation``."""
    rot = _floats(rotation, "rotation", (3, 3), dtype)
    err = np.abs(np.swapaxes(rot, -1, -2) @ rot - np.eye(3)).max(initial=0.0)
    tol = 100.0 * np.sqrt(np.finfo(rot.dtype).eps)
    if err > tol or np.any(np.linalg.det(rot.astype(float)) <= 0):
        raise ValueError(
            f"rotation must be proper rotation matrices (R^T R = I within {tol:.1e}, "
            f"det > 0); largest |R^T R - I| is {err:.2e}"
        )
    return rot


def _sphere_arrays(
    center: ArrayLike, radius: ArrayLike, dtype=None
) -> tuple[np.ndarray, np.ndarray]:
    """Host side, new arrays: sphere centres ``(..., n, 3)`` and radii ``(..., n)`` (one for
    all, or one per centre), finite, radii ``>= 0``; ``ValueError`` naming the argument."""
    c = _floats(center, "center", (3,), dtype)
    r = _floats(_per_primitive(radius, "radius", c.shape[:-1]), "radius", (), dtype)
    return c, _nonnegative(r, "radius")


@jax.tree_util.register_dataclass
@dataclasses.dataclass(frozen=True)
class Spheres:
    """Spheres: ``center`` shape ``(..., n, 3)``, ``radius`` shape ``(..., n)`` (>= 0)."""

    center: jax.Array
    radius: jax.Array

    @classmethod
    def create(cls, center: ArrayLike, radius: ArrayLike, dtype=None) -> Spheres:
        return cls(*map(jax.device_put, _sphere_arrays(center, radius, dtype)))

    @classmethod
    def empty(cls, dtype=None) -> Spheres:
        return cls.create(np.zeros((0, 3)), np.zeros(0), dtype)

    def __len__(self) -> int:
        return self.radius.shape[-1]


@jax.tree_util.register_dataclass
@dataclasses.dataclass(frozen=True)
class Capsules:
    """Capsules (segments ``a``-``b`` grown by ``radius``): ``a, b`` ``(..., n, 3)``,
    ``radius`` ``(..., n)``. A capsule with ``a == b`` is a sphere."""

    a: jax.Array
    b: jax.Array
    radius: jax.Array

    @classmethod
    def create(cls, a: ArrayLike, b: ArrayLike, radius: ArrayLike, dtype=None) -> Capsules:
        pa, pb = _floats(a, "a", (3,), dtype), _floats(b, "b", (3,), dtype)
        _count("Capsules", pa, pb, axes=(2, 2))
        r = _floats(_per_primitive(radius, "radius", pa.shape[:-1]), "radius", (), dtype)
        return cls(*map(jax.device_put, (pa, pb, _nonnegative(r, "radius"))))

    @classmethod
    def empty(cls, dtype=None) -> Capsules:
        return cls.create(np.zeros((0, 3)), np.zeros((0, 3)), np.zeros(0), dtype)

    def __len__(self) -> int:
        return self.radius.shape[-1]


@jax.tree_util.register_dataclass
@dataclasses.dataclass(frozen=True)
class Boxes:
    """Oriented boxes ``{center + rotation @ u : |u_i| <= half_extents_i}``.

    ``center`` ``(..., n, 3)``; ``rotation`` ``(..., n, 3, 3)`` (columns: the box axes in the
    world frame, a proper rotation); ``half_extents`` ``(..., n, 3)`` (>= 0).
    """

    center: jax.Array
    rotation: jax.Array
    half_extents: jax.Array

    @classmethod
    def create(
        cls,
        center: ArrayLike,
        half_extents: ArrayLike,
        rotation: ArrayLike | None = None,
        dtype=None,
    ) -> Boxes:
        c = _floats(center, "center", (3,), dtype)
        given = np.shape(half_extents)
        if given[-2:] == (3, 3) and len(given) > np.ndim(center):
            # the fields' order (center, rotation, half_extents) is not create's
            raise ValueError(
                f"half_extents: got shape {given}, 3x3 matrices (one more axis than center): "
                "Boxes.create takes (center, half_extents, rotation=None); pass rotation= "
                "by name"
            )
        h = _nonnegative(
            _floats(
                _per_primitive(half_extents, "half_extents", c.shape), "half_extents", (3,), dtype
            ),
            "half_extents",
        )
        if rotation is None:
            rotation = np.broadcast_to(np.eye(3), (*c.shape[:-1], 3, 3))
        rot = _rotations(rotation, dtype)
        _count("Boxes", c, rot, axes=(2, 3))
        return cls(*map(jax.device_put, (c, rot, h)))

    @classmethod
    def empty(cls, dtype=None) -> Boxes:
        return cls.create(np.zeros((0, 3)), np.zeros((0, 3)), np.zeros((0, 3, 3)), dtype)

    def __len__(self) -> int:
        return self.center.shape[-2]


@jax.tree_util.register_dataclass
@dataclasses.dataclass(frozen=True)
class Cylinders:
    """Solid cylinders ``{center + z axis + w : |z| <= half_length, w . axis = 0,
    |w| <= radius}``.

    ``center`` ``(..., n, 3)``; ``axis`` ``(..., n, 3)`` (unit: ``create`` normalises it);
    ``radius`` and ``half_length`` ``(..., n)`` (>= 0). A cylinder of radius 0 is a segment,
    one of half-length 0 a disk. URDF's and MoveIt's cylinders lie along their frame's z axis:
    ``create(..., rotation=R)`` takes that frame (the axis is ``R[:, 2]``).
    """

    center: jax.Array
    axis: jax.Array
    radius: jax.Array
    half_length: jax.Array

    @classmethod
    def create(
        cls,
        center: ArrayLike,
        radius: ArrayLike,
        half_length: ArrayLike,
        axis: ArrayLike | None = None,
        rotation: ArrayLike | None = None,
        dtype=None,
    ) -> Cylinders:
        """Cylinders along ``axis`` (non-zero vectors, one per cylinder or one for all), or
        along the z axis of ``rotation`` (proper rotations), or along z when neither is given;
        a ``ValueError`` names the argument otherwise."""
        c = _floats(center, "center", (3,), dtype)
        if axis is not None and rotation is not None:
            raise ValueError("axis, rotation: give one of them (the axis is rotation[..., :, 2])")
        if rotation is not None:
            rot = _rotations(rotation, dtype)
            _count("Cylinders", c, rot, axes=(2, 3))
            direction = rot[..., :, 2]
        else:
            given = np.array([0.0, 0.0, 1.0]) if axis is None else axis
            direction = _floats(_per_primitive(given, "axis", c.shape), "axis", (3,), dtype)
        length = np.linalg.norm(direction.astype(float), axis=-1, keepdims=True)
        if np.any(length == 0):
            raise ValueError("axis must be non-zero vectors")
        r = _floats(_per_primitive(radius, "radius", c.shape[:-1]), "radius", (), dtype)
        h = _floats(
            _per_primitive(half_length, "half_length", c.shape[:-1]), "half_length", (), dtype
        )
        unit = (direction / length).astype(c.dtype)
        return cls(
            jax.device_put(c),
            jax.device_put(unit),
            jax.device_put(_nonnegative(r, "radius")),
            jax.device_put(_nonnegative(h, "half_length")),
        )

    @classmethod
    def empty(cls, dtype=None) -> Cylinders:
        return cls.create(np.zeros((0, 3)), np.zeros(0), np.zeros(0), dtype=dtype)

    def __len__(self) -> int:
        return self.radius.shape[-1]


@jax.tree_util.register_dataclass
@dataclasses.dataclass(frozen=True)
class HalfSpaces:
    """Half-spaces ``{x : normal . x <= offset}``: ``normal`` ``(..., n, 3)`` (unit; ``create``
    divides both by the normal's length), ``offset`` ``(..., n)``. The floor ``z <= 0`` is
    ``normal=(0, 0, 1), offset=0``."""

    normal: jax.Array
    offset: jax.Array

    @classmethod
    def create(cls, normal: ArrayLike, offset: ArrayLike, dtype=None) -> HalfSpaces:
        n = _floats(normal, "normal", (3,), dtype)
        length = np.linalg.norm(n, axis=-1, keepdims=True)
        if np.any(length == 0):
            raise ValueError("normal must be non-zero vectors")
        o = _floats(_per_primitive(offset, "offset", n.shape[:-1]), "offset", (), dtype)
        return cls(jax.device_put(n / length), jax.device_put(o / length[..., 0]))

    @classmethod
    def empty(cls, dtype=None) -> HalfSpaces:
        return cls.create(np.ones((0, 3)), np.zeros(0), dtype)

    def __len__(self) -> int:
        return self.offset.shape[-1]


def point_cloud_spheres(
    points: ArrayLike, voxel: float, point_radius: float = 0.0, dtype=None
) -> Spheres:
    """Spheres covering a point cloud after voxel down-sampling (host side, NumPy).

    Points ``(n, 3)`` are binned on a grid of cell size ``voxel``; each occupied cell gives one
    sphere at the mean of its points with radius ``point_radius`` plus the largest distance from
    that mean to a point of the cell (at most ``voxel * sqrt(3)``), so every point, grown by
    ``point_radius``, lies inside the spheres. The number of spheres is the number of occupied
    cells: pad or fix the voxel size to keep a jitted check's shapes constant.
    """
    pts = _floats(points, "points", (3,), np.float64)
    if pts.ndim != 2:
        raise ValueError(f"points: expected shape (n, 3), got {pts.shape}")
    voxel = positive_number(voxel, "voxel")
    point_radius = finite_number(point_radius, "point_radius")
    if point_radius < 0:
        raise ValueError(f"point_radius must be >= 0, got {point_radius!r}")
    if len(pts) == 0:
        return Spheres.empty(dtype)
    cells = np.floor(pts / voxel).astype(np.int64)
    _, cell_of, counts = np.unique(cells, axis=0, return_inverse=True, return_counts=True)
    cell_of = cell_of.reshape(-1)
    sums = np.zeros((len(counts), 3))
    np.add.at(sums, cell_of, pts)
    centers = sums / counts[:, None]
    reach = np.zeros(len(counts))
    np.maximum.at(reach, cell_of, np.linalg.norm(pts - centers[cell_of], axis=-1))
    # one ulp-scale margin so rounding in another dtype still contains the points
    margin = 4.0 * np.finfo(np.dtype(dtype or jnp.result_type(float))).eps * np.abs(pts).max()
    return Spheres.create(centers, reach + point_radius + margin, dtype)
