"""Motion generation: from a start to goals among obstacles, inside one compiled program.

- ``planner``: ``plan(robot, start, world, goal=... | target=...)`` -> ``MotionPlan`` (status,
  path, simplified path, timed trajectory), many problems per call.
- ``status``: ``MotionStatus`` codes.
- ``space``: the joint space (sampling box, continuous joints, metric).
- ``bound``: how fast the body moves per joint step (conservative advancement).
- ``edges``: straight edges checked inside the search (discrete or certified).
- ``search``: RRT-Connect lanes in one ``lax.while_loop``.
- ``simplify``: shortcuts and a re-checked spline.
- ``goals``: targets to collision-free goal configurations (IK).
- ``collider``: the one adapter to the collision layer.
"""

from .bound import MotionBound as MotionBound
from .bound import motion_bound as motion_bound
from .planner import MotionOptions as MotionOptions
from .planner import MotionPlan as MotionPlan
from .planner import plan as plan
from .space import JointSpace as JointSpace
from .space import joint_space as joint_space
from .status import MotionStatus as MotionStatus
from .status import describe as describe
from .status import status_names as status_names

__all__ = [
    "JointSpace",
    "MotionBound",
    "MotionOptions",
    "MotionPlan",
    "MotionStatus",
    "describe",
    "joint_space",
    "motion_bound",
    "plan",
    "status_names",
]
