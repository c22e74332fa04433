"""The Delta parallel robot [Cardona]: closed-form IK, Newton and closed-form FK, rates,
singularities and workspace.

* ``Delta`` (``jaxkin.delta.robot``): the geometry and the robot; its frame
  (``jaxkin.delta._math``: origin at the fixed platform's centre, z up, platform below;
  ``theta_i`` positive downward).
* ``ik`` (kernel in ``jaxkin.delta.inverse``): actuator angles for platform positions,
  elbow-out (``"out"``, default) or elbow-in (``"in"``) [Cardona, eqs. 1-7].
* ``fk`` (Newton-Raphson, batched, per-element convergence, warm starts) and
  ``fk_closed_form`` (three-sphere intersection, both assemblies), ``which_branch``
  (kernels in ``jaxkin.delta.forward``) [Cardona, eqs. 8-16].
* Rates: analytic from the constraint Jacobians (``method="analytic"``) or by ``jaxkin.lift``
  (``"autodiff"``); ``singularity`` gives the inverse- and direct-type measures
  (``jaxkin.delta.jacobians``).
* ``Delta.workspace_box``: the box of [Cardona, sec. V] that ``jaxkin.workspace.sweep`` sweeps.

Layers, bottom to top: ``_math`` (the kit), ``jacobians``, ``inverse``, ``forward``, ``robot``
(the ``Delta`` class and the entry points above); no module imports one above it.

Statuses are listed in each module; the conventions, the corrections of printed equations and
float32 accuracy are in ``docs/conventions.md``, ``docs/errata.md`` and
``docs/performance.md``.
"""

from ._math import BRANCHES as BRANCHES
from ._math import METHODS as METHODS
from .forward import LOWER as LOWER
from .forward import UPPER as UPPER
from .forward import ClosedFormFKResult as ClosedFormFKResult
from .forward import NewtonFKResult as NewtonFKResult
from .jacobians import SingularityResult as SingularityResult
from .robot import Delta as Delta
from .robot import fk as fk
from .robot import fk_closed_form as fk_closed_form
from .robot import ik as ik
from .robot import singularity as singularity
from .robot import which_branch as which_branch

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
]
