"""The options of a chain's inverse kinematics (``jaxkin.ik`` of a ``JointChain``, ``PoEChain``
or ``DHTable``; the search is ``jaxkin.serial.newton_ik``)."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from .._validate import is_concrete
from ..robot import options

__all__ = ["CHAIN_MIN_PART", "QUEUE_SLOTS", "ChainIKOptions"]

# Lanes of the work queue of the chain IK (``newton_ik._queued``): batches up to this size run
# every target in step; larger ones keep this many iterating and refill them as targets end
# (1e3-1e4 UR5 / Panda poses: 32-64 lanes fastest, 4-7x the batch in step).
QUEUE_SLOTS = 32
# Targets per host-thread part of the chain IK (``_batching.PartsJit``): each part is a queue.
CHAIN_MIN_PART = 4 * QUEUE_SLOTS


def _count(value: Any, name: str) -> None:
    if isinstance(value, bool) or not isinstance(value, int) or value < 1:
        raise ValueError(f"{name} must be an int >= 1, got {value!r}")


def _tolerance(value: Any, name: str) -> Any:
    """A positive finite tolerance as a float, or None; traced values pass (not user input)."""
    if value is None or not is_concrete(value):
        return value
    if isinstance(value, bool | str | bytes) or np.ndim(value) != 0:
        raise ValueError(f"{name} must be a positive finite number, got {value!r}")
    number = float(value)
    if not (math.isfinite(number) and number > 0):
        raise ValueError(f"{name} must be a positive finite number, got {value!r}")
    return number


@options(dynamic=("position_tol", "orientation_tol"))
class ChainIKOptions:
    """Options of a chain's IK (projected Levenberg-Marquardt with restarts).

    Attributes:
        restarts: runs per element at most (>= 1), before the unbounded run.
        max_iter: updates per run (>= 1).
        warm_iter: updates of a later path sample's run from the previous solution (the
            planner's warm-started IK along paths).
        position_tol: length units; None for ``max(1e-10, 1000 eps) * chain.length_scale()``.
            A new value compiles nothing new.
        orientation_tol: rad; None for ``max(1e-10, 1000 eps)``.
        use_limits: respect the chain's position limits (False: search without them).
    """

    restarts: int = 64
    max_iter: int = 12
    warm_iter: int = 20
    position_tol: float | None = None
    orientation_tol: float | None = None
    use_limits: bool = True

    def __post_init__(self) -> None:
        for name in ("restarts", "max_iter", "warm_iter"):
            _count(getattr(self, name), name)
        for name in ("position_tol", "orientation_tol"):
            object.__setattr__(self, name, _tolerance(getattr(self, name), name))
        if not isinstance(self.use_limits, bool):
            object.__setattr__(self, "use_limits", bool(self.use_limits))
