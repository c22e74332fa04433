"""JAX's multi-controller runtime as jaxkin uses it: devices, row layouts, global arrays.

After ``jax.distributed.initialize`` every process runs the same program and
``jax.devices()`` lists every process's devices; a global ``jax.Array`` spans them, each
process holding the shards on its own devices (``jax.local_devices()``). jaxkin splits a
batch along its leading axis into equal blocks of rows, one per device (a ``Layout``), has
each process compute the blocks of its own devices with the single-device kernels (no
communication), and assembles the outputs into global arrays sharded like the blocks.

Inputs are either host data identical on every process (NumPy, or arrays on one device),
from which each process reads only its devices' rows, or global arrays split along the
leading axis, whose own layout is kept. Small host values (counts, top-k lists) are gathered
from every process by ``allgather`` and ``allgather_rows``, one collective each; every process
must make the same calls in the same order. With one process and one device nothing here is
used (``_batching`` keeps its single-device paths).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from typing import Any

import jax
import numpy as np
from jax.sharding import Mesh, NamedSharding, PartitionSpec

__all__ = [
    "Layout",
    "allgather",
    "allgather_rows",
    "assemble",
    "fetchable",
    "global_from_parts",
    "is_split",
    "layout_of",
    "local_rows",
    "ordered_devices",
    "process_count",
    "process_range",
    "read_block",
    "to_host",
]

AXIS = "batch"  # the mesh axis of the layouts built here


def process_count() -> int:
    """The processes of JAX's runtime (1 unless ``jax.distributed`` joined several)."""
    return jax.process_count()


def process_range(n: int) -> tuple[int, int]:
    """``(start, stop)``: this process's contiguous part of ``range(n)``.

    Parts of ``ceil(n / processes)`` elements in process order (the last ones shorter or
    empty); ``(0, n)`` with one process.
    """
    count = process_count()
    part = -(-n // count)
    start = min(n, jax.process_index() * part)
    return start, min(n, start + part)


def ordered_devices() -> list[Any]:
    """Every process's devices, process by process: the order of a standard layout."""
    return sorted(jax.devices(), key=lambda d: (d.process_index, d.id))


# ------------------------------------------------------------------ layouts of rows


@dataclasses.dataclass(frozen=True)
class Layout:
    """Rows of a batch over devices.

    Attributes:
        rows: the batch's own number of rows ``N``.
        size: rows of the global arrays (``N``, or ``N`` rounded up to a multiple of the device
            count when the rows were split from host data; rows past ``N`` repeat row
            ``N - 1``).
        sharding: of the global outputs: split along axis 0 only (any rank).
        blocks: the ``(start, stop)`` row blocks this process computes, one per block of its
            devices (a block held by several of its devices is computed once).
        devices: for each block, this process's devices holding it (the first computes it).
    """

    rows: int
    size: int
    sharding: NamedSharding
    blocks: tuple[tuple[int, int], ...]
    devices: tuple[tuple[Any, ...], ...]

    @property
    def block_rows(self) -> int:
        return self.blocks[0][1] - self.blocks[0][0] if self.blocks else 0


def is_split(x: Any) -> bool:
    """A global array split over several devices (not one device's, nor fully replicated)."""
    return (
        isinstance(x, jax.Array)
        and len(x.sharding.device_set) > 1
        and not x.sharding.is_fully_replicated
    )


def fetchable(x: Any) -> bool:
    """True when ``np.asarray(x)`` works on this process (not an array split over processes)."""
    return not isinstance(x, jax.Array) or x.is_fully_addressable or x.sharding.is_fully_replicated


def _from_rows(rows: int, size: int, sharding: NamedSharding) -> Layout:
    """The layout of ``sharding`` over ``size`` rows, this process's blocks grouped."""
    shape = (size,)
    by_block: dict[tuple[int, int], list[Any]] = {}
    for device, index in sharding.addressable_devices_indices_map(shape).items():
        start, stop, _ = index[0].indices(size)  # type: ignore[index]  # rows: never None
        by_block.setdefault((start, stop), []).append(device)
    blocks = tuple(sorted(by_block))
    return Layout(rows, size, sharding, blocks, tuple(tuple(by_block[b]) for b in blocks))


def standard_layout(rows: int) -> Layout:
    """Equal blocks of ``ceil(rows / devices)`` rows over ``ordered_devices()``."""
    devices = ordered_devices()
    size = len(devices) * max(1, -(-rows // len(devices)))
    mesh = Mesh(np.asarray(devices), (AXIS,))
    return _from_rows(rows, size, NamedSharding(mesh, PartitionSpec(AXIS)))


def _layout_of_split(x: jax.Array, name: str) -> Layout:
    """The layout of a global array split along axis 0; ValueError for any other split."""
    for index in x.sharding.devices_indices_map(x.shape).values():
        for axis, (part, dim) in enumerate(zip(index[1:], x.shape[1:], strict=True), 1):
            if part.indices(dim)[:2] != (0, dim):
                raise ValueError(
                    f"{name}: a global jax.Array must be split along its leading (batch) axis "
                    f"only; this one is split along axis {axis} ({x.sharding})"
                )
    if not isinstance(x.sharding, NamedSharding):
        raise ValueError(
            f"{name}: a global jax.Array needs a NamedSharding (e.g. from "
            f"jax.make_array_from_process_local_data), got {type(x.sharding).__name__}"
        )
    spec = x.sharding.spec
    sharding = NamedSharding(x.sharding.mesh, PartitionSpec(spec[0] if len(spec) else None))
    return _from_rows(x.shape[0], x.shape[0], sharding)


def _describe(leaf: Any) -> str:
    return f"{tuple(np.shape(leaf))} {np.dtype(leaf.dtype).name}"


def layout_of(tree: Any, name: str) -> Layout:
    """How the leaves of ``tree`` (a shared leading axis) are split over the devices.

    The layout of the first leaf that is a split global array (every other split leaf must be
    split alike), else the standard layout. Host leaves must have one shape and dtype on
    every process (they are taken to be the same data everywhere).

    Raises:
        ValueError: naming ``name``: a global array split along another axis, leaves split
            differently, or host leaves whose shapes differ between processes.
    """
    leaves = jax.tree.leaves(tree)
    split = [leaf for leaf in leaves if is_split(leaf)]
    if split:
        layout = _layout_of_split(split[0], name)
        reference = split[0].sharding.devices_indices_map(split[0].shape[:1])
        for leaf in split[1:]:
            if leaf.sharding.devices_indices_map(leaf.shape[:1]) != reference:
                raise ValueError(
                    f"{name}: its global arrays must be split alike along the leading axis, "
                    f"got {split[0].sharding} and {leaf.sharding}"
                )
    else:
        layout = standard_layout(leaves[0].shape[0])
    host = [_describe(leaf) for leaf in leaves if not is_split(leaf)]
    if host and process_count() > 1:
        mine = "; ".join(host)
        every = [bytes(row).rstrip(b"\0").decode() for row in allgather(_padded_text(mine))]
        if any(text != mine for text in every):
            listed = ", ".join(f"process {p}: {text}" for p, text in enumerate(every))
            raise ValueError(
                f"{name}: host (NumPy or single-device) arrays must be the same on every "
                f"process; their shapes differ ({listed}). Pass a global jax.Array "
                "(jax.make_array_from_process_local_data) to give each process its own rows"
            )
    return layout


def _padded_text(text: str, size: int = 512) -> np.ndarray:
    data = text.encode()[:size]
    return np.frombuffer(data + b"\0" * (size - len(data)), np.uint8)


def read_block(leaf: Any, layout: Layout, block: int) -> jax.Array:
    """Rows ``layout.blocks[block]`` of ``leaf`` on the block's first device.

    A split global array gives its own shard (no copy); host data is sliced, rows past the
    end repeating the last row.
    """
    (start, stop), device = layout.blocks[block], layout.devices[block][0]
    if is_split(leaf):
        for shard in leaf.addressable_shards:
            if shard.device == device:
                return shard.data
        raise AssertionError("a split leaf has no shard on its layout's device")
    if isinstance(leaf, jax.Array) and not leaf.is_fully_addressable:
        leaf = leaf.addressable_data(0)  # fully replicated: this process holds all of it
    rows = leaf.shape[0]
    part = leaf[start:stop] if stop <= rows else leaf[np.minimum(np.arange(start, stop), rows - 1)]
    return jax.device_put(part, device)


def assemble(layout: Layout, blocks: Sequence[Any]) -> Any:
    """The global arrays (pytree) of ``layout.size`` rows from each block's outputs.

    ``blocks[i]`` holds block ``i``'s outputs (a pytree of arrays with the block's rows
    leading) on its first device; they are copied to the block's other devices. Rows past
    ``layout.rows`` are dropped at the end: the result is then replicated, since a global
    array's blocks must have one size.
    """

    def leaf(*parts: jax.Array) -> jax.Array:
        arrays = []
        for part, devices in zip(parts, layout.devices, strict=True):
            arrays += [part if d == devices[0] else jax.device_put(part, d) for d in devices]
        shape = (layout.size, *parts[0].shape[1:])
        return jax.make_array_from_single_device_arrays(shape, layout.sharding, arrays)

    whole = jax.tree.map(leaf, *blocks)
    if layout.size == layout.rows:
        return whole
    return jax.tree.map(lambda x: x[: layout.rows], whole)


# ------------------------------------------------------------------ host values


def allgather(x: np.ndarray) -> np.ndarray:
    """Every process's ``x`` (one shape and dtype everywhere), stacked: ``(processes, *shape)``.

    The bytes are gathered, so 64-bit values stay exact whatever JAX's x64 setting.
    """
    x = np.ascontiguousarray(x)
    if process_count() == 1:
        return x[None]
    from jax.experimental import multihost_utils

    payload = np.frombuffer(x.tobytes(), np.uint8)
    every = np.asarray(multihost_utils.process_allgather(payload))
    return every.view(x.dtype).reshape((process_count(), *x.shape))


def allgather_rows(x: np.ndarray) -> np.ndarray:
    """Every process's rows of ``x`` (any number each, one trailing shape), concatenated in
    process order."""
    x = np.ascontiguousarray(x)
    if process_count() == 1:
        return x
    counts = allgather(np.asarray([x.shape[0]], np.int64))[:, 0]
    longest = int(counts.max())
    padded = np.zeros((longest, *x.shape[1:]), x.dtype)
    padded[: x.shape[0]] = x
    every = allgather(padded)
    return np.concatenate([part[:count] for part, count in zip(every, counts, strict=True)])


def local_rows(x: Any) -> list[tuple[int, np.ndarray]]:
    """``(first row, rows)`` of each distinct block of ``x`` this process holds (host copies);
    the whole array as one block when it is fetchable."""
    if fetchable(x):
        return [(0, np.asarray(x))]
    seen, blocks = set(), []
    for shard in x.addressable_shards:
        start = shard.index[0].indices(x.shape[0])[0]
        if start not in seen:
            seen.add(start)
            blocks.append((start, np.asarray(shard.data)))
    return sorted(blocks, key=lambda block: block[0])


def to_host(x: Any) -> np.ndarray:
    """The whole of ``x`` on every process (a collective when ``x`` spans processes)."""
    if fetchable(x):
        return np.asarray(x)
    from jax.experimental import multihost_utils

    return np.asarray(multihost_utils.process_allgather(x, tiled=True))


def global_from_parts(part: np.ndarray, shape: tuple[int, ...]) -> jax.Array:
    """A global array of ``shape`` from each process's run of its flattening (the runs of
    ``process_range`` of its size: they cover it once, in process order).

    Split along axis 0 over one device per process when the processes divide ``shape[0]``
    (each run is then whole axis-0 rows), else replicated: every process holds the whole,
    gathered as bits for a boolean array.
    """
    devices = [min(group, key=lambda d: d.id) for group in _devices_by_process()]
    device = devices[jax.process_index()]
    mesh = Mesh(np.asarray(devices), (AXIS,))
    if shape[0] % len(devices) == 0:
        local = part.reshape((shape[0] // len(devices), *shape[1:]))
        sharding = NamedSharding(mesh, PartitionSpec(AXIS))
    else:
        local = _gather_runs(part).reshape(shape)
        sharding = NamedSharding(mesh, PartitionSpec())
    return jax.make_array_from_single_device_arrays(
        shape, sharding, [jax.device_put(local, device)]
    )


def _gather_runs(part: np.ndarray) -> np.ndarray:
    """Every process's flat run, concatenated in process order (booleans sent as bits)."""
    flat = np.ascontiguousarray(part).reshape(-1)
    if flat.dtype != bool:
        return allgather_rows(flat)
    counts = allgather(np.asarray([flat.size], np.int64))[:, 0]
    bits = allgather_rows(np.packbits(flat))
    runs, offset = [], 0
    for count in counts:
        length = -(-int(count) // 8)
        runs.append(np.unpackbits(bits[offset : offset + length], count=int(count)).astype(bool))
        offset += length
    return np.concatenate(runs)


def _devices_by_process() -> list[list[Any]]:
    groups: dict[int, list[Any]] = {}
    for device in jax.devices():
        groups.setdefault(device.process_index, []).append(device)
    return [groups[p] for p in sorted(groups)]
