"""jaxkin: batched, differentiable robot kinematics on JAX."""

from . import dyad as dyad
from . import planar as planar
from .jet import Jet as Jet
from .jet import lift as lift
from .result import SolverResult as SolverResult
from .status import Status as Status
from .status import describe as describe

__version__ = "0.1.0"

__all__ = ["Jet", "SolverResult", "Status", "describe", "dyad", "lift", "planar", "__version__"]
