"""Per-element status codes shared by every solver.

Failure is data: a solver never raises inside ``jit``; each element of a batch carries one of
these codes (stored as ``int8``) beside finite placeholder values. When several conditions hold,
the most basic one wins: ``INVALID_INPUT`` before ``UNREACHABLE`` before the singular cases.
``UNTIMEABLE`` is the retiming's (``jaxkin.timing``): no timing within the joints' speed and
acceleration limits follows the path. ``DISCONTINUOUS`` is the planner's (``jaxkin.plan``): the
joints jump between this sample and the previous one by a step their rates do not explain (the
inverse kinematics switched solution).
"""

from __future__ import annotations

import dataclasses
import enum
from typing import Any, ClassVar

import jax
import jax.numpy as jnp
import numpy as np
from jax.typing import ArrayLike

__all__ = [
    "STATUS_DTYPE",
    "NamedStatusRepr",
    "Status",
    "describe",
    "named_codes",
    "status_names",
]

STATUS_DTYPE = jnp.int8


class Status(enum.IntEnum):
    """What happened to one element of a batch (see ``describe`` for each code's meaning)."""

    OK = 0
    UNREACHABLE = 1
    SINGULAR_EXTENDED = 2
    SINGULAR_FOLDED = 3
    SINGULAR_COINCIDENT = 4
    SINGULAR = 5
    NOT_CONVERGED = 6
    OUT_OF_LIMITS = 7
    INVALID_INPUT = 8
    UNTIMEABLE = 9
    DISCONTINUOUS = 10
    COLLISION = 11


_DESCRIPTIONS = {
    Status.OK: "solved; position, velocity and acceleration are valid",
    Status.UNREACHABLE: "the target cannot be reached (the mechanism cannot be assembled)",
    Status.SINGULAR_EXTENDED: (
        "dyad with beta = 0 (C on the ray A->B): position valid, rates undefined"
    ),
    Status.SINGULAR_FOLDED: (
        "dyad with beta = pi (C on the ray opposite A->B): position valid, rates undefined"
    ),
    Status.SINGULAR_COINCIDENT: (
        "dyad with coincident known joints and equal links: C is undefined"
    ),
    Status.SINGULAR: "a Jacobian of the mechanism is singular: position valid, rates not",
    Status.NOT_CONVERGED: "an iterative solver stopped before reaching its tolerance",
    Status.OUT_OF_LIMITS: (
        "solved, but a joint limit is violated (a chain's IK search: only with evidence that no "
        "solution lies within the limits, every one of its unbounded runs having met the "
        "tolerances outside them; otherwise NOT_CONVERGED)"
    ),
    Status.INVALID_INPUT: "NaN or inf in this element's input",
    Status.UNTIMEABLE: (
        "the path cannot be timed within the velocity and acceleration limits (a joint that "
        "must move has a zero limit or no acceleration limit, or the start or end speed "
        "cannot be reached)"
    ),
    Status.DISCONTINUOUS: (
        "solved, but the joints jump from the previous sample by a step their rates do not "
        "explain (the solution switched): the path cannot be followed continuously"
    ),
    Status.COLLISION: (
        "solved, but the robot's body touches an obstacle of the world or itself "
        "(collision.check: clearance <= 0)"
    ),
}


def describe(code: int | Status) -> str:
    """One-line, human-readable description of a status code."""
    status = Status(int(code))
    return f"{status.name}: {_DESCRIPTIONS[status]}"


def status_names(status: ArrayLike) -> np.ndarray:
    """Host-side: the names of an array of codes, same shape (for printing and CSV files)."""
    codes = np.asarray(status)
    names = np.array([s.name for s in Status], dtype=object)
    return names[codes]


def named_codes(value: Any, codes: type[enum.IntEnum]) -> str | None:
    """``Array([OK, COLLISION], dtype=int8)``: the repr of a concrete array of ``codes``
    (an ``IntEnum``) with each code's name in place of its number (a number where it is no
    code); None for anything else (a tracer, floats, None), whose own repr serves."""
    if isinstance(value, jax.core.Tracer) or not isinstance(value, jax.Array | np.ndarray):
        return None
    if not np.issubdtype(value.dtype, np.integer):
        return None
    numbers = np.asarray(value)
    known = {int(c): c.name for c in codes}
    names = np.vectorize(lambda c: known.get(int(c), str(int(c))), otypes=[object])(numbers)
    prefix = "Array(" if isinstance(value, jax.Array) else "array("
    text = np.array2string(names, separator=", ", formatter={"all": str}, prefix=prefix)
    return f"{prefix}{text}, dtype={numbers.dtype})"


class NamedStatusRepr:
    """Mixin for result dataclasses: their repr shows status codes by name.

    ``status_fields`` maps field names to their code enum (``{"status": Status}`` by
    default); every other field prints as the dataclass would print it. A subclass that
    defines no ``__repr__`` of its own gets this one (``@dataclass`` keeps a class's own
    ``__repr__``), so that a result prints ``status=Array([OK, COLLISION], dtype=int8)``
    rather than the bare codes.
    """

    status_fields: ClassVar[dict[str, type[enum.IntEnum]]] = {"status": Status}

    def __init_subclass__(cls, **kwargs: Any) -> None:
        super().__init_subclass__(**kwargs)
        if "__repr__" not in cls.__dict__:
            cls.__repr__ = NamedStatusRepr.__repr__  # type: ignore[method-assign]

    def __repr__(self) -> str:
        parts = []
        for field in dataclasses.fields(self):  # type: ignore[arg-type]
            if not field.repr:
                continue
            value = getattr(self, field.name)
            codes = self.status_fields.get(field.name)
            named = None if codes is None else named_codes(value, codes)
            parts.append(f"{field.name}={named if named is not None else repr(value)}")
        return f"{type(self).__qualname__}({', '.join(parts)})"
