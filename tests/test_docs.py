"""Every code block of README.md and of the documentation site runs as written.

``python`` blocks run in a fresh namespace in a temporary directory. ``console`` blocks hold
shell commands: ``jaxkin ...`` lines run through the command line's entry point in the same
directory (where ``spiral.csv``, the spiral of [Noriega, eq. 16] in mm, is provided as the
trajectory file the examples name, and ``arm.urdf`` with ``arm_joints.csv`` for the URDF
arm of ``docs/urdf.md``), and ``make TARGET`` lines must name a target of the
Makefile (running them here would install and test recursively; CI runs them). ``bash`` blocks
are cluster job scripts (SLURM's ``srun`` is not on this machine): they must parse
(``bash -n``), and every ``jaxkin`` command in them must parse with the command line's own
argument parser. Any other fenced block language, or another command in a console block,
fails: a block that cannot be checked is not allowed.
"""

from __future__ import annotations

import re
import shlex
import subprocess
import sys
import types
from pathlib import Path

import numpy as np
import pytest

from jaxkin import cli
from jaxkin.cli.parser import build_parser

ROOT = Path(__file__).resolve().parents[1]
PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").rglob("*.md"))]
FENCE = re.compile(r"^```(\w*)\n(.*?)^```", re.S | re.M)
RUNNABLE = {"python", "console", "bash"}


def blocks() -> list[tuple[str, int, str, str]]:
    """(page, block number, language, code) for every fenced block."""
    found = []
    for page in PAGES:
        text = page.read_text(encoding="utf-8")
        for number, match in enumerate(FENCE.finditer(text)):
            found.append((str(page.relative_to(ROOT)), number, match.group(1), match.group(2)))
    return found


BLOCKS = blocks()


def test_pages_exist_and_have_blocks():
    assert (ROOT / "docs" / "index.md").exists() and (ROOT / "mkdocs.yml").exists()
    assert sum(lang == "python" for _, _, lang, _ in BLOCKS) >= 8


@pytest.mark.parametrize("language", sorted({lang for _, _, lang, _ in BLOCKS}))
def test_every_block_language_is_runnable(language):
    assert language in RUNNABLE, f"a ```{language} block cannot run under test"


def make_targets() -> set[str]:
    text = (ROOT / "Makefile").read_text()
    return set(re.findall(r"^([\w-]+):", text, re.M))


def spiral_csv(path: Path) -> None:
    t = np.linspace(0.0, 8.0, 201)
    w = np.pi / 2
    xyz = np.c_[100 + 20 * np.sin(w * t), -20 * np.cos(w * t), 50 + 10 * t]
    np.savetxt(path, np.c_[t, xyz], delimiter=",", header="t,x,y,z", comments="")


def arm_files(path: Path) -> None:
    """``arm.urdf`` (the three-joint arm of docs/urdf.md) and ``arm_joints.csv``."""
    page = (ROOT / "docs" / "urdf.md").read_text(encoding="utf-8")
    (path / "arm.urdf").write_text(re.search(r'URDF = """(.*?)"""', page, re.S).group(1))
    t = np.linspace(0.0, 1.0, 21)
    joints = np.c_[t, 0.5 + t, 0.3 - 0.5 * t, 1.2 + 0.3 * t]
    np.savetxt(path / "arm_joints.csv", joints, delimiter=",", header="t,turn,shoulder,elbow",
               comments="")  # fmt: skip


# Blocks that plan, optimise or solve URDF arms (each compiles for seconds): the slow tier.
SLOW_BLOCKS = {"docs/planning.md-1", "docs/urdf.md-1", "docs/cli.md-1"}


def _runnable_blocks() -> list:
    cases = []
    for block in BLOCKS:
        if block[2] in RUNNABLE:
            name = f"{block[0]}-{block[1]}"
            slow = pytest.mark.slow if name in SLOW_BLOCKS else ()
            cases.append(pytest.param(*block, id=name, marks=slow))
    return cases


@pytest.mark.parametrize("page, number, language, code", _runnable_blocks())
def test_block_runs(page, number, language, code, tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    if language == "python":
        # A module of its own: dataclasses defined in a block look their module up.
        module = types.ModuleType("__docs__")
        monkeypatch.setitem(sys.modules, module.__name__, module)
        exec(compile(code, f"{page} block {number}", "exec"), module.__dict__)
        return
    if language == "bash":
        subprocess.run(["bash", "-n"], input=code, text=True, check=True)
        parser = build_parser()
        launched = re.compile(r"^\s*(?:srun(?:\s+-\S+)*\s+)?jaxkin\s+(.*)$")
        commands = [m.group(1) for m in map(launched.match, code.splitlines()) if m]
        assert commands, f"{page}: a job script must run jaxkin"
        for command in commands:
            parser.parse_args(shlex.split(command, comments=True))  # SystemExit 2 if unknown
        return
    spiral_csv(tmp_path / "spiral.csv")
    arm_files(tmp_path)
    targets = make_targets()
    for line in code.splitlines():
        command = shlex.split(line, comments=True)
        if not command:
            continue
        if command[0] == "make":
            assert set(command[1:]) <= targets, line
        else:
            assert command[0] == "jaxkin", f"{page}: only jaxkin and make commands run: {line}"
            assert cli.main(command[1:]) == 0, line
