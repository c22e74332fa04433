"""The program store: kernels kept as ``jax.export`` serialisations and called by later
processes without tracing them (``jaxkin._execute.store``).

Checked here: the key states everything a program depends on (values that differ give other
keys, values it cannot state make the call an ordinary trace), a stored program gives the
results of the traced one, a process that finds it neither exports nor traces the kernel
again (a fresh in-process trace after ``jax.clear_caches``; a second process in the slow
tier of ``test_compile_cache.py``), a damaged or mismatched entry is traced again, and the
store stays out of traces inside a caller's ``grad``."""

from __future__ import annotations

import functools

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from jax.experimental.compilation_cache import compilation_cache as jax_cache

import jaxkin
from jaxkin import collision, fixedpoint, jet, serial
from jaxkin._execute import Kernel, store

from .helpers import compilations


@pytest.fixture
def program_store(tmp_path):
    """The store on, in a directory of this test's own, and every program traced again from
    here on; afterwards JAX's cache is where the test configuration put it."""
    saved = jax.config.jax_compilation_cache_dir
    jax.config.update("jax_compilation_cache_dir", str(tmp_path))
    store.keep_programs(True)
    jax.clear_caches()
    yield tmp_path / "programs"
    store.keep_programs(False)
    jax.config.update("jax_compilation_cache_dir", saved)
    jax_cache.reset_cache()  # JAX opens its cache again where the configuration says


def _programs(directory) -> list[str]:
    return sorted(p.name for p in directory.glob("*.program")) if directory.exists() else []


# ------------------------------------------------------------------------------ keys


class _Foreign:  # a class outside jaxkin: the key cannot vouch for its code
    value = 1


def _foreign_function(x):
    return x


def test_fingerprints_state_values_not_identities():
    a = np.arange(2000.0)
    b = a.copy()
    b[1000] += 1.0  # beyond what a repr of the array would show
    assert store.fingerprint(a) == store.fingerprint(a.copy())
    assert store.fingerprint(a) != store.fingerprint(b)
    assert store.fingerprint(np.float32(1.0)) != store.fingerprint(np.float64(1.0))
    assert store.fingerprint((1, True)) != store.fingerprint((True, 1))
    assert store.fingerprint({"a": 1, "b": 2}) == store.fingerprint({"b": 2, "a": 1})
    robot = serial.Puma560()
    assert store.fingerprint(robot) == store.fingerprint(serial.Puma560())
    # closures and partials by what they capture
    quantizer = fixedpoint._quantizer
    three, four = jnp.asarray([3]), jnp.asarray([4])
    assert store.fingerprint(quantizer(three, "floor")) == store.fingerprint(
        quantizer(jnp.asarray([3]), "floor")
    )
    assert store.fingerprint(quantizer(three, "floor")) != store.fingerprint(
        quantizer(four, "floor")
    )
    assert store.fingerprint(quantizer(three, "floor")) != store.fingerprint(
        quantizer(three, "round")
    )
    partial = functools.partial(jaxkin.fk, robot)
    assert store.fingerprint(partial) == store.fingerprint(functools.partial(jaxkin.fk, robot))
    assert store.fingerprint(partial) != store.fingerprint(functools.partial(jaxkin.ik, robot))
    # functions by their code: two lambdas of one function share a qualified name
    add_one, add_two = (lambda x: x + 1), (lambda x: x + 2)
    for f in (add_one, add_two):
        f.__module__, f.__qualname__ = "jaxkin.kernels", "made.<locals>.<lambda>"
    same = type(add_one)(add_one.__code__, add_one.__globals__)
    same.__module__, same.__qualname__ = add_one.__module__, add_one.__qualname__
    assert store.fingerprint(add_one) == store.fingerprint(same)
    assert store.fingerprint(add_one) != store.fingerprint(add_two)
    # a kernel by what determines its programs
    first = Kernel(jet.lift(jnp.sin))
    assert store.fingerprint(first) == store.fingerprint(Kernel(jet.lift(jnp.sin)))
    assert store.fingerprint(first) != store.fingerprint(Kernel(jet.lift(jnp.cos)))


@pytest.mark.parametrize(
    "value",
    [_Foreign(), _foreign_function, jet.lift(_foreign_function), [1]],
    ids=["foreign object", "foreign function", "closure over one", "cycle"],
)
def test_values_the_key_cannot_state_are_unstorable(value):
    if isinstance(value, list):
        value.append(value)  # a cycle
    with pytest.raises(store.Unstorable):
        store.fingerprint(value)


def test_tree_static_data_is_part_of_the_key():
    """Two chains whose static (auxiliary) data differ (joint types, joint names) get
    different keys; the same chain built twice the same key."""
    spec = [jax.ShapeDtypeStruct((3,), jnp.float64)]

    def chain(types="RRR", names=None):
        table = serial.DHTable.create(
            a=[0.0, 0.4, 0.02], alpha=[1.5708, 0.0, -1.5708], d=[0.0, 0.0, 0.15],
            theta=[0.0, 0.0, 0.0], joint_types=types,
        )  # fmt: skip
        return serial.from_dh(table, joint_names=names)

    def key(robot):
        _, tree = jax.tree.flatten({"robot": robot})
        return store.program_key(jaxkin.fk, {}, tree, spec)

    assert key(chain()) == key(chain())
    assert key(chain()) != key(chain("RRP"))
    assert key(chain()) != key(chain(names=["a", "b", "c"]))


# ------------------------------------------------------------------------------ programs


@pytest.mark.slow
def test_stored_programs_give_the_traced_results(program_store):
    robot = serial.Puma560()
    q = np.random.default_rng(0).uniform(-2.0, 2.0, (5, 6))
    store.keep_programs(False)
    want_fk = jaxkin.fk(robot, q)
    want_ik = jaxkin.ik(robot, want_fk.x.p)
    store.keep_programs(True)
    jax.clear_caches()
    got_fk = jaxkin.fk(robot, q)
    got_ik = jaxkin.ik(robot, got_fk.x.p)
    assert _programs(program_store), "nothing was stored"
    for want, got in ((want_fk, got_fk), (want_ik, got_ik)):
        for a, b in zip(jax.tree.leaves(want), jax.tree.leaves(got), strict=True):
            np.testing.assert_allclose(np.asarray(b), np.asarray(a), rtol=1e-13, atol=1e-13)


@pytest.fixture
def stored_off_first(tmp_path):
    """Results with the store off, before the store fixture turns it on."""
    robot = serial.Puma560()
    q = np.random.default_rng(1).uniform(-2.0, 2.0, (3, 6))
    return robot, q, jaxkin.fk(robot, q)


def test_a_later_trace_reads_the_program_instead_of_tracing_the_kernel(
    stored_off_first, program_store, monkeypatch
):
    robot, q, want = stored_off_first
    first = jaxkin.fk(robot, q)
    written = _programs(program_store)
    assert written
    jax.clear_caches()  # as a new process: every program is traced again

    def refuse(*args, **kwargs):
        raise AssertionError("exported again although the program was stored")

    read = store._read
    found = []

    def reading(*args):
        entry = read(*args)
        found.append(entry is not None)
        return entry

    monkeypatch.setattr(store, "_export", refuse)
    monkeypatch.setattr(store, "_read", reading)
    again = jaxkin.fk(robot, q)
    assert found and all(found)  # every program of the call came from the store
    assert _programs(program_store) == written
    for a, b, c in zip(*(jax.tree.leaves(r) for r in (want, first, again)), strict=True):
        np.testing.assert_allclose(np.asarray(b), np.asarray(a), rtol=1e-13, atol=1e-13)
        np.testing.assert_array_equal(np.asarray(c), np.asarray(b))


def test_a_damaged_or_mismatched_entry_is_traced_again(program_store):
    robot = serial.Puma560()
    q = np.full((2, 6), 0.4)
    want = jaxkin.fk(robot, q)
    (name,) = [n for n in _programs(program_store)]
    path = program_store / name
    for damage in (b"not a program", path.read_bytes()[:-100]):
        path.write_bytes(damage)
        jax.clear_caches()
        got = jaxkin.fk(robot, q)
        for a, b in zip(jax.tree.leaves(want), jax.tree.leaves(got), strict=True):
            np.testing.assert_array_equal(np.asarray(b), np.asarray(a))
        assert path.read_bytes() != damage  # written again, whole


def test_a_repeated_call_compiles_nothing_with_the_store(program_store):
    robot = serial.Puma560()
    jaxkin.fk(robot, np.full((4, 6), 0.1))
    with compilations() as count:
        jax.block_until_ready(jaxkin.fk(robot, np.full((4, 6), 0.2)))
        jax.block_until_ready(jaxkin.fk(serial.Puma560(), np.full((4, 6), 0.3)))
    assert count.n == 0, count.events


def test_collision_check_through_the_store(program_store):
    robot = serial.Planar2R(1.0, 0.8, link_radius=0.05)
    world = collision.World.create(
        spheres=collision.Spheres.create([[1.2, 0.6, 0.0], [-0.2, 1.3, 0.0]], [0.25, 0.2])
    )
    q = np.random.default_rng(2).uniform(-3.0, 3.0, (16, 2))
    store.keep_programs(False)
    want = collision.check(robot, q, world)
    store.keep_programs(True)
    jax.clear_caches()
    got = collision.check(robot, q, world)
    assert _programs(program_store)
    np.testing.assert_array_equal(np.asarray(got.collides), np.asarray(want.collides))
    np.testing.assert_allclose(
        np.asarray(got.clearance), np.asarray(want.clearance), rtol=1e-13, atol=1e-13
    )


def test_gradients_through_a_kernel_are_traced_as_usual(program_store):
    """Inside a caller's ``grad`` the kernel is traced (a serialised program has no derivative
    rules); the gradient matches central differences."""
    robot = serial.Puma560()
    q = np.full(6, 0.3)

    def height(q):
        return jaxkin.fk(robot, q).x.p[..., 2, 3]

    g = np.asarray(jax.grad(height)(jnp.asarray(q)))
    h = 1e-6
    for i in range(6):
        dq = np.zeros(6)
        dq[i] = h
        fd = (float(height(q + dq)) - float(height(q - dq))) / (2 * h)
        np.testing.assert_allclose(g[i], fd, rtol=1e-6, atol=1e-9)


def test_store_off_without_its_switch(tmp_path):
    """A JAX cache directory alone (as these tests' configuration sets) keeps no programs."""
    saved = jax.config.jax_compilation_cache_dir
    jax.config.update("jax_compilation_cache_dir", str(tmp_path))
    try:
        assert not store.keeps_programs()
        jaxkin.fk(serial.Puma560(), np.full((3, 6), 0.2))
        assert not (tmp_path / "programs").exists()
    finally:
        jax.config.update("jax_compilation_cache_dir", saved)
        jax_cache.reset_cache()


def test_without_flatbuffers_the_switch_warns_and_keeps_compiled_code_only(tmp_path, monkeypatch):
    from jaxkin._execute import cache

    saved = (
        jax.config.jax_compilation_cache_dir,
        jax.config.jax_persistent_cache_min_compile_time_secs,
    )
    monkeypatch.setattr(store, "serialisable", lambda: False)
    try:
        with pytest.warns(UserWarning, match=r"jaxkin\[cache\]"):
            cache.enable_compilation_cache(tmp_path)
        jax.clear_caches()
        jaxkin.fk(serial.Puma560(), np.full((3, 6), 0.25))
        assert not (tmp_path / "programs").exists()
    finally:
        store.keep_programs(False)
        jax.config.update("jax_compilation_cache_dir", saved[0])
        jax.config.update("jax_persistent_cache_min_compile_time_secs", saved[1])
        jax_cache.reset_cache()
