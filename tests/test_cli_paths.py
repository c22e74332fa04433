"""Trajectory files through ``jaxkin ik`` as paths, and ``jaxkin plan``, via the entry point.

Every path here is the SCARA of [Noriega] (mm, s), whose closed-form IK solves each sample on
its own, so the per-row reference (``tests.references.scara.ik_numpy``, wrapped angles) is
independent of the path logic: a path's joints must equal it up to whole turns of the
revolute joints, with the same rates. Files of up to 32 rows and one or two candidates share
one padded shape, so the SCARA path kernel compiles once for the module. The URDF arms
(chain IK, compile in tens of seconds) are in the slow tier.
"""

from __future__ import annotations

import importlib.metadata
import json

import numpy as np
import pytest

from jaxkin import Jet, cli, paths, plan, scara
from jaxkin.cli import files as kio
from tests.references import scara as scara_ref
from tests.test_cli import spiral

PAPER = ["--robot", "paper"]
L = (150.0, 80.0, 50.0)  # the paper SCARA's l_oa, l_ab, l_bc (mm)
JOINTS = ("theta1", "theta2", "l3")


def behind_the_base(t, radius=100.0, span=1.0):
    """An arc about the base through the -x axis (polar angle pi - span ... pi + span over t
    in [0, 2]), so that the per-row theta1 wraps from +pi to -pi; exact rates."""
    phi = np.pi - span + span * t
    c, s = radius * np.cos(phi), radius * np.sin(phi)
    p = np.stack([c, s, 40.0 + 5.0 * t], -1)
    v = np.stack([-span * s, span * c, np.full_like(t, 5.0)], -1)
    a = np.stack([-span * span * c, -span * span * s, np.zeros_like(t)], -1)
    return p, v, a


def write(path, columns):
    kio.write_table(path, columns)
    return path


def point_columns(t, p, v=None, a=None, candidate=None):
    cols = {} if t is None else {"t": t}
    if candidate is not None:
        cols["candidate"] = candidate
    cols |= {n: p[:, j] for j, n in enumerate("xyz")}
    for block, prefix in ((v, "v"), (a, "a")):
        if block is not None:
            cols |= {f"{prefix}{n}": block[:, j] for j, n in enumerate("xyz")}
    return cols


def run(capsys, *argv):
    code = cli.main([str(x) for x in argv])
    out, err = capsys.readouterr()
    return code, out, err


def read(path, names):
    table = np.genfromtxt(path, delimiter=",", names=True, dtype=None, encoding="utf-8")
    return {n: table[n] for n in names}


def joints_of(table, suffix=""):
    return np.stack([table[n + suffix] for n in JOINTS], -1)


OUT = (*JOINTS, *(n + "_dot" for n in JOINTS), *(n + "_ddot" for n in JOINTS), "status")


def assert_whole_turns(q, reference):
    """Revolute joints equal the reference up to whole turns, the prismatic one exactly."""
    turns = (q[:, :2] - reference[:, :2]) / (2 * np.pi)
    np.testing.assert_allclose(turns, np.round(turns), rtol=0, atol=1e-12)
    np.testing.assert_allclose(q[:, 2], reference[:, 2], rtol=0, atol=1e-12)


def test_a_trajectory_is_one_continuous_path(tmp_path, capsys):
    """Behind the base the rows' own theta1 jumps by 2 pi; as a path it does not: every row
    is OK, the joints are the per-row reference up to whole turns (1e-12), the rates are the
    reference's, and no step is larger than the rates allow. ``--each-row`` keeps the jump."""
    t = np.linspace(0.0, 2.0, 21)
    p, v, a = behind_the_base(t)
    src = write(tmp_path / "arc.csv", point_columns(t, p, v, a))
    reference = scara_ref.ik_numpy(p, v, a, *L, mode=1)
    code, _, err = run(capsys, "ik", "scara", *PAPER, "-i", src, "-o", tmp_path / "q.csv")
    assert code == 0, err
    assert "one path per candidate" in err and "OK 21" in err
    out = read(tmp_path / "q.csv", OUT)
    q = joints_of(out)
    assert_whole_turns(q, reference[0])
    np.testing.assert_allclose(joints_of(out, "_dot"), reference[1], rtol=0, atol=1e-9)
    np.testing.assert_allclose(joints_of(out, "_ddot"), reference[2], rtol=0, atol=1e-9)
    assert np.max(np.abs(np.diff(q[:, 0]))) < 0.2  # 0.1 s at |theta1_dot| <= 1.3 rad/s
    assert np.ptp(np.round((q[:, 0] - reference[0][:, 0]) / (2 * np.pi))) == 1  # a wrap undone
    code, _, err = run(
        capsys, "ik", "scara", *PAPER, "-i", src, "-o", tmp_path / "rows.csv", "--each-row"
    )
    assert code == 0 and "each row" in err
    rows = joints_of(read(tmp_path / "rows.csv", OUT))
    np.testing.assert_allclose(rows, reference[0], rtol=0, atol=1e-12)
    assert np.max(np.abs(np.diff(rows[:, 0]))) > 6.0


def test_speed_limit_and_unexplained_step_statuses(tmp_path, capsys):
    """``--v-max 1,0.5,20`` on the helix of [Noriega, eq. 16]: exactly the rows whose
    |theta2_dot| (the reference's, 0 ... 0.8 rad/s) exceeds 0.5 are OUT_OF_LIMITS. Positions
    shifted by 1 mm from row 12 on, with the exact rates given: row 12's step is not
    explained by the rates, so it alone is DISCONTINUOUS."""
    t = np.linspace(0.0, 2.0, 21)
    p, v, a = spiral(t)
    reference = scara_ref.ik_numpy(p, v, a, *L, mode=1)
    src = write(tmp_path / "helix.csv", point_columns(t, p, v, a))
    code, _, err = run(
        capsys, "ik", "scara", *PAPER, "-i", src, "-o", tmp_path / "q.csv", "--v-max", "1,0.5,20"
    )
    assert code == 0, err
    status = read(tmp_path / "q.csv", OUT)["status"]
    fast = np.abs(reference[1][:, 1]) > 0.5
    assert 0 < fast.sum() < len(t)
    assert (status == "OUT_OF_LIMITS").tolist() == fast.tolist()
    assert set(status[~fast]) == {"OK"}
    shifted = p.copy()
    shifted[12:, 0] += 1.0
    src = write(tmp_path / "jump.csv", point_columns(t, shifted, v, a))
    code, _, err = run(capsys, "ik", "scara", *PAPER, "-i", src, "-o", tmp_path / "j.csv")
    assert code == 0, err
    status = read(tmp_path / "j.csv", OUT)["status"]
    assert status[12] == "DISCONTINUOUS"
    assert set(np.delete(status, 12)) == {"OK"}


def test_candidates_interleaved_or_not_and_an_invalid_row(tmp_path, capsys):
    """Two candidates, in blocks or interleaved row by row, give each its own path (the
    rows of one file solved alone); a NaN row is INVALID_INPUT and its path goes on."""
    t = np.linspace(0.0, 2.0, 15)
    p1, v1, a1 = behind_the_base(t)
    p2, v2, a2 = behind_the_base(t, radius=110.0)
    p1[6] = np.nan
    block = {
        k: np.concatenate([x, y])
        for (k, x), (_, y) in zip(
            point_columns(t, p1, v1, a1, np.zeros(15)).items(),
            point_columns(t, p2, v2, a2, np.ones(15)).items(),
            strict=True,
        )
    }
    order = np.argsort(np.r_[np.arange(15), np.arange(15)], kind="stable")  # interleaved
    mixed = {k: x[order] for k, x in block.items()}
    outputs = []
    for name, columns in (("block.csv", block), ("mixed.csv", mixed)):
        src = write(tmp_path / name, columns)
        code, _, err = run(capsys, "ik", "scara", *PAPER, "-i", src, "-o", tmp_path / f"q{name}")
        assert code == 0, err
        outputs.append(read(tmp_path / f"q{name}", (*OUT, "candidate")))
    back = np.argsort(order, kind="stable")
    for key in OUT:
        got = outputs[1][key][back]
        if key == "status":
            assert got.tolist() == outputs[0][key].tolist()
        else:
            np.testing.assert_array_equal(got, outputs[0][key])
    status = outputs[0]["status"]
    assert status[6] == "INVALID_INPUT" and set(np.delete(status, 6)) == {"OK"}
    q = joints_of(outputs[0])
    keep = np.delete(np.arange(15), 6)
    reference = scara_ref.ik_numpy(p1[keep], v1[keep], a1[keep], *L, mode=1)[0]
    assert_whole_turns(q[keep], reference)
    assert np.max(np.abs(np.diff(q[keep, 0]))) < 0.4 and np.max(np.abs(np.diff(q[15:, 0]))) < 0.2


def test_rows_without_times_are_independent(tmp_path, capsys):
    """A file without t: every row on its own, at rest (zero rates), no t column written."""
    t = np.linspace(0.0, 2.0, 9)
    p, v, a = behind_the_base(t)
    src = write(tmp_path / "rows.csv", point_columns(None, p))
    code, _, err = run(capsys, "ik", "scara", *PAPER, "-i", src, "-o", tmp_path / "q.csv")
    assert code == 0, err
    assert "each row" in err
    header = (tmp_path / "q.csv").read_text().splitlines()[0].split(",")
    assert header[:3] == list(JOINTS)
    out = read(tmp_path / "q.csv", OUT)
    zero = np.zeros_like(p)
    np.testing.assert_allclose(
        joints_of(out), scara_ref.ik_numpy(p, zero, zero, *L, mode=1)[0], rtol=0, atol=1e-12
    )
    assert np.all(joints_of(out, "_dot") == 0)


def test_bad_path_inputs_are_one_line_errors(tmp_path, capsys):
    t = np.array([0.0, 0.1, 0.1, 0.3])
    p, v, a = behind_the_base(t)
    src = write(tmp_path / "t.csv", point_columns(t, p, v, a))
    code, _, err = run(capsys, "ik", "scara", *PAPER, "-i", src, "-o", tmp_path / "q.csv")
    assert code == 2 and "t must increase strictly along a path" in err and ":4:" in err
    src = write(tmp_path / "ok.csv", point_columns(t + np.arange(4), p, v, a))
    for flag, value, fragment in (
        ("--v-max", "1,2", "--v-max: give one value or 3"),
        ("--a-max", "-1", "--a-max must be >= 0"),
        ("--v-max", "fast", "expected a number or comma-separated numbers"),
    ):
        code, _, err = run(
            capsys, "ik", "scara", *PAPER, "-i", src, "-o", tmp_path / "q.csv", flag, value
        )
        assert code == 2 and fragment in err, err
    assert not (tmp_path / "q.csv").exists()


# ------------------------------------------------------------------------------ jaxkin plan
def candidates_file(path, t, arcs, with_rates=True):
    """Candidates 10, 11, ...: the arcs ``behind_the_base(t, radius, span)`` of ``arcs``."""
    rows = []
    for c, (radius, span) in enumerate(arcs):
        p, v, a = behind_the_base(t, radius, span)
        rows.append(point_columns(t, p, v if with_rates else None, a if with_rates else None))
        rows[-1] = {"candidate": np.full(len(t), 10 + c)} | rows[-1]
    write(path, {k: np.concatenate([r[k] for r in rows]) for k in rows[0]})
    return path


ARCS = ((90.0, 1.0), (200.0, 1.0), (60.0, 0.5), (120.0, 1.2))


def test_plan_ranks_by_duration_and_writes_the_best_retimed(tmp_path, capsys):
    """Arcs about the base sweeping 2, 2, 1 and 2.4 rad, the second out of reach (200 mm >
    130 mm): theta1 sweeps the arc's angle, so under the same bounds the durations order as
    the sweeps, and the two best are candidates 12 then 10. The written trajectories are
    sampled every period, start at rest on the candidate's first joints, keep every speed
    (1e-6) and acceleration (0.1 %) within the bounds, and stay on the arc (planar forward
    kinematics written here: radius to 1e-6 mm)."""
    t = np.linspace(0.0, 2.0, 21)
    src = candidates_file(tmp_path / "c.csv", t, ARCS)
    v_max, a_max = np.array([1.5, 2.0, 20.0]), np.array([5.0, 8.0, 100.0])
    code, out, err = run(
        capsys, "plan", "scara", *PAPER, "-i", src, "-o", tmp_path / "best.csv",
        "-k", 2, "--v-max", "1.5,2,20", "--a-max", "5,8,100", "--period", 0.01,
        "--ranking", tmp_path / "rank.csv",
    )  # fmt: skip
    assert code == 0, err
    assert "3 feasible" in err and "the 2 best by time-optimal duration" in err
    ranking = read(tmp_path / "rank.csv", ("candidate", "rank", "feasible", "failure", "duration"))
    assert ranking["candidate"].tolist() == [10, 11, 12, 13]
    assert ranking["feasible"].tolist() == [1, 0, 1, 1] and ranking["failure"][1] == "UNREACHABLE"
    duration = ranking["duration"]
    assert duration[2] < duration[0] < duration[3]
    assert ranking["rank"].tolist() == [2, -1, 1, -1]
    best = read(tmp_path / "best.csv", ("rank", "candidate", "t", *OUT[:-1]))
    for rank, label in ((1, 12), (2, 10)):
        rows = best["rank"] == rank
        assert set(best["candidate"][rows]) == {label}
        times = best["t"][rows]
        np.testing.assert_allclose(np.diff(times), 0.01, rtol=0, atol=1e-12)
        assert times[-1] <= duration[label - 10] < times[-1] + 0.01
        q, qd, qdd = (joints_of({n: best[n][rows] for n in best}, s) for s in ("", "_dot", "_ddot"))
        assert np.all(np.abs(qd) <= v_max * (1 + 1e-6)) and np.all(np.abs(qdd) <= a_max * 1.001)
        np.testing.assert_allclose(qd[0], 0.0, atol=1e-12)
        radius, span = ARCS[label - 10]
        own = scara_ref.ik_numpy(*behind_the_base(t, radius, span), *L, mode=1)[0]
        assert_whole_turns(q[:1], own[:1])
        np.testing.assert_allclose(np.hypot(*scara_xy(q).T), radius, rtol=0, atol=1e-6)
    assert out.splitlines()[1].split()[:2] == ["1", "12"]


def joint_candidates(path, q, rates=None):
    """Joint-space candidates 0, 1, ... of ``q`` ``(N, T, 3)`` at t = 0, 0.1, ..., with
    ``rates`` ``(q_dot, q_ddot)`` columns when given."""
    count, samples = q.shape[:2]
    t = np.arange(samples) * 0.1
    columns = {"candidate": np.repeat(np.arange(count), samples), "t": np.tile(t, count)}
    for j, name in enumerate(JOINTS):
        columns[name] = q[..., j].ravel()
        if rates is not None:
            columns[name + "_dot"], columns[name + "_ddot"] = (x[..., j].ravel() for x in rates)
    return write(path, columns)


def test_plan_joint_space_candidates_are_plan_evaluates(tmp_path, capsys):
    """Joint-space candidates go through ``plan.evaluate``: a 0.4 rad jump of theta1 that
    the file's rates do not explain is DISCONTINUOUS at its sample and not written (the
    command's own check called it feasible and wrote it); and ``--by cost`` ranks the same
    with the column in millimetres or in metres (the command scaled a joint without rate
    limits by 1 in its own unit, so 1e6 apart: it chose candidate 0 in mm, 1 in m)."""
    t = np.arange(21) * 0.1
    q = np.stack([0.3 + 0.2 * t, 1.0 - 0.1 * t, 60.0 + 5 * t], -1)
    jumped = q.copy()
    jumped[11:, 0] += 0.4
    rates = np.broadcast_to([0.2, -0.1, 5.0], (2, 21, 3)), np.zeros((2, 21, 3))
    src = joint_candidates(tmp_path / "jump.csv", np.stack([q, jumped]), rates)
    code, _, err = run(
        capsys, "plan", "scara", *PAPER, "-i", src, "-o", tmp_path / "b.csv", "-k", 2,
        "--v-max", "1,1,50", "--a-max", "10,10,500", "--ranking", tmp_path / "r.csv",
    )  # fmt: skip
    assert code == 0, err
    ranking = read(tmp_path / "r.csv", ("rank", "feasible", "first_failure", "failure"))
    assert ranking["feasible"].tolist() == [1, 0] and ranking["rank"].tolist() == [1, -1]
    assert ranking["failure"][1] == "DISCONTINUOUS" and ranking["first_failure"][1] == 11
    assert set(read(tmp_path / "b.csv", ("candidate",))["candidate"]) == {0}
    limits = plan.Limits.create(3, v_max=[1, 1, 50], a_max=[10, 10, 500])
    path = paths.Path.from_jet(Jet.of(np.stack([q, jumped]), *rates), 0.1, "joint")
    own = plan.evaluate(scara.Scara.paper(), path, limits)
    assert np.asarray(own.first_failure).tolist() == [-1, 11]
    swing = np.stack([0.3 + 0.5 * np.sin(t), 1.0 + 0 * t, 60.0 + 0 * t], -1)
    column = np.stack([0.3 + 0 * t, 1.0 + 0 * t, 60.0 + 10 * np.sin(t)], -1)
    costs = []
    for unit, robot in ((1.0, PAPER), (1e-3, ["--l-oa", 0.15, "--l-ab", 0.08, "--l-bc", 0.05])):
        both = np.stack([swing, column]) * [1.0, 1.0, unit]
        src = joint_candidates(tmp_path / f"units{unit}.csv", both)
        out, ranked = tmp_path / f"u{unit}.csv", tmp_path / f"ur{unit}.csv"
        code, _, err = run(
            capsys, "plan", "scara", *robot, "-i", src, "-o", out, "--by", "cost",
            "--ranking", ranked,
        )  # fmt: skip
        assert code == 0, err
        assert "not retimed (retiming needs a finite acceleration limit" in err
        costs.append(read(ranked, ("rank", "cost")))
    assert costs[0]["rank"].tolist() == costs[1]["rank"].tolist() == [-1, 1]
    np.testing.assert_allclose(costs[1]["cost"], costs[0]["cost"], rtol=1e-9)


def test_plan_two_sample_candidates_are_refused_or_written_at_their_samples(tmp_path, capsys):
    """Candidates of 2 samples have no rest-to-rest retiming: ``--by duration`` is a one-line
    error saying so; ``--by cost`` writes the best at the file's samples, with a warning
    (it wrote a file without rows and said nothing)."""
    q = np.stack([[[0.3, 1.0, 60.0], [0.4, 1.1, 62.0]], [[0.3, 1.0, 60.0], [0.5, 0.9, 65.0]]])
    src = joint_candidates(tmp_path / "two.csv", q)
    limits = ["--v-max", "2,3,40", "--a-max", "6,8,100"]
    code, _, err = run(capsys, "plan", "scara", *PAPER, "-i", src, "-o", tmp_path / "d.csv",
                       *limits)  # fmt: skip
    assert code == 2 and "needs candidates of at least 3 samples, got 2" in err
    assert not (tmp_path / "d.csv").exists()
    code, _, err = run(
        capsys, "plan", "scara", *PAPER, "-i", src, "-o", tmp_path / "c.csv", "--by", "cost",
        *limits,
    )  # fmt: skip
    assert code == 0, err
    assert "not retimed (retiming from rest to rest needs candidates of at least 3" in err
    written = read(tmp_path / "c.csv", ("rank", "candidate", "t", *JOINTS))
    assert written["t"].tolist() == [0.0, 0.1] and set(written["candidate"]) == {0}
    np.testing.assert_allclose(joints_of(written), q[0], rtol=0, atol=1e-12)


def scara_xy(q):
    """Planar forward kinematics of the paper SCARA (independent of the library)."""
    th1, th2 = q[:, 0], q[:, 1]
    return np.stack(
        [
            L[1] * np.cos(th1) + L[2] * np.cos(th1 + th2),
            L[1] * np.sin(th1) + L[2] * np.sin(th1 + th2),
        ],
        -1,
    )


def doubled_joint_candidates(path, t):
    """Two joint-space candidates of the paper SCARA, lines in time: the second moves each
    joint twice as fast (theta1 0.4 rad/s). Returns the file, its columns and the first's
    joints ``(T, 3)``."""
    joints = {"candidate": np.repeat([0, 1], len(t)), "t": np.r_[t, t]}
    q = np.stack([0.3 + 0.2 * t, 1.0 - 0.1 * t, 60.0 + 5 * t], -1)
    for j, n in enumerate(JOINTS):
        joints[n] = np.r_[q[:, j], 2 * q[:, j]]
    return write(path, joints), joints, q


@pytest.mark.slow
def test_plan_by_cost_joint_space_and_errors(tmp_path, capsys):
    """``--by cost`` without rate bounds writes the cheapest at the file's samples; a file of
    joint columns is a joint-space candidate set (forward kinematics, limits); unequal
    candidates and a duration ranking without bounds are one-line errors."""
    t = np.linspace(0.0, 2.0, 21)
    src = candidates_file(tmp_path / "c.csv", t, ((90.0, 1.0), (60.0, 0.5)), with_rates=False)
    code, out, err = run(
        capsys, "plan", "scara", *PAPER, "-i", src, "-o", tmp_path / "b.csv", "--by", "cost"
    )
    assert code == 0, err
    best = read(tmp_path / "b.csv", ("rank", "candidate", "t"))
    assert set(best["candidate"]) == {11} and best["t"].tolist() == t.tolist()
    code, _, err = run(capsys, "plan", "scara", *PAPER, "-i", src, "-o", tmp_path / "d.csv")
    assert code == 2 and "theta1, theta2, l3 have none" in err and "--a-max" in err
    src, joints, q = doubled_joint_candidates(tmp_path / "j.csv", t)
    code, _, err = run(
        capsys, "plan", "scara", *PAPER, "-i", src, "-o", tmp_path / "jb.csv", "-k", 2,
        "--v-max", "0.3,1,50", "--a-max", "10,10,500", "--ranking", tmp_path / "jr.csv",
    )  # fmt: skip
    assert code == 0, err
    assert "(joint space), 1 feasible" in err  # candidate 1's theta1 moves at 0.4 > 0.3 rad/s
    ranking = read(tmp_path / "jr.csv", ("candidate", "rank", "failure", "first_failure"))
    assert ranking["rank"].tolist() == [1, -1]
    assert ranking["failure"][1] == "OUT_OF_LIMITS" and ranking["first_failure"][1] == 0
    written = read(tmp_path / "jb.csv", ("candidate", *JOINTS))
    assert set(written["candidate"]) == {0}
    # From the first sample at rest to within one period (0.1 s) of the last.
    np.testing.assert_allclose(joints_of(written)[0], q[0], rtol=0, atol=1e-12)
    end = np.abs(joints_of(written)[-1] - q[-1])
    assert np.all(end <= np.array([0.3, 1, 50]) * 0.1)
    uneven = write(tmp_path / "u.csv", {k: v[:-1] for k, v in joints.items()})
    code, _, err = run(capsys, "plan", "scara", *PAPER, "-i", uneven, "-o", tmp_path / "u2.csv")
    assert code == 2 and "same number of samples" in err


def test_plan_names_the_joint_and_the_limit_passed(tmp_path, capsys):
    """Per-joint speed bounds (rad/s, rad/s, mm/s): candidate 1's theta1 moves at 0.4 rad/s
    over its 0.3; the ranking names the joint, the limit, the value and the bound, and stderr
    says it with units."""
    src, _, _ = doubled_joint_candidates(tmp_path / "j.csv", np.linspace(0.0, 2.0, 21))
    code, _, err = run(
        capsys, "plan", "scara", *PAPER, "-i", src, "-o", tmp_path / "b.csv",
        "--v-max", "0.3,1,50", "--a-max", "10,10,500", "--ranking", tmp_path / "r.csv",
    )  # fmt: skip
    assert code == 0, err
    names = ("candidate", "failure", "joint", "limit", "value", "bound")
    ranking = read(tmp_path / "r.csv", names)
    assert ranking["failure"].tolist() == ["", "OUT_OF_LIMITS"]
    assert ranking["joint"].tolist() == ["", "theta1"] and ranking["limit"][1] == "v_max"
    np.testing.assert_allclose([ranking["value"][1], ranking["bound"][1]], [0.4, 0.3], rtol=1e-9)
    assert np.isnan(ranking["value"][0])
    assert (
        "1 candidate OUT_OF_LIMITS; the first, candidate 1, at sample 0 (t 0): "
        "theta1 |q_dot| 0.4 rad/s > v_max 0.3 rad/s" in err
    )


URDF_ARM = """<robot name="arm">
  <link name="base"/><link name="l1"/><link name="l2"/><link name="l3"/><link name="tool"/>
  <joint name="turn" type="continuous"><parent link="base"/><child link="l1"/>
    <origin xyz="0 0 0.3"/><axis xyz="0 0 1"/></joint>
  <joint name="shoulder" type="revolute"><parent link="l1"/><child link="l2"/>
    <axis xyz="0 1 0"/><limit lower="-2" upper="2" effort="1" velocity="2"/></joint>
  <joint name="elbow" type="revolute"><parent link="l2"/><child link="l3"/>
    <origin xyz="0 0 0.4"/><axis xyz="0 1 0"/>
    <limit lower="0.1" upper="2.8" effort="1" velocity="2"/></joint>
  <joint name="flange" type="fixed"><parent link="l3"/><child link="tool"/>
    <origin xyz="0 0 0.35" rpy="0 1.5708 0"/></joint>
</robot>"""


@pytest.mark.slow
def test_urdf_arm_straight_line_is_continuous(tmp_path, capsys):
    """A 7-joint arm (xArm7 of example-robot-data) on poses from a straight joint motion of
    21 rows: solved row by row, joints jump by more than 4 rad between rows; as a path every
    row is OK and no joint moves more than 0.1 rad between rows (the motion's own largest
    step is 0.03 rad), and the poses of the written joints (the library's fk, checked against
    Pinocchio in tests/test_urdf.py) are the file's to 1e-9."""
    from scipy.spatial.transform import Rotation

    from jaxkin import fk, serial

    robots = importlib.metadata.distribution("example-robot-data").locate_file(
        "cmeel.prefix/share/example-robot-data/robots"
    )
    urdf = str(robots / "xarm_description/urdf/xarm7.urdf")
    chain = serial.from_urdf(urdf, "link7")
    t = np.linspace(0.0, 2.0, 21)
    q0 = np.array([0.2, -0.3, 0.1, 0.9, 0.2, 1.2, 0.3])
    q = q0 + np.array([0.5, 0.3, -0.2, 0.4, -0.3, -0.4, 0.6]) * (t / 2)[:, None]
    pose = np.asarray(fk(chain, Jet.of(q)).x.p)
    quat = Rotation.from_matrix(pose[:, :3, :3]).as_quat()[:, [3, 0, 1, 2]]
    names = ("x", "y", "z", "qw", "qx", "qy", "qz")
    rows = np.c_[pose[:, :3, 3], quat]
    src = write(tmp_path / "line.csv", {"t": t} | {n: rows[:, j] for j, n in enumerate(names)})
    argv = ["ik", "urdf", "--robot", urdf, "--tip", "link7", "-i", src]
    steps = {}
    for mode in ("path", "--each-row"):
        out = tmp_path / f"{mode}.csv"
        code, _, err = run(capsys, *argv, "-o", out, *([mode] if mode != "path" else []))
        assert code == 0, err
        table = read(out, (*chain.joint_names, "status"))
        assert set(table["status"]) == {"OK"}
        solved = np.stack([table[n] for n in chain.joint_names], -1)
        steps[mode] = np.max(np.abs(np.diff(solved, axis=0)))
        reached = np.asarray(fk(chain, Jet.of(solved)).x.p)
        np.testing.assert_allclose(reached, pose, rtol=0, atol=1e-9)
    assert steps["path"] < 0.1 and steps["--each-row"] > 4.0


@pytest.mark.slow
def test_plan_urdf_arm_joint_and_task_space(tmp_path, capsys):
    """A 3-joint URDF arm: two task-space candidates (poses of one line in joint space,
    timed linearly and by a smoothstep, within the bounds): both feasible, and the k = 2
    written trajectories keep the speed bound (the URDF's 2 rad/s; --v-max 2 for the
    continuous joint, which has none) to 1e-6 and reach it."""
    from scipy.spatial.transform import Rotation

    from jaxkin import fk, serial

    (tmp_path / "arm.urdf").write_text(URDF_ARM)
    chain = serial.from_urdf(str(tmp_path / "arm.urdf"), "tool")
    t = np.linspace(0.0, 1.0, 21)
    names = ("x", "y", "z", "qw", "qx", "qy", "qz")
    columns = {}
    for c, s in enumerate((t, 3 * t**2 - 2 * t**3)):  # one line, timed two ways
        q = np.stack([2.5 + 1.0 * s, 0.3 - 0.5 * s, 1.2 + 0.3 * s], -1)
        pose = np.asarray(fk(chain, Jet.of(q)).x.p)
        quat = Rotation.from_matrix(pose[:, :3, :3]).as_quat()[:, [3, 0, 1, 2]]
        rows = np.c_[np.full(21, c), t, pose[:, :3, 3], quat]
        for j, n in enumerate(("candidate", "t", *names)):
            columns[n] = np.r_[columns.get(n, []), rows[:, j]]
    src = write(tmp_path / "c.csv", columns)
    code, _, err = run(
        capsys, "plan", "urdf", "--robot", tmp_path / "arm.urdf", "--tip", "tool", "-i", src,
        "-o", tmp_path / "b.csv", "-k", 2, "--v-max", 2, "--a-max", 10, "--period", 0.02,
        "--ranking", tmp_path / "r.csv",
    )  # fmt: skip
    assert code == 0, err
    ranking = read(tmp_path / "r.csv", ("candidate", "feasible", "duration"))
    assert ranking["feasible"].tolist() == [1, 1]
    best = read(tmp_path / "b.csv", ("rank", *(n + "_dot" for n in chain.joint_names)))
    assert set(best.pop("rank")) == {1, 2}
    speeds = np.stack(list(best.values()), -1)
    assert np.all(np.abs(speeds) <= 2.0 * (1 + 1e-6))
    assert np.max(np.abs(speeds)) > 1.9  # the time-optimal motion reaches the bound


@pytest.mark.slow
def test_paths_are_written_batch_by_batch(tmp_path, capsys, monkeypatch):
    """Three candidates of 5 rows with ``--chunk-size 16`` (a candidate holds 8 padded
    samples): two batches, each written as soon as it is solved, one header; the same rows
    as one batch gives (to 1e-13: the accelerations' rounding depends on the batch)."""
    t = np.linspace(0.0, 2.0, 5)
    src = candidates_file(tmp_path / "c.csv", t, ((90.0, 1.0), (60.0, 0.5), (120.0, 1.2)))
    code, _, err = run(capsys, "ik", "scara", *PAPER, "-i", src, "-o", tmp_path / "a.csv")
    assert code == 0, err
    parts = []
    original = kio.write_csv

    def counted(f, columns, header=True):
        parts.append((len(next(iter(columns.values()))), header))
        original(f, columns, header)

    monkeypatch.setattr(kio, "write_csv", counted)
    argv = ["--chunk-size", 16, "-i", src, "-o", tmp_path / "b.csv"]
    code, _, err = run(capsys, "ik", "scara", *PAPER, *argv)
    assert code == 0, err
    assert parts == [(10, True), (5, False)]
    one, two = (read(tmp_path / name, OUT) for name in ("a.csv", "b.csv"))
    assert one.pop("status").tolist() == two.pop("status").tolist()
    for key, values in one.items():  # batch shapes change the rounding, not the values
        np.testing.assert_allclose(two[key], values, rtol=1e-13, atol=1e-13)


# ------------------------------------------------------------------------------ streaming
def streamed(path, names, block, size, **kwargs):
    """Every part of ``files.completed_parts`` joined: (p, v, a, valid, part lengths)."""
    parts = list(
        kio.completed_parts(kio.trajectory_parts(path, names, block=block), "not-a-knot", size,
                            **kwargs)
    )  # fmt: skip
    joined = [np.concatenate([part[k] for part in parts]) for k in range(1, 5)]
    return (*joined, [len(part[1]) for part in parts], parts)


@pytest.mark.parametrize("whole", [False, True])
def test_streamed_parts_have_the_whole_files_rates(tmp_path, whole):
    """Three candidates of 150 unevenly spaced rows (a NaN row in the second), read 37 rows
    at a time and given out about 50 at a time: the splined rates are those of the whole
    file (1e-12 relative to their scale: each part's splines see 64 rows of context), the
    NaN row invalid; with ``whole`` every part ends at a candidate's end."""
    rng = np.random.default_rng(0)
    t = np.cumsum(rng.uniform(0.005, 0.02, 150))
    rows = []
    for c in range(3):
        p = np.stack([np.sin(3 * t + c), np.cos(2 * t) * (1 + c), t * t], -1)
        rows.append(np.c_[np.full(150, c), t, p])
    table = np.concatenate(rows)
    table[200, 3] = np.nan
    src = write(
        tmp_path / "c.csv", dict(zip(("candidate", "t", "x", "y", "z"), table.T, strict=True))
    )
    p, v, a, valid, lengths, _ = streamed(src, "xyz", 37, 50, whole=whole)
    ref = kio.complete_rates(kio.read_trajectory(src, "xyz"), "not-a-knot")
    np.testing.assert_array_equal(p, ref[0])
    assert valid.tolist() == ref[3].tolist() and not valid[200]
    for got, want in ((v, ref[1]), (a, ref[2])):
        ok = ref[3]
        scale = np.max(np.abs(want[ok]))
        np.testing.assert_allclose(got[ok], want[ok], rtol=0, atol=1e-12 * scale)
    if whole:
        assert lengths == [150, 150, 150]
    else:
        assert len(lengths) > 3 and sum(lengths) == 450


def test_streamed_pose_rows_keep_quaternion_signs_across_parts(tmp_path):
    """Pose rows whose quaternions flip sign and change length from row to row, read 7 rows
    at a time, given out about 10 at a time: the same unit, sign-continuous quaternions and
    rates as the whole file (1e-12 of their scale)."""
    t = np.linspace(0.0, 2.0, 200)
    half = 0.8 * t
    axis = np.array([1.0, 2.0, 2.0]) / 3.0
    q = np.concatenate([np.cos(half)[:, None], np.sin(half)[:, None] * axis], -1)
    q *= (np.where(np.arange(200) % 3 == 0, -1.0, 1.0) * np.linspace(0.5, 3.0, 200))[:, None]
    names = ("x", "y", "z", "qw", "qx", "qy", "qz")
    block = np.c_[0.1 * t, -0.2 * t, 0.3 + t * t, q]
    src = write(tmp_path / "poses.csv", {"t": t} | {n: block[:, j] for j, n in enumerate(names)})
    p, v, a, valid, lengths, _ = streamed(src, names, 7, 10, quaternions=True)
    whole = kio.continuous_quaternions(kio.read_trajectory(src, names))
    ref = kio.complete_rates(whole, "not-a-knot")
    assert len(lengths) > 1 and sum(lengths) == 200
    for got, want in zip((p, v, a), ref[:3], strict=True):
        np.testing.assert_allclose(got, want, rtol=0, atol=1e-12 * np.max(np.abs(want)))
    assert np.any(np.sum(q[1:] * q[:-1], -1) < 0)  # the file itself flips signs
    assert np.all(np.sum(p[1:, 3:] * p[:-1, 3:], -1) > 0)


def test_streamed_times_must_increase_across_parts(tmp_path):
    """A time going back across a part boundary is found, with its line."""
    t = np.arange(30.0)
    t[20] = 5.0
    p, _, _ = behind_the_base(t / 20)
    src = write(tmp_path / "t.csv", point_columns(t, p))
    with pytest.raises(kio.InputError, match=r"t.csv:22: t must increase strictly"):
        streamed(src, "xyz", 7, 10)


@pytest.mark.slow
@pytest.mark.parametrize("mode", [["--each-row"], []])
def test_memory_is_bounded_by_the_chunk(tmp_path, capsys, mode):
    """``ik scara`` on 8,000 and 32,000 rows (positions only, candidates of 500 rows,
    --chunk-size 2048), rows on their own or as paths: the Python heap's peak (tracemalloc:
    NumPy arrays and parsed text; not XLA's buffers, which a chunk bounds) grows by less than
    20 bytes per extra row, against about 170 before streaming."""
    import tracemalloc

    peaks = []
    for n in (8_000, 32_000):
        t = np.arange(n) * 0.01
        p, _, _ = spiral(t)
        src = write(tmp_path / f"{n}.csv", point_columns(t, p, candidate=np.arange(n) // 500))
        argv = ["ik", "scara", *PAPER, "-i", src, "-o", tmp_path / "q.csv", "-q"]
        argv += ["--chunk-size", 2048, *mode]
        assert run(capsys, *argv)[0] == 0  # compiles
        tracemalloc.start()
        try:
            assert run(capsys, *argv)[0] == 0
            peaks.append(tracemalloc.get_traced_memory()[1])
        finally:
            tracemalloc.stop()
    assert (peaks[1] - peaks[0]) / 24_000 < 20, peaks


def test_plan_with_a_world_file(tmp_path, capsys):
    """``--world``: a post of 6 mm square standing on the -x axis, its near face 87 mm from
    the base. The arm of the arc of 60 mm stays within 80 mm of the base (the elbow's
    radius), so it keeps at least 7 mm clear and stays feasible; the arcs of 90 and 120 mm
    reach past the post's radius while sweeping across the -x axis (the tip, then the
    forearm from the elbow to the tip) and fail with COLLISION; --ranking gets each
    candidate's clearance. Joint-space candidates are checked too, and the post as a cylinder
    gives the same verdicts. A missing file and a bad entry are one-line errors naming the file."""
    t = np.linspace(0.0, 2.0, 21)
    src = candidates_file(tmp_path / "c.csv", t, ARCS)
    post = {"name": "post", "center": [-90.0, 0.0, 0.0], "half_extents": [3, 3, 500]}
    world = {"units": "mm", "frame": "the SCARA's base", "boxes": [post]}
    (tmp_path / "post.json").write_text(json.dumps(world))
    argv = ["plan", "scara", *PAPER, "-i", src, "-o", tmp_path / "best.csv", "-k", 2,
            "--v-max", "1.5,2,20", "--a-max", "5,8,100",
            "--ranking", tmp_path / "rank.csv"]  # fmt: skip
    code, _, err = run(capsys, *argv, "--world", tmp_path / "post.json")
    assert code == 0, err
    names = ("candidate", "feasible", "failure", "first_failure", "clearance")
    ranking = read(tmp_path / "rank.csv", names)
    assert ranking["failure"].tolist() == ["COLLISION", "UNREACHABLE", "", "COLLISION"]
    assert ranking["first_failure"][0] <= 10  # at or before the post (t = 1 is sample 10)
    assert ranking["clearance"][0] < 0 and ranking["clearance"][3] < 0
    assert ranking["clearance"][2] >= 7.0
    # joint space: candidate 0 holds the tool over the post, candidate 1 far from it
    q_post = scara_ref.ik_numpy(*behind_the_base(np.ones(1), 90.0, 1.0), *L, mode=1)[0][0]
    joints = {"candidate": np.repeat([0, 1], 21), "t": np.r_[t, t]}
    for j, n in enumerate(JOINTS):
        joints[n] = np.r_[np.full(21, q_post[j]), np.full(21, [0.0, 0.5, 60.0][j])]
    jsrc = write(tmp_path / "j.csv", joints)
    code, _, err = run(
        capsys, "plan", "scara", *PAPER, "-i", jsrc, "-o", tmp_path / "jb.csv", "--by", "cost",
        "--ranking", tmp_path / "jr.csv", "--world", tmp_path / "post.json",
    )  # fmt: skip
    assert code == 0, err
    jr = read(tmp_path / "jr.csv", names)
    assert jr["failure"].tolist() == ["COLLISION", ""] and jr["first_failure"][0] == 0
    # the same post as an upright cylinder of radius 3 (inside the box): the same verdicts
    cylinder = {"center": [-90.0, 0.0, 0.0], "radius": 3, "half_length": 500, "axis": [0, 0, 1]}
    cyl = {"units": "mm", "boxes": [], "cylinders": [cylinder]}
    (tmp_path / "cyl.json").write_text(json.dumps(cyl))
    code, _, err = run(
        capsys, *argv[:-1], tmp_path / "cyl_rank.csv", "--world", tmp_path / "cyl.json"
    )
    assert code == 0, err
    by_cylinder = read(tmp_path / "cyl_rank.csv", names)
    assert by_cylinder["failure"].tolist() == ["COLLISION", "UNREACHABLE", "", "COLLISION"]
    assert by_cylinder["clearance"][2] >= ranking["clearance"][2]
    code, _, err = run(capsys, *argv, "--world", tmp_path / "none.json")
    assert code == 2 and "--world" in err and "no such world file" in err
    world["boxes"][0]["half_extents"] = [3, 3]
    (tmp_path / "bad.json").write_text(json.dumps(world))
    code, _, err = run(capsys, *argv, "--world", tmp_path / "bad.json")
    assert code == 2 and "bad.json: boxes[0] ('post'): half_extents must be shape [3]" in err
    code, _, err = run(capsys, *argv[:-2], "--ranking", tmp_path / "post.json",
                       "--world", tmp_path / "post.json")  # fmt: skip
    assert code == 2 and str(tmp_path / "post.json") in err  # an input is never overwritten
