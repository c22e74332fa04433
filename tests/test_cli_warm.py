"""The command's second run: executables kept in the cache directory and loaded without
tracing (``jaxkin._compile_cache.stored_jit``), with every unreadable entry compiled again.

The in-process tests use a small function of their own and turn the store off after; the
slow test runs the installed command twice in fresh processes."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxkin
from jaxkin import _compile_cache, paths, serial
from jaxkin.jet import Jet

ROOT = Path(__file__).resolve().parents[1]


def _affine(x, y):
    """A program no other test compiles (its constants)."""
    return {"sum": jnp.sin(x) * 1.6180339 + y, "max": jnp.max(x)}


def _scaled(x, power):
    return x**power + 0.1234567


def _plain(x):
    return x * 2.7182818 - 0.31830988


# These functions are never called through a plain ``jax.jit`` while the store is on: a
# program this process already holds from JAX's persistent cache cannot be written again
# (its entry is then left out, and these tests count entries).


@pytest.fixture
def store(tmp_path):
    directory = _compile_cache.enable_store(tmp_path / "executables")
    yield directory
    _compile_cache.enable_store(None)


@pytest.fixture
def events():
    """Counts of the store's ``jax.monitoring`` events during the test."""
    counts = {"load": 0, "compile": 0}

    def listen(event, **kwargs):
        for name in counts:
            if event == f"/jaxkin/executable_store/{name}":
                counts[name] += 1

    jax.monitoring.register_event_listener(listen)
    yield counts
    jax.monitoring.unregister_event_listener(listen)


def _args():
    return np.linspace(-1.0, 2.0, 7), np.float64(0.5)


def _expected():
    x, y = _args()
    return {"sum": np.sin(x) * 1.6180339 + y, "max": np.max(x)}


def test_stored_program_is_loaded_with_the_same_results(store, events):
    first = _compile_cache.stored_jit(_affine)(*_args())
    assert events == {"load": 0, "compile": 1} and len(list(store.iterdir())) == 1
    # A new instance (as in a new process) loads the executable instead of compiling.
    second = _compile_cache.stored_jit(_affine)(*_args())
    assert events == {"load": 1, "compile": 1}
    for name, expected in _expected().items():
        np.testing.assert_allclose(np.asarray(first[name]), expected, rtol=1e-15, atol=1e-15)
        np.testing.assert_array_equal(np.asarray(second[name]), np.asarray(first[name]))
    # Another shape is another program.
    _compile_cache.stored_jit(_affine)(np.ones(3), np.float64(0.0))
    assert events["compile"] == 2 and len(list(store.iterdir())) == 2


@pytest.mark.parametrize("damage", ["garbage", "truncated", "another program"])
def test_corrupt_or_stale_entry_compiles_again(store, events, damage):
    expected = np.asarray(_compile_cache.stored_jit(_affine)(*_args())["sum"])
    (entry,) = store.iterdir()
    if damage == "garbage":
        entry.write_bytes(b"not an executable")
    elif damage == "truncated":
        entry.write_bytes(entry.read_bytes()[:-1000])
    else:  # a valid entry of a program with other arguments, under this key
        _compile_cache.stored_jit(_scaled, static_argnames=("power",))(np.ones(2), power=2)
        other = next(p for p in store.iterdir() if p != entry)
        shutil.copyfile(other, entry)
    got = _compile_cache.stored_jit(_affine)(*_args())
    np.testing.assert_array_equal(np.asarray(got["sum"]), expected)
    np.testing.assert_allclose(expected, _expected()["sum"], rtol=1e-15, atol=1e-15)
    assert events["load"] == 0
    # The entry was written again: the next instance loads it.
    _compile_cache.stored_jit(_affine)(*_args())
    assert events["load"] == 1


def test_static_arguments_and_tracers(store, events):
    fn = _compile_cache.stored_jit(_scaled, static_argnames=("power",))
    x = np.linspace(0.0, 1.0, 5)
    for power in (2, 3):
        np.testing.assert_array_equal(np.asarray(fn(x, power)), x**power + 0.1234567)
    assert events["compile"] == 2
    # Under a transformation the plain jit runs (nothing stored).
    grad = jax.grad(lambda y: fn(y, power=2).sum())(x)
    np.testing.assert_allclose(np.asarray(grad), 2 * x, rtol=1e-15)
    assert events["compile"] == 2 and len(list(store.iterdir())) == 2


def test_off_by_environment_or_for_a_directory_set_for_jax(monkeypatch, tmp_path, events):
    saved = jax.config.jax_compilation_cache_dir
    try:
        monkeypatch.setenv(_compile_cache.ENV_VAR, "0")
        assert _compile_cache.enable_for_command() is None
        assert _compile_cache.store_directory() is None
        np.testing.assert_allclose(np.asarray(_compile_cache.stored_jit(_plain)(1.0)), 2.39997192)
        assert events == {"load": 0, "compile": 0}  # the plain jit
        monkeypatch.delenv(_compile_cache.ENV_VAR)
        jax.config.update("jax_compilation_cache_dir", str(tmp_path / "jax"))
        assert _compile_cache.enable_for_command() == tmp_path / "jax"
        assert _compile_cache.store_directory() is None
    finally:
        _compile_cache.enable_store(None)
        jax.config.update("jax_compilation_cache_dir", saved)


_COUNTING_RUN = """
import sys
import jax.monitoring
import jaxkin.cli
counts = {"traced": 0, "compiled": 0, "loaded": 0, "missed": 0}
def duration(event, seconds, **kwargs):
    if event == "/jax/core/compile/jaxpr_trace_duration":
        counts["traced"] += 1
    if event == "/jax/core/compile/backend_compile_duration":
        counts["compiled"] += 1
def listen(event, **kwargs):
    if event == "/jaxkin/executable_store/load":
        counts["loaded"] += 1
    if event == "/jax/compilation_cache/cache_misses":
        counts["missed"] += 1
jax.monitoring.register_event_duration_secs_listener(duration)
jax.monitoring.register_event_listener(listen)
code = jaxkin.cli.main(sys.argv[1:])
print("COUNTS", counts["traced"], counts["compiled"], counts["loaded"], counts["missed"])
sys.exit(code)
"""


def _counted_run(tmp_path, env, argv):
    proc = subprocess.run(
        [sys.executable, "-c", _COUNTING_RUN, *argv],
        capture_output=True,
        text=True,
        timeout=900,
        cwd=tmp_path,
        env=env,
    )
    assert proc.returncode == 0, proc.stderr
    line = next(x for x in proc.stdout.splitlines() if x.startswith("COUNTS"))
    return tuple(int(x) for x in line.split()[1:])


@pytest.mark.slow
def test_second_run_traces_nothing_and_writes_the_same_bytes(tmp_path):
    """Two fresh processes of the command with one cache directory, a URDF arm (each row on
    its own) and a SCARA path: the second run loads the stored executables and compiles
    nothing anew (the URDF run traces nothing), and writes byte-identical files; with the
    cache off a third run writes the same bytes again."""
    arm = serial.from_urdf(str(ROOT / "examples" / "ur5.urdf"), "tool0")
    q = np.random.default_rng(3).uniform(-2.0, 2.0, (20, arm.n_joints))
    pose = np.asarray(jaxkin.fk(arm, q).x.p)
    rows = np.asarray(paths.quaternions_from_pose(Jet(pose, 0 * pose, 0 * pose))[0])
    np.savetxt(tmp_path / "poses.csv", rows, delimiter=",", header="x,y,z,qw,qx,qy,qz", comments="")
    t = np.linspace(0.0, 2.0, 20)
    xyz = np.c_[t, 100 + 20 * np.sin(t), -20 * np.cos(t), 50 + 10 * t]  # mm, in reach
    np.savetxt(tmp_path / "path.csv", xyz, delimiter=",", header="t,x,y,z", comments="")
    commands = {
        "urdf": ["ik", "urdf", "--robot", str(ROOT / "examples" / "ur5.urdf"), "--tip", "tool0"],
        "scara": ["ik", "scara", "--robot", "paper"],
    }
    env = {k: v for k, v in os.environ.items() if not k.startswith(("JAX", "XDG_CACHE"))}
    env[_compile_cache.ENV_VAR] = str(tmp_path / "cache")
    for name, source in (("urdf", "poses.csv"), ("scara", "path.csv")):
        argv = [*commands[name], "-q", "-i", source]
        first = _counted_run(tmp_path, env, [*argv, "-o", f"{name}1.csv"])
        second = _counted_run(tmp_path, env, [*argv, "-o", f"{name}2.csv"])
        assert first[0] > 0 and first[1] > 0, first
        # Kernels loaded, nothing compiled anew; the URDF run traces nothing at all (the path
        # mode still converts one input with jnp.asarray: a program traced and loaded).
        assert second[2] > 0 and second[3] == 0, (name, first, second)
        if name == "urdf":
            assert second[0] == 0 and second[1] == 0, (name, first, second)
        written = [(tmp_path / f"{name}{k}.csv").read_bytes() for k in (1, 2)]
        assert written[0] == written[1], name
        off = {**env, _compile_cache.ENV_VAR: "0"}
        third = _counted_run(tmp_path, off, [*argv, "-o", f"{name}3.csv"])
        assert third[2] == 0 and (tmp_path / f"{name}3.csv").read_bytes() == written[0], name
    assert sorted(os.listdir(tmp_path / "cache" / "executables"))


_LAPACK_PROGRAM = """
import sys
import jax, jax.numpy as jnp
from jaxkin import _compile_cache

def damped_solve(a, b):
    return jax.scipy.linalg.cho_solve(jax.scipy.linalg.cho_factor(a @ a.T + jnp.eye(3)), b)

_compile_cache.enable_store(sys.argv[1])
a = jnp.arange(9.0, dtype=jnp.float32).reshape(3, 3) / 10
print(_compile_cache.stored_jit(damped_solve)(a, jnp.ones(3, jnp.float32)).tolist())
"""


def test_a_program_calling_lapack_loads_in_a_fresh_process(tmp_path):
    """LAPACK's entry points are set up when JAX lowers a linear-algebra call; a process
    that only loads a stored program calling LAPACK (a linear-algebra call) must set
    them up itself, or the call crashes the interpreter. Both runs print NumPy's solution."""
    a = np.arange(9.0).reshape(3, 3) / 10
    expected = np.linalg.solve(a @ a.T + np.eye(3), np.ones(3))
    env = {**os.environ, "JAX_ENABLE_X64": "0", "JAX_PLATFORMS": "cpu"}
    store = tmp_path / "executables"
    for run in ("compiled", "loaded"):
        done = subprocess.run(
            [sys.executable, "-c", _LAPACK_PROGRAM, str(store)],
            capture_output=True,
            text=True,
            env=env,
            timeout=120,
        )
        assert done.returncode == 0, (run, done.returncode, done.stderr[-2000:])
        np.testing.assert_allclose(json.loads(done.stdout), expected, rtol=1e-5)
    assert len(list(store.glob("*.exe"))) == 1
