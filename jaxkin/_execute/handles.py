"""Compiled handles: one program for one robot, world layout and batch shape, for hot loops.

A planner asks one state or one edge at a time; there a call's cost is JAX's own (about
10 us, plus 1-3 us per output), not the arithmetic. ``compiled(entry, *args, **kwargs)``
does an entry point's boundary work once (the arguments checked, the robot's body and self
pairs prepared, shapes and dtype fixed), lowers and compiles its program for those shapes
with everything but the per-call arrays compiled in, and returns a ``Handle``:
``handle(*arrays)`` is the compiled executable's call, with no Python work beyond handing the
arrays over. Its results are those of the entry point on the same inputs (the same program).
An input of another shape or dtype is refused by the executable (``TypeError``).

Entry points that offer a handle register a builder with ``builds``; ``compiled`` looks it
up, so a handle is asked for by the public function itself::

    handle = jaxkin.compiled(jaxkin.collision.collides, robot, world, batch=1)
    verdict = handle(q)  # q of shape (1, n_joints)

Outputs that do not depend on the inputs (the zero rates of a query at rest) are computed
once and put back into each result on the host, so the executable returns fewer outputs.
After ``jaxkin.enable_low_latency()`` (``latency``) the program is the body of a loop of one
trip (``latency.in_one_loop``), which XLA compiles as one function run in the calling thread.
"""

from __future__ import annotations

import operator
from collections.abc import Callable
from typing import Any

import jax
import numpy as np

from .. import _batching
from .latency import in_one_loop

__all__ = [
    "Handle",
    "HotQueries",
    "batch_shape",
    "builds",
    "compiled",
    "handle_dtype",
    "shared_by_value",
]


class Handle:
    """A program compiled for fixed input shapes and dtypes (module docstring).

    Args:
        fn: a pure function of ``examples``' structure (arrays, or pytrees of arrays), then of
            the ``bound`` arrays.
        examples: inputs of the shapes and dtypes the handle takes.
        bound: arrays passed to every call after the caller's (a world packed into one array):
            data of the program rather than constants, so ``rebound`` swaps them without
            compiling.
        rebind: ``rebind(*values) -> bound`` for ``rebound`` (checks and converts its
            arguments, e.g. a world of the same layout); None: nothing to rebind.
        compiler_options: XLA options of the compilation (``(name, value)`` pairs), as the
            entry point's ``Policy`` gives them.

    Attributes:
        compiled: the ``jax.stages.Compiled`` executable (its HLO: ``compiled.as_text()``).
    """

    __slots__ = ("_bound", "_constants", "_moving", "_rebind", "_run", "_tree", "compiled")

    def __init__(
        self,
        fn: Callable[..., Any],
        examples: tuple,
        bound: tuple = (),
        rebind: Callable[..., tuple] | None = None,
        compiler_options: tuple = (),
    ) -> None:
        self._bound = tuple(bound)
        self._rebind = rebind
        options = dict(compiler_options) or None
        traced = jax.jit(fn, compiler_options=options).trace(*examples, *self._bound)
        tree = jax.tree.structure(traced.out_info)
        inputs = [True] * len(traced.jaxpr.jaxpr.invars)
        dependent = _input_dependent(traced.jaxpr.jaxpr, inputs)
        moving = [i for i, m in enumerate(dependent) if m]
        if len(moving) == len(dependent) or not moving:
            program = in_one_loop(fn)
            if program is fn:
                self.compiled = traced.lower().compile()
            else:
                self.compiled = (
                    jax.jit(program, compiler_options=options)
                    .lower(*examples, *self._bound)
                    .compile()
                )
            self._run: Any = self.compiled
            self._tree: Any = None
            self._moving: tuple[int, ...] = ()
            self._constants: tuple[Any, ...] = ()
            return

        def outputs(*args: Any) -> list:
            leaves = jax.tree.leaves(fn(*args))
            return [leaves[i] for i in moving]

        # the inputs' constant outputs from one call of ``fn`` as it is (no compilation of them)
        constants = jax.tree.leaves(fn(*examples, *self._bound))
        self.compiled = (
            jax.jit(in_one_loop(outputs), compiler_options=options)
            .lower(*examples, *self._bound)
            .compile()
        )
        self._run = None
        self._tree = tree
        self._moving = tuple(moving)
        self._constants = tuple(constants)

    def __call__(self, *args: Any) -> Any:
        if self._run is not None:
            return self._run(*args, *self._bound)
        leaves = list(self._constants)
        for i, value in zip(self._moving, self.compiled(*args, *self._bound), strict=True):
            leaves[i] = value
        return self._tree.unflatten(leaves)

    def rebound(self, *values: Any) -> Handle:
        """A handle of the same program whose bound arrays are ``rebind(*values)`` (e.g.
        ``handle.rebound(world)``: another world of the same layout): no compilation."""
        if self._rebind is None:
            raise ValueError("this handle has nothing to rebind")
        other = object.__new__(Handle)
        for name in Handle.__slots__:
            object.__setattr__(other, name, getattr(self, name))
        other._bound = tuple(self._rebind(*values))
        return other


_BUILDERS: dict[Any, Callable[..., Handle]] = {}


def builds(entry: Callable[..., Any]) -> Callable[[Callable[..., Handle]], Callable[..., Handle]]:
    """Register the decorated function as the handle builder of the public ``entry``."""

    def register(builder: Callable[..., Handle]) -> Callable[..., Handle]:
        _BUILDERS[entry] = builder
        return builder

    return register


def compiled(entry: Callable[..., Any], *args: Any, **kwargs: Any) -> Handle:
    """A compiled handle of the public function ``entry`` for fixed shapes (module docstring).

    ``entry`` is one of ``jaxkin.ik``, ``jaxkin.fk``, ``collision.check``,
    ``collision.collides`` and ``collision.validate_motions`` (a robot module's own ``ik`` and
    ``fk`` are ``jaxkin.ik``'s); ``args`` and ``kwargs`` are its arguments other than the
    per-call arrays, plus ``batch`` (the leading shape of those arrays, an int or a tuple;
    ``()`` for one element without a batch axis) and ``dtype`` (their floating dtype; JAX's
    default float when None). Each entry point's docstring lists the rest.

    Raises:
        ValueError: ``entry`` offers no handle, or an argument is refused (as the entry point
            refuses it, naming it).
    """
    builder = _BUILDERS.get(entry)
    if builder is None:
        names = sorted(f"{f.__module__}.{f.__qualname__}" for f in _BUILDERS)
        raise ValueError(f"entry: {entry!r} offers no compiled handle; these do: {names}")
    return builder(*args, **kwargs)


def batch_shape(batch: Any) -> tuple[int, ...]:
    """``batch`` (an int or a sequence of ints >= 0) as a shape; ``ValueError`` naming it."""
    try:
        shape = (operator.index(batch),) if not hasattr(batch, "__len__") else tuple(batch)
        shape = tuple(operator.index(d) for d in shape)
    except TypeError:
        raise ValueError(f"batch: expected an int or a tuple of ints, got {batch!r}") from None
    if any(d < 0 for d in shape) or isinstance(batch, bool):
        raise ValueError(f"batch: expected sizes >= 0, got {batch!r}")
    return shape


def handle_dtype(dtype: Any, name: str = "dtype") -> np.dtype:
    """A handle's floating dtype: JAX's default float for None; ``ValueError`` naming
    ``name`` for one that is not floating or needs JAX's 64-bit mode off."""
    dtype = np.dtype(jax.numpy.result_type(float) if dtype is None else dtype)
    if dtype.kind != "f":
        raise ValueError(f"{name}: expected a floating dtype, got {dtype}")
    if dtype != jax.dtypes.canonicalize_dtype(dtype):
        raise ValueError(f"{name}: {dtype} needs JAX's 64-bit mode (jax_enable_x64)")
    return dtype


# ------------------------------------------------------------------ hot single queries


class HotQueries:
    """The handles of the single queries asked most often, the earliest built dropped beyond
    ``size`` (a lookup stays one dictionary read).

    ``get(key, owner, build)`` counts the calls of ``key`` (which starts with ``id(owner)``)
    and returns None until the ``_batching.HOT_AFTER``-th, which calls ``build()`` and keeps
    its result (a handle, or None for a query that has none) with ``owner``: an entry answers
    only while its owner is that very object (a key whose ``id`` was reused starts counting
    again). Handles are shared by the robots of equal values (``by_value``).
    """

    def __init__(self, size: int | None = None) -> None:
        self.size = _batching.HOT_PROGRAMS if size is None else size
        self.programs: dict[tuple, tuple[Any, Any]] = {}
        self.counts: dict[tuple, int] = {}
        self.none: dict[tuple, Any] = {}  # keys without a handle (batches): owner by key
        self.by_value: dict[tuple, Any] = {}  # handles by the robot's values, for its copies

    def get(self, key: tuple, owner: Any, build: Callable[[], Any]) -> Any:
        entry = self.programs.get(key)
        if entry is not None and entry[0] is owner:
            return entry[1]
        if self.none.get(key) is owner:
            return None
        count = self.counts.pop(key, 0) + 1
        if count < _batching.HOT_AFTER:
            bounded_put(self.counts, key, count, 4 * self.size)
            return None
        program = build()
        self.counts.pop(key, None)  # the build may have called the query once more
        if program is None:  # kept apart, so that batches never push handles out
            bounded_put(self.none, key, owner, 4 * self.size)
        else:
            bounded_put(self.programs, key, (owner, program), self.size)
        return program

    def clear(self) -> None:
        """Forget every handle and count."""
        self.programs.clear()
        self.counts.clear()
        self.none.clear()
        self.by_value.clear()


def bounded_put(table: dict, key: Any, value: Any, size: int) -> None:
    """``table[key] = value`` as its newest entry, the oldest dropped beyond ``size``."""
    table.pop(key, None)
    table[key] = value
    if len(table) > size:
        del table[next(iter(table))]


def shared_by_value(table: HotQueries, robot: Any, key: tuple, build: Callable[[], Any]) -> Any:
    """``build()``, shared by robots of equal values: a robot rebuilt with the same values (a
    new object per episode) reuses the handle built for an earlier one (``table.by_value``,
    keyed by the tree and the values of every leaf of ``robot``, and ``key``)."""
    leaves, tree = jax.tree.flatten(robot)
    values = tuple(
        (np.asarray(leaf).dtype.str, np.shape(leaf), np.asarray(leaf).tobytes()) for leaf in leaves
    )
    whole = (tree, values, *key, jax.config.jax_enable_x64)  # type: ignore[attr-defined]  # jax's Config types no options
    try:
        handle = table.by_value.get(whole)
    except TypeError:  # a key that cannot be hashed: not shared
        return build()
    if handle is None:
        handle = build()
        bounded_put(table.by_value, whole, handle, table.size)
    return handle


def _input_dependent(jaxpr: Any, inputs: list[bool] | None = None) -> list[bool]:
    """Per output of ``jaxpr``: whether it depends on an input (``inputs``: which of its
    inputs count; all by default). A nested call (``jit``, ``custom_jvp_call``) is followed
    into its body; any other equation with a dependent operand has every result dependent."""
    inputs = [True] * len(jaxpr.invars) if inputs is None else inputs
    dependent = {id(v) for v, d in zip(jaxpr.invars, inputs, strict=True) if d}
    for eqn in jaxpr.eqns:
        operands = [not _is_literal(v) and id(v) in dependent for v in eqn.invars]
        if not any(operands):
            continue
        body = None
        if eqn.primitive.name in _CALLS:
            body = next((eqn.params[k] for k in ("jaxpr", "call_jaxpr") if k in eqn.params), None)
            body = getattr(body, "jaxpr", body)
        if body is not None and len(getattr(body, "invars", ())) == len(operands):
            results = _input_dependent(body, operands)
        else:
            results = [True] * len(eqn.outvars)
        dependent.update(id(v) for v, d in zip(eqn.outvars, results, strict=True) if d)
    return [not _is_literal(v) and id(v) in dependent for v in jaxpr.outvars]


# Nested calls whose body runs once on the operands (not loops: a loop's carry mixes).
_CALLS = frozenset({"pjit", "jit", "closed_call", "core_call", "custom_jvp_call", "remat"})


def _is_literal(v: Any) -> bool:
    return type(v).__name__ == "Literal"
