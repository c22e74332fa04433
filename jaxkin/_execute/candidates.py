"""The planner's N candidates in chunks: on the host threads, or over the devices.

``map_candidates(fn, tree, chunk_size)`` applies an elementwise ``fn`` to the candidates in
chunks of one size (one compilation for all of them), runs them on the host threads
(``_batching.run_parts``) and joins them back, or, with several devices (one process or many,
``jax.distributed``), computes each device's block of candidates in this process and returns
global arrays split along the candidate axis (``_processes``).
"""

from __future__ import annotations

import math
import threading
from collections.abc import Callable
from typing import Any

import jax

from .. import _processes
from .._batching import overlapping_parts, run_parts
from .._validate import is_concrete
from .kernel import join

__all__ = ["map_candidates"]

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
