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
