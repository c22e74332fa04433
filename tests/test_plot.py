"""Plots (jaxkin.plot) rendered headless to PNG: non-empty images of the expected pixel size."""

import sys

import numpy as np
import pytest

pytest.importorskip("matplotlib")

from matplotlib.image import imread

from jaxkin import Jet, delta, plot, scara, workspace
from jaxkin.status import Status
from tests.references import delta as delta_ref
from tests.references import scara as scara_ref


def check_png(path, width, height):
    image = imread(path)
    assert image.shape[:2] == (height, width)
    rgb = image[..., :3]
    # Non-empty: a good share of the pixels is not background white, in several colours.
    assert np.mean(np.any(rgb < 0.95, axis=-1)) > 0.01
    levels = np.round(rgb.reshape(-1, 3) * 100).astype(np.int64)  # colours to 1/100
    assert len(np.unique(levels @ np.array([101 * 101, 101, 1]))) > 10


@pytest.fixture(scope="module")
def scara_robot():
    return scara.Scara.paper()  # [Noriega]: 150, 80, 50 mm


def test_joint_trajectories_with_status_shading(tmp_path):
    """Joints of the spiral [Noriega, eq. 16] (NumPy reference IK) with an unreachable stretch
    and an invalid sample: one shading colour, and one legend entry, per failing status."""
    t = np.linspace(0.0, 8.0, 80)
    w = np.pi / 2
    d = np.stack([100 + 20 * np.sin(w * t), -20 * np.cos(w * t), 50 + 10 * t], -1)
    rates = np.zeros_like(d)
    q = Jet.of(*scara_ref.ik_numpy(d, rates, rates, 150.0, 80.0, 50.0))
    status = np.full(80, int(Status.OK))
    status[30:35] = Status.UNREACHABLE
    status[50] = Status.INVALID_INPUT
    path = tmp_path / "joints.png"
    fig = plot.joint_trajectories(
        t, q, status=status, names=scara.JOINT_NAMES, path=path, figsize=(8, 6), dpi=50
    )
    assert fig.get_size_inches().tolist() == [8, 6]
    check_png(path, 400, 300)
    legend_labels = [text.get_text() for text in fig.legends[0].get_texts()]
    assert sorted(legend_labels) == ["INVALID_INPUT", "UNREACHABLE"]


def test_joint_trajectories_candidates_without_rates(tmp_path):
    t = np.tile(np.linspace(0, 1, 20), 3)
    candidate = np.repeat([0, 1, 2], 20)
    q = np.stack([np.sin(t + candidate), t * candidate], -1)
    status = np.zeros(60, int)
    status[[25, 45]] = Status.SINGULAR
    path = tmp_path / "c.png"
    plot.joint_trajectories(t, q, status=status, candidate=candidate, path=path, dpi=40)
    check_png(path, 400, 280)


def test_scara_pose(tmp_path, scara_robot):
    t = np.linspace(0, 8, 50)
    trace = np.stack([100 + 20 * np.sin(t), -20 * np.cos(t), 50 + 10 * t], -1)
    rest = np.zeros(3)
    q = scara_ref.ik_numpy(trace[-1], rest, rest, 150.0, 80.0, 50.0)[0]
    path = tmp_path / "scara.png"
    plot.scara_pose(scara_robot, q, trace=trace, path=path, figsize=(6, 3), dpi=60)
    check_png(path, 360, 180)


def test_delta_pose_and_drawn_rods_have_the_rod_length(tmp_path):
    robot = delta.Delta.paper()
    p = np.array([3.0, -2.0, -30.0])
    theta = delta_ref.ik_numpy(p[None])[0]  # elbow out [Cardona, eq. 5]
    pts = plot.delta_points(robot, theta, p)
    # Independent check of the drawing convention: |D_i - E_i| = l_rod at an IK solution.
    np.testing.assert_allclose(
        np.linalg.norm(pts["platform"] - pts["elbow"], axis=-1), robot.l_rod, rtol=1e-12
    )
    np.testing.assert_allclose(np.linalg.norm(pts["base"][:, :2], axis=-1), robot.r_base)
    path = tmp_path / "delta.png"
    plot.delta_pose(robot, theta, trace=np.array([p, p + 1.0]), path=path, figsize=(4, 4), dpi=50)
    check_png(path, 200, 200)


@pytest.fixture(scope="module")
def sweep_result():
    robot = scara.Scara.create(10.0, 8.0, 5.0)
    return workspace.sweep(robot, ((-13, 13), (-13, 13), (0, 10)), 1.0)


@pytest.mark.parametrize(
    ("fn", "size"),
    [("workspace_slices", (8, 5)), ("workspace_cloud", (5, 5)), ("workspace_overview", (10, 5))],
)
def test_workspace_plots(tmp_path, sweep_result, fn, size):
    path = tmp_path / f"{fn}.png"
    fig = getattr(plot, fn)(sweep_result, path=path, figsize=size, dpi=40)
    assert fig is not None
    check_png(path, size[0] * 40, size[1] * 40)


def test_cost_curves(tmp_path):
    path = tmp_path / "cost.png"
    k = np.arange(50)
    plot.cost_curves(
        {"adam": 10 * 0.9**k + 1e-3, "sgd": 10 * 0.95**k + 1e-3}, path=path, figsize=(5, 3), dpi=50
    )
    check_png(path, 250, 150)
    fig = plot.cost_curves(np.exp(-np.arange(10.0)), log=False)
    assert fig.axes[0].get_yscale() == "linear"


def test_missing_matplotlib_message(monkeypatch):
    monkeypatch.setitem(sys.modules, "matplotlib", None)
    with pytest.raises(ImportError, match=r"pip install 'jaxkin\[plot\]'"):
        plot.require_matplotlib()
    with pytest.raises(ImportError, match=r"pip install 'jaxkin\[plot\]'"):
        plot.cost_curves([1.0, 0.5])


def test_cli_plots(tmp_path, capsys):
    from jaxkin import cli

    t = np.linspace(0, 8, 33)  # padded to 64 rows, as in test_cli
    src = tmp_path / "in.csv"
    src.write_text(
        "t,x,y,z\n"
        + "".join(f"{ti},{100 + 20 * np.sin(ti)},{-20 * np.cos(ti)},{50 + 10 * ti}\n" for ti in t)
    )
    png = tmp_path / "q.png"
    assert (
        cli.main(
            [
                "ik",
                "scara",
                "--robot",
                "paper",
                "-q",
                "-i",
                str(src),
                "-o",
                str(tmp_path / "q.csv"),
                "--plot",
                str(png),
            ]
        )
        == 0
    )
    check_png(png, 1000, 700)
    ws = tmp_path / "ws.png"
    assert (
        cli.main(
            [
                "workspace",
                "scara",
                "--l-oa",
                "10",
                "--l-ab",
                "8",
                "--l-bc",
                "5",
                "--resolution",
                "1",
                "-q",
                "--plot",
                str(ws),
            ]
        )
        == 0
    )
    check_png(ws, 1300, 600)
    capsys.readouterr()


# ------------------------------------------------------------------ robots, worlds, motions
def anthropomorphic_points(l1, l2, l3, q):
    """Base, shoulder, elbow and wrist of the anthropomorphic arm [Lopez-Villagomez], written
    out: the shoulder ``l1`` above the base, the upper arm ``l2`` and the forearm ``l3`` in the
    vertical plane at azimuth ``q1``, elevated by ``q2`` and ``q2 + q3``."""
    q1, q2, q3 = q
    along = np.array([np.cos(q1), np.sin(q1)])
    shoulder = np.array([0.0, 0.0, l1])
    elbow = shoulder + l2 * np.r_[np.cos(q2) * along, np.sin(q2)]
    wrist = elbow + l3 * np.r_[np.cos(q2 + q3) * along, np.sin(q2 + q3)]
    return np.stack([np.zeros(3), shoulder, elbow, wrist])


def drawn_as(ax, meshes):
    """Every mesh artist of ``ax`` is the gid's triangles of ``meshes``: its polygons (public
    ``get_paths`` after a draw, in the axes' projected coordinates, in matplotlib's depth
    order) are those triangles projected by the axes' own matrix (``get_proj``,
    ``proj3d.proj_transform``), one for one, to 1e-12 of the view; every gid drawn once."""
    from mpl_toolkits.mplot3d import proj3d

    ax.figure.draw_without_rendering()
    projection = ax.get_proj()
    assert sorted(c.get_gid() for c in ax.collections) == sorted(meshes)
    for collection in ax.collections:
        triangles = meshes[collection.get_gid()]
        x, y, _ = proj3d.proj_transform(*triangles.reshape(-1, 3).T, projection)
        expected = np.stack([x, y], -1).reshape(len(triangles), 6)
        drawn = np.stack([p.vertices[:3].ravel() for p in collection.get_paths()])
        assert drawn.shape == expected.shape
        gap = np.linalg.norm(drawn[:, None] - expected[None], axis=-1)
        scale = np.ptp(expected)
        assert gap.min(axis=0).max() <= 1e-12 * scale and gap.min(axis=1).max() <= 1e-12 * scale


def distance_to_segment(points, a, b):
    t = np.clip((points - a) @ (b - a) / np.dot(b - a, b - a), 0.0, 1.0)
    return np.linalg.norm(points - (a + t[:, None] * (b - a)), axis=-1)


def arm_scene(half_y: float, samples: int):
    """The anthropomorphic arm of links ``(l1, l2, l3) = (0.3, 0.25, 0.2)`` m with capsules of
    radius ``r = 0.03`` m, a box of half-widths ``(0.05, half_y, 0.2)`` at ``(0.3, 0.2, 0.2)``
    on the floor ``z = 0``, and a straight motion of ``samples`` joint vectors: ``(l1, l2,
    l3, r, arm, centre, half, world, motion)``."""
    from jaxkin import collision, serial

    l1, l2, l3, r = 0.3, 0.25, 0.2, 0.03
    arm = serial.Anthropomorphic(l1, l2, l3, link_radius=r)
    centre, half = np.array([0.3, 0.2, 0.2]), np.array([0.05, half_y, 0.2])
    world = collision.World.create(
        boxes=collision.Boxes.create(center=[centre], half_extents=[half]),
        halfspaces=collision.HalfSpaces.create([[0.0, 0.0, 1.0]], [0.0]),
    )
    motion = np.linspace([0.0, 0.3, 0.5], [1.2, 0.6, 0.9], samples)
    return l1, l2, l3, r, arm, centre, half, world, motion


def test_robot_scene_draws_the_body_world_and_motion_where_fk_puts_them(tmp_path):
    """The meshes drawn (``scene_meshes``, the figure's artists by ``drawn_as``): each
    link's capsule at distance r from the segment between the written-out joint positions,
    its poles ``r`` past the ends; the box's corners; the tool path through the written-out
    wrist at every sample; the body at the motion's samples; a PNG of the requested size."""
    l1, l2, l3, r, arm, centre, half, world, motion = arm_scene(0.06, 30)
    q = np.array([0.4, 0.5, 0.7])
    fig = plot.robot_scene(arm, q, world, motion, frames=3, path=tmp_path / "scene.png")
    ax = fig.axes[0]
    triangles = plot.scene_meshes(arm, q, world, motion, frames=3)
    drawn_as(ax, triangles)
    meshes = {gid: corners.reshape(-1, 3) for gid, corners in triangles.items()}
    joints = anthropomorphic_points(l1, l2, l3, q)
    for k in (1, 2, 3):
        a, b = joints[k - 1], joints[k]
        points = meshes[f"body link{k}"]
        np.testing.assert_allclose(distance_to_segment(points, a, b), r, rtol=0, atol=1e-12)
        u = (b - a) / np.linalg.norm(b - a)
        for pole in (a - r * u, b + r * u):
            assert np.min(np.linalg.norm(points - pole, axis=-1)) < 1e-12
    for k, index in enumerate((0, 14, 29)):  # first, middle (14.5 rounded to even), last
        at = anthropomorphic_points(l1, l2, l3, motion[index])
        points = meshes[f"motion {k} link3"]
        np.testing.assert_allclose(distance_to_segment(points, at[2], at[3]), r, atol=1e-12)
    corners = centre + half * np.array(
        [[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)]
    )
    drawn = np.unique(meshes["world box 0"].round(12), axis=0)  # 12 triangles, 8 corners
    np.testing.assert_allclose(drawn, np.unique(corners.round(12), axis=0), atol=1e-12)
    np.testing.assert_allclose(meshes["world halfspace 0"][:, 2], 0.0, atol=1e-12)  # the floor
    lines = {line.get_gid(): np.stack(line.get_data_3d(), -1) for line in ax.lines}
    wrists = np.stack([anthropomorphic_points(l1, l2, l3, m)[3] for m in motion])
    np.testing.assert_allclose(lines["tool path"], wrists, rtol=0, atol=1e-12)
    np.testing.assert_allclose(lines["link origins"][1:3], joints[1:3], atol=1e-12)
    check_png(tmp_path / "scene.png", 700, 650)


def test_robot_scene_of_a_urdf_arm_and_its_errors():
    """A URDF chain's skeleton capsules (``with_link_radius``) drawn at q: the tool link's
    origin (``jaxkin.fk``'s pose) is among the drawn link origins; bad arguments are named."""
    from jaxkin import collision, fk, serial

    urdf = """<robot name="arm">
      <link name="base"/><link name="upper"/><link name="fore"/><link name="tool"/>
      <joint name="shoulder" type="revolute"><parent link="base"/><child link="upper"/>
        <origin xyz="0 0 0.3"/><axis xyz="0 1 0"/>
        <limit lower="-2" upper="2" effort="1" velocity="2"/></joint>
      <joint name="elbow" type="revolute"><parent link="upper"/><child link="fore"/>
        <origin xyz="0 0 0.4"/><axis xyz="0 1 0"/>
        <limit lower="-2" upper="2" effort="1" velocity="2"/></joint>
      <joint name="flange" type="fixed"><parent link="fore"/><child link="tool"/>
        <origin xyz="0 0 0.35"/></joint>
    </robot>"""
    chain = serial.from_urdf(urdf, "tool").with_link_radius(0.04)
    q = np.array([0.3, -0.6])
    fig = plot.robot_scene(chain, q)
    origins = np.stack(fig.axes[0].lines[0].get_data_3d(), -1)
    tip = np.asarray(fk(chain, q).x.p)[:3, 3]
    assert np.min(np.linalg.norm(origins - tip, axis=-1)) < 1e-12
    assert {c.get_gid() for c in fig.axes[0].collections} >= {"body upper", "body fore"}
    with pytest.raises(ValueError, match=r"q: expected joints of shape \(2,\)"):
        plot.robot_scene(chain, np.zeros(3))
    with pytest.raises(ValueError, match="motion: expected joints of shape"):
        plot.robot_scene(chain, q, motion=np.zeros((4, 3)))
    with pytest.raises(ValueError, match="world: expected a collision.World"):
        plot.robot_scene(chain, q, world=collision.Spheres.create([[0.0, 0.0, 0.0]], 1.0))
    with pytest.raises(ValueError, match="q: give the joints"):
        plot.robot_scene(chain)
