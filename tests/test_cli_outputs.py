"""Output paths of the ``jaxkin`` command: nothing an output names is lost or replaced.

Every output (``-o``, ``--plot``) is checked against every input (``-i``, the ``--robot``
file) and each other, and for being writable, before any work: the tests make the solver
raise if it is reached. The runs that do solve use one planar 2R FK of three rows (one
compilation for the module).
"""

import os
import socket
import stat
import tempfile
import threading

import numpy as np
import pytest

from jaxkin import cli
from jaxkin.cli import commands
from jaxkin.cli import files as kio

PLANAR = ["fk", "planar-2r", "--l1", "1.0", "--l2", "0.6"]


def run(capsys, *argv):
    code = cli.main([str(x) for x in argv])
    out, err = capsys.readouterr()
    return code, out, err


def assert_one_line_error(code, err, *fragments):
    assert code == 2, err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("jaxkin: error: "), err
    for fragment in fragments:
        assert fragment in lines[0], lines[0]


@pytest.fixture
def joints(tmp_path):
    path = tmp_path / "q.csv"
    path.write_text("t,q1,q2\n0,0.1,0.2\n1,0.2,0.3\n2,0.3,0.5\n")
    return path


@pytest.fixture
def no_solve(monkeypatch):
    """Any solve fails the test: the checks must come first."""

    def refuse(*args, **kwargs):
        raise AssertionError("the solver was reached")

    monkeypatch.setattr(commands, "fk", refuse)
    monkeypatch.setattr(commands, "ik", refuse)


def expected_xy(q):
    """The planar 2R tip, written out here: l1 (cos q1, sin q1) + l2 (cos, sin)(q1 + q2)."""
    q1, q2 = q[:, 0], q[:, 1]
    return np.stack([np.cos(q1) + 0.6 * np.cos(q1 + q2), np.sin(q1) + 0.6 * np.sin(q1 + q2)], -1)


def read_xy(text):
    lines = text.strip().splitlines()
    names = lines[0].split(",")
    rows = [line.split(",") for line in lines[1:]]
    return np.array([[float(r[names.index(n)]) for n in ("x", "y")] for r in rows])


Q = np.array([[0.1, 0.2], [0.2, 0.3], [0.3, 0.5]])


# ------------------------------------------------------------------- outputs naming inputs


def test_output_naming_the_robot_file_is_refused(tmp_path, capsys, joints, no_solve):
    robot = tmp_path / "arm.toml"
    robot.write_text("l1 = 1.0\nl2 = 0.6\n")
    before = robot.read_bytes()
    argv = ["fk", "planar-2r", "--robot", robot, "-i", joints]
    code, _, err = run(capsys, *argv, "-o", robot)
    assert_one_line_error(code, err, "is the input file", "--robot")
    link = tmp_path / "link.toml"
    link.symlink_to(robot)
    code, _, err = run(capsys, *argv, "-o", tmp_path / "." / "link.toml")
    assert_one_line_error(code, err, "is the input file", "--robot")
    assert robot.read_bytes() == before and link.is_symlink()


def test_output_naming_the_urdf_file_is_refused(tmp_path, capsys, joints, no_solve):
    urdf = tmp_path / "arm.urdf"
    urdf.write_text("<robot name='r'><link name='a'/></robot>")
    before = urdf.read_bytes()
    argv = ["ik", "urdf", "--robot", urdf, "--tip", "a", "-i", joints]
    code, _, err = run(capsys, *argv, "-o", urdf)
    assert_one_line_error(code, err, "is the input file", "--robot")
    code, _, err = run(capsys, *argv, "-o", tmp_path / "o.csv", "--plot", urdf)
    assert_one_line_error(code, err, "--plot", "is the input file")
    assert urdf.read_bytes() == before


def test_output_and_plot_naming_one_file_are_refused(tmp_path, capsys, joints, no_solve):
    out = tmp_path / "o.png"
    out.write_bytes(b"precious")
    code, _, err = run(capsys, *PLANAR, "-i", joints, "-o", out, "--plot", tmp_path / "o.png")
    assert_one_line_error(code, err, "--plot", "is also --output")
    code, _, err = run(capsys, "workspace", "planar-2r", "--l1", 1, "--l2", 0.6, "-o",
                       tmp_path / "w.npz", "--plot", tmp_path / "w.npz")  # fmt: skip
    assert_one_line_error(code, err, "is also --output")
    assert out.read_bytes() == b"precious" and not (tmp_path / "w.npz").exists()


# ----------------------------------------------------------------- outputs that are no file


def test_output_to_a_named_pipe_is_written_into(tmp_path, capsys, joints):
    """The reader of a named pipe gets the data; the pipe stays a pipe."""
    pipe = tmp_path / "pipe"
    os.mkfifo(pipe)
    received = []
    reader = threading.Thread(target=lambda: received.append(pipe.read_text()), daemon=True)
    reader.start()
    code, _, err = run(capsys, *PLANAR, "-i", joints, "-o", pipe)
    reader.join(timeout=30)
    assert code == 0, err
    assert stat.S_ISFIFO(os.stat(pipe).st_mode)
    np.testing.assert_allclose(read_xy(received[0]), expected_xy(Q), atol=1e-12)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["pipe", "q.csv"]


def test_output_to_a_character_device_is_written_into(tmp_path):
    """``-o /dev/null`` (here a private copy of the device node) stays a device node."""
    node = tmp_path / "null"
    try:
        os.mknod(node, stat.S_IFCHR | 0o666, os.makedev(1, 3))
    except (PermissionError, OSError):
        pytest.skip("creating a device node needs privileges")
    kio.write_table(node, {"t": np.arange(3.0)})
    assert stat.S_ISCHR(os.stat(node).st_mode)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["null"]


def test_output_to_a_socket_or_directory_is_refused(tmp_path, capsys, joints, no_solve):
    path = tmp_path / "sock"
    server = socket.socket(socket.AF_UNIX)
    try:
        server.bind(str(path))
        code, _, err = run(capsys, *PLANAR, "-i", joints, "-o", path)
        assert_one_line_error(code, err, "--output", "is a socket")
    finally:
        server.close()
    code, _, err = run(capsys, *PLANAR, "-i", joints, "-o", tmp_path)
    assert_one_line_error(code, err, "is a directory")


# ------------------------------------------------------------ found before the solve, not after


def test_unwritable_plot_format_is_refused_before_solving(tmp_path, capsys, joints, no_solve):
    out = tmp_path / "o.csv"
    out.write_text("precious")
    code, _, err = run(capsys, *PLANAR, "-i", joints, "-o", out, "--plot", tmp_path / "p.xyz")
    assert_one_line_error(code, err, "--plot", "cannot write .xyz")
    assert out.read_text() == "precious"


def test_empty_output_name_is_refused_before_solving(capsys, joints, no_solve):
    code, _, err = run(capsys, *PLANAR, "-i", joints, "-o", "")
    assert_one_line_error(code, err, "--output", "empty name")


def test_unwritable_output_directory_is_refused_before_solving(
    tmp_path, capsys, joints, no_solve, monkeypatch
):
    """A directory where no file can be created (read-only mount, permissions): simulated by
    the creation failing, since the tests may run as root, whom permissions do not stop."""
    real = tempfile.mkstemp

    def refuse(*args, **kwargs):
        if os.fspath(kwargs.get("dir", "")) == os.fspath(tmp_path / "ro"):
            raise PermissionError(13, "Permission denied")
        return real(*args, **kwargs)

    (tmp_path / "ro").mkdir()
    monkeypatch.setattr(tempfile, "mkstemp", refuse)
    code, _, err = run(capsys, *PLANAR, "-i", joints, "-o", tmp_path / "ro" / "o.csv")
    assert_one_line_error(code, err, "--output", "cannot write in", "Permission denied")


@pytest.mark.skipif(os.name != "posix" or os.geteuid() == 0, reason="root writes anyway")
def test_read_only_output_directory_is_refused(tmp_path, capsys, joints, no_solve):
    directory = tmp_path / "ro"
    directory.mkdir()
    directory.chmod(0o555)
    try:
        code, _, err = run(capsys, *PLANAR, "-i", joints, "-o", directory / "o.csv")
        assert_one_line_error(code, err, "cannot write in")
    finally:
        directory.chmod(0o755)


def test_read_only_output_file_is_not_replaced(tmp_path, capsys, joints, no_solve):
    out = tmp_path / "o.csv"
    out.write_text("precious")
    out.chmod(0o444)
    code, _, err = run(capsys, *PLANAR, "-i", joints, "-o", out)
    assert_one_line_error(code, err, "is read-only")
    assert out.read_text() == "precious" and stat.S_IMODE(out.stat().st_mode) == 0o444


# ----------------------------------------------------------------------------------- links


def test_output_through_a_symlink_writes_its_target(tmp_path, capsys, joints):
    target = tmp_path / "data" / "xy.csv"
    target.parent.mkdir()
    target.write_text("old")
    link = tmp_path / "latest.csv"
    link.symlink_to(target)
    code, _, err = run(capsys, *PLANAR, "-i", joints, "-o", link)
    assert code == 0, err
    assert link.is_symlink() and os.readlink(link) == str(target)
    np.testing.assert_allclose(read_xy(target.read_text()), expected_xy(Q), atol=1e-12)
    dangling = tmp_path / "new.csv"
    dangling.symlink_to(tmp_path / "data" / "fresh.csv")
    kio.write_table(dangling, {"t": np.arange(2.0)})
    assert (
        dangling.is_symlink() and (tmp_path / "data" / "fresh.csv").read_text() == "t\n0.0\n1.0\n"
    )
    assert sorted(p.name for p in target.parent.iterdir()) == ["fresh.csv", "xy.csv"]


def test_float64_is_on_before_the_robot_is_built(capsys, joints, monkeypatch):
    """In a new process x64 is off: the command must turn it on before it builds the robot,
    or a URDF chain's geometry is rounded to float32 and its IK cannot meet float64
    tolerances."""
    import jax

    seen = []
    original = commands.robot_from_args

    def record(args):
        seen.append(jax.config.jax_enable_x64)
        return original(args)

    monkeypatch.setattr(commands, "robot_from_args", record)
    jax.config.update("jax_enable_x64", False)
    try:
        code, _, err = run(capsys, *PLANAR, "-i", joints, "-o", "-")
    finally:
        jax.config.update("jax_enable_x64", True)
    assert code == 0, err
    assert seen == [True]
