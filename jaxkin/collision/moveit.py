"""MoveIt planning scenes as data: the collision objects of a ``moveit_msgs/PlanningScene``
written as YAML (as MotionBenchMaker ships its problems) read into a ``World``, and a motion
plan request's start and goal joint values.

A scene (``read_moveit_scene``) is the message as YAML: its ``world.collision_objects`` (or a
``PlanningSceneWorld``'s ``collision_objects`` at the top) each hold ``primitives`` and as many
``primitive_poses``, and optionally an object ``pose`` that the primitive poses are relative
to (newer MoveIt). A pose is ``position [x, y, z]`` and ``orientation [x, y, z, w]`` (ROS's
quaternion order; mappings with those keys are read too). Primitives (``shape_msgs/
SolidPrimitive``, by name or number):

- ``box`` (1): ``dimensions [x, y, z]``, full side lengths;
- ``sphere`` (2): ``[radius]``;
- ``cylinder`` (3): ``[height, radius]``, along the primitive frame's z axis;
- ``cone`` (4), meshes and planes are not read (a ``ValueError`` names the object).

Lengths are metres (ROS). Poses are in the scene's planning frame: an object whose
``header.frame_id`` is empty or ``world`` is taken as given, one in a frame listed in
``fixed_frame_transforms`` is moved by that transform, any other (a robot link: an attached
object) is refused. jaxkin checks obstacles in the robot's base frame, which for
MotionBenchMaker's problems is the planning frame.

Reading needs PyYAML (the ``yaml`` extra). Errors name the file, the object (index and
``id``) and the primitive.
"""

from __future__ import annotations

import dataclasses
import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from .. import lie
from . import _yaml
from .primitives import Boxes, Cylinders, Spheres
from .world import World

__all__ = ["MoveItRequest", "read_moveit_request", "read_moveit_scene", "scene_world"]

_TYPES = {1: "box", 2: "sphere", 3: "cylinder", 4: "cone"}
_DIMENSIONS = {"box": 3, "sphere": 1, "cylinder": 2}
_PLANNING_FRAMES = ("", "world", "/world")


def _document(path: Path) -> Mapping:
    if not path.is_file():
        raise ValueError(f"path: no such MoveIt file {str(path)!r}")
    document = _yaml.load(path)
    if not isinstance(document, Mapping):
        raise ValueError(f"{path}: expected a mapping (a MoveIt message), got {document!r:.60}")
    return document


def _vector(value: Any, keys: str, where: str) -> np.ndarray:
    """A list of numbers, or a mapping with the given one-letter keys, as floats."""
    if isinstance(value, Mapping):
        value = [value.get(k, 0.0 if k != "w" else 1.0) for k in keys]
    try:
        arr = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError(f"{where}: expected {len(keys)} numbers, got {value!r}") from None
    if arr.shape != (len(keys),) or not np.all(np.isfinite(arr)):
        raise ValueError(f"{where}: expected {len(keys)} finite numbers, got {value!r}")
    return arr


def _pose(value: Any, where: str) -> np.ndarray:
    """A ``geometry_msgs/Pose`` as a 4x4 transform."""
    if value is None:
        return np.eye(4)
    if not isinstance(value, Mapping):
        raise ValueError(f"{where}: expected a pose (position, orientation), got {value!r:.60}")
    frame = np.eye(4)
    frame[:3, 3] = _vector(value.get("position", [0.0, 0.0, 0.0]), "xyz", f"{where}.position")
    x, y, z, w = _vector(value.get("orientation", [0, 0, 0, 1]), "xyzw", f"{where}.orientation")
    quaternion = np.array([w, x, y, z])
    if not np.any(quaternion):
        raise ValueError(f"{where}.orientation: a zero quaternion is no rotation")
    frame[:3, :3] = lie.quaternion_to_matrix(quaternion / np.abs(quaternion).max(), xp=np)
    return frame


def _fixed_frames(document: Mapping, path: Path) -> dict[str, np.ndarray]:
    """The scene's ``fixed_frame_transforms``: frame name -> its pose in the planning frame."""
    frames = {}
    for i, entry in enumerate(document.get("fixed_frame_transforms") or []):
        where = f"{path}: fixed_frame_transforms[{i}]"
        if not isinstance(entry, Mapping) or "child_frame_id" not in entry:
            raise ValueError(f"{where}: expected child_frame_id and transform")
        transform = entry.get("transform") or {}
        pose = {"position": transform.get("translation", [0.0, 0.0, 0.0]),
                "orientation": transform.get("rotation", [0.0, 0.0, 0.0, 1.0])}  # fmt: skip
        frames[str(entry["child_frame_id"])] = _pose(pose, f"{where}.transform")
    return frames


def read_moveit_scene(path: str | os.PathLike, dtype=None) -> World:
    """The collision objects of a MoveIt planning scene (YAML) as a ``World`` of boxes,
    spheres and cylinders (module docstring).

    Raises:
        ValueError: no such file, not YAML, no ``collision_objects``, an object in an unknown
            frame, a primitive that is not a box, sphere or cylinder, meshes or planes, bad
            dimensions or poses (the message names the file, the object and the primitive).
        ImportError: PyYAML is missing (the ``yaml`` extra).
    """
    path = Path(path)
    return scene_world(_document(path), path, dtype)


def scene_world(document: Mapping, path: Path, dtype=None) -> World:
    """``read_moveit_scene`` of a document already read from ``path``."""
    world = document.get("world", document)
    if not isinstance(world, Mapping) or "collision_objects" not in world:
        raise ValueError(f"{path}: no world.collision_objects (not a MoveIt planning scene)")
    frames = _fixed_frames(document, path)
    boxes: list[tuple] = []
    spheres: list[tuple] = []
    cylinders: list[tuple] = []
    for i, obj in enumerate(world.get("collision_objects") or []):
        where = f"{path}: collision_objects[{i}]"
        if not isinstance(obj, Mapping):
            raise ValueError(f"{where}: expected a collision object, got {obj!r:.60}")
        where += f" ({str(obj.get('id', ''))!r})"
        operation = obj.get("operation", 0)
        if operation not in (0, 2, "add", "ADD", "append", "APPEND", b"\x00"):
            raise ValueError(f"{where}: operation {operation!r} is not read (add or append)")
        for key in ("meshes", "planes"):
            if obj.get(key):
                raise ValueError(f"{where}: {key} are not read (boxes, spheres, cylinders only)")
        frame_id = str((obj.get("header") or {}).get("frame_id", "") or "")
        if frame_id in frames:
            placed = frames[frame_id]
        elif frame_id in _PLANNING_FRAMES:
            placed = np.eye(4)
        else:
            raise ValueError(
                f"{where}: frame {frame_id!r} is neither the planning frame nor one of the "
                f"scene's fixed frames ({', '.join(frames) or 'none'})"
            )
        placed = placed @ _pose(obj.get("pose"), f"{where}.pose")
        primitives = obj.get("primitives") or []
        poses = obj.get("primitive_poses") or []
        if len(primitives) != len(poses):
            raise ValueError(
                f"{where}: {len(primitives)} primitives but {len(poses)} primitive_poses"
            )
        for k, (primitive, pose) in enumerate(zip(primitives, poses, strict=True)):
            at = f"{where}.primitives[{k}]"
            if not isinstance(primitive, Mapping):
                raise ValueError(f"{at}: expected type and dimensions, got {primitive!r:.60}")
            kind = primitive.get("type")
            kind = _TYPES.get(kind, kind) if isinstance(kind, int) else str(kind).lower()
            if kind not in _DIMENSIONS:
                raise ValueError(f"{at}: type {primitive.get('type')!r} is not read "
                                 "(box, sphere or cylinder)")  # fmt: skip
            dims = np.asarray(primitive.get("dimensions", []), dtype=np.float64)
            if dims.shape != (_DIMENSIONS[kind],) or not np.all(np.isfinite(dims)):
                raise ValueError(f"{at}: a {kind} has {_DIMENSIONS[kind]} dimensions, got "
                                 f"{primitive.get('dimensions')!r}")  # fmt: skip
            if np.any(dims < 0):
                raise ValueError(f"{at}: dimensions must be >= 0, got {dims.tolist()}")
            frame = placed @ _pose(pose, f"{where}.primitive_poses[{k}]")
            centre, rotation = frame[:3, 3], frame[:3, :3]
            if kind == "box":
                boxes.append((centre, 0.5 * dims, rotation))
            elif kind == "sphere":
                spheres.append((centre, dims[0]))
            else:
                cylinders.append((centre, dims[1], 0.5 * dims[0], rotation))
    given: dict[str, Any] = {}
    if boxes:
        c, h, r = (np.stack(x) for x in zip(*boxes, strict=True))
        given["boxes"] = Boxes.create(c, h, r, dtype=np.float64)
    if spheres:
        c, r = (np.stack(x) for x in zip(*spheres, strict=True))
        given["spheres"] = Spheres.create(c, r, np.float64)
    if cylinders:
        c, r, h, rot = (np.stack(x) for x in zip(*cylinders, strict=True))
        given["cylinders"] = Cylinders.create(c, r, h, rotation=rot, dtype=np.float64)
    return World.create(**given, dtype=dtype)


@dataclasses.dataclass(frozen=True)
class MoveItRequest:
    """A motion plan request's ``group`` (``group_name``), ``start`` joint values
    (``start_state.joint_state``: every joint it lists) and ``goals`` (one mapping of joint
    values per entry of ``goal_constraints``, from its ``joint_constraints``)."""

    group: str
    start: Mapping[str, float]
    goals: tuple[Mapping[str, float], ...]


def read_moveit_request(path: str | os.PathLike) -> MoveItRequest:
    """The group, start and joint goals of a ``moveit_msgs/MotionPlanRequest`` (YAML).

    Raises:
        ValueError: no such file, not YAML, a joint state whose names and positions differ
            in number, a goal constraint without a joint name or position.
    """
    path = Path(path)
    document = _document(path)
    state = (document.get("start_state") or {}).get("joint_state") or {}
    names, positions = list(state.get("name") or []), list(state.get("position") or [])
    if len(names) != len(positions):
        raise ValueError(
            f"{path}: start_state.joint_state has {len(names)} names but {len(positions)} positions"
        )
    start = {str(n): float(p) for n, p in zip(names, positions, strict=True)}
    goals = []
    for i, constraint in enumerate(document.get("goal_constraints") or []):
        goal = {}
        for k, joint in enumerate((constraint or {}).get("joint_constraints") or []):
            if (
                not isinstance(joint, Mapping)
                or "joint_name" not in joint
                or "position" not in joint
            ):
                raise ValueError(f"{path}: goal_constraints[{i}].joint_constraints[{k}]: "
                                 "expected joint_name and position")  # fmt: skip
            goal[str(joint["joint_name"])] = float(joint["position"])
        goals.append(goal)
    return MoveItRequest(str(document.get("group_name", "")), start, tuple(goals))
