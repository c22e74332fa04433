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

import numpy as np
import pytest

from jaxkin import Status, collision, serial

from .helpers import compilations

UR5 = Path(__file__).resolve().parents[1] / "examples" / "ur5.urdf"


def _ur5():
    """Spheres on three links (the Chain's rows placement through link home poses), the
    skeleton's capsules on the others (the exact capsule distances)."""
    spheres = {
        "upper_arm_link": (np.array([[0.0, 0.0, 0.1], [0.0, 0.0, 0.3]]), np.array([0.07, 0.06])),
        "forearm_link": (np.array([[0.0, 0.0, 0.05], [0.0, 0.0, 0.25]]), np.array([0.06, 0.05])),
        "wrist_3_link": (np.zeros((1, 3)), np.array([0.05])),
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
