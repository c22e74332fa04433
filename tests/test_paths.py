"""Paths from samples and poses: splines against scipy, rotations against scipy's ``Rotation``,
the pose <-> quaternion rows round trip, and bad arguments named."""

import numpy as np
import pytest

from jaxkin import paths


def test_path_from_samples_reproduces_a_cubic_motion_exactly():
    t = np.arange(12) * 0.1
    coeffs = np.array([[1.0, -2.0, 0.5], [0.3, 0.0, 2.0], [-1.0, 0.7, 0.0], [0.2, 0.1, -0.4]])
    p = sum(coeffs[k] * t[:, None] ** k for k in range(4))
    v = sum(k * coeffs[k] * t[:, None] ** (k - 1) for k in range(1, 4))
    a = sum(k * (k - 1) * coeffs[k] * t[:, None] ** (k - 2) for k in range(2, 4))
    jet = paths.path_from_samples(p[None], 0.1)
    np.testing.assert_allclose(jet.v[0], v, rtol=1e-10, atol=1e-10)
    np.testing.assert_allclose(jet.a[0], a, rtol=1e-9, atol=1e-9)
    with pytest.raises(ValueError, match="dt"):
        paths.path_from_samples(p[None], 0.0)


def test_path_from_poses_against_scipy_splines_and_rotations():
    """Positions: scipy's not-a-knot ``CubicSpline``. Orientations: scipy's spline of the
    quaternion components (after the same sign choice, made here by a loop), turned into
    rotations by scipy's ``Rotation``; the rates against central differences of that curve.
    Quaternions given with flipped signs or unnormalised describe the same path."""
    from scipy.interpolate import CubicSpline
    from scipy.spatial.transform import Rotation

    rng = np.random.default_rng(5)
    n, t, dt = 3, 15, 0.1
    rotvec = np.cumsum(rng.normal(scale=0.2, size=(n, t, 3)), axis=1)
    xyzw = Rotation.from_rotvec(rotvec.reshape(-1, 3)).as_quat().reshape(n, t, 4)
    quat = xyzw[..., [3, 0, 1, 2]]
    positions = rng.normal(size=(n, t, 3))
    given = quat * rng.choice([-2.0, 0.5], size=(n, t, 1))  # signs and lengths vary
    jet = paths.path_from_poses(positions, given, dt)
    assert jet.shape == (n, t, 4, 4)
    np.testing.assert_array_equal(jet.p[..., 3, :], np.broadcast_to([0, 0, 0, 1.0], (n, t, 4)))
    np.testing.assert_array_equal(jet.v[..., 3, :], 0.0)
    times = np.arange(t) * dt
    h = 1e-6
    for c in range(n):
        unit = quat[c].copy()
        for k in range(1, t):
            if unit[k] @ unit[k - 1] < 0:
                unit[k] = -unit[k]
        spline = CubicSpline(times, unit, axis=0)

        def rotation(x, spline=spline):
            s = spline(x)
            return Rotation.from_quat(s[..., [1, 2, 3, 0]]).as_matrix()

        np.testing.assert_allclose(jet.p[c, :, :3, :3], rotation(times), atol=1e-15)
        central = (rotation(times + h) - rotation(times - h)) / (2 * h)

        # Second differences straddle a knot, where the spline's third derivative jumps: the
        # error is O(h), removed by one Richardson step.
        def second_difference(h2, rotation=rotation):
            return (rotation(times + h2) - 2 * rotation(times) + rotation(times - h2)) / h2**2

        second = 2 * second_difference(1e-4) - second_difference(2e-4)
        velocity, acceleration = jet.v[c, :, :3, :3], jet.a[c, :, :3, :3]
        np.testing.assert_allclose(velocity, central, atol=1e-8 * np.abs(velocity).max())
        np.testing.assert_allclose(acceleration, second, atol=1e-5 * np.abs(acceleration).max())
        position = CubicSpline(times, positions[c], axis=0)
        np.testing.assert_allclose(jet.p[c, :, :3, 3], positions[c], atol=0)
        np.testing.assert_allclose(jet.v[c, :, :3, 3], position(times, 1), atol=1e-12)
        np.testing.assert_allclose(jet.a[c, :, :3, 3], position(times, 2), atol=1e-10)
    # R_dot R^T is skew: the rates are those of a rotation
    omega = jet.v[..., :3, :3] @ np.swapaxes(jet.p[..., :3, :3], -1, -2)
    np.testing.assert_allclose(omega, -np.swapaxes(omega, -1, -2), atol=1e-12)


def test_path_from_poses_marks_bad_candidates_and_names_bad_arguments():
    positions = np.zeros((2, 5, 3))
    quat = np.tile([1.0, 0.0, 0.0, 0.0], (2, 5, 1))
    positions[1, 2, 0] = np.nan
    jet = paths.path_from_poses(positions, quat, 0.1)
    assert np.all(np.isfinite(jet.v[0])) and np.all(np.isnan(jet.v[1, :, :3, 3]))
    with pytest.raises(ValueError, match="quaternions: expected shape"):
        paths.path_from_poses(positions, quat[..., :3], 0.1)
    with pytest.raises(ValueError, match="positions: expected shape"):
        paths.path_from_poses(positions[:, :1], quat[:, :1], 0.1)
    with pytest.raises(ValueError, match="same leading axes"):
        paths.path_from_poses(positions, quat[:1], 0.1)
    with pytest.raises(ValueError, match="non-zero"):
        paths.path_from_poses(positions, 0.0 * quat, 0.1)
    with pytest.raises(ValueError, match="dt"):
        paths.path_from_poses(positions, quat, -1.0)


def test_quaternion_rows_round_trip_a_pose_path():
    """Pose rows (x, y, z, qw, qx, qy, qz) with rates read back from a pose path give the same
    path: the rates of ``q`` map to those of ``R`` (both exact along the curve)."""
    from scipy.spatial.transform import Rotation

    rng = np.random.default_rng(8)
    rotvec = np.cumsum(rng.normal(scale=0.3, size=(2, 9, 3)), axis=1)
    xyzw = Rotation.from_rotvec(rotvec.reshape(-1, 3)).as_quat().reshape(2, 9, 4)
    jet = paths.path_from_poses(rng.normal(size=(2, 9, 3)), xyzw[..., [3, 0, 1, 2]], 0.1)
    p, v, a = paths.quaternions_from_pose(jet)
    assert p.shape == v.shape == a.shape == (2, 9, 7)
    np.testing.assert_allclose(np.linalg.norm(p[..., 3:], axis=-1), 1.0, rtol=1e-15)
    assert np.all(p[..., 3] >= 0.0)
    back = paths.pose_from_quaternions(p, v, a)
    for got, want in ((back.p, jet.p), (back.v, jet.v), (back.a, jet.a)):
        np.testing.assert_allclose(got, want, rtol=0, atol=1e-12 * np.abs(want).max())


def test_a_path_carries_its_sampling_period_and_space():
    """``path_from_samples`` / ``path_from_poses`` return ``Path``s with their ``dt``;
    indexing, ``map``, ``astype`` and ``jax.tree.map`` keep it; a bad dt or space is named."""
    import jax

    path = paths.path_from_samples(np.zeros((3, 5, 2)), 0.25)
    assert isinstance(path, paths.Path) and path.dt == 0.25 and path.space == "task"
    for part in (path[:2], path.map(lambda x: 2 * x), jax.tree.map(lambda x: x[1:], path)):
        assert isinstance(part, paths.Path) and part.dt == 0.25 and part.space == "task"
    assert path[:2].shape == (2, 5, 2) and type(path.jet) is paths.Jet
    joint = paths.path_from_samples(np.zeros((3, 5, 2)), 0.5, space="joint")
    assert joint.space == "joint" and joint.dt == 0.5
    poses = paths.path_from_poses(np.zeros((1, 4, 3)), np.tile([1.0, 0, 0, 0], (1, 4, 1)), 0.1)
    assert isinstance(poses, paths.Path) and poses.dt == 0.1
    with pytest.raises(ValueError, match="dt"):
        paths.Path(path.p, path.v, path.a, dt=0.0)
    with pytest.raises(ValueError, match="space"):
        paths.path_from_samples(np.zeros((3, 5, 2)), 0.1, space="tool")


def test_path_from_joint_waypoints_against_scipy():
    """The not-a-knot and natural splines through waypoints at ``t_k = k steps dt``, sampled
    every ``dt``: values and rates equal SciPy's ``CubicSpline`` (1e-10 of their scale); a
    candidate with a NaN waypoint is NaN, the others unaffected; bad arguments named."""
    from scipy.interpolate import CubicSpline

    rng = np.random.default_rng(4)
    way = rng.normal(size=(3, 5, 2))
    way[2, 1, 0] = np.nan
    dt, steps = 0.02, 7
    times = np.arange(4 * steps + 1) * dt
    for end in ("not-a-knot", "natural"):
        path = paths.path_from_joint_waypoints(way, dt, steps, end=end)
        assert path.shape == (3, 4 * steps + 1, 2) and path.space == "joint" and path.dt == dt
        for c in range(2):
            spline = CubicSpline(np.arange(5) * steps * dt, way[c], axis=0, bc_type=end)
            for order, x in enumerate((path.p, path.v, path.a)):
                want = spline(times, order)
                scale = np.abs(want).max()
                np.testing.assert_allclose(x[c], want, rtol=0, atol=1e-10 * scale)
        assert np.all(np.isnan(np.asarray(path.v[2])))
    with pytest.raises(ValueError, match="steps"):
        paths.path_from_joint_waypoints(way, dt, 0)
    with pytest.raises(ValueError, match="waypoints"):
        paths.path_from_joint_waypoints(way[:, :1], dt, 3)
