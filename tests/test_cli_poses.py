"""Pose files (``x, y, z, qw, qx, qy, qz``) and pose paths: one rule for quaternions.

A quaternion of any non-zero length is a rotation (``q`` and ``c q`` are one); a zero one is
invalid input. The CLI's pose rows and ``paths.path_from_poses`` share the rule
(``jaxkin._validate.unit_quaternions``). Host-side NumPy only: no compilation here.
"""

import numpy as np
import pytest

from jaxkin import _validate, paths
from jaxkin.cli import files as kio

# A smooth rotation path: rotation by 0.7 t about a fixed unit axis, plus a translation.
AXIS = np.array([1.0, 2.0, 2.0]) / 3.0


def pose_rows(t):
    half = 0.35 * t
    q = np.concatenate([np.cos(half)[:, None], np.sin(half)[:, None] * AXIS], -1)
    p = np.stack([0.3 + 0.1 * t, -0.2 * t, 0.5 + 0.05 * t * t], -1)
    return p, q


def write_poses(path, t, p, q):
    names = ("x", "y", "z", "qw", "qx", "qy", "qz")
    block = np.concatenate([p, q], -1)
    kio.write_table(path, {"t": t} | {n: block[:, j] for j, n in enumerate(names)})
    return kio.read_trajectory(path, names)


def pose_jet(traj):
    """The CLI's pipeline from rows to pose targets (commands._solve_file, host half)."""
    traj = kio.continuous_quaternions(traj)
    p, v, a, valid = kio.complete_rates(traj, "not-a-knot")
    return paths.pose_from_quaternions(p, v, a), valid


def test_zero_quaternion_row_is_invalid_and_leaves_the_other_rows_alone(tmp_path):
    """Row 4's quaternion is zero: that row is INVALID_INPUT (NaN) and every other row gets
    the pose and rates it gets from the file without row 4 (the spline skips invalid rows)."""
    t = np.linspace(0.0, 2.0, 11)
    p, q = pose_rows(t)
    q_bad = q.copy()
    q_bad[4] = 0.0
    jet, valid = pose_jet(write_poses(tmp_path / "bad.csv", t, p, q_bad))
    keep = np.arange(11) != 4
    ref, ref_valid = pose_jet(write_poses(tmp_path / "ref.csv", t[keep], p[keep], q[keep]))
    assert valid.tolist() == keep.tolist() and ref_valid.all()
    for got, want in ((jet.p, ref.p), (jet.v, ref.v), (jet.a, ref.a)):
        np.testing.assert_allclose(np.asarray(got)[keep], np.asarray(want), rtol=0, atol=1e-13)
        assert np.all(np.isnan(np.asarray(got)[4, :3, :3]))


@pytest.mark.parametrize("given_rates", [False, True])
def test_quaternion_length_changing_by_row_gives_the_unit_rows_rates(tmp_path, given_rates):
    """Rows whose quaternions are the unit ones times 1e-200 ... 1e250 (and a sign) give the
    poses and rates of the unit file, to 1e-13; with given rates, scaled with them."""
    t = np.linspace(0.0, 2.0, 9)
    p, q = pose_rows(t)
    scale = np.array([1.0, 3.0, 1e-200, -0.5, 1e250, 7.0, -1e-3, 2.0, 1e154])
    if given_rates:
        half = 0.35 * t
        dq = 0.35 * np.concatenate([-np.sin(half)[:, None], np.cos(half)[:, None] * AXIS], -1)
        ddq = -(0.35**2) * q
        names = ("x", "y", "z", "qw", "qx", "qy", "qz")
        velocity, acceleration = kio.rate_names(names)
        zeros = np.zeros_like(p)

        def traj_of(path, c):
            cols = {"t": t}
            for block, labels in (
                (np.concatenate([p, c * q], -1), names),
                (np.concatenate([zeros, c * dq], -1), velocity),
                (np.concatenate([zeros, c * ddq], -1), acceleration),
            ):
                cols |= {n: block[:, j] for j, n in enumerate(labels)}
            kio.write_table(path, cols)
            return kio.read_trajectory(path, names)

        scaled, unit = traj_of(tmp_path / "s.csv", scale[:, None]), traj_of(tmp_path / "u.csv", 1)
    else:
        scaled = write_poses(tmp_path / "s.csv", t, p, q * scale[:, None])
        unit = write_poses(tmp_path / "u.csv", t, p, q)
    jet, valid = pose_jet(scaled)
    ref, _ = pose_jet(unit)
    assert valid.all()
    for got, want in ((jet.p, ref.p), (jet.v, ref.v), (jet.a, ref.a)):
        np.testing.assert_allclose(np.asarray(got), np.asarray(want), rtol=0, atol=1e-13)
    rot = np.asarray(jet.p)[:, :3, :3]  # a rotation whatever the length
    np.testing.assert_allclose(
        rot @ np.swapaxes(rot, -1, -2), np.broadcast_to(np.eye(3), rot.shape), atol=1e-14
    )


def test_path_from_poses_takes_any_length_and_names_a_zero_quaternion():
    t = np.linspace(0.0, 2.0, 6)
    p, q = pose_rows(t)
    ref = paths.path_from_poses(p, q, 0.4)
    for scale in (1e-300, 1e155, 1e300):
        got = paths.path_from_poses(p, q * scale, 0.4)
        for a, b in ((got.p, ref.p), (got.v, ref.v), (got.a, ref.a)):
            np.testing.assert_allclose(np.asarray(a), np.asarray(b), rtol=0, atol=1e-13)
    q2 = np.stack([q, q])
    q2[1, 3] = 0.0
    with pytest.raises(ValueError, match=r"quaternions\[1, 3\] is zero"):
        paths.path_from_poses(np.stack([p, p]), q2, 0.4)


def test_unit_quaternions_scale_safely():
    """Lengths from the subnormal to the largest float, written out: unit = q / |q|."""
    q = np.array([[3.0, 0.0, 4.0, 0.0], [5e-324, 0.0, 0.0, 0.0], [1.5e308, 1.5e308, 0.0, 0.0],
                  [0.0, 0.0, 0.0, 0.0], [np.nan, 1.0, 0.0, 0.0]])  # fmt: skip
    unit, length, ok = _validate.unit_quaternions(q)
    assert ok.tolist() == [True, True, True, False, False]
    np.testing.assert_allclose(
        unit[:3], [[0.6, 0, 0.8, 0], [1, 0, 0, 0], [2**-0.5, 2**-0.5, 0, 0]], rtol=1e-15
    )
    np.testing.assert_allclose(length[:2], [5.0, 5e-324], rtol=1e-15)
    assert np.isinf(length[2]) and np.all(np.isnan(unit[3:]))


def test_quaternion_signs_carry_across_chunks():
    """Signs found chunk by chunk (the FK output of a streamed file) equal the signs found on
    the whole file at once, for interleaved candidates and invalid rows."""
    rng = np.random.default_rng(5)
    n = 37
    candidate = rng.integers(0, 3, n)
    t = np.arange(n, dtype=float)  # file order is time order
    q = rng.normal(size=(n, 4))
    q /= np.linalg.norm(q, axis=-1, keepdims=True)
    valid = rng.random(n) > 0.2
    whole = kio.quaternion_signs(t, candidate, valid, q)
    carry = kio.QuaternionSigns()
    parts = [carry(candidate[i : i + 8], valid[i : i + 8], q[i : i + 8]) for i in range(0, n, 8)]
    np.testing.assert_array_equal(np.concatenate(parts)[valid], whole[valid])
