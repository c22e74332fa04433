"""Collision geometry: primitives, exact signed distances, the world, robot bodies as data.

- ``primitives``: ``Spheres``, ``Capsules``, ``Boxes`` (oriented), ``Cylinders``,
  ``HalfSpaces`` as array pytrees; ``point_cloud_spheres`` (voxel down-sampling).
- ``distance``: closed-form signed distances of every robot/world pair (negative in
  penetration, finite gradients everywhere).
- ``world``: ``World`` and ``nearest_obstacles`` (per robot primitive, the smallest signed
  distance over the world and which obstacle).
- ``body``: ``Body``, spheres and capsules attached to links; ``Body.place(link_poses)``.
- ``urdf``: ``read_collision`` (a URDF's ``<collision>`` elements and mesh files, read once)
  and ``body_from_urdf`` (their covers as a ``Body``; spherised URDFs as their spheres).
- ``cover``: conservative sphere covers of meshes and boxes with an overshoot bound; the
  former sphere-and-capsule covers; capsule covers of boxes.
- ``triangles``: host-side triangle geometry (subdivision, exact distances, parts, pairs).
- ``body_files``: bodies as other planners' files: cuRobo's sphere lists
  (``read_sphere_lists``), spherised URDFs (``spherized_urdf``; read by ``body_from_urdf``).
- ``scene``: world files (JSON, YAML): ``read_world``, ``write_world``.
- ``moveit``: MoveIt planning scenes (YAML) as a ``World``: ``read_moveit_scene``; a motion
  plan request's start and goals: ``read_moveit_request``.
- ``pairs``: self-collision link pairs (adjacency, SRDF ``disable_collisions``),
  ``self_distances``, ``propose_disabled``.
- ``check``: ``check(robot, q, world)``, a robot's configurations against the world and
  itself (clearance, collision flag, which pair), batched.
- ``motions``: ``validate_motions(robot, q_from, q_to, world, resolution)``, M joint-space
  edges in one compiled call.
- ``protocol``: ``CollisionRobot``, what the checks ask of a robot (a ``typing.Protocol``).
- ``surfaces``: triangle meshes of the primitives, a body's and a world's, for drawing
  (``jaxkin.plot.robot_scene``, ``jaxkin.viewer``).
- ``fused``: the fused per-configuration check, robot-world and self pairs in one pass
  (``clearance``: the smallest distance and its pair; ``min_clearance``: the distance alone).
- ``verdict``: ``collides(robot, q, world)``, the collision flag alone; ``culled``, its path
  for a body of many spheres (the coarse level's groups first, the spheres where a group's
  bound comes close).
"""

from . import distance as distance
from . import surfaces as surfaces
from .body import Body as Body
from .body_files import read_sphere_lists as read_sphere_lists
from .body_files import spherized_urdf as spherized_urdf
from .check import ROBOT_WORLD as ROBOT_WORLD
from .check import SELF as SELF
from .check import CheckResult as CheckResult
from .check import check as check
from .check import check_kernel as check_kernel
from .check import clearances_kernel as clearances_kernel
from .check import prepare as prepare
from .cover import MeshCover as MeshCover
from .cover import SphereCover as SphereCover
from .cover import box_capsules as box_capsules
from .cover import box_sphere_cover as box_sphere_cover
from .cover import mesh_cover as mesh_cover
from .cover import mesh_sphere_cover as mesh_sphere_cover
from .fused import Clearance as Clearance
from .fused import clearance as clearance
from .fused import min_clearance as min_clearance
from .motions import MotionResult as MotionResult
from .motions import validate_motions as validate_motions
from .motions import validate_motions_kernel as validate_motions_kernel
from .moveit import MoveItRequest as MoveItRequest
from .moveit import read_moveit_request as read_moveit_request
from .moveit import read_moveit_scene as read_moveit_scene
from .pairs import SelfPairs as SelfPairs
from .pairs import adjacent_links as adjacent_links
from .pairs import propose_disabled as propose_disabled
from .pairs import read_srdf_disabled as read_srdf_disabled
from .pairs import self_collision_link_pairs as self_collision_link_pairs
from .pairs import self_distances as self_distances
from .primitives import Boxes as Boxes
from .primitives import Capsules as Capsules
from .primitives import Cylinders as Cylinders
from .primitives import HalfSpaces as HalfSpaces
from .primitives import Spheres as Spheres
from .primitives import point_cloud_spheres as point_cloud_spheres
from .protocol import CollisionRobot as CollisionRobot
from .scene import read_world as read_world
from .scene import write_world as write_world
from .urdf import UrdfBody as UrdfBody
from .urdf import UrdfCollision as UrdfCollision
from .urdf import body_from_urdf as body_from_urdf
from .urdf import read_collision as read_collision
from .verdict import Verdict as Verdict
from .verdict import collides as collides
from .verdict import collides_kernel as collides_kernel
from .world import BOX as BOX
from .world import CAPSULE as CAPSULE
from .world import CYLINDER as CYLINDER
from .world import HALFSPACE as HALFSPACE
from .world import OBSTACLE_BUCKET as OBSTACLE_BUCKET
from .world import SPHERE as SPHERE
from .world import Nearest as Nearest
from .world import World as World
from .world import nearest_obstacles as nearest_obstacles

__all__ = [
    "BOX",
    "CAPSULE",
    "CYLINDER",
    "HALFSPACE",
    "OBSTACLE_BUCKET",
    "ROBOT_WORLD",
    "SELF",
    "SPHERE",
    "Body",
    "Boxes",
    "CollisionRobot",
    "Capsules",
    "CheckResult",
    "Clearance",
    "Cylinders",
    "HalfSpaces",
    "MeshCover",
    "MoveItRequest",
    "MotionResult",
    "Nearest",
    "SelfPairs",
    "SphereCover",
    "Spheres",
    "UrdfBody",
    "UrdfCollision",
    "Verdict",
    "World",
    "adjacent_links",
    "body_from_urdf",
    "box_capsules",
    "box_sphere_cover",
    "check",
    "check_kernel",
    "clearances_kernel",
    "clearance",
    "collides",
    "collides_kernel",
    "distance",
    "mesh_cover",
    "mesh_sphere_cover",
    "min_clearance",
    "nearest_obstacles",
    "point_cloud_spheres",
    "prepare",
    "propose_disabled",
    "read_collision",
    "read_moveit_request",
    "read_moveit_scene",
    "read_sphere_lists",
    "read_srdf_disabled",
    "read_world",
    "self_collision_link_pairs",
    "self_distances",
    "spherized_urdf",
    "surfaces",
    "validate_motions",
    "validate_motions_kernel",
    "write_world",
]
