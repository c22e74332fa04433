"""World files: the obstacles of a ``World`` as JSON or YAML, read back exactly.

A world file (``"format": "jaxkin-world"``, ``"version": 1``; both optional) is one mapping:

- ``units`` (required): the length unit of every number in the file, ``"m"``, ``"cm"`` or
  ``"mm"``; ``read_world(path, units=...)`` converts to another;
- ``frame`` (optional text, for the reader): the frame the obstacles are given in. jaxkin
  takes them in the robot's base frame, the frame of ``robot.link_poses`` (a URDF chain's
  base link);
- one list per kind of obstacle, each entry a mapping (an optional ``name`` is kept for
  error messages only):

  - ``spheres``: ``center [x, y, z]``, ``radius``;
  - ``capsules``: ``a``, ``b`` (the segment's end points), ``radius``;
  - ``boxes``: ``center``, ``half_extents [hx, hy, hz]``, an optional orientation;
  - ``cylinders``: ``center``, ``radius``, ``half_length``, and ``axis [x, y, z]`` or an
    orientation (the cylinder lies along its frame's z axis; along z without either);
  - ``halfspaces``: ``normal``, ``offset``: the solid ``normal . x <= offset``;
  - ``point_clouds``: ``points [[x, y, z], ...]`` or ``file`` (a ``.npy`` array, or a text
    file of three columns separated by commas or blanks, relative to the world file),
    ``voxel`` and an optional ``point_radius``: read as the spheres of
    ``point_cloud_spheres(points, voxel, point_radius)``, which hold every point.

  An orientation is ``rotation`` (a 3x3 rotation matrix, row by row: its columns are the
  obstacle's axes) or ``quaternion [w, x, y, z]`` (any non-zero length).

The suffix chooses the syntax: ``.json``, or ``.yaml`` / ``.yml`` (PyYAML, the ``yaml``
extra). ``write_world`` writes every number in the shortest form that reads back to the same
float, so a world read back is the world written, array for array (a point cloud is written
as the spheres it became). Every error names the file and the entry, e.g.
``scene.json: cylinders[2] ("post"): radius must be >= 0``.
"""

from __future__ import annotations

import json
import os
import tempfile
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

import numpy as np

from .. import lie
from . import _yaml, moveit
from .primitives import (
    Boxes,
    Capsules,
    Cylinders,
    HalfSpaces,
    Spheres,
    point_cloud_spheres,
)
from .world import World

__all__ = ["FORMAT", "UNITS", "read_world", "write_world"]

FORMAT = "jaxkin-world"
VERSION = 1
UNITS = {"m": 1.0, "cm": 0.01, "mm": 0.001}  # metres per unit
_SUFFIXES = {".json": "json", ".yaml": "yaml", ".yml": "yaml"}

# per kind: required keys, optional keys (besides "name")
_KEYS = {
    "spheres": (("center", "radius"), ()),
    "capsules": (("a", "b", "radius"), ()),
    "boxes": (("center", "half_extents"), ("rotation", "quaternion")),
    "cylinders": (("center", "radius", "half_length"), ("axis", "rotation", "quaternion")),
    "halfspaces": (("normal", "offset"), ()),
    "point_clouds": (("voxel",), ("points", "file", "point_radius")),
}
_TOP = ("format", "version", "units", "frame", *_KEYS)


def _syntax(path: Path) -> str:
    syntax = _SUFFIXES.get(path.suffix.lower())
    if syntax is None:
        raise ValueError(
            f"{path}: a world file is .json, .yaml or .yml, got the suffix {path.suffix!r}"
        )
    return syntax


def _load(path: Path) -> Any:
    if not path.is_file():
        raise ValueError(f"path: no such world file {str(path)!r}")
    if _syntax(path) == "yaml":
        return _yaml.load(path)
    try:
        return json.loads(path.read_text(encoding="utf-8"))
    except json.JSONDecodeError as exc:
        raise ValueError(
            f"{path}: not readable JSON ({exc.msg} at line {exc.lineno}, column {exc.colno})"
        ) from None


def _rotation(entry: Mapping, where: str) -> np.ndarray | None:
    """The entry's ``rotation`` or ``quaternion`` as a matrix, None when it gives neither."""
    if "rotation" in entry and "quaternion" in entry:
        raise ValueError(f"{where}: give rotation or quaternion, not both")
    if "quaternion" in entry:
        q = _numbers(entry["quaternion"], where, "quaternion", (4,))
        if not np.any(q):
            raise ValueError(f"{where}: quaternion is zero (give [w, x, y, z], any length)")
        return np.asarray(lie.quaternion_to_matrix(q / np.abs(q).max(), xp=np))
    if "rotation" in entry:
        return _numbers(entry["rotation"], where, "rotation", (3, 3))
    return None


def _numbers(value: Any, where: str, key: str, shape: tuple[int, ...]) -> np.ndarray:
    """``value`` as a float array of ``shape`` (any shape for ``None``), or a ``ValueError``
    naming the entry and the key."""
    try:
        arr = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError(f"{where}: {key} must be numbers, got {value!r}") from None
    if arr.shape != shape:
        want = "a number" if shape == () else f"shape {list(shape)}"
        raise ValueError(f"{where}: {key} must be {want}, got {np.shape(value)}")
    return arr


def _point_cloud(entry: Mapping, where: str, folder: Path, dtype) -> Spheres:
    if ("points" in entry) == ("file" in entry):
        raise ValueError(f"{where}: give points or file (one of them)")
    if "file" in entry:
        source = folder / str(entry["file"])
        if not source.is_file():
            raise ValueError(f"{where}: no such point file {str(source)!r}")
        try:
            if source.suffix.lower() == ".npy":
                points = np.load(source, allow_pickle=False)
            else:
                text = source.read_text(encoding="utf-8").replace(",", " ")
                points = np.loadtxt(text.splitlines(), ndmin=2)
        except (OSError, ValueError) as exc:
            raise ValueError(f"{where}: {source} is not readable points ({exc})") from None
    else:
        points = entry["points"]
    voxel = _numbers(entry["voxel"], where, "voxel", ())
    point_radius = _numbers(entry.get("point_radius", 0.0), where, "point_radius", ())
    return point_cloud_spheres(
        np.asarray(points, dtype=float), float(voxel), float(point_radius), dtype
    )


def _builders(folder: Path) -> dict[str, Callable[[Mapping, str], Any]]:
    """Per kind, the one-entry primitive (validated by its ``create``)."""

    def point3(entry, where, key):
        return _numbers(entry[key], where, key, (3,))[None]

    def number(entry, where, key):
        return _numbers(entry[key], where, key, ())

    def cylinders(entry, where):
        rotation = _rotation(entry, where)
        if rotation is not None and "axis" in entry:
            raise ValueError(f"{where}: give axis or an orientation, not both")
        axis = point3(entry, where, "axis") if "axis" in entry else None
        return Cylinders.create(
            point3(entry, where, "center"),
            number(entry, where, "radius"),
            number(entry, where, "half_length"),
            axis=axis,
            rotation=None if rotation is None else rotation[None],
            dtype=np.float64,
        )

    def boxes(entry, where):
        rotation = _rotation(entry, where)
        return Boxes.create(
            point3(entry, where, "center"),
            point3(entry, where, "half_extents"),
            None if rotation is None else rotation[None],
            dtype=np.float64,
        )

    return {
        "spheres": lambda e, w: Spheres.create(
            point3(e, w, "center"), number(e, w, "radius"), np.float64
        ),
        "capsules": lambda e, w: Capsules.create(
            point3(e, w, "a"), point3(e, w, "b"), number(e, w, "radius"), np.float64
        ),
        "boxes": boxes,
        "cylinders": cylinders,
        "halfspaces": lambda e, w: HalfSpaces.create(
            point3(e, w, "normal"), number(e, w, "offset"), np.float64
        ),
        "point_clouds": lambda e, w: _point_cloud(e, w, folder, np.float64),
    }


def _entries(document: Mapping, kind: str, path: Path) -> list[tuple[Mapping, str]]:
    """The entries of one kind with their names for messages (``kind[i] ("name")``)."""
    entries = document.get(kind) or []
    if not isinstance(entries, list):
        raise ValueError(f"{path}: {kind} must be a list of entries, got {type(entries).__name__}")
    required, optional = _KEYS[kind]
    out = []
    for i, entry in enumerate(entries):
        where = f"{path}: {kind}[{i}]"
        if not isinstance(entry, Mapping):
            raise ValueError(f"{where}: expected a mapping of keys, got {type(entry).__name__}")
        if "name" in entry:
            where += f" ({str(entry['name'])!r})"
        unknown = sorted(set(entry) - {*required, *optional, "name"})
        if unknown:
            raise ValueError(
                f"{where}: unknown key {unknown[0]!r} (keys: {', '.join((*required, *optional))})"
            )
        missing = [key for key in required if key not in entry]
        if missing:
            raise ValueError(f"{where}: missing {missing[0]!r}")
        out.append((entry, where))
    return out


def _scaled(prim: Any, factor: float) -> Any:
    """A primitive's lengths times ``factor`` (directions and rotations unchanged)."""
    if factor == 1.0:
        return prim
    lengths = {
        Spheres: ("center", "radius"),
        Capsules: ("a", "b", "radius"),
        Boxes: ("center", "half_extents"),
        Cylinders: ("center", "radius", "half_length"),
        HalfSpaces: ("offset",),
    }[type(prim)]
    fields = {k: getattr(prim, k) for k in prim.__dataclass_fields__}
    return type(prim)(**{k: v * factor if k in lengths else v for k, v in fields.items()})


def _unit(units: Any) -> float:
    if units not in UNITS:
        raise ValueError(f"units must be one of {', '.join(UNITS)}, got {units!r}")
    return UNITS[units]


def _converted(world: World, factor: float) -> World:
    kinds = {f: _scaled(getattr(world, f), factor) for f in world.__dataclass_fields__}
    return World(**kinds)


def read_world(path: str | os.PathLike, units: str | None = None, dtype=None) -> World:
    """The ``World`` of a world file (module docstring).

    A YAML file without ``units`` that holds ``world.collision_objects`` is a MoveIt planning
    scene, read by ``read_moveit_scene`` (metres).

    Args:
        path: a ``.json``, ``.yaml`` or ``.yml`` world file, or a MoveIt planning scene.
        units: the unit the world is wanted in (``"m"``, ``"cm"``, ``"mm"``); None keeps the
            file's.
        dtype: of the world's arrays (default: JAX's default float).

    Raises:
        ValueError: no such file, a syntax error, an unknown unit, key or kind, a missing key,
            or an entry a primitive's ``create`` refuses; the message names the file and the
            entry.
        ImportError: a YAML file without PyYAML (the ``yaml`` extra).
    """
    path = Path(path)
    document = _load(path)
    if not isinstance(document, Mapping):
        raise ValueError(
            f"{path}: a world file is one mapping of keys, got {type(document).__name__}"
        )
    if "units" not in document and ("world" in document or "collision_objects" in document):
        world = moveit.scene_world(document, path, dtype)  # a MoveIt planning scene: metres
        return world if units is None else _converted(world, UNITS["m"] / _unit(units))
    unknown = sorted(set(document) - set(_TOP))
    if unknown:
        raise ValueError(f"{path}: unknown key {unknown[0]!r} (keys: {', '.join(_TOP)})")
    if document.get("format", FORMAT) != FORMAT:
        raise ValueError(f"{path}: format must be {FORMAT!r}, got {document['format']!r}")
    if document.get("version", VERSION) != VERSION:
        raise ValueError(f"{path}: version {document['version']!r} is not read (only {VERSION})")
    if "units" not in document:
        raise ValueError(f"{path}: missing 'units' (the length unit: {', '.join(UNITS)})")
    if document["units"] not in UNITS:
        raise ValueError(
            f"{path}: units must be one of {', '.join(UNITS)}, got {document['units']!r}"
        )
    factor = 1.0 if units is None else UNITS[document["units"]] / _unit(units)
    builders = _builders(path.parent)
    parts: dict[str, list] = {kind: [] for kind in _KEYS}
    for kind in _KEYS:
        for entry, where in _entries(document, kind, path):
            try:
                parts[kind].append(builders[kind](entry, where))
            except ValueError as exc:
                message = str(exc)
                raise ValueError(
                    message if message.startswith(where) else f"{where}: {message}"
                ) from None
    parts["spheres"] += parts.pop("point_clouds")
    kinds: dict[str, Any] = {
        "spheres": Spheres,
        "capsules": Capsules,
        "boxes": Boxes,
        "cylinders": Cylinders,
        "halfspaces": HalfSpaces,
    }
    given = {}
    for kind, cls in kinds.items():
        if not parts[kind]:
            continue
        fields = cls.__dataclass_fields__
        joined = cls(*(np.concatenate([np.asarray(getattr(p, f)) for p in parts[kind]])
                       for f in fields))  # fmt: skip
        given[kind] = _scaled(joined, factor)
    return World.create(**given, dtype=dtype)


def _rows(world: World) -> dict[str, list[dict]]:
    """The world's obstacles as file entries (host side, Python floats)."""

    def listed(x: Any) -> Any:
        return np.asarray(x, dtype=np.float64).tolist()

    s, c, b, y, h = world.spheres, world.capsules, world.boxes, world.cylinders, world.halfspaces
    boxes = []
    for i in range(len(b)):
        entry = {"center": listed(b.center[i]), "half_extents": listed(b.half_extents[i])}
        rotation = np.asarray(b.rotation[i])
        if not np.array_equal(rotation, np.eye(3)):
            entry["rotation"] = listed(rotation)
        boxes.append(entry)
    return {
        "spheres": [{"center": listed(s.center[i]), "radius": listed(s.radius[i])}
                    for i in range(len(s))],
        "capsules": [{"a": listed(c.a[i]), "b": listed(c.b[i]), "radius": listed(c.radius[i])}
                     for i in range(len(c))],
        "boxes": boxes,
        "cylinders": [{"center": listed(y.center[i]), "axis": listed(y.axis[i]),
                       "radius": listed(y.radius[i]), "half_length": listed(y.half_length[i])}
                      for i in range(len(y))],
        "halfspaces": [{"normal": listed(h.normal[i]), "offset": listed(h.offset[i])}
                       for i in range(len(h))],
    }  # fmt: skip


def write_world(
    world: World, path: str | os.PathLike, units: str = "m", frame: str | None = None
) -> None:
    """Write ``world`` as a world file (JSON or YAML by the suffix), atomically: a temporary
    file beside ``path`` renamed over it when complete.

    Args:
        world: a ``World`` without leading batch axes.
        path: ``.json``, ``.yaml`` or ``.yml``.
        units: the unit of the world's numbers (``"m"``, ``"cm"``, ``"mm"``): written as the
            file's ``units``, the numbers are not converted.
        frame: the frame the obstacles are given in, written as ``frame`` when given.

    Raises:
        ValueError: not a ``World``, a world with leading batch axes, an unknown unit or
            suffix.
    """
    path = Path(path)
    syntax = _syntax(path)
    if not isinstance(world, World):
        raise ValueError(f"world: expected a collision.World, got {type(world).__name__}")
    if units not in UNITS:
        raise ValueError(f"units must be one of {', '.join(UNITS)}, got {units!r}")
    sizes = (world.spheres.radius, world.capsules.radius, world.cylinders.radius)
    if any(np.ndim(x) != 1 for x in sizes) or world.boxes.center.ndim != 2:
        raise ValueError("world: a world with leading batch axes cannot be written (one world)")
    document: dict[str, Any] = {"format": FORMAT, "version": VERSION, "units": units}
    if frame is not None:
        document["frame"] = str(frame)
    document.update({kind: rows for kind, rows in _rows(world).items() if rows})
    text = _yaml.dump(document, path) if syntax == "yaml" else json.dumps(document, indent=1) + "\n"
    handle, temporary = tempfile.mkstemp(dir=path.parent or Path("."), prefix=f".{path.name}.")
    try:
        with os.fdopen(handle, "w", encoding="utf-8") as f:
            f.write(text)
        os.replace(temporary, path)
    except BaseException:
        Path(temporary).unlink(missing_ok=True)
        raise
