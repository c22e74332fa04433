"""Analytic IK of the textbook arms (jaxkin.serial.arms): round trips, known values, statuses.

Independent references: the closed-form forward kinematics below are written by hand from each
arm's geometry (products of elementary rotations, not DH matrices), [Lopez-Villagomez]'s
eqs. 3-5 are multiplied with sympy, and Corke's PUMA 560 ``qz`` pose is a published value.
"""

from __future__ import annotations

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np
import pytest
import sympy as sp

from jaxkin import Status
from jaxkin.serial import arms
from jaxkin.serial.arms import (
    Anthropomorphic,
    Cylindrical,
    Planar2R,
    Planar3R,
    Puma560,
    Spherical,
    Stanford,
    ik_all_branches,
)
from jaxkin.serial.dh import transforms
from tests.helpers import BATCH_SHAPES, compilations, tree_allfinite


def fk(robot, q):
    """The DH forward kinematics of an arm: the 4x4 transform of its last frame."""
    q = jnp.asarray(q)
    return transforms(robot.dh_table(q.dtype), q)


PI = np.pi


# ----------------------------------------------------------------- independent closed forms


def rz(t):
    c, s = np.cos(t), np.sin(t)
    z, o = np.zeros_like(t), np.ones_like(t)
    return np.stack(
        [np.stack([c, -s, z], -1), np.stack([s, c, z], -1), np.stack([z, z, o], -1)], -2
    )


def ry(t):
    c, s = np.cos(t), np.sin(t)
    z, o = np.zeros_like(t), np.ones_like(t)
    return np.stack(
        [np.stack([c, z, s], -1), np.stack([z, o, z], -1), np.stack([-s, z, c], -1)], -2
    )


def rx(t):
    c, s = np.cos(t), np.sin(t)
    z, o = np.zeros_like(t), np.ones_like(t)
    return np.stack(
        [np.stack([o, z, z], -1), np.stack([z, c, -s], -1), np.stack([z, s, c], -1)], -2
    )


def position_reference(robot, q):
    """Hand-derived wrist/tip position (and planar orientation) from the arm's geometry."""
    q = np.asarray(q)
    if isinstance(robot, Planar2R | Planar3R):
        ls = [float(robot.l1), float(robot.l2)] + ([float(robot.l3)] if q.shape[-1] == 3 else [])
        angles = np.cumsum(q, axis=-1)
        x = sum(l * np.cos(angles[..., i]) for i, l in enumerate(ls))
        y = sum(l * np.sin(angles[..., i]) for i, l in enumerate(ls))
        return np.stack([x, y, np.zeros_like(x)], -1)
    q1, q2, q3 = q[..., 0], q[..., 1], q[..., 2]
    if isinstance(robot, Anthropomorphic):
        l1, l2, l3 = float(robot.l1), float(robot.l2), float(robot.l3)
        reach = l2 * np.cos(q2) + l3 * np.cos(q2 + q3)
        return np.stack(
            [np.cos(q1) * reach, np.sin(q1) * reach, l1 + l2 * np.sin(q2) + l3 * np.sin(q2 + q3)],
            -1,
        )
    if isinstance(robot, Cylindrical):
        return np.stack([q2 * np.cos(q1), q2 * np.sin(q1), float(robot.h) + q3], -1)
    if isinstance(robot, Spherical):
        return np.stack(
            [
                q3 * np.cos(q2) * np.cos(q1),
                q3 * np.cos(q2) * np.sin(q1),
                float(robot.h) + q3 * np.sin(q2),
            ],
            -1,
        )
    raise TypeError(robot)


def transform_reference(robot, q):
    """Hand-derived 4x4 transform of the 6-joint arms (wrist centre + tool offset, rotation)."""
    q = np.asarray(q)
    q1, q2, q3, q4, q5, q6 = (q[..., i] for i in range(6))
    if isinstance(robot, Puma560):
        d1, a2, a3, d3, d4, d6 = (
            float(x) for x in (robot.d1, robot.a2, robot.a3, robot.d3, robot.d4, robot.d6)
        )
        x = a2 * np.cos(q2) + a3 * np.cos(q2 + q3) - d4 * np.sin(q2 + q3)
        y = a2 * np.sin(q2) + a3 * np.sin(q2 + q3) + d4 * np.cos(q2 + q3)
        pw = np.stack(
            [np.cos(q1) * x + np.sin(q1) * d3, np.sin(q1) * x - np.cos(q1) * d3, d1 + y], -1
        )
        rot = rz(q1) @ ry(-(q2 + q3)) @ rz(q4) @ ry(-q5) @ rz(q6)
    else:  # Stanford: boom elevation q2, length a2 + q3, ZYZ wrist
        d1, a2, d6 = float(robot.d1), float(robot.a2), float(robot.d6)
        rho = a2 + q3
        pw = np.stack(
            [rho * np.cos(q2) * np.cos(q1), rho * np.cos(q2) * np.sin(q1), d1 + rho * np.sin(q2)],
            -1,
        )
        rot = rz(q1) @ ry(-(q2 + PI / 2)) @ rx(np.full_like(q1, PI)) @ rz(q4) @ ry(q5) @ rz(q6)
    t = np.zeros(q.shape[:-1] + (4, 4))
    t[..., :3, :3] = rot
    t[..., :3, 3] = pw + d6 * rot[..., :, 2]
    t[..., 3, 3] = 1.0
    return t


def target_of(robot, q):
    """The IK target of a joint vector, from the independent forward kinematics."""
    if robot.target.shape == (4, 4):
        return transform_reference(robot, q)
    p = position_reference(robot, q)
    if isinstance(robot, Planar2R):
        return p[..., :2]
    if isinstance(robot, Planar3R):
        return np.concatenate([p[..., :2], np.sum(q, axis=-1, keepdims=True)], -1)
    return p


def target_from_fk(robot, t):
    """Read the IK target back out of ``fk``'s 4x4 transform."""
    t = np.asarray(t)
    if robot.target.shape == (4, 4):
        return t
    if isinstance(robot, Planar2R):
        return t[..., :2, 3]
    if isinstance(robot, Planar3R):
        return np.concatenate(
            [t[..., :2, 3], np.arctan2(t[..., 1, 0], t[..., 0, 0])[..., None]], -1
        )
    return t[..., :3, 3]


def target_error(robot, a, b):
    """Largest entrywise difference of two targets (angles compared modulo 2 pi)."""
    d = np.asarray(a) - np.asarray(b)
    if isinstance(robot, Planar3R):
        d[..., 2] = np.angle(np.exp(1j * d[..., 2]))
    return np.max(np.abs(d), axis=tuple(range(-len(robot.target.shape), 0)))


def joint_distance(robot, qa, qb):
    d = np.asarray(qa) - np.asarray(qb)
    revolute = np.array([k == "R" for k in robot.joint_types])
    d[..., revolute] = np.angle(np.exp(1j * d[..., revolute]))
    return np.max(np.abs(d), axis=-1)


# ----------------------------------------------------------------- random joint samplers


def _sample(robot, rng, n):
    """Random joint vectors away from singular configurations (margins stated inline)."""
    out = []
    while len(out) < n:
        q = rng.uniform(-PI, PI, robot.n_joints)
        if isinstance(robot, Planar2R | Planar3R | Anthropomorphic):
            elbow = q[1] if not isinstance(robot, Anthropomorphic) else q[2]
            if abs(np.sin(elbow)) < 0.1:  # elbow (nearly) straight or folded
                continue
            if isinstance(robot, Anthropomorphic):
                l2, l3 = float(robot.l2), float(robot.l3)
                if abs(l2 * np.cos(q[1]) + l3 * np.cos(q[1] + q[2])) < 0.05:  # near base axis
                    continue
        elif isinstance(robot, Cylindrical):
            q[1:] = rng.uniform(0.1, 1.0, 2)
        elif isinstance(robot, Spherical):
            q[1] = rng.uniform(-1.4, 1.4)  # elevation inside (-pi/2, pi/2): the "front" branch
            q[2] = rng.uniform(0.1, 1.0)
        elif isinstance(robot, Puma560):
            psi = np.arctan2(float(robot.d4), float(robot.a3))
            x = (
                float(robot.a2) * np.cos(q[1])
                + float(robot.a3) * np.cos(q[1] + q[2])
                - float(robot.d4) * np.sin(q[1] + q[2])
            )
            if abs(np.sin(q[2] + psi)) < 0.1 or abs(np.sin(q[4])) < 0.1 or abs(x) < 0.05:
                continue
        elif isinstance(robot, Stanford):
            q[1] = rng.uniform(-1.4, 1.4)
            q[2] = rng.uniform(0.0, 0.5)
            if abs(np.sin(q[4])) < 0.1:
                continue
        out.append(q)
    return np.array(out)


N_RANDOM = 25  # one batch size for every random test: each arm compiles once

ROBOTS = [
    Planar2R(1.0, 0.6),
    Planar3R(0.7, 0.5, 0.3),
    Anthropomorphic(0.3, 0.25, 0.2),
    Cylindrical(0.5),
    Spherical(0.4),
    Puma560(),
    Puma560(d1=0.6718, a2=0.5, a3=-0.05, d3=-0.1, d4=0.45, d6=0.08),
    Stanford(0.412, 0.3, 0.1),
]
IDS = [
    "planar2r",
    "planar3r",
    "anthropomorphic",
    "cylindrical",
    "spherical",
    "puma560",
    "puma_custom",
    "stanford",
]


# ----------------------------------------------------------------- forward kinematics


@pytest.mark.parametrize("robot", ROBOTS, ids=IDS)
def test_fk_matches_hand_derived_geometry(robot):
    q = _sample(robot, np.random.default_rng(1), N_RANDOM)
    t = np.asarray(fk(robot, q))
    assert t.shape == (N_RANDOM, 4, 4)
    np.testing.assert_allclose(t[..., 3, :], np.broadcast_to([0, 0, 0, 1.0], (N_RANDOM, 4)), atol=0)
    if robot.target.shape == (4, 4):
        np.testing.assert_allclose(t, transform_reference(robot, q), atol=1e-13)
    else:
        np.testing.assert_allclose(t[..., :3, 3], position_reference(robot, q), atol=1e-13)
    rot = t[..., :3, :3]
    np.testing.assert_allclose(
        rot @ np.swapaxes(rot, -1, -2), np.broadcast_to(np.eye(3), rot.shape), atol=1e-13
    )


def test_anthropomorphic_fk_against_the_papers_matrices_with_sympy():
    """[Lopez-Villagomez, eqs. 3-5] multiplied symbolically (eq. 4's "C" read as C2: errata)."""
    t1, t2, t3, l1, l2, l3 = sp.symbols("theta1 theta2 theta3 L1 L2 L3", real=True)
    c, s = sp.cos, sp.sin
    a01 = sp.Matrix([[c(t1), 0, s(t1), 0], [s(t1), 0, -c(t1), 0], [0, 1, 0, l1], [0, 0, 0, 1]])
    a12 = sp.Matrix(
        [[c(t2), -s(t2), 0, l2 * c(t2)], [s(t2), c(t2), 0, l2 * s(t2)], [0, 0, 1, 0], [0, 0, 0, 1]]
    )
    a23 = sp.Matrix(
        [[c(t3), -s(t3), 0, l3 * c(t3)], [s(t3), c(t3), 0, l3 * s(t3)], [0, 0, 1, 0], [0, 0, 0, 1]]
    )
    values = {
        t1: sp.pi / 6,
        t2: sp.pi / 4,
        t3: -sp.pi / 3,
        l1: sp.Rational(3, 10),
        l2: sp.Rational(1, 4),
        l3: sp.Rational(1, 5),
    }
    expected = np.array((a01 * a12 * a23).subs(values).evalf(30), dtype=float)
    robot = Anthropomorphic(0.3, 0.25, 0.2)
    q = np.array([PI / 6, PI / 4, -PI / 3])
    np.testing.assert_allclose(np.asarray(fk(robot, q)), expected, atol=1e-15)
    # ...and the IK's front_up branch returns exactly this pose (q3 < 0: elbow up).
    res = ik_all_branches(robot, expected[:3, 3])
    np.testing.assert_allclose(np.asarray(res.branch("front_up").q), q, atol=1e-13)
    assert bool(res.branch("front_up").valid)


def test_puma560_zero_pose_is_corkes_qz():
    """Corke, Robotics Toolbox: p560.fkine(qz) = [I, (0.4521, -0.1500, 0.4318)]."""
    t = np.asarray(fk(Puma560(), np.zeros(6)))
    np.testing.assert_allclose(t[:3, :3], np.eye(3), atol=1e-15)
    np.testing.assert_allclose(t[:3, 3], [0.4318 + 0.0203, -0.15005, 0.4318], atol=1e-15)


# ----------------------------------------------------------------- IK round trips


@pytest.mark.parametrize("robot", ROBOTS, ids=IDS)
def test_ik_round_trip_every_branch(robot):
    """fk of every valid branch reproduces the target (1e-10); the generator is among them.

    The same batch with one target replaced by NaN: that element is INVALID_INPUT with q = 0,
    the others are unchanged.
    """
    q_true = _sample(robot, np.random.default_rng(7), N_RANDOM)
    target = target_of(robot, q_true)
    res = ik_all_branches(robot, target)
    n_branches = len(robot.branches)
    assert res.q.shape == (N_RANDOM, n_branches, robot.n_joints)
    assert res.branches == robot.branches
    valid = np.asarray(res.valid)
    assert valid.all(), np.asarray(res.status)
    assert np.all(np.asarray(res.status) == Status.OK)
    reached = target_from_fk(robot, fk(robot, res.q))
    assert target_error(robot, reached, target[:, None]).max() < 1e-10
    distance = joint_distance(robot, res.q, q_true[:, None, :])
    assert np.all(distance.min(axis=-1) < 1e-8)
    # Branches are distinct solutions (away from singularities).
    if n_branches > 1:
        pairwise = joint_distance(robot, res.q[:, :, None, :], res.q[:, None, :, :])
        off_diagonal = pairwise[:, ~np.eye(n_branches, dtype=bool)]
        assert off_diagonal.min() > 1e-3

    target[1].flat[0] = np.nan
    res_nan = ik_all_branches(robot, target)
    status = np.asarray(res_nan.status)
    assert np.all(status[1] == Status.INVALID_INPUT) and not np.any(np.asarray(res_nan.valid)[1])
    np.testing.assert_array_equal(np.asarray(res_nan.q)[1], 0.0)
    keep = np.arange(N_RANDOM) != 1
    np.testing.assert_array_equal(np.asarray(res_nan.q)[keep], np.asarray(res.q)[keep])
    assert tree_allfinite(res_nan)


def test_planar_2r_known_values():
    """l1 = l2 = 1, target (1, 1): q = (pi/2, -pi/2) (elbow up) and (0, pi/2) (elbow down)."""
    res = ik_all_branches(Planar2R(1.0, 1.0), jnp.array([1.0, 1.0]))
    np.testing.assert_allclose(np.asarray(res.q), [[PI / 2, -PI / 2], [0.0, PI / 2]], atol=1e-15)
    # [Pineiro]'s worked 2R target (0.366, 1.366) for unit links: q = (30 deg, 90 deg) is a branch.
    target = np.array([np.cos(PI / 6) + np.cos(2 * PI / 3), np.sin(PI / 6) + np.sin(2 * PI / 3)])
    res = ik_all_branches(Planar2R(1.0, 1.0), target)
    np.testing.assert_allclose(np.asarray(res.branch("elbow_down").q), [PI / 6, PI / 2], atol=1e-14)


def test_planar_3r_known_value():
    """Unit links, target (2, 1, pi/2): wrist at (2, 0); q = (-pi/3, 2pi/3, 1/6 pi) etc."""
    res = ik_all_branches(Planar3R(1.0, 1.0, 1.0), jnp.array([2.0, 1.0, PI / 2]))
    # Wrist (2, 0) with unit links: straight arm, q1 = q2 = 0, q3 = pi/2: singular (extended).
    np.testing.assert_allclose(np.asarray(res.q), [[0.0, 0.0, PI / 2]] * 2, atol=1e-7)
    assert np.all(np.asarray(res.status) == Status.SINGULAR) and np.all(np.asarray(res.valid))
    res = ik_all_branches(Planar3R(1.0, 1.0, 1.0), jnp.array([1.0, 2.0, PI / 2]))  # wrist (1, 1)
    np.testing.assert_allclose(
        np.asarray(res.q), [[PI / 2, -PI / 2, PI / 2], [0.0, PI / 2, 0.0]], atol=1e-14
    )


def test_cylindrical_and_spherical_known_values():
    res = ik_all_branches(Cylindrical(1.0), jnp.array([0.0, 0.5, 1.2]))
    np.testing.assert_allclose(np.asarray(res.q), [[PI / 2, 0.5, 0.2]], atol=1e-15)
    res = ik_all_branches(Spherical(1.0), jnp.array([0.0, 2.0, 1.0]))
    np.testing.assert_allclose(
        np.asarray(res.q), [[PI / 2, 0.0, 2.0], [-PI / 2, PI, 2.0]], atol=1e-15
    )


def test_stanford_known_value_and_prismatic_offset():
    """Boom horizontal along +y at height d1, wrist pointing down the boom: q3 = r - a2."""
    robot = Stanford(0.4, 0.3, 0.0)
    q = np.array([PI / 2, 0.0, 0.5, 0.3, 0.7, -0.2])
    t = np.asarray(fk(robot, q))
    np.testing.assert_allclose(t[:3, 3], [0.0, 0.8, 0.4], atol=1e-15)
    res = ik_all_branches(robot, t)
    front = np.asarray(res.q)[0]  # front_noflip
    np.testing.assert_allclose(front, q, atol=1e-13)
    assert np.allclose(
        np.asarray(res.q)[:, 2], 0.5
    )  # sqrt(r^2 + s^2) - a2 (corrected, docs/errata.md)


def test_anthropomorphic_branch_labels_are_geometric():
    """'up' branches put the elbow above the line shoulder -> wrist (front and back)."""
    robot = Anthropomorphic(0.3, 0.25, 0.2)
    q_true = _sample(robot, np.random.default_rng(3), N_RANDOM)
    res = ik_all_branches(robot, target_of(robot, q_true))
    frames = np.asarray(_frames(robot, res.q))
    shoulder = np.array([0.0, 0.0, 0.3])
    elbow, wrist = frames[..., 1, :3, 3], frames[..., 2, :3, 3]
    # Height of the elbow above the shoulder-wrist line, in the arm's vertical plane.
    u = wrist - shoulder
    horiz = np.linalg.norm(u[..., :2], axis=-1)
    v = elbow - shoulder
    sign = np.sign(horiz * v[..., 2] - u[..., 2] * np.sum(v[..., :2] * u[..., :2], -1) / horiz)
    up = np.array(["up" in b for b in robot.branches])
    assert np.all(sign[:, up] > 0) and np.all(sign[:, ~up] < 0)
    q3 = np.asarray(res.q)[..., 2]
    assert np.all(q3[:, 0] <= 0) and np.all(q3[:, 2] >= 0)  # front_up, back_up


def _frames(robot, q):
    return transforms(robot.dh_table(jnp.float64), jnp.asarray(q, jnp.float64), all_frames=True)


def test_puma_has_eight_distinct_solutions_with_expected_pairs():
    robot = Puma560()
    q_true = _sample(robot, np.random.default_rng(11), 5)
    res = ik_all_branches(robot, transform_reference(robot, q_true))
    q = np.asarray(res.q)
    # Wrist flip: (q4 + pi, -q5, q6 + pi) with the same arm joints.
    noflip, flip = q[:, 0::2], q[:, 1::2]
    np.testing.assert_allclose(noflip[..., :3], flip[..., :3], atol=0)
    np.testing.assert_allclose(
        np.angle(np.exp(1j * (flip[..., 3] - noflip[..., 3] - PI))), 0, atol=1e-12
    )
    np.testing.assert_allclose(flip[..., 4], -noflip[..., 4], atol=1e-12)
    assert np.all(noflip[..., 4] >= 0)
    # "up": in the arm plane (X along the shoulder direction, Y up) the elbow joint
    # (a2 cos q2, a2 sin q2) lies above the line from the shoulder to the wrist centre.
    a2, a3, d4 = 0.4318, 0.0203, 0.4318
    q2, q23 = q[..., 1], q[..., 1] + q[..., 2]
    x = a2 * np.cos(q2) + a3 * np.cos(q23) - d4 * np.sin(q23)
    y = a2 * np.sin(q2) + a3 * np.sin(q23) + d4 * np.cos(q23)
    above = np.sign(x) * (x * a2 * np.sin(q2) - y * a2 * np.cos(q2))
    up = np.array(["_up_" in b for b in robot.branches])
    assert np.all(above[:, up] > 0) and np.all(above[:, ~up] < 0)
    assert np.all(x[:, :4] > 0) and np.all(x[:, 4:] < 0)  # front / back shoulder


# ----------------------------------------------------------------- statuses


def test_unreachable_targets_are_flagged():
    cases = [
        (Planar2R(1.0, 0.6), [[2.0, 0.0], [0.1, 0.1]]),  # beyond reach; inside the hole
        (Planar3R(0.7, 0.5, 0.3), [[2.0, 0.0, 0.0]]),
        (Anthropomorphic(0.3, 0.25, 0.2), [[1.0, 0.0, 0.3], [0.0, 0.5, 1.0]]),
        (Puma560(), [_translation([2.0, 0.0, 0.0]), _translation([0.1, 0.0, 0.3])]),  # r < d3
    ]
    for robot, targets in cases:
        res = ik_all_branches(robot, np.asarray(targets))
        assert np.all(np.asarray(res.status) == Status.UNREACHABLE), type(robot).__name__
        assert not np.any(np.asarray(res.valid))
        assert tree_allfinite(res)


def _translation(p):
    t = np.eye(4)
    t[:3, 3] = p
    return t


def test_singular_targets_are_valid_with_documented_choices():
    # 2R fully stretched: both branches coincide.
    res = ik_all_branches(Planar2R(1.0, 0.6), jnp.array([0.0, 1.6]))
    assert np.all(np.asarray(res.status) == Status.SINGULAR) and np.all(np.asarray(res.valid))
    np.testing.assert_allclose(np.asarray(res.q), [[PI / 2, 0.0]] * 2, atol=1e-15)
    # Equal links, target on the base joint: q1 free -> 0, elbow folded.
    res = ik_all_branches(Planar2R(1.0, 1.0), jnp.array([0.0, 0.0]))
    np.testing.assert_allclose(np.abs(np.asarray(res.q)), [[0.0, PI]] * 2, atol=1e-15)
    assert np.all(np.asarray(res.status) == Status.SINGULAR)
    # Anthropomorphic on the base axis: q1 = 0 (front) and pi (back), all four valid.
    robot = Anthropomorphic(0.3, 0.25, 0.2)
    target = np.array([0.0, 0.0, 0.6])
    res = ik_all_branches(robot, target)
    assert np.all(np.asarray(res.status) == Status.SINGULAR) and np.all(np.asarray(res.valid))
    np.testing.assert_allclose(np.abs(np.asarray(res.q)[:, 0]), [0.0, 0.0, PI, PI], atol=1e-15)
    np.testing.assert_allclose(
        np.asarray(fk(robot, res.q))[:, :3, 3], np.tile(target, (4, 1)), atol=1e-15
    )
    # PUMA with q5 = 0 (wrist singular): q4 = 0, the pose is still reproduced.
    robot = Puma560()
    q = np.array([0.3, -0.5, 0.4, 0.8, 0.0, -0.6])
    t = transform_reference(robot, q)
    res = ik_all_branches(robot, t)
    status = np.asarray(res.status)
    assert np.all(np.asarray(res.valid))
    # The two branches with the generating arm joints (noflip/flip) see q5 = 0; the other
    # arm configurations see a different R_36 and are regular.
    same_arm = np.max(np.abs(np.angle(np.exp(1j * (np.asarray(res.q)[:, :3] - q[:3])))), -1) < 1e-9
    assert same_arm.sum() == 2
    assert np.all(status[same_arm] == Status.SINGULAR) and np.all(status[~same_arm] == Status.OK)
    np.testing.assert_allclose(np.asarray(res.q)[same_arm, 3], 0.0, atol=1e-15)
    np.testing.assert_allclose(
        np.asarray(fk(robot, res.q)), np.broadcast_to(t, (8, 4, 4)), atol=1e-12
    )
    # Stanford with the wrist centre on the base axis.
    robot = Stanford(0.4, 0.3, 0.0)
    t = transform_reference(robot, np.array([0.0, PI / 2, 0.2, 0.3, 0.5, 0.1]))
    res = ik_all_branches(robot, t)
    assert np.all(np.asarray(res.status) == Status.SINGULAR) and np.all(np.asarray(res.valid))
    np.testing.assert_allclose(
        np.asarray(fk(robot, res.q)), np.broadcast_to(t, (4, 4, 4)), atol=1e-12
    )


# ----------------------------------------------------------------- validation


def test_bad_geometry_raises():
    with pytest.raises(ValueError, match="l1"):
        Planar2R(-1.0, 1.0)
    with pytest.raises(ValueError, match="l2"):
        Planar2R(1.0, 0.0)
    with pytest.raises(ValueError, match="l3"):
        Anthropomorphic(0.3, 0.2, float("nan"))
    with pytest.raises(ValueError, match="scalar"):
        Planar3R(1.0, [1.0, 2.0], 1.0)
    with pytest.raises(ValueError, match="h"):
        Cylindrical(-0.1)
    with pytest.raises(ValueError, match="a2"):
        Puma560(a2=0.0)
    with pytest.raises(ValueError, match="d3"):
        Puma560(d3=float("inf"))
    Cylindrical(0.0)  # a zero column height is allowed
    Puma560(a3=-0.02, d1=-1.0)  # offsets may be negative


def test_bad_calls_raise():
    robot = Anthropomorphic(0.3, 0.25, 0.2)
    with pytest.raises(ValueError, match=r"target.*\(\.\.\., 3\)"):
        ik_all_branches(robot, np.zeros(2))
    with pytest.raises(ValueError, match=r"target.*4, 4"):
        ik_all_branches(Puma560(), np.zeros((3, 4)))
    with pytest.raises(ValueError, match="q"):
        arms.fk(robot, np.zeros(2))
    with pytest.raises(ValueError, match="robot"):
        ik_all_branches("puma", np.zeros(3))
    with pytest.raises(ValueError, match="name"):
        ik_all_branches(robot, np.zeros(3) + 0.3).branch("sideways")


# ----------------------------------------------------------------- batching, jit, grads


@pytest.mark.parametrize(
    "robot, shape",
    [(ROBOTS[2], shape) for shape in BATCH_SHAPES] + [(ROBOTS[5], (3, 5))],
    ids=[f"anthro-{shape}" for shape in BATCH_SHAPES] + ["puma-(3, 5)"],
)
def test_batch_shapes(robot, shape):
    n = int(np.prod(shape))
    q_true = _sample(robot, np.random.default_rng(2), max(n, 1))[:n]
    target = target_of(robot, q_true).reshape(shape + robot.target.shape)
    res = ik_all_branches(robot, target)
    nb = len(robot.branches)
    assert res.q.shape == shape + (nb, robot.n_joints)
    assert res.valid.shape == res.status.shape == shape + (nb,)
    assert fk(robot, res.q).shape == shape + (nb, 4, 4)
    if n:
        flat = ik_all_branches(robot, target.reshape((n,) + robot.target.shape))
        np.testing.assert_array_equal(np.asarray(res.q).reshape(flat.q.shape), np.asarray(flat.q))


def test_no_recompilation_and_vmap_over_geometries():
    robot = Anthropomorphic(0.3, 0.25, 0.2)
    targets = target_of(robot, _sample(robot, np.random.default_rng(4), 6))
    ik_all_branches(robot, targets)
    other, moved = Anthropomorphic(0.4, 0.3, 0.25), targets + 0.01
    with compilations() as count:
        ik_all_branches(other, moved)
    assert count.n == 0
    # vmap over a batch of geometries equals a Python loop (geometry leaves are tracers).
    lengths = np.array([[0.3, 0.25, 0.2], [0.35, 0.3, 0.2], [0.2, 0.3, 0.25]])
    stacked = jax.tree.map(lambda *x: jnp.stack(x), *[Anthropomorphic(*row) for row in lengths])
    batched = jax.vmap(lambda r: ik_all_branches(r, targets[0]).q)(stacked)
    for i, row in enumerate(lengths):
        np.testing.assert_allclose(
            np.asarray(batched[i]),
            np.asarray(ik_all_branches(Anthropomorphic(*row), targets[0]).q),
            atol=1e-15,
        )


GRAD_ROBOTS = [ROBOTS[0], ROBOTS[2], ROBOTS[4], ROBOTS[5]]  # two-link, polar, wrist paths


@pytest.mark.parametrize(
    "robot", GRAD_ROBOTS, ids=["planar2r", "anthropomorphic", "spherical", "puma560"]
)
def test_gradient_of_masked_loss_is_finite_on_mixed_batch(robot):
    good = target_of(robot, _sample(robot, np.random.default_rng(8), 2))
    far = (
        np.full_like(good[:1], 5.0)
        if robot.target.shape != (4, 4)
        else _translation([5.0, 0.0, 0.0])[None]
    )
    nan = np.full_like(good[:1], np.nan)
    singular = _singular_target(robot)[None]
    batch = jnp.asarray(np.concatenate([good, far, nan, singular]))

    def loss(target, geometry):
        res = ik_all_branches(geometry, target)
        return jnp.sum(jnp.where(res.valid[..., None], jnp.sin(res.q) + res.q**2, 0.0))

    g_target, g_robot = jax.jit(jax.grad(loss, argnums=(0, 1)))(batch, robot)
    assert np.all(np.isfinite(np.asarray(g_target)))
    assert tree_allfinite(g_robot)
    assert np.any(np.asarray(g_target)[:2] != 0.0)


def _singular_target(robot):
    if isinstance(robot, Planar2R):
        return np.array([float(robot.l1 + robot.l2), 0.0])
    if isinstance(robot, Planar3R):
        return np.array([float(robot.l1 + robot.l2 + robot.l3), 0.0, 0.0])
    if isinstance(robot, Anthropomorphic | Cylindrical | Spherical):
        return np.array([0.0, 0.0, 0.55])
    q = np.zeros(6)
    if isinstance(robot, Puma560):
        q[1] = 0.3
    return transform_reference(robot, q)  # q5 = 0: wrist singular


def test_float32_round_trip_accuracy():
    """Measured: float32 round trips reproduce targets to ~1e-6 of the arm's size."""
    for robot, scale in [(ROBOTS[2], 0.75), (ROBOTS[5], 0.9)]:
        q_true = _sample(robot, np.random.default_rng(9), N_RANDOM)
        target = target_of(robot, q_true).astype(np.float32)
        res = ik_all_branches(robot, jnp.asarray(target))
        assert res.q.dtype == jnp.float32
        assert np.all(np.asarray(res.valid))
        reached = target_from_fk(robot, fk(robot, np.asarray(res.q, np.float64)))
        err = target_error(robot, reached, target[:, None].astype(np.float64)).max()
        assert err < 5e-6 * max(scale, 1.0), (type(robot).__name__, err)


def test_result_helpers():
    res = ik_all_branches(Planar2R(1.0, 1.0), jnp.array([[1.0, 1.0], [5.0, 0.0]]))
    one = res.branch("elbow_down")
    assert one.q.shape == (2, 2) and one.branches == ("elbow_down",)
    with pytest.raises(RuntimeError, match="UNREACHABLE"):
        res.raise_if_failed()
    assert dataclasses.is_dataclass(res)
    assert set(arms.__all__) >= {"fk", "ik_all_branches", "Puma560", "ArmIKResult"}
