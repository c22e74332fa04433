"""Worlds from MoveIt planning scenes (YAML): boxes, spheres and cylinders.

A MoveIt ``PlanningScene`` message written as YAML (the scenes of MotionBenchMaker
[Chamzas et al. 2022], ``moveit_msgs/PlanningScene``) lists ``world.collision_objects``, each
with an optional ``pose`` and ``primitives`` of type ``box`` (``dimensions``: full sizes x, y,
z), ``sphere`` (radius) or ``cylinder`` (height, radius; its axis the local z), each placed by
the matching ``primitive_poses`` entry (``position``, ``orientation`` as a quaternion
``x, y, z, w``) composed after the object's ``pose``. ``read_scene(text)`` returns the solids
as ``SceneSolids`` (host-side arrays, exact: boxes, spheres, cylinders as centre, axis, half
height, radius) and ``world_from_solids`` the ``collision.World`` the checks take.

Cylinders: the collision layer has no cylinder primitive yet, so ``world_from_solids``
represents each cylinder by the box that holds it (half extents ``r, r, h``, its z axis along
the cylinder's axis). The box contains the cylinder, so a motion free of the box is free of the
cylinder: conservative, never optimistic. It reaches past the cylinder only at its four
vertical edges (by ``(sqrt 2 - 1) r``), not past its flat ends, where the enclosing capsule
would reach a whole radius: on MotionBenchMaker's Panda problems, whose grippers close in on
cans from above, the capsule made 64 of the 100 ``box`` problems' goals collide, the box none.
Neither stand-in suits every robot: the UR5's gripper closes in on the cans from the side,
where the box's edges reach out, and with boxes 11 of its first 28 problems (4 per scene) have
a colliding start or goal, with capsules 1 of its first 70. Exact cylinders are the fix; this
is the one place to change when they arrive.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any

import numpy as np

from ..collision import Boxes, Spheres, World

__all__ = ["SceneSolids", "quaternion_matrix", "read_scene", "world_from_solids"]


@dataclasses.dataclass(frozen=True)
class SceneSolids:
    """The solids of a scene (NumPy, float64), by kind; ``names`` per solid.

    Attributes:
        box_center ``(nb, 3)``, box_rotation ``(nb, 3, 3)``, box_half ``(nb, 3)``;
        sphere_center ``(ns, 3)``, sphere_radius ``(ns,)``;
        cylinder_center ``(nc, 3)``, cylinder_axis ``(nc, 3)`` (unit), cylinder_half_height
        ``(nc,)``, cylinder_radius ``(nc,)``.
    """

    box_center: np.ndarray
    box_rotation: np.ndarray
    box_half: np.ndarray
    sphere_center: np.ndarray
    sphere_radius: np.ndarray
    cylinder_center: np.ndarray
    cylinder_axis: np.ndarray
    cylinder_half_height: np.ndarray
    cylinder_radius: np.ndarray
    names: tuple[str, ...] = ()


def quaternion_matrix(q: Any) -> np.ndarray:
    """The rotation of a quaternion ``(x, y, z, w)`` (normalised first)."""
    x, y, z, w = np.asarray(q, float) / np.linalg.norm(np.asarray(q, float))
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )


def _pose(entry: Any, where: str) -> np.ndarray:
    if entry is None:
        return np.eye(4)
    try:
        position = np.asarray(entry.get("position", [0, 0, 0]), float).reshape(3)
        orientation = np.asarray(entry.get("orientation", [0, 0, 0, 1]), float).reshape(4)
    except (AttributeError, TypeError, ValueError) as error:
        raise ValueError(
            f"{where}: expected position [x, y, z] and orientation [x, y, z, w]"
        ) from error
    if not (np.all(np.isfinite(position)) and np.all(np.isfinite(orientation))):
        raise ValueError(f"{where}: the pose must be finite")
    if np.linalg.norm(orientation) == 0:
        raise ValueError(f"{where}: the orientation quaternion is zero")
    out = np.eye(4)
    out[:3, :3] = quaternion_matrix(orientation)
    out[:3, 3] = position
    return out


def read_scene(source: Any) -> SceneSolids:
    """The solids of a MoveIt planning scene: YAML text, a path, or the parsed mapping.

    Raises:
        ValueError: no ``world.collision_objects``, an unknown primitive type, dimensions
            that are not positive and finite (naming the object and the source).
        ImportError: PyYAML (the ``motion`` extra) is missing for YAML input.
    """
    where = "scene"
    data = source
    if isinstance(source, Path) or (
        isinstance(source, str) and "\n" not in source and source.endswith((".yaml", ".yml"))
    ):
        where = str(source)
        data = Path(source).read_text(encoding="utf-8")
    if isinstance(data, str | bytes):
        try:
            import yaml
        except ImportError as error:  # pragma: no cover - the extra is installed for tests
            raise ImportError(
                "reading YAML scenes needs PyYAML: pip install 'jaxkin[yaml]'"
            ) from error
        data = yaml.safe_load(data)
    if not isinstance(data, dict):
        raise ValueError(f"{where}: expected a planning scene mapping")
    world = data.get("world", data)
    objects = world.get("collision_objects", []) if isinstance(world, dict) else None
    if objects is None:
        raise ValueError(f"{where}: no world.collision_objects")
    boxes, spheres, cylinders, names = [], [], [], []
    for i, obj in enumerate(objects or []):
        name = str(obj.get("id", f"object {i}"))
        base = _pose(obj.get("pose"), f"{where}: {name}.pose")
        prims = obj.get("primitives") or []
        poses = obj.get("primitive_poses") or []
        if len(poses) != len(prims):
            raise ValueError(f"{where}: {name} has {len(prims)} primitives and {len(poses)} poses")
        for k, (prim, pose) in enumerate(zip(prims, poses, strict=True)):
            label = f"{where}: {name}.primitives[{k}]"
            kind = str(prim.get("type", "")).lower()
            dims = np.asarray(prim.get("dimensions", []), float).reshape(-1)
            if not (dims.size and np.all(np.isfinite(dims)) and np.all(dims > 0)):
                raise ValueError(f"{label}: dimensions must be positive and finite, got {dims}")
            t = base @ _pose(pose, f"{label} pose")
            if kind == "box" and dims.size == 3:
                boxes.append((t[:3, 3], t[:3, :3], 0.5 * dims))
            elif kind == "sphere" and dims.size == 1:
                spheres.append((t[:3, 3], dims[0]))
            elif kind == "cylinder" and dims.size == 2:
                cylinders.append((t[:3, 3], t[:3, 2], 0.5 * dims[0], dims[1]))
            else:
                raise ValueError(
                    f"{label}: unsupported primitive {kind!r} with {dims.size} dimensions "
                    "(box: 3, sphere: 1, cylinder: height and radius)"
                )
            names.append(name)

    def rows(items, k, shape):
        return np.array([it[k] for it in items], float).reshape((len(items), *shape))

    return SceneSolids(
        rows(boxes, 0, (3,)),
        rows(boxes, 1, (3, 3)),
        rows(boxes, 2, (3,)),
        rows(spheres, 0, (3,)),
        rows(spheres, 1, ()),
        rows(cylinders, 0, (3,)),
        rows(cylinders, 1, (3,)),
        rows(cylinders, 2, ()),
        rows(cylinders, 3, ()),
        tuple(names),
    )


def world_from_solids(solids: SceneSolids, dtype: Any = None) -> World:
    """The ``collision.World`` of a scene's solids; cylinders as the boxes that hold them
    (module docstring)."""
    centers, halves, rotations = [solids.box_center], [solids.box_half], [solids.box_rotation]
    if len(solids.cylinder_center):
        z = solids.cylinder_axis / np.linalg.norm(solids.cylinder_axis, axis=-1, keepdims=True)
        # any unit x perpendicular to z: the cross product with the axis z is least along
        helper = np.eye(3)[np.argmin(np.abs(z), axis=-1)]
        x = np.cross(helper, z)
        x /= np.linalg.norm(x, axis=-1, keepdims=True)
        rotations.append(np.stack([x, np.cross(z, x), z], axis=-1))
        r = solids.cylinder_radius
        halves.append(np.stack([r, r, solids.cylinder_half_height], axis=-1))
        centers.append(solids.cylinder_center)
    parts = {}
    if sum(len(c) for c in centers):
        parts["boxes"] = Boxes.create(
            np.concatenate(centers), np.concatenate(halves), np.concatenate(rotations)
        )
    if len(solids.sphere_center):
        parts["spheres"] = Spheres.create(solids.sphere_center, solids.sphere_radius)
    return World.create(**parts, dtype=dtype)
