"""First calls and second processes, each timed in fresh processes (a script).

Cold: JAX's persistent compilation cache in a new empty directory (nothing compiled before);
warm: a second process with that directory (the library rows turn it on as README.md says,
``jaxkin.enable_compilation_cache(directory)``). Rows:

- ``docs``: every ``python`` block of README.md and docs/*.md run as its own script (as
  ``tests/test_docs.py`` runs them, 64-bit mode off), the slowest block's seconds;
- ``panda check``: the Panda of example-robot-data with its default body from the URDF and
  SRDF, and ``collision.check`` of one configuration among 20 obstacles;
- ``panda plan``: ``plan.evaluate(..., world=...)`` of one 20-sample pose path of the Panda
  among the same obstacles;
- ``chain ik``: the first ``jaxkin.ik`` of one pose of the Panda's chain;
- ``help``: ``jaxkin --help``.

Each figure is the wall time of the whole process from its start (imports included) unless
the row says otherwise. Prints a Markdown table (``docs/performance.md``)::

    .venv/bin/python benchmarks/first_calls.py [ROW ...]
"""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

_PANDA = """
import time, sys, pathlib, os
start = time.perf_counter()
import numpy as np, jax
import jaxkin
jaxkin.enable_compilation_cache(os.environ["JAXKIN_COMPILATION_CACHE"])  # README's one line
from jaxkin import collision, paths, plan, serial
from jaxkin.jet import Jet
root = next(p / "cmeel.prefix/share/example-robot-data/robots" for p in map(pathlib.Path, sys.path)
            if (p / "cmeel.prefix/share/example-robot-data/robots").is_dir())
robot = serial.from_urdf(root / "panda_description/urdf/panda.urdf", "panda_hand").with_srdf(
    root / "panda_description/srdf/panda.srdf"
)
rng = np.random.default_rng(3)
world = collision.World.create(
    spheres=collision.Spheres.create(rng.uniform(-0.7, 0.7, (12, 3)) + [0, 0, 0.5],
                                     rng.uniform(0.04, 0.12, 12)),
    boxes=collision.Boxes.create(rng.uniform(-0.7, 0.7, (8, 3)) + [0, 0, 0.5],
                                 rng.uniform(0.03, 0.12, (8, 3))),
)
q = np.full((1, 7), 0.3)
built = time.perf_counter()
if sys.argv[1] == "check":
    jax.block_until_ready(collision.check(robot, q, world).clearance)
else:
    qs = 0.3 + np.linspace(0.0, 0.3, 20)[:, None] * np.ones(7)
    pose = np.asarray(jaxkin.fk(robot, qs).x.p)
    quat = paths.quaternions_from_pose(Jet(pose, 0 * pose, 0 * pose))[0]
    path = paths.path_from_poses(pose[None, :, :3, 3], np.asarray(quat)[None, :, 3:], dt=0.05)
    jax.block_until_ready(plan.evaluate(robot, path, world=world).status)
print(f"BODY {built - start:.2f} CALL {time.perf_counter() - built:.2f}")
"""

_IK = """
import time
start = time.perf_counter()
import sys, pathlib, os
import numpy as np, jax
jax.config.update("jax_enable_x64", True)
import jaxkin
jaxkin.enable_compilation_cache(os.environ["JAXKIN_COMPILATION_CACHE"])  # README's one line
from jaxkin import serial
root = next(p / "cmeel.prefix/share/example-robot-data/robots" for p in map(pathlib.Path, sys.path)
            if (p / "cmeel.prefix/share/example-robot-data/robots").is_dir())
robot = serial.from_urdf(root / "panda_description/urdf/panda.urdf", "panda_hand")
x = jaxkin.fk(robot, np.full(7, 0.3)).x.p
built = time.perf_counter()
jax.block_until_ready(jaxkin.ik(robot, x).status)
print(f"BODY {built - start:.2f} CALL {time.perf_counter() - built:.2f}")
"""


def _blocks() -> list[tuple[str, int, str]]:
    fence = re.compile(r"^```python\n(.*?)^```", re.S | re.M)
    out = []
    for page in [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]:
        for k, match in enumerate(fence.finditer(page.read_text())):
            out.append((page.name, k, match.group(1)))
    return out


def _run(args: list[str], cache: Path, cwd: Path) -> tuple[float, str]:
    env = {k: v for k, v in os.environ.items() if not k.startswith(("JAX", "XDG_CACHE"))}
    env["JAX_COMPILATION_CACHE_DIR"] = str(cache)
    env["JAXKIN_COMPILATION_CACHE"] = str(cache)
    start = time.perf_counter()
    proc = subprocess.run(args, env=env, capture_output=True, text=True, cwd=cwd, timeout=1800)
    seconds = time.perf_counter() - start
    if proc.returncode:
        return seconds, "failed: " + proc.stderr.strip()[-200:]
    return seconds, proc.stdout


def _row(name: str, args: list[str], cwd: Path) -> str:
    cache = Path(tempfile.mkdtemp(prefix="jaxkin-first-calls-"))
    try:
        cold, out1 = _run(args, cache, cwd)
        warm, out2 = _run(args, cache, cwd)
    finally:
        shutil.rmtree(cache, ignore_errors=True)
    detail = ""
    for label, out in (("cold", out1), ("warm", out2)):
        found = re.search(r"BODY ([\d.]+) CALL ([\d.]+)", out)
        if found:
            detail += f"{label}: body {found.group(1)} s, call {found.group(2)} s; "
        elif out.startswith("failed"):
            detail += f"{label} {out}; "
    return f"| {name} | {cold:.2f} | {warm:.2f} | {detail.strip()} | {os.getloadavg()[0]:.1f} |"


def main(argv: list[str]) -> None:
    python = sys.executable
    command = shutil.which("jaxkin", path=str(Path(python).parent)) or "jaxkin"
    rows = {
        "help": lambda: [_row("jaxkin --help", [command, "--help"], ROOT)],
        "chain ik": lambda: [_row("chain first IK (Panda)", [python, "-c", _IK], ROOT)],
        "panda check": lambda: [
            _row("Panda check, default body, 20 obstacles", [python, "-c", _PANDA, "check"], ROOT)
        ],
        "panda plan": lambda: [
            _row("Panda plan.evaluate(world)", [python, "-c", _PANDA, "plan"], ROOT)
        ],
        "docs": _docs_rows,
    }
    chosen = argv or list(rows)
    print("| process | cold (s) | warm (s) | detail | load (1 min) |")
    print("| --- | --- | --- | --- | --- |")
    for name in chosen:
        for line in rows[name]():
            print(line, flush=True)


def _docs_rows() -> list[str]:
    """One row: the slowest documentation block, cold and warm (each block a process of its
    own in a scratch directory, as a reader would run them in order)."""
    work = Path(tempfile.mkdtemp(prefix="jaxkin-docs-"))
    worst = (0.0, 0.0, "")
    try:
        for page, k, code in _blocks():
            script = work / f"{page}-{k}.py"
            script.write_text(code)
            cache = Path(tempfile.mkdtemp(prefix="jaxkin-first-calls-"))
            env_args = [sys.executable, str(script)]
            cold, _ = _run(env_args, cache, work)
            warm, _ = _run(env_args, cache, work)
            shutil.rmtree(cache, ignore_errors=True)
            if cold > worst[0]:
                worst = (cold, warm, f"{page} block {k}")
    finally:
        shutil.rmtree(work, ignore_errors=True)
    cold, warm, where = worst
    load = os.getloadavg()[0]
    return [f"| slowest docs block ({where}) | {cold:.2f} | {warm:.2f} | | {load:.1f} |"]


if __name__ == "__main__":
    main(sys.argv[1:])
