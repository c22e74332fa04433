"""Mesh covers by spheres and capsules: containment of the surface and the overshoot bound."""

from __future__ import annotations

import numpy as np
import pytest

from jaxkin import collision as col
from jaxkin.collision import cover


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


@pytest.mark.slow  # about 4 s of CPU (trimesh's signed distances)
def test_mesh_cover_of_a_tube_uses_capsules_and_bounds_its_overshoot():
    """An annulus (a tube, 30 cm long, radii 3 and 6 cm) and a box glued to it (two closed
    parts): every vertex and sampled surface point inside the cover, every sampled point of
    the cover within ``overshoot`` of the solid (trimesh's signed distance of each part), and
    the mixed cover at least as tight as spheres only with the same budget."""
    trimesh = pytest.importorskip("trimesh")
    tube = trimesh.creation.annulus(r_min=0.03, r_max=0.06, height=0.3)
    lug = trimesh.creation.box([0.05, 0.05, 0.05])
    lug.apply_translation([0.08, 0.0, 0.1])
    mesh = trimesh.util.concatenate([tube, lug])
    c = col.mesh_cover(mesh.vertices, mesh.faces, max_primitives=8)
    assert c.num_primitives <= 8 and len(c.capsule_radii) >= 1
    surface = np.concatenate([mesh.vertices, trimesh.sample.sample_surface(mesh, 4000, seed=0)[0]])
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
    # trimesh: positive inside each closed part; the solid is their union
    depth = np.max([trimesh.proximity.signed_distance(p, shell) for p in (tube, lug)], axis=0)
    assert np.max(-depth) <= c.overshoot + 1e-9
    spheres = col.mesh_sphere_cover(mesh.vertices, mesh.faces, max_spheres=8)
    assert c.overshoot <= spheres.overshoot


def test_mesh_cover_rejects_a_bad_budget():
    trimesh = pytest.importorskip("trimesh")
    mesh = trimesh.creation.box([0.1, 0.1, 0.1])
    with pytest.raises(ValueError, match="max_primitives"):
        col.mesh_cover(mesh.vertices, mesh.faces, max_primitives=0)


def test_signed_distance_bound_of_overlapping_parts():
    """Two overlapping unit cubes: a point inside both is at least as deep as its larger depth
    in one cube (0.45 here, where the nearest triangle, an inner face, is 0.05 away; the
    union's true depth is 0.5); outside, the distance to the nearer cube."""
    trimesh = pytest.importorskip("trimesh")
    a = trimesh.creation.box([1.0, 1.0, 1.0])
    b = trimesh.creation.box([1.0, 1.0, 1.0])
    b.apply_translation([0.5, 0.0, 0.0])
    both = trimesh.util.concatenate([a, b])
    parts = cover._closed_bodies(np.asarray(both.vertices), np.asarray(both.faces))
    assert parts is not None and len(parts) == 2
    p = np.array([[0.05, 0.0, 0.0], [0.0, 0.0, 0.9], [1.5, 0.0, 0.0]])
    sd = cover._signed_distance(np.concatenate(parts), parts, p)
    np.testing.assert_allclose(sd, [-0.45, 0.4, 0.5], atol=1e-12)
