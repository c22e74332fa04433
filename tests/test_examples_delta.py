"""Run examples/delta_workspace.py on a coarse grid and check what it prints."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def test_delta_workspace_example_runs():
    completed = subprocess.run(
        [sys.executable, str(ROOT / "examples" / "delta_workspace.py"), "--resolution", "5"],
        capture_output=True,
        text=True,
        timeout=120,
        cwd=ROOT,
    )
    assert completed.returncode == 0, completed.stderr
    out = completed.stdout
    # 5 cm grid over the paper's box: 21 x 21 x 19 voxels
    assert "voxels evaluated: 8,379" in out
    reachable = int(re.search(r"reachable voxels: ([\d,]+)", out).group(1).replace(",", ""))
    assert 0 < reachable < 8379
    assert "shrinks with depth" in out
