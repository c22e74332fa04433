"""JAX's CPU runtime set for a planner's loop, switched on by one call (never on import).

A planner asks one state or one edge at a time, and there the cost of a call is not the
arithmetic but how JAX's CPU runtime runs a small program (measured in
``docs/performance.md``, "The execution layer"):

- **dispatch**: by default JAX hands each call to another thread and the caller waits for it
  (asynchronous dispatch), a thread wake-up of tens of microseconds per call;
- **the thunk executor**: XLA runs a program of more than 8 operations over buffers larger
  than 512 bytes on its thread pool, one hand-off per operation and per step of each loop;
  a loop whose body accesses fewer than ``xla_cpu_small_while_loop_byte_threshold`` bytes
  (1 KiB by default) is compiled instead as one function run in place.

``enable_low_latency()`` sets JAX's ``jax_cpu_enable_async_dispatch`` to False (the calling
thread runs the program) and raises XLA's small-loop threshold to ``SMALL_LOOP_BYTES``; a
compiled handle (``handles.Handle``) then runs its whole program as one such loop of one
trip, so a single query is one compiled function. Both options are read once, when JAX
starts its CPU backend: the call takes effect only before the process's first JAX
computation. Like the compilation cache it changes JAX's configuration for the whole
process, so the library never calls it on its own: an application opts in, and the
``jaxkin`` command and the examples do (``JAXKIN_LOW_LATENCY=0`` turns it off there).

The threshold is set high enough that the loops of jaxkin's programs, batched ones included
(the motion planner's search), run as one function each; measured, batched rates were the
same or higher (``docs/performance.md``). Results are the same either way: the same program,
compiled by XLA's other loop emitter. A loop that holds a sort, a library call (LAPACK) or a
library fusion (YNNPACK) stays as it was, so the programs meant to run as one avoid them.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from typing import Any

import jax
import jax.numpy as jnp

__all__ = ["SMALL_LOOP_BYTES", "enable_for_command", "enable_low_latency", "in_one_loop"]

THRESHOLD_OPTION = "xla_cpu_small_while_loop_byte_threshold"
# Bytes a loop body may access to run as one function: above every loop of jaxkin's programs
# (the motion planner's search loop needed more than 10 MB to gain)
SMALL_LOOP_BYTES = 100_000_000
ENV_VAR = "JAXKIN_LOW_LATENCY"
_OFF = ("0", "off", "false", "no")


def enable_low_latency() -> None:
    """Run small programs in the calling thread, each as one compiled function (module
    docstring): for a planner's loop of single queries through compiled handles.

    Call it before the process's first JAX computation (JAX reads both options when it starts
    its CPU backend; later, the call changes nothing). XLA options the environment already
    gives in ``XLA_FLAGS`` (``--xla_backend_extra_options``) are kept as they are.
    """
    jax.config.update("jax_cpu_enable_async_dispatch", False)
    flags = os.environ.get("XLA_FLAGS", "")
    if "xla_backend_extra_options" not in flags:
        option = f"--xla_backend_extra_options={THRESHOLD_OPTION}={SMALL_LOOP_BYTES}"
        os.environ["XLA_FLAGS"] = f"{flags} {option}".strip()


def enable_for_command() -> bool:
    """The ``jaxkin`` command's and the examples' default: ``enable_low_latency()`` unless
    ``JAXKIN_LOW_LATENCY`` is ``0``, ``off``, ``false`` or ``no``. Returns whether it ran."""
    if os.environ.get(ENV_VAR, "").strip().lower() in _OFF:
        return False
    enable_low_latency()
    return True


def small_loops_in_one_function() -> bool:
    """Whether XLA's small-loop threshold was raised (by ``enable_low_latency`` or by hand)."""
    return THRESHOLD_OPTION in os.environ.get("XLA_FLAGS", "")


def in_one_loop(fn: Callable[..., Any]) -> Callable[..., Any]:
    """``fn`` as the body of a loop of one trip, which XLA compiles as one function when its
    body is small (``enable_low_latency``); ``fn`` itself when the threshold was not raised
    (the loop would only add a step), or when no argument is floating.

    The trip count is ``1 + isnan(x)`` of the first floating argument's first element, a
    value XLA cannot fold (it would remove a loop it knows runs once), and a second trip
    computes the same outputs again. Every argument enters the body through a select on the
    loop counter, so that XLA cannot move work that depends only on the arguments out of
    the loop (where it would run as separate operations again).
    """
    if not small_loops_in_one_function():
        return fn

    def run(*args: Any) -> Any:
        leaves = jax.tree.leaves(args)
        floating = [x for x in leaves if jnp.issubdtype(jnp.result_type(x), jnp.floating)]
        first = next((x for x in floating if jnp.size(x)), None)
        if first is None:
            return fn(*args)
        trips = 1 + jnp.isnan(jnp.ravel(first)[0]).astype(jnp.int32)
        shapes = jax.eval_shape(fn, *args)
        init = jax.tree.map(lambda s: jnp.zeros(s.shape, s.dtype), shapes)

        def body(state: tuple[Any, Any]) -> tuple[Any, Any]:
            trip, _ = state
            # a select on the counter: no argument is loop-invariant to XLA
            inside = jax.tree.map(lambda x: jnp.where(trip < 2, x, jnp.zeros_like(x)), args)
            return trip + 1, fn(*inside)

        return jax.lax.while_loop(lambda s: s[0] < trips, body, (jnp.int32(0), init))[1]

    return run
