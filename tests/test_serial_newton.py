"""Newton-Raphson IK [Pineiro]: step math, convergence, failure as data, validation."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxkin
from jaxkin import Status, serial
from jaxkin.serial import _step, dh, newton
from tests.helpers import compilations, tree_allfinite

RNG = np.random.default_rng(11)

PUMA = serial.from_dh(
    dh.DHTable.create(
        a=[0.0, 0.4318, 0.0203, 0.0, 0.0, 0.0],
        alpha=[np.pi / 2, 0.0, -np.pi / 2, np.pi / 2, -np.pi / 2, 0.0],
        d=[0.0, 0.0, 0.15005, 0.4318, 0.0, 0.0],
        joint_types="RRRRRR",
    )
)
ANTHRO = serial.from_dh(
    dh.DHTable.create(a=[0.0, 0.4, 0.3], alpha=[np.pi / 2, 0.0, 0.0], d=[0.5, 0.0, 0.0])
)


def _fk(chain, q):
    """The chain's tip transforms (``jaxkin.fk(chain, q).x.p``)."""
    return np.asarray(jaxkin.fk(chain, q).x.p)


def _ik_body(chain, *args, **kwargs):
    """``ik_newton`` with [Pineiro]'s body-frame update."""
    return newton.ik_newton(chain, *args, frame="body", **kwargs)


def _planar_2r_body() -> serial.Chain:
    """[Pineiro]'s 2R arm: M = Trans(2, 0, 0), B1 = (0,0,1, 0,2,0), B2 = (0,0,1, 0,1,0)."""
    home = np.eye(4)
    home[0, 3] = 2.0
    screws = np.array([[0, 0, 1, 0, 2, 0], [0, 0, 1, 0, 1, 0]], dtype=float)
    return serial.from_screws(screws, home, frame="body")


def _planar_target(x, y, phi):
    """Planar pose as a 4x4 transform (rotation phi about z), batched over the inputs."""
    x, y, phi = np.broadcast_arrays(*(np.asarray(v, dtype=float) for v in (x, y, phi)))
    t = np.broadcast_to(np.eye(4), (*x.shape, 4, 4)).copy()
    t[..., 0, 0], t[..., 0, 1] = np.cos(phi), -np.sin(phi)
    t[..., 1, 0], t[..., 1, 1] = np.sin(phi), np.cos(phi)
    t[..., 0, 3], t[..., 1, 3] = x, y
    return t


def _planar_2r_pose(q):
    """Pose of [Pineiro]'s 2R arm (links 1 m) at joint angles q (..., 2), by hand."""
    q = np.asarray(q, dtype=float)
    q1, q12 = q[..., 0], q[..., 0] + q[..., 1]
    return _planar_target(np.cos(q1) + np.cos(q12), np.sin(q1) + np.sin(q12), q12)


def _pose_errors(t, t_d):
    """Independent residuals (NumPy): rotation angle of R^T R_d and position distance."""
    t, t_d = np.asarray(t), np.asarray(t_d)
    # |R - R_d|_F = 2 sqrt(2) sin(angle / 2): well conditioned at small angles (arccos is not).
    chord = np.linalg.norm(t[..., :3, :3] - t_d[..., :3, :3], axis=(-2, -1))
    angle = 2.0 * np.arcsin(np.clip(chord / (2.0 * np.sqrt(2.0)), 0.0, 1.0))
    return angle, np.linalg.norm(t[..., :3, 3] - t_d[..., :3, 3], axis=-1)


def _well_conditioned(n, batch=5):
    """Random 6 x n Jacobians with singular values in [0.5, 2] (SVD construction)."""
    k = min(n, 6)
    u = np.linalg.qr(RNG.normal(size=(batch, 6, 6)))[0][..., :k]
    v = np.linalg.qr(RNG.normal(size=(batch, n, n)))[0][..., :k]
    s = RNG.uniform(0.5, 2.0, size=(batch, k))
    return np.einsum("bik,bk,bjk->bij", u, s, v)


@pytest.mark.parametrize("n", [1, 2, 3, 6, 7])
@pytest.mark.parametrize("damping", [0.0, 0.3])
def test_step_matches_pinv_and_damped_formula(n, damping):
    jac = _well_conditioned(n)
    twist = RNG.normal(size=(5, 6))
    step = np.asarray(_step.damped_step(jnp.asarray(jac), jnp.asarray(twist), damping))
    if damping == 0.0:
        # Soft cut-off mu = sqrt(eps) trace(J^T J): relative deviation from pinv <= mu / s^2,
        # here <= 1.5e-8 * 24 / 0.25 ~ 1.5e-6 (module docstring).
        expected = np.einsum("...ij,...j->...i", np.linalg.pinv(jac), twist)
        np.testing.assert_allclose(step, expected, rtol=2e-6, atol=2e-6 * np.abs(expected).max())
    else:
        # Damped least squares, closed form J^T (J J^T + mu I)^-1 V with the documented
        # mu = damping^2 + sqrt(eps) trace(J^T J).
        mu = damping**2 + np.sqrt(np.finfo(np.float64).eps) * np.einsum("bij,bij->b", jac, jac)
        gram = jac @ np.swapaxes(jac, -1, -2) + mu[:, None, None] * np.eye(6)
        y = np.linalg.solve(gram, twist[..., None])[..., 0]
        expected = np.einsum("...ji,...j->...i", jac, y)
        np.testing.assert_allclose(step, expected, rtol=1e-10, atol=1e-12)


def test_step_at_singular_jacobian_is_finite_and_is_pinv():
    # Rank-deficient J (two equal columns): pinv splits the step equally; ours must too.
    col = RNG.normal(size=6)
    jac = np.stack([col, col, RNG.normal(size=6)], axis=-1)
    twist = RNG.normal(size=6)
    step = np.asarray(_step.damped_step(jnp.asarray(jac), jnp.asarray(twist), 0.0))
    np.testing.assert_allclose(step, np.linalg.pinv(jac) @ twist, rtol=1e-6, atol=1e-7)
    zero = _step.damped_step(jnp.zeros((6, 2)), jnp.asarray(twist), 0.0)
    np.testing.assert_array_equal(zero, 0.0)


def test_planar_2r_quadratic_convergence():
    # Error of iterate k+1 is O(error_k^2) once close: check e_{k+1} <= 2 e_k^2.
    chain = _planar_2r_body()
    q_true = np.array([0.4, 1.1])
    target = _fk(chain, q_true)
    res = _ik_body(chain, target, q_true + np.array([0.3, -0.25]), eps_omega=1e-13, eps_v=1e-13)
    assert bool(res.converged)
    errs = np.linalg.norm(np.asarray(res.history) - q_true, axis=-1)[: int(res.iterations) + 1]
    assert errs[-1] < 1e-12
    for e_now, e_next in zip(errs[:-1], errs[1:], strict=True):
        if 1e-7 < e_now < 0.1:
            assert e_next <= 2.0 * e_now**2, errs


@pytest.mark.parametrize(
    "name, table, noise, min_success",
    [("anthropomorphic", ANTHRO, 1.0, 1.0), ("PUMA", PUMA, 0.3, 0.9)],
)
def test_random_reachable_targets(name, table, noise, min_success):
    """Targets = FK of random configurations; seeds perturbed by U(-noise, noise) rad."""
    n = table.n_joints
    q_true = RNG.uniform(-np.pi, np.pi, size=(200, n))
    targets = np.asarray(_fk(table, q_true))
    q0 = q_true + RNG.uniform(-noise, noise, size=q_true.shape)
    res = newton.ik_newton(table, targets, q0, eps_omega=1e-10, eps_v=1e-10, max_iter=20)
    ok = np.asarray(res.converged)
    its = np.asarray(res.iterations)[ok]
    print(
        f"\n{name}: success {ok.mean():.3f} of {ok.size}, iterations median "
        f"{np.median(its):.0f}, 90th pct {np.percentile(its, 90):.0f}, max {its.max()}"
    )
    assert ok.mean() >= min_success
    assert np.all(np.asarray(res.status)[ok] == Status.OK)
    assert np.all(np.asarray(res.status)[~ok] == Status.NOT_CONVERGED)
    ang, lin = _pose_errors(_fk(table, res.q), targets)
    assert np.all(ang[ok] <= 1e-9) and np.all(lin[ok] <= 1e-9)
    assert tree_allfinite(res)


@pytest.mark.parametrize("frame", ["space", "body"])
def test_frames_and_error_field(frame):
    chain = ANTHRO
    q_true = RNG.uniform(-2.0, 2.0, size=(20, 3))
    targets = np.asarray(_fk(chain, q_true))
    res = newton.ik_newton(chain, targets, q_true + 0.2, frame=frame)
    assert np.all(np.asarray(res.converged))
    err = np.asarray(res.error)
    assert err.shape == (20, 2)
    assert np.all(err[:, 0] <= 1e-3) and np.all(err[:, 1] <= 1e-4)
    # |omega| of the twist is the rotation angle in either frame (independent NumPy residual).
    ang, _ = _pose_errors(_fk(chain, res.q), targets)
    np.testing.assert_allclose(err[:, 0], ang, atol=1e-7)


def test_step_limit_bounds_revolute_steps_and_changes_nothing_where_it_does_not_bind():
    # Random configurations kept away from the PUMA's singularities (wrist: sin q5 = 0; elbow
    # stretched or folded: sin(q3 + psi) = 0; wrist centre on the shoulder cylinder |d3|).
    q_true = RNG.uniform(-np.pi, np.pi, size=(800, 6))
    t_true = np.asarray(_fk(PUMA, q_true))
    psi = np.arctan2(0.4318, 0.0203)
    away = (np.abs(np.sin(q_true[:, 4])) >= 0.1) & (np.abs(np.sin(q_true[:, 2] + psi)) >= 0.1)
    away &= np.hypot(t_true[:, 0, 3], t_true[:, 1, 3]) >= 0.15005 + 0.05
    q_true, targets = q_true[away][:400], t_true[away][:400]
    n = len(q_true)
    q0 = q_true + RNG.uniform(-0.5, 0.5, size=q_true.shape)
    tight = dict(eps_omega=1e-10, eps_v=1e-10, max_iter=20)
    free = newton.ik_newton(PUMA, targets, q0, max_step=None, **tight)
    for max_step in (1.0, 0.6):
        res = newton.ik_newton(PUMA, targets, q0, max_step=max_step, **tight)
        steps = np.abs(np.diff(np.asarray(res.history), axis=0))
        assert steps.max() <= max_step * (1.0 + 1e-12)
        # Where the unlimited iteration never stepped further than max_step, the limit never
        # binds and the iterates are the same.
        free_steps = np.abs(np.diff(np.asarray(free.history), axis=0)).max(axis=(0, 2))
        unbound = free_steps < max_step
        assert unbound.sum() > n // 4
        np.testing.assert_array_equal(np.asarray(res.q)[unbound], np.asarray(free.q)[unbound])
    # Default limit (1 rad): every target reached, within the independent NumPy check.
    res = newton.ik_newton(PUMA, targets, q0, **tight)
    print(f"\nPUMA, seeds +-0.5 rad: success {np.mean(free.converged):.3f} without the limit")
    assert np.all(np.asarray(res.converged))
    ang, lin = _pose_errors(_fk(PUMA, res.q), targets)
    assert ang.max() <= 1e-9 and lin.max() <= 1e-9


def test_step_limit_leaves_prismatic_joints_free():
    # Polar RP arm (body frame): revolute about z, then prismatic along the rotated x axis.
    # With q1 already right the residual is linear in q2, so Newton lands in one step of 5
    # length units whatever max_step (radians) is.
    screws = np.array([[0, 0, 1, 0, 1, 0], [0, 0, 0, 1, 0, 0]], dtype=float)
    home = np.eye(4)
    home[0, 3] = 1.0
    chain = serial.from_screws(screws, home, frame="body")
    target = np.asarray(_fk(chain, np.array([0.7, 5.0])))
    res = _ik_body(chain, target, np.array([0.7, 0.0]), max_step=0.1)
    assert bool(res.converged) and int(res.iterations) == 1
    np.testing.assert_allclose(res.q, [0.7, 5.0], atol=1e-12)


def test_history_held_after_convergence_and_elements_independent():
    chain = _planar_2r_body()
    targets = _planar_target(
        [0.366, 1.2, 1.9, 0.5], [1.366, 0.4, 0.0, -1.0], [2.0944, 0.2, 0.1, -1]
    )
    q0 = np.array([[0.0, 0.5236], [0.3, 1.0], [0.2, 0.3], [-0.5, 0.6]])
    # max_iter 15 as in the tests below: one compilation serves them all.
    res = _ik_body(chain, targets, q0, max_iter=15)
    history = np.asarray(res.history)
    assert history.shape == (16, 4, 2)
    np.testing.assert_array_equal(history[0], q0)
    its = np.asarray(res.iterations)
    assert len(set(its.tolist())) > 1  # elements converge at different steps
    for i, k in enumerate(its):
        np.testing.assert_array_equal(history[k:, i], np.broadcast_to(res.q[i], (16 - k, 2)))
        assert np.all(np.any(history[1 : k + 1, i] != history[:k, i], axis=-1))
        single = _ik_body(chain, targets[i], q0[i], max_iter=15)
        np.testing.assert_array_equal(single.q, res.q[i])
        assert int(single.iterations) == k


def test_unreachable_and_invalid_input():
    chain = _planar_2r_body()
    targets = _planar_target([3.0, 0.0, 1.0, 0.366], [0.0, 0.0, 1.0, 1.366], [0.0, 0.0, 0.5, 2.0])
    # 0: beyond the reach of 2 m; 1: out of the plane, unreachable for a planar arm.
    targets[1, 2, 3] = 0.5
    targets[2, 0, 3] = np.nan
    q0 = np.array([[0.1, 0.2], [0.1, 0.2], [0.1, 0.2], [np.inf, 0.5]])
    res = _ik_body(chain, targets, q0, max_iter=15)
    assert [Status(int(s)).name for s in res.status] == [
        "NOT_CONVERGED",
        "NOT_CONVERGED",
        "INVALID_INPUT",
        "INVALID_INPUT",
    ]
    assert tree_allfinite(res)
    assert not np.any(np.asarray(res.converged))
    np.testing.assert_array_equal(res.iterations[2:], 0)
    with pytest.raises(RuntimeError, match="NOT_CONVERGED"):
        res.raise_if_failed()
    # Gradients through the unrolled iterations stay finite even for failing elements.
    grad = jax.grad(lambda t: _ik_body(chain, t, q0, max_iter=5).q.sum())(jnp.asarray(targets))
    assert tree_allfinite(grad)


def test_joint_limits_and_damping():
    chain = _planar_2r_body()
    # A full planar pose (x, y, phi) fixes q uniquely (mod 2 pi): q = (0.3, 0.9) has q2 > 0,
    # so limits forbidding q2 > 0 make the pose unreachable.
    target = _planar_2r_pose([0.3, 0.9])
    q0 = np.array([0.1, 0.5])
    tight = dict(eps_omega=1e-10, eps_v=1e-10)
    free = _ik_body(chain, target, q0, **tight)
    assert bool(free.converged)
    np.testing.assert_allclose(free.q, [0.3, 0.9], atol=1e-9)
    lower, upper = np.array([-np.pi, -np.pi]), np.array([np.pi, 0.0])
    limited = _ik_body(chain, target, q0, limits=(lower, upper), max_iter=15)
    history = np.asarray(limited.history)
    assert np.all(history >= lower) and np.all(history <= upper)
    assert int(limited.status) == Status.NOT_CONVERGED
    damped = _ik_body(chain, target, q0, damping=0.05, max_iter=40, **tight)
    assert bool(damped.converged)
    assert int(damped.iterations) > int(free.iterations)  # damping slows the final approach
    np.testing.assert_allclose(damped.q, [0.3, 0.9], atol=1e-9)


def test_batch_broadcast_no_recompile_and_float32():
    chain = _planar_2r_body()
    targets = _planar_2r_pose(
        np.stack([RNG.uniform(0.0, 0.8, (3, 5)), RNG.uniform(0.6, 1.8, (3, 5))], axis=-1)
    )
    q0 = np.array([0.2, 1.0])  # one seed broadcast over the (3, 5) batch
    res = _ik_body(chain, targets, q0, max_iter=15)
    assert res.q.shape == (3, 5, 2) and res.history.shape == (16, 3, 5, 2)
    assert res.status.shape == (3, 5) and res.error.shape == (3, 5, 2)
    with compilations() as count:
        _ik_body(chain, targets * 1.0, q0 + 0.1, eps_omega=1e-6, damping=0.01, max_iter=15)
        _ik_body(chain.replace(joint_names=("a", "b"), tip_link="tool"), targets, q0, max_iter=15)
    assert count.n == 0
    # float32 end to end (chain, target, seed): converges to the default tolerances.
    chain32 = jax.tree.map(lambda x: x.astype(jnp.float32), chain)
    res32 = _ik_body(chain32, targets.astype(np.float32), q0.astype(np.float32), max_iter=15)
    assert res32.q.dtype == jnp.float32
    assert np.mean(np.asarray(res32.converged)) >= np.mean(np.asarray(res.converged)) - 0.1
    ok = np.asarray(res32.converged) & np.asarray(res.converged)
    np.testing.assert_allclose(np.asarray(res32.q)[ok], np.asarray(res.q)[ok], atol=2e-3)


def test_validation():
    chain = _planar_2r_body()
    target, q0 = np.eye(4), np.zeros(2)
    cases = [
        (dict(target=np.eye(3)), r"target: expected shape \(\.\.\., 4, 4\)"),
        (dict(q0=np.zeros(3)), r"q0: expected shape \(\.\.\., 2\)"),
        (dict(eps_omega=0.0), "eps_omega must be positive"),
        (dict(eps_v=-1.0), "eps_v must be positive"),
        (dict(damping=-0.1), "damping must be non-negative"),
        (dict(max_step=0.0), "max_step must be positive"),
        (dict(max_iter=-1), "max_iter"),
        (dict(max_iter=2.5), "max_iter"),
        (dict(limits=([0.0, 0.0], [-1.0, 1.0])), "limits: need lower <= upper"),
        (dict(limits=[0.0]), "limits: expected a pair"),
        (dict(frame="world"), "frame must be one of"),
        (dict(target=np.tile(np.eye(4), (3, 1, 1)), q0=np.zeros((2, 2))), "do not broadcast"),
    ]
    for kwargs, match in cases:
        args = dict(target=target, q0=q0) | kwargs
        with pytest.raises(ValueError, match=match):
            newton.ik_newton(chain, **args)
    with pytest.raises(ValueError, match="chain: expected a serial.Chain"):
        newton.ik_newton("arm", target, q0)
    with pytest.raises(ValueError, match="chain: expected a serial.Chain"):
        newton.ik_newton(dh.DHTable.create(a=[1.0, 1.0], alpha=[0, 0], d=[0, 0]), target, q0)


def _not_rigid(good):
    """``good`` (4, 4) spoilt four ways: rotation block scaled by 2 (the log of ``R^T R_d =
    2 I`` reads as angle 0: it looked solved), mirrored (det -1), skewed by 1e-6 (beyond
    ``sqrt(eps)``), a NaN in the rotation."""
    bad = np.stack([good] * 4)
    bad[0, :3, :3] *= 2.0
    bad[1, :3, 2] *= -1.0
    bad[2, 0, 1] += 1e-6
    bad[3, 1, 1] = np.nan
    return bad


def test_a_target_that_is_not_a_rigid_transform_is_never_ok():
    chain = _planar_2r_body()
    good = _planar_2r_pose([0.3, 0.9])
    targets = np.concatenate([good[None], _not_rigid(good)])
    res = _ik_body(chain, targets, np.array([0.3, 0.9]), max_iter=15)
    names = [Status(int(s)).name for s in res.status]
    assert names == ["OK"] + ["INVALID_INPUT"] * 4
    assert tree_allfinite(res)


def test_float32_targets_of_float64_joints_are_poses_to_float32_precision():
    """``ik_newton`` of float32 targets from float64 starts works in float64: rounded poses
    (rotation blocks off by float32 rounding, far beyond float64's ``sqrt(eps)``) are ``OK``,
    float32 blocks that are not rotations (``_not_rigid``'s, skewed by 1e-3) stay
    ``INVALID_INPUT``. The float32 blocks, also
    perturbed by up to 1e-4 an entry (within float32's ``sqrt(eps)``), become their polar factor
    (``_step.promoted_pose``): scipy's to 1e-14 (its SVD's own error), a rotation to 4 eps
    whose transpose times the block is symmetric to 1e-15; a float64 target is only cast."""
    from scipy.linalg import polar
    from scipy.spatial.transform import Rotation

    chain = _planar_2r_body()
    good = _planar_2r_pose([[0.3, 0.9], [1.2, -0.7]]).astype(np.float32)
    bad = _not_rigid(good[0].astype(np.float64)).astype(np.float32)
    bad[2, 0, 1] += 1e-3  # beyond float32's sqrt(eps), as 1e-6 is beyond float64's
    targets = np.concatenate([good, bad])
    res = _ik_body(chain, targets, np.array([0.2, 0.8]), max_iter=15)
    assert res.q.dtype == np.float64
    names = [Status(int(s)).name for s in res.status]
    assert names == ["OK"] * 2 + ["INVALID_INPUT"] * 4

    rng = np.random.default_rng(3)
    poses = np.broadcast_to(np.eye(4), (64, 4, 4)).copy()
    poses[:, :3, :3] = Rotation.random(64, random_state=4).as_matrix()
    poses[:, :3, 3] = rng.normal(size=(64, 3))
    poses[32:, :3, :3] += rng.uniform(-1e-4, 1e-4, (32, 3, 3))
    given = poses.astype(np.float32)
    promoted = np.asarray(_step.promoted_pose(jnp.asarray(given), jnp.float64))
    expected = given.astype(np.float64)
    expected[:, :3, :3] = [polar(b)[0] for b in expected[:, :3, :3]]
    np.testing.assert_allclose(promoted, expected, rtol=0, atol=1e-14)  # scipy's SVD: 1e-14
    # The polar factor U of B: U^T U = I and U^T B symmetric (positive definite).
    rot, block = promoted[:, :3, :3], given[:, :3, :3].astype(np.float64)
    eye = np.broadcast_to(np.eye(3), rot.shape)
    np.testing.assert_allclose(np.swapaxes(rot, -1, -2) @ rot, eye, rtol=0, atol=4 * 2.3e-16)
    stretch = np.swapaxes(rot, -1, -2) @ block
    np.testing.assert_allclose(stretch, np.swapaxes(stretch, -1, -2), rtol=0, atol=1e-15)
    assert np.all(np.linalg.eigvalsh(stretch) > 0.99)
    np.testing.assert_array_equal(_step.promoted_pose(jnp.asarray(poses), jnp.float64), poses)


def test_damped_step_looped_matches_numpy():
    """The damped step of the chain IK (``damped_step_looped``: Gauss-Jordan elimination in
    one loop) for 6 x 7 and 6 x 6 Jacobians against numpy's solve of the same damped normal
    equations: 1e-12 relative to the step's size; on ill-conditioned systems to their
    conditioning's bound; finite on singular ones."""
    rng = np.random.default_rng(5)
    for n in (7, 6):
        jac = rng.normal(size=(16, 6, n))
        twist = rng.normal(size=(16, 6))
        damping = jnp.asarray(0.1)
        looped = np.asarray(
            _step.damped_step_looped(jnp.asarray(jac), jnp.asarray(twist), damping, 1e-8)
        )
        scale = np.max(np.abs(looped))
        mu = 0.01 + 1e-8 * np.sum(jac * jac, axis=(-2, -1))
        if n > 6:
            outer = jac @ np.swapaxes(jac, -1, -2) + mu[:, None, None] * np.eye(6)
            ref = np.einsum("bki,bk->bi", jac, np.linalg.solve(outer, twist[..., None])[..., 0])
        else:
            gram = np.swapaxes(jac, -1, -2) @ jac + mu[:, None, None] * np.eye(n)
            ref = np.linalg.solve(gram, np.einsum("bki,bk->bi", jac, twist)[..., None])[..., 0]
        np.testing.assert_allclose(looped, ref, rtol=0, atol=1e-12 * scale)
    # Ill-conditioned systems (singular values of J from 1 down to 1e-6, the search's floor
    # of 16 eps): against numpy's solve to the conditioning's bound (cond(J J^T) eps, about
    # 1e-4 of the step) and finite; the zero system gives a zero step.
    u, _ = np.linalg.qr(rng.normal(size=(16, 6, 6)))
    v, _ = np.linalg.qr(rng.normal(size=(16, 7, 7)))
    sigma = np.logspace(0, -6, 6)
    jac = np.einsum("bij,j,bkj->bik", u, sigma, v[:, :, :6])
    twist = rng.normal(size=(16, 6))
    floor = 16 * float(np.finfo(np.float64).eps)
    zero = jnp.asarray(0.0)
    looped = np.asarray(_step.damped_step_looped(jnp.asarray(jac), jnp.asarray(twist), zero, floor))
    mu = floor * np.sum(jac * jac, axis=(-2, -1))
    outer = jac @ np.swapaxes(jac, -1, -2) + mu[:, None, None] * np.eye(6)
    ref = np.einsum("bki,bk->bi", jac, np.linalg.solve(outer, twist[..., None])[..., 0])
    assert np.all(np.isfinite(looped))
    np.testing.assert_allclose(looped, ref, rtol=0, atol=1e-4 * np.max(np.abs(ref)))
    zero_step = _step.damped_step_looped(jnp.zeros((6, 7)), jnp.ones(6), zero, floor)
    np.testing.assert_array_equal(zero_step, np.zeros(7))
    # A singular Jacobian (two equal rows) with the finish's floor of eps: a finite step.
    jac = rng.normal(size=(16, 6, 7))
    jac[:, 5] = jac[:, 4]
    eps = float(np.finfo(np.float64).eps)
    step = _step.damped_step_looped(
        jnp.asarray(jac), jnp.asarray(rng.normal(size=(16, 6))), zero, eps
    )
    assert np.all(np.isfinite(step))
