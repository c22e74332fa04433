"""Every code block of README.md and of the documentation site runs as a user would run it.

A page's blocks run in order in one temporary directory and one new Python process of their
own (a user working through the page in one folder), and nothing is provided: a file a
command reads (``spiral.csv``, ``arm.urdf``) must come from an earlier block of the same page.
``python`` blocks each run as a fresh script (a new namespace) with JAX's 64-bit mode OFF, as
in a new Python process (the tests' conftest turns it on; the page's process has no conftest):
the pages call float64 optional, so a block that needs it must turn it on itself.
``console`` blocks hold shell commands: ``jaxkin ...`` lines run through the command line's
entry point, and ``make TARGET`` lines must name a target of the Makefile (running them here
would install and test recursively; CI runs them). ``bash`` blocks are cluster job scripts
(SLURM's ``srun`` is not on this machine): they must parse (``bash -n``), and every ``jaxkin``
command in them must parse with the command line's own argument parser. Any other fenced block
language, or another command in a console block, fails: a block that cannot be checked is not
allowed.
"""

from __future__ import annotations

import os
import re
import shlex
import subprocess
import sys
import types
from pathlib import Path

import jax
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


def run_block(page: str, number: int, language: str, code: str, targets: set[str]) -> None:
    """One block, in the current directory (the page's)."""
    if language == "python":
        jax.config.update("jax_enable_x64", False)  # a new process: float32 unless asked
        # A module of its own: dataclasses defined in a block look their module up.
        module = types.ModuleType("__docs__")
        sys.modules[module.__name__] = module
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
    for line in code.splitlines():
        command = shlex.split(line, comments=True)
        if not command:
            continue
        if command[0] == "make":
            assert set(command[1:]) <= targets, line
        else:
            assert command[0] == "jaxkin", f"{page}: only jaxkin and make commands run: {line}"
            assert cli.main(command[1:]) == 0, f"{page} block {number}: {line}"


PAGES_WITH_BLOCKS = sorted({page for page, _, lang, _ in BLOCKS if lang in RUNNABLE})


def run_page(page: str) -> None:
    """Every block of ``page`` in order, in the current directory, in this process: a fresh
    interpreter started by ``test_page_runs``, so JAX's configuration is a user's (64-bit mode
    off), and reset to it before each python block (a ``jaxkin`` command line turns it on in
    its own process)."""
    targets = make_targets()
    for name, number, language, code in BLOCKS:
        if name == page and language in RUNNABLE:
            run_block(page, number, language, code, targets)


# Pages whose blocks plan, optimise or solve URDF arms (each compiles for seconds): slow tier.
SLOW_PAGES = {"docs/planning.md", "docs/urdf.md", "docs/cli.md"}


@pytest.mark.parametrize(
    "page",
    [pytest.param(p, marks=pytest.mark.slow if p in SLOW_PAGES else ()) for p in PAGES_WITH_BLOCKS],
)
def test_page_runs(page, tmp_path):
    """One new Python process per page (JAX as a user gets it: no x64, no conftest), sharing
    the tests' persistent compilation cache."""
    cache = jax.config.jax_compilation_cache_dir or ""
    env = {k: v for k, v in os.environ.items() if not k.startswith(("JAX_", "XLA_"))}
    env.update(JAXKIN_TEST_CACHE=cache, JAX_PLATFORMS="cpu", PYTHONPATH=str(ROOT))
    done = subprocess.run(
        [sys.executable, "-m", "tests.test_docs", page],
        cwd=tmp_path,
        env=env,
        capture_output=True,
        text=True,
        timeout=900,
    )
    assert done.returncode == 0, f"{page}:\n{done.stdout[-3000:]}\n{done.stderr[-5000:]}"


if __name__ == "__main__":
    if os.environ.get("JAXKIN_TEST_CACHE"):
        jax.config.update("jax_compilation_cache_dir", os.environ["JAXKIN_TEST_CACHE"])
        jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.2)
    run_page(sys.argv[1])
