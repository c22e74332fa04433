"""Cylinders: the primitive, exact signed distances (hand-derived values, an independent
reference in every regime, eager and jitted, gradients, float32), the world's per-primitive
query, and the batched checks that take them.

The cross-checks against coal and against an independent minimisation of the penetration
depth over the whole sphere of directions are in tests/test_collision_coal.py (slow tier).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxkin
from jaxkin import collision as col
from jaxkin import costs, plan, scara
from jaxkin.collision import distance as sd

from .helpers import compilations, gradient_against_differences
from .references import cylinders as reference

Z = np.array([0.0, 0.0, 1.0])
O = np.zeros(3)
SQ2 = np.sqrt(2.0)
NEAREST = jax.jit(col.nearest_obstacles)


def v(*x) -> np.ndarray:
    return np.array(x, dtype=float)


# the cylinder r = 1, h = 1 along z about the origin unless given; expected by hand
EY, DH = v(-1, 0, 1) / SQ2, v(1, 0, 1) / SQ2  # a segment at 45 degrees in the xz plane
POINTS = [
    ("radially out", v(3, 0, 0.5), 2.0),
    ("axially out", v(0.5, 0, 4), 3.0),
    ("rim corner", v(4, 0, 5), 5.0),
    ("inside near side", v(0.9, 0, 0), -0.1),
    ("inside near cap", v(0, 0.2, -0.95), -0.05),
    ("centre", v(0, 0, 0), -1.0),
    ("on the rim", v(0, 1, 1), 0.0),
]
SEGMENTS = [
    ("apart, parallel to the axis", v(2, 0, -5), v(2, 0, 5), 1.0),
    ("apart, over the cap", v(-5, 0, 3), v(5, 0, 3), 2.0),
    ("apart, past the rim", v(2, 0, 2), v(3, 0, 3), SQ2),
    ("through, across", v(-3, 0, 0), v(3, 0, 0), -1.0),  # push sideways by r or along z by h
    ("through, under the cap", v(-3, 0, 0.9), v(3, 0, 0.9), -0.1),
    ("along the axis, inside", v(0, 0, -0.5), v(0, 0, 0.5), -1.0),
    ("along the axis, through", v(0, 0, -3), v(0, 0, 3), -1.0),
    ("along the axis, apart", v(0, 0, 2), v(0, 0, 3), 1.0),
    ("parallel inside", v(0.7, 0, -0.5), v(0.7, 0, 0.5), -0.3),
    ("a point inside", v(0.3, 0, 0.5), v(0.3, 0, 0.5), -0.5),
    # perpendicular to the segment past the rim: the projected cylinder's upper rim is the
    # half-ellipse of semi-axes 1 and 1/sqrt(2) centred 1/sqrt(2) above the projected axis;
    # the segment projects 0.9 above it, below the rim's top vertex: depth sqrt(2) - 0.9
    ("through, past the rim", 0.9 * EY - 5 * DH, 0.9 * EY + 5 * DH, -(SQ2 - 0.9)),
]


@pytest.mark.parametrize("name, p, expected", POINTS, ids=[c[0] for c in POINTS])
def test_point_cylinder_by_hand(name, p, expected):
    got = float(jax.jit(sd.point_cylinder)(p, O, Z, 1.0, 1.0))
    assert got == pytest.approx(expected, abs=1e-15)
    assert float(sd.sphere_cylinder(p, 0.25, O, Z, 1.0, 1.0)) == pytest.approx(got - 0.25)


@pytest.mark.parametrize("name, a, b, expected", SEGMENTS, ids=[c[0] for c in SEGMENTS])
def test_segment_cylinder_by_hand(name, a, b, expected):
    got = float(jax.jit(sd.segment_cylinder)(a, b, O, Z, 1.0, 1.0))
    assert got == pytest.approx(expected, abs=1e-14)
    capsule = float(jax.jit(sd.capsule_cylinder)(a, b, 0.25, O, Z, 1.0, 1.0))
    assert capsule == pytest.approx(got - 0.25, abs=1e-14)


def test_rigid_motion_scale_and_orientation_of_the_axis():
    """Distances are invariant under a rigid motion of both shapes, under flipping the axis,
    and scale with size, in float64 (1e-13 relative) and float32 (3e-6 relative)."""
    rng = np.random.default_rng(5)
    n = 256
    a, b = rng.normal(size=(n, 3)), rng.normal(size=(n, 3))
    c = 0.3 * rng.normal(size=(n, 3))
    axis = rng.normal(size=(n, 3))
    axis /= np.linalg.norm(axis, axis=1, keepdims=True)
    r, h = rng.uniform(0.1, 1.0, n), rng.uniform(0.1, 1.0, n)
    f = jax.jit(sd.segment_cylinder)
    base = np.asarray(f(a, b, c, axis, r, h))
    assert np.sum(base < 0) > n // 8 and np.sum(base > 0) > n // 8
    q = np.linalg.qr(rng.normal(size=(3, 3)))[0]
    q *= np.sign(np.linalg.det(q))
    t = rng.normal(size=3)
    moved = f(a @ q.T + t, b @ q.T + t, c @ q.T + t, axis @ q.T, r, h)
    np.testing.assert_allclose(np.asarray(moved), base, atol=1e-13)
    np.testing.assert_allclose(np.asarray(f(b, a, c, -axis, r, h)), base, atol=1e-13)
    for scale in (1e-3, 1e3):
        scaled = f(scale * a, scale * b, scale * c, axis, scale * r, scale * h)
        np.testing.assert_allclose(np.asarray(scaled) / scale, base, atol=1e-13)
        f32 = [jnp.asarray(x, jnp.float32) for x in (scale * a, scale * b, scale * c, axis)]
        d32 = f(*f32, jnp.asarray(scale * r, jnp.float32), jnp.asarray(scale * h, jnp.float32))
        assert d32.dtype == jnp.float32
        np.testing.assert_allclose(np.asarray(d32) / scale, base, atol=3e-6)


# In contact, in penetration, on the axis, at the rim, and degenerate: every gradient finite.
DEGENERATE = [
    (v(0, 0, 0), v(0, 0, 0), O, Z, 1.0, 1.0),  # a point at the centre
    (v(0, 0, -3), v(0, 0, 3), O, Z, 1.0, 1.0),  # along the axis, through
    (v(1, 0, 1), v(2, 0, 2), O, Z, 1.0, 1.0),  # touching the rim
    (v(1, 0, 1), v(1, 0, 1), O, Z, 1.0, 1.0),  # a point on the rim
    (v(1, 0, -2), v(1, 0, 2), O, Z, 1.0, 1.0),  # along the side
    (v(-2, 0, 1), v(2, 0, 1), O, Z, 1.0, 1.0),  # across the cap
    (v(-2, 0, 0), v(2, 0, 0), O, Z, 0.0, 1.0),  # radius 0: a segment
    (v(-2, 0, 0), v(2, 0, 0), O, Z, 1.0, 0.0),  # half-length 0: a disk
    (v(-2, 0, 0.5), v(2, 0, 0.5), O, Z, 0.0, 0.0),  # a point
    (v(0, 0, 0.5), v(0, 0, 0.5), O, Z, 0.0, 1.0),  # a point on a segment
    (0.9 * EY - 5 * DH, 0.9 * EY + 5 * DH, O, Z, 1.0, 1.0),  # through, past the rim
    (v(1, -1, 1), v(1, 1, 1), O, Z, 1.0, 1.0),  # tangent to the rim
    (v(0, 0, 2), v(0, 0, 2), O, Z, 1.0, 1.0),  # a point on the axis, apart
    (v(0, 0, 1), v(0, 0, 3), O, Z, 1.0, 1.0),  # along the axis, touching a cap
    (v(0, 0, -0.5), v(0, 0, 0.5), O, Z, 1.0, 1.0),  # along the axis, inside
    (v(2, 0, -0.5), v(2, 0, 0.5), O, Z, 1.0, 1.0),  # parallel, beside the side
    (v(0.5, 0, 1), v(0.5, 0, 1), O, Z, 1.0, 1.0),  # a point on a cap
]


def test_gradients_finite_everywhere():
    """All the cases in one batch (each row its own pair), with 8 pairs of each of the
    reference's regimes: the gradient of the sum is each pair's gradient."""
    rows = [np.stack([np.broadcast_to(np.asarray(case[k], float), np.shape(DEGENERATE[0][k]))
                      for case in DEGENERATE]) for k in range(6)]  # fmt: skip
    args = [jnp.asarray(np.concatenate(x)) for x in zip(rows, _regime_pairs(8), strict=True)]

    def total(fn, *xs):
        return jnp.sum(fn(*xs))

    segment = jax.jit(jax.grad(lambda *x: total(sd.segment_cylinder, *x), argnums=range(6)))
    point = jax.jit(jax.grad(lambda *x: total(sd.point_cylinder, *x), argnums=range(5)))
    values = np.asarray(jax.jit(sd.segment_cylinder)(*args))
    assert np.all(np.isfinite(values)) and np.all(values[: len(DEGENERATE)] <= 1.0 + 1e-15)
    for grads in (segment(*args), point(args[0], *args[2:])):
        assert all(np.all(np.isfinite(np.asarray(g))) for g in grads)


def _regime_pairs(per_regime: int) -> tuple[np.ndarray, ...]:
    rng = np.random.default_rng(12)
    parts = [reference.pairs(rng, per_regime, regime) for regime in reference.REGIMES]
    return tuple(np.concatenate(x) for x in zip(*parts, strict=True))


def test_segment_cylinder_against_the_reference_in_every_regime():
    """336 segment-cylinder pairs, 24 in each of the reference's regimes (random, parallel and
    perpendicular to the axis, exactly or nearly, through the axis, within a hair's breadth of
    the rim, a cap or the side, points, radius or length 0, the rim problem's double root,
    along the axis): jitted and eager, each equals the independent reference
    (tests/references/cylinders.py: the minimum along the segment where apart, the support
    function's minimum over +-axis and its two great circles where overlapping) to 1e-14 of
    the pair's size, and the two agree to 1e-14 (main's bisection differed between them by
    up to the cylinder's size); float32 equals float64 on the same inputs to 3e-6 of the size.
    """
    pairs = _regime_pairs(24)
    a, b, _, _, radius, half = pairs
    size = np.maximum.reduce([radius, half, np.linalg.norm(b - a, axis=1)])
    # support <= sd <= along, equal to along where apart (a disk's crossing gives 0 to rounding)
    along = reference.along(*pairs)
    want = np.where(along > 1e-14 * size, along, reference.support(*pairs))
    assert 0.25 < np.mean(want > 0) < 0.75
    jitted = np.asarray(jax.jit(sd.segment_cylinder)(*pairs))
    eager = np.asarray(sd.segment_cylinder(*pairs))
    for got in (jitted, eager):
        np.testing.assert_array_less(np.abs(got - want), 1e-14 * size)
    np.testing.assert_array_less(np.abs(jitted - eager), 1e-14 * size)

    rounded = [np.asarray(x, np.float32) for x in pairs]
    low = jax.jit(sd.segment_cylinder)(*rounded)
    assert low.dtype == jnp.float32
    high = np.asarray(jax.jit(sd.segment_cylinder)(*[x.astype(np.float64) for x in rounded]))
    np.testing.assert_array_less(np.abs(np.asarray(low, np.float64) - high), 3e-6 * size)


def _capsule_cylinder_unit(a, b, r, center, axis, radius, half):
    """``capsule_cylinder`` with the axis normalised inside (finite differences may move it)."""
    return sd.capsule_cylinder(a, b, r, center, axis / jnp.linalg.norm(axis), radius, half)


_CAPSULE = jax.jit(_capsule_cylinder_unit)
_CAPSULE_GRAD = jax.jit(jax.grad(_capsule_cylinder_unit, argnums=tuple(range(7))))


def _fd_check(args):
    gradient_against_differences(_CAPSULE, args, grad=_CAPSULE_GRAD)


@pytest.mark.parametrize(
    "name, a, b",
    [
        ("apart, side", v(1.6, 0.3, -0.4), v(1.9, -0.2, 0.7)),
        ("apart, past the rim", v(1.3, 0.2, 1.4), v(2.1, -0.4, 1.9)),
        ("apart, over the cap", v(-0.3, 0.2, 1.5), v(0.4, -0.1, 1.8)),
        ("through, under the cap", v(-2.0, 0.1, 0.83), v(2.1, -0.2, 0.86)),
        ("through, sideways", v(-2.0, 0.35, 0.1), v(2.1, 0.4, -0.2)),
        ("through, past the rim", 0.9 * EY - 5 * DH + v(0.02, 0.01, 0), 0.9 * EY + 5 * DH),
    ],
)
def test_gradients_match_finite_differences(name, a, b):
    """Autodiff through the stopped parameters (Danskin; for the rims, the distance from the
    rim point to the segment's line) equals central differences, in every regime."""
    _fd_check((a, b, 0.1, v(0.02, -0.01, 0.03), v(0.05, -0.03, 1.0), 1.0, 1.0))


def test_cylinders_create_and_errors_name_the_argument():
    rot = np.array([[1.0, 0, 0], [0, 0, -1], [0, 1, 0]])  # its z axis is -y
    by_rotation = col.Cylinders.create([[1, 2, 3]], 0.5, 2.0, rotation=rot[None])
    np.testing.assert_allclose(by_rotation.axis, [[0, -1, 0]])
    by_axis = col.Cylinders.create([[1, 2, 3], [0, 0, 0]], [0.5, 0.2], 2.0, axis=[0, 0, 2])
    np.testing.assert_allclose(by_axis.axis, [[0, 0, 1], [0, 0, 1]])  # normalised, broadcast
    np.testing.assert_allclose(by_axis.half_length, [2.0, 2.0])
    assert len(by_axis) == 2 and len(col.Cylinders.empty()) == 0
    default = col.Cylinders.create([0, 0, 0], 1.0, 1.0)
    np.testing.assert_allclose(default.axis, [[0, 0, 1]])
    for kwargs, match in (
        (dict(center=[[0, 0, 0]], radius=-1.0, half_length=1.0), "radius must be >= 0"),
        (dict(center=[[0, 0, 0]], radius=1.0, half_length=-1.0), "half_length must be >= 0"),
        (dict(center=[[0, 0, 0]], radius=1.0, half_length=1.0, axis=[0, 0, 0]), "axis"),
        (dict(center=[[0, 0]], radius=1.0, half_length=1.0), "center: expected shape"),
        (dict(center=[[0, 0, 0]], radius=[1.0, 2.0], half_length=1.0), "radius: shape"),
        (dict(center=[[0, 0, 0]], radius=np.nan, half_length=1.0), "radius must be finite"),
        (dict(center=[[0, 0, 0]], radius=1.0, half_length=1.0, rotation=2 * np.eye(3)),
         "rotation must be proper"),
        (dict(center=[[0, 0, 0]], radius=1.0, half_length=1.0, axis=Z, rotation=np.eye(3)),
         "give one of them"),
    ):  # fmt: skip
        with pytest.raises(ValueError, match=match):
            col.Cylinders.create(**kwargs)


def test_boxes_create_names_its_argument_order():
    """The fields are (center, rotation, half_extents), create takes (center, half_extents,
    rotation): rotations passed second are refused with the order spelled out."""
    with pytest.raises(ValueError, match=r"Boxes.create takes \(center, half_extents"):
        col.Boxes.create(np.zeros((2, 3)), np.broadcast_to(np.eye(3), (2, 3, 3)))
    with pytest.raises(ValueError, match=r"Boxes.create takes \(center, half_extents"):
        col.Boxes.create(np.zeros(3), np.eye(3))
    three = col.Boxes.create(np.zeros((3, 3)), np.ones((3, 3)))  # three boxes: not a rotation
    assert len(three) == 3


def _world(rng, dtype=jnp.float64):
    axis = rng.normal(size=(3, 3))
    return col.World.create(
        spheres=col.Spheres.create(rng.normal(size=(2, 3)), 0.2),
        boxes=col.Boxes.create(rng.normal(size=(1, 3)), [[0.2, 0.3, 0.4]]),
        cylinders=col.Cylinders.create(
            2.0 * rng.normal(size=(3, 3)), [0.1, 0.3, 0.5], [0.5, 0.2, 1.0], axis=axis
        ),
        dtype=dtype,
    )


def test_nearest_obstacles_includes_cylinders():
    """Each robot primitive's nearest obstacle over a world with cylinders equals the smallest
    of the pair kernels called one pair at a time; any leading batch axes."""
    rng = np.random.default_rng(9)
    world = _world(rng)
    assert world.counts() == {
        "spheres": 2,
        "capsules": 0,
        "boxes": 1,
        "halfspaces": 0,
        "cylinders": 3,
    }
    centers = 1.5 * rng.normal(size=(4, 5, 3))
    a, b = 1.5 * rng.normal(size=(4, 2, 3)), 1.5 * rng.normal(size=(4, 2, 3))
    near_s, near_c = NEAREST(
        col.Spheres.create(centers, 0.1), col.Capsules.create(a, b, 0.1), world
    )
    cyl, sph, box = world.cylinders, world.spheres, world.boxes
    # every (robot primitive, obstacle) pair, one kernel call per pair of kinds
    p = centers[..., None, :]
    to_spheres = sd.sphere_sphere(p, 0.1, sph.center, sph.radius)
    to_box = sd.sphere_box(p, 0.1, box.center, box.rotation, box.half_extents)
    to_cyl = sd.sphere_cylinder(p, 0.1, cyl.center, cyl.axis, cyl.radius, cyl.half_length)
    table = np.concatenate([to_spheres, to_box, to_cyl], axis=-1)
    which = [(col.SPHERE, 0), (col.SPHERE, 1), (col.BOX, 0)] + [(col.CYLINDER, k) for k in range(3)]
    np.testing.assert_allclose(np.asarray(near_s.distance), table.min(axis=-1), atol=1e-14)
    for i in np.ndindex(4, 5):
        assert (int(near_s.kind[i]), int(near_s.index[i])) == which[int(np.argmin(table[i]))]
    caps = jax.jit(sd.capsule_cylinder)(
        a[..., None, :], b[..., None, :], 0.1, cyl.center, cyl.axis, cyl.radius,
        cyl.half_length,
    )  # fmt: skip
    assert np.all(np.asarray(near_c.distance) <= np.asarray(caps).min(axis=-1) + 1e-14)
    assert np.any(np.asarray(near_s.kind) == col.CYLINDER)


@pytest.mark.slow
def test_world_astype_and_float32_distances():
    rng = np.random.default_rng(4)
    world = _world(rng)
    small = world.astype(jnp.float32)
    assert small.cylinders.axis.dtype == jnp.float32
    assert col.World.create(cylinders=world.cylinders, dtype=jnp.float32).cylinders.radius.dtype
    robot = col.Spheres.create(rng.normal(size=(6, 3)), 0.1)
    capsules = col.Capsules.create(rng.normal(size=(3, 3)), rng.normal(size=(3, 3)), 0.1)
    ref = NEAREST(robot, capsules, world)
    low = NEAREST(
        jax.tree.map(lambda x: x.astype(jnp.float32), robot),
        jax.tree.map(lambda x: x.astype(jnp.float32), capsules),
        small,
    )
    for r, lo in zip(ref, low, strict=True):
        assert lo.distance.dtype == jnp.float32
        np.testing.assert_allclose(np.asarray(lo.distance), np.asarray(r.distance), atol=2e-6)


@pytest.mark.slow
def test_program_size_does_not_grow_with_the_number_of_cylinders():
    """The per-primitive query is vectorised over cylinders: 2 or 40 of them give the same
    program (equation count), and moving or resizing them does not recompile."""
    rng = np.random.default_rng(2)
    robot = col.Spheres.create(rng.normal(size=(3, 3)), 0.1)
    capsules = col.Capsules.create(rng.normal(size=(2, 3)), rng.normal(size=(2, 3)), 0.1)

    def size(count):
        world = col.World.create(
            cylinders=col.Cylinders.create(rng.normal(size=(count, 3)), 0.2, 0.3)
        )
        jaxpr = jax.make_jaxpr(col.nearest_obstacles)(robot, capsules, world)
        return len(jaxpr.eqns) + sum(
            len(e.params["jaxpr"].eqns) for e in jaxpr.eqns if "jaxpr" in e.params
        )

    assert size(2) == size(40)
    query = NEAREST

    def world(scale):
        return col.World.create(
            cylinders=col.Cylinders.create(scale * np.ones((3, 3)), scale * 0.2, 0.3)
        )

    query(robot, capsules, world(1.0))
    with compilations() as count:
        query(robot, capsules, world(2.0))
    assert count.n == 0


def test_obstacle_cost_takes_cylinders():
    """The optimiser's obstacle term goes through nearest_obstacles: a robot sphere 0.1 from a
    cylinder with safety 0.4 pays ((0.4 - 0.1) / 0.4)^2."""
    world = col.World.create(cylinders=col.Cylinders.create([[0.0, 0.0, 0.0]], 0.5, 1.0))
    term = costs.Obstacles.create(world=world, safety=0.4)
    assert len(term.world.cylinders) == 1
    robot = col.Spheres.create([[0.7, 0.0, 0.0]], 0.1)
    near, _ = NEAREST(robot, col.Capsules.empty(), term.world)
    assert float(near.distance[0]) == pytest.approx(0.1, abs=1e-15)
    assert float(term._barrier(near.distance, 0.4)[0]) == pytest.approx((0.3 / 0.4) ** 2)


def test_batched_checks_take_cylinders():
    """A SCARA (capsules) and a UR5 chain with spheres among cylinders (and a box): the
    batched check's clearance and closest obstacle equal the per-primitive reference
    (``nearest_obstacles``) to 1e-12, the verdict agrees with it away from contact, the
    handles and the planner take the world."""
    from jaxkin.collision.check import _check_per_primitive

    rng = np.random.default_rng(31)
    scara_robot = scara.Scara(150.0, 80.0, 50.0, link_radius=4.0)
    cylinders = col.Cylinders.create(
        rng.uniform(-150.0, 150.0, (11, 3)) * [1, 1, 0.3] + [0, 0, 60.0],
        rng.uniform(5.0, 20.0, 11),
        rng.uniform(5.0, 40.0, 11),
        axis=rng.normal(size=(11, 3)),
    )
    world = col.World.create(
        cylinders=cylinders, boxes=col.Boxes.create([[0.0, 140.0, 50.0]], [[10.0, 10.0, 30.0]])
    )
    q = np.stack(
        [rng.uniform(-3, 3, 300), rng.uniform(-2.5, 2.5, 300), rng.uniform(0, 90, 300)], -1
    )
    got = col.check(scara_robot, q, world)
    body, pairs = col.prepare(scara_robot)
    want = jax.jit(_check_per_primitive)(scara_robot, body, pairs, jnp.asarray(q), world)
    np.testing.assert_allclose(got.clearance, want.clearance, rtol=0, atol=1e-12)
    np.testing.assert_array_equal(got.world.kind, want.world.kind)
    np.testing.assert_array_equal(got.world.index, want.world.index)
    assert np.any(np.asarray(got.world.kind) == col.CYLINDER)
    hit = np.asarray(want.collides)
    assert 0.05 < np.mean(hit) < 0.95
    verdict = np.asarray(col.collides(scara_robot, q, world).collides)
    near = np.abs(np.asarray(want.clearance)) < 1e-9
    np.testing.assert_array_equal(verdict[~near], hit[~near])
    handle = jaxkin.compiled(col.collides, scara_robot, world, batch=300, dtype=np.float64)
    np.testing.assert_array_equal(handle(q).collides, verdict)
    ev = plan.evaluate(scara_robot, jaxkin_path(scara_robot), world=world)
    assert ev.status.shape == (1, 8)


def jaxkin_path(robot):
    from jaxkin import fk, paths

    q = np.linspace([0.1, 0.2, 10.0], [0.3, 0.4, 20.0], 8)[None]
    points = np.asarray(fk(robot, q).x.p)
    return paths.path_from_samples(points, 0.1)
