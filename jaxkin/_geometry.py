"""Geometry types: validated frozen dataclasses that are pytrees.

Every robot geometry (``Scara``, ``Delta``, the arms, DH and PoE chains, joint limits) is a
frozen dataclass declared with ``@geometry``. Its numeric fields are pytree leaves (so a
geometry can be differentiated, for calibration, and vmapped over); fields marked ``static``
(joint types, frames) are part of the tree structure. Fields marked ``label`` (names of joints
and links) travel with the tree structure but compare equal whatever their values, so two
geometries that differ only in labels share every compiled program.

Validation happens in one way, whether a geometry is built by its constructor or by a factory
(``create``, ``paper``): ``__post_init__`` checks every field declared with ``number(...)``
and raises a ``ValueError`` naming the field. Accepted: real numbers (Python, NumPy or JAX
scalars and arrays of the declared shape); refused: ``bool``, strings, ``None``, complex
values, NaN, and values outside the field's kind (``LENGTH`` > 0, ``NONNEGATIVE`` >= 0,
``REAL`` finite, ``BOUND`` finite or +-inf). Python numbers are kept as Python floats (a
concrete geometry can then be compiled into a kernel as constants), anything else becomes a
floating JAX array of its own (a copy: editing the caller's array afterwards changes nothing).

JAX rebuilds geometries from tracers, abstract values and cotangents: that path (the pytree
unflatten) skips ``__init__`` and so skips validation, because those are not user input (a
gradient with respect to a length may well be negative). Tracers given to a constructor inside
``jit`` are not checked either.
"""

from __future__ import annotations

import dataclasses
import numbers
from typing import Any, TypeVar, dataclass_transform

import jax
import jax.numpy as jnp
import numpy as np

from ._validate import is_concrete, owned_float

LENGTH = "length"
NONNEGATIVE = "nonnegative"
REAL = "real"
BOUND = "bound"

_EXPECTED = {
    LENGTH: ("a positive finite length", "positive finite lengths"),
    NONNEGATIVE: ("a finite number >= 0", "finite numbers >= 0"),
    REAL: ("a finite real number", "finite real numbers"),
    BOUND: ("a real number or +-inf (not NaN)", "real numbers or +-inf (not NaN)"),
}

# A field's shape: () a scalar; a tuple with -1 for "any size" on that axis; None any shape
# (batched geometry values broadcast against the batch).
Shape = tuple[int, ...] | None


Numeric = Any
"""The type of a ``number`` field: the constructor takes any real array-like (a float, a list, a
NumPy or JAX array, a tracer), the field holds a float or a JAX array after validation; JAX's
``ArrayLike`` has no arithmetic in its type, so the fields are ``Any`` to the type checker."""


def number(kind: str = LENGTH, shape: Shape = (), default: Any = dataclasses.MISSING) -> Any:
    """A numeric geometry field of ``kind`` and ``shape``, validated at construction."""
    metadata = {"kind": kind, "shape": shape}
    if default is dataclasses.MISSING:
        return dataclasses.field(metadata=metadata)
    return dataclasses.field(default=default, metadata=metadata)


def static(default: Any = dataclasses.MISSING) -> Any:
    """A discrete field (joint types, a frame name): part of the pytree structure."""
    if default is dataclasses.MISSING:
        return dataclasses.field(metadata={"static": True})
    return dataclasses.field(default=default, metadata={"static": True})


def label(default: Any = dataclasses.MISSING) -> Any:
    """A name (joint or link names): kept by every pytree operation, never a compilation key.

    Labels ride in the tree structure inside a ``Labels`` holder that compares equal to any
    other, so renaming a joint does not recompile. A jitted function that *returns* such a
    geometry returns the labels it was first traced with; kernels return arrays, not robots.
    """
    if default is dataclasses.MISSING:
        return dataclasses.field(metadata={"label": True})
    return dataclasses.field(default=default, metadata={"label": True})


class Labels:
    """The label fields of one geometry, in the tree structure; equal to every ``Labels``."""

    __slots__ = ("values",)

    def __init__(self, values: tuple) -> None:
        self.values = values

    def __eq__(self, other: object) -> bool:
        return isinstance(other, Labels)

    def __hash__(self) -> int:
        return hash(Labels)

    def __repr__(self) -> str:
        return f"Labels{self.values!r}"


def _shape_matches(actual: tuple[int, ...], expected: Shape) -> bool:
    if expected is None:
        return True
    return len(actual) == len(expected) and all(
        e in (-1, a) for a, e in zip(actual, expected, strict=True)
    )


def check_number(value: Any, name: str, kind: str = LENGTH, shape: Shape = ()) -> Any:
    """One validated numeric value (see the module docstring); tracers pass unchecked."""
    if isinstance(value, jax.core.Tracer):
        return value
    single, plural = _EXPECTED[kind]
    what = single if shape == () or np.ndim(value) == 0 else f"an array of {plural}"
    if isinstance(value, bool | np.bool_ | str | bytes) or value is None:
        raise ValueError(f"{name} must be {what}, got {value!r}")
    if isinstance(value, numbers.Number) and not isinstance(value, numbers.Real):
        raise ValueError(f"{name} must be {what}, got the complex value {value!r}")
    try:
        arr = np.asarray(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be {what}, got {value!r}") from None
    if arr.dtype == object or not (
        np.issubdtype(arr.dtype, np.floating) or np.issubdtype(arr.dtype, np.integer)
    ):
        raise ValueError(f"{name} must be {what}, got {value!r} (dtype {arr.dtype})")
    if not _shape_matches(arr.shape, shape):
        wanted = "a scalar" if shape == () else f"of shape {shape} (-1: any size)"
        raise ValueError(f"{name} must be {wanted}, got shape {arr.shape}")
    values = arr.astype(np.float64)
    bad = np.isnan(values)
    if kind != BOUND:
        bad |= ~np.isfinite(values)
    if kind == LENGTH:
        bad |= values <= 0
    elif kind == NONNEGATIVE:
        bad |= values < 0
    if np.any(bad):
        shown = float(values) if values.ndim == 0 else values
        raise ValueError(f"{name} must be {what}, got {shown}")
    if isinstance(value, numbers.Real) and arr.ndim == 0:
        return float(value)
    return owned_float(value)  # the caller's array may change after this returns


class Geometry:
    """Base class of geometry dataclasses: validates the ``number`` fields after ``__init__``.

    Subclasses may override ``_validate`` for checks that involve several fields (call
    ``super()._validate()`` first); it runs only for geometries built by a user.
    """

    def __post_init__(self) -> None:
        self._validate()

    def _validate(self) -> None:
        for field in dataclasses.fields(self):  # type: ignore[arg-type]
            if "kind" not in field.metadata:
                continue
            value = check_number(
                getattr(self, field.name),
                f"{type(self).__name__}.{field.name}",
                field.metadata["kind"],
                field.metadata["shape"],
            )
            object.__setattr__(self, field.name, value)
        # Scalar fields share one batch shape (a default radius beside batched lengths), so
        # that ``jax.vmap`` over a batch of robots maps every leaf.
        scalars = [
            f.name
            for f in dataclasses.fields(self)  # type: ignore[arg-type]
            if "kind" in f.metadata and f.metadata["shape"] in ((), None)
        ]
        shapes = [np.shape(getattr(self, name)) for name in scalars]
        if any(shapes):
            try:
                batch = np.broadcast_shapes(*shapes)
            except ValueError:  # the robot's own batch check names the fields
                return
            for name, shape in zip(scalars, shapes, strict=True):
                if shape != batch:
                    value = jnp.broadcast_to(getattr(self, name), batch)
                    object.__setattr__(self, name, value)

    def replace(self, **changes: Any) -> Any:
        """A copy with some fields changed (validated like a new geometry)."""
        return dataclasses.replace(self, **changes)  # type: ignore[type-var]  # a @geometry

    def astype(self, dtype: Any) -> Any:
        """The same geometry with every numeric leaf cast to ``dtype`` (no validation)."""
        return jax.tree.map(lambda x: jnp.asarray(x).astype(dtype), self)


_Class = TypeVar("_Class", bound=type)


@dataclass_transform(
    frozen_default=True, field_specifiers=(dataclasses.field, number, static, label)
)
def geometry(cls: _Class) -> _Class:
    """Class decorator: a frozen dataclass registered as a pytree that skips validation on
    unflatten (see the module docstring). Fields declared with ``static()`` are metadata, those
    declared with ``label()`` metadata that never keys a compilation."""
    dataclasses.dataclass(frozen=True)(cls)  # in place: the class itself is returned
    fields = dataclasses.fields(cls)

    def is_data(f: dataclasses.Field) -> bool:
        return not (f.metadata.get("static") or f.metadata.get("label"))

    data = tuple(f.name for f in fields if is_data(f))
    meta = tuple(f.name for f in fields if f.metadata.get("static"))
    labels = tuple(f.name for f in fields if f.metadata.get("label"))

    def aux_of(obj: Any) -> tuple:
        aux = tuple(getattr(obj, n) for n in meta)
        return (*aux, Labels(tuple(getattr(obj, n) for n in labels))) if labels else aux

    def flatten_with_keys(obj: Any):
        children = [(jax.tree_util.GetAttrKey(n), getattr(obj, n)) for n in data]
        return children, aux_of(obj)

    def flatten(obj: Any):
        return [getattr(obj, n) for n in data], aux_of(obj)

    def unflatten(aux: tuple, children: Any) -> Any:
        obj: Any = object.__new__(cls)
        for name, value in zip(data, children, strict=True):
            object.__setattr__(obj, name, value)
        for name, value in zip(meta, aux[: len(meta)], strict=True):
            object.__setattr__(obj, name, value)
        if labels:
            for name, value in zip(labels, aux[-1].values, strict=True):
                object.__setattr__(obj, name, value)
        return obj

    jax.tree_util.register_pytree_with_keys(cls, flatten_with_keys, unflatten, flatten)
    return cls


def concrete_scalars(obj: Any, names: tuple[str, ...]) -> tuple[float, ...] | None:
    """The named fields as Python floats when every one is a concrete scalar, else None."""
    values = [getattr(obj, n) for n in names]
    if not all(is_concrete(v) and np.ndim(v) == 0 for v in values):
        return None
    return tuple(float(v) for v in values)
