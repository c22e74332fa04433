"""Analytic inverse kinematics of the textbook arms, every branch at once, and their FK.

=========================  ====================  ==============  ========  ========
arm                        module                target          branches  joints
=========================  ====================  ==============  ========  ========
``Planar2R(l1, l2)``       ``planar``            ``(x, y)``      2         RR
``Planar3R(l1, l2, l3)``   ``planar``            ``(x, y, phi)`` 2         RRR
``Anthropomorphic``        ``three_joint``       point           4         RRR
``Cylindrical(h)``         ``three_joint``       point           1         RPP
``Spherical(h)``           ``three_joint``       point           2         RRP
``Puma560(...)``           ``six_joint``         4x4 pose        8         6R
``Stanford(d1, a2)``       ``six_joint``         4x4 pose        4         RRPRRR
=========================  ====================  ==============  ========  ========

``jaxkin.ik(arm, target, branch)``: one branch with joint rates (``jaxkin.lift`` of the
position IK; a pose target is a Jet of 4x4 matrices) and a margin; ``ik_jet`` is the same.
``ik_all_branches(arm, target)``: every branch, ``ArmIKResult`` with ``q``
``(..., n_branches, n_joints)``, ``valid`` and ``status`` ``(..., n_branches)``;
``result.branch("front_up")`` selects one. ``jaxkin.fk(arm, q)`` (or ``fk``): an ``FKResult``
whose ``x`` is in the form of the targets (the 4x4 transform of the last DH frame:
``jaxkin.fk(serial.from_dh(arm.dh_table()), q).x.p``). Statuses and the margin:
``jaxkin.serial.arms.kernels``; accuracy in float64 and float32: ``docs/performance.md``;
formulas: ``docs/robots.md``.

Layers, bottom to top: ``_kit`` (two-link, wrist, polar, angle wrapping), ``kernels`` (the
shared IK/FK kernels, which read an arm through its methods), ``base`` (the ``Arm`` class and
the entry points), then the arms (``planar``, ``three_joint``, ``six_joint``).
"""

from .base import Arm as Arm
from .base import fk as fk
from .base import ik_all_branches as ik_all_branches
from .base import ik_jet as ik_jet
from .kernels import ArmIKResult as ArmIKResult
from .planar import Planar2R as Planar2R
from .planar import Planar3R as Planar3R
from .six_joint import Puma560 as Puma560
from .six_joint import Stanford as Stanford
from .three_joint import Anthropomorphic as Anthropomorphic
from .three_joint import Cylindrical as Cylindrical
from .three_joint import Spherical as Spherical

__all__ = [
    "ARMS",
    "Anthropomorphic",
    "Arm",
    "ArmIKResult",
    "Cylindrical",
    "Planar2R",
    "Planar3R",
    "Puma560",
    "Spherical",
    "Stanford",
    "fk",
    "ik_all_branches",
    "ik_jet",
]

ARMS: tuple[type[Arm], ...] = (
    Planar2R,
    Planar3R,
    Anthropomorphic,
    Cylindrical,
    Spherical,
    Puma560,
    Stanford,
)
