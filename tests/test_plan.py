"""Planner backend: every robot of the protocol, per-candidate equality with independent IK,
failures at the right sample, limits, branch choice, chunking and sharding.

Compilations dominate the cost of these tests, so the SCARA tests share one batch shape
(``N_SCARA`` candidates of ``T_SCARA`` samples) and every other robot keeps one shape.
"""

import math
import os
import subprocess
import sys
from pathlib import Path
from typing import Any, ClassVar

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxkin
from jaxkin import Jet, Status, delta, paths, plan, scara, serial, timing
from jaxkin._geometry import LENGTH, geometry, number
from jaxkin.jet import lift
from jaxkin.result import FKResult, IKResult
from jaxkin.robot import PLANAR_POINT, Robot
from tests.helpers import compilations, marked_slow, tree_allfinite
from tests.references import delta as delta_ref
from tests.references import scara as scara_ref

ROOT = Path(__file__).resolve().parents[1]
ROBOT = scara.Scara.paper()  # [Noriega, eq. 16] spiral robot: annulus [30, 130] mm
N_SCARA, T_SCARA = 5, 33


def radial_paths(radii_start, radii_end, n_samples=T_SCARA, z=60.0, angle=0.3):
    """Straight radial lines at a fixed angle, with exact (constant) velocity."""
    s = np.linspace(0.0, 1.0, n_samples)
    r = radii_start[:, None] + (radii_end - radii_start)[:, None] * s
    direction = np.array([np.cos(angle), np.sin(angle)])
    p = np.concatenate([r[..., None] * direction, np.full(r.shape + (1,), z)], axis=-1)
    dr = (radii_end - radii_start)[:, None] * np.ones_like(s)
    v = np.concatenate([dr[..., None] * direction, np.zeros(r.shape + (1,))], axis=-1)
    return Jet.of(p, v, np.zeros_like(p)), r


def spiral_candidates(n=N_SCARA, n_samples=T_SCARA):
    """Scaled copies of the spiral of [Noriega, eq. 16], exact derivatives."""
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


def scara_reference(path, branch):
    """Joint trajectories of the SCARA from the NumPy reference of [Noriega, eqs. 1-15]."""
    p, v, a = (np.asarray(x) for x in (path.p, path.v, path.a))
    return scara_ref.ik_numpy(p, v, a, 150.0, 80.0, 50.0, mode=branch)


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


# ------------------------------------------------------------------------------------- SCARA


@pytest.mark.parametrize("branch", [1, -1])
def test_joint_values_equal_the_reference_ik(branch):
    """Every sample's joints and rates equal the NumPy reference IK [Noriega, eqs. 1-15]
    (the same formulas written independently: 1e-12 relative)."""
    path, dt = spiral_candidates()
    ev = plan.evaluate(ROBOT, path, branch=branch, dt=dt)
    q, qd, qdd = scara_reference(path, branch)
    np.testing.assert_allclose(ev.q.p, q, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(ev.q.v, qd, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(ev.q.a, qdd, rtol=1e-12, atol=1e-12)
    assert np.all(ev.status == Status.OK)
    assert np.all(ev.feasible) and np.all(ev.first_failure == -1)
    assert np.all(ev.branch == [1, -1].index(branch)) and ev.branches == (1, -1)
    assert np.all((ev.min_margin > 0) & (ev.min_margin <= 1))


def test_costs_against_direct_numpy_formulas():
    """Each joint's terms in its own units over its scale: speeds over a finite v_max, else
    over the joint's unit (1 rad; the robot's reach 130 mm for the column), accelerations
    likewise with a_max, times the user's weights; limit excess over the same scales."""
    path, dt = spiral_candidates()
    v_max, a_max = np.array([np.inf, 0.9, 60.0]), np.array([1.0, np.inf, np.inf])
    weights = np.array([1.0, 2.0, 0.5])
    limits = plan.Limits.create(3, v_max=v_max, a_max=a_max)
    ev = plan.evaluate(ROBOT, path, limits, dt=dt, weights=weights)
    q = [np.asarray(x) for x in (ev.q.p, ev.q.v, ev.q.a)]
    unit = np.array([1.0, 1.0, 130.0])  # rad, rad, the SCARA's reach l_ab + l_bc (mm)
    speed = np.where(np.isfinite(v_max), v_max, unit) / weights
    accel = np.where(np.isfinite(a_max), a_max, unit) / weights
    c = ev.costs
    steps = np.diff(q[0], axis=1) * weights / unit
    np.testing.assert_allclose(c.path_length, np.linalg.norm(steps, axis=-1).sum(1), rtol=1e-12)
    v, a = q[1] / speed, q[2] / accel
    np.testing.assert_allclose(c.peak_speed, np.abs(v).max(axis=(1, 2)), rtol=1e-14)
    np.testing.assert_allclose(c.integrated_speed, (v**2).sum((1, 2)) * dt, rtol=1e-12)
    np.testing.assert_allclose(c.peak_acceleration, np.abs(a).max(axis=(1, 2)), rtol=1e-14)
    np.testing.assert_allclose(c.integrated_acceleration, (a**2).sum((1, 2)) * dt, rtol=1e-12)
    jerk = np.diff(q[2], axis=1) / dt / accel
    np.testing.assert_allclose(c.peak_jerk, np.abs(jerk).max(axis=(1, 2)), rtol=1e-12)
    np.testing.assert_allclose(c.integrated_jerk, (jerk**2).sum((1, 2)) * dt, rtol=1e-12)
    excess = np.maximum(np.abs(q[1]) - v_max, 0.0) / speed
    excess += np.maximum(np.abs(q[2]) - a_max, 0.0) / accel
    np.testing.assert_allclose(c.limit_violation, excess.sum((1, 2)), rtol=1e-12, atol=1e-300)
    assert np.any(c.limit_violation > 0)
    feasible = np.asarray(ev.feasible)
    np.testing.assert_array_equal(c.total[feasible], c.integrated_acceleration[feasible])
    assert np.all(np.isinf(np.asarray(c.total)[~feasible]))


def test_unreachable_and_singular_samples_fail_at_the_right_index():
    # Radii from 60 up to 150 (outer reach 130), one ending exactly on the boundary, and two
    # inside; plus one starting below the inner reach 30.
    start = np.array([60.0, 60.0, 60.0, 20.0, 60.0])
    path, r = radial_paths(start, np.array([150.0, 130.0, 120.0, 60.0, 100.0]))
    ev = plan.evaluate(ROBOT, path, dt=1 / (T_SCARA - 1))  # s in [0, 1]: the rates' time
    expected_unreachable = int(np.argmax(r[0] > 130.0))
    assert ev.first_failure[0] == expected_unreachable
    assert ev.status[0, expected_unreachable] in (Status.UNREACHABLE, Status.SINGULAR_EXTENDED)
    assert ev.first_failure[1] == r.shape[1] - 1  # r = 130 exactly at the last sample
    assert ev.status[1, -1] == Status.SINGULAR_EXTENDED
    assert ev.first_failure[3] == 0 and ev.status[3, 0] == Status.UNREACHABLE  # r = 20 < 30
    assert list(np.asarray(ev.feasible)) == [False, False, True, False, True]
    assert np.isinf(ev.costs.total[0]) and np.isfinite(ev.costs.total[2])
    assert tree_allfinite(ev.q)


def test_position_and_velocity_limits_are_enforced():
    path, dt = spiral_candidates()
    free = plan.evaluate(ROBOT, path, dt=dt)
    theta1 = np.asarray(free.q.p[..., 0])
    cap = float(np.median(theta1.max(1)))  # some candidates pass it, others stay below
    # a range under one turn: no whole turn brings a candidate above the cap back inside
    limits = plan.Limits.create(3, q_min=[cap - 6.0, -np.inf, -np.inf], q_max=[cap, np.inf, np.inf])
    ev = plan.evaluate(ROBOT, path, limits=limits, dt=dt)
    expected = np.where((theta1 > cap).any(1), np.argmax(theta1 > cap, axis=1), -1)
    assert np.any(expected >= 0) and np.any(expected == -1)
    np.testing.assert_array_equal(ev.first_failure, expected)
    failing = int(np.flatnonzero(expected >= 0)[0])
    assert ev.status[failing, expected[failing]] == Status.OUT_OF_LIMITS
    speed = np.abs(np.asarray(free.q.v[..., 1]))
    v_cap = float(speed.max() * 0.9)
    v_limits = plan.Limits.create(3, v_max=[np.inf, v_cap, np.inf])
    ev_v = plan.evaluate(ROBOT, path, limits=v_limits, dt=dt)
    np.testing.assert_array_equal(ev_v.feasible, ~(speed > v_cap).any(1))
    assert np.all(ev_v.costs.limit_violation[~np.asarray(ev_v.feasible)] > 0)


def test_limit_violations_name_the_joint_and_the_limit():
    """Joint-space lines with known rates: candidate 0 within every bound, 1 passes theta1's
    speed bound from the start, 2 leaves l3's range at its fourth sample, 3 is DISCONTINUOUS
    (no limit named); values and bounds are the lines' own numbers."""
    t = np.linspace(0.0, 1.0, 11)[:, None]
    start = np.array([0.3, 1.0, 60.0])
    rates = np.array([[0.2, -0.1, 5.0], [0.4, -0.1, 5.0], [0.2, -0.1, 50.0], [0.2, -0.1, 5.0]])
    q = start + t * rates[:, None, :]  # (4, 11, 3)
    q[3, 6:, 1] += 1.0  # a jump no rate explains
    v = np.broadcast_to(rates[:, None, :], q.shape)
    path = paths.Path.from_jet(Jet.of(q, v, np.zeros_like(q)), 0.1, "joint")
    limits = plan.Limits.create(3, q_max=[np.inf, np.inf, 80.0], v_max=[0.3, 1.0, 100.0])
    ev = plan.evaluate(ROBOT, path, limits=limits)
    np.testing.assert_array_equal(ev.first_failure, [-1, 0, 5, 6])
    assert ev.status[3, 6] == Status.DISCONTINUOUS
    found = plan.limit_violations(ev)
    assert found.joint.tolist() == [-1, 0, 2, -1]
    assert found.joint_name.tolist() == ["", "theta1", "l3", ""]
    assert found.limit.tolist() == ["", "v_max", "q_max", ""]
    np.testing.assert_allclose(found.value[1:3], [0.4, 60.0 + 50.0 * 0.5], rtol=1e-12)
    np.testing.assert_array_equal(found.bound[1:3], [0.3, 80.0])
    assert np.isnan(found.value[[0, 3]]).all() and found.sample.tolist() == [-1, 0, 5, 6]
    assert found.message(0) == "" and found.message(3) == ""
    assert found.message(1, ("rad", "rad", "mm")) == "theta1 |q_dot| 0.4 rad/s > v_max 0.3 rad/s"
    assert found.message(2) == "l3 q 85 > q_max 80"
    none = plan.limit_violations(plan.evaluate(ROBOT, path[:0], limits=limits))
    assert none.joint.shape == none.value.shape == (0,)


def test_robot_own_joint_limits_apply():
    """A theta1 range on the robot fails the same samples as the same cap given to the
    planner (both compared with the unlimited joints)."""
    path, dt = spiral_candidates()
    free = plan.evaluate(ROBOT, path, dt=dt)
    theta1 = np.asarray(free.q.p[..., 0])
    cap = float(np.median(theta1.max(1)))
    # a range under one turn: no whole turn brings a candidate above the cap back inside
    limited = scara.Scara(150.0, 80.0, 50.0, limits={"theta1": (cap - 6.0, cap)})
    ev = plan.evaluate(limited, path, dt=dt)
    expected = np.where((theta1 > cap).any(1), np.argmax(theta1 > cap, axis=1), -1)
    np.testing.assert_array_equal(ev.first_failure, expected)
    assert not np.all(ev.feasible) and np.any(ev.feasible)


# ---------------------------------------------------------------------------- continuity


def test_unwrapped_equals_numpy_unwrap():
    """Revolute joints come back as ``np.unwrap`` along the samples (the first kept); a
    prismatic joint is left alone even where it steps by more than pi."""
    rng = np.random.default_rng(3)
    true = np.cumsum(rng.uniform(-3.0, 3.0, (4, 30, 3)), axis=1)  # steps below pi
    raw = np.concatenate([wrap(true[..., :2]), true[..., 2:]], -1)
    got = np.asarray(plan.unwrapped(raw, np.array([True, True, False])))
    np.testing.assert_allclose(got[..., :2], np.unwrap(raw[..., :2], axis=1), rtol=0, atol=1e-12)
    np.testing.assert_array_equal(got[..., 2], raw[..., 2])
    np.testing.assert_allclose(got[..., :2] - got[:, :1, :2], true[..., :2] - true[:, :1, :2],
                               rtol=0, atol=1e-12)  # fmt: skip


def test_within_turns_moves_a_candidate_into_its_range_by_whole_turns():
    """Hand cases (one joint, limits [-pi, pi] unless stated): a range above pi comes back by
    one turn; a range that fits stays; one wider than the limits, a prismatic joint and an
    unsolved sample's placeholder do not move anything; the range [-10, 0.3] takes a range
    [0.1, 0.5] one turn down (the shift nearest zero that fits)."""
    turn = 2 * np.pi

    def moved(q, lower=-np.pi, upper=np.pi, revolute=True, solved=None):
        q = np.asarray(q, float)[None, :, None]
        solved = np.ones(q.shape[:2], bool) if solved is None else np.asarray(solved)[None]
        out = plan.within_turns(
            q, np.array([revolute]), solved, np.array([lower]), np.array([upper])
        )
        return np.asarray(out)[0, :, 0]

    np.testing.assert_allclose(moved([5.9, 6.4]), [5.9 - turn, 6.4 - turn], rtol=0, atol=1e-15)
    np.testing.assert_array_equal(moved([-3.0, 3.0]), [-3.0, 3.0])
    np.testing.assert_array_equal(moved([-3.0, 3.5]), [-3.0, 3.5])  # 6.5 rad: never fits
    np.testing.assert_array_equal(moved([5.9, 6.4], revolute=False), [5.9, 6.4])
    unsolved = moved([5.9, 6.4, 90.0], solved=[True, True, False])
    np.testing.assert_allclose(unsolved, np.array([5.9, 6.4, 90.0]) - turn, rtol=0, atol=1e-13)
    np.testing.assert_allclose(moved([0.1, 0.5], -10.0, 0.3), [0.1 - turn, 0.5 - turn], atol=1e-15)


@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test_unexplained_steps_are_exactly_the_jumps(dtype):
    """Smooth sinusoids with exact rates (steps of up to 0.75 rad) are continuous; a jump on
    one joint's positions is caught at its step, and only there, when it exceeds the stated
    tolerance (``STEP_RTOL`` of the rates' reach, computed here by hand) and not below it; a
    joint at rest with round-off noise of 1e-3 sqrt(eps) is not a jump."""
    dt, t = 0.05, np.arange(40)[:, None] * 0.05
    amp, w = np.array([1.0, 0.3, 2.0]), np.array([3.0, 7.0, 7.5])
    p = amp * np.sin(w * t + 0.4)
    v, a = amp * w * np.cos(w * t + 0.4), -amp * w * w * np.sin(w * t + 0.4)

    def steps(p, v=v, a=a):
        q = Jet(*(np.asarray(x, dtype) for x in (p, v, a)))
        return np.asarray(plan.unexplained_steps(q, dt, np.ones(3, dtype)))

    assert not steps(p).any()
    reach = (
        dt * (abs(v[16, 1]) + abs(v[17, 1])) / 2 + dt * dt * (abs(a[16, 1]) + abs(a[17, 1])) / 12
    )
    for factor, caught in ((0.8, []), (1.2, [16])):
        jumped = p.copy()
        jumped[17:, 1] += factor * plan.STEP_RTOL * reach
        np.testing.assert_array_equal(np.flatnonzero(steps(jumped)), caught)
    still = np.concatenate([p[:, :2], 0.5 + 1e-3 * np.sqrt(np.finfo(dtype).eps)
                            * np.sin(100 * t)], -1)  # fmt: skip
    assert not steps(still, v * [1, 1, 0], a * [1, 1, 0]).any()


def arcs_behind_the_base(n_samples=T_SCARA):
    """``N_SCARA`` arcs of radii 70..110 mm through the -x axis (theta1 crosses pi), at a
    constant angular speed, exact rates."""
    dt = 0.05
    t = np.arange(n_samples) * dt
    r = np.linspace(70.0, 110.0, N_SCARA)[:, None, None]
    w = 2.4 / t[-1]  # 2.4 rad centred on pi: theta1 crosses pi on either branch
    angle = (np.pi - 1.2 + w * t)[None, :, None]
    c, s_ = np.cos(angle), np.sin(angle)
    z = np.full((N_SCARA, n_samples, 1), 60.0)
    p = np.concatenate([r * c, r * s_, z], -1)
    v = np.concatenate([-r * w * s_, r * w * c, 0 * z], -1)
    a = np.concatenate([-r * w * w * c, -r * w * w * s_, 0 * z], -1)
    return Jet.of(p, v, a), dt


@pytest.mark.parametrize("branch", [1, -1])
def test_joints_of_an_arc_behind_the_base_are_continuous(branch):
    """theta1 wraps from pi to -pi in the reference IK; the planner's joints are its
    ``np.unwrap`` (continuous), and the candidates are feasible."""
    path, dt = arcs_behind_the_base()
    raw = scara_reference(path, branch)[0]
    assert np.abs(np.diff(raw[..., 0], axis=1)).max() > np.pi  # the wrap is there
    ev = plan.evaluate(ROBOT, path, branch=branch, dt=dt)
    np.testing.assert_allclose(ev.q.p, np.unwrap(raw, axis=1), rtol=0, atol=1e-12)
    assert np.all(ev.status == Status.OK) and np.all(ev.feasible)
    assert np.abs(np.diff(np.asarray(ev.q.p), axis=1)).max() < 0.1


@geometry
class ElbowSwitcher(Robot):
    """A planar 2R arm (links ``l1``, ``0.6 l1``) whose IK takes the elbow down (``q2 < 0``)
    where the target's ``x < 0.5 l1`` and up beyond: an IK that switches solution mid-path.
    Positions, rates and the FK are exact on either side."""

    l1: Any = number(LENGTH, default=1.0)

    target: ClassVar = PLANAR_POINT
    branches: ClassVar = ("switching",)

    @property
    def joint_names(self):
        return ("q1", "q2")

    @property
    def joint_types(self):
        return "RR"

    def length_scale(self):
        return 1.6 * self.l1

    def ik_kernel(self, target, branch, options, rates):
        l1, l2 = self.l1, 0.6 * self.l1

        def solve(x):
            c = (jnp.sum(x * x, -1) - l1 * l1 - l2 * l2) / (2 * l1 * l2)
            elbow = jnp.where(x[..., 0] < 0.5 * l1, -1.0, 1.0)
            q2 = jnp.arctan2(elbow * jnp.sqrt(1 - c * c), c)
            q1 = jnp.arctan2(x[..., 1], x[..., 0])
            q1 = q1 - jnp.arctan2(l2 * jnp.sin(q2), l1 + l2 * jnp.cos(q2))
            return jnp.stack([q1, q2], -1)

        q = lift(solve)(target)
        ok = jnp.zeros(q.p.shape[:-1], jnp.int8)
        return IKResult(q, ok, jnp.ones(q.p.shape[:-1], q.p.dtype))

    def fk_kernel(self, q, options, rates):
        l1, l2 = self.l1, 0.6 * self.l1
        x = l1 * jnp.cos(q.p[..., 0]) + l2 * jnp.cos(q.p[..., 0] + q.p[..., 1])
        y = l1 * jnp.sin(q.p[..., 0]) + l2 * jnp.sin(q.p[..., 0] + q.p[..., 1])
        return FKResult(Jet.constant(jnp.stack([x, y], -1)), jnp.zeros(x.shape, jnp.int8))


def test_a_solution_switch_mid_path_is_discontinuous():
    """Straight lines at y = 0.8: the one crossing x = 0.5 switches elbow at its first sample
    with x >= 0.5, which is DISCONTINUOUS (the candidate infeasible there); the one staying
    left of it, and the same line given at rest (no rates to explain the steps), are not."""
    dt, t = 0.1, np.linspace(0.0, 1.0, 13)[:, None]
    starts, ends = np.array([[0.2, 0.8], [0.0, 0.8]]), np.array([[0.9, 0.8], [0.45, 0.8]])
    points = starts[:, None] + t * (ends - starts)[:, None]
    ev = plan.evaluate(ElbowSwitcher(), paths.path_from_samples(points, dt), dt=dt)
    switch = int(np.argmax(points[0, :, 0] >= 0.5))
    expected = np.full(points.shape[:2], Status.OK)
    expected[0, switch] = Status.DISCONTINUOUS
    np.testing.assert_array_equal(ev.status, expected)
    np.testing.assert_array_equal(ev.feasible, [False, True])
    np.testing.assert_array_equal(ev.first_failure, [switch, -1])
    assert np.isinf(ev.costs.total[0]) and np.isfinite(ev.costs.total[1])
    at_rest = plan.evaluate(ElbowSwitcher(), Jet.constant(points), dt=dt)  # explicitly at rest
    assert np.all(at_rest.status == Status.OK) and np.all(at_rest.feasible)


# -------------------------------------------------------------------- the robot's own limits


def test_robot_own_velocity_limits_apply_and_intersect_with_the_users():
    """A theta2 speed bound on the robot fails the same candidates as the same bound given
    to the planner; user limits intersect with the robot's (the tighter bound wins)."""
    path, dt = spiral_candidates()
    free = plan.evaluate(ROBOT, path, dt=dt)
    speed = np.abs(np.asarray(free.q.v[..., 1]))
    v_cap = float(np.median(speed.max(1)))
    expected = ~(speed > v_cap).any(1)
    assert np.any(expected) and not np.all(expected)
    own = jaxkin.JointLimits(np.full(3, -np.inf), np.full(3, np.inf), [np.inf, v_cap, np.inf])
    limited = scara.Scara(150.0, 80.0, 50.0, limits=own)
    ev = plan.evaluate(limited, path, dt=dt)
    np.testing.assert_array_equal(ev.feasible, expected)
    first = np.where(expected, -1, np.argmax(speed > v_cap, axis=1))
    np.testing.assert_array_equal(ev.first_failure, first)
    looser = plan.Limits.create(3, v_max=[np.inf, 2 * v_cap, 1e9])
    np.testing.assert_array_equal(plan.evaluate(limited, path, looser, dt=dt).feasible, expected)
    tighter = plan.Limits.create(3, v_max=[np.inf, 0.0, np.inf])
    assert not np.any(plan.evaluate(limited, path, tighter, dt=dt).feasible)
    limits = plan.robot_limits(limited, looser)
    np.testing.assert_array_equal(limits.v_max, [np.inf, v_cap, 1e9])
    np.testing.assert_array_equal(limits.a_max, np.inf)


def test_a_chains_velocity_is_its_own_limit():
    chain = serial.Chain.create(
        [[0, 0, 1, 0, 0, 0], [0, 0, 1, 0, -1, 0]], np.eye(4), velocity=[0.84, np.inf]
    )
    own = chain.joint_limits()
    np.testing.assert_array_equal(own.velocity, [0.84, np.inf])
    np.testing.assert_array_equal(own.acceleration, [np.inf, np.inf])
    np.testing.assert_array_equal(plan.robot_limits(chain, None).v_max, [0.84, np.inf])
    with pytest.raises(ValueError, match="JointLimits.velocity"):
        jaxkin.JointLimits([0.0, 0.0], [1.0, 1.0], velocity=[-1.0, 1.0])
    with pytest.raises(ValueError, match="JointLimits.acceleration"):
        jaxkin.JointLimits([0.0, 0.0], [1.0, 1.0], acceleration=[1.0, 1.0, 1.0])


def test_best_branch_picks_the_feasible_lowest_cost_branch():
    path, dt = spiral_candidates()
    plus = plan.evaluate(ROBOT, path, branch=1, dt=dt)
    minus = plan.evaluate(ROBOT, path, branch=-1, dt=dt)
    best = plan.evaluate(ROBOT, path, branch="best", dt=dt)
    expected = np.where(plus.costs.total <= minus.costs.total, 0, 1)
    np.testing.assert_array_equal(best.branch, expected)
    minimum = np.minimum(plus.costs.total, minus.costs.total)  # another program: last bits
    np.testing.assert_allclose(best.costs.total, minimum, rtol=1e-13, atol=0)
    # Now make branch +1 infeasible with a theta1 cap that only its solutions exceed.
    cap = float(np.asarray(minus.q.p[..., 0]).max()) + 1e-3
    assert np.asarray(plus.q.p[..., 0]).max() > cap
    low = float(np.asarray(minus.q.p[..., 0]).min()) - 1e-3  # no whole turn fits +1 inside
    limits = plan.Limits.create(3, q_min=[low, -np.inf, -np.inf], q_max=[cap, np.inf, np.inf])
    chosen = plan.evaluate(ROBOT, path, limits=limits, branch="best", dt=dt)
    assert np.all(chosen.branch == 1) and np.all(chosen.feasible)
    np.testing.assert_array_equal(chosen.q.p, minus.q.p)


def test_best_ranking():
    path, dt = spiral_candidates(n=N_SCARA - 1)
    path_bad, _ = radial_paths(np.array([60.0]), np.array([200.0]))
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
    feasible_totals = np.asarray(ev.costs.total)[: N_SCARA - 1]
    np.testing.assert_array_equal(idx, np.argsort(feasible_totals)[:3])
    np.testing.assert_array_equal(totals, np.sort(feasible_totals)[:3])
    assert N_SCARA - 1 not in plan.best(ev, 10)[0] and len(plan.best(ev, 10)[0]) == N_SCARA - 1


def test_chunking_equals_one_call():
    path, dt = spiral_candidates()
    whole = plan.evaluate(ROBOT, path, dt=dt)
    chunked = plan.evaluate(ROBOT, path, dt=dt, chunk_size=1)
    for x, y in zip(jax.tree.leaves(whole), jax.tree.leaves(chunked), strict=True):
        assert_same_result(x, y)


@pytest.mark.slow
def test_sharded_equals_unsharded(tmp_path):
    """Evaluate on 2 forced CPU devices in a subprocess, in overlapping chunks (5 candidates
    padded to 6, chunks of 4 starting at 0 and 2), and compare with one call in this process
    (one device)."""
    if jax.device_count() != 1:
        pytest.skip("this process must have one device to be the unsharded reference")
    out = tmp_path / "sharded.npz"
    script = (
        "import sys\n"
        "import jax\n"
        "import numpy as np\n"
        "jax.config.update('jax_enable_x64', True)\n"
        "from jaxkin import plan\n"
        "from tests.test_plan import ROBOT, spiral_candidates\n"
        "path, dt = spiral_candidates()\n"
        "ev = plan.evaluate(ROBOT, path, branch='best', dt=dt, chunk_size=4)\n"
        "leaves = [np.asarray(x) for x in jax.tree.leaves(ev)]\n"
        "np.savez(sys.argv[1], *leaves, n=jax.device_count())\n"
    )
    env = dict(os.environ, XLA_FLAGS="--xla_force_host_platform_device_count=2")
    proc = subprocess.run(
        [sys.executable, "-c", script, str(out)],
        cwd=ROOT,
        env=env,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert proc.returncode == 0, proc.stderr[-3000:]
    path, dt = spiral_candidates()
    whole = jax.tree.leaves(plan.evaluate(ROBOT, path, branch="best", dt=dt))
    with np.load(out) as data:
        assert int(data["n"]) == 2
        sharded = [data[f"arr_{i}"] for i in range(len(data.files) - 1)]
    assert len(sharded) == len(whole)
    for x, y in zip(sharded, whole, strict=True):
        assert_same_result(x, y)


# ------------------------------------------------------------------------------- other robots


def delta_circles():
    """Three circles of radius 5 cm at rest, at depths 30, 32 and 30 cm (paper Delta)."""
    t = np.linspace(0, 1, 21)
    p = np.stack([5 * np.cos(2 * t), 5 * np.sin(2 * t), -30 + 0 * t], -1)[None].repeat(3, 0)
    p[1, :, 2] -= 2.0
    return p


# Forward kinematics written out by hand, in NumPy, on (position, velocity, acceleration)
# triples: the product and chain rules of the first two time derivatives.
def _mul(a, b):
    return (a[0] * b[0], a[1] * b[0] + a[0] * b[1], a[2] * b[0] + 2 * a[1] * b[1] + a[0] * b[2])


def _add(*terms):
    return tuple(sum(t[k] for t in terms) for k in range(3))


def _scaled(c, a):
    return tuple(c * x for x in a)


def _cos_sin(angle):
    c, s = np.cos(angle[0]), np.sin(angle[0])
    w, al = angle[1], angle[2]
    return (c, -s * w, -c * w * w - s * al), (s, c * w, -s * w * w + c * al)


def _joints(q):
    q = [np.asarray(x) for x in (q.p, q.v, q.a)]
    return [tuple(x[..., k] for x in q) for k in range(q[0].shape[-1])]


def _planar_two_link(q1, q2, l1, l2):
    """Tip ``l1 (cos q1, sin q1) + l2 (cos(q1 + q2), sin(q1 + q2))`` and ``cos, sin`` of the
    end angle."""
    (c1, s1), (c12, s12) = _cos_sin(q1), _cos_sin(_add(q1, q2))
    x = _add(_scaled(l1, c1), _scaled(l2, c12))
    y = _add(_scaled(l1, s1), _scaled(l2, s12))
    return x, y, c12, s12


def forward(name, q):
    """Targets at joints ``q`` (Jet ``(..., n)``) as a Jet, written from each robot's geometry:
    SCARA [Noriega, eqs. 14-15: C = B + l_bc (cos(theta1 - theta2), sin(...)), z = l_oa - l3];
    anthropomorphic [Lopez-Villagomez, eqs. 2-6]: the wrist at radius l2 cos q2 + l3 cos(q2 +
    q3) and height l1 + l2 sin q2 + l3 sin(q2 + q3); planar 2R and its DH chain [Pineiro]."""
    j = _joints(q)
    if name == "scara":
        x, y, _, _ = _planar_two_link(j[0], _scaled(-1.0, j[1]), 80.0, 50.0)
        z = (150.0 - j[2][0], -j[2][1], -j[2][2])
        out = [x, y, z]
    elif name == "anthropomorphic":
        radius, height, _, _ = _planar_two_link(j[1], j[2], 0.25, 0.2)
        c1, s1 = _cos_sin(j[0])
        out = [_mul(radius, c1), _mul(radius, s1), _add(height, (0.3, 0.0, 0.0))]
    elif name == "planar-2r":
        x, y, _, _ = _planar_two_link(j[0], j[1], 1.0, 0.6)
        out = [x, y]
    else:  # the DH chain of the planar 2R: Rz(q1 + q2) and the tip, as 4x4 poses
        x, y, c, s = _planar_two_link(j[0], j[1], 1.0, 0.6)
        zero = np.zeros_like(x[0])
        one = (zero + 1.0, zero, zero)
        zeros = (zero, zero, zero)
        rows = [
            [c, _scaled(-1.0, s), zeros, x],
            [s, c, zeros, y],
            [zeros, zeros, one, zeros],
            [zeros, zeros, zeros, one],
        ]
        return Jet.of(
            *(np.stack([np.stack([e[k] for e in r], -1) for r in rows], -2) for k in range(3))
        )
    return Jet.of(*(np.stack([c[k] for c in out], -1) for k in range(3)))


JOINT_PATH_DT = 1 / 24  # the time between samples of ``joint_path``


def joint_path(q0, dq, n_samples=25):
    """One candidate's joint trajectory ``q0 + dq sin(s)``, ``s`` in [0, 1] the time, exact
    rates."""
    s = np.linspace(0.0, 1.0, n_samples)[:, None]
    q0, dq = np.asarray(q0, float), np.asarray(dq, float)
    return Jet.of(q0 + dq * np.sin(s), dq * np.cos(s) + 0 * s, -dq * np.sin(s))[None]


def wrap(angle):
    return (np.asarray(angle) + np.pi) % (2 * np.pi) - np.pi


ROBOTS = {
    "scara": ROBOT,
    "delta": delta.Delta.paper(),
    "anthropomorphic": serial.Anthropomorphic(0.3, 0.25, 0.2),
    "planar-2r": serial.Planar2R(1.0, 0.6),
    "puma560": serial.Puma560(),
    "dh-table": serial.from_dh(serial.DHTable([1.0, 0.6], [0.0, 0.0], [0.0, 0.0])),  # 2R chain
}
JOINT_PATHS = {  # each on the default branch
    "anthropomorphic": ([0.4, 0.5, -0.9], [0.2, 0.1, 0.3]),  # front_up: the elbow above
    "planar-2r": ([0.3, -1.2], [0.4, 0.5]),  # elbow_up: q2 <= 0
    "puma560": ([0.3, 1.3, 3.0, 0.4, 1.2, 0.3], [0.1, 0.1, -0.1, 0.2, 0.1, 0.2]),  # front_up_noflip
    "dh-table": ([0.3, 0.8], [0.4, 0.5]),
}


def robot_case(name):
    """``(robot, path, expected, dt)``: a path inside the workspace, the joints it comes from
    on the default branch, found independently of the robot's IK (a Jet), and its time step."""
    robot = ROBOTS[name]
    if name == "scara":
        path, dt = spiral_candidates()
        return robot, path, Jet.of(*scara_reference(path, 1)), dt
    if name == "delta":
        p = delta_circles()
        theta = delta_ref.ik_numpy(p.reshape(-1, 3)).reshape(p.shape)  # elbow out [Cardona]
        return robot, Jet.of(p), Jet.of(theta), 1.0
    q = joint_path(*JOINT_PATHS[name])
    if name == "puma560":  # poses as Jets of 4x4 matrices from the arm's own FK
        return robot, jaxkin.fk(robot, q).x, q, JOINT_PATH_DT
    return robot, forward(name, q), q, JOINT_PATH_DT


def assert_maps_to(name, robot, q, path):
    """Joints ``q`` reach the targets of ``path`` (positions and rates)."""
    if name == "delta":  # at rest: the closed-form NumPy FK of the positions
        p = np.asarray(q.p).reshape(-1, 3)
        back = delta_ref.fk_closed_form_numpy(p).reshape(q.p.shape)
        np.testing.assert_allclose(back, path.p, atol=1e-10)
        np.testing.assert_array_equal(q.v, 0.0)
        return
    if name == "puma560":  # a round trip through the FK that made the path
        back = jaxkin.fk(robot, q).x
    else:
        back = forward(name, q)
    scale = float(np.abs(path.p).max())
    for x, y in zip((back.p, back.v, back.a), (path.p, path.v, path.a), strict=True):
        np.testing.assert_allclose(x, y, rtol=0, atol=1e-9 * scale)


def test_delta_evaluation_equals_the_reference_ik():
    """Joints equal the NumPy elbow-out reference [Cardona, eq. 5]; a candidate leaving the
    workspace fails at the sample where it leaves."""
    robot = delta.Delta.paper()
    p = delta_circles()
    p[2, 10:, 0] += 60.0  # leaves the workspace at sample 10
    ev = plan.evaluate(robot, Jet.constant(p), branch="best", dt=1.0)  # a path at rest
    assert list(np.asarray(ev.feasible)) == [True, True, False]
    assert ev.first_failure[2] == 10 and ev.status[2, 10] == Status.UNREACHABLE
    assert np.all(np.asarray(ev.branch)[:2] == 0)  # at rest both cost 0: the first wins
    reference = delta_ref.ik_numpy(p[:2].reshape(-1, 3)).reshape(2, -1, 3)
    np.testing.assert_allclose(ev.q.p[:2], reference, rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize("name", marked_slow(ROBOTS, ["dh-table"]))
def test_every_robot_with_default_arguments(name):
    """``evaluate(robot, path)`` returns, on the default branch, the joints the path was made
    from (rates included, 1e-9 of their scale) and they reach the path; zero candidates give
    empty arrays of the right trailing shapes."""
    robot, path, expected, dt = robot_case(name)
    n, t = path.shape[:2]
    ev = plan.evaluate(robot, path, dt=dt)
    assert ev.q.shape == (n, t, robot.n_joints) and ev.status.shape == (n, t)
    assert np.all(ev.status == Status.OK) and np.all(ev.feasible)
    assert np.all(ev.first_failure == -1) and np.all(ev.branch == 0)
    assert ev.branches == robot.branches
    assert np.all((ev.min_margin > 0) & (ev.min_margin <= 1))
    got = [np.asarray(x) for x in (ev.q.p, ev.q.v, ev.q.a)]
    if name == "dh-table":  # Newton's angles are defined modulo 2 pi
        got[0] = expected.p + wrap(got[0] - expected.p)
    scale = float(np.abs(expected.p).max())
    for x, y in zip(got, (expected.p, expected.v, expected.a), strict=True):
        np.testing.assert_allclose(x, y, rtol=0, atol=1e-9 * scale)
    assert_maps_to(name, robot, ev.q, path)

    empty = plan.evaluate(robot, path[:0], dt=dt)
    assert empty.q.shape == (0, t, robot.n_joints) and empty.status.shape == (0, t)
    for leaf in (empty.feasible, empty.first_failure, empty.min_margin, empty.branch):
        assert leaf.shape == (0,)
    assert empty.costs.total.shape == (0,) and plan.best(empty, 1)[0].size == 0


@pytest.mark.slow
@pytest.mark.parametrize("name", list(ROBOTS))
def test_every_robot_best_branch(name):
    """``branch="best"`` keeps, per candidate, a branch of no greater cost than the default
    branch whose joints reach the path (positions and rates)."""
    robot, path, _, dt = robot_case(name)
    default = plan.evaluate(robot, path, dt=dt)
    best = plan.evaluate(robot, path, branch="best", dt=dt)
    assert best.q.shape == default.q.shape and best.branches == robot.branches
    # another compiled program (every branch at once) may round the same cost in its last bits
    assert np.all(best.feasible) and np.all(best.costs.total <= default.costs.total * (1 + 1e-13))
    assert np.all((best.branch >= 0) & (best.branch < len(robot.branches)))
    assert_maps_to(name, robot, best.q, path)


# ------------------------------------------------------------------------------- bad input


@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"robot": "scara"}, "robot must be"),
        ({"branch": 2}, "branch"),
        ({"branch": "out"}, "branch"),
        ({"path": Jet.constant(np.zeros((4, 3)))}, "path: expected shape"),
        ({"path": Jet.constant(np.zeros((4, 1, 3)))}, "T >= 2"),
        ({"path": Jet.constant(np.zeros((2, 5, 2)))}, r"path: expected shape \(N, T, 3\)"),
        (
            {"path": np.full((2, 5, 3), 90.0)},
            r"no rates.*paths\.path_from_samples\(positions, dt\)",
        ),
        ({"dt": None}, "dt is required"),
        (
            {"path": paths.path_from_samples(np.full((2, 5, 3), 90.0), 0.1), "dt": 0.2},
            "carries its sampling period",
        ),
        (
            {"path": paths.path_from_samples(np.full((2, 5, 2), 0.1), 0.1, space="joint")},
            r"expected shape \(N, T, 3\).*joint space",
        ),
        ({"weights": [1.0, 0.0, 1.0]}, "weights"),
        ({"weights": [1.0, 1.0]}, "weights"),
        ({"robot": serial.Planar2R(1.0, 0.6)}, r"path: expected shape \(N, T, 2\)"),
        ({"robot": serial.Puma560()}, r"path: expected shape \(N, T, 4, 4\)"),
        ({"dt": 0.0}, "dt"),
        ({"dt": math.inf}, "dt"),
        ({"limits": "none"}, "limits"),
        ({"limits": plan.Limits.create(2)}, "limits"),
        ({"chunk_size": 0}, "chunk_size"),
    ],
)
def test_bad_input(kwargs, match):
    args = {"robot": ROBOT, "path": Jet.constant(np.full((2, 5, 3), 90.0)), "dt": 0.1}
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


# ------------------------------------------------------------------- joint-space candidates
JOINT_DT, JOINT_STEPS = 0.05, 8


def scara_waypoints(n=4, k=4, seed=3):
    """Joint waypoints ``(n, k, 3)`` of the paper SCARA (theta1, theta2, l3) away from its
    singularities (theta2 in (0, pi)) and inside its column's stroke."""
    rng = np.random.default_rng(seed)
    low, high = np.array([-1.0, 0.6, 60.0]), np.array([1.0, 2.2, 110.0])
    return rng.uniform(low, high, (n, k, 3))


def scara_fk_numpy(q):
    """The paper SCARA's forward kinematics [Noriega, eqs. 1-15 inverted]: the arm's second
    link at the absolute angle theta1 - theta2, the column l3 below the base height."""
    l_oa, l_ab, l_bc = 150.0, 80.0, 50.0
    t1, t2, l3 = q[..., 0], q[..., 1], q[..., 2]
    x = l_ab * np.cos(t1) + l_bc * np.cos(t1 - t2)
    y = l_ab * np.sin(t1) + l_bc * np.sin(t1 - t2)
    return np.stack([x, y, l_oa - l3], -1)


def test_joint_space_candidates_against_independent_fk_and_finite_differences():
    """Joint-space candidates: the joints come back as given, the tool path equals the
    closed-form FK (1e-12 mm) and its rates the central differences of that FK along SciPy's
    spline through the same waypoints (h = 1e-4 s: 1e-6 of the scale); the branch and margin
    are those of a task-space evaluation of the tool path on that branch."""
    from scipy.interpolate import CubicSpline

    way = scara_waypoints()
    path = paths.path_from_joint_waypoints(way, JOINT_DT, JOINT_STEPS)
    ev = plan.evaluate(ROBOT, path)
    assert ev.space == "joint" and ev.dt == JOINT_DT and np.all(ev.feasible)
    np.testing.assert_allclose(ev.q.p, path.p, rtol=0, atol=1e-12)
    np.testing.assert_array_equal(ev.q.v, path.v)
    times = np.arange(path.shape[1]) * JOINT_DT
    spline = CubicSpline(np.arange(way.shape[1]) * JOINT_DT * JOINT_STEPS, way, axis=1)
    np.testing.assert_allclose(path.p, spline(times), rtol=0, atol=1e-10)
    np.testing.assert_allclose(ev.tool.p, scara_fk_numpy(spline(times)), rtol=0, atol=1e-10)
    h, scale = 1e-4, 150.0
    ahead, behind = scara_fk_numpy(spline(times + h)), scara_fk_numpy(spline(times - h))
    middle = scara_fk_numpy(spline(times))
    np.testing.assert_allclose(ev.tool.v, (ahead - behind) / (2 * h), rtol=0, atol=1e-6 * scale)
    second = (ahead - 2 * middle + behind) / h**2
    np.testing.assert_allclose(ev.tool.a, second, rtol=0, atol=1e-5 * scale)
    # The same motion as a task-space path on the branch it was read from.
    for b in np.unique(np.asarray(ev.branch)):
        rows = np.flatnonzero(np.asarray(ev.branch) == b)
        task = paths.Path.from_jet(ev.tool[rows], JOINT_DT)
        back = plan.evaluate(ROBOT, task, branch=ROBOT.branches[int(b)])
        np.testing.assert_allclose(back.q.p, path.p[rows], rtol=0, atol=1e-9)
        np.testing.assert_allclose(back.min_margin, ev.min_margin[rows], rtol=1e-9)


def test_joint_space_limits_continuity_and_wraps():
    """A joint path over its limit is OUT_OF_LIMITS from the first sample beyond it; a full
    turn between samples that the rates do not explain is DISCONTINUOUS; a wrap of
    theta1 from pi to -pi is unwrapped and feasible."""
    t = np.arange(JOINT_STEPS * 3 + 1) * JOINT_DT
    base = np.stack([np.pi - 0.5 + 0.04 * t / JOINT_DT, 1.0 + 0 * t, 80.0 + 0 * t], -1)
    wrapped = base.copy()
    wrapped[:, 0] = np.angle(np.exp(1j * base[:, 0]))  # jumps from pi to -pi mid-path
    jumped = base.copy()
    jumped[10:, 1] += 2.0  # a step no rate explains
    ranged = base.copy()
    ranged[:, 2] = 80.0 + 10.0 * t  # the column moves 10 mm/s
    q = np.stack([base, wrapped, jumped, ranged])
    v = np.stack([np.gradient(x, JOINT_DT, axis=0) for x in (base, base, base, ranged)])
    path = paths.Path(q, v, np.zeros_like(q), dt=JOINT_DT, space="joint")
    limits = plan.Limits.create(3, q_max=[np.inf, np.inf, 85.0])
    ev = plan.evaluate(ROBOT, path, limits)
    np.testing.assert_array_equal(ev.feasible, [True, True, False, False])
    np.testing.assert_allclose(ev.q.p[1], base, rtol=0, atol=1e-12)  # unwrapped
    assert ev.first_failure[2] == 10 and ev.status[2, 10] == Status.DISCONTINUOUS
    first_over = int(np.argmax(ranged[:, 2] > 85.0))
    assert ev.first_failure[3] == first_over and ev.status[3, first_over] == Status.OUT_OF_LIMITS


def test_cost_scaling_invariance_under_a_change_of_length_unit():
    """The same SCARA and candidates in metres instead of millimetres (the column's position,
    speed and acceleration limits converted too): every cost is the same (1e-9) and so is
    the ranking, by cost and by duration."""
    path, dt = spiral_candidates()
    v_max, a_max = np.array([2.0, 3.0, 40.0]), np.array([6.0, 8.0, 100.0])
    mm = plan.Limits.create(3, v_max=v_max, a_max=a_max)
    to_m = np.array([1.0, 1.0, 1e-3])
    metres = plan.Limits.create(3, v_max=v_max * to_m, a_max=a_max * to_m)
    small = scara.Scara(0.15, 0.08, 0.05)
    in_mm = plan.evaluate(ROBOT, path, mm, branch="best", dt=dt)
    in_m = plan.evaluate(small, path.map(lambda x: x * 1e-3), metres, branch="best", dt=dt)
    np.testing.assert_allclose(in_m.q.p, in_mm.q.p * to_m, rtol=1e-9, atol=1e-12)
    for name in ("path_length", "peak_speed", "integrated_acceleration", "limit_violation"):
        np.testing.assert_allclose(
            getattr(in_m.costs, name), getattr(in_mm.costs, name), rtol=1e-9, atol=1e-12
        )
    np.testing.assert_array_equal(plan.best(in_m, 5)[0], plan.best(in_mm, 5)[0])
    by_mm, by_m = plan.best(in_mm, 5, by="duration"), plan.best(in_m, 5, by="duration")
    np.testing.assert_array_equal(by_m[0], by_mm[0])
    np.testing.assert_allclose(by_m[1], by_mm[1], rtol=1e-9)


def test_retime_and_rank_by_duration():
    """``plan.retime`` equals ``timing.retime`` of each candidate's joint trajectory (sample
    times as the path parameter) under the limits applied; an infeasible candidate is
    UNTIMEABLE and left out of ``best(by="duration")``, which sorts the others by duration;
    a second call of the same shapes compiles nothing."""

    path = paths.path_from_joint_waypoints(scara_waypoints(n=5), JOINT_DT, JOINT_STEPS)
    v_max, a_max = np.array([12.0, 5.0, 200.0]), np.array([60.0, 25.0, 800.0])
    # theta2 in [0, 2]: one candidate reaches 2.006 (and no whole turn brings it inside)
    q_min, q_max = [-np.inf, 0.0, -np.inf], [np.inf, 2.0, np.inf]
    limits = plan.Limits.create(3, q_min, q_max, v_max, a_max)
    ev = plan.evaluate(ROBOT, path, limits)
    feasible = np.asarray(ev.feasible)
    np.testing.assert_array_equal(feasible, [True, True, True, False, True])
    timed = plan.retime(ev)
    times = np.broadcast_to(np.arange(path.shape[1]) * JOINT_DT, path.shape[:2])
    alone = timing.retime(timing.JointPath(times, ev.q.p, ev.q.v, ev.q.a), v_max, a_max)
    np.testing.assert_allclose(timed.duration[feasible], alone.duration[feasible], rtol=1e-12)
    assert np.all(np.asarray(timed.status)[~feasible] == Status.UNTIMEABLE)
    assert np.all(np.asarray(timed.duration)[~feasible] == 0.0)
    order, durations = plan.best(ev, 10, by="duration", timing=timed)
    ok = np.flatnonzero(feasible & np.asarray(alone.ok))
    np.testing.assert_array_equal(order, ok[np.argsort(np.asarray(alone.duration)[ok])])
    np.testing.assert_allclose(durations, np.asarray(alone.duration)[order], rtol=1e-12)
    np.testing.assert_array_equal(plan.best(ev, 2, by="duration")[0], order[:2])
    # The retimed trajectories stay within the velocity limits at the grid (the samples).
    speeds = np.abs(np.asarray(ev.q.v)) * np.asarray(timed.speed)[..., None]
    assert np.all(speeds[feasible] <= v_max * (1 + 1e-9))
    other = paths.path_from_joint_waypoints(scara_waypoints(n=5, seed=4), JOINT_DT, JOINT_STEPS)
    with compilations() as count:
        plan.retime(plan.evaluate(ROBOT, other, limits))
    assert count.n == 0, count.events
    with pytest.raises(ValueError, match="by must be one of"):
        plan.best(ev, 1, by="speed")
    with pytest.raises(ValueError, match="theta1, theta2, l3 have none"):
        plan.retime(plan.evaluate(ROBOT, path))


def test_retime_refuses_a_joint_without_an_acceleration_limit():
    """A joint with no acceleration limit has no time-optimal motion: with no speed limit
    either, ``plan.retime`` timed theta1's 2 rad turn in 8e-39 s and ranked it first; with a
    speed limit only, its speed jumped within one sample (accelerations set by the sample
    spacing). Both are refused naming the joint, as ``jaxkin plan`` does; a speed limit of
    ``inf`` with a finite acceleration limit is timed, within that acceleration (1e-9)."""
    way = scara_waypoints(n=5)
    way[0] = np.linspace([0.0, 1.0, 60.0], [2.0, 1.0, 60.0], way.shape[1])  # theta1 turns 2 rad
    path = paths.path_from_joint_waypoints(way, JOINT_DT, JOINT_STEPS)
    for v_max, a_max in (([np.inf, 3, 40], [np.inf, 8, 100]), ([2, 3, 40], [np.inf, 8, 100])):
        ev = plan.evaluate(ROBOT, path, plan.Limits.create(3, v_max=v_max, a_max=a_max))
        with pytest.raises(ValueError, match="limit for every joint; theta1 has none"):
            plan.retime(ev)
        with pytest.raises(ValueError, match="theta1 has none"):
            plan.best(ev, 2, by="duration")
    a_max = np.array([6.0, 8.0, 100.0])
    ev = plan.evaluate(ROBOT, path, plan.Limits.create(3, v_max=np.inf, a_max=a_max))
    timed = plan.retime(ev)
    assert np.all(np.asarray(timed.ok) == np.asarray(ev.feasible)) and ev.feasible[0]
    retimed = timing.sample(plan.joint_path(ev), timed, JOINT_DT / 4)
    accelerations = np.abs(np.asarray(retimed.q.a))[np.asarray(retimed.valid)]
    assert np.all(accelerations <= a_max * (1 + 1e-9))
    # A 2 rad turn at 6 rad/s^2 from rest to rest takes at least 2 sqrt(2 / 6) s.
    assert float(timed.duration[0]) >= 2.0 * np.sqrt(2.0 / 6.0) * (1 - 1e-9)


def test_best_ranks_only_feasible_candidates_whatever_the_timing():
    """``best(by="duration")`` with a timing of the joint paths alone (``timing.retime``,
    which knows nothing of the position limits) leaves out the OUT_OF_LIMITS candidate, as it
    does with ``plan.retime``'s; ``by="cost"`` too; a timing of another batch is refused."""

    path = paths.path_from_joint_waypoints(scara_waypoints(n=5), JOINT_DT, JOINT_STEPS)
    v_max, a_max = np.array([12.0, 5.0, 200.0]), np.array([60.0, 25.0, 800.0])
    limits = plan.Limits.create(3, [-np.inf, 0.0, -np.inf], [np.inf, 2.0, np.inf], v_max, a_max)
    ev = plan.evaluate(ROBOT, path, limits)
    feasible = np.asarray(ev.feasible)
    assert not feasible[3] and np.asarray(ev.status)[3].max() == Status.OUT_OF_LIMITS
    times = np.broadcast_to(np.arange(path.shape[1]) * JOINT_DT, path.shape[:2])
    alone = timing.retime(timing.JointPath(times, ev.q.p, ev.q.v, ev.q.a), v_max, a_max)
    assert np.all(np.asarray(alone.ok))  # candidate 3 is timed, and among the fastest
    assert np.argsort(np.asarray(alone.duration))[0] == 3
    for by, given in (("duration", alone), ("duration", None), ("cost", None)):
        order, values = plan.best(ev, 10, by=by, timing=given)
        assert len(order) == feasible.sum() and np.all(feasible[order]), (by, order)
        assert np.all(np.diff(values) >= 0)
    with pytest.raises(ValueError, match="timing: expected one duration per candidate"):
        plan.best(ev, 1, by="duration", timing=jax.tree.map(lambda x: x[:2], alone))


@pytest.mark.slow
def test_durations_against_toppra():
    """Joint-space candidates through 4 waypoints (one cubic per joint: toppra's spline
    through the same waypoints is the same curve): ``plan.retime``'s durations within 1 % of
    toppra's TOPP-RA on the same grid (the samples), and the ranking is the same."""
    from tests.test_timing import toppra_durations

    way = scara_waypoints(n=6, seed=9)
    path = paths.path_from_joint_waypoints(way, 0.25, JOINT_STEPS)  # slow: feasible as sampled
    v_max, a_max = np.array([12.0, 5.0, 200.0]), np.array([60.0, 25.0, 800.0])
    ev = plan.evaluate(ROBOT, path, plan.Limits.create(3, v_max=v_max, a_max=a_max))
    assert np.all(ev.feasible)
    grid = np.arange(path.shape[1]) / JOINT_STEPS  # toppra's s: waypoint k at s = k
    count = len(way)
    reference = toppra_durations(
        way, np.tile(v_max, (count, 1)), np.tile(a_max, (count, 1)), grid, "interpolation"
    )
    timed = plan.retime(ev)
    np.testing.assert_allclose(timed.duration, reference, rtol=1e-2)
    order, _ = plan.best(ev, count, by="duration", timing=timed)
    np.testing.assert_array_equal(order, np.argsort(reference, kind="stable"))
