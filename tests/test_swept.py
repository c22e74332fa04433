"""Straight edges certified piece by piece (``motion.swept``) and the curvature bound they use
(``motion.bound``): the bound against autodiff's second derivatives, certified edges against a
dense clearance check (``collision.check``, an independent code path), grazing edges refused."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxkin import collision, scara, serial
from jaxkin._splines import hermite
from jaxkin.motion import bound as mbound
from jaxkin.motion import collider, simplify, swept
from jaxkin.motion.space import joint_space
from tests.helpers import marked_slow, ur5_mixed_body

TOL = 1e-12  # the rounding term of float64 (the planner's 64 eps (1 + scale))
SLOW_MARK = [pytest.mark.slow]
_ur5 = ur5_mixed_body


ROBOTS = {
    "planar3r": lambda: serial.Planar3R(1.0, 0.7, 0.4, link_radius=0.05),
    "anthropomorphic": lambda: serial.Anthropomorphic(0.3, 0.25, 0.2, link_radius=0.02),
    "scara": lambda: scara.Scara(
        150.0,
        80.0,
        50.0,
        link_radius=4.0,
        limits=scara.JointLimits(np.array([-2.0, -2.0, 0.0]), np.array([2.0, 2.0, 120.0])),
    ),
    "ur5": _ur5,
}


# slow: their bounds and second derivatives compile for 5-10 s each (make test checks the
# bound through the certified edges of the planar scene)
@pytest.mark.parametrize("name", marked_slow(ROBOTS, ROBOTS))
def test_the_curvature_bound_holds_on_random_steps(name):
    """``|c''(t)|`` of every primitive point along ``q0 + t dq`` (autodiff, twice forward) is
    within ``|dq|^T M |dq|``, and the bound is attained within a factor of 3 somewhere."""
    robot = ROBOTS[name]()
    body, pairs = collider.prepare(robot)
    bound = mbound.motion_bound(robot, body, pairs.link_pairs)
    assert bound.proved and bound.curvature is not None
    links = np.asarray(body.sphere_link + body.capsule_link + body.capsule_link)
    points = np.concatenate(
        [np.asarray(x).reshape(-1, 3) for x in (body.sphere_center, body.capsule_a, body.capsule_b)]
    )
    space = joint_space(robot)
    rng = np.random.default_rng(0)
    q0 = space.lower + rng.uniform(size=(256, robot.n_joints)) * (space.upper - space.lower)
    dq = rng.normal(size=q0.shape) * 0.5 / np.asarray(space.weight)

    def placed(t, q0, dq):
        poses = robot.link_poses(q0 + t * dq)[links]
        return jnp.einsum("pij,pj->pi", poses[:, :3, :3], points) + poses[:, :3, 3]

    second = jax.vmap(jax.jacfwd(jax.jacfwd(placed)), in_axes=(None, 0, 0))
    size = np.linalg.norm(np.asarray(second(0.0, jnp.asarray(q0), jnp.asarray(dq))), axis=-1)
    bent = np.asarray(mbound.curvature_bound(bound.curvature, jnp.asarray(dq)))
    nc = body.num_capsules
    bent = np.concatenate([bent, bent[:, bent.shape[1] - nc :]], axis=1)  # both capsule ends
    assert np.all(size <= bent * (1 + 1e-9) + 1e-12)
    assert np.max(size / np.maximum(bent, 1e-12)) > 1 / 3


def _certify(robot, world, a, d, resolution=16.0, slots=64, chunk=32):
    body, pairs = collider.prepare(robot)
    bound = mbound.motion_bound(robot, body, pairs.link_pairs)
    space = joint_space(robot).astype(jnp.float64)

    def run(a, d):
        def touches(qa, qb, grow):
            return collider.piece_touches(robot, body, pairs, qa, qb, grow, world)

        return swept.edges_certified(
            touches,
            bound.curvature,
            space,
            a,
            d,
            jnp.asarray(resolution),
            jnp.asarray(TOL),
            slots,
            chunk,
        )

    return np.asarray(jax.jit(run)(jnp.asarray(a), jnp.asarray(d)))


def _dense_clearance(robot, world, a, d, steps=2001):
    """The smallest clearance along each edge ``a + t d`` at ``steps`` states."""
    t = np.linspace(0.0, 1.0, steps)[None, :, None]
    states = a[:, None] + t * d[:, None]
    return np.min(np.asarray(collision.check(robot, states, world).clearance), axis=1)


def _planar_scene():
    robot = serial.Planar2R(1.0, 0.8, link_radius=0.05)
    world = collision.World.create(
        spheres=collision.Spheres.create([[1.2, 0.6, 0.0], [-0.2, 1.3, 0.0]], [0.25, 0.2])
    )
    return robot, world


def _ur5_scene():
    rng = np.random.default_rng(4)
    world = collision.World.create(
        spheres=collision.Spheres.create(rng.uniform(-0.7, 0.7, (4, 3)), [0.08, 0.1, 0.06, 0.12]),
        boxes=collision.Boxes.create(
            rng.uniform(-0.7, 0.7, (2, 3)),
            [[0.1, 0.05, 0.2], [0.04, 0.2, 0.1]],
            np.stack([np.linalg.qr(rng.normal(size=(3, 3)))[0] for _ in range(2)]),
        ),
        cylinders=collision.Cylinders.create(
            [[0.4, -0.3, 0.2]], [0.05], [0.2], axis=[[0.0, 0.6, 0.8]]
        ),
    )
    return _ur5(), world


@pytest.mark.parametrize(
    "scene",
    [
        pytest.param(_planar_scene, id="planar2r"),
        pytest.param(_ur5_scene, id="ur5", marks=SLOW_MARK),
    ],
)
def test_certified_edges_are_free_under_a_dense_check(scene):
    """Random edges from free states: every certified edge is free at 2,001 states of a dense
    clearance check, the edges that collide there are refused, and every edge at least 2 cm
    clear is certified (the pieces reach contact within ``swept.LEVELS`` cuts)."""
    robot, world = scene()
    rng = np.random.default_rng(1)
    space = joint_space(robot)
    n = robot.n_joints
    a = space.lower + rng.uniform(size=(160, n)) * (space.upper - space.lower)
    a = a[~np.asarray(collision.check(robot, a, world).collides)][:64]
    d = rng.normal(size=a.shape) * 0.6
    good = _certify(robot, world, a, d)
    clearance = _dense_clearance(robot, world, a, d)
    assert np.any(good) and np.any(~good)  # both kinds among the edges
    assert np.all(clearance[good] > 0)
    assert np.all(good[clearance > 0.02])


def test_a_grazing_edge_is_refused_and_the_same_edge_a_millimetre_away_certified():
    """The arm's tip sweeps past a small ball between two states of the resolution: touching
    it (a dense check finds the contact) the edge is not certified; with the ball moved out
    so that the tip passes 1 mm from it, the edge is certified, though clearance balls would
    need thousands of states there."""
    robot = serial.Planar2R(1.0, 0.8, link_radius=0.01)
    a, d = np.array([[0.0, 0.0]]), np.array([[1.0, 0.0]])
    tip = 1.8 * np.array([np.cos(0.53), np.sin(0.53), 0.0])
    touching = collision.World.create(spheres=collision.Spheres.create([tip * 1.012], 0.012))
    assert _dense_clearance(robot, touching, a, d, 4001)[0] < 0
    assert not _certify(robot, touching, a, d)[0]
    # the ball's surface 1 mm beyond the tip capsule's reach (1.8 + 0.01)
    away = tip / 1.8 * (1.81 + 0.001 + 0.012)
    near = collision.World.create(spheres=collision.Spheres.create([away], 0.012))
    assert 0 < _dense_clearance(robot, near, a, d, 4001)[0] < 1.1e-3
    assert _certify(robot, near, a, d)[0]


def test_edges_that_start_in_collision_or_are_not_finite_are_refused():
    robot, world = _planar_scene()
    inside = np.array([[0.5, -0.4]])  # the elbow's link inside the first ball
    assert np.asarray(collision.check(robot, inside, world).collides)[0]
    a = np.concatenate([inside, [[0.0, 0.3], [0.0, 0.3]]])
    d = np.array([[0.1, 0.0], [np.nan, 0.0], [0.0, 0.0]])
    assert _certify(robot, world, a, d).tolist() == [False, False, True]


def _random_spline(robot, rng, knots_count=5, step=0.5):
    """Knots a random walk from a random state, chord parameters, natural-spline slopes."""
    space = joint_space(robot)
    n = robot.n_joints
    start = space.lower + rng.uniform(size=n) * (space.upper - space.lower)
    knots = start + np.cumsum(rng.normal(size=(knots_count, n)) * step, axis=0)
    knots = jnp.asarray(knots)
    count = jnp.int32(knots_count)
    space = space.astype(jnp.float64)
    s = simplify.chord_parameters(knots, count, space)
    return knots, s, simplify.spline_slopes(knots, s, count), count


@pytest.mark.parametrize(
    "name", marked_slow(["anthropomorphic", "ur5"], ["anthropomorphic", "ur5"])
)
def test_the_spline_bend_bounds_the_second_derivative_along_each_piece(name):
    """``spline_bend`` against autodiff: ``|d2c/dtau2|`` of every primitive point at 33 values
    of ``tau`` on each piece of random splines is within the piece's bound."""
    robot = ROBOTS[name]()
    body, pairs = collider.prepare(robot)
    bound = mbound.motion_bound(robot, body, pairs.link_pairs)
    links = np.asarray(body.sphere_link + body.capsule_link + body.capsule_link)
    points = np.concatenate(
        [np.asarray(x).reshape(-1, 3) for x in (body.sphere_center, body.capsule_a, body.capsule_b)]
    )
    rng = np.random.default_rng(2)
    tau = jnp.linspace(0.0, 1.0, 33)

    def placed(t, y0, m0, y1, m1, h):
        poses = robot.link_poses(hermite(y0, m0, y1, m1, h, t)[0])[links]
        return jnp.einsum("pij,pj->pi", poses[:, :3, :3], points) + poses[:, :3, 3]

    # every tau of every piece at once: (pieces, tau, primitive points)
    second = jax.jit(
        jax.vmap(
            jax.vmap(jax.jacfwd(jax.jacfwd(placed)), in_axes=(0, None, None, None, None, None)),
            in_axes=(None, 0, 0, 0, 0, 0),
        )
    )
    ratios = []
    for _ in range(4):
        knots, s, slopes, count = _random_spline(robot, rng)
        bend, _ = swept.spline_bend(bound.prims, bound.curvature, knots, s, slopes, count)
        bend = np.asarray(bend)
        nc = body.num_capsules
        bend = np.concatenate([bend, bend[:, bend.shape[1] - nc :]], axis=1)
        out = second(tau, knots[:-1], slopes[:-1], knots[1:], slopes[1:], jnp.diff(s))
        size = np.max(np.linalg.norm(np.asarray(out), axis=-1), axis=1)  # (pieces, points)
        assert np.all(size <= bend * (1 + 1e-9) + 1e-12)
        ratios.append(np.max(size / np.maximum(bend, 1e-12)))
    assert max(ratios) > 0.1  # not vacuous


@pytest.mark.slow
def test_certified_spline_pieces_are_free_under_a_dense_check():
    """Random splines in the planar scene: every certified piece is free at 1,001 states of
    a dense clearance check along it, and some pieces are certified and some not."""
    robot, world = _planar_scene()
    body, pairs = collider.prepare(robot)
    bound = mbound.motion_bound(robot, body, pairs.link_pairs)
    space = joint_space(robot).astype(jnp.float64)

    @jax.jit
    def certify(knots, s, slopes, count):
        def touches(qa, qb, grow):
            return collider.piece_touches(robot, body, pairs, qa, qb, grow, world)

        return swept.spline_certified(
            touches, bound.prims, bound.curvature, space, knots, s, slopes, count,
            jnp.asarray(16.0), jnp.asarray(TOL), 32, 32,
        )  # fmt: skip

    rng = np.random.default_rng(3)
    tau = np.linspace(0.0, 1.0, 1001)[None, :, None]
    goods, states = [], []
    for _ in range(12):
        knots, s, slopes, count = _random_spline(robot, rng, step=0.7)
        goods.append(np.asarray(certify(knots, s, slopes, count)))
        k_np, m_np, h = np.asarray(knots), np.asarray(slopes), np.diff(np.asarray(s))
        piece = hermite(k_np[:-1, None], m_np[:-1, None], k_np[1:, None], m_np[1:, None],
                        h[:, None, None], tau)  # fmt: skip
        states.append(piece[0])  # (pieces, 1001, n)
    good = np.concatenate(goods)
    clearance = np.asarray(collision.check(robot, np.concatenate(states), world).clearance)
    clearance = np.min(clearance, axis=1)
    assert np.any(good) and np.any(~good)
    assert np.all(clearance[good] > 0)
