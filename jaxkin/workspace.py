"""Chunked voxel sweeps of a robot's reachable workspace.

``sweep(status_of, bounds, resolution)`` evaluates a regular grid of points (voxel centres)
``x_k = lo + k * resolution`` for ``k = 0 .. floor((hi - lo) / resolution)`` on each axis (both
ends included when ``hi - lo`` is a multiple of the resolution, as in the Delta paper's
101 x 101 x 91 grid). ``status_of(points (N, 3)) -> status (N,)`` is any robot's IK status
(e.g. ``lambda pts: scara.ik(robot, pts).status``); a point is reachable where its status is in
``reachable`` (default: ``Status.OK``).

Memory is bounded: points are generated on the host chunk by chunk (``chunk_size`` points, the
last chunk padded so every call has the same shape and compiles once), and only the boolean
mask is kept. A progress bar (``jaxkin.progress.bar``) is shown when stderr is a terminal
(``progress=None``); ``progress=False`` silences it, ``progress=True`` forces it.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Iterable
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from jax import Array

from .progress import bar
from .status import Status

Bounds = tuple[tuple[float, float], tuple[float, float], tuple[float, float]]


@dataclasses.dataclass(frozen=True)
class WorkspaceResult:
    """Result of a voxel sweep (host-side NumPy arrays).

    Attributes:
        mask: reachable voxels, ``bool``, shape ``(nx, ny, nz)`` (index order x, y, z).
        axes: the grid coordinates ``(x (nx,), y (ny,), z (nz,))``.
        resolution: voxel edge length.
        n_evaluated: number of voxels evaluated, ``nx * ny * nz``.
        n_reachable: number of reachable voxels.
        volume: ``n_reachable * resolution^3``.
        slice_areas: reachable area of each z slice, ``(nz,)`` (``count * resolution^2``).
    """

    mask: np.ndarray
    axes: tuple[np.ndarray, np.ndarray, np.ndarray]
    resolution: float
    n_evaluated: int
    n_reachable: int
    volume: float
    slice_areas: np.ndarray


def grid_axes(bounds: Bounds, resolution: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The voxel-centre coordinates on each axis (see the module docstring)."""
    axes = []
    for name, (lo, hi) in zip("xyz", bounds, strict=True):
        lo, hi = float(lo), float(hi)
        if not (math.isfinite(lo) and math.isfinite(hi) and lo <= hi):
            raise ValueError(f"bounds[{name!r}] must be finite with lo <= hi, got {(lo, hi)}")
        count = int(math.floor((hi - lo) / resolution + 1e-9)) + 1
        axes.append(lo + resolution * np.arange(count))
    return axes[0], axes[1], axes[2]


def sweep(
    status_of: Callable[[Array], Array],
    bounds: Bounds,
    resolution: float,
    *,
    chunk_size: int = 1 << 18,
    dtype: Any = None,
    progress: bool | None = None,
    reachable: Iterable[int] = (Status.OK,),
) -> WorkspaceResult:
    """Evaluate ``status_of`` on a voxel grid in chunks; return the reachable mask and volume.

    Args:
        status_of: ``points (N, 3) -> status (N,)``, jit-able (it is wrapped in ``jax.jit``).
        bounds: ``((x_lo, x_hi), (y_lo, y_hi), (z_lo, z_hi))``.
        resolution: voxel edge length (> 0).
        chunk_size: points per call (memory bound; the last chunk is padded).
        dtype: float dtype of the points (default: JAX's default float, float64 under x64).
        progress: progress bar policy (see the module docstring).
        reachable: status codes that count as reachable.

    Raises:
        ValueError: non-positive resolution or chunk size, malformed bounds.
    """
    resolution = float(resolution)
    if not (math.isfinite(resolution) and resolution > 0):
        raise ValueError(f"resolution must be positive and finite, got {resolution}")
    if isinstance(chunk_size, bool) or not isinstance(chunk_size, int) or chunk_size < 1:
        raise ValueError(f"chunk_size must be a positive int, got {chunk_size!r}")
    if len(bounds) != 3 or any(len(b) != 2 for b in bounds):
        raise ValueError(f"bounds must be three (lo, hi) pairs, got {bounds!r}")
    xs, ys, zs = grid_axes(bounds, resolution)
    shape = (len(xs), len(ys), len(zs))
    total = shape[0] * shape[1] * shape[2]
    dtype = jnp.result_type(float) if dtype is None else jnp.dtype(dtype)
    accept = jnp.asarray(sorted(int(s) for s in reachable), jnp.int32)
    chunk = min(chunk_size, total)

    @jax.jit
    def evaluate(points: Array) -> Array:
        status = jnp.asarray(status_of(points)).astype(jnp.int32)
        return jnp.any(status[:, None] == accept[None, :], axis=-1)

    flat = np.zeros(total, dtype=bool)
    with bar(total, "workspace", enabled=progress) as meter:
        for start in range(0, total, chunk):
            stop = min(start + chunk, total)
            index = np.arange(start, start + chunk)
            index[stop - start :] = 0  # pad with a valid voxel, discarded below
            i, rest = np.divmod(index, shape[1] * shape[2])
            j, k = np.divmod(rest, shape[2])
            points = np.stack([xs[i], ys[j], zs[k]], axis=-1).astype(dtype)
            flat[start:stop] = np.asarray(evaluate(points))[: stop - start]
            meter.update(stop - start)
    mask = flat.reshape(shape)
    n_reachable = int(mask.sum())
    return WorkspaceResult(
        mask=mask,
        axes=(xs, ys, zs),
        resolution=resolution,
        n_evaluated=total,
        n_reachable=n_reachable,
        volume=n_reachable * resolution**3,
        slice_areas=mask.sum(axis=(0, 1)) * resolution**2,
    )
