"""Large batches split across host threads, so loop-bound kernels use every CPU core.

XLA on CPU spreads a fused loop over the cores only at the top level of a program: the body of
a ``while_loop`` (a Newton iteration, ``lax.map`` over cache-sized chunks) runs on one core.
Two programs called from two host threads do run at the same time. Measured on the Delta
Newton FK (2-core CPU, float64, batch 1e6): the two halves called from two threads and joined
took 0.6-0.75x the time of one call on the whole batch; the same two halves dispatched from
one thread, or as two independent loops inside one program, took as long as the whole batch.
(The dyad, a loop-free kernel whose fused loops XLA already spreads over the cores, gained
nothing once its outputs were joined.)

``PartsJit`` is ``jax.jit`` for such a kernel. A call with concrete inputs whose batch has at
least ``MIN_PART`` elements per part runs the kernel on ``num_threads()`` contiguous parts of
the flattened batch, each from its own thread, and concatenates the parts' outputs. The parts
have one size (the last one overlaps its neighbour when the batch does not divide evenly), so
they share one compilation; each part slices its inputs inside the kernel (``dynamic_slice``,
which XLA fuses into the kernel: slicing first, as separate calls, measured 1.3x slower).
Every other call (tracer inputs inside a user's ``jit``, small batches, one thread, a non-CPU
backend, arrays sharded over several devices, inputs that only broadcast to the batch, a call
from inside a part) runs the kernel once on the whole batch.
The kernels are elementwise in the batch, so both ways give the same values (tested).

``overlapping_parts``, ``run_parts`` and ``join`` serve callers that loop over chunks on the
host themselves (``jaxkin.plan.map_candidates``).

Thread count: ``set_num_threads(n)``, else the environment variable ``JAXKIN_NUM_THREADS``,
else the CPUs this process may run on; ``1`` turns the splitting off.
"""

from __future__ import annotations

import functools
import inspect
import math
import os
import threading
from collections.abc import Callable, Iterable
from concurrent.futures import ThreadPoolExecutor
from typing import Any

import jax
import jax.numpy as jnp
from jax import Array

from ._validate import is_concrete

# Fewest elements per part: below this the per-part dispatch and the join cost about what the
# second core saves (Delta FK, 2-core CPU, float64: split into two parts 1.07x faster at
# 2^16 elements, 1.15-1.2x at 1.3e5-2.6e5, 1.3-1.55x at 1e6).
MIN_PART = 1 << 15

_requested: int | None = None
_pool: ThreadPoolExecutor | None = None
_pool_workers = 0
_pool_pid = 0  # a forked child inherits the pool object but not its threads
_pool_lock = threading.Lock()
_in_worker = threading.local()


def num_threads() -> int:
    """Host threads a large batch is split across (>= 1)."""
    if _requested is not None:
        return _requested
    env = os.environ.get("JAXKIN_NUM_THREADS", "").strip()
    if env:
        try:
            value = int(env)
        except ValueError:
            value = 0
        if value < 1:
            raise ValueError(f"JAXKIN_NUM_THREADS must be a positive integer, got {env!r}")
        return value
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # not on Linux
        return max(1, os.cpu_count() or 1)


def set_num_threads(n: int | None) -> None:
    """Split large batches across ``n`` host threads (1: never split; None: the default)."""
    global _requested
    if n is not None and (isinstance(n, bool) or not isinstance(n, int) or n < 1):
        raise ValueError(f"n must be a positive int or None, got {n!r}")
    _requested = n


def _executor(workers: int) -> ThreadPoolExecutor:
    """The shared worker pool, grown to ``workers`` threads when needed."""
    global _pool, _pool_workers, _pool_pid
    with _pool_lock:
        if _pool is None or _pool_workers < workers or _pool_pid != os.getpid():
            if _pool is not None and _pool_pid == os.getpid():
                _pool.shutdown(wait=False)  # its running parts finish; new ones go to the new pool
            _pool = ThreadPoolExecutor(workers, thread_name_prefix="jaxkin")
            _pool_workers, _pool_pid = workers, os.getpid()
        return _pool


def overlapping_parts(size: int, n_parts: int, multiple: int = 1) -> tuple[int, list[int]]:
    """``(part size, starts)``: parts of one size covering ``range(size)``, in order.

    The size is ``ceil(size / n_parts)`` rounded up to a multiple of ``multiple`` (at most
    ``size``); the last part starts at ``size - part``, so it overlaps its neighbour by
    ``len(starts) * part - size`` elements, which ``join`` drops. One size means one
    compilation for every part, and nothing is padded or gathered.
    """
    part = -(-size // max(1, n_parts))
    part = min(size, -(-part // multiple) * multiple)
    count = -(-size // part)
    return part, [k * part for k in range(count - 1)] + [size - part]


def _layout(size: int, threads: int) -> tuple[int, list[int]]:
    """The parts for ``threads`` threads; one part when there are too few elements."""
    parts = min(threads, size // MIN_PART)
    if parts < 2:
        return size, [0]
    return overlapping_parts(size, parts)


def run_parts(run: Callable[[int], Any], starts: list[int]) -> list[Any]:
    """``[run(start) for start in starts]``, on the worker threads when there are several.

    ``run`` should return computed (not merely dispatched) arrays: a part's work happens on the
    thread that waits for it. Called from inside a part, the parts run in turn.
    """
    threads = num_threads()
    if threads < 2 or len(starts) < 2 or getattr(_in_worker, "active", False):
        return [run(start) for start in starts]

    def in_worker(start: int) -> Any:
        _in_worker.active = True
        try:
            return jax.block_until_ready(run(start))
        finally:
            _in_worker.active = False

    return list(_executor(threads).map(in_worker, starts))


def _on_one_device(leaf: Any) -> bool:
    """A concrete value on (at most) one device: tracers and sharded arrays are not split."""
    if not is_concrete(leaf):
        return False
    return not isinstance(leaf, jax.Array) or len(leaf.sharding.device_set) == 1


def _splittable(tree: Any, batch: tuple[int, ...]) -> bool:
    """True when every leaf is a scalar (shared) or has the whole batch as leading axes."""
    return all(
        jnp.ndim(leaf) == 0 or tuple(jnp.shape(leaf)[: len(batch)]) == batch
        for leaf in jax.tree.leaves(tree)
    )


def _take(tree: Any, batch: tuple[int, ...], start: Array, part: int) -> Any:
    """Elements ``[start, start + part)`` of the flattened batch of the batched leaves."""
    size = math.prod(batch)

    def take(leaf):
        if jnp.ndim(leaf) == 0:
            return leaf
        rest = jnp.shape(leaf)[len(batch) :]
        flat = jnp.reshape(leaf, (size, *rest))
        return jax.lax.dynamic_slice_in_dim(flat, start, part, axis=0)

    return jax.tree.map(take, tree)


@functools.partial(jax.jit, static_argnames=("batch", "overlap"))
def join(parts: list[Any], batch: tuple[int, ...], overlap: int) -> Any:
    """Concatenate the parts' outputs along the flat batch axis (dropping the last part's
    first ``overlap`` elements, computed twice); restore the batch shape."""

    def join_leaf(*leaves):
        whole = jnp.concatenate([*leaves[:-1], leaves[-1][overlap:]], axis=0)
        return jnp.reshape(whole, (*batch, *whole.shape[1:]))

    return jax.tree.map(join_leaf, *parts)


class PartsJit:
    """``jax.jit(impl, static_argnames)`` that splits large batches across host threads.

    Args:
        impl: the kernel, elementwise in the batch: element ``i`` of every output depends only
            on element ``i`` of the batched arguments; every output leaf has the batch as its
            leading axes.
        static_argnames: as for ``jax.jit``.
        batched_argnames: arguments whose array leaves carry the batch as leading axes (leaves
            of rank 0 are shared by the whole batch); the others are passed to every part.

    Call it as the kernel, with the batch shape as the keyword ``batch``.
    """

    def __init__(
        self,
        impl: Callable[..., Any],
        static_argnames: Iterable[str] = (),
        batched_argnames: Iterable[str] = (),
    ) -> None:
        self._impl = impl
        self._signature = inspect.signature(impl)
        self._static = tuple(static_argnames)
        self._batched = tuple(batched_argnames)
        self.whole = jax.jit(impl, static_argnames=self._static)
        self._part = jax.jit(self._part_impl, static_argnames=("static", "batch", "part"))
        functools.update_wrapper(self, impl)

    def _part_impl(self, dynamic: dict[str, Any], static: tuple, batch, start: Array, part: int):
        arguments = dict(static)
        for name, value in dynamic.items():
            if name in self._batched:
                value = _take(value, batch, start, part)
            arguments[name] = value
        return self._impl(**arguments)

    def __call__(self, *args: Any, batch: tuple[int, ...], **kwargs: Any) -> Any:
        batch = tuple(int(d) for d in batch)
        threads = num_threads()
        size = math.prod(batch)
        part, starts = _layout(size, threads)
        if (
            len(starts) < 2
            or getattr(_in_worker, "active", False)
            or jax.default_backend() != "cpu"
            or not all(_on_one_device(leaf) for leaf in jax.tree.leaves((args, kwargs)))
        ):
            return self.whole(*args, **kwargs)
        bound = self._signature.bind(*args, **kwargs)
        bound.apply_defaults()
        dynamic = {k: v for k, v in bound.arguments.items() if k not in self._static}
        if not _splittable([dynamic[name] for name in self._batched], batch):
            return self.whole(*args, **kwargs)
        static = tuple((k, v) for k, v in bound.arguments.items() if k in self._static)

        def run(start: int) -> Any:
            return self._part(dynamic, static, batch, start, part)

        return join(run_parts(run, starts), batch, len(starts) * part - size)

    def _cache_size(self) -> int:
        """Compilations held (whole-batch and per-part), for recompilation tests."""
        return self.whole._cache_size() + self._part._cache_size()
