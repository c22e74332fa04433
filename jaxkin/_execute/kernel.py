"""``Kernel``: a pure function of arrays, compiled by ``jax.jit`` and run under a ``Policy``.

Every compiled program of jaxkin is a ``Kernel`` (no module calls ``jax.jit`` itself); its
concrete calls are jitted through ``store.stored_jit``, which with the program store on finds
the program a previous process kept instead of tracing it again. A kernel is called like its
function; given the batch shape (``batch=``), its policy decides how a concrete call runs:

* **tracers** (inside a caller's ``jit``, ``vmap`` or ``grad``): the function is traced into
  the caller's program as it is (XLA options are a top-level compilation's: dropped);
* **padded** (``Policy.pad``): a batch of at most ``_batching.PAD_MAX`` elements, any shape,
  is flattened and padded to ``_batching.padded_size`` by repeating its last element (a real
  input, computed and dropped), so batch sizes share one compilation per size class; the
  outputs are cut back on the host (so a new batch shape compiles nothing);
* **host threads** (``Policy.threads``): a large batch is split into one part per host thread
  (``_batching.num_threads``), each part slicing its inputs inside the kernel, and joined:
  XLA on the CPU runs a ``while_loop``'s body on one core, two programs on two threads run at
  once;
* **whole**: anything else, one call of the jitted function.

Every split gives the values of the whole batch (the kernels are elementwise in the batch);
a padded batch those of the padded program (the same to a few ulp). ``batched`` names the
arguments that carry the batch, with the number of trailing (core) axes of their leaves;
leaves of rank 0 with no core axes are shared. ``axes`` names output fields whose batch axis
is not the first.
"""

from __future__ import annotations

import dataclasses
import functools
import inspect
import math
from collections.abc import Callable
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

from .. import _batching
from .._validate import is_concrete
from .store import keeps_programs, stored_jit

__all__ = ["WHOLE", "Kernel", "Policy", "kernel"]


@dataclasses.dataclass(frozen=True)
class Policy:
    """How a kernel's concrete calls are compiled and run (module docstring).

    Attributes:
        pad: concrete batches of at most ``_batching.PAD_MAX`` elements run padded to a power
            of two: batch sizes share one compilation per size class.
        pad_min: the smallest padded size (None: ``_batching.PAD_MIN``); 1 for a kernel
            whose every element is costly (a planner's candidate: a whole path), where
            padding one element to ``PAD_MIN`` would multiply its time.
        threads: large concrete batches are split across the host threads, for loop-bound
            (iterative) kernels.
        min_part: fewest elements per host-thread part (None: ``_batching.MIN_PART``).
        constant_geometry: (robots) a geometry whose every leaf is a concrete scalar is
            compiled into the kernel as constants (one compilation per robot; XLA folds its
            values).
        branch_as_data: (robots) the branch reaches the kernel as a traced index
            (``ik_kernel_indexed``), so every branch shares one compilation.
        bucket: (robots) for an iterative kernel that ends a NaN input at once (a chain's IK
            search): a concrete batch of two or more elements runs in blocks of exactly
            ``bucket`` rows (a smaller batch padded with NaN rows spread among its own, a
            larger one as overlapping blocks on the host threads): one compilation for every
            batch size. None: not so.
        compiler_options: XLA options of this kernel's compilation alone, ``(name, value)``
            pairs (``jax.jit``'s ``compiler_options``), e.g. a cheaper code generation for a
            large loop-bound kernel.
    """

    pad: bool = True
    pad_min: int | None = None
    threads: bool = False
    min_part: int | None = None
    constant_geometry: bool = False
    branch_as_data: bool = False
    bucket: int | None = None
    compiler_options: tuple[tuple[str, Any], ...] = ()


WHOLE = Policy(pad=False)  # one call of the jitted function, whatever the batch


class Kernel:
    """A pure function compiled once per shapes and static arguments, run under ``policy``.

    Args:
        fn: the kernel, elementwise in the batch (element ``i`` of every output depends only
            on element ``i`` of the batched arguments).
        static: names of the arguments that are compile-time constants (hashable).
        batched: argument name -> the number of trailing axes of its leaves that are not batch
            axes (1 for points ``(..., 3)``, 0 for per-element scalars).
        policy: how concrete calls run (``Policy``; ``WHOLE`` by default).
        axes: output field name -> its batch axis where it is not the first (a history
            ``(steps, ..., n)``: ``{"history": 1}``).

    ``kernel(*args, **kwargs)`` runs the jitted function; ``kernel(*args, batch=shape,
    **kwargs)`` applies the policy (``pad=False`` where an argument outside ``batched`` has
    batch axes, or ``pad`` a dict that replaces ``batched`` for this call). ``lower`` and
    ``trace`` are ``jax.jit``'s.
    """

    def __init__(
        self,
        fn: Callable[..., Any],
        *,
        static: tuple[str, ...] = (),
        batched: dict[str, int] | None = None,
        policy: Policy = WHOLE,
        axes: dict[str, int] | None = None,
    ) -> None:
        self.fn = fn
        self.static = tuple(static)
        self.batched = dict(batched or {})
        self.policy = policy
        self.axes = dict(axes or {})
        options = dict(policy.compiler_options) or None
        # concrete calls: programs a later process finds without tracing (``store``)
        self.jitted = stored_jit(fn, static_argnames=self.static, compiler_options=options)
        # inside a caller's jit, vmap or grad: traced as it is, under the enclosing program's
        # compilation settings
        self._nested = jax.jit(fn, static_argnames=self.static or None)
        self._part: Any = None
        if policy.threads:
            self._part = stored_jit(
                self._part_impl,
                static_argnames=("static_values", "batch", "part"),
                compiler_options=options,
                identity=("part", self),
            )
        self._signature = inspect.signature(fn)
        functools.update_wrapper(self, fn)

    def lower(self, *args: Any, **kwargs: Any) -> Any:
        return self.jitted.lower(*args, **kwargs)

    def trace(self, *args: Any, **kwargs: Any) -> Any:
        return self.jitted.trace(*args, **kwargs)

    def __call__(
        self,
        *args: Any,
        batch: tuple[int, ...] | None = None,
        pad: bool | dict[str, int] = True,
        **kwargs: Any,
    ) -> Any:
        if batch is None or not all(is_concrete(x) for x in jax.tree.leaves((args, kwargs))):
            return self.direct(*args, **kwargs)
        batch = tuple(int(d) for d in batch)
        size = math.prod(batch)
        padded = _batching.padded_size(size, self.policy.pad_min)
        if (
            not self.policy.pad
            or not pad
            or size == 0
            or (padded == size and len(batch) == 1)
            or jax.device_count() > 1
        ):
            return self.whole(args, kwargs, batch)
        bound = self._signature.bind(*args, **kwargs)
        for name, core in (pad if isinstance(pad, dict) else self.batched).items():
            if bound.arguments.get(name) is not None:
                bound.arguments[name] = jax.tree.map(
                    lambda leaf, core=core: _batching.pad_leaf(leaf, batch, core, padded),
                    bound.arguments[name],
                )
        out = self.whole(bound.args, bound.kwargs, (padded,))
        leaves, tree = jax.tree_util.tree_flatten_with_path(out)
        axes = [self.axes.get(_field(path) or "", 0) for path, _ in leaves]
        cut = [_cut(leaf, axis, batch, size) for (_, leaf), axis in zip(leaves, axes, strict=True)]
        return jax.tree.unflatten(tree, cut)

    def direct(self, *args: Any, **kwargs: Any) -> Any:
        """One call of the jitted function (the nested one for tracers)."""
        # (with neither XLA options nor the store, ``jitted`` traces into a caller's program as
        # ``_nested`` would: the leaves need not be looked at)
        if (self.policy.compiler_options or keeps_programs()) and any(
            isinstance(x, jax.core.Tracer) for x in jax.tree.leaves((args, kwargs))
        ):
            return self._nested(*args, **kwargs)
        return self.jitted(*args, **kwargs)

    def __fingerprint__(self) -> tuple:
        """What determines this kernel's programs (``store.fingerprint``)."""
        return (self.fn, self.static, self.batched, self.policy, self.axes)

    def whole(self, args: tuple, kwargs: dict, batch: tuple[int, ...]) -> Any:
        """The kernel on the whole (concrete) batch: in parts on the host threads when the
        policy says so and the batch is large enough."""
        if self._part is None:
            return self.jitted(*args, **kwargs)
        size = math.prod(batch)
        part, starts = _batching.thread_layout(size, self.policy.min_part)
        if (
            len(starts) < 2
            or _batching.in_worker()
            or _batching.on_accelerator()
            or not all(_batching.on_one_device(leaf) for leaf in jax.tree.leaves((args, kwargs)))
        ):
            return self.jitted(*args, **kwargs)
        bound = self._signature.bind(*args, **kwargs)
        bound.apply_defaults()
        dynamic = {k: v for k, v in bound.arguments.items() if k not in self.static}
        if not _batching.splittable([dynamic[name] for name in self.batched], batch):
            return self.jitted(*args, **kwargs)
        static_values = tuple((k, v) for k, v in bound.arguments.items() if k in self.static)

        def run(start: int) -> Any:
            return self._part(dynamic, static_values, batch, start, part)

        parts = _batching.run_parts(run, starts)
        return join(parts, batch, len(starts) * part - size)

    def _part_impl(
        self, dynamic: dict[str, Any], static_values: tuple, batch, start: Any, part: int
    ) -> Any:
        arguments = dict(static_values)
        for name, value in dynamic.items():
            if name in self.batched:
                value = _batching.take_part(value, batch, start, part)
            arguments[name] = value
        return self.fn(**arguments)


def kernel(
    fn: Callable[..., Any] | None = None,
    *,
    static: tuple[str, ...] = (),
    batched: dict[str, int] | None = None,
    policy: Policy = WHOLE,
    axes: dict[str, int] | None = None,
) -> Any:
    """``Kernel`` as a decorator: ``@kernel`` or ``@kernel(static=("branch",), ...)``."""

    def wrap(fn: Callable[..., Any]) -> Kernel:
        return Kernel(fn, static=static, batched=batched, policy=policy, axes=axes)

    return wrap if fn is None else wrap(fn)


@functools.partial(jax.jit, static_argnames=("batch", "overlap"))
def join(parts: list[Any], batch: tuple[int, ...], overlap: int) -> Any:
    """Concatenate parts' outputs along the flat batch axis (dropping the last part's first
    ``overlap`` elements, computed twice); restore the batch shape."""

    def join_leaf(*leaves):
        whole = jnp.concatenate([*leaves[:-1], leaves[-1][overlap:]], axis=0)
        return jnp.reshape(whole, (*batch, *whole.shape[1:]))

    return jax.tree.map(join_leaf, *parts)


def _cut(leaf: Any, axis: int, batch: tuple[int, ...], size: int) -> Any:
    """An output leaf's first ``size`` rows on its batch axis, that axis reshaped to
    ``batch``: on the host (a padded batch holds at most ``_batching.PAD_MAX`` elements), so
    a new batch shape compiles nothing."""
    host = np.asarray(leaf)
    rows = np.take(host, np.arange(size), axis=axis)
    return jax.device_put(rows.reshape((*rows.shape[:axis], *batch, *rows.shape[axis + 1 :])))


def _field(path: tuple) -> str | None:
    """The attribute name of a pytree path's first dataclass field, if any."""
    for key in path:
        if isinstance(key, jax.tree_util.GetAttrKey):
            return key.name
    return None
