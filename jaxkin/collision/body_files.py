"""Robot bodies as files other planners read and write: cuRobo's sphere lists (read) and
spherised URDFs (read by ``body_from_urdf``, written here).

- cuRobo's robot configurations list spheres per link (YAML)::

      collision_spheres:
        panda_link1:
          - center: [0.0, -0.08, 0.0]
            radius: 0.055

  either in the robot file (``robot_cfg.kinematics.collision_spheres``, which may instead
  name a spheres file, relative to the robot file) or in a spheres file of its own (the key
  at the top). Centres are in their link's frame, in metres. ``read_sphere_lists`` gives them
  as ``{link: (centers (k, 3), radii (k,))}``, as ``Body.create`` and
  ``Chain.with_link_spheres`` take them; a sphere of negative radius (cuRobo's mark of a
  disabled sphere) is left out. cuRobo's ``collision_sphere_buffer`` (an inflation added at
  check time) is not applied.
- A spherised URDF (VAMP's ``*_spherized.urdf``) is a URDF whose ``<collision>`` elements are
  spheres; ``spherized_urdf(body, urdf)`` writes a body's spheres into a URDF's links in place
  of their ``<collision>`` elements, keeping its joints, inertias and visuals, so that a cover
  jaxkin computed (``body_from_urdf(..., max_spheres_per_mesh=k)``) serves a sphere-based
  planner. Reading it back with ``body_from_urdf`` gives the same spheres.

Reading YAML needs PyYAML (the ``yaml`` extra).
"""

from __future__ import annotations

import io
import os
from collections.abc import Mapping
from pathlib import Path
from xml.etree import ElementTree

import numpy as np

from . import _yaml
from .body import Body

__all__ = ["read_sphere_lists", "spherized_urdf"]


def _spheres_section(path: Path, seen: tuple[Path, ...] = ()) -> tuple[Mapping, Path]:
    """The ``collision_spheres`` mapping of a cuRobo file (following a file name), and the
    file it is in."""
    document = _yaml.load(path)
    if not isinstance(document, Mapping):
        raise ValueError(f"{path}: expected a mapping (a cuRobo robot or spheres file)")
    kinematics = ((document.get("robot_cfg") or {}).get("kinematics") or {}) if isinstance(
        document.get("robot_cfg"), Mapping) else {}  # fmt: skip
    section = document.get("collision_spheres", kinematics.get("collision_spheres"))
    if section is None:
        raise ValueError(f"{path}: no collision_spheres (at the top, or in robot_cfg.kinematics)")
    if isinstance(section, str):  # a spheres file, relative to this one
        target = (path.parent / section).resolve()
        if not target.is_file():
            raise ValueError(f"{path}: collision_spheres names {section!r}, no such file")
        if target in seen:
            raise ValueError(f"{path}: collision_spheres files name each other ({target})")
        return _spheres_section(target, (*seen, target))
    if not isinstance(section, Mapping):
        raise ValueError(f"{path}: collision_spheres must map link names to sphere lists")
    return section, path


def read_sphere_lists(path: str | os.PathLike) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """cuRobo's spheres per link: ``{link: (centers (k, 3), radii (k,))}`` (module
    docstring); links with no enabled sphere are left out.

    Raises:
        ValueError: no such file, no ``collision_spheres``, a sphere without a three-number
            ``center`` or a finite ``radius`` (named by file, link and index).
        ImportError: PyYAML is missing (the ``yaml`` extra).
    """
    path = Path(path)
    if not path.is_file():
        raise ValueError(f"path: no such cuRobo file {str(path)!r}")
    section, source = _spheres_section(path.resolve())
    out = {}
    for link, spheres in section.items():
        if not isinstance(spheres, list):
            raise ValueError(f"{source}: collision_spheres[{link!r}] must be a list of spheres")
        centers, radii = [], []
        for i, sphere in enumerate(spheres):
            where = f"{source}: collision_spheres[{link!r}][{i}]"
            if not isinstance(sphere, Mapping) or not {"center", "radius"} <= set(sphere):
                raise ValueError(f"{where}: expected center and radius, got {sphere!r:.60}")
            try:
                center = np.asarray(sphere["center"], dtype=np.float64)
                radius = float(sphere["radius"])
            except (TypeError, ValueError):
                raise ValueError(f"{where}: center and radius must be numbers") from None
            if center.shape != (3,) or not np.all(np.isfinite(center)) or not np.isfinite(radius):
                raise ValueError(f"{where}: expected a finite center [x, y, z] and radius")
            if radius >= 0:
                centers.append(center)
                radii.append(radius)
        if radii:
            out[str(link)] = (np.stack(centers), np.asarray(radii))
    return out


def _number(x: float) -> str:
    return repr(float(x))


def spherized_urdf(body: Body, urdf: str | os.PathLike) -> str:
    """The URDF ``urdf`` (a path or its XML text) with every link's ``<collision>`` elements
    replaced by ``body``'s spheres on that link (one ``<collision>`` per sphere, named
    ``sphere_<i>``, its centre as the origin), as XML text; everything else is kept.

    Raises:
        ValueError: a body with capsules (a spherised URDF holds spheres: cover with
            ``body_from_urdf(..., max_spheres_per_mesh=k)``), a body link the URDF does not
            have, an unreadable URDF.
    """
    if not isinstance(body, Body):
        raise ValueError(f"body: expected a collision.Body, got {type(body).__name__}")
    if body.num_capsules:
        raise ValueError(
            f"body: {body.num_capsules} capsules; a spherised URDF holds spheres only (a "
            "sphere cover: body_from_urdf(..., max_spheres_per_mesh=k))"
        )
    text = os.fsdecode(urdf) if isinstance(urdf, os.PathLike) else urdf
    if isinstance(text, str) and text.lstrip("\ufeff \t\r\n").startswith("<"):
        data, where = text.encode("utf-8"), "urdf (URDF text)"
    else:
        source = Path(text)
        if not source.is_file():
            raise ValueError(f"urdf: no such URDF file {str(source)!r}")
        data, where = source.read_bytes(), f"urdf {str(source)!r}"
    parser = ElementTree.XMLParser(target=ElementTree.TreeBuilder(insert_comments=True))
    try:
        root = ElementTree.fromstring(data, parser=parser)
    except ElementTree.ParseError as exc:
        raise ValueError(f"{where}: not well-formed XML ({exc})") from None
    links = {link.get("name"): link for link in root.findall("link")}
    spheres, _ = body.per_link()
    unknown = [name for name in spheres if name not in links]
    if unknown:
        raise ValueError(f"body: link {unknown[0]!r} is not a link of the {where}")
    for name, link in links.items():
        for element in link.findall("collision"):
            link.remove(element)
        centers, radii = spheres.get(name, (np.zeros((0, 3)), np.zeros(0)))
        for i, (center, radius) in enumerate(zip(centers, radii, strict=True)):
            collision = ElementTree.SubElement(link, "collision", name=f"sphere_{i}")
            ElementTree.SubElement(
                collision, "origin", xyz=" ".join(map(_number, center)), rpy="0 0 0"
            )
            geometry = ElementTree.SubElement(collision, "geometry")
            ElementTree.SubElement(geometry, "sphere", radius=_number(radius))
    ElementTree.indent(root, space="  ")
    out = io.BytesIO()
    ElementTree.ElementTree(root).write(out, encoding="utf-8", xml_declaration=True)
    return out.getvalue().decode("utf-8") + "\n"
