"""The ``jaxkin`` command: round trips, every error path (one line, exit 2), no partial output.

Every test but one calls ``jaxkin.cli.main(argv)`` in-process (a process start imports JAX,
~1-2 s); ``test_console_script_end_to_end`` runs the installed console script. The command
pads each file's rows to a power of two, so the files here have few distinct padded lengths
(4, 32 and 64 rows) and share compilations.
"""

import io
import os
import shutil
import signal
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import jaxkin
from jaxkin import Jet, Robot, cli, delta, scara, serial
from jaxkin.cli import commands, demo, progress
from jaxkin.cli import files as kio
from jaxkin.cli.parser import build_parser
from jaxkin.cli.robots import ROBOTS, RobotEntry
from tests.references import delta as delta_ref
from tests.references import scara as scara_ref
from tests.test_plan import forward

SCARA_PAPER = ["--robot", "paper"]
ARM = ["--l1", 0.3, "--l2", 0.25, "--l3", 0.2]  # anthropomorphic arm (m)


def spiral(t):
    """[Noriega, eq. 16] with its exact derivatives (mm, s)."""
    w = np.pi / 2
    s, c = np.sin(w * t), np.cos(w * t)
    p = np.stack([100 + 20 * s, -20 * c, 50 + 10 * t], -1)
    v = np.stack([20 * w * c, 20 * w * s, np.full_like(t, 10.0)], -1)
    a = np.stack([-20 * w * w * s, 20 * w * w * c, np.zeros_like(t)], -1)
    return p, v, a


def delta_path(t):
    """A circle at varying height inside the paper Delta's workspace (cm)."""
    p = np.stack([5 * np.cos(3 * t), 5 * np.sin(3 * t), -30 + 3 * np.sin(2 * t)], -1)
    v = np.stack([-15 * np.sin(3 * t), 15 * np.cos(3 * t), 6 * np.cos(2 * t)], -1)
    a = np.stack([-45 * np.cos(3 * t), -45 * np.sin(3 * t), -12 * np.sin(2 * t)], -1)
    return p, v, a


def write_points(path, t, p, v=None, a=None, candidate=None, names="xyz"):
    cols = {"t": t}
    if candidate is not None:
        cols["candidate"] = candidate
    cols.update({n: p[:, j] for j, n in enumerate(names)})
    velocity, acceleration = kio.rate_names(tuple(names))
    for block, rate_names in ((v, velocity), (a, acceleration)):
        if block is not None:
            cols.update({n: block[:, j] for j, n in enumerate(rate_names)})
    kio.write_table(path, cols)
    return path


def run(capsys, *argv):
    """main(argv) -> (exit status, stdout, stderr)."""
    code = cli.main([str(x) for x in argv])
    out, err = capsys.readouterr()
    return code, out, err


def load(path):
    path = Path(path)
    if path.suffix == ".npz":
        with np.load(path, allow_pickle=False) as f:
            return {k: f[k] for k in f.files}
    names = [n for n in path.read_text().splitlines()[0].split(",") if n != "status"]
    return kio.read_table(path, names).data | {"status": _status_column(path)}


def _status_column(path):
    lines = Path(path).read_text().splitlines()
    index = lines[0].split(",").index("status")
    return np.array([line.split(",")[index] for line in lines[1:]])


def columns(table, names):
    return np.stack([table[k] for k in names], -1)


def assert_one_line_error(code, err, *fragments):
    assert code == 2
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith("jaxkin: error: ")
    assert "Traceback" not in err
    for fragment in fragments:
        assert fragment in lines[0], lines[0]


def wrap(angle):
    return (angle + np.pi) % (2 * np.pi) - np.pi


# ------------------------------------------------------------------------------ round trips


@pytest.mark.parametrize("branch", ["+1", "-1"])
def test_scara_csv_round_trip_with_spline_rates(tmp_path, capsys, branch):
    """ik then fk reproduce the path; the spline rates match the exact derivatives of
    [Noriega, eq. 16] to the spline's accuracy. ``--mode`` is the old name of ``--branch``."""
    t = np.linspace(0.0, 1.6, 33)  # h = 0.05 s
    p, v, a = spiral(t)
    src = write_points(tmp_path / "in.csv", t, p)  # positions only: rates by spline
    option = "--mode" if branch == "-1" else "--branch"
    code, _, err = run(
        capsys, "ik", "scara", *SCARA_PAPER, option, branch, "-i", src, "-o", tmp_path / "q.csv"
    )
    assert code == 0, err
    assert f"(branch {int(branch)})" in err and "OK 33" in err
    q = load(tmp_path / "q.csv")
    assert set(q["status"]) == {"OK"}
    expected = scara_ref.ik_numpy(p, v, a, 150.0, 80.0, 50.0, mode=int(branch))[0]
    np.testing.assert_allclose(columns(q, ("theta1", "theta2", "l3")), expected, atol=1e-12)
    code, _, err = run(
        capsys, "fk", "scara", *SCARA_PAPER, "-i", tmp_path / "q.csv", "-o", tmp_path / "p.csv"
    )
    assert code == 0, err
    back = load(tmp_path / "p.csv")
    np.testing.assert_allclose(columns(back, "xyz"), p, rtol=0, atol=1e-9)
    # Spline rates (h = 0.05 s) against the exact derivatives of eq. 16: velocity to ~1e-3
    # of its scale (|v| ~ 31 mm/s), acceleration to ~1 % (|a| ~ 49 mm/s^2, worst at the ends).
    v_back = columns(back, ("vx", "vy", "vz"))
    a_back = columns(back, ("ax", "ay", "az"))
    np.testing.assert_allclose(v_back, v, atol=0.03)
    np.testing.assert_allclose(a_back, a, atol=0.5)
    np.testing.assert_allclose(a_back[5:-5], a[5:-5], atol=0.05)  # h^2 |y""""| / 12 ~ 0.025


def test_scara_given_rates_reproduce_the_reference_and_paper_value(tmp_path, capsys):
    """Given rates pass through unchanged: the joints and their rates equal the NumPy reference
    [Noriega, eqs. 1-15], theta1_ddot(0) is the corrected paper value (docs/errata.md), and the
    margin column is sin(beta)^2 of the shoulder angle beta (law of cosines)."""
    t = np.linspace(0.0, 8.0, 33)
    p, v, a = spiral(t)
    src = write_points(tmp_path / "in.npz", t, p, v, a)
    lengths = ["--l-oa", 150, "--l-ab", 80, "--l-bc", 50]
    code, _, err = run(capsys, "ik", "scara", *lengths, "-i", src, "-o", tmp_path / "q.npz")
    assert code == 0, err
    q = load(tmp_path / "q.npz")
    ref = scara_ref.ik_numpy(p, v, a, 150.0, 80.0, 50.0, mode=1)
    names = ("theta1", "theta2", "l3")
    for block, suffix in zip(ref, ("", "_dot", "_ddot"), strict=True):
        got = columns(q, [n + suffix for n in names])
        np.testing.assert_allclose(got, block, rtol=1e-12, atol=1e-12)
    # docs/errata.md: theta1_ddot(0) = 0.309 rad/s^2 on the spiral, branch +1.
    assert q["theta1_ddot"][0] == pytest.approx(0.309, abs=5e-4)
    r2 = p[:, 0] ** 2 + p[:, 1] ** 2
    cos_beta = (r2 + 80.0**2 - 50.0**2) / (2 * np.sqrt(r2) * 80.0)
    np.testing.assert_allclose(q["margin"], 1 - cos_beta**2, rtol=1e-12)


def test_delta_npz_round_trip_with_candidates(tmp_path, capsys):
    t = np.linspace(0.0, 0.6, 16)  # h = 0.04 s
    p, v, a = delta_path(t)
    t2 = np.concatenate([t, t])
    p2 = np.concatenate([p, p * np.array([0.5, 0.5, 1.0])])
    candidate = np.repeat([0, 1], len(t))
    src = write_points(tmp_path / "in.npz", t2, p2, candidate=candidate)
    code, _, err = run(
        capsys, "ik", "delta", "--robot", "paper", "-i", src, "-o", tmp_path / "theta.npz"
    )
    assert code == 0, err
    theta = load(tmp_path / "theta.npz")
    assert theta["candidate"].tolist() == candidate.tolist()
    assert set(theta["status"].tolist()) == {"OK"}
    assert np.all((theta["margin"] > 0) & (theta["margin"] <= 1))
    expected = delta_ref.ik_numpy(p2)  # elbow out, the default branch [Cardona, eq. 5]
    np.testing.assert_allclose(columns(theta, ("theta1", "theta2", "theta3")), expected, atol=1e-12)
    code, _, err = run(
        capsys,
        "fk",
        "delta",
        "--robot",
        "paper",
        "-i",
        tmp_path / "theta.npz",
        "-o",
        tmp_path / "p.npz",
    )
    assert code == 0, err
    back = load(tmp_path / "p.npz")
    np.testing.assert_allclose(columns(back, "xyz"), p2, atol=1e-9)
    # Candidate 0's velocity from splines of theta, mapped back by fk: close to the exact one.
    v_back = columns(back, ("vx", "vy", "vz"))[: len(t)]
    np.testing.assert_allclose(v_back, v, atol=0.05)


def test_delta_branch_in(tmp_path, capsys):
    """The elbow-in solution reaches the targets (NumPy FK, [Cardona]) and differs from the
    elbow-out reference. (Float32 output: ``test_console_script_end_to_end``.)"""
    t = np.linspace(0.0, 2.0, 21)
    p, v, a = delta_path(t)
    src = write_points(tmp_path / "in.csv", t, p, v, a)
    out = tmp_path / "q.csv"
    code, _, err = run(
        capsys, "ik", "delta", "--robot", "paper", "--branch", "in", "-i", src, "-o", out
    )
    assert code == 0, err
    assert "(branch in)" in err
    theta = columns(load(out), ("theta1", "theta2", "theta3"))
    np.testing.assert_allclose(delta_ref.fk_closed_form_numpy(theta), p, atol=1e-10)
    assert np.all(np.abs(theta - delta_ref.ik_numpy(p)) > 0.1)


def test_stdout_output(tmp_path, capsys):
    src = write_points(tmp_path / "in.csv", np.arange(3.0), np.array([[100.0, 0, 50]] * 3))
    code, out, _ = run(capsys, "ik", "scara", *SCARA_PAPER, "-q", "-i", src, "-o", "-")
    assert code == 0
    lines = out.splitlines()
    assert lines[0] == (
        "t,theta1,theta2,l3,theta1_dot,theta2_dot,l3_dot,theta1_ddot,theta2_ddot,l3_ddot,"
        "status,margin"
    )
    assert len(lines) == 4


def test_robot_file_toml_and_json(tmp_path, capsys):
    src = write_points(tmp_path / "in.csv", np.arange(3.0), np.array([[100.0, 0, 50]] * 3))
    toml = tmp_path / "robot.toml"
    toml.write_text('robot = "scara"\nl_oa = 150\nl_ab = 80\nl_bc = 50.0\n')
    code, _, err = run(capsys, "ik", "scara", "--robot", toml, "-i", src, "-o", tmp_path / "a.csv")
    assert code == 0, err
    json_file = tmp_path / "robot.json"
    json_file.write_text('{"l_oa": 150, "l_ab": 80, "l_bc": 50}')
    code, _, err = run(
        capsys, "ik", "scara", "--robot", json_file, "-i", src, "-o", tmp_path / "b.csv"
    )
    assert code == 0, err
    assert (tmp_path / "a.csv").read_text() == (tmp_path / "b.csv").read_text()
    # An option overrides the file: a longer forearm changes the answer.
    code, _, _ = run(
        capsys, "ik", "scara", "--robot", toml, "--l-bc", 60, "-i", src, "-o", tmp_path / "c.csv"
    )
    assert code == 0
    assert (tmp_path / "c.csv").read_text() != (tmp_path / "a.csv").read_text()


def test_anthropomorphic_branch_and_rates(tmp_path, capsys):
    """ik on the back_down branch: the joints, mapped by the arm's forward kinematics written
    out in NumPy [Lopez-Villagomez, eqs. 2-6], reproduce the path with its velocity and
    acceleration, and q1 is the back shoulder angle atan2(y, x) + pi."""
    t = np.linspace(0.0, 2.0, 21)
    p = np.stack([0.25 + 0.05 * np.cos(t), 0.05 * np.sin(2 * t), 0.35 + 0.02 * t], -1)
    v = np.stack([-0.05 * np.sin(t), 0.1 * np.cos(2 * t), np.full_like(t, 0.02)], -1)
    a = np.stack([-0.05 * np.cos(t), -0.2 * np.sin(2 * t), np.zeros_like(t)], -1)
    src = write_points(tmp_path / "in.csv", t, p, v, a)
    argv = ["anthropomorphic", *ARM, "--branch", "back_down"]
    code, _, err = run(capsys, "ik", *argv, "-i", src, "-o", tmp_path / "q.csv")
    assert code == 0, err
    q = load(tmp_path / "q.csv")
    joints = Jet.of(
        *(columns(q, [f"q{k}{suffix}" for k in (1, 2, 3)]) for suffix in ("", "_dot", "_ddot"))
    )
    back = forward("anthropomorphic", joints)  # the arm l1, l2, l3 = 0.3, 0.25, 0.2
    for got, block in zip((back.p, back.v, back.a), (p, v, a), strict=True):
        np.testing.assert_allclose(got, block, atol=1e-10)
    back_q1 = np.abs(wrap(q["q1"] - np.arctan2(p[:, 1], p[:, 0])))
    np.testing.assert_allclose(back_q1, np.pi, atol=1e-12)
    assert set(q["status"]) == {"OK"} and np.all((q["margin"] > 0) & (q["margin"] <= 1))
    code, _, err = run(
        capsys, "ik", "anthropomorphic", "--robot", "paper", "-i", src, "-o", tmp_path / "x.csv"
    )
    assert_one_line_error(code, err, "no anthropomorphic dimensions")
    code, _, err = run(capsys, "ik", *argv[:-1], "left", "-i", src, "-o", tmp_path / "x.csv")
    assert_one_line_error(code, err, "front_up, front_down, back_up, back_down")


def test_spherical_and_planar_2r(tmp_path, capsys):
    """Two of the new robots of the command: the spherical arm's joints from the [UANL]
    formulas written out here (q = (atan2(y, x), atan2(z - h, r), |p - (0, 0, h)|)); a planar
    2R file has x, y columns and its ik then fk close the loop."""
    p = np.array([[0.5, 0.2, 0.7], [-0.3, 0.4, 0.1], [0.2, -0.6, 0.4]])
    src = write_points(tmp_path / "in.csv", np.arange(3.0), p)
    r, dz = np.hypot(p[:, 0], p[:, 1]), p[:, 2] - 0.4
    expected = np.stack([np.arctan2(p[:, 1], p[:, 0]), np.arctan2(dz, r), np.hypot(r, dz)], -1)
    argv = ["-i", src, "-o", tmp_path / "s.csv", "--each-row"]  # scattered points, not a path
    code, _, err = run(capsys, "ik", "spherical", "--h", 0.4, *argv)
    assert code == 0, err
    q = load(tmp_path / "s.csv")
    np.testing.assert_allclose(columns(q, ("q1", "q2", "q3")), expected, atol=1e-12)
    assert set(q["status"]) == {"OK"} and np.all(q["margin"] > 0)
    xy = p[:, :2] * 2.0  # inside the annulus 0.4 <= r <= 1.6
    src = write_points(tmp_path / "xy.csv", np.arange(3.0), xy, names="xy")
    geometry = ["--l1", 1.0, "--l2", 0.6]
    argv = ["-i", src, "-o", tmp_path / "q.csv", "--each-row"]
    code, _, err = run(capsys, "ik", "planar-2r", *geometry, *argv)
    assert code == 0, err
    q = load(tmp_path / "q.csv")
    assert np.all(q["q2"] <= 0)  # elbow_up, the default branch
    assert set(q["status"]) == {"OK"} and np.all((q["margin"] > 0) & (q["margin"] <= 1))
    tip = np.stack(
        [
            np.cos(q["q1"]) + 0.6 * np.cos(q["q1"] + q["q2"]),
            np.sin(q["q1"]) + 0.6 * np.sin(q["q1"] + q["q2"]),
        ],
        -1,
    )
    np.testing.assert_allclose(tip, xy, atol=1e-12)
    code, _, err = run(
        capsys, "fk", "planar-2r", *geometry, "-i", tmp_path / "q.csv", "-o", tmp_path / "p.csv"
    )
    assert code == 0, err
    assert (tmp_path / "p.csv").read_text().splitlines()[0] == "t,x,y,vx,vy,ax,ay,status"
    np.testing.assert_allclose(columns(load(tmp_path / "p.csv"), "xy"), xy, atol=1e-12)


def test_no_geometry_uses_the_paper_robot_with_a_note(tmp_path, capsys):
    src = write_points(tmp_path / "in.csv", np.arange(3.0), np.array([[100.0, 0, 50]] * 3))
    code, _, err = run(capsys, "ik", "scara", "-i", src, "-o", tmp_path / "a.csv")
    assert code == 0
    assert "no geometry given, used the paper's scara (l_oa 150, l_ab 80, l_bc 50 mm)" in err


@pytest.mark.parametrize(
    ("kind", "options", "expected"),
    [
        ("scara", ["--robot", "paper"], scara.Scara(150.0, 80.0, 50.0)),
        ("delta", ["--robot", "paper"], delta.Delta(7.0, 2.5, 15.5, 30.0)),
        ("anthropomorphic", ARM, serial.Anthropomorphic(0.3, 0.25, 0.2)),
        ("cylindrical", ["--h", 0.4], serial.Cylindrical(0.4)),
        ("spherical", ["--h", 0.5], serial.Spherical(0.5)),
        ("planar-2r", ["--l1", 1.0, "--l2", 0.6], serial.Planar2R(1.0, 0.6)),
    ],
)
def test_robot_registry_builds_each_robot_from_its_options(kind, options, expected):
    """Every ``ROBOTS`` entry turns its options into the robot (the papers' dimensions for
    ``--robot paper``: [Noriega] 150, 80, 50 mm; [Cardona] 7, 2.5, 15.5, 30 cm)."""
    entry = ROBOTS[kind]
    assert isinstance(entry, RobotEntry) and entry.name == kind
    args = build_parser().parse_args(["ik", kind, *map(str, options), "-i", "in", "-o", "out"])
    args.notes = []
    robot = commands.robot_from_args(args)
    assert type(robot) is type(expected) and isinstance(robot, Robot)
    for key in entry.fields:
        assert float(getattr(robot, key)) == float(getattr(expected, key))
    assert robot.target.is_point and args.notes == []


def test_robot_registry_lists_the_command_robots():
    assert list(ROBOTS) == [
        "scara",
        "delta",
        "anthropomorphic",
        "cylindrical",
        "spherical",
        "planar-2r",
        "puma560",
        "stanford",
        "urdf",
    ]
    assert ROBOTS["scara"].unit == "mm" and ROBOTS["delta"].unit == "cm"


@pytest.mark.parametrize(
    "kind, options, robot",
    [
        ("puma560", ["--robot", "paper"], serial.Puma560()),
        ("stanford", ["--d1", 0.4, "--a2", 0.3, "--d6", 0.1], serial.Stanford(0.4, 0.3, 0.1)),
    ],
)
def test_six_joint_arms_round_trip_through_pose_files(tmp_path, capsys, kind, options, robot):
    """fk of a joint path writes the arm's poses (the library's FK); ik on the branch the
    joints lie on gives them back with their rates (linear joints: constant speeds)."""
    t = np.linspace(0.0, 1.0, 11)
    speeds = np.array([0.3, 0.2, -0.1, 0.05, 0.1, 0.2])
    q = np.array([0.2, -0.5, 0.3, 0.1, 0.6, -0.2]) + t[:, None] * speeds
    kio.write_table(
        tmp_path / "q.csv", {"t": t} | {n: q[:, j] for j, n in enumerate(robot.joint_names)}
    )
    code, _, err = run(
        capsys, "fk", kind, *options, "-i", tmp_path / "q.csv", "-o", tmp_path / "x.csv"
    )
    assert code == 0, err
    x = load(tmp_path / "x.csv")
    pose = np.asarray(jaxkin.fk(robot, q).x.p)
    np.testing.assert_allclose(columns(x, "xyz"), pose[:, :3, 3], rtol=0, atol=1e-12)
    every = serial.ik_all_branches(robot, pose[0]).q
    branch = robot.branches[int(np.argmin(np.abs(wrap(np.asarray(every) - q[0])).max(-1)))]
    code, _, err = run(
        capsys, "ik", kind, *options, "--branch", branch, "-i", tmp_path / "x.csv",
        "-o", tmp_path / "back.csv",
    )  # fmt: skip
    assert code == 0, err
    back = load(tmp_path / "back.csv")
    assert set(back["status"]) == {"OK"}
    np.testing.assert_allclose(wrap(columns(back, robot.joint_names) - q), 0.0, atol=1e-9)
    rates = columns(back, [n + "_dot" for n in robot.joint_names])
    np.testing.assert_allclose(rates, np.broadcast_to(speeds, q.shape), atol=1e-6)


# ------------------------------------------------------------------------------ NaN rows


def test_nan_rows_get_invalid_input_and_the_rest_is_solved(tmp_path, capsys):
    t = np.linspace(0.0, 8.0, 33)
    p, _, _ = spiral(t)
    p[[3, 17], 1] = np.nan
    p[20, 2] = np.inf
    src = write_points(tmp_path / "in.csv", t, p)
    code, _, err = run(capsys, "ik", "scara", *SCARA_PAPER, "-i", src, "-o", tmp_path / "q.csv")
    assert code == 0
    assert "warning: 3 of 33 rows have NaN/inf input (first at" in err
    assert f"{src}:5" in err  # row 3 is on line 5 (header on line 1)
    q = load(tmp_path / "q.csv")
    bad = np.zeros(33, bool)
    bad[[3, 17, 20]] = True
    assert set(q["status"][bad]) == {"INVALID_INPUT"}
    assert set(q["status"][~bad]) == {"OK"}
    assert np.all(np.isnan(q["theta1"][bad])) and np.all(np.isfinite(q["theta1_ddot"][~bad]))
    assert np.all(q["margin"][bad] == -1.0) and np.all(q["margin"][~bad] > 0)


def test_warning_when_no_row_is_solved(tmp_path, capsys):
    t = np.linspace(0.0, 8.0, 20)
    src = write_points(tmp_path / "mm.csv", t, spiral(t)[0])  # mm targets, cm robot
    code, _, err = run(
        capsys, "ik", "delta", "--robot", "paper", "-i", src, "-o", tmp_path / "q.csv"
    )
    assert code == 0
    assert "warning: no row has status OK (UNREACHABLE 20): check the geometry and the units" in err


# ------------------------------------------------------------------------------ error paths


@pytest.fixture
def good_csv(tmp_path):
    """Five rows: in chunks of 4 (``--chunk-size 4``), the shape of the 3-row files above."""
    t = np.linspace(0.0, 1.0, 5)
    return write_points(tmp_path / "good.csv", t, spiral(t)[0])


@pytest.mark.parametrize(
    ("text", "fragments"),
    [
        ("t,x,y,z\n0,100,0,50\n1,100,oops,50\n", ["bad.csv:3", "'y'", "not a number: 'oops'"]),
        ("t,x,y\n0,100,0\n", ["missing column(s) z", "found: t, x, y"]),
        ("t,x,y,z\n0,100,0,50\n1,100,0\n", ["bad.csv:3", "expected 4 fields"]),
        ("", ["empty file"]),
        ("t,x,y,z\n", ["no data rows"]),
        ("t,x,y,z\n0,100,0,50\n0,101,0,50\n", ["bad.csv:3", "t must increase strictly"]),
        ("t,candidate,x,y,z\n0,a,100,0,50\n", ["bad.csv:2", "'candidate'", "not a number"]),
        ("t,x,y,z,vx,vy\n0,100,0,50,1,1\n", ["velocity columns come as a set"]),
    ],
)
def test_bad_input_files(tmp_path, capsys, text, fragments):
    bad = tmp_path / "bad.csv"
    bad.write_text(text)
    code, _, err = run(capsys, "ik", "scara", *SCARA_PAPER, "-i", bad, "-o", tmp_path / "o.csv")
    assert_one_line_error(code, err, *fragments)
    assert not (tmp_path / "o.csv").exists()


def test_missing_and_unreadable_files(tmp_path, capsys, good_csv):
    code, _, err = run(
        capsys, "ik", "scara", *SCARA_PAPER, "-i", tmp_path / "nope.csv", "-o", tmp_path / "o.csv"
    )
    assert_one_line_error(code, err, "nope.csv: no such file")
    fake = tmp_path / "fake.npz"
    fake.write_bytes(b"PK\x03\x04 not really a zip")
    code, _, err = run(capsys, "fk", "delta", "-i", fake, "-o", tmp_path / "o.npz")
    assert_one_line_error(code, err, "not a readable .npz")
    code, _, err = run(
        capsys, "ik", "scara", *SCARA_PAPER, "-i", good_csv, "-o", tmp_path / "no" / "dir" / "o.csv"
    )
    assert_one_line_error(code, err, "does not exist")
    code, _, err = run(capsys, "ik", "scara", *SCARA_PAPER, "-i", good_csv, "-o", good_csv)
    assert_one_line_error(code, err, "is the input file")


@pytest.mark.parametrize(
    ("argv", "fragments"),
    [
        (
            ["ik", "scara", "--l-oa", "150", "--l-ab", "-80", "--l-bc", "50"],
            ["invalid scara geometry", "Scara.l_ab must be a positive"],
        ),
        (
            [
                "ik",
                "delta",
                "--r-base",
                "7",
                "--r-platform",
                "2.5",
                "--l-arm",
                "0",
                "--l-rod",
                "30",
            ],
            ["invalid delta geometry", "Delta.l_arm must be a positive"],
        ),
        (["ik", "scara", "--l-oa", "150", "--l-ab", "80"], ["missing geometry --l-bc"]),
        (["ik", "scara", "--robot", "paper", "--l-rod", "3"], ["--l-rod is a delta option"]),
        (["ik", "scara", "--robot", "paper", "--h", "3"], ["--h is a cylindrical/spherical"]),
        (["ik", "scara", "--robot", "paper", "--mode", "out"], ["--branch for Scara", "'out'"]),
        (["ik", "delta", "--robot", "paper", "--branch", "+1"], ["--branch for Delta"]),
        (["ik", "planar-2r", "--robot", "paper"], ["no planar-2r dimensions"]),
        (["ik", "puma", "--robot", "paper"], ["invalid choice: 'puma'"]),
        (["ik", "scara", "--robot", "nothere.toml"], ["nothere.toml: no such file"]),
        (["ik", "scara", "--robot", "paper", "--l-ab", "abc"], ["--l-ab", "invalid float value"]),
        (["ik", "scara", "--robot", "paper", "--dtype", "float16"], ["--dtype"]),
        (["ik", "scara", "--robot", "paper", "--chunk-size", "0"], ["--chunk-size"]),
        (["frobnicate"], ["invalid choice: 'frobnicate'"]),
        ([], ["required"]),
    ],
)
def test_bad_options(tmp_path, capsys, good_csv, argv, fragments):
    extra = ["-i", str(good_csv), "-o", str(tmp_path / "o.csv")] if argv[:1] == ["ik"] else []
    code, _, err = run(capsys, *argv, *extra)
    assert_one_line_error(code, err, *fragments)
    assert not (tmp_path / "o.csv").exists()


@pytest.mark.parametrize(
    ("name", "text", "fragments"),
    [
        ("r.toml", "l_oa = 150\nl_ab = 8 0\n", ["r.toml: invalid TOML", "line 2"]),
        ("r.json", '{"l_oa": 150,\n "l_ab": }', ["r.json:2: invalid JSON"]),
        ("r.toml", "l_oa = 150\nl_ab = 80\nl_bc = 50\nelbow = 3\n", ["unknown key(s) elbow"]),
        ("r.toml", 'l_oa = 150\nl_ab = "80"\nl_bc = 50\n', ["l_ab must be a number"]),
        ("r.toml", 'robot = "delta"\nl_oa = 1\n', ["describes a 'delta' robot, not 'scara'"]),
        ("r.yaml", "l_oa: 1\n", ["expected a .toml or .json file"]),
        ("r.toml", "l_oa = 150\nl_ab = 80\nl_bc = -5\n", ["invalid scara geometry"]),
    ],
)
def test_bad_robot_files(tmp_path, capsys, good_csv, name, text, fragments):
    spec = tmp_path / name
    spec.write_text(text)
    code, _, err = run(
        capsys, "ik", "scara", "--robot", spec, "-i", good_csv, "-o", tmp_path / "o.csv"
    )
    assert_one_line_error(code, err, *fragments)


def test_plot_without_matplotlib_fails_before_solving(tmp_path, capsys, good_csv, monkeypatch):
    monkeypatch.setitem(sys.modules, "matplotlib", None)  # import matplotlib -> ImportError
    monkeypatch.setitem(sys.modules, "matplotlib.figure", None)
    code, _, err = run(
        capsys,
        "ik",
        "scara",
        *SCARA_PAPER,
        "-i",
        good_csv,
        "-o",
        tmp_path / "o.csv",
        "--plot",
        tmp_path / "o.png",
    )
    assert_one_line_error(code, err, "pip install 'jaxkin[plot]'")
    assert not (tmp_path / "o.csv").exists()


# ------------------------------------------------------------------------- nothing is lost


def _precious(path):
    path.write_text("precious, do not truncate\n")
    return path.read_bytes()


def test_failed_run_leaves_existing_output_intact(tmp_path, capsys):
    out = tmp_path / "out.csv"
    before = _precious(out)
    bad = tmp_path / "bad.csv"
    bad.write_text("t,x,y,z\n0,1,2,3\n1,2,x,4\n")
    code, _, _ = run(capsys, "ik", "scara", *SCARA_PAPER, "-i", bad, "-o", out)
    assert code == 2 and out.read_bytes() == before


def test_solver_failing_midway_leaves_output_intact(tmp_path, capsys, good_csv, monkeypatch):
    out = tmp_path / "out.csv"
    before = _precious(out)
    calls = []
    original = commands.ik

    def failing_ik(robot, d, branch):
        calls.append(1)
        if len(calls) == 2:
            raise RuntimeError("simulated crash in the second chunk")
        return original(robot, d, branch)

    monkeypatch.setattr(commands, "ik", failing_ik)
    argv = ["--chunk-size", 4, "-i", good_csv, "-o", out, "--each-row"]
    code, _, err = run(capsys, "ik", "scara", *SCARA_PAPER, *argv)
    assert_one_line_error(code, err, "internal error (RuntimeError)", "simulated crash")
    assert len(calls) == 2 and out.read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["good.csv", "out.csv"]


@pytest.mark.parametrize("exc", [OSError("disk full"), KeyboardInterrupt()])
def test_writer_failing_midway_leaves_output_intact(tmp_path, capsys, good_csv, monkeypatch, exc):
    out = tmp_path / "out.csv"
    before = _precious(out)
    original = kio.write_csv

    def half_then_fail(f, columns, header=True):
        original(f, columns, header)  # the new content is in the temporary file...
        f.flush()
        raise exc  # ...and then the run dies before the rename

    monkeypatch.setattr(kio, "write_csv", half_then_fail)
    argv = ["--chunk-size", 4, "-i", good_csv, "-o", out]
    code, _, err = run(capsys, "ik", "scara", *SCARA_PAPER, *argv)
    if isinstance(exc, KeyboardInterrupt):
        assert code == 130 and "interrupted" in err
    else:
        assert_one_line_error(code, err, "disk full")
    assert out.read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["good.csv", "out.csv"]


@pytest.mark.parametrize("signum", [signal.SIGTERM, signal.SIGHUP])
def test_terminated_while_writing_leaves_no_temporary_file(
    tmp_path, capsys, good_csv, monkeypatch, signum
):
    """SIGTERM (or SIGHUP) arriving while the output is being written: the temporary file is
    removed, the old output kept, and the status is 128 + the signal's number."""
    out = tmp_path / "out.csv"
    before = _precious(out)
    original = kio.write_csv

    def write_then_signal(f, columns, header=True):
        original(f, columns, header)
        f.flush()
        assert any(p.name.startswith(".out.csv.") for p in tmp_path.iterdir())
        os.kill(os.getpid(), signum)  # delivered to this (the main) thread

    monkeypatch.setattr(kio, "write_csv", write_then_signal)
    handler = signal.getsignal(signum)
    code, _, err = run(capsys, "ik", "scara", *SCARA_PAPER, "-i", good_csv, "-o", out)
    assert code == 128 + signum and "terminated by signal" in err
    assert out.read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["good.csv", "out.csv"]
    assert signal.getsignal(signum) == handler  # restored after the command


def test_output_is_written_chunk_by_chunk(tmp_path, capsys, good_csv, monkeypatch):
    """Each chunk's rows are written as soon as they are solved (memory bounded by a chunk):
    five rows in chunks of 4 are two writes, one header, the same file as one chunk gives."""
    code, _, err = run(
        capsys, "ik", "scara", *SCARA_PAPER, "-i", good_csv, "-o", tmp_path / "a.csv", "--each-row"
    )
    assert code == 0, err
    parts = []
    original = kio.write_csv

    def counted(f, columns, header=True):
        parts.append((len(next(iter(columns.values()))), header))
        original(f, columns, header)

    monkeypatch.setattr(kio, "write_csv", counted)
    argv = ["--chunk-size", 4, "-i", good_csv, "-o", tmp_path / "b.csv", "--each-row"]
    code, _, err = run(capsys, "ik", "scara", *SCARA_PAPER, *argv)
    assert code == 0, err
    assert parts == [(4, True), (1, False)]
    assert (tmp_path / "a.csv").read_text() == (tmp_path / "b.csv").read_text()


# --------------------------------------------------------------------------------- workspace


def test_workspace_scara_volume_and_npz(tmp_path, capsys):
    out = tmp_path / "ws.npz"
    geometry = ["--l-oa", 10, "--l-ab", 8, "--l-bc", 5]
    code, stdout, err = run(
        capsys, "workspace", "scara", *geometry, "--resolution", 0.5, "-q", "-o", out
    )
    assert code == 0, err
    with np.load(out) as ws:
        mask, res = ws["mask"], float(ws["resolution"])
        assert ws["volume"] == pytest.approx(mask.sum() * res**3)
        assert float(ws["geometry_l_ab"]) == 8.0 and str(ws["robot"]) == "scara"
        assert mask.shape == (len(ws["x"]), len(ws["y"]), len(ws["z"]))
    # Annulus 3 <= r <= 13 times the height 10 (z from 0 to l_oa): pi (13^2 - 3^2) 10.
    exact = np.pi * (13**2 - 3**2) * 10.0
    volume = float(stdout.split("reachable volume: ")[1].split()[0])
    assert volume == pytest.approx(exact * 21 / 20, rel=0.03)  # 21 z-layers of 0.5 over 10
    assert "voxels of edge 0.5" in stdout


def test_workspace_anthropomorphic_is_a_spherical_shell(capsys):
    code, stdout, _ = run(capsys, "workspace", "anthropomorphic", *ARM, "--resolution", 0.03, "-q")
    assert code == 0
    # Reachable wrist positions: |p - shoulder| between l2 - l3 and l2 + l3.
    exact = 4 / 3 * np.pi * (0.45**3 - 0.05**3)
    volume = float(stdout.split("reachable volume: ")[1].split()[0])
    assert volume == pytest.approx(exact, rel=0.03)


def test_workspace_planar_2r_area_with_four_bounds(capsys):
    """A planar robot sweeps a 2-D grid; ``--bounds`` takes 4 numbers for it, 6 for a 3-D
    robot, and the area of the annulus 0.4 <= r <= 1.6 is pi (1.6^2 - 0.4^2)."""
    geometry = ["--l1", 1.0, "--l2", 0.6, "--resolution", 0.05, "-q"]
    code, stdout, err = run(
        capsys, "workspace", "planar-2r", *geometry, "--bounds", -1.6, 1.6, -1.6, 1.6
    )
    assert code == 0, err
    area = float(stdout.split("reachable area: ")[1].split()[0])
    assert area == pytest.approx(np.pi * (1.6**2 - 0.4**2), rel=0.02)
    assert "of 4225 voxels of edge 0.05" in stdout  # 65 x 65
    bounds = ["--bounds", 0, 1, 0, 1, 0, 1]
    code, _, err = run(capsys, "workspace", "planar-2r", *geometry, *bounds)
    assert_one_line_error(code, err, "--bounds: planar-2r needs 4 numbers")
    code, _, err = run(capsys, "workspace", "scara", "--robot", "paper", *bounds[:5])
    assert_one_line_error(code, err, "--bounds: scara needs 6 numbers")
    code, _, err = run(
        capsys, "workspace", "scara", "--robot", "paper", "--bounds", 1, 0, 0, 1, 0, 1
    )
    assert_one_line_error(code, err, "--bounds: need finite xmin <= xmax")


def test_workspace_delta_bounds_and_errors(tmp_path, capsys):
    code, stdout, err = run(
        capsys,
        "workspace",
        "delta",
        "--robot",
        "paper",
        "--resolution",
        2,
        "--bounds",
        -4,
        4,
        -4,
        4,
        -34,
        -26,
        "-q",
    )
    assert code == 0, err
    # Every voxel of this small box below the centre is reachable: 5 x 5 x 5 of edge 2.
    assert "125 of 125 voxels" in stdout
    code, _, err = run(capsys, "workspace", "delta", "--robot", "paper", "--resolution", 0)
    assert_one_line_error(code, err, "--resolution must be positive")
    code, _, err = run(capsys, "workspace", "delta", "--robot", "paper", "-o", tmp_path / "w.csv")
    assert_one_line_error(code, err, "saved as .npz")
    code, _, err = run(capsys, "workspace", "delta", "--robot", "paper", "--resolution", 1e-4)
    assert_one_line_error(code, err, "voxels is too many")


# ------------------------------------------------------------------------------------- demo


def test_demo_list_and_errors(capsys, monkeypatch, tmp_path):
    """``--list`` shows every shipped example (whatever the set), one line each with its
    summary, the default marked; unknown names, a missing output folder and a missing
    ``jaxkin.examples`` package are one-line errors."""
    code, out, err = run(capsys, "demo", "--list")
    assert code == 0, err
    found = demo.examples()
    lines = out.splitlines()
    assert [line.split()[0] for line in lines] == list(found)
    assert demo.DEFAULT == "planner-scara" and demo.DEFAULT in found
    assert all(len(line.split()) > 1 for line in lines)  # a summary on every line
    assert [line for line in lines if line.endswith("(default)")] == [
        next(line for line in lines if line.split()[0] == demo.DEFAULT)
    ]
    code, _, err = run(capsys, "demo", "no-such-example")
    assert_one_line_error(code, err, "example 'no-such-example' is not an example", demo.DEFAULT)
    code, _, err = run(capsys, "demo", "--output-dir", tmp_path / "missing", demo.DEFAULT)
    assert_one_line_error(code, err, "--output-dir", "no such directory")
    monkeypatch.setattr(demo, "examples", dict)
    code, _, err = run(capsys, "demo")
    assert_one_line_error(code, err, "no examples installed")


def test_demo_runs_the_named_example_in_process(capsys, monkeypatch, tmp_path):
    """The default, a name and a unique prefix each run one example in this process as
    ``__main__`` with ``--output-dir`` and the remaining arguments; its exit status is the
    command's. (Example scripts written here: the shipped set may change.)"""
    scripts = {}
    for name in ("planner-scara", "planner-delta", "dyad", "delta-workspace"):
        path = tmp_path / (name.replace("-", "_") + ".py")
        path.write_text(f'"""The {name} example."""\n')
        scripts[name] = path
    monkeypatch.setattr(demo, "examples", lambda: dict(scripts))
    seen = []

    def fake_run(path, run_name):
        seen.append((Path(path).name, run_name, list(sys.argv)))
        if Path(path).name == "dyad.py":
            raise SystemExit(3)  # the example's exit status is the command's

    monkeypatch.setattr(demo.runpy, "run_path", fake_run)
    argv = sys.argv
    assert run(capsys, "demo", "--output-dir", tmp_path)[0] == 0
    assert run(capsys, "demo", "dyad")[0] == 3
    assert run(capsys, "demo", "delta-work", "--resolution", "5")[0] == 0  # unique prefix
    assert sys.argv == argv  # restored
    assert [s[0] for s in seen] == ["planner_scara.py", "dyad.py", "delta_workspace.py"]
    assert all(s[1] == "__main__" for s in seen)
    assert seen[0][2] == [str(scripts["planner-scara"]), "--output-dir", str(tmp_path)]
    assert seen[2][2][1:] == ["--output-dir", ".", "--resolution", "5"]
    code, _, err = run(capsys, "demo", "planner")
    assert_one_line_error(code, err, "example 'planner' is ambiguous")


def test_demo_output_dir_after_the_name_is_the_commands(capsys, monkeypatch, tmp_path):
    """``jaxkin demo NAME --output-dir X``: X is checked before the example runs (a missing
    one is an error naming it) and passed on once; the announcement names it."""
    script = tmp_path / "dyad_demo.py"
    script.write_text('"""The dyad example."""\n')
    monkeypatch.setattr(demo, "examples", lambda: {"dyad": script})
    seen = []
    monkeypatch.setattr(demo.runpy, "run_path", lambda path, run_name: seen.append(sys.argv))
    code, _, err = run(capsys, "demo", "dyad", "--output-dir", tmp_path / "missing", "--n", "3")
    assert_one_line_error(code, err, "--output-dir", "missing: no such directory")
    assert seen == []
    code, _, err = run(capsys, "demo", "dyad", "--n", "3", f"--output-dir={tmp_path}")
    assert code == 0 and f"files go to {tmp_path}" in err
    assert seen == [[str(script), "--output-dir", str(tmp_path), "--n", "3"]]


def test_demo_runs_a_shipped_example(capsys, tmp_path):
    """A quick shipped example (the dyad batch, no files) runs for real, in this process."""
    assert "dyad" in demo.examples()
    code, out, err = run(capsys, "demo", "--output-dir", tmp_path, "dyad")
    assert code == 0, err
    assert "running the dyad example" in err and out.strip()


# ------------------------------------------------------------------------------------- help


@pytest.mark.parametrize(
    ("argv", "expected"),
    [
        ([], ["demo", "ik", "fk", "workspace"]),
        (["demo"], ["NAME", "--list", "--output-dir"]),
        (
            ["ik"],
            [
                "ROBOT",
                "--input",
                "--output",
                "--robot",
                "--l-oa",
                "--r-base",
                "--h",
                "--branch",
                "--mode",
                "--dtype",
                "--spline",
                "--plot",
                "cylindrical",
                "spherical",
                "planar-2r",
            ],
        ),
        (["fk"], ["ROBOT", "--input", "--output", "--l-rod"]),
        (["workspace"], ["--resolution", "--bounds", "--plot", "--output", "[ZMIN ZMAX]"]),
    ],
)
def test_help(capsys, argv, expected):
    with pytest.raises(SystemExit) as info:
        cli.main([*argv, "--help"])
    assert info.value.code == 0
    out = capsys.readouterr().out
    assert out.startswith("usage: jaxkin")
    for word in expected:
        assert word in out


def test_version(capsys):
    from jaxkin import __version__

    with pytest.raises(SystemExit) as info:
        cli.main(["--version"])
    assert info.value.code == 0
    assert capsys.readouterr().out.strip() == f"jaxkin {__version__}"


class _Terminal(io.StringIO):
    def isatty(self):
        return True


def test_help_imports_no_jax():
    """``jaxkin --help``, a subcommand's ``--help`` and ``--version`` (a fresh process) load
    neither JAX nor NumPy: the parser names the subcommands' modules, imported when one runs."""
    argvs = [["--help"], ["ik", "--help"], ["plan", "--help"], ["workspace", "--help"]]
    argvs += [["demo", "--help"], ["--version"]]
    script = (
        "import sys\n"
        "from jaxkin import cli\n"
        f"for argv in {argvs!r}:\n"
        "    try:\n"
        "        cli.main(argv)\n"
        "    except SystemExit as exit:\n"
        "        assert exit.code == 0, (argv, exit.code)\n"
        "print(sorted(m for m in ('jax', 'numpy', 'jaxkin.robot') if m in sys.modules))\n"
    )
    done = subprocess.run(
        [sys.executable, "-c", script], capture_output=True, text=True, timeout=300, check=True
    )
    assert done.stdout.strip().splitlines()[-1] == "[]"
    assert "usage: jaxkin workspace" in done.stdout


def test_parser_spells_the_spline_ends_of_the_library():
    from jaxkin import _splines
    from jaxkin.cli import parser

    assert parser.SPLINE_ENDS == _splines.END_CONDITIONS


def test_progress_bar_only_on_a_terminal(monkeypatch):
    """Without tqdm (its import blocked) the command draws its own bar, on a terminal only."""
    monkeypatch.setitem(sys.modules, "tqdm", None)
    pipe = io.StringIO()
    with progress.bar(10, "work", stream=pipe) as bar:
        bar.update(10)
    assert pipe.getvalue() == ""
    term = _Terminal()
    with progress.bar(10, "work", stream=term) as bar:
        assert isinstance(bar, progress.TextBar)
        for _ in range(10):
            bar.update(1)
    text = term.getvalue()
    assert text.startswith("\rwork [") and "100%" in text and text.endswith("\n")
    quiet = _Terminal()
    with progress.bar(10, "work", enabled=False, stream=quiet) as bar:
        bar.update(10)
    assert quiet.getvalue() == ""


def test_progress_bar_is_tqdm_when_installed():
    """With the cli extra's tqdm the bar is tqdm's, on a terminal only (the same policy)."""
    tqdm = pytest.importorskip("tqdm")
    term = _Terminal()
    with progress.bar(10, "work", stream=term) as bar:
        assert isinstance(bar, tqdm.tqdm)
        bar.update(10)
    assert "work" in term.getvalue() and "100%" in term.getvalue()
    pipe = io.StringIO()
    with progress.bar(10, "work", stream=pipe) as bar:
        assert isinstance(bar, progress.NullBar)


@pytest.mark.parametrize("tqdm_installed", [True, False])
def test_progress_callback_of_a_library_call_draws_one_bar(monkeypatch, tqdm_installed):
    """``reporting`` turns a library's ``progress(done, total)`` into one bar of ``total``
    (workspace.sweep's calls: (0, 2197), then after each chunk of 1000 voxels)."""
    if tqdm_installed:
        pytest.importorskip("tqdm")
    else:
        monkeypatch.setitem(sys.modules, "tqdm", None)
    term = _Terminal()
    with progress.reporting("workspace", stream=term) as report:
        for done in (0, 1000, 2000, 2197):
            report(done, 2197)
    text = term.getvalue()
    assert "workspace" in text and "100%" in text
    assert text.endswith("\n")  # closed: the bar's line ended
    quiet = _Terminal()
    with progress.reporting("workspace", enabled=False, stream=quiet) as report:
        report(0, 10)
        report(10, 10)
    assert quiet.getvalue() == ""


# ------------------------------------------------------------------------- a real process


def test_console_script_end_to_end(tmp_path):
    """The installed ``jaxkin`` script in a fresh process (JAX's 64-bit mode off until the
    command turns it on): a float32 solve writes float32 columns equal to the elbow-out
    reference; a bad geometry exits with status 2 and one line, the output untouched."""
    exe = shutil.which("jaxkin", path=str(Path(sys.executable).parent))
    assert exe is not None, "the jaxkin console script is not installed"
    t = np.linspace(0.0, 2.0, 21)
    p, v, a = delta_path(t)
    src = write_points(tmp_path / "in.npz", t, p, v, a)
    out = tmp_path / "q.npz"
    argv = ["ik", "delta", "--robot", "paper", "--dtype", "float32", "-i", src, "-o", out]
    proc = subprocess.run(
        [exe, *map(str, argv)], capture_output=True, text=True, timeout=120, cwd=tmp_path
    )
    assert proc.returncode == 0, proc.stderr
    q = load(out)
    assert q["theta1"].dtype == np.float32 and set(q["status"].tolist()) == {"OK"}
    theta = columns(q, ("theta1", "theta2", "theta3"))
    np.testing.assert_allclose(theta, delta_ref.ik_numpy(p), atol=1e-4)
    before = out.read_bytes()
    argv = ["ik", "delta", "--l-arm", "-1", "-i", src, "-o", out]
    proc = subprocess.run(
        [exe, *map(str, argv)], capture_output=True, text=True, timeout=120, cwd=tmp_path
    )
    assert proc.returncode == 2
    assert proc.stderr.count("\n") == 1 and proc.stderr.startswith("jaxkin: error: ")
    assert "Traceback" not in proc.stderr
    assert out.read_bytes() == before
