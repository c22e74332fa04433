"""A robot's body for collision: spheres and capsules attached to its links, as data.

``Body`` lists spheres (centre and radius in their link's frame) and capsules (end points and
radius in their link's frame), each with the index of its link in ``Body.links``. Positions and
radii are array leaves (a different radius or a moved sphere does not recompile, and a body can
be differentiated); the link of each primitive and the link names are static. ``place`` maps
the primitives to the world given every link's pose, for any leading batch of configurations;
the robot that owns the body supplies those poses.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from numpy.typing import ArrayLike  # host data: lists too

from .primitives import Capsules, Spheres, _sphere_arrays

__all__ = ["Body"]


def _link_points(x: ArrayLike, name: str) -> np.ndarray:
    """Points on one link as ``(k, 3)``: one point may be ``(3,)``, no points ``[]``."""
    arr = np.asarray(x)
    if arr.shape == (0,):
        arr = arr.reshape(0, 3)
    elif arr.shape == (3,):
        arr = arr[None]
    if arr.ndim != 2 or arr.shape[1] != 3:
        raise ValueError(f"{name}: expected shape (k, 3), got {arr.shape}")
    return arr


def _fields(value: Any, where: str, names: tuple[str, ...]) -> tuple:
    """One link's primitives ``value``: a tuple or list of ``len(names)`` arrays."""
    if not (isinstance(value, tuple | list) and len(value) == len(names)):
        raise ValueError(f"{where}: expected ({', '.join(names)}), got {type(value).__name__}")
    return tuple(value)


def link_spheres(
    spheres: Mapping[str, tuple[ArrayLike, ArrayLike]], links: tuple[str, ...]
) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """The user's spheres per link, checked and copied (host side, float64, read-only):
    link name -> ``(centers (k, 3), radii (k,))``; a ``ValueError`` names ``spheres`` and the
    link otherwise (an unknown link, a shape, a value that is not finite, a negative radius).
    """
    if not isinstance(spheres, Mapping):
        raise ValueError(
            f"spheres: expected a mapping link name -> (centers, radii), "
            f"got {type(spheres).__name__}"
        )
    out = {}
    for name, value in spheres.items():
        if name not in links:
            raise ValueError(f"spheres: unknown link {name!r} (links: {links})")
        where = f"spheres[{name!r}]"
        center, radius = _fields(value, where, ("centers (k, 3)", "radii (k,)"))
        try:
            arrays = _sphere_arrays(_link_points(center, "center"), radius, np.float64)
        except ValueError as err:
            raise ValueError(f"{where}: {err}") from None
        for arr in arrays:
            arr.setflags(write=False)  # the copies a frozen robot keeps
        out[name] = arrays
    return out


@jax.tree_util.register_dataclass
@dataclasses.dataclass(frozen=True)
class Body:
    """Spheres and capsules attached to links.

    Fields:
        sphere_center: ``(ns, 3)``, in the frame of link ``links[sphere_link[i]]``.
        sphere_radius: ``(ns,)``.
        capsule_a, capsule_b: ``(nc, 3)``, segment end points in their link's frame.
        capsule_radius: ``(nc,)``.
        sphere_link, capsule_link: static tuples of link indices, one per primitive.
        links: static tuple of link names (all links of the robot, with or without geometry).
    """

    sphere_center: jax.Array
    sphere_radius: jax.Array
    capsule_a: jax.Array
    capsule_b: jax.Array
    capsule_radius: jax.Array
    sphere_link: tuple[int, ...] = dataclasses.field(metadata={"static": True})
    capsule_link: tuple[int, ...] = dataclasses.field(metadata={"static": True})
    links: tuple[str, ...] = dataclasses.field(metadata={"static": True})

    @classmethod
    def create(
        cls,
        links: tuple[str, ...] | list[str],
        spheres: Mapping[str, tuple[ArrayLike, ArrayLike]] | None = None,
        capsules: Mapping[str, tuple[ArrayLike, ArrayLike, ArrayLike]] | None = None,
        dtype=None,
    ) -> Body:
        """A body from per-link primitives.

        Args:
            links: every link name, in the order of the poses ``place`` will receive.
            spheres: link name -> ``(centers (k, 3), radii (k,))`` in that link's frame.
            capsules: link name -> ``(a (k, 3), b (k, 3), radii (k,))`` in that link's frame.
        """
        links = tuple(links)
        if len(set(links)) != len(links) or not all(isinstance(n, str) for n in links):
            raise ValueError(f"links must be distinct link names, got {links!r}")
        index = {name: i for i, name in enumerate(links)}
        s_link, s_c, s_r, c_link, c_a, c_b, c_r = [], [], [], [], [], [], []
        for name, (center, radius) in link_spheres(spheres or {}, links).items():
            s_link += [index[name]] * len(radius)
            s_c.append(center)
            s_r.append(radius)
        for name, value in (capsules or {}).items():
            if name not in index:
                raise ValueError(f"capsules: unknown link {name!r} (links: {links})")
            where = f"capsules[{name!r}]"
            a, b, radius = _fields(value, where, ("a (k, 3)", "b (k, 3)", "radii (k,)"))
            try:
                cap = Capsules.create(
                    _link_points(a, "a"), _link_points(b, "b"), radius, np.float64
                )
            except ValueError as err:
                raise ValueError(f"{where}: {err}") from None
            c_link += [index[name]] * len(cap)
            c_a.append(np.asarray(cap.a))
            c_b.append(np.asarray(cap.b))
            c_r.append(np.asarray(cap.radius))
        dtype = dtype or jnp.result_type(float)

        def stack(parts: list[np.ndarray], tail: tuple[int, ...]) -> jax.Array:
            arr = np.concatenate(parts) if parts else np.zeros((0, *tail))
            return jnp.asarray(arr, dtype=dtype)

        return cls(
            stack(s_c, (3,)),
            stack(s_r, ()),
            stack(c_a, (3,)),
            stack(c_b, (3,)),
            stack(c_r, ()),
            tuple(s_link),
            tuple(c_link),
            links,
        )

    @classmethod
    def of_capsules(
        cls, links: tuple[str, ...], capsule_link: tuple[int, ...], a: Any, b: Any, radius: Any
    ) -> Body:
        """A body of capsules only, from arrays ``a, b (nc, 3)``, ``radius (nc,)`` (link index
        per capsule static): no host-side checks, so that it can be built from traced
        geometry (a robot's lengths under ``jit``)."""
        a, b = jnp.asarray(a), jnp.asarray(b)
        dtype = jnp.result_type(a, b, radius, float)
        radius = jnp.broadcast_to(jnp.asarray(radius, dtype), (len(capsule_link),))
        empty = jnp.zeros((0, 3), dtype)
        return cls(
            empty,
            jnp.zeros((0,), dtype),
            a.astype(dtype),
            b.astype(dtype),
            radius,
            (),
            tuple(capsule_link),
            tuple(links),
        )

    @property
    def num_spheres(self) -> int:
        return len(self.sphere_link)

    @property
    def num_capsules(self) -> int:
        return len(self.capsule_link)

    def astype(self, dtype) -> Body:
        return jax.tree.map(lambda x: x.astype(dtype), self)

    def per_link(self) -> tuple[dict, dict]:
        """Host-side ``(spheres, capsules)`` dictionaries by link name, as ``create`` takes."""
        spheres: dict = {}
        capsules: dict = {}
        s_link, c_link = np.asarray(self.sphere_link, int), np.asarray(self.capsule_link, int)
        for i, name in enumerate(self.links):
            s, c = s_link == i, c_link == i
            if s.any():
                spheres[name] = (
                    np.asarray(self.sphere_center)[s],
                    np.asarray(self.sphere_radius)[s],
                )
            if c.any():
                capsules[name] = (
                    np.asarray(self.capsule_a)[c],
                    np.asarray(self.capsule_b)[c],
                    np.asarray(self.capsule_radius)[c],
                )
        return spheres, capsules

    def with_link_spheres(self, spheres: Mapping[str, tuple[ArrayLike, ArrayLike]]) -> Body:
        """This body with the given links' primitives replaced by the user's own spheres."""
        own_s, own_c = self.per_link()
        for name in spheres:
            if name not in self.links:
                raise ValueError(f"spheres: unknown link {name!r} (links: {self.links})")
            own_s.pop(name, None)
            own_c.pop(name, None)
        return Body.create(self.links, {**own_s, **spheres}, own_c, dtype=self.sphere_radius.dtype)

    def place(self, link_poses: jax.Array) -> tuple[Spheres, Capsules]:
        """The primitives in the world frame, given every link's pose.

        Args:
            link_poses: ``(..., len(links), 4, 4)`` homogeneous transforms, world <- link.

        Returns:
            ``(Spheres, Capsules)`` with shapes ``(..., ns, 3)`` / ``(..., nc, 3)``.
        """
        if link_poses.shape[-3:] != (len(self.links), 4, 4):
            raise ValueError(
                f"link_poses: expected shape (..., {len(self.links)}, 4, 4), got {link_poses.shape}"
            )

        def to_world(points: jax.Array, link: tuple[int, ...]) -> jax.Array:
            pose = link_poses[..., np.asarray(link, dtype=np.int32), :, :]
            p = points.astype(pose.dtype)
            # written out: a batched 3x3 product is an unfused, slow dot on CPU
            rows = [
                pose[..., i, 0] * p[..., 0]
                + pose[..., i, 1] * p[..., 1]
                + pose[..., i, 2] * p[..., 2]
                + pose[..., i, 3]
                for i in range(3)
            ]
            return jnp.stack(rows, axis=-1)

        dtype = link_poses.dtype
        batch = link_poses.shape[:-3]
        spheres = Spheres(
            to_world(self.sphere_center, self.sphere_link),
            jnp.broadcast_to(self.sphere_radius.astype(dtype), (*batch, self.num_spheres)),
        )
        capsules = Capsules(
            to_world(self.capsule_a, self.capsule_link),
            to_world(self.capsule_b, self.capsule_link),
            jnp.broadcast_to(self.capsule_radius.astype(dtype), (*batch, self.num_capsules)),
        )
        return spheres, capsules
