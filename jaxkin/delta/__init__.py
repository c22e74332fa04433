"""The Delta parallel robot [Cardona]: closed-form IK, Newton and closed-form FK, rates,
singularities and workspace.

* ``Delta`` (``jaxkin.delta.geometry``): the geometry and its frame (origin at the fixed
  platform's centre, z up, platform below; ``theta_i`` positive downward).
* ``ik`` (``jaxkin.delta.inverse``): actuator angles for platform positions, elbow-out (``"out"``,
  default) or elbow-in (``"in"``) [Cardona, eqs. 1-7].
* ``fk`` (Newton-Raphson, batched, per-element convergence, warm starts) and
  ``fk_closed_form`` (three-sphere intersection, both assemblies), ``which_branch``
  (``jaxkin.delta.forward``) [Cardona, eqs. 8-16].
* Rates: analytic from the constraint Jacobians (``method="analytic"``) or by ``jaxkin.lift``
  (``"autodiff"``); ``singularity`` gives the inverse- and direct-type measures
  (``jaxkin.delta.rates``).
* ``workspace``: a voxel sweep (``jaxkin.workspace.sweep``) over the box of [Cardona, sec. V].

Statuses are listed in each module; the conventions, the corrections of printed equations and
float32 accuracy are in ``docs/conventions.md``, ``docs/errata.md`` and
``docs/performance.md``.
"""

from typing import Any

from .. import workspace as _workspace
from .forward import LOWER as LOWER
from .forward import UPPER as UPPER
from .forward import ClosedFormFKResult as ClosedFormFKResult
from .forward import NewtonFKResult as NewtonFKResult
from .forward import fk as fk
from .forward import fk_closed_form as fk_closed_form
from .forward import which_branch as which_branch
from .geometry import BRANCHES as BRANCHES
from .geometry import METHODS as METHODS
from .geometry import Delta as Delta
from .geometry import check_robot as _check_robot
from .inverse import ik as ik
from .rates import SingularityResult as SingularityResult
from .rates import singularity as singularity

__all__ = [
    "BRANCHES",
    "LOWER",
    "METHODS",
    "UPPER",
    "ClosedFormFKResult",
    "Delta",
    "NewtonFKResult",
    "SingularityResult",
    "fk",
    "fk_closed_form",
    "ik",
    "singularity",
    "which_branch",
    "workspace",
]


def workspace(robot: Delta, bounds: Any = None, resolution: float | None = None, **options: Any):
    """Voxel sweep of the reachable workspace (``jaxkin.workspace.sweep``; default box
    ``Delta.workspace_box``: for the paper's robot 101 x 101 x 91 voxels of 1 cm). A voxel is
    reachable where ``ik`` gives ``OK`` or ``SINGULAR`` (the boundary itself is singular)."""
    return _workspace.sweep(_check_robot(robot), bounds, resolution, **options)
