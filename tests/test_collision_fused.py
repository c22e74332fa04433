"""The fused clearance against the per-primitive queries it replaces.

``clearance`` / ``min_clearance`` must equal the smallest entry of ``nearest_obstacles`` and
of the self pairs' distances (the same closed forms, so to a few ulps), and the pair it names
must give that distance when evaluated alone with ``collision.distance`` (slow tier).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxkin import collision as col
from jaxkin.collision import distance as sd
from jaxkin.collision import fused as cl
from jaxkin.collision.pairs import _primitive_pair_distances

from .helpers import compilations

pytestmark = pytest.mark.slow  # each test compiles the written-out kernel (seconds apiece)


def _rotations(rng, n):
    q = rng.normal(size=(n, 4))
    q /= np.linalg.norm(q, axis=-1, keepdims=True)
    w, x, y, z = q.T
    return np.stack(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
        ]
    ).transpose(2, 0, 1)


def _scene(rng, dtype=None, spheres=4):
    world = col.World.create(
        spheres=col.Spheres.create(rng.normal(size=(spheres, 3)), rng.uniform(0.1, 0.3, spheres)),
        capsules=col.Capsules.create(rng.normal(size=(2, 3)), rng.normal(size=(2, 3)), 0.1),
        boxes=col.Boxes.create(
            rng.normal(size=(3, 3)), rng.uniform(0.1, 0.4, (3, 3)), _rotations(rng, 3)
        ),
        halfspaces=col.HalfSpaces.create([[0.0, 0.0, 1.0]], -2.5),
        dtype=dtype,
    )
    body = col.Body.create(
        ["a", "b", "c"],
        spheres={"a": (rng.normal(size=(3, 3)), 0.1), "c": (rng.normal(size=(4, 3)), 0.05)},
        capsules={
            "b": (rng.normal(size=(2, 3)), rng.normal(size=(2, 3)), 0.08),
            "c": (rng.normal(size=(1, 3)), rng.normal(size=(1, 3)), 0.02),
        },
        dtype=dtype,
    )
    pairs = col.SelfPairs.create(body, [(0, 1), (0, 2), (1, 2)])
    batch = (4, 6)
    poses = np.tile(np.eye(4), (*batch, 3, 1, 1))
    poses[..., :3, 3] = rng.normal(size=(*batch, 3, 3))
    poses[..., :3, :3] = _rotations(rng, 72).reshape(*batch, 3, 3, 3)
    spheres, capsules = body.place(jnp.asarray(poses, dtype=dtype))
    return world, pairs, spheres, capsules


def _pair_distance(full, k, spheres, capsules, world):
    """The distance of the pair ``full`` names for flat configuration ``k``, alone."""
    s = (
        spheres.center.reshape(-1, len(spheres), 3)[k],
        spheres.radius.reshape(-1, len(spheres))[k],
    )
    c = (
        capsules.a.reshape(-1, len(capsules), 3)[k],
        capsules.b.reshape(-1, len(capsules), 3)[k],
        capsules.radius.reshape(-1, len(capsules))[k],
    )
    robot_kind, robot_index = int(full.robot_kind.ravel()[k]), int(full.robot_index.ravel()[k])
    other_kind, other_index = int(full.other_kind.ravel()[k]), int(full.other_index.ravel()[k])
    me = [x[robot_index] for x in (s if robot_kind == col.SPHERE else c)]
    if not bool(full.world.ravel()[k]):
        other = [x[other_index] for x in (s if other_kind == col.SPHERE else c)]
        fn = {
            (0, 0): sd.sphere_sphere,
            (0, 1): sd.sphere_capsule,
            (1, 1): sd.capsule_capsule,
        }[(robot_kind, other_kind)]
        return fn(*me, *other)
    w = world
    obstacle = {
        col.SPHERE: (w.spheres.center, w.spheres.radius),
        col.CAPSULE: (w.capsules.a, w.capsules.b, w.capsules.radius),
        col.BOX: (w.boxes.center, w.boxes.rotation, w.boxes.half_extents),
        col.HALFSPACE: (w.halfspaces.normal, w.halfspaces.offset),
    }[other_kind]
    obstacle = [x[other_index] for x in obstacle]
    if robot_kind == col.SPHERE:
        fn = [sd.sphere_sphere, sd.sphere_capsule, sd.sphere_box, sd.sphere_halfspace][other_kind]
        return fn(*me, *obstacle)
    if other_kind == col.SPHERE:
        return sd.sphere_capsule(*obstacle, *me)
    fn = [None, sd.capsule_capsule, sd.capsule_box, sd.capsule_halfspace][other_kind]
    return fn(*me, *obstacle)


@pytest.mark.parametrize("n_spheres", [4, 19], ids=["one-step", "three-steps"])
def test_clearance_equals_the_per_primitive_queries(n_spheres):
    """Random bodies (spheres and capsules on three links, self pairs on all three link
    pairs) in a world of every kind, a batch (4, 6): the minimum equals the minimum of
    ``nearest_obstacles`` and of every self primitive pair to 1e-14, and the pair it names
    gives that distance alone; obstacle spheres in one loop step, and in three (the last
    padded)."""
    world, pairs, spheres, capsules = _scene(np.random.default_rng(5), spheres=n_spheres)
    near_s, near_c = col.nearest_obstacles(spheres, capsules, world)
    own = _primitive_pair_distances(spheres, capsules, pairs)
    world_min = jnp.minimum(near_s.distance.min(-1), near_c.distance.min(-1))
    expected = np.minimum(world_min, own.min(-1))
    full = jax.jit(cl.clearance)(spheres, capsules, world, pairs)
    assert full.distance.shape == (4, 6)
    np.testing.assert_allclose(full.distance, expected, rtol=0, atol=1e-14)
    np.testing.assert_allclose(
        jax.jit(cl.min_clearance)(spheres, capsules, world, pairs), expected, rtol=0, atol=1e-14
    )
    assert np.array_equal(np.asarray(full.world), np.asarray(world_min <= own.min(-1)))
    if n_spheres == 4:  # both world and self pairs win somewhere
        assert 0 < np.asarray(full.world).sum() < 24
    for k in range(24):
        alone = _pair_distance(full, k, spheres, capsules, world)
        assert float(alone) == pytest.approx(float(full.distance.ravel()[k]), abs=1e-14)


def test_world_only_self_only_and_float32():
    rng = np.random.default_rng(6)
    world, pairs, spheres, capsules = _scene(rng, jnp.float32)
    empty = col.World.create(dtype=jnp.float32)
    near_s, near_c = col.nearest_obstacles(spheres, capsules, world)
    only_world = cl.clearance(spheres, capsules, world)
    assert only_world.distance.dtype == jnp.float32 and bool(jnp.all(only_world.world))
    np.testing.assert_allclose(
        only_world.distance,
        np.minimum(near_s.distance.min(-1), near_c.distance.min(-1)),
        rtol=0,
        atol=1e-6,
    )
    only_self = cl.clearance(spheres, capsules, empty, pairs)
    assert not bool(jnp.any(only_self.world))
    own = _primitive_pair_distances(spheres, capsules, pairs)
    np.testing.assert_allclose(only_self.distance, own.min(-1), rtol=0, atol=1e-6)
    nothing = cl.clearance(spheres, capsules, empty)
    assert np.all(np.asarray(nothing.distance) == np.finfo(np.float32).max)
    assert np.all(np.asarray(nothing.robot_kind) == -1)


def test_rows_layout_and_no_recompile_when_obstacles_move():
    """The rows entry point equals the per-primitive minimum; moved obstacles reuse the
    compiled kernel."""
    rng = np.random.default_rng(7)
    world, pairs, spheres, capsules = _scene(rng)
    placed, _ = cl.as_placed(spheres, capsules)
    fused = jax.jit(cl.min_clearance_rows)
    np.testing.assert_allclose(
        fused(placed, world, pairs),
        np.minimum(
            np.min(col.nearest_obstacles(spheres, capsules, world)[0].distance, -1),
            np.min(col.nearest_obstacles(spheres, capsules, world)[1].distance, -1),
        )
        .ravel()
        .clip(max=np.min(_primitive_pair_distances(spheres, capsules, pairs), -1).ravel()),
        rtol=0,
        atol=1e-15,
    )
    moved = jax.tree.map(lambda x: x * 1.1, world)
    with compilations() as count:
        fused(placed, moved, pairs)
    assert count.n == 0
