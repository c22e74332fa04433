"""jaxkin: batched, differentiable robot kinematics on JAX.

Modules: ``dyad`` (RRR dyad / Assur group), ``scara``, ``delta``, ``serial`` (DH, PoE, analytic
and Newton IK), ``plan`` (planner backend), ``optimize`` (optax trajectory optimisation),
``workspace`` (voxel sweeps), ``newton`` (batched Newton-Raphson), ``planar`` (angle and
distance rates), ``fixedpoint`` (bit-width studies), ``splines``, ``io``, ``plot`` (needs the
``plot`` extra; imported on demand). ``set_num_threads``/``num_threads``: the host threads a
large batch of a loop-bound kernel (the Delta Newton FK) is split across (``jaxkin._threads``).
"""

from . import delta as delta
from . import dyad as dyad
from . import fixedpoint as fixedpoint
from . import newton as newton
from . import optimize as optimize
from . import plan as plan
from . import planar as planar
from . import scara as scara
from . import serial as serial
from . import splines as splines
from . import workspace as workspace
from ._threads import num_threads as num_threads
from ._threads import set_num_threads as set_num_threads
from .jet import Jet as Jet
from .jet import lift as lift
from .result import SolverResult as SolverResult
from .status import Status as Status
from .status import describe as describe

__version__ = "0.1.0"

__all__ = [
    "Jet",
    "SolverResult",
    "Status",
    "__version__",
    "delta",
    "describe",
    "dyad",
    "fixedpoint",
    "lift",
    "newton",
    "num_threads",
    "optimize",
    "plan",
    "planar",
    "scara",
    "serial",
    "set_num_threads",
    "splines",
    "workspace",
]
