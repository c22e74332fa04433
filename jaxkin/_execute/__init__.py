"""The execution layer: how every public entry point of jaxkin is compiled and run.

One place to read (this package), one concept per module:

- ``kernel``: ``Kernel``, a pure function compiled by ``jax.jit`` once per shapes and static
  arguments and run under a ``Policy`` (small batches padded to a power of two, large ones
  split across host threads, XLA options of its own), its concrete calls through ``store``.
- ``candidates``: the planner's N candidates in chunks, on the host threads or over the
  devices and processes (``jax.distributed``).
- ``pipeline``: ``jaxkin.ik`` / ``jaxkin.fk``, the robots' boundary written once (robot and
  branch checks, options, ``Jet`` conversion, dtype, batch shape), a program per robot class
  under the robot's policy, and hot single queries.
- ``handles``: ``compiled(entry, ...)``, a program compiled for one robot, world layout and
  batch shape, called with no Python work beyond the array hand-off (a planner's loop).
- ``cache``: JAX's persistent compilation cache, switched on by one call.
- ``store``: kernels kept as ``jax.export`` serialisations beside that cache, which later
  processes call without tracing them.
- ``latency``: JAX's CPU runtime set for a planner's loop of single queries (inline dispatch,
  small loops as one function), switched on by one call.

Every public entry point (``jaxkin.ik``/``fk``, ``plan.evaluate``, ``plan.retime``,
``timing.retime``, ``collision.check``/``collides``/``validate_motions``,
``optimize.optimize``, ``workspace.sweep``) checks its arguments at its own boundary, then
runs ``Kernel``s of this package.
"""

from .cache import default_cache_dir as default_cache_dir
from .cache import enable_compilation_cache as enable_compilation_cache
from .candidates import map_candidates as map_candidates
from .handles import Handle as Handle
from .handles import batch_shape as batch_shape
from .handles import builds as builds
from .handles import compiled as compiled
from .handles import handle_dtype as handle_dtype
from .kernel import WHOLE as WHOLE
from .kernel import Kernel as Kernel
from .kernel import Policy as Policy
from .kernel import kernel as kernel
from .latency import enable_low_latency as enable_low_latency
from .pipeline import as_robot as as_robot
from .pipeline import fk as fk
from .pipeline import ik as ik
from .pipeline import make_options as make_options
from .pipeline import solve_fk as solve_fk
from .pipeline import solve_ik as solve_ik

__all__ = [
    "WHOLE",
    "Handle",
    "Kernel",
    "Policy",
    "as_robot",
    "batch_shape",
    "builds",
    "compiled",
    "default_cache_dir",
    "enable_compilation_cache",
    "enable_low_latency",
    "fk",
    "handle_dtype",
    "ik",
    "kernel",
    "make_options",
    "map_candidates",
    "solve_fk",
    "solve_ik",
]
