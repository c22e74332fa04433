"""Cross-checks of the collision geometry against independent references (slow tier).

- Signed distances of random pairs, separated and penetrating, against coal (the FCL fork
  Pinocchio uses) to 1e-9, and capsule-box penetration depths against qhull's facets of the
  Minkowski difference; cylinders against coal (signs, separated distances) and their
  penetration depths against a minimisation of the support function.
- The sphere covers of Panda's and UR5's collision meshes hold every vertex and sampled
  surface point within their overshoot bounds; no collision coal finds on the meshes is
  missed, and the false-positive rates are printed.
"""

from __future__ import annotations

import sys
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxkin import collision as col
from jaxkin.collision import distance as sd
from jaxkin.serial import from_urdf as serial_from_urdf

from .references import cylinders as cylinder_reference

coal = pytest.importorskip("coal")
Rotation = pytest.importorskip("scipy.spatial.transform").Rotation
ConvexHull = pytest.importorskip("scipy.spatial").ConvexHull

pytestmark = pytest.mark.slow

N = 400
TOL = 1e-9


def _robots() -> Path:
    for base in map(Path, sys.path):
        root = base / "cmeel.prefix" / "share" / "example-robot-data" / "robots"
        if root.is_dir():
            return root
    pytest.skip("example-robot-data's robots folder not found")


def _coal_distance(g1, t1, g2, t2) -> float:
    request, result = coal.DistanceRequest(), coal.DistanceResult()
    return coal.distance(g1, t1, g2, t2, request, result)


def _pose(rotation=None, translation=(0.0, 0.0, 0.0)):
    return coal.Transform3s(np.eye(3) if rotation is None else rotation, np.asarray(translation))


def _coal_capsule(a, b, r):
    """coal's capsule is centred on its frame, along z, of length ``lz``."""
    d = b - a
    length = np.linalg.norm(d)
    rot = Rotation.align_vectors([d / length], [[0.0, 0.0, 1.0]])[0].as_matrix()
    return coal.Capsule(r, length), _pose(rot, 0.5 * (a + b))


def _random_rotations(rng, n):
    return Rotation.random(n, random_state=rng.integers(1 << 31)).as_matrix()


def _pairs(rng):
    """Random robot primitives and obstacles at mixed scales, many of them overlapping; a
    quarter of the segments are along a box axis or nearly parallel to one another."""
    scale = 10.0 ** rng.uniform(-1, 1, N)[:, None]
    a = rng.normal(size=(N, 3)) * scale
    d = rng.normal(size=(N, 3)) * scale
    d[: N // 8] = np.eye(3)[rng.integers(0, 3, N // 8)] * scale[: N // 8]  # along a box axis
    b = a + d
    r = rng.uniform(0.02, 0.4, N) * scale[:, 0]
    c = a + rng.normal(size=(N, 3)) * 0.6 * scale
    h = rng.uniform(0.05, 1.0, (N, 3)) * scale
    rot = _random_rotations(rng, N)
    rot[: N // 8] = np.eye(3)
    c2 = c + rng.normal(size=(N, 3)) * 0.3 * scale
    e = rng.normal(size=(N, 3)) * scale
    e[N // 8 : N // 4] = d[N // 8 : N // 4] * rng.uniform(-1, 1, (N // 8, 1))  # ~parallel
    e[N // 8 : N // 4] += 1e-7 * rng.normal(size=(N // 8, 3)) * scale[N // 8 : N // 4]
    r2 = rng.uniform(0.02, 0.4, N) * scale[:, 0]
    return a, b, r, c, h, rot, c2, c2 + e, r2


def _segment_distance_1d(a0, a1, b0, b1) -> float:
    """Distance between two segments by minimising the convex function ``s -> dist(p(s),
    segment b)`` (Brent's bounded method, point-segment distance in closed form)."""
    minimize_scalar = pytest.importorskip("scipy.optimize").minimize_scalar
    d = b1 - b0

    def gap(s: float) -> float:
        p = a0 + s * (a1 - a0)
        t = np.clip((p - b0) @ d / (d @ d), 0.0, 1.0)
        return float(np.linalg.norm(p - b0 - t * d))

    best = minimize_scalar(gap, bounds=(0.0, 1.0), method="bounded", options={"xatol": 1e-13})
    return min(best.fun, gap(0.0), gap(1.0))


def _compare(mine, ref, name):
    mine, ref = np.asarray(mine), np.asarray(ref)
    assert np.sum(ref < 0) >= N // 20 and np.sum(ref > 0) >= N // 20, f"{name}: regimes"
    err = np.abs(mine - ref)
    assert err.max() <= TOL, f"{name}: largest error {err.max():.2e} at {np.argmax(err)}"


def test_distances_against_coal():
    rng = np.random.default_rng(20)
    a, b, r, c, h, rot, p0, p1, r2 = _pairs(rng)
    box = [(coal.Box(*(2 * h[i])), _pose(rot[i], c[i])) for i in range(N)]
    cap = [_coal_capsule(a[i], b[i], r[i]) for i in range(N)]
    cap2 = [_coal_capsule(p0[i], p1[i], r2[i]) for i in range(N)]
    sph = [(coal.Sphere(r[i]), _pose(None, a[i])) for i in range(N)]
    sph2 = [(coal.Sphere(r2[i]), _pose(None, p0[i])) for i in range(N)]
    normal = rng.normal(size=(N, 3))
    normal /= np.linalg.norm(normal, axis=1, keepdims=True)
    offset = np.einsum("ij,ij->i", normal, c)
    half = [(coal.Halfspace(normal[i], offset[i]), _pose()) for i in range(N)]

    def ref(first, second):
        return [_coal_distance(*first[i], *second[i]) for i in range(N)]

    jit = jax.jit
    _compare(jit(sd.capsule_box)(a, b, r, c, rot, h), ref(cap, box), "capsule-box")
    _compare(jit(sd.sphere_box)(a, r, c, rot, h), ref(sph, box), "sphere-box")
    # coal's capsule-capsule is not exact for nearly parallel segments (measured: 7e-8 off
    # at a relative angle of 1e-7): those are compared with a convex 1-D minimisation instead
    cc = np.asarray(jit(sd.capsule_capsule)(a, b, r, p0, p1, r2))
    cc_coal = np.asarray(ref(cap, cap2))
    parallel = np.zeros(N, bool)
    parallel[N // 8 : N // 4] = True
    _compare(np.where(parallel, cc_coal, cc), cc_coal, "capsule-capsule")
    exact = [_segment_distance_1d(a[i], b[i], p0[i], p1[i]) - r[i] - r2[i] for i in range(N)]
    np.testing.assert_allclose(cc[parallel], np.asarray(exact)[parallel], atol=TOL)
    assert np.abs(cc_coal - cc)[parallel].max() < 1e-6
    _compare(jit(sd.sphere_capsule)(p0, r2, a, b, r), ref(sph2, cap), "sphere-capsule")
    _compare(jit(sd.sphere_sphere)(a, r, p0, r2), ref(sph, sph2), "sphere-sphere")
    _compare(jit(sd.sphere_halfspace)(a, r, normal, offset), ref(sph, half), "sphere-halfspace")
    _compare(
        jit(sd.capsule_halfspace)(a, b, r, normal, offset), ref(cap, half), "capsule-halfspace"
    )


def test_segment_box_depth_against_qhull():
    """Inside, minus the distance from the origin to the boundary of the Minkowski difference
    box - segment: qhull's facets of the 16 differences of corners and end points."""
    rng = np.random.default_rng(21)
    corners = np.array(np.meshgrid([-1, 1], [-1, 1], [-1, 1])).reshape(3, -1).T
    mine, ref = [], []
    while len(ref) < 200:
        h = rng.uniform(0.1, 1.0, 3)
        u0 = rng.uniform(-1, 1, 3) * h * 1.2
        u1 = u0 + rng.normal(size=3) * 0.8
        pts = np.concatenate([corners * h - u0, corners * h - u1])
        hull = ConvexHull(pts)
        offsets = -hull.equations[:, 3]  # facets n . x <= offset, unit n
        if offsets.min() <= 1e-6:
            continue  # origin outside the difference: no penetration
        ref.append(-offsets.min())
        mine.append(float(jax.jit(sd.segment_box)(u0, u1, np.zeros(3), np.eye(3), h)))
    np.testing.assert_allclose(mine, ref, atol=1e-12)


def _cylinder_pairs(rng, n):
    """Random cylinders and capsules at mixed scales, about a third overlapping; an eighth of
    the segments nearly parallel to the axis, an eighth exactly perpendicular to it."""
    scale = 10.0 ** rng.uniform(-1, 1, n)[:, None]
    c = rng.normal(size=(n, 3)) * scale
    axis = rng.normal(size=(n, 3))
    axis /= np.linalg.norm(axis, axis=1, keepdims=True)
    radius = rng.uniform(0.05, 1.0, n) * scale[:, 0]
    half = rng.uniform(0.05, 1.0, n) * scale[:, 0]
    a = c + rng.normal(size=(n, 3)) * scale
    d = rng.normal(size=(n, 3)) * scale
    k = n // 8
    d[:k] = axis[:k] * rng.uniform(-1, 1, (k, 1)) * scale[:k]
    d[:k] += 1e-7 * rng.normal(size=(k, 3)) * scale[:k]
    d[k : 2 * k] -= np.einsum("ij,ij->i", d[k : 2 * k], axis[k : 2 * k])[:, None] * axis[k : 2 * k]
    r = rng.uniform(0.02, 0.4, n) * scale[:, 0]
    return a, a + d, r, c, axis, radius, half


def _coal_cylinder(c, axis, radius, half):
    """coal's cylinder is centred on its frame, along z, of length ``lz``."""
    rot = Rotation.align_vectors([axis], [[0.0, 0.0, 1.0]])[0].as_matrix()
    return coal.Cylinder(radius, 2.0 * half), _pose(rot, c)


def _coal_tight(g1, t1, g2, t2) -> float:
    """coal's GJK/EPA on the exact shapes, converged to 1e-11 (its default stops at 1e-6;
    tighter than 1e-12 its GJK fails on a few pairs: -DBL_MAX or a wrong sign)."""
    request, result = coal.DistanceRequest(), coal.DistanceResult()
    request.gjk_tolerance = request.epa_tolerance = 1e-11
    request.gjk_max_iterations = request.epa_max_iterations = 10_000
    return coal.distance(g1, t1, g2, t2, request, result)


def _segment_cylinder_apart(a, b, c, axis, radius, half) -> float:
    """min over t of the point's signed distance along the segment: a convex function of t
    (dense samples, then Brent's bounded method around the best)."""
    minimize_scalar = pytest.importorskip("scipy.optimize").minimize_scalar

    def gap(t: float) -> float:
        return cylinder_reference.point(a + t * (b - a), c, axis, radius, half)

    ts = np.linspace(0.0, 1.0, 401)
    values = [gap(t) for t in ts]
    k = int(np.argmin(values))
    bounds = (ts[max(k - 1, 0)], ts[min(k + 1, len(ts) - 1)])
    best = minimize_scalar(gap, bounds=bounds, method="bounded", options={"xatol": 1e-14})
    return min(best.fun, min(values))


def _penetration_reference(a, b, c, axis, radius, half, directions) -> float:
    """The penetration depth as the smallest support value of ``cylinder - segment`` over
    unit directions: the best of dense directions, each of the twelve best polished by
    Nelder-Mead in spherical angles. Every value is an attained support value, so the result
    bounds the depth from above; the cylinder's support term is ``r |axis x n|`` (``r
    sqrt(1 - (axis . n)^2)`` loses half the digits near the caps' normals)."""
    minimize = pytest.importorskip("scipy.optimize").minimize

    def support(n):
        n = np.atleast_2d(n)
        cyl = n @ c + half * np.abs(n @ axis) + radius * np.linalg.norm(np.cross(n, axis), axis=-1)
        return cyl - np.minimum(n @ a, n @ b)

    values = support(directions)
    best = float(values.min())

    def angles(x):
        return support([np.cos(x[0]) * np.sin(x[1]), np.sin(x[0]) * np.sin(x[1]), np.cos(x[1])])[0]

    for k in np.argsort(values)[:12]:
        n = directions[k]
        x0 = np.array([np.arctan2(n[1], n[0]), np.arccos(np.clip(n[2], -1.0, 1.0))])
        simplex = np.array([x0, x0 + [0.02, 0.0], x0 + [0.0, 0.02]])
        options = {"xatol": 1e-13, "fatol": 1e-15, "maxiter": 4000, "initial_simplex": simplex}
        best = min(best, minimize(angles, x0, method="Nelder-Mead", options=options).fun)
    return best


def test_cylinder_distances_against_coal():
    """2000 sphere-cylinder and capsule-cylinder pairs: every sign as coal's; separated
    distances to 1e-9 (coal converged to 1e-11), and each separated capsule also against a
    1-D minimisation along it. Penetrating capsules against coal's EPA with its default
    request (tolerance 1e-6; its depths spread to 4e-6 about the exact ones here) to 1e-5:
    converged to 1e-11 its EPA fails on about a tenth of the deep pairs (depths too large by
    up to 1e-3, or -DBL_MAX), which tests/test_collision_cylinders.py's exact reference and
    ``test_segment_cylinder_regimes_against_the_sphere_of_directions`` cover. Spheres inside
    against the point's depth written here, and against coal where the side is nearer than a
    cap (coal's sphere-cylinder depth is the radial one, also where a cap is nearer)."""
    rng = np.random.default_rng(23)
    n = 2000
    a, b, r, c, axis, radius, half = _cylinder_pairs(rng, n)
    cylinders = [_coal_cylinder(c[i], axis[i], radius[i], half[i]) for i in range(n)]
    spheres = [(coal.Sphere(r[i]), _pose(None, a[i])) for i in range(n)]
    capsules = [_coal_capsule(a[i], b[i], r[i]) for i in range(n)]
    mine_s = np.asarray(jax.jit(sd.sphere_cylinder)(a, r, c, axis, radius, half))
    mine_c = np.asarray(jax.jit(sd.capsule_cylinder)(a, b, r, c, axis, radius, half))
    ref_s = np.array([_coal_tight(*spheres[i], *cylinders[i]) for i in range(n)])
    ref_c = np.array([_coal_tight(*capsules[i], *cylinders[i]) for i in range(n)])
    for name, mine, ref in (("sphere", mine_s, ref_s), ("capsule", mine_c, ref_c)):
        assert np.sum(ref < 0) >= n // 10 and np.sum(ref > 0) >= n // 10, f"{name}: regimes"
        np.testing.assert_array_equal(np.sign(mine), np.sign(ref), err_msg=name)
        apart = ref > 0
        err = np.abs(mine - ref)[apart]
        assert err.max() <= TOL, f"{name}: largest error {err.max():.2e}"
    deep = np.flatnonzero(ref_c < 0)
    epa = np.array([_coal_distance(*capsules[i], *cylinders[i]) for i in deep])
    np.testing.assert_allclose(mine_c[deep], epa, rtol=0, atol=1e-5)
    inside = ref_s < 0
    exact = [cylinder_reference.point(a[i], c[i], axis[i], radius[i], half[i]) - r[i]
             for i in np.flatnonzero(inside)]  # fmt: skip
    np.testing.assert_allclose(mine_s[inside], exact, atol=1e-12)
    u = a - c
    z = np.einsum("ij,ij->i", u, axis)
    side = radius - np.linalg.norm(u - z[:, None] * axis, axis=1) < half - np.abs(z)
    assert np.sum(inside & side) >= n // 20
    np.testing.assert_allclose(mine_s[inside & side], ref_s[inside & side], rtol=0, atol=TOL)
    apart = np.flatnonzero(ref_c > 0)[:400]
    along = [_segment_cylinder_apart(a[i], b[i], c[i], axis[i], radius[i], half[i]) - r[i]
             for i in apart]  # fmt: skip
    np.testing.assert_allclose(mine_c[apart], along, atol=TOL)


def test_segment_cylinder_regimes_against_the_sphere_of_directions():
    """560 pairs, 40 in each of tests/references/cylinders.py's regimes: overlapping, equal to
    the support function's minimum over the whole sphere of directions (dense directions
    polished by grid search: no assumption on where it lies) to 1e-12 of the pair's size;
    as capsules of radius 0.05 of the size, signs as coal's (converged to 1e-11), separated
    distances to 1e-9, and penetration depths to 1e-6 of the size with coal's EPA under its
    default request or converged to 1e-11: each alone misses on some pairs (the default one
    by up to 0.5 % of the depth along the axis, the converged one by a NaN, -DBL_MAX or 1e-3
    too deep), the two together on none."""
    rng = np.random.default_rng(25)
    parts = [cylinder_reference.pairs(rng, 40, regime) for regime in cylinder_reference.REGIMES]
    a, b, c, axis, radius, half = (np.concatenate(x) for x in zip(*parts, strict=True))
    size = np.maximum.reduce([radius, half, np.linalg.norm(b - a, axis=1)])
    mine = np.asarray(jax.jit(sd.segment_cylinder)(a, b, c, axis, radius, half))
    deep = np.flatnonzero(mine < 0)
    assert len(deep) >= 150
    directions = cylinder_reference.fibonacci_sphere(20_000)
    full = cylinder_reference.support(*(x[deep] for x in (a, b, c, axis, radius, half)), directions)
    np.testing.assert_array_less(np.abs(mine[deep] - full), 1e-12 * size[deep])

    r = 0.05 * size
    capsule = mine - r
    cylinders = [_coal_cylinder(c[i], axis[i], radius[i], half[i]) for i in range(len(a))]
    capsules = [_coal_capsule(a[i], b[i], r[i]) if np.any(a[i] != b[i])
                else (coal.Sphere(r[i]), _pose(None, a[i])) for i in range(len(a))]  # fmt: skip
    tight = np.array([_coal_tight(*capsules[i], *cylinders[i]) for i in range(len(a))])
    np.testing.assert_array_equal(np.sign(capsule), np.sign(tight))
    apart = tight > 0
    np.testing.assert_allclose(capsule[apart], tight[apart], rtol=0, atol=TOL)
    epa = np.array([_coal_distance(*capsules[i], *cylinders[i]) for i in np.flatnonzero(~apart)])
    # each of coal's two EPA results alone misses on some pairs (see the docstring)
    err = np.fmin(np.abs(capsule[~apart] - epa), np.abs(capsule[~apart] - tight[~apart]))
    np.testing.assert_array_less(err, 1e-6 * size[~apart])


def test_segment_cylinder_depth_against_support_minimisation():
    """Overlapping segments and cylinders (random, along and across the axis, through a cap,
    radius or half-length 0): minus the smallest support value of ``cylinder - segment``
    found by dense directions and Nelder-Mead (an upper bound of the depth it finds to about
    1e-14): jaxkin's depth is never larger and at most 1e-12 smaller."""
    rng = np.random.default_rng(24)
    directions = cylinder_reference.fibonacci_sphere(60_000)
    a, b, _, c, axis, radius, half = _cylinder_pairs(rng, 400)
    scale = np.maximum(radius, half)
    # unit scale, closer: most overlap
    a, b = (
        c + 0.6 * (a - c) / scale[:, None],
        c + 0.6 * (a - c) / scale[:, None] + (b - a) / scale[:, None],
    )
    radius, half = radius / scale, half / scale
    radius[:8], half[8:16] = 0.0, 0.0
    mine = np.asarray(jax.jit(sd.segment_cylinder)(a, b, c, axis, radius, half))
    overlapping = np.flatnonzero(mine < -1e-3)[:80]
    assert len(overlapping) >= 60
    ref = np.array([-_penetration_reference(a[i], b[i], c[i], axis[i], radius[i], half[i],
                                            directions) for i in overlapping])  # fmt: skip
    diff = mine[overlapping] - ref
    assert diff.max() <= 1e-12 and diff.min() >= -1e-12, (diff.min(), diff.max())


@pytest.fixture(scope="module")
def robots():
    return _robots()


def _mesh_links(robots: Path, path: Path):
    """Per collision mesh of a URDF: its link and its vertices and faces in the link's frame
    (trimesh; yourdfpy reads the elements)."""
    trimesh = pytest.importorskip("trimesh")
    yourdfpy = pytest.importorskip("yourdfpy")
    model = yourdfpy.URDF.load(str(path), build_scene_graph=False, load_meshes=False).robot
    for link in model.links:
        for element in link.collisions:
            if element.geometry.mesh is None:
                continue
            name = element.geometry.mesh.filename.split("://", 1)[-1]
            mesh = trimesh.load(str(robots.parent.parent / name), force="mesh")
            pose = np.eye(4) if element.origin is None else element.origin
            mesh.apply_transform(pose)
            yield link.name, mesh


@pytest.mark.parametrize(
    "urdf",
    ["panda_description/urdf/panda.urdf", "ur_description/urdf/ur5_robot.urdf"],
    ids=["panda", "ur5"],
)
def test_mesh_covers_hold_the_meshes_within_their_bounds(robots, urdf):
    """The default covers (spheres, bound 1 cm, at most 256 per mesh) and covers of at most 16
    spheres per mesh: every vertex and 3000 random surface points of every collision mesh
    inside its link's spheres; the default's bound at most 1 cm on every link, and points
    sampled in the spheres within each link's bound of the mesh's solid (trimesh's signed
    distances, each closed part of the mesh a solid). Prints the counts per link
    (docs/collision.md lists them) and the largest overshoot measured."""
    trimesh = pytest.importorskip("trimesh")
    path = robots / urdf
    default = col.body_from_urdf(path)
    few = col.body_from_urdf(path, max_spheres_per_mesh=16)
    assert default.body.num_capsules == 0 and few.body.num_capsules == 0
    rng = np.random.default_rng(30)
    counts, measured = {}, {}
    for link, mesh in _mesh_links(robots, path):
        # trimesh's surface samples, its random generator's key (31) given by position
        samples = trimesh.sample.sample_surface(mesh, 3000, None, False, False, 31)[0]
        surface = np.concatenate([mesh.vertices, samples])
        for read, budget in ((default, 256), (few, 16)):
            centers, radii = read.body.per_link()[0][link]
            assert len(radii) <= budget
            gap = np.linalg.norm(surface[:, None] - centers[None], axis=-1) - radii[None]
            assert np.all(gap.min(axis=1) <= 0.0), link
        centers, radii = default.body.per_link()[0][link]
        counts[link] = len(radii)
        assert default.overshoot[link] <= 0.01
        dirs = rng.normal(size=(len(radii), 8, 3))
        dirs /= np.linalg.norm(dirs, axis=-1, keepdims=True)
        shell = (centers[:, None] + radii[:, None, None] * dirs).reshape(-1, 3)
        parts = mesh.split(only_watertight=True)
        depth = np.max([trimesh.proximity.signed_distance(p, shell) for p in parts], axis=0)
        measured[link] = float(np.max(-depth))
        assert measured[link] <= default.overshoot[link] + 1e-9, link
    print(
        f"{urdf}: {sum(counts.values())} spheres, {counts}; overshoot measured on the shells "
        f"at most {max(measured.values()):.4f} (bounds {max(default.overshoot.values()):.4f})"
    )


def test_panda_collision_primitives(robots):
    """The primitives URDF: every sphere as given, every cylinder as a capsule through its
    axis."""
    read = col.body_from_urdf(robots / "panda_description/urdf/panda_collision.urdf")
    body = read.body
    text = (robots / "panda_description/urdf/panda_collision.urdf").read_text()
    assert body.num_spheres == text.count("<sphere") and body.num_capsules == text.count(
        "<cylinder"
    )
    link1 = body.links.index("panda_link1")
    k = body.capsule_link.index(link1)
    # <cylinder length="0.283" radius="0.09"/> at z = -0.1915 in panda_link1
    np.testing.assert_allclose(np.asarray(body.capsule_a[k]), [0, 0, -0.1915 - 0.1415], atol=1e-12)
    np.testing.assert_allclose(np.asarray(body.capsule_b[k]), [0, 0, -0.1915 + 0.1415], atol=1e-12)
    assert float(body.capsule_radius[k]) == 0.09


def test_panda_self_distances_bound_coal_with_meshes(robots):
    """Random Panda configurations (Pinocchio's FK), the SRDF's remaining link pairs: the
    sphere covers' distance never exceeds coal's distance between the original meshes (the
    covers contain them), so no collision coal finds is missed."""
    pin = pytest.importorskip("pinocchio")
    path = robots / "panda_description/urdf/panda.urdf"
    read = col.body_from_urdf(path)
    body = read.body
    disabled = col.read_srdf_disabled(robots / "panda_description/srdf/panda.srdf")
    link_pairs = col.self_collision_link_pairs(body, read.joints, disabled)
    pairs = col.SelfPairs.create(body, link_pairs)
    model, cmodel, _ = pin.buildModelsFromUrdf(str(path), str(robots.parent.parent))
    data, cdata = model.createData(), pin.GeometryData(cmodel)
    frames = [model.getFrameId(name) for name in body.links]
    geoms: dict[str, list[int]] = {}
    for g, obj in enumerate(cmodel.geometryObjects):
        geoms.setdefault(model.frames[obj.parentFrame].name, []).append(g)
    rng = np.random.default_rng(22)
    n = 300
    qs = rng.uniform(model.lowerPositionLimit, model.upperPositionLimit, (n, model.nq))
    poses = np.zeros((n, len(frames), 4, 4))
    reference = np.zeros((n, len(link_pairs)))
    request, result = coal.DistanceRequest(), coal.DistanceResult()
    for k, q in enumerate(qs):
        pin.framesForwardKinematics(model, data, q)
        pin.updateGeometryPlacements(model, data, cmodel, cdata, q)
        poses[k] = [data.oMf[f].homogeneous for f in frames]
        placed = [coal.Transform3s(m.rotation, m.translation) for m in cdata.oMg]
        for p, (i, j) in enumerate(link_pairs):
            best = np.inf
            for gi in geoms[body.links[i]]:
                for gj in geoms[body.links[j]]:
                    result.clear()
                    d = coal.distance(
                        cmodel.geometryObjects[gi].geometry,
                        placed[gi],
                        cmodel.geometryObjects[gj].geometry,
                        placed[gj],
                        request,
                        result,
                    )
                    best = min(best, d)
            reference[k, p] = best
    mine = np.asarray(jax.jit(lambda x: col.self_distances(*body.place(x), pairs))(poses))
    colliding = reference <= 0.0
    assert colliding.sum() >= 5  # the samples do reach self-collisions
    assert np.all(mine[colliding] <= 0.0)  # no missed collision
    assert np.all(mine <= np.maximum(reference, 0.0) + 1e-9)  # the covers' distance is a bound


@pytest.mark.parametrize(
    "urdf, srdf",
    [
        ("panda_description/urdf/panda.urdf", "panda_description/srdf/panda.srdf"),
        ("ur_description/urdf/ur5_robot.urdf", "ur_description/srdf/ur5.srdf"),
    ],
    ids=["panda", "ur5"],
)
def test_no_missed_collision_among_obstacles(robots, urdf, srdf):
    """Random configurations among random spheres and boxes: Pinocchio places the original
    meshes and coal decides every robot-obstacle pair and the SRDF's self pairs
    (``computeCollisions``); jaxkin's default covers, placed with Pinocchio's link poses,
    checked by the per-primitive queries (``nearest_obstacles``, ``self_distances``): every
    configuration coal finds in collision is in collision for jaxkin (no false negative). The
    false-positive rates (the covers' overshoot), overall, robot-world and self, are printed
    (docs/performance.md lists them, and ``benchmarks/cover_quality.py`` measures more)."""
    pin = pytest.importorskip("pinocchio")

    path, package = robots / urdf, str(robots.parent.parent)
    read = col.body_from_urdf(path)
    body = read.body
    disabled = col.read_srdf_disabled(robots / srdf) if (robots / srdf).is_file() else ()
    pairs = col.SelfPairs.create(body, col.self_collision_link_pairs(body, read.joints, disabled))
    model, cmodel, _ = pin.buildModelsFromUrdf(str(path), package)
    rng = np.random.default_rng(28)
    n, n_spheres, n_boxes = 400, 6, 4
    reach = 0.9
    s_center = rng.uniform([-reach, -reach, -0.2], [reach, reach, reach], (n_spheres, 3))
    s_radius = rng.uniform(0.03, 0.12, n_spheres)
    b_center = rng.uniform([-reach, -reach, -0.2], [reach, reach, reach], (n_boxes, 3))
    b_half = rng.uniform(0.02, 0.1, (n_boxes, 3))
    b_rot = _random_rotations(rng, n_boxes)
    world = col.World.create(
        spheres=col.Spheres.create(s_center, s_radius),
        boxes=col.Boxes.create(b_center, b_half, b_rot),
    )
    robot_geoms = list(range(len(cmodel.geometryObjects)))
    obstacle_ids = []
    for k in range(n_spheres):
        place = pin.SE3(np.eye(3), s_center[k])
        obj = pin.GeometryObject(f"s{k}", 0, 0, place, coal.Sphere(s_radius[k]))
        obstacle_ids.append(cmodel.addGeometryObject(obj))
    for k in range(n_boxes):
        place = pin.SE3(b_rot[k], b_center[k])
        obj = pin.GeometryObject(f"b{k}", 0, 0, place, coal.Box(*(2.0 * b_half[k])))
        obstacle_ids.append(cmodel.addGeometryObject(obj))
    for g in robot_geoms:
        for o in obstacle_ids:
            cmodel.addCollisionPair(pin.CollisionPair(g, o))
    link_of = {g: model.frames[cmodel.geometryObjects[g].parentFrame].name for g in robot_geoms}
    checked = {frozenset((body.links[i], body.links[j])) for i, j in pairs.link_pairs}
    for a in robot_geoms:
        for b in robot_geoms[a + 1 :]:
            if frozenset((link_of[a], link_of[b])) in checked:
                cmodel.addCollisionPair(pin.CollisionPair(a, b))
    data, cdata = model.createData(), pin.GeometryData(cmodel)
    frames = [model.getFrameId(name) for name in body.links]
    qs = rng.uniform(model.lowerPositionLimit, model.upperPositionLimit, (n, model.nq))
    reference = np.zeros(n, bool)
    self_hit = np.zeros(n, bool)
    n_world_pairs = len(robot_geoms) * len(obstacle_ids)
    poses = np.zeros((n, len(frames), 4, 4))
    for k, q in enumerate(qs):
        reference[k] = pin.computeCollisions(model, data, cmodel, cdata, q, False)
        self_hit[k] = any(r.isCollision() for r in cdata.collisionResults[n_world_pairs:])
        pin.framesForwardKinematics(model, data, q)
        poses[k] = [data.oMf[f].homogeneous for f in frames]

    def verdicts(x, body, world):
        spheres, capsules = body.place(x)
        d_world = jnp.concatenate(
            [n.distance for n in col.nearest_obstacles(spheres, capsules, world)], axis=-1
        )
        return d_world.min(axis=-1) <= 0.0, col.self_distances(spheres, capsules, pairs).min(
            -1
        ) <= 0

    mine_world, mine_self = map(np.asarray, jax.jit(verdicts)(poses, body, world))
    hit = mine_world | mine_self
    assert reference.sum() >= 20 and (~reference).sum() >= 20  # both verdicts occur
    assert self_hit.sum() >= 1 or "ur5" in urdf  # the Panda reaches self-collisions
    missed = np.flatnonzero(reference & ~hit)
    assert missed.size == 0, f"collisions coal finds and jaxkin misses: {missed}"
    assert np.all(mine_self[self_hit])  # every self-collision coal finds, on the SRDF pairs
    world_hit = reference & ~self_hit
    # the 1 cm covers: the old covers (bound 3.7 and 4.7 cm) flagged 18 % and 16 %
    assert np.mean(hit[~reference]) < 0.08
    print(
        f"{urdf}: {reference.mean():.2f} colliding; false-positive rate "
        f"{np.mean(hit[~reference]):.3f} overall, {np.mean(mine_world[~reference]):.3f} "
        f"robot-world, {np.mean(mine_self[~self_hit]):.3f} self ({world_hit.sum()} world hits)"
    )


def test_panda_propose_disabled_against_the_srdf(robots):
    """``propose_disabled`` on 2000 uniform Panda configurations (the chain's link poses, the
    fingers closed), every pair of links with geometry, against coal on the original meshes
    at the same configurations (Pinocchio's placements) and the SRDF. The covers contain the
    meshes, so every pair proposed "never" is free on the meshes in every sample, and every
    pair coal finds in collision in every sample is proposed "always". Of the SRDF's "Never"
    pairs that the meshes keep free by more than the two covers' overshoot bounds in every
    sample, every one is proposed "never" (the bound makes the covers free there too); the
    "never" pairs proposed hold most of the SRDF's free "Never" pairs."""
    pin = pytest.importorskip("pinocchio")
    path = robots / "panda_description/urdf/panda.urdf"
    chain = serial_from_urdf(path, "panda_hand")
    read = col.body_from_urdf(path)
    body = chain.collision_body()
    srdf = col.read_srdf_disabled(robots / "panda_description/srdf/panda.srdf")
    model, cmodel, _ = pin.buildModelsFromUrdf(str(path), str(robots.parent.parent))
    cmodel.addAllCollisionPairs()
    data, cdata = model.createData(), pin.GeometryData(cmodel)
    link_of = [model.frames[g.parentFrame].name for g in cmodel.geometryObjects]
    rng = np.random.default_rng(23)
    n = 2000
    lo, hi = model.lowerPositionLimit[:7], model.upperPositionLimit[:7]
    qs = rng.uniform(lo, hi, (n, 7))
    proposed = col.propose_disabled(body, chain.link_poses, qs, chunk=25)
    hits: dict[frozenset, int] = {}
    nearest: dict[frozenset, float] = {}
    for q in qs:
        q_pin = np.zeros(model.nq)
        q_pin[:7] = q
        pin.computeCollisions(model, data, cmodel, cdata, q_pin, False)
        pin.computeDistances(model, data, cmodel, cdata, q_pin)
        for k, pair in enumerate(cmodel.collisionPairs):
            key = frozenset((link_of[pair.first], link_of[pair.second]))
            hits[key] = hits.get(key, 0) + int(cdata.collisionResults[k].isCollision())
            d = cdata.distanceResults[k].min_distance
            nearest[key] = min(nearest.get(key, np.inf), d)
    never = {frozenset(p) for p in proposed["never"]}
    always = {frozenset(p) for p in proposed["always"]}
    assert all(hits[p] == 0 for p in never)  # conservative: never a pair that collides
    assert {p for p, h in hits.items() if h == n} <= always
    srdf_never = {frozenset((a, b)) for a, b, why in srdf if why == "Never"}
    free = {p for p in srdf_never if p in hits and hits[p] == 0}
    clear = {p for p in free if nearest[p] > sum(read.overshoot[x] for x in p)}
    assert clear <= never
    assert len(free & never) >= 0.7 * len(free)
    print(
        f"propose_disabled: {len(never)} never, {len(always)} always; SRDF Never pairs "
        f"free on the meshes: {len(free)}, proposed: {len(free & never)}"
    )
