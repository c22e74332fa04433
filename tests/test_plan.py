"""Planner backend: per-candidate equality with per-point IK, failures at the right sample,
limits, branch choice, chunking and sharding."""

import os
import subprocess
import sys
from pathlib import Path

import jax
import numpy as np
import pytest
from helpers import tree_allfinite

from jaxkin import Jet, Status, delta, plan, scara

ROBOT = scara.Scara.create(150.0, 80.0, 50.0)  # seed 000 spiral robot: annulus [30, 130] mm


def radial_paths(radii_start, radii_end, n_samples=41, z=60.0, angle=0.3):
    """Straight radial lines at a fixed angle, with exact (constant) velocity."""
    s = np.linspace(0.0, 1.0, n_samples)
    r = radii_start[:, None] + (radii_end - radii_start)[:, None] * s
    direction = np.array([np.cos(angle), np.sin(angle)])
    p = np.concatenate([r[..., None] * direction, np.full(r.shape + (1,), z)], axis=-1)
    dr = (radii_end - radii_start)[:, None] * np.ones_like(s)
    v = np.concatenate([dr[..., None] * direction, np.zeros(r.shape + (1,))], axis=-1)
    return Jet.of(p, v, np.zeros_like(p)), r


def spiral_candidates(n=6, n_samples=33):
    """Scaled copies of the seed's spiral (eq. 16), exact derivatives."""
    t = np.linspace(0.0, 8.0, n_samples)
    w = np.pi / 2
    scale = np.linspace(0.8, 1.2, n)[:, None]
    x = 100 + 20 * scale * np.sin(w * t)
    y = -20 * scale * np.cos(w * t)
    z = np.broadcast_to(50 + 10 * t, x.shape)
    p = np.stack([x, y, z], -1)
    v = np.stack([20 * scale * w * np.cos(w * t), 20 * scale * w * np.sin(w * t), 10 + 0 * x], -1)
    a = np.stack(
        [-20 * scale * w * w * np.sin(w * t), 20 * scale * w * w * np.cos(w * t), 0 * x], -1
    )
    return Jet.of(p, v, a), t[1] - t[0]


def assert_same_result(x, y):
    """Statuses, masks and indices identical; floats equal up to rounding.

    The same kernel compiled for another batch shape may round differently in the last bit
    (XLA vectorises the loop body and the remainder differently), hence 1e-13, not bitwise.
    """
    x, y = np.asarray(x), np.asarray(y)
    if np.issubdtype(x.dtype, np.floating):
        np.testing.assert_allclose(x, y, rtol=1e-13, atol=1e-13)
    else:
        np.testing.assert_array_equal(x, y)


@pytest.mark.parametrize("mode", [1, -1])
def test_joint_values_equal_per_point_ik(mode):
    path, dt = spiral_candidates()
    ev = plan.evaluate(ROBOT, path, mode=mode, dt=dt)
    for i in (0, 3, 5):
        for k in (0, 10, 32):
            point = Jet(path.p[i, k], path.v[i, k], path.a[i, k])
            ref = scara.ik(ROBOT, point, mode=mode)
            # Same formulas, compiled for another shape: equal up to rounding (XLA may fuse
            # differently), hence 1e-13 rather than bitwise equality.
            np.testing.assert_allclose(ev.q.p[i, k], ref.q.p, rtol=1e-13, atol=1e-15)
            np.testing.assert_allclose(ev.q.a[i, k], ref.q.a, rtol=1e-13, atol=1e-15)
            assert ev.status[i, k] == ref.status
    assert np.all(ev.feasible) and np.all(ev.first_failure == -1)
    assert np.all(ev.branch == [1, -1].index(mode))


def test_costs_against_direct_numpy_formulas():
    path, dt = spiral_candidates(n=3)
    ev = plan.evaluate(ROBOT, path, dt=dt)
    q = [np.asarray(x) for x in (ev.q.p, ev.q.v, ev.q.a)]
    np.testing.assert_allclose(
        ev.costs.path_length, np.linalg.norm(np.diff(q[0], axis=1), axis=-1).sum(1), rtol=1e-12
    )
    np.testing.assert_allclose(ev.costs.peak_speed, np.abs(q[1]).max(axis=(1, 2)), rtol=1e-14)
    np.testing.assert_allclose(ev.costs.integrated_acceleration, (q[2] ** 2).sum((1, 2)) * dt)
    jerk = np.diff(q[2], axis=1) / dt
    np.testing.assert_allclose(ev.costs.peak_jerk, np.abs(jerk).max(axis=(1, 2)), rtol=1e-12)
    np.testing.assert_allclose(ev.costs.total, ev.costs.integrated_acceleration)
    np.testing.assert_array_equal(ev.costs.limit_violation, 0.0)


def test_unreachable_and_singular_samples_fail_at_the_right_index():
    # Radii from 60 up to 150 (outer reach 130) and one ending exactly on the boundary.
    path, r = radial_paths(np.array([60.0, 60.0, 60.0]), np.array([150.0, 130.0, 120.0]))
    ev = plan.evaluate(ROBOT, path)
    expected_unreachable = int(np.argmax(r[0] > 130.0))
    assert ev.first_failure[0] == expected_unreachable
    assert ev.status[0, expected_unreachable] in (Status.UNREACHABLE, Status.SINGULAR_EXTENDED)
    assert ev.first_failure[1] == r.shape[1] - 1  # r = 130 exactly at the last sample
    assert ev.status[1, -1] == Status.SINGULAR_EXTENDED
    assert ev.first_failure[2] == -1 and ev.feasible[2] and not ev.feasible[0]
    assert np.isinf(ev.costs.total[0]) and np.isfinite(ev.costs.total[2])
    assert tree_allfinite(ev.q)


def test_position_and_velocity_limits_are_enforced():
    path, dt = spiral_candidates(n=2)
    free = plan.evaluate(ROBOT, path, dt=dt)
    theta1 = np.asarray(free.q.p[..., 0])
    cap = float(np.median(theta1))
    limits = plan.Limits.create(3, q_max=[cap, np.inf, np.inf])
    ev = plan.evaluate(ROBOT, path, limits=limits, dt=dt)
    expected = np.where((theta1 > cap).any(1), np.argmax(theta1 > cap, axis=1), -1)
    np.testing.assert_array_equal(ev.first_failure, expected)
    assert ev.status[0, expected[0]] == Status.OUT_OF_LIMITS
    speed = np.abs(np.asarray(free.q.v[..., 1]))
    v_cap = float(speed.max() * 0.9)
    ev_v = plan.evaluate(ROBOT, path, limits=plan.Limits.create(3, v_max=[np.inf, v_cap, np.inf]))
    np.testing.assert_array_equal(ev_v.feasible, ~(speed > v_cap).any(1))
    assert np.all(ev_v.costs.limit_violation[~np.asarray(ev_v.feasible)] > 0)


def test_robot_own_joint_limits_apply():
    path, dt = spiral_candidates(n=2)
    free = plan.evaluate(ROBOT, path, dt=dt)
    cap = float(np.median(np.asarray(free.q.p[..., 0])))
    limited = scara.Scara.create(150.0, 80.0, 50.0, limits={"theta1": (-10.0, cap)})
    assert not np.all(plan.evaluate(limited, path, dt=dt).feasible)


def test_best_mode_picks_the_feasible_lowest_cost_branch():
    path, dt = spiral_candidates(n=4)
    plus = plan.evaluate(ROBOT, path, mode=1, dt=dt)
    minus = plan.evaluate(ROBOT, path, mode=-1, dt=dt)
    best = plan.evaluate(ROBOT, path, mode="best", dt=dt)
    expected = np.where(plus.costs.total <= minus.costs.total, 0, 1)
    np.testing.assert_array_equal(best.branch, expected)
    # Now make mode +1 infeasible with a theta1 cap that only its solutions exceed.
    cap = float(np.asarray(minus.q.p[..., 0]).max()) + 1e-3
    assert np.asarray(plus.q.p[..., 0]).max() > cap
    limits = plan.Limits.create(3, q_max=[cap, np.inf, np.inf])
    chosen = plan.evaluate(ROBOT, path, limits=limits, mode="best", dt=dt)
    assert np.all(chosen.branch == 1) and np.all(chosen.feasible)
    np.testing.assert_array_equal(chosen.q.p, minus.q.p)


def test_best_ranking():
    path, dt = spiral_candidates(n=6)
    path_bad, _ = radial_paths(np.array([60.0]), np.array([200.0]), n_samples=33)
    both = Jet(
        *(
            np.concatenate([x, y])
            for x, y in zip(
                (path.p, path.v, path.a), (path_bad.p, path_bad.v, path_bad.a), strict=True
            )
        )
    )
    ev = plan.evaluate(ROBOT, both, dt=dt)
    idx, totals = plan.best(ev, 3)
    feasible_totals = np.asarray(ev.costs.total)[:6]
    np.testing.assert_array_equal(idx, np.argsort(feasible_totals)[:3])
    assert np.all(np.diff(totals) >= 0)
    assert 6 not in plan.best(ev, 10)[0]


def test_chunking_equals_one_call():
    path, dt = spiral_candidates(n=7)
    whole = plan.evaluate(ROBOT, path, dt=dt)
    chunked = plan.evaluate(ROBOT, path, dt=dt, chunk_size=3)
    for x, y in zip(jax.tree.leaves(whole), jax.tree.leaves(chunked), strict=True):
        assert_same_result(x, y)


def test_delta_evaluation_equals_per_point_ik():
    robot = delta.Delta.paper()
    t = np.linspace(0, 1, 21)
    p = np.stack([5 * np.cos(2 * t), 5 * np.sin(2 * t), -30 + 0 * t], -1)[None].repeat(3, 0)
    p[1, :, 2] -= 2.0
    p[2, 10:, 0] += 60.0  # leaves the workspace at sample 10
    ev = plan.evaluate(robot, Jet.of(p), mode="best")
    ref = delta.ik(robot, Jet.of(p[0]))
    np.testing.assert_array_equal(ev.q.p[0], ref.theta.p)
    assert list(np.asarray(ev.feasible)) == [True, True, False]
    assert ev.first_failure[2] == 10 and ev.status[2, 10] == Status.UNREACHABLE


def test_sharded_equals_unsharded():
    """Run evaluate on 2 forced CPU devices in a subprocess and compare with 1 device."""
    script = (
        "import jax, numpy as np, sys\n"
        "jax.config.update('jax_enable_x64', True)\n"
        "sys.path.insert(0, sys.argv[1])\n"
        "from test_plan import spiral_candidates, ROBOT\n"
        "from jaxkin import plan\n"
        "path, dt = spiral_candidates(n=5)\n"
        "ev = plan.evaluate(ROBOT, path, mode='best', dt=dt, chunk_size=4)\n"
        "leaves = [np.asarray(x) for x in jax.tree.leaves(ev)]\n"
        "np.savez(sys.argv[2], *leaves, n=jax.device_count())\n"
    )
    results = []
    for devices in (1, 2):
        out = Path(os.environ.get("TMPDIR", "/tmp")) / f"jaxkin_shard_{os.getpid()}_{devices}.npz"
        env = dict(os.environ, XLA_FLAGS=f"--xla_force_host_platform_device_count={devices}")
        proc = subprocess.run(
            [sys.executable, "-c", script, str(Path(__file__).parent), str(out)],
            env=env,
            capture_output=True,
            text=True,
            timeout=300,
        )
        assert proc.returncode == 0, proc.stderr[-3000:]
        with np.load(out) as data:
            assert int(data["n"]) == devices
            results.append([data[f"arr_{i}"] for i in range(len(data.files) - 1)])
        out.unlink()
    for x, y in zip(*results, strict=True):
        assert_same_result(x, y)


@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"robot": "scara"}, "robot must be"),
        ({"mode": 2}, "mode"),
        ({"mode": "out"}, "mode"),
        ({"path": np.zeros((4, 3))}, "path: expected shape"),
        ({"path": np.zeros((4, 1, 3))}, "T >= 2"),
        ({"dt": 0.0}, "dt"),
        ({"limits": "none"}, "limits"),
        ({"chunk_size": 0}, "chunk_size"),
    ],
)
def test_bad_input(kwargs, match):
    args = {"robot": ROBOT, "path": np.full((2, 5, 3), 90.0)}
    args.update(kwargs)
    with pytest.raises(ValueError, match=match):
        plan.evaluate(**args)


def test_limits_validation():
    with pytest.raises(ValueError, match="q_min must be <= q_max"):
        plan.Limits.create(3, q_min=[0, 0, 0], q_max=[1, -1, 1])
    with pytest.raises(ValueError, match="v_max"):
        plan.Limits.create(3, v_max=[-1, 1, 1])
    with pytest.raises(ValueError, match="broadcast"):
        plan.Limits.create(3, a_max=[1, 2])


def test_path_from_samples_reproduces_a_cubic_motion_exactly():
    t = np.arange(12) * 0.1
    coeffs = np.array([[1.0, -2.0, 0.5], [0.3, 0.0, 2.0], [-1.0, 0.7, 0.0], [0.2, 0.1, -0.4]])
    p = sum(coeffs[k] * t[:, None] ** k for k in range(4))
    v = sum(k * coeffs[k] * t[:, None] ** (k - 1) for k in range(1, 4))
    a = sum(k * (k - 1) * coeffs[k] * t[:, None] ** (k - 2) for k in range(2, 4))
    jet = plan.path_from_samples(p[None], 0.1)
    np.testing.assert_allclose(jet.v[0], v, rtol=1e-10, atol=1e-10)
    np.testing.assert_allclose(jet.a[0], a, rtol=1e-9, atol=1e-9)
    with pytest.raises(ValueError, match="dt"):
        plan.path_from_samples(p[None], 0.0)


def test_serial_arm_evaluation_equals_per_point_ik_and_fk():
    from jaxkin.serial import arms

    robot = arms.Anthropomorphic(0.3, 0.25, 0.2)
    t = np.linspace(0.0, 1.0, 25)
    p = np.stack([0.25 + 0.05 * t, 0.1 * np.sin(2 * t), 0.35 + 0.05 * t**2], -1)
    v = np.stack([0.05 + 0 * t, 0.2 * np.cos(2 * t), 0.1 * t], -1)
    a = np.stack([0 * t, -0.4 * np.sin(2 * t), 0.1 + 0 * t], -1)
    path = Jet.of(p[None], v[None], a[None])
    ev = plan.evaluate(robot, path, mode="best", dt=t[1] - t[0])
    assert bool(ev.feasible[0]) and 0 < float(ev.min_margin[0]) <= 1
    branch = robot.BRANCHES[int(ev.branch[0])]
    ref = arms.ik(robot, p).branch(branch)
    np.testing.assert_allclose(ev.q.p[0], ref.q, rtol=1e-12, atol=1e-14)
    # Joint rates reproduce the Cartesian rates through the FK (chain rule, by lift of fk).
    from jaxkin import lift

    back = lift(lambda q: arms.fk(robot, q)[..., :3, 3])(Jet(ev.q.p[0], ev.q.v[0], ev.q.a[0]))
    np.testing.assert_allclose(back.v, v, atol=1e-10)
    np.testing.assert_allclose(back.a, a, atol=1e-9)
