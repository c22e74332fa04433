"""Covers of link geometry: containment of the surface and the overshoot bound, against trimesh.

The references are trimesh's (a library nobody here wrote): surface samples
(``trimesh.sample.sample_surface``) and signed distances (``trimesh.proximity``, positive
inside a closed mesh) of points sampled in the spheres.
"""

from __future__ import annotations

import numpy as np
import pytest

from jaxkin import collision as col
from jaxkin.collision import cover, triangles

trimesh = pytest.importorskip("trimesh")


def _surface_gaps(c: col.MeshCover, points: np.ndarray) -> np.ndarray:
    """For each point, the smallest signed distance to the cover's primitives (<= 0 inside)."""
    gaps = [np.linalg.norm(points[:, None] - c.centers[None], axis=-1) - c.radii[None]]
    if len(c.capsule_radii):
        d = c.b - c.a
        t = np.clip(
            np.einsum("pkc,kc->pk", points[:, None] - c.a[None], d)
            / np.maximum((d**2).sum(-1), 1e-300),
            0.0,
            1.0,
        )
        foot = c.a[None] + t[..., None] * d[None]
        gaps.append(np.linalg.norm(points[:, None] - foot, axis=-1) - c.capsule_radii[None])
    return np.concatenate(gaps, axis=1).min(axis=1)


def _sphere_gaps(centers: np.ndarray, radii: np.ndarray, points: np.ndarray) -> np.ndarray:
    return (np.linalg.norm(points[:, None] - centers[None], axis=-1) - radii[None]).min(axis=1)


def _surface(mesh, count: int, key: int) -> np.ndarray:
    """``count`` random points of the mesh's surface (trimesh's ``sample_surface``, its random
    generator's key given by position after ``face_weight``, ``sample_color`` and
    ``return_barycentric``)."""
    return trimesh.sample.sample_surface(mesh, count, None, False, False, key)[0]


def _in_spheres(centers: np.ndarray, radii: np.ndarray, per: int, key: int) -> np.ndarray:
    """Points of every sphere: ``per`` on its boundary and ``per`` inside (uniform)."""
    rng = np.random.default_rng(key)
    dirs = rng.normal(size=(len(radii), 2 * per, 3))
    dirs /= np.linalg.norm(dirs, axis=-1, keepdims=True)
    scale = np.concatenate([np.ones(per), rng.uniform(0.0, 1.0, per) ** (1 / 3)])
    return (centers[:, None] + radii[:, None, None] * scale[None, :, None] * dirs).reshape(-1, 3)


def _distance_to_solid(parts: list, points: np.ndarray) -> np.ndarray:
    """trimesh's distance from points to the union of closed ``parts`` (0 inside one)."""
    inside = np.max([trimesh.proximity.signed_distance(p, points) for p in parts], axis=0)
    return np.maximum(-inside, 0.0)


def _check_sphere_cover(found: col.SphereCover, parts: list, surface: np.ndarray, key: int):
    """Every surface point inside; sampled points of the spheres within ``overshoot``."""
    assert np.all(_sphere_gaps(found.centers, found.radii, surface) <= 0.0)
    points = _in_spheres(found.centers, found.radii, 40, key)
    assert _distance_to_solid(parts, points).max() <= found.overshoot + 1e-9


def _two_boxes():
    a = trimesh.creation.box([0.12, 0.08, 0.05])
    b = trimesh.creation.box([0.05, 0.05, 0.2])
    b.apply_translation([0.05, 0.0, 0.06])
    return [a, b]


SHAPES = {
    "box": lambda: [trimesh.creation.box([0.2, 0.1, 0.05])],
    "cylinder": lambda: [trimesh.creation.cylinder(0.05, 0.2, sections=24)],
    "capsule": lambda: [trimesh.creation.capsule(0.15, 0.04, count=[12, 12])],
    "torus": lambda: [trimesh.creation.torus(0.08, 0.025, major_sections=24, minor_sections=12)],
    "two overlapping boxes": _two_boxes,
}


@pytest.mark.parametrize("shape", list(SHAPES))
def test_sphere_cover_holds_the_surface_and_meets_its_bound(shape):
    """trimesh primitives (closed, one or two overlapping parts), bound 2 cm: every vertex and
    4000 random surface points inside the spheres, the bound met, and points sampled in every
    sphere within the reported overshoot of the solid (trimesh's signed distance)."""
    parts = SHAPES[shape]()
    mesh = trimesh.util.concatenate(parts)
    found = col.mesh_sphere_cover(mesh.vertices, mesh.faces, max_overshoot=0.02)
    assert 1 <= len(found.radii) <= 200
    assert found.overshoot <= 0.02
    samples = _surface(mesh, 4000, 1)
    _check_sphere_cover(found, parts, np.concatenate([mesh.vertices, samples]), key=2)
    again = col.mesh_sphere_cover(mesh.vertices, mesh.faces, max_overshoot=0.02)
    np.testing.assert_array_equal(again.centers, found.centers)  # deterministic
    np.testing.assert_array_equal(again.radii, found.radii)


def test_an_open_mesh_is_covered_within_the_bound_of_its_surface():
    """A box without its top: no inside, so every point of the spheres lies within the bound of
    the triangles themselves (trimesh's closest points)."""
    box = trimesh.creation.box([0.1, 0.1, 0.1])
    faces = box.faces[box.face_normals[:, 2] < 0.5]
    found = col.mesh_sphere_cover(box.vertices, faces, max_overshoot=0.02)
    opened = trimesh.Trimesh(box.vertices, faces, process=False)
    samples = _surface(opened, 3000, 3)
    assert np.all(_sphere_gaps(found.centers, found.radii, samples) <= 0.0)
    points = _in_spheres(found.centers, found.radii, 30, key=4)
    distance = trimesh.proximity.closest_point(opened, points)[1]
    assert distance.max() <= found.overshoot + 1e-9 and found.overshoot <= 0.02


def test_a_budget_relaxes_the_bound_and_none_finds_the_smallest():
    """At most the budget of spheres; the bound grows to what that many allow, and with
    ``max_overshoot=None`` the smallest bound the budget allows is found (a sixth of the
    spheres of the 1 cm cover needs a looser bound)."""
    mesh = trimesh.creation.box([0.2, 0.1, 0.05])
    parts = [mesh]
    surface = np.concatenate([mesh.vertices, _surface(mesh, 3000, 5)])
    fine = col.mesh_sphere_cover(mesh.vertices, mesh.faces, max_overshoot=0.01)
    few = col.mesh_sphere_cover(mesh.vertices, mesh.faces, max_spheres=6, max_overshoot=0.01)
    best = col.mesh_sphere_cover(mesh.vertices, mesh.faces, max_spheres=6, max_overshoot=None)
    assert len(fine.radii) > 6 and fine.overshoot <= 0.01
    for found in (few, best):
        assert len(found.radii) <= 6 and found.overshoot > 0.01
        _check_sphere_cover(found, parts, surface, key=6)
    assert best.overshoot <= few.overshoot * 1.1
    with pytest.raises(ValueError, match="max_spheres"):
        col.mesh_sphere_cover(mesh.vertices, mesh.faces, max_spheres=0)
    with pytest.raises(ValueError, match="max_overshoot"):
        col.mesh_sphere_cover(mesh.vertices, mesh.faces, max_overshoot=-0.01)
    with pytest.raises(ValueError, match="give max_overshoot, max_spheres"):
        col.mesh_sphere_cover(mesh.vertices, mesh.faces, max_overshoot=None)


@pytest.mark.parametrize("half", [[0.25, 0.25, 0.0005], [0.3, 0.002, 0.002], [0.2, 0.1, 0.0]])
def test_thin_and_flat_boxes_stay_within_the_budget(half):
    """A plate, a wire and a flat box (zero thickness) of tens of centimetres: at most 32
    spheres (the default budget of a box), holding the box's corners and surface."""
    found = col.box_sphere_cover(np.array(half))
    assert len(found.radii) <= 32
    box = trimesh.creation.box(2 * np.maximum(half, 1e-9))
    corners = np.array(np.meshgrid(*[[-h, h] for h in half])).reshape(3, -1).T
    surface = np.concatenate([corners, _surface(box, 3000, 7)])
    surface = np.clip(surface, -np.array(half), np.array(half))
    assert np.all(_sphere_gaps(found.centers, found.radii, surface) <= 0.0)


def test_subdivided_pieces_tile_the_triangles():
    """Every piece's edges at most the length asked; the pieces' areas and oriented normals
    sum to the triangles' (the pieces tile them, orientation kept)."""
    rng = np.random.default_rng(8)
    tri = rng.normal(size=(50, 3, 3)) * np.array([0.3, 0.01, 0.05])
    pieces = triangles.subdivide(tri, 0.004)
    edges = np.linalg.norm(pieces - np.roll(pieces, 1, axis=1), axis=-1)
    assert edges.max() <= 0.004

    def normals(t):
        return np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0])

    np.testing.assert_allclose(normals(pieces).sum(0), normals(tri).sum(0), atol=1e-15)
    area = np.linalg.norm(normals(pieces), axis=1).sum()
    np.testing.assert_allclose(area, np.linalg.norm(normals(tri), axis=1).sum(), rtol=1e-12)


def test_point_triangle_distance_against_trimesh():
    mesh = trimesh.creation.icosphere(1, 0.1)
    mesh.vertices += np.random.default_rng(9).normal(size=mesh.vertices.shape) * 0.01
    points = np.random.default_rng(10).normal(size=(500, 3)) * 0.12
    mine = triangles.point_triangle_distance(points[:, None], mesh.triangles[None]).min(axis=1)
    np.testing.assert_allclose(mine, trimesh.proximity.closest_point(mesh, points)[1], atol=1e-12)


@pytest.mark.slow  # about 4 s of CPU (trimesh's signed distances)
def test_mesh_cover_of_a_tube_uses_capsules_and_bounds_its_overshoot():
    """An annulus (a tube, 30 cm long, radii 3 and 6 cm) and a box glued to it (two closed
    parts): every vertex and sampled surface point inside the cover, every sampled point of
    the cover within ``overshoot`` of the solid (trimesh's signed distance of each part), and
    the mixed cover at least as tight as the former spheres-only top-down cover."""
    tube = trimesh.creation.annulus(r_min=0.03, r_max=0.06, height=0.3)
    lug = trimesh.creation.box([0.05, 0.05, 0.05])
    lug.apply_translation([0.08, 0.0, 0.1])
    mesh = trimesh.util.concatenate([tube, lug])
    c = col.mesh_cover(mesh.vertices, mesh.faces, max_primitives=8)
    assert c.num_primitives <= 8 and len(c.capsule_radii) >= 1
    surface = np.concatenate([mesh.vertices, _surface(mesh, 4000, 0)])
    assert np.all(_surface_gaps(c, surface) <= 0.0)
    rng = np.random.default_rng(1)
    dirs = rng.normal(size=(200, 3))
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    shell = [c.centers[:, None] + c.radii[:, None, None] * dirs[None]]
    s = rng.uniform(0.0, 1.0, (200, 1))
    shell.append(
        c.a[:, None] + s[None] * (c.b - c.a)[:, None] + c.capsule_radii[:, None, None] * dirs[None]
    )
    shell = np.concatenate([x.reshape(-1, 3) for x in shell])
    assert np.max(_distance_to_solid([tube, lug], shell)) <= c.overshoot + 1e-9
    spheres = col.mesh_cover(mesh.vertices, mesh.faces, max_primitives=8, capsules=False)
    assert c.overshoot <= spheres.overshoot


def test_mesh_cover_rejects_a_bad_budget():
    mesh = trimesh.creation.box([0.1, 0.1, 0.1])
    with pytest.raises(ValueError, match="max_primitives"):
        col.mesh_cover(mesh.vertices, mesh.faces, max_primitives=0)


def test_signed_distance_bound_of_overlapping_parts():
    """Two overlapping unit cubes: a point inside both is at least as deep as its larger depth
    in one cube (0.45 here, where the nearest triangle, an inner face, is 0.05 away; the
    union's true depth is 0.5); outside, the distance to the nearer cube."""
    a = trimesh.creation.box([1.0, 1.0, 1.0])
    b = trimesh.creation.box([1.0, 1.0, 1.0])
    b.apply_translation([0.5, 0.0, 0.0])
    both = trimesh.util.concatenate([a, b])
    parts = cover._closed_bodies(np.asarray(both.vertices), np.asarray(both.faces))
    assert parts is not None and len(parts) == 2
    p = np.array([[0.05, 0.0, 0.0], [0.0, 0.0, 0.9], [1.5, 0.0, 0.0]])
    sd = cover._signed_distance(np.concatenate(parts), parts, p)
    np.testing.assert_allclose(sd, [-0.45, 0.4, 0.5], atol=1e-12)


def test_parts_are_found_closed_and_turned_outward():
    """Two separate boxes, one with inward faces (flipped): two closed parts, both turned
    outward (positive enclosed volume); a box without one face is not closed."""
    a = trimesh.creation.box([0.1, 0.1, 0.1])
    b = trimesh.creation.box([0.1, 0.1, 0.1])
    b.apply_translation([1.0, 0.0, 0.0])
    vertices = np.concatenate([a.vertices, b.vertices])
    faces = np.concatenate([a.faces, b.faces[:, ::-1] + len(a.vertices)])
    found = triangles.parts(vertices, faces)
    assert [p.closed for p in found] == [True, True]
    for part in found:
        t = part.triangles
        volume = np.einsum("ij,ij->i", t[:, 0], np.cross(t[:, 1], t[:, 2])).sum() / 6
        assert volume == pytest.approx(1e-3, rel=1e-9)
    assert [p.closed for p in triangles.parts(a.vertices, a.faces[1:])] == [False]


def _robot_mesh(relative: str):
    """A collision mesh of example-robot-data, read by trimesh (not by jaxkin's STL reader)."""
    for base in map(__import__("pathlib").Path, __import__("sys").path):
        root = base / "cmeel.prefix" / "share" / "example-robot-data" / "robots"
        if (root / relative).is_file():
            return trimesh.load(str(root / relative), force="mesh", process=False)
    pytest.skip("example-robot-data's meshes not found")


def _barycentric_samples(vertices: np.ndarray, faces: np.ndarray, n: int, key: int):
    """``n`` points uniform on the surface (triangles by area, then uniform barycentric
    coordinates), with NumPy alone, and the midpoints of every edge."""
    rng = np.random.default_rng(key)
    tri = vertices[faces]
    area = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    pick = rng.choice(len(tri), n, p=area / area.sum())
    u, v = rng.uniform(size=(2, n))
    flip = u + v > 1.0
    u[flip], v[flip] = 1.0 - u[flip], 1.0 - v[flip]
    t = tri[pick]
    points = t[:, 0] + u[:, None] * (t[:, 1] - t[:, 0]) + v[:, None] * (t[:, 2] - t[:, 0])
    middles = 0.5 * (tri + np.roll(tri, 1, axis=1)).reshape(-1, 3)
    return np.concatenate([points, middles])


@pytest.mark.parametrize(
    "mesh",
    [
        "panda_description/meshes/collision/link4.stl",
        "ur_description/meshes/ur5/collision/forearm.stl",
    ],
    ids=["panda link4", "ur5 forearm"],
)
def test_default_cover_of_a_robot_mesh_holds_sampled_surface_points(mesh):
    """The default cover (bound 1 cm) of a real collision mesh: every vertex, every edge's
    midpoint and 20,000 surface points drawn by barycentric sampling (NumPy) lie inside some
    sphere; the overshoot measured on the spheres' shells (32 directions each, trimesh's signed
    distance to the mesh's closed parts) is within the reported bound, itself <= 1 cm."""
    loaded = _robot_mesh(mesh)
    vertices, faces = np.asarray(loaded.vertices, float), np.asarray(loaded.faces)
    found = col.mesh_sphere_cover(vertices, faces)
    assert 0 < found.overshoot <= 0.01
    points = np.concatenate([vertices, _barycentric_samples(vertices, faces, 20_000, key=40)])
    gaps = _sphere_gaps(found.centers, found.radii, points)
    assert gaps.max() <= 0.0, gaps.max()
    k = np.arange(32) + 0.5  # Fibonacci directions on the unit sphere
    z, phi = 1.0 - 2.0 * k / 32, np.pi * (1.0 + 5**0.5) * k
    dirs = np.stack([np.sqrt(1 - z**2) * np.cos(phi), np.sqrt(1 - z**2) * np.sin(phi), z], 1)
    shell = (found.centers[:, None] + found.radii[:, None, None] * dirs).reshape(-1, 3)
    parts = trimesh.Trimesh(vertices, faces).split(only_watertight=True)  # vertices merged
    assert parts, "the mesh has a closed part"
    measured = _distance_to_solid(parts, shell).max()
    assert measured <= found.overshoot + 1e-9
    assert measured >= 0.5 * found.overshoot  # the bound is near what the spheres reach
    print(
        f"{mesh}: {len(found.radii)} spheres, bound {found.overshoot:.4f}, measured {measured:.4f}"
    )
