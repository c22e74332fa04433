"""MotionBenchMaker problems as VAMP ships them: the archives read, worlds and robots built.

MotionBenchMaker [Chamzas et al., "MotionBenchMaker: A Tool to Generate and Benchmark Motion
Planning Datasets", RA-L 2022] poses, per robot, seven scenes of 100 problems each
(``table_pick``, ``table_under_pick``, ``box``, ``bookshelf_small``, ``bookshelf_tall``,
``bookshelf_thin``, ``cage``). VAMP [Thomason, Kingston & Kavraki, ICRA 2024] ships them as
``problems.tar.bz2`` archives of MoveIt YAML files, ``problems/<scene>_<robot>/sceneNNNN.yaml``
(a ``PlanningScene``: boxes, cylinders, spheres, read exactly by
``collision.read_moveit_scene``'s reader) and ``requestNNNN.yaml`` (a ``MotionPlanRequest``:
``start_state.joint_state`` and one ``goal_constraints`` entry of joint constraints). The
archives, the spherised URDFs and the SRDFs in ``benchmarks/mbm/`` are VAMP's data
(Apache-2.0, ``benchmarks/mbm/LICENSE``); this reader is the project's own.
"""

from __future__ import annotations

import dataclasses
import re
import tarfile
from pathlib import Path

import numpy as np

from jaxkin import collision, serial
from jaxkin.collision.moveit import scene_world

HERE = Path(__file__).resolve().parent / "mbm"
SCENES = (
    "table_pick",
    "table_under_pick",
    "box",
    "bookshelf_small",
    "bookshelf_tall",
    "bookshelf_thin",
    "cage",
)
TIPS = {"panda": "panda_hand", "ur5": "wrist_3_link"}
# VAMP's published RRT-Connect ranges (its ROBOT_RRT_RANGES) and resolution (32)
RANGES = {"panda": 1.0, "ur5": 1.5}


@dataclasses.dataclass(frozen=True)
class Problem:
    """One problem: ``scene`` and ``index`` (the file number), its ``world`` (float64: boxes,
    spheres and exact cylinders), ``start`` and ``goal`` joint configurations in the robot's
    joint order."""

    scene: str
    index: int
    world: collision.World
    start: np.ndarray
    goal: np.ndarray


def request_configurations(request: dict, joint_names: tuple[str, ...], where: str):
    """``(start, goal)`` of a MoveIt motion plan request, in the order ``joint_names``."""
    state = request["start_state"]["joint_state"]
    names, positions = list(state["name"]), list(state["position"])
    constraints = request["goal_constraints"][0]["joint_constraints"]
    goal = {c["joint_name"]: float(c["position"]) for c in constraints}
    missing = [j for j in joint_names if j not in names or j not in goal]
    if missing:
        raise ValueError(f"{where}: joints {missing} missing from the start or the goal")
    start = np.array([float(positions[names.index(j)]) for j in joint_names])
    return start, np.array([goal[j] for j in joint_names])


def read_problems(archive: Path | str, joint_names: tuple[str, ...]) -> dict[str, list[Problem]]:
    """Every problem of an archive, by scene (scene names without the robot suffix), in file
    order. Raises ``ValueError`` for a scene without its request or the reverse."""
    import yaml

    scenes: dict[tuple[str, int], dict] = {}
    requests: dict[tuple[str, int], dict] = {}
    with tarfile.open(archive, "r:bz2") as tar:
        for member in tar.getmembers():
            if not member.isfile():
                continue
            parts = member.name.split("/")
            match = re.fullmatch(r"(scene|request)(\d+)\.yaml", parts[-1])
            if len(parts) < 2 or match is None:
                continue
            name = re.sub(r"_[^_]+$", "", parts[-2])  # "<scene>_<robot>"
            key = (name, int(match.group(2)))
            data = yaml.safe_load(tar.extractfile(member).read())
            data = (Path(archive) / member.name, data)
            (scenes if match.group(1) == "scene" else requests)[key] = data
    if set(scenes) != set(requests):
        odd = sorted(set(scenes) ^ set(requests))[:3]
        raise ValueError(f"{archive}: scenes and requests do not pair up, e.g. {odd}")
    out: dict[str, list[Problem]] = {}
    for key in sorted(scenes):
        where = f"{archive}: {key[0]} {key[1]}"
        start, goal = request_configurations(requests[key][1], joint_names, where)
        path, document = scenes[key]
        world = scene_world(document, path, "float64")
        out.setdefault(key[0], []).append(Problem(key[0], key[1], world, start, goal))
    return out


def robot(name: str) -> serial.Chain:
    """VAMP's spherised robot: the chain to its tip, its spheres, the SRDF's pairs."""
    return serial.from_urdf(HERE / f"{name}_spherized.urdf", TIPS[name]).with_srdf(
        HERE / f"{name}.srdf"
    )


def problems(name: str) -> dict[str, list[Problem]]:
    """The robot's archive in ``benchmarks/mbm/``, its worlds in float64 whatever JAX's
    default (the re-check reads them exactly)."""
    import jax

    with jax.enable_x64(True):
        return read_problems(HERE / f"{name}_problems.tar.bz2", robot(name).joint_names)
