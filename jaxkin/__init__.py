"""jaxkin: batched, differentiable robot kinematics on JAX.

The robot protocol (``jaxkin.robot``): ``ik(robot, target, branch=None)`` and
``fk(robot, q)`` for every robot: ``scara.Scara``, ``delta.Delta``, the serial arms and chains
of ``serial``. Kernels: ``dyad`` (the RRR dyad), ``scara``, ``delta``, ``serial`` (DH, PoE,
analytic and Newton IK), ``newton`` (batched Newton-Raphson), ``planar`` (angle and distance
rates), ``lie`` (every rotation: SO(3)/SE(3), quaternions). Built on them: ``paths`` (paths
from samples or poses), ``plan`` (the planner backend), ``optimize`` (trajectory optimisation
with optax; its cost terms in ``costs``), ``workspace`` (voxel sweeps), ``fixedpoint``
(bit-width studies), ``plot`` (needs the ``plot`` extra; imported on demand).
``set_num_threads``: the host threads a large batch of
a loop-bound kernel is split across.
"""

import importlib
from typing import Any

# Submodules and names are imported on first use (PEP 562): ``import jaxkin`` stays cheap and
# the ``jaxkin`` command loads only what a subcommand needs (optax only for ``optimize``).
_SUBMODULES = frozenset(
    {"costs", "delta", "dyad", "fixedpoint", "lie", "newton", "optimize", "paths", "plan"}
    | {"planar", "robot", "scara", "serial", "workspace"}
)
_NAMES = {
    "num_threads": "_batching",
    "set_num_threads": "_batching",
    "enable_compilation_cache": "_execute",
    "enable_low_latency": "_execute",
    "compiled": "_execute",
    "Jet": "jet",
    "lift": "jet",
    "FKResult": "result",
    "IKResult": "result",
    "SolverResult": "result",
    "JointLimits": "robot",
    "Robot": "robot",
    "fk": "_execute",
    "ik": "_execute",
    "Status": "status",
    "describe": "status",
}


def __getattr__(name: str) -> Any:
    if name in _SUBMODULES:
        value = importlib.import_module(f"{__name__}.{name}")
    elif name in _NAMES:
        value = getattr(importlib.import_module(f"{__name__}.{_NAMES[name]}"), name)
    else:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))


__version__ = "0.1.0"

__all__ = [
    "FKResult",
    "IKResult",
    "Jet",
    "JointLimits",
    "Robot",
    "SolverResult",
    "Status",
    "__version__",
    "costs",
    "delta",
    "describe",
    "dyad",
    "enable_compilation_cache",
    "enable_low_latency",
    "compiled",
    "fixedpoint",
    "fk",
    "ik",
    "lie",
    "lift",
    "newton",
    "num_threads",
    "optimize",
    "paths",
    "plan",
    "planar",
    "robot",
    "scara",
    "serial",
    "set_num_threads",
    "workspace",
]
