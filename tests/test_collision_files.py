"""Collision geometry as files: world files (JSON, YAML) read back exactly, MoveIt planning
scenes, cuRobo's sphere lists, spherised URDFs written and read back, a chain given a whole
body; errors that name the file and the entry. VAMP's archive of MotionBenchMaker problems and
its spherised Panda are read from the local mirror when it is there (slow tier)."""

from __future__ import annotations

import importlib.metadata
import json
import subprocess
import tarfile
from pathlib import Path

import jax
import numpy as np
import pytest

from jaxkin import collision as col
from jaxkin import serial

yaml = pytest.importorskip("yaml")

ROBOTS = importlib.metadata.distribution("example-robot-data").locate_file(
    "cmeel.prefix/share/example-robot-data/robots"
)
PANDA = ROBOTS / "panda_description/urdf/panda.urdf"
VAMP = Path("/work/.mirror/KavrakiLab+vamp/repo")


def _leaves_equal(a: col.World, b: col.World) -> bool:
    same_tree = jax.tree.structure(a) == jax.tree.structure(b)
    leaves = zip(jax.tree.leaves(a), jax.tree.leaves(b), strict=True)
    return same_tree and all(np.array_equal(np.asarray(x), np.asarray(y)) for x, y in leaves)


def _world(rng) -> col.World:
    rot = np.linalg.qr(rng.normal(size=(2, 3, 3)))[0]
    rot *= np.sign(np.linalg.det(rot))[:, None, None]
    return col.World.create(
        spheres=col.Spheres.create(rng.normal(size=(3, 3)), [0.1, 1e17, 3e-300]),
        capsules=col.Capsules.create(rng.normal(size=(1, 3)), rng.normal(size=(1, 3)), 0.2),
        boxes=col.Boxes.create(rng.normal(size=(2, 3)), rng.uniform(0.1, 1, (2, 3)), rot),
        cylinders=col.Cylinders.create(
            rng.normal(size=(2, 3)), [0.3, 0.0], [1.0, 2.0], axis=rng.normal(size=(2, 3))
        ),
        halfspaces=col.HalfSpaces.create([0.0, 0.0, 1.0], -0.5),
    )


@pytest.mark.parametrize("suffix", [".json", ".yaml", ".yml"])
def test_world_files_read_back_exactly(tmp_path, suffix):
    """Every array of every kind (irrational values, 1e17, a subnormal-scale radius) reads
    back bit for bit; units convert on request; an empty world is a world."""
    world = _world(np.random.default_rng(0))
    path = tmp_path / f"scene{suffix}"
    col.write_world(world, path, frame="panda_link0")
    assert _leaves_equal(col.read_world(path), world)
    text = path.read_text()
    assert "panda_link0" in text and "units" in text
    in_mm = col.read_world(path, units="mm")
    np.testing.assert_array_equal(in_mm.cylinders.radius, 1000.0 * world.cylinders.radius)
    np.testing.assert_array_equal(in_mm.cylinders.axis, world.cylinders.axis)
    np.testing.assert_array_equal(in_mm.halfspaces.offset, 1000.0 * world.halfspaces.offset)
    col.write_world(col.World.create(), tmp_path / f"empty{suffix}")
    assert col.read_world(tmp_path / f"empty{suffix}").counts() == col.World.create().counts()


def test_world_file_by_hand_orientations_and_point_clouds(tmp_path):
    """A file written by hand: a quaternion (any length) and a rotation matrix give the same
    box; a cylinder's rotation gives its z axis; a point cloud inline and from a .npy or a
    text file gives the spheres of point_cloud_spheres; mm converts to m."""
    points = np.random.default_rng(1).uniform(0.0, 100.0, (40, 3))
    np.save(tmp_path / "cloud.npy", points)
    np.savetxt(tmp_path / "cloud.csv", points, delimiter=",")
    half_turn = [0.0, 0.0, 0.0, 2.0]  # w, x, y, z: a half turn about z, length 2
    document = {
        "units": "mm",
        "frame": "base",
        "boxes": [
            {"name": "a", "center": [1, 2, 3], "half_extents": [4, 5, 6], "quaternion": half_turn},
            {
                "center": [1, 2, 3],
                "half_extents": [4, 5, 6],
                "rotation": [[-1, 0, 0], [0, -1, 0], [0, 0, 1]],
            },
        ],  # fmt: skip
        "cylinders": [
            {
                "center": [0, 0, 0],
                "radius": 10,
                "half_length": 20,
                "rotation": [[1, 0, 0], [0, 0, -1], [0, 1, 0]],
            },
        ],  # fmt: skip
        "point_clouds": [
            {"points": points.tolist(), "voxel": 25.0, "point_radius": 1.0},
            {"file": "cloud.npy", "voxel": 25.0, "point_radius": 1.0},
            {"file": "cloud.csv", "voxel": 25.0, "point_radius": 1.0},
        ],
    }
    path = tmp_path / "hand.json"
    path.write_text(json.dumps(document))
    world = col.read_world(path, units="m")
    np.testing.assert_allclose(world.boxes.rotation[0], world.boxes.rotation[1], atol=1e-15)
    np.testing.assert_array_equal(world.boxes.half_extents[0], [0.004, 0.005, 0.006])
    np.testing.assert_allclose(world.cylinders.axis[0], [0.0, -1.0, 0.0], atol=1e-15)
    cloud = col.point_cloud_spheres(points, 25.0, 1.0)
    assert len(world.spheres) == 3 * len(cloud)
    for k in range(3):
        part = slice(k * len(cloud), (k + 1) * len(cloud))
        np.testing.assert_allclose(world.spheres.radius[part], cloud.radius / 1000, rtol=1e-15)
        np.testing.assert_allclose(world.spheres.center[part], cloud.center / 1000, rtol=1e-15)


BAD_ENTRIES = [
    ({"cylinders": [{"center": [0, 0, 0], "radius": -1, "half_length": 1}]},
     r"cylinders\[0\]: radius must be >= 0"),
    ({"boxes": [{}, {"name": "post", "center": [0, 0, 0]}]}, r"boxes\[0\]: missing 'center'"),
    ({"boxes": [{"name": "post", "center": [0, 0], "half_extents": [1, 1, 1]}]},
     r"boxes\[0\] \('post'\): center must be shape \[3\]"),
    ({"spheres": [{"center": [0, 0, 0], "radius": 1, "colour": "red"}]},
     r"spheres\[0\]: unknown key 'colour'"),
    ({"boxes": [{"center": [0, 0, 0], "half_extents": [1, 1, 1], "quaternion": [0, 0, 0, 0]}]},
     r"boxes\[0\]: quaternion is zero"),
    ({"boxes": [{"center": [0, 0, 0], "half_extents": [1, 1, 1], "rotation": np.eye(3).tolist(),
                 "quaternion": [1, 0, 0, 0]}]}, r"boxes\[0\]: give rotation or quaternion"),
    ({"halfspaces": [{"normal": [0, 0, 0], "offset": 0}]}, r"halfspaces\[0\]: normal must be"),
    ({"point_clouds": [{"voxel": 0.1}]}, r"point_clouds\[0\]: give points or file"),
    ({"point_clouds": [{"file": "missing.npy", "voxel": 0.1}]}, "no such point file"),
    ({"spheres": {"center": [0, 0, 0]}}, "spheres must be a list"),
    ({"obstacles": []}, "unknown key 'obstacles'"),
]  # fmt: skip


@pytest.mark.parametrize("entry, message", BAD_ENTRIES)
def test_world_file_errors_name_the_file_and_the_entry(tmp_path, entry, message):
    path = tmp_path / "bad.json"
    path.write_text(json.dumps({"units": "m", **entry}))
    with pytest.raises(ValueError, match=message) as info:
        col.read_world(path)
    assert str(path) in str(info.value)


def test_world_file_errors_of_the_file_itself(tmp_path):
    path = tmp_path / "w.json"
    for text, message in (
        ('{"spheres": []}', "missing 'units'"),
        ('{"units": "inch"}', "units must be one of m, cm, mm"),
        ('{"units": "m", "format": "other"}', "format must be 'jaxkin-world'"),
        ('{"units": "m",', "not readable JSON"),
        ("[1, 2]", "one mapping"),
    ):
        path.write_text(text)
        with pytest.raises(ValueError, match=message):
            col.read_world(path)
    (tmp_path / "w.yaml").write_text("units: [m\n")
    with pytest.raises(ValueError, match="w.yaml: not readable YAML"):
        col.read_world(tmp_path / "w.yaml")
    with pytest.raises(ValueError, match="no such world file"):
        col.read_world(tmp_path / "none.json")
    with pytest.raises(ValueError, match=r"\.json, \.yaml or \.yml"):
        col.write_world(col.World.create(), tmp_path / "w.txt")
    with pytest.raises(ValueError, match="units must be one of"):
        col.write_world(col.World.create(), tmp_path / "w.json", units="ft")
    batched = col.World.create(spheres=col.Spheres.create(np.zeros((2, 1, 3)), 1.0))
    with pytest.raises(ValueError, match="leading batch axes"):
        col.write_world(batched, tmp_path / "w.json")
    col.write_world(col.World.create(), tmp_path / "kept.json")
    before = (tmp_path / "kept.json").read_text()
    with pytest.raises(ValueError):
        col.write_world(batched, tmp_path / "kept.json")
    assert (tmp_path / "kept.json").read_text() == before  # a failed write leaves the file


def test_yaml_is_an_optional_extra(tmp_path, monkeypatch):
    """Without PyYAML a YAML file is an ImportError naming the extra; JSON still works."""
    import builtins

    real_import = builtins.__import__

    def no_yaml(name, *args, **kwargs):
        if name == "yaml":
            raise ImportError("no module named yaml")
        return real_import(name, *args, **kwargs)

    (tmp_path / "w.yaml").write_text("units: m\n")
    (tmp_path / "w.json").write_text('{"units": "m"}')
    monkeypatch.setattr(builtins, "__import__", no_yaml)
    with pytest.raises(ImportError, match=r"'yaml' extra.*jaxkin\[yaml\]"):
        col.read_world(tmp_path / "w.yaml")
    assert col.read_world(tmp_path / "w.json").counts()["spheres"] == 0


SCENE = """
robot_model_name: panda
fixed_frame_transforms:
  - transform: {rotation: [0, 0, 0, 1], translation: [0, 0, 0]}
    child_frame_id: world
  - transform: {rotation: [0, 0, 0.7071067811865476, 0.7071067811865476], translation: [1, 0, 0]}
    child_frame_id: table
world:
  collision_objects:
    - id: can
      primitives: [{type: cylinder, dimensions: [0.14, 0.03]}]
      primitive_poses:
        - {position: [0.5, 0.2, 0.1], orientation: [0.7071067811865476, 0, 0, 0.7071067811865476]}
    - id: shelf
      header: {frame_id: table}
      primitives: [{type: box, dimensions: [0.7, 0.4, 0.04]}, {type: 2, dimensions: [0.05]}]
      primitive_poses:
        - {position: {x: 0.1, y: 0, z: 0}, orientation: {x: 0, y: 0, z: 0, w: 1}}
        - {position: [0, 0, 0.3], orientation: [0, 0, 0, 1]}
    - id: moved
      pose: {position: [0, 0, 1], orientation: [0, 0, 0, 1]}
      primitives: [{type: sphere, dimensions: [0.1]}]
      primitive_poses: [{position: [0, 0, 0.5], orientation: [0, 0, 0, 1]}]
"""


def test_moveit_scene_by_hand(tmp_path):
    """Cylinders along their frame's z (here turned onto -y by a quarter turn about x),
    dimensions [height, radius]; boxes of full sides; an object in a fixed frame (a quarter
    turn about z at x = 1) moved by it; an object pose composed with its primitive's."""
    path = tmp_path / "scene.yaml"
    path.write_text(SCENE)
    world = col.read_moveit_scene(path)
    assert world.counts() == {
        "spheres": 2, "capsules": 0, "boxes": 1, "halfspaces": 0, "cylinders": 1
    }  # fmt: skip
    np.testing.assert_allclose(world.cylinders.center, [[0.5, 0.2, 0.1]], atol=1e-15)
    np.testing.assert_allclose(world.cylinders.axis, [[0.0, -1.0, 0.0]], atol=1e-15)
    np.testing.assert_allclose(world.cylinders.radius, [0.03])
    np.testing.assert_allclose(world.cylinders.half_length, [0.07])
    np.testing.assert_allclose(world.boxes.center, [[1.0, 0.1, 0.0]], atol=1e-15)
    np.testing.assert_allclose(world.boxes.half_extents, [[0.35, 0.2, 0.02]])
    np.testing.assert_allclose(world.boxes.rotation[0][:, 0], [0.0, 1.0, 0.0], atol=1e-15)
    np.testing.assert_allclose(world.spheres.center, [[1, 0, 0.3], [0, 0, 1.5]], atol=1e-15)
    assert _leaves_equal(col.read_world(path), world)  # read_world recognises the scene


@pytest.mark.parametrize(
    "change, message",
    [
        (("type: cylinder", "type: cone"), r"collision_objects\[0\] \('can'\).primitives\[0\]"),
        (("dimensions: [0.14, 0.03]", "dimensions: [0.14]"), "a cylinder has 2 dimensions"),
        (("{frame_id: table}", "{frame_id: panda_hand}"), "frame 'panda_hand' is neither"),
        (("[0.5, 0.2, 0.1]", "[0.5, 0.2]"), r"\('can'\).primitive_poses\[0\].position: expected 3"),
        (("world:\n", "nothing:\n"), "no world.collision_objects"),
    ],
)
def test_moveit_scene_errors_name_the_object(tmp_path, change, message):
    path = tmp_path / "scene.yaml"
    path.write_text(SCENE.replace(*change, 1))
    with pytest.raises(ValueError, match=message) as info:
        col.read_moveit_scene(path)
    assert str(path) in str(info.value)


def test_moveit_request(tmp_path):
    path = tmp_path / "request.yaml"
    path.write_text(
        "group_name: panda_arm\n"
        "start_state: {joint_state: {name: [j1, j2], position: [0.5, -1]}}\n"
        "goal_constraints:\n"
        "  - joint_constraints: [{joint_name: j1, position: 1.5}, {position: 2, joint_name: j2}]\n"
    )
    request = col.read_moveit_request(path)
    assert request.group == "panda_arm"
    assert request.start == {"j1": 0.5, "j2": -1.0} and request.goals == ({"j1": 1.5, "j2": 2.0},)
    path.write_text("start_state: {joint_state: {name: [j1, j2], position: [0.5]}}\n")
    with pytest.raises(ValueError, match="2 names but 1 positions"):
        col.read_moveit_request(path)


CUROBO = """
robot_cfg:
  kinematics:
    urdf_path: robot/arm.urdf
    collision_spheres: spheres/arm.yml
    collision_sphere_buffer: 0.004
"""
SPHERES = """
collision_spheres:
  l1:
    - center: [0.0, 0.0, 0.1]
      radius: 0.05
    - {center: [0.0, 0.0, 0.2], radius: 0.04}
  l2:
    - center: [0.1, 0.0, 0.0]
      radius: -0.01
  tool:
    - center: [0, 0, 0.05]
      radius: 0.02
"""
ARM = """<robot name="arm">
  <link name="base"/>
  <link name="l1"><collision><geometry><box size="0.1 0.1 0.3"/></geometry></collision></link>
  <link name="l2"/><link name="tool"><!-- the flange -->
    <collision><geometry><cylinder radius="0.02" length="0.1"/></geometry></collision></link>
  <joint name="turn" type="continuous"><parent link="base"/><child link="l1"/>
    <origin xyz="0 0 0.3"/><axis xyz="0 0 1"/></joint>
  <joint name="shoulder" type="revolute"><parent link="l1"/><child link="l2"/>
    <axis xyz="0 1 0"/><limit lower="-2" upper="2" effort="1" velocity="2"/></joint>
  <joint name="flange" type="fixed"><parent link="l2"/><child link="tool"/>
    <origin xyz="0 0 0.35"/></joint>
</robot>"""


def test_curobo_sphere_lists_and_a_chain_given_the_whole_body(tmp_path):
    """The robot file names a spheres file relative to itself; disabled spheres (negative
    radius) are left out; the chain given the body uses exactly those spheres (the URDF's
    box and cylinder are not read)."""
    (tmp_path / "spheres").mkdir()
    (tmp_path / "spheres" / "arm.yml").write_text(SPHERES)
    (tmp_path / "arm.yml").write_text(CUROBO)
    lists = col.read_sphere_lists(tmp_path / "arm.yml")
    assert lists.keys() == {"l1", "tool"}
    np.testing.assert_array_equal(lists["l1"][0], [[0, 0, 0.1], [0, 0, 0.2]])
    np.testing.assert_array_equal(lists["l1"][1], [0.05, 0.04])
    assert col.read_sphere_lists(tmp_path / "spheres" / "arm.yml").keys() == lists.keys()
    chain = serial.from_urdf(ARM, "tool")
    body = col.Body.create(chain.links.names, spheres=lists)
    given = chain.with_body(body)
    own = given.collision_body()
    assert own.num_capsules == 0 and own.num_spheres == 3
    per_link, _ = own.per_link()
    for link, (centers, radii) in lists.items():
        np.testing.assert_array_equal(per_link[link][0], centers)
        np.testing.assert_array_equal(per_link[link][1], radii)
    assert chain.collision_body().num_capsules > 0  # the URDF's own, unchanged
    with pytest.raises(ValueError, match="are not the chain's"):
        chain.with_body(col.Body.create(("base", "l1"), spheres={"l1": lists["l1"]}))
    (tmp_path / "bad.yml").write_text(
        "collision_spheres:\n  l1:\n    - {center: [0, 0], radius: 1}\n"
    )
    with pytest.raises(ValueError, match=r"collision_spheres\['l1'\]\[0\]"):
        col.read_sphere_lists(tmp_path / "bad.yml")


def test_spherized_urdf_round_trip(tmp_path):
    """A body's spheres written into a URDF in place of its <collision> elements read back
    (body_from_urdf) to the same spheres on the same links, bit for bit; joints, comments and
    the chain's kinematics are kept; capsules and unknown links are refused."""
    rng = np.random.default_rng(3)
    chain = serial.from_urdf(ARM, "tool")
    names = chain.links.names
    spheres = {"l1": (rng.normal(size=(3, 3)), rng.uniform(0.01, 0.1, 3)),
               "tool": (rng.normal(size=(1, 3)), [1 / 3])}  # fmt: skip
    body = col.Body.create(names, spheres=spheres)
    text = col.spherized_urdf(body, ARM)
    assert "the flange" in text and "<box" not in text and "<cylinder" not in text
    back = col.body_from_urdf(text).body
    assert back.links == body.links and back.sphere_link == body.sphere_link
    np.testing.assert_array_equal(back.sphere_center, body.sphere_center)
    np.testing.assert_array_equal(back.sphere_radius, body.sphere_radius)
    again = serial.from_urdf(text, "tool")
    np.testing.assert_array_equal(again.link_poses(np.array([0.2, 0.1])),
                                  chain.link_poses(np.array([0.2, 0.1])))  # fmt: skip
    (tmp_path / "arm.urdf").write_text(ARM)
    assert col.spherized_urdf(body, tmp_path / "arm.urdf") == text
    with pytest.raises(ValueError, match="capsules"):
        col.spherized_urdf(chain.collision_body(), ARM)
    other = col.Body.create(("base", "l9"), spheres={"l9": ([0.0, 0.0, 0.0], [0.1])})
    with pytest.raises(ValueError, match="link 'l9' is not a link"):
        col.spherized_urdf(other, ARM)


@pytest.fixture(scope="module")
def vamp_problems(tmp_path_factory):
    """VAMP's MotionBenchMaker Panda problems, extracted from the local mirror."""
    if not VAMP.is_dir():
        pytest.skip("no local mirror of VAMP's repository")
    archive = tmp_path_factory.mktemp("vamp") / "problems.tar.bz2"
    data = subprocess.run(
        ["git", "-C", str(VAMP), "show", "HEAD:resources/panda/problems.tar.bz2"],
        capture_output=True, check=True,
    ).stdout  # fmt: skip
    archive.write_bytes(data)
    with tarfile.open(archive) as tar:
        tar.extractall(archive.parent, filter="data")
    return archive.parent / "problems"


@pytest.mark.slow
def test_motionbenchmaker_panda_scenes_parse(vamp_problems):
    """Every scene of the 7 Panda problem sets parses (700 scenes: 5500 boxes, 2700
    cylinders, nothing else), and every request has one joint goal of the 7 arm joints."""
    totals = {}
    scenes = sorted(vamp_problems.glob("*/scene*.yaml"))
    for path in scenes:
        for kind, count in col.read_moveit_scene(path).counts().items():
            totals[kind] = totals.get(kind, 0) + count
    assert len(scenes) == 700
    assert totals == {"spheres": 0, "capsules": 0, "boxes": 5500, "halfspaces": 0,
                      "cylinders": 2700}  # fmt: skip
    for path in sorted(vamp_problems.glob("*/request*.yaml")):
        request = col.read_moveit_request(path)
        assert len(request.goals) == 1 and len(request.goals[0]) == 7


@pytest.mark.slow
def test_vamp_spherized_panda():
    """VAMP's spherised Panda: 59 spheres on the arm's links, the hand and the fingers, and
    written back as a spherised URDF it reads the same."""
    if not VAMP.is_dir():
        pytest.skip("no local mirror of VAMP's repository")
    text = subprocess.run(
        ["git", "-C", str(VAMP), "show", "HEAD:resources/panda/panda_spherized.urdf"],
        capture_output=True, check=True, text=True,
    ).stdout  # fmt: skip
    body = col.body_from_urdf(text).body
    counts = {}
    for link in body.sphere_link:
        counts[body.links[link]] = counts.get(body.links[link], 0) + 1
    assert body.num_spheres == 59 and body.num_capsules == 0
    assert counts == {"panda_link0": 1, "panda_link1": 4, "panda_link2": 4, "panda_link3": 4,
                      "panda_link4": 4, "panda_link5": 12, "panda_link6": 3, "panda_link7": 5,
                      "panda_hand": 18, "panda_leftfinger": 2, "panda_rightfinger": 2}  # fmt: skip
    back = col.body_from_urdf(col.spherized_urdf(body, text)).body
    np.testing.assert_array_equal(back.sphere_center, body.sphere_center)
    chain = serial.from_urdf(text, "panda_hand")
    assert chain.collision_body().num_spheres == 59
