"""The command's second run: every program comes back from JAX's persistent compilation
cache (the command keeps every program it compiles), nothing is compiled anew, and the files
written are byte for byte those of the first run (and of a run with the cache off)."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest

import jaxkin
from jaxkin import paths, serial
from jaxkin._execute import cache
from jaxkin.jet import Jet

from .helpers import script_line

ROOT = Path(__file__).resolve().parents[1]

_COUNTING_RUN = """
import sys
import jax.monitoring
import jaxkin.cli
counts = {"hits": 0, "misses": 0}
def listen(event, **kwargs):
    for name in counts:
        if event == "/jax/compilation_cache/cache_" + name:
            counts[name] += 1
jax.monitoring.register_event_listener(listen)
code = jaxkin.cli.main(sys.argv[1:])
print("COUNTS", counts["hits"], counts["misses"])
sys.exit(code)
"""


def _counted_run(tmp_path, env, argv):
    return tuple(int(x) for x in script_line(_COUNTING_RUN, "COUNTS", tmp_path, env, *argv))


@pytest.mark.slow
def test_second_run_compiles_nothing_and_writes_the_same_bytes(tmp_path):
    """Two fresh processes of the command with one cache directory, a URDF arm (each row on
    its own) and a SCARA path: the second run finds every program in the cache (hits, no
    miss) and writes byte-identical files; with the cache off a third run writes the same
    bytes again."""
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
    env[cache.ENV_VAR] = str(tmp_path / "cache")
    for name, source in (("urdf", "poses.csv"), ("scara", "path.csv")):
        argv = [*commands[name], "-q", "-i", source]
        first = _counted_run(tmp_path, env, [*argv, "-o", f"{name}1.csv"])
        second = _counted_run(tmp_path, env, [*argv, "-o", f"{name}2.csv"])
        assert first[1] > 0, first
        assert second[0] > 0 and second[1] == 0, (name, first, second)
        written = [(tmp_path / f"{name}{k}.csv").read_bytes() for k in (1, 2)]
        assert written[0] == written[1], name
        off = {**env, cache.ENV_VAR: "0"}
        third = _counted_run(tmp_path, off, [*argv, "-o", f"{name}3.csv"])
        assert third == (0, 0) and (tmp_path / f"{name}3.csv").read_bytes() == written[0], name
