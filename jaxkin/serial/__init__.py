"""Serial arms: one chain robot with its builders and solvers, and the analytic arms.

Every arm and chain here is a robot of the protocol (``jaxkin.ik`` / ``jaxkin.fk``).

* ``Chain``: THE serial-chain robot (named, typed, limited joints, mimic couplings; pose
  targets). Its forward kinematics is ``jaxkin.fk(chain, q)`` (``.x.p``: the tip's 4x4
  transform), its IK ``jaxkin.ik(chain, pose)`` (the search of ``serial.search``).
* Builders: ``from_dh`` (a ``DHTable``: standard Denavit-Hartenberg [Lopez-Villagomez, eq. 2];
  ``dh_transform``, one link's transform), ``from_screws`` (product of exponentials, space or
  body frame [Pineiro]) and ``from_urdf`` (the chain from a base link to a tip link of a URDF,
  the ``urdf`` extra); ``example_robot(name)``: the URDF, SRDF and tool link of an arm of
  example-robot-data (the ``robots`` extra), ``.chain()`` the arm as a chain.
* ``space_jacobian``, ``body_jacobian``: the Jacobians of a chain; ``ik_newton``: the textbook
  Newton-Raphson IK [Pineiro] from given starts.
* The analytic arms ``Planar2R``, ``Planar3R``, ``Anthropomorphic``, ``Cylindrical``,
  ``Spherical``, ``Puma560``, ``Stanford`` (``jaxkin.serial.arms``): ``ik_all_branches``
  (every branch at once), ``ik_jet`` (one branch with rates and a margin, as ``jaxkin.ik``)
  and ``fk`` (in the form of the targets); an arm's ``dh_table()`` gives its chain with
  ``from_dh``.
"""

from .arms import ARMS as ARMS
from .arms import Anthropomorphic as Anthropomorphic
from .arms import ArmIKResult as ArmIKResult
from .arms import Cylindrical as Cylindrical
from .arms import Planar2R as Planar2R
from .arms import Planar3R as Planar3R
from .arms import Puma560 as Puma560
from .arms import Spherical as Spherical
from .arms import Stanford as Stanford
from .arms import fk as fk
from .arms import ik_all_branches as ik_all_branches
from .arms import ik_jet as ik_jet
from .chain import Chain as Chain
from .chain import body_jacobian as body_jacobian
from .chain import space_jacobian as space_jacobian
from .dh import DHTable as DHTable
from .dh import dh_transform as dh_transform
from .dh import from_dh as from_dh
from .example_robots import ExampleRobot as ExampleRobot
from .example_robots import example_robot as example_robot
from .newton import NewtonIKResult as NewtonIKResult
from .newton import ik_newton as ik_newton
from .poe import from_screws as from_screws
from .urdf import from_urdf as from_urdf

__all__ = [
    "ARMS",
    "Anthropomorphic",
    "ArmIKResult",
    "Chain",
    "Cylindrical",
    "DHTable",
    "ExampleRobot",
    "NewtonIKResult",
    "Planar2R",
    "Planar3R",
    "Puma560",
    "Spherical",
    "Stanford",
    "body_jacobian",
    "dh_transform",
    "example_robot",
    "fk",
    "from_dh",
    "from_screws",
    "from_urdf",
    "ik_all_branches",
    "ik_jet",
    "ik_newton",
    "space_jacobian",
]
