"""Triangle meshes of the collision primitives (collision.surfaces): every vertex on the
exact surface (the signed distance of collision.distance is 0 there), faces outward (the
mesh's signed volume is positive and below the solid's, by the chord error)."""

import numpy as np
import pytest

from jaxkin import collision
from jaxkin.collision import distance, surfaces


def volume(surface):
    v = surface.vertices[surface.faces]
    return np.einsum("ij,ij->i", v[:, 0], np.cross(v[:, 1], v[:, 2])).sum() / 6.0


def rotation(seed):
    q, r = np.linalg.qr(np.random.default_rng(seed).normal(size=(3, 3)))
    q = q * np.sign(np.diag(r))
    return q * np.linalg.det(q)


@pytest.mark.parametrize("segments", [8, 16, 32])
def test_meshes_lie_on_their_primitives_and_face_outward(segments):
    centre, rot = np.array([0.3, -0.2, 0.5]), rotation(0)
    a, b, r = np.array([0.1, 0.2, 0.3]), np.array([0.4, -0.1, 0.8]), 0.15
    cases = [
        (surfaces.sphere(centre, r, segments), 4 / 3 * np.pi * r**3, None),
        (
            surfaces.capsule(a, b, r, segments),
            np.pi * r**2 * np.linalg.norm(b - a) + 4 / 3 * np.pi * r**3,
            None,
        ),
        (
            surfaces.cylinder(centre, rot[:, 2], r, 0.4, segments),
            np.pi * r**2 * 0.8,
            None,
        ),
        (surfaces.box(centre, rot, [0.1, 0.2, 0.3]), 8 * 0.1 * 0.2 * 0.3, 1e-12),
    ]
    for surface, exact, rtol in cases:
        got = volume(surface)
        assert 0 < got <= exact * (1 + 1e-12)
        chord = 1 - np.cos(np.pi / segments)  # the chord error, relative to r
        assert got >= exact * (1 - 6 * chord) if rtol is None else np.isclose(got, exact, rtol)
    p = cases[0][0].vertices
    np.testing.assert_allclose(distance.point_segment(p, centre, centre) - r, 0.0, atol=1e-12)
    p = cases[1][0].vertices
    np.testing.assert_allclose(distance.point_segment(p, a, b) - r, 0.0, atol=1e-12)
    p = cases[2][0].vertices
    got = distance.point_cylinder(p, centre, rot[:, 2], r, 0.4)
    np.testing.assert_allclose(got, 0.0, atol=1e-12)
    got = distance.point_box(cases[3][0].vertices, centre, rot, np.array([0.1, 0.2, 0.3]))
    np.testing.assert_allclose(got, 0.0, atol=1e-12)


def test_world_surfaces_name_every_obstacle_and_put_half_spaces_on_their_plane():
    world = collision.World.create(
        spheres=collision.Spheres.create([[0.0, 0.0, 1.0], [1.0, 0.0, 1.0]], 0.2),
        cylinders=collision.Cylinders.create([[0.0, 1.0, 0.5]], 0.1, 0.5),
        halfspaces=collision.HalfSpaces.create([[0.0, 0.0, 2.0]], [0.2]),  # z <= 0.1
    )
    drawn = surfaces.world_surfaces(world, extent=3.0, center=(1.0, 2.0, 5.0))
    assert [s.name for s in drawn] == ["sphere 0", "sphere 1", "cylinder 0", "halfspace 0"]
    square = drawn[-1].vertices
    np.testing.assert_allclose(square[:, 2], 0.1, atol=1e-12)
    np.testing.assert_allclose(square.mean(0), [1.0, 2.0, 0.1], atol=1e-12)
    np.testing.assert_allclose(np.ptp(square[:, :2], axis=0), 6.0, atol=1e-12)
