"""``jaxkin.ik`` and ``jaxkin.fk``: the robots' pipeline, written once for every robot.

The input work is done here once (robot and branch checks, options, ``Jet`` conversion, the
target's shape against ``robot.target``, the work dtype, the batch shape broadcast with the
geometry's own, zero rates at rest) and the robot's kernel runs in one compiled program
(``Kernel``) per robot class, branch and rates, under the robot's compile policy
(``robot.ik_policy`` / ``robot.fk_policy``, a ``Policy``): small batches padded to a power of
two, large ones split across host threads, a concrete geometry compiled in as constants,
the branch passed as data, or every batch in blocks of one size (``Policy.bucket``). One
element (batch ``()`` or ``(1,)``, the single query of a planner between batches) goes
straight to the program compiled for its shape.

A robot object asked the same single query (kind, branch, options, input shape and dtype)
``HOT_AFTER`` times gets a compiled handle of its own (``handles.hot_handle``: the geometry
and options compiled in as constants, the outputs that do not depend on the input computed
once, no input work in Python), kept in a table of the ``HOT_PROGRAMS`` most recently built;
its results and statuses are the batched path's. ``jaxkin.compiled(jaxkin.ik, robot, ...)``
gives the same handle on request.
"""

from __future__ import annotations

import dataclasses
import functools
import math
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from jax import Array
from jax.typing import ArrayLike

from .. import _batching, _validate
from .._validate import is_concrete
from ..jet import Jet
from ..result import FKResult, IKResult
from .handles import Handle, HotQueries, batch_shape, builds, handle_dtype, shared_by_value
from .kernel import Kernel, Policy

__all__ = [
    "as_robot",
    "fk",
    "ik",
    "make_options",
    "solve_fk",
    "solve_ik",
]


def as_robot(robot: Any, name: str = "robot") -> Any:
    """``robot`` if it implements the robot protocol (a ``jaxkin.Robot``: its kernels, target
    and branches), else a ``ValueError`` naming the argument."""
    kind = type(robot)
    if not all(hasattr(kind, m) for m in ("ik_kernel", "fk_kernel", "target", "branches")):
        raise ValueError(
            f"{name} must be a jaxkin robot (scara.Scara, delta.Delta, a serial arm, "
            f"serial.Chain), got {kind.__name__}"
        )
    return robot


def make_options(cls: type, given: Any, values: dict[str, Any], name: str = "options") -> Any:
    """An instance of the options class ``cls``: ``given`` (an instance, or None for the
    defaults) with the keyword ``values`` replaced; a ``ValueError`` names unknown keys or an
    instance of another class."""
    if given is None:
        if not values:
            default = _DEFAULTS.get(cls)
            if default is None:
                default = _DEFAULTS[cls] = cls()
            return default
        given = cls()
    elif type(given) is not cls:
        raise ValueError(f"{name} must be a {cls.__qualname__} (or None), got {given!r}")
    if values:
        fields = {f.name for f in dataclasses.fields(cls)}
        unknown = sorted(set(values) - fields)
        if unknown:
            raise ValueError(
                f"unknown option(s) {unknown} for {cls.__qualname__}; expected some of "
                f"{sorted(fields)}"
            )
        given = dataclasses.replace(given, **values)
    return given


_DEFAULTS: dict[type, Any] = {}


# ------------------------------------------------------------------------------ inputs


def _float_dtype(dtypes: tuple, canonical: bool) -> Any:
    """The floating dtype inputs of ``dtypes`` are computed in (canonical for the x64 flag;
    ``canonical``: the inputs are JAX arrays, whose dtypes already are)."""
    if canonical and len(dtypes) == 1 and dtypes[0] in _FLOATS:
        return dtypes[0]
    key = (dtypes, jax.config.jax_enable_x64)  # type: ignore[attr-defined]  # jax's Config types no options
    found = _FLOAT_DTYPES.get(key)
    if found is None:
        canonical_dtypes = (jax.dtypes.canonicalize_dtype(d) for d in dtypes)
        found = _FLOAT_DTYPES[key] = jnp.result_type(*canonical_dtypes, float)
    return found


_FLOATS = (np.dtype(np.float32), np.dtype(np.float64))
_FLOAT_DTYPES: dict[Any, Any] = {}


def _inputs(robot: Any, x: Any, name: str, core: tuple[int, ...], target: bool = False):
    """``(p, v, a, rates, batch)``: the input's arrays in the work dtype (``v``, ``a`` None at
    rest; ``p`` of a ``target`` through ``robot.work_target``) and its batch shape broadcast
    with the geometry's; ``ValueError`` naming ``name``."""
    rates = isinstance(x, Jet)
    if rates:
        arrays = [_array(y, name) for y in (x.p, x.v, x.a)]
        shapes = {tuple(y.shape) for y in arrays}
        if len(shapes) != 1:
            raise ValueError(f"{name}: p, v and a must have one shape, got {sorted(shapes)}")
    else:
        arrays = [_array(x, name)]
    shape = arrays[0].shape
    k = len(core)
    if len(shape) < k or tuple(shape[len(shape) - k :]) != core:
        want = ", ".join(str(d) for d in core)
        raise ValueError(
            f"{name}: {type(robot).__name__} expects shape (..., {want}), got {tuple(shape)}"
        )
    canonical = all(type(y) in _JAX_TYPES for y in arrays)
    dtype = robot.work_dtype(_float_dtype(tuple(y.dtype for y in arrays), canonical))
    first = robot.work_target if target else _cast
    arrays = [
        y if y.dtype is dtype or y.dtype == dtype else (_cast if i else first)(y, dtype)
        for i, y in enumerate(arrays)
    ]
    batch = tuple(shape[: len(shape) - k])
    extra = robot.batch_shape()
    if extra:
        batch = _validate.batch_shape({name: batch, "robot": extra})
    p, v, a = arrays if rates else (arrays[0], None, None)
    return p, v, a, rates, batch


def _array(x: Any, name: str) -> Any:
    """``x`` as an array of real numbers with a shape and a dtype (JAX and NumPy arrays and
    tracers as they are; anything else through NumPy); ``ValueError`` naming ``name`` for
    anything else (complex numbers would lose their imaginary part)."""
    kind = type(x)
    if kind not in _ARRAY_TYPES:
        if isinstance(x, _ARRAYS):
            if isinstance(x, jax.Array) and not isinstance(x, jax.core.Tracer):
                _ARRAY_TYPES.add(kind)
                _JAX_TYPES.add(kind)
        elif not hasattr(x, "shape") or not hasattr(x, "dtype"):
            try:
                x = np.asarray(x)
            except (TypeError, ValueError):
                raise ValueError(f"{name}: expected an array of numbers, got {x!r}") from None
    if np.dtype(x.dtype).kind not in "biuf":
        raise ValueError(f"{name}: expected real numbers, got dtype {x.dtype}")
    return x


_ARRAYS = (jax.Array, np.ndarray)
_ARRAY_TYPES = {np.ndarray}  # concrete array types seen: checked before the slower isinstance
_JAX_TYPES: set[type] = set()  # concrete JAX array types seen


def _cast(x: Any, dtype: Any) -> Any:
    """``x`` in ``dtype``: on the host for NumPy input (no dispatch), else one JAX cast."""
    if isinstance(x, np.ndarray):
        return x.astype(dtype)
    return jnp.asarray(x).astype(dtype)


def _as_target(robot: Any, p: Array, v: Any, a: Any, core: int) -> Jet:
    """The kernel's input Jet, broadcast against the geometry's batch (zero rates at rest)."""
    extra = robot.batch_shape()
    if extra:
        shape = (*jnp.broadcast_shapes(p.shape[: p.ndim - core], extra), *p.shape[p.ndim - core :])
        p = jnp.broadcast_to(p, shape)
        v, a = (None if x is None else jnp.broadcast_to(x, shape) for x in (v, a))
    if v is None:
        zeros = jnp.zeros_like(p)
        return Jet(p, zeros, zeros)
    return Jet(p, v, a)


# ------------------------------------------------------------------------------ programs


def _ik_impl(branch: Any, rates: bool, robot: Any, p, v, a, index, options) -> IKResult:
    target = _as_target(robot, p, v, a, len(robot.target.shape))
    if index is not None:
        return robot.ik_kernel_indexed(target, index, options, rates)
    return robot.ik_kernel(target, branch, options, rates)


def _fk_impl(rates: bool, outside: bool, robot: Any, p, v, a, index, options) -> FKResult:
    result = robot.fk_kernel(_as_target(robot, p, v, a, 1), options, rates)
    if rates:
        return result
    # At rest the zero rates are written once: here, or by the caller for a large batch.
    x = Jet.positions(result.x.p) if outside else Jet.constant(result.x.p)
    return dataclasses.replace(result, x=x)


class _Program:
    """The compiled kernel of one robot class, branch and rates (the options are an argument:
    their static fields are part of its compilation key, the dynamic ones data), as the
    policy says, and the same with the geometry compiled in as constants when the policy says
    so (``Policy.constant_geometry``)."""

    def __init__(self, impl: Any, policy: Policy, core: int) -> None:
        self.policy = policy
        batched = {"p": core, "v": core, "a": core}
        self.dynamic = Kernel(impl, batched=batched, policy=policy)
        self.static = None
        if policy.constant_geometry:
            self.static = Kernel(impl, static=("robot",), batched=batched, policy=policy)

    def __call__(self, robot: Any, p, v, a, index, options, *, batch: tuple, pad: bool) -> Any:
        kernel = self.dynamic
        if self.static is not None:
            constant = _constant_geometry(robot)
            if constant is not None:
                robot, kernel = constant, self.static
        return kernel(robot, p, v, a, index, options, batch=batch, pad=pad)


def _constant_geometry(robot: Any) -> Any:
    """``robot`` with Python-float leaves when every leaf is a concrete scalar, else None."""
    leaves, tree = jax.tree.flatten(robot)
    if not all(is_concrete(leaf) and np.ndim(leaf) == 0 for leaf in leaves):
        return None
    return jax.tree.unflatten(tree, [float(leaf) for leaf in leaves])


_PROGRAMS: dict[tuple, _Program] = {}


def _program(kind: str, robot: Any, key: tuple, policy: Policy) -> _Program:
    """The cached ``_Program`` of ``kind`` (``"ik"``/``"fk"``) for the robot's class and the
    static ``key`` (branch, options, rates, ...)."""
    full = (kind, type(robot), *key)
    program = _PROGRAMS.get(full)
    if program is None:
        impl = _ik_impl if kind == "ik" else _fk_impl
        core = len(robot.target.shape) if kind == "ik" else 1
        program = _PROGRAMS[full] = _Program(functools.partial(impl, *key), policy, core)
    return program


def _run(program: _Program, robot: Any, p, v, a, index, options, batch: tuple) -> Any:
    """Apply the compile policy: one element straight to the kernel compiled for its shape
    (the single-query fast path), small batches padded, large ones as the policy says; with
    ``bucket``, every concrete batch (one element included) in the blocks of ``_bucketed``."""
    if program.policy.bucket and not robot.batch_shape():
        return _bucketed(program, robot, p, v, a, index, options, batch)
    pad = math.prod(batch) != 1 and not robot.batch_shape()
    return program(robot, p, v, a, index, options, batch=batch, pad=pad)


def _bucketed(program: _Program, robot: Any, p, v, a, index, options, batch: tuple) -> Any:
    """``Policy.bucket``: the batch in blocks of ``bucket`` rows (a small batch's rows
    spread among NaN rows, gathered back; a large one as overlapping blocks, joined), each
    through the one program of that block size (tracers run as they are)."""
    if not all(is_concrete(x) for x in jax.tree.leaves((robot, p, v, a, options))):
        return program(robot, p, v, a, index, options, batch=batch, pad=False)
    size = math.prod(batch)
    block: int = program.policy.bucket  # type: ignore[assignment]  # a bucketed policy's
    core = p.ndim - len(batch)

    def run(p, v, a) -> Any:
        return program(robot, p, v, a, index, options, batch=(block,), pad=False)

    if size <= block:
        p, v, a = (
            None if x is None else _batching.spread_rows(x, batch, core, block, np.nan)
            for x in (p, v, a)
        )
        result = run(p, v, a)
        # gathered on the host: a program per batch shape would compile anew for each size
        rows = _batching.spread_positions(size, block)
        return jax.tree.map(
            lambda x: jax.device_put(np.asarray(x)[rows].reshape((*batch, *x.shape[1:]))), result
        )
    given = [
        None if x is None else np.broadcast_to(np.asarray(x), (*batch, *p.shape[len(batch) :]))
        for x in (p, v, a)
    ]
    host_rows = [None if x is None else x.reshape(size, *x.shape[len(batch) :]) for x in given]
    count = -(-size // block)
    starts = [k * block for k in range(count - 1)] + [size - block]

    def part(start: int) -> Any:
        return run(*(None if x is None else x[start : start + block] for x in host_rows))

    parts = _batching.run_parts(part, starts)
    overlap = count * block - size

    def joined(*leaves: Any) -> Any:
        host = [np.asarray(x) for x in leaves]
        whole = np.concatenate([*host[:-1], host[-1][overlap:]], axis=0)
        return jax.device_put(whole.reshape((*batch, *whole.shape[1:])))

    return jax.tree.map(joined, *parts)


# ------------------------------------------------------------------ hot single queries

HOT = HotQueries()


def _hot_query(robot: Any, kind: str, branch: Any, options: Any, x: Any) -> Any:
    """The handle of ``robot``'s single query for this input's type, shape and dtype, once
    the same robot object has asked it ``hot.HOT_AFTER`` times; None for anything else (the
    pipeline then does its usual input work). ``options`` as the caller gave it: None (the
    defaults) or an instance; the robot, branch and options are checked when the handle is
    built, so a later call that finds it skips every check."""
    kx = type(x)
    if kx in _JAX_TYPES:  # its abstract value holds the shape and dtype (its properties: 3x)
        aval = x.aval
        shape, dtype = aval.shape, aval.dtype
    elif kx is np.ndarray:
        shape, dtype = x.shape, x.dtype
    else:
        return None  # a Jet, a tracer, a list: the usual path
    try:
        key = (id(robot), kind, branch, options, kx, shape, dtype, jax.config.jax_enable_x64)  # type: ignore[attr-defined]  # jax's Config types no options
        entry = HOT.programs.get(key)
    except TypeError:  # options or a branch that cannot be hashed: the usual path
        return None
    if entry is not None and entry[0] is robot:
        return entry[1]
    return HOT.get(key, robot, lambda: _single_query(robot, kind, branch, options, x))


def _single_query(robot: Any, kind: str, branch: Any, options: Any, x: Any) -> Handle | None:
    """The handle of one element's query, or None when it has none: a batch, a geometry
    with batch axes or traced leaves, bad arguments (the usual path says what is wrong), or
    the IK of a chain (an iterative search, dominated by its own iterations) or of an
    analytic arm (every branch in one program: a second compilation of a minute would cost
    more than it saves)."""
    try:
        robot = as_robot(robot)
    except ValueError:
        return None
    core = robot.target.shape if kind == "ik" else (robot.n_joints,)
    if np.shape(x) not in (core, (1, *core)) or robot.batch_shape():
        return None
    if kind == "ik" and (robot.ik_policy.bucket or robot.ik_policy.branch_as_data):
        return None  # a search, or every branch solved at once: compiles for tens of seconds
    if not all(is_concrete(leaf) for leaf in jax.tree.leaves(robot)):
        return None
    batch = tuple(np.shape(x)[: np.ndim(x) - len(core)])
    dtype = jax.dtypes.canonicalize_dtype(x.dtype)  # as a call of the handle takes it
    try:  # the arguments as the handle holds them: a robot of equal values shares it
        if kind == "ik":
            branch = robot.check_branch(branch)
            options = make_options(robot.IKOptions, options, {})
        else:
            options = make_options(robot.FKOptions, options, {})
    except ValueError:
        return None
    build = _ik_handle if kind == "ik" else _fk_handle
    args = (branch, options) if kind == "ik" else (options,)
    key = (kind, *args, batch, dtype)
    return shared_by_value(HOT, robot, key, lambda: build(robot, batch, *args, dtype))


def ik(
    robot: Any,
    target: Jet | ArrayLike,
    branch: Any = None,
    options: Any = None,
    **option_values: Any,
) -> IKResult:
    """Inverse kinematics of any robot for one branch.

    Args:
        robot: any ``Robot``.
        target: ``Jet`` (or plain array, at rest) of shape ``(..., *robot.target.shape)``.
        branch: one of ``robot.branches``; None for ``robot.default_branch``.
        options: an instance of ``robot.IKOptions`` (None: its defaults).
        **option_values: fields of ``robot.IKOptions`` replaced (e.g. ``method="autodiff"``).

    Returns:
        ``IKResult`` (or a subclass): ``q`` (Jet, ``(..., n_joints)``), ``status``, ``margin``.
        Work is done in the target's floating dtype (``robot.work_dtype``), the target cast to
        it by ``robot.work_target`` (a chain's float32 pose becomes a rotation in float64).

    Raises:
        ValueError: not a robot, an unknown branch or option, or a target of the wrong shape
            or a batch shape that does not broadcast with the geometry's.
    """
    if not option_values:  # a hot single query answers before any input work
        hot = _hot_query(robot, "ik", branch, options, target)
        if hot is not None:
            return hot(target)
        robot = as_robot(robot)
        return _solve_ik(robot, target, branch, make_options(robot.IKOptions, options, {}))
    robot = as_robot(robot)
    return solve_ik(robot, target, branch, make_options(robot.IKOptions, options, option_values))


def solve_ik(robot: Any, target: Any, branch: Any, options: Any, name: str = "target") -> Any:
    """``ik`` with ``options`` an ``IKOptions`` instance and the target named ``name`` in
    messages (a robot module's own function, e.g. ``scara.ik``, calls this)."""
    hot = _hot_query(robot, "ik", branch, options, target)
    if hot is not None:
        return hot(target)
    return _solve_ik(robot, target, branch, options, name)


def _solve_ik(robot: Any, target: Any, branch: Any, options: Any, name: str = "target") -> Any:
    """``solve_ik`` without the hot single query."""
    branch = robot.check_branch(branch)
    p, v, a, rates, batch = _inputs(robot, target, name, robot.target.shape, target=True)
    policy = robot.ik_policy
    if policy.branch_as_data:
        index = np.int32(robot.branches.index(branch))
        program = _program("ik", robot, (None, rates), policy)
    else:
        index = None
        program = _program("ik", robot, (branch, rates), policy)
    return _run(program, robot, p, v, a, index, options, batch)


def fk(robot: Any, q: Jet | ArrayLike, options: Any = None, **option_values: Any) -> FKResult:
    """Forward kinematics of any robot.

    Args:
        robot: any ``Robot``.
        q: ``Jet`` (or plain array, at rest) of joint coordinates, shape ``(..., n_joints)``.
        options: an instance of ``robot.FKOptions`` (None: its defaults).
        **option_values: fields of ``robot.FKOptions`` replaced (e.g. ``tol`` for the Delta's
            Newton FK).

    Returns:
        ``FKResult`` (or a subclass): ``x`` (Jet in the form of the robot's targets) and
        ``status``.

    Raises:
        ValueError: not a robot, an unknown option, or ``q`` of the wrong shape.
    """
    if not option_values:  # a hot single query answers before any input work
        hot = _hot_query(robot, "fk", None, options, q)
        if hot is not None:
            return hot(q)
        robot = as_robot(robot)
        return _solve_fk(robot, q, make_options(robot.FKOptions, options, {}))
    robot = as_robot(robot)
    return solve_fk(robot, q, make_options(robot.FKOptions, options, option_values))


def solve_fk(robot: Any, q: Any, options: Any, name: str = "q") -> Any:
    """``fk`` with ``options`` an ``FKOptions`` instance and ``q`` named ``name``."""
    hot = _hot_query(robot, "fk", None, options, q)
    if hot is not None:
        return hot(q)
    return _solve_fk(robot, q, options, name)


def _solve_fk(robot: Any, q: Any, options: Any, name: str = "q") -> Any:
    """``solve_fk`` without the hot single query."""
    p, v, a, rates, batch = _inputs(robot, q, name, (robot.n_joints,))
    outside = _batching.zero_rates_outside(rates, batch)
    program = _program("fk", robot, (rates, outside), robot.fk_policy)
    result = _run(program, robot, p, v, a, None, options, batch)
    return dataclasses.replace(result, x=Jet.constant(result.x.p)) if outside else result


# ------------------------------------------------------------------ compiled handles


@builds(ik)
def _ik_handle(
    robot: Any,
    batch: Any = (),
    branch: Any = None,
    options: Any = None,
    dtype: Any = None,
    rates: bool = False,
    **option_values: Any,
) -> Handle:
    """``compiled(jaxkin.ik, robot, batch=(), branch=None, options=None, dtype=None,
    rates=False, **option_values)``: ``handle(target)`` for targets of shape ``(*batch,
    *robot.target.shape)`` in ``dtype`` (a ``Jet`` with ``rates``), the geometry, branch and
    options compiled in; the results of ``jaxkin.ik`` on the same input."""
    robot = as_robot(robot)
    branch = robot.check_branch(branch)
    options = make_options(robot.IKOptions, options, option_values)
    example = _example(robot, batch, robot.target.shape, dtype, rates, "target")
    xla = robot.ik_policy.compiler_options
    return Handle(lambda x: _solve_ik(robot, x, branch, options), (example,), compiler_options=xla)


@builds(fk)
def _fk_handle(
    robot: Any,
    batch: Any = (),
    options: Any = None,
    dtype: Any = None,
    rates: bool = False,
    **option_values: Any,
) -> Handle:
    """``compiled(jaxkin.fk, robot, batch=(), options=None, dtype=None, rates=False,
    **option_values)``: ``handle(q)`` for joints of shape ``(*batch, robot.n_joints)``."""
    robot = as_robot(robot)
    options = make_options(robot.FKOptions, options, option_values)
    example = _example(robot, batch, (robot.n_joints,), dtype, rates, "q")
    xla = robot.fk_policy.compiler_options
    return Handle(lambda q: _solve_fk(robot, q, options), (example,), compiler_options=xla)


def _example(robot: Any, batch: Any, core: tuple, dtype: Any, rates: bool, name: str) -> Any:
    """Zeros of shape ``(*batch, *core)`` in ``dtype`` (a ``Jet`` with ``rates``): the input
    a handle is compiled for; ``ValueError`` naming ``batch`` or ``dtype``."""
    batch = batch_shape(batch)
    zeros = np.zeros((*batch, *core), handle_dtype(dtype))
    return Jet(zeros, zeros, zeros) if rates else zeros  # type: ignore[arg-type]  # host data
