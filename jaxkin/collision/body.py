"""A robot's body for collision: spheres and capsules attached to its links, as data.

``Body`` lists spheres (centre and radius in their link's frame) and capsules (end points and
radius in their link's frame), each with the index of its link in ``Body.links``. Positions and
radii are array leaves (a different radius or a moved sphere does not recompile, and a body can
be differentiated); the link of each primitive and the link names are static. ``place`` maps
the primitives to the world given every link's pose, for any leading batch of configurations;
the robot that owns the body supplies those poses.

The coarse level: bounding spheres per link (``bound_*``), each containing a static group
of that link's primitives (``sphere_bound``, ``capsule_bound``), for a pass that rules out
most pairs before the primitives are tested (``place_bounds``; ``collision.culled``, the
verdict of a body of many spheres). A link's primitives form one group, split in two along
the principal axis of their centres while it holds more than ``GROUP_SIZE`` primitives (at a
multiple of ``GROUP_SIZE``, so that the groups are full) or, up to ``MAX_BOUNDS`` groups per
link, at the median while the two halves' bounding volumes together are at most half the
whole's (a long link gets a few, a compact one of few primitives a single sphere). A
bounding sphere's centre is the middle of its group's bounding box, its radius ``max |c - g| +
r`` over the group's spheres and capsule end points (a capsule's farthest point from ``g`` is
an end point's), so it contains every primitive of its group.

``save`` and ``load``: a body as a NumPy ``.npz`` archive (read without pickle), so covers
computed once per robot serve every later process.
"""

from __future__ import annotations

import dataclasses
import os
import tempfile
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from numpy.typing import ArrayLike  # host data: lists too

from .._validate import on_device
from .primitives import Capsules, Spheres, _sphere_arrays

__all__ = ["GROUP_SIZE", "MAX_BOUNDS", "Body"]

MAX_BOUNDS = 8  # bounding spheres per link at most from the volume rule
# Primitives per bounding sphere at most: 12 ran the culled verdict fastest (8, 10, 16 slower)
GROUP_SIZE = 12
_FORMAT = 1  # version of the saved archive


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


def _bounding(
    s_c: np.ndarray, s_r: np.ndarray, c_a: np.ndarray, c_b: np.ndarray, c_r: np.ndarray
) -> tuple[np.ndarray, float]:
    """The sphere ``(g, R)`` holding the spheres ``(s_c, s_r)`` and capsules ``(c_a, c_b,
    c_r)``: ``g`` the middle of their bounding box, ``R`` the exact largest reach from ``g``."""
    lo = np.concatenate([s_c - s_r[:, None], c_a - c_r[:, None], c_b - c_r[:, None]])
    hi = np.concatenate([s_c + s_r[:, None], c_a + c_r[:, None], c_b + c_r[:, None]])
    g = 0.5 * (lo.min(axis=0) + hi.max(axis=0))
    reach = np.concatenate(
        [
            np.linalg.norm(s_c - g, axis=1) + s_r,
            np.maximum(np.linalg.norm(c_a - g, axis=1), np.linalg.norm(c_b - g, axis=1)) + c_r,
        ]
    )
    return g, float(reach.max())


def _groups(
    s_c: np.ndarray, s_r: np.ndarray, c_a: np.ndarray, c_b: np.ndarray, c_r: np.ndarray
) -> list[tuple[np.ndarray, np.ndarray]]:
    """One link's primitives in groups (module docstring): ``(sphere indices, capsule
    indices)`` per group."""
    mid = np.concatenate([s_c, 0.5 * (c_a + c_b)])
    ns = len(s_c)

    def ball(members: np.ndarray) -> float:
        s, c = members[members < ns], members[members >= ns] - ns
        return _bounding(s_c[s], s_r[s], c_a[c], c_b[c], c_r[c])[1]

    groups = [np.arange(len(mid))]
    while True:
        best = None
        for k, members in enumerate(groups):
            if len(members) < 2:
                continue
            centred = mid[members] - mid[members].mean(axis=0)
            axis = np.linalg.svd(centred, full_matrices=False)[2][0]
            along = centred @ axis
            if len(members) > GROUP_SIZE:  # whole groups of GROUP_SIZE on one side
                order = np.argsort(along, kind="stable")
                cut = (-(-len(members) // GROUP_SIZE) + 1) // 2 * GROUP_SIZE
                best = (-1.0, k, (members[order[:cut]], members[order[cut:]]))
                break
            if len(groups) >= MAX_BOUNDS:
                continue
            lower = along <= np.median(along)
            if lower.all():
                continue
            halves = (members[lower], members[~lower])
            gain = (ball(halves[0]) ** 3 + ball(halves[1]) ** 3) / ball(members) ** 3
            if gain <= 0.5 and (best is None or gain < best[0]):
                best = (gain, k, halves)
        if best is None:
            break
        _, k, halves = best
        groups[k : k + 1] = list(halves)
    return [(m[m < ns], m[m >= ns] - ns) for m in groups]


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
        bound_center: ``(nb, 3)``, the coarse level's bounding spheres (module docstring), in
            the frame of link ``links[bound_link[j]]``.
        bound_radius: ``(nb,)``.
        bound_link: static tuple of link indices, one per bounding sphere (a link's are
            consecutive, links in increasing order).
        sphere_bound, capsule_bound: static tuples, per primitive the index of the bounding
            sphere that contains it.
    """

    sphere_center: jax.Array
    sphere_radius: jax.Array
    capsule_a: jax.Array
    capsule_b: jax.Array
    capsule_radius: jax.Array
    sphere_link: tuple[int, ...] = dataclasses.field(metadata={"static": True})
    capsule_link: tuple[int, ...] = dataclasses.field(metadata={"static": True})
    links: tuple[str, ...] = dataclasses.field(metadata={"static": True})
    bound_center: jax.Array = None  # type: ignore[assignment]
    bound_radius: jax.Array = None  # type: ignore[assignment]
    bound_link: tuple[int, ...] = dataclasses.field(default=(), metadata={"static": True})
    sphere_bound: tuple[int, ...] = dataclasses.field(default=(), metadata={"static": True})
    capsule_bound: tuple[int, ...] = dataclasses.field(default=(), metadata={"static": True})

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

        def stack(parts: list[np.ndarray], tail: tuple[int, ...]) -> np.ndarray:
            return np.concatenate(parts) if parts else np.zeros((0, *tail))

        spheres_ = (stack(s_c, (3,)), stack(s_r, ()), tuple(s_link))
        capsules_ = (stack(c_a, (3,)), stack(c_b, (3,)), stack(c_r, ()), tuple(c_link))
        return cls._assemble(links, spheres_, capsules_, dtype)

    @classmethod
    def _assemble(cls, links: tuple[str, ...], spheres: tuple, capsules: tuple, dtype) -> Body:
        """A body from host arrays ``spheres = (centers, radii, link)`` and ``capsules = (a, b,
        radii, link)`` (checked), its coarse level computed link by link."""
        s_c, s_r, s_link = spheres
        c_a, c_b, c_r, c_link = capsules
        s_of, c_of = np.asarray(s_link, np.int64), np.asarray(c_link, np.int64)
        b_c: list[np.ndarray] = []
        b_r: list[float] = []
        b_link: list[int] = []
        s_bound, c_bound = np.zeros(len(s_of), np.int64), np.zeros(len(c_of), np.int64)
        for k in sorted(set(s_link) | set(c_link)):
            s_idx, c_idx = np.flatnonzero(s_of == k), np.flatnonzero(c_of == k)
            parts = (s_c[s_idx], s_r[s_idx], c_a[c_idx], c_b[c_idx], c_r[c_idx])
            for s_in, c_in in _groups(*parts):
                s_bound[s_idx[s_in]], c_bound[c_idx[c_in]] = len(b_r), len(b_r)
                g, r = _bounding(
                    s_c[s_idx[s_in]], s_r[s_idx[s_in]], *(x[c_idx[c_in]] for x in (c_a, c_b, c_r))
                )
                b_c.append(g)
                b_r.append(r * (1.0 + 1e-6))  # survives rounding to float32
                b_link.append(k)
        dtype = dtype or jnp.result_type(float)

        def arr(x: Any, tail: tuple[int, ...] = ()) -> jax.Array:
            return on_device(np.asarray(x, dtype=float).reshape(-1, *tail), dtype)

        return cls(
            arr(s_c, (3,)),
            arr(s_r),
            arr(c_a, (3,)),
            arr(c_b, (3,)),
            arr(c_r),
            tuple(int(i) for i in s_link),
            tuple(int(i) for i in c_link),
            tuple(links),
            arr(b_c, (3,)),
            arr(b_r),
            tuple(b_link),
            tuple(int(i) for i in s_bound),
            tuple(int(i) for i in c_bound),
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
        a, b = a.astype(dtype), b.astype(dtype)
        radius = jnp.broadcast_to(jnp.asarray(radius, dtype), (len(capsule_link),))
        # the coarse level: one bounding sphere per link (traceable arrays, static grouping)
        owners = sorted(set(capsule_link))
        group = np.asarray([owners.index(k) for k in capsule_link], dtype=np.int32)
        lo = jax.ops.segment_min(jnp.minimum(a, b) - radius[:, None], group, len(owners))
        hi = jax.ops.segment_max(jnp.maximum(a, b) + radius[:, None], group, len(owners))
        g = 0.5 * (lo + hi)
        ends = jnp.maximum(
            jnp.linalg.norm(a - g[group], axis=-1), jnp.linalg.norm(b - g[group], axis=-1)
        )
        reach = jax.ops.segment_max(ends + radius, group, len(owners)) * (1.0 + 1e-6)
        empty = jnp.zeros((0, 3), dtype)
        return cls(
            empty,
            jnp.zeros((0,), dtype),
            a,
            b,
            radius,
            (),
            tuple(capsule_link),
            tuple(links),
            g.reshape(-1, 3),
            reach.reshape(-1),
            tuple(owners),
            (),
            tuple(int(i) for i in group),
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

    @property
    def num_bounds(self) -> int:
        return len(self.bound_link)

    def place_bounds(self, link_poses: jax.Array) -> Spheres:
        """The coarse level's bounding spheres in the world frame, given every link's pose
        ``(..., len(links), 4, 4)``: ``Spheres`` of shape ``(..., nb, 3)``."""
        coarse = Body(
            self.bound_center, self.bound_radius, self.capsule_a[:0], self.capsule_b[:0],
            self.capsule_radius[:0], self.bound_link, (), self.links,
            self.bound_center[:0], self.bound_radius[:0],
        )  # fmt: skip
        return coarse.place(link_poses)[0]

    def save(self, path: str | os.PathLike) -> None:
        """Write the body to ``path``, a NumPy ``.npz`` archive of its fields (``load`` reads
        it back equal, without pickle); the file is replaced whole or not at all."""
        leaves = jax.tree.leaves(self)
        if any(isinstance(x, jax.core.Tracer) for x in leaves):
            raise ValueError("Body.save: the body's arrays must be values, not traced")
        arrays = {"format": np.array(_FORMAT), "links": np.array(self.links, dtype=str)}
        for field in dataclasses.fields(self):
            if field.name != "links":
                value = getattr(self, field.name)
                static = field.metadata.get("static")
                arrays[field.name] = np.asarray(value, np.int64) if static else np.asarray(value)
        target = Path(path)
        fd, tmp = tempfile.mkstemp(prefix=f".{target.name}.", dir=target.parent)
        try:
            with os.fdopen(fd, "wb") as f:
                np.savez(f, allow_pickle=False, **arrays)
            os.replace(tmp, target)
        except BaseException:
            Path(tmp).unlink(missing_ok=True)
            raise

    @classmethod
    def load(cls, path: str | os.PathLike) -> Body:
        """A body written by ``save``; a ``ValueError`` naming the file when it is not one
        (unreadable, another format, inconsistent counts or indices, values that are not
        finite, negative radii, a primitive outside its bounding sphere)."""
        where = f"Body.load: {os.fspath(path)!r}"
        try:
            with np.load(path, allow_pickle=False) as data:
                arrays = {key: data[key] for key in data.files}
        except (OSError, ValueError, EOFError) as exc:
            raise ValueError(f"{where}: not a readable body archive ({exc})") from None
        names = [field.name for field in dataclasses.fields(cls)]
        missing = [name for name in ["format", *names] if name not in arrays]
        if missing or arrays["format"].shape != () or int(arrays["format"]) != _FORMAT:
            raise ValueError(f"{where}: not a body archive of format {_FORMAT} (missing {missing})")
        try:
            return cls._checked(arrays)
        except (ValueError, TypeError, IndexError) as exc:
            raise ValueError(f"{where}: {exc}") from None

    @classmethod
    def _checked(cls, arrays: dict) -> Body:
        """A body from the archive's arrays, each checked (``load``)."""
        links = tuple(str(x) for x in arrays["links"].reshape(-1))
        statics: dict[str, Any] = {}
        for field in dataclasses.fields(cls):
            if field.metadata.get("static") and field.name != "links":
                values = arrays[field.name]
                if values.ndim != 1 or not np.issubdtype(values.dtype, np.integer):
                    raise ValueError(f"{field.name}: expected integers")
                statics[field.name] = tuple(int(i) for i in values)
        data = {}
        for field in dataclasses.fields(cls):
            if not field.metadata.get("static"):
                value = arrays[field.name]
                if not np.issubdtype(value.dtype, np.floating) or not np.all(np.isfinite(value)):
                    raise ValueError(f"{field.name}: expected finite floats")
                data[field.name] = value
        counts = {
            "sphere": (len(statics["sphere_link"]), len(statics["sphere_bound"])),
            "capsule": (len(statics["capsule_link"]), len(statics["capsule_bound"])),
            "bound": (len(statics["bound_link"]),) * 2,
        }
        shapes = {
            "sphere_center": ("sphere", 3),
            "sphere_radius": ("sphere", None),
            "capsule_a": ("capsule", 3),
            "capsule_b": ("capsule", 3),
            "capsule_radius": ("capsule", None),
            "bound_center": ("bound", 3),
            "bound_radius": ("bound", None),
        }
        for name, (kind, tail) in shapes.items():
            n, m = counts[kind]
            want = (n,) if tail is None else (n, tail)
            if n != m or data[name].shape != want:
                raise ValueError(f"{name}: shape {data[name].shape}, expected {want}")
            if tail is None and np.any(data[name] < 0):
                raise ValueError(f"{name}: negative radii")
        for name in ("sphere_link", "capsule_link", "bound_link"):
            if not all(0 <= i < len(links) for i in statics[name]):
                raise ValueError(f"{name}: a link index out of range")
        for kind, ends in (("sphere", ("sphere_center",)), ("capsule", ("capsule_a", "capsule_b"))):
            bound = np.asarray(statics[f"{kind}_bound"], np.int64)
            if np.any(bound < 0) or np.any(bound >= counts["bound"][0]):
                raise ValueError(f"{kind}_bound: an index out of range")
            if np.any(
                np.asarray(statics["bound_link"], np.int64)[bound] != statics[f"{kind}_link"]
            ):
                raise ValueError(f"{kind}_bound: a bounding sphere of another link")
            g, r = data["bound_center"][bound], data["bound_radius"][bound]
            for end in ends:
                reach = np.linalg.norm(data[end] - g, axis=-1) + data[f"{kind}_radius"]
                if np.any(reach > r * (1 + 1e-5)):
                    raise ValueError(f"{kind}_bound: a primitive outside its bounding sphere")
        fields: dict[str, Any] = {name: jnp.asarray(value) for name, value in data.items()}
        return cls(**fields, **statics, links=links)
