"""``jaxkin.enable_low_latency``: JAX's CPU runtime set for a planner's loop of single queries.

The options take effect only in a process whose JAX has not started, so the checks that need
them run in a fresh interpreter; what can be checked in this one (the one-trip loop, the
environment's handling) is checked here (``conftest`` puts both options back after each
test).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

from jaxkin._execute import latency

ROOT = Path(__file__).resolve().parents[1]

# A fresh process: low latency on, then the UR5's verdict, check and edge handles against the
# public calls on the same inputs (float64), and whether XLA made each program one function.
_PROBE = r"""
import json, os, sys
import jaxkin
jaxkin.enable_low_latency()
import jax
jax.config.update("jax_enable_x64", True)
import numpy as np
from jaxkin import collision, serial
robot = serial.from_urdf(sys.argv[1], "tool0").with_link_radius(0.04)
rng = np.random.default_rng(0)
world = collision.World.create(
    spheres=collision.Spheres.create(rng.uniform(-0.8, 0.8, (6, 3)), rng.uniform(0.05, 0.15, 6)),
    halfspaces=collision.HalfSpaces.create([[0.0, 0.0, 1.0]], [-0.6]),
)
q = rng.uniform(-3.0, 3.0, (64, 6))


def ik_report():
    from jaxkin import scara
    arm = scara.Scara.paper()
    x = np.array([[60.0, 70.0, 40.0], [500.0, 0.0, 40.0], [np.nan, 1.0, 2.0], [90, 0, 50]])
    ik = jaxkin.compiled(jaxkin.ik, arm, batch=4, dtype=np.float64)(x)
    fk = jaxkin.compiled(jaxkin.fk, arm, batch=4, dtype=np.float64)(np.nan_to_num(ik.q.p))
    want_ik, want_fk = jaxkin.ik(arm, x), jaxkin.fk(arm, np.nan_to_num(ik.q.p))
    gap = lambda a, b: float(np.nanmax(np.abs(np.asarray(a) - np.asarray(b))))
    return {
        "status": np.asarray(ik.status).tolist(),
        "want_status": np.asarray(want_ik.status).tolist(),
        "q_gap": gap(ik.q.p, want_ik.q.p) / float(arm.length_scale()),
        "x_gap": gap(fk.x.p, want_fk.x.p) / float(arm.length_scale()),
    }


state = jaxkin.compiled(collision.collides, robot, world, batch=(), dtype=np.float64)
edge = jaxkin.compiled(collision.validate_motions, robot, world, 8.0, 16, batch=1,
                       dtype=np.float64)
verdicts = [bool(state(x).collides) for x in q]
ends = q[:32] + rng.uniform(-0.3, 0.3, (32, 6))
valid = [bool(edge(a[None], b[None]).valid[0]) for a, b in zip(q[:32], ends)]
print(json.dumps({
    "async": bool(jax.config.read("jax_cpu_enable_async_dispatch")),
    "flags": os.environ.get("XLA_FLAGS", ""),
    "verdicts": verdicts,
    "public": np.asarray(collision.check(robot, q, world).collides).tolist(),
    "valid": valid,
    "public_valid": np.asarray(
        collision.validate_motions(robot, q[:32], ends, world, 8.0, samples=16).valid
    ).tolist(),
    "one_function": [
        'xla_cpu_small_call="true"' in h.compiled.as_text() for h in (state, edge)
    ],
    "ik": ik_report(),
}))
"""


def test_handles_run_as_one_function_with_the_public_results():
    """In a fresh process after ``enable_low_latency()``: JAX's dispatch is inline, XLA's
    small-loop threshold raised, each handle's program compiled as one function (XLA's
    small-call mark in its HLO), and the state and edge handles' verdicts equal
    ``collision.check`` and ``collision.validate_motions`` on the same 64 states and 32
    short edges (some colliding, some free)."""
    env = {k: v for k, v in os.environ.items() if k not in ("XLA_FLAGS", latency.ENV_VAR)}
    proc = subprocess.run(
        [sys.executable, "-c", _PROBE, str(ROOT / "examples" / "ur5.urdf")],
        capture_output=True,
        text=True,
        timeout=300,
        env=env,
        cwd=ROOT,
    )
    assert proc.returncode == 0, proc.stderr[-3000:]
    out = json.loads(proc.stdout.strip().splitlines()[-1])
    assert out["async"] is False
    assert f"{latency.THRESHOLD_OPTION}={latency.SMALL_LOOP_BYTES}" in out["flags"]
    assert out["one_function"] == [True, True]
    assert out["verdicts"] == out["public"]
    assert 0 < sum(out["verdicts"]) < 64
    assert out["valid"] == out["public_valid"]
    assert 0 < sum(out["valid"]) < 32
    ik = out["ik"]  # SCARA IK and FK handles against jaxkin.ik / jaxkin.fk, to 4 ulp
    assert ik["status"] == ik["want_status"] and len(set(ik["status"])) > 1
    assert ik["q_gap"] <= 4 * np.finfo(np.float64).eps
    assert ik["x_gap"] <= 4 * np.finfo(np.float64).eps


def test_options_from_the_environment_are_kept(monkeypatch):
    """An ``XLA_FLAGS`` that already gives backend options is left as it is; others get the
    threshold appended; ``JAXKIN_LOW_LATENCY=0`` (or off, false, no) turns the command's
    default off and changes nothing."""
    given = "--xla_backend_extra_options=some_option=1"
    monkeypatch.setenv("XLA_FLAGS", given)
    latency.enable_low_latency()
    assert os.environ["XLA_FLAGS"] == given
    monkeypatch.setenv("XLA_FLAGS", "--xla_cpu_enable_fast_math=false")
    latency.enable_low_latency()
    assert os.environ["XLA_FLAGS"] == (
        "--xla_cpu_enable_fast_math=false --xla_backend_extra_options="
        f"{latency.THRESHOLD_OPTION}={latency.SMALL_LOOP_BYTES}"
    )
    for off in ("0", "off", "False", " no "):
        monkeypatch.setenv(latency.ENV_VAR, off)
        monkeypatch.setenv("XLA_FLAGS", "")
        jax.config.update("jax_cpu_enable_async_dispatch", True)
        assert latency.enable_for_command() is False
        assert os.environ["XLA_FLAGS"] == ""
        assert jax.config.read("jax_cpu_enable_async_dispatch")
    monkeypatch.setenv(latency.ENV_VAR, "")
    assert latency.enable_for_command() is True
    assert latency.small_loops_in_one_function()


def test_one_trip_loop_gives_the_function_outputs(monkeypatch):
    """``in_one_loop(fn)``: ``fn`` itself without the raised threshold; with it, one
    ``while`` around ``fn`` whose outputs equal ``fn``'s for pytrees of floats, integers and
    booleans, also when the first float is NaN (two trips); arguments without a float (or
    empty) call ``fn`` directly."""

    def fn(x, pair):
        k, flag = pair
        return {"y": jnp.sin(x) * k, "z": jnp.where(flag, x.sum(), -1.0), "k": k + 1}

    monkeypatch.setenv("XLA_FLAGS", "")
    assert latency.in_one_loop(fn) is fn
    monkeypatch.setenv("XLA_FLAGS", f"--xla_backend_extra_options={latency.THRESHOLD_OPTION}=9")
    wrapped = latency.in_one_loop(fn)
    pair = (np.int32(3), np.array([True, False]))
    for x in (np.linspace(0.0, 1.0, 5), np.array([np.nan, 1.0, 2.0, 3.0, 4.0])):
        want = jax.jit(fn)(x, pair)
        got = jax.jit(wrapped)(x, pair)
        for a, b in zip(jax.tree.leaves(got), jax.tree.leaves(want), strict=True):
            np.testing.assert_array_equal(np.asarray(a), np.asarray(b))
    assert "while" in str(jax.make_jaxpr(wrapped)(np.ones(5), pair))

    def count(k):
        return k * 2

    assert "while" not in str(jax.make_jaxpr(latency.in_one_loop(count))(np.int32(2)))
    assert "while" not in str(jax.make_jaxpr(latency.in_one_loop(jnp.sum))(np.ones(0)))
