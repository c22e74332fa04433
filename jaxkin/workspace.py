"""Voxel sweeps of the reachable workspace of any robot whose targets are points.

``sweep(robot)`` evaluates the robot's inverse kinematics (``jaxkin.ik``, one branch) on a
regular grid of voxel centres ``x_k = lo + k * resolution``, ``k = 0 .. floor((hi - lo) /
resolution)`` per axis (both ends included when ``hi - lo`` is a multiple of the resolution,
as in the 101 x 101 x 91 grid of [Cardona, sec. V]); a voxel is reachable where its status is
one of ``robot.reachable`` (solved positions, the singular boundary included). Planar robots
get a 2-D grid, 3-D point robots a 3-D one; robots whose targets are poses have no voxel
workspace.

Memory is bounded: points are made on the host chunk by chunk (``jaxkin._batching.host_chunks``,
one compiled shape for every chunk) and only the boolean mask is kept. ``progress`` (a callback
``progress(done, total)``, e.g. the command line's progress bar) hears of every chunk swept.

Several processes (``jax.distributed``; every process calls ``sweep`` with the same
arguments): the flattened grid (index order x, y, z) is split into one contiguous run of
voxels per process (``jaxkin._processes.process_range``), each process sweeps its own run,
and every process gets the global counts, volume and slice areas. The mask is then a global
``jax.Array`` of the grid's shape: split along x over one device per process when the
process count divides ``nx`` (each process holds its own slab of x), else replicated (each
holds the whole mask, gathered as bits); ``jaxkin._processes.to_host`` gives it as NumPy.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from jax import Array

from . import _batching, _processes, _validate
from ._execute import as_robot, ik, kernel
from .robot import Robot

__all__ = ["WorkspaceResult", "grid_axes", "sweep"]

Bounds = tuple[tuple[float, float], ...]


@dataclasses.dataclass(frozen=True)
class WorkspaceResult:
    """Result of a voxel sweep (host-side NumPy arrays, but for a global mask).

    Attributes:
        mask: reachable voxels, ``bool``, shape ``(nx, ny, nz)`` (``(nx, ny)`` for a planar
            robot; index order x, y, z); a global ``jax.Array`` when several processes swept
            the grid (module docstring).
        axes: the grid coordinates per axis, ``(x (nx,), y (ny,)[, z (nz,)])``.
        resolution: voxel edge length.
        n_evaluated: number of voxels evaluated.
        n_reachable: number of reachable voxels.
        volume: ``n_reachable * resolution^d`` (an area for a planar robot).
        slice_areas: reachable area of each z slice, ``(nz,)`` (``count * resolution^2``); for
            a planar robot the one area, ``(1,)``.
    """

    mask: np.ndarray | jax.Array
    axes: tuple[np.ndarray, ...]
    resolution: float
    n_evaluated: int
    n_reachable: int
    volume: float
    slice_areas: np.ndarray


def grid_axes(bounds: Bounds, resolution: float) -> tuple[np.ndarray, ...]:
    """The voxel-centre coordinates on each axis (see the module docstring)."""
    axes = []
    for name, (lo, hi) in zip("xyz", bounds, strict=False):
        lo, hi = float(lo), float(hi)
        if not (math.isfinite(lo) and math.isfinite(hi) and lo <= hi):
            raise ValueError(f"bounds[{name!r}] must be finite with lo <= hi, got {(lo, hi)}")
        count = int(math.floor((hi - lo) / resolution + 1e-9)) + 1
        axes.append(lo + resolution * np.arange(count))
    return tuple(axes)


def _check_box(robot: Robot, bounds: Any, resolution: Any) -> tuple[Bounds, float]:
    dims = robot.target.shape[0]
    if bounds is None:
        bounds, default_resolution = robot.workspace_box()
        resolution = default_resolution if resolution is None else resolution
    try:
        bounds = tuple((float(lo), float(hi)) for lo, hi in bounds)
    except (TypeError, ValueError):
        raise ValueError(
            f"bounds must be {dims} (lo, hi) pairs of numbers, got {bounds!r}"
        ) from None
    if len(bounds) != dims:
        raise ValueError(
            f"bounds must be {dims} (lo, hi) pairs (one per coordinate), got {bounds!r}"
        )
    if resolution is None:
        resolution = max(hi - lo for lo, hi in bounds) / 50.0
    if isinstance(resolution, bool) or not isinstance(resolution, int | float | np.number):
        raise ValueError(f"resolution must be a positive number, got {resolution!r}")
    resolution = float(resolution)
    if not (math.isfinite(resolution) and resolution > 0):
        raise ValueError(f"resolution must be positive and finite, got {resolution}")
    return bounds, resolution


@kernel(static=("branch", "accept"))
def _reachable(robot: Robot, points: Array, branch: Any, accept: tuple[int, ...]) -> Array:
    """Whether each point's status is one of ``accept``: ``(M,)`` bool."""
    status = ik(robot, points, branch).status.astype(jnp.int32)
    return jnp.any(status[:, None] == jnp.asarray(accept, jnp.int32), axis=-1)


def sweep(
    robot: Robot,
    bounds: Bounds | None = None,
    resolution: float | None = None,
    *,
    branch: Any = None,
    chunk_size: int = _batching.SWEEP_CHUNK,
    dtype: Any = None,
    progress: _validate.Progress | None = None,
) -> WorkspaceResult:
    """Sweep a voxel grid with the robot's inverse kinematics; the reachable mask and volume.

    Args:
        robot: any robot whose targets are points (``robot.target.is_point``).
        bounds: one ``(lo, hi)`` pair per target coordinate; None for
            ``robot.workspace_box()``.
        resolution: voxel edge (> 0); None for the box's default (with explicit ``bounds``:
            the longest side / 50).
        branch: the IK branch evaluated (None: ``robot.default_branch``).
        chunk_size: voxels per call (memory bound; every call has one shape).
        dtype: float dtype of the points (default: JAX's default float, float64 under x64).
        progress: None, or a callback ``progress(done, total)`` told the voxels swept so far
            (by this process) after every chunk.

    Raises:
        ValueError: a robot whose targets are not points, malformed bounds, a non-positive
            resolution or chunk size, an unknown branch, a progress that is not callable.
    """
    robot = as_robot(robot)
    if not robot.target.is_point:
        raise ValueError(
            f"{type(robot).__name__}'s targets are {robot.target.name}s: a voxel workspace "
            "sweep needs a robot whose targets are points"
        )
    branch = robot.check_branch(branch)
    chunk_size = _validate.count(chunk_size, "chunk_size")
    report = _validate.progress(progress) or _validate.no_progress
    bounds, resolution = _check_box(robot, bounds, resolution)
    axes = grid_axes(bounds, resolution)
    shape = tuple(len(a) for a in axes)
    total = math.prod(shape)
    dtype = jnp.result_type(float) if dtype is None else jnp.dtype(dtype)
    accept = tuple(sorted(int(s) for s in robot.reachable))

    first, last = _processes.process_range(total)  # (0, total) with one process
    flat = np.zeros(last - first, dtype=bool)
    slice_counts = np.zeros(shape[-1] if len(shape) == 3 else 1, dtype=np.int64)
    report(0, last - first)
    for start, stop, index in _batching.host_chunks(last - first, chunk_size):
        coords = np.unravel_index(first + index, shape)
        points = np.stack([a[i] for a, i in zip(axes, coords, strict=True)], -1)
        inside = np.asarray(_reachable(robot, points.astype(dtype), branch, accept))
        flat[start:stop] = inside[: stop - start]
        if len(shape) == 3:
            z = coords[-1][: stop - start][inside[: stop - start]]
            slice_counts += np.bincount(z, minlength=shape[-1])
        report(stop, last - first)
    mask: np.ndarray | Array
    if _processes.process_count() == 1:
        mask = flat.reshape(shape)
        n_reachable = int(mask.sum())
    else:  # counts summed over the processes; the mask a global array (module docstring)
        mask = _processes.global_from_parts(flat, shape)
        counts = np.append(slice_counts, np.count_nonzero(flat))
        counts = _processes.allgather(counts).sum(axis=0)
        slice_counts, n_reachable = counts[:-1], int(counts[-1])
    if len(shape) == 3:
        slice_areas = slice_counts * resolution**2
    else:
        slice_areas = np.array([n_reachable * resolution**2])
    return WorkspaceResult(
        mask=mask,
        axes=axes,
        resolution=resolution,
        n_evaluated=total,
        n_reachable=n_reachable,
        volume=n_reachable * resolution ** len(shape),
        slice_areas=slice_areas,
    )
