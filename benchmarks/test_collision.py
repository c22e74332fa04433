"""Signed distances per second: capsule-box, sphere-box, capsule-capsule, capsule-cylinder,
beside coal.

jaxkin's closed forms (``jaxkin.collision.distance``) on batches of 1e4 to 1e6 random pairs
(about a third penetrating), float32 and float64, against coal's ``distance`` called from a
Python loop over 1e4 prebuilt pairs (shapes, transforms and the request built outside the
timer: the per-query cost of a planner's Python validity checker). ``extra_info`` records the
largest deviation from coal on the first 1,000 pairs.

A last benchmark measures the world query of a planner's check for pre-placed robot
primitives: 60 spheres against 18 obstacles (12 spheres, 6 boxes) per configuration, the
Panda-sized problem, per configuration.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxkin import collision as col
from jaxkin.collision import distance as sd
from jaxkin.collision import fused as cl
from jaxkin.collision.rows import Placed

coal = pytest.importorskip("coal")
Rotation = pytest.importorskip("scipy.spatial.transform").Rotation

PAIRS = ("capsule-box", "sphere-box", "capsule-capsule", "capsule-cylinder")
N_COAL = 10_000


def _data(n: int, seed: int = 0) -> dict[str, np.ndarray]:
    rng = np.random.default_rng(seed)
    a = rng.normal(size=(n, 3))
    b = a + 0.6 * rng.normal(size=(n, 3))
    rot = Rotation.random(n, random_state=seed).as_matrix()
    return {
        "a": a,
        "b": b,
        "r": rng.uniform(0.02, 0.2, n),
        "c": a + 0.7 * rng.normal(size=(n, 3)),
        "rot": rot,
        "h": rng.uniform(0.05, 0.5, (n, 3)),
        "p": a + 0.5 * rng.normal(size=(n, 3)),
        "q": a + rng.normal(size=(n, 3)),
        "s": rng.uniform(0.02, 0.2, n),
        "axis": rot[:, :, 2],
        "radius": rng.uniform(0.05, 0.5, n),
        "half": rng.uniform(0.05, 0.5, n),
    }


def _kernel(pair: str, d: dict):
    if pair == "capsule-box":
        return sd.capsule_box, (d["a"], d["b"], d["r"], d["c"], d["rot"], d["h"])
    if pair == "sphere-box":
        return sd.sphere_box, (d["a"], d["r"], d["c"], d["rot"], d["h"])
    if pair == "capsule-cylinder":
        cylinder = (d["c"], d["axis"], d["radius"], d["half"])
        return sd.capsule_cylinder, (d["a"], d["b"], d["r"], *cylinder)
    return sd.capsule_capsule, (d["a"], d["b"], d["r"], d["p"], d["q"], d["s"])


def _coal_capsule(a, b, r):
    d = b - a
    length = np.linalg.norm(d)
    rot = Rotation.align_vectors([d / length], [[0.0, 0.0, 1.0]])[0].as_matrix()
    return coal.Capsule(r, length), coal.Transform3s(rot, 0.5 * (a + b))


def _coal_queries(pair: str, d: dict, n: int):
    out = []
    for i in range(n):
        first = _coal_capsule(d["a"][i], d["b"][i], d["r"][i])
        if pair == "sphere-box":
            first = (coal.Sphere(d["r"][i]), coal.Transform3s(np.eye(3), d["a"][i]))
        if pair == "capsule-capsule":
            second = _coal_capsule(d["p"][i], d["q"][i], d["s"][i])
        elif pair == "capsule-cylinder":  # coal's cylinder: along its frame's z, length lz
            pose = coal.Transform3s(d["rot"][i], d["c"][i])
            second = (coal.Cylinder(d["radius"][i], 2.0 * d["half"][i]), pose)
        else:
            second = (coal.Box(*(2.0 * d["h"][i])), coal.Transform3s(d["rot"][i], d["c"][i]))
        out.append((*first, *second))
    return out


def _coal_loop(queries):
    request, result = coal.DistanceRequest(), coal.DistanceResult()

    def run():
        out = []
        for g1, t1, g2, t2 in queries:
            result.clear()  # a result keeps the smallest distance of every query it has seen
            out.append(coal.distance(g1, t1, g2, t2, request, result))
        return out

    return run


@pytest.mark.parametrize("n", [10_000, 100_000, 1_000_000])
@pytest.mark.parametrize("dtype", ["float32", "float64"])
@pytest.mark.parametrize("pair", PAIRS)
def test_jaxkin_signed_distance(measure, benchmark, pair, dtype, n):
    d = _data(n)
    fn, args = _kernel(pair, d)
    fn = jax.jit(fn)
    args = [jax.device_put(jnp.asarray(x, dtype=dtype)) for x in args]
    out = measure(lambda: fn(*args), n, pair=pair, dtype=dtype, batch=n)
    reference = np.asarray(_coal_loop(_coal_queries(pair, d, 1000))())
    deviation = float(np.max(np.abs(np.asarray(out[:1000], np.float64) - reference)))
    benchmark.extra_info["max_abs_deviation_from_coal"] = deviation
    benchmark.extra_info["penetrating_fraction"] = float(np.mean(reference < 0))
    # coal's GJK/EPA on a cylinder stops at its default tolerance, 1e-6 (its deviations: 4e-6)
    tolerance = 1e-5 if pair == "capsule-cylinder" or dtype == "float32" else 1e-9
    assert deviation < tolerance


@pytest.mark.parametrize("pair", PAIRS)
def test_coal_signed_distance(measure, pair):
    queries = _coal_queries(pair, _data(N_COAL), N_COAL)
    measure(_coal_loop(queries), N_COAL, rounds=3, pair=pair, peer="coal (Python loop)")


@pytest.mark.parametrize("dtype", ["float32", "float64"])
def test_world_query_panda_sized(measure, dtype):
    """Per configuration: 60 robot spheres against 12 spheres and 6 boxes, batch 1e4."""
    n, k = 10_000, 60
    rng = np.random.default_rng(1)
    world = col.World.create(
        spheres=col.Spheres.create(rng.uniform(-1, 1, (12, 3)), rng.uniform(0.05, 0.2, 12)),
        boxes=col.Boxes.create(
            rng.uniform(-1, 1, (6, 3)),
            rng.uniform(0.05, 0.3, (6, 3)),
            Rotation.random(6, random_state=1).as_matrix(),
        ),
        dtype=dtype,
    )
    robot = col.Spheres(
        jnp.asarray(rng.uniform(-1, 1, (n, k, 3)), dtype),
        jnp.asarray(rng.uniform(0.03, 0.08, (n, k)), dtype),
    )

    @jax.jit
    def clearance(spheres, world):
        near, _ = col.nearest_obstacles(spheres, col.Capsules.empty(dtype), world)
        return jnp.min(near.distance, axis=-1)

    measure(lambda: clearance(robot, world), n, kernel="60 spheres x 18 obstacles", dtype=dtype)


# ---------------------------------------------------------------------------------------
# The Panda's configuration check: forward kinematics, placement and the fused clearance.


def _robots_folder():
    import sys
    from pathlib import Path

    for base in map(Path, sys.path):
        root = base / "cmeel.prefix" / "share" / "example-robot-data" / "robots"
        if root.is_dir():
            return root
    pytest.skip("example-robot-data's robots folder not found")


@pytest.fixture(scope="module")
def panda():
    """The Panda as spheres: mesh covers of at most 5 spheres per mesh (``body_from_urdf``;
    65 spheres with the former covers, whose finger boxes were capsules, each replaced here
    by its bounding sphere; 59 with the 1 cm covers, whose boxes are spheres); the SRDF's
    self pairs; the URDF's joints for the forward kinematics; a world of 12 spheres and 6
    boxes (VAMP's scene size) around the arm."""
    yourdfpy = pytest.importorskip("yourdfpy")
    root = _robots_folder()
    urdf = root / "panda_description/urdf/panda.urdf"
    _, capsules = col.body_from_urdf(urdf, max_spheres_per_mesh=5).body.per_link()
    fingers = {
        name: (0.5 * (a + b), r + 0.5 * np.linalg.norm(b - a, axis=-1))
        for name, (a, b, r) in capsules.items()
    }
    read = col.body_from_urdf(urdf, max_spheres_per_mesh=5, link_spheres=fingers)
    body = read.body
    disabled = col.read_srdf_disabled(root / "panda_description/srdf/panda.srdf")
    pairs = col.SelfPairs.create(body, col.self_collision_link_pairs(body, read.joints, disabled))
    model = yourdfpy.URDF.load(str(urdf), build_scene_graph=False, load_meshes=False).robot
    joints = [
        (
            body.links.index(j.parent),
            body.links.index(j.child),
            j.type,
            np.eye(4) if j.origin is None else np.asarray(j.origin),
        )
        for j in model.joints
    ]
    assert all(np.allclose(j.axis, [0, 0, 1]) for j in model.joints if j.type == "revolute")
    rng = np.random.default_rng(3)
    low, high = [-0.7, -0.7, 0.0], [0.7, 0.7, 1.1]
    world = col.World.create(
        spheres=col.Spheres.create(rng.uniform(low, high, (12, 3)), rng.uniform(0.04, 0.12, 12)),
        boxes=col.Boxes.create(
            rng.uniform(low, high, (6, 3)),
            rng.uniform(0.03, 0.12, (6, 3)),
            Rotation.random(6, random_state=3).as_matrix(),
        ),
    )
    limits = np.array(
        [(j.limit.lower, j.limit.upper) for j in model.joints if j.type == "revolute"]
    )
    return {"body": body, "pairs": pairs, "joints": joints, "world": world, "limits": limits}


def _panda_rows(panda, q):
    """Forward kinematics of every link written elementwise (rotation entries and positions
    as ``(B,)`` arrays; revolute joints about z, fingers closed), and the spheres placed in
    the rows layout: centres ``(3, ns, B)``, radii ``(ns, B)``."""
    body = panda["body"]
    one, zero = jnp.ones(q.shape[:-1], q.dtype), jnp.zeros(q.shape[:-1], q.dtype)
    poses = [None] * len(body.links)
    poses[0] = ([[one, zero, zero], [zero, one, zero], [zero, zero, one]], [zero, zero, zero])
    k = 0
    for parent, child, kind, origin in panda["joints"]:
        rot, pos = poses[parent]

        def affine(i, j, base=None, rot=rot, origin=origin):
            terms = [rot[i][m] * float(origin[m, j]) for m in range(3) if origin[m, j] != 0.0]
            terms += [] if base is None else [base]
            return sum(terms[1:], terms[0]) if terms else zero

        rot2 = [[affine(i, j) for j in range(3)] for i in range(3)]
        pos2 = [affine(i, 3, pos[i]) for i in range(3)]
        if kind == "revolute":
            c, s = jnp.cos(q[..., k]), jnp.sin(q[..., k])
            k += 1
            rot2 = [[r[0] * c + r[1] * s, r[1] * c - r[0] * s, r[2]] for r in rot2]
        poses[child] = (rot2, pos2)
    center = np.asarray(body.sphere_center, dtype=q.dtype)
    link = np.asarray(body.sphere_link)
    rows = [[], [], []]
    cuts = np.flatnonzero(np.diff(link)) + 1  # runs of one link's spheres
    for start, stop in zip([0, *cuts], [*cuts, len(link)], strict=True):
        rot, pos = poses[link[start]]
        c = center[start:stop]
        for i in range(3):
            rows[i].append(
                sum(rot[i][m][None, :] * c[:, m, None] for m in range(3)) + pos[i][None, :]
            )
    radius = jnp.broadcast_to(
        jnp.asarray(body.sphere_radius, q.dtype)[:, None], (len(link), q.shape[0])
    )
    return col.Spheres(jnp.stack([jnp.concatenate(r) for r in rows]), radius)


CHUNK = 2000  # configurations per step of the check (divides 1e3..1e6): its rows stay in L2


def _panda_check(panda, dtype, fk: bool):
    """The jitted check: ``q (n, 7)`` (or placed rows, chunked) -> clearance ``(n,)``."""
    world = panda["world"].astype(dtype)
    pairs = panda["pairs"]

    def from_rows(rows):
        none = jnp.zeros((3, 0, rows.radius.shape[-1]), dtype)
        placed = Placed(rows.center, rows.radius, none, none, jnp.zeros((0, 1), dtype))
        return cl.min_clearance_rows(placed, world, pairs)

    def from_q(q):
        return from_rows(_panda_rows(panda, q))

    one = from_q if fk else from_rows

    @jax.jit
    def check(chunks):
        return jax.lax.map(one, chunks).reshape(-1)

    return check


def _configurations(panda, n, dtype, seed=0):
    low, high = panda["limits"].T
    return np.random.default_rng(seed).uniform(low, high, (n, 7)).astype(dtype)


@pytest.mark.parametrize("n", [1_000, 10_000, 100_000, 1_000_000])
@pytest.mark.parametrize("dtype", ["float32", "float64"])
@pytest.mark.parametrize("fk", [True, False], ids=["with-fk", "placed"])
def test_panda_configurations(measure, benchmark, panda, dtype, n, fk):
    """Panda configurations checked per second (robot-world and SRDF self pairs), with the
    forward kinematics and placement inside the timed call or spheres placed beforehand."""
    if not fk and n > 100_000:
        pytest.skip("1e6 placed configurations hold 0.8-1.6 GB of sphere rows")
    q = _configurations(panda, n, dtype)
    chunk = min(n, CHUNK)
    chunks = jnp.asarray(q.reshape(n // chunk, chunk, 7))
    check = _panda_check(panda, dtype, fk)
    if not fk:
        chunks = jax.block_until_ready(jax.jit(jax.vmap(lambda c: _panda_rows(panda, c)))(chunks))
    out = measure(lambda: check(chunks), n, kernel="Panda check", dtype=dtype, batch=n, fk=fk)
    body, pairs = panda["body"], panda["pairs"]
    benchmark.extra_info["spheres"] = body.num_spheres
    benchmark.extra_info["self_pairs"] = pairs.num_primitive_pairs
    benchmark.extra_info["colliding_fraction"] = float(np.mean(np.asarray(out) <= 0))
    benchmark.extra_info["goal_ratio"] = n / benchmark.stats.stats.min / 1e6


@pytest.mark.parametrize("dtype", ["float32", "float64"])
def test_panda_edges(measure, benchmark, panda, dtype):
    """Edges validated per second: 10,000 edges of joint length 0.3 rad, each at 10 states
    (about 32 states per unit of joint distance, VAMP's resolution), every state checked."""
    m, states = 10_000, 10
    start = _configurations(panda, m, dtype, seed=1)
    step = np.random.default_rng(2).normal(size=(m, 7))
    end = start + 0.3 * step / np.linalg.norm(step, axis=-1, keepdims=True)
    t = np.linspace(0.0, 1.0, states, dtype=dtype)
    q = (start[:, None] + t[:, None] * (end - start)[:, None]).reshape(-1, 7).astype(dtype)
    chunks = jnp.asarray(q.reshape(-1, CHUNK, 7))
    check = _panda_check(panda, dtype, fk=True)

    def edges():
        return jnp.min(check(chunks).reshape(m, states), axis=-1) > 0

    valid = measure(edges, m, kernel="Panda edges", dtype=dtype, states_per_edge=states)
    benchmark.extra_info["valid_fraction"] = float(np.mean(np.asarray(valid)))


@pytest.fixture(scope="module")
def panda_chain(panda):
    """The Panda as a public robot: ``serial.from_urdf`` to the hand, the SRDF, and the
    benchmark body's spheres on every link (``with_link_spheres``): the same spheres and
    20 link pairs as ``panda``."""
    from jaxkin import serial

    root = _robots_folder()
    spheres, _ = panda["body"].per_link()
    robot = (
        serial.from_urdf(root / "panda_description/urdf/panda.urdf", "panda_hand")
        .with_srdf(root / "panda_description/srdf/panda.srdf")
        .with_link_spheres(spheres)
    )
    body, pairs = col.prepare(robot)
    assert body.num_spheres == panda["body"].num_spheres and body.num_capsules == 0
    assert pairs.link_pairs == panda["pairs"].link_pairs
    return robot


@pytest.mark.parametrize("n", [1_000, 10_000, 100_000])
@pytest.mark.parametrize("dtype", ["float32", "float64"])
def test_panda_public_check(measure, benchmark, panda, panda_chain, dtype, n):
    """Panda configurations per second through the public ``collision.check(robot, q, world)``
    (the chain's own forward kinematics, placement, the fused clearance and the pair, chunk
    by chunk): what a user calls."""
    q = jnp.asarray(_configurations(panda, n, dtype))
    world = panda["world"].astype(dtype)
    out = measure(
        lambda: col.check(panda_chain, q, world).clearance,
        n,
        kernel="collision.check",
        dtype=dtype,
        batch=n,
    )
    benchmark.extra_info["colliding_fraction"] = float(np.mean(np.asarray(out) <= 0))
    benchmark.extra_info["goal_ratio"] = n / benchmark.stats.stats.min / 1e6


def test_coal_panda_configurations(measure, panda):
    """Pinocchio + coal on the same scene with the Panda's original meshes: computeCollisions
    (stop at the first collision) per configuration from a Python loop, 300 configurations."""
    pin = pytest.importorskip("pinocchio")
    root = _robots_folder()
    model, cmodel, _ = pin.buildModelsFromUrdf(
        str(root / "panda_description/urdf/panda.urdf"), str(root.parent.parent)
    )
    world = panda["world"]
    links = [cmodel.geometryObjects[g].name for g in range(len(cmodel.geometryObjects))]
    obstacles = []
    for k in range(len(world.spheres)):
        shape = coal.Sphere(float(world.spheres.radius[k]))
        place = pin.SE3(np.eye(3), np.asarray(world.spheres.center[k]))
        obstacles.append(pin.GeometryObject(f"sphere{k}", 0, 0, place, shape))
    for k in range(len(world.boxes)):
        shape = coal.Box(*(2.0 * np.asarray(world.boxes.half_extents[k])))
        place = pin.SE3(np.asarray(world.boxes.rotation[k]), np.asarray(world.boxes.center[k]))
        obstacles.append(pin.GeometryObject(f"box{k}", 0, 0, place, shape))
    ids = [cmodel.addGeometryObject(o) for o in obstacles]
    for g in range(len(links)):
        for o in ids:
            cmodel.addCollisionPair(pin.CollisionPair(g, o))
    srdf = str(root / "panda_description/srdf/panda.srdf")
    self_model = pin.buildGeomFromUrdf(
        model,
        str(root / "panda_description/urdf/panda.urdf"),
        pin.COLLISION,
        str(root.parent.parent),
    )
    self_model.addAllCollisionPairs()
    pin.removeCollisionPairs(model, self_model, srdf)
    for pair in self_model.collisionPairs:
        cmodel.addCollisionPair(pin.CollisionPair(pair.first, pair.second))
    data, cdata = model.createData(), pin.GeometryData(cmodel)
    q7 = _configurations(panda, 300, "float64")
    qs = np.concatenate([q7, np.zeros((300, model.nq - 7))], axis=1)

    def run():
        return [pin.computeCollisions(model, data, cmodel, cdata, q, True) for q in qs]

    measure(run, len(qs), rounds=3, peer="pinocchio + coal, meshes (Python loop)")


@pytest.mark.parametrize("n", [1_000, 10_000, 100_000])
@pytest.mark.parametrize("dtype", ["float32", "float64"])
@pytest.mark.parametrize("path", ["collides", "check"])
def test_panda_public_verdict(measure, benchmark, panda, panda_chain, dtype, n, path):
    """Panda configurations per second through the public verdict path
    ``collision.collides(robot, q, world)`` (squared distances, the chain's forward kinematics
    in rows) beside the public clearance path ``collision.check`` in the same run."""
    q = jnp.asarray(_configurations(panda, n, dtype))
    world = panda["world"].astype(dtype)
    fn = col.collides if path == "collides" else col.check
    out = measure(
        lambda: fn(panda_chain, q, world).collides,
        n,
        kernel=f"collision.{path}",
        dtype=dtype,
        batch=n,
    )
    benchmark.extra_info["colliding_fraction"] = float(np.mean(np.asarray(out)))
    benchmark.extra_info["goal_ratio"] = n / benchmark.stats.stats.min / 1e6


@pytest.mark.parametrize("dtype", ["float32", "float64"])
@pytest.mark.parametrize("clearance", [False, True], ids=["verdict", "clearance"])
def test_panda_public_edges(measure, benchmark, panda, panda_chain, dtype, clearance):
    """Edges validated per second through ``collision.validate_motions``: 1,000 edges of
    joint length 0.3 rad at 32 states per unit of joint distance (10 intervals, 16 slots)."""
    m = 1_000
    start = _configurations(panda, m, dtype, seed=1)
    step = np.random.default_rng(2).normal(size=(m, 7))
    end = (start + 0.3 * step / np.linalg.norm(step, axis=-1, keepdims=True)).astype(dtype)
    world = panda["world"].astype(dtype)
    a, b = jnp.asarray(start), jnp.asarray(end)

    def edges():
        return col.validate_motions(
            panda_chain, a, b, world, 32.0, samples=16, clearance=clearance
        ).valid

    valid = measure(edges, m, kernel="validate_motions", dtype=dtype, clearance=clearance)
    benchmark.extra_info["valid_fraction"] = float(np.mean(np.asarray(valid)))


# ---------------------------------------------------------------------------------------
# An independent sphere-model checker beside `collision.collides`: a fused Numba loop per
# configuration (benchmarks/sphere_reference.py), on the same spheres, self pairs and world.


@pytest.fixture(scope="module")
def sphere_reference(panda, panda_chain):
    """``make(dtype) -> check(q (n, 7)) -> collides (n,)``: the Numba reference with the
    spheres and self pairs of ``col.prepare(panda_chain)`` (what ``collides`` checks), the
    world of ``panda``, margin 0 (``collides``' default), its forward kinematics from the
    URDF's joints read by its own parser, on 2 threads."""
    pytest.importorskip("numba")
    import sphere_reference as ref

    body, pairs = col.prepare(panda_chain)
    world = panda["world"]
    assert not body.num_capsules and not pairs.sc_pair and not pairs.cc_pair
    assert not len(world.capsules) and not len(world.halfspaces)
    joints = ref.read_urdf_joints(_robots_folder() / "panda_description/urdf/panda.urdf")

    def make(dtype):
        model = ref.SphereModel.create(
            joints,
            body.links,
            7,
            spheres=(body.sphere_link, np.asarray(body.sphere_center), body.sphere_radius),
            obstacles=(world.spheres.center, world.spheres.radius),
            boxes=(world.boxes.center, world.boxes.rotation, world.boxes.half_extents),
            pairs=pairs.ss,
            margin=0.0,
            dtype=dtype,
        )
        return ref.make_checker(model, threads=2)

    return make


def _interleaved(contenders: dict, rounds: int = 5) -> tuple[dict, dict]:
    """Each contender's best wall time and best process CPU time over ``rounds`` rounds, the
    contenders called in turn within each round (machine load hits them alike)."""
    import time

    wall = dict.fromkeys(contenders, float("inf"))
    cpu = dict.fromkeys(contenders, float("inf"))
    for fn in contenders.values():
        jax.block_until_ready(fn())
    for _ in range(rounds):
        for name, fn in contenders.items():
            start, start_cpu = time.perf_counter(), time.process_time()
            jax.block_until_ready(fn())
            wall[name] = min(wall[name], time.perf_counter() - start)
            cpu[name] = min(cpu[name], time.process_time() - start_cpu)
    return wall, cpu


@pytest.mark.parametrize("n", [10_000, 100_000])
@pytest.mark.parametrize("dtype", ["float32", "float64"])
def test_panda_sphere_reference(measure, benchmark, panda, panda_chain, sphere_reference, dtype, n):
    """The Numba reference's configurations per second (the row), then the reference and
    ``collision.collides`` in interleaved rounds in the same process: their throughput ratio
    (wall clock) and their ratio per CPU-second (process CPU time; both use the 2 cores)."""
    q = _configurations(panda, n, dtype)
    reference = sphere_reference(dtype)
    out = measure(
        lambda: reference(q), n, kernel="Numba sphere reference", dtype=dtype, batch=n, threads=2
    )
    q_jax, world = jnp.asarray(q), panda["world"].astype(dtype)
    contenders = {
        "collides": lambda: col.collides(panda_chain, q_jax, world).collides,
        "reference": lambda: reference(q),
    }
    wall, cpu = _interleaved(contenders)
    verdict = np.asarray(contenders["collides"]())
    info = benchmark.extra_info
    info["collides_cases_per_second"] = n / wall["collides"]
    info["reference_cases_per_second_interleaved"] = n / wall["reference"]
    info["ratio_collides_over_reference"] = wall["reference"] / wall["collides"]
    info["collides_cases_per_cpu_second"] = n / cpu["collides"]
    info["reference_cases_per_cpu_second"] = n / cpu["reference"]
    info["cpu_ratio_collides_over_reference"] = cpu["reference"] / cpu["collides"]
    info["colliding_fraction"] = float(np.mean(out))
    info["verdicts_differing_from_collides"] = int(np.sum(out != verdict))
    # collides is conservative by a rounding tolerance: it may flag, never miss
    assert not np.any(out & ~verdict)


@pytest.mark.parametrize("dtype", ["float32", "float64"])
def test_sphere_reference_agrees_with_check(benchmark, panda, panda_chain, sphere_reference, dtype):
    """The reference's verdicts against ``collision.check(...).collides`` on 10,000 random
    configurations of the scene: equal except within rounding of contact (every differing
    configuration's float64 clearance within ``tol`` of 0: 1e-9 in float64, 1e-5 in float32,
    about 100 float32 ulps of the scene's 1 m size)."""
    n, tol = 10_000, {"float64": 1e-9, "float32": 1e-5}[dtype]
    q = _configurations(panda, n, dtype, seed=7)
    reference = sphere_reference(dtype)
    out = benchmark.pedantic(lambda: reference(q), rounds=1, iterations=1, warmup_rounds=1)
    world = panda["world"].astype(dtype)
    verdict = np.asarray(col.check(panda_chain, jnp.asarray(q), world).collides)
    exact = col.check(panda_chain, jnp.asarray(q, jnp.float64), panda["world"])
    clearance = np.asarray(exact.clearance)
    differ = out != verdict
    info = benchmark.extra_info
    info.update(kernel="Numba sphere reference vs collision.check", dtype=dtype, n_cases=n)
    info["colliding_fraction"] = float(np.mean(out))
    info["verdicts_differing"] = int(np.sum(differ))
    info["max_abs_clearance_of_differing"] = float(np.max(np.abs(clearance[differ]), initial=0.0))
    info["min_abs_clearance"] = float(np.min(np.abs(clearance)))
    assert 0.3 < np.mean(out) < 0.8  # the scene is neither empty nor solid
    assert np.all(np.abs(clearance[differ]) <= tol)
