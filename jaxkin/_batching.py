"""Every way jaxkin splits a batch, and every size threshold, in one place (the execution
layer, ``jaxkin._execute``, applies them).

* **Chunks inside a kernel** (``map_chunks``): an iterative kernel (a Newton ``while_loop``)
  runs on cache-sized slices of the flattened batch with ``lax.map``, so its state stays in
  cache and each chunk stops as soon as its own elements have converged.
* **Host parts on threads** (``run_parts``, ``thread_layout``, ``overlapping_parts``): XLA
  on CPU runs the body of a ``while_loop`` on one core, but two programs called from two host
  threads run at the same time. A large concrete batch is split into one part per thread, each
  part slicing its inputs inside the kernel, and the parts are joined.
* **Candidate chunks** (``_execute.map_candidates``): the planner's N candidates in equal
  chunks, each sharded over the devices when there are several, else run on the host threads.
* **Host chunks** (``host_chunks``): a host-side loop over fixed-size, padded chunks (files of
  the command line, voxels of a workspace sweep), so one compilation serves every chunk.
* **Work queue inside a kernel** (``work_queue``): an iterative kernel whose elements need very
  different numbers of steps (a chain's IK search) keeps a fixed number of lanes iterating and
  hands each lane the next element as its own ends.
* **Padded small batches** (``padded_size``, ``pad_leaf``): a small concrete batch is
  flattened and padded to a power of two, so calls whose batch shapes differ (a replanning
  loop whose candidate count changes, a batch ``(3, 5)`` then ``(12,)``) share one
  compilation per size.

Every split gives the same values as the whole batch: the kernels are elementwise in the batch
(tested). Thread count: ``set_num_threads(n)``, else ``JAXKIN_NUM_THREADS``, else the CPUs this
process may run on; ``1`` turns host parts off. How the thresholds below were measured is in
``docs/performance.md``.
"""

from __future__ import annotations

import dataclasses
import math
import os
import threading
from collections.abc import Callable, Iterator
from concurrent.futures import ThreadPoolExecutor
from typing import Any, TypeVar

import jax
import jax.numpy as jnp
import numpy as np
from jax import Array

from ._validate import is_concrete

# ------------------------------------------------------------------------------- thresholds
# Tuned on a 2-core x86-64 CPU, float64, JAX 0.10 (docs/performance.md has the measurements).

# Elements per chunk of map_chunks: ~20 loop arrays of 8192 float64 stay in L2 (Delta Newton
# FK at 1e6: 2048-32768 within 15 %; the whole batch is bandwidth-bound).
CHUNK = 8192
# Fewest elements per host-thread part (Delta Newton FK: below it dispatch and join cost what
# the second core saves).
MIN_PART = 1 << 15
# Planner samples (candidates x T) per call (N = 1e4, T = 100: larger calls map their
# temporaries afresh every call, smaller ones gain nothing).
PLAN_CHUNK_SAMPLES = 1 << 17
# The same on an accelerator (one call's temporaries: about 1 GB in float64).
ACCELERATOR_CHUNK_SAMPLES = 1 << 21
# FK at rest writes its zero rates outside the kernel from this many elements (the extra eager
# call costs more than the kernel's writes below it; ``zero_rates_outside``).
SHARED_ZEROS_MIN = 1 << 16
# Rows per call of the command line (files) and voxels per call of a workspace sweep: memory
# bounds (a few tens of MB of intermediates per call in float64).
HOST_CHUNK = 1 << 16
SWEEP_CHUNK = 1 << 18
# Small batches are padded to a power of two, at least PAD_MIN, up to PAD_MAX elements: there
# the padding costs about 0.1 ms per call, a compilation a fraction of a second or more.
PAD_MIN = 64
PAD_MAX = 1 << 12
# The planner pads its candidates while the padded call holds at most this many samples
# (candidates x T x branches held): a few milliseconds of work.
PLAN_PAD_SAMPLES = 1 << 15

# A robot object asked one element at a time this many times (same kind, branch, options,
# input shape and dtype) gets its own compiled handle with the geometry as constants (a
# compilation of 0.1-2 s; the call then costs 0.3-0.75x the generic one-element path's,
# docs/performance.md).
HOT_AFTER = 8
# Hot single-query handles kept (the earliest built dropped): each holds its robot.
HOT_PROGRAMS = 32


# ------------------------------------------------------------------ chunks in a kernel


def zero_rates_outside(rates: bool, batch: tuple[int, ...]) -> bool:
    """True for a large batch at rest: the FK kernel returns positions only and the caller
    adds the zero rates (``Jet.constant``), since writing them costs more in the
    memory-bound kernel than in one eager call (from ``SHARED_ZEROS_MIN`` elements)."""
    return not rates and math.prod(batch) >= SHARED_ZEROS_MIN


def _chunk_layout(size: int, limit: int | None = None) -> tuple[int, int]:
    """``(n_chunks, chunk)`` for a flat batch of ``size > limit`` elements (``limit``: CHUNK
    by default).

    Prefers a chunk that divides ``size`` (between limit/2 and limit, e.g. 8000 for 10^6):
    then neither the input nor the output is copied to add or drop padding, and the stacked
    loop output is the result itself.
    """
    limit = CHUNK if limit is None else limit
    for chunk in range(limit, limit // 2, -1):
        if size % chunk == 0:
            return size // chunk, chunk
    n_chunks = math.ceil(size / limit)
    return n_chunks, math.ceil(size / n_chunks)


def map_chunks(
    fn: Callable[[Any], Any], tree: Any, batch: tuple[int, ...], limit: int | None = None
) -> Any:
    """``fn(tree)`` computed chunk by chunk over the flattened batch.

    Args:
        fn: elementwise in the batch (element ``i`` of the output depends only on element
            ``i`` of the input); takes and returns pytrees of arrays of shape ``(chunk, ...)``.
        tree: pytree whose leaves have shape ``(*batch, ...)``.
        batch: the batch shape (static).
        limit: the largest chunk (static; ``CHUNK`` by default).

    Returns:
        ``fn``'s output with leaves reshaped to ``(*batch, ...)``. Batches of at most ``CHUNK``
        elements are passed to ``fn`` whole. Otherwise the batch is split into equal chunks of
        at most ``CHUNK`` elements (``_chunk_layout``: a divisor of the batch size when there is one
        above ``CHUNK / 2``; else the last chunk is padded by repeating the final element, the
        padding computed and dropped), so the loop body compiles once.
    """
    size = math.prod(batch)
    if size <= (CHUNK if limit is None else limit):
        return fn(tree)
    n_chunks, chunk = _chunk_layout(size, limit)
    padded = n_chunks * chunk

    def split(x):
        flat = x.reshape((size, *x.shape[len(batch) :]))
        if padded > size:
            tail = jnp.broadcast_to(flat[-1:], (padded - size, *flat.shape[1:]))
            flat = jnp.concatenate([flat, tail])
        return flat.reshape((n_chunks, chunk, *flat.shape[1:]))

    def join(y):
        flat = y.reshape((padded, *y.shape[2:]))[:size]
        return flat.reshape((*batch, *flat.shape[1:]))

    out = jax.lax.map(fn, jax.tree.map(split, tree))
    return jax.tree.map(join, out)


# ------------------------------------------------------------------ host threads

_requested: int | None = None
_pool: ThreadPoolExecutor | None = None
_pool_workers = 0
_pool_pid = 0  # a forked child inherits the pool object but not its threads
_pool_lock = threading.Lock()
_in_worker = threading.local()


def on_accelerator() -> bool:
    """True when JAX's default backend is not the CPU (a GPU or TPU): the host-thread split
    and the CPU's chunk sizes are then off (``docs/scaling.md``)."""
    return jax.default_backend() != "cpu"


def plan_chunk_samples() -> int:
    """Samples per planner call: ``PLAN_CHUNK_SAMPLES`` on the CPU, ``ACCELERATOR_CHUNK_SAMPLES``
    on an accelerator (its memory and parallelism favour larger calls)."""
    return ACCELERATOR_CHUNK_SAMPLES if on_accelerator() else PLAN_CHUNK_SAMPLES


def num_threads() -> int:
    """Host threads a large batch is split across (>= 1): 1 on an accelerator, whose own
    parallelism serves the whole batch, unless set explicitly."""
    if _requested is not None:
        return _requested
    if on_accelerator():
        return 1
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
    if n is not None and (isinstance(n, bool) or not isinstance(n, int | np.integer) or n < 1):
        raise ValueError(f"n must be a positive int or None, got {n!r}")
    _requested = None if n is None else int(n)


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


def thread_layout(size: int, min_part: int | None = None) -> tuple[int, list[int]]:
    """``(part size, starts)`` of a batch of ``size`` elements on the host threads
    (``num_threads``), each part of ``min_part`` (default ``MIN_PART``) elements at least; one
    part when there are too few elements."""
    parts = min(num_threads(), size // (MIN_PART if min_part is None else min_part))
    if parts < 2:
        return size, [0]
    return overlapping_parts(size, parts)


def in_worker() -> bool:
    """True on a worker thread of ``run_parts`` (nested calls run their parts in turn)."""
    return getattr(_in_worker, "active", False)


_Start = TypeVar("_Start")


def run_parts(run: Callable[[_Start], Any], starts: list[_Start]) -> list[Any]:
    """``[run(start) for start in starts]``, on the worker threads when there are several.

    ``run`` should return computed (not merely dispatched) arrays: a part's work happens on the
    thread that waits for it. Called from inside a part, the parts run in turn.
    """
    threads = num_threads()
    if threads < 2 or len(starts) < 2 or getattr(_in_worker, "active", False):
        return [run(start) for start in starts]

    def in_worker(start: _Start) -> Any:
        _in_worker.active = True
        try:
            return jax.block_until_ready(run(start))
        finally:
            _in_worker.active = False

    return list(_executor(threads).map(in_worker, starts))


def on_one_device(leaf: Any) -> bool:
    """A concrete value on (at most) one device: tracers and sharded arrays are not split."""
    if not is_concrete(leaf):
        return False
    return not isinstance(leaf, jax.Array) or len(leaf.sharding.device_set) == 1


def splittable(tree: Any, batch: tuple[int, ...]) -> bool:
    """True when every leaf is a scalar (shared) or has the whole batch as leading axes."""
    return all(
        jnp.ndim(leaf) == 0 or tuple(jnp.shape(leaf)[: len(batch)]) == batch
        for leaf in jax.tree.leaves(tree)
    )


def take_part(tree: Any, batch: tuple[int, ...], start: Array, part: int) -> Any:
    """Elements ``[start, start + part)`` of the flattened batch of the batched leaves."""
    size = math.prod(batch)

    def take(leaf):
        if jnp.ndim(leaf) == 0:
            return leaf
        rest = jnp.shape(leaf)[len(batch) :]
        flat = jnp.reshape(leaf, (size, *rest))
        return jax.lax.dynamic_slice_in_dim(flat, start, part, axis=0)

    return jax.tree.map(take, tree)


# ------------------------------------------------------------------ host chunks


def host_chunks(n: int, chunk: int) -> Iterator[tuple[int, int, np.ndarray]]:
    """``(start, stop, index)`` over ``range(n)`` in chunks of one size.

    ``index`` always has the same length (``chunk``, or the next power of two at or above
    ``n`` when that is smaller, so inputs of similar sizes share one compilation); past
    ``stop`` it repeats ``start`` (a real element, computed and dropped by the caller).
    """
    chunk = max(1, min(chunk, 1 << max(n - 1, 0).bit_length()))
    for start in range(0, n, chunk):
        stop = min(start + chunk, n)
        index = np.arange(start, start + chunk)
        index[stop - start :] = start
        yield start, stop, index


# ------------------------------------------------------------------ padded small batches


def padded_size(size: int, smallest: int | None = None) -> int:
    """The size a batch of ``size`` elements is computed at: the next power of two, at least
    ``smallest`` (None: ``PAD_MIN``), for ``0 < size <= PAD_MAX``; ``size`` itself otherwise."""
    if not 0 < size <= PAD_MAX:
        return size
    return max(PAD_MIN if smallest is None else smallest, 1 << (size - 1).bit_length())


def shared_geometry(robot: Any) -> bool:
    """True when every array leaf of ``robot`` is a scalar: nothing in it has batch axes."""
    return all(np.ndim(leaf) == 0 for leaf in jax.tree.leaves(robot))


def pad_leaf(leaf: Any, batch: tuple[int, ...], core: int, padded: int) -> Any:
    """``leaf`` (``(*b, *core)`` with ``b`` broadcasting to ``batch``) as a host array
    ``(padded, *core)``, the last element repeated, for the kernel to take in; a scalar
    without core axes unchanged (shared). On the host: no program per input shape."""
    if core == 0 and np.ndim(leaf) == 0:
        return leaf
    host = np.asarray(leaf)
    shape = host.shape[host.ndim - core :] if core else ()
    flat = np.broadcast_to(host, (*batch, *shape)).reshape((-1, *shape))
    return np.concatenate([flat, np.broadcast_to(flat[-1:], (padded - len(flat), *shape))])


def bucket_size(size: int, smallest: int) -> int:
    """The size a batch of an iterative kernel is computed at when its padding rows cost
    almost nothing (they are marked done from the start): ``size`` for a single element (the
    one-query shape), else the next power of two, at least ``smallest``. No upper bound: each
    size class is one compilation, and a class at most doubles the rows."""
    if size <= 1:
        return size
    return max(smallest, 1 << (size - 1).bit_length())


def spread_positions(size: int, padded: int) -> np.ndarray:
    """Where the ``size`` rows of a batch sit among ``padded`` rows: spread evenly, so that
    every host-thread part of the padded batch holds its share of real rows."""
    return (np.arange(size) * padded) // max(size, 1)


def spread_rows(leaf: Any, batch: tuple[int, ...], core: int, padded: int, fill: float) -> Any:
    """``leaf`` ``(*batch, *core)`` as a host array ``(padded, *core)``: the batch's rows at
    ``spread_positions``, ``fill`` elsewhere (e.g. NaN: rows an iterative kernel marks
    invalid at once)."""
    host = np.asarray(leaf)
    shape = host.shape[host.ndim - core :] if core else ()
    flat = np.broadcast_to(host, (*batch, *shape)).reshape((-1, *shape))
    out = np.full((padded, *shape), fill, flat.dtype)
    out[spread_positions(len(flat), padded)] = flat
    return out


# ------------------------------------------------------------------ work queue in a kernel


@jax.tree_util.register_dataclass
@dataclasses.dataclass(frozen=True)
class QueueState:
    """The ``lax.while_loop`` state of ``work_queue``.

    Attributes:
        slot: ``(lanes,)`` int32, the element each lane holds (``>= size``: the lane is idle).
        lanes: the per-lane state, a pytree whose leaves lead with the lane axis.
        out: the per-element outputs, a pytree whose leaves lead with the element axis.
        following: the next element to hand out (int32 scalar).
        steps: steps taken (int32 scalar).
    """

    slot: Array
    lanes: Any
    out: Any
    following: Array
    steps: Array


def work_queue(
    step: Callable[[Array, Any], tuple[Any, Array, Any]],
    fresh: Callable[[Array], Any],
    out: Any,
    size: int,
    lanes: int,
    max_steps: int,
) -> Any:
    """Run ``size`` elements of an iterative kernel on ``lanes`` lanes, refilled as they end.

    A batch iterated in step costs its hardest element's work times its size; a queue costs
    about its elements' total work. ``fresh(slot)`` is the lane state of elements ``slot``
    ``(lanes,)`` (past the end: an idle lane); ``step(slot, state)`` advances every lane once
    and returns ``(state, finished, result)``: ``finished`` ``(lanes,)`` marks lanes whose
    element has ended, ``result`` their outputs (leaves ``(lanes, ...)``), written to ``out``
    (leaves ``(size, ...)``) at the element's index. Finished lanes take the next elements in
    order. Stops when every element has ended or after ``max_steps`` steps; returns ``out``.
    """

    def body(state: QueueState) -> QueueState:
        kept, finished, result = step(state.slot, state.lanes)
        where = jnp.where(finished, state.slot, size)  # out of range: dropped
        written = jax.tree.map(lambda o, r: o.at[where].set(r, mode="drop"), state.out, result)
        rank = jnp.cumsum(finished, dtype=jnp.int32) - 1
        slot = jnp.where(finished, state.following + rank, state.slot)
        following = state.following + jnp.sum(finished, dtype=jnp.int32)
        refill = jax.tree.map(
            lambda a, b: jnp.where(finished.reshape(finished.shape + (1,) * (a.ndim - 1)), b, a),
            kept,
            fresh(slot),
        )
        return QueueState(slot, refill, written, following, state.steps + 1)

    def cond(state: QueueState) -> Array:
        return jnp.any(state.slot < size) & (state.steps < max_steps)

    slot = jnp.arange(lanes, dtype=jnp.int32)
    init = QueueState(slot, fresh(slot), out, jnp.int32(lanes), jnp.int32(0))
    return jax.lax.while_loop(cond, body, init).out
