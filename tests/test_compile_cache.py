"""The persistent compilation cache: one library call turns it on, the command turns it on by
default, ``JAXKIN_COMPILATION_CACHE`` turns it off or moves it, importing jaxkin never does.

Each in-process test restores JAX's cache settings (the test configuration sets its own
cache directory) so no other test sees a change."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from jax.experimental.compilation_cache import compilation_cache as jax_cache

import jaxkin
from jaxkin._execute import cache as _compile_cache

from .helpers import script_line


@pytest.fixture
def restore_jax_cache():
    saved = (
        jax.config.jax_compilation_cache_dir,
        jax.config.jax_persistent_cache_min_compile_time_secs,
    )
    yield
    jax.config.update("jax_compilation_cache_dir", saved[0])
    jax.config.update("jax_persistent_cache_min_compile_time_secs", saved[1])
    jax_cache.reset_cache()


def _entries(directory: Path) -> list[str]:
    return sorted(os.listdir(directory)) if directory.exists() else []


def test_enable_writes_compiled_programs_to_the_directory(tmp_path, restore_jax_cache):
    directory = jaxkin.enable_compilation_cache(tmp_path / "cache", min_compile_time_secs=0.0)
    assert directory == tmp_path / "cache" and _entries(directory) == []
    # A program no other test compiles (its constant), so it cannot come from another cache.
    jax.block_until_ready(jax.jit(lambda x: jnp.sin(x) * 2.718281 + 0.577215)(jnp.ones(3)))
    assert _entries(directory), "no compiled program was written"


def test_default_directory_follows_xdg_cache_home(monkeypatch, tmp_path):
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    assert _compile_cache.default_cache_dir() == tmp_path / "jaxkin"
    monkeypatch.delenv("XDG_CACHE_HOME")
    assert _compile_cache.default_cache_dir() == Path.home() / ".cache" / "jaxkin"


@pytest.mark.parametrize(
    ("setting", "expected"), [(None, "xdg/jaxkin"), ("", "xdg/jaxkin"), ("0", None),
                              ("off", None), ("elsewhere", "elsewhere")]
)  # fmt: skip
def test_command_default_and_environment(
    monkeypatch, tmp_path, restore_jax_cache, setting, expected
):
    jax.config.update("jax_compilation_cache_dir", None)
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    if setting is None:
        monkeypatch.delenv(_compile_cache.ENV_VAR, raising=False)
    else:
        monkeypatch.setenv(_compile_cache.ENV_VAR, setting)
    monkeypatch.chdir(tmp_path)
    used = _compile_cache.enable_for_command()
    if expected is None:
        assert used is None and jax.config.jax_compilation_cache_dir is None
    else:
        assert used.resolve() == tmp_path / expected
        assert Path(jax.config.jax_compilation_cache_dir).resolve() == (tmp_path / expected)


def test_command_keeps_a_cache_directory_set_for_jax(monkeypatch, tmp_path, restore_jax_cache):
    jax.config.update("jax_compilation_cache_dir", str(tmp_path / "mine"))
    monkeypatch.delenv(_compile_cache.ENV_VAR, raising=False)
    assert _compile_cache.enable_for_command() == tmp_path / "mine"
    assert jax.config.jax_compilation_cache_dir == str(tmp_path / "mine")


def test_bad_arguments_raise_value_error_naming_them(tmp_path, restore_jax_cache):
    (tmp_path / "file").write_text("not a directory")
    with pytest.raises(ValueError, match="path"):
        jaxkin.enable_compilation_cache(tmp_path / "file")
    with pytest.raises(ValueError, match="min_compile_time_secs"):
        jaxkin.enable_compilation_cache(tmp_path / "ok", min_compile_time_secs=-1.0)


@pytest.mark.slow
def test_console_script_fills_the_cache_unless_turned_off(tmp_path):
    """Fresh processes of the installed ``jaxkin`` script: the user's cache directory gets
    entries by default and none with ``JAXKIN_COMPILATION_CACHE=0``; importing jaxkin alone
    leaves JAX's cache off."""
    exe = shutil.which("jaxkin", path=str(Path(sys.executable).parent))
    assert exe is not None, "the jaxkin console script is not installed"
    t = np.linspace(0.0, 2.0, 20)
    xyz = np.c_[t, 100 + 20 * np.sin(t), -20 * np.cos(t), 50 + 10 * t]  # mm, in reach
    np.savetxt(tmp_path / "in.csv", xyz, delimiter=",", header="t,x,y,z", comments="")
    argv = [exe, "ik", "scara", "--robot", "paper", "-i", "in.csv", "-o", "out.csv"]
    env = {k: v for k, v in os.environ.items() if not k.startswith(("JAX", "XDG_CACHE"))}
    for name, extra in (("on", {}), ("off", {_compile_cache.ENV_VAR: "0"})):
        home = tmp_path / name
        run_env = {**env, "XDG_CACHE_HOME": str(home), **extra}
        proc = subprocess.run(
            argv, capture_output=True, text=True, timeout=300, cwd=tmp_path, env=run_env
        )
        assert proc.returncode == 0, proc.stderr
        found = _entries(home / "jaxkin")
        assert found if name == "on" else not found, (name, found)
    probe = "import jax, jaxkin; print(jax.config.jax_compilation_cache_dir)"
    proc = subprocess.run(
        [sys.executable, "-c", probe], capture_output=True, text=True, timeout=120, env=env
    )
    assert proc.stdout.strip() == "None", proc.stderr


_COUNTING_RUN = """
import sys
import jax.monitoring
import jaxkin.cli
counts = {"hits": 0, "misses": 0, "exports": 0}
def listen(event, **kwargs):
    for name in ("hits", "misses"):
        if event == "/jax/compilation_cache/cache_" + name:
            counts[name] += 1
jax.monitoring.register_event_listener(listen)
import jaxkin._execute.store as store
export = store._export
def counted(*args):  # the store traces a kernel only to export it
    counts["exports"] += 1
    return export(*args)
store._export = counted
code = jaxkin.cli.main(sys.argv[1:])
print("COUNTS", counts["hits"], counts["misses"], counts["exports"])
sys.exit(code)
"""


@pytest.mark.slow
def test_second_command_run_compiles_nothing(tmp_path):
    """The command's cache keeps every program it compiles: a second run of the same command
    on another file of the same length loads each program (cache hits) and compiles none,
    and finds its kernels in the program store (it traces none of them to export it)."""
    t = np.linspace(0.0, 2.0, 20)
    env = {k: v for k, v in os.environ.items() if not k.startswith(("JAX", "XDG_CACHE"))}
    env["XDG_CACHE_HOME"] = str(tmp_path / "home")
    counts = []
    for run, phase in enumerate((0.0, 0.3)):
        xyz = np.c_[t, 100 + 20 * np.sin(t + phase), -20 * np.cos(t), 50 + 10 * t]
        np.savetxt(tmp_path / "in.csv", xyz, delimiter=",", header="t,x,y,z", comments="")
        argv = ["ik", "scara", "--robot", "paper", "-q", "-i", "in.csv", "-o", f"out{run}.csv"]
        counted = script_line(_COUNTING_RUN, "COUNTS", tmp_path, env, *argv)
        counts.append(tuple(int(x) for x in counted))
    (_, first_misses, first_exports), (second_hits, second_misses, second_exports) = counts
    assert first_misses > 0 and second_hits > 0 and first_exports > 0
    assert second_misses == 0 and second_exports == 0, counts
    assert list((tmp_path / "home" / "jaxkin" / "programs").glob("*.program"))


_BOUNDARY_RUN = """
import jax
from jax import monitoring

jax.config.update("jax_enable_x64", True)

compiled = []
monitoring.register_event_duration_secs_listener(
    lambda event, duration, **kw: compiled.append(str(kw.get("fun_name", "")))
    if event == "/jax/core/compile/backend_compile_duration"
    else None
)
import numpy as np

from jaxkin import collision, motion, paths, plan, serial

robot = serial.Planar2R(1.0, 0.8, link_radius=0.05)
world = collision.World.create(
    spheres=collision.Spheres.create([[1.2, 0.6, 0.0]], 0.25),
    capsules=collision.Capsules.create([[-0.2, 1.3, -0.2]], [[-0.2, 1.3, 0.2]], 0.15),
)
small = dict(lanes=2, capacity=256, path_points=32, spline_states=256, grid=64)
result = motion.plan(robot, np.array([0.0, 0.3]), world, goal=np.array([2.5, 0.4]), **small)
assert result.solved[0]
collision.check(robot, np.zeros((3, 2)), world.astype(np.float32))
way = np.array([[[0.0, 0.3], [0.5, 0.2], [1.0, 0.1]]])
limits = plan.Limits.create(2, v_max=[2.0, 2.0], a_max=[8.0, 8.0])
path = paths.path_from_joint_waypoints(way, 0.05, 10)
plan.retime(plan.evaluate(robot, path, limits, world=world))
print("COMPILED", " ".join(compiled))
"""


@pytest.mark.slow  # a fresh process planning a motion: the fast tier is near its 5 minutes
def test_a_fresh_process_compiles_only_the_library_s_kernels(tmp_path):
    """The boundary work (worlds and bodies made and converted, a robot's size, the motion
    bound, the planner's limits, paths, the timing's inputs) is done on the host: a fresh
    process that plans a motion, checks a world and evaluates and retimes a path compiles its
    kernels and no eager JAX operation (each of which a fresh process would compile again)."""
    env = dict(os.environ, JAX_COMPILATION_CACHE_DIR=jax.config.jax_compilation_cache_dir)
    names = script_line(_BOUNDARY_RUN, "COMPILED", tmp_path, env)
    functions = [name.removeprefix("jit(").removesuffix(")") for name in names]
    operations = set(dir(jax.lax)) | set(dir(jnp)) | {"stage"}
    eager = [f for f in functions if f.strip("_").replace("-", "_") in operations]
    assert {"search_kernel", "check_kernel", "_evaluate_impl", "_retime"} <= set(functions)
    assert not eager, eager
