"""The URDF collision reader: bad geometry refused naming the link and the file, the body read
once with the chain, package folders, XML text, no trimesh for primitives, thin boxes; the
body's coarse level and its files."""

from __future__ import annotations

import contextlib
import subprocess
import sys
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxkin import collision as col
from jaxkin import scara, serial
from jaxkin.collision import urdf as urdf_module
from jaxkin.collision.stl import read_stl

ROOT = Path(__file__).resolve().parents[1]


def _stl(path: Path, vertices: np.ndarray, faces: np.ndarray) -> Path:
    """An ASCII STL of the mesh (written here, without trimesh)."""
    lines = ["solid m"]
    for f in faces:
        lines += ["facet normal 0 0 0", "outer loop"]
        lines += [f"vertex {x:.17g} {y:.17g} {z:.17g}" for x, y, z in vertices[f]]
        lines += ["endloop", "endfacet"]
    path.write_text("\n".join([*lines, "endsolid m", ""]))
    return path


def _box_stl(path: Path, half=(0.05, 0.03, 0.1)) -> Path:
    vertices, faces = col.cover.box_mesh(np.asarray(half))
    return _stl(path, vertices, faces)


def _urdf(geometry: dict[str, str], origin: str = "") -> str:
    """A two-joint arm base - l1 - l2 - tool; ``geometry`` maps a link to the inside of its
    ``<geometry>``."""
    links = []
    for name in ("base", "l1", "l2", "tool"):
        inside = ""
        if name in geometry:
            inside = f"<collision>{origin}<geometry>{geometry[name]}</geometry></collision>"
        links.append(f'<link name="{name}">{inside}</link>')
    joints = [
        ("j1", "base", "l1", "0 0 0.1"),
        ("j2", "l1", "l2", "0 0 0.3"),
        ("j3", "l2", "tool", "0.3 0 0"),
    ]
    text = []
    for name, parent, child, xyz in joints:
        kind = "fixed" if name == "j3" else "revolute"
        limit = '<limit lower="-3" upper="3" effort="1" velocity="1"/>' if kind != "fixed" else ""
        text.append(
            f'<joint name="{name}" type="{kind}"><parent link="{parent}"/><child link="{child}"/>'
            f'<origin xyz="{xyz}"/><axis xyz="0 1 0"/>{limit}</joint>'
        )
    return f'<robot name="arm">{"".join(links)}{"".join(text)}</robot>'


PRIMITIVES = {
    "base": '<box size="0.2 0.2 0.1"/>',
    "l1": '<cylinder radius="0.04" length="0.3"/>',
    "l2": '<sphere radius="0.05"/>',
}


def _same_body(a: col.Body, b: col.Body) -> None:
    assert jax.tree.structure(a) == jax.tree.structure(b)
    for x, y in zip(jax.tree.leaves(a), jax.tree.leaves(b), strict=True):
        np.testing.assert_array_equal(np.asarray(x), np.asarray(y))
        assert x.dtype == y.dtype


def test_a_thin_box_is_a_few_spheres(tmp_path):
    """A 1 m x 1 m x 2 mm plate: at most 32 spheres (the default budget of a box), no
    capsules, its bound relaxed and reported (it was 302 capsules)."""
    path = tmp_path / "plate.urdf"
    path.write_text(_urdf({"l2": '<box size="1.0 1.0 0.002"/>'}))
    read = col.body_from_urdf(path)
    assert read.body.num_spheres + read.body.num_capsules <= 32
    assert read.body.num_spheres >= 1 and read.body.num_capsules == 0
    assert read.overshoot["l2"] > 0.01
    chain = serial.from_urdf(path, "tool")
    assert chain.collision_body().num_spheres == read.body.num_spheres


BAD = {
    "two-number box": ('<box size="0.1 0.2"/>', "expected 3 numbers"),
    "negative box": ('<box size="0.1 -0.2 0.3"/>', "negative size"),
    "NaN box": ('<box size="nan 0.2 0.3"/>', "finite"),
    "negative length": ('<cylinder radius="0.1" length="-0.3"/>', "negative size"),
    "negative radius": ('<cylinder radius="-0.1" length="0.3"/>', "negative size"),
    "negative sphere": ('<sphere radius="-0.1"/>', "negative size"),
    "mesh without a file": ("<mesh/>", "no filename"),
    "missing mesh": ('<mesh filename="nowhere.stl"/>', "no such file"),
    "empty mesh": ('<mesh filename="empty.stl"/>', "has no triangles"),
    "no shape": ("", "needs one shape"),
}


@pytest.mark.parametrize("case", list(BAD))
def test_bad_geometry_is_refused_naming_the_link_and_the_file(tmp_path, case):
    """``body_from_urdf`` raises a ValueError naming the link and the URDF file; the chain
    still does its kinematics and raises the same error when its body is asked for."""
    geometry, message = BAD[case]
    (tmp_path / "empty.stl").write_text("solid m\nendsolid m\n")
    path = tmp_path / "bad_robot.urdf"
    path.write_text(_urdf({"base": '<sphere radius="0.1"/>', "l1": geometry}))
    pattern = rf"link 'l1' of source '.*bad_robot\.urdf'.*{message}"
    with pytest.raises(ValueError, match=pattern):
        col.body_from_urdf(path)
    chain = serial.from_urdf(path, "tool")
    assert chain.joint_names == ("j1", "j2")
    with pytest.raises(ValueError, match=pattern):
        chain.collision_body()


def test_the_body_is_read_with_the_chain(tmp_path):
    """Editing the URDF and deleting its mesh after the chain is built changes nothing: the
    chain's body is the one read from the files as they were (covered on first use)."""
    mesh = _box_stl(tmp_path / "link.stl")
    path = tmp_path / "robot.urdf"
    path.write_text(_urdf({**PRIMITIVES, "l1": '<mesh filename="link.stl"/>'}))
    before = col.body_from_urdf(path).body
    chain = serial.from_urdf(path, "tool")
    path.write_text(_urdf({"l1": '<sphere radius="9"/>'}))
    mesh.unlink()
    _same_body(chain.collision_body(), before)
    srdf = '<robot name="arm"><disable_collisions link1="base" link2="l2" reason="x"/></robot>'
    _same_body(chain.with_srdf(srdf).collision_body(), before)


@contextlib.contextmanager
def _compilation_cache_dir(directory):
    """JAX's compilation cache directory (and with it the covers' store) set to ``directory``
    (None: off) inside the block, then restored."""
    before = jax.config.jax_compilation_cache_dir
    jax.config.update("jax_compilation_cache_dir", directory)
    try:
        yield
    finally:
        jax.config.update("jax_compilation_cache_dir", before)


@pytest.fixture
def no_cover_store():
    """The store off: an earlier test of the process may have turned JAX's cache on."""
    with _compilation_cache_dir(None):
        yield


@pytest.fixture
def cover_calls(monkeypatch):
    """The calls of the reader's ``mesh_sphere_cover``, counted (a list, one entry a call)."""
    calls = []
    original = urdf_module.mesh_sphere_cover

    def mesh_sphere_cover(*args, **kwargs):
        calls.append(1)
        return original(*args, **kwargs)

    monkeypatch.setattr(urdf_module, "mesh_sphere_cover", mesh_sphere_cover)
    return calls


def _mesh_arm(tmp_path: Path, half=(0.05, 0.03, 0.1)) -> Path:
    """``_urdf``'s arm with its link ``l1`` a box mesh of half-extents ``half`` (STL)."""
    _box_stl(tmp_path / "link.stl", half)
    path = tmp_path / "robot.urdf"
    path.write_text(_urdf({**PRIMITIVES, "l1": '<mesh filename="link.stl"/>'}))
    return path


def test_covers_are_computed_once_per_chain(tmp_path, no_cover_store, cover_calls):
    """The chain's mesh is covered once: asking for the body again, through a chain derived
    from it (``with_srdf``), or through ``collision.check`` reuses it."""
    calls = cover_calls
    path = _mesh_arm(tmp_path)
    chain = serial.from_urdf(path, "tool")
    assert not calls  # reading the chain covers nothing yet
    body = chain.collision_body()
    assert chain.collision_body() is body
    other = chain.with_srdf('<robot name="arm"/>')
    assert other.collision_body() is body
    assert col.prepare(other)[0] is body
    assert len(calls) == 1


def test_package_dirs_as_one_folder(tmp_path):
    """``package_dirs="/ws/src"`` is one folder (it was searched one character at a time), as
    a path or inside a list; without it the mesh is not found."""
    (tmp_path / "ws" / "src" / "arm_pkg" / "meshes").mkdir(parents=True)
    _box_stl(tmp_path / "ws" / "src" / "arm_pkg" / "meshes" / "link.stl")
    (tmp_path / "elsewhere").mkdir()
    path = tmp_path / "elsewhere" / "robot.urdf"
    path.write_text(_urdf({"l1": '<mesh filename="package://arm_pkg/meshes/link.stl"/>'}))
    folder = tmp_path / "ws" / "src"
    reference = col.body_from_urdf(path, package_dirs=[folder]).body
    assert reference.num_spheres + reference.num_capsules >= 1
    for given in (str(folder), folder):
        _same_body(col.body_from_urdf(path, package_dirs=given).body, reference)
    _same_body(serial.from_urdf(path, "tool", package_dirs=str(folder)).collision_body(), reference)
    with pytest.raises(ValueError, match="link 'l1'.*not found under package_dirs"):
        col.body_from_urdf(path)
    with pytest.raises(ValueError, match="package_dirs"):
        col.body_from_urdf(path, package_dirs=3)


def test_urdf_text_with_an_encoding_declaration(tmp_path):
    """The URDF as text with ``<?xml ... encoding=...?>`` gives the body the same file gives,
    for ``body_from_urdf`` and for a chain's collision check: UTF-8, and ISO-8859-1 with a
    link named ``"bras_\u00e9"`` (the text is already decoded: its declaration names the
    file's encoding, not the text's; read as UTF-8 bytes declared Latin-1, the name came
    back as ``"bras_\u00c3\u00a9"`` and the body's links differed from the chain's)."""
    world = col.World.create(spheres=col.Spheres.create([[0.0, 0.0, 0.45]], 0.05))
    q = np.array([[0.0, 0.0], [1.5, 0.0]])
    for encoding in ("utf-8", "ISO-8859-1"):
        quick = {link: PRIMITIVES[link] for link in ("l1", "l2")}  # no box: nothing to cover
        body = _urdf(quick).replace('"l2"', '"bras_\u00e9"')
        text = f'<?xml version="1.0" encoding="{encoding}"?>\n' + body
        path = tmp_path / f"robot_{encoding}.urdf"
        path.write_text(text, encoding=encoding)
        from_path = col.body_from_urdf(path).body
        assert "bras_\u00e9" in from_path.links
        _same_body(col.body_from_urdf(text).body, from_path)
        chain = serial.from_urdf(text, "tool")
        _same_body(chain.collision_body(), serial.from_urdf(path, "tool").collision_body())
    assert list(np.asarray(col.check(chain, q, world).collides)) == [True, False]


def test_primitives_need_no_trimesh_and_meshes_name_the_extra(tmp_path, monkeypatch):
    """Without trimesh: a URDF of boxes, cylinders, spheres and STL meshes is read and covered
    (its body and self pairs prepared for the checks); one with an OBJ mesh fails with an
    ImportError naming the link, the mesh and the ``urdf`` extra."""
    monkeypatch.setitem(sys.modules, "trimesh", None)  # `import trimesh` fails
    _box_stl(tmp_path / "link.stl")
    path = tmp_path / "robot.urdf"
    path.write_text(_urdf({**PRIMITIVES, "tool": '<mesh filename="link.stl"/>'}))
    body, _ = col.prepare(serial.from_urdf(path, "tool"))
    assert body.num_spheres >= 3 and body.num_capsules == 1
    (tmp_path / "link.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    path.write_text(_urdf({**PRIMITIVES, "l1": '<mesh filename="link.obj"/>'}))
    chain = serial.from_urdf(path, "tool")
    extra = r"link 'l1' of source .*: the mesh 'link\.obj' needs trimesh.*jaxkin\[urdf\]"
    with pytest.raises(ImportError, match=extra):
        chain.collision_body()
    with pytest.raises(ImportError, match=extra):
        col.body_from_urdf(path)


def test_stl_files_read_as_trimesh_reads_them(tmp_path):
    """Binary (trimesh's export) and ASCII STL: the same triangles, in the same order, as
    trimesh reads; bytes that are neither are refused."""
    trimesh = pytest.importorskip("trimesh")
    mesh = trimesh.creation.icosphere(2, 0.1)
    binary = tmp_path / "binary.stl"
    mesh.export(binary)
    ascii_ = _stl(tmp_path / "ascii.stl", np.asarray(mesh.vertices), np.asarray(mesh.faces))
    for path in (binary, ascii_):
        vertices, faces = read_stl(path.read_bytes())
        reference = trimesh.load_mesh(path, process=False).triangles
        np.testing.assert_array_equal(vertices[faces], reference)
    with pytest.raises(ValueError, match="not an STL file"):
        read_stl(b"\x00\xff" * 30)


def test_former_mixed_covers_are_still_asked_for(tmp_path):
    """``max_primitives_per_mesh=k``: the mesh as at most ``k`` spheres and capsules (the
    former covers), holding its vertices."""
    pytest.importorskip("scipy")
    vertices, faces = col.cover.box_mesh(np.array([0.02, 0.02, 0.2]))
    _stl(tmp_path / "rod.stl", vertices, faces)
    path = tmp_path / "robot.urdf"
    path.write_text(_urdf({"l1": '<mesh filename="rod.stl"/>'}))
    body = col.body_from_urdf(path, max_primitives_per_mesh=4).body
    assert 1 <= body.num_spheres + body.num_capsules <= 4 and body.num_capsules >= 1
    a, b, r = (np.asarray(x) for x in (body.capsule_a, body.capsule_b, body.capsule_radius))
    t = np.clip(
        np.einsum("pkc,kc->pk", vertices[:, None] - a, b - a) / ((b - a) ** 2).sum(-1), 0, 1
    )
    gap = np.linalg.norm(vertices[:, None] - a - t[..., None] * (b - a), axis=-1) - r
    assert np.all(gap.min(axis=1) <= 0.0)


def test_a_garbage_edge_div_variable_breaks_nothing():
    """The cover module reads no environment variable (``EDGE_DIV`` broke ``import
    jaxkin.plan`` and the command line when set to garbage)."""
    env = {"EDGE_DIV": "garbage", "PATH": ""}
    code = "import jaxkin.plan, jaxkin.collision.cover"
    done = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True)
    assert done.returncode == 0, done.stderr


def _bodies():
    """A long link of spheres along 1 m, a compact link of spheres and a capsule, and a link
    without geometry."""
    rng = np.random.default_rng(11)
    line = np.stack([np.linspace(0.0, 1.0, 40), np.zeros(40), np.zeros(40)], axis=1)
    spheres = {
        "long": (line + rng.normal(size=(40, 3)) * 0.01, rng.uniform(0.02, 0.05, 40)),
        "compact": (rng.normal(size=(6, 3)) * 0.03, rng.uniform(0.01, 0.03, 6)),
    }
    capsules = {"compact": (np.array([[0.0, 0.0, 0.1]]), np.array([[0.05, 0.0, 0.2]]), [0.02])}
    return col.Body.create(["empty", "long", "compact"], spheres, capsules)


def _check_bounds(body: col.Body) -> None:
    """Every primitive inside the bounding sphere it names, on its own link."""
    g, r = np.asarray(body.bound_center), np.asarray(body.bound_radius)
    for k, j in enumerate(body.sphere_bound):
        assert body.bound_link[j] == body.sphere_link[k]
        reach = np.linalg.norm(np.asarray(body.sphere_center[k]) - g[j])
        assert reach + float(body.sphere_radius[k]) <= r[j]
    for k, j in enumerate(body.capsule_bound):
        assert body.bound_link[j] == body.capsule_link[k]
        for end in (body.capsule_a[k], body.capsule_b[k]):
            assert np.linalg.norm(np.asarray(end) - g[j]) + float(body.capsule_radius[k]) <= r[j]


def test_the_coarse_level_holds_every_primitive():
    """Bounding spheres: every sphere and capsule inside its own; a 1 m link of 40 spheres
    gets several (5 to 8: at most ``GROUP_SIZE`` primitives each), a compact link of 7
    primitives one; placed, they follow their links."""
    body = _bodies()
    _check_bounds(body)
    long, compact = body.links.index("long"), body.links.index("compact")
    assert 5 <= body.bound_link.count(long) <= 8 and body.bound_link.count(compact) == 1
    members = np.bincount([*body.sphere_bound, *body.capsule_bound])
    assert members.max() <= col.body.GROUP_SIZE
    assert list(body.bound_link) == sorted(body.bound_link)
    rng = np.random.default_rng(12)
    poses = np.broadcast_to(np.eye(4), (5, 3, 4, 4)).copy()
    poses[:, :, :3, 3] = rng.normal(size=(5, 3, 3))
    placed = body.place_bounds(jnp.asarray(poses))
    link = np.asarray(body.bound_link)
    expected = np.asarray(body.bound_center) + poses[:, link][:, :, :3, 3]
    np.testing.assert_allclose(np.asarray(placed.center), expected, atol=1e-15)
    # a robot's capsule body built from traced lengths: one bounding sphere per link
    robot = scara.Scara.paper()
    _check_bounds(robot.collision_body())
    traced = jax.jit(lambda r: r.collision_body().bound_radius)(robot)
    np.testing.assert_allclose(traced, robot.collision_body().bound_radius, rtol=1e-15)


def test_a_body_saves_and_loads(tmp_path):
    """``Body.save`` / ``Body.load``: the same arrays, links, coarse level and dtype (float64
    and float32); a chain takes a loaded body; files that are not bodies are refused naming
    the file, without unpickling anything."""
    body = _bodies()
    for dtype in (jnp.float64, jnp.float32):
        mine = body.astype(dtype)
        mine.save(tmp_path / "body.npz")
        _same_body(col.Body.load(tmp_path / "body.npz"), mine)
    path = tmp_path / "robot.urdf"
    path.write_text(_urdf(PRIMITIVES))
    chain = serial.from_urdf(path, "tool")
    chain.collision_body().save(tmp_path / "arm.npz")
    loaded = col.Body.load(tmp_path / "arm.npz")
    _same_body(chain.with_body(loaded).collision_body(), loaded)
    with pytest.raises(ValueError, match="links"):
        chain.with_body(body)
    (tmp_path / "text.npz").write_text("not an archive")
    with pytest.raises(ValueError, match=r"Body\.load: '.*text\.npz'"):
        col.Body.load(tmp_path / "text.npz")
    np.savez(tmp_path / "other.npz", links=np.array([{"a": 1}], dtype=object))
    with pytest.raises(ValueError, match=r"other\.npz"):
        col.Body.load(tmp_path / "other.npz")


@pytest.fixture
def cover_store(tmp_path):
    """JAX's compilation cache in a fresh folder for the test; its covers' folder."""
    with _compilation_cache_dir(str(tmp_path / "cache")):
        yield tmp_path / "cache" / "covers"


def test_covers_are_stored_for_later_processes(tmp_path, cover_store, cover_calls):
    """With the compilation cache on, a mesh's cover is written once and read back by a later
    reader (another chain of the same file: what a second process does) equal to the array,
    without covering again; another bound is another entry; a damaged entry is covered again
    and gives the same body, so does a truncated one; with the cache off nothing is written."""
    calls = cover_calls
    path = _mesh_arm(tmp_path, half=(0.05, 0.03, 0.12))
    first = serial.from_urdf(path, "tool").collision_body()
    assert len(calls) == 1 and len(list(cover_store.glob("*.npz"))) == 1
    again = serial.from_urdf(path, "tool").collision_body()
    assert len(calls) == 1
    _same_body(again, first)
    col.body_from_urdf(path, max_overshoot=0.02)
    assert len(calls) == 2 and len(list(cover_store.glob("*.npz"))) == 2
    for entry in cover_store.glob("*.npz"):
        entry.write_bytes(b"not a cover")
    _same_body(serial.from_urdf(path, "tool").collision_body(), first)
    assert len(calls) == 3
    for entry in cover_store.glob("*.npz"):  # cut short, as by a full disk
        entry.write_bytes(entry.read_bytes()[: entry.stat().st_size // 2])
    _same_body(serial.from_urdf(path, "tool").collision_body(), first)
    assert len(calls) == 4
    jax.config.update("jax_compilation_cache_dir", None)
    for entry in cover_store.glob("*.npz"):
        entry.unlink()
    _same_body(serial.from_urdf(path, "tool").collision_body(), first)
    assert len(calls) == 5 and not list(cover_store.glob("*.npz"))
