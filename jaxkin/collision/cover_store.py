"""Mesh covers kept on disk beside JAX's persistent compilation cache, for later processes.

A mesh's cover takes up to seconds of CPU (the Panda's 18 meshes about 3 s), paid again by
every process that reads the robot. When JAX's persistent compilation cache is on
(``jaxkin.enable_compilation_cache()``, the ``jaxkin`` command's default), each cover
computed is written to ``<cache directory>/covers/<key>.npz`` and read back by later
processes instead of being computed. The key is the SHA-256 of the mesh (its vertices' and
faces' dtypes, shapes and bytes), the cover's kind and parameters, and the source of the
modules that compute covers: another mesh, bound or budget, or any change of the algorithm,
gives another entry. With the cache off (no directory set) covers are computed every time; an
entry that cannot be read or written is computed (and the failure otherwise ignored), so the
store never changes a result, only when it is computed.
"""

from __future__ import annotations

import dataclasses
import functools
import hashlib
import zipfile
from collections.abc import Callable
from pathlib import Path
from typing import Any, TypeVar

import jax
import numpy as np

from .._output import atomic_write
from . import cover, triangles

__all__ = ["cached_cover", "store_directory"]

Cover = TypeVar("Cover", cover.SphereCover, cover.MeshCover)


def store_directory() -> Path | None:
    """``<JAX's compilation cache directory>/covers``, or None when that cache is off."""
    configured = jax.config.jax_compilation_cache_dir  # type: ignore[attr-defined]  # jax types no options
    return Path(configured) / "covers" if configured else None


@functools.cache
def _algorithm() -> bytes:
    """The source of the modules that compute covers (a change makes new keys)."""
    digest = hashlib.sha256()
    for module in (cover, triangles):
        digest.update(Path(module.__file__ or "").read_bytes())
    return digest.digest()


def _key(kind: str, vertices: np.ndarray, faces: np.ndarray, params: tuple) -> str:
    digest = hashlib.sha256(_algorithm())
    digest.update(repr((kind, params)).encode())
    for a in (np.ascontiguousarray(vertices), np.ascontiguousarray(faces)):
        digest.update(repr((a.dtype.str, a.shape)).encode())
        digest.update(a.tobytes())
    return digest.hexdigest()


def _read(path: Path, cls: type[Cover]) -> Cover | None:
    try:
        with np.load(path) as data:
            values: dict[str, Any] = {name: data[name] for name in data.files}
        fields = {f.name for f in dataclasses.fields(cls)}
        if set(values) != fields:
            return None
        values["overshoot"] = float(values["overshoot"])
        return cls(**values)
    except (OSError, ValueError, KeyError, TypeError, EOFError, zipfile.BadZipFile):
        return None  # damaged or foreign: computed again


def _write(path: Path, found: Any) -> None:
    arrays: dict[str, Any] = {k: np.asarray(v) for k, v in dataclasses.asdict(found).items()}
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        # written whole, then renamed: a reader never sees half a file
        with atomic_write(path, "wb") as f:
            np.savez(f, **arrays)
    except (OSError, ValueError):  # a store that cannot be written is no store
        pass


def cached_cover(
    compute: Callable[..., Cover],
    cls: type[Cover],
    vertices: np.ndarray,
    faces: np.ndarray,
    *params: Any,
) -> Cover:
    """``compute(vertices, faces, *params)``, read from the store when an earlier process
    computed it (module docstring); ``cls`` is the cover's class."""
    directory = store_directory()
    if directory is None:
        return compute(vertices, faces, *params)
    path = directory / f"{_key(compute.__name__, vertices, faces, params)}.npz"
    found = _read(path, cls) if path.is_file() else None
    if found is None:
        found = compute(vertices, faces, *params)
        _write(path, found)
    return found
