"""``jaxkin.compiled``: a program compiled for one robot, world layout and batch shape.

Each handle's results are the public entry point's on the same input: statuses, verdicts and
integer fields identical, floating values to 4 ulp of the robot's size (the handle's program
holds the public one inside a program of its own, which XLA may fuse differently); a call
compiles nothing, another world of the same layout is rebound without compiling, and bad
arguments are refused where the handle is made, naming the argument.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxkin
from jaxkin import collision, scara, serial
from jaxkin.jet import Jet

from .helpers import UR5, compilations, ur5_mixed_body

_ur5 = ur5_mixed_body


def _world(seed: int, spheres: int = 5) -> collision.World:
    rng = np.random.default_rng(seed)
    return collision.World.create(
        spheres=collision.Spheres.create(
            rng.uniform(-0.8, 0.8, (spheres, 3)), rng.uniform(0.03, 0.12, spheres)
        ),
        boxes=collision.Boxes.create(
            rng.uniform(-0.8, 0.8, (3, 3)),
            rng.uniform(0.03, 0.15, (3, 3)),
            np.stack([np.linalg.qr(rng.normal(size=(3, 3)))[0] for _ in range(3)]),
        ),
        halfspaces=collision.HalfSpaces.create([[0.0, 0.0, 1.0]], [-0.6]),
    )


def _equal(got, want, scale: float = 1.0) -> None:
    """Same types, shapes and dtypes; integers and booleans equal, floats to 4 ulp of
    ``scale`` (NaN where NaN)."""
    assert type(got) is type(want)
    for a, b in zip(jax.tree.leaves(got), jax.tree.leaves(want), strict=True):
        a, b = np.asarray(a), np.asarray(b)
        assert a.shape == b.shape and a.dtype == b.dtype
        if a.dtype.kind == "f":
            tol = 4 * np.finfo(a.dtype).eps * scale
            np.testing.assert_allclose(a, b, rtol=0, atol=tol)
        else:
            np.testing.assert_array_equal(a, b)


def test_ik_and_fk_handles_equal_the_pipeline_and_compile_once():
    """SCARA and a screw chain, batch ``()``, ``(1,)`` and ``(4,)``, at rest and with rates:
    the handle's results are ``jaxkin.ik``/``fk``'s; calls compile nothing."""
    robot = scara.Scara.paper()
    targets = np.array([[60.0, 70.0, 40.0], [500.0, 0.0, 40.0], [np.nan, 1.0, 2.0], [90, 0, 50]])
    for batch, x in (((), targets[0]), ((1,), targets[:1]), ((4,), targets)):
        handle = jaxkin.compiled(jaxkin.ik, robot, batch=batch, dtype=np.float64)
        with compilations() as count:
            got = handle(x)
            again = handle(x + 1.0)
        assert count.n == 0
        size = float(robot.length_scale())
        _equal(got, jaxkin.ik(robot, x), size)
        _equal(again, jaxkin.ik(robot, x + 1.0), size)
        q = got.q.p
        fk = jaxkin.compiled(jaxkin.fk, robot, batch=batch, dtype=np.float64)
        _equal(fk(q), jaxkin.fk(robot, q), size)
    moving = Jet(targets[:1], np.ones((1, 3)), np.zeros((1, 3)))
    handle = jaxkin.compiled(jaxkin.ik, robot, batch=1, branch=-1, rates=True, dtype=np.float64)
    _equal(handle(moving), jaxkin.ik(robot, moving, branch=-1), float(robot.length_scale()))
    chain = serial.from_urdf(UR5, "tool0")
    q = np.random.default_rng(0).uniform(-2.0, 2.0, (3, chain.n_joints))
    handle = jaxkin.compiled(jaxkin.fk, chain, batch=3, dtype=np.float64)
    _equal(handle(q), jaxkin.fk(chain, q))


def test_handles_refuse_bad_arguments_when_made():
    robot = scara.Scara.paper()
    with pytest.raises(ValueError, match="entry"):
        jaxkin.compiled(print, robot)
    with pytest.raises(ValueError, match="robot"):
        jaxkin.compiled(jaxkin.ik, "scara")
    with pytest.raises(ValueError, match="branch"):
        jaxkin.compiled(jaxkin.ik, robot, branch=7)
    with pytest.raises(ValueError, match="batch"):
        jaxkin.compiled(jaxkin.fk, robot, batch=(2, -1))
    with pytest.raises(ValueError, match="batch"):
        jaxkin.compiled(jaxkin.fk, robot, batch=1.5)
    with pytest.raises(ValueError, match="dtype"):
        jaxkin.compiled(jaxkin.fk, robot, dtype=np.int32)
    with pytest.raises(ValueError, match="option"):
        jaxkin.compiled(jaxkin.ik, robot, tolerance=1.0)
    arm = _ur5()
    world = _world(1)
    with pytest.raises(ValueError, match="world"):
        jaxkin.compiled(collision.collides, arm, "world")
    with pytest.raises(ValueError, match="margin"):
        jaxkin.compiled(collision.collides, arm, world, margin=np.nan)
    with pytest.raises(ValueError, match="resolution"):
        jaxkin.compiled(collision.validate_motions, arm, world, 0.0, 16)
    with pytest.raises(ValueError, match="samples"):
        jaxkin.compiled(collision.validate_motions, arm, world, 8.0, 1)
    handle = jaxkin.compiled(jaxkin.fk, robot, batch=1, dtype=np.float64)
    with pytest.raises(TypeError):  # another shape: refused by the executable
        handle(np.zeros((2, 3)))


@pytest.mark.slow  # the fast tier keeps the low-latency handles' equality
def test_collision_handles_equal_the_public_checks_and_rebind_worlds():
    """Collides, check and validate_motions through their handles (float64, batch 1 and 8):
    the public calls' results to the bit; another world of the same layout rebound without
    compiling gives that world's results; a world of another layout is refused."""
    robot = _ur5()
    world, other = _world(2), _world(3)
    rng = np.random.default_rng(4)
    q = rng.uniform(-3.0, 3.0, (8, robot.n_joints))
    for batch in (1, 8):
        qs = q[:batch]
        verdict = jaxkin.compiled(collision.collides, robot, world, batch=batch, dtype=np.float64)
        check = jaxkin.compiled(collision.check, robot, world, batch=batch, dtype=np.float64)
        _equal(verdict(qs), collision.collides(robot, qs, world))
        _equal(check(qs), collision.check(robot, qs, world))
        with compilations() as count:
            moved = verdict.rebound(other)
            result = moved(qs)
        assert count.n == 0
        _equal(result, collision.collides(robot, qs, other))
        _equal(verdict(qs), collision.collides(robot, qs, world))  # the first world kept
    assert 0 < np.sum(collision.collides(robot, q, world).collides) < 8
    edges = jaxkin.compiled(
        collision.validate_motions, robot, world, 6.0, 16, batch=8, dtype=np.float64
    )
    a, b = q, rng.uniform(-3.0, 3.0, (8, robot.n_joints))
    _equal(edges(a, b), collision.validate_motions(robot, a, b, world, 6.0, samples=16))
    with pytest.raises(ValueError, match="world: another layout"):
        verdict.rebound(_world(5, spheres=collision.OBSTACLE_BUCKET + 1))


@pytest.mark.slow  # the fast tier is near its 5 minutes
def test_programs_do_not_grow_with_obstacles_primitives_or_pairs():
    """The verdict's and the check's programs for 10 and 100 obstacles of each kind, and for
    bodies of 60 and 400 spheres (with their self pairs), hold the same operations within a
    few percent: every count is a loop bound or an array size, not written-out code; so do
    the verdict's through the groups' bounds for bodies of spheres alone of 360 and 900."""
    from jaxkin.collision import culled

    rng = np.random.default_rng(6)

    def world(m: int) -> collision.World:
        return collision.World.create(
            spheres=collision.Spheres.create(rng.normal(size=(m, 3)), np.full(m, 0.1)),
            boxes=collision.Boxes.create(rng.normal(size=(m, 3)), np.full((m, 3), 0.1)),
        )

    def arm(
        per_link: int, links=("upper_arm_link", "forearm_link", "wrist_1_link", "wrist_2_link")
    ):
        spheres = {
            name: (rng.normal(scale=0.05, size=(per_link, 3)), np.full(per_link, 0.02))
            for name in links
        }
        return serial.from_urdf(UR5, "tool0").with_link_spheres(spheres)

    def size(kernel, robot, w) -> int:
        """Operations in the lowered program, constants (the data of tables) left out."""
        body, pairs = collision.prepare(robot)
        q = jnp.zeros((4, robot.n_joints))
        fn = jax.jit(lambda q, w, body: kernel(robot, body, pairs, q, w, 0.0))
        text = fn.lower(q, w, body).as_text()
        return sum(1 for line in text.splitlines() if " = " in line and "constant" not in line)

    small_arm, large_arm = arm(15), arm(100)
    for kernel in (collision.collides_kernel, collision.check_kernel):
        by_world = [size(kernel, small_arm, world(m)) for m in (10, 100)]
        by_body = [size(kernel, robot, world(10)) for robot in (small_arm, large_arm)]
        for sizes in (by_world, by_body):
            assert max(sizes) <= 1.05 * min(sizes), (kernel.__name__, sizes)
    # spheres on every link: the verdict through the groups' bounds (collision.culled)
    body = small_arm.collision_body()
    every = tuple(body.links[i] for i in sorted({*body.sphere_link, *body.capsule_link}))
    grouped = [arm(40, every), arm(100, every)]
    assert all(culled.groups_of(*collision.prepare(robot)) is not None for robot in grouped)
    by_world = [size(collision.collides_kernel, grouped[0], world(m)) for m in (10, 100)]
    by_body = [size(collision.collides_kernel, robot, world(10)) for robot in grouped]
    for sizes in (by_world, by_body):
        assert max(sizes) <= 1.05 * min(sizes), ("culled", sizes)


def test_a_far_padding_obstacle_loosens_no_other_test():
    """Float32: one padding sphere 100 km away leaves the verdict of configurations a few
    centimetres clear of the real obstacles unchanged (the rounding tolerance follows each
    obstacle's own coordinates, not the world's largest)."""
    robot = _ur5()
    near = _world(7)
    q = np.random.default_rng(8).uniform(-3.0, 3.0, (400, robot.n_joints)).astype(np.float32)
    result = collision.check(robot, q, near.astype(np.float32))
    clearance = np.asarray(result.world.clearance)  # the wrist's self pair stays 4.65 mm apart
    clear = (clearance > 0.01) & (clearance < 0.1) & ~np.asarray(result.collides)
    assert np.sum(clear) >= 10
    padded = collision.World.create(
        spheres=collision.Spheres.create(
            np.concatenate([np.asarray(near.spheres.center), [[1e5, 0.0, 0.0]]]),
            np.concatenate([np.asarray(near.spheres.radius), [0.1]]),
        ),
        boxes=near.boxes,
        halfspaces=near.halfspaces,
        dtype=np.float32,
    )
    flagged = np.asarray(collision.collides(robot, q, padded).collides)
    assert not np.any(flagged[clear])


def test_new_batch_sizes_and_worlds_within_their_buckets_compile_nothing():
    """After one call, batches of other sizes (up to the padded size class) and worlds whose
    obstacle counts stay within their buckets (``collision.OBSTACLE_BUCKET``) compile
    nothing in ``collides``, ``check`` and ``validate_motions``; the padded obstacles (the
    last one repeated) change no verdict, clearance or reported obstacle."""
    robot = _ur5()
    rng = np.random.default_rng(9)
    q = rng.uniform(-3.0, 3.0, (30, robot.n_joints))
    first, other = _world(10, spheres=5), _world(11, spheres=7)
    assert collision.OBSTACLE_BUCKET >= 7
    collision.collides(robot, q[:10], first)
    collision.check(robot, q[:10], first)
    collision.validate_motions(robot, q[:10], q[15:25], first, 4.0, samples=16)
    with compilations() as count:
        for n, world in ((7, other), (13, first), (3, other)):
            collision.collides(robot, q[:n], world)
            result = collision.check(robot, q[:n], world)
            collision.validate_motions(robot, q[:n], q[15 : 15 + n], world, 4.0, samples=16)
    assert count.n == 0
    bucketed = other.bucketed()
    assert len(bucketed.spheres) == collision.OBSTACLE_BUCKET and len(bucketed.boxes) == 8
    assert bucketed.bucketed().layout() == bucketed.layout()
    exact = jax.jit(collision.check_kernel)(robot, *collision.prepare(robot), q[:3], other)
    _equal(result, exact)


def test_a_world_is_bucketed_once_and_a_traced_one_every_time():
    """``World.bucketed`` of a concrete world is padded once and kept (a check per call reuses
    it), equal leaf for leaf to a fresh padding; under ``jax.jit`` the traced world is padded
    too."""
    world = _world(9, spheres=5)
    padded = world.bucketed()
    assert world.bucketed() is padded
    fresh = collision.World.create(
        spheres=world.spheres, boxes=world.boxes, halfspaces=world.halfspaces
    ).bucketed()
    assert fresh is not padded and jax.tree.structure(fresh) == jax.tree.structure(padded)
    for a, b in zip(jax.tree.leaves(fresh), jax.tree.leaves(padded), strict=True):
        np.testing.assert_array_equal(np.asarray(a), np.asarray(b))
    assert padded.spheres.radius.shape == (collision.OBSTACLE_BUCKET,)

    @jax.jit
    def count(w):
        return w.bucketed().spheres.radius.shape[0]

    assert count(world) == collision.OBSTACLE_BUCKET
    assert count(world) == collision.OBSTACLE_BUCKET


def test_a_repeated_single_state_is_answered_by_a_handle_of_its_own(monkeypatch):
    """``collision.collides`` of one configuration asked again and again (a planner's loop)
    is answered by a compiled handle after ``HOT_AFTER`` calls: the usual path's verdicts and
    statuses, for a free and a colliding state, ``(n,)`` and ``(1, n)``; once hot, calls
    compile nothing; another world object gets its own answers (never the first world's);
    bad arguments are still refused naming them; a list and a traced ``q`` take the usual
    path."""
    from jaxkin import _batching
    from jaxkin.collision import verdict

    monkeypatch.setattr(_batching, "HOT_AFTER", 2)
    verdict.HOT_STATES.clear()
    robot = _ur5()
    world, other = _world(2), _world(3)
    rng = np.random.default_rng(4)
    q = rng.uniform(-3.0, 3.0, (64, robot.n_joints))
    hits = np.asarray(collision.check(robot, q, world).collides)
    free, hit = q[np.argmin(hits)], q[np.argmax(hits)]
    assert not hits[np.argmin(hits)] and hits[np.argmax(hits)]
    for x in (free, hit[None], hit):
        want = collision.check(robot, x, world)
        for _ in range(4):
            got = collision.collides(robot, x, world)
            np.testing.assert_array_equal(got.collides, want.collides)
            np.testing.assert_array_equal(got.status, want.status)
    assert len(verdict.HOT_STATES.programs) == 2  # one per shape: (n,) and (1, n)
    with compilations() as count:
        for x in (free, hit[None], hit):
            collision.collides(robot, x, world)
    assert count.n == 0
    for x in (free, hit):
        for _ in range(3):
            got = collision.collides(robot, x, other)
            np.testing.assert_array_equal(got.collides, collision.check(robot, x, other).collides)
    with pytest.raises(ValueError, match="q: expected shape"):
        collision.collides(robot, free[:3], world)
    with pytest.raises(ValueError, match="margin"):
        collision.collides(robot, free, world, margin=float("nan"))
    assert bool(collision.collides(robot, hit.tolist(), world).collides)
    traced = jax.jit(lambda x: collision.collides(robot, x, world).collides)
    assert bool(traced(hit)) and not bool(traced(free))
    verdict.HOT_STATES.clear()
