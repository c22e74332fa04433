"""Delta robot: IK, Newton FK, closed-form FK, rates, singularities, against independent geometry.

Independent sources used here: plain NumPy geometry written in this file (chain directions from
an explicit rotation matrix, elbow positions, rod lengths), hand-computed poses, the closed-form
three-sphere intersection, finite differences, and the NumPy references in ``tests/references``.
"""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxkin import Jet, Status, _batching, delta
from tests.helpers import BATCH_SHAPES, compilations, fd_rates, tree_allfinite
from tests.references import delta as reference_delta

ROBOT = delta.Delta.paper()
N = 256  # one batch size for most tests: each new shape costs a compilation
RB, RP, LA, LR = 7.0, 2.5, 15.5, 30.0


# ------------------------------------------------------------- independent NumPy geometry


def rot_z(deg: float) -> np.ndarray:
    c, s = math.cos(math.radians(deg)), math.sin(math.radians(deg))
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


# chain 1 on the -y side; chains 2 and 3 rotated by +120 and +240 degrees about +z
U = np.stack([rot_z(120.0 * i) @ np.array([0.0, -1.0, 0.0]) for i in range(3)])


def elbows_np(theta: np.ndarray) -> np.ndarray:
    """(..., 3 chains, 3): A_i + l_arm (cos th u_i - sin th e_z), theta positive downward."""
    c, s = np.cos(theta)[..., None], np.sin(theta)[..., None]
    return RB * U + LA * (c * U - s * np.array([0.0, 0.0, 1.0]))


def rod_lengths_np(p: np.ndarray, theta: np.ndarray) -> np.ndarray:
    joints = p[..., None, :] + RP * U
    return np.linalg.norm(joints - elbows_np(theta), axis=-1)


def random_workspace_points(n: int, seed: int = 0) -> np.ndarray:
    """Points in a cylinder inside the paper robot's workspace (radius 15, z in [-40, -20])."""
    rng = np.random.default_rng(seed)
    r = 15.0 * np.sqrt(rng.uniform(size=n))
    a = rng.uniform(0, 2 * np.pi, n)
    return np.stack([r * np.cos(a), r * np.sin(a), rng.uniform(-40.0, -20.0, n)], -1)


# ------------------------------------------------------------------------ geometry / errors


def test_geometry_validation_and_paper():
    robot = delta.Delta.paper()
    assert (robot.r_base, robot.r_platform, robot.l_arm, robot.l_rod) == (7.0, 2.5, 15.5, 30.0)
    for bad in ((0.0, 2.5, 15.5, 30.0), (7.0, -1.0, 15.5, 30.0), (7.0, 2.5, np.nan, 30.0)):
        with pytest.raises(ValueError):
            delta.Delta(*bad)
    with pytest.raises(ValueError, match="theta_min must be < theta_max"):
        robot.with_limits(1.0, -1.0)
    with pytest.raises(ValueError, match="scalar"):
        delta.Delta(np.ones(2), 2.5, 15.5, 30.0)


def test_bad_inputs_raise():
    with pytest.raises(ValueError, match="p"):
        delta.ik(ROBOT, np.zeros((4, 2)))
    with pytest.raises(ValueError, match="branch"):
        delta.ik(ROBOT, np.zeros(3), branch="up")
    with pytest.raises(ValueError, match="method"):
        delta.ik(ROBOT, np.zeros(3), method="numeric")
    with pytest.raises(ValueError, match="robot"):
        delta.ik((7, 2.5, 15.5, 30), np.zeros(3))
    with pytest.raises(ValueError, match="theta"):
        delta.fk(ROBOT, np.zeros(2))
    with pytest.raises(ValueError, match="tol"):
        delta.fk(ROBOT, np.zeros(3), tol=-1.0)
    with pytest.raises(ValueError, match="max_iter"):
        delta.fk(ROBOT, np.zeros(3), max_iter=0)
    with pytest.raises(ValueError, match="guess"):
        delta.fk(ROBOT, np.zeros(3), guess=np.zeros(2))
    with pytest.raises(ValueError, match="broadcast"):
        delta.fk(ROBOT, np.zeros((4, 3)), guess=np.zeros((5, 3)))
    with pytest.raises(ValueError, match="theta"):
        delta.fk_closed_form(ROBOT, np.zeros((3, 4)))


# -------------------------------------------------------------------------- IK correctness


def test_hand_computed_home_pose():
    # theta = 0: arms horizontal, elbows at radius 22.5; the platform joints at radius 2.5 are
    # 20 cm inward, so the platform hangs sqrt(30^2 - 20^2) = sqrt(500) below the base.
    p_home = np.array([0.0, 0.0, -math.sqrt(500.0)])
    result = delta.ik(ROBOT, p_home)
    np.testing.assert_allclose(result.q.p, 0.0, atol=1e-12)
    assert int(result.status) == Status.OK
    np.testing.assert_allclose(delta.fk_closed_form(ROBOT, np.zeros(3)).x, p_home, atol=1e-12)
    np.testing.assert_allclose(delta.fk(ROBOT, np.zeros(3)).x.p, p_home, atol=1e-12)


@pytest.mark.parametrize("z", [-21.0, -30.0, -42.0])
def test_platform_below_centre_gives_equal_angles(z):
    theta = np.asarray(delta.ik(ROBOT, np.array([0.0, 0.0, z])).q.p)
    np.testing.assert_allclose(theta, theta[0], atol=1e-13)
    # by hand in the chain plane: (4.5 + 15.5 cos t)^2 + (z + 15.5 sin t)^2 = 30^2 (rod)
    t = theta[0]
    assert abs((4.5 + 15.5 * math.cos(t)) ** 2 + (z + 15.5 * math.sin(t)) ** 2 - 900.0) < 1e-10
    # deeper targets need larger (downward) angles
    deeper = np.asarray(delta.ik(ROBOT, np.array([0.0, 0.0, z - 1.0])).q.p)
    assert np.all(deeper > theta)


def test_convention_chain_one_on_minus_y():
    # Pushing the platform toward -y (toward chain 1's actuator) lifts arm 1 (theta_1 decreases)
    # and lowers arms 2 and 3, whose actuators are on the +y side.
    centre = np.asarray(delta.ik(ROBOT, np.array([0.0, 0.0, -30.0])).q.p)
    moved = np.asarray(delta.ik(ROBOT, np.array([0.0, -5.0, -30.0])).q.p)
    assert moved[0] < centre[0]
    assert moved[1] > centre[1] and moved[2] > centre[2]
    np.testing.assert_allclose(moved[1], moved[2], atol=1e-13)  # mirror symmetry about x = 0
    # +x is on chain 2's side (at -90 + 120 = 30 degrees): chain 2 lifts, chain 3 lowers
    moved_x = np.asarray(delta.ik(ROBOT, np.array([5.0, 0.0, -30.0])).q.p)
    assert moved_x[1] < centre[1] and moved_x[2] > centre[2]


@pytest.mark.parametrize("branch", ["out", "in"])
def test_ik_satisfies_rod_lengths_independently(branch):
    p = random_workspace_points(N, seed=1)
    result = delta.ik(ROBOT, p, branch=branch)
    assert np.all(np.asarray(result.status) == Status.OK)
    np.testing.assert_allclose(rod_lengths_np(p, np.asarray(result.q.p)), LR, rtol=1e-12)


def test_elbow_out_is_farther_from_axis():
    p = random_workspace_points(N, seed=2)
    out = elbows_np(np.asarray(delta.ik(ROBOT, p, branch="out").q.p))
    inn = elbows_np(np.asarray(delta.ik(ROBOT, p, branch="in").q.p))
    radial_out = np.sum(out * U, -1)
    radial_in = np.sum(inn * U, -1)
    assert np.all(radial_out > radial_in)  # farther out along the chain's radial direction
    # and farther from the z axis (for this robot the elbow-in arm folds across the axis)
    dist_out = np.linalg.norm(out[..., :2], axis=-1)
    dist_in = np.linalg.norm(inn[..., :2], axis=-1)
    assert np.all(dist_out > dist_in)


def test_ik_matches_numpy_reference():
    p = random_workspace_points(N, seed=3)
    np.testing.assert_allclose(delta.ik(ROBOT, p).q.p, reference_delta.ik_numpy(p), atol=1e-12)


def test_unreachable_invalid_and_limits_are_flagged():
    p = np.array([[0.0, 0.0, -30.0], [0.0, 0.0, -60.0], [80.0, 0.0, -20.0], [np.nan, 0.0, -30.0]])
    result = delta.ik(ROBOT, p)
    assert result.status.tolist() == [
        Status.OK,
        Status.UNREACHABLE,
        Status.UNREACHABLE,
        Status.INVALID_INPUT,
    ]
    assert tree_allfinite(result)
    assert float(result.margin[1]) < 0 < float(result.margin[0])
    limited = delta.ik(ROBOT.with_limits(-0.5, 0.5), np.array([[0.0, 0.0, -25.0], [0, 0, -40.0]]))
    assert limited.status.tolist() == [Status.OK, Status.OUT_OF_LIMITS]


def test_inverse_singularity_on_the_boundary():
    # On the axis with every arm and rod aligned (fully stretched): |A_i Q_i| = 15.5 + 30.
    z = -math.sqrt(45.5**2 - 4.5**2)
    result = delta.ik(ROBOT, np.array([0.0, 0.0, z]))
    assert int(result.status) == Status.SINGULAR
    assert abs(float(result.margin)) < 1e-6
    measure = delta.singularity(ROBOT, np.array([0.0, 0.0, z]))
    assert float(measure.inverse) < 1e-6 and int(measure.status) == Status.SINGULAR
    inside = delta.singularity(ROBOT, random_workspace_points(50))
    assert np.all(np.asarray(inside.status) == Status.OK)
    assert np.all((np.asarray(inside.inverse) > 0) & (np.asarray(inside.inverse) <= 1))
    assert np.all((np.asarray(inside.direct) > 0) & (np.asarray(inside.direct) <= 1))


# ------------------------------------------------------------------------------ FK


def test_fk_of_ik_round_trip_and_closed_form():
    p = random_workspace_points(N, seed=4)
    theta = np.asarray(delta.ik(ROBOT, p).q.p)
    fk = delta.fk(ROBOT, theta)
    assert np.all(np.asarray(fk.status) == Status.OK)
    np.testing.assert_allclose(fk.x.p, p, atol=1e-10)
    # plain angles are taken at rest: zero rates of the position's shape and dtype, written by
    # the kernel for small batches and by fk itself from _batching.SHARED_ZEROS_MIN elements on
    big = delta.fk(ROBOT, np.repeat(theta[:4], _batching.SHARED_ZEROS_MIN // 4, axis=0))
    np.testing.assert_allclose(
        np.asarray(big.x.p)[:: _batching.SHARED_ZEROS_MIN // 4], fk.x.p[:4], atol=1e-12
    )
    for result in (fk, big):
        for rate in (result.x.v, result.x.a):
            assert rate.shape == result.x.p.shape and rate.dtype == result.x.p.dtype
            assert not np.any(np.asarray(rate))
    closed = delta.fk_closed_form(ROBOT, theta)
    assert np.all(np.asarray(closed.status) == Status.OK)
    np.testing.assert_allclose(closed.x, p, atol=1e-10)
    assert np.all(np.asarray(delta.which_branch(ROBOT, theta, fk.x.p)) == delta.LOWER)
    # the upper assembly lies above the plane of the sphere centres and satisfies the rods too
    np.testing.assert_allclose(rod_lengths_np(np.asarray(closed.x_upper), theta), LR, rtol=1e-12)
    assert np.all(np.asarray(closed.x_upper)[:, 2] > np.asarray(closed.x)[:, 2])
    # elbow-in angles reach the same platform positions
    theta_in = np.asarray(delta.ik(ROBOT, p, branch="in").q.p)
    np.testing.assert_allclose(delta.fk_closed_form(ROBOT, theta_in).x, p, atol=1e-10)


def test_newton_matches_closed_form_on_random_angles_and_reports_branch():
    rng = np.random.default_rng(5)
    theta = rng.uniform(-0.6, 1.2, size=(N, 3))
    closed = delta.fk_closed_form(ROBOT, theta)
    fk = delta.fk(ROBOT, theta)
    ok = np.asarray(closed.status) == Status.OK
    assert ok.mean() > 0.9
    assert np.all(np.asarray(fk.status)[ok] == Status.OK)  # 100 % convergence where assemblable
    np.testing.assert_allclose(np.asarray(fk.x.p)[ok], np.asarray(closed.x)[ok], atol=1e-10)
    # A guess above the centres converges to the upper assembly, and which_branch says so.
    upper = delta.fk(ROBOT, theta, guess=np.asarray(closed.x_upper) + 0.5)
    np.testing.assert_allclose(np.asarray(upper.x.p)[ok], np.asarray(closed.x_upper)[ok], atol=1e-9)
    branch = np.asarray(delta.which_branch(ROBOT, theta, upper.x.p))
    assert np.all(branch[ok] == delta.UPPER)


def test_convergence_counts_default_home_and_warm_start():
    p = random_workspace_points(N, seed=6)
    theta = np.asarray(delta.ik(ROBOT, p).q.p)
    default = np.asarray(delta.fk(ROBOT, theta).iterations)
    # default guess (centroid of the sphere centres, lowered): measured max 5, mean ~4
    assert default.max() <= 6 and default.mean() < 5
    home = np.array([0.0, 0.0, -math.sqrt(500.0)])
    from_home = delta.fk(ROBOT, theta, guess=home)
    assert np.all(np.asarray(from_home.status) == Status.OK)
    # the paper's start (the home pose): measured max 6
    assert np.asarray(from_home.iterations).max() <= 7
    # warm start along a trajectory sampled at 1 kHz (circle of radius 10 cm at 1 m/s)
    t = np.arange(N + 1) * 1e-3
    path = np.stack([10 * np.cos(10 * t), 10 * np.sin(10 * t), -30 + 0 * t], -1)
    theta_path = np.asarray(delta.ik(ROBOT, path).q.p)
    warm = delta.fk(ROBOT, theta_path[1:], guess=path[:-1])
    assert np.all(np.asarray(warm.status) == Status.OK)
    assert np.asarray(warm.iterations).max() <= 3
    assert np.asarray(warm.residual).max() <= 1e-12 * (LA + LR)
    np.testing.assert_allclose(warm.x.p, path[1:], atol=1e-11)


def test_unassemblable_angles_and_invalid_input():
    rng = np.random.default_rng(7)
    theta = rng.uniform(-np.pi, np.pi, size=(N, 3))
    closed = delta.fk_closed_form(ROBOT, theta)
    unreachable = np.asarray(closed.status) == Status.UNREACHABLE
    assert unreachable.sum() > 5
    fk = delta.fk(ROBOT, theta)
    assert np.all(np.asarray(fk.status)[unreachable] == Status.NOT_CONVERGED)
    assert tree_allfinite((closed, fk))
    bad = np.array([[0.1, 0.2, 0.3], [np.nan, 0.0, 0.0], [0.0, np.inf, 0.0]])
    fk_bad = delta.fk(ROBOT, bad)
    assert fk_bad.status.tolist() == [Status.OK, Status.INVALID_INPUT, Status.INVALID_INPUT]
    assert delta.fk_closed_form(ROBOT, bad).status.tolist()[1:] == [Status.INVALID_INPUT] * 2
    assert tree_allfinite(fk_bad)
    guess_bad = delta.fk(ROBOT, bad[:1], guess=np.array([[np.nan, 0, 0]]))
    assert guess_bad.status.tolist() == [Status.INVALID_INPUT]


def test_direct_singularity_flagged():
    # Bisect along theta(s) = s * theta_far between an assemblable pose and one that cannot
    # be assembled: at the boundary the two assemblies meet (rods coplanar).
    rng = np.random.default_rng(7)
    theta = rng.uniform(-np.pi, np.pi, size=(N, 3))
    bad = theta[np.asarray(delta.fk_closed_form(ROBOT, theta).status) == Status.UNREACHABLE][0]
    lo, hi = 0.0, 1.0
    for _ in range(80):
        mid = 0.5 * (lo + hi)
        status = int(delta.fk_closed_form(ROBOT, mid * bad).status)
        lo, hi = (mid, hi) if status != Status.UNREACHABLE else (lo, mid)
    edge = lo * bad
    closed = delta.fk_closed_form(ROBOT, edge)
    assert int(closed.status) == Status.SINGULAR
    measure = delta.singularity(ROBOT, closed.x, edge)
    assert float(measure.direct) < 1e-6 and int(measure.status) == Status.SINGULAR
    fk = delta.fk(ROBOT, edge)
    assert int(fk.status) in (Status.SINGULAR, Status.NOT_CONVERGED)
    assert tree_allfinite(fk)


def test_references_agree_with_jaxkin():
    p = random_workspace_points(N, seed=8)
    theta = np.asarray(delta.ik(ROBOT, p).q.p)
    np.testing.assert_allclose(reference_delta.fk_closed_form_numpy(theta), p, atol=1e-10)
    np.testing.assert_allclose(reference_delta.fk_newton_numpy(theta), p, atol=1e-10)
    pytest.importorskip("numba")
    numba_fk = reference_delta.make_numba_fk_newton()
    np.testing.assert_allclose(numba_fk(theta[:10]), p[:10], atol=1e-10)


# ------------------------------------------------------------------------------- rates


def helix(t):
    return np.array([8.0 * np.cos(2.0 * t), 8.0 * np.sin(2.0 * t), -30.0 + 3.0 * np.sin(t)])


def helix_jet(t):
    p = helix(t)
    v = np.array([-16.0 * np.sin(2 * t), 16.0 * np.cos(2 * t), 3.0 * np.cos(t)])
    a = np.array([-32.0 * np.cos(2 * t), -32.0 * np.sin(2 * t), -3.0 * np.sin(t)])
    return Jet.of(p, v, a)


@pytest.mark.parametrize("t", [0.3, 1.7])
def test_ik_rates_analytic_autodiff_and_finite_differences(t):
    jet = helix_jet(t)
    analytic = delta.ik(ROBOT, jet)
    autodiff = delta.ik(ROBOT, jet, method="autodiff")
    np.testing.assert_allclose(analytic.q.v, autodiff.q.v, rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(analytic.q.a, autodiff.q.a, rtol=1e-10, atol=1e-12)
    v_fd, a_fd = fd_rates(lambda s: np.asarray(delta.ik(ROBOT, helix(s)).q.p), t)
    np.testing.assert_allclose(analytic.q.v, v_fd, rtol=1e-8, atol=1e-9)
    np.testing.assert_allclose(analytic.q.a, a_fd, rtol=1e-6, atol=1e-6)


@pytest.mark.parametrize("t", [0.3, 1.7])
def test_fk_rates_analytic_autodiff_and_finite_differences(t):
    theta = delta.ik(ROBOT, helix_jet(t)).q  # a joint-space Jet
    analytic = delta.fk(ROBOT, theta)
    autodiff = delta.fk(ROBOT, theta, method="autodiff")
    assert int(analytic.status) == Status.OK and int(autodiff.status) == Status.OK
    np.testing.assert_allclose(analytic.x.v, autodiff.x.v, rtol=1e-10, atol=1e-11)
    np.testing.assert_allclose(analytic.x.a, autodiff.x.a, rtol=1e-10, atol=1e-10)
    # the round trip recovers the Cartesian rates exactly
    jet = helix_jet(t)
    np.testing.assert_allclose(analytic.x.v, jet.v, rtol=1e-10, atol=1e-11)
    np.testing.assert_allclose(analytic.x.a, jet.a, rtol=1e-10, atol=1e-10)

    def theta_of(s):  # a joint trajectory, then FK by Newton as a black box
        base = np.asarray(theta.p)
        return base + np.asarray(theta.v) * (s - t) + 0.5 * np.asarray(theta.a) * (s - t) ** 2

    v_fd, a_fd = fd_rates(lambda s: np.asarray(delta.fk(ROBOT, theta_of(s)).x.p), t)
    np.testing.assert_allclose(analytic.x.v, v_fd, rtol=1e-8, atol=1e-8)
    np.testing.assert_allclose(analytic.x.a, a_fd, rtol=1e-6, atol=1e-6)


def test_rates_are_zero_placeholders_where_not_ok():
    p = Jet.of(np.array([[0.0, 0.0, -30.0], [0.0, 0.0, -60.0]]), np.ones((2, 3)), np.ones((2, 3)))
    result = delta.ik(ROBOT, p)
    assert result.status.tolist() == [Status.OK, Status.UNREACHABLE]
    assert np.all(np.asarray(result.q.v)[1] == 0) and np.all(np.asarray(result.q.a)[1] == 0)


# ------------------------------------------------------------------ batching, jit, gradients


@pytest.mark.parametrize("shape", BATCH_SHAPES)
def test_batch_shapes(shape):
    n = int(np.prod(shape)) if shape else 1
    p = random_workspace_points(n, seed=9).reshape(*shape, 3)
    ik = delta.ik(ROBOT, p)
    assert ik.q.p.shape == (*shape, 3) and ik.status.shape == shape
    fk = delta.fk(ROBOT, ik.q)
    assert fk.x.p.shape == (*shape, 3) and fk.iterations.shape == shape
    np.testing.assert_allclose(fk.x.p, p, atol=1e-10)


def test_jit_over_batch_and_time_without_recompilation():
    p = random_workspace_points(4 * 6, seed=10).reshape(4, 6, 3)  # (N, T, 3)
    theta = delta.ik(ROBOT, p).q.p
    delta.fk(ROBOT, theta)  # the first FK of this shape compiles
    others = p + 0.1, p - 0.1, theta + 0.01
    with compilations() as count:
        delta.ik(ROBOT, others[0])
        delta.ik(ROBOT, others[1])
        delta.fk(ROBOT, others[2])
    assert count.n == 0
    user = jax.jit(lambda th: delta.fk(ROBOT, th).x.p)
    np.testing.assert_allclose(user(theta), p, atol=1e-10)
    with compilations() as count:
        user(others[2])
    assert count.n == 0
    # the geometry is a pytree: it can be vmapped (e.g. a batch of robots)
    robots = jax.tree.map(lambda x: jnp.stack([x, x * 1.01]), ROBOT)
    per_robot = jax.vmap(lambda r: delta.ik(r, p[0]))
    assert per_robot(robots).q.p.shape == (2, 6, 3)


def test_chunked_batches_equal_small_batches():
    """A batch over ``_batching.CHUNK`` is solved in padded chunks: same answers per element.

    The reference solves slices of at most CHUNK elements whole; the compiled loops differ,
    so values agree to rounding (1e-12 cm on a 30 cm robot) and counts/statuses exactly.
    """
    n = _batching.CHUNK + 37  # two chunks, the last one padded
    p = random_workspace_points(n, seed=11)
    theta = np.array(delta.ik(ROBOT, p).q.p)
    theta[5] = np.nan  # invalid input in the first chunk
    theta[-1] = [np.pi, 0.0, 0.0]  # cannot be assembled (fk_closed_form: UNREACHABLE)
    whole = delta.fk(ROBOT, theta)
    half = n // 2
    parts = [delta.fk(ROBOT, theta[:half]), delta.fk(ROBOT, theta[half:])]
    np.testing.assert_allclose(
        whole.x.p, np.concatenate([r.x.p for r in parts]), rtol=0, atol=1e-12
    )
    for field in ("iterations", "status", "converged"):
        np.testing.assert_array_equal(
            getattr(whole, field), np.concatenate([getattr(r, field) for r in parts])
        )
    assert whole.status[5] == Status.INVALID_INPUT
    np.testing.assert_allclose(whole.x.p[:-1][whole.ok[:-1]], p[:-1][whole.ok[:-1]], atol=1e-10)


def test_fk_diagnostics_refer_to_the_original_constraints():
    """Newton runs on rows taken relative to row 1; residual/conditioning are the original's.

    Independent check: the rod lengths (numpy geometry of this file) give the residuals
    ``(|rod|^2 - l_rod^2) / (2 l_rod)``, and the Hadamard ratio of the stacked Jacobian
    ``[p - C_i]`` comes from NumPy (``|det| / prod_i |row_i|``).
    """
    p = random_workspace_points(300, seed=21)
    theta = np.asarray(delta.ik(ROBOT, p).q.p)
    # Stop early so the residual is far from rounding and the comparison is meaningful.
    result = delta.fk(ROBOT, theta, max_iter=2)
    x = np.asarray(result.x.p)
    rods = rod_lengths_np(x, theta)
    expected = np.max(np.abs((rods * rods - LR * LR) / (2.0 * LR)), axis=-1)
    np.testing.assert_allclose(result.residual, expected, rtol=1e-9, atol=1e-12)
    rows = x[..., None, :] + RP * U - elbows_np(theta)  # p - C_i = D_i - E_i
    ratio = np.abs(np.linalg.det(rows)) / np.prod(np.linalg.norm(rows, axis=-1), axis=-1)
    np.testing.assert_allclose(result.conditioning, ratio, rtol=1e-9)
    scale = LA + LR
    np.testing.assert_array_equal(result.converged, expected <= 1e-12 * scale)
    assert not np.all(result.converged)  # two updates are not enough for every point
    full = delta.fk(ROBOT, theta)
    assert np.all(full.converged) and np.all(full.residual <= 1e-12 * scale)


def test_static_and_traced_geometry_agree():
    """Concrete geometry is compiled in as constants; traced geometry takes the data path."""
    p = random_workspace_points(64, seed=12)
    theta = delta.ik(ROBOT, p).q
    static = delta.fk(ROBOT, theta)
    traced = jax.jit(lambda robot, th: delta.fk(robot, th))(ROBOT, theta)
    for a, b in zip(jax.tree.leaves(static.x), jax.tree.leaves(traced.x), strict=True):
        np.testing.assert_allclose(a, b, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(static.residual, traced.residual, rtol=0, atol=1e-12)
    np.testing.assert_array_equal(static.iterations, traced.iterations)
    np.testing.assert_array_equal(static.status, traced.status)
    closed = jax.jit(lambda robot, th: delta.fk_closed_form(robot, th).x)(ROBOT, theta.p)
    np.testing.assert_allclose(closed, delta.fk_closed_form(ROBOT, theta.p).x, rtol=1e-12)


def test_finite_gradients_on_mixed_batches():
    p = np.array([[0.0, 0.0, -30.0], [0.0, 0.0, -60.0], [np.nan, 0.0, -30.0], [3.0, 4.0, -25.0]])

    def ik_loss(p):
        return jnp.sum(delta.ik(ROBOT, p).q.p ** 2)

    grad = jax.grad(ik_loss)(jnp.asarray(p))
    assert np.all(np.isfinite(np.asarray(grad)))
    theta = np.array([[0.1, 0.2, 0.3], [np.nan, 0.0, 0.0], [3.0, -3.0, 2.5], [0.0, 0.0, 0.0]])

    def fk_loss(theta):
        return jnp.sum(delta.fk(ROBOT, theta).x.p ** 2)

    grad = np.asarray(jax.grad(fk_loss)(jnp.asarray(theta)))
    assert np.all(np.isfinite(grad))
    # gradient of the first (OK) element against central differences
    eps = 1e-6
    fd = [
        (
            float(fk_loss(theta + eps * np.eye(4 * 3)[k].reshape(4, 3)))
            - float(fk_loss(theta - eps * np.eye(4 * 3)[k].reshape(4, 3)))
        )
        / (2 * eps)
        for k in range(3)
    ]
    np.testing.assert_allclose(grad[0], fd, rtol=1e-6)

    def calibration_loss(robot):
        return jnp.sum(delta.fk(robot, theta[:1]).x.p)

    robot_grad = jax.grad(calibration_loss)(ROBOT)
    assert tree_allfinite(robot_grad)


def test_float32():
    p = random_workspace_points(N, seed=11).astype(np.float32)
    ik = delta.ik(ROBOT, p)
    assert ik.q.p.dtype == jnp.float32
    fk = delta.fk(ROBOT, ik.q.p)  # the float32 default tolerance is 8 eps = 9.5e-7
    assert fk.x.p.dtype == jnp.float32
    assert np.all(np.asarray(fk.status) == Status.OK)
    assert np.asarray(fk.iterations).max() <= 4
    # 1e-12 is below float32 resolution: most elements cannot meet it
    strict = delta.fk(ROBOT, ik.q.p, tol=1e-12)
    assert np.mean(np.asarray(strict.status) == Status.NOT_CONVERGED) > 0.5
    # measured: ~1e-5 cm on a 50 cm robot (float32 eps 1.2e-7 times the ~30 cm rods, amplified)
    assert np.abs(np.asarray(fk.x.p, np.float64) - p).max() < 1e-4
    closed = delta.fk_closed_form(ROBOT, ik.q.p)
    assert np.abs(np.asarray(closed.x, np.float64) - p).max() < 1e-4
