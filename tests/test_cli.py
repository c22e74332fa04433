"""The ``jaxkin`` command: round trips, every error path (one line, exit 2), no partial output.

Most tests call ``jaxkin.cli.main(argv)`` in-process (a process start imports JAX, ~1-2 s);
a few real subprocess round trips check the installed console script end to end.
"""

import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from jaxkin import cli
from jaxkin import io as kio

ROOT = Path(__file__).resolve().parents[1]
SCARA_PAPER = ["--robot", "paper"]


def spiral(t):
    """Seed 000 eq. 16 with its exact derivatives (mm, s)."""
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


def write_points(path, t, p, v=None, a=None, candidate=None):
    cols = {"t": t}
    if candidate is not None:
        cols["candidate"] = candidate
    cols.update({"x": p[:, 0], "y": p[:, 1], "z": p[:, 2]})
    for block, names in ((v, kio.CARTESIAN_VELOCITY), (a, kio.CARTESIAN_ACCELERATION)):
        if block is not None:
            cols.update({n: block[:, j] for j, n in enumerate(names)})
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


def assert_one_line_error(code, err, *fragments):
    assert code == 2
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith("jaxkin: error: ")
    assert "Traceback" not in err
    for fragment in fragments:
        assert fragment in lines[0], lines[0]


# ------------------------------------------------------------------------------ round trips


@pytest.mark.parametrize("mode", ["+1", "-1"])
def test_scara_csv_round_trip_with_spline_rates(tmp_path, capsys, mode):
    t = np.linspace(0.0, 8.0, 161)
    p, v, a = spiral(t)
    src = write_points(tmp_path / "in.csv", t, p)  # positions only: rates by spline
    code, _, err = run(
        capsys, "ik", "scara", *SCARA_PAPER, "--mode", mode, "-i", src, "-o", tmp_path / "q.csv"
    )
    assert code == 0, err
    assert "OK 161" in err
    q = load(tmp_path / "q.csv")
    assert set(q["status"]) == {"OK"}
    code, _, err = run(
        capsys, "fk", "scara", *SCARA_PAPER, "-i", tmp_path / "q.csv", "-o", tmp_path / "p.csv"
    )
    assert code == 0, err
    back = load(tmp_path / "p.csv")
    np.testing.assert_allclose(np.stack([back[k] for k in "xyz"], -1), p, rtol=0, atol=1e-9)
    # Spline rates (h = 0.05 s) against the exact derivatives of eq. 16: velocity to ~1e-3
    # of its scale (|v| ~ 31 mm/s), acceleration to ~1 % (|a| ~ 49 mm/s^2, worst at the ends).
    v_back = np.stack([back[k] for k in ("vx", "vy", "vz")], -1)
    a_back = np.stack([back[k] for k in ("ax", "ay", "az")], -1)
    np.testing.assert_allclose(v_back, v, atol=0.03)
    np.testing.assert_allclose(a_back, a, atol=0.5)
    np.testing.assert_allclose(a_back[5:-5], a[5:-5], atol=0.05)  # h^2 |y""""| / 12 ~ 0.025


def test_scara_given_rates_reproduce_library_and_paper_value(tmp_path, capsys):
    from jaxkin import Jet, scara

    t = np.linspace(0.0, 8.0, 33)
    p, v, a = spiral(t)
    src = write_points(tmp_path / "in.npz", t, p, v, a)
    code, _, err = run(
        capsys,
        "ik",
        "scara",
        "--l-oa",
        150,
        "--l-ab",
        80,
        "--l-bc",
        50,
        "-i",
        src,
        "-o",
        tmp_path / "q.npz",
    )
    assert code == 0, err
    q = load(tmp_path / "q.npz")
    ref = scara.ik(scara.Scara.create(150.0, 80.0, 50.0), Jet.of(p, v, a), mode=1)
    got = np.stack([q[k] for k in ("theta1_ddot", "theta2_ddot", "l3_ddot")], -1)
    np.testing.assert_allclose(got, np.asarray(ref.q.a), rtol=1e-12, atol=1e-12)
    # ERRATA seed 000 item 4: theta1_ddot(0) = 0.309 rad/s^2 on the spiral, mode +1.
    assert q["theta1_ddot"][0] == pytest.approx(0.309, abs=5e-4)
    np.testing.assert_allclose(q["margin"], np.asarray(ref.margin), rtol=1e-12)


def test_delta_npz_round_trip_with_candidates(tmp_path, capsys):
    t = np.linspace(0.0, 2.0, 41)
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
    np.testing.assert_allclose(np.stack([back[k] for k in "xyz"], -1), p2, atol=1e-9)
    # Candidate 0's velocity from splines of theta, mapped back by fk: close to the exact one.
    v_back = np.stack([back[k] for k in ("vx", "vy", "vz")], -1)[: len(t)]
    np.testing.assert_allclose(v_back, v, atol=0.05)


def test_delta_branch_in_and_float32(tmp_path, capsys):
    t = np.linspace(0.0, 2.0, 21)
    p, v, a = delta_path(t)
    src = write_points(tmp_path / "in.csv", t, p, v, a)
    outs = {}
    for dtype in ("float64", "float32"):
        out = tmp_path / f"q_{dtype}.csv"
        code, _, err = run(
            capsys,
            "ik",
            "delta",
            "--robot",
            "paper",
            "--mode",
            "in",
            "--dtype",
            dtype,
            "-i",
            src,
            "-o",
            out,
        )
        assert code == 0, err
        outs[dtype] = load(out)
    for key in ("theta1", "theta2", "theta3"):
        np.testing.assert_allclose(outs["float32"][key], outs["float64"][key], atol=1e-4)
    from jaxkin import delta

    ref = delta.ik(delta.Delta.paper(), p, branch="in").theta.p
    np.testing.assert_allclose(outs["float64"]["theta1"], np.asarray(ref)[:, 0], rtol=1e-12)


def test_stdout_output(tmp_path, capsys):
    src = write_points(tmp_path / "in.csv", np.arange(3.0), np.array([[100.0, 0, 50]] * 3))
    code, out, _ = run(capsys, "ik", "scara", *SCARA_PAPER, "-q", "-i", src, "-o", "-")
    assert code == 0
    assert out.splitlines()[0].startswith("t,theta1,theta2,l3,")
    assert len(out.splitlines()) == 4


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


def test_anthropomorphic_round_trip_and_rates(tmp_path, capsys):
    from jaxkin import Jet, lift
    from jaxkin.serial import arms

    t = np.linspace(0.0, 2.0, 21)
    p = np.stack([0.25 + 0.05 * np.cos(t), 0.05 * np.sin(2 * t), 0.35 + 0.02 * t], -1)
    v = np.stack([-0.05 * np.sin(t), 0.1 * np.cos(2 * t), np.full_like(t, 0.02)], -1)
    a = np.stack([-0.05 * np.cos(t), -0.2 * np.sin(2 * t), np.zeros_like(t)], -1)
    src = write_points(tmp_path / "in.csv", t, p, v, a)
    geometry = ["--l1", 0.3, "--l2", 0.25, "--l3", 0.2]
    code, _, err = run(
        capsys,
        "ik",
        "anthropomorphic",
        *geometry,
        "--mode",
        "back_down",
        "-i",
        src,
        "-o",
        tmp_path / "q.csv",
    )
    assert code == 0, err
    code, _, err = run(
        capsys,
        "fk",
        "anthropomorphic",
        *geometry,
        "-i",
        tmp_path / "q.csv",
        "-o",
        tmp_path / "p.csv",
    )
    assert code == 0, err
    back = load(tmp_path / "p.csv")
    # fk(ik(x)) reproduces the path and, through the joint rates, its velocity and acceleration.
    for block, names in ((p, "xyz"), (v, ("vx", "vy", "vz")), (a, ("ax", "ay", "az"))):
        np.testing.assert_allclose(np.stack([back[k] for k in names], -1), block, atol=1e-10)
    robot = arms.Anthropomorphic(0.3, 0.25, 0.2)
    ref = lift(lambda x: arms.ik(robot, x).branch("back_down").q)(Jet.of(p, v, a))
    q = load(tmp_path / "q.csv")
    np.testing.assert_allclose(q["q2_dot"], np.asarray(ref.v)[:, 1], rtol=1e-12, atol=1e-14)
    code, _, err = run(
        capsys, "ik", "anthropomorphic", "--robot", "paper", "-i", src, "-o", tmp_path / "x.csv"
    )
    assert_one_line_error(code, err, "no anthropomorphic dimensions")
    code, _, err = run(
        capsys,
        "ik",
        "anthropomorphic",
        *geometry,
        "--mode",
        "left",
        "-i",
        src,
        "-o",
        tmp_path / "x.csv",
    )
    assert_one_line_error(code, err, "front_up, front_down, back_up, back_down")


def test_no_geometry_uses_the_paper_robot_with_a_note(tmp_path, capsys):
    src = write_points(tmp_path / "in.csv", np.arange(2.0), np.array([[100.0, 0, 50]] * 2))
    code, _, err = run(capsys, "ik", "scara", "-i", src, "-o", tmp_path / "a.csv")
    assert code == 0
    assert "no geometry given, used the paper's scara (l_oa 150, l_ab 80, l_bc 50 mm)" in err


# ------------------------------------------------------------------------------ NaN rows


def test_nan_rows_get_invalid_input_and_the_rest_is_solved(tmp_path, capsys):
    t = np.linspace(0.0, 8.0, 41)
    p, _, _ = spiral(t)
    p[[3, 17], 1] = np.nan
    p[20, 2] = np.inf
    src = write_points(tmp_path / "in.csv", t, p)
    code, _, err = run(capsys, "ik", "scara", *SCARA_PAPER, "-i", src, "-o", tmp_path / "q.csv")
    assert code == 0
    assert "warning: 3 of 41 rows have NaN/inf input (first at" in err
    assert f"{src}:5" in err  # row 3 is on line 5 (header on line 1)
    q = load(tmp_path / "q.csv")
    bad = np.zeros(41, bool)
    bad[[3, 17, 20]] = True
    assert set(q["status"][bad]) == {"INVALID_INPUT"}
    assert set(q["status"][~bad]) == {"OK"}
    assert np.all(np.isnan(q["theta1"][bad])) and np.all(np.isfinite(q["theta1_ddot"][~bad]))


def test_warning_when_no_row_is_solved(tmp_path, capsys):
    t = np.linspace(0.0, 8.0, 9)
    src = write_points(tmp_path / "mm.csv", t, spiral(t)[0])  # mm targets, cm robot
    code, _, err = run(
        capsys, "ik", "delta", "--robot", "paper", "-i", src, "-o", tmp_path / "q.csv"
    )
    assert code == 0
    assert "warning: no row has status OK (UNREACHABLE 9): check the geometry and the units" in err


# ------------------------------------------------------------------------------ error paths


@pytest.fixture
def good_csv(tmp_path):
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


@pytest.mark.parametrize(
    ("argv", "fragments"),
    [
        (
            ["ik", "scara", "--l-oa", "150", "--l-ab", "-80", "--l-bc", "50"],
            ["invalid scara geometry", "l_ab must be positive"],
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
            ["invalid delta geometry", "l_arm must be positive"],
        ),
        (["ik", "scara", "--l-oa", "150", "--l-ab", "80"], ["missing geometry --l-bc"]),
        (["ik", "scara", "--robot", "paper", "--l-rod", "3"], ["--l-rod is a delta option"]),
        (["ik", "scara", "--robot", "paper", "--mode", "out"], ["--mode for scara", "'out'"]),
        (["ik", "delta", "--robot", "paper", "--mode", "+1"], ["--mode for delta"]),
        (["ik", "puma", "--robot", "paper"], ["invalid choice: 'puma'"]),
        (["ik", "scara", "--robot", "nothere.toml"], ["nothere.toml: no such file"]),
        (["ik", "scara", "--robot", "paper", "--l-ab", "abc"], ["--l-ab", "invalid float value"]),
        (["ik", "scara", "--robot", "paper", "--dtype", "float16"], ["--dtype"]),
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
    original = cli.ROBOTS["scara"].ik

    def failing_ik(robot, d, mode):
        calls.append(1)
        if len(calls) == 2:
            raise RuntimeError("simulated crash in the second chunk")
        return original(robot, d, mode)

    monkeypatch.setitem(
        cli.ROBOTS, "scara", cli.dataclasses.replace(cli.ROBOTS["scara"], ik=failing_ik)
    )
    code, _, err = run(
        capsys, "ik", "scara", *SCARA_PAPER, "--chunk-size", 2, "-i", good_csv, "-o", out
    )
    assert_one_line_error(code, err, "simulated crash")
    assert len(calls) == 2 and out.read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["good.csv", "out.csv"]


@pytest.mark.parametrize("exc", [OSError("disk full"), KeyboardInterrupt()])
def test_writer_failing_midway_leaves_output_intact(tmp_path, capsys, good_csv, monkeypatch, exc):
    out = tmp_path / "out.csv"
    before = _precious(out)
    original = kio.write_csv

    def half_then_fail(f, columns):
        original(f, columns)  # the whole new content is in the temporary file...
        f.flush()
        raise exc  # ...and then the run dies before the rename

    monkeypatch.setattr(kio, "write_csv", half_then_fail)
    code, _, err = run(capsys, "ik", "scara", *SCARA_PAPER, "-i", good_csv, "-o", out)
    if isinstance(exc, KeyboardInterrupt):
        assert code == 130 and "interrupted" in err
    else:
        assert_one_line_error(code, err, "disk full")
    assert out.read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["good.csv", "out.csv"]


# --------------------------------------------------------------------------------- workspace


def test_workspace_scara_volume_and_npz(tmp_path, capsys):
    out = tmp_path / "ws.npz"
    code, stdout, err = run(
        capsys,
        "workspace",
        "scara",
        "--l-oa",
        10,
        "--l-ab",
        8,
        "--l-bc",
        5,
        "--resolution",
        0.5,
        "-q",
        "-o",
        out,
    )
    assert code == 0, err
    with np.load(out) as ws:
        mask, res = ws["mask"], float(ws["resolution"])
        assert ws["volume"] == pytest.approx(mask.sum() * res**3)
        assert float(ws["geometry_l_ab"]) == 8.0
    # Annulus 3 <= r <= 13 times the height 10 (z from 0 to l_oa): pi (13^2 - 3^2) 10.
    exact = np.pi * (13**2 - 3**2) * 10.0
    volume = float(stdout.split("reachable volume: ")[1].split()[0])
    assert volume == pytest.approx(exact * 21 / 20, rel=0.03)  # 21 z-layers of 0.5 over 10
    assert "voxels of edge 0.5" in stdout


def test_workspace_anthropomorphic_is_a_spherical_shell(capsys):
    code, stdout, _ = run(
        capsys,
        "workspace",
        "anthropomorphic",
        "--l1",
        0.3,
        "--l2",
        0.25,
        "--l3",
        0.2,
        "--resolution",
        0.03,
        "-q",
    )
    assert code == 0
    # Reachable wrist positions: |p - shoulder| between l2 - l3 and l2 + l3.
    exact = 4 / 3 * np.pi * (0.45**3 - 0.05**3)
    volume = float(stdout.split("reachable volume: ")[1].split()[0])
    assert volume == pytest.approx(exact, rel=0.03)


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


# ------------------------------------------------------------------------------------- demo


def test_demo_list_and_errors(capsys, monkeypatch, tmp_path):
    code, out, _ = run(capsys, "demo", "--list")
    assert code == 0
    names = [line.split()[0] for line in out.splitlines()]
    assert "scara-spiral" in names and "dyad" in names
    code, _, err = run(capsys, "demo", "no-such-example")
    assert_one_line_error(code, err, "example 'no-such-example' is not present", "scara-spiral")
    monkeypatch.setattr(cli, "EXAMPLES_DIR", tmp_path / "missing")
    code, _, err = run(capsys, "demo")
    assert_one_line_error(code, err, "no examples found")


def test_demo_runs_the_named_script(capsys, monkeypatch):
    seen = []
    monkeypatch.setattr(cli.subprocess, "call", lambda cmd: seen.append(cmd) or 0)
    assert run(capsys, "demo")[0] == 0
    assert run(capsys, "demo", "dyad")[0] == 0
    assert run(capsys, "demo", "delta-work", "--resolution", "5")[0] == 0  # unique prefix
    assert Path(seen[0][1]) == ROOT / "examples" / "scara_spiral.py"
    assert Path(seen[1][1]) == ROOT / "examples" / "dyad_demo.py"
    assert seen[2][1:] == [str(ROOT / "examples" / "delta_workspace.py"), "--resolution", "5"]
    assert seen[0][0] == sys.executable
    monkeypatch.setattr(cli.subprocess, "call", lambda cmd: 3)  # the example's exit status
    assert run(capsys, "demo", "dyad")[0] == 3


# ------------------------------------------------------------------------------------- help


@pytest.mark.parametrize(
    ("argv", "expected"),
    [
        ([], ["demo", "ik", "fk", "workspace"]),
        (["demo"], ["NAME", "--list"]),
        (
            ["ik"],
            [
                "ROBOT",
                "--input",
                "--output",
                "--robot",
                "--l-oa",
                "--r-base",
                "--mode",
                "--dtype",
                "--spline",
                "--plot",
            ],
        ),
        (["fk"], ["ROBOT", "--input", "--output", "--l-rod"]),
        (["workspace"], ["--resolution", "--bounds", "--plot", "--output"]),
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


def test_progress_bar_only_on_a_terminal(monkeypatch):
    import io

    from jaxkin import progress

    monkeypatch.setitem(sys.modules, "tqdm", None)  # the built-in bar, even if tqdm is installed

    class Terminal(io.StringIO):
        def isatty(self):
            return True

    pipe = io.StringIO()
    with progress.bar(10, "work", stream=pipe) as bar:
        bar.update(10)
    assert pipe.getvalue() == ""
    term = Terminal()
    with progress.bar(10, "work", stream=term) as bar:
        for _ in range(10):
            bar.update(1)
    text = term.getvalue()
    assert text.startswith("\rwork [") and "100%" in text and text.endswith("\n")
    quiet = Terminal()
    with progress.bar(10, "work", enabled=False, stream=quiet) as bar:
        bar.update(10)
    assert quiet.getvalue() == ""


# ------------------------------------------------------------------------- real processes


def _jaxkin():
    exe = Path(sys.executable).parent / "jaxkin"
    return [str(exe)] if exe.exists() else [sys.executable, "-m", "jaxkin.cli"]


def test_subprocess_scara_csv_round_trip(tmp_path):
    t = np.linspace(0.0, 8.0, 41)
    p, _, _ = spiral(t)
    src = write_points(tmp_path / "in.csv", t, p)
    for argv in (
        ["ik", "scara", "--robot", "paper", "-i", src, "-o", tmp_path / "q.csv"],
        ["fk", "scara", "--robot", "paper", "-i", tmp_path / "q.csv", "-o", tmp_path / "p.csv"],
    ):
        proc = subprocess.run(
            [*_jaxkin(), *map(str, argv)], capture_output=True, text=True, timeout=120
        )
        assert proc.returncode == 0, proc.stderr
    back = load(tmp_path / "p.csv")
    np.testing.assert_allclose(np.stack([back[k] for k in "xyz"], -1), p, atol=1e-9)


def test_subprocess_delta_npz_and_error(tmp_path):
    t = np.linspace(0.0, 2.0, 21)
    p, v, a = delta_path(t)
    src = write_points(tmp_path / "in.npz", t, p, v, a)
    out = tmp_path / "q.npz"
    proc = subprocess.run(
        [
            *_jaxkin(),
            "ik",
            "delta",
            "--robot",
            "paper",
            "--dtype",
            "float32",
            "-i",
            str(src),
            "-o",
            str(out),
        ],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert proc.returncode == 0, proc.stderr
    assert load(out)["theta1"].dtype == np.float32
    before = out.read_bytes()
    proc = subprocess.run(
        [*_jaxkin(), "ik", "delta", "--l-arm", "-1", "-i", str(src), "-o", str(out)],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert proc.returncode == 2
    assert proc.stderr.count("\n") == 1 and "Traceback" not in proc.stderr
    assert out.read_bytes() == before


def test_console_script_is_installed():
    assert shutil.which("jaxkin", path=str(Path(sys.executable).parent)) is not None
