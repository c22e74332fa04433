"""Fuzzing the command line (slow tier): pose files, output paths and ``jaxkin plan``.

Pose files: a smooth rotation path written with every quaternion scaled by a random length
(1e-150 to 1e150), a random sign, and some rows zero. Every non-zero row must give the pose and
rates the unit file without the zero rows gives (the rule: ``q`` and ``c q`` are one rotation,
a zero quaternion is invalid input and stays out of the others' splines); end to end, the UR5's
``ik`` of such a file must solve every non-zero row (its FK returns the written pose) and mark
the zero rows ``INVALID_INPUT``.

The library's ``paths.path_from_poses`` follows the same rule: any length and sign per sample
gives the unit path, and a zero quaternion is refused naming the argument.

Output paths: every kind of thing a path can name (a new name, a regular file, a read-only
one, a symlink to a file, a dangling symlink, a chain of links, a link to a directory, a
directory, a named pipe, a socket, a device node, a hard link to the input, the input through
``..``, a missing directory, an empty name), each spelled relative, absolute and through a
symlinked directory. The expected outcome is written here per kind; a refused path must leave
every file as it was (contents, kinds and link targets) and reach no solver.

``jaxkin plan``: random joint- and task-space candidate files (one infeasible), ranked by cost
or by duration; the ranking file and the written trajectories must be ``plan.evaluate``,
``plan.retime`` and ``plan.best`` of the same samples.
"""

from __future__ import annotations

import os
import socket
import stat
import threading
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import jaxkin
from jaxkin import cli, paths, serial
from jaxkin.cli import commands
from jaxkin.cli import files as kio

pytestmark = pytest.mark.slow

SETTINGS = settings(
    max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow], derandomize=True
)
POSE = ("x", "y", "z", "qw", "qx", "qy", "qz")
ROOT = Path(__file__).resolve().parents[1]


def rotation_path(t, axis, rate):
    half = 0.5 * rate * t
    q = np.concatenate([np.cos(half)[:, None], np.sin(half)[:, None] * axis], -1)
    p = np.stack([0.4 + 0.05 * t, 0.1 * np.sin(t), 0.3 + 0.02 * t], -1)
    return p, q


def write(path, t, p, q, candidate=None):
    block = np.concatenate([p, q], -1)
    cols = {"t": t} | ({} if candidate is None else {"candidate": candidate})
    kio.write_table(path, cols | {n: block[:, j] for j, n in enumerate(POSE)})
    return kio.read_trajectory(path, POSE)


def pose_jet(traj):
    traj = kio.continuous_quaternions(traj)
    p, v, a, valid = kio.complete_rates(traj, "not-a-knot")
    jet = paths.pose_from_quaternions(p, v, a)
    return [np.asarray(x) for x in (jet.p, jet.v, jet.a)], valid


@given(
    n=st.integers(6, 40),
    exponents=st.lists(st.floats(-150, 150), min_size=40, max_size=40),
    flips=st.lists(st.booleans(), min_size=40, max_size=40),
    zeros=st.sets(st.integers(0, 39), max_size=6),
    axis=st.tuples(*[st.floats(-1, 1)] * 3).filter(lambda a: np.linalg.norm(a) > 0.1),
    rate=st.floats(-3.0, 3.0),
)
@SETTINGS
def test_pose_files_scale_sign_and_zero_rows(tmp_path_factory, n, exponents, flips, zeros, axis,
                                             rate):  # fmt: skip
    tmp = tmp_path_factory.mktemp("poses")
    t = np.sort(np.linspace(0.0, 2.0, n))
    axis = np.asarray(axis) / np.linalg.norm(axis)
    p, q = rotation_path(t, axis, rate)
    zero = np.isin(np.arange(n), sorted(zeros))
    if zero.sum() > n - 4:  # keep enough rows for a spline
        zero[:] = False
    scale = 10.0 ** np.asarray(exponents[:n]) * np.where(flips[:n], -1.0, 1.0)
    q_file = q * scale[:, None]
    q_file[zero] = 0.0
    got, valid = pose_jet(write(tmp / "f.csv", t, p, q_file))
    ref, ref_valid = pose_jet(write(tmp / "r.csv", t[~zero], p[~zero], q[~zero]))
    assert valid.tolist() == (~zero).tolist() and ref_valid.all()
    for g, r in zip(got, ref, strict=True):
        np.testing.assert_allclose(g[~zero], r, rtol=0, atol=1e-11)
        assert np.all(np.isnan(g[zero][:, :3, :3]))


@given(
    candidates=st.integers(1, 3),
    n=st.integers(4, 30),
    seed=st.integers(0, 2**32 - 1),
    exponent_range=st.floats(0, 150),
    zero=st.booleans(),
)
@SETTINGS
def test_path_from_poses_scale_sign_and_zero_rows(candidates, n, seed, exponent_range, zero):
    """The library's pose paths follow the same rule as the files: every quaternion scaled by
    ``10^e`` (``|e|`` up to 150) with a random sign gives the unit path's poses and rates
    (1e-11; ``R`` a rotation at every sample), and a zero quaternion is refused naming
    ``quaternions`` (the library takes whole arrays: no row to mark)."""
    rng = np.random.default_rng(seed)
    t = np.linspace(0.0, 2.0, n)
    dt = float(t[1] - t[0])
    axes = rng.normal(size=(candidates, 3))
    axes /= np.linalg.norm(axes, axis=-1, keepdims=True)
    rates = rng.uniform(-3.0, 3.0, candidates)
    blocks = [rotation_path(t, axis, rate) for axis, rate in zip(axes, rates, strict=True)]
    p = np.stack([b[0] for b in blocks])
    q = np.stack([b[1] for b in blocks])
    scale = 10.0 ** rng.uniform(-exponent_range, exponent_range, (candidates, n))
    scale *= rng.choice([-1.0, 1.0], (candidates, n))
    reference = paths.path_from_poses(p, q, dt)
    scaled = q * scale[..., None]
    if zero:
        scaled[rng.integers(candidates), rng.integers(n)] = 0.0
        with pytest.raises(ValueError, match="quaternions"):
            paths.path_from_poses(p, scaled, dt)
        return
    got = paths.path_from_poses(p, scaled, dt)
    for g, r in zip((got.p, got.v, got.a), (reference.p, reference.v, reference.a), strict=True):
        np.testing.assert_allclose(np.asarray(g), np.asarray(r), rtol=0, atol=1e-11)
    rot = np.asarray(got.p)[..., :3, :3]
    gram = rot @ np.swapaxes(rot, -1, -2)
    np.testing.assert_allclose(gram, np.broadcast_to(np.eye(3), rot.shape), rtol=0, atol=1e-12)


def test_ur5_ik_of_a_scaled_signed_pose_file_with_zero_rows(tmp_path, capsys):
    """End to end on the UR5 of examples/: joints -> fk file -> quaternions rescaled, signs
    flipped, two rows zeroed -> ik: every other row OK and its FK is the pose fk wrote."""
    urdf = str(ROOT / "examples" / "ur5.urdf")
    chain = serial.from_urdf(urdf, "tool0")
    t = np.linspace(0.0, 1.0, 12)
    joints = np.stack([0.3 + 0.5 * t, -1.0 + 0.3 * t, 1.2 - 0.4 * t, -0.8 + 0.2 * t,
                       1.1 + 0.3 * t, 0.2 - 0.5 * t], -1)  # fmt: skip
    columns = {"t": t} | {n: joints[:, j] for j, n in enumerate(chain.joint_names)}
    kio.write_table(tmp_path / "q.csv", columns)
    argv = ["urdf", "--robot", urdf, "--tip", "tool0", "-q"]
    assert (
        cli.main(["fk", *argv, "-i", str(tmp_path / "q.csv"), "-o", str(tmp_path / "x.csv")]) == 0
    )
    poses = kio.read_table(tmp_path / "x.csv", POSE).data
    written = np.stack([poses[n] for n in POSE], -1)
    block = written.copy()
    rng = np.random.default_rng(3)
    block[:, 3:] *= (10.0 ** rng.uniform(-100, 100, len(t)) * rng.choice([-1.0, 1.0], len(t)))[
        :, None
    ]
    block[[3, 8], 3:] = 0.0
    kio.write_table(tmp_path / "s.csv", {"t": t} | {n: block[:, j] for j, n in enumerate(POSE)})
    assert (
        cli.main(["ik", *argv, "-i", str(tmp_path / "s.csv"), "-o", str(tmp_path / "j.csv")]) == 0
    )
    capsys.readouterr()
    lines = (tmp_path / "j.csv").read_text().splitlines()
    column = lines[0].split(",").index("status")
    status = [line.split(",")[column] for line in lines[1:]]
    ok = ~np.isin(np.arange(len(t)), [3, 8])
    assert status == ["OK" if k else "INVALID_INPUT" for k in ok]
    solved = kio.read_table(tmp_path / "j.csv", chain.joint_names).data
    q = np.stack([solved[n] for n in chain.joint_names], -1)[ok]
    zeros = np.zeros_like(written[ok])
    reference = np.asarray(paths.pose_from_quaternions(written[ok], zeros, zeros).p)
    np.testing.assert_allclose(np.asarray(jaxkin.fk(chain, q).x.p), reference, atol=1e-9)


# ------------------------------------------------------------------------------ output paths


def snapshot(root: Path) -> dict[str, tuple]:
    """Every entry under ``root``: kind, link target, contents of regular files, mode."""
    seen = {}
    for dirpath, dirnames, filenames in os.walk(root):
        for name in dirnames + filenames:
            path = Path(dirpath) / name
            info = os.lstat(path)
            key = str(path.relative_to(root))
            if stat.S_ISLNK(info.st_mode):
                seen[key] = ("link", os.readlink(path))
            elif stat.S_ISREG(info.st_mode):
                seen[key] = ("file", path.read_bytes(), stat.S_IMODE(info.st_mode))
            else:
                seen[key] = (stat.S_IFMT(info.st_mode),)
    return seen


def make_kind(base: Path, kind: str, source: Path) -> tuple[str, str]:
    """Create a thing of ``kind`` at ``base / 'out'``; return (name, expected outcome):
    ``"write:<relative target>"``, ``"stream"`` or ``"refuse:<message fragment>"``."""
    out = base / "out.csv"
    data = base / "data"
    data.mkdir(exist_ok=True)
    if kind == "new":
        return "out.csv", "write:out.csv"
    if kind == "regular":
        out.write_text("old")
        return "out.csv", "write:out.csv"
    if kind == "read-only":
        out.write_text("old")
        out.chmod(0o444)
        return "out.csv", "refuse:read-only"
    if kind == "link":
        (data / "target.csv").write_text("old")
        out.symlink_to(data / "target.csv")
        return "out.csv", "write:data/target.csv"
    if kind == "relative-link":
        (data / "target.csv").write_text("old")
        out.symlink_to("data/target.csv")
        return "out.csv", "write:data/target.csv"
    if kind == "dangling-link":
        out.symlink_to(data / "fresh.csv")
        return "out.csv", "write:data/fresh.csv"
    if kind == "link-chain":
        (data / "target.csv").write_text("old")
        (data / "hop.csv").symlink_to(data / "target.csv")
        out.symlink_to(data / "hop.csv")
        return "out.csv", "write:data/target.csv"
    if kind == "link-to-directory":
        out.symlink_to(data)
        return "out.csv", "refuse:is a directory"
    if kind == "directory":
        return "data", "refuse:is a directory"
    if kind == "missing-directory":
        return "nowhere/out.csv", "refuse:does not exist"
    if kind == "fifo":
        os.mkfifo(out)
        return "out.csv", "stream"
    if kind == "socket":
        server = socket.socket(socket.AF_UNIX)
        server.bind(str(out))
        server.close()
        return "out.csv", "refuse:is a socket"
    if kind == "device":
        try:
            os.mknod(out, stat.S_IFCHR | 0o666, os.makedev(1, 3))
        except OSError:
            pytest.skip("creating a device node needs privileges")
        return "out.csv", "stream"
    if kind == "block-device":
        try:
            os.mknod(out, stat.S_IFBLK | 0o600, os.makedev(7, 0))
        except OSError:
            pytest.skip("creating a device node needs privileges")
        return "out.csv", "refuse:is a block device"
    if kind == "hard-link-to-input":
        os.link(source, out)
        return "out.csv", "refuse:is the input file"
    if kind == "input-through-dotdot":
        return f"data/../{source.name}", "refuse:is the input file"
    if kind == "input-through-link":
        out.symlink_to(source)
        return "out.csv", "refuse:is the input file"
    if kind == "robot-file":
        return "arm.toml", "refuse:is the input file"
    if kind == "empty":
        return "", "refuse:empty name"
    raise AssertionError(kind)


KINDS = ["new", "regular", "read-only", "link", "relative-link", "dangling-link", "link-chain",
         "link-to-directory", "directory", "missing-directory", "fifo", "socket", "device",
         "block-device", "hard-link-to-input", "input-through-dotdot", "input-through-link",
         "robot-file", "empty"]  # fmt: skip
Q = np.array([[0.1, 0.2], [0.2, 0.3], [0.3, 0.5]])


@pytest.mark.parametrize("spelling", ["relative", "absolute", "via-linked-directory"])
@pytest.mark.parametrize("kind", KINDS)
def test_every_kind_of_output_path(tmp_path, capsys, monkeypatch, kind, spelling):
    base = tmp_path / "work"
    base.mkdir()
    (tmp_path / "alias").symlink_to(base)
    source = base / "q.csv"
    source.write_text("t,q1,q2\n0,0.1,0.2\n1,0.2,0.3\n2,0.3,0.5\n")
    (base / "arm.toml").write_text("l1 = 1.0\nl2 = 0.6\n")
    name, expected = make_kind(base, kind, source)
    if name and spelling == "absolute":
        name = str(base / name)
    elif name and spelling == "via-linked-directory":
        name = str(tmp_path / "alias" / name)
    monkeypatch.chdir(base)
    before = snapshot(tmp_path)
    solved = []
    original = commands.fk
    monkeypatch.setattr(commands, "fk", lambda *a: solved.append(1) or original(*a))
    received = []
    if expected == "stream" and kind == "fifo":
        reader = threading.Thread(
            target=lambda: received.append((base / "out.csv").read_text()), daemon=True
        )
        reader.start()
    argv = ["fk", "planar-2r", "--robot", "arm.toml", "-i", "q.csv", "-o", name, "-q"]
    code = cli.main(argv)
    err = capsys.readouterr().err
    if expected.startswith("refuse:"):
        assert code == 2 and expected.split(":", 1)[1] in err, err
        assert not solved and snapshot(tmp_path) == before
        return
    assert code == 0, err
    if kind == "fifo":
        reader.join(timeout=30)
        assert received and received[0].startswith("t,x,y,")
    after = snapshot(tmp_path)
    if expected == "stream":
        assert after == before  # written into, nothing replaced or added
        return
    target = expected.split(":", 1)[1]
    changed = {k for k in set(before) | set(after) if before.get(k) != after.get(k)}
    assert changed == {f"work/{target}"}, changed  # links stay links, nothing else moves
    text = (base / target).read_text()
    xy = np.array([[float(c) for c in line.split(",")[1:3]] for line in text.splitlines()[1:]])
    q1, q2 = Q[:, 0], Q[:, 1]
    expected_xy = np.c_[np.cos(q1) + 0.6 * np.cos(q1 + q2), np.sin(q1) + 0.6 * np.sin(q1 + q2)]
    np.testing.assert_allclose(xy, expected_xy, atol=1e-12)


# --------------------------------------------------------------------------- jaxkin plan
# One shape for every example: 4 candidates of 25 samples (3 cubic segments of 8 steps).
PLAN_CANDIDATES, PLAN_DT = 4, 0.1
SCARA_JOINTS = ("theta1", "theta2", "l3")
PLAN_SETTINGS = settings(  # capsys is read out after every example
    max_examples=8,
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture],
    derandomize=True,
)


def _plan_candidates(rng, space):
    """Joint paths of the paper SCARA through random waypoints (exact rates), as joint or
    task samples; candidate 1 made infeasible: its theta1 jumps by 0.3 rad that its rates do
    not explain (joint space), or its tool path pushed out of reach (task space)."""
    from jaxkin import plan, scara

    start = np.array([0.3, 1.0, 60.0]) + rng.uniform(-0.2, 0.2, 3) * [1, 1, 50]
    way = start + np.cumsum(rng.uniform(-0.4, 0.4, (PLAN_CANDIDATES, 4, 3)) * [1, 1, 20], 1)
    path = paths.path_from_joint_waypoints(way, PLAN_DT, 8)
    q = [np.array(x) for x in (path.p, path.v, path.a)]
    robot = scara.Scara.paper()
    if space == "joint":
        q[0][1, 12:, 0] += 0.3
        names, rows = SCARA_JOINTS, q
    else:
        tool = jaxkin.fk(robot, jaxkin.Jet(*q)).x
        rows = [np.array(x) for x in (tool.p, tool.v, tool.a)]
        rows[0][1, :, :2] *= 3.0  # far out of the 30-130 mm annulus
        names = ("x", "y", "z")
    return robot, plan, names, rows


@given(
    seed=st.integers(0, 2**31 - 1),
    space=st.sampled_from(["joint", "task"]),
    by=st.sampled_from(["cost", "duration"]),
    k=st.integers(1, 4),
)
@PLAN_SETTINGS
def test_plan_ranks_as_plan_evaluate_retime_and_best(tmp_path_factory, capsys, seed, space, by,
                                                     k):  # fmt: skip
    """``jaxkin plan`` on joint- and task-space candidates (rates in the file), by cost or by
    duration: its ranking file is ``plan.evaluate`` / ``plan.retime`` /  ``plan.best`` of the
    same samples (feasibility, first failure, cost and duration to 1e-12, the rank), and it
    writes exactly the ranked candidates, each from rest at t = 0 within the speed bounds."""
    tmp = tmp_path_factory.mktemp("plan")
    rng = np.random.default_rng(seed)
    robot, plan, names, rows = _plan_candidates(rng, space)
    count, samples = rows[0].shape[:2]
    v_max = rng.uniform(1.0, 4.0, 3) * [1, 1, 50]
    a_max = rng.uniform(5.0, 20.0, 3) * [1, 1, 200]
    t = np.arange(samples) * PLAN_DT
    columns = {"candidate": np.repeat(np.arange(count), samples), "t": np.tile(t, count)}
    velocity, acceleration = kio.rate_names(names)
    for j in range(len(names)):
        for name, values in ((names, rows[0]), (velocity, rows[1]), (acceleration, rows[2])):
            columns[name[j]] = values[..., j].ravel()
    kio.write_table(tmp / "c.csv", columns)
    bounds = [",".join(map(str, x)) for x in (v_max, a_max)]
    code = cli.main(
        ["plan", "scara", "--robot", "paper", "-i", str(tmp / "c.csv"), "-o", str(tmp / "b.csv"),
         "-k", str(k), "--by", by, "--v-max", bounds[0], "--a-max", bounds[1],
         "--ranking", str(tmp / "r.csv")]
    )  # fmt: skip
    _, err = capsys.readouterr()
    assert code == 0, err
    limits = plan.Limits.create(3, v_max=v_max, a_max=a_max)
    path = paths.Path.from_jet(jaxkin.Jet(*rows), PLAN_DT, space)
    ev = plan.evaluate(robot, path, limits)
    timed = plan.retime(ev, speed_bound="interval")
    order, _ = plan.best(ev, k, by=by, timing=timed)
    table = np.genfromtxt(tmp / "r.csv", delimiter=",", names=True, dtype=None, encoding="utf-8")
    feasible = np.asarray(ev.feasible)
    assert not feasible[1]
    np.testing.assert_array_equal(table["feasible"], feasible)
    np.testing.assert_array_equal(table["first_failure"], np.asarray(ev.first_failure))
    cost = np.asarray(ev.costs.total)
    np.testing.assert_allclose(table["cost"][feasible], cost[feasible], rtol=1e-12)
    ok = np.asarray(timed.ok)
    np.testing.assert_allclose(table["duration"][ok], np.asarray(timed.duration)[ok], rtol=1e-12)
    assert np.all(np.isnan(table["duration"][~ok]))
    rank = np.full(count, -1)
    rank[order] = np.arange(1, len(order) + 1)
    np.testing.assert_array_equal(table["rank"], rank)
    best = np.genfromtxt(tmp / "b.csv", delimiter=",", names=True, dtype=None, encoding="utf-8")
    assert sorted(set(np.atleast_1d(best["candidate"]).tolist())) == sorted(order.tolist())
    for place, index in enumerate(order.tolist()):
        mine = np.atleast_1d(best["rank"]) == place + 1
        assert np.all(np.atleast_1d(best["candidate"])[mine] == index)
        assert np.atleast_1d(best["t"])[mine][0] == 0.0
        speeds = np.stack([np.atleast_1d(best[n + "_dot"])[mine] for n in SCARA_JOINTS], -1)
        assert np.all(np.abs(speeds) <= v_max * (1 + 1e-6))
