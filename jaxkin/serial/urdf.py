"""URDF import: ``from_urdf(source, tip_link, base_link=None)`` -> a ``serial.Chain``.

The file is read by the standard library's XML parser (no scene graph, no optional
dependency); this module walks the joint tree. The ``<collision>`` elements and the mesh files
they name are read at the same time (``collision.read_collision``): the chain's collision body
comes from what was read then, covered once when it is first asked for. From the tip
link up to the base link (the root link by default) every joint on the path is kept, side
branches (fingers, sensors) are ignored. With ``T_j`` the composed joint origins from the base
to joint ``j`` at ``theta = 0`` (fixed joints fold into it) and ``a_j`` the unit joint axis in
joint ``j``'s frame::

    omega_j = R(T_j) a_j,   revolute/continuous: S_j = (omega_j, -omega_j x p(T_j)),
                            prismatic: S_j = (0, omega_j);      home M = T_tip

Joint kinds: ``revolute``, ``continuous`` (no position limits) and ``prismatic``; ``fixed``
joints are folded in; ``floating`` and ``planar`` joints on the path are refused. A ``mimic``
joint (``theta = multiplier * theta_leader + offset``) becomes a path joint following its
leader's coordinate (a chain of mimics is composed); its own position and speed limits are
carried over to the leader (``lower <= c q + b <= upper`` and ``|c q_dot| <= v``). Limits:
``<limit lower upper>`` of revolute and prismatic joints (none when absent), ``velocity`` as
the speed limit (none when absent or not positive).

The reader refuses, as Pinocchio's does, a file whose joints do not form a tree: two joints
(or two links) of one name, a link that is the child of two joints. It also refuses numbers
that mean nothing: NaN or inf in a joint's ``<origin>`` (``xyz``, ``rpy``), ``<axis>``,
``<limit>`` or ``<mimic>``, and a mimic joint whose value ``c theta_leader + b`` can never lie
within its own limits (a constant ``b`` outside them when ``c = 0``, or no overlap over the
leader's range). Errors name the link or joint: an unknown link, no path from the base to the
tip, an unsupported joint type, a zero axis, a mimic joint whose leader is not on the path.

``target="point"`` builds a chain whose targets are the tip link's origin ``(3,)`` (position
only: a leg's foot, a finger's tip, an arm of fewer than six joints), ``"pose"`` (the default)
one whose targets are the tip's 4x4 pose.

Joints off the path (a gripper's fingers) are held where ``fixed`` says, 0 otherwise:
``fixed={"panda_finger_joint1": 0.04}`` opens the Panda's fingers, and a joint off the path
that mimics a held one follows it (``panda_finger_joint2``: ``theta = multiplier *
theta_leader + offset``), so the links they carry, and their collision bodies, are placed
there (``Chain.link_poses``). Each value must lie within its joint's limits (the follower's
too); a joint on the path, a fixed or unknown joint, or a mimic joint given directly is
refused, naming the joint.
"""

from __future__ import annotations

import dataclasses
import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from ..collision.urdf import UrdfCollision, origin_matrix, read_collision, read_xml
from .chain import TARGETS, Chain, ChainLinks

__all__ = ["from_urdf"]

_MOVING = ("revolute", "continuous", "prismatic")


@dataclasses.dataclass
class _Limit:
    lower: float | None
    upper: float | None
    velocity: float | None
    effort: float | None


@dataclasses.dataclass
class _Mimic:
    joint: str | None
    multiplier: float
    offset: float


@dataclasses.dataclass
class _Joint:
    name: str
    type: str | None
    parent: str
    child: str
    origin: np.ndarray | None
    axis: np.ndarray
    limit: _Limit | None
    mimic: _Mimic | None


@dataclasses.dataclass
class _Link:
    name: str


@dataclasses.dataclass
class _Robot:
    name: str
    links: list[_Link]
    joints: list[_Joint]


def _float(text: str | None) -> float | None:
    return None if text is None else float(text)


def _joint(element) -> _Joint:
    axis, limit, mimic = element.find("axis"), element.find("limit"), element.find("mimic")
    return _Joint(
        name=element.attrib["name"],
        type=element.get("type"),
        parent=element.find("parent").attrib["link"],
        child=element.find("child").attrib["link"],
        origin=origin_matrix(element.find("origin")),
        axis=np.array(
            [float(v) for v in ("1 0 0" if axis is None else axis.get("xyz", "1 0 0")).split()]
        ),
        limit=None
        if limit is None
        else _Limit(*(_float(limit.get(k)) for k in ("lower", "upper", "velocity", "effort"))),
        mimic=None
        if mimic is None
        else _Mimic(
            mimic.get("joint"),
            float(mimic.get("multiplier", 1.0)),
            float(mimic.get("offset", 0.0)),
        ),
    )


def _load(source: str | bytes | os.PathLike, package_dirs: Any) -> tuple[_Robot, UrdfCollision]:
    """The links and joints of a path or XML text (strict XML: no silent recovery), read by the
    standard library's XML parser, and its collision geometry (``collision.read_collision``:
    meshes read now, covered when a body is asked for)."""
    root, where, folder = read_xml(source)
    try:  # NaN or inf in an origin is named per joint after loading (_check_numbers)
        with np.errstate(invalid="ignore", over="ignore"):
            robot = _Robot(
                name=root.attrib["name"],
                links=[_Link(link.attrib["name"]) for link in root.findall("link")],
                joints=[_joint(joint) for joint in root.findall("joint")],
            )
    except Exception as exc:  # a malformed element: a missing attribute or a bad number
        raise ValueError(f"{where}: not a readable URDF ({type(exc).__name__}: {exc})") from None
    return robot, read_collision(package_dirs=package_dirs, root=root, where=where, folder=folder)


def _check_tree(robot) -> None:
    """Unique joint and link names, and one parent joint per link (Pinocchio's own checks)."""
    for kind, names in (
        ("joint", [joint.name for joint in robot.joints]),
        ("link", [link.name for link in robot.links]),
    ):
        seen: set[str] = set()
        for name in names:
            if name in seen:
                raise ValueError(
                    f"robot {robot.name!r}: two {kind}s are named {name!r} ({kind} names must "
                    "be unique)"
                )
            seen.add(name)
    parent: dict[str, str] = {}
    for joint in robot.joints:
        if joint.child in parent:
            raise ValueError(
                f"link {joint.child!r} is the child of two joints, {parent[joint.child]!r} and "
                f"{joint.name!r} (a link has one parent joint)"
            )
        parent[joint.child] = joint.name


def _check_numbers(robot) -> None:
    """NaN or inf in a joint's origin, axis, limit or mimic: a ``ValueError`` naming it."""
    for joint in robot.joints:
        fields = [("<origin>", joint.origin), ("<axis>", joint.axis)]
        if joint.limit is not None:
            fields += [
                (f"<limit {name}>", getattr(joint.limit, name))
                for name in ("lower", "upper", "velocity", "effort")
            ]
        if joint.mimic is not None:
            fields += [
                (f"<mimic {name}>", getattr(joint.mimic, name)) for name in ("multiplier", "offset")
            ]
        for where, value in fields:
            if value is None:
                continue
            try:
                values = np.asarray(value, dtype=float)
            except (TypeError, ValueError):
                raise ValueError(
                    f"joint {joint.name!r}: {where} is not a number: {value!r}"
                ) from None
            if not np.all(np.isfinite(values)):
                shown = "xyz/rpy" if where == "<origin>" else np.array2string(values)
                raise ValueError(
                    f"joint {joint.name!r}: {where} has a NaN or inf ({shown}); every number "
                    "of a joint must be finite"
                )


def _listed(names: list[str], limit: int = 12) -> str:
    shown = ", ".join(repr(n) for n in names[:limit])
    return shown + (f", ... ({len(names)} links)" if len(names) > limit else "")


def _path_joints(robot, tip_link: str, base_link: str | None) -> tuple[list, str]:
    """The joints from the base link down to the tip link, in that order, and the base."""
    links = [link.name for link in robot.links]
    by_child = {joint.child: joint for joint in robot.joints}
    known = set(links) | set(by_child) | {joint.parent for joint in robot.joints}
    for name, link in (("tip_link", tip_link), ("base_link", base_link)):
        if link is not None and (not isinstance(link, str) or link not in known):
            raise ValueError(
                f"{name}: no link {link!r} in robot {robot.name!r} (links: {_listed(links)})"
            )
    if base_link is None:
        roots = sorted({j.parent for j in robot.joints if j.parent not in by_child})
        if not robot.joints:
            roots = links[:1]
        if len(roots) != 1:
            raise ValueError(
                f"base_link: robot {robot.name!r} has {len(roots)} root links "
                f"({_listed(roots)}); name the base link"
            )
        base_link = roots[0]
    path, link = [], tip_link
    while link != base_link:
        joint = by_child.get(link)
        if joint is None:
            raise ValueError(
                f"no path from base link {base_link!r} to tip link {tip_link!r}: "
                f"{tip_link!r} is not below {base_link!r} (its root is {link!r})"
            )
        path.append(joint)
        link = joint.parent
        if len(path) > len(robot.joints):
            raise ValueError(f"robot {robot.name!r}: the joints form a loop at link {link!r}")
    return path[::-1], base_link


def _axis(joint) -> np.ndarray:
    axis = np.asarray(joint.axis if joint.axis is not None else (1.0, 0.0, 0.0), dtype=float)
    norm = np.linalg.norm(axis)
    if axis.shape != (3,) or not np.isfinite(norm) or norm == 0.0:
        raise ValueError(f"joint {joint.name!r}: the axis must be a non-zero 3-vector, got {axis}")
    return axis / norm


def _limits(joint) -> tuple[float, float, float]:
    """``(lower, upper, velocity)`` of one joint (``+-inf`` for none)."""
    limit = joint.limit
    lower, upper, velocity = -np.inf, np.inf, np.inf
    if limit is not None:
        if joint.type != "continuous":
            lower = -np.inf if limit.lower is None else float(limit.lower)
            upper = np.inf if limit.upper is None else float(limit.upper)
        if limit.velocity is not None and float(limit.velocity) > 0:
            velocity = float(limit.velocity)
    if np.isnan(lower) or np.isnan(upper) or lower > upper:
        raise ValueError(
            f"joint {joint.name!r}: limits need lower <= upper, got lower {lower}, upper {upper}"
        )
    return lower, upper, velocity


def from_urdf(
    source: str | os.PathLike,
    tip_link: str,
    base_link: str | None = None,
    target: str = "pose",
    fixed: Mapping[str, float] | None = None,
    package_dirs: Any = (),
) -> Chain:
    """The chain from ``base_link`` to ``tip_link`` of a URDF (module docstring).

    Args:
        source: a path to a ``.urdf`` file, or the URDF's XML text.
        tip_link: the link whose pose the chain computes (e.g. ``"tool0"``).
        base_link: the link the pose is expressed in; None for the root link.
        target: ``"pose"``: targets are the tip's 4x4 poses; ``"point"``: the tip link's
            origin ``(3,)`` in the base frame (position-only IK, e.g. for a chain of fewer
            than six joints).
        fixed: values of joints off the path, ``{joint name: position}`` (rad or length),
            held there (the others at 0); the joints that mimic them follow.
        package_dirs: folders searched first for ``package://`` meshes (one folder or a
            sequence of them); the meshes are read now, their covers computed when the
            chain's collision body is first asked for (``collision.read_collision``).

    Returns:
        A ``serial.Chain`` (a robot of the protocol: ``jaxkin.ik``/``jaxkin.fk`` with 4x4
        poses, or 3-vectors with ``target="point"``) whose coordinates are the independent
        moving joints on the path, named as in the URDF, base to tip (``joint_names``; their
        URDF types in ``joint_kinds``).

    Raises:
        ValueError: an unreadable source, duplicate joint or link names, a link with two parent
            joints, NaN or inf in a joint's numbers, an unknown link, no path from the base to
            the tip, no moving joint on it, a ``floating`` or ``planar`` joint on it, a zero
            axis, bad limits, a mimic joint whose leader is not a moving joint on the path or
            whose value can never lie within its own limits, an unknown ``target``, or a
            ``fixed`` entry that is not a moving joint off the path within its limits.
    """
    if target not in TARGETS:
        raise ValueError(f"target: expected one of {TARGETS}, got {target!r}")
    robot, collision = _load(source, package_dirs)
    _check_tree(robot)
    _check_numbers(robot)
    path, base_link = _path_joints(robot, tip_link, base_link)
    frame = np.eye(4)
    rows, moving = [], []
    for joint in path:
        origin = np.eye(4) if joint.origin is None else np.asarray(joint.origin, dtype=float)
        frame = frame @ origin
        if joint.type == "fixed":
            continue
        if joint.type not in _MOVING:
            raise ValueError(
                f"joint {joint.name!r} ({joint.type}) between links {joint.parent!r} and "
                f"{joint.child!r}: only revolute, continuous, prismatic and fixed joints are "
                "supported on the path from base to tip"
            )
        omega = frame[:3, :3] @ _axis(joint)
        if joint.type == "prismatic":
            rows.append(np.concatenate([np.zeros(3), omega]))
        else:
            rows.append(np.concatenate([omega, -np.cross(omega, frame[:3, 3])]))
        moving.append(joint)
    if not moving:
        raise ValueError(
            f"no moving joint on the path from base link {base_link!r} to tip link {tip_link!r}"
        )
    index = {joint.name: i for i, joint in enumerate(moving)}
    by_name = {joint.name: joint for joint in robot.joints}

    def leader_of(joint) -> tuple[int, float, float]:
        """``(row of the independent leader, c, b)``: ``theta = c theta_leader + b``."""
        c, b, seen = 1.0, 0.0, {joint.name}
        while joint.mimic is not None:
            name = joint.mimic.joint
            if name not in index:
                kind = "is not a joint" if name not in by_name else "is not on the path"
                raise ValueError(
                    f"joint {joint.name!r} mimics {name!r}, which {kind} from base link "
                    f"{base_link!r} to tip link {tip_link!r}"
                )
            multiplier = 1.0 if joint.mimic.multiplier is None else float(joint.mimic.multiplier)
            offset = 0.0 if joint.mimic.offset is None else float(joint.mimic.offset)
            c, b = c * multiplier, c * offset + b
            joint = moving[index[name]]
            if joint.name in seen:
                raise ValueError(f"joint {joint.name!r}: mimic joints form a loop")
            seen.add(joint.name)
        return index[joint.name], c, b

    couplings = [leader_of(joint) for joint in moving]
    own = [i for i, (leader, _, _) in enumerate(couplings) if leader == i]
    coordinate = {row: j for j, row in enumerate(own)}
    lower, upper, velocity = (np.array([_limits(moving[i])[k] for i in own]) for k in range(3))
    for i, (leader, c, b) in enumerate(couplings):
        if leader == i:
            continue
        j = coordinate[leader]
        low, high, speed = _limits(moving[i])
        if c == 0.0:
            if not low <= b <= high:
                raise ValueError(
                    f"joint {moving[i].name!r}: it mimics {moving[leader].name!r} with "
                    f"multiplier 0, so it stays at its offset {b}, outside its limits "
                    f"[{low}, {high}]"
                )
            continue
        bounds = sorted(((low - b) / c, (high - b) / c))
        lower[j], upper[j] = max(lower[j], bounds[0]), min(upper[j], bounds[1])
        velocity[j] = min(velocity[j], speed / abs(c))
        if lower[j] > upper[j]:
            raise ValueError(
                f"joint {moving[i].name!r}: its limits leave no position for its leader "
                f"{moving[leader].name!r}"
            )
    held = _held_joints(robot, fixed, {joint.name for joint in path})
    links = _chain_links(
        robot, base_link, [joint.name for joint in moving], source, collision, held
    )
    return Chain(
        np.stack(rows),
        frame,
        np.array([c for _, c, _ in couplings]),
        np.array([b for _, _, b in couplings]),
        lower,
        upper,
        velocity,
        follows=tuple(coordinate[leader] for leader, _, _ in couplings),
        joint_kinds=tuple(moving[i].type for i in own),
        joint_names=tuple(moving[i].name for i in own),
        base_link=base_link,
        tip_link=tip_link,
        target_kind=target,
        links=links,
    )


def _held_joints(robot, fixed: Any, on_path: set[str]) -> dict[str, float]:
    """The positions of the joints off the path: the user's (checked) and those of the
    joints that mimic them (or an off-path joint held at 0); ``{}`` when nothing moves."""
    if fixed is None:
        fixed = {}
    if not isinstance(fixed, Mapping):
        raise ValueError(f"fixed: expected a mapping joint name -> position, got {fixed!r:.60}")
    by_name = {joint.name: joint for joint in robot.joints}
    off_path = sorted(
        j.name
        for j in robot.joints
        if j.type in _MOVING and j.mimic is None and j.name not in on_path
    )
    held = {}
    for name, value in fixed.items():
        joint = by_name.get(name)
        if joint is None:
            raise ValueError(
                f"fixed: no joint {name!r} in robot {robot.name!r} (joints off the path: "
                f"{_listed(off_path)})"
            )
        if joint.type not in _MOVING:
            raise ValueError(f"fixed: joint {name!r} is {joint.type}, not a moving joint")
        if name in on_path:
            raise ValueError(f"fixed: joint {name!r} is on the chain's path (a coordinate)")
        if joint.mimic is not None:
            raise ValueError(
                f"fixed: joint {name!r} mimics {joint.mimic.joint!r}: give that joint's value"
            )
        held[name] = _within_limits(joint, value, "fixed")
    # joints off the path that mimic a held joint (or one held at 0) follow it
    for joint in robot.joints:
        if joint.mimic is None or joint.name in on_path or joint.type not in _MOVING:
            continue
        leader, c, b, seen = joint, 1.0, 0.0, {joint.name}
        while leader.mimic is not None and leader.mimic.joint in by_name:
            c, b = c * leader.mimic.multiplier, c * leader.mimic.offset + b
            leader = by_name[leader.mimic.joint]
            if leader.name in seen or leader.name in on_path:
                break
            seen.add(leader.name)
        else:
            value = c * held.get(leader.name, 0.0) + b
            if leader.name in held:
                _within_limits(joint, value, f"fixed: {leader.name!r} = {held[leader.name]} moves")
            if value != 0.0:
                held[joint.name] = value
    return {name: value for name, value in held.items() if value != 0.0}


def _within_limits(joint, value: Any, where: str) -> float:
    """A finite position of ``joint`` within its limits, or a ``ValueError`` naming it."""
    if isinstance(value, bool) or not isinstance(value, int | float | np.integer | np.floating):
        raise ValueError(f"{where}: joint {joint.name!r} needs a number, got {value!r}")
    value = float(value)
    lower, upper, _ = _limits(joint)
    if not np.isfinite(value) or not lower <= value <= upper:
        raise ValueError(
            f"{where}: joint {joint.name!r} = {value} lies outside its limits [{lower}, {upper}]"
        )
    return value


def _motion(joint, value: float) -> np.ndarray:
    """The transform of a joint at ``value`` in its own frame: a rotation about its axis, or a
    translation along it."""
    axis = _axis(joint)
    motion = np.eye(4)
    if joint.type == "prismatic":
        motion[:3, 3] = value * axis
        return motion
    k = np.array([[0.0, -axis[2], axis[1]], [axis[2], 0.0, -axis[0]], [-axis[1], axis[0], 0.0]])
    motion[:3, :3] = np.eye(3) + np.sin(value) * k + (1.0 - np.cos(value)) * (k @ k)
    return motion


def _chain_links(
    robot,
    base_link: str,
    moving: list[str],
    source,
    collision: UrdfCollision,
    held: dict[str, float] | None = None,
) -> ChainLinks:
    """Every link's pose in the base frame with every path joint at 0 and the joints off the
    path at ``held`` (else 0), and how many of the path's moving joints (in ``moving`` order)
    carry it, for ``Chain.link_poses``."""
    held = held or {}
    by_child = {joint.child: joint for joint in robot.joints}
    row = {name: i for i, name in enumerate(moving)}
    world: dict[str, np.ndarray] = {}
    carried: dict[str, int] = {}

    def place(link: str) -> tuple[np.ndarray, int]:
        if link not in world:
            joint = by_child.get(link)
            if joint is None:
                world[link], carried[link] = np.eye(4), 0
            else:
                parent, k = place(joint.parent)
                origin = np.eye(4) if joint.origin is None else np.asarray(joint.origin, float)
                if joint.name in held:
                    origin = origin @ _motion(joint, held[joint.name])
                world[link] = parent @ origin
                carried[link] = max(k, row[joint.name] + 1 if joint.name in row else 0)
        return world[link], carried[link]

    names = tuple(link.name for link in robot.links)
    base = np.linalg.inv(place(base_link)[0])
    homes = np.stack([base @ place(name)[0] for name in names])
    tree = tuple((j.parent, j.child, j.type) for j in robot.joints)
    text = source if isinstance(source, str) else os.fsdecode(source)
    if not text.lstrip("\ufeff \t\r\n").startswith("<"):
        text = str(Path(text).resolve())
    return ChainLinks(
        homes,
        tuple(carried[name] for name in names),
        names,
        text,
        tree,
        collision=collision,
        held=tuple(sorted(held.items())),
    )
