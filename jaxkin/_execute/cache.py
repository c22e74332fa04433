"""JAX's persistent compilation cache, switched on by one call (never on import).

A kernel compiled once is written to a directory and loaded from there by later processes
with the same JAX version, device and program, instead of being compiled again (XLA compiles
jaxkin's kernels in 0.2-30 s each on a 2-core CPU; loading one takes milliseconds).
``enable_compilation_cache()`` points JAX's cache at ``$XDG_CACHE_HOME/jaxkin`` (or
``~/.cache/jaxkin``) or at a given directory. It changes JAX's global configuration, so the
library never calls it on its own: an application opts in, and the ``jaxkin`` command does
(``JAXKIN_COMPILATION_CACHE`` turns it off or moves it, see ``docs/cli.md``). Both also keep
jaxkin's kernels there as serialised programs (``store``), which later processes call
without tracing.
"""

from __future__ import annotations

import os
import warnings
from pathlib import Path

import jax
from jax.experimental.compilation_cache import compilation_cache as _jax_cache

from . import store

__all__ = ["default_cache_dir", "enable_compilation_cache"]

# Programs that compile faster than this are not written (their files would cost more disk
# than the time they save); jaxkin's kernels mostly take longer.
DEFAULT_MIN_COMPILE_TIME_SECS = 0.1


def default_cache_dir() -> Path:
    """``$XDG_CACHE_HOME/jaxkin``, or ``~/.cache/jaxkin`` when ``XDG_CACHE_HOME`` is unset."""
    base = os.environ.get("XDG_CACHE_HOME", "").strip()
    return Path(base or Path.home() / ".cache") / "jaxkin"


def enable_compilation_cache(
    path: str | os.PathLike | None = None,
    *,
    min_compile_time_secs: float = DEFAULT_MIN_COMPILE_TIME_SECS,
    programs: bool = True,
) -> Path:
    """Keep compiled kernels on disk in ``path`` and reuse them in later processes.

    Sets JAX's ``jax_compilation_cache_dir`` and ``jax_persistent_cache_min_compile_time_secs``
    for the whole process (every JAX program, not only jaxkin's) and takes effect even when
    something was compiled before the call. With ``programs`` (and ``flatbuffers``
    installed: the ``cache`` extra), jaxkin's kernels are also kept as ``jax.export``
    serialisations in ``path/programs`` (``store``), so a later process calls them without
    tracing them again.

    Args:
        path: the cache directory, created if missing; ``None``: ``default_cache_dir()``.
        min_compile_time_secs: programs that compile faster than this are not written.
        programs: keep jaxkin's kernels as serialised programs too.

    Returns:
        The cache directory.

    Raises:
        ValueError: ``path`` exists and is not a directory, cannot be created, or
            ``min_compile_time_secs`` is negative.
    """
    if not min_compile_time_secs >= 0:
        raise ValueError(f"min_compile_time_secs must be >= 0, got {min_compile_time_secs!r}")
    directory = Path(path).expanduser() if path is not None else default_cache_dir()
    try:
        directory.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        message = f"path: cannot use {str(directory)!r} as a cache directory: {exc}"
        raise ValueError(message) from exc
    jax.config.update("jax_compilation_cache_dir", str(directory))
    jax.config.update("jax_persistent_cache_min_compile_time_secs", float(min_compile_time_secs))
    # JAX decides once per process whether the cache is used; forget a decision taken before.
    _jax_cache.reset_cache()
    store.keep_programs(programs)
    if programs and not store.serialisable():
        warnings.warn(
            "jaxkin keeps compiled code only: keeping its programs needs flatbuffers "
            "(pip install 'jaxkin[cache]'), so later processes trace every kernel again",
            stacklevel=2,
        )
    return directory


ENV_VAR = "JAXKIN_COMPILATION_CACHE"
_OFF = ("0", "off", "false", "no")


def enable_for_command() -> Path | None:
    """The ``jaxkin`` command's default: the cache on, unless the environment says otherwise.

    ``JAXKIN_COMPILATION_CACHE`` unset or empty: ``default_cache_dir()``; ``0``, ``off``,
    ``false`` or ``no``: off; anything else: that directory. A cache directory already set
    for JAX (``JAX_COMPILATION_CACHE_DIR``) is left as it is. Returns the directory in use, or
    None when off. A directory that cannot be used leaves the cache off (the command runs
    anyway, compiling as usual). The command keeps every program it compiles (no minimum
    compile time) and keeps jaxkin's kernels as serialised programs: its second run on the same
    kind of input then neither traces jaxkin's kernels nor compiles them.
    """
    setting = os.environ.get(ENV_VAR, "").strip()
    if setting.lower() in _OFF:
        return None
    configured = jax.config.jax_compilation_cache_dir  # type: ignore[attr-defined]  # jax's Config types no options
    if configured:
        store.keep_programs()
        return Path(configured)
    try:
        # Every program, however quick to compile: a second run then compiles nothing.
        return enable_compilation_cache(setting or None, min_compile_time_secs=0.0)
    except ValueError:
        return None
