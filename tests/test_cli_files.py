"""Trajectory files of the command line (jaxkin.cli.files): CSV/NPZ round trips, parse errors
with line numbers, atomic writes, spline rates per candidate, chunked solving."""

import os
import stat

import numpy as np
import pytest

from jaxkin.cli import files as kio


def _write(path, text, encoding="utf-8"):
    path.write_text(text, encoding=encoding)
    return path


def test_csv_round_trip_is_exact(tmp_path):
    rng = np.random.default_rng(0)
    columns = {
        "t": np.linspace(0, 1, 7),
        "candidate": np.array([0, 0, 0, 1, 1, 1, 1]),
        "x": rng.normal(size=7) * 1e3,
        "y": rng.normal(size=7) * 1e-7,
        "z": np.array([1.0, np.nan, np.inf, -np.inf, 0.0, -0.0, 1e300]),
        "status": np.array(["OK"] * 6 + ["UNREACHABLE"]),
    }
    path = tmp_path / "a.csv"
    kio.write_table(path, columns)
    table = kio.read_table(path, ["t", "candidate", "x", "y", "z"])
    assert table.columns == tuple(columns)
    for name in ("t", "candidate", "x", "y", "z"):
        np.testing.assert_array_equal(table.data[name], columns[name].astype(float))
    assert "status" not in table.data  # present but not requested: never parsed
    assert table.lines.tolist() == list(range(2, 9))


def test_npz_round_trip(tmp_path):
    path = tmp_path / "a.npz"
    columns = {"t": np.arange(3.0), "x": np.array([1.0, 2.0, 3.0]), "status": np.array(["OK"] * 3)}
    kio.write_table(path, columns)
    with np.load(path, allow_pickle=False) as archive:
        assert archive["status"].tolist() == ["OK"] * 3
    table = kio.read_table(path, ["t", "x", "y"])
    np.testing.assert_array_equal(table.data["x"], [1.0, 2.0, 3.0])
    assert "y" not in table.data and table.lines is None
    assert table.where(2) == f"{path}, row 2"


def test_csv_dialect_comments_blank_lines_bom_and_empty_cells(tmp_path):
    path = _write(
        tmp_path / "a.csv",
        "\ufeff# a comment\n T , X ,y,z\n\n0, 1 ,2,3\n# another\n1,,2,nan\n",
    )
    table = kio.read_table(path, ["t", "x", "y", "z"])
    assert table.columns == ("t", "x", "y", "z")
    assert table.lines.tolist() == [4, 6]
    assert table.data["x"][0] == 1.0 and np.isnan(table.data["x"][1])
    assert np.isnan(table.data["z"][1])
    semicolons = _write(tmp_path / "b.csv", "t;x;y;z\n0;1;2;3\n")
    assert kio.read_table(semicolons, ["x"]).data["x"].tolist() == [1.0]


@pytest.mark.parametrize(
    "text",
    [
        "# units: mm; s\nt,x,y,z\n0,1,2,3\n",
        "\n  # made by a tool, v2\n# t;x\nt;x;y;z\n0;1;2;3\n",
        "#\tcomment\nt,x,y,z\n0,1,2,3\n",
    ],
)
def test_csv_delimiter_comes_from_the_header_not_a_comment(tmp_path, text):
    table = kio.read_table(_write(tmp_path / "a.csv", text), ["t", "x", "y", "z"])
    assert table.columns == ("t", "x", "y", "z")
    assert [table.data[n].tolist() for n in "txyz"] == [[0.0], [1.0], [2.0], [3.0]]


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("", "empty file, expected a header row"),
        ("t,x,y,z\n", "no data rows"),
        ("t,x,y,z\n0,1,2,3\n1,2,abc,4\n", r"a.csv:3: column 'y': not a number: 'abc'"),
        ("t,x,y,z\n0,1,2,3\n\n1,2,3\n", r"a.csv:4: expected 4 fields \(t,x,y,z\), got 3"),
        ("t,x,y,z\n0,1,2,3,4\n", r"a.csv:2: expected 4 fields"),
        ("0,1,2,3\n1,2,3,4\n", "a.csv:1: the first row must be a header"),
        ("t,x,x,z\n0,1,2,3\n", "a.csv:1: duplicate column"),
        ('t,x,y,z\n0,"1,2,3\n', "malformed CSV"),
    ],
)
def test_csv_errors_name_file_and_line(tmp_path, text, message):
    path = _write(tmp_path / "a.csv", text)
    with pytest.raises(kio.InputError, match=message) as info:
        kio.read_table(path, ["t", "x", "y", "z"])
    assert "\n" not in str(info.value)


def test_file_errors(tmp_path):
    with pytest.raises(kio.InputError, match="no such file"):
        kio.read_table(tmp_path / "missing.csv", ["t"])
    with pytest.raises(kio.InputError, match="is a directory"):
        kio.read_table(tmp_path, ["t"])
    binary = tmp_path / "b.csv"
    binary.write_bytes(b"\xff\xfe\x00\x81garbage")
    with pytest.raises(kio.InputError, match="not a UTF-8 text CSV"):
        kio.read_table(binary, ["t"])
    not_zip = _write(tmp_path / "c.npz", "t,x\n1,2\n")
    with pytest.raises(kio.InputError, match="not a readable .npz"):
        kio.read_table(not_zip, ["t"])
    np.savez(tmp_path / "d.npz", t=np.zeros((2, 2)))
    with pytest.raises(kio.InputError, match=r"'t' has shape \(2, 2\), expected 1-D"):
        kio.read_table(tmp_path / "d.npz", ["t"])
    np.savez(tmp_path / "e.npz", t=np.zeros(2), x=np.zeros(3))
    with pytest.raises(kio.InputError, match="has 3 rows, others have 2"):
        kio.read_table(tmp_path / "e.npz", ["t", "x"])
    np.savez(tmp_path / "f.npz", t=np.array(["a", "b"]))
    with pytest.raises(kio.InputError, match="not numeric"):
        kio.read_table(tmp_path / "f.npz", ["t"])


def test_read_trajectory(tmp_path):
    path = _write(
        tmp_path / "a.csv",
        "t,candidate,x,y,z,vx,vy,vz\n0,3,1,2,3,0,0,0\n1,3,1,2,nan,0,0,0\n0,4,1,2,3,1,1,1\n",
    )
    traj = kio.read_trajectory(path)
    assert traj.candidate.tolist() == [3, 3, 4]
    assert traj.v.shape == (3, 3) and traj.a is None
    assert traj.valid.tolist() == [True, False, True]
    missing = _write(tmp_path / "b.csv", "t,x,y\n0,1,2\n")
    with pytest.raises(kio.InputError, match=r"missing column\(s\) z \(found: t, x, y\)"):
        kio.read_trajectory(missing)
    partial = _write(tmp_path / "c.csv", "t,x,y,z,vx\n0,1,2,3,4\n")
    with pytest.raises(kio.InputError, match="velocity columns come as a set"):
        kio.read_trajectory(partial)
    bad_candidate = _write(tmp_path / "d.csv", "t,candidate,x,y,z\n0,0,1,2,3\n1,0.5,1,2,3\n")
    with pytest.raises(kio.InputError, match="d.csv:3: column 'candidate' must hold integers"):
        kio.read_trajectory(bad_candidate)
    joints = _write(
        tmp_path / "e.csv", "t,theta1,theta2,l3,theta1_ddot,theta2_ddot,l3_ddot\n0,1,2,3,0,0,0\n"
    )
    traj = kio.read_trajectory(joints, ("theta1", "theta2", "l3"))
    assert traj.v is None and traj.a.shape == (1, 3)


def test_atomic_write_keeps_the_old_file_on_failure(tmp_path):
    path = _write(tmp_path / "out.csv", "precious\n")
    with pytest.raises(RuntimeError), kio.atomic_write(path) as f:
        f.write("half a file")
        raise RuntimeError("boom")
    assert path.read_text() == "precious\n"
    with pytest.raises(KeyboardInterrupt), kio.atomic_write(path) as f:
        f.write("half a file")
        raise KeyboardInterrupt
    assert path.read_text() == "precious\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out.csv"]  # no temporary left


def test_atomic_write_replaces_and_keeps_permissions(tmp_path):
    path = _write(tmp_path / "out.csv", "old\n")
    os.chmod(path, 0o640)
    with kio.atomic_write(path) as f:
        f.write("new\n")
    assert path.read_text() == "new\n"
    assert stat.S_IMODE(path.stat().st_mode) == 0o640
    fresh = tmp_path / "fresh.csv"
    with kio.atomic_write(fresh) as f:
        f.write("x\n")
    umask = os.umask(0)
    os.umask(umask)
    assert stat.S_IMODE(fresh.stat().st_mode) == 0o666 & ~umask


def test_atomic_write_errors(tmp_path):
    with pytest.raises(kio.InputError, match="does not exist"):
        with kio.atomic_write(tmp_path / "nodir" / "out.csv"):
            pass
    with pytest.raises(kio.InputError, match="is a directory"):
        with kio.atomic_write(tmp_path):
            pass


def test_trajectory_columns_order():
    cols = kio.trajectory_columns(
        np.arange(2.0),
        None,
        ("theta1", "l3"),
        np.zeros((2, 2)),
        np.ones((2, 2)),
        2 * np.ones((2, 2)),
        np.array(["OK", "UNREACHABLE"]),
        {"margin": np.zeros(2)},
    )
    assert list(cols) == [
        "t",
        "theta1",
        "l3",
        "theta1_dot",
        "l3_dot",
        "theta1_ddot",
        "l3_ddot",
        "status",
        "margin",
    ]
    assert kio.rate_names(("x", "y", "z")) == (("vx", "vy", "vz"), ("ax", "ay", "az"))


def _trajectory(tmp_path, text):
    return kio.read_trajectory(_write(tmp_path / "a.csv", text))


def test_complete_rates_by_cubic_splines_per_candidate(tmp_path):
    """Not-a-knot splines reproduce a cubic exactly (its derivatives written out here), per
    candidate and around a NaN row, which gets NaN rates; given rates pass through."""
    t = np.array([0.0, 0.3, 0.5, 1.0, 1.2, 0.0, 0.5, 1.5, 2.0])
    candidate = np.array([0, 0, 0, 0, 0, 7, 7, 7, 7])
    coeffs = np.array([[1.0, -2.0, 0.5], [0.3, 0.0, 2.0], [-1.0, 0.7, 0.0], [0.2, 0.1, -0.4]])
    p = sum(coeffs[k] * t[:, None] ** k for k in range(4))
    v = sum(k * coeffs[k] * t[:, None] ** (k - 1) for k in range(1, 4))
    a = sum(k * (k - 1) * coeffs[k] * t[:, None] ** (k - 2) for k in range(2, 4))
    p[2, 1] = np.nan  # row 2 invalid: candidate 0 is splined through rows 0, 1, 3, 4
    rows = "".join(
        f"{ti},{c},{x},{y},{z}\n" for ti, c, (x, y, z) in zip(t, candidate, p, strict=True)
    )
    traj = _trajectory(tmp_path, "t,candidate,x,y,z\n" + rows)
    pos, vel, acc, valid = kio.complete_rates(traj, "not-a-knot")
    assert valid.tolist() == [True, True, False] + [True] * 6
    np.testing.assert_array_equal(pos, traj.p)
    np.testing.assert_allclose(vel[valid], v[valid], rtol=1e-10, atol=1e-10)
    np.testing.assert_allclose(acc[valid], a[valid], rtol=1e-9, atol=1e-9)
    assert np.all(np.isnan(vel[2])) and np.all(np.isnan(acc[2]))
    natural = kio.complete_rates(traj, "natural")[2]
    np.testing.assert_allclose(natural[[0, 4, 5, 8]], 0.0, atol=1e-12)  # s'' = 0 at the ends
    path = _write(tmp_path / "b.csv", "t,x,y,vx,vy,ax,ay\n0,1,2,3,4,5,6\n0,1,2,3,4,5,6\n")
    given = kio.read_trajectory(path, ("x", "y"))  # t not increasing: no spline needed
    out = kio.complete_rates(given, "not-a-knot")
    np.testing.assert_array_equal(out[1], [[3.0, 4.0]] * 2)
    np.testing.assert_array_equal(out[2], [[5.0, 6.0]] * 2)


def test_complete_rates_needs_increasing_times_per_candidate(tmp_path):
    traj = _trajectory(tmp_path, "t,candidate,x,y,z\n0,1,0,0,0\n1,1,0,0,0\n1,1,0,0,0\n")
    with pytest.raises(kio.InputError, match=r"a.csv:4: candidate 1: t must increase strictly"):
        kio.complete_rates(traj, "not-a-knot")
    # Times may restart from one candidate to the next.
    traj = _trajectory(tmp_path, "t,candidate,x,y,z\n0,1,0,0,0\n1,1,0,0,0\n0,2,0,0,0\n")
    assert kio.complete_rates(traj, "not-a-knot")[3].all()


def test_solve_in_chunks_calls_one_shape_and_joins_the_rows():
    """Each call gets the same number of rows (the chunk, or the next power of two of a small
    input); the padding rows are dropped and the outputs joined in order."""
    seen = []

    def fn(x, y):
        seen.append(len(x))
        return x + y, (x * 2, y)

    x, y = np.arange(5.0), np.arange(5.0) * 10
    sums, doubled, ys = kio.solve_in_chunks(fn, (x, y), chunk=2, desc="test", quiet=True)
    assert seen == [2, 2, 2]
    np.testing.assert_array_equal(sums, x + y)
    np.testing.assert_array_equal(doubled, 2 * x)
    np.testing.assert_array_equal(ys, y)
    seen.clear()
    sums = kio.solve_in_chunks(fn, (x, y), chunk=1 << 16, desc="test", quiet=True)[0]
    assert seen == [8]  # 5 rows padded to 8, not to the chunk
    np.testing.assert_array_equal(sums, x + y)
