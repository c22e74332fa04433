"""Every way jaxkin splits a batch, and every size threshold, in one place.

* **Chunks inside a kernel** (``map_chunks``): an iterative kernel (a Newton ``while_loop``)
  runs on cache-sized slices of the flattened batch with ``lax.map``, so its state stays in
  cache and each chunk stops as soon as its own elements have converged.
* **Host parts on threads** (``PartsJit``, ``run_parts``, ``overlapping_parts``, ``join``): XLA
  on CPU runs the body of a ``while_loop`` on one core, but two programs called from two host
  threads run at the same time. A large concrete batch is split into one part per thread, each
  part slicing its inputs inside the kernel, and the parts are joined.
* **Candidate chunks** (``map_candidates``): the planner's N candidates in equal chunks, each
  sharded over the devices when there are several, else run on the host threads.
* **Host chunks** (``host_chunks``): a host-side loop over fixed-size, padded chunks (files of
  the command line, voxels of a workspace sweep), so one compilation serves every chunk.
* **Work queue inside a kernel** (``work_queue``): an iterative kernel whose elements need very
  different numbers of steps (a chain's IK search) keeps a fixed number of lanes iterating and
  hands each lane the next element as its own ends.
* **Padded small batches** (``PaddedJit``): a small concrete batch is flattened and padded to a
  power of two, so calls whose batch shapes differ (a replanning loop whose
  candidate count changes, a batch ``(3, 5)`` then ``(12,)``) share one compilation per size.

Every split gives the same values as the whole batch: the kernels are elementwise in the batch
(tested). Thread count: ``set_num_threads(n)``, else ``JAXKIN_NUM_THREADS``, else the CPUs this
process may run on; ``1`` turns host parts off. How the thresholds below were measured is in
``docs/performance.md``.
"""

from __future__ import annotations

import dataclasses
import functools
import inspect
import math
import os
import threading
from collections.abc import Callable, Iterable, Iterator
from concurrent.futures import ThreadPoolExecutor
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from jax import Array

from . import _processes
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
# input shape and dtype) gets its own program with the geometry as constants (a compilation of
# 0.1-2 s; the call then costs 0.3-0.75x the generic one-element path's, docs/performance.md).
HOT_AFTER = 8
# Hot single-query programs kept (the earliest built dropped): each holds its robot.
HOT_PROGRAMS = 32


# ------------------------------------------------------------------ hot single queries


class HotQueries:
    """The compiled single queries of the robots asked most often, the earliest built dropped
    beyond ``HOT_PROGRAMS`` (a lookup stays one dictionary read).

    ``get(key, owner, build)`` counts the calls of ``key`` (which starts with ``id(owner)``)
    and returns None until the ``HOT_AFTER``-th, which calls ``build()`` and keeps its result
    (a program, or None for a query that has none) with ``owner``: an entry answers only
    while its owner is that very object (a key whose ``id`` was reused starts counting again).
    """

    def __init__(self, size: int | None = None) -> None:
        self.size = HOT_PROGRAMS if size is None else size
        self.programs: dict[tuple, tuple[Any, Any]] = {}
        self.counts: dict[tuple, int] = {}
        self.none: dict[tuple, Any] = {}  # keys without a program (batches): owner by key
        self.by_value: dict[tuple, Any] = {}  # programs by the robot's values, for its copies

    def get(self, key: tuple, owner: Any, build: Callable[[], Any]) -> Any:
        entry = self.programs.get(key)
        if entry is not None and entry[0] is owner:
            return entry[1]
        if self.none.get(key) is owner:
            return None
        count = self.counts.pop(key, 0) + 1
        if count < HOT_AFTER:
            bounded_put(self.counts, key, count, 4 * self.size)
            return None
        program = build()
        self.counts.pop(key, None)  # the build may have called the query once more
        if program is None:  # kept apart, so that batches never push programs out
            bounded_put(self.none, key, owner, 4 * self.size)
        else:
            bounded_put(self.programs, key, (owner, program), self.size)
        return program

    def clear(self) -> None:
        """Forget every program and count."""
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


def hot_program(fn: Callable[[Array], Any], example: Any) -> Callable[[Array], Any]:
    """``fn`` (one array in, a pytree out) compiled for ``example``'s shape and dtype, its
    output leaves that do not depend on the input (the zero rates of a query at rest) taken
    once from ``fn(example)`` and returned as they are: every output of a compiled call costs
    about 1-2 us. One trace of ``fn`` (which outputs move) and one compilation (of those)."""
    traced = jax.jit(fn).trace(example)
    tree = jax.tree.structure(traced.out_info)
    moving = _input_dependent(traced.jaxpr.jaxpr)
    fixed = [i for i, m in enumerate(moving) if not m]
    moving = [i for i, m in enumerate(moving) if m]

    def pick(indices: list[int]) -> Callable[[Array], list]:
        return lambda x: [jax.tree.leaves(fn(x))[i] for i in indices]

    constants = {}
    if fixed:  # from one call of ``fn`` as it is (its usual program): no compilation of them
        computed = jax.tree.leaves(fn(example))
        constants = {i: computed[i] for i in fixed}
    jitted = jax.jit(pick(moving))
    # Called as the compiled executable: a jitted closure over concrete arrays passes them as
    # arguments on every call (tens of microseconds); the executable holds them as constants.
    compiled = jitted.lower(example).compile()
    try:  # sets up JAX's C++ entry of the executable, called directly below
        compiled(example)
    except (TypeError, ValueError):  # an example it does not take as it is: see call
        pass
    run = getattr(compiled, "_call", None) or compiled
    call = _builder(traced.out_info, moving, constants, run, jitted)
    if call is None:
        position = {i: k for k, i in enumerate(moving)}
        n = tree.num_leaves

        def call(x: Array) -> Any:
            try:
                values = run(x)
            except (TypeError, ValueError):  # an input it does not take as it is
                values = jitted(x)
            leaves = [constants[i] if i in constants else values[position[i]] for i in range(n)]
            return tree.unflatten(leaves)

    call.compiled = compiled  # for inspection (its cost analysis, its HLO)
    return call


def _builder(
    example: Any, moving: list[int], constants: dict[int, Any], run: Callable, fallback: Callable
) -> Callable[[Any], Any] | None:
    """The hot call: ``run(x)`` (the compiled outputs: leaves ``moving`` of ``example``'s
    tree, in order; ``fallback(x)`` for an input ``run`` refuses) and the tree built from them
    with the leaves ``constants`` (by leaf index) in place, for nested frozen dataclasses (the
    results), written out as one straight-line function: the objects made with
    ``object.__new__`` and given their ``__dict__`` whole (their ``__init__`` and JAX's
    unflatten cost several microseconds per call), fields that hold no leaf copied from
    ``example``. None for any other tree."""
    paths = [path for path, _ in jax.tree_util.tree_flatten_with_path(example)[0]]
    if not paths or not all(
        path and all(isinstance(k, jax.tree_util.GetAttrKey) for k in path) for path in paths
    ):
        return None
    source = {i: f"v[{k}]" for k, i in enumerate(moving)}
    namespace: dict[str, Any] = {
        "new": object.__new__,
        "set_attribute": object.__setattr__,
        "run": run,
        "fallback": fallback,
    }
    for i, value in constants.items():
        source[i] = f"k{i}"
        namespace[f"k{i}"] = value
    lines: list[str] = []

    def node(obj: Any, entries: list[tuple[tuple, int]]) -> str | None:
        """Appends the lines that build ``obj``'s node; returns the name that holds it."""
        if not dataclasses.is_dataclass(obj) or not hasattr(obj, "__dict__"):
            return None
        groups: dict[str, list] = {}
        for path, index in entries:
            groups.setdefault(path[0].name, []).append((path[1:], index))
        if any(name not in obj.__dict__ for name in groups):
            return None
        fields = {}
        for name, group in groups.items():
            if len(group) == 1 and not group[0][0]:
                fields[name] = source[group[0][1]]
            elif any(not rest for rest, _ in group):
                return None
            else:
                child = node(obj.__dict__[name], group)
                if child is None:
                    return None
                fields[name] = child
        var = f"o{len(namespace)}"
        namespace[f"{var}_cls"] = type(obj)
        for name, value in obj.__dict__.items():
            if name not in groups:  # a field without leaves, kept as it is
                fields[name] = f"{var}_field_{name}"
                namespace[f"{var}_field_{name}"] = value
        items = ", ".join(f"{name!r}: {fields[name]}" for name in obj.__dict__ if name in fields)
        lines.append(f"{var} = new({var}_cls)")
        lines.append(f"set_attribute({var}, '__dict__', {{{items}}})")
        return var

    root = node(example, [(tuple(path), i) for i, path in enumerate(paths)])
    if root is None:
        return None
    head = [
        "try:",
        "    v = run(x)",
        "except (TypeError, ValueError):  # an input it does not take as it is (another device)",
        "    v = fallback(x)",
    ]
    body = "\n".join(f"    {line}" for line in (*head, *lines, f"return {root}"))
    exec(f"def call(x):\n{body}\n", namespace)  # straight-line code from the field names
    return namespace["call"]


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


def _layout(size: int, threads: int, min_part: int | None = None) -> tuple[int, list[int]]:
    """The parts for ``threads`` threads, each of ``min_part`` (default ``MIN_PART``) elements
    at least; one part when there are too few elements."""
    parts = min(threads, size // (MIN_PART if min_part is None else min_part))
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
        min_part: fewest elements per part (None: ``MIN_PART``; an iterative kernel whose
            every element costs much, such as a chain's IK, splits far smaller batches).

    Call it as the kernel, with the batch shape as the keyword ``batch``.
    """

    def __init__(
        self,
        impl: Callable[..., Any],
        static_argnames: Iterable[str] = (),
        batched_argnames: Iterable[str] = (),
        min_part: int | None = None,
    ) -> None:
        self._impl = impl
        self._min_part = min_part
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
        part, starts = _layout(size, threads, self._min_part)
        if (
            len(starts) < 2
            or getattr(_in_worker, "active", False)
            or on_accelerator()
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


# ------------------------------------------------------------------ candidates and devices


_device_block = threading.local()  # set while a device's block runs: nested calls stay local


def map_candidates(fn: Callable[[Any], Any], tree: Any, chunk_size: int, name: str = "path") -> Any:
    """Apply ``fn`` to a pytree whose leaves share a leading candidate axis N, in chunks.

    ``fn`` is elementwise in the candidates. With one device the chunks have one size, at most
    ``chunk_size`` candidates (the last one overlaps its neighbour rather than being padded:
    ``overlapping_parts``), so one compilation serves them all; they run on the host threads
    concurrently and are joined back to N candidates.

    With several devices (one process or many, ``jax.distributed``) the candidates are split
    into one block per device (``_processes.layout_of``: equal blocks of host data, the last
    rows repeating the last candidate, or a global array's own blocks), each process computes
    its own devices' blocks in chunks of at most ``chunk_size`` as above, with no
    communication, and the outputs are global arrays split along the candidate axis like the
    blocks (replicated when N is not a multiple of the device count: ``_processes.assemble``).
    ``name`` names ``tree`` in the ``ValueError`` for a global array split otherwise, or host
    arrays whose shapes differ between processes.
    """
    leaves = jax.tree.leaves(tree)
    if (
        jax.device_count() == 1
        or getattr(_device_block, "active", False)
        or not all(is_concrete(leaf) for leaf in leaves)
    ):
        return _map_on_one_device(fn, tree, chunk_size)
    layout = _processes.layout_of(tree, name)
    block = layout.block_rows
    chunk, starts = _candidate_chunks(block, chunk_size)
    blocks = [
        jax.tree.map(lambda leaf, i=i: _processes.read_block(leaf, layout, i), tree)
        for i in range(len(layout.blocks))
    ]

    def run(task: tuple[int, int]) -> Any:
        i, start = task
        part = blocks[i]
        if chunk < block:
            part = jax.tree.map(lambda x: x[start : start + chunk], part)
        _device_block.active = True
        try:
            return fn(part)
        finally:
            _device_block.active = False

    outputs = run_parts(run, [(i, start) for i in range(len(blocks)) for start in starts])
    joined = []
    for i in range(len(blocks)):
        mine = outputs[i * len(starts) : (i + 1) * len(starts)]
        joined.append(
            mine[0] if len(mine) == 1 else join(mine, (block,), len(mine) * chunk - block)
        )
    return _processes.assemble(layout, joined)


def _candidate_chunks(size: int, chunk_size: int) -> tuple[int, list[int]]:
    """Chunks of one size, at most ``chunk_size``, covering ``size`` rows (overlapping)."""
    return overlapping_parts(size, math.ceil(size / max(1, min(chunk_size, size))))


def _map_on_one_device(fn: Callable[[Any], Any], tree: Any, chunk_size: int) -> Any:
    """``map_candidates`` on the device the leaves are on (chunks on the host threads)."""
    size = jax.tree.leaves(tree)[0].shape[0]
    if size == 0:
        return fn(tree)
    chunk, starts = _candidate_chunks(size, chunk_size)

    def run(start: int) -> Any:
        part = tree if chunk == size else jax.tree.map(lambda x: x[start : start + chunk], tree)
        return fn(part)

    outputs = run_parts(run, starts)
    return outputs[0] if len(outputs) == 1 else join(outputs, (size,), len(starts) * chunk - size)


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


def padded_size(size: int) -> int:
    """The size a batch of ``size`` elements is computed at: the next power of two, at least
    ``PAD_MIN``, for ``0 < size <= PAD_MAX``; ``size`` itself otherwise."""
    if not 0 < size <= PAD_MAX:
        return size
    return max(PAD_MIN, 1 << (size - 1).bit_length())


class PaddedJit:
    """A jitted kernel whose small concrete batches run padded to one size class.

    Args:
        jitted: the kernel (``jax.jit``, or ``PartsJit`` or another callable with a true
            ``takes_batch`` attribute, called with ``batch=``), elementwise in the batch:
            element ``i`` of every output depends only on element ``i`` of the batched
            arguments.
        core: for each batched argument, the number of trailing axes of its leaves that are
            not batch axes (1 for points ``(..., 3)``, 0 for per-element scalars). Leaves of
            rank 0 with no core axes (a scalar length) are shared by the whole batch.
        axes: the batch axis of output fields where it is not the first (e.g. a history
            ``(steps, ..., n)``: ``{"history": 1}``); the field is the leaf's attribute name.

    Call it as the kernel, with the batch shape as the keyword ``batch``; ``pad=False`` where
    an argument outside ``core`` has batch axes (e.g. a batched geometry), or ``pad`` a dict
    that replaces ``core`` for this call (a target whose core shape depends on the robot).

    A batch of at most ``PAD_MAX`` elements (``()`` included) whose arguments are all concrete,
    on a single-device machine, is broadcast to ``batch``, flattened and padded to
    ``padded_size`` on the host by repeating its last element (a real input, computed and
    dropped), and the outputs are cut back by one small program (``_cut``) compiled per batch
    shape in milliseconds, where the kernel takes a fraction of a second or more. Larger batches,
    tracers (under a user's ``jit``, ``vmap`` or ``grad``) and several devices go to the
    kernel as they are.
    """

    def __init__(
        self,
        jitted: Callable[..., Any],
        core: dict[str, int],
        axes: dict[str, int] | None = None,
    ) -> None:
        self.jitted = jitted
        self._core = dict(core)
        self._axes = dict(axes or {})
        self._takes_batch = isinstance(jitted, PartsJit) or getattr(jitted, "takes_batch", False)
        self._signature = inspect.signature(getattr(jitted, "__wrapped__", jitted))
        functools.update_wrapper(self, jitted)

    def __call__(
        self, *args: Any, batch: tuple[int, ...], pad: bool | dict[str, int] = True, **kwargs: Any
    ) -> Any:
        batch = tuple(int(d) for d in batch)
        size = math.prod(batch)
        padded = padded_size(size)
        if (
            not pad
            or size == 0
            or (padded == size and len(batch) == 1)
            or jax.device_count() > 1
            or not all(is_concrete(leaf) for leaf in jax.tree.leaves((args, kwargs)))
        ):
            return self._direct(args, kwargs, batch)
        bound = self._signature.bind(*args, **kwargs)
        for name, core in (pad if isinstance(pad, dict) else self._core).items():
            if bound.arguments.get(name) is not None:
                bound.arguments[name] = jax.tree.map(
                    lambda leaf, core=core: _pad_leaf(leaf, batch, core, padded),
                    bound.arguments[name],
                )
        out = self._direct(bound.args, bound.kwargs, (padded,))
        leaves, tree = jax.tree_util.tree_flatten_with_path(out)
        axes = tuple(self._axes.get(_field(path), 0) for path, _ in leaves)
        return jax.tree.unflatten(tree, _cut([leaf for _, leaf in leaves], axes, batch, size))

    def _direct(self, args: tuple, kwargs: dict, batch: tuple[int, ...]) -> Any:
        if self._takes_batch:
            return self.jitted(*args, batch=batch, **kwargs)
        return self.jitted(*args, **kwargs)


def shared_geometry(robot: Any) -> bool:
    """True when every array leaf of ``robot`` is a scalar: nothing in it has batch axes."""
    return all(np.ndim(leaf) == 0 for leaf in jax.tree.leaves(robot))


def _pad_leaf(leaf: Any, batch: tuple[int, ...], core: int, padded: int) -> Any:
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


def gather_back(tree: Any, batch: tuple[int, ...]) -> Any:
    """The batch's rows (``spread_positions``) of every leaf of a kernel's output on the
    spread rows, reshaped to ``batch``: one small program per output structure and shape."""
    leaves, structure = jax.tree.flatten(tree)
    rows = jnp.asarray(spread_positions(math.prod(batch), leaves[0].shape[0]), jnp.int32)
    return jax.tree.unflatten(structure, _gather(leaves, rows, batch))


@functools.partial(jax.jit, static_argnames=("batch",))
def _gather(leaves: list, rows: Array, batch: tuple[int, ...]) -> list:
    return [leaf[rows].reshape((*batch, *leaf.shape[1:])) for leaf in leaves]


@functools.partial(jax.jit, static_argnames=("axes", "batch", "size"))
def _cut(leaves: list, axes: tuple[int, ...], batch: tuple[int, ...], size: int) -> list:
    """Each output leaf's first ``size`` rows on its batch axis, that axis reshaped to
    ``batch``: one small program per output structure and batch shape, compiled in
    milliseconds (a transfer through the host would cost about 20 us per leaf and call)."""

    def cut(leaf, axis):
        rows = jax.lax.slice_in_dim(leaf, 0, size, axis=axis)
        return rows.reshape((*rows.shape[:axis], *batch, *rows.shape[axis + 1 :]))

    return [cut(leaf, axis) for leaf, axis in zip(leaves, axes, strict=True)]


def _field(path: tuple) -> str | None:
    """The attribute name of a pytree path's first dataclass field, if any."""
    for key in path:
        if isinstance(key, jax.tree_util.GetAttrKey):
            return key.name
    return None


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
