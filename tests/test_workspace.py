"""Chunked voxel sweeps: exact counts for simple shapes, chunk invariance, the Delta tori,
the SCARA's annulus and a planar arm's 2-D grid."""

from __future__ import annotations

import math
from typing import Any, ClassVar

import jax.numpy as jnp
import numpy as np
import pytest

from jaxkin import FKResult, IKResult, Jet, Status, delta, scara, serial, workspace
from jaxkin._geometry import LENGTH, geometry, number
from jaxkin.robot import POINT, Robot
from tests.helpers import compilations


@geometry
class Ball(Robot):
    """A 'robot' of this test reaching the closed ball of ``radius`` about the origin."""

    radius: Any = number(LENGTH, default=2.5)

    target: ClassVar = POINT
    branches: ClassVar = ("only",)

    @property
    def joint_names(self):
        return ("x", "y", "z")

    @property
    def joint_types(self):
        return "PPP"

    def length_scale(self):
        return self.radius

    def ik_kernel(self, target, branch, options, rates):
        p = target.p
        inside = jnp.sum(p * p, axis=-1) <= self.radius**2
        status = jnp.where(inside, Status.OK, Status.UNREACHABLE).astype(jnp.int8)
        return IKResult(Jet.constant(p), status, jnp.zeros(p.shape[:-1]))

    def fk_kernel(self, q, options, rates):
        return FKResult(q, jnp.zeros(q.p.shape[:-1], jnp.int8))


ball_status = Ball()


def test_ball_counts_match_numpy_and_chunking():
    bounds = ((-3.0, 3.0), (-3.0, 3.0), (-3.0, 3.0))
    grid = np.arange(-3.0, 3.0 + 1e-9, 0.5)
    x, y, z = np.meshgrid(grid, grid, grid, indexing="ij")
    expected = x**2 + y**2 + z**2 <= 2.5**2
    for chunk in (7, 100, 10_000):  # last chunk padded; results must not depend on chunking
        result = workspace.sweep(ball_status, bounds, 0.5, chunk_size=chunk)
        np.testing.assert_array_equal(result.mask, expected)
    assert result.n_evaluated == 13**3
    assert result.n_reachable == int(expected.sum())
    assert result.volume == pytest.approx(expected.sum() * 0.125)
    np.testing.assert_allclose(result.slice_areas, expected.sum(axis=(0, 1)) * 0.25)
    # the voxel volume converges to the ball's volume as the grid is refined
    fine = workspace.sweep(ball_status, bounds, 0.1)
    assert fine.volume == pytest.approx(4.0 / 3.0 * math.pi * 2.5**3, rel=0.02)


def test_paper_grid_axes_count():
    xs, ys, zs = workspace.grid_axes(((-50, 50), (-50, 50), (-45, 45)), 1.0)
    assert (len(xs), len(ys), len(zs)) == (101, 101, 91)
    assert len(xs) * len(ys) * len(zs) == 928_291


def test_bad_arguments():
    bounds = ((0, 1), (0, 1), (0, 1))
    with pytest.raises(ValueError, match="resolution"):
        workspace.sweep(ball_status, bounds, 0.0)
    with pytest.raises(ValueError, match="chunk_size"):
        workspace.sweep(ball_status, bounds, 0.5, chunk_size=0)
    with pytest.raises(ValueError, match="bounds"):
        workspace.sweep(ball_status, ((1, 0), (0, 1), (0, 1)), 0.5)
    with pytest.raises(ValueError, match="bounds"):
        workspace.sweep(ball_status, ((0, 1), (0, 1)), 0.5)
    with pytest.raises(ValueError, match="no default workspace box"):
        workspace.sweep(ball_status)
    with pytest.raises(ValueError, match="points"):
        workspace.sweep(serial.Puma560())
    with pytest.raises(ValueError, match="branch"):
        workspace.sweep(ball_status, bounds, 0.5, branch="other")
    with pytest.raises(ValueError, match="progress must be None or a callable"):
        workspace.sweep(ball_status, bounds, 0.5, progress=True)


def test_progress_callback_hears_every_chunk():
    """``progress(done, total)``: ``(0, total)`` first, then the voxels swept after each chunk
    (13**3 = 2197 voxels in chunks of 1000)."""
    calls = []
    bounds = ((-3.0, 3.0), (-3.0, 3.0), (-3.0, 3.0))
    report = lambda done, total: calls.append((done, total))  # noqa: E731
    workspace.sweep(ball_status, bounds, 0.5, chunk_size=1000, progress=report)
    assert calls == [(0, 2197), (1000, 2197), (2000, 2197), (2197, 2197)]


def in_three_tori(points: np.ndarray) -> np.ndarray:
    """Independent membership test: for each chain, the rod sphere about the platform joint
    must meet the elbow circle (centre A_i, radius l_arm, in the vertical plane of u_i):
    min distance <= l_rod <= max distance, with distances computed from the torus geometry."""
    rb, rp, la, lr = 7.0, 2.5, 15.5, 30.0
    ok = np.ones(points.shape[0], bool)
    for deg in (-90.0, 30.0, 150.0):
        u = np.array([math.cos(math.radians(deg)), math.sin(math.radians(deg)), 0.0])
        q = points + rp * u - rb * u  # platform joint relative to the actuator axis
        radial = q @ u
        out_of_plane = q @ np.array([-u[1], u[0], 0.0])
        in_plane = np.hypot(radial, q[:, 2])  # distance from A_i within the arm's plane
        d_min = np.hypot(in_plane - la, out_of_plane)
        d_max = np.hypot(in_plane + la, out_of_plane)
        ok &= (d_min <= lr) & (lr <= d_max)
    return ok


def test_delta_workspace_is_the_intersection_of_three_tori():
    robot = delta.Delta.paper()
    result = workspace.sweep(robot, resolution=5.0)
    xs, ys, zs = result.axes
    x, y, z = np.meshgrid(xs, ys, zs, indexing="ij")
    points = np.stack([x.ravel(), y.ravel(), z.ravel()], -1)
    expected = in_three_tori(points).reshape(result.mask.shape)
    # identical up to voxels within rounding of a torus surface (none on this grid)
    np.testing.assert_array_equal(result.mask, expected)
    # symmetric about z = 0, and shrinking with depth below the widest slice (Fig. 8)
    np.testing.assert_array_equal(result.mask, result.mask[:, :, ::-1])
    areas = result.slice_areas
    widest = int(np.argmax(areas))
    below = areas[: widest + 1]
    assert np.all(np.diff(below[below > 0]) >= 0)


def test_scara_workspace_is_its_annulus_and_a_planar_arm_gets_a_2d_grid():
    robot = scara.Scara.paper()
    result = workspace.sweep(robot, resolution=10.0)
    xs, ys, zs = result.axes
    r = np.hypot(*np.meshgrid(xs, ys, indexing="ij"))
    tol = 1e-6 * 130.0
    clear = (np.abs(r - 130.0) > tol) & (np.abs(r - 30.0) > tol)
    expected = (r < 130.0) & (r > 30.0)
    for k in range(len(zs)):  # every height of the column is reached alike
        np.testing.assert_array_equal(result.mask[:, :, k][clear], expected[clear])
    arm = serial.Planar2R(1.0, 0.6)
    flat = workspace.sweep(arm, resolution=0.1)
    assert flat.mask.ndim == 2 and len(flat.axes) == 2
    gx, gy = np.meshgrid(*flat.axes, indexing="ij")
    rr = np.hypot(gx, gy)
    inside = (rr < 1.6 - 1e-6) & (rr > 0.4 + 1e-6)
    outside = (rr > 1.6 + 1e-6) | (rr < 0.4 - 1e-6)
    assert np.all(flat.mask[inside]) and not np.any(flat.mask[outside])
    assert flat.volume == pytest.approx(flat.n_reachable * 0.01)


def test_a_repeated_sweep_compiles_nothing_new():
    bounds = ((-3.0, 3.0),) * 3
    workspace.sweep(Ball(2.0), bounds, 0.5)
    with compilations() as count:
        again = workspace.sweep(Ball(2.2), bounds, 0.5)  # a new robot object
    assert count.n == 0
    assert again.n_reachable > 0
