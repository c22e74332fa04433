"""A long path through ``jaxkin ik`` solved in windows (``--chunk-size``) against the same
path solved whole: the warm start, the branch, the unwrapping turns, the shift into the
limits, the continuity check of each window's first step and the limit checks are carried
across window boundaries, so the rows written are the whole path's.

The reference is the whole-path solve of the same file with a chunk larger than the path (one
window), itself checked against independent per-row references in tests/test_cli_paths.py.
Positions, speeds, statuses and margins must be identical; accelerations agree to 1e-13
(the SCARA kernel's rounding depends on the padded shape it runs at, as between batches).
"""

from __future__ import annotations

import os
import subprocess
import sys

import numpy as np
import pytest

from jaxkin.cli import files as kio
from jaxkin.cli import planning
from tests.test_cli_paths import JOINTS, OUT, PAPER, URDF_ARM, behind_the_base, read, run, write

SCARA_TOML = """robot = "scara"
l_oa = 150.0
l_ab = 80.0
l_bc = 50.0
[limits]
theta1 = [-4.6, -1.0]
"""


def point_file(path, t, p, v, a):
    columns = {"t": t} | {n: p[:, j] for j, n in enumerate("xyz")}
    columns |= {f"v{n}": v[:, j] for j, n in enumerate("xyz")}
    columns |= {f"a{n}": a[:, j] for j, n in enumerate("xyz")}
    return write(path, columns)


def solved_both_ways(capsys, argv, tmp_path, window, names):
    """The file solved with one window and with windows of ``window`` rows."""
    tables = []
    for name, chunk in (("whole", 1 << 16), ("windows", window)):
        out = tmp_path / f"{name}.csv"
        code, _, err = run(capsys, *argv, "-o", out, "--chunk-size", chunk)
        assert code == 0, err
        tables.append(read(out, names))
    return tables


def assert_same_rows(whole, windows, accel_atol=1e-13, atol=0.0):
    """The same statuses; positions, speeds and margins equal (to ``atol``), accelerations
    to ``accel_atol``."""
    assert whole["status"].tolist() == windows["status"].tolist()
    for key, values in whole.items():
        if key == "status":
            continue
        if key.endswith("_ddot"):
            np.testing.assert_allclose(windows[key], values, rtol=0, atol=accel_atol)
        elif atol:
            np.testing.assert_allclose(windows[key], values, rtol=0, atol=atol)
        else:
            np.testing.assert_array_equal(windows[key], values)


@pytest.mark.slow
@pytest.mark.parametrize("dtype", ["float64", "float32"])
def test_scara_windows_give_the_whole_paths_rows(tmp_path, capsys, dtype):
    """30 rows of an arc behind the base (theta1 wraps from +pi to -pi per row), rates given,
    positions shifted by 1 mm from row 16 on (the first row of the third window of 8): solved
    in windows of 8 rows, the same rows as whole, row 16 alone DISCONTINUOUS; theta1's
    unwrapped range is moved one turn down into the limits [-4.6, -1] (below -pi: a whole
    turn carried across windows, no per-row angle lies there); theta2's speed bound 0.72
    rad/s is crossed between windows (rows OUT_OF_LIMITS on both sides). In float32 too, the
    statuses identical, positions and speeds to 5e-7 (two ulps of theta1 ~ 3: the window
    adds its whole turns in a separate program), accelerations to 1e-4 (of about 1)."""
    (tmp_path / "scara.toml").write_text(SCARA_TOML)
    t = np.linspace(0.0, 2.0, 30)
    p, v, a = behind_the_base(t)
    p = p.copy()
    p[16:, 0] += 1.0
    src = point_file(tmp_path / "arc.csv", t, p, v, a)
    argv = ["ik", "scara", "--robot", tmp_path / "scara.toml", "-i", src, "--v-max", "2,0.72,50"]
    argv += ["--dtype", dtype]
    whole, windows = solved_both_ways(capsys, argv, tmp_path, 8, (*OUT, "margin"))
    if dtype == "float64":
        assert_same_rows(whole, windows)
    else:  # an ulp of theta1 (about 2.4e-7 rad) from where the turns are added
        assert_same_rows(whole, windows, accel_atol=1e-4, atol=5e-7)
    status = whole["status"]
    assert status[16] == "DISCONTINUOUS"
    assert {"OK", "OUT_OF_LIMITS"} <= set(np.delete(status, 16))
    assert np.min(whole["theta1"]) < -np.pi and np.max(whole["theta1"]) <= -1.0
    assert np.all(np.abs(np.diff(whole["theta1"])) < 1.0)


@pytest.mark.slow
def test_scara_long_path_windows_and_one_program_per_window_size(tmp_path, capsys):
    """1,000 rows (arc behind the base, three jumps: at window boundaries 512 and 576 and
    within a window at 700, an invalid row at 300) in windows of 64 rows: the rows of the
    whole solve; the rows whose per-row theta1 (in (-pi, pi]) is outside the limits are
    OUT_OF_LIMITS (the first half), the others moved a turn down into them. A second file of
    another length (777 rows) compiles no new window program: every window, the last too, is
    padded to the window's size."""
    (tmp_path / "scara.toml").write_text(SCARA_TOML)
    t = np.linspace(0.0, 2.0, 1000)
    p, v, a = behind_the_base(t)
    p = p.copy()
    for row in (512, 576, 700):
        p[row:, 1] += 0.5
    p[300, 2] = np.nan
    src = point_file(tmp_path / "arc.csv", t, p, v, a)
    argv = ["ik", "scara", "--robot", tmp_path / "scara.toml", "-i", src]
    whole, windows = solved_both_ways(capsys, argv, tmp_path, 64, (*OUT, "margin"))
    assert_same_rows(whole, windows)
    status = whole["status"]
    jumps = [512, 576, 700]
    assert status[jumps].tolist() == ["DISCONTINUOUS"] * 3
    assert status[300] == "INVALID_INPUT"
    assert set(np.delete(status, [*jumps, 300])) == {"OK", "OUT_OF_LIMITS"}
    assert np.nanmin(whole["theta1"]) < -np.pi
    sizes = (
        planning._window_jit.jitted._cache_size(),
        planning._window_checks_jit.jitted._cache_size(),
    )
    src = point_file(tmp_path / "short.csv", t[:777], p[:777], v[:777], a[:777])
    out = tmp_path / "short_out.csv"
    argv[argv.index("-i") + 1] = src
    code, _, err = run(capsys, *argv, "-o", out, "--chunk-size", 64)
    assert code == 0, err
    assert (
        planning._window_jit.jitted._cache_size(),
        planning._window_checks_jit.jitted._cache_size(),
    ) == sizes
    assert read(out, ("status",))["status"].tolist() == status[:777].tolist()


@pytest.mark.slow
def test_urdf_chain_windows_give_the_whole_paths_rows(tmp_path, capsys):
    """A 3-joint URDF arm (chain IK, warm-started along the path) on 100 pose rows with their
    exact rates, from a joint motion whose continuous base joint crosses pi near row 42 and
    whose shoulder jumps by 0.3 rad at row 48 (rates unchanged): in windows of 16 rows, the
    rows of the whole solve, identical (the warm start carried from the last solved sample),
    row 48 DISCONTINUOUS (the first row of a window), the rows where the shoulder exceeds
    --v-max 0.8 OUT_OF_LIMITS (rows 36-67, across the boundaries at rows 48 and 64), a NaN row
    INVALID_INPUT; the base joint is continuous through pi."""
    from jaxkin import Jet, fk, paths, serial

    (tmp_path / "arm.urdf").write_text(URDF_ARM)
    chain = serial.from_urdf(str(tmp_path / "arm.urdf"), "tool")
    t = np.linspace(0.0, 1.0, 100)
    w = 3.0
    q = np.stack([2.5 + 1.5 * t, 0.3 - 0.3 * np.cos(w * t), 1.2 + 0.3 * np.sin(w * t)], -1)
    qd = np.stack([np.full_like(t, 1.5), 0.3 * w * np.sin(w * t), 0.3 * w * np.cos(w * t)], -1)
    qdd = np.stack([0 * t, 0.3 * w * w * np.cos(w * t), -0.3 * w * w * np.sin(w * t)], -1)
    q[48:, 1] += 0.3
    pose = fk(chain, Jet(*(np.asarray(x) for x in (q, qd, qdd)))).x
    rows = [np.asarray(x) for x in paths.quaternions_from_pose(pose)]
    names = ("x", "y", "z", "qw", "qx", "qy", "qz")
    rate_names = kio.rate_names(names)
    columns = {"t": t} | {n: rows[0][:, j] for j, n in enumerate(names)}
    for block, group in zip(rows[1:], rate_names, strict=True):
        columns |= {n: block[:, j] for j, n in enumerate(group)}
    columns["x"][70] = np.nan
    src = write(tmp_path / "poses.csv", columns)
    joints = chain.joint_names
    out_names = (*joints, *(n + "_dot" for n in joints), *(n + "_ddot" for n in joints))
    argv = ["ik", "urdf", "--robot", tmp_path / "arm.urdf", "--tip", "tool", "-i", src]
    argv += ["--v-max", "3,0.8,3"]
    whole, windows = solved_both_ways(capsys, argv, tmp_path, 16, (*out_names, "status", "margin"))
    assert_same_rows(whole, windows, accel_atol=0.0)
    status = whole["status"]
    fast = np.abs(qd[:, 1]) > 0.8
    assert fast[47] and fast[49] and fast[63] and fast[64]
    assert status[48] == "DISCONTINUOUS" and status[70] == "INVALID_INPUT"
    others = np.setdiff1d(np.arange(100), [48, 70])
    assert (status[others] == "OUT_OF_LIMITS").tolist() == fast[others].tolist()
    assert set(status[others][~fast[others]]) == {"OK"}
    turn = whole["turn"]
    assert np.max(np.abs(np.diff(turn[np.isfinite(turn)]))) < 0.1 and np.nanmax(turn) > np.pi


MEASURE = """
import sys
from jaxkin import cli
code = cli.main(sys.argv[1:])
# VmHWM (kB): this process's own peak; ru_maxrss keeps the forking parent's across exec
print(next(l.split()[1] for l in open("/proc/self/status") if l.startswith("VmHWM")))
sys.exit(code)
"""


@pytest.mark.slow
def test_path_mode_peak_memory_does_not_grow_with_the_path(tmp_path):
    """``ik scara`` on one path (positions only, rates splined) of 20,000 and 200,000 rows
    with ``--chunk-size 4096``, each in a fresh process: the peak resident memory grows by
    less than 400 bytes per extra row. Measured: the two peaks within 10 MB of each other
    (about 350 MB, set by compilation, varies by that much from process to process), so
    the long path is needed to see growth through that noise; the whole-path solve,
    compiled for the path's length, grew by about 1.5 kB per row (270 MB)."""
    from tests.test_cli import spiral

    peaks = []
    for n in (20_000, 200_000):
        t = np.arange(n) * 0.01
        p, _, _ = spiral(t)
        src = write(tmp_path / f"{n}.csv", {"t": t} | {k: p[:, j] for j, k in enumerate("xyz")})
        argv = ["ik", "scara", *PAPER, "-i", src, "-o", tmp_path / "q.csv", "-q"]
        argv += ["--chunk-size", "4096"]
        # no compilation cache: both runs compile the same programs (a stored program loaded
        # by the second run and compiled by the first would make their peaks incomparable)
        env = dict(os.environ, JAX_PLATFORMS="cpu", JAXKIN_COMPILATION_CACHE="0")
        done = subprocess.run(
            [sys.executable, "-c", MEASURE, *map(str, argv)],
            capture_output=True,
            text=True,
            env=env,
            check=False,
        )
        assert done.returncode == 0, done.stderr
        peaks.append(int(done.stdout.split()[-1]) * 1024)  # ru_maxrss: kB on Linux
    assert (peaks[1] - peaks[0]) / 180_000 < 400, peaks
    assert read(tmp_path / "q.csv", JOINTS)["theta1"].shape == (200_000,)


def test_plan_checks_in_windows_equal_the_whole_paths():
    """``plan.unwrapped(turns=)``, ``solved_range``, ``range_turns`` and
    ``checked_samples(turns=)`` window by window (8 samples, each prefixed with the previous
    window's last one) on 40 SCARA samples (theta1 given per sample in (-pi, pi], unwrapped
    2.66 ... 4.66 rad, limits [-4.6, -1]; a jump at sample 16, a window's first; a sample
    not converged, one outside a limit in the solve; exact rates): the joints and statuses
    of ``checked_samples`` on the whole path, exactly."""
    import jax

    from jaxkin import Jet, Status, plan
    from jaxkin.scara import Scara

    robot = Scara.paper()
    t = np.linspace(0.0, 2.0, 40)
    dt = t[1] - t[0]
    unwrapped = np.stack([2.66 + t, 0.5 + 0.3 * np.sin(t), 10.0 + t * t], -1)
    rates = np.stack([np.ones_like(t), 0.3 * np.cos(t), 2 * t], -1)
    accelerations = np.stack([0 * t, -0.3 * np.sin(t), np.full_like(t, 2.0)], -1)
    p = unwrapped.copy()
    p[:, 0] = np.angle(np.exp(1j * p[:, 0]))  # as a per-sample IK gives it
    p[16:, 1] += 0.2
    q = Jet(*(x[None] for x in (p, rates, accelerations)))
    status = np.zeros((1, 40), np.int8)
    status[0, 5], status[0, 30] = Status.NOT_CONVERGED, Status.OUT_OF_LIMITS
    limits = plan.Limits.create(3, q_min=[-4.6, -np.inf, -np.inf], q_max=[-1.0, np.inf, np.inf])
    moving = np.array([True])

    @jax.jit
    def check(q, status, turns):
        return plan.checked_samples(robot, q, status, moving, limits, dt, turns=turns)[:2]

    @jax.jit
    def unwrap(joined, k):  # a window prefixed with the previous sample and its turns
        u = plan.unwrapped(joined, revolute, k)[:, 1:]
        return u, plan.unwrapping_turns(joined, revolute, k)[:, 1:]

    whole_q, whole_status = check(q, status, None)
    revolute = np.array([True, True, False])
    size = 8
    parts, carried, low, high = [], (q.p[:, 0], np.zeros((1, 3))), None, None
    for start in range(0, 40, size):  # the first window prefixed with its own first sample
        raw = q.p[:, start : start + size]
        u, k = unwrap(np.concatenate([carried[0][:, None], raw], 1), carried[1])
        carried = (raw[:, -1], k[:, -1])
        lo, hi = plan.solved_range(u, status[:, start : start + size] == Status.OK)
        low = lo if low is None else np.minimum(low, lo)
        high = hi if high is None else np.maximum(high, hi)
        parts.append(np.asarray(u))
    turns = plan.range_turns(low, high, revolute, limits.q_min, limits.q_max)
    assert np.asarray(turns).tolist() == [[-1.0, 0.0, 0.0]]
    u = np.concatenate(parts, 1)
    got_q, got_status = [], []
    for start in range(0, 40, size):  # prefixed with the previous sample (the first: itself)
        rows = np.r_[max(start - 1, 0), start : start + size]
        window = Jet(u[:, rows], q.v[:, rows], q.a[:, rows])
        before = status[:, rows].copy()
        before[:, 0] = before[:, 0] if start else Status.INVALID_INPUT  # no step into sample 0
        checked, checked_status = check(window, before, turns)
        got_q.append(np.asarray(checked.p)[:, 1:])
        got_status.append(np.asarray(checked_status)[:, 1:])
    np.testing.assert_array_equal(np.concatenate(got_q, 1), whole_q.p)
    np.testing.assert_array_equal(np.concatenate(got_status, 1), whole_status)
    assert whole_status[0, 16] == Status.DISCONTINUOUS
