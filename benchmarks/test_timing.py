"""Time-optimal retiming throughput: 1,000 six-joint paths of 100 waypoints in one call, beside
toppra (TOPP-RA, one path per call) on the same paths, spline, grid and limits, in the same
process. The ratio of throughputs is the number to read (goal: at least 20x).
"""

import time

import jax
import numpy as np
import pytest

from jaxkin import timing

N_PATHS, N_WAYPOINTS, N_JOINTS = 1_000, 100, 6
TOPPRA_PATHS = 40  # toppra's per-path time is steady: a sample of paths gives its throughput


def smooth_paths(n: int, dtype: str) -> np.ndarray:
    """Waypoints on sums of three sines per joint, ``(n, N_WAYPOINTS, N_JOINTS)``."""
    rng = np.random.default_rng(0)
    s = np.linspace(0.0, 1.0, N_WAYPOINTS)
    modes = np.arange(1, 4)
    amp = rng.normal(size=(n, 3, N_JOINTS)) / modes[None, :, None]
    phase = rng.uniform(0.0, 2.0 * np.pi, size=(n, 3, N_JOINTS))
    angle = np.pi * modes[None, None, :, None] * s[None, :, None, None] + phase[:, None]
    return np.sum(amp[:, None] * np.sin(angle), axis=2).astype(dtype)


def toppra_durations(waypoints: np.ndarray, v_max: np.ndarray, a_max: np.ndarray):
    """toppra's durations and seconds per path (spline, constraints, both passes)."""
    import toppra
    import toppra.algorithm
    import toppra.constraint

    toppra.setup_logging("ERROR")
    grid = np.arange(N_WAYPOINTS, dtype=float)
    durations = []
    start = time.perf_counter()
    for way in waypoints:
        spline = toppra.SplineInterpolator(grid, way)
        constraints = [
            toppra.constraint.JointVelocityConstraint(v_max),
            toppra.constraint.JointAccelerationConstraint(a_max),  # interpolation scheme
        ]
        algorithm = toppra.algorithm.TOPPRA(
            constraints, spline, gridpoints=grid, parametrizer="ParametrizeConstAccel"
        )
        durations.append(algorithm.compute_trajectory().duration)
    return np.array(durations), (time.perf_counter() - start) / len(waypoints)


@pytest.mark.parametrize("dtype", ["float64", "float32"])
def test_retime_against_toppra(measure, benchmark, dtype):
    pytest.importorskip("toppra")
    waypoints = smooth_paths(N_PATHS, dtype)
    v_max = np.linspace(0.8, 1.6, N_JOINTS)
    a_max = np.linspace(1.5, 3.0, N_JOINTS)

    def retime():
        path = timing.path_from_waypoints(waypoints)  # grid: the waypoints
        return timing.retime(path, v_max.astype(dtype), a_max.astype(dtype))

    result = measure(
        retime, N_PATHS, kernel="timing.retime (TOPP-RA)", dtype=dtype, waypoints=N_WAYPOINTS
    )
    assert np.all(np.asarray(result.ok))
    reference, seconds = toppra_durations(waypoints[:TOPPRA_PATHS].astype(float), v_max, a_max)
    ours = np.asarray(jax.device_get(result.duration[:TOPPRA_PATHS]), dtype=float)
    error = float(np.max(np.abs(ours / reference - 1.0)))
    assert error < 1e-2
    ratio = N_PATHS / benchmark.stats.stats.min * seconds  # our throughput / toppra's
    benchmark.extra_info.update(
        toppra_paths_per_second=1.0 / seconds,
        speedup_vs_toppra=ratio,
        max_relative_duration_difference_vs_toppra=error,
    )
