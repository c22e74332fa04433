"""What the collision checks ask of a robot: ``CollisionRobot``, a ``typing.Protocol``.

``check``, ``collides``, ``validate_motions`` and ``prepare`` take any object with these
members (every ``jaxkin.Robot`` has them: the class gives a robot with no self pairs that
always assembles, one frame per link); ``check`` and the others refuse anything else at their
boundary with a ``ValueError`` naming ``robot`` (``conforms``: the members are present; their
results are checked where they are used, ``prepare``'s body).

* ``n_joints``: the joint count ``n``;
* ``collision_body()``: the ``Body`` of spheres and capsules attached to links (host side);
* ``link_poses(q)``: every link's pose ``(..., L, 4, 4)`` (world <- link, in the order of the
  body's ``links``) at joints ``q`` ``(..., n)``, a pure kernel;
* ``link_frame_rows(q)``: the same poses in the rows layout of the checks (``rows.frames_of``):
  rotations ``(F, 3, 3, B)`` and translations ``(F, 3, B)`` of ``F`` frames at ``q``
  ``(B, n)``, the frame of each link, each link's pose in its frame (None: the identity);
* ``placeable(q)``: ``(...,)`` bool, whether the robot assembles at joints ``q`` (where it
  does not, the checks report ``UNREACHABLE``);
* ``self_collision_pairs()``: the link index pairs ``(i, j)``, ``i < j``, checked against
  each other (host side).
"""

from __future__ import annotations

from typing import Any, Protocol, runtime_checkable

from jax import Array

from .body import Body

__all__ = ["CollisionRobot", "LinkFrameRows", "conforms"]

LinkFrameRows = tuple[tuple[Array, Array], tuple[int, ...], Array | None]
"""``((rotations (F, 3, 3, B), translations (F, 3, B)), frame of each link, homes)``."""


@runtime_checkable
class CollisionRobot(Protocol):
    """A robot the collision checks can place (module docstring)."""

    @property
    def n_joints(self) -> int: ...

    def collision_body(self) -> Body: ...

    def link_poses(self, q: Array) -> Array: ...

    def link_frame_rows(self, q: Array) -> LinkFrameRows: ...

    def placeable(self, q: Array) -> Array: ...

    def self_collision_pairs(self) -> tuple[tuple[int, int], ...]: ...


_MEMBERS = tuple(name for name in vars(CollisionRobot) if not name.startswith("_"))
_CONFORMING: set[type] = set()  # classes that carry every member themselves


def conforms(robot: Any) -> bool:
    """``isinstance(robot, CollisionRobot)``, remembered for classes that carry every member
    (Python 3.11's protocol check takes tens of microseconds, a single query's budget)."""
    kind = type(robot)
    if kind in _CONFORMING:
        return True
    if not isinstance(robot, CollisionRobot):
        return False
    if all(hasattr(kind, name) for name in _MEMBERS):  # then every instance has them
        _CONFORMING.add(kind)
    return True
