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

from . import costs as costs
from . import delta as delta
from . import dyad as dyad
from . import fixedpoint as fixedpoint
from . import lie as lie
from . import newton as newton
from . import optimize as optimize
from . import paths as paths
from . import plan as plan
from . import planar as planar
from . import robot as robot
from . import scara as scara
from . import serial as serial
from . import workspace as workspace
from ._batching import num_threads as num_threads
from ._batching import set_num_threads as set_num_threads
from ._compile_cache import enable_compilation_cache as enable_compilation_cache
from .jet import Jet as Jet
from .jet import lift as lift
from .result import FKResult as FKResult
from .result import IKResult as IKResult
from .result import SolverResult as SolverResult
from .robot import JointLimits as JointLimits
from .robot import Robot as Robot
from .robot import fk as fk
from .robot import ik as ik
from .status import Status as Status
from .status import describe as describe

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
