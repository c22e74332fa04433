"""Fuzzing the URDF reader (slow tier): generated trees against Pinocchio's parser.

Each example writes a tree: a path of 1 to 7 joints from the root link to the tip link, of every
joint type (``revolute``, ``continuous``, ``prismatic``, ``fixed``, ``floating``, ``planar``),
with random origins (lengths from 1e-3 to 1e3, any ``rpy``), random axes (not unit length),
limits, mimic joints (of an earlier moving joint), side branches, and sometimes one defect:
two joints or two links of one name, a link with two parent joints, NaN or inf in an origin, an
axis, a limit or a mimic, a zero axis, a mimic whose value never lies within its limits.

The reader must either refuse the file with a ``ValueError`` naming the element that is wrong
(the joint or link named in the defect), or give a chain whose forward kinematics is
Pinocchio's placement of the tip link's frame (Pinocchio reads the same text with urdfdom;
a mimic joint's coordinate is set to ``multiplier * leader + offset`` here, a continuous
joint's to ``(cos, sin)``): rotation within 1e-12, translation within 1e-12 of the tree's size
(the sum of its origins' lengths). Every defect Pinocchio's parser refuses is refused.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import jaxkin
from jaxkin import serial

pytestmark = pytest.mark.slow

SETTINGS = settings(
    max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow], derandomize=True
)
TYPES = ("revolute", "continuous", "prismatic", "fixed", "floating", "planar")
MOVING = ("revolute", "continuous", "prismatic")
DEFECTS = (
    "duplicate joint",
    "duplicate link",
    "two parents",
    "bad origin",
    "bad axis",
    "bad limit",
    "bad mimic",
    "zero axis",
    "mimic outside its limits",
)


def _tree(rng: np.random.Generator, defect: str | None):
    """The URDF text, the path's joints (dicts), the names of which the error must contain one
    (none when the file is sound and must load) and the tree's size."""
    n = int(rng.integers(1, 8))
    weights = np.array([4, 2, 3, 2, 0.3, 0.3])
    joints, moving = [], []
    size = 0.0
    for i in range(n):
        kind = str(rng.choice(TYPES, p=weights / weights.sum()))
        scale = 10.0 ** rng.uniform(-3, 3)
        xyz = rng.normal(size=3) * scale
        size += float(np.linalg.norm(xyz))
        joint = {
            "name": f"j{i}",
            "type": kind,
            "parent": f"l{i}",
            "child": f"l{i + 1}",
            "xyz": xyz,
            "rpy": rng.uniform(-4, 4, 3),
            "axis": rng.normal(size=3) * 10.0 ** rng.uniform(-2, 2),
            "limit": None,
            "mimic": None,
        }
        if kind in ("revolute", "prismatic"):
            low = rng.uniform(-2, 0)
            joint["limit"] = (low, low + rng.uniform(0.1, 3), rng.uniform(0.1, 5))
        if kind == "prismatic":  # its stroke (a mimic's at most 2 * 3 + 0.2)
            size += 7.0
        if kind in MOVING and moving and rng.random() < 0.25:
            leader = moving[int(rng.integers(len(moving)))]
            if leader["mimic"] is None:
                joint["mimic"] = (leader["name"], rng.uniform(-2, 2), rng.uniform(-0.2, 0.2))
                if kind != "continuous":  # a mimic within reach of its limits: wide ones
                    joint["limit"] = (-50.0, 50.0, 1.0)
        if kind in MOVING:
            moving.append(joint)
        joints.append(joint)
    sides = [
        {
            "name": f"s{k}",
            "type": "revolute",
            "parent": f"l{int(rng.integers(0, n + 1))}",
            "child": f"side{k}",
            "xyz": rng.normal(size=3),
            "rpy": np.zeros(3),
            "axis": np.array([0.0, 0.0, 1.0]),
            "limit": (-1.0, 1.0, 1.0),
            "mimic": None,
        }
        for k in range(int(rng.integers(0, 3)))
    ]
    links = [f"l{i}" for i in range(n + 1)] + [s["child"] for s in sides]
    named = None
    victim = joints[int(rng.integers(n))]
    if defect == "duplicate joint" and n > 1:
        named = victim["name"]
        other = joints[(joints.index(victim) + 1) % n]
        other["name"] = named
    elif defect == "duplicate link":
        named = links[int(rng.integers(len(links)))]
        links.append(named)
    elif defect == "two parents":  # a second parent above it: no cycle (Pinocchio's parser
        named = victim["child"]  # recurses around a cycle until its stack overflows)
        above = f"l{int(rng.integers(0, joints.index(victim) + 1))}"
        sides.append(dict(joints[0], name="extra", parent=above, child=named))
    elif defect == "bad origin":
        named = victim["name"]
        victim[str(rng.choice(["xyz", "rpy"]))][int(rng.integers(3))] = rng.choice(
            [np.nan, np.inf, -np.inf]
        )
    elif defect == "bad axis":
        named = victim["name"]
        victim["axis"][int(rng.integers(3))] = rng.choice([np.nan, np.inf])
    elif defect == "bad limit" and victim["limit"] is not None:
        named = victim["name"]
        limit = list(victim["limit"])
        limit[int(rng.integers(3))] = rng.choice([np.nan, np.inf, -np.inf])
        victim["limit"] = tuple(limit)
    elif defect == "bad mimic" and any(j["mimic"] for j in joints):
        victim = next(j for j in joints if j["mimic"])
        named = victim["name"]
        leader, c, b = victim["mimic"]
        victim["mimic"] = (leader, np.nan, b) if rng.random() < 0.5 else (leader, c, np.inf)
    elif defect == "zero axis" and victim["type"] in MOVING:
        named = victim["name"]
        victim["axis"] = np.zeros(3)
    elif defect == "mimic outside its limits" and any(
        j["mimic"] and j["type"] != "continuous" for j in joints
    ):
        victim = next(j for j in joints if j["mimic"] and j["type"] != "continuous")
        named = victim["name"]
        leader = victim["mimic"][0]
        bounded = next(j for j in joints if j["name"] == leader)["type"] != "continuous"
        shifted = bounded and rng.random() < 0.5  # beyond reach of a bounded leader's range
        victim["mimic"] = (leader, 1.0, 500.0) if shifted else (leader, 0.0, 60.0)
    if named is None:  # the defect does not apply to this tree: a sound file
        defect = None
    floating = [j["name"] for j in joints if j["type"] in ("floating", "planar")]
    names = [] if named is None else [named]
    if defect in (None, "zero axis", "mimic outside its limits"):  # met on the path: the
        names += floating  # path's floating or planar joints may be met first
    if defect is None and not moving:
        names.append("no moving joint")
    return _urdf(links, joints + sides), joints, names, size


def _number(x: float) -> str:
    return repr(float(x))


def _urdf(links: list[str], joints: list[dict]) -> str:
    lines = ['<?xml version="1.0"?>', '<robot name="fuzz">']
    lines += [f'  <link name="{name}"/>' for name in links]
    for j in joints:
        lines.append(f'  <joint name="{j["name"]}" type="{j["type"]}">')
        lines.append(f'    <parent link="{j["parent"]}"/><child link="{j["child"]}"/>')
        xyz, rpy = (" ".join(_number(v) for v in j[k]) for k in ("xyz", "rpy"))
        lines.append(f'    <origin xyz="{xyz}" rpy="{rpy}"/>')
        lines.append(f'    <axis xyz="{" ".join(_number(v) for v in j["axis"])}"/>')
        if j["limit"] is not None:
            low, high, speed = (_number(v) for v in j["limit"])
            lines.append(f'    <limit lower="{low}" upper="{high}" effort="1" velocity="{speed}"/>')
        elif j["type"] == "continuous":
            lines.append('    <limit effort="1" velocity="2"/>')
        if j["mimic"] is not None:
            leader, c, b = j["mimic"]
            lines.append(
                f'    <mimic joint="{leader}" multiplier="{_number(c)}" offset="{_number(b)}"/>'
            )
        lines.append("  </joint>")
    lines.append("</robot>")
    return "\n".join(lines)


def _pinocchio_tip(model, joints: list[dict], chain, q: np.ndarray, tip: str) -> np.ndarray:
    """Pinocchio's placement of ``tip`` with the path's joints set from the chain's ``q``."""
    data = model.createData()
    coordinate = dict(zip(chain.joint_names, q, strict=True))
    value = {}
    for j in joints:  # base to tip: a leader comes before its mimics
        if j["type"] not in MOVING:
            continue
        if j["mimic"] is not None:
            leader, c, b = j["mimic"]
            value[j["name"]] = c * value[leader] + b
        else:
            value[j["name"]] = coordinate[j["name"]]
    full = pin.neutral(model)
    for name, theta in value.items():
        joint = model.joints[model.getJointId(name)]
        if joint.nq == 2:  # continuous: (cos, sin)
            full[joint.idx_q : joint.idx_q + 2] = np.cos(theta), np.sin(theta)
        else:
            full[joint.idx_q] = theta
    pin.framesForwardKinematics(model, data, full)
    return data.oMf[model.getFrameId(tip)].homogeneous


@given(seed=st.integers(0, 2**32 - 1), defect=st.sampled_from((None, None, None, *DEFECTS)))
@SETTINGS
def test_generated_trees_load_as_pinocchio_does_or_are_refused_by_name(seed, defect):
    rng = np.random.default_rng(seed)
    text, joints, names, size = _tree(rng, defect)
    tip = joints[-1]["child"]
    try:
        model = pin.buildModelFromXML(text)
    except ValueError:
        model = None
    try:
        chain = serial.from_urdf(text, tip)
    except ValueError as exc:
        assert names, f"a sound tree was refused: {exc}\n{text}"
        quoted = [name if " " in name else repr(name) for name in names]
        assert any(name in str(exc) for name in quoted), f"{exc!r} names none of {names}"
        return
    assert not names, f"accepted, expected an error naming one of {names}\n{text}"
    assert model is not None, f"Pinocchio refuses a tree the reader accepts\n{text}"
    lower = np.where(np.isfinite(chain.lower), chain.lower, -np.pi)
    upper = np.where(np.isfinite(chain.upper), chain.upper, np.pi)
    q = rng.uniform(lower, upper, size=(4, chain.n_joints))
    ours = np.asarray(jaxkin.fk(chain, q).x.p)
    theirs = np.array([_pinocchio_tip(model, joints, chain, qi, tip) for qi in q])
    np.testing.assert_allclose(ours[:, :3, :3], theirs[:, :3, :3], rtol=0, atol=1e-12)
    np.testing.assert_allclose(ours[:, :3, 3], theirs[:, :3, 3], rtol=0, atol=1e-12 * size)
