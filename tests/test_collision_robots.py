"""Robots' collision bodies and the batched checks: collision.check, validate_motions,
plan.evaluate(world=...).

Bodies are checked against hand-placed geometry (closed forms written here in NumPy, and the
robots' own forward kinematics); ``check`` against brute-force NumPy distances over densely
sampled link segments; ``validate_motions`` against ``check`` of every state of the edges.
The URDF chain's link poses against Pinocchio's frame placements are in the slow tier.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxkin
from jaxkin import Status, collision, delta, paths, plan, scara, serial

from .helpers import compilations

UR5 = Path(__file__).resolve().parents[1] / "examples" / "ur5.urdf"
SCARA = scara.Scara(150.0, 80.0, 50.0, link_radius=4.0)


def scara_points(q: np.ndarray, robot=SCARA) -> np.ndarray:
    """O, A, B, C, D of [Noriega, Fig. 5] (closed form), ``(..., 5, 3)``."""
    t1, t2, l3 = q[..., 0], q[..., 1], q[..., 2]
    zero = np.zeros_like(t1)
    o = np.stack([zero, zero, zero], -1)
    a = np.stack([zero, zero, zero + robot.l_oa], -1)
    b = a + robot.l_ab * np.stack([np.cos(t1), np.sin(t1), zero], -1)
    c = b + robot.l_bc * np.stack([np.cos(t1 - t2), np.sin(t1 - t2), zero], -1)
    d = c - np.stack([zero, zero, l3], -1)
    return np.stack([o, a, b, c, d], -2)


def placed_segments(robot, q):
    body = robot.collision_body()
    _, capsules = body.place(robot.link_poses(jnp.asarray(q)))
    return np.asarray(capsules.a), np.asarray(capsules.b), body


def test_scara_body_is_its_closed_form_links():
    q = np.random.default_rng(0).uniform([-3, -3, 0], [3, 3, 150], (6, 3))
    a, b, body = placed_segments(SCARA, q)
    assert body.links == ("column", "arm", "forearm", "quill")
    o, pa, pb, pc, pd = np.moveaxis(scara_points(q), -2, 0)
    np.testing.assert_allclose(a, np.stack([o, pa, pb, pd], -2), atol=1e-12)
    quill_top = pd + np.array([0.0, 0.0, SCARA.l_oa])
    np.testing.assert_allclose(b, np.stack([pa, pb, pc, quill_top], -2), atol=1e-12)
    # the quill's lower end is the robot's own forward kinematics
    np.testing.assert_allclose(a[:, 3], np.asarray(jaxkin.fk(SCARA, q).x.p), atol=1e-12)
    np.testing.assert_array_equal(np.asarray(body.capsule_radius), 4.0)


def test_delta_body_arms_rods_and_platform():
    robot = delta.Delta(7.0, 2.5, 15.5, 30.0, link_radius=0.5)
    q = np.random.default_rng(1).uniform(-0.3, 0.6, (5, 3))
    a, b, body = placed_segments(robot, q)
    x = np.asarray(jaxkin.fk(robot, q).x.p)  # Newton FK: independent of the closed form used
    ux, uy = np.array([0.0, np.sqrt(3) / 2, -np.sqrt(3) / 2]), np.array([-1.0, 0.5, 0.5])
    for i in range(3):
        u = np.array([ux[i], uy[i], 0.0])
        axis = robot.r_base * u
        elbow = axis + robot.l_arm * (
            np.cos(q[:, i, None]) * u - np.sin(q[:, i, None]) * np.array([0.0, 0.0, 1.0])
        )
        np.testing.assert_allclose(a[:, i], np.broadcast_to(axis, elbow.shape), atol=1e-12)
        np.testing.assert_allclose(b[:, i], elbow, atol=1e-12)
        np.testing.assert_allclose(a[:, 3 + i], elbow, atol=1e-12)
        np.testing.assert_allclose(b[:, 3 + i], x + robot.r_platform * u, atol=1e-9)
        corner = x + robot.r_platform * u
        np.testing.assert_allclose(a[:, 6 + i], corner, atol=1e-9)
    assert body.links[-1] == "platform" and len(robot.self_collision_pairs()) == 15


def test_delta_that_does_not_assemble_is_unreachable_not_free():
    """Rods too short to reach the platform from some actuator angles: the closed form FK
    finds no assembly there, so the body has no pose; ``check`` and ``collides`` report
    UNREACHABLE (colliding, clearance 0) for those elements alone."""
    robot = delta.Delta(7.0, 2.5, 15.5, 10.0, link_radius=0.5)
    q = np.array([[0.0, 0.0, 0.0], [-1.2, 1.2, 0.0], [1.4, 1.4, 1.4], [np.nan, 0.0, 0.0]])
    fk = np.asarray(delta.fk_closed_form(robot, q[:3]).status)
    np.testing.assert_array_equal(fk, [Status.UNREACHABLE, Status.UNREACHABLE, Status.OK])
    world = collision.World.create(spheres=collision.Spheres.create([[0.0, 0.0, 500.0]], 1.0))
    expected = [Status.UNREACHABLE, Status.UNREACHABLE, Status.OK, Status.INVALID_INPUT]
    result = collision.check(robot, q, world)
    np.testing.assert_array_equal(result.status, expected)
    np.testing.assert_array_equal(result.collides, [True, True, False, True])
    clearance, link = np.asarray(result.clearance), np.asarray(result.link)
    np.testing.assert_array_equal(clearance[[0, 1, 3]], 0.0)
    assert clearance[2] > 0 and np.all(link[[0, 1, 3]] == -1)
    np.testing.assert_array_equal(collision.collides(robot, q, world).status, expected)
    alone = collision.check(robot, q[2:3], world)
    np.testing.assert_array_equal(result.clearance[2], alone.clearance[0])


def dh_origins(table, q):
    """Origins of DH frames 0 ... n, written out (standard DH)."""
    a, alpha, d, theta = (np.asarray(getattr(table, k)) for k in ("a", "alpha", "d", "theta"))
    pose, out = np.eye(4), [np.zeros(3)]
    for k, kind in enumerate(table.joint_types):
        th = theta[k] + (q[k] if kind == "R" else 0.0)
        dk = d[k] + (q[k] if kind == "P" else 0.0)
        ct, st, ca, sa = np.cos(th), np.sin(th), np.cos(alpha[k]), np.sin(alpha[k])
        link = np.array(
            [
                [ct, -st * ca, st * sa, a[k] * ct],
                [st, ct * ca, -ct * sa, a[k] * st],
                [0, sa, ca, dk],
                [0, 0, 0, 1],
            ]
        )
        pose = pose @ link
        out.append(pose[:3, 3])
    return np.stack(out)


@pytest.mark.parametrize(
    "arm", [serial.Puma560(link_radius=0.05), serial.Anthropomorphic(0.3, 0.25, 0.2)]
)
def test_arm_body_joins_the_dh_origins(arm):
    q = np.random.default_rng(2).uniform(-2, 2, (3, arm.n_joints))
    a, b, body = placed_segments(arm, q)
    for i in range(len(q)):
        origins = dh_origins(arm.dh_table(), q[i])
        np.testing.assert_allclose(a[i], origins[:-1], atol=1e-12)
        np.testing.assert_allclose(b[i], origins[1:], atol=1e-12)
    assert body.links[0] == "base" and len(body.links) == arm.n_joints + 1


def test_links_that_touch_at_home_are_no_self_pair():
    """The Stanford arm's column and its prismatic rod (radius 0) touch at q = 0: their
    distance there is round-off (+2.4e-17 on this machine), which ``d > 0`` kept as a pair,
    and 11 % of random configurations then collided in an empty world (none now: the slow
    test below checks q = 0 of every arm). A pair within 64 ulp of the robot's size at
    q = 0 is left out."""
    pairs = serial.Stanford(d1=0.4, a2=0.3).self_collision_pairs()
    assert (1, 3) not in pairs and (1, 4) in pairs


@pytest.mark.slow
@pytest.mark.parametrize("radius", [0.0, 0.02])
@pytest.mark.parametrize("arm", serial.ARMS, ids=lambda cls: cls.__name__)
def test_every_arm_is_clear_of_itself_at_home(arm, radius):
    """Every analytic arm, with capsules of radius 0 or 2 cm: q = 0 does not collide with
    itself in an empty world (its self pairs leave out the links in contact there), nor
    does the Stanford arm with radius 0 anywhere (its links meet only where they touch at
    home: 11 % of random configurations collided)."""
    from tests.test_geometry import GEOMETRIES

    robot = GEOMETRIES[arm.__name__][0](**GEOMETRIES[arm.__name__][1], link_radius=radius)
    q = np.random.default_rng(0).uniform(-np.pi, np.pi, (64, robot.n_joints))
    q[0] = 0.0
    if arm is serial.Stanford:
        q[:, 2] = np.random.default_rng(1).uniform(0.0, 0.5, 64)  # the prismatic joint
    empty = collision.World.create()
    verdict, exact = collision.collides(robot, q, empty), collision.check(robot, q, empty)
    assert not bool(verdict.collides[0]) and not bool(exact.collides[0])
    if arm is serial.Stanford and radius == 0.0:
        assert not np.any(np.asarray(verdict.collides))


def test_link_radius_is_validated_and_arms_keep_their_lengths():
    with pytest.raises(ValueError, match="link_radius"):
        scara.Scara(150.0, 80.0, 50.0, link_radius=-1.0)
    arm = serial.Anthropomorphic(0.3, 0.25, 0.2, link_radius=0.1)
    assert len(arm.lengths(float)) == 3 and float(arm.length_scale()) == pytest.approx(0.75)


def test_arm_radius_traced_needs_its_pairs_from_values():
    """An analytic arm's self pairs leave out the links in contact at q = 0, a choice made
    from values: a traced radius gets a clear error naming the way out, and without self
    pairs the clearance's derivative in the radius is the finite difference's."""
    world = collision.World.create(spheres=collision.Spheres.create([[0.4, 0.1, 0.3]], 0.1))
    q = np.random.default_rng(0).uniform(-3.0, 3.0, (3, 6))

    def total(radius, self_collision=True):
        arm = serial.Puma560(link_radius=radius)
        return collision.check(arm, q, world, self_collision=self_collision).clearance.sum()

    with pytest.raises(ValueError, match="self_collision=False"):
        jax.grad(total)(0.03)
    slope = float(jax.grad(lambda r: total(r, False))(0.03))
    step = (float(total(0.03 + 1e-6, False)) - float(total(0.03 - 1e-6, False))) / 2e-6
    assert np.isfinite(slope) and slope == pytest.approx(step, rel=1e-8)


def test_chain_from_urdf_tip_link_pose_and_skeleton():
    chain = serial.from_urdf(UR5, "tool0").with_link_radius(0.04)
    q = np.random.default_rng(3).uniform(-2, 2, (4, 6))
    poses = np.asarray(chain.link_poses(jnp.asarray(q)))
    body = chain.collision_body()
    tip = body.links.index("tool0")
    np.testing.assert_allclose(poses[:, tip], np.asarray(jaxkin.fk(chain, q).x.p), atol=1e-12)
    # a skeleton capsule ends at its child link's origin in every configuration
    _, capsules = body.place(jnp.asarray(poses))
    ends = np.asarray(capsules.b)
    for k, link in enumerate(body.capsule_link):
        distances = [np.linalg.norm(ends[:, k] - poses[:, j, :3, 3], axis=-1) for j in range(9)]
        assert np.min(np.max(distances, axis=-1)) < 1e-12, body.links[link]


def test_chain_own_spheres_override():
    chain = serial.from_urdf(UR5, "tool0").with_link_spheres(
        {"forearm_link": (np.zeros((1, 3)), np.array([0.07]))}
    )
    body = chain.collision_body()
    forearm = body.links.index("forearm_link")
    assert body.sphere_link == (forearm,) and forearm not in body.capsule_link
    with pytest.raises(ValueError, match="unknown link"):
        chain.with_link_spheres({"nope": (np.zeros((1, 3)), np.array([0.1]))})


def test_chain_own_spheres_keep_the_other_links_skeleton():
    """A URDF without ``<collision>`` elements: spheres for one link replace that link's
    skeleton capsules only; every other link keeps its own (the body had the user's spheres
    alone, so a penetration of another link read as clear), and the self pairs are the
    skeleton's that do not touch at q = 0 (as without the spheres), and the forearm's."""
    skeleton = serial.from_urdf(UR5, "tool0").with_link_radius(0.04)
    chain = skeleton.with_link_spheres({"forearm_link": (np.zeros((1, 3)), [0.07])})
    spheres, capsules = chain.collision_body().per_link()
    own = skeleton.collision_body().per_link()[1]
    assert set(spheres) == {"forearm_link"} and set(capsules) == set(own) - {"forearm_link"}
    for link, arrays in capsules.items():
        for got, expected in zip(arrays, own[link], strict=True):
            np.testing.assert_array_equal(got, expected)
    pairs = chain.self_collision_pairs()
    forearm = chain.collision_body().links.index("forearm_link")
    others = {pair for pair in pairs if forearm not in pair}
    assert others == {p for p in skeleton.self_collision_pairs() if forearm not in p}
    assert len(others) < len(pairs)  # the forearm's spheres against the others' capsules


def test_chain_own_spheres_are_copied_and_checked():
    centers, radii = np.zeros((2, 3)), np.array([0.05, 0.06])
    chain = serial.from_urdf(UR5, "tool0").with_link_spheres({"forearm_link": (centers, radii)})
    centers[0, 0], radii[0] = 5.0, 9.0  # the chain kept copies: its body does not move
    own_c, own_r = chain.collision_body().per_link()[0]["forearm_link"]
    np.testing.assert_array_equal(own_c, np.zeros((2, 3)))
    np.testing.assert_array_equal(own_r, [0.05, 0.06])
    one = chain.with_link_spheres({"forearm_link": ([0.0, 0.0, 0.1], 0.07)})  # one sphere
    np.testing.assert_array_equal(one.collision_body().per_link()[0]["forearm_link"][1], [0.07])
    bad = [
        ((np.zeros((1, 2)), [0.1]), r"center: expected shape \(k, 3\), got \(1, 2\)"),
        ((np.zeros((3, 2)), [0.1, 0.2]), r"center: expected shape \(k, 3\), got \(3, 2\)"),
        ((np.zeros((2, 3)), [0.1, 0.2, 0.3]), "radius: shape"),
        ((np.zeros((1, 3)), [-0.1]), "radius must be >= 0"),
        (([[0.0, np.nan, 0.0]], [0.1]), "center must be finite"),
        ((np.zeros((1, 3)), [np.inf]), "radius must be finite"),
        (np.zeros((1, 3)), r"expected \(centers"),
    ]
    for value, message in bad:
        with pytest.raises(ValueError, match=r"spheres\['forearm_link'\]: " + message):
            chain.with_link_spheres({"forearm_link": value})


# ------------------------------------------------------------------ brute-force check
def segment_points(a, b, n):
    t = np.linspace(0.0, 1.0, n)[:, None]
    return a[..., None, :] + t * (b - a)[..., None, :]


def brute_clearance(robot, q, centres, radii, floor_z, samples=801):
    """Min over sampled points of the robot's capsules of the distance to sphere obstacles and
    a floor, and over sampled point pairs of the self-collision pairs (NumPy)."""
    a, b, body = placed_segments(robot, q)
    r = np.asarray(body.capsule_radius)
    pts = segment_points(a, b, samples)  # (N, nc, S, 3)
    to_spheres = np.linalg.norm(pts[..., None, :] - centres, axis=-1) - radii  # (N, nc, S, m)
    world = np.min(to_spheres, axis=(-2, -1)) - r
    world = np.minimum(world, np.min(pts[..., 2], axis=-1) - floor_z - r)
    best = np.min(world, axis=-1)
    sp = segment_points(a, b, 201)
    link = np.asarray(body.capsule_link)
    for i, j in robot.self_collision_pairs():
        for p in np.flatnonzero(link == i):
            for s in np.flatnonzero(link == j):
                gap = np.linalg.norm(sp[:, p, :, None] - sp[:, s, None, :], axis=-1)
                best = np.minimum(best, np.min(gap, axis=(-2, -1)) - r[p] - r[s])
    return best


def scara_world(centres, radii, floor_z):
    return collision.World.create(
        spheres=collision.Spheres.create(centres, radii),
        halfspaces=collision.HalfSpaces.create([[0.0, 0.0, 1.0]], [floor_z]),
    )


def test_check_against_brute_force_distances():
    rng = np.random.default_rng(4)
    q = rng.uniform([-3, -3, 0], [3, 3, 170], (24, 3))
    centres = rng.uniform([-120, -120, 0], [120, 120, 160], (5, 3))
    radii = rng.uniform(5, 25, 5)
    floor_z = -10.0  # the obstacle is the half-space z <= -10 (the quill reaches below it)
    world = scara_world(centres, radii, floor_z)
    result = collision.check(SCARA, q, world)
    expected = brute_clearance(SCARA, q, centres, radii, floor_z)
    # sampled points overestimate the distance by at most half their spacing (sampled pairs:
    # half of each spacing)
    clearance = np.asarray(result.clearance)
    assert np.all(clearance <= expected + 1e-9)
    np.testing.assert_allclose(clearance, expected, atol=0.5 * 150.0 / 200 + 1e-9)
    np.testing.assert_array_equal(np.asarray(result.collides), clearance <= 0)
    assert 0 < np.sum(result.collides) < len(q)  # both kinds present
    status = np.where(clearance <= 0, Status.COLLISION, Status.OK)
    np.testing.assert_array_equal(np.asarray(result.status), status)


def test_check_reports_the_pair_and_isolates_bad_elements():
    world = scara_world([[130.0, 0.0, 150.0]], [10.0], -1000.0)
    q = np.array([[0.0, 0.0, 10.0], [np.nan, 0.0, 0.0], [np.pi, 0.0, 10.0]])
    result = collision.check(SCARA, q, world)
    # stretched along +x the forearm (link 2) reaches into the sphere: 130 - 10 - 4 = 116 < 130
    assert result.pair_kind[0] == collision.ROBOT_WORLD
    assert result.link[0] == 2 and result.obstacle_kind[0] == collision.SPHERE
    assert result.other[0] == 0
    np.testing.assert_allclose(result.clearance[0], -14.0, atol=1e-9)
    assert result.status[1] == Status.INVALID_INPUT and result.collides[1]
    assert np.isfinite(result.clearance[1])
    alone = collision.check(SCARA, q[2:], world)
    np.testing.assert_allclose(result.clearance[2], alone.clearance[0], rtol=0, atol=0)


def test_check_compiles_once_per_shapes_and_under_jit_vmap():
    world = scara_world([[130.0, 0.0, 150.0]], [10.0], 0.0)
    q = np.random.default_rng(5).uniform([-3, -3, 0], [3, 3, 150], (8, 3))
    first = collision.check(SCARA, q, world)
    moved = scara_world([[0.0, 100.0, 150.0]], [20.0], 5.0)
    thicker = SCARA.replace(link_radius=9.0)
    with compilations() as count:
        second = collision.check(SCARA, q, moved)
        third = collision.check(thicker, q, moved)
    assert count.n == 0
    assert not np.allclose(first.clearance, second.clearance)
    assert np.all(np.asarray(third.clearance) < np.asarray(second.clearance))
    traced = jax.jit(jax.vmap(lambda x: collision.check(SCARA, x, moved).clearance))(q)
    np.testing.assert_allclose(traced, second.clearance, rtol=1e-12)


@pytest.mark.slow
def test_clearance_gradient_is_finite_in_contact_and_penetration():
    # the forearm's end C = (130, 0, 150) at q = 0: touching and inside a sphere
    body, pairs = collision.prepare(SCARA)
    q = jnp.array([0.0, 0.0, 10.0])
    for radius in (16.0, 14.0, 40.0):  # contact (130 - 16 - 4 = 110: the arm tip), inside
        world = scara_world([[126.0, 0.0, 150.0]], [radius], -1000.0)

        def clearance(x, world=world):
            return collision.check_kernel(SCARA, body, pairs, x, world).clearance

        g = jax.grad(clearance)(q)
        assert np.all(np.isfinite(g))
        eps = 1e-6
        fd = [
            (clearance(q.at[k].add(eps)) - clearance(q.at[k].add(-eps))) / (2 * eps)
            for k in range(3)
        ]
        np.testing.assert_allclose(g, fd, atol=1e-5)


def test_check_arguments_name_the_argument():
    """A margin that is not one finite number, complex or boolean ``q`` and a missing robot
    raise naming the argument; integer ``q`` and a traced margin still work."""
    world = scara_world([[130.0, 0.0, 150.0]], [10.0], -1000.0)
    q = np.array([[0.0, 0.0, 10.0], [3.0, 0.0, 10.0]])
    for margin in (np.nan, np.inf, "a", np.array([0.0, 1.0]), True):
        with pytest.raises(ValueError, match="margin must be a finite number"):
            collision.check(SCARA, q, world, margin=margin)
        with pytest.raises(ValueError, match="margin must be a finite number"):
            collision.validate_motions(SCARA, q, q[::-1], world, 2.0, margin=margin)
    for bad in (q.astype(complex), q.astype(bool)):
        with pytest.raises(ValueError, match="q: expected real joint coordinates"):
            collision.check(SCARA, bad, world)
        with pytest.raises(ValueError, match="q_from: expected real joint coordinates"):
            collision.validate_motions(SCARA, bad, q, world, 2.0)
    with pytest.raises(ValueError, match="robot: expected a robot"):
        collision.check(None, q, world)
    with pytest.raises(ValueError, match="robot: expected a robot"):
        collision.validate_motions(None, q, q, world, 2.0)
    exact = collision.check(SCARA, q, world, margin=1.0)
    assert exact.collides[0] and not exact.collides[1]
    ints = collision.check(SCARA, q.astype(int), world, margin=1)
    np.testing.assert_array_equal(ints.clearance, exact.clearance)
    same = collision.check(SCARA, q, world, margin=np.float32(1.0))
    np.testing.assert_array_equal(same.collides, exact.collides)
    traced = jax.jit(lambda m: collision.check(SCARA, q, world, margin=m).collides)(1.0)
    np.testing.assert_array_equal(traced, exact.collides)


_PROTOCOL = (
    "n_joints",
    "collision_body",
    "link_poses",
    "link_frame_rows",
    "placeable",
    "self_collision_pairs",
)


@jax.tree_util.register_dataclass
@dataclasses.dataclass(frozen=True)
class _Checkable:
    """No ``jaxkin.Robot``: the collision protocol's members alone, delegated to a robot."""

    robot: Any

    @property
    def n_joints(self):
        return self.robot.n_joints

    def collision_body(self):
        return self.robot.collision_body()

    def link_poses(self, q):
        return self.robot.link_poses(q)

    def link_frame_rows(self, q):
        return self.robot.link_frame_rows(q)

    def placeable(self, q):
        return self.robot.placeable(q)

    def self_collision_pairs(self):
        return self.robot.self_collision_pairs()


class _Members:
    """The protocol's members as instance attributes, all or all but ``missing``."""

    def __init__(self, robot, missing=()):
        for name in _PROTOCOL:
            if name not in missing:
                setattr(self, name, getattr(robot, name))


def test_checks_take_any_robot_of_the_collision_protocol():
    """``check`` and ``collides`` take their robot through ``collision.CollisionRobot``: every
    jaxkin robot is one; an object with its members and no ``jaxkin.Robot`` gets the robot's
    own results; one without a member is refused naming ``robot``, also after another
    instance of its class had them all."""
    for robot in (SCARA, delta.Delta.paper(), serial.Puma560(), serial.from_urdf(UR5, "tool0")):
        assert isinstance(robot, collision.CollisionRobot)
    world = scara_world([[130.0, 0.0, 150.0]], [10.0], -1000.0)
    q = np.array([[0.0, 0.0, 10.0], [3.0, 0.0, 10.0], [1.0, -2.0, 150.0]])
    own, duck = collision.check(SCARA, q, world), collision.check(_Checkable(SCARA), q, world)
    np.testing.assert_array_equal(duck.clearance, own.clearance)
    np.testing.assert_array_equal(duck.status, own.status)
    verdict = collision.collides(_Checkable(SCARA), q, world)
    np.testing.assert_array_equal(verdict.collides, own.collides)
    assert collision.protocol.conforms(_Members(SCARA))
    for name in _PROTOCOL:
        partial = _Members(SCARA, missing=(name,))
        assert not isinstance(partial, collision.CollisionRobot)
        with pytest.raises(ValueError, match="robot: expected a robot with the collision"):
            collision.check(partial, q, world)
        with pytest.raises(ValueError, match="robot: expected a robot with the collision"):
            collision.validate_motions(partial, q, q, world, 2.0)


# ------------------------------------------------------------------ motions
@pytest.mark.slow
def test_validate_motions_against_check_of_every_state():
    rng = np.random.default_rng(6)
    world = scara_world(
        rng.uniform([-120, -120, 100], [120, 120, 160], (4, 3)), [15.0] * 4, -1000.0
    )
    q_from = rng.uniform([-3, -3, 0], [3, 3, 100], (12, 3))
    q_to = rng.uniform([-3, -3, 0], [3, 3, 100], (12, 3))
    q_to[:, 2] = q_from[:, 2]  # keep the prismatic joint's distance small: radians dominate
    resolution = 4.0
    result = collision.validate_motions(SCARA, q_from, q_to, world, resolution)
    assert 0 < np.sum(result.valid) < 12
    for m in range(12):
        k = int(result.states[m])
        assert k == max(1, int(np.ceil(np.linalg.norm(q_to[m] - q_from[m]) * resolution)))
        states = q_from[m] + (np.arange(k + 1) / k)[:, None] * (q_to[m] - q_from[m])
        hit = np.flatnonzero(np.asarray(collision.check(SCARA, states, world).collides))
        assert bool(result.valid[m]) == (hit.size == 0)
        assert int(result.first[m]) == (hit[0] if hit.size else -1)
        if hit.size:
            assert float(result.fraction[m]) == pytest.approx(hit[0] / k)
            np.testing.assert_allclose(result.last_valid[m], states[max(hit[0] - 1, 0)])


def test_validate_motions_reuses_its_compilation():
    world = scara_world([[130.0, 0.0, 150.0]], [10.0], 0.0)
    rng = np.random.default_rng(7)
    a, b = rng.uniform(-2, 2, (2, 5, 3))
    collision.validate_motions(SCARA, a, b, world, 2.0, samples=16)
    with compilations() as count:
        collision.validate_motions(
            SCARA, b, a, scara_world([[0, 90, 150]], [5.0], 1.0), 3.0, samples=16
        )
    assert count.n == 0
    with pytest.raises(ValueError, match="resolution"):
        collision.validate_motions(SCARA, a, b, world, 0.0)
    with pytest.raises(ValueError, match="q_to"):
        collision.validate_motions(SCARA, a, b[:, :2], world, 1.0)


def test_validate_motions_takes_numpy_resolutions():
    world = scara_world([[130.0, 0.0, 150.0]], [10.0], -1000.0)
    a, b = np.array([[-1.0, 0.0, 10.0]]), np.array([[1.0, 0.0, 10.0]])
    plain = collision.validate_motions(SCARA, a, b, world, 4.0)
    assert not plain.valid[0] and int(plain.states[0]) == 8
    for resolution in (np.float32(4.0), np.int64(4), np.array(4.0), 4):
        other = collision.validate_motions(SCARA, a, b, world, resolution)
        for field in ("valid", "first", "fraction", "states"):
            np.testing.assert_array_equal(getattr(other, field), getattr(plain, field))
    for resolution in (True, np.array([4.0]), np.float32(np.nan), -1):
        with pytest.raises(ValueError, match="resolution must be a positive finite number"):
            collision.validate_motions(SCARA, a, b, world, resolution)


def test_an_edge_longer_than_its_slots_is_not_valid():
    """Slots fixed by the caller that end before the edge does: the edge is checked at its
    own spacing as far as they reach and reported not valid, never checked more coarsely.
    The ball sits at the edge's midpoint, which 4 slots do not reach."""
    world = scara_world([[130.0, 0.0, 150.0]], [10.0], -1000.0)
    a, b = np.array([[-1.0, 0.0, 10.0]]), np.array([[1.0, 0.0, 10.0]])  # 2 rad: 16 intervals
    assert bool(collision.check(SCARA, (a + b) / 2, world).collides[0])
    whole = collision.validate_motions(SCARA, a, b, world, 8.0)
    assert not bool(whole.valid[0]) and int(whole.states[0]) == 16
    for samples in (2, 4, 8):
        short = collision.validate_motions(SCARA, a, b, world, 8.0, samples=samples)
        states = a + (np.arange(samples) / 16)[:, None] * (b - a)
        assert not np.any(np.asarray(collision.check(SCARA, states, world).collides))
        assert not bool(short.valid[0])
        assert int(short.first[0]) == samples and int(short.states[0]) == 16
        assert float(short.fraction[0]) == samples / 16
        np.testing.assert_allclose(short.last_valid[0], states[-1], rtol=0, atol=1e-12)
    fits = collision.validate_motions(SCARA, a, a + (b - a) / 8, world, 8.0, samples=4)
    assert bool(fits.valid[0]) and int(fits.first[0]) == -1  # 2 intervals fit in 4 slots


# ------------------------------------------------------------------ plan.evaluate
def test_plan_evaluate_with_a_world():
    t = np.linspace(0.0, 1.0, 12)
    path = np.stack(
        [np.stack([100 - 20 * t, -40 + 80 * t + s, 100 + 0 * t], -1) for s in (0.0, 30.0)]
    )
    path = paths.path_from_samples(path, 1.0 / 11)
    world = scara_world([[90.0, -20.0, 150.0]], [8.0], -1000.0)
    ev = plan.evaluate(SCARA, path, world=world)
    checked = collision.check(SCARA, ev.q.p, world)
    plain = plan.evaluate(SCARA, path)
    expected = np.where(
        (np.asarray(plain.status) == Status.OK) & np.asarray(checked.collides),
        Status.COLLISION,
        np.asarray(plain.status),
    )
    np.testing.assert_array_equal(ev.status, expected)
    assert np.any(expected == Status.COLLISION)
    bad = expected != Status.OK
    np.testing.assert_array_equal(ev.feasible, ~bad.any(-1))
    np.testing.assert_array_equal(ev.first_failure, np.where(bad.any(-1), bad.argmax(-1), -1))
    np.testing.assert_allclose(ev.min_clearance, np.min(checked.clearance, -1), rtol=1e-12)
    assert plain.min_clearance is None
    with pytest.raises(ValueError, match="world"):
        plan.evaluate(SCARA, path, world="floor")


def test_plan_min_clearance_leaves_out_unsolved_samples():
    """A path that ends inside the inner hole of the workspace: the unreachable samples'
    joints are placeholders (the arm folded) and their clearance is not the candidate's;
    a candidate with no solved sample reports 0."""
    s = np.linspace(0.0, 1.0, 20)[None, :, None]
    into_hole = np.array([100.0, 0.0, 60.0]) + s * np.array([-90.0, 0.0, 0.0])
    inside = np.broadcast_to(np.array([5.0, 0.0, 60.0]), into_hole.shape)
    path = paths.path_from_samples(np.concatenate([into_hole, inside]), 0.05)
    world = scara_world([[0.0, 0.0, 400.0]], [1.0], -1000.0)
    ev = plan.evaluate(SCARA, path, world=world)
    status = np.asarray(ev.status)
    solved = status == Status.OK
    assert 0 < solved[0].sum() < 20 and not solved[1].any()
    clearance = np.asarray(collision.check(SCARA, ev.q.p, world).clearance)
    assert clearance[0][~solved[0]].min() < clearance[0][solved[0]].min()  # what was counted
    np.testing.assert_allclose(ev.min_clearance[0], clearance[0][solved[0]].min(), rtol=1e-12)
    assert float(ev.min_clearance[1]) == 0.0


# ------------------------------------------------------------------ slow: Pinocchio
@pytest.mark.slow
def test_urdf_chain_link_poses_against_pinocchio():
    pin = pytest.importorskip("pinocchio")
    chain = serial.from_urdf(UR5, "tool0")
    model = pin.buildModelFromUrdf(str(UR5))
    data = model.createData()
    names = chain.links.names
    q = np.random.default_rng(8).uniform(-3, 3, (16, 6))
    poses = np.asarray(chain.link_poses(jnp.asarray(q)))
    base = model.getFrameId("base_link")
    slots = [model.joints[model.getJointId(name)].idx_q for name in chain.joint_names]
    for i in range(len(q)):
        q_pin = np.zeros(model.nq)  # joints off the path (the finger) at 0
        q_pin[slots] = q[i]
        pin.framesForwardKinematics(model, data, q_pin)
        base_inv = data.oMf[base].inverse()
        for k, name in enumerate(names):
            expected = (base_inv * data.oMf[model.getFrameId(name)]).homogeneous
            np.testing.assert_allclose(poses[i, k], expected, atol=1e-12, err_msg=name)


# ------------------------------------------------------------------ optimiser cost
def segment_point_distance(a, b, p):
    t = np.clip(np.sum((p - a) * (b - a), -1) / np.sum((b - a) ** 2, -1), 0.0, 1.0)
    return np.linalg.norm(a + t[..., None] * (b - a) - p, axis=-1)


@pytest.mark.slow
def test_obstacles_cost_on_the_body_with_planar_obstacles():
    from jaxkin import costs
    from jaxkin.jet import Jet

    arm = serial.Planar2R(1.0, 0.5, link_radius=0.05)
    safety = 0.3
    cost = costs.Obstacles.create(
        spheres=([[1.2, 0.3]], [0.2]), boxes=([[0.0, -1.7]], [[0.2, 0.1]]), safety=safety, dims=2
    )
    q = np.random.default_rng(9).uniform(-2.5, 2.5, (2, 5, 2))
    zeros = np.zeros_like(q)
    sample = costs.TrajectorySample(
        Jet(q, zeros, zeros), None, np.zeros((2, 5)), 0.1, None, None, arm
    )
    value = np.asarray(cost(sample))
    # NumPy: the two links as segments in the plane, the sphere exactly, the box (out of reach
    # 1.5: never penetrated) by sampling
    c1 = np.stack([np.cos(q[..., 0]), np.sin(q[..., 0])], -1)
    c2 = c1 + 0.5 * np.stack([np.cos(q.sum(-1)), np.sin(q.sum(-1))], -1)
    ends = [(np.zeros_like(c1), c1), (c1, c2)]
    total = np.zeros(2)
    for a, b in ends:
        to_sphere = segment_point_distance(a, b, np.array([1.2, 0.3])) - 0.2
        pts = a[..., None, :] + np.linspace(0, 1, 20001)[:, None] * (b - a)[..., None, :]
        u = np.abs(pts - np.array([0.0, -1.7])) - np.array([0.2, 0.1])
        to_box = np.min(np.linalg.norm(np.maximum(u, 0.0), axis=-1), axis=-1)
        d = np.minimum(to_sphere, to_box) - 0.05
        total += np.sum((np.maximum(safety - d, 0.0) / safety) ** 2, axis=-1)
    np.testing.assert_allclose(value, total, atol=1e-3)
    assert np.any(value > 0)
    grad = jax.grad(lambda x: cost(dataclasses_replace(sample, x)).sum())(jnp.asarray(q))
    assert np.all(np.isfinite(grad))


def dataclasses_replace(sample, q):
    import dataclasses

    from jaxkin.jet import Jet

    return dataclasses.replace(sample, q=Jet(q, jnp.zeros_like(q), jnp.zeros_like(q)))


def _fields(result) -> dict[str, np.ndarray]:
    """Every field of a ``CheckResult``, its closest pair's and its world and self parts'."""
    names = ("clearance", "collides", "status", "pair_kind", "link", "other", "obstacle_kind")
    out = {f: np.array(getattr(result, f)) for f in names}
    for part in ("world", "self_collision"):
        value = getattr(result, part)
        out.update({f"{part}.{f}": np.array(getattr(value, f)) for f in value.__dataclass_fields__})
    return out


@pytest.mark.slow
def test_check_fused_pass_equals_the_per_primitive_queries():
    """``check_kernel``'s fused pass (chunked beyond ``CHECK_CHUNK`` configurations)
    against the per-primitive queries (``nearest_obstacles`` and ``self_distances``): the
    same clearance to 1e-12 and the same pair, every obstacle kind, a NaN element."""
    from jaxkin.collision.check import CHECK_CHUNK, _check_per_primitive

    arm = serial.Puma560(link_radius=0.05)
    rng = np.random.default_rng(11)
    world = collision.World.create(
        spheres=collision.Spheres.create(rng.uniform(-1.2, 1.2, (4, 3)), rng.uniform(0.02, 0.1, 4)),
        capsules=collision.Capsules.create(
            rng.uniform(-1.2, 1.2, (2, 3)), rng.uniform(-1.2, 1.2, (2, 3)), [0.02, 0.05]
        ),
        boxes=collision.Boxes.create(
            rng.uniform(-0.8, 0.8, (2, 3)),
            rng.uniform(0.05, 0.2, (2, 3)),
            np.tile(np.eye(3), (2, 1, 1)),
        ),
        halfspaces=collision.HalfSpaces.create([[0.0, 0.0, 1.0]], [-1.0]),
    )
    body, pairs = collision.prepare(arm)
    assert pairs.link_pairs  # the self pairs take part
    n = 2 * CHECK_CHUNK + 500  # three chunks of the fused pass
    q = rng.uniform(-3.0, 3.0, (n, arm.n_joints))
    q[5, 2] = np.nan
    fused = _fields(collision.check(arm, q, world))
    reference = _fields(jax.jit(_check_per_primitive)(arm, body, pairs, jnp.asarray(q), world))
    np.testing.assert_allclose(fused.pop("clearance"), reference.pop("clearance"), atol=1e-12)
    # ties: a primitive nearest to a joint centre is as near to both links that meet there
    # (their capsules share the end point), and either link may be reported
    tie = np.zeros(n, bool)
    links = ("link", "other", "world.link", "self_collision.first", "self_collision.second")
    for name in links:
        differs = fused[name] != reference[name]
        np.testing.assert_array_equal(np.abs(fused[name] - reference[name])[differs], 1)
        tie |= differs
    assert np.sum(tie) <= 1e-3 * n
    for name in links:
        fused[name][tie] = reference[name][tie]
    for part in ("world.clearance", "self_collision.clearance"):
        np.testing.assert_allclose(fused.pop(part), reference.pop(part), atol=1e-12)
    for name, value in reference.items():
        np.testing.assert_array_equal(fused[name], value, err_msg=name)
    assert 0 < np.sum(fused["collides"]) < n
    assert set(np.unique(fused["pair_kind"])) == {collision.ROBOT_WORLD, collision.SELF, -1}
    assert fused["status"][5] == Status.INVALID_INPUT
