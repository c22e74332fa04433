"""Batched time-optimal retiming (``jaxkin.timing``).

References outside the code under test: the trapezoid and triangle speed profiles of a straight
line by hand, the host-side spline of ``jaxkin._splines``, finite differences of the sampled
trajectory, and toppra (slow tier) on the same spline and grid.
"""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxkin import _splines, timing
from jaxkin.status import Status

from .helpers import compilations

# Six candidates of three joints, eight waypoints, four grid intervals per spline segment
# (grid spacing 0.25 in s). Candidates 0 and 1 move joint 0 along a straight line of length 7
# (dq/ds = 1); the others follow smooth random curves.
K, N_JOINTS, SUB = 8, 3, 4
LENGTH = 7.0


def smooth_paths(rng: np.random.Generator, count: int, k: int, n: int) -> np.ndarray:
    """Waypoints on sums of three sines per joint, ``(count, k, n)``."""
    s = np.linspace(0.0, 1.0, k)
    modes = np.arange(1, 4)
    amp = rng.normal(size=(count, 3, n)) / modes[None, :, None]
    phase = rng.uniform(0.0, 2.0 * np.pi, size=(count, 3, n))
    angle = np.pi * modes[None, None, :, None] * s[None, :, None, None] + phase[:, None]
    return np.sum(amp[:, None] * np.sin(angle), axis=2)


def problem():
    rng = np.random.default_rng(7)
    way = smooth_paths(rng, 6, K, N_JOINTS)
    line = np.zeros((K, N_JOINTS))
    line[:, 0] = np.linspace(0.0, LENGTH, K)
    line[:, 1:] = [0.3, -0.2]
    way[0] = way[1] = line
    v_max = rng.uniform(0.5, 2.0, (6, N_JOINTS))
    a_max = rng.uniform(1.0, 4.0, (6, N_JOINTS))
    v_max[0] = [1.0, 0.0, 0.0]  # trapezoid; joints 1, 2 do not move, so 0 limits them not
    a_max[0] = [2.0, 1.0, 1.0]
    v_max[1] = [10.0, 1.0, 1.0]  # triangle: never reaches its top speed
    a_max[1] = [1.0, 1.0, 1.0]
    v_max[4, 2] = 0.0  # a joint that must move cannot: untimeable
    start = np.zeros(6)
    start[5] = 100.0  # far beyond what the limits allow at the start
    return way, v_max, a_max, start


@pytest.fixture(scope="module")
def solved():
    way, v_max, a_max, start = problem()
    path = timing.path_from_waypoints(way, subdivisions=SUB)
    result = timing.retime(path, v_max, a_max, start_speed=start, speed_bound="interval")
    return way, v_max, a_max, start, path, result


def test_straight_line_durations_by_hand(solved):
    # Trapezoid: accelerate over v^2 / (2 a) = 0.25, cruise, brake: T = L / v + v / a.
    # Triangle: accelerate to L / 2, brake: T = 2 sqrt(L / a). Switches fall on the grid, so the
    # grid's piecewise-constant path acceleration is the exact optimum.
    _, _, _, _, _, result = solved
    duration = np.asarray(result.duration)
    np.testing.assert_allclose(duration[0], LENGTH / 1.0 + 1.0 / 2.0, rtol=1e-12)
    np.testing.assert_allclose(duration[1], 2.0 * math.sqrt(LENGTH / 1.0), rtol=1e-12)
    # The trapezoid cruises at the speed limit: s_dot = v / (dq/ds) = 1.
    speed = np.asarray(result.speed[0])
    np.testing.assert_allclose(speed[1:-1].max(), 1.0, rtol=1e-12)


def test_statuses_and_placeholders(solved):
    _, _, _, _, _, result = solved
    status = np.asarray(result.status)
    assert status.dtype == np.int8
    np.testing.assert_array_equal(status, [0, 0, 0, 0, Status.UNTIMEABLE, Status.UNTIMEABLE])
    assert Status(9).name == "UNTIMEABLE"
    for leaf in (result.duration, result.t, result.speed, result.acceleration):
        values = np.asarray(leaf)[4:]
        assert np.all(values == 0.0)
    with pytest.raises(RuntimeError, match="UNTIMEABLE"):
        result.raise_if_failed()


def test_invalid_element_does_not_poison_the_batch_nor_recompile(solved):
    way, v_max, a_max, start, path, result = solved
    dq = np.asarray(path.dq).copy()
    dq[3, 5, 1] = np.nan
    broken = timing.JointPath(path.s, path.q, jnp.asarray(dq), path.ddq)
    with compilations() as count:
        again = timing.retime(broken, v_max, a_max, start_speed=start, speed_bound="interval")
        jax.block_until_ready(again)
    assert count.n == 0
    status = np.asarray(again.status)
    assert status[3] == Status.INVALID_INPUT and np.all(np.isfinite(np.asarray(again.t)))
    keep = [0, 1, 2, 4, 5]
    np.testing.assert_array_equal(
        np.asarray(again.duration)[keep], np.asarray(result.duration)[keep]
    )
    np.testing.assert_array_equal(status[keep], np.asarray(result.status)[keep])


def test_a_moving_joint_without_an_acceleration_limit_is_untimeable(solved):
    """A joint that moves with an acceleration limit of inf (and a speed limit, or none) has
    no time-optimal timing: its candidate is UNTIMEABLE (with neither limit it was timed in
    about 1e-38 and OK); a joint that does not move needs none (candidate 0's joints 1 and
    2), and the other candidates' durations are unchanged (no recompilation)."""
    _, v_max, a_max, start, path, result = solved
    v_max, a_max = v_max.copy(), a_max.copy()
    a_max[0, 1:] = np.inf  # candidate 0 moves joint 0 only
    a_max[2, 1] = np.inf  # with its speed limit
    v_max[3, 0], a_max[3, 0] = np.inf, np.inf  # with neither
    with compilations() as count:
        again = timing.retime(path, v_max, a_max, start_speed=start, speed_bound="interval")
        jax.block_until_ready(again)
    assert count.n == 0
    status = np.asarray(again.status)
    assert status[2] == status[3] == Status.UNTIMEABLE
    assert np.all(np.asarray(again.duration)[2:4] == 0.0)
    keep = [0, 1, 4, 5]
    np.testing.assert_array_equal(status[keep], np.asarray(result.status)[keep])
    np.testing.assert_array_equal(
        np.asarray(again.duration)[keep], np.asarray(result.duration)[keep]
    )


def test_spline_matches_the_host_spline(solved):
    # jaxkin._splines solves the same spline on the host (general knots, its own code).
    way, *_, path, _ = solved
    knots = np.broadcast_to(np.arange(K, dtype=float), way.shape[:-1])
    slope, curvature = _splines.derivatives(knots, way)
    np.testing.assert_allclose(path.q[:, ::SUB], way, rtol=0, atol=1e-13)
    np.testing.assert_allclose(path.dq[:, ::SUB], slope, rtol=0, atol=1e-12)
    np.testing.assert_allclose(path.ddq[:, ::SUB], curvature, rtol=0, atol=1e-11)
    rng = np.random.default_rng(3)
    for count, end in [(2, "not-a-knot"), (3, "not-a-knot"), (5, "natural")]:
        way = rng.normal(size=(2, count, 3))
        knots = np.broadcast_to(np.arange(count, dtype=float), (2, count))
        slope, curvature = _splines.derivatives(knots, way, end=end)
        path = timing.path_from_waypoints(way, subdivisions=1, end=end)
        np.testing.assert_allclose(path.q, way, rtol=0, atol=1e-13)
        np.testing.assert_allclose(path.dq, slope, rtol=0, atol=1e-12)
        np.testing.assert_allclose(path.ddq, curvature, rtol=0, atol=1e-11)


def test_sampled_rates_are_the_derivatives_and_respect_the_limits(solved):
    _, v_max, a_max, _, path, result = solved
    period = 1e-3
    traj = timing.sample(path, result, period)
    count = np.asarray(traj.count)
    assert traj.q.p.shape == (6, len(traj.t), N_JOINTS) and traj.valid.shape == (6, len(traj.t))
    np.testing.assert_array_equal(count, np.sum(traj.valid, axis=-1))
    np.testing.assert_array_equal(count[:4], np.floor(np.asarray(result.duration[:4]) / period) + 1)
    assert np.all(count[4:] == 0)
    p, v, a = (np.asarray(x) for x in (traj.q.p, traj.q.v, traj.q.a))
    # Central differences of the sampled positions (error O(period^2)), away from the samples
    # next to a grid point, where s_ddot jumps (there the error is up to half the jump).
    for c in range(4):
        n = count[c]
        interval = np.searchsorted(np.asarray(result.t[c]), np.asarray(traj.t[:n]), "right")
        smooth = interval[2:] == interval[:-2]
        assert smooth.mean() > 0.9
        fd_v = (p[c, 2:n] - p[c, : n - 2]) / (2.0 * period)
        np.testing.assert_allclose(v[c, 1 : n - 1][smooth], fd_v[smooth], rtol=0, atol=1e-5)
        fd_a = (v[c, 2:n] - v[c, : n - 2]) / (2.0 * period)
        np.testing.assert_allclose(a[c, 1 : n - 1][smooth], fd_a[smooth], rtol=0, atol=1e-5)
    # At rest at both ends, the end waypoint reached; padding holds the end at rest.
    way = np.asarray(path.q)
    np.testing.assert_allclose(p[:4, 0], way[:4, 0], atol=1e-12)
    np.testing.assert_allclose(v[:4, 0], 0.0, atol=1e-12)
    np.testing.assert_allclose(p[:4, -1], way[:4, -1], atol=1e-9)
    padding = ~np.asarray(traj.valid)
    assert np.all(v[padding] == 0.0) and np.all(a[padding] == 0.0)
    held = np.where(np.asarray(result.ok)[:, None], way[:, -1], way[:, 0])  # end, or start
    np.testing.assert_array_equal(p, np.where(padding[..., None], held[:, None], p))
    # Limits: speeds everywhere (speed_bound="interval"), to round-off; accelerations exactly
    # on the grid and between grid points (four per spline segment here) within 5 %.
    valid = np.asarray(traj.valid)
    pinned = (v_max == 0)[:, None, :] & valid[..., None]  # zero limits on joints at rest
    assert pinned.any() and np.all(v[pinned] == 0.0)
    assert (np.abs(v) / np.where(v_max > 0, v_max, np.inf)[:, None])[valid].max() <= 1 + 1e-9
    assert (np.abs(a) / a_max[:, None, :])[valid].max() <= 1.05


def test_batch_shapes_and_broadcast_limits(solved):
    way, v_max, a_max, start, path, result = solved
    grid = jax.tree.map(lambda x: x.reshape(2, 3, *x.shape[1:]), path)
    grid = timing.JointPath(path.s[0], grid.q, grid.dq, grid.ddq)  # one grid for all
    shaped = timing.retime(
        grid,
        v_max.reshape(2, 3, N_JOINTS),
        a_max.reshape(2, 3, -1),
        start_speed=start.reshape(2, 3),
        speed_bound="interval",
    )
    assert shaped.duration.shape == (2, 3) and shaped.t.shape == (2, 3, path.s.shape[-1])
    np.testing.assert_array_equal(np.asarray(shaped.duration).ravel(), result.duration)
    one = timing.retime(
        jax.tree.map(lambda x: x[2], path), v_max[2], a_max[2], speed_bound="interval"
    )
    assert one.duration.shape == () and one.status.shape == ()
    np.testing.assert_allclose(one.duration, result.duration[2], rtol=1e-14)
    # One limit row for the whole batch broadcasts over the candidates, with the program
    # compiled for per-candidate limits.
    with compilations() as count:
        shared = timing.retime(path, v_max[2], a_max[2], start_speed=0.0, speed_bound="interval")
    assert count.compiled("_retime") == 0
    np.testing.assert_array_equal(shared.duration[2], result.duration[2])


def test_float32(solved):
    way, v_max, a_max, start, _, result = solved
    path = timing.path_from_waypoints(way.astype(np.float32), subdivisions=SUB)
    single = timing.retime(
        path,
        v_max.astype(np.float32),
        a_max.astype(np.float32),
        start_speed=start,
        speed_bound="interval",
    )
    assert single.duration.dtype == jnp.float32 and path.dq.dtype == jnp.float32
    np.testing.assert_array_equal(single.status, result.status)
    np.testing.assert_allclose(single.duration, result.duration, rtol=2e-5)


def test_under_a_users_jit():
    # Traced waypoints and limits: shape checks only, then the same numbers as eagerly. The
    # straight line of length 2 over three waypoints (dq/ds = 1) with v = 1, a = 4 is a
    # trapezoid: T = L / v + v / a.
    way = np.array([[[0.0], [1.0], [2.0]]])

    @jax.jit
    def duration(way, v_max, a_max):
        path = timing.path_from_waypoints(way, subdivisions=8)
        return timing.retime(path, v_max, a_max).duration

    np.testing.assert_allclose(duration(way, jnp.ones(1), jnp.full(1, 4.0)), [2.25], rtol=1e-12)


def test_a_stop_between_neighbouring_grid_points_is_untimeable():
    # One grid interval from rest to rest: the speed is zero at both of its grid points, and
    # no time would cover the interval.
    line = timing.JointPath(
        jnp.array([0.0, 1.0]), jnp.array([[0.0], [1.0]]), jnp.ones((2, 1)), jnp.zeros((2, 1))
    )
    result = timing.retime(line, [1.0], [1.0])
    assert result.status == Status.UNTIMEABLE and result.duration == 0.0


def test_best(solved):
    *_, result = solved
    index, duration = timing.best(result, 3)
    order = np.argsort(np.asarray(result.duration)[:4])[:3]
    np.testing.assert_array_equal(index, order)
    np.testing.assert_array_equal(duration, np.asarray(result.duration)[order])
    assert len(timing.best(result, 10)[0]) == 4  # the two untimeable ones are left out
    with pytest.raises(ValueError, match="k must be"):
        timing.best(result, 0)


def test_bad_input_names_the_argument(solved):
    way, v_max, a_max, _, path, result = solved
    with pytest.raises(ValueError, match="waypoints"):
        timing.path_from_waypoints(np.zeros((5, 1, 3)))
    with pytest.raises(ValueError, match="waypoints must be finite"):
        timing.path_from_waypoints(np.full((4, 3), np.nan))
    with pytest.raises(ValueError, match="subdivisions"):
        timing.path_from_waypoints(way, subdivisions=0)
    with pytest.raises(ValueError, match="end"):
        timing.path_from_waypoints(way, end="clamped")
    with pytest.raises(ValueError, match="v_max must be non-negative"):
        timing.retime(path, -v_max, a_max)
    with pytest.raises(ValueError, match="a_max"):
        timing.retime(path, v_max, a_max[:, :2])
    with pytest.raises(ValueError, match="start_speed"):
        timing.retime(path, v_max, a_max, start_speed=-1.0)
    with pytest.raises(ValueError, match="speed_bound"):
        timing.retime(path, v_max, a_max, speed_bound="exact")
    with pytest.raises(ValueError, match="scheme"):
        timing.retime(path, v_max, a_max, scheme="exact")
    with pytest.raises(ValueError, match="path must be a JointPath"):
        timing.retime(way, v_max, a_max)
    with pytest.raises(ValueError, match="batch shapes do not broadcast"):
        timing.retime(path, v_max[:4], a_max)
    with pytest.raises(ValueError, match="period"):
        timing.sample(path, result, 0.0)
    backwards = timing.JointPath(path.s[..., ::-1], path.q, path.dq, path.ddq)
    with pytest.raises(ValueError, match="path.s must be strictly increasing"):
        timing.retime(backwards, v_max, a_max)
    short = timing.JointPath(path.s, path.q, path.dq[..., :2], path.ddq)
    with pytest.raises(ValueError, match="path.dq"):
        timing.retime(short, v_max, a_max)


# --------------------------------------------------------------------------------------------
# Against toppra (slow tier): the same spline (SciPy's not-a-knot CubicSpline through the same
# waypoints at s = 0..K-1), the same grid and the same discretisation scheme.


def toppra_durations(way, v_max, a_max, grid, scheme):
    pytest.importorskip("toppra")
    import toppra
    import toppra.algorithm
    import toppra.constraint

    toppra.setup_logging("ERROR")
    kind = toppra.constraint.DiscretizationType
    durations = []
    for w, v, a in zip(way, v_max, a_max, strict=True):
        spline = toppra.SplineInterpolator(np.arange(len(w), dtype=float), w)
        constraints = [
            toppra.constraint.JointVelocityConstraint(v),
            toppra.constraint.JointAccelerationConstraint(
                a,
                discretization_scheme=(
                    kind.Interpolation if scheme == "interpolation" else kind.Collocation
                ),
            ),
        ]
        algorithm = toppra.algorithm.TOPPRA(
            constraints, spline, gridpoints=grid, parametrizer="ParametrizeConstAccel"
        )
        trajectory = algorithm.compute_trajectory()
        durations.append(np.nan if trajectory is None else trajectory.duration)
    return np.array(durations)


@pytest.mark.slow
@pytest.mark.parametrize("scheme", ["interpolation", "collocation"])
def test_durations_match_toppra(scheme):
    rng = np.random.default_rng(11)
    count, k, n, sub = 24, 12, 6, 4
    way = smooth_paths(rng, count, k, n)
    v_max = rng.uniform(0.3, 2.0, (count, n))
    a_max = rng.uniform(0.5, 4.0, (count, n))
    path = timing.path_from_waypoints(way, subdivisions=sub)
    result = timing.retime(path, v_max, a_max, scheme=scheme)
    grid = np.asarray(path.s[0])
    reference = toppra_durations(way, v_max, a_max, grid, scheme)
    assert np.all(np.asarray(result.ok)) and np.all(np.isfinite(reference))
    # toppra shrinks each forward step by 1e-4 against round-off; the rest is the same LP.
    np.testing.assert_allclose(result.duration, reference, rtol=1e-2)
    assert np.max(np.abs(np.asarray(result.duration) / reference - 1.0)) < 1e-3


@pytest.mark.slow
@pytest.mark.parametrize("speed_bound", ["grid", "interval"])
def test_limits_at_every_sample_on_a_fine_grid(speed_bound):
    rng = np.random.default_rng(12)
    count, k, n = 16, 12, 6
    way = smooth_paths(rng, count, k, n)
    v_max = rng.uniform(0.3, 2.0, (count, n))
    a_max = rng.uniform(0.5, 4.0, (count, n))
    path = timing.path_from_waypoints(way, subdivisions=16)
    result = timing.retime(path, v_max, a_max, speed_bound=speed_bound)
    traj = timing.sample(path, result, 2e-3)
    valid = np.asarray(traj.valid)
    assert np.all(np.asarray(result.ok))
    # 16 grid intervals per spline segment: speeds within 2 % on the grid's bound (exact with
    # the interval bound), accelerations within 1 %.
    speed = 1.02 if speed_bound == "grid" else 1 + 1e-9
    assert (np.abs(np.asarray(traj.q.v)) / v_max[:, None])[valid].max() <= speed
    assert (np.abs(np.asarray(traj.q.a)) / a_max[:, None])[valid].max() <= 1.01


def turning_joint_path(tiny: float) -> timing.JointPath:
    """Joint 0 steady (``q = s``), joint 1 ``cos(pi s)`` turning at the middle grid point
    ``s = 1``, where its ``dq/ds`` is set to ``tiny`` (a round-off of either sign) and its
    acceleration is all centripetal, ``ddq x``: at that point's top speed the joint is at its
    acceleration limit with ``dq/ds`` of about zero."""
    s = np.linspace(0.0, 2.0, 9)
    q = np.stack([s, np.cos(np.pi * s)], -1)
    dq = np.stack([np.ones_like(s), -np.pi * np.sin(np.pi * s)], -1)
    ddq = np.stack([np.zeros_like(s), -(np.pi**2) * np.cos(np.pi * s)], -1)
    dq[4, 1] = tiny
    return timing.JointPath(*(np.broadcast_to(x, (16, *x.shape)) for x in (s, q, dq, ddq)))


TURNING_A_MAX = np.stack([np.full(16, 50.0), np.linspace(4.0, 6.0, 16)], -1)


def test_a_round_off_of_a_turning_joints_rate_changes_no_duration():
    """The sign of a round-off ``dq/ds`` (+-1e-17) of a joint at its turning point, at its
    acceleration limit there, changes no duration (1e-12): the forward pass's bound on the
    path acceleration from that joint, room / dq/ds, was 0 / 0 and its sign chose between
    no bound and none at all (up to 18 % longer)."""
    v_max = np.array([10.0, 10.0])
    plus, minus = (
        timing.retime(turning_joint_path(tiny), v_max, TURNING_A_MAX) for tiny in (1e-17, -1e-17)
    )
    assert np.all(np.asarray(plus.ok)) and np.all(np.asarray(minus.ok))
    np.testing.assert_allclose(plus.duration, minus.duration, rtol=1e-12)
    # At the turning point the joint's acceleration is ddq x = pi^2 x: at its limit a_1.
    np.testing.assert_allclose(
        np.asarray(plus.speed)[:, 4] ** 2 * np.pi**2, TURNING_A_MAX[:, 1], rtol=1e-12
    )


class GridPath:
    """A toppra geometric path given by its values and derivatives on a grid (toppra
    evaluates it at the grid points only)."""

    def __init__(self, s, q, dq, ddq):
        self.grid, self.values = np.asarray(s), (np.asarray(q), np.asarray(dq), np.asarray(ddq))

    def __call__(self, at, order=0):
        index = np.clip(np.searchsorted(self.grid, np.atleast_1d(at)), 0, len(self.grid) - 1)
        assert np.allclose(self.grid[index], at)
        out = self.values[order][index]
        return out if np.ndim(at) else out[0]

    eval = __call__

    def evald(self, at):
        return self(at, 1)

    def evaldd(self, at):
        return self(at, 2)

    @property
    def dof(self):
        return self.values[0].shape[1]

    @property
    def path_interval(self):
        return np.array([self.grid[0], self.grid[-1]])


def toppra_grid_durations(path: timing.JointPath, v_max, a_max) -> np.ndarray:
    """toppra's durations (interpolation scheme, at rest at both ends) of a batch of grid
    paths ``(N, M, n)``, with limits ``(N, n)``."""
    pytest.importorskip("toppra")
    import toppra
    import toppra.algorithm
    import toppra.constraint

    toppra.setup_logging("ERROR")
    kind = toppra.constraint.DiscretizationType.Interpolation
    durations = []
    for s, q, dq, ddq, v, a in zip(path.s, path.q, path.dq, path.ddq, v_max, a_max, strict=True):
        constraints = [
            toppra.constraint.JointVelocityConstraint(np.stack([-v, v], -1)),
            toppra.constraint.JointAccelerationConstraint(
                np.stack([-a, a], -1), discretization_scheme=kind
            ),
        ]
        algorithm = toppra.algorithm.TOPPRA(
            constraints, GridPath(s, q, dq, ddq), gridpoints=np.asarray(s)
        )
        _, speed, _, _ = algorithm.compute_parameterization(0.0, 0.0, return_data=True)
        durations.append(np.sum(2.0 * np.diff(s) / (speed[:-1] + speed[1:])))
    return np.array(durations)


@pytest.mark.slow
def test_turning_joint_durations_match_toppra():
    """The turning joint's durations against toppra on the same grid and derivatives, with
    either sign of the round-off (1e-6; measured 1.1e-8)."""
    v_max = np.broadcast_to([10.0, 10.0], TURNING_A_MAX.shape)
    for tiny in (1e-17, -1e-17):
        path = turning_joint_path(tiny)
        result = timing.retime(path, v_max, TURNING_A_MAX)
        reference = toppra_grid_durations(path, v_max, TURNING_A_MAX)
        np.testing.assert_allclose(result.duration, reference, rtol=1e-6)
