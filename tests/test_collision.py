"""Collision geometry: hand-derived signed distances, gradients, batching, the world, bodies.

The cross-checks against coal and the mesh covers of real arms are in
tests/test_collision_coal.py (slow tier).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxkin import collision as col
from jaxkin.collision import distance as sd

from .helpers import compilations, gradient_against_differences

SQ2, SQ3 = np.sqrt(2.0), np.sqrt(3.0)
EYE = np.eye(3)


def rot_z(angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def v(*x) -> np.ndarray:
    return np.array(x, dtype=float)


# Hand-derived values: (function, arguments, expected signed distance).
HALF = v(1.0, 0.5, 0.25)  # a box 2 x 1 x 0.5 about the origin
CASES = [
    ("sphere_sphere apart", sd.sphere_sphere, (v(0, 0, 0), 1.0, v(3, 4, 0), 1.0), 3.0),
    ("sphere_sphere overlap", sd.sphere_sphere, (v(0, 0, 0), 1.0, v(1, 0, 0), 0.5), -0.5),
    ("point_segment interior", sd.point_segment, (v(0.5, 2, 0), v(0, 0, 0), v(1, 0, 0)), 2.0),
    ("point_segment end", sd.point_segment, (v(4, 4, 0), v(0, 0, 0), v(1, 0, 0)), 5.0),
    ("point_segment degenerate", sd.point_segment, (v(0, 3, 4), v(0, 0, 0), v(0, 0, 0)), 5.0),
    (
        "segments crossing",
        sd.segment_segment,
        (v(-1, 0, 0), v(1, 0, 0), v(0, -1, 2), v(0, 1, 2)),
        2.0,
    ),
    (
        "segments parallel",
        sd.segment_segment,
        (v(0, 0, 0), v(2, 0, 0), v(1, 1, 0), v(3, 1, 0)),
        1.0,
    ),
    (
        "segments parallel apart",
        sd.segment_segment,
        (v(0, 0, 0), v(1, 0, 0), v(4, 4, 0), v(5, 4, 0)),
        5.0,
    ),
    (
        "segments collinear",
        sd.segment_segment,
        (v(0, 0, 0), v(1, 0, 0), v(3, 0, 0), v(5, 0, 0)),
        2.0,
    ),
    (
        "segments both points",
        sd.segment_segment,
        (v(0, 0, 0), v(0, 0, 0), v(0, 3, 4), v(0, 3, 4)),
        5.0,
    ),
    (
        "segments touching",
        sd.segment_segment,
        (v(0, 0, 0), v(1, 0, 0), v(1, 0, 0), v(1, 5, 0)),
        0.0,
    ),
    ("point_box face", sd.point_box, (v(0, 0, 1), v(0, 0, 0), EYE, HALF), 0.75),
    ("point_box corner", sd.point_box, (v(2, 1.5, 1.25), v(0, 0, 0), EYE, HALF), SQ3),
    ("point_box inside", sd.point_box, (v(0.9, 0, 0), v(0, 0, 0), EYE, HALF), -0.1),
    ("point_box centre", sd.point_box, (v(0, 0, 0), v(0, 0, 0), EYE, HALF), -0.25),
    (
        "point_box rotated",  # box turned 90 degrees about z: its x half extent lies along y
        sd.point_box,
        (v(0, 2, 0), v(0, 0, 0), rot_z(np.pi / 2), HALF),
        1.0,
    ),
    (
        "segment_box above a face",
        sd.segment_box,
        (v(-3, 0, 1), v(3, 0, 1), v(0, 0, 0), EYE, HALF),
        0.75,
    ),
    (
        "segment_box past an edge",  # nearest the box edge x = 1, z = 0.25 (y free)
        sd.segment_box,
        (v(2, -3, 1.25), v(2, 3, 1.25), v(0, 0, 0), EYE, HALF),
        SQ2,
    ),
    (
        "segment_box diagonal past a corner",  # line x + y = 2.5 past the corner (1, 0.5)
        sd.segment_box,
        (v(0.5, 2, 0.25), v(2.5, 0, 0.25), v(0, 0, 0), EYE, HALF),
        1.0 / SQ2,
    ),
    (
        "segment_box through, along x",  # leave through y (0.5) or z (0.25): depth 0.25
        sd.segment_box,
        (v(-3, 0, 0), v(3, 0, 0), v(0, 0, 0), EYE, HALF),
        -0.25,
    ),
    (
        "segment_box inside, short",  # pushes: +x 0.5, -x 1.8, +-y 0.5, +z 0.15, -z 0.35
        sd.segment_box,
        (v(0.5, 0, 0.1), v(0.8, 0, 0.1), v(0, 0, 0), EYE, HALF),
        -0.15,
    ),
    (
        "segment_box through, along z",  # tall segment through the thin axis: leave via y
        sd.segment_box,
        (v(0.9, 0.3, -5), v(0.9, 0.3, 5), v(0, 0, 0), EYE, HALF),
        -0.1,
    ),
    (
        "segment_box diagonal through",  # in the xy plane through the centre, 45 degrees
        sd.segment_box,  # m = (d x e_z)/|.| = (1, -1, 0)/sqrt2: support (1 + 0.5)/sqrt2 > 0.25
        (v(-3, -3, 0), v(3, 3, 0), v(0, 0, 0), EYE, HALF),
        -0.25,
    ),
    (
        "segment_box diagonal through, thick box",  # box 2 x 2 x 2: separate along (1,-1,0)
        sd.segment_box,  # support of the box on (1,-1,0)/sqrt2 is 2/sqrt2 = sqrt2
        (v(-3, -3, 0), v(3, 3, 0), v(0, 0, 0), EYE, v(1, 1, 1)),
        -1.0,
    ),
    ("sphere_halfspace", sd.sphere_halfspace, (v(0, 0, 2), 0.5, v(0, 0, 1), 1.0), 0.5),
    (
        "capsule_halfspace",
        sd.capsule_halfspace,
        (v(0, 0, 2), v(0, 0, -1), 0.5, v(0, 0, 1), 1.0),
        -2.5,
    ),
    (
        "capsule_capsule",
        sd.capsule_capsule,
        (v(-1, 0, 0), v(1, 0, 0), 0.5, v(0, -1, 2), v(0, 1, 2), 0.25),
        1.25,
    ),
    ("capsule_box", sd.capsule_box, (v(-3, 0, 1), v(3, 0, 1), 0.25, v(0, 0, 0), EYE, HALF), 0.5),
    ("sphere_box", sd.sphere_box, (v(2, 1.5, 1.25), 1.0, v(0, 0, 0), EYE, HALF), SQ3 - 1.0),
]


_JITTED: dict = {}


def jitted(fn):
    """One jitted copy per function, shared by the tests (one compilation per shape)."""
    return _JITTED.setdefault(fn, jax.jit(fn))


@pytest.mark.parametrize("name, fn, args, expected", CASES, ids=[c[0] for c in CASES])
def test_hand_derived_distances(name, fn, args, expected):
    assert float(jitted(fn)(*args)) == pytest.approx(expected, abs=1e-14)


def test_segment_box_depth_fully_inside_is_the_smallest_push():
    # segment (0.2, 0.1, 0) - (0.4, 0.1, 0) in the box of half extents (1, 0.5, 0.25): pushes
    # +x 1 - 0.2 = 0.8, -x 1 + 0.4 = 1.4, +y 0.5 - 0.1 = 0.4, -y 0.6, +-z 0.25: depth 0.25;
    # with z made thick (h_z = 2) the y push 0.4 wins.
    a, b = v(0.2, 0.1, 0), v(0.4, 0.1, 0)
    segment_box = jitted(sd.segment_box)
    assert float(segment_box(a, b, v(0, 0, 0), EYE, HALF)) == pytest.approx(-0.25, abs=1e-15)
    thick = v(1.0, 0.5, 2.0)
    assert float(segment_box(a, b, v(0, 0, 0), EYE, thick)) == pytest.approx(-0.4, abs=1e-15)


def test_rigid_motion_and_scale():
    """Distances are invariant under a rigid motion of both shapes and scale with size, in
    float64 (1e-13 relative) and float32 (2e-6 relative to the shapes' size)."""
    rng = np.random.default_rng(3)
    a, b = rng.normal(size=(64, 3)), rng.normal(size=(64, 3))
    c, h = 0.3 * rng.normal(size=(64, 3)), rng.uniform(0.1, 1.0, size=(64, 3))
    rot = np.linalg.qr(rng.normal(size=(64, 3, 3)))[0]
    rot *= np.sign(np.linalg.det(rot))[:, None, None]
    segment_box = jitted(sd.segment_box)
    base = np.asarray(segment_box(a, b, c, rot, h))
    q = np.linalg.qr(rng.normal(size=(3, 3)))[0]
    q *= np.sign(np.linalg.det(q))
    t = rng.normal(size=3)
    moved = np.asarray(segment_box(a @ q.T + t, b @ q.T + t, c @ q.T + t, q @ rot, h))
    np.testing.assert_allclose(moved, base, atol=1e-13)
    for scale in (1e-3, 1e3):
        scaled = np.asarray(segment_box(scale * a, scale * b, scale * c, rot, scale * h))
        np.testing.assert_allclose(scaled / scale, base, atol=1e-13)
        f32 = [
            jnp.asarray(x, jnp.float32) for x in (scale * a, scale * b, scale * c, rot, scale * h)
        ]
        d32 = segment_box(*f32)
        assert d32.dtype == jnp.float32
        np.testing.assert_allclose(np.asarray(d32) / scale, base, atol=2e-6 * 4.0)
    assert np.any(base < 0) and np.any(base > 0)  # both regimes were exercised


# Pairs at contact, in penetration, with coincident centres and degenerate segments: every
# gradient must be finite.
DEGENERATE = [
    (sd.sphere_sphere, (v(0, 0, 0), 1.0, v(0, 0, 0), 1.0)),
    (sd.sphere_sphere, (v(0, 0, 0), 1.0, v(2, 0, 0), 1.0)),
    (sd.capsule_capsule, (v(0, 0, 0), v(0, 0, 0), 0.1, v(0, 0, 0), v(0, 0, 0), 0.1)),
    (sd.capsule_capsule, (v(-1, 0, 0), v(1, 0, 0), 0.1, v(0, -1, 0), v(0, 1, 0), 0.1)),
    (sd.capsule_capsule, (v(0, 0, 0), v(1, 0, 0), 0.1, v(0, 0, 0), v(1, 0, 0), 0.1)),
    (sd.sphere_capsule, (v(0.5, 0, 0), 0.1, v(0, 0, 0), v(1, 0, 0), 0.1)),
    (sd.sphere_box, (v(0, 0, 0), 0.1, v(0, 0, 0), EYE, v(1, 1, 1))),
    (sd.sphere_box, (v(1, 0, 0), 0.1, v(0, 0, 0), EYE, v(1, 1, 1))),
    (sd.sphere_box, (v(1, 1, 1), 0.1, v(0, 0, 0), EYE, v(1, 1, 1))),
    (sd.capsule_box, (v(0, 0, 0), v(0, 0, 0), 0.1, v(0, 0, 0), EYE, v(1, 1, 1))),
    (sd.capsule_box, (v(-2, 0, 0), v(2, 0, 0), 0.1, v(0, 0, 0), EYE, v(1, 1, 1))),
    (sd.capsule_box, (v(1, 1, -2), v(1, 1, 2), 0.1, v(0, 0, 0), EYE, v(1, 1, 1))),
    (sd.capsule_box, (v(-2, 1, 1), v(2, 1, 1), 0.1, v(0, 0, 0), EYE, v(1, 1, 1))),
    (sd.capsule_box, (v(0, 0, 0), v(0, 0, 0), 0.0, v(0, 0, 0), EYE, v(0, 0, 0))),
    (sd.capsule_halfspace, (v(0, 0, 0), v(1, 0, 0), 0.1, v(0, 0, 1), 0.0)),
]


_GRADS: dict = {}


@pytest.mark.parametrize("k", range(len(DEGENERATE)))
def test_gradients_finite_in_contact_penetration_and_degenerate(k):
    fn, args = DEGENERATE[k]
    grad = _GRADS.setdefault(fn, jax.jit(jax.grad(fn, argnums=tuple(range(len(args))))))
    grads = grad(*[jnp.asarray(x) for x in args])
    assert all(np.all(np.isfinite(np.asarray(g))) for g in grads)


def _fd_check(fn, args):
    gradient_against_differences(fn, args)


def test_gradients_match_finite_differences():
    """Separated and penetrating generic pairs (away from the pieces' boundaries): autodiff
    (through the stopped closest-point parameters, Danskin) equals central differences."""
    rot = np.linalg.qr(np.array([[1.0, 0.2, 0.1], [0.3, 1.0, 0.2], [0.1, 0.4, 1.0]]))[0]
    rot *= np.sign(np.linalg.det(rot))
    h = v(0.6, 0.4, 0.3)
    jit = jax.jit(sd.capsule_box)
    _fd_check(jit, (v(-1, 0.2, 1.1), v(1.2, 0.4, 0.9), 0.1, v(0.05, 0, 0), rot, h))  # apart
    _fd_check(jit, (v(-1, 0.1, 0.05), v(1.2, 0.2, 0.1), 0.1, v(0.05, 0, 0), rot, h))  # through
    _fd_check(
        jax.jit(sd.capsule_capsule),
        (v(-1, 0, 0), v(1, 0.1, 0), 0.1, v(0.2, -1, 0.3), v(0.1, 1, 0.5), 0.2),
    )
    _fd_check(jax.jit(sd.sphere_box), (v(0.3, 0.1, 0.05), 0.1, v(0, 0, 0), rot, h))  # inside


@pytest.mark.slow
def test_jacfwd_equals_jacrev():
    args = (v(-1, 0.1, 0.05), v(1.2, 0.2, 0.1), 0.1, v(0.05, 0, 0), EYE, v(0.6, 0.4, 0.3))
    fwd = jax.jit(jax.jacfwd(sd.capsule_box, argnums=(0, 1)))(*args)
    rev = jax.jit(jax.jacrev(sd.capsule_box, argnums=(0, 1)))(*args)
    for f, r in zip(fwd, rev, strict=True):
        np.testing.assert_allclose(np.asarray(f), np.asarray(r), atol=1e-14)


def _random_world(rng, dtype=jnp.float64):
    rot = np.linalg.qr(rng.normal(size=(3, 3, 3)))[0]
    rot *= np.sign(np.linalg.det(rot))[:, None, None]
    return col.World.create(
        spheres=col.Spheres.create(rng.normal(size=(4, 3)), rng.uniform(0.1, 0.3, 4)),
        capsules=col.Capsules.create(rng.normal(size=(2, 3)), rng.normal(size=(2, 3)), 0.1),
        boxes=col.Boxes.create(rng.normal(size=(3, 3)), rng.uniform(0.1, 0.5, (3, 3)), rot),
        halfspaces=col.HalfSpaces.create(v(0, 0, 1), -2.0),
        dtype=dtype,
    )


def _all_pairs(world, centers, radii, a, b, r):
    """Every (robot primitive, obstacle) signed distance from the pair kernels, one call per
    pair of kinds on explicit pair lists: ``[(distance, kind, index)]`` per primitive."""
    w = world
    ns, nc = len(radii), len(r)
    table = [[] for _ in range(ns + nc)]

    def add(kind, count, sphere_fn, capsule_fn, fields):
        if count == 0:
            return
        obs = [np.asarray(f) for f in fields]
        rep = lambda x, n: np.repeat(x, count, axis=0)  # noqa: E731
        til = lambda x, n: np.tile(x, (n,) + (1,) * (x.ndim - 1))  # noqa: E731
        ds = np.asarray(
            jitted(sphere_fn)(rep(centers, ns), rep(radii, ns), *[til(o, ns) for o in obs])
        )
        dc = np.asarray(
            jitted(capsule_fn)(rep(a, nc), rep(b, nc), rep(r, nc), *[til(o, nc) for o in obs])
        )
        for k, d in enumerate(np.concatenate([ds, dc])):
            table[k // count].append((float(d), kind, k % count))

    def swap_sphere_capsule(c, rc, oa, ob, orr):
        return sd.sphere_capsule(c, rc, oa, ob, orr)

    def capsule_sphere(pa, pb, pr, oc, orr):
        return sd.sphere_capsule(oc, orr, pa, pb, pr)

    add(
        col.SPHERE,
        len(w.spheres),
        sd.sphere_sphere,
        capsule_sphere,
        (w.spheres.center, w.spheres.radius),
    )
    add(
        col.CAPSULE,
        len(w.capsules),
        swap_sphere_capsule,
        sd.capsule_capsule,
        (w.capsules.a, w.capsules.b, w.capsules.radius),
    )
    add(
        col.BOX,
        len(w.boxes),
        sd.sphere_box,
        sd.capsule_box,
        (w.boxes.center, w.boxes.rotation, w.boxes.half_extents),
    )
    add(
        col.HALFSPACE,
        len(w.halfspaces),
        sd.sphere_halfspace,
        sd.capsule_halfspace,
        (w.halfspaces.normal, w.halfspaces.offset),
    )
    return [min(row) for row in table]


NEAREST = jax.jit(col.nearest_obstacles)


def test_nearest_obstacles_equals_loops_and_batches():
    rng = np.random.default_rng(7)
    world = _random_world(rng)
    centers, radii = rng.normal(size=(2, 5, 3)), rng.uniform(0.05, 0.2, (2, 5))
    a, b, r = rng.normal(size=(2, 3, 3)), rng.normal(size=(2, 3, 3)), rng.uniform(0.05, 0.2, (2, 3))
    near_s, near_c = NEAREST(
        col.Spheres(jnp.asarray(centers), jnp.asarray(radii)),
        col.Capsules(jnp.asarray(a), jnp.asarray(b), jnp.asarray(r)),
        world,
    )
    assert near_s.distance.shape == (2, 5) and near_c.kind.shape == (2, 3)
    for k in range(2):
        expected = _all_pairs(world, centers[k], radii[k], a[k], b[k], r[k])
        got = list(
            zip(
                np.concatenate([near_s.distance[k], near_c.distance[k]]).tolist(),
                np.concatenate([near_s.kind[k], near_c.kind[k]]).tolist(),
                np.concatenate([near_s.index[k], near_c.index[k]]).tolist(),
                strict=True,
            )
        )
        for (d, kind, i), (de, kinde, ie) in zip(got, expected, strict=True):
            assert d == pytest.approx(de, abs=1e-14) and (kind, i) == (kinde, ie)


def test_moving_or_resizing_obstacles_does_not_recompile():
    rng = np.random.default_rng(1)
    world = _random_world(rng)
    robot = (
        col.Spheres.create(rng.normal(size=(6, 3)), 0.1),
        col.Capsules.create(rng.normal(size=(2, 3)), rng.normal(size=(2, 3)), 0.1),
    )
    check = jax.jit(col.nearest_obstacles)
    first = check(*robot, world)
    moved = col.World.create(
        spheres=col.Spheres.create(
            np.asarray(world.spheres.center) + 0.5, 2.0 * np.asarray(world.spheres.radius)
        ),
        capsules=world.capsules,
        boxes=col.Boxes.create(
            np.asarray(world.boxes.center) - 0.3, v(0.9, 0.1, 0.2), np.asarray(world.boxes.rotation)
        ),
        halfspaces=col.HalfSpaces.create(v(1, 0, 1), 0.4),
    )
    with compilations() as count:
        second = check(*robot, moved)
    assert count.n == 0
    assert not np.allclose(np.asarray(first[0].distance), np.asarray(second[0].distance))


def test_empty_world_and_empty_kinds():
    robot_s = col.Spheres.create(np.zeros((2, 3)), 0.1)
    robot_c = col.Capsules.empty()
    near_s, near_c = col.nearest_obstacles(robot_s, robot_c, col.World.create())
    assert np.all(np.asarray(near_s.kind) == -1) and np.all(np.isfinite(near_s.distance))
    assert near_c.distance.shape == (0,)
    floor = col.World.create(halfspaces=col.HalfSpaces.create(v(0, 0, 2), -1.0))
    near_s, _ = col.nearest_obstacles(robot_s, robot_c, floor)  # z <= -0.5 after normalising
    np.testing.assert_allclose(np.asarray(near_s.distance), 0.4, atol=1e-15)
    assert np.all(np.asarray(near_s.kind) == col.HALFSPACE)


@pytest.mark.slow
def test_float32_world_keeps_float32():
    rng = np.random.default_rng(2)
    world = _random_world(rng, jnp.float32)
    robot = col.Spheres.create(rng.normal(size=(3, 3)), 0.1, dtype=jnp.float32)
    near_s, _ = NEAREST(robot, col.Capsules.empty(jnp.float32), world)
    assert near_s.distance.dtype == jnp.float32
    ref, _ = NEAREST(
        robot.__class__(robot.center.astype(float), robot.radius.astype(float)),
        col.Capsules.empty(),
        world.astype(jnp.float64),
    )
    np.testing.assert_allclose(np.asarray(near_s.distance), np.asarray(ref.distance), atol=1e-6)


def test_boundary_errors_name_the_argument():
    with pytest.raises(ValueError, match="radius"):
        col.Spheres.create(np.zeros((2, 3)), -1.0)
    with pytest.raises(ValueError, match="center"):
        col.Spheres.create(np.zeros((2, 2)), 1.0)
    with pytest.raises(ValueError, match="rotation"):
        col.Boxes.create(np.zeros((1, 3)), np.ones((1, 3)), 2.0 * np.eye(3)[None])
    with pytest.raises(ValueError, match="half_extents"):
        col.Boxes.create(np.zeros((1, 3)), -np.ones((1, 3)))
    with pytest.raises(ValueError, match="normal"):
        col.HalfSpaces.create(np.zeros((1, 3)), 0.0)
    with pytest.raises(ValueError, match="Capsules"):
        col.Capsules.create(np.zeros((2, 3)), np.zeros((3, 3)), 0.1)
    with pytest.raises(ValueError, match="voxel"):
        col.point_cloud_spheres(np.zeros((4, 3)), 0.0)
    with pytest.raises(ValueError, match="boxes"):
        col.World.create(boxes=col.Spheres.empty())


def test_counts_that_do_not_broadcast_and_scalar_sizes_name_the_argument():
    with pytest.raises(ValueError, match=r"radius: shape \(3,\) does not broadcast to \(2,\)"):
        col.Spheres.create(np.zeros((2, 3)), [1.0, 2.0, 3.0])
    with pytest.raises(ValueError, match="radius: shape"):
        col.Capsules.create(np.zeros((2, 3)), np.ones((2, 3)), [0.1, 0.2, 0.3])
    with pytest.raises(ValueError, match="half_extents: shape"):
        col.Boxes.create(np.zeros((2, 3)), np.ones((3, 3)))
    with pytest.raises(ValueError, match="offset: shape"):
        col.HalfSpaces.create(np.eye(3), [1.0, 2.0])
    for center in (np.zeros((1, 2)), np.zeros((3, 2)), np.zeros(2)):
        with pytest.raises(ValueError, match="center: expected shape"):
            col.Spheres.create(center, 1.0)
    with pytest.raises(ValueError, match="points: expected shape"):
        col.point_cloud_spheres(np.zeros((4, 2)), 0.1)
    pts = np.random.default_rng(3).uniform(-1, 1, (50, 3))
    for voxel in (np.array([0.1, 0.1, 0.1]), np.nan, True):
        with pytest.raises(ValueError, match="voxel must be a positive finite number"):
            col.point_cloud_spheres(pts, voxel)
    for point_radius in (np.nan, np.ones(2)):
        with pytest.raises(ValueError, match="point_radius must be a finite number"):
            col.point_cloud_spheres(pts, 0.5, point_radius)
    with pytest.raises(ValueError, match="point_radius must be >= 0"):
        col.point_cloud_spheres(pts, 0.5, -0.1)
    plain = col.point_cloud_spheres(pts, 0.5, 0.01, dtype=np.float64)
    for voxel in (np.float32(0.5), np.array(0.5)):
        same = col.point_cloud_spheres(pts, voxel, np.float64(0.01), dtype=np.float64)
        np.testing.assert_array_equal(same.radius, plain.radius)
    one = col.Spheres.create(np.zeros((2, 3)), [1.0])  # one radius for all
    np.testing.assert_array_equal(one.radius, [1.0, 1.0])


def test_point_cloud_spheres_contain_every_point():
    rng = np.random.default_rng(4)
    pts = rng.uniform(-1, 1, size=(2000, 3))
    spheres = col.point_cloud_spheres(pts, voxel=0.25, point_radius=0.01, dtype=np.float64)
    assert len(spheres) <= 8**3
    gap = np.linalg.norm(pts[:, None, :] - np.asarray(spheres.center)[None], axis=-1) - np.asarray(
        spheres.radius
    )
    assert np.all(gap.min(axis=1) <= -0.01)  # every point, grown by its radius, is inside
    assert np.asarray(spheres.radius).max() <= 0.25 * SQ3 + 0.011


# ---------------------------------------------------------------- bodies, covers and pairs


def _z_pose(angle: float, translation) -> np.ndarray:
    pose = np.eye(4)
    pose[:3, :3] = rot_z(angle)
    pose[:3, 3] = translation
    return pose


def test_body_place_and_override():
    body = col.Body.create(
        ["base", "arm", "tool"],
        spheres={"arm": (v(1, 0, 0), 0.2), "tool": (np.zeros((2, 3)), [0.1, 0.05])},
        capsules={"arm": (v(0, 0, 0), v(1, 0, 0), 0.1)},
    )
    assert body.num_spheres == 3 and body.num_capsules == 1
    assert body.sphere_link == (1, 2, 2) and body.capsule_link == (1,)
    poses = np.stack([np.eye(4), _z_pose(np.pi / 2, v(0, 0, 1)), _z_pose(0.0, v(2, 0, 0))])
    spheres, capsules = jax.jit(col.Body.place)(body, jnp.asarray(np.stack([poses, poses])))
    assert spheres.center.shape == (2, 3, 3) and capsules.radius.shape == (2, 1)
    np.testing.assert_allclose(np.asarray(spheres.center[0, 0]), v(0, 1, 1), atol=1e-15)
    np.testing.assert_allclose(np.asarray(capsules.b[1, 0]), v(0, 1, 1), atol=1e-15)
    np.testing.assert_allclose(np.asarray(spheres.center[0, 1]), v(2, 0, 0), atol=1e-15)
    own = body.with_link_spheres({"arm": (np.array([[0.5, 0, 0]]), [0.3])})
    assert own.num_capsules == 0 and own.num_spheres == 3
    assert float(own.sphere_radius[own.sphere_link.index(1)]) == 0.3
    with pytest.raises(ValueError, match="unknown link"):
        body.with_link_spheres({"hand": (np.zeros((1, 3)), [0.1])})
    with pytest.raises(ValueError, match="link_poses"):
        body.place(jnp.zeros((2, 4, 4)))


def test_body_shapes_name_the_link_and_nothing_is_reshaped():
    for center in (np.arange(6.0).reshape(3, 2), np.zeros((1, 2)), np.zeros((1, 1, 3))):
        with pytest.raises(ValueError, match=r"spheres\['a'\]: center: expected shape \(k, 3\)"):
            col.Body.create(["a"], spheres={"a": (center, [0.1, 0.2])})
    with pytest.raises(ValueError, match=r"spheres\['a'\]: radius: shape"):
        col.Body.create(["a"], spheres={"a": (np.zeros((2, 3)), [0.1, 0.2, 0.3])})
    with pytest.raises(ValueError, match=r"spheres\['a'\]: expected \(centers"):
        col.Body.create(["a"], spheres={"a": np.zeros((1, 3))})
    with pytest.raises(ValueError, match=r"capsules\['a'\]: b: expected shape \(k, 3\)"):
        col.Body.create(["a"], capsules={"a": (np.zeros((1, 3)), np.zeros((1, 2)), 0.1)})
    with pytest.raises(ValueError, match=r"spheres: expected a mapping"):
        col.Body.create(["a"], spheres=[(np.zeros((1, 3)), 0.1)])
    body = col.Body.create(["a", "b"], spheres={"a": (v(1, 2, 3), 0.5), "b": ([], [])})
    np.testing.assert_array_equal(body.sphere_center, [[1.0, 2.0, 3.0]])
    assert body.sphere_link == (0,)


def test_box_capsules_contain_the_box():
    rng = np.random.default_rng(5)
    for half in (v(0.5, 0.2, 0.05), v(0.1, 0.1, 0.1), v(0.02, 0.3, 0.3)):
        a, b, r = col.box_capsules(half)
        corners = np.array(np.meshgrid(*[[-x, x] for x in half])).reshape(3, -1).T
        inside = rng.uniform(-1, 1, size=(500, 3)) * half
        pts = np.concatenate([corners, inside])
        t = np.clip(
            np.einsum("pkc,kc->pk", pts[:, None] - a[None], b - a) / ((b - a) ** 2).sum(-1), 0, 1
        )
        foot = a[None] + t[..., None] * (b - a)[None]
        d = np.linalg.norm(pts[:, None] - foot, axis=-1) - r[None]
        assert np.all(d.min(axis=1) <= 1e-12)


def test_mesh_sphere_cover_contains_the_surface():
    """A tube (annulus, 30 cm long, radii 3 and 6 cm) in at most 6 spheres: every vertex and
    sampled surface point inside; sampled points of the spheres within the reported
    overshoot of the solid (trimesh's signed distance); one sphere overshoots more."""
    trimesh = pytest.importorskip("trimesh")
    mesh = trimesh.creation.annulus(r_min=0.03, r_max=0.06, height=0.3)
    cover = col.mesh_sphere_cover(mesh.vertices, mesh.faces, max_spheres=6)
    assert len(cover.radii) <= 6
    pts = np.concatenate([mesh.vertices, trimesh.sample.sample_surface(mesh, 3000, seed=0)[0]])
    gap = np.linalg.norm(pts[:, None] - cover.centers[None], axis=-1) - cover.radii[None]
    assert np.all(gap.min(axis=1) <= 0.0)  # every vertex and sampled surface point inside
    rng = np.random.default_rng(0)
    dirs = rng.normal(size=(100, 3))
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    shell = (cover.centers[:, None] + cover.radii[:, None, None] * dirs[None]).reshape(-1, 3)
    outside = -trimesh.proximity.signed_distance(mesh, shell)  # trimesh: positive inside
    assert outside.max() <= cover.overshoot + 1e-9
    coarse = col.mesh_sphere_cover(mesh.vertices, mesh.faces, max_spheres=1)
    assert len(coarse.radii) == 1 and coarse.overshoot >= cover.overshoot


SRDF = """<robot name="toy">
  <disable_collisions link1="l0" link2="l3" reason="Never"/>
  <disable_collisions link1="l1" link2="l2" reason="Adjacent"/>
</robot>"""


def _toy_chain():
    """A planar chain l0 - l1 - flange (no geometry) - l2 - l3, unit capsules along x."""
    links = ["l0", "l1", "flange", "l2", "l3"]
    cap = (v(0, 0, 0), v(1, 0, 0), 0.1)
    body = col.Body.create(links, capsules={name: cap for name in ("l0", "l1", "l2", "l3")})
    joints = [
        ("l0", "l1", "revolute"),
        ("l1", "flange", "fixed"),
        ("flange", "l2", "revolute"),
        ("l2", "l3", "revolute"),
    ]
    return body, joints


def _toy_poses(q):
    """Link poses of the toy chain: each joint turns about z at the end of the previous link."""
    q = jnp.atleast_2d(q)
    n = q.shape[0]
    poses, pose = [], jnp.broadcast_to(jnp.eye(4), (n, 4, 4))
    angles = [q[:, 0] * 0.0, q[:, 0], q[:, 0] * 0.0, q[:, 1], q[:, 2]]
    offsets = [0.0, 1.0, 1.0, 0.0, 1.0]
    for angle, offset in zip(angles, offsets, strict=True):
        c, s = jnp.cos(angle), jnp.sin(angle)
        step = jnp.zeros((n, 4, 4)).at[:, 0, 0].set(c).at[:, 0, 1].set(-s).at[:, 1, 0].set(s)
        step = (
            step.at[:, 1, 1]
            .set(c)
            .at[:, 2, 2]
            .set(1.0)
            .at[:, 3, 3]
            .set(1.0)
            .at[:, 0, 3]
            .set(offset)
        )
        pose = pose @ step
        poses.append(pose)
    return jnp.stack(poses, axis=1)


def test_srdf_adjacency_and_self_pairs():
    body, joints = _toy_chain()
    disabled = col.read_srdf_disabled(SRDF)
    assert disabled == (("l0", "l3", "Never"), ("l1", "l2", "Adjacent"))
    adjacent = col.adjacent_links(body, joints)  # through the geometry-less flange
    assert adjacent == {frozenset(p) for p in (("l0", "l1"), ("l1", "l2"), ("l2", "l3"))}
    pairs = col.self_collision_link_pairs(body, joints, disabled)
    names = [(body.links[i], body.links[j]) for i, j in pairs]
    assert names == [("l0", "l2"), ("l1", "l3")]
    with pytest.raises(ValueError, match="disabled"):
        col.self_collision_link_pairs(body, joints, [("l0", "nope")])
    # l3 fixed to l2 instead: one rigid body, adjacent to l1 (and to l2) as l2 is
    rigid = [*joints[:3], ("l2", "l3", "fixed")]
    assert col.adjacent_links(body, rigid) == adjacent | {frozenset(("l1", "l3"))}
    assert col.adjacent_links(body, rigid, through_fixed=False) == adjacent
    names = [(body.links[i], body.links[j]) for i, j in col.self_collision_link_pairs(body, rigid)]
    assert names == [("l0", "l2"), ("l0", "l3")]
    # folded back on itself: l2 (turned by pi) runs over l1, l3 ends near the base
    sp = col.SelfPairs.create(body, pairs)

    @jax.jit
    def distances(q):
        return col.self_distances(*body.place(_toy_poses(q)), sp)

    d = np.asarray(distances(jnp.array([[0.0, np.pi, 0.0], [0.0, 0.0, 0.0]])))
    # stretched out: l0 [0,1] and l2 [2,3] are 1 apart, l1 and l3 too; minus two radii
    np.testing.assert_allclose(d[1], [0.8, 0.8], atol=1e-14)
    assert d[0, 0] < 0  # l2 lies back over l0's end region


def test_propose_disabled_from_samples():
    body, joints = _toy_chain()
    rng = np.random.default_rng(0)
    q = rng.uniform(-0.3, 0.3, size=(64, 3))  # nearly straight: nothing folds back
    proposed = col.propose_disabled(body, _toy_poses, q, chunk=32)
    assert ("l0", "l2") in proposed["never"] and ("l0", "l3") in proposed["never"]
    assert ("l0", "l1") in proposed["always"]  # they share a joint: always touching


def test_panda_srdf_pairs_and_moveit_adjacency():
    """example-robot-data's Panda: the SRDF disables 35 pairs; the adjacency rule gives exactly
    the pairs MoveIt's setup assistant marked "Adjacent"; 20 link pairs remain to check."""
    import sys
    from pathlib import Path

    pytest.importorskip("yourdfpy")
    roots = [Path(p) / "cmeel.prefix/share/example-robot-data/robots" for p in sys.path]
    root = next((r for r in roots if r.is_dir()), None)
    if root is None:
        pytest.skip("example-robot-data is not installed")
    read = col.body_from_urdf(root / "panda_description/urdf/panda_collision.urdf")
    disabled = col.read_srdf_disabled(root / "panda_description/srdf/panda.srdf")
    assert len(disabled) == 35
    marked = {frozenset(d[:2]) for d in disabled if d[2] == "Adjacent"}
    assert col.adjacent_links(read.body, read.joints, through_fixed=False) == marked
    # link 7, the flange link 8 and the hand are one rigid body: the hand is adjacent to
    # link 6 as well, and the fingers to link 7, pairs the SRDF disables from samples
    extra = col.adjacent_links(read.body, read.joints) - marked
    assert extra == {
        frozenset(p)
        for p in [
            ("panda_link6", "panda_hand"),
            ("panda_link7", "panda_leftfinger"),
            ("panda_link7", "panda_rightfinger"),
        ]
    }
    assert extra <= {frozenset(d[:2]) for d in disabled}
    pairs = col.self_collision_link_pairs(read.body, read.joints, disabled)
    assert len(pairs) == 20
    names = {frozenset((read.body.links[i], read.body.links[j])) for i, j in pairs}
    assert frozenset(("panda_link2", "panda_hand")) in names
    assert not names & {frozenset(d[:2]) for d in disabled}


@pytest.mark.parametrize("d", [3, 2])
def test_segment_and_box_distances_against_dense_sampling(d):
    """In 3-D and 2-D (the planar robots' obstacle costs): the nearest point of a segment
    against 20,001 points along it; axis-aligned boxes against the closed form of a point
    outside (distance to the clamped point) and inside (face depth)."""
    rng = np.random.default_rng(11)
    a, b = rng.normal(size=(2, 4, d))
    points = rng.normal(size=(5, d))
    t = np.linspace(0.0, 1.0, 20001)[:, None, None]
    dense = np.min(np.linalg.norm(a + t * (b - a) - points[:, None, None], axis=-1), axis=1).T
    distance = jax.jit(lambda a, b, p: sd.point_segment(p, a[..., None, :], b[..., None, :]))
    np.testing.assert_allclose(distance(a, b, points), dense, atol=1e-7)
    same = distance(a, a, points)
    np.testing.assert_allclose(same, np.linalg.norm(a[:, None] - points, axis=-1), rtol=1e-15)
    half = np.array([1.0, 2.0, 3.0])[:d]
    probe = np.array([[2.0, 0.5, 0.0], [2.0, 3.0, 4.0], [0.5, 0.0, 0.0], [0.0, 0.0, -2.5]])
    want = [1.0, np.sqrt(3.0), -0.5, -0.5] if d == 3 else [1.0, np.sqrt(2.0), -0.5, -1.0]
    got = jax.jit(lambda p: sd.point_box(p, np.zeros(d), None, half))(probe[:, :d])
    np.testing.assert_allclose(got, want, rtol=1e-15)
