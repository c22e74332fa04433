"""``collision.collides``: the verdict alone against the exact clearance of ``collision.check``.

Reference: ``check(robot, q, world, margin).collides`` (exact signed distances, square roots,
the robot's own ``link_poses``). The verdict may only differ within its rounding tolerance
``16 eps (1 + X)`` of contact (``collision.verdict``'s docstring): no configuration whose exact
clearance is ``<= margin`` is missed, and none farther than the tolerance from contact is
flagged. Cheap robots here (a URDF chain with spheres and skeleton capsules, the PUMA-560 with
capsules); the Panda and UR5 of example-robot-data with mesh covers are in the slow tier.
"""

from __future__ import annotations

from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxkin import Status, collision, serial

from .helpers import compilations

UR5 = Path(__file__).resolve().parents[1] / "examples" / "ur5.urdf"


def _ur5():
    """Spheres on three links (the Chain's rows placement through link home poses), the
    skeleton's capsules on the others (the exact capsule distances). The wrist's sphere
    clears the wrist_1 capsule by 0.025 in every configuration (more than a margin)."""
    spheres = {
        "upper_arm_link": (np.array([[0.0, 0.0, 0.1], [0.0, 0.0, 0.3]]), np.array([0.07, 0.06])),
        "forearm_link": (np.array([[0.0, 0.0, 0.05], [0.0, 0.0, 0.25]]), np.array([0.06, 0.05])),
        "wrist_3_link": (np.zeros((1, 3)), np.array([0.03])),
    }
    return serial.from_urdf(UR5, "tool0").with_link_radius(0.04).with_link_spheres(spheres)


def _world(seed: int, scale: float = 0.8) -> collision.World:
    rng = np.random.default_rng(seed)
    return collision.World.create(
        spheres=collision.Spheres.create(
            rng.uniform(-scale, scale, (5, 3)), rng.uniform(0.03, 0.12, 5)
        ),
        capsules=collision.Capsules.create(
            rng.uniform(-scale, scale, (2, 3)), rng.uniform(-scale, scale, (2, 3)), [0.03, 0.05]
        ),
        boxes=collision.Boxes.create(
            rng.uniform(-scale, scale, (3, 3)),
            rng.uniform(0.03, 0.15, (3, 3)),
            np.stack([np.linalg.qr(rng.normal(size=(3, 3)))[0] for _ in range(3)]),
        ),
        halfspaces=collision.HalfSpaces.create([[0.0, 0.0, 1.0]], [-0.6]),
    )


def _agree(robot, q, world, margin, dtype):
    """The verdict flags every exact collision; away from contact the two are equal."""
    exact = collision.check(robot, q, world, margin)
    fast = collision.collides(robot, q, world, margin)
    hit, flagged = np.asarray(exact.collides), np.asarray(fast.collides)
    assert flagged.shape == hit.shape == np.shape(q)[:-1]
    assert not np.any(hit & ~flagged), "a collision the exact clearance reports is missed"
    tol = 1e-4 if dtype == "float32" else 1e-11  # well above 16 eps (1 + X)
    near = np.abs(np.asarray(exact.clearance, np.float64) - margin) <= tol
    np.testing.assert_array_equal(flagged[~near], hit[~near])
    np.testing.assert_array_equal(np.asarray(fast.status), np.asarray(exact.status))
    return hit


def test_collides_equals_the_exact_verdict():
    """Float64, a URDF chain (spheres and capsules) over two chunks, two margins, one
    configuration alone."""
    robot = _ur5()
    world = _world(2)
    rng = np.random.default_rng(1)
    q = rng.uniform(-3.0, 3.0, (700, robot.n_joints))
    for margin in (0.0, 0.02):
        hit = _agree(robot, q, world, margin, "float64")
        assert 0.05 < np.mean(hit) < 0.95  # both verdicts occur
    _agree(robot, q[3], world, 0.0, "float64")


@pytest.mark.slow
@pytest.mark.parametrize("dtype", ["float64", "float32"])
def test_collides_equals_the_exact_verdict_shapes_and_robots(dtype):
    rng = np.random.default_rng(1)
    robots = [_ur5(), serial.Puma560(link_radius=0.05)]
    for robot, seed in zip(robots, (2, 3), strict=True):
        world = _world(seed).astype(dtype)
        q = rng.uniform(-3.0, 3.0, (700, robot.n_joints)).astype(dtype)  # two chunks
        for margin in (0.0, 0.02):
            hit = _agree(robot, q, world, margin, dtype)
            assert 0.05 < np.mean(hit) < 0.95
        for shape in [(), (7,), (3, 5)]:
            qs = rng.uniform(-3.0, 3.0, (*shape, robot.n_joints)).astype(dtype)
            _agree(robot, qs, world, 0.0, dtype)


@pytest.mark.slow
@pytest.mark.parametrize("dtype", ["float64", "float32"])
def test_collides_in_contact_within_rounding(dtype):
    """Margins set to configurations' own exact clearances (contact within rounding): the
    exact verdict is True, and so is the fast one; a margin 1e-3 below it is free for both."""
    robot = _ur5()
    world = _world(4).astype(dtype)
    q = np.random.default_rng(5).uniform(-3.0, 3.0, (40, robot.n_joints)).astype(dtype)
    for k in range(0, 40, 5):
        margin = float(collision.check(robot, q[k], world).clearance)
        assert bool(collision.check(robot, q[k], world, margin).collides)
        assert bool(collision.collides(robot, q[k], world, margin).collides)
        below = margin - 1e-3
        assert not bool(collision.check(robot, q[k], world, below).collides)
        assert not bool(collision.collides(robot, q[k], world, below).collides)


def test_collides_nan_rows_and_no_recompilation():
    robot = _ur5()
    world = _world(6)
    q = np.random.default_rng(7).uniform(-3.0, 3.0, (6, robot.n_joints))
    q[2, 1] = np.nan
    q[4, 0] = np.inf
    out = collision.collides(robot, q, world)
    assert out.collides[2] and out.collides[4]
    assert out.status[2] == Status.INVALID_INPUT and out.status[4] == Status.INVALID_INPUT
    assert np.all(np.asarray(out.status)[[0, 1, 3, 5]] != Status.INVALID_INPUT)
    moved = _world(8)
    with compilations() as count:
        collision.collides(robot, q, moved)
        collision.collides(robot, q, moved, margin=0.01)
    assert count.n == 0
    with pytest.raises(ValueError, match="q"):
        collision.collides(robot, q[:, :3], world)


def test_collides_arguments_name_the_argument():
    """A NaN margin would make every configuration free (``clearance <= NaN`` is False)."""
    robot = _ur5()
    world = _world(6)
    q = np.random.default_rng(7).uniform(-3.0, 3.0, (4, robot.n_joints))
    for margin in (np.nan, -np.inf, np.zeros(2), "0"):
        with pytest.raises(ValueError, match="margin must be a finite number"):
            collision.collides(robot, q, world, margin)
    with pytest.raises(ValueError, match="q: expected real joint coordinates"):
        collision.collides(robot, q + 0j, world)
    with pytest.raises(ValueError, match="robot: expected a robot"):
        collision.collides(None, q, world)
    exact = collision.collides(robot, q, world, 0.01)
    same = collision.collides(robot, q, world, np.float32(0.01))
    np.testing.assert_array_equal(same.collides, exact.collides)


def test_validate_motions_with_the_verdict_alone():
    robot = _ur5()
    world = _world(9)
    rng = np.random.default_rng(10)
    a, b = rng.uniform(-2.0, 2.0, (2, 12, robot.n_joints))
    exact = collision.validate_motions(robot, a, b, world, 4.0, samples=16)
    fast = collision.validate_motions(robot, a, b, world, 4.0, samples=16, clearance=False)
    assert 0 < np.sum(exact.valid) < 12
    np.testing.assert_array_equal(fast.valid, exact.valid)
    np.testing.assert_array_equal(fast.first, exact.first)
    assert np.all(np.isnan(np.asarray(fast.clearance)))


def _spheres_ur5():
    """Spheres on every link of the UR5: the forearm with 7, the wrist links with one each."""
    line = lambda k, length, r: (  # noqa: E731
        np.stack([np.zeros(k), np.zeros(k), np.linspace(0.0, length, k)], -1),
        np.full(k, r),
    )
    spheres = {
        "base_link": line(2, 0.1, 0.05),
        "shoulder_link": line(2, 0.1, 0.05),
        "upper_arm_link": line(4, 0.4, 0.05),
        "forearm_link": line(7, 0.35, 0.04),
        "wrist_1_link": line(1, 0.0, 0.02),
        "wrist_2_link": line(1, 0.0, 0.02),
        "wrist_3_link": line(1, 0.0, 0.02),
    }
    return serial.from_urdf(UR5, "tool0").with_link_spheres(spheres)


@pytest.mark.slow
@pytest.mark.parametrize("dtype", ["float64", "float32"])
def test_sphere_body_over_chunks_shapes_contact_and_nan(dtype):
    """A sphere body, both dtypes, over two chunks of the verdict: the exact verdict's flags
    (``_agree``); batch shapes () (7,) (3,5); margins at configurations' own clearances
    (contact within rounding); NaN rows; a moved obstacle reuses the compilation."""
    robot = _spheres_ur5()
    world = _world(13).astype(dtype)
    rng = np.random.default_rng(14)
    q = rng.uniform(-3.0, 3.0, (700, robot.n_joints)).astype(dtype)
    q[5, 2] = np.nan
    out = collision.collides(robot, q, world)
    assert out.status[5] == Status.INVALID_INPUT
    hit = _agree(robot, q[:300], world, 0.01, dtype)
    assert 0.05 < np.mean(hit) < 0.95
    for shape in [(), (7,), (3, 5)]:
        qs = rng.uniform(-3.0, 3.0, (*shape, robot.n_joints)).astype(dtype)
        _agree(robot, qs, world, 0.0, dtype)
    for k in range(0, 40, 8):
        margin = float(collision.check(robot, q[k], world).clearance)
        assert bool(collision.collides(robot, q[k], world, margin).collides)
        assert not bool(collision.collides(robot, q[k], world, margin - 1e-3).collides)
    with compilations() as count:
        collision.collides(robot, q, _world(15).astype(dtype))
    assert count.n == 0


def test_pair_chunks_cover_every_self_pair_once_and_halving_is_the_minimum():
    """``rows.pair_chunks``: the chunks of self pairs hold every pair once, in order, the
    last chunk padded with the last pair (random pair sets, one chunk and several);
    ``tree_min`` and ``tree_argmin`` equal ``jnp.min``/``argmin`` along either axis for even
    and odd lengths (ties: the first)."""
    from jaxkin.collision import rows

    rng = np.random.default_rng(16)
    for count in (1, 7, rows.PAIR_CHUNK, rows.PAIR_CHUNK + 5, 3 * rows.PAIR_CHUNK - 1):
        pairs = rng.integers(0, 90, (count, 2))
        firsts, seconds = rows.pair_chunks(pairs[:, 0], pairs[:, 1])
        assert firsts.shape == seconds.shape and firsts.size >= count
        flat = list(zip(firsts.ravel().tolist(), seconds.ravel().tolist(), strict=True))
        assert flat[:count] == [tuple(p) for p in pairs.tolist()]
        assert set(flat[count:]) <= {tuple(pairs[-1].tolist())}
    for n in (1, 2, 5, 8):
        x = rng.normal(size=(n, 4, 3))
        np.testing.assert_array_equal(rows.tree_min(jnp.asarray(x)), x.min(axis=0))
        np.testing.assert_array_equal(rows.tree_min(jnp.asarray(x.transpose(1, 0, 2)), 1), x.min(0))
        value, code = rows.tree_argmin(jnp.asarray(x), jnp.arange(n)[:, None, None])
        np.testing.assert_array_equal(value, x.min(axis=0))
        np.testing.assert_array_equal(code, x.argmin(axis=0))
    tied = jnp.asarray([[1.0, 2.0], [1.0, 0.5], [3.0, 0.5]])
    _, code = rows.tree_argmin(tied, jnp.arange(3)[:, None])
    np.testing.assert_array_equal(code, [0, 1])


def test_loops_skip_the_trailing_copies_of_a_kind_s_last_obstacle():
    """``rows.distinct_rows``: the rows up to the first of the trailing copies of the last
    (a NaN field never equal, so never dropped); ``rows.loop_world`` with a ``stop`` (or
    ``skip_copies``) tests them and no more (the largest index it tests), without it every
    step of ``chunk`` obstacles."""
    from jaxkin.collision import rows

    a, b, c = np.eye(3)
    cases = [
        ([a, b, c, c, c, c, c], 3),
        ([a, b, c], 3),
        ([c, c, c, c], 1),
        ([a, c, b, c, c], 4),  # a copy before a different row is kept
        ([a, np.full(3, np.nan), c, c], 3),
        ([a, b, np.full(3, np.nan), np.full(3, np.nan)], 4),
    ]
    for row_list, expected in cases:
        centre = jnp.asarray(np.stack(row_list))
        radius = jnp.ones(len(row_list))
        assert int(rows.distinct_rows((centre, radius))) == expected
        # a different radius on a copy makes it a row of its own
        assert int(rows.distinct_rows((centre, radius.at[-1].set(2.0)))) == len(row_list)

        def largest(arrays=(centre, radius), **how):
            return int(
                rows.loop_world(
                    lambda obstacle, j: j, arrays, jnp.int32(-1), jnp.maximum, jnp.maximum,
                    chunk=2, **how,
                )
            )  # fmt: skip

        padded = -(-len(row_list) // 2) * 2  # two obstacles per step
        assert largest(stop=lambda carry: jnp.bool_(False)) == expected - 1
        assert largest(skip_copies=True) == expected - 1
        assert largest() == padded - 1


def test_fold_passes_over_the_steps_not_needed():
    """``rows.fold`` with ``needed``: the steps it runs are those ``needed`` marks (in order,
    the carry as it stands), up to ``used``; with a ``stop`` it ends there."""
    from jaxkin.collision import rows

    marks = jnp.asarray([True, False, False, True, True, False, True])

    def run(**how):
        visits = rows.fold(
            7, lambda k, seen: seen.at[k].set(True), jnp.zeros(7, bool), **how
        )  # fmt: skip
        return np.flatnonzero(np.asarray(visits)).tolist()

    assert run(stop=None, needed=lambda k, seen: marks[k]) == [0, 3, 4, 6]
    assert run(stop=None, used=jnp.int32(5), needed=lambda k, seen: marks[k]) == [0, 3, 4]
    assert run(stop=lambda seen: jnp.sum(seen) >= 2, needed=lambda k, seen: marks[k]) == [0, 3]
    # the carry decides: a step is needed while fewer than 2 were run before it
    assert run(stop=None, needed=lambda k, seen: (jnp.sum(seen) < 2) & marks[k]) == [0, 3]
    assert run(stop=None, needed=lambda k, seen: jnp.bool_(False)) == []


def test_frame_bounds_hold_their_spheres():
    """``rows.place_bounded``: per frame carrying spheres, the placed bound ``(g, R)`` holds
    every sphere ``(c, r)`` of that frame, ``|c - g| + r <= R``, at every configuration
    (float64, the UR5 with spheres on every link: link home poses between frames and links),
    and the spheres are those of ``rows.place``."""
    from jaxkin.collision import rows

    robot = _spheres_ur5()
    body, _ = collision.prepare(robot)
    q = jnp.asarray(np.random.default_rng(3).uniform(-3.0, 3.0, (40, robot.n_joints)))
    placed, bounds = rows.place_bounded(robot, body, q)
    np.testing.assert_array_equal(placed.spheres, rows.place(robot, body, q).spheres)
    _, of_link, _ = rows.frames_of(robot, q)
    frame = np.asarray(of_link)[np.asarray(body.sphere_link)]
    which = np.searchsorted(np.unique(frame), frame)  # each sphere's bound
    c, g = np.asarray(placed.spheres), np.asarray(bounds.center)[:, which]  # (3, S, B)
    gap = np.linalg.norm(c - g, axis=0) + np.asarray(body.sphere_radius)[:, None]
    assert np.all(gap <= np.asarray(bounds.reach)[which])
    scale = np.max(np.abs(np.asarray(bounds.center)) + np.asarray(bounds.reach)[None], (0, 1))
    np.testing.assert_allclose(bounds.scale, scale, rtol=1e-12)


@pytest.mark.slow
@pytest.mark.parametrize("dtype", ["float64", "float32"])
def test_frame_bounds_give_the_same_verdicts(dtype):
    """``collides_kernel(..., frame_bounds=True)`` (the motion planner's states) passes over
    the obstacles no frame's bound comes near and gives the dense tests' verdicts bit for
    bit: every kind of obstacle, margins of both signs, configurations in contact within
    rounding (margins set to their own exact clearances), one configuration and a chunk; and
    obstacles (a small sphere, a half-space) touching, or 1 mm from, the sphere that reaches
    farthest from its frame's bound, where a bound 2 mm too small misses the contact."""
    robot = _spheres_ur5()
    body, pairs = collision.prepare(robot)
    rng = np.random.default_rng(11)
    q = rng.uniform(-3.0, 3.0, (64, robot.n_joints)).astype(dtype)

    @jax.jit
    def both(q, world, margin):
        return tuple(
            collision.collides_kernel(robot, body, pairs, q, world, margin, frame_bounds=b).collides
            for b in (False, True)
        )  # fmt: skip

    flagged = []
    for draw in (1, 2):
        world = _every_kind(draw).astype(dtype)
        contact = float(collision.check(robot, q[5], world).clearance)
        for margin in (0.0, 0.03, -0.01, contact):
            for chunk in (q, q[5:6]):
                dense, bounded = both(chunk, world, jnp.asarray(margin, dtype))
                np.testing.assert_array_equal(bounded, dense)
                flagged.append(np.asarray(dense))
        assert bool(both(q[5:6], world, jnp.asarray(contact, dtype))[1][0])  # in contact
    assert 0.1 < np.mean(np.concatenate(flagged)) < 0.9  # both verdicts occur

    # at the edge of a bound: an obstacle touching (or 1 mm from) the sphere that reaches
    # farthest from its frame's bound, on the far side, where the coarse test has no slack
    from jaxkin.collision import rows

    _, alone = collision.prepare(robot, self_collision=False)

    @jax.jit
    def world_only(q, world):
        return tuple(
            collision.collides_kernel(robot, body, alone, q, world, 0.0, frame_bounds=b).collides
            for b in (False, True)
        )  # fmt: skip

    q64 = jnp.asarray(q[:4], jnp.float64)
    placed, bounds = rows.place_bounded(robot, body.astype(jnp.float64), q64)
    frame = np.asarray(rows.frames_of(robot, q64)[1])[np.asarray(body.sphere_link)]
    which = np.searchsorted(np.unique(frame), frame)
    c, r = np.asarray(placed.spheres), np.asarray(body.sphere_radius, np.float64)
    for b in range(4):
        for f in np.unique(which):
            members = np.flatnonzero(which == f)
            g = np.asarray(bounds.center)[:, f, b]
            i = members[np.argmax(np.linalg.norm(c[:, members, b].T - g, axis=1) + r[members])]
            u = c[:, i, b] - g
            u = u / np.linalg.norm(u) if np.linalg.norm(u) > 0 else np.array([0.0, 0.0, 1.0])
            for gap in (0.0, 1e-3):
                far = c[:, i, b] + (r[i] + gap) * u  # the sphere's far point, and beyond
                ball = collision.Spheres.create([far + 0.005 * u], [0.005])
                plane = collision.HalfSpaces.create([-u], [-u @ far])
                for world in (
                    collision.World.create(spheres=ball),
                    collision.World.create(halfspaces=plane),
                ):
                    dense, bounded = world_only(q[b : b + 1], world.astype(dtype))
                    assert bool(bounded[0]) == bool(dense[0])
                    assert bool(dense[0]) or gap > 0  # touching: flagged


@pytest.mark.slow
def test_padded_worlds_give_the_same_verdicts_and_clearances():
    """A world padded to its buckets (``World.bucketed``: copies of each kind's last
    obstacle, which the loops skip) gives the verdicts of the world itself, bit for bit, and
    ``clearances_kernel`` skipping the copies the distances of testing them all, to a few
    ulp (float32, the planner's dtype; distances within 1 m of 0)."""
    robot = _spheres_ur5()
    world = _spheres_and_boxes(17).astype("float32")
    padded = world.bucketed()
    assert len(padded.spheres) == 8 and len(padded.boxes) == 8
    rng = np.random.default_rng(7)
    q = jnp.asarray(rng.uniform(-3.0, 3.0, (300, robot.n_joints)), "float32")
    body, pairs = collision.prepare(robot, self_collision=False)  # the world's loops
    verdict = jax.jit(lambda w, m: collision.collides_kernel(robot, body, pairs, q, w, m).collides)
    for margin in (0.0, 0.02):
        plain = np.asarray(verdict(world, margin))
        np.testing.assert_array_equal(np.asarray(verdict(padded, margin)), plain)
        assert 0.05 < np.mean(plain) < 0.95
    clearances = jax.jit(
        lambda skip: collision.clearances_kernel(robot, body, pairs, q, padded, skip),
        static_argnums=0,
    )
    every, skipped = clearances(False), clearances(True)
    np.testing.assert_array_equal(np.asarray(skipped[2]), np.asarray(every[2]))
    for x, y in zip(every[:2], skipped[:2], strict=True):
        # one obstacle per step against eight: XLA may fuse the arithmetic differently
        np.testing.assert_allclose(np.asarray(y), np.asarray(x), rtol=0, atol=1e-6)


def _spheres_and_boxes(seed: int) -> collision.World:
    """``_world``'s spheres and boxes alone (a cheaper compilation)."""
    world = _world(seed)
    return collision.World.create(spheres=world.spheres, boxes=world.boxes)


@pytest.mark.slow
def test_collides_host_thread_parts_equal_the_whole_batch():
    """A batch split into one part per host thread (two parts of ``VERDICT_MIN_PART`` or more
    that overlap) gives the whole batch's verdict; a moved obstacle reuses the compilation."""
    from jaxkin import set_num_threads
    from jaxkin.collision import verdict

    robot = _spheres_ur5()
    world = _spheres_and_boxes(17)
    n = 2 * verdict.VERDICT_MIN_PART + 3
    q = np.random.default_rng(18).uniform(-3.0, 3.0, (n, robot.n_joints))
    body, pairs = collision.prepare(robot)
    whole = verdict._collides_jit(robot, body, pairs, jnp.asarray(q), world, 0.01)
    set_num_threads(2)
    try:
        parts = collision.collides(robot, q, world, 0.01)
        with compilations() as count:
            collision.collides(robot, q, _spheres_and_boxes(19), 0.01)
        assert count.n == 0
    finally:
        set_num_threads(None)
    np.testing.assert_array_equal(parts.collides, whole.collides)
    np.testing.assert_array_equal(parts.status, whole.status)
    assert 0.05 < np.mean(np.asarray(whole.collides)) < 0.95


def _many_spheres_ur5():
    """A cover-like UR5: spheres filling a cylinder along every link with geometry (60 of
    2-4 cm on the upper arm and the forearm, 12 of 0.75-1.5 cm at each of the seven others:
    204 spheres), enough to take the groups' path (``collision.culled``)."""
    rng = np.random.default_rng(21)

    def cloud(k: int, length: float, radius: float, size: float) -> tuple:
        angle, height = rng.uniform(0.0, 2 * np.pi, k), rng.uniform(0.0, length, k)
        ring = rng.uniform(0.0, radius, k)
        centres = np.stack([ring * np.cos(angle), ring * np.sin(angle), height], -1)
        return centres, rng.uniform(0.5 * size, size, k)

    small = (12, 0.02, 0.01, 0.015)
    spheres = {
        name: cloud(*small)
        for name in (
            "base_link",
            "shoulder_link",
            "wrist_1_link",
            "wrist_2_link",
            "wrist_3_link",
            "tool0",
            "finger",
        )
    }
    spheres["upper_arm_link"] = cloud(60, 0.4, 0.04, 0.04)
    spheres["forearm_link"] = cloud(60, 0.35, 0.03, 0.04)
    return serial.from_urdf(UR5, "tool0").with_link_spheres(spheres)


def _every_kind(draw: int) -> collision.World:
    """``_world`` and two cylinders: every kind of obstacle a robot sphere is tested against."""
    world = _world(draw)
    rng = np.random.default_rng(draw + 100)
    return collision.World.create(
        spheres=world.spheres,
        capsules=world.capsules,
        boxes=world.boxes,
        halfspaces=world.halfspaces,
        cylinders=collision.Cylinders.create(
            rng.uniform(-0.6, 0.6, (2, 3)), [0.05, 0.1], [0.2, 0.3], axis=[[0, 0, 1], [1, 0, 0]]
        ),
    )


@pytest.mark.slow
@pytest.mark.parametrize("dtype", ["float64", "float32"])
def test_many_spheres_take_the_groups_and_keep_the_exact_verdict(dtype):
    """A body of 204 spheres goes through its groups' bounds first (``culled.groups_of``
    gives groups: its self sphere pairs are whole group pairs): over two chunks and every
    kind of obstacle, the exact verdict's flags (``_agree``) with margins 0 and 0.02, both
    verdicts occurring, some configurations colliding with themselves alone; a NaN row."""
    from jaxkin.collision import culled

    robot = _many_spheres_ur5()
    body, pairs = collision.prepare(robot)
    groups = culled.groups_of(body, pairs)
    assert groups is not None and body.num_spheres == 204 and not body.num_capsules
    sizes = np.bincount(np.asarray(body.sphere_bound))
    assert sizes.max() <= culled.GROUP and len(groups.link) == len(sizes)
    world = _every_kind(22).astype(dtype)
    q = np.random.default_rng(23).uniform(-3.0, 3.0, (700, robot.n_joints)).astype(dtype)
    q[5, 2] = np.nan
    for margin in (0.0, 0.02):
        hit = _agree(robot, q, world, margin, dtype)
        assert 0.2 < np.mean(hit) < 0.9
    exact = collision.check(robot, q, world)
    own = np.asarray(exact.self_collision.clearance) <= 0.0
    assert np.sum(own & (np.asarray(exact.world.clearance) > 0.0)) >= 10  # self alone
    assert collision.collides(robot, q, world).status[5] == Status.INVALID_INPUT


@pytest.mark.slow
@pytest.mark.parametrize("dtype", ["float64", "float32"])
def test_many_spheres_in_contact_and_batch_shapes(dtype):
    """The groups' path (``_many_spheres_ur5``): configurations at their own exact clearance
    (a world or a self contact within rounding) flagged, 1 mm below it free; one
    configuration alone and a (3, 5) batch give the exact verdict's flags."""
    robot = _many_spheres_ur5()
    world = _every_kind(24).astype(dtype)
    q = np.random.default_rng(25).uniform(-3.0, 3.0, (40, robot.n_joints)).astype(dtype)
    exact = collision.check(robot, q, world)
    kinds = set()
    for k in range(40):
        margin = float(exact.clearance[k])
        assert bool(collision.collides(robot, q[k], world, margin).collides)
        assert not bool(collision.collides(robot, q[k], world, margin - 1e-3).collides)
        kinds.add(bool(exact.world.clearance[k] <= exact.self_collision.clearance[k]))
    assert kinds == {True, False}  # world and self contacts both
    _agree(robot, q[7], world, 0.0, dtype)
    _agree(robot, q[:15].reshape(3, 5, -1), world, 0.0, dtype)


@pytest.mark.slow
@pytest.mark.parametrize("size", [8, 20])
def test_bodies_grouped_otherwise_keep_the_exact_verdict(monkeypatch, size):
    """A body whose coarse level was cut into groups of another size than ``culled.GROUP``
    (a body of groups of 8, saved before the groups grew to 12, or a larger size): through
    ``collides_kernel`` with that body its short groups are padded and its long ones cut into
    runs, and the verdict is still the exact one (``_many_spheres_ur5``, 300 configurations,
    float64, margins 0 and 0.02)."""
    from jaxkin.collision import body as body_module
    from jaxkin.collision import culled, verdict

    robot = _many_spheres_ur5()
    spheres, capsules = robot.collision_body().per_link()
    monkeypatch.setattr(body_module, "GROUP_SIZE", size)
    body = collision.Body.create(robot.collision_body().links, spheres, capsules)
    monkeypatch.undo()
    assert np.bincount(np.asarray(body.sphere_bound)).max() == size != culled.GROUP
    pairs = collision.SelfPairs.create(body, robot.self_collision_pairs())
    groups = culled.groups_of(body, pairs)
    assert groups is not None and groups.members.shape[1] == culled.GROUP
    world = _every_kind(28)
    q = np.random.default_rng(29).uniform(-3.0, 3.0, (300, robot.n_joints))
    run = jax.jit(lambda q, margin: verdict.collides_kernel(robot, body, pairs, q, world, margin))
    for margin in (0.0, 0.02):
        fast, exact = run(jnp.asarray(q), margin), collision.check(robot, q, world, margin)
        near = np.abs(np.asarray(exact.clearance) - margin) <= 1e-11
        assert not np.any(np.asarray(exact.collides) & ~np.asarray(fast.collides))
        np.testing.assert_array_equal(
            np.asarray(fast.collides)[~near], np.asarray(exact.collides)[~near]
        )
        assert 0.2 < np.mean(np.asarray(exact.collides)) < 0.9


def test_the_groups_path_gives_the_exact_verdict_on_a_small_body(monkeypatch):
    """Float64, ``_spheres_ur5``'s 18 spheres and one on the tool sent through the groups'
    path (``CULL_SPHERES`` lowered to 0; a fresh program, not the public call's): the exact
    verdict's flags over a chunk of 300 configurations, margins 0.01 and -0.01, spheres and
    boxes; a NaN row settled as in the dense path."""
    from jaxkin.collision import culled, verdict

    monkeypatch.setattr(culled, "CULL_SPHERES", 0)
    robot = _spheres_ur5().with_link_spheres({"tool0": (np.zeros((1, 3)), np.array([0.005]))})
    body, pairs = collision.prepare(robot)
    assert culled.groups_of(body, pairs) is not None
    world = _spheres_and_boxes(26)
    q = np.random.default_rng(27).uniform(-3.0, 3.0, (300, robot.n_joints))
    q[3, 1] = np.nan
    run = jax.jit(lambda q, margin: verdict.collides_kernel(robot, body, pairs, q, world, margin))
    for margin in (0.01, -0.01):
        fast = run(jnp.asarray(q), margin)
        exact = collision.check(robot, q, world, margin)
        near = np.abs(np.asarray(exact.clearance) - margin) <= 1e-11
        assert not np.any(np.asarray(exact.collides) & ~np.asarray(fast.collides))
        np.testing.assert_array_equal(
            np.asarray(fast.collides)[~near], np.asarray(exact.collides)[~near]
        )
        np.testing.assert_array_equal(np.asarray(fast.status), np.asarray(exact.status))
        assert 0.1 < np.mean(np.asarray(exact.collides)) < 0.9


def _panda_scene(dtype: str):
    """The Panda of example-robot-data with its default body (its meshes covered within 1 cm:
    363 spheres, 22,792 self sphere pairs after the SRDF), 12 spheres and 8 boxes of 5-15 cm
    at least 5 cm from its base link (which never moves), and 2,000 random configurations."""
    import sys

    root = next(
        (p for p in (Path(b) / "cmeel.prefix/share/example-robot-data/robots" for b in sys.path)
         if p.is_dir()),
        None,
    )  # fmt: skip
    if root is None:
        pytest.skip("example-robot-data's robots folder not found")
    urdf = root / "panda_description/urdf/panda.urdf"
    robot = serial.from_urdf(urdf, "panda_hand").with_srdf(
        root / "panda_description/srdf/panda.srdf"
    )
    body = robot.collision_body()
    spheres, _ = body.place(robot.link_poses(np.zeros(robot.n_joints)))
    base = np.asarray(body.sphere_link) == body.links.index("panda_link0")
    centres, radii = np.asarray(spheres.center)[base], np.asarray(spheres.radius)[base]
    rng = np.random.default_rng(28)
    found = []
    while len(found) < 20:
        centre, size = rng.uniform([-0.7, -0.7, 0.0], [0.7, 0.7, 1.1]), rng.uniform(0.05, 0.15)
        if np.all(np.linalg.norm(centres - centre, axis=1) - radii - size >= 0.05):
            found.append((centre, size))
    c = np.array([f[0] for f in found])
    s = np.array([f[1] for f in found])
    rotations = np.stack([np.linalg.qr(rng.normal(size=(3, 3)))[0] for _ in range(8)])
    world = collision.World.create(
        spheres=collision.Spheres.create(c[:12], s[:12]),
        boxes=collision.Boxes.create(
            c[12:], s[12:, None] / np.sqrt(3) * [1.0, 0.8, 0.6], rotations
        ),
    ).astype(dtype)
    lower, upper = np.asarray(robot.lower), np.asarray(robot.upper)
    q = rng.uniform(lower, upper, (2000, robot.n_joints)).astype(dtype)
    return robot, world, q


@pytest.mark.slow
@pytest.mark.parametrize("dtype", ["float32", "float64"])
def test_panda_default_body_verdict_equals_the_exhaustive_check(dtype):
    """The Panda's default body (``_panda_scene``) goes through its groups' bounds
    (``collision.culled``), and its verdict on 2,000 random configurations, about half of
    them colliding, equals ``check``'s flag for flag (none of them within the rounding
    tolerance of contact); margins at some configurations' own clearances are flagged."""
    from jaxkin.collision import culled

    robot, world, q = _panda_scene(dtype)
    body, pairs = collision.prepare(robot)
    assert body.num_spheres == 363 and len(pairs.ss[0]) == 22792
    assert culled.groups_of(body, pairs) is not None
    exact = collision.check(robot, q, world)
    fast = collision.collides(robot, q, world)
    np.testing.assert_array_equal(np.asarray(fast.collides), np.asarray(exact.collides))
    np.testing.assert_array_equal(np.asarray(fast.status), np.asarray(exact.status))
    assert 0.3 < np.mean(np.asarray(exact.collides)) < 0.7
    own = np.asarray(exact.self_collision.clearance) <= 0.0
    assert np.sum(own & (np.asarray(exact.world.clearance) > 0.0)) >= 20  # self alone
    for k in range(0, 200, 40):
        margin = float(exact.clearance[k])
        assert bool(collision.collides(robot, q[k : k + 1], world, margin).collides[0])
