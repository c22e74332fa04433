"""A robot's collision body and kinematic tree read from a URDF's ``<collision>`` elements.

Reading (``read_collision``, standard library only): the URDF (a path or its XML text, with or
without an XML declaration naming its encoding) is parsed once; each ``<collision>`` element
of a link is kept with its ``<origin>`` and its numbers, and every mesh file it names is found
and read into memory then (``package://pkg/rel`` as ``pkg/rel`` or ``rel`` under the given
``package_dirs``, then under every parent of the URDF's folder; ``file://`` and relative
paths from the URDF's folder). What is read does not change afterwards: editing or deleting
the URDF or its meshes later changes nothing. Numbers that mean nothing (a box of two numbers,
negative sizes, NaN), a mesh without a file name or a mesh file that cannot be found are
refused with a ``ValueError`` naming the link and the file; ``read_collision`` keeps that
message and raises it when a body is asked for, so that a chain whose collision geometry is
broken still does its kinematics.

Covering (``UrdfCollision.body``), in that link's frame (its ``<origin>`` applied):

- ``<sphere>``: the sphere as given (a "spherized" URDF, spheres only, is taken as it is);
- ``<cylinder>`` (and the non-standard ``<capsule>``): the capsule with the same axis
  segment and radius (it contains the cylinder; it reaches one radius past each flat end);
- ``<box>``: spheres containing the solid box (``cover.box_sphere_cover``, the bound
  ``max_overshoot``, at most ``max_spheres_per_box``: a thin or flat box gets a looser bound,
  never hundreds of spheres);
- ``<mesh>``: spheres containing every triangle (``cover.mesh_sphere_cover``: the bound
  ``max_overshoot``, 1 cm by default, at most ``max_spheres_per_mesh``), the mesh's ``scale``
  applied. STL files are read with NumPy (``stl.read_stl``); other formats (OBJ, DAE, PLY)
  need trimesh (the ``urdf`` extra). With ``max_primitives_per_mesh``, spheres and capsules
  top down instead (``cover.mesh_cover``, which needs SciPy).

A URDF of spheres, cylinders, boxes and STL meshes needs nothing beyond NumPy. ``link_spheres``
replaces the primitives of the named links by the user's own spheres. The covers are computed
once per ``UrdfCollision`` and set of options (a chain keeps its ``UrdfCollision``).
"""

from __future__ import annotations

import dataclasses
import io
import os
import re
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any
from xml.etree import ElementTree

import numpy as np

from .body import Body
from .cover import MeshCover, SphereCover, box_sphere_cover, mesh_cover, mesh_sphere_cover
from .cover_store import cached_cover
from .stl import read_stl

__all__ = [
    "Element",
    "UrdfBody",
    "UrdfCollision",
    "body_from_urdf",
    "origin_matrix",
    "read_collision",
    "read_xml",
]

MESH_SPHERES = 256  # default budget of spheres per mesh (the UR5's upper arm needs 210 at 1 cm)
BOX_SPHERES = 32  # default budget of spheres per box


@dataclasses.dataclass(frozen=True)
class UrdfBody:
    """What ``body_from_urdf`` reads: the ``body``; ``joints`` as ``(parent, child, type)``
    link-name triples (the kinematic tree, for adjacency); and per link the overshoot bound of
    its primitives (how far they can reach past the URDF's geometry: a mesh's or box's cover
    bound, a cylinder's radius, 0 for spheres and links without geometry)."""

    body: Body
    joints: tuple[tuple[str, str, str], ...]
    overshoot: Mapping[str, float]


@dataclasses.dataclass(frozen=True, eq=False)
class Element:
    """One ``<collision>`` element: its ``link``, ``kind`` (``"sphere"``, ``"cylinder"``,
    ``"box"`` or ``"mesh"``), ``pose`` in the link's frame ``(4, 4)``, and ``size``: the
    radius; radius and length; the three edge lengths; or the mesh's three scale factors. A
    mesh also has its ``file`` (as the URDF names it), ``path`` (where it was found) and
    ``data`` (the file's bytes, read with the URDF)."""

    link: str
    kind: str
    pose: np.ndarray
    size: tuple[float, ...]
    file: str = ""
    path: str = ""
    data: bytes = b""


@dataclasses.dataclass(frozen=True, eq=False)
class UrdfCollision:
    """A URDF's collision geometry, read once (module docstring).

    Attributes:
        where: the source for messages (``"source 'path'"`` or ``"source (URDF text)"``).
        links: every link name, in file order.
        joints: ``(parent, child, type)`` per joint.
        elements: the ``<collision>`` elements.
        problem: a ``ValueError`` message raised by ``body`` (bad geometry), or empty.
    """

    where: str
    links: tuple[str, ...]
    joints: tuple[tuple[str, str, str], ...]
    elements: tuple[Element, ...]
    problem: str = ""
    _bodies: dict = dataclasses.field(default_factory=dict, repr=False)

    def body(
        self,
        max_primitives_per_mesh: int | None = None,
        max_overshoot: float | None = 0.01,
        max_spheres_per_mesh: int | None = MESH_SPHERES,
        max_spheres_per_box: int | None = BOX_SPHERES,
    ) -> UrdfBody:
        """The covers of every element (module docstring; ``body_from_urdf`` documents the
        options), computed on the first call with these options and kept."""
        key = (max_primitives_per_mesh, max_overshoot, max_spheres_per_mesh, max_spheres_per_box)
        if key not in self._bodies:
            if self.problem:
                raise ValueError(self.problem)
            self._bodies[key] = _cover(self, *key)
        return self._bodies[key]


def _text_as_utf8(text: str) -> bytes:
    """XML text (already decoded) as UTF-8 bytes, read as a file with the same content is: a
    byte-order mark dropped, an XML declaration's ``encoding`` (e.g. ISO-8859-1, the file's
    encoding, no longer the text's) replaced by UTF-8."""
    text = text.lstrip("\ufeff")
    text = re.sub(
        r"""^(\s*<\?xml[^>]*?\bencoding\s*=\s*)(["']).*?\2""", r"\1\2UTF-8\2", text, count=1
    )
    return text.encode("utf-8")


def read_xml(source: Any, kind: str = "URDF") -> tuple[ElementTree.Element, str, Path]:
    """The root element of a path or XML text (str or bytes), the source's name for messages
    and the folder relative paths start from (the current folder for text)."""
    if isinstance(source, bytes) and source.lstrip(b"\xef\xbb\xbf \t\r\n").startswith(b"<"):
        data, where, folder = source, f"source ({kind} text)", Path.cwd()
    elif isinstance(source, str) and source.lstrip("\ufeff \t\r\n").startswith("<"):
        data, where, folder = _text_as_utf8(source), f"source ({kind} text)", Path.cwd()
    else:
        if isinstance(source, bytes):
            source = os.fsdecode(source)
        if not isinstance(source, str | os.PathLike):
            raise ValueError(f"source: expected a {kind} path or XML text, got {source!r}")
        path = Path(source)
        if not path.is_file():
            raise ValueError(f"source: no such {kind} file {str(path)!r}")
        data, where, folder = path.read_bytes(), f"source {str(path)!r}", path.resolve().parent
    try:
        return ElementTree.fromstring(data), where, folder
    except ElementTree.ParseError as exc:
        raise ValueError(f"{where}: not well-formed XML ({exc})") from None


def origin_matrix(element) -> np.ndarray | None:
    """``<origin xyz rpy>`` as a 4x4 transform ``Trans(xyz) Rz(yaw) Ry(pitch) Rx(roll)`` (fixed
    axes x, y, z), each entry computed as trimesh's ``compose_matrix`` computes it; None
    without an element."""
    if element is None:
        return None
    xyz = [float(v) for v in element.get("xyz", "0 0 0").split()]
    rpy = [float(v) for v in element.get("rpy", "0 0 0").split()]
    if len(xyz) < 3 or len(rpy) < 3:
        raise ValueError(f"<origin> needs three numbers in xyz and rpy, got {xyz} and {rpy}")
    (si, sj, sk), (ci, cj, ck) = np.sin(rpy[:3]), np.cos(rpy[:3])
    cc, cs, sc, ss = ci * ck, ci * sk, si * ck, si * sk
    frame = np.eye(4)
    frame[:3, :3] = [
        [cj * ck, sj * sc - cs, sj * cc + ss],
        [cj * sk, sj * ss + cc, sj * cs - sc],
        [-sj, cj * si, cj * ci],
    ]
    frame[:3, 3] = xyz[:3]
    return frame


def _package_dirs(package_dirs: Any) -> list[Path]:
    """``package_dirs`` as folders: one path (a string or path-like) is one folder."""
    if isinstance(package_dirs, str | bytes | os.PathLike):
        package_dirs = [package_dirs]
    try:
        return [Path(os.fsdecode(p)) for p in package_dirs]
    except TypeError:
        raise ValueError(
            f"package_dirs: expected a folder or a sequence of folders, got {package_dirs!r}"
        ) from None


def _resolve(filename: str, folder: Path, package_dirs: list[Path]) -> Path:
    """The mesh file a URDF names (``package://``, ``file://`` or a relative path); a
    ``ValueError`` (without the link: the caller adds it) when it is not found."""
    name = filename[len("file://") :] if filename.startswith("file://") else filename
    if name.startswith("package://"):
        rel = name[len("package://") :]
        tails = [Path(rel), Path(*Path(rel).parts[1:])]
        for root in [*package_dirs, folder, *folder.parents]:
            for tail in tails:
                if (root / tail).is_file():
                    return root / tail
        raise ValueError(f"mesh {filename!r} not found under package_dirs or the URDF's parents")
    path = Path(name) if Path(name).is_absolute() else folder / name
    if not path.is_file():
        raise ValueError(f"mesh {filename!r}: no such file {str(path)!r}")
    return path


def _numbers(element, attribute: str, count: tuple[int, ...], default: str | None = None):
    """The numbers of an attribute, as many as one of ``count``, finite; ValueError else."""
    text = element.get(attribute, default)
    if text is None:
        raise ValueError(f"<{element.tag}> has no {attribute}")
    try:
        values = tuple(float(v) for v in text.split())
    except ValueError:
        raise ValueError(f"<{element.tag} {attribute}={text!r}>: not numbers") from None
    if len(values) not in count:
        wanted = " or ".join(str(c) for c in count)
        raise ValueError(f"<{element.tag} {attribute}={text!r}>: expected {wanted} numbers")
    if not all(np.isfinite(values)):
        raise ValueError(f"<{element.tag} {attribute}={text!r}>: expected finite numbers")
    return values


def _element(link: str, collision, folder: Path, package_dirs: list[Path]) -> Element:
    """One ``<collision>`` element of ``link``; a ``ValueError`` for what means nothing."""
    pose = origin_matrix(collision.find("origin"))
    pose = np.eye(4) if pose is None else pose
    if not np.all(np.isfinite(pose)):
        raise ValueError("<origin> has a NaN or inf")
    geometry = collision.find("geometry")
    shapes = [] if geometry is None else list(geometry)
    if len(shapes) != 1:
        raise ValueError(f"a <collision> element needs one shape in <geometry>, got {len(shapes)}")
    shape = shapes[0]
    if shape.tag == "sphere":
        size = _numbers(shape, "radius", (1,))
    elif shape.tag in ("cylinder", "capsule"):
        size = _numbers(shape, "radius", (1,)) + _numbers(shape, "length", (1,))
    elif shape.tag == "box":
        size = _numbers(shape, "size", (3,))
    elif shape.tag == "mesh":
        file = shape.get("filename", "").strip()
        if not file:
            raise ValueError("<mesh> has no filename")
        scale = _numbers(shape, "scale", (1, 3), "1 1 1")
        scale = scale * 3 if len(scale) == 1 else scale
        path = _resolve(file, folder, package_dirs)
        return Element(link, "mesh", pose, scale, file, str(path), path.read_bytes())
    else:
        raise ValueError(f"unknown shape <{shape.tag}> in <geometry>")
    if any(v < 0 for v in size):
        raise ValueError(f"<{shape.tag}> has a negative size {size}")
    kind = "cylinder" if shape.tag == "capsule" else shape.tag
    return Element(link, kind, pose, size)


def read_collision(
    source: Any = None,
    package_dirs: Any = (),
    root: ElementTree.Element | None = None,
    where: str = "",
    folder: Path | None = None,
) -> UrdfCollision:
    """The collision geometry of a URDF (module docstring): from ``source`` (a path or XML
    text), or from an already parsed ``root`` with its ``where`` and ``folder``
    (``read_xml``). A problem with an element is kept in ``problem`` (raised by ``body``),
    naming the link and the file; an unreadable URDF raises at once."""
    if root is None:
        root, where, folder = read_xml(source)
    folder = Path.cwd() if folder is None else folder
    dirs = _package_dirs(package_dirs)
    links, elements, problem = [], [], ""
    for link in root.findall("link"):
        name = link.get("name", "")
        links.append(name)
        for collision in link.findall("collision"):
            try:
                elements.append(_element(name, collision, folder, dirs))
            except (ValueError, OSError) as err:
                problem = problem or f"link {name!r} of {where}: {err}"
    joints = []
    for joint in root.findall("joint"):
        parent, child = joint.find("parent"), joint.find("child")
        if parent is None or child is None:
            raise ValueError(f"{where}: joint {joint.get('name')!r} lacks <parent> or <child>")
        joints.append((parent.get("link", ""), child.get("link", ""), joint.get("type", "")))
    return UrdfCollision(where, tuple(links), tuple(joints), tuple(elements), problem)


def _mesh(element: Element, where: str) -> tuple[np.ndarray, np.ndarray]:
    """A mesh element's vertices (scaled, in its link's frame) and faces: STL files read with
    NumPy (``stl.read_stl``), other formats with trimesh."""
    file_type = Path(element.path).suffix.lstrip(".").lower()
    try:
        if file_type == "stl":
            vertices, faces = read_stl(element.data)
        else:
            vertices, faces = _trimesh_mesh(element, where, file_type)
    except (ValueError, TypeError) as exc:
        raise ValueError(
            f"link {element.link!r} of {where}: mesh {element.file!r} is not readable ({exc})"
        ) from None
    if len(faces) == 0 or not np.all(np.isfinite(vertices)):
        what = "has no triangles" if len(faces) == 0 else "has NaN or inf vertices"
        raise ValueError(f"link {element.link!r} of {where}: mesh {element.file!r} {what}")
    vertices = vertices * np.asarray(element.size)
    return vertices @ element.pose[:3, :3].T + element.pose[:3, 3], faces


def _trimesh_mesh(element: Element, where: str, file_type: str) -> tuple[np.ndarray, np.ndarray]:
    try:
        import trimesh
    except ImportError:
        raise ImportError(
            f"link {element.link!r} of {where}: the mesh {element.file!r} needs trimesh, "
            "the 'urdf' extra: pip install 'jaxkin[urdf]'"
        ) from None
    try:
        mesh = trimesh.load_mesh(io.BytesIO(element.data), file_type=file_type)
        return np.asarray(mesh.vertices, float), np.asarray(mesh.faces)
    except Exception as exc:  # a file trimesh cannot decode raises what its parser meets
        raise ValueError(f"{type(exc).__name__}: {exc}") from None


def _cover(
    read: UrdfCollision,
    max_primitives_per_mesh: int | None,
    max_overshoot: float | None,
    max_spheres_per_mesh: int | None,
    max_spheres_per_box: int | None,
) -> UrdfBody:
    spheres: dict[str, list] = {}
    capsules: dict[str, list] = {}
    overshoot: dict[str, float] = {name: 0.0 for name in read.links}

    def add(link: str, found, reach: float) -> None:
        if len(found.radii):
            spheres.setdefault(link, []).append((found.centers, found.radii))
        if len(getattr(found, "capsule_radii", ())):
            capsules.setdefault(link, []).append((found.a, found.b, found.capsule_radii))
        overshoot[link] = max(overshoot[link], reach)

    found: MeshCover | SphereCover
    for element in read.elements:
        pose, link = element.pose, element.link
        if element.kind == "sphere":
            spheres.setdefault(link, []).append((pose[None, :3, 3], np.array(element.size)))
        elif element.kind == "cylinder":
            radius, length = element.size
            ends = np.array([[0.0, 0.0, -0.5 * length], [0.0, 0.0, 0.5 * length]])
            ends = ends @ pose[:3, :3].T + pose[:3, 3]
            capsules.setdefault(link, []).append((ends[:1], ends[1:], np.array([radius])))
            overshoot[link] = max(overshoot[link], radius)
        elif element.kind == "box":
            found = box_sphere_cover(
                0.5 * np.array(element.size), max_spheres_per_box, max_overshoot
            )
            centers = found.centers @ pose[:3, :3].T + pose[:3, 3]
            add(link, dataclasses.replace(found, centers=centers), found.overshoot)
        else:
            vertices, faces = _mesh(element, read.where)
            if max_primitives_per_mesh is not None:
                found = cached_cover(
                    mesh_cover, MeshCover, vertices, faces, max_primitives_per_mesh, max_overshoot
                )
            else:
                found = cached_cover(
                    mesh_sphere_cover, SphereCover, vertices, faces, max_spheres_per_mesh,
                    max_overshoot,
                )  # fmt: skip
            add(link, found, found.overshoot)
    sphere_data = {
        name: (np.concatenate([c for c, _ in parts]), np.concatenate([r for _, r in parts]))
        for name, parts in spheres.items()
    }
    capsule_data = {
        name: (
            np.concatenate([a for a, _, _ in parts]),
            np.concatenate([b for _, b, _ in parts]),
            np.concatenate([r for _, _, r in parts]),
        )
        for name, parts in capsules.items()
    }
    body = Body.create(read.links, sphere_data, capsule_data)
    return UrdfBody(body, read.joints, overshoot)


def _option(value: Any, name: str) -> int | None:
    if value is None:
        return None
    if isinstance(value, bool) or not isinstance(value, int | np.integer) or value < 1:
        raise ValueError(f"{name} must be an integer >= 1 or None, got {value!r}")
    return int(value)


def body_from_urdf(
    source: str | os.PathLike,
    max_primitives_per_mesh: int | None = None,
    max_overshoot: float | None = 0.01,
    link_spheres: Mapping[str, tuple[np.ndarray, np.ndarray]] | None = None,
    package_dirs: str | os.PathLike | Sequence[str | os.PathLike] = (),
    dtype=None,
    max_spheres_per_mesh: int | None = MESH_SPHERES,
    max_spheres_per_box: int | None = BOX_SPHERES,
) -> UrdfBody:
    """Read a URDF's collision geometry as a ``Body`` (module docstring).

    Args:
        source: path of the URDF file, or its XML text (meshes then relative to the current
            folder).
        max_primitives_per_mesh: None (default) for sphere covers of meshes; a number for
            the former covers of spheres and capsules together, this many per mesh, top down
            (``cover.mesh_cover``, stopped early once ``max_overshoot`` is met).
        max_overshoot: the overshoot bound of the sphere covers (length units of the URDF,
            metres; default 1 cm): every point of a mesh's or box's spheres lies within it of
            the mesh's or box's solid. None: the smallest bound each budget allows.
        link_spheres: link name -> ``(centers (k, 3), radii (k,))``: the user's own spheres,
            which replace everything the URDF gives that link.
        package_dirs: folders searched first for ``package://`` meshes (one folder or a
            sequence of them).
        dtype: of the body's arrays (default: JAX's default float).
        max_spheres_per_mesh: the budget of spheres of each mesh (default 256): a mesh whose
            bound needs more gets a looser bound (``overshoot`` says which); None for none.
        max_spheres_per_box: the same for each ``<box>`` (default 32).

    Returns:
        ``UrdfBody(body, joints, overshoot)``; ``body.links`` lists every URDF link.

    Raises:
        ValueError: an unreadable URDF, bad geometry (naming the link and the file), bad
            options.
        ImportError: a URDF with meshes without trimesh (the ``urdf`` extra).
    """
    options = (
        _option(max_primitives_per_mesh, "max_primitives_per_mesh"),
        max_overshoot,
        _option(max_spheres_per_mesh, "max_spheres_per_mesh"),
        _option(max_spheres_per_box, "max_spheres_per_box"),
    )
    if max_overshoot is not None and (
        isinstance(max_overshoot, bool) or not np.isfinite(max_overshoot) or max_overshoot <= 0
    ):
        raise ValueError(f"max_overshoot must be a positive length or None, got {max_overshoot!r}")
    if max_overshoot is None and (options[2] is None or options[3] is None):
        raise ValueError("max_overshoot=None needs max_spheres_per_mesh and max_spheres_per_box")
    read = read_collision(source, package_dirs).body(*options)
    body = read.body if dtype is None else read.body.astype(dtype)
    overshoot = dict(read.overshoot)
    if link_spheres:
        body = body.with_link_spheres(link_spheres)
        for name in link_spheres:
            overshoot[name] = 0.0
    return UrdfBody(body, read.joints, overshoot)
