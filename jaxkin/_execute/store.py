"""Programs kept on disk as ``jax.export`` serialisations, so later processes do not trace them.

JAX's persistent compilation cache (``cache``) keeps compiled code, but it is keyed by the
lowered program: a second process must still trace and lower every kernel to find its entry,
which for the large ones (a chain's path IK, the motion planner's search) takes seconds. With
the store on (``keep_programs``: ``enable_compilation_cache()`` and the command line turn it
on) and that cache's directory set, ``stored_jit(fn, ...)`` is ``jax.jit(fn, ...)`` whose
trace looks first in ``<cache directory>/programs`` for ``fn``'s program at the call's static
arguments and argument shapes:

* **found**: the serialised program (``jax.export.deserialize``) is called in place of
  ``fn`` (``Exported.call``), so nothing of ``fn`` is traced or lowered again, and the
  compiled code comes from JAX's cache as before;
* **not found**: ``fn`` is exported (``jax.export.export``: traced and lowered once, as
  ``jax.jit`` would), written there, and called the same way, so the first process compiles
  the very program later ones find.

The key is a SHA-256 of everything the program depends on: the source of every module of
jaxkin, the versions of JAX and jaxlib, the backend, the configuration and environment that
shape a trace (``jax_enable_x64``, ``XLA_FLAGS``, ``JAXKIN_*``, the host's threads), ``fn``
and its static arguments by value (closures and partials included), the arguments' pytree
structure with its static data, and each argument's shape, dtype and weak type. Anything the
key cannot state for certain (an object of a class defined outside jaxkin, JAX and NumPy, a
function from a user's module, a cycle) makes the call an ordinary ``jax.jit`` trace: a
program is reused only when it is the program ``fn`` would trace. (jaxkin's module-level
constants are read from its source: a process that assigns new values to them at run time
should keep compiled code only, ``enable_compilation_cache(programs=False)``.) With the cache
off, on more than one device, or when exporting fails (a program JAX cannot serialise), it is
``jax.jit(fn)`` as well; an entry that cannot be read or written is traced again. The store
never changes a result, only how it is found: the same StableHLO reaches XLA. One thing does
change: JAX commits the outputs of a serialised program to the device
(``jax.Array.committed``), so a kernel given such an output in one call and a new host array
in the same place in another compiles once for each (a second variant, once).

Only calls on concrete arrays go through the store (``Kernel`` calls it for those); a kernel
traced inside a caller's ``jit``, ``vmap`` or ``grad`` is traced as it is (a serialised
program has no derivative rules).
"""

from __future__ import annotations

import dataclasses
import enum
import functools
import hashlib
import importlib.util
import inspect
import os
import pickle
import struct
import types
from collections.abc import Callable
from pathlib import Path
from typing import Any

import jax
import numpy as np

from .._output import atomic_write

__all__ = [
    "Unstorable",
    "fingerprint",
    "keep_programs",
    "keeps_programs",
    "program_key",
    "serialisable",
    "store_directory",
    "stored_jit",
]

_MAGIC = b"JAXKINPROGRAM1\n"
# Modules whose objects the key may name by module and name alone: their code is versioned
# (jaxkin's source is in the key, JAX's and NumPy's versions are).
_NAMED_MODULES = ("jaxkin", "jax", "jaxlib", "numpy", "builtins", "math", "operator")
_CONFIG = (
    "jax_enable_x64",
    "jax_default_matmul_precision",
    "jax_numpy_dtype_promotion",
    "jax_default_prng_impl",
    "jax_threefry_partitionable",
)


class Unstorable(Exception):
    """The key cannot state a value for certain: the program is traced as usual."""


_KEEP = [False]  # set by keep_programs (``enable_compilation_cache`` and the command line)


def keep_programs(on: bool = True) -> None:
    """Turn the store on (or off) for this process; it is used while JAX's compilation cache
    has a directory."""
    _KEEP[0] = bool(on)


def keeps_programs() -> bool:
    """Whether the store is on for this process (``keep_programs``)."""
    return _KEEP[0]


def store_directory() -> Path | None:
    """``<JAX's compilation cache directory>/programs``, or None when the store or that cache
    is off."""
    configured = jax.config.jax_compilation_cache_dir  # type: ignore[attr-defined]  # jax types no options
    return Path(configured) / "programs" if configured and _KEEP[0] else None


def stored_jit(
    fn: Callable[..., Any],
    *,
    static_argnames: tuple[str, ...] = (),
    compiler_options: dict[str, Any] | None = None,
    identity: Any = None,
) -> Any:
    """``jax.jit(fn, static_argnames=..., compiler_options=...)`` whose traces use the store
    (module docstring). ``identity`` stands for ``fn`` in the key (``fn`` itself when None):
    a value that determines ``fn``'s program together with the static arguments."""
    jit = functools.partial(
        jax.jit, static_argnames=static_argnames or None, compiler_options=compiler_options
    )
    signature = inspect.signature(fn)
    kinds = {p.kind for p in signature.parameters.values()}
    if kinds & {inspect.Parameter.VAR_POSITIONAL, inspect.Parameter.VAR_KEYWORD}:
        return jit(fn)
    static = frozenset(static_argnames)
    who = fn if identity is None else identity

    @functools.wraps(fn)
    def traced(*args: Any, **kwargs: Any) -> Any:
        bound = signature.bind(*args, **kwargs)
        bound.apply_defaults()
        statics = {k: v for k, v in bound.arguments.items() if k in static}
        dynamic = {k: v for k, v in bound.arguments.items() if k not in static}
        leaves, in_tree = jax.tree.flatten(dynamic)
        entry = _entry(fn, who, statics, leaves, in_tree, compiler_options)
        if entry is None:
            return fn(*args, **kwargs)
        exported, out_tree = entry
        return jax.tree.unflatten(out_tree, exported.call(*leaves))

    return jit(traced)


# ------------------------------------------------------------------------------ entries


def _entry(
    fn: Callable[..., Any],
    who: Any,
    statics: dict[str, Any],
    leaves: list[Any],
    in_tree: Any,
    options: dict[str, Any] | None,
) -> tuple[Any, Any] | None:
    """``(exported, out_tree)`` of ``fn`` at these arguments: from the store, or exported and
    stored now; None when the store is off or the key cannot be stated (called once per
    trace: the jitted function's own cache holds the program after that)."""
    directory = store_directory()
    if directory is None or jax.device_count() != 1 or not serialisable():
        return None
    specs = [_spec(leaf) for leaf in leaves]
    try:
        key = program_key(who, statics, in_tree, specs, options)
    except Unstorable:
        return None
    path = directory / f"{key}.program"
    refused = path.with_suffix(".refused")
    found = _read(path, specs)
    if found is None:
        if refused.exists():  # JAX could not export it before: do not try again
            return None
        found = _export(fn, statics, in_tree, specs)
        if found is None:
            _write(refused, None)
            return None
        _write(path, found)
    return found


@functools.cache
def serialisable() -> bool:
    """Whether JAX can serialise exported programs here (it needs ``flatbuffers``)."""
    return importlib.util.find_spec("flatbuffers") is not None


def _spec(leaf: Any) -> jax.ShapeDtypeStruct:
    aval = jax.typeof(leaf)
    return jax.ShapeDtypeStruct(aval.shape, aval.dtype, weak_type=aval.weak_type)


def _export(fn, statics, in_tree, specs) -> tuple[Any, Any] | None:
    trees: list[Any] = []

    def flat(*xs: Any) -> list[Any]:
        out = fn(**statics, **jax.tree.unflatten(in_tree, xs))
        out_leaves, out_tree = jax.tree.flatten(out)
        trees.append(out_tree)
        return out_leaves

    try:
        exported = jax.export.export(jax.jit(flat))(*specs)
        # the same bytes a later process reads: both processes lower the identical program
        exported = jax.export.deserialize(exported.serialize())
    except Exception:  # noqa: BLE001  # a program JAX cannot export is traced as usual
        return None
    return exported, trees[-1]


def _read(path: Path, specs: list[Any]) -> tuple[Any, Any] | None:
    try:
        data = path.read_bytes()
    except OSError:
        return None
    try:
        if not data.startswith(_MAGIC):
            return None
        start = len(_MAGIC)
        (length,) = struct.unpack_from("<Q", data, start)
        start += 8
        out_tree = pickle.loads(data[start : start + length])
        exported = jax.export.deserialize(bytearray(data[start + length :]))
    except Exception:  # noqa: BLE001  # damaged or foreign: traced again
        return None
    wanted = [(s.shape, np.dtype(s.dtype)) for s in specs]
    if [(a.shape, np.dtype(a.dtype)) for a in exported.in_avals] != wanted:
        return None
    return exported, out_tree


def _write(path: Path, entry: tuple[Any, Any] | None) -> None:
    """``entry`` to ``path`` (None: an empty marker)."""
    try:
        blob = b""
        if entry is not None:
            exported, out_tree = entry
            tree = pickle.dumps(out_tree)
            blob = _MAGIC + struct.pack("<Q", len(tree)) + tree + bytes(exported.serialize())
        path.parent.mkdir(parents=True, exist_ok=True)
        # written whole, then renamed: a reader never sees half a file
        with atomic_write(path, "wb") as f:
            f.write(blob)
    except Exception:  # noqa: BLE001  # a store that cannot be written is no store
        pass


# ------------------------------------------------------------------------------ keys


def program_key(
    who: Any,
    statics: dict[str, Any],
    in_tree: Any,
    specs: list[Any],
    options: dict[str, Any] | None = None,
) -> str:
    """The SHA-256 (hex) naming a program (module docstring); ``Unstorable`` when some part
    cannot be stated for certain."""
    digest = hashlib.sha256(_environment())
    for part in (who, statics, options or {}):
        digest.update(fingerprint(part))
    digest.update(_tree_fingerprint(in_tree))
    for s in specs:
        digest.update(repr((s.shape, np.dtype(s.dtype).str, bool(s.weak_type))).encode())
    return digest.hexdigest()


@functools.cache
def _source() -> bytes:
    """The source of every module of jaxkin (any change of the code makes new keys)."""
    root = Path(__file__).resolve().parents[1]
    digest = hashlib.sha256()
    for path in sorted(root.rglob("*.py")):
        digest.update(str(path.relative_to(root)).encode() + b"\0")
        digest.update(path.read_bytes())
    return digest.digest()


def _environment() -> bytes:
    import jaxlib

    config = tuple(repr(getattr(jax.config, name, None)) for name in _CONFIG)
    env = tuple(sorted((k, v) for k, v in os.environ.items() if k.startswith("JAXKIN_")))
    parts = (
        jax.__version__,
        jaxlib.__version__,
        jax.default_backend(),
        str(jax.devices()[0].device_kind),
        config,
        os.environ.get("XLA_FLAGS", ""),
        env,
        os.cpu_count(),
        len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else None,
    )
    return _source() + repr(parts).encode()


def fingerprint(value: Any) -> bytes:
    """Bytes that determine ``value`` for a traced program: equal values give equal bytes,
    and a value whose behaviour the bytes would not determine raises ``Unstorable``."""
    out: list[bytes] = []
    _walk(value, out, set())
    return b"".join(out)


def _named(obj: Any) -> str:
    """``module:qualname`` of a class or function whose code the key versions."""
    module = getattr(obj, "__module__", None) or ""
    qualname = getattr(obj, "__qualname__", None) or getattr(obj, "__name__", None)
    if not qualname or module.split(".")[0] not in _NAMED_MODULES:
        raise Unstorable(f"{module}.{qualname}")
    return f"{module}:{qualname}"


def _walk(value: Any, out: list[bytes], path: set[int]) -> None:
    if value is None or isinstance(value, (bool, int, float, complex, str, bytes)):
        out.append(f"{type(value).__name__}:{value!r};".encode())
        return
    if isinstance(value, (np.ndarray, np.generic, jax.Array)):
        if isinstance(value, jax.core.Tracer):
            raise Unstorable("tracer")
        array = np.asarray(value)
        if array.dtype == object:
            raise Unstorable("object array")
        out.append(f"array:{array.dtype.str}:{array.shape};".encode())
        out.append(np.ascontiguousarray(array).tobytes())
        return
    if isinstance(value, np.dtype):
        out.append(f"dtype:{value.str};".encode())
        return
    if isinstance(value, enum.Enum):
        out.append(f"enum:{_named(type(value))}:{value.name};".encode())
        return
    if isinstance(value, type):
        out.append(f"type:{_named(value)};".encode())
        return
    if hasattr(type(value), "__fingerprint__"):  # a jaxkin object that says what matters
        _named(type(value))  # (Unstorable unless the key versions its class)
        value = value.__fingerprint__()
    if id(value) in path:
        raise Unstorable("cycle")
    path.add(id(value))
    try:
        _walk_container(value, out, path)
    finally:
        path.discard(id(value))


def _walk_container(value: Any, out: list[bytes], path: set[int]) -> None:
    if isinstance(value, (tuple, list)):
        out.append(f"{type(value).__name__}:{len(value)}(".encode())
        if type(value) not in (tuple, list):  # a named tuple: its class matters
            out.append(_named(type(value)).encode())
        for item in value:
            _walk(item, out, path)
        out.append(b")")
    elif isinstance(value, dict):
        out.append(f"dict:{len(value)}(".encode())
        for k in sorted(value, key=repr):
            _walk(k, out, path)
            _walk(value[k], out, path)
        out.append(b")")
    elif isinstance(value, (set, frozenset)):
        items = sorted(fingerprint(item) for item in value)
        out.append(f"set:{len(items)}(".encode() + b"|".join(items) + b")")
    elif isinstance(value, functools.partial):
        out.append(b"partial(")
        for part in (value.func, value.args, value.keywords):
            _walk(part, out, path)
        out.append(b")")
    elif isinstance(value, types.MethodType):
        out.append(b"method(")
        _walk(value.__func__, out, path)
        _walk(value.__self__, out, path)
        out.append(b")")
    elif isinstance(value, types.FunctionType):
        _walk_function(value, out, path)
    elif isinstance(value, (types.BuiltinFunctionType, np.ufunc)):
        out.append(f"builtin:{_named(value)};".encode())
    elif hasattr(value, "__wrapped__") and callable(value):  # jax.jit and functools.wraps
        out.append(f"wrapped:{type(value).__name__}(".encode())
        _walk(value.__wrapped__, out, path)
        out.append(b")")
    elif dataclasses.is_dataclass(value):
        out.append(f"dataclass:{_named(type(value))}(".encode())
        for field in dataclasses.fields(value):
            out.append(f"{field.name}=".encode())
            _walk(getattr(value, field.name), out, path)
        out.append(b")")
    elif hasattr(value, "__dict__") or hasattr(type(value), "__slots__"):
        out.append(f"object:{_named(type(value))}(".encode())
        attributes = dict(getattr(value, "__dict__", {}))
        for name in _slots(type(value)):
            if hasattr(value, name):
                attributes[name] = getattr(value, name)
        for name in sorted(attributes):
            out.append(f"{name}=".encode())
            _walk(attributes[name], out, path)
        out.append(b")")
    else:
        raise Unstorable(type(value).__name__)


def _walk_function(fn: types.FunctionType, out: list[bytes], path: set[int]) -> None:
    out.append(f"function:{_named(fn)}(".encode())
    # its code too: two lambdas of one function share a qualified name
    out.append(_code_fingerprint(fn.__code__))
    cells = tuple(c.cell_contents for c in fn.__closure__ or ())
    for part in (cells, fn.__defaults__, fn.__kwdefaults__):
        _walk(part, out, path)
    out.append(b")")


def _code_fingerprint(code: types.CodeType) -> bytes:
    """A function's code by value: its first line, bytecode, names and constants (nested
    code likewise; a set of constants sorted, so the bytes do not depend on hashing)."""
    parts = [f"code:{code.co_firstlineno}:{code.co_names!r}:".encode(), code.co_code]
    for const in code.co_consts:
        if isinstance(const, types.CodeType):
            parts.append(_code_fingerprint(const))
        elif isinstance(const, frozenset):
            parts.append(repr(sorted(const, key=repr)).encode())
        else:
            parts.append(repr(const).encode())
    return b";".join(parts)


def _slots(cls: type) -> list[str]:
    names: list[str] = []
    for klass in cls.__mro__:
        slots = klass.__dict__.get("__slots__", ())
        names.extend([slots] if isinstance(slots, str) else slots)
    return [n for n in names if n not in ("__dict__", "__weakref__")]


def _tree_fingerprint(tree: Any) -> bytes:
    """The pytree structure with each node's type and static (auxiliary) data by value."""
    out: list[bytes] = []

    def walk(node: Any) -> None:
        if node.num_nodes == 1 and node.num_leaves == 1:
            out.append(b"*")
            return
        data = node.node_data()
        if data is None:
            out.append(b"*")
            return
        kind, aux = data
        out.append(f"node:{_named(kind)}(".encode())
        _walk(aux, out, set())
        for child in node.children():
            walk(child)
        out.append(b")")

    walk(tree)
    return b"".join(out)
