"""Chunked voxel sweeps: exact counts for simple shapes, chunk invariance, the Delta tori."""

from __future__ import annotations

import math

import jax.numpy as jnp
import numpy as np
import pytest

from jaxkin import Status, delta, workspace


def ball_status(points):
    """A 'robot' reaching the closed ball of radius 2.5 about the origin."""
    inside = jnp.sum(points * points, axis=-1) <= 2.5**2
    return jnp.where(inside, Status.OK, Status.UNREACHABLE)


def test_ball_counts_match_numpy_and_chunking():
    bounds = ((-3.0, 3.0), (-3.0, 3.0), (-3.0, 3.0))
    grid = np.arange(-3.0, 3.0 + 1e-9, 0.5)
    x, y, z = np.meshgrid(grid, grid, grid, indexing="ij")
    expected = x**2 + y**2 + z**2 <= 2.5**2
    for chunk in (7, 100, 10_000):  # last chunk padded; results must not depend on chunking
        result = workspace.sweep(ball_status, bounds, 0.5, chunk_size=chunk, progress=False)
        np.testing.assert_array_equal(result.mask, expected)
    assert result.n_evaluated == 13**3
    assert result.n_reachable == int(expected.sum())
    assert result.volume == pytest.approx(expected.sum() * 0.125)
    np.testing.assert_allclose(result.slice_areas, expected.sum(axis=(0, 1)) * 0.25)
    # the voxel volume converges to the ball's volume as the grid is refined
    fine = workspace.sweep(ball_status, bounds, 0.1, progress=False)
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
    result = delta.workspace(robot, resolution=5.0, progress=False)
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
