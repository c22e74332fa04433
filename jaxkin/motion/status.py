"""Per-problem outcomes of motion planning (``int8`` codes, ``MotionStatus``)."""

from __future__ import annotations

import enum

import numpy as np
from jax.typing import ArrayLike

__all__ = ["MotionStatus", "describe", "status_names"]


class MotionStatus(enum.IntEnum):
    """What happened to one planning problem (``describe`` explains each code)."""

    SOLVED = 0
    NO_PATH = 1
    INVALID_START = 2
    INVALID_GOAL = 3
    UNREACHABLE_GOAL = 4
    INVALID_INPUT = 5


_DESCRIPTIONS = {
    MotionStatus.SOLVED: "a collision-free path from the start to a goal was found",
    MotionStatus.NO_PATH: "no path was found within the iteration budget",
    MotionStatus.INVALID_START: "the start collides, leaves the joint limits or the robot "
    "does not assemble there",
    MotionStatus.INVALID_GOAL: "every goal configuration collides, leaves the joint limits or "
    "does not assemble",
    MotionStatus.UNREACHABLE_GOAL: "the inverse kinematics found no collision-free solution "
    "within the limits for any goal pose or point",
    MotionStatus.INVALID_INPUT: "NaN or inf in the start or the goals",
}


def describe(code: int | MotionStatus) -> str:
    """One line: the code's name and meaning."""
    status = MotionStatus(int(code))
    return f"{status.name}: {_DESCRIPTIONS[status]}"


def status_names(status: ArrayLike) -> np.ndarray:
    """Host side: the names of an array of codes, same shape."""
    names = np.array([s.name for s in MotionStatus], dtype=object)
    return names[np.asarray(status)]
