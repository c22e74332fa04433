"""Every example runs to completion (each is a user-facing promise)."""

import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


@pytest.mark.parametrize(
    "script, args, expected",
    [
        ("dyad_demo.py", [], "statuses"),
        ("planner_scara.py", ["400"], "feasible:"),
        ("optimise_scara.py", [], "cost after"),
    ],
)
def test_example_runs(script, args, expected):
    proc = subprocess.run(
        [sys.executable, str(ROOT / "examples" / script), *args],
        capture_output=True,
        text=True,
        timeout=300,
        cwd=ROOT,
    )
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert expected in proc.stdout
