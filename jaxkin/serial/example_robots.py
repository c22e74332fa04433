"""The arms of example-robot-data by name: their URDF, SRDF, mesh folder and tool link.

example-robot-data (the ``robots`` extra, also part of ``test``; a cmeel package) installs
URDFs, SRDFs and meshes under ``<site-packages>/cmeel.prefix/share/example-robot-data/robots``,
one ``<robot>_description`` folder per robot. ``example_robot(name)`` finds them for the arms
listed in ``EXAMPLE_ROBOTS`` (the tool link and, for a torso robot, the base link that the
tests solve on), so that an arm with its body and self-collision pairs is one line::

    panda = serial.example_robot("panda")
    chain = panda.chain()  # serial.from_urdf(panda.urdf, panda.tip).with_srdf(panda.srdf)

``package_dir`` is the folder that holds the ``<robot>_description`` folders, where a URDF's
``package://<robot>_description/meshes/...`` names resolve.
"""

from __future__ import annotations

import dataclasses
import importlib.metadata
from pathlib import Path
from typing import Any

from .urdf import from_urdf

__all__ = ["EXAMPLE_ROBOTS", "ExampleRobot", "example_robot", "example_robots_dir"]

_DISTRIBUTION = "example-robot-data"
_ROBOTS = "cmeel.prefix/share/example-robot-data/robots"

# name: (URDF, SRDF or None, tip link, base link or None for the URDF's root)
EXAMPLE_ROBOTS: dict[str, tuple[str, str | None, str, str | None]] = {
    "panda": (
        "panda_description/urdf/panda.urdf",
        "panda_description/srdf/panda.srdf",
        "panda_hand",
        None,
    ),
    "ur3": ("ur_description/urdf/ur3_robot.urdf", None, "tool0", None),
    "ur5": ("ur_description/urdf/ur5_robot.urdf", "ur_description/srdf/ur5.srdf", "tool0", None),
    "ur10": ("ur_description/urdf/ur10_robot.urdf", None, "tool0", None),
    "kinova": (
        "kinova_description/robots/kinova.urdf",
        "kinova_description/srdf/kinova.srdf",
        "j2s6s200_end_effector",
        None,
    ),
    "xarm7": (
        "xarm_description/urdf/xarm7.urdf",
        "xarm_description/srdf/xarm7.srdf",
        "link_eef",
        None,
    ),
    "z1": ("z1_description/urdf/z1.urdf", "z1_description/srdf/z1.srdf", "gripperStator", None),
    "so101": ("so_arm_description/urdf/so101.urdf", None, "gripper_frame_link", None),
    "tiago": ("tiago_description/robots/tiago.urdf", None, "arm_tool_link", "base_link"),
    "baxter": (
        "baxter_description/urdf/baxter.urdf",
        "baxter_description/srdf/baxter_manipulation.srdf",
        "left_gripper",
        "torso",
    ),
    "pr2": (
        "pr2_description/urdf/pr2.urdf",
        "pr2_description/srdf/pr2.srdf",
        "r_gripper_tool_frame",
        "base_link",
    ),
}


@dataclasses.dataclass(frozen=True)
class ExampleRobot:
    """One arm of example-robot-data.

    Attributes:
        name: its name in ``EXAMPLE_ROBOTS``.
        urdf: the URDF file.
        srdf: the SRDF file (its disabled collision pairs), None where the data has none.
        package_dir: the folder of the ``<robot>_description`` folders (``package://``).
        tip: the tool link a planner solves for.
        base: the base link of the chain (None: the URDF's root).
    """

    name: str
    urdf: Path
    srdf: Path | None
    package_dir: Path
    tip: str
    base: str | None = None

    def chain(self, **kwargs: Any) -> Any:
        """``serial.from_urdf(urdf, tip, base_link=base, **kwargs)``, with the SRDF's
        disabled pairs left out of its self-collision pairs (``with_srdf``) where there is
        one: the arm as a chain robot, its body read from the URDF's collision elements (the
        ``urdf`` extra)."""
        chain = from_urdf(self.urdf, self.tip, base_link=self.base, **kwargs)
        return chain if self.srdf is None else chain.with_srdf(self.srdf)


def example_robots_dir() -> Path:
    """The ``robots`` folder of the installed example-robot-data.

    Raises:
        ImportError: example-robot-data is not installed (naming the ``robots`` extra).
    """
    try:
        distribution = importlib.metadata.distribution(_DISTRIBUTION)
    except importlib.metadata.PackageNotFoundError:
        raise ImportError(
            "the example robots' files come from the example-robot-data package, which is not "
            "installed: pip install 'jaxkin[robots]' (or example-robot-data; the 'test' extra "
            "has it too)"
        ) from None
    root = Path(str(distribution.locate_file(_ROBOTS)))
    if not root.is_dir():
        raise ImportError(
            f"example-robot-data is installed, but its robots folder {root} is missing"
        )
    return root


def example_robot(name: str) -> ExampleRobot:
    """The files of the example-robot-data arm ``name`` (one of ``EXAMPLE_ROBOTS``).

    Raises:
        ValueError: an unknown name (the known ones listed).
        ImportError: example-robot-data is not installed (naming the ``robots`` extra).
    """
    if name not in EXAMPLE_ROBOTS:
        raise ValueError(f"name: expected one of {', '.join(EXAMPLE_ROBOTS)}, got {name!r}")
    root = example_robots_dir()
    urdf, srdf, tip, base = EXAMPLE_ROBOTS[name]
    return ExampleRobot(
        name=name,
        urdf=root / urdf,
        srdf=None if srdf is None else root / srdf,
        package_dir=root,
        tip=tip,
        base=base,
    )
