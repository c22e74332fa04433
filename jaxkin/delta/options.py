"""The Delta's solver options: ``DeltaIKOptions`` and ``DeltaFKOptions`` (frozen, hashable
dataclasses with defaults; ``jaxkin.ik(robot, p, method=...)`` and ``jaxkin.fk(robot, theta,
tol=...)`` build them). Validated on construction, on the host: a ``ValueError`` names the
option."""

from __future__ import annotations

import jax.numpy as jnp

from .. import _validate
from ..robot import options
from ._math import METHODS

__all__ = ["DeltaFKOptions", "DeltaIKOptions"]


@options
class DeltaIKOptions:
    """Options of the Delta's IK: ``method`` ``"analytic"`` (constraint Jacobians) or
    ``"autodiff"`` (``jaxkin.lift``)."""

    method: str = "analytic"

    def __post_init__(self) -> None:
        _validate.choice(self.method, "method", METHODS)


@options
class DeltaFKOptions:
    """Options of the Delta's Newton FK (``jaxkin.delta.fk``).

    Attributes:
        tol: converged where ``max_i |r_i| <= tol * (l_arm + l_rod)``; None for
            ``max(1e-12, 8 eps(dtype))`` (``tolerance``).
        max_iter: maximum number of Newton updates (>= 1).
        method: ``"analytic"`` rates or ``"autodiff"``.
    """

    tol: float | None = None
    max_iter: int = 30
    method: str = "analytic"

    def __post_init__(self) -> None:
        if self.tol is not None:
            object.__setattr__(self, "tol", _validate.positive_number(self.tol, "tol"))
        object.__setattr__(self, "max_iter", _validate.count(self.max_iter, "max_iter"))
        _validate.choice(self.method, "method", METHODS)

    def tolerance(self, dtype) -> float:
        """``tol``, or its default for ``dtype``: ``max(1e-12, 8 eps(dtype))``, i.e. 1e-12 in
        float64 and 9.5e-7 in float32 (1e-12 is below float32 resolution)."""
        if self.tol is not None:
            return self.tol
        return max(1e-12, 8.0 * float(jnp.finfo(dtype).eps))
