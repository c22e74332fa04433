"""Serial arms: DH and product-of-exponentials kinematics, analytic and numerical IK.

Every arm and chain here is a robot of the protocol (``jaxkin.ik`` / ``jaxkin.fk``).

* ``DHTable``, ``fk_dh``: standard Denavit-Hartenberg forward kinematics
  [Lopez-Villagomez, eq. 2].
* ``PoEChain``, ``fk_poe``, ``chain_fk``, ``fk_chain``, ``space_jacobian``, ``body_jacobian``,
  ``poe_from_dh``, ``change_frame``: product of exponentials [Pineiro] (rotations:
  ``jaxkin.lie``).
* ``JointChain``: a chain with named, typed, limited joints and mimic couplings;
  ``from_urdf``: the chain from a base link to a tip link of a URDF (the ``urdf`` extra).
* ``ik_newton``: Newton-Raphson IK with body/space twists [Pineiro], per-element convergence
  from given seeds; ``ik_chain``: the protocol's IK of a chain (restarts, rates, margin).
* The analytic arms ``Planar2R``, ``Planar3R``, ``Anthropomorphic``, ``Cylindrical``,
  ``Spherical``, ``Puma560``, ``Stanford``: ``ik`` (every branch at once), ``ik_jet`` (one
  branch with rates and a margin) and ``fk`` (in the form of the targets).
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
from .arms import ik as ik
from .arms import ik_jet as ik_jet
from .chain import JointChain as JointChain
from .dh import DHTable as DHTable
from .dh import dh_transform as dh_transform
from .dh import fk_dh as fk_dh
from .newton_ik import NewtonIKResult as NewtonIKResult
from .newton_ik import ik_chain as ik_chain
from .newton_ik import ik_newton as ik_newton
from .poe import PoEChain as PoEChain
from .poe import body_jacobian as body_jacobian
from .poe import chain_fk as chain_fk
from .poe import change_frame as change_frame
from .poe import fk_chain as fk_chain
from .poe import fk_poe as fk_poe
from .poe import poe_from_dh as poe_from_dh
from .poe import space_jacobian as space_jacobian
from .urdf import from_urdf as from_urdf

__all__ = [
    "ARMS",
    "Anthropomorphic",
    "ArmIKResult",
    "Cylindrical",
    "DHTable",
    "JointChain",
    "NewtonIKResult",
    "Planar2R",
    "Planar3R",
    "PoEChain",
    "Puma560",
    "Spherical",
    "Stanford",
    "body_jacobian",
    "chain_fk",
    "change_frame",
    "dh_transform",
    "fk",
    "fk_chain",
    "fk_dh",
    "fk_poe",
    "from_urdf",
    "ik",
    "ik_chain",
    "ik_jet",
    "ik_newton",
    "poe_from_dh",
    "space_jacobian",
]
