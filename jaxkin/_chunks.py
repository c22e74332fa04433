"""Cache-sized chunks inside a jitted kernel (``lax.map`` over slices of a flat batch).

An iterative kernel (a Newton ``while_loop``) over a whole batch of 1e6 elements streams every
state array through memory once per iteration; on a 2-core CPU that, not arithmetic, sets its
speed. Running the same loop on chunks of a few thousand elements keeps the state in cache and
lets each chunk stop as soon as its own elements have converged. Measured on the Delta Newton
FK (2-core CPU, float64, 1e6 cases): 1.6-1.8x faster than one loop over the whole batch. Not
worth it for loop-free kernels: the dyad measured 2.5x slower in chunks of 8k-256k elements.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import jax
import jax.numpy as jnp

# Elements per chunk: the loop's arrays (~20) of 8192 float64 elements are ~1.3 MB, which
# stay in L2. 2048-32768 measured within 15 % of each other; much smaller chunks pay the
# per-iteration overhead of the loop, the whole batch pays memory bandwidth.
CHUNK = 8192


def _layout(size: int) -> tuple[int, int]:
    """``(n_chunks, chunk)`` for a flat batch of ``size > CHUNK`` elements.

    Prefers a chunk that divides ``size`` (between CHUNK/2 and CHUNK, e.g. 8000 for 1e6): then
    neither the input nor the output is copied to add or drop padding, and the stacked loop
    output is the result itself.
    """
    for chunk in range(CHUNK, CHUNK // 2, -1):
        if size % chunk == 0:
            return size // chunk, chunk
    n_chunks = math.ceil(size / CHUNK)
    return n_chunks, math.ceil(size / n_chunks)


def map_chunks(fn: Callable[[Any], Any], tree: Any, batch: tuple[int, ...]) -> Any:
    """``fn(tree)`` computed chunk by chunk over the flattened batch.

    Args:
        fn: elementwise in the batch (element ``i`` of the output depends only on element
            ``i`` of the input); takes and returns pytrees of arrays of shape ``(chunk, ...)``.
        tree: pytree whose leaves have shape ``(*batch, ...)``.
        batch: the batch shape (static).

    Returns:
        ``fn``'s output with leaves reshaped to ``(*batch, ...)``. Batches of at most ``CHUNK``
        elements are passed to ``fn`` whole. Otherwise the batch is split into equal chunks of
        at most ``CHUNK`` elements (``_layout``: a divisor of the batch size when there is one
        above ``CHUNK / 2``; else the last chunk is padded by repeating the final element, the
        padding computed and dropped), so the loop body compiles once.
    """
    size = math.prod(batch)
    if size <= CHUNK:
        return fn(tree)
    n_chunks, chunk = _layout(size)
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


def in_two_halves(fn: Callable[..., Any], args: tuple[Any, ...], batch: tuple[int, ...]) -> Any:
    """``fn(*args)`` computed on the two halves of the flattened batch, then joined.

    ``args``' leaves have shape ``(*batch, ...)`` or are scalars (passed to both halves);
    ``fn`` is elementwise in the batch. Two top-level computations, not a loop (``map_chunks``
    is for iterative kernels): used where XLA measured faster on two independent halves than
    on the whole batch (the dyad's autodiff path, see ``jaxkin.dyad``). Odd sizes give halves
    of unequal length.
    """
    size = math.prod(batch)
    half = size // 2

    def part(x, lo, hi):
        if jnp.ndim(x) == 0:
            return x
        return x.reshape((size, *x.shape[len(batch) :]))[lo:hi]

    first = fn(*jax.tree.map(lambda x: part(x, 0, half), args))
    second = fn(*jax.tree.map(lambda x: part(x, half, size), args))

    def join(x, y):
        joined = jnp.concatenate([x, y], axis=0)
        return joined.reshape((*batch, *joined.shape[1:]))

    return jax.tree.map(join, first, second)
