"""A robot's collision body and kinematic tree read from a URDF's ``<collision>`` elements.

Each ``<collision>`` element of a link becomes, in that link's frame (its ``<origin>``
applied):

- ``<sphere>``: the sphere as given (a "spherized" URDF, spheres only, is taken as it is);
- ``<cylinder>``: the capsule with the same axis segment and radius (it contains the cylinder;
  it reaches one radius past each flat end);
- ``<box>``: capsules along its longest axis containing the solid box (``cover.box_capsules``);
- ``<mesh>``: spheres and capsules containing every triangle, computed on load with trimesh
  (``cover.mesh_cover``: a budget of primitives per mesh and an overshoot bound; spheres only
  with ``max_spheres_per_mesh``), the mesh's ``scale`` applied. Mesh files are found from
  ``package://pkg/rel`` by looking for ``pkg/rel`` or ``rel`` under the given ``package_dirs``
  and then under every parent of the URDF's folder.

``link_spheres`` replaces the primitives of the named links by the user's own spheres.
Parsing uses yourdfpy and meshes trimesh (the ``urdf`` extra).
"""

from __future__ import annotations

import dataclasses
import io
import os
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from .body import Body
from .cover import box_capsules, mesh_cover

__all__ = ["UrdfBody", "body_from_urdf"]


@dataclasses.dataclass(frozen=True)
class UrdfBody:
    """What ``body_from_urdf`` reads: the ``body``; ``joints`` as ``(parent, child, type)``
    link-name triples (the kinematic tree, for adjacency); and per link the overshoot bound of
    its mesh covers (0 for links without meshes)."""

    body: Body
    joints: tuple[tuple[str, str, str], ...]
    overshoot: Mapping[str, float]


def _load_model(source: str | os.PathLike):
    try:
        import yourdfpy
    except ImportError as exc:  # pragma: no cover - the extra is part of the test install
        raise ImportError(
            "reading a URDF needs the 'urdf' extra: pip install 'jaxkin[urdf]'"
        ) from exc
    text = os.fsdecode(source) if isinstance(source, bytes | os.PathLike) else source
    data: io.BytesIO | str
    if isinstance(text, str) and text.lstrip("\ufeff \t\r\n").startswith("<"):
        path, data = Path("URDF text"), io.BytesIO(text.encode("utf-8"))
    else:
        path = Path(source)
        if not path.is_file():
            raise ValueError(f"source: no such URDF file {str(path)!r}")
        data = str(path)
    try:
        return yourdfpy.URDF.load(
            data,
            build_scene_graph=False,
            build_collision_scene_graph=False,
            load_meshes=False,
            load_collision_meshes=False,
        ).robot
    except Exception as exc:  # a malformed element: yourdfpy raises what its parser meets
        raise ValueError(f"source {str(path)!r}: not a readable URDF ({exc})") from None


def _resolve(filename: str, urdf_dir: Path, package_dirs: Sequence[str | os.PathLike]) -> Path:
    """The mesh file a URDF names (``package://``, ``file://`` or a relative path)."""
    name = filename
    for prefix in ("file://",):
        if name.startswith(prefix):
            name = name[len(prefix) :]
    if name.startswith("package://"):
        rel = name[len("package://") :]
        tails = [Path(rel), Path(*Path(rel).parts[1:])]
        roots = [Path(p) for p in package_dirs] + [urdf_dir, *urdf_dir.parents]
        for root in roots:
            for tail in tails:
                if (root / tail).is_file():
                    return root / tail
        raise ValueError(f"mesh {filename!r}: not found under package_dirs or the URDF's parents")
    path = Path(name) if Path(name).is_absolute() else urdf_dir / name
    if not path.is_file():
        raise ValueError(f"mesh {filename!r}: no such file {str(path)!r}")
    return path


def _origin(element) -> np.ndarray:
    return np.eye(4) if element.origin is None else np.asarray(element.origin, dtype=float)


def _apply(pose: np.ndarray, points: np.ndarray) -> np.ndarray:
    return points @ pose[:3, :3].T + pose[:3, 3]


def body_from_urdf(
    source: str | os.PathLike,
    max_primitives_per_mesh: int = 16,
    max_overshoot: float | None = None,
    link_spheres: Mapping[str, tuple[np.ndarray, np.ndarray]] | None = None,
    package_dirs: Sequence[str | os.PathLike] = (),
    dtype=None,
    max_spheres_per_mesh: int | None = None,
) -> UrdfBody:
    """Read a URDF's collision geometry as a ``Body`` (spheres and capsules per link).

    Args:
        source: path of the URDF file, or its XML text (meshes then relative to the current
            folder).
        max_primitives_per_mesh: budget of spheres and capsules of each mesh cover.
        max_overshoot: stop refining a mesh cover once its overshoot bound is at most this
            (metres); ``None`` uses the whole budget.
        link_spheres: link name -> ``(centers (k, 3), radii (k,))``: the user's own spheres,
            which replace everything the URDF gives that link.
        package_dirs: folders searched first for ``package://`` meshes.
        max_spheres_per_mesh: covers of spheres only, this many per mesh (a sphere model, as
            sphere-based checkers use), instead of ``max_primitives_per_mesh``.

    Returns:
        ``UrdfBody(body, joints, overshoot)``; ``body.links`` lists every URDF link.
    """
    import trimesh

    model = _load_model(source)
    is_text = isinstance(source, str) and source.lstrip("\ufeff \t\r\n").startswith("<")
    path = Path.cwd() / "urdf" if is_text else Path(source)
    links = tuple(link.name for link in model.links)
    budget = max_primitives_per_mesh if max_spheres_per_mesh is None else max_spheres_per_mesh
    if int(budget) < 1:
        name = "max_primitives_per_mesh" if max_spheres_per_mesh is None else "max_spheres_per_mesh"
        raise ValueError(f"{name} must be >= 1, got {budget}")
    spheres: dict[str, list] = {}
    capsules: dict[str, list] = {}
    overshoot: dict[str, float] = {name: 0.0 for name in links}
    for link in model.links:
        for element in link.collisions:
            pose = _origin(element)
            geometry = element.geometry
            if geometry.sphere is not None:
                spheres.setdefault(link.name, []).append(
                    (pose[None, :3, 3], np.array([geometry.sphere.radius]))
                )
            elif geometry.cylinder is not None:
                half = 0.5 * geometry.cylinder.length
                ends = _apply(pose, np.array([[0.0, 0.0, -half], [0.0, 0.0, half]]))
                capsules.setdefault(link.name, []).append(
                    (ends[:1], ends[1:], np.array([geometry.cylinder.radius]))
                )
            elif geometry.box is not None:
                a, b, r = box_capsules(0.5 * np.asarray(geometry.box.size, dtype=float))
                capsules.setdefault(link.name, []).append((_apply(pose, a), _apply(pose, b), r))
            elif geometry.mesh is not None:
                mesh_path = _resolve(geometry.mesh.filename, path.parent, package_dirs)
                mesh: Any = trimesh.load(str(mesh_path), force="mesh")  # a Trimesh
                scale = geometry.mesh.scale
                vertices = np.asarray(mesh.vertices) * (1.0 if scale is None else np.asarray(scale))
                cover = mesh_cover(
                    _apply(pose, vertices),
                    np.asarray(mesh.faces),
                    budget,
                    max_overshoot,
                    capsules=max_spheres_per_mesh is None,
                )
                if len(cover.radii):
                    spheres.setdefault(link.name, []).append((cover.centers, cover.radii))
                if len(cover.capsule_radii):
                    capsules.setdefault(link.name, []).append(
                        (cover.a, cover.b, cover.capsule_radii)
                    )
                overshoot[link.name] = max(overshoot[link.name], cover.overshoot)
            else:
                raise ValueError(f"link {link.name!r}: a <collision> element without geometry")
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
    body = Body.create(links, sphere_data, capsule_data, dtype=dtype)
    if link_spheres:
        body = body.with_link_spheres(link_spheres)
        for name in link_spheres:
            overshoot[name] = 0.0
    joints = tuple((j.parent, j.child, j.type) for j in model.joints)
    return UrdfBody(body, joints, overshoot)
