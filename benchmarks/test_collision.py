"""Signed distances per second: capsule-box, sphere-box, capsule-capsule, beside coal.

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

coal = pytest.importorskip("coal")
Rotation = pytest.importorskip("scipy.spatial.transform").Rotation

PAIRS = ("capsule-box", "sphere-box", "capsule-capsule")
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
    }


def _kernel(pair: str, d: dict):
    if pair == "capsule-box":
        return sd.capsule_box, (d["a"], d["b"], d["r"], d["c"], d["rot"], d["h"])
    if pair == "sphere-box":
        return sd.sphere_box, (d["a"], d["r"], d["c"], d["rot"], d["h"])
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
    assert deviation < (1e-9 if dtype == "float64" else 1e-5)


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
