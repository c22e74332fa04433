"""JAX's persistent compilation cache, switched on by one call (never on import).

A kernel compiled once is written to a directory and loaded from there by later processes
with the same JAX version, device and program, instead of being compiled again (XLA compiles
jaxkin's kernels in 0.2-30 s each on a 2-core CPU; loading one takes milliseconds).
``enable_compilation_cache()`` points JAX's cache at ``$XDG_CACHE_HOME/jaxkin`` (or
``~/.cache/jaxkin``) or at a given directory. It changes JAX's global configuration, so the
library never calls it on its own: an application opts in, and the ``jaxkin`` command does
(``JAXKIN_COMPILATION_CACHE`` turns it off or moves it, see ``docs/cli.md``).
"""

from __future__ import annotations

import contextlib
import functools
import hashlib
import inspect
import os
import pickle
import platform
import tempfile
import threading
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import jax
import numpy as np
from jax.experimental import serialize_executable as _serialize
from jax.experimental.compilation_cache import compilation_cache as _jax_cache

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
) -> Path:
    """Keep compiled kernels on disk in ``path`` and reuse them in later processes.

    Sets JAX's ``jax_compilation_cache_dir`` and ``jax_persistent_cache_min_compile_time_secs``
    for the whole process (every JAX program, not only jaxkin's) and takes effect even when
    something was compiled before the call.

    Args:
        path: the cache directory, created if missing; ``None``: ``default_cache_dir()``.
        min_compile_time_secs: programs that compile faster than this are not written.

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
    compile time): its second run on the same kind of input then compiles nothing. In a
    directory of its own choice (not one set for JAX) the executables of ``stored_jit``
    programs go to the subdirectory ``executables`` (``enable_store``): a second run loads
    them without tracing. The caller turns the store off again (``enable_store(None)``).
    """
    setting = os.environ.get(ENV_VAR, "").strip()
    enable_store(None)
    if setting.lower() in _OFF:
        return None
    if jax.config.jax_compilation_cache_dir:
        return Path(jax.config.jax_compilation_cache_dir)  # JAX's own, without executables
    try:
        # Every program, however quick to compile: a second run then compiles nothing.
        directory = enable_compilation_cache(setting or None, min_compile_time_secs=0.0)
    except ValueError:
        return None
    enable_store(directory / STORE_SUBDIR)
    return directory


# ---------------------------------------------------------------- stored executables
#
# JAX's persistent cache saves XLA's compilation, but a later process still traces the
# function and lowers it to find the cache key (for a chain's IK search, seconds per run).
# The ``jaxkin`` command also keeps each compiled program's executable, keyed on everything
# that decides it (the function, the arguments' tree and static fields, shapes and dtypes,
# the versions, jaxkin's source files, the backend, the machine), so that a second run loads
# and calls it without tracing. Anything that cannot be read back compiles as usual.

STORE_SUBDIR = "executables"
_MAGIC = b"jaxkin-executable-1\n"
_store: Path | None = None  # the directory of stored executables; None: off
_LOCK = threading.RLock()  # loads and compiles (which turn JAX's cache off for a while)
# ``jax.monitoring`` events: an executable loaded from the store, or compiled (not found).
STORE_LOAD_EVENT = "/jaxkin/executable_store/load"
STORE_COMPILE_EVENT = "/jaxkin/executable_store/compile"


def store_directory() -> Path | None:
    """The directory of stored executables (``enable_for_command``), or None when off."""
    return _store


def enable_store(directory: str | os.PathLike | None) -> Path | None:
    """Keep executables of ``stored_jit`` programs in ``directory`` (None: off). Returns it."""
    global _store
    if directory is None:
        _store = None
        return None
    path = Path(directory)
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError:
        _store = None
        return None
    _store = path
    return path


def stored_jit(
    fun: Any, static_argnames: tuple[str, ...] = (), compiler_options: dict | None = None
) -> Any:
    """``jax.jit(fun, static_argnames=..., compiler_options=...)``, whose calls on concrete
    arguments go through the executable store when it is on (``enable_store``); tracers, and
    every call while it is off, go to the plain ``jax.jit``."""
    return _StoredJit(fun, tuple(static_argnames), dict(compiler_options or {}))


class _StoredJit:
    """``jax.jit(fun)`` with the executable store in front of its concrete calls."""

    def __init__(self, fun: Any, static_argnames: tuple[str, ...], options: dict) -> None:
        self._fun = fun
        self._static = static_argnames
        self._options = options or None
        self.jitted = jax.jit(
            fun, static_argnames=static_argnames or None, compiler_options=self._options
        )
        self._nested = jax.jit(fun, static_argnames=static_argnames or None)
        self._signature = inspect.signature(fun)
        self._dynamic = tuple(n for n in self._signature.parameters if n not in static_argnames)
        self._by_static: dict[tuple, Any] = {}  # a jitted function per static values
        self._loaded: dict[str, Any] = {}  # this process's executables by key
        functools.update_wrapper(self, _unwrapped(fun))

    def __getattr__(self, name: str) -> Any:  # lower, trace, eval_shape ...
        return getattr(self.jitted, name)

    def __call__(self, *args: Any, **kwargs: Any) -> Any:
        if self._options is not None and _traced((args, kwargs)):
            # inside a caller's jit the enclosing program's compilation settings apply (JAX
            # takes compiler options on a top-level jit only)
            return self._nested(*args, **kwargs)
        if _store is None:
            return self.jitted(*args, **kwargs)
        jitted, dynamic, static = self.jitted, args, ""
        if self._static or kwargs:
            try:
                bound = self._signature.bind(*args, **kwargs)
                bound.apply_defaults()
                values = tuple((n, bound.arguments[n]) for n in self._static)
                jitted = self._by_static.get(values) or self._bind(values)
            except TypeError:  # bad arguments or unhashable static values: jit says so
                return self.jitted(*args, **kwargs)
            dynamic, static = tuple(bound.arguments[n] for n in self._dynamic), repr(values)
        leaves, tree = jax.tree.flatten(dynamic)
        key = _key(self._fun, static + repr(sorted((self._options or {}).items())), tree, leaves)
        if key is None:
            return self.jitted(*args, **kwargs)
        compiled = self._loaded.get(key)
        if compiled is not None:
            return compiled(*dynamic)
        with _LOCK:  # host threads calling one new program: loaded or compiled once
            compiled = self._loaded.get(key)
            if compiled is not None:
                return compiled(*dynamic)
            return self._first_call(key, jitted, dynamic)

    def _first_call(self, key: str, jitted: Any, dynamic: tuple) -> Any:
        """Load the program of ``key`` from the store, or compile and store it; then call it."""
        path = _store / f"{key}.exe"
        compiled = _load(path)
        if compiled is not None:
            try:
                result = compiled(*dynamic)
            except Exception:  # an executable that loads but does not run: compiled again
                compiled = None
            else:
                self._loaded[key] = compiled
                jax.monitoring.record_event(STORE_LOAD_EVENT)
                return result
        jax.monitoring.record_event(STORE_COMPILE_EVENT)
        with _without_persistent_cache():
            # An executable that JAX's cache gave back cannot be written again (XLA's CPU
            # client keeps its code apart): compiled here from the traced program.
            compiled = jitted.lower(*dynamic).compile()
        if _save(path, compiled):
            # Called as a later run will call it, read back: the same results in every run,
            # and an entry that does not run is removed (this process may hold the program
            # from JAX's cache already, whose copy cannot be written).
            stored = _load(path)
            try:
                result = stored(*dynamic) if stored is not None else None
            except Exception:
                stored = None
            if stored is not None:
                self._loaded[key] = stored
                return result
            with contextlib.suppress(OSError):
                path.unlink()
        self._loaded[key] = compiled
        return compiled(*dynamic)

    def _bind(self, values: tuple) -> Any:
        """``fun`` with the static arguments ``values`` bound, jitted, taking the others in
        signature order."""
        fun, names, static = self._fun, self._dynamic, dict(values)
        hash(values)  # TypeError when unhashable

        def call(*dynamic: Any) -> Any:
            return fun(**dict(zip(names, dynamic, strict=True)), **static)

        jitted = self._by_static[values] = jax.jit(call, compiler_options=self._options)
        return jitted


@contextlib.contextmanager
def _without_persistent_cache() -> Iterator[None]:
    """JAX's persistent cache off while compiling (on again after, as it was)."""
    saved = jax.config.jax_enable_compilation_cache
    jax.config.update("jax_enable_compilation_cache", False)
    _jax_cache.reset_cache()
    try:
        yield
    finally:
        jax.config.update("jax_enable_compilation_cache", saved)
        _jax_cache.reset_cache()


def _traced(tree: Any) -> bool:
    """Whether any leaf of ``tree`` is a tracer (a call inside a caller's transformation)."""
    return any(isinstance(leaf, jax.core.Tracer) for leaf in jax.tree.leaves(tree))


def _unwrapped(fun: Any) -> Any:
    while isinstance(fun, functools.partial):
        fun = fun.func
    return fun


def _describe(fun: Any) -> str:
    """The function's module, qualified name and bound arguments (``functools.partial``)."""
    bound = []
    while isinstance(fun, functools.partial):
        bound.append(repr((fun.args, sorted(fun.keywords.items()))))
        fun = fun.func
    return f"{fun.__module__}.{fun.__qualname__}{''.join(reversed(bound))}"


def _key(fun: Any, static: str, tree: Any, leaves: list) -> str | None:
    """The store's key of a call, or None when the call must not be stored (a tracer, an
    argument that is not an array or a number, several devices or processes)."""
    if jax.process_count() != 1:
        return None
    parts = [_describe(fun) + static, str(tree), _environment()]
    for leaf in leaves:
        if isinstance(leaf, jax.core.Tracer):
            return None
        if isinstance(leaf, jax.Array):
            if len(leaf.devices()) != 1:
                return None
            parts.append(f"{leaf.shape}{leaf.dtype}{leaf.weak_type}{leaf.sharding}")
        elif isinstance(leaf, np.ndarray | np.generic):
            parts.append(f"{np.shape(leaf)}{leaf.dtype}np")
        elif isinstance(leaf, bool | int | float | complex):
            parts.append(type(leaf).__name__)
        else:
            return None
    if " at 0x" in parts[0] or " at 0x" in parts[1]:
        return None  # an object's address in a static field: a key that changes every run
    return hashlib.sha256("\n".join(parts).encode()).hexdigest()


@functools.cache
def _environment_fixed() -> str:
    """What decides an executable besides the call: versions, backend, machine, the sources
    of jaxkin (edited code, same version number) and the flags read by XLA."""
    import jaxlib

    from . import __version__

    root = Path(__file__).parent
    sources = sorted(
        f"{p.relative_to(root)}:{s.st_size}:{s.st_mtime_ns}"
        for p in root.rglob("*.py")
        for s in (p.stat(),)
    )
    device = jax.devices()[0]
    return "\n".join(
        [
            f"jax {jax.__version__} jaxlib {jaxlib.__version__} jaxkin {__version__}",
            f"{device.platform} {device.device_kind} {device.client.platform_version}",
            f"{platform.machine()} {_cpu_flags()}",
            os.environ.get("XLA_FLAGS", ""),
            hashlib.sha256("\n".join(sources).encode()).hexdigest(),
        ]
    )


def _environment() -> str:
    config = jax.config
    flags = (
        config.jax_enable_x64,
        config.jax_default_matmul_precision,
        config.jax_numpy_rank_promotion,
    )
    return f"{_environment_fixed()}\n{flags}"


def _cpu_flags() -> str:
    try:
        with open("/proc/cpuinfo", encoding="ascii", errors="replace") as f:
            for line in f:
                if line.startswith(("flags", "Features")):
                    return hashlib.sha256(line.encode()).hexdigest()[:16]
    except OSError:
        pass
    return platform.processor()


def _initialize_lapack() -> None:
    """Load LAPACK's entry points, as JAX does when it lowers a linear-algebra call: a
    program that calls LAPACK and is loaded without being lowered in this process would
    otherwise call a null function and crash the interpreter. Only for a program that names
    a LAPACK call (``_load``): the set-up imports scipy, about 0.2 s."""
    from jaxlib import lapack

    lapack._lapack.initialize()


def _load(path: Path) -> Any:
    """The executable stored at ``path``, or None when missing, corrupt or unloadable."""
    try:
        data = path.read_bytes()
    except OSError:
        return None
    head = len(_MAGIC) + 32
    body = data[head:]
    if data[: len(_MAGIC)] != _MAGIC or hashlib.sha256(body).digest() != data[len(_MAGIC) : head]:
        return None  # truncated, overwritten or not ours: compiled again
    try:
        payload, in_tree, out_tree = pickle.loads(body)
        if b"lapack" in payload:  # the serialised program names its LAPACK calls
            _initialize_lapack()
        return _serialize.deserialize_and_load(payload, in_tree, out_tree)
    except Exception:  # written by another version of a library: compiled again
        return None


def _save(path: Path, compiled: Any) -> bool:
    """Write ``compiled`` at ``path`` atomically; False when the executable cannot be
    serialised or the directory cannot be written (the run goes on)."""
    try:
        body = pickle.dumps(_serialize.serialize(compiled))
    except Exception:
        return False
    data = _MAGIC + hashlib.sha256(body).digest() + body
    try:
        with tempfile.NamedTemporaryFile(dir=path.parent, prefix=".tmp-", delete=False) as f:
            f.write(data)
        os.replace(f.name, path)
    except OSError:
        with contextlib.suppress(OSError, NameError):
            os.unlink(f.name)
        return False
    return True
